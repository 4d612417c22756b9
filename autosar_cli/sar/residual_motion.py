"""Residual-motion autofocus: the phase-centre motion the navigation missed, measured on the radar's own echoes.

A phase-centre error ``e`` along the line of sight ``u`` (unit, radar -> scatterer) adds ``4 pi e . u / lambda``
to a pulse's phase: 3.2 rad per mm at 77 GHz. Back-projection onto a bright, isolated, stationary point ``p``
turns each pulse into one complex number ``z_k`` (the channels summed); along an error-free track every ``z_k``
has the same phase. So the phase history of a few such points per aperture measures the error, as in
phase-gradient autofocus (Wahl et al. 1994), but solved for a correction of the trajectory, not of the image
(generalised PGA, as in torchbp; "Residual Motion Compensation in Automotive MIMO SAR Imaging", RadarConf 2022):

* the points: the brightest isolated point-like pixels 3-12 m from the track in a first image along the
  navigated track (:func:`~autosar_cli.sar.point_selection.select_points`), about one per ``point_spacing_m`` of
  travel, and as many again 12-16 m out, which measure the motion but not the scale;
* their histories over a wide beam (+-28 deg), each pulse's channels summed, ``presum`` pulses summed after
  compensation (:func:`gather_phase_histories` keeps a few range bins per pulse and channel, so the iterations do
  not read the radar again);
* the model, for the phase step between successive presummed samples a, b of point j::

      psi_b - psi_a = -kappa (u_b . dc(t_b) - u_a . dc(t_a) - (u_b - u_a) . d_j),   kappa = 4 pi / lambda

  with ``dc(t)`` the correction (across track and up, piecewise linear on ``node_s`` nodes) and ``d_j`` the
  point's own position error (it absorbs the parts of the correction that only move a point: a constant and a
  steady drift over its aperture). Phase steps need no unwrapping; each is weighted by its signal-to-noise ratio;
* fused with the navigation: a prior of ``prior_across_m`` and ``prior_up_m`` on the correction (the size of the
  motion the navigation leaves unmodelled; its own covariance bounds the absolute position to ~0.3 m, which
  constrains nothing at this scale) and ``step_across_m`` / ``step_up_m`` on its change between nodes, so a stretch
  with no point keeps the navigated track; a sparse weighted least-squares solve, Gauss-Newton iterations with each
  point's position updated, posterior standard deviations from the normal matrix;
* points whose phases do not fit (moving targets, multipath) are dropped. The correction is refused, with the
  reason, when fewer than ``min_points`` points remain or when it does not make the points' histories more
  coherent.

What it cannot see: a correction constant or linear in time over the whole drive (it moves every point alike),
and the along-track direction (hardly in any line of sight).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from autosar_cli.config import Config
from autosar_cli.nav.trajectory import radar_track, track_scale_std
from autosar_cli.sar.autofocus import scale_track, scaled_filter
from autosar_cli.sar.channel_calibration import ChannelCalibration
from autosar_cli.sar.channel_gains import ChannelGains
from autosar_cli.sar.fast_motion import FastMotion
from autosar_cli.sar.focus import FocusOptions
from autosar_cli.sar.normal_equations import factor_normal, node_difference, node_posterior_std
from autosar_cli.sar.pass_ranges import SlowMotion
from autosar_cli.sar.phase_history import (
    PhaseHistories,
    focus_history,
    frame_geometry,
    gather_phase_histories,
    histories_of,
    narrow_histories,
    pair_antennas,
    range_offsets,
)
from autosar_cli.types import MotionCorrection, Trajectory

Array = NDArray[np.float64]


#: The navigation's own track-scale std, times this, is the autofocus's prior on the scale. Over test1-3 and
#: urban (full vehicle, seeds 0-9: benches/results/nav_seeds_full.json's scale_z_rms) the scale's error is 0.9-1.5
#: times that std RMS: on the full vehicle the filter's covariance is that much too small.
NAV_SCALE_STD_FACTOR = 2.0

#: Range bins kept beyond the phases' window on either side where their histories are narrowed from the passes'
#: (:func:`~autosar_cli.sar.autofocus_stage.residual_motion_of_points`): room for the slow motion's change of each
#: pulse's path.
NARROWING_SLACK_BINS = 6

#: Probability of the points' agreement test on the track scale (:func:`_agreement_limit`): a scale that the points
#: disagree on by more is not the track's (urban seed 0: reduced chi-square 80 over 10 points, the scale -0.12 % where
#: the truth says 0; test3 seed 2: 1.5 over 5, test1 seed 0: 0.5 over 4).
SCALE_AGREEMENT_PROBABILITY = 0.999

#: a boresight further than this (deg) from the stated one is no mounting error: points that all cross the beam
#: alike (:func:`~autosar_cli.sar.autofocus_stage.autofocus_residual_motion`)
MAX_MOUNTING_YAW_DEG = 5.0


@dataclass(frozen=True)
class AutofocusOptions:
    """Parameters of the residual-motion autofocus (their reasons: docs/AUTOFOCUS.md, "What it does")."""

    half_beam_deg: float = 28.0  #: half-width of the beam over which each point's history is taken
    channels: int = 2  #: channels of the first image and the histories (sar.focus.channel_pairs)
    min_range_m: float = 3.0  #: ground distance from the track of the points chosen
    max_range_m: float = 16.0
    #: points farther than this measure the motion, not the scale: chosen apart from the nearer ones, and left out of
    #: the scale's fits and agreement test (with a 2 mm sine across, a corner reflector at 12.5 m made test1 seed 1's
    #: points disagree; in the joint fit such points pulled test1 seeds 0-9's scale by -0.05 % mean)
    scale_max_range_m: float = 12.0
    point_spacing_m: float = 1.5  #: about one point per this much travel (and no two points closer)
    presum: int = 4  #: pulses summed (after compensation) per sample of a history
    node_s: float = 0.01  #: spacing of the correction's nodes (s)
    window_bins: int = 32  #: range bins kept around each pulse's expected range
    iterations: int = 4  #: Gauss-Newton iterations at most
    prior_across_m: float = 0.005  #: prior std of the across-track correction
    prior_up_m: float = 0.005  #: prior std of the vertical correction
    #: prior std of the correction's change from one node to the next, across track (1 cm/s: body roll and the
    #: case's horizontal vibration, 0.1 mm at 4-25 Hz, move it less; looser, it takes the scale's share of each
    #: aperture's quadratic phase on a rough road) and up (the case's vertical vibration, ~1 mm)
    step_across_m: float = 0.0001
    step_up_m: float = 0.001
    point_prior_m: float = 0.02  #: prior std of a point's own position error
    #: prior std of the track's along-track scale; None: ``NAV_SCALE_STD_FACTOR`` times the navigation's own std
    #: (:func:`~autosar_cli.nav.trajectory.track_scale_std`), or ``fallback_prior_scale`` where it has none
    prior_scale: float | None = None
    fallback_prior_scale: float = 0.003  #: a track without a scale covariance (GNSS velocity: ~0.04 % on 25 s)
    max_scale_std: float = 0.0003  #: a scale measured less well than this is not applied
    range_sigma_m: float = 0.002  #: std of a point's bistatic path from its range envelope
    #: points fitting worse than this are dropped (moving, multipath: 1.8-2 rad; corner reflectors under three times
    #: the radar case's vibration fit at 0.12-0.20 rad within the node steps' priors)
    max_phase_rms_rad: float = 0.3
    #: and from the scale's joint fit, worse than this (the 0.15-0.3 rad points moved test2 seeds 0-6's scale by up
    #: to 0.009 % towards 0, away from the track's error)
    scale_max_phase_rms_rad: float = 0.15
    #: points beyond the joint fit's that fit worse than this along its track, before any fit, are not fitted
    #: again (clutter and moving scatterers: 1.4-2 rad; test2 seed 1's that fit at 0.15-0.3 rad: 0.5-0.6 rad)
    screen_phase_rms_rad: float = 1.0
    min_points: int = 2  #: fewer usable points: no correction
    #: a point with fewer phase steps than this is weighted by all the points' noise, not its own: the median of n
    #: steps measures a noise power to about 2.3/sqrt(n) (43 % at 30), and a point seen by a few pulses would
    #: otherwise weigh as much as its luck (the used points of test2 seed 1 hold 185-255)
    min_steps_own_noise: int = 30
    #: a used point whose phase between its first and last channel (:func:`~autosar_cli.sar.phase_history.
    #: channel_phase`: the virtual array's ends, along the road) is larger than this moves across the beam, which
    #: back-projection places further along: it is left out and the points fitted again (the 40 drives' used
    #: points: benches/results/af_movers.json; one crossing at 0.5 m/s: 2.1 rad); None: no such test
    max_channel_phase_rad: float | None = 0.5
    #: where the channels agree at least this well (|sum z1 z2*| / sum |z1 z2|): a weak point's phase says nothing
    #: (test3 seed 2 used one at 0.35 rad and 0.28; the movers measured: 0.89-0.99)
    min_channel_coherence: float = 0.6
    #: each point's aperture stretched by the road's grade (:func:`grade_stretch`), which the scale then leaves out
    grade_stretch: bool = True
    #: first the track's slow motion from the points' ranges over their whole passes (:mod:`autosar_cli.sar.
    #: pass_ranges`): the along-track error between points, which no phase over +-``half_beam_deg`` measures. The
    #: config's ``processing.autofocus_slow_motion`` where the options are not given (on; its figures and cost:
    #: docs/AUTOFOCUS.md, "The slow motion from the points' passes")
    slow_motion: bool = True
    #: last, the fast across-track motion from many scatterers (:mod:`autosar_cli.sar.fast_motion`). The config's
    #: ``processing.autofocus_fast_motion`` where the options are not given (off: with it ``run --autofocus`` takes
    #: 1.45-1.65 times ``run`` on test2 as the host moves it, against the 1.5 asked; the far swath then within 0.2 %
    #: of the truth's on 22 of the 40, at most 0.2 % above on 39; docs/AUTOFOCUS.md)
    fast_motion: bool = False
    #: first, the radar's channel gains from the points (:mod:`autosar_cli.sar.channel_calibration`), undone where
    #: they are off; the config's ``processing.autofocus_channel_gains`` where the options are not given (on)
    channel_gains: bool = True

    @classmethod
    def from_config(cls, config: Config) -> AutofocusOptions:
        return cls(slow_motion=config.processing.autofocus_slow_motion,
                   fast_motion=config.processing.autofocus_fast_motion,
                   channel_gains=config.processing.autofocus_channel_gains)


@dataclass
class _Samples:
    """Presummed history samples: point, group, time (s from t0), value, line of sight."""

    point: NDArray[np.int64]
    t_s: Array
    z: NDArray[np.complex128]
    los: Array
    lever: Array  #: (M, 3) d(phase centre)/d(track scale): the rear axle's horizontal offset from the scaling centre


def _presum(hist: PhaseHistories, z: NDArray[np.complex128], los: Array, presum: int, t0_ns: int,
            scale_lever: Array) -> _Samples:
    if len(z) == 0:
        return _Samples(np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.complex128), np.zeros((0, 3)),
                        np.zeros((0, 3)))
    key = hist.point * (len(hist.frame_t_ns) // presum + 2) + hist.frame // presum
    uniq, inv = np.unique(key, return_inverse=True)
    n = len(uniq)
    zs = np.bincount(inv, z.real, n) + 1j * np.bincount(inv, z.imag, n)
    count = np.bincount(inv, minlength=n).astype(np.float64)
    t = np.bincount(inv, (hist.frame_t_ns[hist.frame] - t0_ns) / 1e9, n) / count
    u = np.stack([np.bincount(inv, los[:, k], n) for k in range(3)], axis=-1)
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    lever = np.stack([np.bincount(inv, scale_lever[hist.frame, k], n) for k in range(3)], axis=-1) / count[:, None]
    point = np.zeros(n, np.int64)
    point[inv] = hist.point
    order = np.lexsort((t, point))
    return _Samples(point[order], t[order], zs[order], u[order], lever[order])


@dataclass(frozen=True)
class ResidualMotion:
    """Result of :func:`estimate_residual_motion` /
    :func:`~autosar_cli.sar.autofocus_stage.autofocus_residual_motion`."""

    trajectory: Trajectory  #: the input with its correction (unchanged where ``reason`` says why not)
    #: what the radar data measured (None where refused); the trajectory's correction is this plus the one the
    #: input carried (e.g. the radar's offset on a graded road, :mod:`autosar_cli.nav.vertical`)
    correction: MotionCorrection | None
    points_enu: Array  #: (P, 3) the candidate points, where the (corrected) track focuses them
    points_used: NDArray[np.bool_]  #: (P,) those that fit and were used
    phase_rms_rad: Array  #: (P,) each point's phase residual (rad RMS of its phase steps)
    coherence_before: float  #: median over used points of |sum z| / sum |z| along the navigated track
    coherence_after: float  #: the same along the corrected track
    coverage: float  #: fraction of the moving frames that at least one used point sees
    iterations: int
    reason: str = ""
    seen_t_ns: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))  #: those frames' times
    scale: float = 0.0  #: the along-track scale applied to the track (distances times 1 + scale)
    scale_std: float = 0.0  #: its posterior std
    scale_note: str = ""  #: why the scale was kept, where it was
    #: the points' own scales about the common one: reduced chi-square and the number of points (the scale fit's)
    scale_agreement: tuple[float, int] = (1.0, 0)
    scale_prior: float = 0.0  #: the prior std the scale was fitted with (:func:`with_scale_prior`)
    #: the used points' mean stretch of their apertures by the road's grade, which the scale leaves out
    grade_stretch: float = 0.0
    #: a fit run without its posterior: the same result with the correction's std (None where it has it)
    with_posterior: Callable[[], ResidualMotion] | None = field(default=None, repr=False, compare=False)
    #: the slow motion measured first (:mod:`autosar_cli.sar.pass_ranges`); where applied, ``trajectory`` and its
    #: correction hold it, and ``correction`` (the phases') does not
    slow_motion: SlowMotion | None = None
    #: the fast motion measured last (:mod:`autosar_cli.sar.fast_motion`); where applied, ``trajectory`` and its
    #: correction hold it, and ``correction`` does not
    fast_motion: FastMotion | None = None
    #: (M, 3) candidate points left out as moving (where the first fit put them) and their channel phases (rad)
    moving_points_enu: Array = field(default_factory=lambda: np.zeros((0, 3)))
    moving_channel_phase_rad: Array = field(default_factory=lambda: np.zeros(0))
    #: the radar's boresight (deg, from ``radar.mounting.yaw_deg``) that would put every moving point's channel phase
    #: at 0, where they agree on one (:func:`~autosar_cli.sar.autofocus_stage.mounting_yaw_agreed`): a still scene
    #: seen through a radar mounted otherwise than stated shows as points that all cross the beam alike; None where
    #: they do not agree. Taken for a mounting error (and the autofocus run along it) only within
    #: ``MAX_MOUNTING_YAW_DEG``
    moving_mounting_yaw_deg: float | None = None
    #: the radar's boresight (deg, ``radar.mounting.yaw_deg``'s convention) the points were fitted along, where the
    #: stated one left them all moving and the one they agreed on let them fit
    #: (:func:`~autosar_cli.sar.autofocus_stage.autofocus_residual_motion`): the corrected trajectory's ``info``
    #: carries it, and focus takes it; None: the stated one
    radar_mounting_yaw_deg: float | None = None
    #: the radar's channel gains measured first (:mod:`autosar_cli.sar.channel_calibration`); where applied, every
    #: read after it, and the image focused along ``trajectory``, undo them
    channel_calibration: ChannelCalibration | None = None
    #: how late (s) the radar's frame stamps run on the navigation's clock, as the points' passes measured it and
    #: read again along the track so shifted (:func:`~autosar_cli.sar.autofocus_stage.radar_clock_rereads`);
    #: ``trajectory`` is on the radar's clock by this much (0: on the navigation's)
    radar_clock_offset_s: float = 0.0
    #: each read's measured offset (s), its std (s) and whether it was applied, the first read first (empty where
    #: the passes fitted no clock): what a read not applied showed is kept too
    radar_clock_reads: tuple[tuple[float, float, bool], ...] = ()

    @property
    def radar_clock_rereads(self) -> int:
        """How many times the passes were read again along the track on the radar's clock."""
        return max(len(self.radar_clock_reads) - 1, 0)

    @property
    def channel_gains(self) -> ChannelGains | None:
        """The channel gains applied (None: the channels as matched)."""
        c = self.channel_calibration
        return c.gains if c is not None and c.applied else None

    @property
    def applied(self) -> bool:
        """Whether the track was corrected at all: by the phases, or by the slow motion alone."""
        return not self.reason or (self.slow_motion is not None and self.slow_motion.applied)

    def labelled(self, method: str) -> Trajectory:
        """The corrected trajectory named ``method``, its info holding what autofocus measured."""
        gains = {"channel_gains": self.channel_gains.to_dict()} if self.channel_gains is not None else {}
        yaw = self.radar_mounting_yaw_deg
        mounting = {} if yaw is None else {"radar_mounting_yaw_deg": yaw}
        return replace(self.trajectory, method=method, info={**self.trajectory.info, "track_scale": self.scale,
                                                             "autofocus": self.to_dict(), **gains, **mounting})

    def correction_summary(self) -> dict[str, float]:
        c = self.correction
        if c is None:
            return {}
        mag = np.linalg.norm(c.offset_enu, axis=-1)
        return {"rms_mm": float(1e3 * np.sqrt(np.mean(mag**2))), "max_mm": float(1e3 * mag.max()),
                "std_median_mm": float(1e3 * np.median(np.linalg.norm(c.std_enu, axis=-1)))}

    def to_dict(self) -> dict[str, object]:
        return {"applied": self.applied, "reason": self.reason,
                "channel_gains": self.channel_calibration.to_dict() if self.channel_calibration is not None else None,
                "slow_motion": self.slow_motion.to_dict() if self.slow_motion is not None else None,
                "radar_clock": {"offset_s": self.radar_clock_offset_s, "rereads": self.radar_clock_rereads,
                                "reads": [{"offset_s": o, "std_s": e, "applied": a}
                                          for o, e, a in self.radar_clock_reads]},
                "fast_motion": self.fast_motion.to_dict() if self.fast_motion is not None else None,
                "track_scale": self.scale,
                "track_scale_std": self.scale_std, "track_scale_prior_std": self.scale_prior,
                "track_scale_note": self.scale_note, "grade_stretch": self.grade_stretch,
                "track_scale_agreement": {"reduced_chi2": round(self.scale_agreement[0], 3),
                                          "points": self.scale_agreement[1]},
                "points": int(len(self.points_enu)),
                "points_used": int(self.points_used.sum()), "coverage": round(self.coverage, 4),
                "coherence_before": round(self.coherence_before, 4), "coherence_after": round(self.coherence_after, 4),
                "iterations": self.iterations, "correction": self.correction_summary(),
                "points_enu": np.round(self.points_enu, 4).tolist(),
                "moving_points": [{"enu": np.round(p, 4).tolist(), "channel_phase_rad": round(float(a), 3)}
                                  for p, a in zip(self.moving_points_enu, self.moving_channel_phase_rad, strict=True)],
                "moving_points_mounting_yaw_deg": None if self.moving_mounting_yaw_deg is None
                else round(self.moving_mounting_yaw_deg, 2),
                "radar_mounting_yaw_deg": self.radar_mounting_yaw_deg}

    def _moving_summary(self) -> str:
        if not len(self.moving_points_enu):
            return ""
        phases = ", ".join(f"{abs(a):.2f}" for a in self.moving_channel_phase_rad)
        yaw = self.moving_mounting_yaw_deg
        if yaw is None:
            mounting = ""
        elif abs(yaw) <= MAX_MOUNTING_YAW_DEG:
            mounting = (f"; or they are still, seen by a radar whose boresight lies at radar.mounting.yaw_deg "
                        f"{yaw:+.1f} deg, on which they all agree: check the radar's mounting")
        else:
            mounting = (f"; they agree on a boresight at radar.mounting.yaw_deg {yaw:+.1f} deg, beyond the "
                        f"{MAX_MOUNTING_YAW_DEG:g} deg taken for a mounting error: points crossing alike, or a radar "
                        "mounted that far off its stated boresight")
        return (f"; {len(self.moving_points_enu)} moving point(s) left out (their channels' phase {phases} rad: "
                f"they cross the beam{mounting})")

    def summary(self) -> str:
        """One line: what was corrected, or why nothing was."""
        cal = self.channel_calibration
        gains = f"{cal.summary()}; " if cal is not None and cal.applied else ""
        slow = "" if self.slow_motion is None else self.slow_motion.summary() + "; "
        if self.radar_clock_offset_s:
            slow = (f"the radar's frame stamps {1e3 * self.radar_clock_offset_s:+.1f} ms late on the navigation's "
                    f"clock (the passes read {self.radar_clock_rereads + 1} times), the track put on the radar's; "
                    + slow)
        fast = "" if self.fast_motion is None else "; " + self.fast_motion.summary()
        if self.radar_mounting_yaw_deg is not None:
            gains = (f"the radar's boresight taken at yaw {self.radar_mounting_yaw_deg:.1f} deg, on which its points "
                     "agreed where the stated one had them all cross the beam; " + gains)
        if self.reason:  # which says what moved, where that left too few points
            return gains + (f"{slow}track not corrected by the phases: {self.reason}{fast}" if slow else
                            f"track not corrected: {self.reason}")
        return gains + slow + self._phase_summary() + self._moving_summary() + fast

    def _phase_summary(self) -> str:
        c = self.correction_summary()
        scaled = self.scale_note or f"distances scaled by {self.scale * 100:+.4f} ± {self.scale_std * 100:.4f} %"
        if abs(self.grade_stretch) >= 1e-4:  # a grade of 1.4 % and more: say what the scale left out
            scaled += (f" (the road's grade: the radar's path {self.grade_stretch * 100:+.3f} % on the track's, "
                       "left out)")
        return (f"{scaled}, residual motion corrected by {c['rms_mm']:.2f} mm RMS ({c['max_mm']:.2f} max, "
                f"±{c['std_median_mm']:.2f} mm), measured on {int(self.points_used.sum())} points seen over "
                f"{100 * self.coverage:.0f} % of the drive; their coherence {self.coherence_before:.3f} -> "
                f"{self.coherence_after:.3f}")


