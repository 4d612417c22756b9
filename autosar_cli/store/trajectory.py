"""trajectory.h5 (format ``autosar-trajectory`` version 1): what navigate writes and focus reads.

Datasets (K samples): ``t_ns`` int64; ``rear_axle_enu`` (K, 2) m; ``position_enu`` (K, 3) m of the CoG;
``heading`` (K,) rad (ENU, unwrapped); ``speed`` (K,) m/s; ``yaw_rate`` (K,) rad/s; for sar-min also
``state`` (K, n) with attribute ``names`` and ``covariance`` (K, n, n). Attributes: ``method``,
``origin_lat_deg``, ``origin_lon_deg``, ``origin_height_m`` (road surface), ``cog_to_rear_axle_m``,
``cog_height_m``, ``rear_slip_gain`` (body yaw = heading + gain x speed x yaw rate), ``info`` (JSON: updates,
rejections, inputs), ``autosar_version``. A motion
correction (the body's roll and pitch, the autofocus's), where there is one, is the group ``correction`` with
``t_ns`` (M,), ``offset_enu`` (M, 3) m and ``std_enu`` (M, 3) m. Written atomically.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from autosar_cli import __version__
from autosar_cli.store.atomic import partial_path
from autosar_cli.store.attr_checksum import attributes_damage, stamp_attributes
from autosar_cli.store.hdf5_read import DamagedFileError, open_hdf5, read_dataset
from autosar_cli.store.outputs import SMALL_FILE_MARGIN_BYTES, check_free_space, not_the_format
from autosar_cli.types import GeodeticOrigin, MotionCorrection, Trajectory

FORMAT = "autosar-trajectory"
FORMAT_VERSION = 1


class TrajectoryFormatError(ValueError):
    """Not a trajectory.h5 this version reads."""


def write_trajectory(path: str | Path, traj: Trajectory, attrs: dict[str, Any] | None = None) -> Path:
    path = Path(path)
    arrays = (traj.t_ns, traj.rear_axle_enu, traj.heading, traj.speed, traj.yaw_rate, traj.state, traj.covariance)
    # the CoG positions (K, 3) are 1.5 times the rear axle's (K, 2)
    needed = sum(a.nbytes for a in arrays if a is not None) + traj.rear_axle_enu.nbytes * 3 // 2
    check_free_space(path, needed, "the trajectory", SMALL_FILE_MARGIN_BYTES)
    partial = partial_path(path)
    try:
        with h5py.File(partial, "w") as f:
            f.attrs.update({"format": FORMAT, "format_version": FORMAT_VERSION, "autosar_version": __version__,
                            "method": traj.method, "origin_lat_deg": traj.origin.lat_deg,
                            "origin_lon_deg": traj.origin.lon_deg, "origin_height_m": traj.origin.height_m,
                            "cog_to_rear_axle_m": traj.cog_to_rear_axle_m, "cog_height_m": traj.cog_height_m,
                            "rear_slip_gain": traj.rear_slip_gain,
                            "info": json.dumps(traj.info), **(attrs or {})})
            # Fletcher-32 checksums: a flipped byte is a read error, not a different track
            f.create_dataset("t_ns", data=traj.t_ns, fletcher32=True)
            f.create_dataset("rear_axle_enu", data=traj.rear_axle_enu, fletcher32=True)
            f.create_dataset("position_enu", data=traj.cog_enu, fletcher32=True)
            for name in ("heading", "speed", "yaw_rate"):
                f.create_dataset(name, data=getattr(traj, name), fletcher32=True)
            if traj.state is not None:
                f.create_dataset("state", data=traj.state, compression="lzf", fletcher32=True)
                f["state"].attrs["names"] = json.dumps(traj.state_names)
            if traj.covariance is not None:
                # uncompressed: lzf saved 8 % of test1's 28 MB for 0.33 s of writing and 0.15 s of reading (gzip-1
                # 23 % for 0.63 s); raw it takes 0.03 s each way (measured)
                f.create_dataset("covariance", data=traj.covariance, fletcher32=True)
            if traj.correction is not None:
                g = f.create_group("correction")
                for name in ("t_ns", "offset_enu", "std_enu"):
                    g.create_dataset(name, data=getattr(traj.correction, name), fletcher32=True)
            stamp_attributes(f)  # the georeference and the info, which no dataset checksum covers
        os.replace(partial, path)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    return path


def read_trajectory(path: str | Path, *, covariance: bool = True) -> Trajectory:
    """Read a trajectory.h5; ``covariance=False`` leaves out the (K, n, n) covariance (28 MB on test1), which
    focusing does not use."""
    path = Path(path)
    with open_hdf5(path, TrajectoryFormatError) as f:
        if f.attrs.get("format") != FORMAT:
            raise TrajectoryFormatError(not_the_format(path, f.attrs.get("format"), FORMAT))
        version = f.attrs.get("format_version")
        if version is None:
            raise TrajectoryFormatError(f"{path}: has no format_version attribute (damaged trajectory.h5)")
        if (why := attributes_damage(f)) is not None:
            raise TrajectoryFormatError(f"{path}: {why}; damaged trajectory.h5")
        if int(version) > FORMAT_VERSION:
            raise TrajectoryFormatError(f"{path}: format version {version} is too new")
        a = f.attrs
        try:
            origin = GeodeticOrigin(float(a["origin_lat_deg"]), float(a["origin_lon_deg"]),
                                    float(a["origin_height_m"]))
            method, lever, height = str(a["method"]), float(a["cog_to_rear_axle_m"]), float(a["cog_height_m"])
        except KeyError as exc:
            raise TrajectoryFormatError(f"{path}: attribute {exc.args[0]} is missing") from None
        try:
            traj = _trajectory_of(f, path, method, origin, lever, height, covariance)
        except DamagedFileError as exc:  # nothing of a track is usable without the rest: it is cheap to make again
            raise DamagedFileError(f"{exc}; make the trajectory again from its drive (autosar navigate)") from None
    check_plausible(traj, path)
    return traj


def _trajectory_of(f: h5py.File, path: Path, method: str, origin: GeodeticOrigin, lever: float, height: float,
                   covariance: bool) -> Trajectory:
    """The trajectory of an open trajectory.h5 (``covariance``: with it), its attributes read."""
    a = f.attrs
    return Trajectory(
        method, read_dataset(f, "t_ns", path), read_dataset(f, "rear_axle_enu", path),
        read_dataset(f, "heading", path), read_dataset(f, "speed", path), read_dataset(f, "yaw_rate", path),
        origin, lever, height,
        state=read_dataset(f, "state", path) if "state" in f else None,
        state_names=json.loads(f["state"].attrs["names"]) if "state" in f else [],
        covariance=read_dataset(f, "covariance", path) if covariance and "covariance" in f else None,
        info=json.loads(a.get("info", "{}")),
        correction=MotionCorrection(*(read_dataset(f, f"correction/{name}", path) for name in
                                      ("t_ns", "offset_enu", "std_enu"))) if "correction" in f else None,
        rear_slip_gain=float(a.get("rear_slip_gain", 0.0)),
    )


#: Limits of a car's motion that no trajectory may exceed (a damaged file or a diverged filter does).
MAX_SPEED_MPS = 100.0
MAX_YAW_RATE_RADPS = 10.0  # ~6x a car at full lock; GNSS-course baselines are noisy at walking pace
#: Steps between successive samples always allowed: the baselines' headings switch source (the INS's yaw
#: below 0.5 m/s, its course above) and GNSS positions jump by their noise, both within one IMU sample.
MAX_HEADING_STEP_RAD = np.pi / 2
MAX_POSITION_STEP_M = 5.0


def check_plausible(traj: Trajectory, path: str | Path) -> None:
    """Refuse a trajectory that no car drove: non-finite values, time not increasing, stored speed or yaw
    rate beyond MAX_SPEED_MPS / MAX_YAW_RATE_RADPS, or a step between successive positions (headings) larger
    than both MAX_POSITION_STEP_M (MAX_HEADING_STEP_RAD) and what those limits allow in its time."""
    t = np.asarray(traj.t_ns, dtype=np.int64)
    if len(t) < 2:
        raise TrajectoryFormatError(f"{path}: holds {len(t)} sample(s); a trajectory needs at least 2")
    if np.any(np.diff(t) <= 0):
        k = int(np.argmax(np.diff(t) <= 0))
        raise TrajectoryFormatError(f"{path}: t_ns does not increase at sample {k + 1}")
    dt = np.diff(t) / 1e9
    xy = np.asarray(traj.rear_axle_enu, np.float64)
    heading = np.asarray(traj.heading, np.float64)
    checks = (  # name, values, per-sample limit (None: finite only), unit
        ("rear_axle_enu", xy, None, "m"),
        ("heading", heading, None, "rad"),
        ("speed", np.abs(np.asarray(traj.speed, np.float64)), MAX_SPEED_MPS, "m/s"),
        ("yaw_rate", np.abs(np.asarray(traj.yaw_rate, np.float64)), MAX_YAW_RATE_RADPS, "rad/s"),
        ("step between positions", np.hypot(*np.diff(xy, axis=0).T),
         np.maximum(MAX_POSITION_STEP_M, MAX_SPEED_MPS * dt), "m"),
        ("step between headings", np.abs(np.diff(heading)),
         np.maximum(MAX_HEADING_STEP_RAD, MAX_YAW_RATE_RADPS * dt), "rad"),
    )
    for name, values, limit, unit in checks:
        bad = ~np.isfinite(values) if limit is None else ~(values <= limit)
        if bad.ndim > 1:
            bad = bad.any(axis=tuple(range(1, bad.ndim)))
        if bad.any():
            k = int(np.argmax(bad))
            shown = values[k].tolist() if values.ndim > 1 else f"{values[k]:.4g} {unit}"
            lim = limit if limit is None or np.isscalar(limit) else limit[k]
            what = "is not finite" if lim is None else f"exceeds {lim:.4g} {unit}"
            raise TrajectoryFormatError(f"{path}: {name} {what} at sample {k} ({shown}); the file is damaged or "
                                        f"the navigation diverged")
