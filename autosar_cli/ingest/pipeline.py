"""``autosar ingest``: logs in, one drive.h5 out (streaming, bounded memory, atomic).

Streams are found by message type; the config names them (a topic pinned to a sensor gets that
sensor's name) and may pin the CAN topic. Everything skipped is counted and reported, nothing is fatal
but an unreadable input, a log with no sensor stream at all, or (unless ``allow_partial``) a drive
without radar or without any navigation stream.
"""

from __future__ import annotations

import contextlib
import dataclasses
import difflib
import hashlib
import json
import math
import os
import re
import statistics
import time
from collections import Counter, deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, NamedTuple

from autosar_cli import __version__, msgs
from autosar_cli.candb import DBC_UNITS, DbcError, load_dbc
from autosar_cli.config import Config, role_unit
from autosar_cli.store.drive import NMEA_TEXT_MSGTYPE, DriveWriter, chirp_on_navigation_clock
from autosar_cli.store.outputs import input_bytes

from . import fastcdr
from .dca1000 import CaptureError, Dca1000Capture, find_capture
from .decoders import (
    FIX_COLUMNS,
    IMU_COLUMNS,
    VELOCITY_COLUMNS,
    CanDecoder,
    CanStats,
    NmeaStreams,
    RadarDecoder,
    StreamInfo,
    TableStream,
    _stamp_ns,
    fix_row,
    imu_row,
    velocity_row,
)
from .inputs import InputError, SortedInputs
from .inputs import sort_inputs as _sort_inputs
from .radar_block import (
    CAPTURE_MSGTYPE,
    RadarParamsError,
    Recorded,
    capture_frame_starts,
    recorded_from_capture,
    resolve,
    write_capture_stream,
)
from .records import UNKNOWN_TIME, CanRecord, NmeaHeading, NmeaRecord, utc_text
from .series import ClockRate
from .sources import (
    Channel,
    LogReadError,
    LogSource,
    RawMessage,
    open_source,
)
from .typesys import MessageTypes, SchemaError

KIND_OF_TYPE = {
    msgs.CAN_FRAME: "can",
    msgs.NAV_SAT_FIX: "fix",
    msgs.TWIST_STAMPED: "velocity",
    msgs.TWIST_WITH_COVARIANCE_STAMPED: "velocity",
    msgs.NMEA_SENTENCE: "nmea",
    msgs.IMU: "imu",
    msgs.RAW_FRAME: "radar",
}
#: how the error of a drive without radar or navigation ends (a command that focuses says :func:`chain_hint`)
PARTIAL_HINT = " (use --allow-partial to write the drive anyway)"
MAX_TIME_GAP_S = 3600.0  #: inputs further apart than this are refused (unless --allow-time-gap)
#: inputs apart by more than this, less than MAX_TIME_GAP_S, are warned of: a recorder's split files meet (a few ms
#: apart), a log whose clock is off by a time zone's hours does not
APART_WARN_S = 60.0
#: rows of one stream from two inputs interleaving over longer than this are refused: a split recording's files
#: reorder across their boundary only by the messages' latency
INTERLEAVE_NS = 250_000_000
#: a CAN log's frame stamped this much (ns) before one read before it in the file (a logger writes frames as they
#: come: a clock set back while it recorded) is a warning; within it, frames of two channels a logger buffers apart
CAN_LOG_STEP_BACK_NS = 50_000_000
#: a CAN log with no frame for over this many periods of a frame ID that came regularly before (and over
#: CAN_LOG_STEP_BACK_NS) is a warning: frames lost, or the logger's clock set forward while it recorded
CAN_LOG_JUMP_PERIODS = 10
#: the intervals of a frame ID its period is the median of (regular: the longest within twice the shortest)
_JUMP_INTERVALS = 8


class _ForwardJumps:
    """Where a CAN log's times jump forward: no frame for over :data:`CAN_LOG_JUMP_PERIODS` periods of a frame ID that
    came regularly before, and the regular ID's frame after the silence late by it too (one on time: that ID came on,
    another one paused). Frames lost on the bus or by the logger, or the logger's clock set forward while it recorded
    (the frames after it read that much late); the rolling counters of the IDs across it tell which: on by one, no
    frame was lost."""

    def __init__(self) -> None:
        self.intervals: dict[tuple[str, int, bool], deque[int]] = {}
        self.last: dict[tuple[str, int, bool], int] = {}
        #: (size ns, the frame before it (1-based), the time before it ns, the ID's period ns, the ID) of each jump
        self.jumps: list[tuple[int, int, int, int, tuple[str, int, bool]]] = []
        #: a silence no regular ID's frame has ended yet: (size ns, frame, time before it, {ID: its period ns})
        self.pending: tuple[int, int, int, dict[tuple[str, int, bool], float]] | None = None
        #: the IDs whose first frame after the last jump is still to come: the frames lost there, were any lost
        self.waiting: dict[tuple[str, int, bool], int] = {}
        self.kept = self.skipped = 0  #: IDs whose rolling counter went on by one across a jump, or skipped

    def _period(self, key: tuple[str, int, bool]) -> float | None:
        """The median of the ID's last intervals (ns) where they are regular (the longest within twice the shortest)."""
        d = self.intervals.get(key)
        if d is None or len(d) < _JUMP_INTERVALS or min(d) <= 0 or max(d) > 2 * min(d):
            return None
        return statistics.median(d)

    def see(self, rec: CanRecord, frame: int, latest: int, counter_step: bool | None) -> None:
        """Take the frame ``rec`` (``frame`` frames before it; ``latest``: the latest time before it, ns), fed with
        ``counter_step`` (:attr:`CanDecoder.counter_step`)."""
        key = (rec.channel, rec.frame_id, rec.is_extended)
        gap = rec.t_ns - latest
        if frame and gap > CAN_LOG_STEP_BACK_NS:
            missed = {k: p for k in self.intervals if (p := self._period(k)) is not None
                      and gap > CAN_LOG_JUMP_PERIODS * p}
            if missed:
                self.pending = (gap, frame, latest, missed)
        before = self.last.get(key)
        if self.pending is not None and before is not None and (period := self._period(key)) is not None:
            gap, at_frame, at, missed = self.pending
            self.pending = None
            if rec.t_ns - before - period > gap / 2:  # its own frame late by the silence too
                fastest = min(missed, key=missed.__getitem__)
                self.jumps.append((gap, at_frame, at, int(missed[fastest]), fastest))
                self.waiting = {k: round(gap / p) - 1 for k, p in missed.items()}
        lost = self.waiting.pop(key, None)
        if lost is not None and counter_step is not None and lost % 16:  # 16 frames lost: the counter on by one
            self.kept += counter_step
            self.skipped += not counter_step
        if before is not None and rec.t_ns > before:
            self.intervals.setdefault(key, deque(maxlen=_JUMP_INTERVALS)).append(rec.t_ns - before)
        self.last[key] = rec.t_ns

    def warning(self, path: Path) -> str | None:
        """The one warning of the jumps, naming the largest; None where there are none."""
        if not self.jumps:
            return None
        gap, frame, at, period, (channel, frame_id, _) = max(self.jumps)
        said = (f"{path}: its frame times jump forward by up to {gap / 1e9:.3f} s after frame {frame} "
                f"({utc_text(at, 'milliseconds')}; {len(self.jumps)} such jump{'s' if len(self.jumps) > 1 else ''}): "
                f"no frame where ID 0x{frame_id:X}{f' on {channel}' if channel else ''} came every "
                f"{period / 1e6:.3g} ms ({gap / period:.0f} periods); ")
        if self.skipped:
            return said + (f"the rolling counters of {self.skipped} of the {self.kept + self.skipped} IDs that have "
                           "one skip across it: frames lost on the bus or by the logger, their signals missing there")
        if self.kept:
            return said + (f"the rolling counters of the {self.kept} IDs that have one go on by one across it: no "
                           "frame lost, the logger's clock set forward while it recorded? The frames after it are read "
                           "that much late (split the log there and give --time-offset)")
        return said + ("frames lost on the bus or by the logger, or its clock set forward while it recorded (no "
                       "rolling counter tells which; the frames after a clock set forward are read that much late: "
                       "split the log there and give --time-offset)")

ProgressFn = Callable[[int, int], None]


