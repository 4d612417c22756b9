"""What every log reader yields: channels (topic, type, encoding, embedded definition) and raw messages.

One reader per container: :mod:`.mcap_source` (MCAP, also rosbag2 directories with MCAP storage) and
:mod:`.rosbag_source` (ROS1 bags, rosbag2 sqlite3 storage). Each registers its containers here with
:func:`register_container` when it is imported (:mod:`autosar_cli.ingest` imports them), and
:func:`open_source` picks the reader from that registry. Payloads stay serialized here; decoding is
the job of :mod:`.typesys` and :mod:`.decoders`.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol, runtime_checkable

from autosar_cli.store.outputs import what_autosar_wrote


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


@dataclass(frozen=True, slots=True)
class Container:
    """One log container a reader handles (see :func:`register_container`)."""

    name: str  #: "mcap", "ros1", "rosbag2", ...
    expected: str  #: how an error message names what it accepts: ".mcap", "a rosbag2 directory"
    detect: Callable[[Path], bool]  #: True if this reader takes the path (file or directory), by its name
    open: Callable[[Path], LogSource]
    magic: bytes = b""  #: how a file of this container begins (b"": not known)


_CONTAINERS: list[Container] = []


def register_container(name: str, expected: str, detect: Callable[[Path], bool],
                       open: Callable[[Path], LogSource], magic: bytes = b"") -> None:
    """Make :func:`open_source` hand files that begin with `magic`, and paths that `detect` accepts, to `open`.

    Each reader module registers its containers when it is imported; :mod:`autosar_cli.ingest` imports
    them all, so this module never imports a reader (the readers import it)."""
    _CONTAINERS[:] = [c for c in _CONTAINERS if c.name != name] + [Container(name, expected, detect, open, magic)]


def _head(path: Path, size: int) -> bytes:
    """The first `size` bytes of a file (fewer if it is shorter; none if it cannot be read)."""
    try:
        with open(path, "rb") as f:
            return f.read(size)
    except OSError:
        return b""


def _by_magic(path: Path) -> Container | None:
    """The container whose first bytes the file ``path`` begins with, if any."""
    if path.is_file():
        head = _head(path, max((len(c.magic) for c in _CONTAINERS), default=0))
        for container in _CONTAINERS:
            if container.magic and head.startswith(container.magic):
                return container
    return None


def begins_as_a_container(path: Path) -> bool:
    """Whether ``path`` is a file that begins as a log container does (an MCAP, a ROS 1 bag), whatever its name."""
    return _by_magic(Path(path)) is not None


def _container(path: Path) -> Container:
    # a file's first bytes before its name: an MCAP saved without its suffix, or a bag renamed, is still what it is
    if (container := _by_magic(path)) is not None:
        return container
    for container in _CONTAINERS:
        if container.detect(path):
            return container
    if (product := what_autosar_wrote(path)) is not None:
        raise LogReadError(f"{path}: {product}, not a log")
    if path.is_dir():
        raise LogReadError(f"{path}: a directory but not a rosbag2 bag (no metadata.yaml, no .db3 or .mcap files)")
    if path.suffix.lower() == ".bin":
        raise LogReadError(f"{path}: a raw .bin without a DCA1000 parameter file (*.mmwave.json, .cfg or .lua) "
                           "beside it")
    if path.suffix.lower() == ".dbc":
        raise LogReadError(f"{path}: a CAN database (DBC), not a log: give it with --dbc")
    names = [c.expected for c in _CONTAINERS]
    expected = " or ".join([", ".join(names[:-1]), names[-1]] if len(names) > 1 else names)
    raise LogReadError(f"{path}: unknown log container (expected {expected}; nor is it a CAN log (.blf .asc .trc "
                       ".log .mf4), an NMEA text capture or a DCA1000 capture)")


def is_log_directory(path: Path) -> bool:
    """Whether the directory ``path`` is a log some registered container reads (a rosbag2 bag)."""
    return any(c.detect(path) for c in _CONTAINERS)


def container_of(path: Path) -> str:
    """The registered container that takes `path`: "mcap", "ros1" or "rosbag2" (a rosbag2 bag is a
    directory with metadata.yaml)."""
    return _container(path).name


@runtime_checkable
class KeepsUnverified(Protocol):
    """A reader of a container whose parts carry checksums (MCAP chunks' CRCs): it can read a part whose checksum
    fails, when asked, instead of leaving it out."""

    keep_unverified: bool


def open_source(path: Path, keep_unverified: bool = False) -> LogSource:
    """The reader for one log (file or rosbag2 directory). ``keep_unverified``: read the parts whose checksum fails
    (a warning names each) where the container has such parts."""
    path = Path(path)
    if not path.exists():
        raise LogReadError(f"{path}: no such file or directory")
    source = _container(path).open(path)
    if isinstance(source, KeepsUnverified):
        source.keep_unverified = keep_unverified
    return source
