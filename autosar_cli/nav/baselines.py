"""Reference trajectories: GNSS only, a straight line at constant speed (paper Fig. 10a), and the
simulator's ground truth. Array-in, array-out like SAR-MIN."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from autosar_cli.config import Config
from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.nav.inputs import Measurements, NavInputError, NavInputs
from autosar_cli.nav.trajectory import Trajectory, radar_phase_centres, rear_axle_from_body_point
from autosar_cli.store.drive import radar_clock_reading, stamps_on_navigation_clock
from autosar_cli.types import MotionCorrection

Array = NDArray[np.float64]


def _geometry(config: Config) -> dict[str, float]:
    return {"cog_to_rear_axle_m": config.vehicle.cog_to_rear_axle_m, "cog_height_m": config.vehicle.cog_height_m}


#: the span (s) of the fixes' central differences that stand for the velocity of a receiver logging fixes alone
FIX_VELOCITY_SPAN_S = 2.0


def fix_velocity(pos: Measurements, span_s: float = FIX_VELOCITY_SPAN_S) -> Measurements:
    """The fixes' own velocity (ENU m/s) where a receiver logs no velocity: central differences over about
    ``span_s`` (fixes ``n`` either side, ``n`` the fixes in half of it, at least 1; one-sided at the ends), so a
    fix's white noise sigma leaves sqrt(2) sigma / span_s on it."""
    t, z = pos.t, pos.z[:, :2]
    if len(t) < 2:
        raise NavInputError("the gnss/none baselines need a GNSS velocity stream or at least two fixes")
    rate = (len(t) - 1) / max(float(t[-1] - t[0]), 1e-9)
    n = max(1, round(0.5 * span_s * rate))
    i = np.arange(len(t))
    a, b = np.clip(i - n, 0, len(t) - 1), np.clip(i + n, 0, len(t) - 1)
    v = (z[b] - z[a]) / (t[b] - t[a])[:, None]
    return Measurements(pos.name, t, v, np.full(2, math.sqrt(2.0) * float(pos.sigma[0]) / span_s))


def _ground_velocity(inputs: NavInputs) -> Measurements:
    """The GNSS velocity stream, or the fixes' own where the receiver logs none (:func:`fix_velocity`)."""
    if inputs.gnss_velocity is not None:
        return inputs.gnss_velocity
    assert inputs.gnss_position is not None
    return fix_velocity(inputs.gnss_position)


def _gnss_heading(vel: Measurements, t: Array) -> Array:
    """Course of the ground velocity ``vel`` (rad, ENU), interpolated to ``t``."""
    speed = np.hypot(vel.z[:, 0], vel.z[:, 1])
    ok = speed > 0.3
    if not ok.any():
        raise NavInputError("the vehicle never moves faster than 0.3 m/s: no GNSS course")
    course = np.unwrap(np.arctan2(vel.z[ok, 1], vel.z[ok, 0]))
    return np.interp(t, vel.t[ok], course)


def gnss_only(inputs: NavInputs, config: Config) -> Trajectory:
    """GNSS fixes moved from the antenna to the rear axle with the GNSS course as heading (of the receiver's
    velocity, or of the fixes' own where it logs none)."""
    pos = inputs.gnss_position
    assert pos is not None
    t = pos.t
    vel = _ground_velocity(inputs)
    psi = _gnss_heading(vel, t)
    rear = rear_axle_from_body_point(pos.z, psi, inputs.gnss_lever_m, config.vehicle.cog_to_rear_axle_m)
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


