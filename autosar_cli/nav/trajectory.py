"""What focus needs from a vehicle trajectory: body points, lever arms and radar phase centres.

:class:`Trajectory` itself (samples, CTRV pose between them, body points) lives in :mod:`autosar_cli.types`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from autosar_cli.config import Config
from autosar_cli.nav.frames import mounting_rotation
from autosar_cli.types import TRAVEL_HALF_SPAN_S, Trajectory

__all__ = ["TRAVEL_HALF_SPAN_S", "PhaseCentres", "Trajectory", "antenna_lever_arms", "centre_instant",
           "cumulative_travel", "gyro_bias_mean_std", "heading_ramp_displacement", "phase_centre_lever_arm",
           "radar_phase_centres", "radar_track", "rear_axle_from_body_point", "relative_pose_error",
           "track_scale_std", "wheel_scale_mean_std", "yaw_rate_bias_std"]

Array = NDArray[np.float64]


def rear_axle_from_body_point(point_xy: Array, heading: Array, lever_arm: ArrayLike,
                              cog_to_rear_axle_m: float) -> Array:
    """Rear-axle centre ENU (M, 2) (m) of a level vehicle whose body point ``lever_arm`` (x forward, y left, m,
    from the CoG) is at ENU ``point_xy`` (M, 2) (m) with ``heading`` (M,) (rad, ENU): the inverse of
    :meth:`Trajectory.body_points` in the horizontal plane."""
    lever = np.asarray(lever_arm, dtype=np.float64)
    lx = lever[0] + cog_to_rear_axle_m
    c, s = np.cos(heading), np.sin(heading)
    return np.asarray(point_xy, dtype=np.float64)[:, :2] - np.stack([c * lx - s * lever[1], s * lx + c * lever[1]],
                                                                     axis=1)


@dataclass(frozen=True)
class PhaseCentres:
    """Antenna positions of every chirp (ENU, m): Tx k at its own chirp start, Rx at the same instant."""

    tx: Array  #: (F, T, 3): Tx k of frame f
    rx: Array  #: (F, T, R, 3): Rx r while Tx k of frame f transmits
    t_ns: NDArray[np.int64]  #: (F, T) chirp start times


def antenna_lever_arms(config: Config) -> tuple[Array, Array]:
    """Tx (T, 3) and Rx (R, 3) phase centres in the body frame (m from the CoG): mounting + antenna layout."""
    r = config.radar
    rot = mounting_rotation(r.mounting.yaw_deg, r.mounting.pitch_deg, r.mounting.roll_deg)
    lever = np.asarray(r.mounting.lever_arm_m, dtype=np.float64)
    return lever + np.asarray(r.tx_positions_m) @ rot.T, lever + np.asarray(r.rx_positions_m) @ rot.T


def with_mounting_yaw(config: Config, yaw_deg: float) -> Config:
    """``config`` with the radar's boresight at ``yaw_deg`` (deg, ``radar.mounting.yaw_deg``'s convention)."""
    return replace(config, radar=replace(config.radar, mounting=replace(config.radar.mounting, yaw_deg=yaw_deg)))


def measured_mounting(config: Config, trajectory: Trajectory) -> Config:
    """``config`` with the radar's boresight that ``trajectory``'s autofocus measured on its points, where it took
    one (its ``info["radar_mounting_yaw_deg"]``, :mod:`autosar_cli.sar.residual_motion`), else ``config``."""
    yaw = trajectory.info.get("radar_mounting_yaw_deg")
    return config if yaw is None else with_mounting_yaw(config, float(yaw))


def radar_side(config: Config) -> float:
    """The side the radar looks to, +1 left of the car's x-axis (mounting yaw in (0, 180) deg), -1 right: the
    one definition of the looking side for the grid, the beam and the reflectors' expected positions."""
    return 1.0 if math.sin(math.radians(config.radar.mounting.yaw_deg)) > 0 else -1.0


def phase_centre_lever_arm(config: Config) -> Array:
    """Body-frame lever arm (3,) (m from the CoG) of the radar's mean phase centre: the mean of Tx and Rx means."""
    tx, rx = antenna_lever_arms(config)
    return 0.5 * (tx.mean(axis=0) + rx.mean(axis=0))


def radar_track(trajectory: Trajectory, frame_t_ns: NDArray[np.int64], config: Config) -> Array:
    """Horizontal ENU track (M, 2) (m) of the radar's mean phase centre at the radar frame times ``frame_t_ns``
    (ns) within ``trajectory``'s span."""
    t = frame_t_ns[(frame_t_ns >= trajectory.t_ns[0]) & (frame_t_ns <= trajectory.t_ns[-1])]
    return trajectory.body_points(t, phase_centre_lever_arm(config)[None])[:, 0, :2]