def chain_hint(what: str) -> str:
    """:data:`PARTIAL_HINT` as a command that focuses the drive, so has no ``--allow-partial``, says it (``what``:
    "a run", "a comparison")."""
    return f" ({what} needs radar and navigation; `autosar ingest --allow-partial` writes such a drive on its own)"


class IngestError(RuntimeError):
    """Ingest cannot produce a useful drive.h5; the message says which file and why, ``warnings`` what ingest had
    found wrong before it gave up (a storage file missing, a chunk skipped), which may be the cause."""

    def __init__(self, message: str, warnings: Iterable[str] = ()) -> None:
        super().__init__(message)
        self.warnings = list(warnings)


def carry_warnings(exc: BaseException, warnings: Iterable[str]) -> None:
    """Have ``exc`` (a later stage's failure) carry what the ingest warned of before it, as an
    :class:`IngestError`'s ``warnings`` do: the command says them before the error (a log cut short is what makes
    the navigation find no GNSS)."""
    warnings = list(warnings)
    if warnings and isinstance(exc, Exception):
        with contextlib.suppress(AttributeError, TypeError):  # an exception that takes no attributes
            exc.warnings = list(dict.fromkeys([*warnings, *getattr(exc, "warnings", [])]))  # type: ignore[attr-defined]


