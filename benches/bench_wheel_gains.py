"""Benchmark SAR-MIN's wheel-speed fit against the truth: are its slip gains and lag what the wheels really do?

Usage: python benches/bench_wheel_gains.py [--scenarios test1,test2,test3,urban] [--seeds 0-9]
                                           [--true-gnss-velocity] [--output benches/results/wheel_gains.json]

For every drive (``simulate --dynamics full`` with the radar at 20 Hz, as bench_nav_seeds.py: the navigation
sensors' samples are those of the full simulation), ``ingest``, then the longitudinal fit that SAR-MIN applies
(``nav.wheel_speeds.fit_wheel_speeds``: each axle's mean wheel speed less the GNSS speed moved to the rear axle,
regressed on the speed, the lag's ``-a / v`` and the slip's ``a v`` split at ``a = 0``, conditioned on the wheel
sensor's stated window), and the same regression with the GNSS speed replaced by the truth's rear-axle speed at the
same instants: what the wheels' lag and slip are under that model, with no GNSS noise. Per gain and drive: the
fitted value, its stated std, the truth's, and the z-score (fitted - truth) / std; the summary gives each gain's
mean and RMS z over the drives (a mean away from 0 is a bias of the fit, an RMS above 1 a std stated too small)
and its mean error. The ``alone_`` entries are the same fit on every drive without the stated window: the window
conditions only the drives whose own lag agrees with it, so the other drives' errors lean one way, and only the
unconditioned set says how the fit's std compares with its error. ``--true-gnss-velocity`` gives the fit the GNSS
receiver's true velocity (the sidecar's, no noise; ``--scenarios test1 --seeds 0,2,6 --true-gnss-velocity --output
/tmp/w.json``): what is left is not the GNSS's.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_nav_seeds import NAV_ONLY_PRF_HZ  # noqa: E402
from bench_paper import parse_seeds  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
NAMES = ("lag_m", "front_drive", "front_brake", "rear_drive", "rear_brake")


def truth_regression(inputs: Any, truth: Any, wheelbase_m: float, min_speed_mps: float = 1.0) -> dict[str, float]:
    """The longitudinal regression of ``nav.wheel_speeds._fit_longitudinal`` (``longitudinal_regression``, at the
    GNSS velocity's instants) against the truth's rear-axle speed: c and the four slip gains."""
    from autosar_cli.nav.wheel_speeds import (
        ACCEL_WINDOW_S,
        longitudinal_regression,
        raw_gyro_yaw_rate,
        wheel_acceleration,
    )

    wheels, gnss = inputs.wheels, inputs.gnss_velocity
    inside = (gnss.t > wheels.t[0] + ACCEL_WINDOW_S) & (gnss.t < wheels.t[-1] - ACCEL_WINDOW_S)
    ts = gnss.t[inside]
    t_ns = inputs.t0_ns + np.round(ts * 1e9).astype(np.int64)
    v = np.interp(t_ns, truth.t_ns, np.abs(truth.speed), left=np.nan, right=np.nan)
    w = np.nan_to_num(raw_gyro_yaw_rate(inputs, ts))
    use = v >= min_speed_mps  # (NaN outside the truth's span: False)
    ts, v, w = ts[use], v[use], w[use]
    design, y = longitudinal_regression(wheels, ts, v, w, wheel_acceleration(wheels, ts), wheelbase_m)
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    return dict(zip(NAMES, (float(c) for c in coef[2:]), strict=True))


def true_gnss_velocity(inputs: Any, truth_path: Path, sensor: str) -> Any:
    """``inputs`` with the GNSS velocity replaced by the receiver's true velocity at the same instants."""
    import h5py

    with h5py.File(truth_path, "r") as f:
        g = f[f"sensors/{sensor}"]
        t = (g["t_ns"][:] - inputs.t0_ns) / 1e9
        true = g["velocity_enu"][:, :2]
    gv = inputs.gnss_velocity
    z = np.stack([np.interp(gv.t, t, true[:, k]) for k in range(2)], axis=1)
    return dataclasses.replace(inputs, gnss_velocity=dataclasses.replace(gv, z=z))


def measure(scenario: str, seed: int, config: Any, work: Path, true_velocity: bool = False) -> dict[str, Any]:
    from autosar_cli.ingest.pipeline import ingest
    from autosar_cli.nav.baselines import from_truth
    from autosar_cli.nav.inputs import load_inputs
    from autosar_cli.nav.sarmin import gnss_lever_rear
    from autosar_cli.nav.wheel_speeds import fit_wheel_speeds
    from autosar_cli.sim.simulate import simulate
    from autosar_cli.store.drive import Drive

    log = work / f"{scenario}_s{seed}.mcap"
    sim = simulate(scenario, log, seed=seed, config=config, dynamics="full")
    drive = work / f"{scenario}_s{seed}.h5"
    ingest([log], drive, config=config)
    with Drive(drive) as d:
        inputs = load_inputs(d, config)
    if true_velocity:
        inputs = true_gnss_velocity(inputs, Path(sim.truth_path), config.navigation.gnss)
    veh = config.vehicle
    geometry = (gnss_lever_rear(inputs, config), veh.wheelbase_m, (veh.track_front_m, veh.track_rear_m))
    # the same fit on every drive without the stated window too: which drives the window conditions depends on
    # their own error, so only that set says whether the fit's std is its error's
    fits = {"": fit_wheel_speeds(inputs, *geometry),
            "alone_": fit_wheel_speeds(dataclasses.replace(inputs, wheel_lag_prior_m=(0.0, 0.0)), *geometry)}
    truth = from_truth(str(sim.truth_path), inputs.origin, config)
    true = truth_regression(inputs, truth, veh.wheelbase_m)
    for p in (log, drive, sim.truth_path):
        Path(p).unlink(missing_ok=True)
    row: dict[str, Any] = {"scenario": scenario, "seed": seed}
    for prefix, (lag, radii) in fits.items():
        if lag is None or radii is None:
            return {**row, "skipped": "no longitudinal fit"}
        fitted = {"lag_m": (lag.lag_distance_m, lag.std_m),
                  **{k: (radii.slip_gain[k], radii.slip_gain_std[k]) for k in NAMES[1:]}}
        for k in NAMES:
            value, std = fitted[k]
            row[prefix + k] = {"fitted": round(value, 5), "std": round(std, 5), "truth": round(true[k], 5),
                               "z": round((value - true[k]) / std, 3) if std > 0 else None}
    return row


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {"drives": len(rows)}
    for k in (*NAMES, *(f"alone_{k}" for k in NAMES)):
        z = np.array([r[k]["z"] for r in rows if k in r and r[k]["z"] is not None])
        err = np.array([r[k]["fitted"] - r[k]["truth"] for r in rows if k in r])
        if len(z):
            out[f"{k}_z_mean"] = round(float(z.mean()), 3)
            out[f"{k}_z_rms"] = round(float(np.sqrt(np.mean(z**2))), 3)
            out[f"{k}_error_mean"] = round(float(err.mean()), 5)
    return out


def main() -> None:
    from autosar_cli.config import load_config

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", default="test1,test2,test3,urban")
    ap.add_argument("--seeds", default="0-9")
    ap.add_argument("--true-gnss-velocity", action="store_true",
                    help="fit on the GNSS receiver's true velocity (a diagnostic: what is left is not the GNSS's)")
    ap.add_argument("--output", type=Path, default=RESULTS / "wheel_gains.json")
    args = ap.parse_args()
    base = load_config()
    config = dataclasses.replace(base, radar=dataclasses.replace(base.radar, prf_hz=NAV_ONLY_PRF_HZ))
    rows: list[dict[str, Any]] = []
    summary: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for scenario in args.scenarios.split(","):
            start = time.perf_counter()
            these = [measure(scenario, seed, config, Path(tmp), args.true_gnss_velocity)
                     for seed in parse_seeds(args.seeds)]
            rows += these
            summary[scenario] = s = summarise([r for r in these if "skipped" not in r])
            gains = ", ".join(f"{k} z {s[f'{k}_z_mean']:+.2f} mean / {s[f'{k}_z_rms']:.2f} RMS"
                              for k in (*NAMES, "alone_lag_m", "alone_rear_drive") if f"{k}_z_mean" in s)
            print(f"{scenario}: {s['drives']} drives; {gains} ({time.perf_counter() - start:.0f} s)", flush=True)
    summary["all"] = summarise([r for r in rows if "skipped" not in r])
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps({"benchmark": "wheel_gains", "radar_prf_hz": NAV_ONLY_PRF_HZ,
                                       "summary": summary, "rows": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
