"""Estimated vehicle trajectories and what focus needs from them: body points and radar phase centres.

A :class:`Trajectory` holds the rear-axle centre, heading, speed and yaw rate at its sample times.
Between samples the vehicle follows CTRV from the preceding sample (exact for the filter's own model,
and the samples are milliseconds apart). Body points are given relative to the CoG (ISO 8855 body
frame); the CoG lies ``cog_to_rear_axle_m`` ahead of the rear axle and ``cog_height_m`` above the road
(ENU z = 0 is the road surface at the origin).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from autosar_cli.config import Config
from autosar_cli.nav.frames import mounting_rotation
from autosar_cli.nav.geodesy import GeodeticOrigin

Array = NDArray[np.float64]

#: half-span (s) of :meth:`Trajectory.travel_velocity`'s average: of the order of the processed apertures
#: (5-130 ms at 4 cm resolution and 5 m/s), long enough to smooth a filter's sample-to-sample jitter
TRAVEL_HALF_SPAN_S = 0.05


@dataclass
class Trajectory:
    method: str
    t_ns: NDArray[np.int64]  #: (K,) sample times, ns since the Unix epoch, strictly increasing
    rear_axle_enu: Array  #: (K, 2) m
    heading: Array  #: (K,) rad, ENU (from East, CCW), unwrapped
    speed: Array  #: (K,) m/s of the rear-axle centre
    yaw_rate: Array  #: (K,) rad/s
    origin: GeodeticOrigin
    cog_to_rear_axle_m: float
    cog_height_m: float
    state: Array | None = None  #: (K, n) full filter state (method sar-min)
    state_names: list[str] = field(default_factory=list)
    covariance: Array | None = None  #: (K, n, n)
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def t(self) -> Array:
        """Seconds since the first sample."""
        return (self.t_ns - self.t_ns[0]) / 1e9

    @property
    def cog_enu(self) -> Array:
        """(K, 3) ENU position of the CoG (body-frame origin)."""
        return self.body_points(self.t_ns, np.zeros((1, 3)))[:, 0]

    def pose(self, t_ns: ArrayLike) -> tuple[Array, Array]:
        """Rear-axle ENU (M, 2) and heading (M,) at arbitrary times, by CTRV from the preceding sample."""
        t_ns = np.asarray(t_ns, dtype=np.int64)
        return self._pose_from(self._segment(t_ns), t_ns)

    def _segment(self, t_ns: NDArray[np.int64]) -> NDArray[np.intp]:
        """Index of the sample each time propagates from (the preceding one; the first before the start)."""
        return np.clip(np.searchsorted(self.t_ns, t_ns, side="right") - 1, 0, len(self.t_ns) - 1)

    def _pose_from(self, k: NDArray[np.intp], t_ns: NDArray[np.int64]) -> tuple[Array, Array]:
        dt = (t_ns - self.t_ns[k]) / 1e9
        v, psi, w = self.speed[k], self.heading[k], self.yaw_rate[k]
        half = 0.5 * w * dt
        chord = v * dt * np.sinc(half / np.pi)
        xy = self.rear_axle_enu[k] + np.stack([chord * np.cos(psi + half), chord * np.sin(psi + half)], axis=-1)
        return xy, psi + w * dt

    def body_points(self, t_ns: ArrayLike, lever_arms: ArrayLike) -> Array:
        """ENU positions (M, A, 3) of body points ``lever_arms`` (A, 3) (m, from the CoG) at times ``t_ns`` (M,)."""
        return self._place(*self.pose(t_ns), lever_arms)

    def travel_velocity(self, t_ns: ArrayLike, lever_arms: ArrayLike,
                        half_span_s: float = TRAVEL_HALF_SPAN_S) -> Array:
        """Velocity (M, A, 3) (ENU m/s) of body points ``lever_arms`` (A, 3) (m, from the CoG) averaged over
        ``t_ns`` (M,) +- ``half_span_s``, clamped to the trajectory's span: the direction a synthetic aperture
        travels, along which focus's stripmap beam is pointed.

        The average is that of the trajectory's own motion (speed, heading, yaw rate: the CTRV segments
        between samples joined end to end), not a difference of its positions, so the steps between
        samples (a filter's updates, an INS's GNSS resets) do not tilt it. A 1 ms difference of SAR-MIN's
        positions on test1 jittered by 1.1 mrad RMS (4.5 mrad at most, against a processed half-beam of
        12 mrad); this average over +-50 ms by 0.09 mrad, and an INS's by 0.2 mrad where its 1 ms position
        differences jittered by 129 mrad (measured 2026-11-22, docs/FOCUS.md).
        """
        t_ns = np.asarray(t_ns, dtype=np.int64)
        h = int(round(half_span_s * 1e9))
        t_a = np.clip(t_ns - h, self.t_ns[0], self.t_ns[-1])
        t_b = np.clip(t_ns + h, self.t_ns[0], self.t_ns[-1])
        t_b = np.maximum(t_b, t_a + 1)  # a single sample, or a time beyond the span: the motion there (1 ns)
        lever = np.asarray(lever_arms, dtype=np.float64).reshape(-1, 3)
        # each segment's displacement under its own motion model, summed: the continuous path at every sample
        samples = self._place(self.rear_axle_enu, self.heading, lever)
        ends = self._place(*self._pose_from(np.arange(len(self.t_ns) - 1), self.t_ns[1:]), lever)
        at_sample = np.concatenate([np.zeros((1, *samples.shape[1:])), np.cumsum(ends - samples[:-1], axis=0)])

        def path(t: NDArray[np.int64]) -> Array:
            k = self._segment(t)
            return at_sample[k] + self._place(*self._pose_from(k, t), lever) - samples[k]

        return (path(t_b) - path(t_a)) / ((t_b - t_a) * 1e-9)[:, None, None]

    def _place(self, xy: Array, psi: Array, lever_arms: ArrayLike) -> Array:
        """Body points (M, A, 3) of rear-axle positions xy (M, 2) and headings psi (M,)."""
        lever = np.asarray(lever_arms, dtype=np.float64).reshape(-1, 3)
        lx = lever[:, 0] + self.cog_to_rear_axle_m
        c, s = np.cos(psi)[:, None], np.sin(psi)[:, None]
        x = xy[:, :1] + c * lx - s * lever[:, 1]
        y = xy[:, 1:] + s * lx + c * lever[:, 1]
        z = np.broadcast_to(self.cog_height_m + lever[:, 2], x.shape)
        return np.stack([x, y, z], axis=-1)


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


def phase_centre_lever_arm(config: Config) -> Array:
    """Body-frame lever arm (3,) (m from the CoG) of the radar's mean phase centre: the mean of Tx and Rx means."""
    tx, rx = antenna_lever_arms(config)
    return 0.5 * (tx.mean(axis=0) + rx.mean(axis=0))