def reference_track(traj: Trajectory, t_ns: NDArray[np.int64], config: Config) -> tuple[Array, Array]:
    """Tx0 reference point (M, 3) and its direction of travel (M, 3), as focus points its beam
    (:meth:`Trajectory.travel_velocity`)."""
    tx0 = antenna_lever_arms(config)[0][:1]
    return traj.body_points(t_ns, tx0)[:, 0], traj.travel_velocity(t_ns, tx0)[:, 0]


def zero_doppler_times(traj: Trajectory, points_enu: ArrayLike, config: Config, t_ns: ArrayLike
                       ) -> NDArray[np.int64]:
    """For each point (C, 3) (ENU m), the instant (ns) the radar reference (Tx0) of ``traj`` passes it: the point
    lies perpendicular to the reference's velocity (the centre of its processed aperture). ``t_ns``: candidate
    instants (the radar frame times), interpolated between; the closest one when the point is never passed."""
    true = np.asarray(points_enu, dtype=np.float64).reshape(-1, 3)
    t = np.asarray(t_ns, dtype=np.int64)
    c, v = reference_track(traj, t, config)
    out = np.empty(len(true), np.int64)
    for i, p in enumerate(true):
        f = np.sum((p[:2] - c[:, :2]) * v[:, :2], axis=1)  # > 0 while the target is ahead
        k = np.flatnonzero((f[:-1] > 0) & (f[1:] <= 0))
        if k.size == 0:
            out[i] = t[int(np.argmin(np.abs(f)))]
            continue
        k0 = k[np.argmin(np.linalg.norm(p[:2] - c[k, :2], axis=1))]
        w = f[k0] / (f[k0] - f[k0 + 1])
        out[i] = t[k0] + int(round(w * (t[k0 + 1] - t[k0])))
    return out


def radar_phase_centres(traj: Trajectory, frame_t_ns: ArrayLike, tx_start_offsets_s: ArrayLike,
                        config: Config) -> PhaseCentres:
    """Tx/Rx phase centres of every chirp from the trajectory, the mounting and the antenna layout.

    ``frame_t_ns`` (F,): start of each PRI; ``tx_start_offsets_s`` (T,): chirp start of Tx k in the PRI
    (TDM chirps 60 µs apart move the antennas ~0.4 mm at 7 m/s: a tenth of a wavelength).
    """
    tx_levers, rx_levers = antenna_lever_arms(config)
    frame_t_ns = np.asarray(frame_t_ns, dtype=np.int64)
    offsets_ns = np.round(np.asarray(tx_start_offsets_s, dtype=np.float64) * 1e9).astype(np.int64)
    t = frame_t_ns[:, None] + offsets_ns[None, :]  # (F, T)
    flat = t.ravel()
    T = len(offsets_ns)
    tx_all = traj.body_points(flat, tx_levers).reshape(len(frame_t_ns), T, T, 3)
    tx = tx_all[:, np.arange(T), np.arange(T)]  # Tx k at its own chirp time
    rx = traj.body_points(flat, rx_levers).reshape(len(frame_t_ns), T, len(rx_levers), 3)
    return PhaseCentres(tx, rx, t)


def cumulative_travel(points: ArrayLike) -> Array:
    """Distance (N,) (m) travelled along the polyline ``points`` (N, D) (m, any frame) up to each point: 0 at
    the first point, then the running sum of the straight steps between consecutive points."""
    p = np.asarray(points, dtype=np.float64)
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=-1))])


def relative_pose_error(est_xy: Array, est_heading: Array, ref_xy: Array, ref_heading: Array,
                        delta_m: float) -> Array:
    """SE(2) relative pose error like ``evo_rpe --delta D --delta_unit m``: (P, 2) [along, across] errors (m).

    For every pose i and the first pose j at least ``delta_m`` of (reference) travel later, the estimated
    displacement expressed in the estimated pose i frame minus the reference one in the reference frame.
    A rigid offset or rotation of the whole estimate gives zero.
    """
    dist = cumulative_travel(ref_xy)
    j = np.searchsorted(dist, dist + delta_m)
    i = np.flatnonzero(j < len(dist))
    j = j[i]

    def local(xy: Array, psi: Array) -> Array:
        d = xy[j] - xy[i]
        c, s = np.cos(psi[i]), np.sin(psi[i])
        return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)

    return local(est_xy, est_heading) - local(ref_xy, ref_heading)


