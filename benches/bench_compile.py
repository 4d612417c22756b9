"""Benchmark the first run after an install: how long numba takes to compile the kernels, and what the cache saves.

Usage: python benches/bench_compile.py [--repeat 3] [--against DIR] [--output benches/results/compile.json]

Each figure comes from a fresh process with an empty numba cache (NUMBA_CACHE_DIR in a new temporary directory):

1. the back-projection kernel (``sar/backprojection.py::_tdbp``, the largest): the wall time of a first call on a
   tiny case (compile included) and of a second process's first call with the cache then filled (load only);
2. ``autosar run sample_logs/ci_seed1.mcap``: the whole chain, cold and then with the cache filled.

``--against DIR`` runs the same in another checkout of the package (e.g. ``git worktree add DIR REV``) in the same
session, alternating, so the two are measured side by side; medians of ``--repeat`` runs. Writes JSON.
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

ROOT = Path(__file__).resolve().parent.parent

#: A first call of the back-projection kernel on 8 pixels and 64 pulses of one channel: nearly all of it compiling.
KERNEL_CALL = """
import time
import numpy as np
from autosar_cli.sar.backprojection import backproject
t = time.perf_counter()
ant = np.zeros((2, 64, 3)); ant[:, :, 0] = np.arange(64) * 0.004
prof = np.ones((1, 32, 64), np.complex64)
pix = np.array([[0.1 * k, 3.0, 0.0] for k in range(8)])
backproject(prof, ant, [[0, 1]], pix, np.tile([0, 64], (8, 1)), range0_m=0.0, bin_m=0.04, cycles_per_m=500.0)
print(time.perf_counter() - t)
"""


def _env(source: Path, cache: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(source), "NUMBA_CACHE_DIR": str(cache)}


def kernel_seconds(source: Path, cache: Path) -> float:
    """Wall time of the kernel's first call in a fresh process (imports excluded)."""
    out = subprocess.run([sys.executable, "-c", KERNEL_CALL], env=_env(source, cache), check=True,
                         capture_output=True, text=True, cwd=source)
    return float(out.stdout.strip().splitlines()[-1])


def run_seconds(source: Path, cache: Path, work: Path) -> float:
    """Wall time of ``autosar run`` on the bundled sample log in a fresh process."""
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "autosar_cli.cli", "run", str(ROOT / "sample_logs" / "ci_seed1.mcap"),
                    "-o", str(work / "run"), "--overwrite"], env=_env(source, cache), check=True,
                   capture_output=True, cwd=source)
    return time.perf_counter() - t


def revision(source: Path) -> str:
    """The checkout's commit, "+changes" where its package differs from it."""
    git = ["git", "-C", str(source)]
    rev = subprocess.run([*git, "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    dirty = subprocess.run([*git, "diff", "--quiet", "HEAD", "--", "autosar_cli"]).returncode != 0
    return (rev or "no git") + ("+changes" if dirty else "")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--against", type=Path, default=None, help="another checkout, measured alternately")
    ap.add_argument("--runs", type=int, default=1, help="cold `autosar run`s per source (each ~1-2 min)")
    ap.add_argument("--output", type=Path, default=ROOT / "benches" / "results" / "compile.json")
    args = ap.parse_args()
    sources = {"this": ROOT} | ({"against": args.against.resolve()} if args.against else {})
    figures: dict[str, dict[str, list[float]]] = {k: {"kernel_cold_s": [], "kernel_cached_s": [], "run_cold_s": [],
                                                       "run_cached_s": []} for k in sources}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(max(args.repeat, args.runs)):
            for name, source in sources.items():
                cache = Path(tmp) / f"cache_{name}_{r}"
                f = figures[name]
                if r < args.repeat:
                    f["kernel_cold_s"].append(kernel_seconds(source, cache))
                    f["kernel_cached_s"].append(kernel_seconds(source, cache))
                if r < args.runs:
                    work = Path(tmp) / f"work_{name}_{r}"
                    f["run_cold_s"].append(run_seconds(source, cache / "run", work))
                    f["run_cached_s"].append(run_seconds(source, cache / "run", work))
                print(name, {k: [round(x, 1) for x in v] for k, v in f.items()}, flush=True)
    # one row per source: the medians, then the runs
    table = {f"{name} ({revision(sources[name])})": {k: round(statistics.median(v), 2) for k, v in f.items() if v}
             | {k.removesuffix("_s") + "_runs": [round(x, 1) for x in v] for k, v in f.items() if v}
             for name, f in figures.items()}
    result: dict[str, object] = {"benchmark": "compile", "cpus": os.cpu_count(), "repeat": args.repeat,
                                 "table": table}
    if args.against:
        this, other = table.values()
        result["kernel_cold_ratio"] = round(this["kernel_cold_s"] / other["kernel_cold_s"], 3)
        if "run_cold_s" in this:
            result["run_cold_ratio"] = round(this["run_cold_s"] / other["run_cold_s"], 3)
    print(json.dumps(result, indent=2))
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
