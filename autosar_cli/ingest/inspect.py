"""Summaries of drive logs without decoding payloads: streams, types, counts, rates, time span.

Logs are read once without decoding payloads (through the same readers as ingest, so damaged files and
unparseable schemas behave the same); a drive.h5 is summarised from its series groups. Used by
``autosar info``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from .sources import LogReadError, open_source

__all__ = ["LogReadError", "LogSummary", "StreamSummary", "summarize", "summarize_drive", "summarize_log"]


@dataclass
class StreamSummary:
    topic: str
    msgtype: str
    count: int
    start_ns: int
    end_ns: int
    gaps: int = 0

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
    warnings: list[str] = field(default_factory=list)
    #: radar parameter -> {"value", "source"} ("recording" or "config"): a drive.h5's radar or a capture's
    radar_parameters: dict[str, dict[str, Any]] = field(default_factory=dict)

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


def summarize(path: Path) -> LogSummary:
    """Summary of a drive log or of a drive.h5."""
    from .inputs import classify_input

    path = Path(path)
    if path.is_file() and path.suffix.lower() in (".h5", ".hdf5"):
        return summarize_drive(path)
    if not path.exists():
        raise LogReadError(f"{path}: no such file or directory")
    kind = classify_input(path)
    if kind == "drive":
        raise LogReadError(f"{path}: a drive folder, not one log: summarise each input it holds "
                           "(autosar_cli.ingest.inputs.drive_folder)")
    if kind == "radar":
        return summarize_capture(path)
    if kind == "can":
        return summarize_can_log(path)
    if kind == "nmea":
        return summarize_nmea_log(path)
    return summarize_log(path)


def _add(streams: dict[str, StreamSummary], name: str, msgtype: str, t_ns: int) -> None:
    s = streams.get(name)
    if s is None:
        s = streams[name] = StreamSummary(name, msgtype, 0, t_ns, t_ns)
    s.count += 1
    s.start_ns = min(s.start_ns, t_ns)
    s.end_ns = max(s.end_ns, t_ns)


def summarize_can_log(path: Path) -> LogSummary:
    """Frames of a standalone CAN log per channel and ID."""
    from .canlog import CanLogError, read_can_log

    summary = LogSummary(str(path), f"CAN log ({path.suffix.lower().lstrip('.')})", path.stat().st_size)
    streams: dict[str, StreamSummary] = {}
    try:
        for rec in read_can_log(path, summary.warnings.append):
            ch = f"ch{rec.channel or '?'}"
            if rec.is_error:  # an error frame's ID field means nothing
                _add(streams, f"{ch} error frames", "CAN error frame", rec.t_ns)
            elif rec.is_remote:
                _add(streams, f"{ch} 0x{rec.frame_id:X} remote", "CAN remote frame", rec.t_ns)
            else:
                _add(streams, f"{ch} 0x{rec.frame_id:X}", "CAN frame", rec.t_ns)
    except CanLogError as exc:
        if not streams:
            raise LogReadError(str(exc)) from exc
        summary.warnings.append(str(exc))
    summary.streams.extend(sorted(streams.values(), key=lambda s: s.topic))
    return summary


def summarize_nmea_log(path: Path) -> LogSummary:
    """Decoded records of an NMEA text capture per kind (GGA fixes, RMC/VTG velocities, HDT headings)."""
    from .nmea import NmeaLogReader, nothing_read

    summary = LogSummary(str(path), "NMEA text", path.stat().st_size)
    streams: dict[str, StreamSummary] = {}
    reader = NmeaLogReader(path)
    for rec in reader:
        _add(streams, type(rec).__name__, "NMEA", rec.t_ns)
    summary.streams.extend(streams.values())
    # date/time sentences carry no record of their own but say how the capture is dated
    sentences = reader.decoder.sentences
    span = (summary.start_ns, summary.end_ns)
    summary.streams.extend(StreamSummary(f"{kind} sentences", "NMEA", n, *span) for kind, n in sorted(sentences.items())
                           if kind == "ZDA")
    if reader.skipped:
        summary.warnings.append("skipped sentences: " + ", ".join(f"{k} ×{v}" for k, v in reader.skipped.items()))
    unread = nothing_read(reader)
    if unread:  # as ingest refuses it
        raise LogReadError(f"{path}: {unread} (read as an NMEA text capture by its name)")
    return summary


def summarize_log(path: Path) -> LogSummary:
    """Streams of an MCAP / ROS1 / rosbag2 log, read once through the ingest readers (no decoding)."""
    src = open_source(Path(path))
    summary = LogSummary(str(path), src.container, src.stats.bytes_total)
    streams: dict[str, StreamSummary] = {}
    try:
        for msg in src.messages():
            _add(streams, msg.channel.topic, msg.channel.msgtype, msg.log_ns)
    except LogReadError:
        raise
    except Exception as exc:  # the readers raise many types; the user needs file + reason
        raise LogReadError(f"{path}: cannot read {src.container} log: {exc}") from exc
    summary.streams.extend(sorted(streams.values(), key=lambda s: s.topic))
    summary.warnings.extend(src.stats.warnings)
    return summary


def summarize_capture(path: Path) -> LogSummary:
    """A TI DCA1000 capture: its layout, frame count and the radar parameters its parameter file states.

    Frame times are relative to the first frame: the capture's absolute start comes with ingest.
    """
    from .dca1000 import Dca1000Capture
    from .radar_block import recorded_from_capture

    cap = Dca1000Capture(path)
    p = cap.params
    stated_by = " + ".join([cap.param_file.name, *(c.name for c in cap.config_files)])
    summary = LogSummary(str(path), f"TI DCA1000 capture ({p.lanes}-lane {p.adc_format}, {len(cap.files)} file"
                         f"{'s' if len(cap.files) > 1 else ''}, {stated_by}; {cap.layout})", cap.bytes_total)
    t = cap.pri_times_ns(cap.frame_starts_ns(0))
    summary.streams.append(StreamSummary("radar frames (PRIs)", p.describe_layout(), cap.num_pris,
                                         int(t[0]) if len(t) else 0, int(t[-1]) if len(t) else 0))
    rec = recorded_from_capture(cap)
    values = {**{k: getattr(rec, k) for k in ("start_frequency_hz", "slope_hz_per_s", "sample_rate_hz",
                                              "num_samples", "num_tx", "num_rx", "prf_hz", "bandwidth_hz")},
              "tx_start_offsets_s": list(rec.tx_start_offsets_s), "tx_channels": list(p.tx_order),
              "rx_channels": list(p.rx_channels), **rec.extra}
    summary.radar_parameters = {k: {"value": v, "source": "recording"} for k, v in values.items()}
    summary.warnings.extend(cap.warnings)
    return summary


def _radar_parameters(attrs: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """A drive's radar attributes with the origin ``parameter_sources`` records for each."""
    import json

    import numpy as np

    sources = json.loads(attrs.get("parameter_sources", "{}") or "{}")
    out = {}
    for key, source in sources.items():
        v = attrs.get(key)
        if f"configured_{key}" in attrs:  # taken onto the triggers' clock at ingest
            source = f"{source}, on the triggers' clock"
        out[key] = {"value": v.tolist() if isinstance(v, np.ndarray) else v.item() if isinstance(v, np.generic)
                    else v, "source": source}
    # the radar's clock as ingest measured it (ingest.radar_block, ingest.pipeline._radar_clock_rates)
    for key, source in (("frame_clock_drift_ppm", "its triggers"), ("log_clock_drift_ppm", "the log times")):
        if key in attrs:
            std = float(attrs.get(key.replace("_ppm", "_std_ppm"), float("nan")))
            applied = " (applied)" if key == "frame_clock_drift_ppm" and attrs.get("frame_clock_applied") else ""
            out[key] = {"value": f"{float(attrs[key]):+.2f} ± {std:.2f} ppm{applied}", "source": source}
    return out


