"""Benchmark `autosar run` (ingest -> navigate -> focus) on test1: wall time as a fraction of the drive.

Usage: python benches/bench_run.py [--repeat 3] [--workdir DIR]

Simulates test1 (MCAP, seed 1) once, then runs ``autosar run LOG -o DIR --overwrite --json`` in a fresh
process per repeat (numba kernels come from the on-disk cache after the first), and records the wall
time of the whole command, each stage's time from run.json, and the fraction of the drive's duration
(target <= 0.25). Writes benches/results/run.json.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--workdir", type=Path, default=None)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = args.workdir or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        log = work / "test1_seed1.mcap"
        if not log.exists():
            subprocess.run([sys.executable, "-m", "autosar_cli.cli", "simulate", "--scenario", "test1", "--seed", "1",
                            "--output", str(log), "--overwrite"], check=True, capture_output=True)
        runs = []
        for _ in range(args.repeat + 1):  # the first run warms numba's on-disk cache
            t = time.perf_counter()
            res = subprocess.run([sys.executable, "-m", "autosar_cli.cli", "run", str(log), "-o", str(work / "run"),
                                  "--overwrite", "--json"], check=True, capture_output=True, text=True)
            wall = time.perf_counter() - t
            manifest = json.loads(res.stdout)
            runs.append({"process_wall_s": wall, "manifest": manifest})
        runs = runs[1:]
    walls = [r["process_wall_s"] for r in runs]
    med = sorted(runs, key=lambda r: r["process_wall_s"])[len(runs) // 2]
    m = med["manifest"]
    row = {"scenario": "test1 (seed 1, MCAP)", "drive_s": round(m["drive_s"], 2),
           "median_process_wall_s": round(statistics.median(walls), 3), "walls_s": [round(w, 3) for w in walls],
           "fraction_of_drive": round(statistics.median(walls) / m["drive_s"], 3),
           "stages_s_of_median_run": {k: round(v["wall_s"], 3) for k, v in m["stages"].items()},
           "focus_split_s": {k: round(v, 3) for k, v in m["stages"]["focus"]["timings_s"].items()},
           "target_fraction": 0.25}
    print(json.dumps(row, indent=2))
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "run.json").write_text(json.dumps({"benchmark": "run", "rows": [row]}, indent=2) + "\n")


if __name__ == "__main__":
    main()