def _coherence(samples: _Samples, used: NDArray[np.bool_]) -> float:
    """Median over the used points of |sum z| / sum |z| over each point's presummed history (1: perfectly focused)."""
    vals = []
    for j in np.flatnonzero(used):
        z = samples.z[(samples.point == j) & np.isfinite(samples.z)]
        if len(z):
            vals.append(abs(z.sum()) / max(np.abs(z).sum(), 1e-30))
    return float(np.median(vals)) if vals else 0.0


@dataclass
class _Linear:
    """The phase steps of the used points at the current state and their derivatives."""

    step: Array  #: (M,) wrapped phase step between successive samples of a point (rad)
    design: sp.csr_matrix  #: (M, unknowns): step after the increment dx is step + design @ dx
    rel_var: Array  #: (M,) relative variance of each step (noise power units)
    point: NDArray[np.int64]  #: (M,) the point of each step
    range_resid: Array = field(default_factory=lambda: np.zeros(0))  #: (Q,) envelope range offset per used point (m)
    range_design: sp.csr_matrix | None = None  #: (Q, unknowns): its change with the increment


def _phase_steps(smp: _Samples, used: NDArray[np.bool_]) -> tuple[NDArray[np.int64], Array]:
    """The first sample's index of each step between successive valid samples of a used point, and the step (rad,
    wrapped)."""
    valid = np.isfinite(smp.z)
    a_idx = np.flatnonzero((smp.point[1:] == smp.point[:-1]) & used[smp.point[1:]] & valid[1:] & valid[:-1])
    return a_idx, np.angle(smp.z[a_idx + 1] * np.conj(smp.z[a_idx]))


