"""Summaries of drive logs without decoding payloads: streams, types, counts, rates, time span.

MCAP files are summarised from their index (summary section); ROS1 bags and rosbag2 directories with
rosbags. Used by ``autosar info``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any


@dataclass
class StreamSummary:
    topic: str
    msgtype: str
    count: int
    start_ns: int
    end_ns: int

    @property
    def rate_hz(self) -> float:
        span = (self.end_ns - self.start_ns) / 1e9
        return (self.count - 1) / span if self.count > 1 and span > 0 else 0.0


@dataclass
class LogSummary:
    path: str
    container: str
    size_bytes: int
    streams: list[StreamSummary] = field(default_factory=list)

    @property
    def start_ns(self) -> int:
        return min((s.start_ns for s in self.streams if s.count), default=0)

    @property
    def end_ns(self) -> int:
        return max((s.end_ns for s in self.streams if s.count), default=0)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["duration_s"] = (self.end_ns - self.start_ns) / 1e9
        for s, ds in zip(self.streams, d["streams"], strict=True):
            ds["rate_hz"] = round(s.rate_hz, 3)
        return d


class LogReadError(RuntimeError):
    """A log cannot be opened or summarised; the message names the file and the problem."""


def container_of(path: Path) -> str:
    if path.is_dir():
        return "rosbag2"
    if path.suffix == ".mcap":
        return "mcap"
    if path.suffix == ".bag":
        return "ros1"
    raise LogReadError(f"{path}: unknown log container (expected .mcap, .bag or a rosbag2 directory)")


def summarize_log(path: Path) -> LogSummary:
    path = Path(path)
    if not path.exists():
        raise LogReadError(f"{path}: no such file or directory")
    kind = container_of(path)
    size = sum(p.stat().st_size for p in path.rglob("*") if p.is_file()) if path.is_dir() else path.stat().st_size
    summary = LogSummary(str(path), kind, size)
    try:
        if kind == "mcap":
            _summarize_mcap(path, summary)
        else:
            _summarize_rosbags(path, summary)
    except LogReadError:
        raise
    except Exception as exc:  # the readers raise many types; the user needs file + reason
        raise LogReadError(f"{path}: cannot read {kind} log: {exc}") from exc
    summary.streams.sort(key=lambda s: s.topic)
    return summary


def _summarize_mcap(path: Path, summary: LogSummary) -> None:
    """One pass over the records (no payload decoding): works for indexed and unindexed files."""
    from mcap.reader import make_reader

    streams: dict[int, StreamSummary] = {}
    with open(path, "rb") as f:
        for schema, channel, msg in make_reader(f).iter_messages(log_time_order=False):
            s = streams.get(channel.id)
            if s is None:
                s = streams[channel.id] = StreamSummary(channel.topic, schema.name if schema else "?", 0,
                                                        msg.log_time, msg.log_time)
            s.count += 1
            s.start_ns = min(s.start_ns, msg.log_time)
            s.end_ns = max(s.end_ns, msg.log_time)
    summary.streams.extend(streams.values())


def _summarize_rosbags(path: Path, summary: LogSummary) -> None:
    from rosbags.highlevel import AnyReader

    with AnyReader([path]) as reader:
        for conn in reader.connections:
            times = [t for _, t, _ in reader.messages(connections=[conn])]
            summary.streams.append(StreamSummary(conn.topic, conn.msgtype, len(times),
                                                 min(times, default=0), max(times, default=0)))