@dataclass
class IngestReport:
    output: str
    inputs: list[dict[str, Any]] = field(default_factory=list)
    streams: list[dict[str, Any]] = field(default_factory=list)
    can: dict[str, Any] = field(default_factory=dict)
    skipped_channels: list[dict[str, Any]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    start_ns: int = 0
    end_ns: int = 0
    bytes_read: int = 0
    messages: int = 0
    wall_s: float = 0.0
    partial: bool = False

    def to_dict(self) -> dict[str, Any]:
        d = dict(self.__dict__)
        d["duration_s"] = (self.end_ns - self.start_ns) / 1e9
        d["throughput_mb_s"] = self.bytes_read / 1e6 / self.wall_s if self.wall_s > 0 else 0.0
        return d


def sort_inputs(logs: Iterable[Path], can_logs: Iterable[Path] = (), nmea_logs: Iterable[Path] = (),
                radar_captures: Iterable[Path] = ()) -> SortedInputs:
    """:func:`.inputs.sort_inputs`, its refusal an :class:`IngestError`."""
    try:
        return _sort_inputs(logs, can_logs, nmea_logs, radar_captures)
    except InputError as exc:
        raise IngestError(str(exc)) from None


def _sanitise(topic: str) -> str:
    return re.sub(r"\W+", "_", topic.strip("/")) or "root"


def capture_files(path: Path) -> list[Path]:
    """The files a DCA1000 capture given as ``path`` reads: its parameter file and data files, where ``path`` names
    one of them (a capture's folder holds them all; ``[path]`` where none is found, as ingest then refuses it)."""
    if path.is_dir():
        return [path]
    try:
        data, params = find_capture(path)
    except CaptureError:
        return [path]
    return [params, *data]


def _sha256(path: Path, files: Sequence[Path] | None = None) -> tuple[int, str]:
    """(size in bytes, sha256 hex) of a file; of a directory, or of ``files`` (a capture named by one of its files):
    sha256 over the files' names (relative to the directory, or to ``path``'s folder) and digests."""
    folder = path if path.is_dir() else path.parent
    if files is None:
        files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    digests = []
    for p in files:
        with open(p, "rb") as f:
            digests.append(hashlib.file_digest(f, "sha256"))
    size = sum(p.stat().st_size for p in files)
    if not path.is_dir() and list(files) == [path]:
        return size, digests[0].hexdigest()
    h = hashlib.sha256()
    for p, d in zip(files, digests, strict=True):
        h.update(str(p.relative_to(folder)).encode() + d.digest())
    return size, h.hexdigest()


@dataclass(frozen=True)
class RadarCaptureOptions:
    """How a DCA1000 capture joins the drive: its start time (ns since the epoch, else the first message of
    ``sync_topic`` in the logs) and whether the recording's radar parameters override the config's."""

    start_ns: int | None = None
    sync_topic: str = "/dca1000/sync"
    override: bool = False


@dataclass(frozen=True)
class IngestOptions:
    """How :func:`ingest` reads a drive's inputs, as ``autosar run``, ``compare`` and ``batch`` pass it on: each
    field is the :func:`ingest` argument of its name (``radar``: ``radar_options``)."""

    dbc: Path | None = None
    radar: RadarCaptureOptions = RadarCaptureOptions()
    time_offsets: Mapping[Path, float] = field(default_factory=dict)
    max_time_gap_s: float = MAX_TIME_GAP_S
    allow_time_gap: bool = False
    allow_unverified: bool = False

    def files(self) -> list[Path]:
        """The files these options name (inputs too: never written)."""
        return [self.dbc] if self.dbc is not None else []

    def ingest_kwargs(self) -> dict[str, Any]:
        """These options as :func:`ingest`'s keyword arguments."""
        return {"dbc": self.dbc, "radar_options": self.radar, "time_offsets": self.time_offsets,
                "max_time_gap_s": self.max_time_gap_s, "allow_time_gap": self.allow_time_gap,
                "allow_unverified": self.allow_unverified}

    def to_dict(self) -> dict[str, Any]:
        """As run.json records them (paths as text)."""
        return {**dataclasses.asdict(self), "dbc": None if self.dbc is None else str(self.dbc),
                "time_offsets": {str(p): float(s) for p, s in self.time_offsets.items()}}


class _Tally(NamedTuple):
    """Counts of an ingest at one moment, for :meth:`_Ingest.check_used`."""

    can: CanStats  #: a copy
    skipped: set[tuple[str, str]]  #: channels (topic, type) skipped
    triggers: int  #: the radar's frame triggers taken
    duplicates: int  #: rows of every stream dropped as duplicates
    dropped: int  #: rows dropped as late or stamp outliers
    undecodable: int  #: messages of sensor streams that could not be decoded
    rows: int  #: rows the streams took from the inputs ended so far


class _Ingest:
    def __init__(self, writer: DriveWriter, config: Config, dbc: Path | None,
                 radar_options: RadarCaptureOptions = RadarCaptureOptions()) -> None:
        self.writer = writer
        self.config = config
        self.radar_options = radar_options
        self.sync_stamps: list[int] = []  #: every frame trigger on the sync topic (ns), as recorded
        self.sync_log_ns: list[int] = []  #: and when the logger took each in
        self.types = MessageTypes()
        self.warnings: list[str] = []
        #: inputs of which nothing went into the drive, and why: said once the drive is known to be written
        self.unused: list[str] = []
        self.rows_in_drive: list[int] = []  #: rows of the drive's streams each input gave, in their order
        self.skipped_channels: dict[tuple[str, str], dict[str, Any]] = {}
        self.streams: dict[str, Any] = {}  # drive.h5 group -> TableStream / NmeaStreams / RadarDecoder
        self.handlers: dict[tuple[str, int], Callable[[RawMessage], None] | None] = {}
        self.bad_messages: Counter[str] = Counter()
        self.bad_near: dict[str, int] = {}  #: first read position (byte) of each kind of undecodable message
        self.source_file = ""
        self.spans: dict[str, tuple[int, int]] = {}  #: input -> (first, last) message time, ns
        dbc_path = Path(dbc) if dbc else config.dbc_path
        try:
            db, dbc_warnings = load_dbc(dbc_path)
        except DbcError as exc:  # names the file already
            raise IngestError(str(exc)) from exc
        except Exception as exc:
            raise IngestError(f"{dbc_path}: {exc}") from exc
        self.dbc_path = dbc_path
        self.warnings.extend(dbc_warnings)
        self.can = CanDecoder(writer, db, config.can.checksum, lambda: {"source_file": self.source_file},
                              geodetic={(m, sig) for role, ref in config.can.roles.items() if role_unit(role) == "deg"
                                        for m, _, sig in [ref.partition(".")]})
        self.names = self._configured_names()
        self.used_names: dict[tuple[str, str], str] = {}
        #: the streams named after their topic, no sensor of the config's naming it: (kind, topic)
        self.unnamed: set[tuple[str, str]] = set()
        self.named: set[str] = set()  #: the pinned topics the logs hold

    # -- naming ------------------------------------------------------------------------------------
    def _configured_names(self) -> dict[str, tuple[str, str]]:
        """topic -> (kind, sensor name) for every topic the config pins."""
        return {topic: (kind, name) for topic, (kind, name, _) in self.config.pinned_topics().items()}

    def _name(self, kind: str, topic: str) -> str:
        pinned = self.names.get(topic)
        if pinned and pinned[0] == kind:
            self.named.add(topic)
            return pinned[1]
        if kind in ("fix", "velocity", "nmea"):
            ns = topic.rsplit("/", 1)[0].strip("/")
            name = _sanitise(ns) if ns else "gnss"
        else:
            name = _sanitise(topic)
        self.unnamed.add((kind, topic))
        return name

    def misnamed_topics(self) -> list[str]:
        """A warning for each topic the config pins that no log holds where a stream of its kind came in on a
        topic of a near spelling no sensor names, and the logs hold another pinned topic of that kind (the config
        is the drive's) or it is its kind's only one: a typo in the config's topic (navigation would go without
        that sensor, or without its velocity, and say nothing). A log recorded on other topics altogether is the
        config sketch's to map."""
        pinned = self.config.pinned_topics()
        kinds_found = {pinned[t][0] for t in self.named if t in pinned}
        pinned_per_kind = Counter(kind for kind, _, _ in pinned.values())
        said = []
        for topic, (kind, sensor, key) in pinned.items():
            if not topic or topic in self.named or (kind not in kinds_found and pinned_per_kind[kind] > 1):
                continue
            near = difflib.get_close_matches(topic, [t for k, t in self.unnamed if k == kind], n=3, cutoff=0.75)
            if near:
                said.append(f"{key}: {topic} is in none of the logs, which hold {kind} on {', '.join(near)}, a topic "
                            f"no sensor of the config names (a typo in the topic?): {sensor}'s {kind} is not in the "
                            "drive")
        return said

    def _attrs(self, ch: Channel, sensor: str) -> dict[str, Any]:
        attrs: dict[str, Any] = {"topic": ch.topic, "msgtype": ch.msgtype, "source_file": self.source_file,
                                 "sensor": sensor}
        s = self.config.sensors.get(sensor)
        if s is not None:
            attrs["lever_arm_m"] = list(s.lever_arm_m)
            attrs["configured_rate_hz"] = s.rate_hz
            if s.kind == "imu":
                attrs["dof"] = s.dof
        return attrs

    # -- routing -----------------------------------------------------------------------------------
    def _skip_channel(self, ch: Channel, reason: str) -> None:
        self.skipped_channels[(ch.topic, ch.msgtype)] = {"topic": ch.topic, "msgtype": ch.msgtype, "reason": reason,
                                                        "messages": 0}
        self.handlers[ch.key] = None

    def _route(self, ch: Channel) -> Callable[[RawMessage], None] | None:
        kind = "sync" if ch.topic == self.radar_options.sync_topic else KIND_OF_TYPE.get(ch.msgtype)
        if kind is None:
            self._skip_channel(ch, "not a sensor stream")
            return None
        if kind == "can" and self.config.can.topic and ch.topic != self.config.can.topic:
            self._skip_channel(ch, f"CAN topic pinned to {self.config.can.topic}")
            return None
        try:
            deser = self.types.deserializer(ch)
        except SchemaError as exc:
            self._skip_channel(ch, str(exc))
            self.warnings.append(f"{self.source_file}: topic {ch.topic} ({ch.msgtype}) skipped: {exc}")
            return None
        self.warnings.extend(self.types.warnings)
        self.types.warnings.clear()
        fn = getattr(self, f"_handler_{kind}")(ch, deser)
        self.handlers[ch.key] = fn
        return fn

    def _table(self, path: str, kind: str, columns: dict[str, Any], ch: Channel, sensor: str) -> TableStream:
        stream = self.streams.get(path)
        if stream is None:
            stream = self.streams[path] = TableStream(self.writer, path, kind, columns, self._attrs(ch, sensor))
        stream.info.topics.add(ch.topic)
        return stream

    def _handler_sync(self, ch: Channel, deser: Callable[[Any], Any]) -> Callable[[RawMessage], None]:
        def handle(raw: RawMessage) -> None:
            m = deser(raw.data)
            self.sync_stamps.append(_stamp_ns(getattr(m, "header", m)))
            self.sync_log_ns.append(raw.log_ns)

        return handle

    def _handler_imu(self, ch: Channel, deser: Callable[[Any], Any]) -> Callable[[RawMessage], None]:
        name = self._name("imu", ch.topic)
        stream = self._table(f"imu/{name}", "imu", IMU_COLUMNS, ch, name)
        push = stream.push

        def handle(raw: RawMessage) -> None:
            m = deser(raw.data)
            push(_stamp_ns(m.header), raw.log_ns, imu_row(m))

        if not self.types.is_builtin(ch):
            return handle
        fast = fastcdr.imu

        def handle_fast(raw: RawMessage) -> None:
            try:
                stamp, row = fast(raw.data)
            except fastcdr.NotLittleEndian:
                return handle(raw)
            push(stamp, raw.log_ns, row)

        return handle_fast

    def _handler_fix(self, ch: Channel, deser: Callable[[Any], Any]) -> Callable[[RawMessage], None]:
        name = self._name("fix", ch.topic)
        stream = self._table(f"gnss/{name}/fix", "fix", FIX_COLUMNS, ch, name)

        def handle(raw: RawMessage) -> None:
            m = deser(raw.data)
            row = fix_row(m)
            if row is None:
                stream.skip("no fix")
            elif row[0] == 0.0 and row[1] == 0.0:  # its status said fix: a receiver's placeholder before its first
                stream.skip("at 0°, 0°")
            else:
                stream.push(_stamp_ns(m.header), raw.log_ns, row)

        return handle

    def _handler_velocity(self, ch: Channel, deser: Callable[[Any], Any]) -> Callable[[RawMessage], None]:
        name = self._name("velocity", ch.topic)
        stream = self._table(f"gnss/{name}/velocity", "velocity", VELOCITY_COLUMNS, ch, name)

        def handle(raw: RawMessage) -> None:
            m = deser(raw.data)
            row = velocity_row(m)
            if row is None:
                stream.skip("no velocity")
            else:
                stream.push(_stamp_ns(m.header), raw.log_ns, row)

        return handle

    def _handler_nmea(self, ch: Channel, deser: Callable[[Any], Any]) -> Callable[[RawMessage], None]:
        name = self._name("nmea", ch.topic)
        path = f"gnss/{name}"
        streams = self.streams.get(path)
        if streams is None:
            streams = self.streams[path] = NmeaStreams(self.writer, path, self._attrs(ch, name))
        for s in (streams.fix, streams.velocity, streams.vtg, streams.heading):
            s.info.topics.add(ch.topic)

        def handle(raw: RawMessage) -> None:
            m = deser(raw.data)
            streams.feed(m.sentence, _stamp_ns(m.header), raw.log_ns)

        return handle

    def _handler_can(self, ch: Channel, deser: Callable[[Any], Any]) -> Callable[[RawMessage], None]:
        feed = self.can.feed
        topic = ch.topic

        def handle(raw: RawMessage) -> None:
            m = deser(raw.data)
            stamp = _stamp_ns(m.header)
            frame = CanRecord(stamp or raw.log_ns, int(m.id), bool(m.is_extended), int(m.dlc), bytes(m.data),
                              bool(m.is_error), bool(m.is_rtr))
            feed(frame, stamp, raw.log_ns, topic)

        if not self.types.is_builtin(ch):
            return handle
        fast = fastcdr.can_frame

        def handle_fast(raw: RawMessage) -> None:
            try:
                stamp, frame_id, is_rtr, is_extended, is_error, dlc, data = fast(raw.data)
            except fastcdr.NotLittleEndian:
                return handle(raw)
            feed(CanRecord(stamp or raw.log_ns, frame_id, is_extended, dlc, data, is_error, is_rtr), stamp,
                 raw.log_ns, topic)

        return handle_fast

    def _handler_radar(self, ch: Channel, deser: Callable[[Any], Any]) -> Callable[[RawMessage], None]:
        name = self._name("radar", ch.topic)
        path = f"radar/{name}"
        dec = self.streams.get(path)
        if dec is None:
            what = f"{self.source_file}: topic {ch.topic}"
            dec = self.streams[path] = RadarDecoder(self.writer, path, self._attrs(ch, name),
                                                    lambda params: self._radar_block(params, what))
        dec.info.topics.add(ch.topic)
        feed, feed_parts = dec.feed, dec.feed_parts

        def handle(raw: RawMessage) -> None:
            feed(deser(raw.data), raw.log_ns)

        if not self.types.is_builtin(ch):
            return handle
        fast = fastcdr.raw_frame

        def handle_fast(raw: RawMessage) -> None:
            try:
                parts = fast(raw.data)
            except fastcdr.NotLittleEndian:
                return handle(raw)
            feed_parts(*parts, raw.log_ns)

        return handle_fast

    def _radar_block(self, params: tuple[Any, ...], what: str) -> dict[str, Any]:
        """Radar attributes for a RawFrame stream's parameters (see :func:`.fastcdr.raw_frame`)."""
        f0, slope, fs, offsets, (n_tx, n_rx, n_samples) = params
        rec = Recorded(f0, slope, fs, n_samples, n_tx, n_rx, tuple(offsets))
        return resolve(rec, self.config.radar, what=what, override=self.radar_options.override,
                       warn=self.warnings.append)

    def run_capture(self, path: Path, progress: Callable[[int], None]) -> int:
        """A DCA1000 capture into the configured radar's group; after the logs (their sync topic gives its start)."""
        cap = Dca1000Capture(path)
        self.source_file = str(path)
        try:
            frame_starts, timing = capture_frame_starts(cap, self.radar_options.start_ns, self.sync_stamps,
                                                        self.radar_options.sync_topic, warn=self.warnings.append)
        except ValueError as exc:
            raise IngestError(f"{path}: {exc}") from None
        name = self.config.radar.name
        group = f"radar/{name}"
        if group in self.streams:
            raise IngestError(f"{path}: the drive already has radar {name} from a log; give one radar source")
        attrs = resolve(recorded_from_capture(cap), self.config.radar, what=str(path),
                        override=self.radar_options.override, warn=self.warnings.append)
        attrs.update({"topic": "", "msgtype": CAPTURE_MSGTYPE, "source_file": str(path), "sensor": name,
                      "start_time_source": f"topic {self.radar_options.sync_topic}, a trigger per frame"
                      if cap.params.hardware_trigger else "--radar-start" if self.radar_options.start_ns is not None
                      else f"topic {self.radar_options.sync_topic}",
                      "layout": "frame, tx, rx, sample, I/Q", **timing})
        if timing.get("frame_clock_applied"):  # the crystal the frames showed times the chirps too
            attrs = chirp_on_navigation_clock(attrs, timing["frame_clock_drift_ppm"])
        info = write_capture_stream(self.writer, group, cap, frame_starts, attrs, progress)
        if info.stats is not None and self.radar_options.start_ns is None:
            # the triggers' stamps against when the logger took them in: their clock's rate (_radar_clock_rates)
            rate = ClockRate()
            for stamp, log_ns in zip(self.sync_stamps, self.sync_log_ns, strict=True):
                if stamp > 0:
                    rate.add(stamp, log_ns)
            if (fit := rate.fit()) is not None:
                info.stats.clock_rate_ppm, info.stats.clock_rate_std_ppm = fit
        self.warnings.extend(cap.warnings)  # after the stream: the PRIs left out are known once it is read
        if cap.params.range_bias_m:
            self.warnings.append(f"{cap.params.source}: compRangeBiasAndRxChanPhase's range bias "
                                 f"{cap.params.range_bias_m:g} m is not applied: ranges as the capture measures them")
        self.streams[group] = _Finished(info)
        return cap.num_pris

    # -- driving -----------------------------------------------------------------------------------
    def run_source(self, src: LogSource, progress: Callable[[int], None]) -> int:
        self.source_file = str(src.path)
        handlers = self.handlers
        n = 0
        first = last = None
        for raw in src.messages():
            n += 1
            last = raw
            if first is None:
                first = raw.log_ns
            key = raw.channel.key
            fn = handlers[key] if key in handlers else self._route(raw.channel)
            if fn is None:
                sk = self.skipped_channels.get((raw.channel.topic, raw.channel.msgtype))
                if sk is not None:
                    sk["messages"] += 1
                continue
            try:
                fn(raw)
            except RadarParamsError:
                raise
            except Exception as exc:  # one undecodable message must not end the ingest
                what = f"{self.source_file}: {raw.channel.topic}: {type(exc).__name__}"
                self.bad_messages[what] += 1
                self.bad_near.setdefault(what, src.stats.bytes_read)
            if n & 1023 == 0:
                progress(src.stats.bytes_read)
        progress(src.stats.bytes_total)
        self.warnings.extend(src.stats.warnings)
        if first is not None and last is not None:
            self.spans[str(src.path)] = (first, last.log_ns)
        return n

    def run_can_log(self, path: Path, offset_ns: int = 0) -> int:
        from .canlog import CanLogError, read_can_log

        self.source_file = str(path)
        n = 0
        first = last = latest = 0
        back = (0, 0, 0, 0)  # the largest step back: (ns, frame, its time, frames stamped before one read earlier)
        jumps = _ForwardJumps()
        try:
            for rec in read_can_log(path, self.warnings.append):
                if offset_ns:
                    rec = dataclasses.replace(rec, t_ns=rec.t_ns + offset_ns)
                self.can.feed(rec, None, rec.t_ns, f"file:{path.name}")
                jumps.see(rec, n, latest, self.can.counter_step)
                first = rec.t_ns if n == 0 else first
                last = rec.t_ns
                if latest - rec.t_ns > CAN_LOG_STEP_BACK_NS:
                    back = (max(back[0], latest - rec.t_ns), *(back[1:3] if back[3] else (n + 1, rec.t_ns)),
                            back[3] + 1)
                latest = max(latest, rec.t_ns)
                n += 1
        except CanLogError as exc:
            if n == 0:
                raise LogReadError(str(exc)) from exc
            self.warnings.append(str(exc))  # it says how many frames came before the damage
        if back[3]:
            self.warnings.append(
                f"{path}: its frame times step back by up to {back[0] / 1e9:.3f} s from frame {back[1]} on "
                f"({utc_text(back[2], 'milliseconds')}; {back[3]} frames stamped over "
                f"{CAN_LOG_STEP_BACK_NS / 1e6:g} ms before one the file holds before them): the logger's clock set "
                "back while it recorded? The frames either side are read as stamped, those on one side that much off "
                "(split the log there and give --time-offset)")
        if (jumped := jumps.warning(path)) is not None:
            self.warnings.append(jumped)
        if n:
            self.spans[str(path)] = (first, last)
        return n

    def run_nmea_log(self, path: Path, offset_ns: int = 0) -> int:
        from .nmea import NmeaLogReader, nothing_read

        self.source_file = str(path)
        name = _sanitise(path.stem)
        key = f"gnss/{name}"
        streams = self.streams.get(key)
        if streams is None:
            attrs = {"topic": "", "msgtype": NMEA_TEXT_MSGTYPE, "source_file": str(path), "sensor": name}
            streams = self.streams[key] = NmeaStreams(self.writer, key, attrs)
        # a capture without RMC/ZDA has times of day only: date them by the streams read so far
        anchor = min((a for a, _ in self.spans.values()), default=None)
        reader = NmeaLogReader(path, None if anchor is None else anchor - offset_ns)
        n = 0
        first = last = 0
        for rec in reader:
            if offset_ns:
                rec = _shifted(rec, offset_ns)
            streams.route([rec], None)
            first = rec.t_ns if n == 0 else min(first, rec.t_ns)
            last = max(last, rec.t_ns)
            n += 1
        streams.decoder.skipped.update(reader.skipped)
        dec = reader.decoder
        unread = nothing_read(reader)
        if unread:
            raise LogReadError(f"{path}: {unread} (read as an NMEA text capture"
                               + (": its name ends in .log but it is not a CAN log either)" if
                                  path.suffix.lower() == ".log" else ")"))
        if reader.skipped["cut off by the file's end"]:
            self.warnings.append(f"{path}: its last line is cut off by the file's end (a capture cut short); the "
                                 "sentence there skipped")
        if reader.damaged_lines:
            self.warnings.append(f"{path}: {reader.damaged_lines} damaged line(s), {reader.damaged_bytes} bytes, "
                                 "skipped (a bad or no checksum, or bytes that are no sentence; the first at byte "
                                 f"{reader.first_damage_byte})")
        if dec.anchored:
            self.warnings.append(f"{path}: no RMC or ZDA sentence gives the date; {dec.anchored} NMEA records dated "
                                 "by the other inputs (the day that puts them within 12 h of "
                                 f"{utc_text(anchor or 0)})")
        if n:
            self.spans[str(path)] = (first, last)
        return n

    def tally(self) -> _Tally:
        """What :meth:`check_used` compares, so far."""
        st = self.can.stats
        series = [s for _, s in self.named_series()]
        return _Tally(dataclasses.replace(st, unknown_ids=Counter(st.unknown_ids), other_bus=Counter(st.other_bus)),
                      set(self.skipped_channels),
                      len(self.sync_stamps), sum(s.stats.duplicates for s in series),
                      sum(s.stats.late_dropped + s.stats.stamp_outliers for s in series), self.bad_messages.total(),
                      sum(rows for s in series for *_, rows in s.inputs))

    def check_used(self, path: Path, kind: str, read: int, before: _Tally) -> None:
        """What the input just read (``read`` messages, frames or records; ended with :meth:`end_input`) gave the
        drive (``before``: :meth:`tally` before it), in :attr:`rows_in_drive`; where nothing, why, in
        :attr:`unused`."""
        now, can, was = self.tally(), self.can.stats, before.can
        # a capture writes its own group (or fails saying why); frame triggers time one
        rows = read if kind == "radar" else now.rows - before.rows + now.triggers - before.triggers
        self.rows_in_drive.append(rows)
        if rows:
            return
        frames = can.frames - was.frames
        if now.duplicates > before.duplicates or now.dropped > before.dropped:
            dup, late = now.duplicates - before.duplicates, now.dropped - before.dropped
            why = "every row of it dropped: " + ", ".join(p for p in (
                f"{dup} the same as rows read before (duplicates)" if dup else "",
                f"{late} stamped before rows already written (repeats of them, or late)" if late else "") if p)
        elif now.undecodable > before.undecodable:
            why = (f"{now.undecodable - before.undecodable} messages of its sensor streams could not be decoded "
                   "(the warning of undecodable messages names them)")
        elif frames:
            unknown = can.unknown_ids - was.unknown_ids
            ids = ", ".join(k for k, _ in unknown.most_common(5))
            parts = [f"{unknown.total()} with an ID not in the DBC {self.dbc_path} ({ids})" if unknown else "",
                     f"{other.total()} on a second bus ({', '.join(k for k, _ in other.most_common(3))})"
                     if (other := can.other_bus - was.other_bus) else "",
                     f"{can.error_frames - was.error_frames} error frames" if can.error_frames > was.error_frames
                     else "",
                     f"{can.remote_frames - was.remote_frames} remote frames" if can.remote_frames > was.remote_frames
                     else ""]
            said = ", ".join(p for p in parts if p)
            why = f"none of its {frames} CAN frames decoded" + (f": {said}" if said else " (the CAN counts say why)")
        elif kind == "can":
            why = "the file is empty" if path.stat().st_size == 0 else \
                "no CAN frame read from it (a file of its kind, but no frame python-can reads)"
        elif read:
            seen = [f"{t} ({m})" for t, m in self.skipped_channels if (t, m) not in before.skipped]
            why = f"none of its {read} messages is of a known sensor stream" + (f"; found {', '.join(seen[:5])}"
                                                                                 if seen else "")
        else:
            why = "no message in it"
        self.unused.append(f"{path}: nothing of it is in the drive: {why}")

    def end_input(self, path: Path | str) -> None:
        """Every stream's rows since the last input came from ``path``."""
        for _, series in self.named_series():
            series.end_input(str(path))

    def named_series(self) -> list[tuple[str, Any]]:
        return [pair for s in self.streams.values() for pair in s.named_series()] + self.can.named_series()

    def check_interleaved(self) -> None:
        """Refuse inputs whose rows of one stream interleave for longer than a split recording's boundary
        reorders them (:meth:`Series.interleaved`): the drive would mix two recordings of that stream."""
        for path, series in self.named_series():
            got = series.interleaved(INTERLEAVE_NS)
            if got is not None:
                a, b, t0, t1 = got
                raise IngestError(
                    f"{b}: its {path} interleaves with {a}'s over {(t1 - t0) / 1e9:.2f} s "
                    f"({utc_text(t0, 'milliseconds')} to {utc_text(t1, 'milliseconds')}): two recordings of one "
                    "stream, or one sensor recorded twice on other clocks? Give the logs of one recording (the same "
                    "messages in two files are duplicates, dropped)")

    def finish(self) -> list[StreamInfo]:
        infos: list[StreamInfo] = []
        for stream in self.streams.values():
            got = stream.finish()
            if isinstance(got, list):
                infos.extend(got)
            elif got is not None:
                infos.append(got)
        infos.extend(self.can.finish())
        for info in infos:
            st = info.stats
            if st is None:
                continue
            source = "log" if st.log_time_used >= st.received else "header" if st.log_time_used == 0 else "mixed"
            self.writer.set_attrs(info.path, {"time_source": source, "messages": st.written,
                                              "clock_offset_ns": st.clock_offset_ns})
        return infos


def ingest(logs: Sequence[Path], output: Path, *, config: Config, can_logs: Iterable[Path] = (),
           nmea_logs: Iterable[Path] = (), radar_captures: Iterable[Path] = (), **options: Any) -> IngestReport:
    """Ingest ``logs`` (+ standalone CAN and NMEA logs, DCA1000 captures) into ``output`` (drive.h5), atomically.

    A CAN log, NMEA capture or DCA1000 capture among ``logs`` is read as one, a drive folder as the inputs it holds
    (:func:`.inputs.sort_inputs`); ``options`` as :func:`ingest_sorted` takes them.
    """
    given = sort_inputs([] if logs is None else logs, can_logs, nmea_logs, radar_captures)
    return ingest_sorted(given, output, config=config, **options)


def _radar_alone_hint(capture: Path) -> str:
    """How a capture with no log could be ingested alone: by ``--radar-start``, unless its frames start on a
    hardware trigger (then only their triggers time them)."""
    try:
        hardware = Dca1000Capture(capture).params.hardware_trigger
    except (CaptureError, OSError, ValueError):  # only the hint depends on it; ingest names a damaged capture
        hardware = False
    if hardware:
        return (": its frames start on a hardware trigger (triggerSelect 2), so only their triggers time them; "
                "--radar-start cannot")
    return ", or --radar-start TIME --allow-partial for the radar alone"


def ingest_sorted(given: SortedInputs, output: Path, *, config: Config, dbc: Path | None = None,
                  radar_options: RadarCaptureOptions = RadarCaptureOptions(), allow_partial: bool = False,
                  progress: ProgressFn | None = None, command: str = "",
                  time_offsets: Mapping[Path, float] | None = None, max_time_gap_s: float = MAX_TIME_GAP_S,
                  allow_time_gap: bool = False, allow_unverified: bool = False,
                  partial_hint: str = PARTIAL_HINT) -> IngestReport:
    """Ingest inputs already sorted by :func:`sort_inputs` into ``output`` (drive.h5), atomically.

    ``time_offsets``: seconds added to every time of a standalone CAN or NMEA log (a logger's clock set
    wrong). Inputs whose spans lie more than ``max_time_gap_s`` apart are refused unless ``allow_time_gap``.
    ``allow_unverified``: read the MCAP chunks whose CRC fails (each named in a warning) rather than leave them out.
    ``partial_hint``: how the error of a drive without radar or navigation ends.
    """
    t0 = time.perf_counter()
    inputs = given.all()  # a CAN log, NMEA capture or DCA1000 capture among the logs is read as what it is
    if not inputs:
        raise IngestError("no input: give at least one log, --can-log or --nmea file")
    captures = [p for p, kind in inputs if kind == "radar"]
    if captures and radar_options.start_ns is None and not any(kind == "log" for _, kind in inputs):
        raise IngestError(f"{captures[0]}: a DCA1000 capture and no log, so no start time for its frames: the log "
                          f"recorded with it holds the triggers that time them (topic {radar_options.sync_topic}) "
                          f"and the drive's navigation; give it too (autosar ingest LOG --radar {captures[0]})"
                          + _radar_alone_hint(captures[0]))
    offsets = {Path(p): round(float(s) * 1e9) for p, s in (time_offsets or {}).items()}
    for p in offsets:
        if (p, "can") not in inputs and (p, "nmea") not in inputs:
            raise IngestError(f"--time-offset {p}: not one of the CAN or NMEA logs given (a container log's "
                              "header stamps cannot be shifted; use --allow-time-gap)")
    inputs = can_logs_in_time_order(inputs, offsets)
    sources: list[tuple[Path, str, LogSource | None]] = []
    for path, kind in inputs:
        if kind == "log" and path.name == "metadata.yaml":  # a rosbag2 bag: the directory is the input (provenance)
            path = path.parent
        try:
            sources.append((path, kind, open_source(path, allow_unverified) if kind == "log" else None))
        except LogReadError as exc:
            raise IngestError(str(exc)) from exc
    total = sum(_input_bytes(path, s) for path, _, s in sources)
    report = IngestReport(str(output))
    hasher = ThreadPoolExecutor(1, thread_name_prefix="sha256")
    hashes: list[Future[tuple[int, str]]] = [
        hasher.submit(_sha256, p, capture_files(p) if kind == "radar" and p.is_file() else None)
        for p, kind, _ in sources]
    attrs = {"autosar_version": __version__, "created_utc": datetime.now(UTC).isoformat(timespec="seconds"),
             "config_path": config.source, "config_toml": _config_text(config)}
    done = 0
    writer = DriveWriter(output, attrs)
    job: _Ingest | None = None
    try:
        job = _Ingest(writer, config, dbc, radar_options)
        job.warnings += given.warnings  # what a drive folder holds that is no input
        for path, kind, src in sources:
            report_progress = (lambda b, base=done: progress(base + b, total)) if progress else (lambda b: None)
            before = job.tally()
            try:
                if src is not None:
                    read = job.run_source(src, report_progress)
                elif kind == "can":
                    read = job.run_can_log(path, offsets.get(path, 0))
                elif kind == "radar":
                    read = job.run_capture(path, report_progress)
                else:
                    read = job.run_nmea_log(path, offsets.get(path, 0))
            except (LogReadError, RadarParamsError) as exc:
                raise IngestError(str(exc), src.stats.warnings if src is not None else ()) from exc
            report.messages += read
            job.end_input(path)
            job.check_used(path, kind, read, before)
            done += _input_bytes(path, src)
            report_progress(0)
        check_time_gaps(job.spans, max_time_gap_s, allow_time_gap, job.warnings,
                        {str(p): offsets.get(p, 0) for p, kind in inputs if kind in ("can", "nmea")})
        job.check_interleaved()
        infos = job.finish()
        _check_content(inputs, infos, job, allow_partial, report, partial_hint)
        job.warnings += job.unused + job.misnamed_topics()
        _radar_clock_rates(infos, writer, job.warnings)
        _plausibility(infos, job)
        roles, missing_roles = _resolve_roles(job, infos)
        job.warnings += _role_unit_warnings(job, roles)
        if missing_roles and job.can.stats.frames:  # with no CAN at all, `ingest` says the roles go unused
            job.warnings.append(f"CAN roles of the config in no frame of the logs: {', '.join(missing_roles)} "
                                "(a message or signal the DBC or the log does not have): the stages go without them")
        report.streams = [i.to_dict() for i in infos]
        report.can = {**job.can.stats.to_dict(), "roles": roles, "missing_roles": missing_roles}
        if job.bad_messages:
            report.can["undecodable_messages"] = dict(job.bad_messages)
            report.warnings.append(f"{sum(job.bad_messages.values())} messages could not be decoded: "
                                   + ", ".join(f"{k} ×{v} (the first near byte {job.bad_near.get(k, 0)})"
                                               for k, v in job.bad_messages.items()))
        report.skipped_channels = list(job.skipped_channels.values())
        report.warnings = job.warnings + report.warnings
        written = [i.stats for i in infos if i.stats is not None and i.stats.written]
        report.start_ns = min((s.first_ns for s in written), default=0)
        report.end_ns = max((s.last_ns for s in written), default=0)
        for (path, kind, _), fut, rows in zip(sources, hashes, job.rows_in_drive, strict=True):
            size, digest = fut.result()
            # absolute: a later command finds the input (its truth sidecar) from any directory
            report.inputs.append({"path": os.path.abspath(path), "kind": kind, "size_bytes": size, "sha256": digest,
                                  "rows_in_drive": rows})
        report.bytes_read = total
        report.wall_s = time.perf_counter() - t0
        writer.set_attrs("can", {"roles": roles, "dbc_path": str(job.dbc_path)})
        writer.set_attrs("/", {"start_ns": report.start_ns, "end_ns": report.end_ns})
        writer.write_inputs(report.inputs)
        writer.set_attrs("provenance", {"command": command, "report": json.dumps(report.to_dict())})
        writer.commit()
    except IngestError as exc:
        writer.abort()
        exc.warnings = list(dict.fromkeys((job.warnings if job is not None else []) + exc.warnings))
        raise
    except BaseException:
        writer.abort()
        raise
    finally:
        hasher.shutdown(wait=False, cancel_futures=True)
    report.wall_s = time.perf_counter() - t0
    return report


_EARLIEST_START_NS = 946_684_800 * 1_000_000_000  #: 2000-01-01 UTC: no radar capture is older
_CENTURY_S = 100 * 365.25 * 86400.0


def parse_time_ns(text: str) -> int:
    """``--radar-start``: integer ns since the Unix epoch, or an ISO 8601 time (UTC unless it says otherwise)."""
    text = text.strip()
    if re.fullmatch(r"-?\d+", text):
        ns = int(text)
    else:
        try:
            dt = datetime.fromisoformat(text.replace("Z", "+00:00"))
        except ValueError:
            raise IngestError(f"--radar-start {text!r}: expected ns since the Unix epoch or an ISO 8601 time") \
                from None
        if dt.tzinfo is None:
            dt = dt.replace(tzinfo=UTC)
        ns = int(dt.replace(microsecond=0).timestamp()) * 1_000_000_000 + dt.microsecond * 1000
    if not _EARLIEST_START_NS <= ns < 2**63:  # seconds or ms given for ns would put the radar in 1970
        raise IngestError(f"--radar-start {text!r}: not a time from 2000 on in ns since the Unix epoch (seconds "
                          "or milliseconds given? give ns, or an ISO 8601 time)")
    return ns


def can_logs_in_time_order(inputs: list[tuple[Path, str]], offsets: Mapping[Path, int]) -> list[tuple[Path, str]]:
    """``inputs`` (path, kind) with their CAN logs in the order of their first frames' times (plus their
    ``--time-offset``, ns), the other inputs where they are. A logger splits a drive into files that do not overlap,
    and a stream's reorder buffer puts back a few hundred messages: read after a later file, an earlier one's frames
    of a fast stream came too late and were dropped. A CAN log whose first frame is not read keeps its place (reading
    it says why); logs of one first time keep their order."""
    can = [path for path, kind in inputs if kind == "can"]
    if len(can) < 2:
        return inputs
    from .canlog import first_frame_ns

    firsts = {path: first_frame_ns(path) for path in can}
    timed = iter(sorted((p for p in can if firsts[p] is not None),
                        key=lambda p: (firsts[p] or 0) + offsets.get(p, 0)))
    ordered = iter([next(timed) if firsts[p] is not None else p for p in can])
    return [(next(ordered), kind) if kind == "can" else (path, kind) for path, kind in inputs]


def _input_bytes(path: Path, src: LogSource | None) -> int:
    if src is not None:
        return src.stats.bytes_total
    return input_bytes([path])


@dataclass
class _Finished:
    """A stream written in one go (a DCA1000 capture): nothing left to flush."""

    info: StreamInfo

    def finish(self) -> StreamInfo:
        return self.info

    def named_series(self) -> list[tuple[str, Any]]:
        return []


def _shifted(rec: NmeaRecord, offset_ns: int) -> NmeaRecord:
    """``rec`` with its times moved by ``offset_ns`` (``--time-offset``)."""
    if isinstance(rec, NmeaHeading):
        return dataclasses.replace(rec, t_ns=rec.t_ns + offset_ns)
    fix = rec.fix_time_ns if rec.fix_time_ns == UNKNOWN_TIME else rec.fix_time_ns + offset_ns
    return dataclasses.replace(rec, t_ns=rec.t_ns + offset_ns, fix_time_ns=fix)


def parse_time_offsets(items: Iterable[str]) -> dict[Path, float]:
    """``--time-offset PATH=SECONDS`` values as {path: seconds}."""
    out: dict[Path, float] = {}
    for item in items:
        path, sep, value = item.rpartition("=")
        try:
            seconds = float(value)
        except ValueError:
            seconds = math.nan
        if not sep or not path or not math.isfinite(seconds):
            raise IngestError(f"--time-offset {item!r}: expected PATH=SECONDS, e.g. can.asc=-3600")
        if abs(seconds) > _CENTURY_S:  # a logger's clock set wrong is years off at most
            raise IngestError(f"--time-offset {item!r}: more than a century either way")
        out[Path(path)] = seconds
    return out


#: a radar stream's stamps against its log times are reported where their rate differs from the navigation
#: streams' by this many std and moves the last frame by this much (s)
LOG_CLOCK_MIN_SIGMAS = 4.0
LOG_CLOCK_MIN_SHIFT_S = 1e-4


def _radar_clock_rates(infos: list[StreamInfo], writer: DriveWriter, warnings: list[str]) -> None:
    """How fast each radar stream's frame stamps run against the log times, less the navigation streams' rate
    (their median; 0 where none has header stamps): a radar that stamps its frames by its own frame counter runs
    at its crystal's rate, which the logger's reception times show. Stored on the radar's group
    (``log_clock_drift_ppm``, ``_std_ppm``) and, where it shows, one warning that names the value to state
    (``radar.clock_drift_ppm``). Not applied: a logger that falls further behind under load looks the same."""
    nav = [(i.stats.clock_rate_ppm, i.stats.clock_rate_std_ppm) for i in infos if i.kind != "radar"
           and i.stats is not None and i.stats.clock_rate_ppm is not None]
    reference = float(statistics.median(r for r, _ in nav)) if nav else 0.0
    reference_std = float(statistics.median(s or 0.0 for _, s in nav)) if nav else 0.0
    for info in infos:
        st = info.stats
        if info.kind != "radar" or st is None or st.clock_rate_ppm is None or st.clock_rate_std_ppm is None:
            continue
        drift, std = st.clock_rate_ppm - reference, math.hypot(st.clock_rate_std_ppm, reference_std)
        writer.set_attrs(info.path, {"log_clock_drift_ppm": drift, "log_clock_drift_std_ppm": std})
        shift_s = abs(drift) * 1e-6 * (st.last_ns - st.first_ns) / 1e9
        if abs(drift) >= LOG_CLOCK_MIN_SIGMAS * std and shift_s >= LOG_CLOCK_MIN_SHIFT_S:
            warnings.append(f"{info.path}: its frame stamps run {drift:+.1f} ± {std:.1f} ppm fast against the log "
                            f"times (the navigation's streams: {reference:+.1f} ppm), {shift_s * 1e3:.2g} ms over "
                            f"the drive: a radar clock of its own? state radar.clock_drift_ppm = {drift:.1f} (a "
                            "logger that falls behind under load looks the same)")


def check_time_gaps(spans: dict[str, tuple[int, int]], max_gap_s: float, allow: bool, warnings: list[str],
                    shiftable: Mapping[str, int] | None = None) -> None:
    """Refuse inputs whose time spans lie more than ``max_gap_s`` apart (different drives, or a clock set
    wrong), unless ``allow``: then warn. ``spans``: input -> (first, last) time, ns since the epoch;
    ``shiftable``: the CAN and NMEA logs among them -> the offset (ns) already added to their times, for the
    ``--time-offset`` the refusal proposes."""
    shiftable = shiftable or {}
    items = sorted(spans.items(), key=lambda kv: kv[1][0])
    said: set[tuple[str, str]] = set()
    for path, (a, b) in items:
        others = [(p, span) for p, span in items if p != path]
        if not others:
            return
        near, (c, d) = min(others, key=lambda o: max(0, a - o[1][1], o[1][0] - b))
        gap = max(0, a - d, c - b)
        if gap <= max_gap_s * 1e9:
            if gap > APART_WARN_S * 1e9 and a > c:  # said once, of the later of the two
                warnings.append(f"{path} ({utc_text(a)} to {utc_text(b)}) shares no time with the other inputs: it "
                                f"lies {_human(gap / 1e9)} after {near} ({utc_text(c)} to {utc_text(d)}), so nothing "
                                "in it joins them. A clock set wrong? (ASC and BLF logs carry the recording PC's local "
                                "time.) Shift a CAN or NMEA log with --time-offset PATH=SECONDS")
            continue
        what = (f"{path} ({utc_text(a)} to {utc_text(b)}) lies {_human(gap / 1e9)} away from {near} "
                f"({utc_text(c)} to {utc_text(d)}), more than the {max_gap_s:g} s allowed")
        if allow:
            if (near, path) not in said:  # a pair each the other's nearest: said once
                warnings.append(what + "; ingested as recorded (--allow-time-gap)")
                said.add((path, near))
            continue
        proposed = [f"{p}={(shiftable[p] + move) / 1e9:.0f}" for p, move in ((path, c - a), (near, a - c))
                    if p in shiftable]
        shift = ("Shift a CAN or NMEA log with --time-offset PATH=SECONDS"
                 + (f" (the starts lined up: {' or '.join(proposed)})" if proposed else "") + ", or give"
                 if shiftable else "Give")  # a container log's stamps are not shifted
        raise IngestError(what + f": different drives, or a clock set wrong? {shift} --allow-time-gap to ingest the "
                          "inputs as recorded")


def _human(seconds: float) -> str:
    for unit, size in (("years", 365.25 * 86400), ("days", 86400), ("h", 3600), ("min", 60)):
        if seconds >= size:
            return f"{seconds / size:.1f} {unit}"
    return f"{seconds:.1f} s"


def _config_text(config: Config) -> str:
    try:
        return config.text()
    except OSError:
        return ""


def _check_content(inputs: list[tuple[Path, str]], infos: list[StreamInfo], job: _Ingest, allow_partial: bool,
                   report: IngestReport, partial_hint: str = PARTIAL_HINT) -> None:
    names = ", ".join(str(p) for p, _ in inputs)
    written = [i for i in infos if i.stats is not None and i.stats.written]
    if not written:
        can = job.can.stats
        if can.frames and not can.decoded and can.unknown_ids:
            ids = ", ".join(k for k, _ in can.unknown_ids.most_common(5))
            raise IngestError(f"{names}: none of the {can.frames} CAN frames has an ID in the DBC {job.dbc_path} "
                              f"({len(can.unknown_ids)} IDs, e.g. {ids}); give the vehicle's DBC with --dbc")
        seen = ", ".join(f"{s['topic']} ({s['msgtype']})" for s in job.skipped_channels.values())
        damage = sorted((w for w in job.warnings if "damaged" in w or "truncated" in w or "corrupt" in w),
                        key=lambda w: "byte" not in w)  # the warning with the offset first
        dropped = _checksum_rule_misfit(job)
        raise IngestError(f"{names}: no known sensor streams (CAN frames, NavSatFix, NMEA, Imu, ScanBrick RawFrame)"
                          + (f"; found only {seen}" if seen else "") + (f"; {damage[0]}" if damage else "")
                          + (f"; {dropped}" if dropped else ""))
    has_radar = any(i.kind == "radar" for i in written)
    has_nav = any(i.kind in ("imu", "fix", "nmea_fix", "velocity") for i in written) or any(
        i.kind == "can" for i in written)
    missing = [what for what, ok in (("radar", has_radar), ("navigation (CAN, GNSS or IMU)", has_nav)) if not ok]
    if missing:
        msg = f"{names}: no {' and no '.join(missing)} stream"
        if not has_radar and (hint := _capture_hint(inputs, job)):
            msg += f"; {hint}"
        if not allow_partial:
            raise IngestError(msg + partial_hint)
        report.partial = True
        report.warnings.append(msg + "; written anyway (--allow-partial)")


def _capture_hint(inputs: list[tuple[Path, str]], job: _Ingest) -> str | None:
    """Where a drive without radar has a DCA1000 capture that was not given: its frame triggers in the log, or a
    capture beside a log; what to give."""
    from .dca1000 import is_capture

    logs = [p for p, kind in inputs if kind == "log" and p.parent.is_dir()]
    beside = sorted({d for p in logs for d in p.parent.iterdir() if d.is_dir() and d != p and is_capture(d)})
    named = [d for d in beside if any(d.name.startswith(p.name.split(".")[0]) for p in logs)]  # x.dca1000, x.mcap
    if len(named) == 1 or len(beside) == 1:
        capture = (named or beside)[0]
        return f"a DCA1000 capture lies beside it ({capture}): give it with --radar {capture}"
    if beside:
        shown = ", ".join(d.name for d in beside[:3])
        return f"{len(beside)} DCA1000 captures lie beside it ({shown}): give its own with --radar CAPTURE"
    if job.sync_stamps:
        return (f"the log holds {len(job.sync_stamps)} DCA1000 frame triggers on {job.radar_options.sync_topic}: "
                "give their capture with --radar CAPTURE")
    return None


#: a topic whose header stamps lie this far (s) from its log times beyond the other topics' (their median) is stamped
#: on another clock: a boot clock, GPS time's leap seconds (18 s), a sensor's own unsynchronised one
MAX_CLOCK_DISAGREEMENT_S = 1.0


def _clock_disagreements(infos: list[StreamInfo]) -> list[str]:
    """One warning per topic whose header stamps run on another clock than the other topics' (their offset from
    the log times, :attr:`SeriesStats.clock_offset_ns`, over :data:`MAX_CLOCK_DISAGREEMENT_S` from the median of
    the others'): its times are taken as stamped, and the stages would find it nowhere near the rest."""
    offsets: dict[str, tuple[int, list[str]]] = {}
    for info in infos:
        st = info.stats
        if st is None or not st.received or st.log_time_used >= st.received:  # timed by the log: nothing to compare
            continue
        if info.msgtype == CAPTURE_MSGTYPE:  # no log times: its frames on the sync topic's clock or --radar-start's
            continue
        for topic in info.topics:
            offsets.setdefault(topic, (st.clock_offset_ns, []))[1].append(info.path)
    if len(offsets) < 3:
        return []
    out = []
    for topic, (offset, paths) in sorted(offsets.items()):
        others = statistics.median(o for t, (o, _) in offsets.items() if t != topic)
        if abs(offset - others) > MAX_CLOCK_DISAGREEMENT_S * 1e9:
            out.append(f"{topic}: stamped {(offset - others) / 1e9:+.3f} s from the other topics' clock (header stamps "
                       f"against the log's times: a boot clock, GPS time, a sensor's own?): "
                       f"{', '.join(sorted(paths)[:3])} {'hold' if len(paths) > 1 else 'holds'} its times as stamped, "
                       "the stages find it beside the rest only if the clock is right")
    return out


def _plausibility(infos: list[StreamInfo], job: _Ingest) -> None:
    """Warnings for data that decoded but cannot be right (ROS containers carry no checksums)."""
    job.warnings += _clock_disagreements(infos)
    for info in infos:
        if info.stats is not None and info.stats.late_dropped:
            job.warnings.append(f"{info.path}: {info.stats.late_dropped} message(s) dropped as late: stamped before "
                                "rows already written, further out of order than its reorder buffer reaches (inputs "
                                "of one stream out of time order, or their stamps damaged?)")
        if info.stats is not None and info.stats.stamps_in_microseconds:
            job.warnings.append(f"{info.path}: its header stamps' nanoseconds field holds microseconds (each under 1 "
                                "ms, and steady against the log's times only when read so: a driver's bug): read "
                                "as microseconds")
        if info.stats is not None and info.stats.stamp_outliers:
            job.warnings.append(f"{info.path}: {info.stats.stamp_outliers} message(s) stamped over a second after the "
                                "ones before and after them dropped (a damaged stamp)")
        bad = info.extra.get("implausible_frames")
        if bad:
            job.warnings.append(f"{info.path}: {len(bad)} radar frames have a crest factor (peak/RMS) far above "
                                f"the stream's, or are all zero (damaged data?): frame indices {_listed(bad)}")
        if info.extra.get("full_scale_frames") and info.stats is not None:
            lo, hi = info.extra["adc_full_scale"]
            job.warnings.append(f"{info.path}: {info.extra['full_scale_frames']} of {info.stats.written} frames hold "
                                f"samples at the ADC's full scale ({info.extra['full_scale_samples']} samples at {lo} "
                                f"or {hi}; clipped: a reflector too strong or too close; the image may hold ghosts)")
    can = job.can.stats
    if can.impossible_ids:
        job.warnings.append(f"{can.impossible_ids} CAN frames with an id no frame of theirs can have (a standard id "
                            "over 0x7FF) skipped (damaged data?)")
    if can.other_bus:
        job.warnings.append(f"{sum(can.other_bus.values())} CAN frames of a DBC message's id on a second bus skipped "
                            "(another bus's message of that id; each read from the bus it came on first): "
                            + ", ".join(f"{k} ×{v}" for k, v in can.other_bus.most_common(4)))
    if can.out_of_range:
        job.warnings.append(f"{sum(can.out_of_range.values())} CAN values outside their DBC range (damaged data?): "
                            + ", ".join(f"{k} ×{v}" for k, v in can.out_of_range.most_common(8)))
    if can.frames and not can.decoded and can.unknown_ids:
        job.warnings.append(f"none of the {can.frames} CAN frames has an ID in the DBC {job.dbc_path}; give the "
                            "vehicle's DBC with --dbc")
    if (dropped := _checksum_rule_misfit(job)) is not None:
        job.warnings.append(dropped)


def _checksum_rule_misfit(job: _Ingest) -> str | None:
    """What to say where the checksum rule dropped at least as many CAN frames as it passed: a car whose messages
    carry another checksum than the rule's (a DBC of one's own with a CHECKSUM signal), not damage."""
    can, rule = job.can.stats, job.config.can.checksum
    failed = sum(can.checksum_errors.values())
    if not failed or failed < can.decoded:
        return None
    return (f"{failed} CAN frames dropped by the checksum rule [can] checksum = \"{rule}\" ("
            + ", ".join(f"{k} ×{v}" for k, v in can.checksum_errors.most_common(4))
            + f", {can.decoded} frames passed); a car whose checksums are not that rule's: [can] checksum = \"none\"")


def _listed(values: Sequence[int], n: int = 8) -> str:
    return ", ".join(str(v) for v in values[:n]) + (f" and {len(values) - n} more" if len(values) > n else "")


def _role_unit_warnings(job: _Ingest, roles: dict[str, str]) -> list[str]:
    """A warning for each CAN role whose DBC signal's unit converts to another than the one the stages read it in
    (an empty unit, 'rpm'): its values are stored as they come, and a steering in degrees read as radians
    or a wheel speed in km/h as m/s is wrong by a factor the stages only partly see."""
    out = []
    for role, ref in roles.items():
        expected = role_unit(role)
        group, _, signal = ref.partition("/")
        units = job.can.signal_unit(group, signal)
        # a latitude/longitude keeps its DBC's degrees (CanDecoder's geodetic): any spelling of them
        read_as = {expected, *(u for u, (f, si) in DBC_UNITS.items()
                               if si == expected or expected == "deg" and si == "rad" and f == DBC_UNITS["deg"][0])}
        if expected is None or units is None or units[1].lower() in read_as:
            continue
        spellings = sorted(read_as)
        out.append(f"can.roles.{role} = {job.config.can.roles[role]}: the DBC gives its unit as {units[0]!r}, not one "
                   f"read as {expected} ({', '.join(spellings)}): its values are taken as {expected} as they are")
    return out


def _resolve_roles(job: _Ingest, infos: list[StreamInfo]) -> tuple[dict[str, str], list[str]]:
    """Role -> "GROUP/SIGNAL" for every configured CAN role whose message was ingested (by its DBC name, or by its
    group's where the DBC names two frame ids alike); the roles without one, those the log holds twice named."""
    groups = {i.path.split("/", 1)[1] for i in infos if i.kind == "can" and i.stats is not None and i.stats.written}
    roles: dict[str, str] = {}
    missing: list[str] = []
    for role, ref in job.config.can.roles.items():
        message, _, signal = ref.partition(".")
        found = [g for g in job.can.groups_of(message) if g in groups]
        if len(found) == 1:
            roles[role] = f"{found[0]}/{signal}"
        elif found:  # one name, several frame ids in the log: which one the role means is the config's to say
            missing.append(f"{role} ({message} is {' and '.join(found)}: name one)")
        else:
            missing.append(role)
    return roles, missing
