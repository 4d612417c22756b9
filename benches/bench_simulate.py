"""Benchmark `autosar simulate`: wall time and log size per scenario and format.

Usage: python benches/bench_simulate.py [--scenarios ci,test1,test2,test3] [--dynamics kinematic,full]
Prints a table and writes benches/results/simulate.json; with both vehicle models, each scenario's full / kinematic
ratio of wall time per second of drive. Each run is a fresh process so the numba
compile cache state is the same as for a user (compiled once, cached on disk).
"""

from __future__ import annotations

import argparse
import itertools
import json
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def size_of(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file()) if path.is_dir() else path.stat().st_size


def run_once(scenario: str, fmt: str, workdir: Path, dynamics: str = "kinematic") -> dict:
    ext = {"mcap": ".mcap", "ros1": ".bag", "ros2": ""}[fmt]
    log = workdir / f"{scenario}{ext}"
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "autosar_cli.cli", "simulate", "--scenario", scenario,
                           "--format", fmt, "--seed", "1", "--output", str(log), "--overwrite", "--json",
                           "--dynamics", dynamics],
                          check=True, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    info = json.loads(proc.stdout)
    result = {"wall_s": wall, "drive_s": info["duration_s"], "radar_frames": info["radar_frames"],
              "log_bytes": size_of(log), "truth_bytes": size_of(Path(info["truth"]))}
    shutil.rmtree(log) if log.is_dir() else log.unlink()
    Path(info["truth"]).unlink()
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", default="ci,test1,test2,test3")
    ap.add_argument("--formats", default="mcap")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--dynamics", default="kinematic", help="vehicle models, comma-separated: kinematic,full")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        run_once("ci", "mcap", Path(tmp))  # warm the numba cache
        for scenario, fmt, dynamics in itertools.product(args.scenarios.split(","), args.formats.split(","),
                                                         args.dynamics.split(",")):
            runs = [run_once(scenario, fmt, Path(tmp), dynamics) for _ in range(args.repeat)]
            wall = statistics.median(r["wall_s"] for r in runs)
            r0 = runs[0]
            row = {"scenario": scenario, "format": fmt, "dynamics": dynamics, "repeat": args.repeat,
                   "median_wall_s": round(wall, 2),
                   "drive_s": r0["drive_s"], "realtime_factor": round(wall / r0["drive_s"], 2),
                   "radar_frames": r0["radar_frames"], "log_MB": round(r0["log_bytes"] / 1e6, 1),
                   "truth_MB": round(r0["truth_bytes"] / 1e6, 1),
                   "log_MB_per_drive_s": round(r0["log_bytes"] / 1e6 / r0["drive_s"], 1)}
            base = [r for r in rows if r["scenario"] == scenario and r["format"] == fmt
                    and r["dynamics"] == "kinematic"]
            if dynamics != "kinematic" and base:
                row["vs_kinematic"] = round(row["realtime_factor"] / base[0]["realtime_factor"], 2)
            rows.append(row)
            print(f"{scenario:6s} {fmt:5s} {dynamics:9s} wall {wall:6.1f} s  drive {r0['drive_s']:5.1f} s  "
                  f"x{row['realtime_factor']:.2f} real time  log {row['log_MB']:7.1f} MB  "
                  f"truth {row['truth_MB']:5.1f} MB", flush=True)
    RESULTS.mkdir(exist_ok=True)
    out = RESULTS / "simulate.json"
    out.write_text(json.dumps({"machine": platform.processor() or platform.machine(), "python": sys.version.split()[0],
                               "results": rows}, indent=2) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
