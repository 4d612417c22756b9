"""The track's slow motion, along and across, from each bright point's range over its whole pass through the beam.

The phase autofocus (:mod:`autosar_cli.sar.residual_motion`) takes each point over +-28 deg of broadside. There a
range error bends the phase history as a speed error does, so it cannot tell how far the track went between two
points, and each point's free position absorbs whatever moves it rigidly. The ScanBrick looks 45 deg forward with
a 120 deg beam: it sees a roadside point from ~26 m ahead down to broadside, and over that pass the point's range
falls by metres while the car moves along. The range then measures the track's motion against the point with no
angle and no phase: along the track through the line of sight's forward component (up to sin 70 deg), across it
through the rest.

* the points: the first image's (:func:`~autosar_cli.sar.point_selection.candidate_points`), their echoes over
  +-``half_beam_deg`` (:func:`~autosar_cli.sar.phase_history.gather_phase_histories`);
* every ``block_s`` of a point's pulses summed coherently along the track's predicted phase, and the peak of that
  sum's range envelope (:func:`~autosar_cli.sar.phase_history.range_offsets`): how much longer the point's
  bistatic path is than predicted, less the envelope's shift by the echo's own Doppler, ``(dp/dt) f_c / slope``
  (1 cm of path at 5 m/s straight ahead, none at broadside), which over a pass would read as a stretch;
* only the points whose blocks fit a point over at least ``min_span_m`` of travel to ``max_point_sigma_m`` (its
  own shift, height and stretch, the slip gains' drift, and a step across each wheel gap inside its pass; corner
  reflectors and poles 0.2-6 mm, car bodies, facades and clutter, whose bright spot moves with the aspect,
  10-130 mm: urban seed 0);
* the model, for block b of point j::

      offset_b = -2 u_b . (a(t_b) along_b + c(t_b) across_b - d_j)

  with ``u`` the line of sight (point -> radar), ``a``, ``c`` the track's error along and across it (piecewise
  linear on ``node_s`` nodes; their change between nodes has a prior of ``step_along`` / ``step_across`` per metre
  of travel, the size of the navigation's local scale error, plus, across a span where the navigation had no wheel
  speeds (``trajectory.info["wheel_gaps"]``: its start and pull-away, where the ECU's window reaches across a
  standstill), the drift the GNSS velocity leaves there; ``c`` is held by default), ``d_j`` the point's own
  position error (3-D, its prior ``point_prior_m``). ``a`` also holds the drift of the navigation's mean drive and
  brake slip gains' errors, the integral of ``v a`` over the time the car speeds up or slows down times each
  (:func:`~autosar_cli.nav.wheel_speeds.slip_gain_drift`, their prior the std the navigation stated): one error
  for every braking of the drive, so a gain the points measure at one stop corrects another no point sees, and a
  point seen through a braking fits its own point (its own fit holds them too). On a drive that slows and speeds
  up again, ``a`` also holds how late the radar's frame stamps run, times its speed (:func:`fit_blocks`). Weighted
  least squares, each point weighted by its own residual, blocks beyond ``reject_sigma`` dropped and the fit
  repeated.

What it cannot see: a rigid motion of the whole track (it moves every point alike), the track between points'
passes, where the priors keep the navigated shape, and the bend of a yaw-rate error (well under a millimetre over a
pass), whose share of the track's scale its std takes from the navigation's own (:func:`heading_ramp_scale_std`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from autosar_cli.config import SPEED_OF_LIGHT, Config
from autosar_cli.nav.trajectory import (
    centre_instant,
    cumulative_travel,
    heading_ramp_displacement,
    radar_track,
    yaw_rate_bias_std,
)
from autosar_cli.nav.wheel_speeds import slip_gain_drift
from autosar_cli.sar.focus import FocusOptions
from autosar_cli.sar.normal_equations import factor_normal
from autosar_cli.sar.phase_history import (
    PhaseHistories,
    frame_geometry,
    gather_phase_histories,
    pair_antennas,
    range_offsets,
)
from autosar_cli.types import MotionCorrection, Trajectory

Array = NDArray[np.float64]


@dataclass(frozen=True)
class PassOptions:
    """Parameters of :func:`estimate_slow_motion`."""

    half_beam_deg: float = 70.0  #: each point's echoes within this of broadside (the beam: 45 deg forward +- 60)
    channels: int = 2  #: channels summed per block (sar.focus.channel_pairs)
    #: pulses summed per envelope (0.5 m of travel at 5 m/s; the config's ``processing.autofocus_pass_block_s``).
    #: A point above a road that reflects is also seen by way of its image in the road; the paths' interference
    #: cycles every ~0.4-0.8 m of travel at 10 m and moves the envelope's peak by centimetres. A block of 1 m averages
    #: more of it, which helped urban seeds 1-2 on a wet road but not seeds 3-5, and costs on a dry road
    #: (docs/SIMULATION.md, "A road that reflects")
    block_s: float = 0.1
    search_bins: float = 6.0  #: the envelope's peak is sought within +- this many bins of the predicted range
    min_relative_power: float = 0.3  #: blocks weaker than this times the point's median are left out
    max_point_sigma_m: float = 0.008  #: a point whose own fit leaves more (robust std of its path) is no point
    min_span_m: float = 8.0  #: nor one seen over less travel
    min_blocks: int = 8
    min_points: int = 3  #: fewer usable points: no correction
    node_s: float = 1.0  #: spacing of the correction's nodes (s)
    step_along: float = 0.0005  #: prior std of the along-track correction's change per metre of travel
    #: and of the across-track one's; 0: none (a change of heading between passes, which their ranges hardly see,
    #: turns the image by it: urban seeds 0, 1, 6 came out 2.8-3.4 cm with 0.001 against 2.3-2.5 without)
    step_across: float = 0.0
    point_prior_m: float = 0.1  #: prior std of a point's own position error
    prior_m: float = 0.1  #: prior std of the correction at every node (only a whole-track shift is left to it)
    reject_sigma: float = 3.5
    iterations: int = 5
    noise_floor_m: float = 0.0005  #: no point weighs as if its path were measured better than this
    #: the navigation's wheel gaps (``trajectory.info["wheel_gaps"]``) loosen the along prior by their drift, and
    #: a point's own fit takes a step across each gap inside its pass
    wheel_gaps: bool = True
    #: the navigation's drive and brake slip gains are fitted again, within the std it stated, as a drift along the
    #: track wherever the car speeds up or slows down (:func:`~autosar_cli.nav.wheel_speeds.slip_gain_drift`)
    slip_gains: bool = True
    #: prior std (s) of how late the radar's frame stamps run against the navigation's clock (a capture on its
    #: host's clock, a sync message that is not the first frame's trigger): the track is then ahead along by the
    #: radar's speed times it. Fitted beside the rest on a drive that slows and speeds up again, and applied only
    #: where the passes show it (:func:`radar_clock_significant`); 0: not fitted
    radar_clock_std_s: float = 0.05
    #: fitted only on a drive whose speed falls by this much and rises again (m/s; a stop and a pull-away): on one
    #: that only speeds up, the track's speed, travel and drive gain rise alike, and what the passes took for the
    #: clock was what the navigation left along (test1 seed 0, on time: -67 +- 5 ms; its truth track with a 0.1 %
    #: stretch: +6 +- 1.5 ms)
    radar_clock_min_dip_mps: float = 2.0
    #: applied where it is this many of its std from 0, that std taken with ``radar_clock_model_std_s`` ...
    radar_clock_min_sigmas: float = 3.0
    #: ... added in quadrature (s): what the fit's std leaves out. The navigation's own along-track error where the
    #: car stops and pulls away shares the clock's signature (the speed times it), so on a drive on time the offset
    #: scatters by more than its std says: urban seeds 0-15 on time read 1.4 ms RMS (twice their std, 0.6-0.9 ms),
    #: seed 4 -3.8 +- 0.7 ms, which applied would put its worst reflector at 2.19 cm (1.45 cm without)
    radar_clock_model_std_s: float = 0.0015
    #: ... and moves the track by at least this much at its fastest (m)
    radar_clock_min_effect_m: float = 0.002
    #: the autofocus reads the passes again along the track on the radar's clock so measured, at most this many
    #: times (:func:`~autosar_cli.sar.autofocus_stage.radar_clock_rereads`)
    radar_clock_rereads: int = 3

    @classmethod
    def from_config(cls, config: Config) -> PassOptions:
        return cls(block_s=config.processing.autofocus_pass_block_s)


@dataclass(frozen=True)
class PassBlocks:
    """One envelope per point and block of pulses (B,): what :func:`estimate_slow_motion` fits."""

    point: NDArray[np.int64]  #: (B,) index of the point
    t_ns: NDArray[np.int64]  #: (B,) the block's mean pulse time
    los: Array  #: (B, 3) unit line of sight, point -> radar (ENU)
    along: Array  #: (B, 3) unit along-track vector of the track (ENU)
    across: Array  #: (B, 3) unit across-track vector towards the radar side (ENU)
    offset_m: Array  #: (B,) measured less predicted bistatic path (m), the echo's Doppler shift taken out
    doppler_m: Array  #: (B,) that shift of the envelope, (dp/dt) f_c / slope (m of path)
    usable: NDArray[np.bool_]  #: (B,) strong enough and inside the search
    n_points: int


@dataclass(frozen=True)
class SlowMotion:
    """Result of :func:`estimate_slow_motion`."""

    trajectory: Trajectory  #: the input with the correction added (the input itself where refused)
    correction: MotionCorrection | None  #: what the ranges measured (None where refused)
    point_shift_enu: Array  #: (P, 3) each point's position error d_j (m; 0 for the points not used)
    points_used: NDArray[np.bool_]  #: (P,)
    point_sigma_m: Array  #: (P,) each point's own fit's robust std of its path (inf: too few blocks)
    #: median over the used points of their joint fit's robust std: the envelopes' scatter, a few tenths of a mm on a
    #: dry road, millimetres where a point's image in the road swings its envelope and the correction can be
    #: centimetres off (the measured ranges: docs/SIMULATION.md, "A road that reflects")
    residual_m: float
    reason: str = ""
    #: the correction's whole-track stretch: its along-track part's slope against the travel (distances times
    #: 1 + stretch), fitted over the nodes by their std, and that fit's std
    stretch: float = 0.0
    stretch_std: float = 0.0
    #: the correction less that stretch (about the track's point nearest its centroid, where
    #: :func:`~autosar_cli.sar.autofocus.scale_track` scales), and each point's shift along the input with it (P, 3)
    #: (ENU m)
    shape_correction: MotionCorrection | None = None
    shape_point_shift_enu: Array | None = None
    #: how far the navigation's mean drive and brake slip gains were off, as the passes measured them (per m/s^2;
    #: :func:`~autosar_cli.nav.wheel_speeds.slip_gain_drift`), and their std; empty where not fitted
    slip_gain_error: Array = dataclasses.field(default_factory=lambda: np.zeros(0))
    slip_gain_error_std: Array = dataclasses.field(default_factory=lambda: np.zeros(0))
    #: the input track's scale error as the correction gives it, read as the evaluation reads a track's
    #: (:func:`similarity_scale_gain`: the whole correction, moving instants alike), and its std: the nodes' and
    #: what the navigation's yaw-rate uncertainty leaves in it (:func:`heading_ramp_scale_std`)
    scale: float = 0.0
    scale_std: float = 0.0
    #: how late the radar's frame stamps run against the navigation's clock (s), and its std, as the passes measure
    #: it (nan where not fitted); applied: the correction holds it (its along-track part, the radar's speed times it)
    radar_clock_offset_s: float = float("nan")
    radar_clock_offset_std_s: float = float("nan")
    radar_clock_applied: bool = False
    #: the largest correlation of that offset's error with a slip gain's, in the joint fit (0 where none is fitted)
    radar_clock_correlation: float = 0.0

    @property
    def applied(self) -> bool:
        return not self.reason

    def to_dict(self) -> dict[str, object]:
        c = self.correction
        out: dict[str, object] = {"applied": self.applied, "reason": self.reason,
                                  "points_used": int(self.points_used.sum()),
                                  "residual_mm": round(1e3 * self.residual_m, 3),
                                 "stretch": self.stretch, "stretch_std": self.stretch_std,
                                  "scale": self.scale, "scale_std": self.scale_std}
        if len(self.slip_gain_error):
            out["slip_gain_error"] = {mode: {"value": float(v), "std": float(sd)} for mode, v, sd in
                                      zip(("drive", "brake"), self.slip_gain_error, self.slip_gain_error_std,
                                          strict=True)}
        if np.isfinite(self.radar_clock_offset_s):
            out["radar_clock"] = {"offset_s": self.radar_clock_offset_s, "std_s": self.radar_clock_offset_std_s,
                                  "correlation": self.radar_clock_correlation, "applied": self.radar_clock_applied}
        if c is not None:
            mag = np.linalg.norm(c.offset_enu, axis=-1)
            out["correction"] = {"rms_mm": round(float(1e3 * np.sqrt(np.mean(mag**2))), 3),
                                 "max_mm": round(float(1e3 * mag.max()), 3),
                                 "std_median_mm": round(float(1e3 * np.median(np.linalg.norm(c.std_enu, axis=-1))),
                                                        3)}
        return out

    def summary(self) -> str:
        if not self.applied:
            return f"slow motion not corrected: {self.reason}"
        d = self.to_dict()
        c, slip = d["correction"], d.get("slip_gain_error", {})
        assert isinstance(c, dict) and isinstance(slip, dict)
        gains = "".join(f", {mode} {100 * g['value']:+.2f} ± {100 * g['std']:.2f} %" for mode, g in slip.items())
        return (f"slow motion corrected by {c['rms_mm']:.1f} mm RMS ({c['max_mm']:.1f} max, ±{c['std_median_mm']:.1f}"
                f" mm) from {int(self.points_used.sum())} points' ranges over their passes, their paths"
                f" {1e3 * self.residual_m:.1f} mm about the fit"
                + (f" (the navigation's slip gains off by{gains[1:]} per m/s²)" if gains else "")
                + (f"; the radar's frame stamps {1e3 * self.radar_clock_offset_s:+.1f} ± "
                   f"{1e3 * self.radar_clock_offset_std_s:.1f} ms late on the navigation's clock, taken out"
                   if self.radar_clock_applied else ""))


def pass_histories(drive_path: str | Path, trajectory: Trajectory, config: Config, points_enu: Array,
                   focus: FocusOptions, opts: PassOptions, min_window_bins: int = 0) -> PhaseHistories:
    """The points' (P, 3) (ENU m) histories over their passes along ``trajectory``, as :func:`pass_blocks` takes
    them, their windows at least ``min_window_bins`` wide (for other fits to narrow from)."""
    return gather_phase_histories(drive_path, trajectory, config, points_enu, focus, half_beam_deg=opts.half_beam_deg,
                                  window_bins=max(int(2 * opts.search_bins) + 18, min_window_bins),
                                  channels=opts.channels)


def pass_blocks(drive_path: str | Path, trajectory: Trajectory, config: Config, points_enu: Array,
                focus: FocusOptions, opts: PassOptions, histories: PhaseHistories | None = None) -> PassBlocks:
    """Each point's (P, 3) (ENU m) range envelope per ``opts.block_s`` of its pulses over its pass, against the
    path predicted along ``trajectory``; from ``histories`` (:func:`pass_histories` along ``trajectory``) where
    given, else from the radar data."""
    points = np.asarray(points_enu, dtype=np.float64).reshape(-1, 3)
    hist = histories if histories is not None else pass_histories(drive_path, trajectory, config, points, focus, opts)
    if len(hist.point) == 0:
        empty = np.zeros((0, 3))
        return PassBlocks(np.zeros(0, np.int64), np.zeros(0, np.int64), empty, empty, empty, np.zeros(0),
                          np.zeros(0), np.zeros(0, bool), len(points))
    tx, rx = pair_antennas(hist, trajectory, config)
    pulse_t = hist.frame_t_ns[hist.frame]
    block = (pulse_t - pulse_t.min()) // int(round(opts.block_s * 1e9))
    n_blocks = int(block.max()) + 1
    keys, group = np.unique(hist.point * n_blocks + block, return_inverse=True)
    point = keys // n_blocks
    offset, power, _ = range_offsets(dataclasses.replace(hist, point=group), tx, rx, points[point], len(keys),
                                     half_bins=opts.search_bins)
    centre, across, along = frame_geometry(trajectory, hist.frame_t_ns, config)
    velocity = np.gradient(centre, hist.frame_t_ns.astype(np.float64) * 1e-9, axis=0)
    count = np.bincount(group).astype(np.float64)

    def mean(a: Array) -> Array:
        return np.stack([np.bincount(group, a[hist.frame, k]) for k in range(a.shape[1])], -1) / count[:, None]

    c, v = mean(centre), mean(velocity)
    t_ns = (np.bincount(group, (pulse_t - pulse_t.min()).astype(np.float64)) / count).astype(np.int64) + pulse_t.min()
    los = c - points[point]
    los /= np.linalg.norm(los, axis=1, keepdims=True)
    # the echo's Doppler moves its beat frequency, and so its envelope, by (dp/dt) f_c / slope of path
    carrier_hz = hist.cycles_per_m * SPEED_OF_LIGHT
    doppler = 2 * np.einsum("ij,ij->i", los, v) * carrier_hz / hist.slope_hz_per_s
    offset = offset - doppler
    median_power = np.zeros(len(points))
    for j in np.unique(point):
        median_power[j] = np.median(power[point == j])
    usable = ((np.abs(offset) < (opts.search_bins - 0.5) * hist.bin_m)
              & (power > opts.min_relative_power * median_power[point]))
    return PassBlocks(point, t_ns, los, mean(along), mean(across), offset, doppler, usable, len(points))


def _travel(trajectory: Trajectory, config: Config) -> tuple[Array, Array]:
    """Seconds since the trajectory's start (K,) and the radar's travel then (K,) (m)."""
    return (trajectory.t_ns - trajectory.t_ns[0]) / 1e9, cumulative_travel(radar_track(trajectory, trajectory.t_ns,
                                                                                          config))


def _gaps(trajectory: Trajectory, opts: PassOptions) -> list[tuple[int, int, float]]:
    """The navigation's wheel gaps (start ns, end ns, along-track drift m) where ``opts`` takes them."""
    if not opts.wheel_gaps:
        return []
    return [(int(g["start_ns"]), int(g["end_ns"]), np.inf if g["along_std_m"] is None else float(g["along_std_m"]))
            for g in trajectory.info.get("wheel_gaps", [])]


