"""``autosar navigate``: drive.h5 in, trajectory out, by one of the methods."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from autosar_cli.config import Config
from autosar_cli.nav import models as m
from autosar_cli.nav.baselines import from_truth, gnss_only, straight_line
from autosar_cli.nav.inputs import NavInputError, load_inputs
from autosar_cli.nav.sarmin import run_sarmin
from autosar_cli.nav.trajectory import Trajectory
from autosar_cli.store.drive import Drive

METHODS = ("sar-min", "ins", "gnss", "none", "truth")


def default_truth_path(drive: Drive) -> Path | None:
    """``<log>.truth.h5`` next to the first input log of the drive, if it exists."""
    from autosar_cli.sim.truth import truth_path_for

    if "provenance/inputs" not in drive.h5:
        return None
    for row in drive.h5["provenance/inputs"][()]:
        path = row["path"].decode() if isinstance(row["path"], bytes) else str(row["path"])
        candidate = truth_path_for(Path(path))
        if candidate.exists():
            return candidate
    return None


def navigate(drive_path: str | Path, method: str, config: Config, *, smooth: bool = True,
             truth_path: str | Path | None = None) -> Trajectory:
    """Estimate the trajectory of a drive.h5 with ``method`` (sar-min, ins, gnss, none, truth)."""
    if method not in METHODS:
        raise NavInputError(f"unknown method {method!r} (choose from {', '.join(METHODS)})")
    t0 = time.perf_counter()
    with Drive(drive_path) as drive:
        inputs = load_inputs(drive, config)
        if method == "ins":
            from autosar_cli.nav.ins import load_ins_inputs

            ins_inputs = load_ins_inputs(drive, config, inputs.origin, inputs.t0_ns)
        if method == "truth":
            truth_path = truth_path or default_truth_path(drive)
            if truth_path is None:
                raise NavInputError(f"{drive_path}: no truth sidecar found; give --truth LOG.truth.h5")
    if method == "sar-min":
        sol = run_sarmin(inputs, config, smooth=smooth)
        t_ns = inputs.t0_ns + np.round(sol.t * 1e9).astype(np.int64)
        traj = Trajectory("sar-min", t_ns, sol.x[:, [m.PX, m.PY]], np.unwrap(sol.x[:, m.PSI]), sol.x[:, m.V],
                          sol.x[:, m.OMEGA], inputs.origin, config.vehicle.cog_to_rear_axle_m,
                          config.vehicle.cog_height_m, state=sol.x, state_names=sol.state_names,
                          covariance=sol.P, rear_slip_gain=config.vehicle.rear_slip_gain_rad_per_mps2,
                          info={"updates": sol.updates, "rejected": sol.rejected,
                                                  "smoothed": smooth})
    elif method == "ins":
        from autosar_cli.nav.ins import run_ins

        traj = run_ins(ins_inputs, config)
    elif method == "gnss":
        traj = gnss_only(inputs, config)
    elif method == "none":
        traj = straight_line(inputs, config)
    else:
        traj = from_truth(str(truth_path), inputs.origin, config)
        traj.info["truth"] = str(truth_path)
    traj.info["drive"] = str(drive_path)
    traj.info["elapsed_s"] = time.perf_counter() - t0
    return traj
