"""The drive's radar block: what the recording states wins, the config supplies the rest.

Frequencies, slope, sampling, chirp timing and Tx/Rx counts and order come from the recording (a RawFrame's
fields, a DCA1000 capture's parameter file); mounting and antenna positions from the config. A value that
both state must agree, else ingest stops with a one-line error naming both values (``override``: the
recording's values are kept and the disagreements reported as a warning). Every attribute's origin is
stored in the radar group's ``parameter_sources`` attribute and shown by ``autosar info``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from autosar_cli.config import MAX_CLOCK_DRIFT_PPM, RadarConfig
from autosar_cli.store.drive import DriveWriter

from .dca1000 import Dca1000Capture
from .decoders import FrameGaps, StreamInfo, clipping, frame_statistics, implausible_frames
from .series import SeriesStats

OVERRIDE_OPTION = "--radar-override"
#: a DCA1000 capture's stream type: no log times of its own (its frames timed by the sync topic or --radar-start)
CAPTURE_MSGTYPE = "TI DCA1000 capture"
_REL_TOL = 1e-6
_TIME_TOL_S = 1e-9


class RadarParamsError(ValueError):
    """The recording and the config disagree about the radar (one line, both values named)."""


@dataclass
class Recorded:
    """Radar parameters a recording states (None: not stated)."""

    start_frequency_hz: float
    slope_hz_per_s: float
    sample_rate_hz: float
    num_samples: int
    num_tx: int
    num_rx: int
    tx_start_offsets_s: tuple[float, ...]
    prf_hz: float | None = None
    tx_channels: tuple[int, ...] | None = None  #: physical Tx index of each Tx of the cube
    rx_channels: tuple[int, ...] | None = None  #: physical Rx index of each Rx of the cube
    extra: dict[str, Any] = field(default_factory=dict)  #: further recorded attributes (stored as they are)

    @property
    def bandwidth_hz(self) -> float:
        return self.slope_hz_per_s * self.num_samples / self.sample_rate_hz


def resolve(rec: Recorded, cfg: RadarConfig, *, what: str, override: bool,
            warn: Callable[[str], None]) -> dict[str, Any]:
    """The radar attributes of the drive for recording ``rec`` and config ``cfg``; ``what`` names the recording."""

    clashes: list[str] = []

    def clash(name: str, recorded: Any, configured: Any) -> None:
        clashes.append(f"the recording's {name} is {recorded} but the config's radar.{name} is {configured}")

    for name in ("num_tx", "num_rx", "num_samples"):
        if getattr(rec, name) != getattr(cfg, name):
            hint = _channels_hint(rec, name[4:]) if name in ("num_tx", "num_rx") else ""
            clash(name, getattr(rec, name), f"{getattr(cfg, name)}{hint}")
    for kind in ("tx", "rx"):
        stated, configured = getattr(rec, f"{kind}_channels"), getattr(cfg, f"{kind}_channels")
        if stated is not None and configured is not None and tuple(stated) != configured:
            clash(f"{kind}_channels", list(stated), list(configured))
    for name in ("start_frequency_hz", "slope_hz_per_s", "sample_rate_hz"):
        if not math.isclose(getattr(rec, name), getattr(cfg, name), rel_tol=_REL_TOL):
            clash(name, f"{getattr(rec, name):.9g}", f"{getattr(cfg, name):.9g}")
    if not math.isclose(rec.bandwidth_hz, cfg.bandwidth_hz, rel_tol=_REL_TOL):
        clash("bandwidth_hz", f"{rec.bandwidth_hz:.9g} (slope x ADC window)", f"{cfg.bandwidth_hz:.9g}")
    if rec.prf_hz is not None and not math.isclose(rec.prf_hz, cfg.prf_hz, rel_tol=_REL_TOL):
        clash("prf_hz", f"{rec.prf_hz:.9g}", f"{cfg.prf_hz:.9g}")
    cfg_offsets = cfg.tx_start_offsets_s
    if len(cfg_offsets) == len(rec.tx_start_offsets_s) and any(
            abs(a - b) > _TIME_TOL_S for a, b in zip(rec.tx_start_offsets_s, cfg_offsets, strict=True)):
        clash("tx_start_offsets_s", f"{list(rec.tx_start_offsets_s)}",
              f"{list(cfg_offsets)} (k x chirp_period_s)")
    if clashes:
        if not override:
            raise RadarParamsError(f"{what}: " + "; ".join(clashes)
                                   + f" (fix the config, or give {OVERRIDE_OPTION} to keep the recording's)")
        warn(f"{what}: " + "; ".join(clashes) + f"; kept the recording's ({OVERRIDE_OPTION})")

    tx_used, tx_rows = _rows(cfg, "tx", rec.tx_channels, rec.num_tx, what)
    rx_used, rx_rows = _rows(cfg, "rx", rec.rx_channels, rec.num_rx, what)
    m = cfg.mounting
    recorded = {"start_frequency_hz": rec.start_frequency_hz, "slope_hz_per_s": rec.slope_hz_per_s,
                "sample_rate_hz": rec.sample_rate_hz, "tx_start_offsets_s": list(rec.tx_start_offsets_s),
                "num_tx": rec.num_tx, "num_rx": rec.num_rx, "num_samples": rec.num_samples,
                "bandwidth_hz": rec.bandwidth_hz, **rec.extra}
    configured: dict[str, Any] = {"tx_positions_m": tx_rows, "rx_positions_m": rx_rows,
                                  "tx_channels": list(tx_used), "rx_channels": list(rx_used),
                                  "lever_arm_m": list(m.lever_arm_m), "yaw_deg": m.yaw_deg, "pitch_deg": m.pitch_deg,
                                  "roll_deg": m.roll_deg}
    if rec.prf_hz is not None:
        recorded["prf_hz"] = rec.prf_hz
    else:
        configured["prf_hz"] = cfg.prf_hz
    sources = {k: "recording" for k in recorded} | {k: "config" for k in configured}
    for kind in ("tx", "rx"):
        if getattr(rec, f"{kind}_channels") is not None:
            sources[f"{kind}_channels"] = "recording"
    return {**configured, **recorded, "geometry_source": "config", "parameter_sources": sources}


def _channels_hint(rec: Recorded, kind: str) -> str:
    """How a config states the board's antennas a recording uses (``kind`` "tx" or "rx"), where it names them."""
    stated = getattr(rec, f"{kind}_channels", None)
    if stated is None:
        return ""
    return (f" (the recording uses its board's {kind.title()} {list(stated)}: radar.num_{kind} = {len(stated)}, "
            f"radar.{kind}_channels = {list(stated)}, a row of radar.{kind}_positions_wavelengths for each of the "
            "board's antennas)")


