"""trajectory.h5 (format ``autosar-trajectory`` version 1): what navigate writes and focus reads.

Datasets (K samples): ``t_ns`` int64; ``rear_axle_enu`` (K, 2) m; ``position_enu`` (K, 3) m of the CoG;
``heading`` (K,) rad (ENU, unwrapped); ``speed`` (K,) m/s; ``yaw_rate`` (K,) rad/s; for sar-min also
``state`` (K, n) with attribute ``names`` and ``covariance`` (K, n, n). Attributes: ``method``,
``origin_lat_deg``, ``origin_lon_deg``, ``origin_height_m`` (road surface), ``cog_to_rear_axle_m``,
``cog_height_m``, ``info`` (JSON: updates, rejections, inputs), ``autosar_version``. Written atomically.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import h5py

from autosar_cli import __version__
from autosar_cli.types import GeodeticOrigin, Trajectory

FORMAT = "autosar-trajectory"
FORMAT_VERSION = 1


class TrajectoryFormatError(ValueError):
    """Not a trajectory.h5 this version reads."""


def write_trajectory(path: str | Path, traj: Trajectory, attrs: dict[str, Any] | None = None) -> Path:
    path = Path(path)
    partial = path.with_name(path.name + ".partial")
    try:
        with h5py.File(partial, "w") as f:
            f.attrs.update({"format": FORMAT, "format_version": FORMAT_VERSION, "autosar_version": __version__,
                            "method": traj.method, "origin_lat_deg": traj.origin.lat_deg,
                            "origin_lon_deg": traj.origin.lon_deg, "origin_height_m": traj.origin.height_m,
                            "cog_to_rear_axle_m": traj.cog_to_rear_axle_m, "cog_height_m": traj.cog_height_m,
                            "info": json.dumps(traj.info), **(attrs or {})})
            f["t_ns"] = traj.t_ns
            f["rear_axle_enu"] = traj.rear_axle_enu
            f["position_enu"] = traj.cog_enu
            for name in ("heading", "speed", "yaw_rate"):
                f[name] = getattr(traj, name)
            if traj.state is not None:
                f.create_dataset("state", data=traj.state, compression="lzf")
                f["state"].attrs["names"] = json.dumps(traj.state_names)
            if traj.covariance is not None:
                # uncompressed: lzf saved 8 % of test1's 28 MB for 0.33 s of writing and 0.15 s of reading (gzip-1
                # 23 % for 0.63 s); raw it takes 0.03 s each way (measured)
                f.create_dataset("covariance", data=traj.covariance)
        os.replace(partial, path)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    return path


def read_trajectory(path: str | Path, *, covariance: bool = True) -> Trajectory:
    """Read a trajectory.h5; ``covariance=False`` leaves out the (K, n, n) covariance (28 MB on test1), which
    focusing does not use."""
    path = Path(path)
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise TrajectoryFormatError(f"{path}: not an HDF5 file ({exc})") from exc
    with f:
        if f.attrs.get("format") != FORMAT:
            raise TrajectoryFormatError(f"{path}: not a trajectory.h5 (format {f.attrs.get('format')!r})")
        if int(f.attrs["format_version"]) > FORMAT_VERSION:
            raise TrajectoryFormatError(f"{path}: format version {f.attrs['format_version']} is too new")
        a = f.attrs
        origin = GeodeticOrigin(float(a["origin_lat_deg"]), float(a["origin_lon_deg"]), float(a["origin_height_m"]))
        return Trajectory(
            str(a["method"]), f["t_ns"][()], f["rear_axle_enu"][()], f["heading"][()], f["speed"][()],
            f["yaw_rate"][()], origin, float(a["cog_to_rear_axle_m"]), float(a["cog_height_m"]),
            state=f["state"][()] if "state" in f else None,
            state_names=json.loads(f["state"].attrs["names"]) if "state" in f else [],
            covariance=f["covariance"][()] if covariance and "covariance" in f else None,
            info=json.loads(a.get("info", "{}")),
        )