def from_truth(truth_path: str, origin: GeodeticOrigin, config: Config, *, radar_motion: bool = False) -> Trajectory:
    """The simulator's true rear-axle track, re-expressed in the drive's ENU origin.

    ``radar_motion``: also carry, as the trajectory's :attr:`~Trajectory.correction`, the motion of the
    radar's mean phase centre that the planar track lacks (the sidecar's ``radar/phase_centre_enu``: body roll and
    pitch, the grade's fore-aft offset of a radar mounted above the road, vibration), so that its body points
    follow the radar as it really moved. Focusing and the reflector metrics use it; the navigation benchmarks,
    which compare filter states, do not. Its height is the radar's above the road at the start (the grade, the
    body's tilt and heave), which the focusing surface follows (:meth:`Trajectory.height_offset`). Where the
    simulator gave the radar's channels their own phase and gain, its ``info["channel_gains"]`` holds them (focus
    undoes them along it). Where it stamped the radar's frames on a clock of their own (``radar_clock_offset_s``
    late, ``radar_clock_drift_ppm`` fast), the radar's motion is given on that clock less what ``config.radar``
    states of it (:func:`_focus_clock`), so that focusing along it at the frames' stamps (less that) finds the
    radar where it was.
    """

    from autosar_cli.sim.truth import open_truth

    try:
        truth = open_truth(truth_path)
    except ValueError as exc:
        raise NavInputError(str(exc)) from None
    with truth as f:
        tr = f["trajectory"]
        t_ns = tr["t_ns"][()]
        rear = tr["rear_axle_enu"][()]
        heading = np.unwrap(tr["heading"][()])
        speed = tr["speed"][()]
        yaw_rate = tr["yaw_rate"][()]
        truth_origin = GeodeticOrigin(float(f.attrs["origin_lat_deg"]), float(f.attrs["origin_lon_deg"]),
                                      float(f.attrs["origin_height_m"]))
        # the front end's true channel gains, where the simulator put them on: focusing along the truth undoes them
        gains = {"phase_deg": np.asarray(f.attrs["channel_phase_deg"]).tolist(),
                 "gain_db": np.asarray(f.attrs["channel_gain_db"]).tolist()} \
            if np.any(f.attrs.get("channel_phase_deg", 0.0)) or np.any(f.attrs.get("channel_gain_db", 0.0)) else None
        radar = f.get("radar")
        phase_centres = None
        clock_ns = t_ns
        if radar_motion and radar is not None and len(radar["t_ns"]):
            stamps = radar["t_ns"][()]
            on_focus_clock = _focus_clock(int(stamps[0]), config)
            clock_ns = on_focus_clock(_sidecar_clock_reading(f.attrs, int(stamps[0]), t_ns))
            offsets = radar.get("chirp_t_ns")
            phase_centres = (on_focus_clock(stamps), radar["phase_centre_enu"][()],
                             None if offsets is None else on_focus_clock(offsets[()]))
    lat, lon, h = truth_origin.to_geodetic(np.c_[rear, np.zeros(len(rear))])
    enu = origin.to_enu(lat, lon, h)
    # The two tangent planes differ by a tiny rotation: apply it to the heading too.
    ref = truth_origin.to_geodetic(np.c_[rear + np.c_[np.cos(heading), np.sin(heading)], np.zeros(len(rear))])
    ahead = origin.to_enu(*ref)
    psi = np.unwrap(np.arctan2(ahead[:, 1] - enu[:, 1], ahead[:, 0] - enu[:, 0]))
    psi += np.round((heading[0] - psi[0]) / (2 * np.pi)) * 2 * np.pi
    traj = Trajectory("truth", clock_ns, enu[:, :2], psi, speed, yaw_rate, origin, **_geometry(config))
    if gains is not None:
        traj.info = {**traj.info, "channel_gains": gains}
    if phase_centres is not None:
        traj.correction = _radar_motion(traj, truth_origin, config, *phase_centres)
    return traj


def _focus_clock(first_stamp_ns: int, config: Config) -> Callable[[NDArray[np.int64]], NDArray[np.int64]]:
    """The instants (ns) focus reads a drive's radar frames at, from what the sidecar's radar clock reads (ns; its
    first frame stamped ``first_stamp_ns``): that reading less what ``config.radar`` states of the clock
    (store.drive.stamps_on_navigation_clock; :func:`_sidecar_clock_reading` gives the reading of true instants)."""
    return lambda read: stamps_on_navigation_clock(read, first_stamp_ns, config.radar.clock_offset_s,
                                                   config.radar.clock_drift_ppm)


def _sidecar_clock_reading(attrs: Any, first_stamp_ns: int, t_ns: NDArray[np.int64]) -> NDArray[np.int64]:
    """What the sidecar's radar clock reads (ns) at true instants ``t_ns``: its frames stamped
    ``radar_clock_offset_s`` late, counting ``radar_clock_drift_ppm`` fast from the first frame on
    (store.drive.radar_clock_reading)."""
    return radar_clock_reading(t_ns, first_stamp_ns, float(attrs.get("radar_clock_offset_s", 0.0)),
                               float(attrs.get("radar_clock_drift_ppm", 0.0)))


def _radar_motion(planar: Trajectory, truth_origin: GeodeticOrigin, config: Config, frame_t_ns: NDArray[np.int64],
                  phase_centre_enu: Array, chirp_t_ns: NDArray[np.int64] | None) -> MotionCorrection:
    """The true mean phase centre (F, T, R, 3) (ENU m of ``truth_origin``) of every radar frame minus the same
    mean of ``planar``'s antennas at the same chirps, as a correction of ``planar``."""
    inside = (frame_t_ns >= planar.t_ns[0]) & (frame_t_ns <= planar.t_ns[-1])
    t = frame_t_ns[inside]
    true_own = phase_centre_enu[inside].reshape(len(t), -1, 3).mean(axis=1)
    lat, lon, h = truth_origin.to_geodetic(true_own)
    true = planar.origin.to_enu(lat, lon, h)
    offsets_s = (np.zeros(phase_centre_enu.shape[1]) if chirp_t_ns is None
                 else (chirp_t_ns[inside][0] - t[0]) / 1e9)
    pc = radar_phase_centres(planar, t, offsets_s, config)
    modelled = 0.5 * (pc.tx[:, :, None, :] + pc.rx).reshape(len(t), -1, 3).mean(axis=1)
    offset = np.zeros((len(t), 3))
    offset[:, :2] = true[:, :2] - modelled[:, :2]
    # the height in the truth's own frame, whose z = 0 is the road under the start: the drive's frame takes its
    # height from a GNSS fix, decimetres off
    offset[:, 2] = true_own[:, 2] - modelled[:, 2]
    return MotionCorrection(t.astype(np.int64), offset, np.zeros_like(offset))
