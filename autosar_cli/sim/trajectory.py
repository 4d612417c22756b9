"""Ground-truth vehicle motion: a kinematic bicycle whose rear-axle centre follows a smooth planar path.

The rear-axle centre moves along the body x-axis (no lateral slip at low speed), so the path tangent is
the heading, its curvature kappa gives the yaw rate omega = kappa * v and the road-wheel angle
atan(L * kappa). Any body point follows rigidly (level road, no roll/pitch). Positions are exact to
well below a micrometre at any instant, which the radar echo synthesis needs (lambda/100 ~ 40 um).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import cumulative_simpson
from scipy.interpolate import CubicSpline, PchipInterpolator

GRAVITY = 9.80665

LateralProfile = Callable[[NDArray[np.float64], int], NDArray[np.float64]]
"""w(u) and its derivatives: profile(u, order) for order 0, 1, 2, 3 (m, -, 1/m, 1/m^2)."""


@dataclass(frozen=True)
class PointKinematics:
    """ENU kinematics of a body-fixed point: position (m), velocity (m/s), acceleration (m/s^2), (N, 3)."""

    position: NDArray[np.float64]
    velocity: NDArray[np.float64]
    acceleration: NDArray[np.float64]


class TruthMotion:
    """Rear-axle path in ENU plus a speed profile in time.

    Args:
        lateral: lateral offset w(u) of the path from its nominal straight line, with derivatives.
        length_m: nominal along-track length of the path (u from 0 to length_m).
        direction_rad: ENU heading of the nominal line (0 = towards East).
        start_enu: ENU position of the rear-axle centre at u = 0 (m, 2 values).
        speed_knots: (time s, speed m/s) knots of a monotone-cubic speed profile.
        cog_to_rear_axle_m, cog_height_m: where the body origin (CoG) sits above/ahead of the rear axle.
    """

    def __init__(
        self,
        lateral: LateralProfile,
        length_m: float,
        direction_rad: float,
        start_enu: tuple[float, float],
        speed_knots: list[tuple[float, float]],
        cog_to_rear_axle_m: float,
        cog_height_m: float,
    ) -> None:
        self.lateral = lateral
        self.length_m = float(length_m)
        self.direction_rad = float(direction_rad)
        self.start_enu = np.asarray(start_enu, dtype=np.float64)
        self.cog_to_rear_axle_m = float(cog_to_rear_axle_m)
        self.cog_height_m = float(cog_height_m)
        # Arc length s(u) on a 2 mm grid, inverted with a cubic spline u(s).
        u = np.linspace(0.0, self.length_m, int(self.length_m / 0.002) + 1)
        ds_du = np.hypot(1.0, lateral(u, 1))
        s = cumulative_simpson(ds_du, x=u, initial=0.0)
        self.path_length_m = float(s[-1])
        self._u_of_s = CubicSpline(s, u)
        self._set_speed_profile(speed_knots)

    def _set_speed_profile(self, speed_knots: list[tuple[float, float]]) -> None:
        kt, kv = np.array(speed_knots, dtype=np.float64).T
        self._speed = PchipInterpolator(kt, kv, extrapolate=True)
        self._accel = self._speed.derivative()
        self._distance = self._speed.antiderivative()
        # Duration: when the travelled distance reaches the path length.
        t_grid = np.linspace(kt[0], kt[-1] + 3600.0, 200001)
        d = self._distance(t_grid)
        if d[-1] < self.path_length_m:
            raise ValueError("speed profile never covers the path length")
        self.duration_s = float(np.interp(self.path_length_m, d, t_grid))

    # -- scalar states of the rear axle ---------------------------------------------------------------
    def speed(self, t: ArrayLike) -> NDArray[np.float64]:
        """Rear-axle speed (m/s) at times t (s from drive start)."""
        return np.asarray(self._speed(np.asarray(t, dtype=np.float64)))

    def states(self, t: ArrayLike) -> dict[str, NDArray[np.float64]]:
        """Rear-axle states at times t (s): position ENU (N,2), heading, speed, accel, curvature, yaw rate,
        yaw acceleration."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        s = self._distance(t)
        v = self._speed(t)
        a = self._accel(t)
        pos, psi, kappa, dkappa_ds = self.path(s)
        return {
            "position": pos,
            "heading": psi,
            "speed": v,
            "accel": a,
            "curvature": kappa,
            "yaw_rate": kappa * v,
            "yaw_accel": dkappa_ds * v * v + kappa * a,
        }

    def distance(self, t: ArrayLike) -> NDArray[np.float64]:
        """Arc length (m) travelled along the path by the rear axle at times t (s)."""
        return np.asarray(self._distance(np.asarray(t, dtype=np.float64)))

    def path(self, s: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        """Path at arc lengths s (m): ENU position (N, 2), tangent heading (rad), curvature (1/m), dkappa/ds."""
        u = self._u_of_s(s)
        w1, w2, w3 = self.lateral(u, 1), self.lateral(u, 2), self.lateral(u, 3)
        q = 1.0 + w1 * w1
        kappa = w2 / q**1.5
        # d(kappa)/du, then per unit arc length (du/ds = 1/sqrt(q)).
        dkappa_du = w3 / q**1.5 - 3.0 * w1 * w2 * w2 / q**2.5
        dkappa_ds = dkappa_du / np.sqrt(q)
        psi = self.direction_rad + np.arctan(w1)
        c, sn = np.cos(self.direction_rad), np.sin(self.direction_rad)
        w0 = self.lateral(u, 0)
        pos = np.stack([self.start_enu[0] + c * u - sn * w0, self.start_enu[1] + sn * u + c * w0], -1)
        return pos, psi, kappa, dkappa_ds

    def point(self, t: ArrayLike, lever_arm_m: ArrayLike) -> PointKinematics:
        """ENU kinematics of body points at lever arms (..., 3) from the CoG (body frame), at times t (N,).

        lever_arm_m broadcasts against (N, 3): pass (3,) for one point or (N, 3) for one per time.
        """
        st = self.states(t)
        r = np.broadcast_to(np.asarray(lever_arm_m, dtype=np.float64), (st["speed"].size, 3))
        rx = r[:, 0] + self.cog_to_rear_axle_m
        ry = r[:, 1]
        psi, v, a = st["heading"], st["speed"], st["accel"]
        om, om_dot = st["yaw_rate"], st["yaw_accel"]
        c, s = np.cos(psi), np.sin(psi)
        # offset from the rear axle rotated into ENU, and its 90-deg rotation J @ R @ r
        ox, oy = c * rx - s * ry, s * rx + c * ry
        jx, jy = -oy, ox
        pos = np.stack([st["position"][:, 0] + ox, st["position"][:, 1] + oy,
                        self.cog_height_m + r[:, 2]], -1)
        vel = np.stack([v * c + om * jx, v * s + om * jy, np.zeros_like(v)], -1)
        acc = np.stack([
            a * c - v * om * s + om_dot * jx - om * om * ox,
            a * s + v * om * c + om_dot * jy - om * om * oy,
            np.zeros_like(v),
        ], -1)
        return PointKinematics(pos, vel, acc)

    def specific_force_body(self, t: ArrayLike, lever_arm_m: ArrayLike) -> NDArray[np.float64]:
        """What an ideal accelerometer at lever_arm_m reads, in the body frame (N, 3) m/s^2."""
        k = self.point(t, lever_arm_m)
        psi = self.states(t)["heading"]
        c, s = np.cos(psi), np.sin(psi)
        ax, ay = k.acceleration[:, 0], k.acceleration[:, 1]
        return np.stack([c * ax + s * ay, -s * ax + c * ay, np.full_like(ax, GRAVITY)], -1)

    def road_wheel_angle(self, t: ArrayLike, wheelbase_m: float) -> NDArray[np.float64]:
        """Kinematic (Ackermann, bicycle) road-wheel angle (rad): atan(L * kappa)."""
        return np.arctan(wheelbase_m * self.states(t)["curvature"])


def smoothstep(x: NDArray[np.float64], order: int = 0) -> NDArray[np.float64]:
    """Quintic step 0 -> 1 on [0, 1] (C2 at both ends) and its derivative (order 1)."""
    x = np.clip(x, 0.0, 1.0)
    if order == 0:
        return x**3 * (10.0 - 15.0 * x + 6.0 * x * x)
    return 30.0 * x * x * (1.0 - x) ** 2


class ArcPathMotion(TruthMotion):
    """Kinematic motion along a path given by its curvature: arcs joined by C2 curvature ramps (clothoid-like).

    Args:
        arcs: (start s, end s, curvature 1/m) of each arc; the curvature ramps in and out over ramp_m.
        length_m: path length (m); the path runs straight before 0 and after length_m.
        direction_rad, start_enu: heading and ENU position of the rear axle at s = 0.
    """

    def __init__(self, arcs: list[tuple[float, float, float]], ramp_m: float, length_m: float,
                 direction_rad: float, start_enu: tuple[float, float], speed_knots: list[tuple[float, float]],
                 cog_to_rear_axle_m: float, cog_height_m: float) -> None:
        self.arcs, self.ramp_m = arcs, float(ramp_m)
        self.length_m = self.path_length_m = float(length_m)
        self.direction_rad = float(direction_rad)
        self.start_enu = np.asarray(start_enu, dtype=np.float64)
        self.cog_to_rear_axle_m = float(cog_to_rear_axle_m)
        self.cog_height_m = float(cog_height_m)
        s = np.arange(-60.0, length_m + 60.0 + 1e-9, 0.002)
        psi = self.direction_rad + cumulative_simpson(self._curvature(s, 0), x=s, initial=0.0)
        psi -= np.interp(0.0, s, psi) - self.direction_rad
        xy = np.stack([cumulative_simpson(np.cos(psi), x=s, initial=0.0),
                       cumulative_simpson(np.sin(psi), x=s, initial=0.0)], -1)
        xy += self.start_enu - np.array([np.interp(0.0, s, xy[:, 0]), np.interp(0.0, s, xy[:, 1])])
        self._xy_psi = CubicSpline(s, np.column_stack([xy, psi]), axis=0)
        self._set_speed_profile(speed_knots)

    def _curvature(self, s: NDArray[np.float64], order: int) -> NDArray[np.float64]:
        out = np.zeros_like(np.asarray(s, dtype=np.float64))
        for s0, s1, k in self.arcs:
            if order == 0:
                out += k * (smoothstep((s - s0) / self.ramp_m) - smoothstep((s - s1) / self.ramp_m))
            else:
                out += k / self.ramp_m * (smoothstep((s - s0) / self.ramp_m, 1) - smoothstep((s - s1) / self.ramp_m, 1))
        return out

    def path(self, s: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        """Path at arc lengths s (m): ENU position (N, 2), tangent heading (rad), curvature (1/m), dkappa/ds."""
        s = np.asarray(s, dtype=np.float64)
        q = self._xy_psi(s)
        return q[..., :2], q[..., 2], self._curvature(s, 0), self._curvature(s, 1)
