"""Benchmark the GNSS velocity's floor: the worst corner reflector along a track whose only error is its scale.

The scale is the one the GNSS velocity alone gives.

Usage: python benches/bench_scale_floor.py [--scenarios test1,test2,test3,urban] [--seeds 0-9]
                                           [--check benches/results/paper_full_level.json]
                                           [--output benches/results/scale_floor.json]

SAR-MIN's track scale follows the GNSS velocity's error (NAVIGATION.md: correlation 0.84-0.95 over seeds), and where
the autofocus's points disagree on a scale (urban: all 10 drives) nothing else measures it. So this is the floor of
the worst reflector there, for navigation with these sensors. Per scenario: one full-vehicle simulation (seed 0,
radar at 20 Hz: only the truth's track and targets are used); per seed: the GNSS velocity's scale of that seed's draw
(``bench_paper.gnss_velocity_scale``: the simulator's own noise, as in the log), the truth's trajectory (the radar's
true motion) stretched by it about its start, and the evaluation's own geometry (``evaluate.reflectors.
predict_image_positions`` and the rigid alignment of the radar tracks, as ``autosar compare`` does): each reflector's
distance from where it should appear. No image is focused, so a drive takes well under a second after its
scenario's simulation (~1 min for the 40). ``--check`` tests the model: per drive of that bench_paper result, the
same geometry with SAR-MIN's own measured track scale (``sarmin_track_scale_pct``) beside SAR-MIN's measured worst
reflector, whose error also holds the track's shape and the image's own.
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
from bench_paper import gnss_velocity_scale, parse_seeds  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
WITHIN_CM = 2.0


def stretched(trajectory: Any, factor: float) -> Any:
    """``trajectory`` with its rear axle's track scaled by ``factor`` about its start and its speed with it: what
    integrating a speed ``factor`` times the truth's along the same headings gives."""
    start = trajectory.rear_axle_enu[0]
    return dataclasses.replace(trajectory, rear_axle_enu=start + factor * (trajectory.rear_axle_enu - start),
                               speed=factor * trajectory.speed)


def worst_reflector_cm(truth: Any, scale: float, config: Any) -> float:
    """The worst corner reflector's aligned error (cm) in the image of a track whose similarity onto the truth's
    has the scale ``1 + scale`` (``bench_paper.track_scale``'s sign: below 0 the track is too long)."""
    from autosar_cli.evaluate.alignment import fit_se2
    from autosar_cli.evaluate.reflectors import predict_image_positions
    from autosar_cli.evaluate.trajectory_metrics import common_instants
    from autosar_cli.nav.trajectory import radar_track
    from autosar_cli.sar.focus import FocusOptions

    est = stretched(truth.trajectory, 1.0 / (1.0 + scale))
    t = common_instants(est, truth.trajectory)
    crs = truth.targets.corner_reflectors
    image = predict_image_positions(est, truth.trajectory, truth.targets_above_road(crs), config, t,
                                    FocusOptions().height_m)
    alignment = fit_se2(radar_track(est, t, config), radar_track(truth.trajectory, t, config))
    expected = alignment.inverse().apply(truth.targets.position_enu[crs, :2])
    return 100.0 * float(np.max(np.hypot(*(image - expected).T)))


def scenario_truth(scenario: str, config: Any, work: Path) -> Any:
    import h5py

    from autosar_cli.evaluate.evaluation import load_truth
    from autosar_cli.sim.simulate import simulate
    from autosar_cli.types import GeodeticOrigin

    log = work / f"{scenario}.mcap"
    sim = simulate(scenario, log, seed=0, config=config, dynamics="full")
    with h5py.File(sim.truth_path, "r") as f:
        origin = GeodeticOrigin(float(f.attrs["origin_lat_deg"]), float(f.attrs["origin_lon_deg"]),
                                float(f.attrs["origin_height_m"]))
    truth = load_truth(sim.truth_path, origin, config)
    for p in (log, sim.truth_path):
        Path(p).unlink(missing_ok=True)
    return truth


def main() -> None:
    from autosar_cli.config import load_config

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", default="test1,test2,test3,urban")
    ap.add_argument("--seeds", default="0-9")
    ap.add_argument("--check", type=Path, default=None,
                    help="a bench_paper result: SAR-MIN's measured scale and worst reflector beside this model's")
    ap.add_argument("--output", type=Path, default=RESULTS / "scale_floor.json")
    args = ap.parse_args()
    base = load_config()
    config = dataclasses.replace(base, radar=dataclasses.replace(base.radar, prf_hz=NAV_ONLY_PRF_HZ))
    measured = {(r["scenario"], r["seed"]): r for r in json.loads(args.check.read_text())["rows"]} if args.check else {}
    rows: list[dict[str, Any]] = []
    summary: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for scenario in args.scenarios.split(","):
            start = time.perf_counter()
            truth = scenario_truth(scenario, config, Path(tmp))
            these = []
            for seed in parse_seeds(args.seeds):
                scale, _ = gnss_velocity_scale(scenario, seed)
                row = {"scenario": scenario, "seed": seed, "gnss_velocity_scale_pct": round(100 * scale, 4),
                       "worst_reflector_cm": round(worst_reflector_cm(truth, scale, config), 2)}
                if (m := measured.get((scenario, seed))) and m.get("sarmin_track_scale_pct") is not None:
                    row["check"] = {"sarmin_track_scale_pct": m["sarmin_track_scale_pct"],
                                    "model_cm": round(worst_reflector_cm(truth, m["sarmin_track_scale_pct"] / 100,
                                                                         config), 2),
                                    "sarmin_measured_cm": m["sar-min"]["reflector_error_max_cm"]}
                these.append(row)
            rows += these
            worst = [r["worst_reflector_cm"] for r in these]
            for key, value in ((f"within_{WITHIN_CM:g}cm", sum(w <= WITHIN_CM for w in worst)),
                               ("worst_reflector_median_cm", round(float(np.median(worst)), 2)),
                               ("worst_reflector_max_cm", max(worst))):
                summary.setdefault(key, {})[scenario] = value
            print(f"{scenario}: within {WITHIN_CM:g} cm on {sum(w <= WITHIN_CM for w in worst)} of {len(these)}; "
                  f"worst reflector median {np.median(worst):.2f} cm, max {max(worst):.2f} "
                  f"({time.perf_counter() - start:.0f} s)", flush=True)
            checked = [r["check"] for r in these if "check" in r]
            if checked:
                model = np.array([c["model_cm"] for c in checked])
                real = np.array([c["sarmin_measured_cm"] for c in checked])
                corr, excess = float(np.corrcoef(model, real)[0, 1]), float(np.median(real - model))
                summary.setdefault("check_correlation", {})[scenario] = round(corr, 3)
                summary.setdefault("check_measured_minus_model_median_cm", {})[scenario] = round(excess, 2)
                print(f"  check against {args.check.name}: SAR-MIN's measured worst reflector against this model "
                      f"with its own scale: correlation {corr:.2f}, measured - model median {excess:+.2f} cm",
                      flush=True)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps({"benchmark": "scale_floor", "within_cm": WITHIN_CM, "summary": summary,
                                       "rows": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
