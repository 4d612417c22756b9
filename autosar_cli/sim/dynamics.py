"""Full truth motion: a single-track car with tyre slip, driven along the scenario's path, on its suspension.

The scenario's kinematic motion (``TruthMotion``) gives the path and the speed along it. A driver model
(curvature feed-forward with preview plus a Stanley lateral/heading feedback) steers a linear-tyre
single-track model (saturating as mu F_z tanh(C alpha / mu F_z)); the car's rear axle then runs a few
centimetres off the path and the body slips sideways. Body heave, pitch and roll are damped second-order
responses to the road under the four wheels and to the accelerations. The 6-DOF pose is integrated on a
1 kHz grid and interpolated with cubic splines, which keeps positions between samples to a few nm.

Frames: ENU world; body x forward, y left, z up (ISO 8855) with origin at the CoG; attitude
R = Rz(yaw) Ry(pitch) Rx(roll) maps body to ENU. Wheels in the order fl, fr, rl, rr.
"""

from __future__ import annotations

import math
import zlib

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import cumulative_trapezoid
from scipy.interpolate import CubicSpline
from scipy.signal import cont2discrete, lfilter, lfilter_zi

from autosar_cli.config import VehicleConfig, VehicleDynamicsConfig
from autosar_cli.sim.road import RoadLayout, RoadProfile
from autosar_cli.sim.trajectory import GRAVITY, PointKinematics, TruthMotion

WHEELS = ("fl", "fr", "rl", "rr")
AIR_DENSITY = 1.2  # kg/m^3
MIN_SLIP_SPEED = 1.0  # m/s: below it the slip angles relax towards zero instead of growing as 1/v


def understeer_gradient(vehicle: VehicleConfig, dyn: VehicleDynamicsConfig) -> float:
    """K (rad per m/s^2) of the linear single-track model: delta = L kappa + K a_y."""
    b = vehicle.cog_to_rear_axle_m
    a = vehicle.wheelbase_m - b
    return dyn.mass_kg / vehicle.wheelbase_m * (b / dyn.cornering_stiffness_front_n_per_rad
                                                - a / dyn.cornering_stiffness_rear_n_per_rad)


@nb.njit(cache=True)
def _derivative(x: NDArray[np.float64], v: float, kappa: float, kappa_prev: float,
                p: NDArray[np.float64]) -> tuple[float, float, float, float, float, float, float, float]:
    m, iz, a, b, wheelbase, cf, cr, lim_f, lim_r, k_us, k_lat, k_head = (
        p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10], p[11])
    e, dpsi, vy, r = x[0], x[1], x[2], x[3]
    vyr = vy - b * r
    cd, sd = math.cos(dpsi), math.sin(dpsi)
    vx = (v * (1.0 - kappa * e) + vyr * sd) / cd
    e_front = e + wheelbase * sd
    delta = (math.atan(wheelbase * kappa_prev) + k_us * v * v * kappa_prev - k_head * dpsi
             - math.atan(k_lat * e_front / (v + 1.0)))
    veff = max(vx, MIN_SLIP_SPEED)
    # the exact angles between each wheel's plane and its velocity: small-angle forms (delta - (vy + a r) / vx)
    # make a 10 m turn's steady steering L kappa instead of atan(L kappa), 7 mrad less at the junction's 0.28 rad
    alpha_f = delta * vx / veff - math.atan((vy + a * r) / veff)
    alpha_r = math.atan((b * r - vy) / veff)
    ff = lim_f * math.tanh(cf * alpha_f / lim_f)
    fr = lim_r * math.tanh(cr * alpha_r / lim_r)
    cdel = math.cos(delta)
    return (vx * sd + vyr * cd, r - kappa * v, (ff * cdel + fr) / m - vx * r, (a * ff * cdel - b * fr) / iz,
            delta, ff, fr, vx)


