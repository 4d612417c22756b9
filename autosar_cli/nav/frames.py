"""Frame conventions, defined once.

- Navigation frame: local ENU (x East, y North, z Up) at a geodetic origin.
- Heading psi: angle of the body x-axis from East, counter-clockwise (rad).
- Course / true heading as GNSS reports them: from North, clockwise (deg). Convert only here.
- Body frame (ISO 8855): x forward, y left, z up, origin at the centre of gravity.
- Radar frame: x boresight, y along the horizontal antenna row (left), z up; its pose in the body
  frame is a lever arm plus yaw-pitch-roll (z-y-x) rotation.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray


def wrap_angle(angle: ArrayLike) -> NDArray[np.float64]:
    """Wrap angles (rad) to [-pi, pi)."""
    a = np.asarray(angle, dtype=np.float64)
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def heading_from_course_deg(course_deg: ArrayLike) -> NDArray[np.float64]:
    """ENU heading (rad, from East, CCW) from a GNSS course/true heading (deg, from North, CW)."""
    return wrap_angle(np.deg2rad(90.0 - np.asarray(course_deg, dtype=np.float64)))


def course_deg_from_heading(heading_rad: ArrayLike) -> NDArray[np.float64]:
    """GNSS course/true heading (deg in [0, 360), from North, CW) from an ENU heading (rad)."""
    return np.mod(90.0 - np.rad2deg(np.asarray(heading_rad, dtype=np.float64)), 360.0)


def rot_z(angle: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrices about z (..., 3, 3) for angles (rad)."""
    a = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def rot_y(angle: float) -> NDArray[np.float64]:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_x(angle: float) -> NDArray[np.float64]:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def mounting_rotation(yaw_deg: float, pitch_deg: float = 0.0, roll_deg: float = 0.0) -> NDArray[np.float64]:
    """Rotation radar frame -> body frame (3, 3), yaw-pitch-roll applied z-y-x."""
    return rot_z(np.deg2rad(yaw_deg)) @ rot_y(np.deg2rad(pitch_deg)) @ rot_x(np.deg2rad(roll_deg))


def sensor_to_body(vectors: ArrayLike, mounting_ypr_deg: tuple[float, float, float]) -> NDArray[np.float64]:
    """Vectors (N, 3) on a sensor's axes turned onto the body's by its mounting (yaw, pitch, roll, deg:
    :func:`mounting_rotation`). An axis the sensor does not have (NaN) reaches only the body axes it turns into:
    a 3-DoF IMU's yaw rate stays a number under a yaw."""
    v = np.asarray(vectors, dtype=np.float64)
    if not any(mounting_ypr_deg):
        return v
    r = mounting_rotation(*mounting_ypr_deg)
    return np.stack([sum(r[i, j] * v[:, j] for j in range(3) if r[i, j] != 0.0) for i in range(3)], axis=-1)


def gravity_tilt_deg(gravity: ArrayLike) -> float:
    """How far (deg) an accelerometer triad's reading of gravity ``gravity`` (3,) lies from its +z axis."""
    gx, gy, gz = (float(v) for v in gravity)
    return math.degrees(math.atan2(math.hypot(gx, gy), gz))


def levelling_pitch_roll_deg(gravity: ArrayLike) -> tuple[float, float]:
    """The pitch and roll (deg, :func:`mounting_rotation`'s) that turn an accelerometer
    triad's reading of gravity ``gravity`` (3,) onto +z: roll = atan2(g_y, g_z), pitch = atan2(-g_x, hypot(g_y,
    g_z)). Gravity says nothing of the yaw."""
    gx, gy, gz = (float(v) for v in gravity)
    return math.degrees(math.atan2(-gx, math.hypot(gy, gz))), math.degrees(math.atan2(gy, gz))


def body_to_enu(heading: ArrayLike, offsets_body: ArrayLike) -> NDArray[np.float64]:
    """Rotate body-frame vectors (..., 3) into ENU for a level vehicle with heading (rad)."""
    return np.einsum("...ij,...j->...i", rot_z(heading), np.asarray(offsets_body, dtype=np.float64))
