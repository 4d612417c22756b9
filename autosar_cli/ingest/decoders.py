"""Decoders: one per message kind, from a deserialized message to rows of a drive.h5 series.

Each decoder owns the :class:`~.series.Series` (ordering, duplicates, gaps) and the drive.h5 table of its
stream. Values leave here in SI units and the project's frames (see :mod:`autosar_cli.store.drive`).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Collection
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from cantools.database.can import Database, Message, Signal

from autosar_cli.candb import giorgio_checksum, si_factor
from autosar_cli.store.drive import Column, DriveWriter, RadarCube, Table

from .records import UNKNOWN_TIME, CanRecord, NmeaFix, NmeaHeading, NmeaRecord, NmeaVelocity
from .series import Series, SeriesStats

_NAN9 = (math.nan,) * 9


def _stamp_ns(header: Any) -> int:
    s = header.stamp
    return int(s.sec) * 1_000_000_000 + int(getattr(s, "nanosec", getattr(s, "nsec", 0)))


@dataclass
class StreamInfo:
    """Where a stream came from and what became of it (one entry of the ingest report)."""

    path: str  #: drive.h5 group
    kind: str
    topics: set[str] = field(default_factory=set)
    msgtype: str = ""
    stats: SeriesStats | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        d = {"path": self.path, "kind": self.kind, "topics": sorted(self.topics), "msgtype": self.msgtype}
        if self.stats is not None:
            d.update(self.stats.to_dict())
        d.update(self.extra)
        return d


class TableStream:
    """A series whose rows are flat tuples written to a drive.h5 table (the common case)."""

    def __init__(self, writer: DriveWriter, path: str, kind: str, columns: dict[str, Column],
                 attrs: dict[str, Any], window: int = 512) -> None:
        self.info = StreamInfo(path, kind, msgtype=str(attrs.get("msgtype", "")))
        self.columns = columns
        self.table: Table = writer.table(path, columns, attrs)
        self.series = Series(self._sink, window=window)
        # Flat tuple layout: each column takes prod(shape) consecutive values.
        self._slices: list[tuple[str, slice, tuple[int, ...]]] = []
        i = 0
        for name, col in columns.items():
            if name == "t_ns":
                continue
            n = int(np.prod(col.shape)) if col.shape else 1
            self._slices.append((name, slice(i, i + n), col.shape))
            i += n

    def _sink(self, t_ns: np.ndarray, rows: list[Any]) -> None:
        flat = np.asarray(rows, dtype=np.float64)
        data: dict[str, np.ndarray] = {"t_ns": t_ns}
        for name, sl, shape in self._slices:
            block = flat[:, sl]
            data[name] = block.reshape(len(rows), *shape) if shape else block[:, 0]
        self.table.append(data)

    def push(self, header_ns: int | None, log_ns: int, row: tuple[float, ...]) -> None:
        self.series.push(header_ns, log_ns, row)

    def skip(self, reason: str) -> None:
        self.series.stats.received += 1
        self.series.stats.skipped[reason] += 1

    def named_series(self) -> list[tuple[str, Series]]:
        """(drive.h5 path, series) of what this stream writes."""
        return [(self.info.path, self.series)]

    def finish(self) -> StreamInfo:
        stats = self.series.finish()
        self.table.write_dataset("gaps", np.asarray(stats.gaps, dtype=np.int64).reshape(-1, 2))
        self.info.stats = stats
        return self.info


def _f(unit: str = "", shape: tuple[int, ...] = ()) -> Column:
    return Column(np.float64, shape, unit)


IMU_COLUMNS = {
    "t_ns": Column(np.int64, (), "ns"),
    "angular_velocity": _f("rad/s", (3,)),
    "linear_acceleration": _f("m/s^2", (3,)),
    "orientation": _f("", (4,)),
    "angular_velocity_covariance": _f("rad^2/s^2", (9,)),
    "linear_acceleration_covariance": _f("m^2/s^4", (9,)),
    "orientation_covariance": _f("rad^2", (9,)),
}
FIX_COLUMNS = {
    "t_ns": Column(np.int64, (), "ns"),
    "latitude_deg": _f("deg"),
    "longitude_deg": _f("deg"),
    "altitude_m": _f("m"),
    "status": _f(),
    "service": _f(),
    "position_covariance": _f("m^2", (9,)),
    "position_covariance_type": _f(),
}
VELOCITY_COLUMNS = {
    "t_ns": Column(np.int64, (), "ns"),
    "velocity_enu": _f("m/s", (3,)),
    "angular_velocity": _f("rad/s", (3,)),
    "velocity_variance": _f("m^2/s^2", (3,)),
}
NMEA_FIX_COLUMNS = {
    "t_ns": Column(np.int64, (), "ns"),
    "fix_time_ns": _f("ns"),
    "latitude_deg": _f("deg"),
    "longitude_deg": _f("deg"),
    "altitude_m": _f("m"),
    "quality": _f(),
    "num_satellites": _f(),
    "hdop": _f(),
}
NMEA_VELOCITY_COLUMNS = {
    "t_ns": Column(np.int64, (), "ns"),
    "fix_time_ns": _f("ns"),
    "speed_mps": _f("m/s"),
    "course_rad": _f("rad"),
    "latitude_deg": _f("deg"),  # RMC's position; NaN in VTG's table
    "longitude_deg": _f("deg"),
}
NMEA_HEADING_COLUMNS = {"t_ns": Column(np.int64, (), "ns"), "heading_rad": _f("rad")}


def imu_row(m: Any) -> tuple[float, ...]:
    w, a, q = m.angular_velocity, m.linear_acceleration, m.orientation
    return (w.x, w.y, w.z, a.x, a.y, a.z, q.x, q.y, q.z, q.w, *m.angular_velocity_covariance,
            *m.linear_acceleration_covariance, *m.orientation_covariance)


def fix_row(m: Any) -> tuple[float, ...] | None:
    """Row of a NavSatFix, or None when it holds no fix (status < 0 or non-finite coordinates)."""
    if m.status.status < 0 or not (math.isfinite(m.latitude) and math.isfinite(m.longitude)):
        return None
    return (m.latitude, m.longitude, m.altitude, m.status.status, m.status.service, *m.position_covariance,
            m.position_covariance_type)


def velocity_row(m: Any) -> tuple[float, ...] | None:
    """Row of a twist (ENU velocity), or None when its horizontal velocity is not finite (a receiver's NaN before its
    first fix: one NaN sample made SAR-MIN's whole trajectory NaN). A NaN up velocity is kept: a receiver without one
    writes NaN there."""
    twist = m.twist
    if hasattr(twist, "covariance"):  # TwistWithCovarianceStamped
        cov = twist.covariance
        var = (cov[0], cov[7], cov[14])
        twist = twist.twist
    else:
        var = (math.nan, math.nan, math.nan)
    v, w = twist.linear, twist.angular
    if not (math.isfinite(v.x) and math.isfinite(v.y)):
        return None
    return (v.x, v.y, v.z, w.x, w.y, w.z, *var)


class NmeaStreams:
    """The three NMEA series of one GNSS source, fed by an :class:`~.nmea.NmeaDecoder`."""

    def __init__(self, writer: DriveWriter, base: str, attrs: dict[str, Any]) -> None:
        from .nmea import NmeaDecoder

        self.decoder = NmeaDecoder()
        self.fix = TableStream(writer, f"{base}/nmea_fix", "nmea_fix", NMEA_FIX_COLUMNS, attrs)
        self.velocity = TableStream(writer, f"{base}/nmea_velocity", "nmea_velocity", NMEA_VELOCITY_COLUMNS, attrs)
        # VTG repeats RMC's speed and course without a time: its own table, not RMC's duplicates.
        self.vtg = TableStream(writer, f"{base}/nmea_vtg", "nmea_vtg", NMEA_VELOCITY_COLUMNS, attrs)
        self.heading = TableStream(writer, f"{base}/nmea_heading", "nmea_heading", NMEA_HEADING_COLUMNS, attrs)

    def feed(self, sentence: str | bytes, stamp_ns: int | None, log_ns: int | None) -> None:
        self.route(self.decoder.feed(sentence, stamp_ns), log_ns)

    def route(self, records: list[NmeaRecord], log_ns: int | None) -> None:
        for r in records:
            lg = r.t_ns if log_ns is None else log_ns
            if isinstance(r, NmeaFix):
                fix_t = math.nan if r.fix_time_ns == UNKNOWN_TIME else float(r.fix_time_ns)
                self.fix.push(r.t_ns, lg, (fix_t, r.latitude_deg, r.longitude_deg, r.altitude_m, r.quality,
                                           r.num_satellites, r.hdop))
            elif isinstance(r, NmeaVelocity):
                if r.fix_time_ns == UNKNOWN_TIME:
                    self.vtg.push(r.t_ns, lg, (math.nan, r.speed_mps, r.course_rad, math.nan, math.nan))
                else:
                    self.velocity.push(r.t_ns, lg, (float(r.fix_time_ns), r.speed_mps, r.course_rad, r.latitude_deg,
                                                    r.longitude_deg))
            elif isinstance(r, NmeaHeading):
                self.heading.push(r.t_ns, lg, (r.heading_rad,))

    def named_series(self) -> list[tuple[str, Series]]:
        """(drive.h5 path, series) of what this stream writes."""
        return [pair for s in (self.fix, self.velocity, self.vtg, self.heading) for pair in s.named_series()]

    def finish(self) -> list[StreamInfo]:
        self.route(self.decoder.flush(), None)
        infos = [s.finish() for s in (self.fix, self.velocity, self.vtg, self.heading)]
        skipped = self.decoder.skipped
        if infos[0].stats is not None:
            infos[0].stats.skipped.update(skipped)
        infos[0].extra["sentences"] = dict(sorted(self.decoder.sentences.items()))  # ZDA has no table of its own
        return [i for i in infos if i.stats is not None and (i.stats.received or i.kind == "nmea_fix")]


# ------------------------------------------------------------------------------------------------- CAN
_MAX_STANDARD_ID = 0x7FF
_MAX_EXTENDED_ID = 0x1FFFFFFF


@dataclass
class CanStats:
    frames: int = 0
    decoded: int = 0
    unknown_ids: Counter[str] = field(default_factory=Counter)
    dlc_mismatch: Counter[str] = field(default_factory=Counter)
    checksum_errors: Counter[str] = field(default_factory=Counter)
    counter_errors: Counter[str] = field(default_factory=Counter)
    error_frames: int = 0
    remote_frames: int = 0
    #: frames whose id no frame of theirs can have (a standard id over 0x7FF) and no DBC message takes: damage
    impossible_ids: int = 0
    #: "MESSAGE.SIGNAL" -> values outside the DBC's [minimum, maximum] (kept: flagged, not dropped)
    out_of_range: Counter[str] = field(default_factory=Counter)
    #: "MESSAGE (0xID) on BUS, read from BUS" -> its id's frames on a second bus, skipped (another message's)
    other_bus: Counter[str] = field(default_factory=Counter)

    def to_dict(self) -> dict[str, Any]:
        return {"frames": self.frames, "decoded": self.decoded, "unknown_ids": dict(self.unknown_ids),
                "dlc_mismatch": dict(self.dlc_mismatch), "checksum_errors": dict(self.checksum_errors),
                "counter_errors": dict(self.counter_errors), "error_frames": self.error_frames,
                "remote_frames": self.remote_frames, "impossible_ids": self.impossible_ids,
                "out_of_range": dict(self.out_of_range), "other_bus": dict(self.other_bus)}


def _meaningful_range(sg: Any) -> bool:
    """Whether a DBC signal's [minimum, maximum] can be broken: set (not 0|0), and not just the raw
    integer range of its bits (opendbc-style DBCs write that, in raw units, which says nothing)."""
    lo, hi = sg.minimum, sg.maximum
    if lo is None or hi is None or not lo < hi:
        return False
    n = sg.length
    raw = (-(1 << (n - 1)), (1 << (n - 1)) - 1) if sg.is_signed else (0, (1 << n) - 1)
    physical = sorted((raw[0] * sg.scale + sg.offset, raw[1] * sg.scale + sg.offset))
    return (lo, hi) != raw and not (lo <= physical[0] + 1e-9 and hi >= physical[1] - 1e-9)


@dataclass
class _CanLayout:
    message: Message
    group: str
    names: list[str]
    factors: list[float]
    has_checksum: bool
    has_counter: bool
    unscaled_integrity: bool = True
    stream: TableStream | None = None
    topics: set[str] = field(default_factory=set)
    #: (signal, minimum, maximum) of the signals whose DBC range is set (0|0 means "not given")
    ranges: list[tuple[str, float, float]] = field(default_factory=list)
    bus: str | None = None  #: the channel its frames are read from: the first a frame of its id came on

    def skip_counter(self) -> None:
        if self.last_counter is not None:
            self.last_counter = (self.last_counter + 1) % 16
    last_counter: int | None = None


class CanDecoder:
    """Decodes CAN frames with a DBC into one series per message (/can/<MESSAGE>), SI units.

    Frames are looked up by frame ID (DBCs such as CSS's gnss.dbc reuse names); messages whose name is
    not unique get the ID appended to their group name. Integrity problems are counted, never fatal:
    unknown IDs, DLC mismatch and bad checksums drop the frame; counter jumps are counted and kept.
    """

    def __init__(self, writer: DriveWriter, db: Database, checksum_rule: str, attrs: Callable[[], dict[str, Any]],
                 geodetic: Collection[tuple[str, str]] = ()):
        """``geodetic``: the (message or group, signal) pairs of the latitude/longitude roles, kept in degrees
        whatever their names (OxTS's ``PosLat``, which :func:`~autosar_cli.candb.si_factor` cannot tell from an
        angle of the car's)."""
        self.writer = writer
        self._geodetic = set(geodetic)
        self.db = db
        self.checksum_rule = checksum_rule
        self.stats = CanStats()
        #: whether the last frame fed carried its message's rolling counter on by one (False: it skipped), None
        #: where it was not checked (no counter, its id's first frame, or a frame dropped before it)
        self.counter_step: bool | None = None
        self._attrs = attrs
        names = Counter(m.name for m in db.messages)
        self._layouts: dict[tuple[int, bool], _CanLayout] = {}
        for m in db.messages:
            group = m.name if names[m.name] == 1 else f"{m.name}_0x{m.frame_id:X}"
            sig_names = [s.name for s in m.signals]
            factors = [self._si(m, group, s)[0] for s in m.signals]
            integrity = [s for s in m.signals if s.name in ("CHECKSUM", "COUNTER")]
            plain = all(s.scale == 1 and s.offset == 0 for s in integrity)
            ranges = [(sg.name, float(sg.minimum), float(sg.maximum)) for sg in m.signals if _meaningful_range(sg)]
            self._layouts[(m.frame_id, m.is_extended_frame)] = _CanLayout(
                m, group, sig_names, factors, "CHECKSUM" in sig_names, "COUNTER" in sig_names, plain,
                ranges=ranges)

    def signal_unit(self, group: str, signal: str) -> tuple[str, str] | None:
        """(the DBC's unit, the SI unit it is stored in) of a signal of the message whose drive.h5 group is
        ``group``; None where no message or signal of those names is in the DBC."""
        for lay in self._layouts.values():
            if lay.group == group:
                sig = next((s for s in lay.message.signals if s.name == signal), None)
                return None if sig is None else ((sig.unit or "").strip(), self._si(lay.message, group, sig)[1])
        return None

    def _si(self, m: Message, group: str, s: Signal) -> tuple[float, str]:
        """(factor, unit) the signal ``s`` of message ``m`` (drive.h5 group ``group``) is stored in."""
        if (m.name, s.name) in self._geodetic or (group, s.name) in self._geodetic:
            return 1.0, (s.unit or "").strip()
        return si_factor(s.name, s.unit)

    def groups_of(self, message: str) -> list[str]:
        """The drive.h5 groups a role's message may name: the DBC messages of that name (a DBC may give two frame
        ids one name: each its own group, ``NAME_0xID``), or the group itself."""
        return [lay.group for lay in self._layouts.values() if message in (lay.message.name, lay.group)]

    def _stream(self, lay: _CanLayout) -> TableStream:
        columns: dict[str, Column] = {"t_ns": Column(np.int64, (), "ns")}
        for s in lay.message.signals:
            columns[s.name] = Column(np.float64, (), self._si(lay.message, lay.group, s)[1])
        attrs = {**self._attrs(), "frame_id": lay.message.frame_id, "is_extended": lay.message.is_extended_frame,
                 "message": lay.message.name, "msgtype": "can_msgs/msg/Frame"}
        lay.stream = TableStream(self.writer, f"can/{lay.group}", "can", columns, attrs)
        return lay.stream

    def feed(self, frame: CanRecord, header_ns: int | None, log_ns: int, topic: str = "") -> None:
        st = self.stats
        st.frames += 1
        self.counter_step = None
        if frame.is_error:
            st.error_frames += 1
            return
        if frame.is_remote:
            st.remote_frames += 1
            return
        lay = self._layouts.get((frame.frame_id, frame.is_extended))
        if lay is None and frame.frame_id > _MAX_STANDARD_ID:
            # a DBC may leave out an extended message's flag (opendbc's do); an extended frame of an id a standard
            # one can have is another message (a J1939 ECU's 0x00000100 beside 0x100), not the DBC's
            lay = self._layouts.get((frame.frame_id, not frame.is_extended))
        if lay is None:
            if frame.frame_id > (_MAX_EXTENDED_ID if frame.is_extended else _MAX_STANDARD_ID):
                st.impossible_ids += 1
            else:
                st.unknown_ids[f"0x{frame.frame_id:X}"] += 1
            return
        m = lay.message
        if frame.channel:
            if lay.bus is None:
                lay.bus = frame.channel
            elif frame.channel != lay.bus:  # one id on two buses: two messages, of which the DBC describes one
                st.other_bus[f"{m.name} (0x{m.frame_id:X}) on {frame.channel}, read from {lay.bus}"] += 1
                return
        data = frame.data
        # a classic frame's DLC 9-15 states its 8 bytes (ISO 11898-1)
        stated = 8 if 8 < frame.dlc <= 15 and len(data) == 8 else frame.dlc
        if stated != m.length or len(data) < m.length:
            st.dlc_mismatch[m.name] += 1
            lay.skip_counter()  # a rejected frame still took its counter value: no counter error next
            return
        data = bytes(data[: m.length])
        values = m.decode(data, decode_choices=False, scaling=lay.unscaled_integrity)
        if lay.unscaled_integrity:  # COUNTER/CHECKSUM have scale 1, offset 0: one decode serves both
            raw = values
        else:
            raw = m.decode(data, decode_choices=False, scaling=False)
            values = m.decode(data, decode_choices=False, scaling=True)
        if lay.has_checksum and self.checksum_rule == "fca_giorgio" and "CHECKSUM" in raw:
            if int(raw["CHECKSUM"]) != giorgio_checksum(m.frame_id, data):
                st.checksum_errors[m.name] += 1
                lay.skip_counter()
                return
        if lay.has_counter and "COUNTER" in raw:
            c = int(raw["COUNTER"])
            if lay.last_counter is not None:
                self.counter_step = c == (lay.last_counter + 1) % 16
                if not self.counter_step:
                    st.counter_errors[m.name] += 1
            lay.last_counter = c
        for name, lo, hi in lay.ranges:  # ROS containers have no checksums: a flipped bit shows here
            if name in values and not lo <= values[name] <= hi:
                st.out_of_range[f"{m.name}.{name}"] += 1
        # a multiplexed message's frame carries only the signals its multiplexer selects: the others NaN in its row
        row = tuple(float(values.get(n, math.nan)) * f for n, f in zip(lay.names, lay.factors, strict=True))
        stream = lay.stream or self._stream(lay)
        if topic:
            lay.topics.add(topic)
        stream.push(header_ns, log_ns, row)
        st.decoded += 1

    def named_series(self) -> list[tuple[str, Series]]:
        """(drive.h5 path, series) of every CAN message table."""
        return [pair for lay in self._layouts.values() if lay.stream is not None for pair in lay.stream.named_series()]

    def finish(self) -> list[StreamInfo]:
        out = []
        for lay in self._layouts.values():
            if lay.stream is not None:
                info = lay.stream.finish()
                info.topics |= lay.topics
                out.append(info)
        return out


# ----------------------------------------------------------------------------------------------- radar
class FrameGaps:
    """The jumps of a radar stream's frame index, block by block: (time before, time after, index before, index
    after) each, stored as the group's ``gaps`` and ``gap_frame_index``."""

    def __init__(self) -> None:
        self.gaps: list[tuple[int, int, int, int]] = []
        self._last: tuple[int, int] | None = None

    def add(self, frame_index: np.ndarray, t_ns: np.ndarray) -> None:
        """The next block's frame indices and times (ns), in order."""
        if not len(frame_index):
            return
        prev = np.concatenate([[self._last[0]], frame_index]) if self._last else frame_index
        prev_t = np.concatenate([[self._last[1]], t_ns]) if self._last else t_ns
        for j in np.flatnonzero(np.diff(prev) != 1):
            self.gaps.append((int(prev_t[j]), int(prev_t[j + 1]), int(prev[j]), int(prev[j + 1])))
        self._last = (int(frame_index[-1]), int(t_ns[-1]))

    @property
    def missing(self) -> int:
        """Frames the forward jumps skip."""
        return sum(b - a - 1 for _, _, a, b in self.gaps if b > a)

    def write(self, cube: RadarCube, stats: SeriesStats) -> None:
        cube.write_dataset("gaps", np.asarray([g[:2] for g in self.gaps], dtype=np.int64).reshape(-1, 2))
        cube.write_dataset("gap_frame_index", np.asarray([g[2:] for g in self.gaps], dtype=np.int64).reshape(-1, 2))
        stats.gaps = [g[:2] for g in self.gaps]  # radar gaps are frame-index jumps, not time steps


class RadarDecoder:
    """ScanBrick RawFrame messages into /radar/<name>: frame times, indices and the raw int16 cube."""

    BLOCK = 128  # frames per HDF5 write (3.3 MB of ScanBrick data): fewer, larger writes

    def __init__(self, writer: DriveWriter, path: str, attrs: dict[str, Any],
                 radar_attrs: Callable[[tuple[Any, ...]], dict[str, Any]]) -> None:
        """``radar_attrs(params)``: the radar block for the first frame's parameters (may raise)."""
        self.writer = writer
        self.path = path
        self.attrs = attrs
        self.radar_attrs = radar_attrs
        self.info = StreamInfo(path, "radar", msgtype="scanbrick_msgs/msg/RawFrame")
        self.cube: RadarCube | None = None
        self.params: tuple[Any, ...] | None = None
        self.shape: tuple[int, int, int] | None = None
        self.series = Series(self._sink, window=self.BLOCK, flush_rows=self.BLOCK)
        self.frame_gaps = FrameGaps()
        self._frame_stats: list[np.ndarray] = []  # per block: (frame index, peak |sample|, RMS, full-scale samples)

    def feed(self, m: Any, log_ns: int) -> None:
        """A deserialized RawFrame."""
        shape = (int(m.num_tx), int(m.num_rx), int(m.num_samples))
        params = (float(m.start_frequency_hz), float(m.slope_hz_per_s), float(m.sample_rate_hz),
                  tuple(float(x) for x in m.tx_start_offsets_s), shape)
        self.feed_parts(_stamp_ns(m.header), int(m.frame_index), params, m.data, log_ns)

    def feed_parts(self, stamp_ns: int, frame_index: int, params: tuple[Any, ...], data: np.ndarray,
                   log_ns: int) -> None:
        """One frame: header stamp (ns), index, parameters (see :func:`.fastcdr.raw_frame`), int16 samples."""
        shape = params[4]
        if len(data) != shape[0] * shape[1] * shape[2] * 2:
            self.series.stats.received += 1
            self.series.stats.skipped["wrong data size"] += 1
            return
        if self.params is None:
            self._open(params, shape)
        elif params != self.params:
            self.series.stats.received += 1
            self.series.stats.skipped["radar parameters changed"] += 1
            return
        self.series.push(stamp_ns, log_ns, (frame_index, data))

    def _open(self, params: tuple[Any, ...], shape: tuple[int, int, int]) -> None:
        attrs = {**self.attrs, **self.radar_attrs(params), "layout": "frame, tx, rx, sample, I/Q"}
        self.params, self.shape = params, shape
        self.cube = self.writer.radar(self.path, shape, attrs)

    def _sink(self, t_ns: np.ndarray, rows: list[Any]) -> None:
        assert self.cube is not None and self.shape is not None
        idx = np.fromiter((r[0] for r in rows), dtype=np.int64, count=len(rows))
        self.frame_gaps.add(idx, t_ns)
        # Gathering the frames here rather than on the writer thread balances the two cores better
        # (benches/bench_ingest.py: 1.15 s vs 1.30 s median on test1).
        raw = np.stack([r[1] for r in rows]).reshape(len(rows), *self.shape, 2)
        self._frame_stats.append(frame_statistics(idx, raw))
        self.cube.append_frames(t_ns, idx, raw)

    def named_series(self) -> list[tuple[str, Series]]:
        """(drive.h5 path, series) of the radar frames."""
        return [(self.path, self.series)]

    def finish(self) -> StreamInfo | None:
        stats = self.series.finish()
        self.info.stats = stats
        if self.cube is None:
            return self.info if stats.received else None
        self.frame_gaps.write(self.cube, stats)
        self.info.extra["missing_frames"] = self.frame_gaps.missing
        stats_rows = np.concatenate(self._frame_stats) if self._frame_stats else np.zeros((0, 4))
        flagged = implausible_frames(stats_rows)
        if len(flagged):
            self.info.extra["implausible_frames"] = [int(i) for i in flagged]
        self.info.extra.update(clipping(stats_rows, 16))  # a RawFrame's samples are int16
        return self.info


#: a frame's crest factor (peak/RMS) over the stream's median crest factor beyond which it is flagged. Peak and
#: RMS follow the scene (on the test2 drive RMS spans 0.3x-48x its median as strong targets pass), but a beat
#: signal's crest factor stays within 0.48x-1.57x of its median there (ci: 3.1 +- 0.15, at most 4.0); one
#: sample with a flipped high byte raises it to ~9.
CREST_RATIO = 2.0
#: a frame's peak or RMS against the running median of its NEIGHBOURS frames: at 990 frames/s the scene barely
#: changes from one frame to the next (test2: 0.68x-1.55x, ci: 0.88x-1.22x), a garbage block does
LOCAL_RATIO = 2.0
NEIGHBOURS = 9


def frame_statistics(frame_index: np.ndarray, raw: np.ndarray, adc_bits: int = 16) -> np.ndarray:
    """(frame index, peak |sample|, RMS, samples at the ADC's full scale) per frame of ``raw`` (frames first, int16
    ADC counts of an ``adc_bits``-bit ADC, sign-extended: its full scale -2^(bits-1) and 2^(bits-1) - 1)."""
    x = raw.reshape(len(raw), -1)
    # the peak on the int16 values and one float32 copy for the RMS: 9x faster than abs and square copies
    top, bottom = x.max(axis=1), x.min(axis=1)
    peak = np.maximum(top.astype(np.int32), -bottom.astype(np.int32))
    xf = x.astype(np.float32)
    rms = np.sqrt(np.einsum("ij,ij->i", xf, xf) / max(x.shape[1], 1))
    lo, hi = full_scale(adc_bits)
    full = np.zeros(len(x), dtype=np.int64)
    # counted only in a frame whose max or min reaches full scale, row by row: count_nonzero along an axis is 6x slower
    for i in np.flatnonzero((top >= hi) | (bottom <= lo)):
        full[i] = np.count_nonzero(x[i] >= hi) + np.count_nonzero(x[i] <= lo)
    return np.column_stack([frame_index, peak, rms, full]).astype(np.float64)


def full_scale(adc_bits: int) -> tuple[int, int]:
    """The lowest and highest sample of an ``adc_bits``-bit ADC (two's complement): where a clipped one sits."""
    return -(1 << (adc_bits - 1)), (1 << (adc_bits - 1)) - 1


def clipping(stats: np.ndarray, adc_bits: int) -> dict[str, Any]:
    """The radar stream's report entries for its samples at the ADC's full scale (``stats``: rows of
    :func:`frame_statistics`): how many frames hold any, how many samples, and the full scale."""
    full = stats[:, 3] if len(stats) else np.zeros(0)
    return {"full_scale_frames": int(np.count_nonzero(full)), "full_scale_samples": int(full.sum()),
            "adc_full_scale": list(full_scale(adc_bits))}


def implausible_frames(stats: np.ndarray) -> np.ndarray:
    """Frame indices whose samples cannot be the ADC's: a crest factor (peak/RMS) far above the stream's (a
    flipped high byte), a peak or RMS far from the neighbouring frames' (a garbage block), or all zeros.

    ``stats``: rows of :func:`frame_statistics` in time order. Flags nothing below 8 frames.
    """
    from scipy.ndimage import median_filter

    if len(stats) < 8:
        return np.zeros(0, dtype=np.int64)
    peak, rms = stats[:, 1], stats[:, 2]
    crest = peak / np.maximum(rms, 1e-9)
    bad = (crest > CREST_RATIO * np.median(crest)) | (rms == 0)
    for v in (peak, rms):
        local = np.maximum(median_filter(v, size=NEIGHBOURS, mode="nearest"), 1e-9)
        bad |= (v > LOCAL_RATIO * local) | (v * LOCAL_RATIO < local)
    return stats[bad, 0].astype(np.int64)
