"""Benchmark `autosar compare` on one drive: this checkout against another, side by side.

Usage: python benches/bench_compare.py --baseline DIR [--scenario test1] [--seed 1] [--repeat 3]

DIR is a checkout of the code to measure against (e.g. ``git worktree add /tmp/old <commit>``). The drive is
simulated once (kinematic, MCAP); then ``autosar compare LOG`` runs with the baseline's code and with this
checkout's in turn, in fresh processes, so both see the same host load (after one warm-up of each on the ci
drive, which fills each checkout's numba cache). Records each command's wall time and compare.json's stage
times, their medians and the ratio new / old, and whether the two agree on every method's image metrics
(entropy, far swath, range-normalised) and reflectors. Writes benches/results/compare.json.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

RESULTS = Path(__file__).resolve().parent / "results"
HERE = Path(__file__).resolve().parents[1]
#: summary figures that must not depend on how the product image was made
SAME = ("entropy", "entropy_rn", "entropy_far", "aligned_error_max_m", "peak_loss_max_db")


def autosar(src: Path, *args: str) -> float:
    """Wall time (s) of one `autosar ...` command run with the package at ``src``, in a fresh process (started in
    ``src``: `python -m` puts the working directory ahead of PYTHONPATH)."""
    env = {**os.environ, "PYTHONPATH": str(src)}
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "autosar_cli.cli", *args], check=True, capture_output=True, env=env,
                   cwd=src)
    return time.perf_counter() - t


def simulate(scenario: str, seed: int, log: Path) -> None:
    if not log.exists():
        autosar(HERE, "simulate", "--scenario", scenario, "--seed", str(seed), "--dynamics", "kinematic",
                "--output", str(log), "--overwrite")


def grouped_stages(timings: dict[str, float]) -> dict[str, float]:
    """compare.json's stage times summed over the methods: focus, evaluate, the rest as they are."""
    out: dict[str, float] = {}
    for k, v in timings.items():
        key = k.split("_", 1)[0] if k.startswith(("focus_", "evaluate_")) else k
        out[key] = out.get(key, 0.0) + v
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", type=Path, required=True, help="checkout of the code to compare against")
    ap.add_argument("--scenario", default="test1")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--workdir", type=Path, default=None)
    ap.add_argument("--output", type=Path, default=RESULTS / "compare.json")
    args = ap.parse_args()
    codes = {"baseline": args.baseline.resolve(), "this": HERE}
    commits = {k: subprocess.run(["git", "-C", str(v), "rev-parse", "--short", "HEAD"], capture_output=True,
                                 text=True).stdout.strip() for k, v in codes.items()}
    with tempfile.TemporaryDirectory() as tmp:
        work = args.workdir or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        warm = work / "ci_s1.mcap"
        simulate("ci", 1, warm)
        log = work / f"{args.scenario}_s{args.seed}.mcap"
        simulate(args.scenario, args.seed, log)
        for name, src in codes.items():
            autosar(src, "compare", str(warm), "-o", str(work / f"warm_{name}"), "--overwrite")
        walls: dict[str, list[float]] = {k: [] for k in codes}
        stages: dict[str, list[dict[str, float]]] = {k: [] for k in codes}
        summaries: dict[str, dict[str, Any]] = {}
        for _ in range(args.repeat):
            for name, src in codes.items():
                out = work / f"compare_{name}"
                walls[name].append(round(autosar(src, "compare", str(log), "-o", str(out), "--overwrite"), 3))
                result = json.loads((out / "compare.json").read_text())
                stages[name].append(grouped_stages(result["timings_s"]))
                summaries[name] = {m: r["summary"] for m, r in result["results"].items()}
                print(f"{name} ({commits[name]}): {walls[name][-1]:.2f} s " + ", ".join(
                    f"{k} {v:.2f}" for k, v in stages[name][-1].items()), flush=True)
    medians = {k: statistics.median(v) for k, v in walls.items()}
    agree = {m: {k: summaries["this"][m][k] == summaries["baseline"][m][k] for k in SAME if k in summaries["this"][m]}
             for m in summaries["this"]}
    straight = {f"{m} {line}": round(100 * (summaries["this"][m][f"straightness_{line}_m"]
                                            - summaries["baseline"][m][f"straightness_{line}_m"]), 3)
                for m in summaries["this"] for line in ("facade", "kerb")}  # the product's sampling moved
    result = {"benchmark": "compare", "cpus": os.cpu_count(), "scenario": args.scenario, "seed": args.seed,
              "repeat": args.repeat,
              "commits": commits, "wall_s": walls, "median_wall_s": medians,
              "ratio_this_to_baseline": round(medians["this"] / medians["baseline"], 3),
              **{f"median_stage_s_{k}": {s: round(statistics.median(r[s] for r in v), 2) for s in v[0]}
                 for k, v in stages.items()},
              "image_metrics_equal": all(all(v.values()) for v in agree.values()),
              "straightness_change_cm": straight}
    print(json.dumps({k: v for k, v in result.items() if k.startswith(("median", "ratio", "image"))}, indent=1))
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