def _linearise(smp: _Samples, used: NDArray[np.bool_], node_across: Array, node_s: float, kappa: float,
               n_pts: int) -> _Linear:
    """Phase steps of successive presummed samples of each used point and their linear model: with the
    correction dc (across, up on the nodes), the point shifts d and the track scale ds, psi_b - psi_a changes by
    kappa (u_b . dc(t_b) - u_a . dc(t_a) - (u_b - u_a) . d_j + (u_b . l_b - u_a . l_a) ds), l the scale's lever."""
    n_nodes = len(node_across)
    a_idx, step = _phase_steps(smp, used)
    b_idx = a_idx + 1
    pa, pb = np.abs(smp.z[a_idx]) ** 2, np.abs(smp.z[b_idx]) ** 2
    rel_var = 0.5 * (1.0 / np.maximum(pa, 1e-30) + 1.0 / np.maximum(pb, 1e-30))
    cols, vals = [], []
    for which, sign in ((a_idx, -1.0), (b_idx, 1.0)):
        u = smp.los[which]
        pos = np.clip(smp.t_s[which] / node_s, 0.0, n_nodes - 1.000001)
        n0 = np.floor(pos).astype(np.int64)
        frac = pos - n0
        across = node_across[n0] * (1 - frac)[:, None] + node_across[n0 + 1] * frac[:, None]
        k_across = np.einsum("nk,nk->n", u, across)
        for col, wgt in ((n0, 1 - frac), (n0 + 1, frac)):
            cols += [col, n_nodes + col]
            vals += [sign * kappa * wgt * k_across, sign * kappa * wgt * u[:, 2]]
    du = smp.los[b_idx] - smp.los[a_idx]
    pt = smp.point[b_idx]
    for k in range(3):
        cols.append(2 * n_nodes + 3 * pt + k)
        vals.append(-kappa * du[:, k])
    # the track scale moves every phase centre by scale * lever (a similarity about the track's centre)
    cols.append(np.full(len(step), 2 * n_nodes + 3 * n_pts))
    vals.append(kappa * (np.einsum("nk,nk->n", smp.los[b_idx], smp.lever[b_idx])
                         - np.einsum("nk,nk->n", smp.los[a_idx], smp.lever[a_idx])))
    m = len(step)
    design = sp.csr_matrix((np.concatenate(vals), (np.tile(np.arange(m), len(vals)), np.concatenate(cols))),
                           shape=(m, 2 * n_nodes + 3 * n_pts + 1))
    return _Linear(step, design, rel_var, pt)


