"""Trajectory accuracy against the truth: absolute error, relative pose error, rigid SE(2) alignment.

Everything is evaluated at common instants (normally the radar frame times, so each frame counts once)
at the radar's mean antenna phase centre (the point whose motion shapes the image), in the local ENU
frame of the estimate. Errors are split into along-track and across-track components in the frame of
the true heading (across positive to the left of the direction of travel).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from autosar_cli.config import Config
from autosar_cli.evaluate.alignment import Se2, fit_se2, fit_similarity_scale
from autosar_cli.nav.trajectory import Trajectory, cumulative_travel, radar_track, relative_pose_error

Array = NDArray[np.float64]

#: Travel distances (m) of the relative pose error, as ``evo_rpe --delta D --delta_unit m``.
RPE_DELTAS_M = (1.0, 10.0)


@dataclass
class TrajectoryErrors:
    """Time series of an estimate's errors at common instants (arrays of length M)."""

    method: str
    t_ns: NDArray[np.int64]  #: instants, ns since the Unix epoch
    distance_m: Array  #: true travel of the phase centre since the first instant, m
    est_xy: Array  #: (M, 2) estimated phase centre, ENU m
    ref_xy: Array  #: (M, 2) true phase centre, ENU m
    ref_heading: Array  #: (M,) true heading of the body, rad (ENU, from East CCW)
    error_along: Array  #: estimate - truth, along the true heading, m
    error_across: Array  #: estimate - truth, across (left positive), m
    alignment: Se2  #: maps estimated positions onto the truth (least squares over all instants)
    aligned_along: Array  #: T(estimate) - truth, along, m
    aligned_across: Array  #: T(estimate) - truth, across, m

    @property
    def t_s(self) -> Array:
        return (self.t_ns - self.t_ns[0]) / 1e9


@dataclass(frozen=True)
class TrajectoryMetrics:
    """Summary of :class:`TrajectoryErrors` (metres unless the name says otherwise)."""

    method: str
    samples: int
    duration_s: float
    distance_m: float
    abs_rmse_m: float  #: horizontal RMSE, time-matched, no alignment
    abs_max_m: float
    abs_rmse_along_m: float
    abs_rmse_across_m: float
    rpe_1m_along_m: float  #: RMS relative pose error over 1 m of travel, along-track component
    rpe_1m_across_m: float
    rpe_10m_along_m: float
    rpe_10m_across_m: float
    alignment_angle_deg: float  #: rotation of the SE(2) alignment (estimate -> truth)
    alignment_translation_m: tuple[float, float]  #: its translation (ENU x, y)
    aligned_rmse_m: float  #: horizontal RMSE after the alignment
    aligned_rmse_across_m: float
    aligned_max_m: float
    #: the absolute error over the std the trajectory states for its position, RMS (:func:`stated_position_z`;
    #: 1 where that std is right, NaN where it states none)
    position_z_along_rms: float = math.nan
    position_z_across_rms: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _rms(x: Array) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else math.nan


def _along_across(d: Array, heading: Array) -> tuple[Array, Array]:
    c, s = np.cos(heading), np.sin(heading)
    return c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]


def common_instants(est: Trajectory, ref: Trajectory, t_ns: ArrayLike | None = None, *,
                    min_speed_mps: float = 0.2, rate_hz: float = 100.0) -> NDArray[np.int64]:
    """Instants inside both trajectories' spans where the truth moves at ``min_speed_mps`` or more.

    ``t_ns``: candidate instants (e.g. the radar frame times); default: a uniform ``rate_hz`` grid.
    """
    lo, hi = max(est.t_ns[0], ref.t_ns[0]), min(est.t_ns[-1], ref.t_ns[-1])
    if hi <= lo:
        raise ValueError(f"the {est.method} and {ref.method} trajectories do not overlap in time")
    if t_ns is None:
        t = np.arange(lo, hi, int(1e9 / rate_hz), dtype=np.int64)
    else:
        t = np.asarray(t_ns, dtype=np.int64)
        t = t[(t >= lo) & (t <= hi)]
    speed = np.interp(t, ref.t_ns, ref.speed)
    t = t[speed >= min_speed_mps]
    if len(t) < 2:
        raise ValueError(f"the {est.method} and truth trajectories share fewer than two moving instants")
    return t


def radar_track_scale(est: Trajectory, ref: Trajectory, frame_t_ns: ArrayLike, config: Config) -> float:
    """Scale of the similarity mapping ``est``'s radar phase-centre track onto ``ref``'s, less 1, over the radar
    frame times ``frame_t_ns`` (ns) where both move (:func:`common_instants`). Below 0 ``est``'s track is too long;
    its reflectors are then displaced by about the scale times their along-track distance from the track's centre,
    which no rigid alignment removes. The autofocus's scale (``ResidualMotion.scale``) estimates it without ``ref``."""
    t = common_instants(est, ref, frame_t_ns)
    return fit_similarity_scale(radar_track(est, t, config), radar_track(ref, t, config)) - 1.0