@nb.njit(cache=True)
def single_track(dt: float, v: NDArray[np.float64], kappa: NDArray[np.float64], kappa_prev: NDArray[np.float64],
                 x0: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]:
    """RK4 integration of the driven single-track model along a path.

    v, kappa, kappa_prev: path speed (m/s), path curvature and previewed curvature (1/m) on a half-step
    grid (2N - 1 values, t = k dt / 2). Returns (N, 8): rear-axle lateral offset from the path (m, left +),
    heading minus path tangent (rad), CoG lateral velocity (m/s, body y), yaw rate (rad/s), road-wheel angle
    (rad), front and rear axle lateral forces (N), longitudinal velocity (m/s).
    """
    n = (v.size + 1) // 2
    out = np.empty((n, 8))
    x = x0.copy()
    k = np.empty((4, 4))
    for i in range(n):
        j = 2 * i
        d = _derivative(x, v[j], kappa[j], kappa_prev[j], p)
        out[i, :4] = x
        out[i, 4:] = d[4], d[5], d[6], d[7]
        if i == n - 1:
            break
        k[0] = d[0], d[1], d[2], d[3]
        d = _derivative(x + 0.5 * dt * k[0], v[j + 1], kappa[j + 1], kappa_prev[j + 1], p)
        k[1] = d[0], d[1], d[2], d[3]
        d = _derivative(x + 0.5 * dt * k[1], v[j + 1], kappa[j + 1], kappa_prev[j + 1], p)
        k[2] = d[0], d[1], d[2], d[3]
        d = _derivative(x + dt * k[2], v[j + 2], kappa[j + 2], kappa_prev[j + 2], p)
        k[3] = d[0], d[1], d[2], d[3]
        x = x + dt / 6.0 * (k[0] + 2.0 * k[1] + 2.0 * k[2] + k[3])
    return out


def suspension_response(dt: float, base_input: NDArray[np.float64], force_input: NDArray[np.float64],
                        frequency_hz: float, damping_ratio: float) -> NDArray[np.float64]:
    """Body coordinate (heave m, or pitch/roll rad) of a damped 2nd-order mode on a uniform time grid.

    base_input: what the road imposes (same unit), through (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2);
    force_input: the static deflection the inertial load would give, through w^2 / (s^2 + 2 zeta w s + w^2).
    Both start in steady state. Discretised with the bilinear transform (warping < 1e-5 at 2 Hz, 1 kHz).
    """
    w = 2.0 * np.pi * frequency_hz
    den = [1.0, 2.0 * damping_ratio * w, w * w]
    out = np.zeros_like(np.asarray(base_input, dtype=np.float64))
    for num, u in (([2.0 * damping_ratio * w, w * w], base_input), ([w * w], force_input)):
        bz, az, _ = cont2discrete((num, den), dt, method="bilinear")
        bz = np.ravel(bz)
        u = np.asarray(u, dtype=np.float64)
        y, _ = lfilter(bz, az, u, zi=lfilter_zi(bz, az) * u[0])
        out += y
    return out


def euler_rates_to_body(att: NDArray[np.float64], att_dot: NDArray[np.float64]) -> NDArray[np.float64]:
    """Body angular rates (N, 3) rad/s from roll, pitch, yaw (N, 3) rad and their time derivatives."""
    phi, th = att[:, 0], att[:, 1]
    dphi, dth, dpsi = att_dot[:, 0], att_dot[:, 1], att_dot[:, 2]
    sf, cf, st, ct = np.sin(phi), np.cos(phi), np.sin(th), np.cos(th)
    return np.stack([dphi - dpsi * st, dth * cf + dpsi * ct * sf, -dth * sf + dpsi * ct * cf], -1)