def radar_track(trajectory: Trajectory, frame_t_ns: NDArray[np.int64], config: Config) -> Array:
    """Horizontal ENU track (M, 2) (m) of the radar's mean phase centre at the radar frame times ``frame_t_ns``
    (ns) within ``trajectory``'s span."""
    t = frame_t_ns[(frame_t_ns >= trajectory.t_ns[0]) & (frame_t_ns <= trajectory.t_ns[-1])]
    return trajectory.body_points(t, phase_centre_lever_arm(config)[None])[:, 0, :2]


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


def relative_pose_error(est_xy: Array, est_heading: Array, ref_xy: Array, ref_heading: Array,
                        delta_m: float) -> Array:
    """SE(2) relative pose error like ``evo_rpe --delta D --delta_unit m``: (P, 2) [along, across] errors (m).

    For every pose i and the first pose j at least ``delta_m`` of (reference) travel later, the estimated
    displacement expressed in the estimated pose i frame minus the reference one in the reference frame.
    A rigid offset or rotation of the whole estimate gives zero.
    """
    dist = np.r_[0.0, np.cumsum(np.hypot(*np.diff(ref_xy, axis=0).T))]
    j = np.searchsorted(dist, dist + delta_m)
    i = np.flatnonzero(j < len(dist))
    j = j[i]

    def local(xy: Array, psi: Array) -> Array:
        d = xy[j] - xy[i]
        c, s = np.cos(psi[i]), np.sin(psi[i])
        return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)

    return local(est_xy, est_heading) - local(ref_xy, ref_heading)

