"""``autosar navigate``: drive.h5 in, trajectory out, by one of the methods."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from autosar_cli.config import Config
from autosar_cli.nav import models as m
from autosar_cli.nav.baselines import from_truth, gnss_only, straight_line
from autosar_cli.nav.inputs import NavInputError, NavInputs, load_inputs
from autosar_cli.nav.sarmin import NavSolution, run_sarmin
from autosar_cli.nav.trajectory import Trajectory
from autosar_cli.nav.understeer import fit_understeer
from autosar_cli.nav.wheel_lag import fit_wheel_lag, lag_compensated_wheels
from autosar_cli.store.drive import Drive

METHODS = ("sar-min", "ins", "gnss", "none", "truth")
SIGNIFICANT = 3.0  # a fitted lag or gradient is applied where it differs from the default by more stds than this
# ... and by more than these: a tenth of a sedan's understeer gradient (rad per m/s^2), 5 ms of yaw lag, 1 cm of
# wheel-speed lag distance. Smaller ones, significant or not, are below what changes a track: a kinematic drive's
# sensors show sub-millisecond timing offsets at several sigma
MIN_UNDERSTEER_CHANGE = 2e-4
MIN_YAW_LAG_S = 0.005
MIN_WHEEL_LAG_M = 0.01


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


def _shows(change: float, std: float, minimum: float) -> bool:
    """Whether a fitted change from the default is both significant and large enough to matter."""
    return abs(change) > SIGNIFICANT * std and abs(change) > minimum


def wheel_lag_compensated(inputs: NavInputs, config: Config) -> tuple[NavInputs, dict]:
    """The inputs with the wheel samples moved back by their fitted lag (:mod:`.wheel_lag`) where
    ``navigation.estimate_wheel_lag`` is on, the fit's std is small enough and the lag differs from 0 by more than
    ``SIGNIFICANT`` of them; and what the fit found."""
    nav = config.navigation
    if not nav.estimate_wheel_lag:
        return inputs, {"applied": False, "reason": "navigation.estimate_wheel_lag is off"}
    fit = fit_wheel_lag(inputs)
    if fit is None:
        return inputs, {"applied": False, "reason": "no wheel speeds, GNSS velocity, or motion above 1 m/s"}
    if not fit.std_m <= nav.wheel_lag_max_std_m:
        return inputs, replace(fit, reason=f"std {fit.std_m:.2g} m above navigation.wheel_lag_max_std_m (a / v "
                                           f"{fit.accel_over_speed_rms:.2f} 1/s RMS): samples as stamped").to_dict()
    if not _shows(fit.lag_distance_m, fit.std_m, MIN_WHEEL_LAG_M):
        return inputs, replace(fit, reason=f"lag within {SIGNIFICANT:g} std or {MIN_WHEEL_LAG_M} m of 0: samples as "
                                           "stamped").to_dict()
    moved = replace(inputs, wheels=lag_compensated_wheels(inputs.wheels, fit))
    return moved, replace(fit, applied=True, reason="fitted to the drive").to_dict()


def sarmin_with_understeer(inputs: NavInputs, config: Config, smooth: bool = True) -> tuple[NavSolution, dict]:
    """SAR-MIN; with ``navigation.estimate_understeer``, first without the steering, and the steering's understeer
    gradient and yaw lag fitted against the gyros on that pass (:mod:`.understeer`). Where the drive shows the car
    steering otherwise than the kinematic bicycle (K off the vehicle's, or a yaw lag, by more than ``SIGNIFICANT``
    std and the ``MIN_*`` sizes) that pass is the solution: the steering is left out. Else SAR-MIN runs again with
    the steering. Returns the solution and what the fit found, and why the steering was or was not used."""
    nav, veh = config.navigation, config.vehicle
    vehicle_k = {"applied": False, "gradient": veh.understeer_gradient_rad_per_mps2}
    if not nav.estimate_understeer or inputs.steering is None:
        why = "navigation.estimate_understeer is off" if inputs.steering else "no steering"
        return run_sarmin(inputs, config, smooth=smooth), {**vehicle_k, "reason": f"{why}: the steering as recorded"}
    first = run_sarmin(replace(inputs, steering=None), config, smooth=smooth)
    scales = [i for i, name in enumerate(first.state_names) if name.startswith("scale.wheel_")]
    common_scale_std = float(np.sqrt(first.P[-1][np.ix_(scales, scales)].sum())) / len(scales)
    fit = fit_understeer(inputs, first.t, first.x, veh.wheelbase_m, nav.steering_min_speed_mps, common_scale_std)
    if fit is None:
        info = {**vehicle_k, "reason": "no steering samples above navigation.steering_min_speed_mps: the steering "
                                       "as recorded"}
    elif not fit.std <= nav.understeer_max_std_rad_per_mps2:
        info = replace(fit, reason=f"K's std {fit.std:.2g} above navigation.understeer_max_std_rad_per_mps2 "
                                   f"(lateral acceleration {fit.lateral_accel_rms_mps2:.2f} m/s^2 RMS): the steering "
                                   "as recorded").to_dict()
    elif not (_shows(fit.gradient - veh.understeer_gradient_rad_per_mps2, fit.std, MIN_UNDERSTEER_CHANGE)
              or (_shows(fit.yaw_lag_coefficient_s2, fit.yaw_lag_coefficient_std_s2, 0.0)
                  and abs(fit.yaw_lag_s) > MIN_YAW_LAG_S)):
        info = replace(fit, reason=f"K within {SIGNIFICANT:g} std or {MIN_UNDERSTEER_CHANGE:g} of the vehicle's and "
                                   f"the lag within {SIGNIFICANT:g} std or {MIN_YAW_LAG_S * 1000:g} ms of 0: the "
                                   "steering as recorded").to_dict()
    else:
        return first, replace(fit, applied=True, reason="the car does not steer as the kinematic bicycle: navigated "
                                                        "without the steering").to_dict()
    return run_sarmin(inputs, config, smooth=smooth), info


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
        inputs, wheel_lag = wheel_lag_compensated(inputs, config)
        sol, understeer = sarmin_with_understeer(inputs, config, smooth=smooth)
        t_ns = inputs.t0_ns + np.round(sol.t * 1e9).astype(np.int64)
        traj = Trajectory("sar-min", t_ns, sol.x[:, [m.PX, m.PY]], np.unwrap(sol.x[:, m.PSI]), sol.x[:, m.V],
                          sol.x[:, m.OMEGA], inputs.origin, config.vehicle.cog_to_rear_axle_m,
                          config.vehicle.cog_height_m, state=sol.x, state_names=sol.state_names,
                          covariance=sol.P, rear_slip_gain=config.vehicle.rear_slip_gain_rad_per_mps2,
                          info={"updates": sol.updates, "rejected": sol.rejected, "smoothed": smooth,
                                "understeer": understeer, "wheel_lag": wheel_lag})
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