def gap_ramps(t_ns: NDArray[np.int64], gaps: list[tuple[int, int, float]]) -> Array:
    """(N, G): how far through each gap ``t_ns`` is (0 before it, 1 after it, linear inside)."""
    t = np.asarray(t_ns, dtype=np.float64)
    return np.stack([np.clip((t - a) / max(b - a, 1), 0.0, 1.0) for a, b, _ in gaps], axis=1) if gaps else (
        np.zeros((len(t), 0)))


def slip_drift(trajectory: Trajectory, t_ns: NDArray[np.int64], opts: PassOptions) -> tuple[Array, Array]:
    """(N, G) the along-track drift per unit error of each slip gain the slow motion fits, and their prior std (G,)
    (none where ``opts`` leaves them out)."""
    if not opts.slip_gains:
        return np.zeros((len(t_ns), 0)), np.zeros(0)
    return slip_gain_drift(trajectory, t_ns)


def radar_clock_drift(trajectory: Trajectory, clock: tuple[Array, Array], t_ns: NDArray[np.int64],
                      opts: PassOptions) -> tuple[Array, Array]:
    """(N, 1): how far along (m) the track puts the radar at ``t_ns`` per second its frame stamps run late (the
    radar's speed, from ``clock``: :func:`_travel`), and the prior std (1,) (s); (N, 0) and (0,) where
    ``opts.radar_clock_std_s`` is 0."""
    if opts.radar_clock_std_s <= 0.0:
        return np.zeros((len(t_ns), 0)), np.zeros(0)
    return np.interp((np.asarray(t_ns) - trajectory.t_ns[0]) / 1e9, clock[0], _speed(clock))[:, None], np.array(
        [opts.radar_clock_std_s])