def trajectory_errors(est: Trajectory, ref: Trajectory, lever_arm: ArrayLike, t_ns: ArrayLike) -> TrajectoryErrors:
    """Errors of ``est`` against ``ref`` (same ENU frame) at instants ``t_ns`` for the body point ``lever_arm``."""
    t = np.asarray(t_ns, dtype=np.int64)
    lever = np.asarray(lever_arm, dtype=np.float64).reshape(1, 3)
    est_xy = est.body_points(t, lever)[:, 0, :2]
    ref_xy = ref.body_points(t, lever)[:, 0, :2]
    ref_psi = ref.body_heading(t)
    dist = cumulative_travel(ref_xy)
    along, across = _along_across(est_xy - ref_xy, ref_psi)
    align = fit_se2(est_xy, ref_xy)
    a_along, a_across = _along_across(align.apply(est_xy) - ref_xy, ref_psi)
    return TrajectoryErrors(est.method, t, dist, est_xy, ref_xy, ref_psi, along, across, align, a_along, a_across)


def stated_position_z(est: Trajectory, errors: TrajectoryErrors) -> tuple[Array, Array] | None:
    """``errors``' absolute error along and across (M,) each over the std ``est`` states for its position there:
    its filter's covariance of the rear axle's position (px, py) at the preceding sample and, in quadrature, its
    correction's ``std_enu``. None where ``est`` carries no such covariance."""
    names = est.state_names
    if est.covariance is None or not {"px", "py"} <= set(names):
        return None
    t = errors.t_ns
    k = np.clip(np.searchsorted(est.t_ns, t, side="right") - 1, 0, len(est.t_ns) - 1)
    i = [names.index("px"), names.index("py")]
    cov = est.covariance[k][:, i][:, :, i]
    if est.correction is not None:
        std = est.correction.std_at(t)[:, :2]
        cov = cov + np.einsum("mi,ij->mij", std**2, np.eye(2))
    c, s = np.cos(errors.ref_heading), np.sin(errors.ref_heading)
    along, across = np.stack([c, s], axis=1), np.stack([-s, c], axis=1)

    def std(u: Array) -> Array:
        return np.sqrt(np.einsum("mi,mij,mj->m", u, cov, u))

    return errors.error_along / std(along), errors.error_across / std(across)


def trajectory_metrics(est: Trajectory, errors: TrajectoryErrors,
                       deltas_m: tuple[float, float] = RPE_DELTAS_M) -> TrajectoryMetrics:
    """Summarise ``errors`` and add the relative pose error over ``deltas_m`` (1 m and 10 m) of true travel.

    The RPE is computed on SE(2) poses (phase-centre position, the body's heading) at the same instants: the
    estimate's body heading is its course plus the rear tyres' slip where it models one, as the truth's is the body's.
    """
    t = errors.t_ns
    est_psi = est.body_heading(t)
    rpe: dict[float, tuple[float, float]] = {}
    for d in deltas_m:
        err = relative_pose_error(errors.est_xy, est_psi, errors.ref_xy, errors.ref_heading, d)
        rpe[d] = (_rms(err[:, 0]), _rms(err[:, 1])) if len(err) else (math.nan, math.nan)
    abs_err = np.hypot(errors.error_along, errors.error_across)
    aligned = np.hypot(errors.aligned_along, errors.aligned_across)
    d1, d10 = deltas_m
    z = stated_position_z(est, errors)
    return TrajectoryMetrics(
        method=est.method, samples=int(len(t)), duration_s=float((t[-1] - t[0]) / 1e9),
        distance_m=float(errors.distance_m[-1]), abs_rmse_m=_rms(abs_err), abs_max_m=float(abs_err.max()),
        abs_rmse_along_m=_rms(errors.error_along), abs_rmse_across_m=_rms(errors.error_across),
        rpe_1m_along_m=rpe[d1][0], rpe_1m_across_m=rpe[d1][1], rpe_10m_along_m=rpe[d10][0],
        rpe_10m_across_m=rpe[d10][1], alignment_angle_deg=math.degrees(errors.alignment.angle_rad),
        alignment_translation_m=errors.alignment.translation, aligned_rmse_m=_rms(aligned),
        aligned_rmse_across_m=_rms(errors.aligned_across), aligned_max_m=float(aligned.max()),
        position_z_along_rms=_rms(z[0]) if z is not None else math.nan,
        position_z_across_rms=_rms(z[1]) if z is not None else math.nan)


#: Half-length (m of true travel) of the track the local alignment of a reflector is fitted on.
LOCAL_HALF_SPAN_M = 5.0


def local_alignments(errors: TrajectoryErrors, t0_ns: ArrayLike, half_span_m: float = LOCAL_HALF_SPAN_M) -> list[Se2]:
    """For each instant t0 (e.g. when the radar passes a reflector), the rigid SE(2) motion estimate -> truth
    fitted only on the instants within ``half_span_m`` of true travel of t0 (10 m of track by default, the
    scale of the 10 m relative pose error). It removes the slowly varying (GNSS-driven) part of the error that
    a whole-track alignment leaves on a long drive, keeping what deforms the image around the reflector."""
    out = []
    for t0 in np.atleast_1d(np.asarray(t0_ns, dtype=np.int64)):
        s0 = float(np.interp(t0, errors.t_ns, errors.distance_m))
        sel = np.abs(errors.distance_m - s0) <= half_span_m
        out.append(fit_se2(errors.est_xy[sel], errors.ref_xy[sel]) if sel.sum() >= 2 else errors.alignment)
    return out
