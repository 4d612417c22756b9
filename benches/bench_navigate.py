"""Benchmark `autosar navigate`: wall time per second of drive for SAR-MIN (filter + RTS smoother).

Usage: python benches/bench_navigate.py [--scenario S[,S2]] [--seed N] [--repeat R] [--workdir D] [--no-reference]

Simulates (MCAP, ``--seed``) and ingests each scenario once (kept in ``--workdir`` between runs when given),
then times ``navigate(drive, "sar-min")`` (reading the inputs from drive.h5 included) ``--repeat`` times
in one process after a warm-up run (numba's compiled kernels are cached on disk, so the warm-up only
loads them), alternating with single-pass runs (the fitted steering and wheel-speed lags off, side by side),
the same without the smoother, and reading the inputs alone; plus one run of the
filterpy/numpy reference engine (unless ``--no-reference``). Writes benches/results/navigate.json.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def time_drive(scenario: str, seed: int, work: Path, repeat: int, reference_engine: bool) -> dict:
    """Simulate and ingest one drive into ``work`` (kept there), then time navigate on it; one JSON row."""
    from autosar_cli.config import load_config
    from autosar_cli.ingest.pipeline import ingest
    from autosar_cli.nav.inputs import load_inputs
    from autosar_cli.nav.navigate import navigate
    from autosar_cli.nav.sarmin import run_sarmin
    from autosar_cli.store.drive import Drive

    cfg = load_config()
    single = replace(cfg, navigation=replace(cfg.navigation, estimate_understeer=False, estimate_wheel_lag=False,
                                             estimate_wheel_radii=False))
    log = work / f"{scenario}_seed{seed}.mcap"
    if not log.exists():
        subprocess.run([sys.executable, "-m", "autosar_cli.cli", "simulate", "--scenario", scenario,
                        "--seed", str(seed), "--output", str(log), "--overwrite"], check=True, capture_output=True)
    drive = work / f"{scenario}_seed{seed}.drive.h5"
    if not drive.exists():
        ingest([log], drive, config=cfg)
    t = time.perf_counter()
    first = navigate(drive, "sar-min", cfg)
    warmup = time.perf_counter() - t
    duration = (first.t_ns[-1] - first.t_ns[0]) / 1e9
    walls, single_walls = [], []
    for _ in range(repeat):
        t = time.perf_counter()
        navigate(drive, "sar-min", cfg)
        walls.append(time.perf_counter() - t)
        t = time.perf_counter()
        navigate(drive, "sar-min", single)
        single_walls.append(time.perf_counter() - t)
    unsmoothed = []
    for _ in range(repeat):
        t = time.perf_counter()
        navigate(drive, "sar-min", cfg, smooth=False)
        unsmoothed.append(time.perf_counter() - t)
    loads = []
    for _ in range(repeat):
        t = time.perf_counter()
        with Drive(drive) as d:
            inputs = load_inputs(d, cfg)
        loads.append(time.perf_counter() - t)
    reference = None
    if reference_engine:
        t = time.perf_counter()
        run_sarmin(inputs, cfg, engine="numpy")
        reference = time.perf_counter() - t
    wall = statistics.median(walls)
    filter_only = statistics.median(unsmoothed)
    # which passes the product ran: the first alone where the steering is left out and no rear slip shows
    steering = first.info.get("understeer", {})  # none without a steering
    one_pass = steering.get("steering_left_out", False) and not first.info["rear_slip"].get("applied")
    return {"scenario": scenario, "seed": seed, "drive_s": round(duration, 2), "samples": len(first.t_ns),
            "passes": 1 if one_pass else 2, "first_run_s": round(warmup, 3), "median_wall_s": round(wall, 3),
            "walls_s": [round(w, 3) for w in walls], "realtime_factor": round(duration / wall, 1),
            "s_per_drive_s": round(wall / duration, 4),
            "single_pass_median_s": round(statistics.median(single_walls), 3),
            "vs_single_pass": round(wall / statistics.median(single_walls), 2),
            "filter_only_median_s": round(filter_only, 3), "smoother_median_s": round(wall - filter_only, 3),
            "load_inputs_median_s": round(statistics.median(loads), 3),
            "reference_engine_s": round(reference, 2) if reference else None,
            "reference_realtime_factor": round(duration / reference, 2) if reference else None}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="test1", help="scenario, or several, comma-separated")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--workdir", type=Path, default=None)
    ap.add_argument("--no-reference", action="store_true", help="skip the (slow) numpy reference engine")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = args.workdir or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        for scenario in args.scenario.split(","):
            rows.append(time_drive(scenario, args.seed, work, args.repeat, not args.no_reference))
            print(json.dumps(rows[-1], indent=2), flush=True)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "navigate.json").write_text(json.dumps({"benchmark": "navigate", "target_realtime_factor": 50,
                                                       "rows": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
