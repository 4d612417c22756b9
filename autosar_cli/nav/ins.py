"""INS baseline (paper Sec. II-A, the "commercial INS"): 3-D strapdown navigation driven by the
radar-mounted IMU, corrected by its own GNSS with a loosely coupled error-state Kalman filter.

Like the real unit it is a causal filter (no smoother): between GNSS fixes the position follows the
IMU, whose residual biases make it drift, and every fix pulls it back, giving the sawtooth of the
paper's Fig. 11. Flat-earth ENU mechanization (no Earth rotation or transport rate: over a drive of
a few hundred metres they are below the IMU's own errors).

Error state (15): position, velocity (ENU), attitude error (ENU small angles), accelerometer bias,
gyro bias (body frame).

The output is the common trajectory model (rear-axle centre, no sideslip): its heading is the course of the
rear axle, derived from the INS's velocity and yaw rate (:func:`rear_axle_motion`), not the INS's yaw, so
that the motion the trajectory describes is the motion the INS measured.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from autosar_cli.config import Config
from autosar_cli.nav.frames import wrap_angle
from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.nav.inputs import (
    NavInputError,
    read_imu,
    receiver_streams,
    streams_held,
    velocities_with_fixes,
    velocity_frame_checked,
    with_altitudes,
    without_repeated_samples,
)
from autosar_cli.nav.trajectory import Trajectory, rear_axle_from_body_point
from autosar_cli.store.drive import Drive

Array = NDArray[np.float64]
GRAVITY = np.array([0.0, 0.0, -9.80665])


def _skew(v: Array) -> Array:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _rotation(rotvec: Array) -> Array:
    """Rotation matrix of a rotation vector (Rodrigues)."""
    a = float(np.linalg.norm(rotvec))
    K = _skew(rotvec)
    if a < 1e-12:
        return np.eye(3) + K
    return np.eye(3) + np.sin(a) / a * K + (1.0 - np.cos(a)) / a**2 * K @ K


@dataclass
class InsInputs:
    t0_ns: int
    origin: GeodeticOrigin
    imu_t: Array  # (N,) s
    gyro: Array  # (N, 3) rad/s, body axes
    accel: Array  # (N, 3) m/s^2 specific force, body axes
    gnss_t: Array
    gnss_pos: Array  # (M, 3) ENU of the antenna
    vel_t: Array
    gnss_vel: Array  # (M', 3) ENU
    imu_lever: Array  # (3,) body frame, from the CoG
    gnss_lever: Array  # (3,) body frame, from the CoG
    warnings: list[str] = field(default_factory=list)  # what its receiver's velocity got wrong, one line each


def load_ins_inputs(drive: Drive, config: Config, origin: GeodeticOrigin, t0_ns: int) -> InsInputs:
    nav = config.navigation
    imu_cfg, gnss_cfg = config.sensors.get(nav.ins_imu), config.sensors.get(nav.ins_gnss)
    if imu_cfg is None or gnss_cfg is None:
        raise NavInputError(f"navigation.ins_imu / ins_gnss ({nav.ins_imu}, {nav.ins_gnss}) are not configured sensors")
    if nav.ins_imu not in drive.imu_sources():
        raise NavInputError(f"{drive.path}: the INS baseline needs imu/{nav.ins_imu} (config navigation.ins_imu); "
                            f"{streams_held(drive, 'imu')}")
    streams = receiver_streams(drive, nav.ins_gnss, "navigation.ins_gnss", gnss_cfg.latency_s)
    imu, repeated = without_repeated_samples(read_imu(drive, nav.ins_imu, config), f"imu/{nav.ins_imu}")
    if streams.velocity is None:
        raise NavInputError(f"{drive.path}: the INS baseline needs the GNSS velocity gnss/{nav.ins_gnss}/velocity, "
                            "which the receiver did not log (its fixes alone: --method sar-min or gnss)")
    fix, _ = with_altitudes(streams.fix, streams.fix_stream)
    vel = streams.velocity
    if np.isnan(imu["angular_velocity"]).any() or np.isnan(imu["linear_acceleration"]).any():
        raise NavInputError(f"{drive.path}: imu/{nav.ins_imu} is not a 6-DoF IMU")

    def rel(t: Array, latency: float) -> Array:
        return (np.asarray(t, dtype=np.int64) - t0_ns) / 1e9 - latency

    enu = origin.to_enu(fix["latitude_deg"], fix["longitude_deg"], fix["altitude_m"])
    stream = streams.velocity_stream
    vel, unfixed = velocities_with_fixes(fix["t_ns"], vel, stream)
    velocity, frame = velocity_frame_checked(rel(fix["t_ns"], 0.0), enu[:, :2], rel(vel["t_ns"], 0.0),
                                             np.asarray(vel["velocity_enu"], dtype=np.float64), stream)
    return InsInputs(t0_ns, origin, rel(imu["t_ns"], imu_cfg.latency_s), imu["angular_velocity"],
                     imu["linear_acceleration"], rel(fix["t_ns"], gnss_cfg.latency_s), enu,
                     rel(vel["t_ns"], gnss_cfg.latency_s), velocity,
                     np.asarray(imu_cfg.lever_arm_m, dtype=np.float64),
                     np.asarray(gnss_cfg.lever_arm_m, dtype=np.float64),
                     [*streams.warnings, *(w for w in (unfixed, frame, repeated) if w)])


def run_ins(ins: InsInputs, config: Config) -> Trajectory:
    """Filter the radar IMU + GNSS; returns the vehicle (rear-axle) track at the IMU rate."""
    nav = config.navigation
    s_imu = config.sensors[nav.ins_imu]
    s_gnss = config.sensors[nav.ins_gnss]
    assert s_imu.gyro is not None and s_imu.accel is not None and s_gnss.gnss is not None
    g_noise = np.deg2rad(s_imu.gyro.noise_density_dps_rthz)
    a_noise = s_imu.accel.noise_density_mps2_rthz
    g_walk = np.deg2rad(s_imu.gyro.bias_instability_dps) * np.sqrt(2.0 / s_imu.gyro.bias_tau_s)
    a_walk = s_imu.accel.bias_instability_mps2 * np.sqrt(2.0 / s_imu.accel.bias_tau_s)
    e = s_gnss.gnss
    R_pos = np.diag([e.horizontal_std_m**2 + e.white_std_m**2] * 2 + [e.vertical_std_m**2 + e.white_std_m**2])
    R_vel = np.diag([max(e.velocity_std_mps, 1e-3) ** 2] * 3)  # a perfect (simulated) receiver's 0: 1 mm/s
    lever_ga = ins.gnss_lever - ins.imu_lever  # GNSS antenna seen from the IMU, body frame

    # Alignment from the first GNSS data: position, velocity, yaw from the course; level start.
    speed = np.linalg.norm(ins.gnss_vel[:, :2], axis=1)
    moving = np.flatnonzero(speed > 0.5)
    if not len(moving):
        raise NavInputError("the INS baseline needs the vehicle to move (GNSS speed > 0.5 m/s) to align")
    k0 = moving[0]
    t_start = max(ins.vel_t[k0], ins.gnss_t[0], ins.imu_t[0])
    yaw = float(np.arctan2(ins.gnss_vel[k0, 1], ins.gnss_vel[k0, 0]))
    C = _rotation(np.array([0.0, 0.0, yaw]))  # body -> ENU
    kp = int(np.argmin(np.abs(ins.gnss_t - t_start)))
    p = ins.gnss_pos[kp] - C @ lever_ga
    v = np.nan_to_num(ins.gnss_vel[k0])
    ba = np.zeros(3)
    bg = np.zeros(3)
    ba_std = 1.5 * s_imu.accel.turn_on_bias_mps2
    bg_std = np.deg2rad(1.5 * s_imu.gyro.turn_on_bias_dps)
    P = np.diag([R_pos[0, 0]] * 2 + [R_pos[2, 2]] + [0.05**2] * 3 + [0.02**2, 0.02**2, 0.05**2]
                + [ba_std**2] * 3 + [bg_std**2] * 3)

    i0 = int(np.searchsorted(ins.imu_t, t_start))
    n = len(ins.imu_t) - i0
    out_t = np.empty(n)
    out_p = np.empty((n, 3))
    out_yaw = np.empty(n)
    out_v = np.empty((n, 2))
    out_w = np.empty(n)
    gi = int(np.searchsorted(ins.gnss_t, ins.imu_t[i0], side="right"))
    vi = int(np.searchsorted(ins.vel_t, ins.imu_t[i0], side="right"))
    t_prev = ins.imu_t[i0]
    I15 = np.eye(15)
    for k in range(n):
        idx = i0 + k
        t = ins.imu_t[idx]
        dt = t - t_prev
        t_prev = t
        w = ins.gyro[idx] - bg
        f = ins.accel[idx] - ba
        if dt > 0:
            # Mechanization
            a_enu = C @ f + GRAVITY
            p = p + v * dt + 0.5 * a_enu * dt * dt
            v = v + a_enu * dt
            C = C @ _rotation(w * dt)
            # Error propagation
            F = np.zeros((15, 15))
            F[0:3, 3:6] = np.eye(3)
            F[3:6, 6:9] = -_skew(C @ f)
            F[3:6, 9:12] = -C
            F[6:9, 12:15] = -C
            Phi = I15 + F * dt
            Q = np.zeros((15, 15))
            Q[3:6, 3:6] = np.eye(3) * a_noise**2 * dt
            Q[6:9, 6:9] = np.eye(3) * g_noise**2 * dt
            Q[9:12, 9:12] = np.eye(3) * a_walk**2 * dt
            Q[12:15, 12:15] = np.eye(3) * g_walk**2 * dt
            P = Phi @ P @ Phi.T + Q
        # GNSS corrections that have become due
        while gi < len(ins.gnss_t) and ins.gnss_t[gi] <= t:
            la = C @ lever_ga
            H = np.zeros((3, 15))
            H[:, 0:3] = np.eye(3)
            H[:, 6:9] = -_skew(la)
            y = ins.gnss_pos[gi] - (p + la)
            p, v, C, ba, bg, P = _correct(p, v, C, ba, bg, P, H, y, R_pos)
            gi += 1
        while vi < len(ins.vel_t) and ins.vel_t[vi] <= t:
            given = np.isfinite(ins.gnss_vel[vi])  # an NMEA receiver gives no up
            H = np.zeros((3, 15))
            H[:, 3:6] = np.eye(3)
            y = ins.gnss_vel[vi] - v
            p, v, C, ba, bg, P = _correct(p, v, C, ba, bg, P, H[given], y[given], R_vel[np.ix_(given, given)])
            vi += 1
        out_t[k] = t
        out_p[k] = p
        out_yaw[k] = np.arctan2(C[1, 0], C[0, 0])
        out_v[k] = v[:2]
        out_w[k] = (C @ w)[2]
    # IMU point -> rear-axle centre (level vehicle)
    lx = ins.imu_lever[0] + config.vehicle.cog_to_rear_axle_m
    ly = ins.imu_lever[1]
    heading, speed = rear_axle_motion(out_v, np.unwrap(out_yaw), _smoothed(out_t, out_w, YAW_RATE_SPAN_S), (lx, ly))
    rear = rear_axle_from_body_point(out_p, heading, ins.imu_lever, config.vehicle.cog_to_rear_axle_m)
    t_ns = ins.t0_ns + np.round(out_t * 1e9).astype(np.int64)
    keep = np.r_[True, np.diff(t_ns) > 0]
    return Trajectory("ins", t_ns[keep], rear[keep], heading[keep], speed[keep], out_w[keep], ins.origin,
                      config.vehicle.cog_to_rear_axle_m, config.vehicle.cog_height_m)


#: below this rear-axle speed (m/s) the INS's velocity gives no usable course, and its yaw sets the heading
COURSE_MIN_SPEED_MPS = 0.5
#: span (s) of the moving average of the yaw rate in the lever arm's omega x L: one gyro sample's noise
#: (~2 mrad/s at 250 Hz) times 3.6 m would turn the course by ~7 mrad at 1 m/s from sample to sample
YAW_RATE_SPAN_S = 0.1


def _smoothed(t: Array, x: Array, span_s: float) -> Array:
    """Centred moving average of x (N,) sampled at times t (N,) s over ~span_s (edges: the mean of what exists)."""
    steps = np.diff(t)
    steps = steps[steps > 0]
    if not steps.size:
        return x
    half = int(round(0.5 * span_s / float(np.median(steps))))
    kernel = np.ones(2 * half + 1)
    return np.convolve(x, kernel, mode="same") / np.convolve(np.ones_like(x), kernel, mode="same")


def rear_axle_motion(v_enu: Array, yaw: Array, yaw_rate: Array, lever_xy: tuple[float, float]) -> tuple[Array, Array]:
    """Heading (rad, ENU, unwrapped) and speed (m/s) of the rear-axle centre from an INS at body point ``lever_xy``.

    ``v_enu`` (N, 2) m/s: the INS's horizontal velocity (of its IMU); ``yaw`` (N,) rad and ``yaw_rate`` (N,)
    rad/s: its attitude; ``lever_xy`` m: the IMU seen from the rear-axle centre, body frame. The trajectory model
    has no sideslip, so its heading is the course of the rear axle, whose velocity is the IMU's minus
    omega x lever (at 3.6 m ahead of the axle the IMU's own course turns by omega L / v, 0.1-0.3 rad in a
    slow zig-zag). That course is GNSS-aided through the velocity; the INS's yaw drifts with its gyro bias
    (tens of mrad over a drive), and a heading off the motion points the processed beam off its aperture.
    Where the rear axle moves slower than ``COURSE_MIN_SPEED_MPS`` the course is noise, and the heading is
    the yaw plus the course-yaw offset at the nearest faster sample.
    """
    yaw = np.asarray(yaw, dtype=np.float64)
    # v_imu = R(psi) (u - omega ly, omega lx) for rear-axle speed u and heading psi: solved exactly, the
    # root (forward or reversing) being the one whose heading lies nearer the yaw
    a = yaw_rate * lever_xy[0]
    b = np.sqrt(np.maximum(np.sum(v_enu**2, axis=1) - a**2, 0.0))
    course = np.arctan2(v_enu[:, 1], v_enu[:, 0])
    offset_f = wrap_angle(course - np.arctan2(a, b) - yaw)
    offset_r = wrap_angle(course - np.arctan2(a, -b) - yaw)
    ahead = np.abs(offset_f) <= np.abs(offset_r)
    speed = yaw_rate * lever_xy[1] + np.where(ahead, b, -b)
    offset = np.where(ahead, offset_f, offset_r)
    moving = np.abs(speed) > COURSE_MIN_SPEED_MPS
    if not moving.any():
        return yaw, speed
    index = np.arange(len(yaw))
    idx = np.flatnonzero(moving)
    pos = np.searchsorted(idx, index)
    after = idx[np.minimum(pos, len(idx) - 1)]
    before = idx[np.maximum(pos - 1, 0)]
    return yaw + offset[np.where(np.abs(before - index) < np.abs(after - index), before, after)], speed


def _correct(p: Array, v: Array, C: Array, ba: Array, bg: Array, P: Array, H: Array, y: Array,
             R: Array) -> tuple[Array, Array, Array, Array, Array, Array]:
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T
    dx = K @ y
    I_KH = np.eye(15) - K @ H
    P = I_KH @ P @ I_KH.T + K @ R @ K.T  # Joseph form
    C = _rotation(dx[6:9]) @ C  # attitude error is in the ENU frame
    return p + dx[0:3], v + dx[3:6], C, ba + dx[9:12], bg + dx[12:15], P
