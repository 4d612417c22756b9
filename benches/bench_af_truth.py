"""Benchmark the autofocus's track scale on the truth track: what each effect of the full vehicle model biases it by.

Usage: python benches/bench_af_truth.py [--scenario test1] [--seeds 0,9]
                                        [--components "kinematic;body;road;;slip,tyre_radius,wheel_ticks"]
                                        [--car KEY=VALUE,...] [--append]
                                        [--output benches/results/af_truth_scale.json]

For every seed and components set (``kinematic``: the kinematic car; otherwise the full model with only those
effects, empty: none of them): ``simulate``, ``ingest``, then the residual-motion autofocus
(``sar.autofocus_stage.autofocus_residual_motion``) on the simulator's own truth track. The truth's scale is
exact, so the scale the autofocus applies to it is its bias there, to compare with its stated std; the same on
the truth track carrying the radar's motion as the IMU's roll and pitch move it (``navigate.with_attitude``, what
SAR-MIN's trajectory carries); and on the truth track carrying the radar's true 6-DOF motion
(``from_truth(radar_motion=True)``: the sidecar's phase centres). With the IMU's roll and pitch it also runs
with the road's grade left in the points' apertures (``AutofocusOptions(grade_stretch=False)``), for an A/B.
``--car``: entries of the simulated car's [vehicle_dynamics] (e.g. ``road_grade_percent=4.0``). Prints one line
per drive and writes the rows as JSON (``--scenario test1 --seeds 0,9 --components road``:
benches/results/af_truth_scale.json; ``--append``: added to its rows).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
import time
from pathlib import Path
from typing import Any

RESULTS = Path(__file__).resolve().parent / "results"


def measure(scenario: str, seed: int, components: str, work: Path, car: str | None = None) -> dict[str, Any]:
    from bench_paper import config_copy

    from autosar_cli.config import load_config
    from autosar_cli.ingest.pipeline import ingest
    from autosar_cli.nav.baselines import from_truth
    from autosar_cli.nav.inputs import load_inputs
    from autosar_cli.nav.navigate import body_attitude, navigate, with_attitude
    from autosar_cli.sar.autofocus_stage import autofocus_residual_motion
    from autosar_cli.sar.residual_motion import AutofocusOptions
    from autosar_cli.sim.simulate import simulate
    from autosar_cli.store.drive import Drive

    config = load_config(config_copy(None, None, work, car=car) if car else None)
    dynamics = "kinematic" if components == "kinematic" else "full"
    if dynamics == "full":
        wanted = tuple(c for c in components.split(",") if c)
        config = dataclasses.replace(config, vehicle_dynamics=dataclasses.replace(config.vehicle_dynamics,
                                                                                  components=wanted))
    log = work / f"{scenario}_s{seed}.mcap"
    sim = simulate(scenario, log, seed=seed, config=config, dynamics=dynamics)  # type: ignore[arg-type]
    drive = work / f"{scenario}_s{seed}.h5"
    ingest([log], drive, config=config)
    origin = navigate(drive, "none", config).origin
    truth = from_truth(str(sim.truth_path), origin, config)
    t = time.perf_counter()
    result = autofocus_residual_motion(drive, truth, config)
    row = {"scenario": scenario, "seed": seed, "components": components, "car": car, "applied": result.applied,
           "track_scale_pct": round(100 * result.scale, 4),
           "track_scale_std_pct": round(100 * result.scale_std, 4),
           "grade_stretch_pct": round(100 * result.grade_stretch, 4),
           "autofocus_s": round(time.perf_counter() - t, 1),
           "summary": result.summary()}
    # the same with the radar moved by the IMU's roll and pitch, as in SAR-MIN's trajectory
    with Drive(drive) as d:
        inputs = load_inputs(d, config)
    tilted = with_attitude(truth, *body_attitude(inputs, config), inputs.t0_ns, config)
    row["attitude_applied"] = bool(tilted.info["attitude"]["applied"])
    if row["attitude_applied"]:
        on_imu = autofocus_residual_motion(drive, tilted, config)
        row["track_scale_with_attitude_pct"] = round(100 * on_imu.scale, 4)
        row["track_scale_with_attitude_std_pct"] = round(100 * on_imu.scale_std, 4)
        row["grade_stretch_with_attitude_pct"] = round(100 * on_imu.grade_stretch, 4)
        flat = autofocus_residual_motion(drive, tilted, config, opts=AutofocusOptions(grade_stretch=False))
        row["track_scale_with_attitude_no_grade_pct"] = round(100 * flat.scale, 4)
    moving = from_truth(str(sim.truth_path), origin, config, radar_motion=True)
    on_radar = autofocus_residual_motion(drive, moving, config)
    row["track_scale_radar_motion_pct"] = round(100 * on_radar.scale, 4)
    row["track_scale_radar_motion_std_pct"] = round(100 * on_radar.scale_std, 4)
    for path in work.iterdir():
        if path.is_file():
            path.unlink()
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="test1")
    ap.add_argument("--seeds", default="0,9")
    ap.add_argument("--components", default="kinematic;body;road;;slip,tyre_radius,wheel_ticks,imu_misalignment")
    ap.add_argument("--car", default=None, help="entries of the simulated car's [vehicle_dynamics], KEY=VALUE,...")
    ap.add_argument("--append", action="store_true", help="add the rows to those of --output")
    ap.add_argument("--output", type=Path, default=RESULTS / "af_truth_scale.json")
    args = ap.parse_args()
    rows = json.loads(args.output.read_text())["rows"] if args.append else []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in (int(s) for s in args.seeds.split(",")):
            for components in args.components.split(";"):
                row = measure(args.scenario, seed, components, Path(tmp), args.car)
                rows.append(row)
                tilted = (f"; with the IMU's roll and pitch {row['track_scale_with_attitude_pct']:+.4f} % "
                          f"({row['track_scale_with_attitude_no_grade_pct']:+.4f} % with the grade's stretch left in)"
                          if row["attitude_applied"] else "; no attitude")
                print(f"{args.scenario} seed {seed} [{components or 'none'}]: truth track scaled by "
                      f"{row['track_scale_pct']:+.4f} +- {row['track_scale_std_pct']:.4f} % (the grade's stretch "
                      f"{row['grade_stretch_pct']:.4f} % left out){tilted}; on the radar's "
                      f"true motion {row['track_scale_radar_motion_pct']:+.4f} %", flush=True)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps({"benchmark": "af_truth_scale", "rows": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