def body_to_enu(att: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation matrices (N, 3, 3) Rz(yaw) Ry(pitch) Rx(roll) from roll, pitch, yaw (N, 3) rad."""
    sf, cf = np.sin(att[:, 0]), np.cos(att[:, 0])
    st, ct = np.sin(att[:, 1]), np.cos(att[:, 1])
    sp, cp = np.sin(att[:, 2]), np.cos(att[:, 2])
    return np.stack([
        np.stack([cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf], -1),
        np.stack([sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf], -1),
        np.stack([-st, ct * sf, ct * cf], -1),
    ], -2)


def wheel_shares(front_fraction: float) -> NDArray[np.float64]:
    """Each wheel's share (4,) (FL, FR, RL, RR) of a longitudinal force whose front axle takes ``front_fraction``."""
    return np.array([front_fraction / 2] * 2 + [(1 - front_fraction) / 2] * 2)


def rolled_wheel_angle(t: NDArray[np.float64],
                       wheel_rate: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Wheel angle (rad, from 0 at t[0]) integrated from wheel_rate (rad/s, (N,) or (N, wheels)) on t (s),
    with one sample a second before the log: the car was already rolling at its initial rate, so that an ABS
    ECU has edge history at t = 0. Returns (times (N + 1,) s, angle (N + 1, ...) rad)."""
    return (np.concatenate([[-1.0], t]),
            np.concatenate([-wheel_rate[:1], cumulative_trapezoid(wheel_rate, t, axis=0, initial=0.0)]))


class FullMotion:
    """6-DOF truth motion of the full model, with the same interface as ``TruthMotion`` plus attitude,
    body rates, side-slip and per-wheel loads, rolling radii and rotation.

    Args:
        reference: the scenario's kinematic motion (path and speed profile).
        vehicle, dyn: geometry and the full model's parameters.
        road: the road under the path.
        rate_hz: rate of the integration grid and of the truth sidecar's pose.
    """

    def __init__(self, reference: TruthMotion, vehicle: VehicleConfig, dyn: VehicleDynamicsConfig,
                 road: RoadProfile, rate_hz: float = 1000.0) -> None:
        self.reference = reference
        self.vehicle, self.dyn, self.road = vehicle, dyn, road
        self.duration_s = reference.duration_s
        self.cog_to_rear_axle_m = b = vehicle.cog_to_rear_axle_m
        self.cog_height_m = vehicle.cog_height_m
        wheelbase = vehicle.wheelbase_m
        a = wheelbase - b
        dt = 1.0 / rate_hz
        n = int(np.ceil((self.duration_s + 0.25) / dt)) + 1
        t_half = np.arange(2 * n - 1) * (dt / 2.0)
        s_half = reference.distance(t_half)
        v_half = reference.speed(t_half)
        kappa_half = reference.path(s_half)[2]
        kappa_prev = reference.path(s_half + v_half * dyn.driver_preview_s)[2]
        m = dyn.mass_kg
        load_f, load_r = m * GRAVITY * b / wheelbase, m * GRAVITY * a / wheelbase
        p = np.array([m, dyn.yaw_inertia_kgm2, a, b, wheelbase, dyn.cornering_stiffness_front_n_per_rad,
                      dyn.cornering_stiffness_rear_n_per_rad, dyn.friction_coefficient * load_f,
                      dyn.friction_coefficient * load_r, understeer_gradient(vehicle, dyn),
                      dyn.driver_lateral_gain, dyn.driver_heading_gain])
        r0 = v_half[0] * kappa_half[0]
        x = single_track(dt, v_half, kappa_half, kappa_prev, np.array([0.0, 0.0, b * r0, r0]), p)
        on = set(dyn.components)
        if "slip" not in on:  # the kinematic bicycle's planar motion
            x[:] = 0.0
            x[:, 4] = np.arctan(wheelbase * kappa_half[::2])
            x[:, 5] = m * v_half[::2] ** 2 * kappa_half[::2]  # lateral force, all on the front axle's slot
        t = t_half[::2]
        self.t = t
        s = s_half[::2]
        self.s = s
        pos0, psi0, kappa, _ = reference.path(s)
        e, dpsi = x[:, 0], x[:, 1]
        self.lateral_offset, self.steer = e, x[:, 4]
        rear = pos0 + e[:, None] * np.stack([-np.sin(psi0), np.cos(psi0)], -1)
        accel_x = reference.states(t)["accel"]
        v = v_half[::2]
        drag = 0.5 * AIR_DENSITY * dyn.drag_area_m2 * v * v + dyn.rolling_resistance * m * GRAVITY * (v > 0.05)
        accel_y = (x[:, 5] * np.cos(x[:, 4]) + x[:, 6]) / m
        self.accel_body = np.stack([accel_x, accel_y], -1)

        # road under each wheel: rear wheels at the rear-axle station, front ones a wheelbase ahead
        half_f, half_r = vehicle.track_front_m / 2, vehicle.track_rear_m / 2
        w_front = e + wheelbase * np.sin(dpsi)
        self.road_height = np.stack([
            road.height(s + wheelbase, w_front + half_f, 0), road.height(s + wheelbase, w_front - half_f, 1),
            road.height(s, e + half_r, 0), road.height(s, e - half_r, 1)], -1)
        if "road" not in on:
            self.road_height[:] = 0.0
        h = self.road_height
        roll_road = 0.5 * ((h[:, 0] - h[:, 1]) / vehicle.track_front_m + (h[:, 2] - h[:, 3]) / vehicle.track_rear_m)
        pitch_road = -(0.5 * (h[:, 0] + h[:, 1]) - 0.5 * (h[:, 2] + h[:, 3])) / wheelbase
        heave_road = (b * 0.5 * (h[:, 0] + h[:, 1]) + a * 0.5 * (h[:, 2] + h[:, 3])) / wheelbase
        k_roll = np.deg2rad(dyn.roll_gradient_deg_per_g) / GRAVITY * ("body" in on)
        k_pitch = np.deg2rad(dyn.pitch_gradient_deg_per_g) / GRAVITY * ("body" in on)
        roll = suspension_response(dt, roll_road, k_roll * accel_y, dyn.roll_frequency_hz, dyn.roll_damping_ratio)
        pitch = suspension_response(dt, pitch_road, -k_pitch * accel_x, dyn.pitch_frequency_hz,
                                    dyn.pitch_damping_ratio)
        heave = suspension_response(dt, heave_road, np.zeros_like(heave_road), dyn.heave_frequency_hz,
                                    dyn.heave_damping_ratio)
        self.pose_samples = np.stack([rear[:, 0], rear[:, 1], roll, pitch, psi0 + dpsi, heave], -1)
        self._pose = CubicSpline(t, self.pose_samples, axis=0)
        self._steer = CubicSpline(t, x[:, 4])
        self._path_kappa = kappa
        self.pivot_height_m = dyn.roll_centre_height_m

        # wheel loads (static + lateral and longitudinal transfer), rolling radii, slip and rotation
        static = np.array([load_f / 2, load_f / 2, load_r / 2, load_r / 2])
        d_lat_f = m * accel_y * vehicle.cog_height_m / vehicle.track_front_m * b / wheelbase
        d_lat_r = m * accel_y * vehicle.cog_height_m / vehicle.track_rear_m * a / wheelbase
        d_long = m * accel_x * vehicle.cog_height_m / wheelbase / 2
        self.wheel_load = static + np.stack([-d_lat_f - d_long, d_lat_f - d_long, -d_lat_r + d_long,
                                             d_lat_r + d_long], -1)
        self.rolling_radius = ((vehicle.wheel_radius_m - dyn.rolling_radius_deflection_fraction
                                * (self.wheel_load - static) / dyn.tyre_vertical_stiffness_n_per_m)
                               * (1.0 + dyn.rolling_radius_speed_growth_per_mps2 * v[:, None] ** 2))
        force_x = m * accel_x + drag
        drive = np.where(force_x >= 0, 1.0, 0.0)
        share = (drive[:, None] * wheel_shares(dyn.drive_front_fraction)
                 + (1 - drive[:, None]) * wheel_shares(dyn.brake_front_fraction))
        self.longitudinal_slip = force_x[:, None] * share / (dyn.slip_stiffness_per_load * self.wheel_load)
        if "tyre_radius" not in on:
            self.rolling_radius = np.full_like(self.rolling_radius, vehicle.wheel_radius_m)
            self.longitudinal_slip = np.zeros_like(self.longitudinal_slip)
        self.wheel_positions = np.array([[a, half_f, -vehicle.cog_height_m], [a, -half_f, -vehicle.cog_height_m],
                                         [-b, half_r, -vehicle.cog_height_m], [-b, -half_r, -vehicle.cog_height_m]])
        v_long = np.empty((t.size, 4))
        rot = body_to_enu(self.pose_samples[:, 2:5])
        for i in range(4):
            vel_b = np.einsum("nji,nj->ni", rot, self.point(t, self.wheel_positions[i]).velocity)
            heading = x[:, 4] if i < 2 else np.zeros(t.size)
            v_long[:, i] = vel_b[:, 0] * np.cos(heading) + vel_b[:, 1] * np.sin(heading)
        self.wheel_rate = v_long * (1.0 + self.longitudinal_slip) / self.rolling_radius
        # wheel_angle (M, 4) rad on wheel_t (M,) s = (-1, t...)
        self.wheel_t, self.wheel_angle = rolled_wheel_angle(t, self.wheel_rate)

    # -- pose --------------------------------------------------------------------------------------
    def _pose_derivatives(self, t: ArrayLike) -> tuple[NDArray[np.float64], ...]:
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        return self._pose(t), self._pose(t, 1), self._pose(t, 2)

    def attitude(self, t: ArrayLike) -> NDArray[np.float64]:
        """Roll, pitch, yaw (N, 3) rad at times t (s)."""
        return self._pose(np.atleast_1d(np.asarray(t, dtype=np.float64)))[:, 2:5]

    def body_to_enu(self, t: ArrayLike) -> NDArray[np.float64]:
        """Body-to-ENU rotations (N, 3, 3) at times t (s)."""
        return body_to_enu(self.attitude(t))

    def body_rates(self, t: ArrayLike) -> NDArray[np.float64]:
        """Angular velocity of the body in body axes (N, 3) rad/s."""
        q, dq, _ = self._pose_derivatives(t)
        return euler_rates_to_body(q[:, 2:5], dq[:, 2:5])

    def _body_rate_derivative(self, q: NDArray[np.float64], dq: NDArray[np.float64],
                              ddq: NDArray[np.float64]) -> NDArray[np.float64]:
        phi, th = q[:, 2], q[:, 3]
        dphi, dth, dpsi = dq[:, 2], dq[:, 3], dq[:, 4]
        ddphi, ddth, ddpsi = ddq[:, 2], ddq[:, 3], ddq[:, 4]
        sf, cf, st, ct = np.sin(phi), np.cos(phi), np.sin(th), np.cos(th)
        return np.stack([
            ddphi - ddpsi * st - dpsi * dth * ct,
            ddth * cf - dth * dphi * sf + ddpsi * ct * sf - dpsi * dth * st * sf + dpsi * dphi * ct * cf,
            -ddth * sf - dth * dphi * cf + ddpsi * ct * cf - dpsi * dth * st * cf - dpsi * dphi * ct * sf,
        ], -1)

    def point(self, t: ArrayLike, lever_arm_m: ArrayLike) -> PointKinematics:
        """ENU kinematics of body points at lever arms (3,) or (N, 3) from the CoG (body frame) at times t (N,)."""
        q, dq, ddq = self._pose_derivatives(t)
        n = q.shape[0]
        r = np.broadcast_to(np.asarray(lever_arm_m, dtype=np.float64), (n, 3)).copy()
        r[:, 2] += self.cog_height_m - self.pivot_height_m  # from the roll/pitch pivot
        b = self.cog_to_rear_axle_m
        psi, dpsi, ddpsi = q[:, 4], dq[:, 4], ddq[:, 4]
        c, s = np.cos(psi), np.sin(psi)
        pivot = np.stack([q[:, 0] + b * c, q[:, 1] + b * s, q[:, 5] + self.pivot_height_m], -1)
        pivot_v = np.stack([dq[:, 0] - b * dpsi * s, dq[:, 1] + b * dpsi * c, dq[:, 5]], -1)
        pivot_a = np.stack([ddq[:, 0] - b * (ddpsi * s + dpsi * dpsi * c),
                            ddq[:, 1] + b * (ddpsi * c - dpsi * dpsi * s), ddq[:, 5]], -1)
        rot = body_to_enu(q[:, 2:5])
        w = euler_rates_to_body(q[:, 2:5], dq[:, 2:5])
        w_dot = self._body_rate_derivative(q, dq, ddq)
        wxr = np.cross(w, r)
        acc_b = np.cross(w_dot, r) + np.cross(w, wxr)
        return PointKinematics(pivot + np.einsum("nij,nj->ni", rot, r),
                               pivot_v + np.einsum("nij,nj->ni", rot, wxr),
                               pivot_a + np.einsum("nij,nj->ni", rot, acc_b))

    def specific_force_body(self, t: ArrayLike, lever_arm_m: ArrayLike) -> NDArray[np.float64]:
        """What an ideal accelerometer at lever_arm_m reads, in the body frame (N, 3) m/s^2."""
        k = self.point(t, lever_arm_m)
        rot = self.body_to_enu(t)
        return np.einsum("nji,nj->ni", rot, k.acceleration + np.array([0.0, 0.0, GRAVITY]))

    def side_slip(self, t: ArrayLike) -> NDArray[np.float64]:
        """Body side-slip angle at the CoG (rad): direction of its velocity in the body frame (0 below 5 cm/s)."""
        vel = np.einsum("nji,nj->ni", self.body_to_enu(t), self.point(t, np.zeros(3)).velocity)
        return np.where(np.hypot(vel[:, 0], vel[:, 1]) > 0.05, np.arctan2(vel[:, 1], vel[:, 0]), 0.0)

    # -- the TruthMotion interface ---------------------------------------------------------------------
    def speed(self, t: ArrayLike) -> NDArray[np.float64]:
        """Rear-axle ground speed (m/s)."""
        return np.asarray(np.hypot(*self._pose(np.atleast_1d(np.asarray(t, dtype=np.float64)), 1)[:, :2].T))

    def states(self, t: ArrayLike) -> dict[str, NDArray[np.float64]]:
        """Rear-axle position (N, 2), heading, speed, accel, path curvature, yaw rate, yaw acceleration."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        q, dq, ddq = self._pose_derivatives(t)
        return {
            "position": q[:, :2], "heading": q[:, 4], "speed": np.hypot(dq[:, 0], dq[:, 1]),
            "accel": self.reference.states(t)["accel"], "curvature": np.interp(t, self.t, self._path_kappa),
            "yaw_rate": dq[:, 4], "yaw_accel": ddq[:, 4],
        }

    def road_wheel_angle(self, t: ArrayLike, wheelbase_m: float) -> NDArray[np.float64]:
        """The driver's road-wheel angle (rad) at times t (s)."""
        return np.asarray(self._steer(np.atleast_1d(np.asarray(t, dtype=np.float64))))

    def wheel_rotation(self, t: ArrayLike) -> NDArray[np.float64]:
        """Rotation angle of each wheel since the drive start (N, 4) rad."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        return np.stack([np.interp(t, self.wheel_t, self.wheel_angle[:, i]) for i in range(4)], -1)


def full_motion(name: str, reference: TruthMotion, layout: RoadLayout, vehicle: VehicleConfig,
                dyn: VehicleDynamicsConfig, rate_hz: float = 1000.0) -> FullMotion:
    """The full model driving scenario ``name``'s path; its road is fixed per scenario like its scene."""
    rng = np.random.default_rng(zlib.crc32(f"road/{name}".encode()))
    track = 0.5 * (vehicle.track_front_m + vehicle.track_rear_m)
    road = RoadProfile(-5.0, reference.path_length_m + vehicle.wheelbase_m + 10.0, layout, dyn, track, rng)
    return FullMotion(reference, vehicle, dyn, road, rate_hz)