def estimate_residual_motion(drive_path: str | Path, trajectory: Trajectory, config: Config, points_enu: Array,
                             focus: FocusOptions | None = None, opts: AutofocusOptions | None = None,
                             unscaled: tuple[Trajectory, Array] | None = None,
                             histories: PhaseHistories | None = None) -> ResidualMotion:
    """The correction of ``trajectory`` that makes the phase histories of the points ``points_enu`` (P, 3) (ENU m,
    where ``trajectory`` focuses them) coherent; see the module's docstring. ``unscaled``: where the points do not
    measure the scale, the motion is fitted along this trajectory instead, the points (P, 3) where it focuses them
    (the passes' stretch, :func:`~autosar_cli.sar.autofocus_stage.residual_motion_of_points`), on the same
    histories. ``histories``: the points' histories over a wider beam and window along a track near ``trajectory``,
    narrowed here
    (:func:`~autosar_cli.sar.phase_history.narrow_histories`) instead of read again."""
    focus = focus or FocusOptions.from_config(config)
    opts = with_scale_prior(opts or AutofocusOptions(), trajectory)
    points0 = np.asarray(points_enu, dtype=np.float64).reshape(-1, 3)
    n_pts = len(points0)
    if n_pts == 0:
        return ResidualMotion(trajectory, None, points0, np.zeros(0, dtype=bool), np.zeros(0), 0.0, 0.0, 0.0, 0,
                              f"no bright isolated point {opts.min_range_m:g}-{opts.max_range_m:g} m from the track")
    if histories is not None:
        hist = narrow_histories(histories, trajectory, config, points0, focus, half_beam_deg=opts.half_beam_deg,
                                window_bins=opts.window_bins)
    else:
        hist = gather_phase_histories(drive_path, trajectory, config, points0, focus,
                                      half_beam_deg=opts.half_beam_deg, window_bins=opts.window_bins,
                                      channels=opts.channels)
    grade = grade_stretch(drive_path, trajectory, config, hist.frame_t_ns) if opts.grade_stretch else None
    # first the scale alone, the track otherwise as navigated: its signature is each aperture's quadratic phase
    # (the wide beam's defocus the old scale sweep measured), which a free across-track correction would absorb
    # (the uncorrected motion leaves larger phase residuals: a looser test of which points are points)
    held = replace(opts, prior_across_m=1e-6, prior_up_m=1e-6, max_phase_rms_rad=max(opts.max_phase_rms_rad, 0.5))
    near = _ground_distance(trajectory, config, points0) <= opts.scale_max_range_m
    first = _fit(hist, trajectory, config, points0, held, used0=near, posterior=False, grade_stretch=grade)
    scale, scale_std, note = first.scale, first.scale_std, ""
    if not first.applied:
        scale, note = 0.0, f"track scale not measured: {first.reason}"
    elif scale_std > opts.max_scale_std:
        scale, note = 0.0, f"track scale not measured (its std would be {scale_std * 100:.3f} %)"
    elif first.scale_agreement[0] > _agreement_limit(first.scale_agreement[1]):
        chi2, n = first.scale_agreement
        scale, note = 0.0, (f"track scale not measured: its {n} points disagree on it (reduced chi-square "
                            f"{chi2:.1f}, above {_agreement_limit(n):.1f})")
    used0 = first.points_used | ~near if first.applied else None
    motion = replace(opts, prior_scale=1e-9)  # the scale held
    if scale:
        # then the residual motion and the scale together, from that scale and the points that fitted it: the
        # motion the first fit held takes back the share of each aperture's quadratic phase that is its own
        # (test3 seed 1: +0.037 % alone, -0.002 % together, the track's error -0.017 %); the near points alone, for
        # the farther pull the scale (test1 seeds 0-9: -0.064 % mean against the track's error with them)
        result = _fit(hist, trajectory, config, first.points_enu,
                      replace(opts, max_phase_rms_rad=opts.scale_max_phase_rms_rad),
                      used0=first.points_used, scale0=scale, posterior=False,
                      grade_stretch=grade)  # the fit below may replace it
        scale, scale_std = (result.scale, result.scale_std) if result.applied else (0.0, scale_std)
        extra = used0 & ~result.points_used if result.applied else np.zeros(n_pts, dtype=bool)
        if np.any(extra):
            # and the motion on every point along the track so scaled, the scale held: the points the joint fit
            # did not place where the first image put them, scaled with the track, less those that are no point
            # along the joint fit's track before any fit (clutter: 1.4-2 rad)
            centre = trajectory.rear_axle_enu.mean(axis=0)
            moved = np.where(result.points_used[:, None], result.points_enu, points0)
            moved[~result.points_used, :2] = centre + (1.0 + scale) * (moved[~result.points_used, :2] - centre)
            extra &= _phase_rms(hist, result.trajectory, config, moved, extra, opts.presum) <= opts.screen_phase_rms_rad
            if np.any(extra):
                every = _fit(hist, scale_track(trajectory, scale, centre), config, moved, motion,
                             used0=result.points_used | extra, motion0=result.correction, point_noise=True,
                             grade_stretch=grade)
                result = every if every.applied else result
    # without the scale, the motion is fitted from the points where the track without it focuses them: the first
    # fit moved its points with the scale it measured (a stretch of the track over each aperture), so where that
    # scale is not kept, neither are they (and its unconverged shifts moved urban seed 8's correction by 2.5 mm for
    # a change of 1 nm in the track)
    elif unscaled is not None:  # the residual motion alone along the track given for it
        track, moved = unscaled
        result = _fit(hist, track, config, np.asarray(moved, dtype=np.float64), motion, used0=used0,
                      point_noise=True, grade_stretch=grade)
    else:  # the residual motion alone along the navigated track
        result = _fit(hist, trajectory, config, points0, motion, used0=used0, point_noise=True, grade_stretch=grade)
    if result.with_posterior is not None:
        result = result.with_posterior()
    if scale and result.applied:
        # the track as scaled keeps the navigation's state and covariance, carried once here rather than by each fit
        state, covariance = scaled_filter(trajectory, scale, trajectory.rear_axle_enu.mean(axis=0), scale_std)
        result = replace(result, trajectory=replace(result.trajectory, state=state, covariance=covariance))
    return replace(result, scale=scale, scale_std=scale_std, scale_note=note,
                   scale_agreement=first.scale_agreement if first.applied else (1.0, 0), scale_prior=opts.prior_scale)


