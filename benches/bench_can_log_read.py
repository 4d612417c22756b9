"""CAN log read speed: undamaged BLF, ASC, TRC, candump and MDF4 logs read by ``read_can_log``, beside another
checkout.

Each log holds the same ``--frames`` frames (seeded ids and data, two channels), written by python-can; the MDF4
figure is the three real CANedge files of ``../shared/realdata/css-electronics`` read in turn (13199 frames; left
out where that folder is absent). A round
reads every log with this checkout's package and, with ``--against DIR`` (``git worktree add DIR REV``), with the
other's, each in a fresh process, one after the other, the order turned each round; a read is timed as the best of
three. Given: each format's median over ``--rounds`` rounds and the ratio of the medians (this / the other). This
measures what reading an undamaged log costs for the damage checks (the text logs' line feed, the BLF's container
walk, the MDF4's block walk and DLC tables; its mending runs only on a damaged file). Results:
``benches/results/can_log_read.json``.

Usage: python benches/bench_can_log_read.py [--against DIR] [--frames 100000] [--rounds 7]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import random
import statistics
import tempfile
import time
from pathlib import Path

from checkouts import in_checkout, revision

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
SUFFIXES = (".blf", ".asc", ".trc", ".log")
#: the real CANedge MDF4 files, read as one figure
REAL_MF4 = REPO.parent / "shared" / "realdata" / "css-electronics"


def _write_logs(directory: Path, frames: int) -> list[Path]:
    """One log per format of the same ``frames`` frames (python-can's writers)."""
    import can

    rng = random.Random(0)
    messages = []
    for i in range(frames):
        dlc = rng.choice((8, 8, 8, 6, 4))
        extended = rng.random() < 0.2
        messages.append(can.Message(
            timestamp=1_600_000_000.0 + i * 5e-4, arbitration_id=rng.randrange(0x1FFFFFFF if extended else 0x7FF),
            is_extended_id=extended, dlc=dlc, data=rng.randbytes(dlc), channel=i % 2))
    writers = {".blf": can.BLFWriter, ".asc": can.ASCWriter, ".trc": can.TRCWriter, ".log": can.CanutilsLogWriter}
    paths = []
    for suffix in SUFFIXES:
        path = directory / f"frames{suffix}"
        with writers[suffix](path) as writer:
            for msg in messages:
                writer.on_message_received(msg)
        paths.append(path)
    return paths


def _time_reads(files: list[Path]) -> dict[str, float]:
    """Seconds to read each of ``files`` (best of three) with the package importable now."""
    from autosar_cli.ingest.canlog import read_can_log

    out: dict[str, float] = {}
    for path in files:
        best = float("inf")
        for _ in range(3):
            t0 = time.perf_counter()
            n = sum(1 for _ in read_can_log(path))
            best = min(best, time.perf_counter() - t0)
        suffix = path.suffix.lower()  # the MDF4 files add up to one figure
        out[suffix] = out.get(suffix, 0.0) + best
        out[f"{suffix}_frames"] = out.get(f"{suffix}_frames", 0) + n
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--against", type=Path, help="another checkout whose package reads the same logs beside")
    ap.add_argument("--frames", type=int, default=100_000)
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--output", type=Path, default=HERE / "results" / "can_log_read.json")
    ap.add_argument("--worker", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("files", nargs="*", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        args.worker.write_text(json.dumps(_time_reads(args.files)))
        return
    roots = {"this": REPO, **({"against": args.against.resolve()} if args.against else {})}
    rows = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="bench-can-read-") as scratch:
        files = _write_logs(Path(scratch), args.frames) + sorted(REAL_MF4.glob("*.MF4"))
        for n in range(args.rounds):
            order = list(roots) if n % 2 == 0 else list(reversed(roots))
            for name in order:
                times = in_checkout(__file__, roots[name], list(map(str, files)), Path(scratch) / f"{name}.json")
                rows.append({"round": n, "checkout": name, **times})
                print(json.dumps(rows[-1]))
    summary: dict[str, object] = {name: revision(root) for name, root in roots.items()}
    for suffix in (*SUFFIXES, *((".mf4",) if any(".mf4" in r for r in rows) else ())):
        medians = {name: statistics.median(float(r[suffix]) for r in rows if r["checkout"] == name)
                   for name in roots}
        frames = {int(r[f"{suffix}_frames"]) for r in rows}
        summary[suffix.lstrip(".")] = {f"{name}_s": round(m, 4) for name, m in medians.items()} | (
            {"ratio": round(medians["this"] / medians["against"], 3)} if "against" in medians else {}) | {
            "frames": sorted(frames)}
    result = {"benchmark": "can_log_read", "frames": args.frames, "rounds": args.rounds, "summary": summary,
              "wall_s": round(time.perf_counter() - t0, 1), "rows": rows, "python": platform.python_version(),
              "cores": os.cpu_count()}
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(result, indent=1) + "\n")
    print("summary", json.dumps(summary))
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
