"""Benchmark `autosar run --autofocus` against `autosar run` on one drive, side by side, and what it recovers.

Usage: python benches/bench_autofocus.py [--scenario test2] [--seed 1] [--dynamics full] [--repeat 5]
                                         [--phases-only] [--with-fast]

Simulates the drive once (MCAP), then alternates ``autosar run LOG`` and ``autosar run LOG --autofocus`` in fresh
processes (after one warm-up of each, which fills numba's cache), each round starting with the next command, so
that all see the same host load and none is always first; records each command's wall time and stage times, and the
ratio of the medians (the issue's target: <= 1.5). Then evaluates the last --autofocus run against the truth
(reflector errors and peak losses, the scale applied against the truth's), and the plain run the same way.
``--phases-only``: a third command in each round, ``autosar run LOG --autofocus`` with the config's
``processing.autofocus_slow_motion`` off (no slow motion from the points' passes first); ``--with-fast``: one with
``processing.autofocus_fast_motion`` on (the fast motion from many scatterers last). Writes
benches/results/autofocus.json (``--output``). The committed file: ``--with-fast`` on the full vehicle (``--dynamics
full``, the simulator's default and the default here).
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
from typing import Any

RESULTS = Path(__file__).resolve().parent / "results"
PHASES = "run --autofocus (phases only)"
FAST = "run --autofocus (with the fast motion)"
OUT_DIRS = {"run": "run", "run --autofocus": "run_autofocus", PHASES: "run_autofocus_phases",
            FAST: "run_autofocus_with_fast"}


def autosar(*args: str) -> tuple[float, dict[str, Any]]:
    """Wall time (s) of one `autosar ... --json` command in a fresh process, and its JSON output."""
    t = time.perf_counter()
    res = subprocess.run([sys.executable, "-m", "autosar_cli.cli", *args, "--json"], check=True, capture_output=True,
                         text=True)
    return time.perf_counter() - t, json.loads(res.stdout)


def flat_correction(stage: dict[str, Any]) -> dict[str, Any]:
    """A stage's ``correction`` figures (RMS, max, median std) as scalars ``correction_*``."""
    return {f"correction_{k}": v for k, v in (stage.get("correction") or {}).items()}


def flat_slow_motion(slow: dict[str, Any] | None) -> dict[str, Any] | None:
    """run.json's ``slow_motion`` with each slip gain's error as two scalars (``slip_gain_error_drive`` and its
    ``_std``), the radar clock's figures as ``radar_clock_*`` and the correction's as ``correction_*``, not tables
    of their own."""
    if not slow:
        return slow
    gains = slow.get("slip_gain_error") or {}
    return {**{k: v for k, v in slow.items() if k not in ("slip_gain_error", "correction", "radar_clock")},
            **flat_correction(slow),
            **{f"radar_clock_{k}": v for k, v in (slow.get("radar_clock") or {}).items()},
            **{f"slip_gain_error_{name}{tail}": g[key] for name, g in gains.items()
               for key, tail in (("value", ""), ("std", "_std"))}}


def reflectors(run_dir: Path) -> dict[str, Any]:
    """`autosar evaluate` of a run: each reflector's aligned error (cm) and peak loss (dB)."""
    autosar("evaluate", str(run_dir), "-o", str(run_dir / "report"), "--overwrite")
    m = json.loads((run_dir / "report" / "metrics.json").read_text())
    return {"error_cm": [round(100 * r["aligned_error_m"], 2) for r in m["reflectors"]],
            "peak_loss_db": [round(r["peak_loss_db"], 2) for r in m["reflectors"]]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="test2")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--dynamics", choices=("kinematic", "full"), default="full")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--workdir", type=Path, default=None)
    ap.add_argument("--output", type=Path, default=RESULTS / "autofocus.json")
    ap.add_argument("--phases-only", action="store_true",
                    help="also run --autofocus with processing.autofocus_slow_motion off")
    ap.add_argument("--with-fast", action="store_true",
                    help="also run --autofocus with processing.autofocus_fast_motion on")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = args.workdir or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        log = work / f"{args.scenario}_s{args.seed}_{args.dynamics}.mcap"
        if not log.exists():
            subprocess.run([sys.executable, "-m", "autosar_cli.cli", "simulate", "--scenario", args.scenario, "--seed",
                            str(args.seed), "--dynamics", args.dynamics, "--output", str(log), "--overwrite"],
                           check=True, capture_output=True)
        commands: dict[str, list[str]] = {"run": [], "run --autofocus": ["--autofocus"]}
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from bench_paper import config_copy

        for flag, name, setting in ((args.phases_only, PHASES, "autofocus_slow_motion=false"),
                                    (args.with_fast, FAST, "autofocus_fast_motion=true")):
            if flag:
                variant = work / (OUT_DIRS[name] + "_config")
                variant.mkdir(exist_ok=True)
                commands[name] = ["--autofocus", "--config", str(config_copy(None, None, variant, processing=setting))]
        runs: dict[str, list[float]] = {name: [] for name in commands}
        stages: dict[str, list[dict[str, float]]] = {name: [] for name in commands}
        names = list(commands)
        for i in range(args.repeat + 1):  # the first round warms numba's on-disk cache
            for name in names[i % len(names):] + names[:i % len(names)]:
                extra = commands[name]
                out = work / OUT_DIRS[name]
                wall, manifest = autosar("run", str(log), "-o", str(out), "--overwrite", *extra)
                if i:
                    runs[name].append(round(wall, 3))
                    stages[name].append({k: v["wall_s"] for k, v in manifest["stages"].items()})
                    print(f"{name}: {wall:.2f} s " + ", ".join(f"{k} {v['wall_s']:.2f}"
                                                               for k, v in manifest["stages"].items()), flush=True)
        af = json.loads((work / OUT_DIRS["run --autofocus"] / "run.json").read_text())["stages"]["autofocus"]
        medians = {k: statistics.median(v) for k, v in runs.items()}
        result = {"benchmark": "autofocus", "scenario": args.scenario, "seed": args.seed, "dynamics": args.dynamics,
                  "repeat": args.repeat, "wall_s": runs, "median_wall_s": medians,
                  "median_stage_s": {k: {s: round(statistics.median(r[s] for r in v), 3) for s in v[0]}
                                     for k, v in stages.items()},
                  "ratio_autofocus_to_run": round(medians["run --autofocus"] / medians["run"], 3),
                  "autofocus": {**{k: af[k] for k in ("summary", "applied", "track_scale", "track_scale_std",
                                                       "points", "points_used", "coverage", "coherence_before",
                                                       "coherence_after") if k in af},
                                **flat_correction(af),
                                **({"slow_motion": flat_slow_motion(af["slow_motion"])} if "slow_motion" in af
                                   else {})},
                  "reflectors": {name: reflectors(work / OUT_DIRS[name]) for name in commands}}
        if args.phases_only:
            phases_af = json.loads((work / OUT_DIRS[PHASES] / "run.json").read_text())["stages"]["autofocus"]
            result["ratio_phases_only_to_run"] = round(medians[PHASES] / medians["run"], 3)
            result["phases_only_autofocus"] = {k: phases_af[k] for k in ("summary", "applied", "track_scale",
                                                                          "track_scale_std")}
        if args.with_fast:
            result["ratio_with_fast_to_run"] = round(medians[FAST] / medians["run"], 3)
    print(json.dumps({k: result[k] for k in ("median_wall_s", "ratio_autofocus_to_run", "ratio_phases_only_to_run",
                                              "ratio_with_fast_to_run",
                                              "autofocus", "reflectors") if k in result}, indent=2))
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