def _speed(clock: tuple[Array, Array]) -> Array:
    """The radar's speed (m/s) at the trajectory's instants, from ``clock`` (:func:`_travel`)."""
    t_s, travel = clock
    return np.gradient(travel, t_s) if len(t_s) > 1 else np.zeros(len(t_s))


def speed_dip(clock: tuple[Array, Array]) -> float:
    """How far (m/s) the radar's speed falls and then rises again at least, at its deepest: a stop from 5 m/s and
    a pull-away back to it 5; a drive that only speeds up, or only slows down, 0."""
    v = _speed(clock)
    if len(v) == 0:
        return 0.0
    return float(np.max(np.minimum(np.maximum.accumulate(v) - v, np.maximum.accumulate(v[::-1])[::-1] - v)))


def along_drifts(trajectory: Trajectory, clock: tuple[Array, Array], t_ns: NDArray[np.int64], opts: PassOptions
                 ) -> tuple[Array, Array]:
    """The along-track drifts the slow motion fits beside its nodes, per unit of each (N, G) (m), and their prior
    std (G,): the slip gains' (:func:`slip_drift`), then the radar clock's (:func:`radar_clock_drift`)."""
    slip, slip_std = slip_drift(trajectory, t_ns, opts)
    late, late_std = radar_clock_drift(trajectory, clock, t_ns, opts)
    return np.hstack([slip, late]), np.concatenate([slip_std, late_std])


