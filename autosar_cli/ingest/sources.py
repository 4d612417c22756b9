"""What every log reader yields: channels (topic, type, encoding, embedded definition) and raw messages.

One reader per container: :mod:`.mcap_source` (MCAP, also rosbag2 directories with MCAP storage) and
:mod:`.rosbag_source` (ROS1 bags, rosbag2 sqlite3 storage). Payloads stay serialized here; decoding is
the job of :mod:`.typesys` and :mod:`.decoders`.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol


class LogReadError(RuntimeError):
    """A log cannot be opened or read; the message names the file (and offset) and the problem."""


@dataclass(frozen=True, slots=True)
class Channel:
    """One stream of a log."""

    key: tuple[str, int]  #: unique within one ingest: (file, channel id)
    topic: str
    msgtype: str  #: normalised ROS 2 style name, "pkg/msg/Name"
    encoding: str  #: "cdr" (ROS 2) or "ros1"
    schema: str = ""  #: embedded message definition ("" if the log has none)
    schema_encoding: str = ""  #: "ros2msg", "ros1msg", "ros2idl" or ""
    declared_count: int | None = None  #: message count the log's metadata claims, if it has any


@dataclass(slots=True)  # not frozen: a frozen dataclass's __init__ costs ~1 µs more, per message
class RawMessage:
    channel: Channel
    log_ns: int  #: recording time, ns since the Unix epoch
    data: bytes | memoryview


@dataclass
class ReadStats:
    """Progress and problems of one reader (filled while iterating)."""

    bytes_total: int = 0
    bytes_read: int = 0
    messages: int = 0
    warnings: list[str] = field(default_factory=list)
    counts: dict[tuple[str, int], int] = field(default_factory=dict)


class LogSource(Protocol):
    path: Path
    container: str
    stats: ReadStats

    def messages(self) -> Iterator[RawMessage]: ...


_TYPE = re.compile(r"^([\w]+)/(?:msg/)?([\w]+)$")


def normalise_type(name: str) -> str:
    """"sensor_msgs/Imu" and "sensor_msgs/msg/Imu" both become "sensor_msgs/msg/Imu"."""
    m = _TYPE.match(name.strip())
    return f"{m.group(1)}/msg/{m.group(2)}" if m else name.strip()


def container_of(path: Path) -> str:
    """"mcap", "ros1" or "rosbag2" from the path (a rosbag2 bag is a directory with metadata.yaml)."""
    if path.is_dir():
        if (path / "metadata.yaml").exists():
            return "rosbag2"
        raise LogReadError(f"{path}: a directory but not a rosbag2 bag (no metadata.yaml)")
    suffix = path.suffix.lower()
    if suffix == ".mcap":
        return "mcap"
    if suffix == ".bag":
        return "ros1"
    if suffix == ".yaml" and path.name == "metadata.yaml":
        return "rosbag2"
    if suffix == ".bin":
        raise LogReadError(f"{path}: a raw .bin without a DCA1000 parameter file (*.mmwave.json or .cfg) beside it")
    raise LogReadError(f"{path}: unknown log container (expected .mcap, .bag or a rosbag2 directory)")


def open_source(path: Path) -> LogSource:
    """The reader for one log (file or rosbag2 directory)."""
    path = Path(path)
    if not path.exists():
        raise LogReadError(f"{path}: no such file or directory")
    kind = container_of(path)
    if kind == "mcap":
        from .mcap_source import McapSource

        return McapSource(path)
    if kind == "ros1":
        from .rosbag_source import Ros1BagSource

        return Ros1BagSource(path)
    from .rosbag_source import open_rosbag2

    return open_rosbag2(path.parent if path.name == "metadata.yaml" else path)