def grade_stretch(drive_path: str | Path, trajectory: Trajectory, config: Config, t_ns: NDArray[np.int64]
                  ) -> Array | None:
    """How much longer (F,) the radar's path is than ``trajectory``'s at times ``t_ns`` (F,): sqrt(1 + m^2) -
    sqrt(1 + n^2) for the slope m of the radar's path from the drive's GNSS climb
    (:func:`~autosar_cli.nav.navigate.radar_slope`) and n that of the track's own height (0 for a planar track).
    The planar track's points lie on a tilted road as on a level one, but the radar passes them over the slope's
    length: 0.08 % at a 4 % grade, which the scale would otherwise read as the track's. None without a climb."""
    from autosar_cli.nav.attitude import SLOPE_HALF_SPAN_S
    from autosar_cli.nav.inputs import NavInputError, load_inputs
    from autosar_cli.nav.navigate import radar_slope
    from autosar_cli.store.drive import Drive

    try:
        with Drive(drive_path) as drive:
            inputs = load_inputs(drive, config)
    except NavInputError:
        return None
    t_ns = np.asarray(t_ns, dtype=np.int64)
    m = radar_slope(inputs, config, (t_ns - inputs.t0_ns) / 1e9)
    if m is None:
        return None
    half = int(SLOPE_HALF_SPAN_S * 1e9)
    ends = np.clip(np.stack([t_ns - half, t_ns + half]), trajectory.t_ns[0], trajectory.t_ns[-1])
    run = np.linalg.norm(trajectory.pose(ends[1])[0] - trajectory.pose(ends[0])[0], axis=-1)
    rise = trajectory.height_offset(ends[1]) - trajectory.height_offset(ends[0])
    n = np.divide(rise, run, out=np.zeros_like(run), where=run > 0.5)
    return np.sqrt(1.0 + m**2) - np.sqrt(1.0 + n**2)