def _rows(cfg: RadarConfig, kind: str, channels: tuple[int, ...] | None, count: int,
          what: str) -> tuple[tuple[int, ...], list[list[float]]]:
    """The board's antennas (``kind`` "tx" or "rx") the recording uses and their config rows (m, radar frame): those
    it names (``channels``), else the config's in use, which must be ``count``."""
    name = f"radar.{kind}_positions_wavelengths"
    board = cfg.board_positions_m(getattr(cfg, f"{kind}_positions_wavelengths"))
    if channels is None:
        channels = cfg.tx_in_use if kind == "tx" else cfg.rx_in_use
        if len(channels) != count:
            raise RadarParamsError(f"{what}: the recording has {count} {kind.title()} antennas but the config's "
                                   f"radar uses {len(channels)} ({name}, radar.{kind}_channels)")
    elif max(channels) >= len(board):
        raise RadarParamsError(f"{what}: the recording uses {kind.title()} {max(channels)} of its board but the "
                               f"config's {name} has {len(board)} rows (0-{len(board) - 1}): give a row for each of "
                               f"the board's antennas and radar.{kind}_channels = {list(channels)}")
    return tuple(channels), [list(board[c]) for c in channels]


def recorded_from_capture(cap: Dca1000Capture) -> Recorded:
    p = cap.params
    return Recorded(
        start_frequency_hz=p.start_frequency_hz, slope_hz_per_s=p.slope_hz_per_s, sample_rate_hz=p.sample_rate_hz,
        num_samples=p.num_samples, num_tx=p.num_tx, num_rx=p.num_rx, tx_start_offsets_s=p.tx_start_offsets_s,
        prf_hz=p.prf_hz, tx_channels=p.tx_order, rx_channels=p.rx_channels,
        extra={"adc_format": p.adc_format, "lvds_lanes": p.lanes, "chirp_tx_order": list(p.chirp_tx),
               "frame_period_s": p.frame_period_s, "loops_per_frame": p.num_loops,
               "parameter_file": str(p.source), **_stated_gains(p.channel_gains())})


def _stated_gains(gains: NDArray[np.complex128] | None) -> dict[str, Any]:
    """The radar attributes of the channel gains a capture's calibration states (none where it states none)."""
    if gains is None:
        return {}
    return {"channel_phase_deg": np.degrees(np.angle(gains)).tolist(),
            "channel_gain_db": (20 * np.log10(np.abs(gains))).tolist(),
            "channel_gains_source": "compRangeBiasAndRxChanPhase"}