def _mean_std(P: Array, state_names: list[str], member: Callable[[str], bool]) -> float | None:
    """The std of the mean of the states ``member`` picks from a covariance ``P`` (n, n) over ``state_names``; None
    where it picks none."""
    idx = [i for i, name in enumerate(state_names) if member(name)]
    if not idx:
        return None
    return float(np.sqrt(max(P[np.ix_(idx, idx)].sum(), 0.0))) / len(idx)


def _mid_drive(trajectory: Trajectory) -> Array | None:
    """The trajectory's covariance (n, n) in the middle of the drive; None where it has none."""
    if trajectory.covariance is None or len(trajectory.covariance) == 0:
        return None
    return trajectory.covariance[len(trajectory.covariance) // 2]


def wheel_scale_mean_std(P: Array, state_names: list[str]) -> float | None:
    """The std of the four wheel scales' mean (``scale.wheel_*``) from a covariance ``P`` (n, n) over
    ``state_names``: a common error s in them is a speed, and so a track, scaled by -s. None without them."""
    return _mean_std(P, state_names, lambda name: name.startswith("scale.wheel_"))


def track_scale_std(trajectory: Trajectory) -> float | None:
    """The navigation's own std of the track's along-track scale (dimensionless): the wheel scales' mean's
    (:func:`wheel_scale_mean_std`) in the middle of the drive, from the trajectory's covariance. None where the
    trajectory has no covariance or no wheel-scale states."""
    P = _mid_drive(trajectory)
    return None if P is None else wheel_scale_mean_std(P, trajectory.state_names)


def gyro_bias_mean_std(P: Array, state_names: list[str]) -> float | None:
    """The std (rad/s) of the gyros' biases' mean (``bias.<gyro>``; the steering's offset is no gyro) from a
    covariance ``P`` (n, n) over ``state_names``: a common error in them is one in the yaw rate the track turns by.
    None without them."""
    return _mean_std(P, state_names, lambda name: name.startswith("bias.") and name != "bias.steering")


def yaw_rate_bias_std(trajectory: Trajectory) -> float | None:
    """The navigation's own std (rad/s) of its yaw rate's slow error: the gyros' biases' mean
    (:func:`gyro_bias_mean_std`) in the middle of the drive. None where the trajectory has no covariance or no
    gyro-bias states."""
    P = _mid_drive(trajectory)
    return None if P is None else gyro_bias_mean_std(P, trajectory.state_names)


def centre_instant(trajectory: Trajectory) -> int:
    """The instant (ns) at which the rear axle is nearest its track's centroid."""
    xy = trajectory.rear_axle_enu
    return int(trajectory.t_ns[np.argmin(np.linalg.norm(xy - xy.mean(axis=0), axis=1))])


def heading_ramp_displacement(trajectory: Trajectory, t_ns: ArrayLike, t_ref_ns: int, config: Config) -> Array:
    """How far (N, 2) (ENU m) a yaw-rate error of 1 rad/s from ``t_ref_ns`` on moves the radar's mean phase centre
    at ``t_ns`` (N,) (ns): the heading is off by ``t - t_ref`` (s), so each step of the rear axle turns by it, and
    so does the lever arm. A track built on a yaw rate ``b`` too high is bent by ``b`` times this."""
    t_s = (trajectory.t_ns - t_ref_ns) / 1e9
    step = np.diff(trajectory.rear_axle_enu, axis=0)
    turned = 0.5 * (t_s[1:] + t_s[:-1])[:, None] * np.stack([-step[:, 1], step[:, 0]], axis=1)
    moved = np.vstack([np.zeros((1, 2)), np.cumsum(turned, axis=0)])
    moved -= moved[np.argmin(np.abs(trajectory.t_ns - t_ref_ns))]
    t = np.asarray(t_ns, dtype=np.int64)
    axle = np.stack([np.interp(t, trajectory.t_ns, trajectory.rear_axle_enu[:, k]) for k in range(2)], axis=1)
    lever = trajectory.body_points(t, phase_centre_lever_arm(config)[None])[:, 0, :2] - axle
    return (np.stack([np.interp(t, trajectory.t_ns, moved[:, k]) for k in range(2)], axis=1)
            + ((t - t_ref_ns) / 1e9)[:, None] * np.stack([-lever[:, 1], lever[:, 0]], axis=1))