def with_scale_prior(opts: AutofocusOptions, trajectory: Trajectory) -> AutofocusOptions:
    """``opts`` with its track-scale prior set: as given, else from the navigation's covariance
    (``NAV_SCALE_STD_FACTOR`` times :func:`~autosar_cli.nav.trajectory.track_scale_std`), else the fallback."""
    if opts.prior_scale is not None:
        return opts
    nav_std = track_scale_std(trajectory)
    prior = NAV_SCALE_STD_FACTOR * nav_std if nav_std else opts.fallback_prior_scale
    return replace(opts, prior_scale=prior)


def _phase_rms(hist: PhaseHistories, trajectory: Trajectory, config: Config, points_enu: Array,
               used: NDArray[np.bool_], presum: int) -> Array:
    """Each used point's (P,) phase residual (rad RMS of its presummed phase steps) along ``trajectory`` as it is,
    with no fit (inf for the others); ``points_enu`` (P, 3) ENU m."""
    h, _ = histories_of(hist, used)
    z, los = focus_history(h, *pair_antennas(h, trajectory, config), points_enu)
    smp = _presum(h, z, los, presum, int(trajectory.t_ns[0]), np.zeros((len(h.frame_t_ns), 3)))
    a_idx, step = _phase_steps(smp, used)
    n = len(points_enu)
    point = smp.point[a_idx + 1]
    count = np.bincount(point, minlength=n)
    return np.where(count > 0, np.sqrt(np.bincount(point, step**2, n) / np.maximum(count, 1)), np.inf)


def _ground_distance(trajectory: Trajectory, config: Config, points_enu: Array) -> Array:
    """Each point's (P, 3) (ENU m) horizontal distance (m) from the radar's track."""

    track = radar_track(trajectory, trajectory.t_ns, config)[:, :2]
    return np.array([float(np.min(np.hypot(*(track - p[:2]).T))) for p in points_enu])


def _agreement_limit(n_points: int) -> float:
    """The reduced chi-square of ``n_points`` points' own scales above which they disagree on a common one: the
    0.999 quantile of chi-square with n - 1 degrees of freedom over n - 1 (infinite for one point)."""
    from scipy.stats import chi2

    return float(chi2.ppf(SCALE_AGREEMENT_PROBABILITY, n_points - 1) / (n_points - 1)) if n_points > 1 else math.inf


def _measured_noise(resid_norm: Array, steps_of: list[Array], min_steps: int | None) -> Array:
    """Noise power of one phase step at unit relative variance, per point, from the fit's residuals.

    ``resid_norm`` (M,): each step's squared residual over its relative variance (rad²); ``steps_of``: each point's
    step indices. All points share the median's level (the median of χ²(1) is 0.455), robust to the few steps a
    moving scatterer spoils; with ``min_steps``, a point with at least that many steps gets its own level instead.
    Returns (P,).
    """
    noise = np.full(len(steps_of), float(np.median(resid_norm)) / 0.455)
    if min_steps is not None:
        for j, own in enumerate(steps_of):
            if len(own) >= max(min_steps, 1):
                noise[j] = float(np.median(resid_norm[own])) / 0.455
    return noise


