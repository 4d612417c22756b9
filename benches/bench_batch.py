"""Benchmark `autosar batch`: throughput of 4 `ci` drives on a LocalCluster with 1 and with 2 workers.

Usage: python benches/bench_batch.py [--drives 4] [--repeat 3] [--workdir DIR] [--no-serial]

The drives (``ci`` scenario, seeds 1..N, MCAP) are simulated once into the work directory. Each run
(1 and 2 workers interleaved, ``--repeat`` times) starts a fresh LocalCluster (worker processes, one
task thread each, numba threads = cores // workers), imports the chain on every worker (cluster start,
reported apart), then runs every drive through ``run_batch`` into a fresh directory. Throughput =
drives / wall time from the first submit to the last result (median and best over ``--repeat``); the
scaling factor is the 2-worker throughput over the 1-worker one. The 1-minute load average before
each run is recorded: on a shared machine the spread is large. For reference, the same drives one
after the other with ``autosar run``'s function in this process (numba with all cores, no Dask).
Writes benches/results/batch.json.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import tempfile
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def load() -> str:
    try:
        return " ".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:
        return "n/a"


def simulate_drives(work: Path, n: int) -> list[Path]:
    from autosar_cli.sim.simulate import simulate

    logs = []
    for seed in range(1, n + 1):
        log = work / f"ci_seed{seed}.mcap"
        if not log.exists():
            simulate("ci", log, seed=seed)
        logs.append(log)
    return logs


def batch_run(logs: list[Path], work: Path, workers: int, k: int) -> dict[str, object]:
    from autosar_cli.batch import run_batch
    from autosar_cli.config import load_config

    out = work / f"batch_w{workers}_{k}"
    shutil.rmtree(out, ignore_errors=True)
    load_before = load()
    m = run_batch(logs, out, load_config(), workers=workers)
    assert m["failed"] == 0, m["drives"]
    shutil.rmtree(out, ignore_errors=True)
    row = {"wall_s": round(m["wall_s"], 3), "cluster_start_s": m["cluster"]["start_s"],
           "total_wall_s": round(m["total_wall_s"], 3), "drives_per_minute": round(m["drives_per_minute"], 2),
           "drive_wall_s": [round(d["wall_s"], 3) for d in m["drives"]],
           "numba_threads_per_task": m["cluster"]["numba_threads_per_task"], "load_before": load_before}
    print(json.dumps({"workers": workers, **row}))
    return row


def batch_cases(logs: list[Path], work: Path, repeat: int) -> list[dict[str, object]]:
    """1 and 2 workers, interleaved (1, 2, 1, 2, ...) so that a drifting background load hits both alike."""
    runs: dict[int, list[dict[str, object]]] = {1: [], 2: []}
    for k in range(repeat):
        for workers in (1, 2):
            runs[workers].append(batch_run(logs, work, workers, k))
    cases = []
    for workers, rows in runs.items():
        wall = statistics.median(r["wall_s"] for r in rows)
        best = min(r["wall_s"] for r in rows)
        cases.append({"workers": workers, "drives": len(logs), "median_wall_s": round(wall, 3),
                      "drives_per_minute": round(60.0 * len(logs) / wall, 2), "best_wall_s": round(best, 3),
                      "best_drives_per_minute": round(60.0 * len(logs) / best, 2), "runs": rows})
    return cases


def serial_case(logs: list[Path], work: Path) -> dict[str, object]:
    from autosar_cli.config import load_config
    from autosar_cli.run import run

    cfg = load_config()
    run([logs[0]], work / "serial_warmup", cfg, overwrite=True)  # imports and kernels loaded, like the workers
    t = time.perf_counter()
    for log in logs:
        run([log], work / f"serial_{log.stem}", cfg, overwrite=True)
    wall = time.perf_counter() - t
    row = {"case": "in-process, one drive after the other (no Dask)", "drives": len(logs), "wall_s": round(wall, 3),
           "drives_per_minute": round(60.0 * len(logs) / wall, 2), "load_before": load()}
    print(json.dumps(row))
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drives", type=int, default=4)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--workdir", type=Path, default=None)
    ap.add_argument("--no-serial", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = args.workdir or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        logs = simulate_drives(work, args.drives)
        cases = batch_cases(logs, work, args.repeat)
        result: dict[str, object] = {
            "benchmark": "batch", "scenario": "ci", "cores": os.cpu_count(), "cases": cases,
            "scaling_2_over_1": round(cases[1]["drives_per_minute"] / cases[0]["drives_per_minute"], 3),
            "scaling_2_over_1_best": round(cases[1]["best_drives_per_minute"] / cases[0]["best_drives_per_minute"], 3),
            "load_after": load(),
        }
        if not args.no_serial:
            result["serial"] = serial_case(logs, work)
    print(json.dumps({k: result[k] for k in ("scaling_2_over_1", "scaling_2_over_1_best")}))
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "batch.json").write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