def capture_frame_starts(cap: Dca1000Capture, start_ns: int | None, triggers: Sequence[int], topic: str,
                         warn: Callable[[str], None]) -> tuple[NDArray[np.int64], dict[str, Any]]:
    """Each frame's start (ns since the epoch), and the radar attributes that say how its frames were timed. A
    capture's files hold no time: the frames of a software-triggered capture start every frame period from
    ``start_ns`` (``--radar-start``) or from the first of ``triggers`` (the frame-trigger topic's stamps, as
    recorded); those of a hardware-triggered one (triggerSelect 2) start on their own triggers, one each. Where a
    software-triggered capture has a trigger per frame, its frame clock is measured against them
    (:func:`frame_clock_against_triggers`). Raises ValueError where the times cannot be known; ``warn`` where the
    triggers contradict the frame period."""
    p, n = cap.params, cap.num_frames
    stamps = np.asarray(triggers, dtype=np.int64)
    if p.hardware_trigger:
        if len(stamps) < n:
            raise ValueError(f"its frames start on a hardware trigger (triggerSelect 2), so each frame's time is "
                             f"its trigger on topic {topic}: {len(stamps)} triggers for {n} frames")
        if len(stamps) > n:
            warn(f"{cap.name}: {len(stamps)} triggers on topic {topic} for {n} frames: the first {n} taken")
        starts = stamps[:n]
        if np.any(np.diff(starts) <= 0):
            raise ValueError(f"the triggers on topic {topic} do not rise: they cannot time its frames")
        return starts, {}
    if start_ns is None and not len(stamps):
        raise ValueError(f"no start time for the DCA1000 capture: give --radar-start, or record its first frame "
                         f"trigger on topic {topic} in a log")
    start = start_ns if start_ns is not None else int(stamps[0])
    starts = cap.frame_starts_ns(start)
    attrs: dict[str, Any] = {}
    if len(stamps) > 1 and len(stamps) != n:  # triggers, yet not one per frame
        # the ADC stream marks no frame: a loop count other than the recording's shows only against the triggers
        loops = cap.whole_loops
        other = "" if loops is None or loops % len(stamps) or loops // len(stamps) == p.num_loops else (
            f"; its {loops} loops would be {loops // len(stamps)} a frame, one frame a trigger: does "
            f"{cap.param_file.name} state the recording's loop count (numLoops {p.num_loops})?")
        if start_ns is None:
            warn(f"{cap.name}: {len(stamps)} triggers on topic {topic} for its {n} frames: timed from the first "
                 f"trigger, so every frame the capture missed at its start puts all its frames a frame period "
                 f"({p.frame_period_s * 1e3:g} ms) early; where it did, give --radar-start{other}")
        else:
            warn(f"{cap.name}: {len(stamps)} triggers on topic {topic} for its {n} frames (timed from "
                 f"--radar-start){other}")
    if start_ns is None and len(stamps) == n and n > 2:  # a trigger per frame: they must follow the period
        clock = frame_clock_against_triggers(stamps, p.frame_period_s)
        attrs = clock.attrs()
        if clock.applied:
            starts = cap.frame_starts_ns(start, clock.period_s)
            warn(f"{cap.name}: its {n} triggers on topic {topic} come every {clock.period_s * 1e3:.7g} ms, not "
                 f"every {p.frame_period_s * 1e3:g} ms: the radar's frame clock runs {clock.drift_ppm:+.1f} ± "
                 f"{clock.drift_std_ppm:.1f} ppm fast; its frames timed by the triggers' period")
        drift = np.abs(stamps - starts)
        if drift.max() > p.frame_period_s * 1e9 / 2:
            warn(f"{cap.name}: frames every {p.frame_period_s * 1e3:g} ms drift up to {drift.max() / 1e6:.3g} ms "
                 f"from their {n} triggers on topic {topic} (frame {int(np.argmax(drift))}): a frame period or "
                 "trigger mode that differs from the recording's?")
    return starts, attrs


@dataclass(frozen=True)
class FrameClock:
    """A radar's frame clock measured against its per-frame triggers' clock (the logger's)."""

    period_s: float  #: the frames' period on the triggers' clock (s)
    drift_ppm: float  #: how fast the radar's frame clock runs (ppm; ``radar.clock_drift_ppm``'s sign)
    drift_std_ppm: float  #: its 1-sigma from the triggers' scatter about the line (ppm)
    applied: bool  #: the frames are timed by ``period_s`` (not by the stated frame period)

    def attrs(self) -> dict[str, Any]:
        return {"frame_clock_drift_ppm": self.drift_ppm, "frame_clock_drift_std_ppm": self.drift_std_ppm,
                "frame_clock_applied": self.applied}


#: a measured drift is taken where it is this many sigma from 0 and moves the last frame by this much (s); beyond
#: MAX_CLOCK_DRIFT_PPM it is a wrong period
FRAME_CLOCK_MIN_SIGMAS = 4.0
FRAME_CLOCK_MIN_SHIFT_S = 1e-5