def _fit(hist: PhaseHistories, trajectory: Trajectory, config: Config, points0: Array, opts: AutofocusOptions,
         used0: NDArray[np.bool_] | None = None, scale0: float = 0.0,
         motion0: MotionCorrection | None = None, posterior: bool = True, point_noise: bool = False,
         grade_stretch: Array | None = None) -> ResidualMotion:
    """The fit of :func:`estimate_residual_motion` on gathered histories (a refused one: the scale's std infinite).
    ``used0``: the points to start from (default: all); ``scale0``: the scale to start from (its prior stays about 0);
    ``motion0``: the residual motion to start from (none: the track as it is); ``posterior``: whether to compute
    the correction's std (else NaN until ``with_posterior()``: a fit that may give only the scale and the points,
    or be replaced); ``point_noise``: each point's steps weighted by its own measured noise (else, or with fewer than
    ``opts.min_steps_own_noise`` steps, by all the used points' together); ``grade_stretch`` (F,): how much
    longer the radar's path along the road is than the planar track at each frame (:func:`grade_stretch`), by which
    each point's aperture is stretched about its centre (else none); ``opts``' scale prior set
    (:func:`with_scale_prior`)."""
    assert opts.prior_scale is not None
    n_pts = len(points0)
    t0 = int(trajectory.t_ns[0])
    n_nodes = int(math.ceil((int(trajectory.t_ns[-1]) - t0) / 1e9 / opts.node_s)) + 1
    nodes_ns = t0 + np.round(np.arange(n_nodes) * opts.node_s * 1e9).astype(np.int64)
    _, node_across, _ = frame_geometry(trajectory, nodes_ns, config)
    up = np.array([0.0, 0.0, 1.0])
    sigma_across = np.full(n_nodes, opts.prior_across_m)
    kappa = 4.0 * math.pi * hist.cycles_per_m
    # a correction the trajectory already carries is kept, and this one added to it
    carried = trajectory.correction
    base, base_std = ((carried.at(nodes_ns), carried.std_at(nodes_ns)) if carried is not None
                      else (np.zeros((n_nodes, 3)), np.zeros((n_nodes, 3))))
    # priors: the correction's size (the navigation's own uncertainty), its change between nodes, the point shifts
    prior_diag = np.concatenate([1.0 / sigma_across**2, np.full(n_nodes, 1.0 / opts.prior_up_m**2),
                                 np.full(3 * n_pts, 1.0 / opts.point_prior_m**2), [1.0 / opts.prior_scale**2]])
    diff = node_difference(n_nodes)
    smooth = sp.block_diag([diff / opts.step_across_m, diff / opts.step_up_m,
                            sp.csr_matrix((0, 3 * n_pts + 1))]).tocsc()
    prior_normal = (sp.diags(prior_diag) + smooth.T @ smooth).tocsc()

    shifts = slice(2 * n_nodes, 2 * n_nodes + 3 * n_pts)  # x: across, up per node; the point shifts; the scale
    centre = trajectory.rear_axle_enu.mean(axis=0)
    scale_lever = np.zeros((len(hist.frame_t_ns), 3))
    scale_lever[:, :2] = trajectory.pose(hist.frame_t_ns)[0] - centre

    # each point's mean time and scale lever over its pulses, for its range row
    counts = np.maximum(np.bincount(hist.point, minlength=n_pts), 1)
    t_mean = np.bincount(hist.point, (hist.frame_t_ns[hist.frame] - t0) / 1e9, n_pts) / counts
    lever_mean = np.stack([np.bincount(hist.point, scale_lever[hist.frame, k], n_pts) for k in range(3)], -1)
    lever_mean /= counts[:, None]
    # a road's grade lengthens the radar's path over each aperture, as a scale there does (sqrt(1 + m^2) - 1 for
    # slope m): the points' own, about their apertures' centres, not the track's
    stretch = (None if grade_stretch is None
               else np.bincount(hist.point, grade_stretch[hist.frame], n_pts) / counts)
    # the antennas move rigidly with the correction and the scale (a similarity about ``centre``): computed once
    tx0, rx0 = pair_antennas(hist, trajectory, config)
    if stretch is not None:  # it does not change with the fit's unknowns: into the antennas it starts from
        stretched = stretch[hist.point, None] * (scale_lever[hist.frame] - lever_mean[hist.point])
        tx0, rx0 = tx0 + stretched[:, None, :], rx0 + stretched[:, None, :]
    pos = np.clip((hist.frame_t_ns - t0) / 1e9 / opts.node_s, 0.0, n_nodes - 1.000001)
    f_node = np.floor(pos).astype(np.int64)
    f_frac = (pos - f_node)[:, None]

    active_cache: dict[bytes, tuple[PhaseHistories, Array, Array]] = {}

    def active(used: NDArray[np.bool_]) -> tuple[PhaseHistories, Array, Array]:
        """The histories and antennas of the used points' pulses only (a dropped point costs nothing more)."""
        key = used.tobytes()
        if key not in active_cache:
            h, keep = histories_of(hist, used)
            active_cache.clear()
            active_cache[key] = (h, tx0[keep], rx0[keep])
        return active_cache[key]

    def antennas(x: Array, h: PhaseHistories, tx_0: Array, rx_0: Array) -> tuple[Array, Array]:
        at_nodes = x[:n_nodes, None] * node_across + x[n_nodes:2 * n_nodes, None] * up
        moved = at_nodes[f_node] * (1.0 - f_frac) + at_nodes[f_node + 1] * f_frac + x[-1] * scale_lever
        d = moved[h.frame]
        return tx_0 + d[:, None, :], rx_0 + d[:, None, :]

    def presummed(x: Array, points: Array, used: NDArray[np.bool_]) -> _Samples:
        h, tx_0, rx_0 = active(used)
        z, los = focus_history(h, *antennas(x, h, tx_0, rx_0), points)
        return _presum(h, z, los, opts.presum, t0, scale_lever)

    r_pos = np.clip(t_mean / opts.node_s, 0.0, n_nodes - 1.000001)
    r_node = np.floor(r_pos).astype(np.int64)
    r_frac = r_pos - r_node

    def linearise(x: Array, used: NDArray[np.bool_], envelope_of: tuple[_Linear, Array] | None = None) -> _Linear:
        """The phase steps at ``x``, and the points' range rows: measured at ``x``, or, with ``envelope_of`` =
        (the linearisation at x - dx, dx), carried over linearly (the envelope changes slowly; measuring it costs
        as much as the phases)."""
        points = points0 + x[shifts].reshape(n_pts, 3)
        h, tx_0, rx_0 = active(used)
        tx, rx = antennas(x, h, tx_0, rx_0)
        z, los = focus_history(h, tx, rx, points)
        lin = _linearise(_presum(h, z, los, opts.presum, t0, scale_lever), used, node_across, opts.node_s,
                         kappa, n_pts)
        if envelope_of is not None:
            prev, dx = envelope_of
            lin.range_resid = prev.range_resid + prev.range_design @ dx
            lin.range_design = prev.range_design
            return lin
        offset, _, u = range_offsets(h, tx, rx, points, n_pts)
        q = np.flatnonzero(used & (np.bincount(h.point, minlength=n_pts) > 0))
        # the path is 2 u . (point - antenna): a point shift lengthens it, a correction towards it shortens it
        k_across = np.einsum("qk,qk->q", u[q], node_across[r_node[q]])
        cols = [2 * n_nodes + 3 * q + k for k in range(3)] + [r_node[q], r_node[q] + 1, n_nodes + r_node[q],
                                                                n_nodes + r_node[q] + 1, np.full(len(q), len(x) - 1)]
        vals = [-2.0 * u[q, k] for k in range(3)] + [
            2.0 * k_across * (1 - r_frac[q]), 2.0 * k_across * r_frac[q], 2.0 * u[q, 2] * (1 - r_frac[q]),
            2.0 * u[q, 2] * r_frac[q], 2.0 * np.einsum("qk,qk->q", u[q], lever_mean[q])]
        lin.range_resid = offset[q]
        lin.range_design = sp.csr_matrix((np.concatenate(vals), (np.tile(np.arange(len(q)), len(vals)),
                                                                 np.concatenate(cols))), shape=(len(q), len(x)))
        return lin

    def cost(lin: _Linear, x: Array, noise: Array, n_ref: int) -> float:
        """The fit's cost, its data term scaled to ``n_ref`` steps (a point's edge samples come and go with it);
        ``noise`` (P,) per point."""
        data = float(np.sum(lin.step**2 / (noise[lin.point] * lin.rel_var))) * n_ref / max(len(lin.step), 1)
        return data + float(np.sum(lin.range_resid**2)) / opts.range_sigma_m**2 + float(x @ (prior_normal @ x))

    x = np.zeros(2 * n_nodes + 3 * n_pts + 1)
    x[-1] = scale0
    if motion0 is not None:
        start = motion0.at(nodes_ns)
        x[:n_nodes] = np.einsum("nk,nk->n", start, node_across)
        x[n_nodes:2 * n_nodes] = start[:, 2]
    used = np.ones(n_pts, dtype=bool) if used0 is None else used0.copy()
    lin = linearise(x, used)
    # the noise power of a sample, until the fit measures it: 20 dB below the points' typical sample (the noise
    # another fit measured, kept, under-fitted points it had not seen: test1 seed 17 with a shaking radar case, a
    # corner reflector at 0.24 rad, 0.14 with its own)
    noise = np.full(n_pts, 0.01 / float(np.median(lin.rel_var)))
    iterations = 0
    for _ in range(4):  # fit; measure the noise and drop the points that do not fit; fit again
        damping = 1e-3
        current = cost(lin, x, noise, len(lin.step))
        for _ in range(opts.iterations):
            iterations += 1
            w = 1.0 / (noise[lin.point] * lin.rel_var)
            rd = lin.range_design
            normal = ((lin.design.T @ lin.design.multiply(w[:, None])) + (rd.T @ rd) / opts.range_sigma_m**2
                      ).tocsc() + prior_normal
            rhs = (-(lin.design.T @ (w * lin.step)) - (rd.T @ lin.range_resid) / opts.range_sigma_m**2
                   - prior_normal @ x)
            while damping < 1e6:  # Levenberg-Marquardt: a step that does not lower the cost is damped
                dx = factor_normal(normal + sp.diags(damping * normal.diagonal())).solve(rhs)
                trial = linearise(x + dx, used, (lin, dx))
                # a step that pushes a point's samples out of their range window loses data: not a better fit
                if (len(trial.step) >= 0.99 * len(lin.step)
                        and cost(trial, x + dx, noise, len(lin.step)) < current):
                    x, lin, damping = x + dx, trial, damping / 10.0
                    if np.max(np.abs(dx[shifts])) > 1e-3:  # a point moved by more than a mm: measure again
                        lin = linearise(x, used)
                    current = cost(lin, x, noise, len(lin.step))
                    break
                damping *= 10.0
            else:
                break
            # converged: the last step moved the correction by < 2 um, the points by < 50 um, the scale by < 2e-6
            if np.max(np.abs(dx[:2 * n_nodes])) < 2e-6 and np.max(np.abs(dx[shifts])) < 5e-5 and abs(dx[-1]) < 2e-6:
                break
        resid_norm = lin.step**2 / lin.rel_var
        # each point's steps, in their order (one sort, not a mask per point)
        order = np.argsort(lin.point, kind="stable")
        bounds = np.searchsorted(lin.point[order], np.arange(n_pts + 1))
        steps_of = [order[bounds[j]:bounds[j + 1]] for j in range(n_pts)]
        new_noise = np.maximum(_measured_noise(resid_norm, steps_of, opts.min_steps_own_noise if point_noise else None),
                               1e-12 * noise)
        phase_rms = np.array([float(np.sqrt(np.mean(lin.step[own] ** 2))) if len(own) else np.inf
                              for own in steps_of])
        bad = used & (phase_rms > opts.max_phase_rms_rad)
        # the weights' scale, not the fit, moves with the noise
        settled = bool(np.all(np.abs(new_noise[used] / noise[used] - 1.0) < 0.5))
        noise = new_noise
        if not bad.any() and settled:
            break
        used &= ~bad
        if used.sum() < opts.min_points:
            break
        x[shifts].reshape(n_pts, 3)[bad] = 0.0
        lin = linearise(x, used)
    points = points0 + x[shifts].reshape(n_pts, 3)
    cross = np.stack([x[:n_nodes], x[n_nodes:2 * n_nodes]], axis=-1)
    scale = float(x[-1]) if opts.prior_scale > 1e-9 else 0.0  # a prior that small holds the scale (the motion fit)
    # with the points where the fit puts them, so that only the track differs
    unchanged = np.zeros_like(x)
    unchanged[shifts] = x[shifts]
    coherence_before = _coherence(presummed(unchanged, points, used), used)
    coherence_after = _coherence(presummed(x, points, used), used)
    seen_frames = np.unique(hist.frame[used[hist.point]])
    coverage = len(seen_frames) / max(len(hist.frame_t_ns), 1)

    def refuse(reason: str) -> ResidualMotion:
        return ResidualMotion(trajectory, None, points0, used, phase_rms, coherence_before, coherence_after, coverage,
                              iterations, reason, hist.frame_t_ns[seen_frames], 0.0, math.inf)

    if used.sum() < opts.min_points:
        return refuse(f"{int(used.sum())} of the {n_pts} candidate points behave as stationary point scatterers "
                      f"(phase residual <= {opts.max_phase_rms_rad:g} rad); {opts.min_points} needed")
    if coherence_after <= coherence_before:
        return refuse(f"the correction does not sharpen its points (coherence {coherence_before:.3f} -> "
                      f"{coherence_after:.3f})")
    # the posterior at the solution, with the measured noise
    w = 1.0 / (noise[lin.point] * lin.rel_var)
    rd = lin.range_design
    lu = factor_normal((lin.design.T @ lin.design.multiply(w[:, None])) + (rd.T @ rd) / opts.range_sigma_m**2
                       + prior_normal)
    unit = np.zeros(len(x))
    unit[-1] = 1.0
    scale_std = float(np.sqrt(max(lu.solve(unit)[-1], 0.0)))
    scale_agreement = (_point_scale_chi2(lin, w, 2 * n_nodes, used, opts.point_prior_m) if opts.prior_scale > 1e-9
                       else (1.0, 0))
    measured = cross[:, :1] * node_across + cross[:, 1:] * up
    scaled = scale_track(trajectory, scale, centre) if scale else trajectory

    def finished(std: Array) -> ResidualMotion:
        std_enu = np.stack([np.abs(std[:, 0] * node_across[:, 0]), np.abs(std[:, 0] * node_across[:, 1]),
                            std[:, 1]], axis=-1)
        # the carried correction and this one are independent estimates: their sum's std adds in quadrature
        total = MotionCorrection(nodes_ns, base + measured, np.hypot(base_std, std_enu))
        return ResidualMotion(replace(scaled, correction=total), MotionCorrection(nodes_ns, measured, std_enu),
                              points, used, phase_rms, coherence_before, coherence_after, coverage, iterations, "",
                              hist.frame_t_ns[seen_frames], scale, scale_std, scale_agreement=scale_agreement,
                              grade_stretch=float(np.mean(stretch[used])) if stretch is not None else 0.0)

    if posterior:
        return finished(node_posterior_std(lu, n_nodes, 2))
    return replace(finished(np.full((n_nodes, 2), np.nan)),
                   with_posterior=lambda: finished(node_posterior_std(lu, n_nodes, 2)))


def _point_scale_chi2(lin: _Linear, w: Array, shift0: int, used: NDArray[np.bool_], point_prior_m: float
                      ) -> tuple[float, int]:
    """How well the used points agree on the track's scale: each point's own scale (its phase steps alone, its
    position shift free, the rest of the solution held) about the common one, as a reduced chi-square, and the
    number of points in it."""
    col_scale = lin.design.shape[1] - 1
    z2 = []
    for j in np.flatnonzero(used):
        rows = np.flatnonzero(lin.point == j)
        if len(rows) < 8:
            continue
        cols = [col_scale, shift0 + 3 * j, shift0 + 3 * j + 1, shift0 + 3 * j + 2]
        a = lin.design[rows][:, cols].toarray()
        wj = w[rows]
        normal = a.T @ (a * wj[:, None]) + np.diag([0.0, *(3 * [1.0 / point_prior_m**2])])
        try:
            cov = np.linalg.inv(normal)
        except np.linalg.LinAlgError:
            continue
        dx = cov @ (-(a.T @ (wj * lin.step[rows])))
        if cov[0, 0] > 0:
            z2.append(dx[0] ** 2 / cov[0, 0])
    return (float(np.mean(z2)), len(z2)) if z2 else (1.0, 0)