def radar_clock_significant(fit: SlowMotion, speed_mps: float, opts: PassOptions) -> bool:
    """Whether the radar clock offset the passes measured is shown (``opts.radar_clock_min_sigmas`` from 0, its std
    and ``opts.radar_clock_model_std_s`` in quadrature) and matters (the track moved by
    ``opts.radar_clock_min_effect_m`` at ``speed_mps``, the fastest)."""
    offset = abs(fit.radar_clock_offset_s)
    return bool(offset >= opts.radar_clock_min_sigmas * math.hypot(fit.radar_clock_offset_std_s,
                                                                     opts.radar_clock_model_std_s)
                and offset * speed_mps >= opts.radar_clock_min_effect_m)


def point_sigmas(blocks: PassBlocks, trajectory: Trajectory, clock: tuple[Array, Array], opts: PassOptions
                 ) -> tuple[Array, Array]:
    """Per point: the robust std (m) of its blocks about its own fit (its 3-D shift, the track's stretch about it,
    and a step along across each wheel gap inside its pass; inf with fewer than ``opts.min_blocks``) and the travel
    (m) its fitted blocks span. ``clock``: the trajectory's seconds and travel (:func:`_travel`)."""
    t_s, travel = clock
    s = np.interp((blocks.t_ns - trajectory.t_ns[0]) / 1e9, t_s, travel)
    ramps = gap_ramps(blocks.t_ns, _gaps(trajectory, opts))
    drift, drift_std = along_drifts(trajectory, clock, blocks.t_ns, opts)
    sigma, span = np.full(blocks.n_points, np.inf), np.zeros(blocks.n_points)
    for j in range(blocks.n_points):
        m = (blocks.point == j) & blocks.usable
        if m.sum() < opts.min_blocks:
            continue
        u, y, sj = blocks.los[m], blocks.offset_m[m], s[m]
        u_along = 2 * np.einsum("ij,ij->i", u, blocks.along[m])
        # a gap inside the pass (blocks either side of it) may move the track along by a step across it
        inside = [g for g in range(ramps.shape[1]) if 0.0 < ramps[m, g].mean() < 1.0
                  and min(np.sum(ramps[m, g] == 0.0), np.sum(ramps[m, g] == 1.0)) >= opts.min_blocks // 2]
        design = np.column_stack([u_along * (sj - sj.mean()), 2 * u, u_along[:, None] * ramps[m][:, inside],
                                  u_along[:, None] * (drift[m] - drift[m].mean(axis=0))])
        # the slip gains within their stated std, the radar clock within its prior (a prior row each, at the
        # point's own noise level so far)
        prior = np.zeros((len(drift_std), design.shape[1]))
        prior[:, design.shape[1] - len(drift_std):] = np.diag(1.0 / drift_std)
        keep, sg = np.ones(len(y), dtype=bool), opts.max_point_sigma_m
        for _ in range(opts.iterations):
            level = max(sg, opts.noise_floor_m)
            x, *_ = np.linalg.lstsq(np.vstack([design[keep], level * prior]),
                                    np.concatenate([y[keep], np.zeros(len(prior))]), rcond=None)
            resid = y - design @ x
            sg = 1.4826 * float(np.median(np.abs(resid[keep])))
            new = np.abs(resid) < opts.reject_sigma * max(sg, opts.noise_floor_m)
            if new.sum() < opts.min_blocks:
                break
            keep = new
        sigma[j], span[j] = sg, float(np.ptp(sj[keep]))
    return sigma, span


def estimate_slow_motion(drive_path: str | Path, trajectory: Trajectory, config: Config, points_enu: Array,
                         focus: FocusOptions | None = None, opts: PassOptions | None = None,
                         histories: PhaseHistories | None = None) -> SlowMotion:
    """The slow along- and across-track correction of ``trajectory`` that the ranges of the points ``points_enu``
    (P, 3) (ENU m, where ``trajectory`` focuses them) measure over their passes; see the module's docstring.
    ``histories``: their histories gathered already (:func:`pass_histories`)."""
    focus = focus or FocusOptions.from_config(config)
    opts = opts or PassOptions.from_config(config)
    points = np.asarray(points_enu, dtype=np.float64).reshape(-1, 3)
    if len(points) == 0:
        return _refused(trajectory, 0, "no bright point")
    return fit_blocks(pass_blocks(drive_path, trajectory, config, points, focus, opts, histories), trajectory, config,
                      opts)


def _refused(trajectory: Trajectory, n_pts: int, reason: str, sigma: Array | None = None) -> SlowMotion:
    return SlowMotion(trajectory, None, np.zeros((n_pts, 3)), np.zeros(n_pts, dtype=bool),
                      np.full(n_pts, np.inf) if sigma is None else sigma, float("nan"), reason)


def fit_blocks(blocks: PassBlocks, trajectory: Trajectory, config: Config, opts: PassOptions) -> SlowMotion:
    """The slow motion the points' envelopes ``blocks`` (:func:`pass_blocks` along ``trajectory``) measure: the
    points that fit a point over their pass, then the joint fit; on a drive that slows and speeds up again
    (:func:`speed_dip`) the radar's clock fitted beside the rest, and kept only where the passes show it
    (:func:`radar_clock_significant`). Elsewhere the motion is the fit without it: what a weakly measured offset
    would add, its std times the speed, stays out."""
    clock = _travel(trajectory, config)
    n_pts = blocks.n_points

    def fitted(o: PassOptions) -> SlowMotion:
        sigma, span = point_sigmas(blocks, trajectory, clock, o)
        good = (sigma <= o.max_point_sigma_m) & (span >= o.min_span_m)
        if good.sum() < o.min_points:
            return _refused(trajectory, n_pts, f"{int(good.sum())} of {n_pts} points fit a point over "
                            f"{o.min_span_m:g} m of their pass to {1e3 * o.max_point_sigma_m:g} mm (at least "
                            f"{o.min_points} needed)", sigma)
        return _fit(blocks, trajectory, config, clock, o, good, sigma)

    held = fitted(dataclasses.replace(opts, radar_clock_std_s=0.0))
    if opts.radar_clock_std_s <= 0.0 or speed_dip(clock) < opts.radar_clock_min_dip_mps:
        return held
    late = fitted(opts)
    if not late.applied:
        return held
    if radar_clock_significant(late, float(np.max(_speed(clock), initial=0.0)), opts):
        return dataclasses.replace(late, radar_clock_applied=True)
    return dataclasses.replace(held, radar_clock_offset_s=late.radar_clock_offset_s,
                               radar_clock_offset_std_s=late.radar_clock_offset_std_s,
                               radar_clock_correlation=late.radar_clock_correlation)


def _node_weights(nodes_s: Array, t_s: Array) -> tuple[NDArray[np.intp], Array]:
    """For each of ``t_s`` (s) the node ``k`` before it and how far it is towards the next, ``f`` (piecewise linear
    on ``nodes_s``: ``(1 - f)`` of node ``k`` and ``f`` of node ``k + 1``)."""
    k = np.clip(np.searchsorted(nodes_s, t_s, side="right") - 1, 0, len(nodes_s) - 2)
    return k, np.clip((t_s - nodes_s[k]) / (nodes_s[k + 1] - nodes_s[k]), 0.0, 1.0)


def _fit(blocks: PassBlocks, trajectory: Trajectory, config: Config, clock: tuple[Array, Array], opts: PassOptions,
         good: NDArray[np.bool_], point_sigma: Array) -> SlowMotion:
    t0 = trajectory.t_ns[0]
    t_s, travel = clock
    nodes = np.arange(0.0, t_s[-1] + opts.node_s, opts.node_s)
    k_n, n_pts = len(nodes), blocks.n_points
    tb = (blocks.t_ns - t0) / 1e9
    k, f = _node_weights(nodes, tb)
    u_along = np.einsum("ij,ij->i", blocks.los, blocks.along)
    u_across = np.einsum("ij,ij->i", blocks.los, blocks.across)
    n_b = len(tb)
    rows = np.arange(n_b)
    comps = [(u_along, opts.step_along)] + ([(u_across, opts.step_across)] if opts.step_across > 0 else [])
    n_nodes = len(comps) * k_n  # the along nodes, then the across ones where they are fitted
    t_nodes = t0 + np.round(nodes * 1e9).astype(np.int64)
    # then each point's shift, then the slip gains' errors and the radar clock's offset, whose drift adds to the
    # along nodes' correction
    drift, drift_std = along_drifts(trajectory, clock, np.concatenate([blocks.t_ns, t_nodes]), opts)
    drift_nodes, n_slip = drift[len(tb):], len(drift_std)
    n_late = 1 if opts.radar_clock_std_s > 0.0 else 0
    n_var = n_nodes + 3 * n_pts + n_slip
    entries: list[tuple[NDArray[np.int64], Array]] = []
    for c, (u, _) in enumerate(comps):
        entries += [(c * k_n + k, -2 * u * (1 - f)), (c * k_n + k + 1, -2 * u * f)]
    entries += [(n_nodes + 3 * blocks.point + i, 2 * blocks.los[:, i]) for i in range(3)]
    entries += [(np.full(n_b, n_var - n_slip + g), -2 * u_along * drift[:n_b, g]) for g in range(n_slip)]
    design = sp.csr_matrix((np.concatenate([v for _, v in entries]),
                            (np.tile(rows, len(entries)), np.concatenate([c for c, _ in entries]))),
                           shape=(n_b, n_var))
    ds = np.maximum(np.diff(np.interp(nodes, t_s, travel)), 1e-3)
    # a node step spanning (part of) a wheel gap may also drift by the gap's share of its drift (variances add)
    gaps = _gaps(trajectory, opts)
    gap_var = np.zeros(k_n - 1)
    if gaps:
        ramps = gap_ramps(t0 + np.round(nodes * 1e9).astype(np.int64), gaps)
        gap_var = np.diff(ramps, axis=0) @ np.array([min(std, opts.prior_m) ** 2 for _, _, std in gaps])
    diff = sp.diags([-np.ones(k_n - 1), np.ones(k_n - 1)], [0, 1], shape=(k_n - 1, k_n))
    steps = [sp.hstack([sp.csr_matrix((k_n - 1, c * k_n)), diff, sp.csr_matrix((k_n - 1, n_var - (c + 1) * k_n))])
             for c in range(len(comps))]
    prior = sp.vstack([*steps, sp.eye(n_var)]).tocsr()
    prior_std = np.concatenate([np.sqrt((step * ds) ** 2 + (gap_var if c == 0 else 0.0))
                                for c, (_, step) in enumerate(comps)] + [np.full(n_nodes, opts.prior_m),
                                                                    np.full(3 * n_pts, opts.point_prior_m),
                                                                    drift_std])
    weighted_prior = sp.diags(1.0 / prior_std) @ prior
    keep = blocks.usable & good[blocks.point]
    sigma = np.where(good, point_sigma, np.inf)
    x = np.zeros(n_var)
    for _ in range(opts.iterations):
        w = np.where(keep, 1.0 / np.maximum(sigma[blocks.point], opts.noise_floor_m), 0.0)
        normal = (design.T @ sp.diags(w**2) @ design + weighted_prior.T @ weighted_prior).tocsc()
        lu = factor_normal(normal)
        x = lu.solve(design.T @ (w**2 * blocks.offset_m))
        resid = blocks.offset_m - design @ x
        for j in np.flatnonzero(good):
            m = keep & (blocks.point == j)
            if m.sum() >= opts.min_blocks:
                sigma[j] = 1.4826 * float(np.median(np.abs(resid[m])))
        new = blocks.usable & good[blocks.point] & (np.abs(resid) < opts.reject_sigma * np.maximum(
            sigma[blocks.point], opts.noise_floor_m))
        counts = np.bincount(blocks.point[new], minlength=n_pts)
        new &= counts[blocks.point] >= opts.min_blocks
        if np.array_equal(new, keep):
            break
        keep = new
    used = np.bincount(blocks.point[keep], minlength=n_pts) >= opts.min_blocks
    if used.sum() < opts.min_points:
        return SlowMotion(trajectory, None, np.zeros((n_pts, 3)), used, point_sigma, float("nan"),
                          f"{int(used.sum())} points kept fitting the joint model (at least {opts.min_points} needed)")
    # posterior covariance of the nodes (the along ones with the slip gains' and the clock's drift) from the normal
    # matrix's inverse (one column per node: a few dozen to hundreds)
    cols = np.concatenate([np.arange(n_nodes), np.arange(n_var - n_slip, n_var)])
    e = np.zeros((n_var, len(cols)))
    e[cols, np.arange(len(cols))] = 1.0
    full = lu.solve(e)[cols]
    to_nodes = np.zeros((n_nodes, len(cols)))
    to_nodes[:, :n_nodes] = np.eye(n_nodes)
    to_nodes[:k_n, n_nodes:] = drift_nodes
    cov = to_nodes @ full @ to_nodes.T
    std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    across, across_std = (-x[k_n:n_nodes], std[k_n:]) if len(comps) == 2 else (np.zeros(k_n), np.zeros(k_n))
    along = -(x[:k_n] + drift_nodes @ x[n_var - n_slip:])
    drift_error_std = np.sqrt(np.maximum(np.diag(full)[n_nodes:], 0.0))
    clock_correlation = float(np.max(np.abs(full[-1, n_nodes:-1]) / np.maximum(
        drift_error_std[-1] * drift_error_std[:-1], 1e-300))) if n_late and n_slip > n_late else 0.0
    correction = node_correction(trajectory, config, t_nodes, along, across, std[:k_n], across_std)
    shift = x[n_nodes:n_nodes + 3 * n_pts].reshape(n_pts, 3) * used[:, None]
    # the stretch: a straight line through the along nodes against their travel, weighted by their std
    s_nodes = np.interp(nodes, t_s, travel)
    xy = trajectory.rear_axle_enu
    s_centre = np.interp((trajectory.t_ns[np.argmin(np.linalg.norm(xy - xy.mean(axis=0), axis=1))] - t0) / 1e9, t_s,
                         travel)
    line = np.column_stack([np.ones(k_n), s_nodes - s_centre])
    w = 1.0 / np.maximum(std[:k_n], 1e-6) ** 2
    gain = np.linalg.solve(line.T @ (w[:, None] * line), (w[:, None] * line).T)  # (2, k_n): nodes -> line
    stretch = float(gain[1] @ along)
    stretch_std = float(np.sqrt(max(gain[1] @ cov[:k_n, :k_n] @ gain[1], 0.0)))
    scale_gain = similarity_scale_gain(trajectory, config, nodes, len(comps))
    node_values = np.concatenate([along, across][:len(comps)])
    # its std: the nodes', and the share of the navigation's yaw-rate uncertainty no pass measures
    scale = float(scale_gain @ node_values)
    scale_std = float(np.hypot(np.sqrt(max(scale_gain @ cov @ scale_gain, 0.0)),
                               heading_ramp_scale_std(trajectory, config)))
    shape = node_correction(trajectory, config, t_nodes, along - stretch * (s_nodes - s_centre), across, std[:k_n],
                            across_std)
    # each point moves with the track at its broadside block (the one whose line of sight is least along)
    shape_shift = shift.copy()
    for j in np.unique(blocks.point):
        m = np.flatnonzero(blocks.point == j)
        b = m[np.argmin(np.abs(u_along[m]))]
        s_j = np.interp((blocks.t_ns[b] - t0) / 1e9, t_s, travel)
        shape_shift[j] += stretch * (s_j - s_centre) * blocks.along[b]
    return SlowMotion(with_correction(trajectory, correction), correction, shift, used, point_sigma,
                      float(np.median(sigma[used])), stretch=stretch, stretch_std=stretch_std,
                      shape_correction=shape, shape_point_shift_enu=shape_shift,
                      slip_gain_error=x[n_var - n_slip:n_var - n_late].copy(),
                      slip_gain_error_std=drift_error_std[:n_slip - n_late], scale=scale, scale_std=scale_std,
                      radar_clock_offset_s=float(x[-1]) if n_late else float("nan"),
                      radar_clock_offset_std_s=float(drift_error_std[-1]) if n_late else float("nan"),
                      radar_clock_correlation=clock_correlation)


#: the evaluation's moving instants (:func:`autosar_cli.evaluate.trajectory_metrics.common_instants`)
MOVING_MPS = 0.2


def _moving_track(trajectory: Trajectory, config: Config) -> tuple[NDArray[np.int64], Array]:
    """The evaluation's moving instants every 0.1 s (M,) and the radar's track there about its centroid (M, 2)
    (ENU m)."""
    t = np.arange(trajectory.t_ns[0], trajectory.t_ns[-1], 100_000_000, dtype=np.int64)
    t = t[np.interp(t, trajectory.t_ns, trajectory.speed) >= MOVING_MPS]
    if len(t) == 0:
        return t, np.zeros((0, 2))
    xy = radar_track(trajectory, t, config)
    return t, xy - xy.mean(axis=0)


def similarity_scale_gain(trajectory: Trajectory, config: Config, nodes_s: Array, components: int) -> Array:
    """(C K,) the weights that give, from a correction's node values (along the track, then across it where
    ``components`` is 2; on the nodes ``nodes_s``, s since the trajectory's start), the scale of the similarity that
    maps the trajectory's radar track onto the corrected one, less 1 (Umeyama's, as
    :func:`~autosar_cli.evaluate.trajectory_metrics.radar_track_scale` fits it), to first order: each moving
    instant's offset (every 0.1 s) along its position about their centroid, over their spread."""
    t, a = _moving_track(trajectory, config)
    k_n = len(nodes_s)
    if len(t) < 2:
        return np.zeros(components * k_n)
    _, across, along = frame_geometry(trajectory, t, config)
    k, f = _node_weights(nodes_s, (t - trajectory.t_ns[0]) / 1e9)
    gain = np.zeros(components * k_n)
    for c, unit in enumerate((along, across)[:components]):
        proj = np.einsum("ij,ij->i", a, unit[:, :2]) / float(np.sum(a * a))
        np.add.at(gain, c * k_n + k, proj * (1 - f))
        np.add.at(gain, c * k_n + k + 1, proj * f)
    return gain


def heading_ramp_scale_std(trajectory: Trajectory, config: Config) -> float:
    """The std that the navigation's own yaw-rate uncertainty leaves in the similarity scale of its radar track
    (to first order, as :func:`similarity_scale_gain` reads one), which the passes, holding the track across, do
    not measure: :func:`~autosar_cli.nav.trajectory.yaw_rate_bias_std` times the scale by which a yaw-rate error
    of 1 rad/s bends the track (:func:`~autosar_cli.nav.trajectory.heading_ramp_displacement`, the heading turning
    about the instant nearest its centroid). On urban's right turn 0.008 %, twice the nodes' own; on test1-3's
    tracks 0.001-0.003 %. 0 where the trajectory states none."""
    std = yaw_rate_bias_std(trajectory)
    t, a = _moving_track(trajectory, config)
    if not std or len(t) < 2:
        return 0.0
    bend = heading_ramp_displacement(trajectory, t, centre_instant(trajectory), config)
    return std * abs(float(np.sum(a * bend))) / float(np.sum(a * a))


def node_correction(trajectory: Trajectory, config: Config, t_ns: NDArray[np.int64], along_m: Array, across_m: Array,
                    along_std_m: Array, across_std_m: Array) -> MotionCorrection:
    """The ENU offset (a :class:`MotionCorrection` on ``t_ns``) of ``along_m`` along and ``across_m`` across the
    track (towards the radar side) at each of ``t_ns``, and its std."""
    t = np.clip(t_ns, trajectory.t_ns[0], trajectory.t_ns[-1])
    _, across, along = frame_geometry(trajectory, t, config)
    offset = along_m[:, None] * along + across_m[:, None] * across
    std = np.sqrt((along_std_m[:, None] * along) ** 2 + (across_std_m[:, None] * across) ** 2)
    return MotionCorrection(t_ns, offset, std)


def with_correction(trajectory: Trajectory, correction: MotionCorrection) -> Trajectory:
    """``trajectory`` with ``correction`` added to the one it carries (sampled on the union of their times)."""
    old = trajectory.correction
    if old is None:
        return dataclasses.replace(trajectory, correction=correction)
    t = np.union1d(old.t_ns, correction.t_ns)
    return dataclasses.replace(trajectory, correction=MotionCorrection(
        t, old.at(t) + correction.at(t), np.sqrt(old.std_at(t) ** 2 + correction.std_at(t) ** 2)))
