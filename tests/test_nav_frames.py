"""The radar's mounting angles (nav/frames.py): what each turns, worked by hand, in the config's words."""

from __future__ import annotations

import math

import numpy as np

from autosar_cli.nav.frames import mounting_rotation

BORESIGHT, ROW = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])


def test_mounting_angles_turn_the_radar_as_the_config_says() -> None:
    """``radar.mounting`` (radar frame -> body frame, yaw-pitch-roll applied z-y-x, each right-handed): yaw -45 deg
    points the boresight 45 deg right of the car's nose (the config's radar); pitch +10 deg tilts it 10 deg below
    the horizon; roll +10 deg raises the antenna row's left end (+y) by 10 deg; pitched and yawed, the radar looks
    down along its yawed boresight."""
    c45, c10, s10 = math.cos(math.radians(45.0)), math.cos(math.radians(10.0)), math.sin(math.radians(10.0))
    np.testing.assert_allclose(mounting_rotation(-45.0) @ BORESIGHT, [c45, -c45, 0.0], atol=1e-15)
    np.testing.assert_allclose(mounting_rotation(0.0, 10.0) @ BORESIGHT, [c10, 0.0, -s10], atol=1e-15)
    np.testing.assert_allclose(mounting_rotation(0.0, 0.0, 10.0) @ ROW, [0.0, c10, s10], atol=1e-15)
    np.testing.assert_allclose(mounting_rotation(-45.0, 10.0) @ BORESIGHT, [c10 * c45, -c10 * c45, -s10], atol=1e-15)
    rot = mounting_rotation(-45.0, 10.0, 5.0)
    np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(rot) > 0.999999