def frame_clock_against_triggers(stamps_ns: NDArray[np.int64], frame_period_s: float) -> FrameClock:
    """The line through the frames' triggers ``stamps_ns`` (ns, one per frame in order) against their index: its
    slope is the frame period on the triggers' clock. A robust fit: triggers more than 5 scaled MADs off the
    first line (a late message) are left out of the second. Applied where its drift from ``frame_period_s`` is
    at least ``FRAME_CLOCK_MIN_SIGMAS`` std, moves the last frame by ``FRAME_CLOCK_MIN_SHIFT_S`` (not the ns
    rounding of triggers a period apart) and is at most ``MAX_CLOCK_DRIFT_PPM`` (more is a period that is not the
    recording's, which :func:`capture_frame_starts` reports)."""
    k = np.arange(len(stamps_ns), dtype=np.float64)
    y = (stamps_ns - stamps_ns[0]).astype(np.float64)  # ns since the first trigger: exact in float64
    keep = np.ones(len(k), dtype=bool)
    for _ in range(2):
        slope, intercept = np.polyfit(k[keep], y[keep], 1)
        residual = y - (slope * k + intercept)
        mad = 1.4826 * np.median(np.abs(residual[keep] - np.median(residual[keep])))
        keep = np.abs(residual) <= max(5 * mad, 1.0)
    kk = k[keep]
    scatter = float(np.sqrt(np.sum(residual[keep] ** 2) / max(len(kk) - 2, 1)))
    slope_std = max(scatter, 0.5) / math.sqrt(max(np.sum((kk - kk.mean()) ** 2), 1.0))  # ns: at least the rounding
    period_ns = frame_period_s * 1e9
    drift_ppm = (period_ns / slope - 1.0) * 1e6
    drift_std_ppm = period_ns / slope ** 2 * slope_std * 1e6
    shift_s = abs(drift_ppm) * 1e-6 * frame_period_s * (len(k) - 1)
    applied = bool(FRAME_CLOCK_MIN_SIGMAS * drift_std_ppm <= abs(drift_ppm) <= MAX_CLOCK_DRIFT_PPM
                   and shift_s >= FRAME_CLOCK_MIN_SHIFT_S)
    return FrameClock(float(slope / 1e9), float(drift_ppm), float(drift_std_ppm), applied)


def write_capture_stream(writer: DriveWriter, path: str, cap: Dca1000Capture, frame_starts_ns: NDArray[np.int64],
                         attrs: dict[str, Any], progress: Callable[[int], None]) -> StreamInfo:
    """Stream a capture's PRIs into the drive's radar group ``path``; frame times from ``frame_starts_ns``
    (:func:`capture_frame_starts`). PRIs that hold data the DCA1000 lost are left out: the frame index jumps
    there, as in a log that lost frames."""
    p = cap.params
    cube = writer.radar(path, (p.num_tx, p.num_rx, p.num_samples), attrs)
    t_ns = cap.pri_times_ns(frame_starts_ns)
    gaps = FrameGaps()
    frame_stats: list[np.ndarray] = []  # per block: (PRI index, peak, RMS, full-scale samples), as for RawFrame logs
    done = written = 0
    for first, block, damaged in cap.blocks():
        n = len(block)
        idx = np.arange(first, first + n, dtype=np.int64)
        done += n
        if damaged.any():
            keep = ~damaged
            idx, block = idx[keep], block[keep]
        if len(idx):  # a block the DCA1000 lost whole leaves nothing to write
            gaps.add(idx, t_ns[idx])
            frame_stats.append(frame_statistics(idx, block, p.adc_bits))
            cube.append_frames(t_ns[idx], idx, block)
            written += len(idx)
        progress(done // p.num_loops * p.frame_bytes)
    stats = SeriesStats(received=done, written=written, first_ns=int(t_ns[0]) if done else 0,
                        last_ns=int(t_ns[-1]) if done else 0)
    gaps.write(cube, stats)
    if cap.partial_bytes:
        stats.skipped["trailing partial frame"] = 1
    if done > written:
        stats.skipped["PRIs holding data the DCA1000 lost"] = done - written
    info = StreamInfo(path, "radar", topics={str(cap.path)}, msgtype=CAPTURE_MSGTYPE, stats=stats)
    info.extra["missing_frames"] = gaps.missing
    stats_rows = np.concatenate(frame_stats) if frame_stats else np.zeros((0, 4))
    flagged = implausible_frames(stats_rows)
    if len(flagged):
        info.extra["implausible_frames"] = [int(i) for i in flagged]
    info.extra.update(clipping(stats_rows, p.adc_bits))
    return info
