"""Reference trajectories: GNSS only, a straight line at constant speed (paper Fig. 10a), and the
simulator's ground truth. Array-in, array-out like SAR-MIN."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from autosar_cli.config import Config
from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.nav.inputs import NavInputError, NavInputs
from autosar_cli.nav.trajectory import Trajectory, rear_axle_from_body_point

Array = NDArray[np.float64]


def _geometry(config: Config) -> dict[str, float]:
    return {"cog_to_rear_axle_m": config.vehicle.cog_to_rear_axle_m, "cog_height_m": config.vehicle.cog_height_m}


def _gnss_heading(inputs: NavInputs, t: Array) -> Array:
    """Course of the GNSS velocity (rad, ENU), interpolated to ``t``; needs a velocity stream."""
    vel = inputs.gnss_velocity
    if vel is None:
        raise NavInputError("the gnss/none baselines need a GNSS velocity stream")
    speed = np.hypot(vel.z[:, 0], vel.z[:, 1])
    ok = speed > 0.3
    if not ok.any():
        raise NavInputError("the vehicle never moves faster than 0.3 m/s: no GNSS course")
    course = np.unwrap(np.arctan2(vel.z[ok, 1], vel.z[ok, 0]))
    return np.interp(t, vel.t[ok], course)


def gnss_only(inputs: NavInputs, config: Config) -> Trajectory:
    """GNSS fixes moved from the antenna to the rear axle with the GNSS course as heading."""
    pos = inputs.gnss_position
    assert pos is not None
    t = pos.t
    psi = _gnss_heading(inputs, t)
    rear = rear_axle_from_body_point(pos.z, psi, inputs.gnss_lever_m, config.vehicle.cog_to_rear_axle_m)
    vel = inputs.gnss_velocity
    assert vel is not None
    speed = np.interp(t, vel.t, np.hypot(vel.z[:, 0], vel.z[:, 1]))
    yaw_rate = np.gradient(psi, t) if len(t) > 1 else np.zeros_like(t)
    t_ns = inputs.t0_ns + np.round(t * 1e9).astype(np.int64)
    return Trajectory("gnss", t_ns, rear, psi, speed, yaw_rate, inputs.origin, **_geometry(config))


def straight_line(inputs: NavInputs, config: Config) -> Trajectory:
    """No navigation: a straight line from the first to the last GNSS fix at constant speed."""
    gnss = gnss_only(inputs, config)
    if len(gnss.t_ns) < 2:
        raise NavInputError("the straight-line baseline needs at least two GNSS fixes")
    t = gnss.t
    a, b = gnss.rear_axle_enu[0], gnss.rear_axle_enu[-1]
    span = t[-1] - t[0]
    direction = (b - a) / span
    k = np.linspace(0.0, 1.0, 1001)
    tt = t[0] + k * span
    rear = a + np.outer(tt - t[0], direction)
    n = len(tt)
    psi = np.full(n, float(np.arctan2(direction[1], direction[0])))
    t_ns = gnss.t_ns[0] + np.round((tt - t[0]) * 1e9).astype(np.int64)
    return Trajectory("none", t_ns, rear, psi, np.full(n, float(np.hypot(*direction))), np.zeros(n),
                      inputs.origin, **_geometry(config))


def from_truth(truth_path: str, origin: GeodeticOrigin, config: Config) -> Trajectory:
    """The simulator's true rear-axle track, re-expressed in the drive's ENU origin."""
    import h5py

    with h5py.File(truth_path, "r") as f:
        if f.attrs.get("format") != "autosar-truth":
            raise NavInputError(f"{truth_path}: not an autosar truth sidecar")
        tr = f["trajectory"]
        t_ns = tr["t_ns"][()]
        rear = tr["rear_axle_enu"][()]
        heading = np.unwrap(tr["heading"][()])
        speed = tr["speed"][()]
        yaw_rate = tr["yaw_rate"][()]
        truth_origin = GeodeticOrigin(float(f.attrs["origin_lat_deg"]), float(f.attrs["origin_lon_deg"]),
                                      float(f.attrs["origin_height_m"]))
    lat, lon, h = truth_origin.to_geodetic(np.c_[rear, np.zeros(len(rear))])
    enu = origin.to_enu(lat, lon, h)
    # The two tangent planes differ by a tiny rotation: apply it to the heading too.
    ref = truth_origin.to_geodetic(np.c_[rear + np.c_[np.cos(heading), np.sin(heading)], np.zeros(len(rear))])
    ahead = origin.to_enu(*ref)
    psi = np.unwrap(np.arctan2(ahead[:, 1] - enu[:, 1], ahead[:, 0] - enu[:, 0]))
    psi += np.round((heading[0] - psi[0]) / (2 * np.pi)) * 2 * np.pi
    return Trajectory("truth", t_ns, enu[:, :2], psi, speed, yaw_rate, origin, **_geometry(config))