def summarize_drive(path: Path) -> LogSummary:
    """Series of a drive.h5: group, type, count, rate, span and recorded gaps."""
    from autosar_cli.store.drive import Drive, DriveFormatError

    try:
        drive = Drive(path)
    except DriveFormatError as exc:
        raise LogReadError(str(exc)) from exc
    summary = LogSummary(str(path), f"drive.h5 v{int(drive.attrs['format_version'])}", path.stat().st_size)
    with drive:
        def visit(name: str, obj: object) -> None:
            import h5py

            if isinstance(obj, h5py.Group) and "t_ns" in obj:
                t = obj["t_ns"]
                n = t.shape[0]
                gaps = obj["gaps"].shape[0] if "gaps" in obj else 0
                summary.streams.append(StreamSummary(name, str(obj.attrs.get("msgtype", "")), n,
                                                     int(t[0]) if n else 0, int(t[-1]) if n else 0, gaps))

        drive.h5.visititems(visit)
        for name in drive.radar_names():
            summary.radar_parameters.update(_radar_parameters(dict(drive.h5["radar"][name].attrs)))
        # the ingest's, as its report keeps them: said as such, not as what reading the drive now found
        summary.warnings.extend(f"at ingest: {w}" for w in drive.report().get("warnings", []))
    return summary
