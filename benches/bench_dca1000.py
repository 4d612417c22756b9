"""Benchmark the TI DCA1000 capture reader: MB/s of capture, read alone and ingested into drive.h5.

Usage: python benches/bench_dca1000.py [--copies 16] [--repeat 3] [--workdir DIR]

Simulates the ``ci`` scenario as a DCA1000 capture (4-lane complex, seed 1), tiles its adc_data.bin
``--copies`` times into one capture (~25 MB each), also writes it in the 2-lane layout and as the DCA1000's
recorded packets (10-byte header + 1456 data bytes each, 4-lane), then times, after
one warm-up pass (the file in the page cache, as on a second read of a recording):

* read: :meth:`Dca1000Capture.blocks` over the whole capture, every PRI decoded into the drive's
  (tx, rx, sample, I/Q) layout;
* ingest: :func:`autosar_cli.ingest.pipeline.ingest` of the capture alone (``allow_partial``) into a
  drive.h5 (Blosc-LZ4 radar cube, input sha256), end to end.

Throughput is capture bytes / median wall. Prints a table and writes benches/results/dca1000.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import statistics
import tempfile
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"
TARGET_MB_S = 300.0


def build_captures(work: Path, copies: int) -> dict[str, Path]:
    """The simulated capture tiled ``copies`` times, in the 4-lane (as simulated) and 2-lane layouts."""
    from autosar_cli.ingest.dca1000 import CaptureWriter, Dca1000Capture
    from autosar_cli.sim.simulate import simulate

    sim = simulate("ci", work / "ci.mcap", fmt="dca1000", seed=1)
    assert sim.radar_capture is not None
    src = Dca1000Capture(sim.radar_capture)
    pris = [block for _, block, _ in src.blocks()]
    out: dict[str, Path] = {}
    for lanes in (4, 2):
        folder = work / f"capture_{lanes}lane"
        params = dataclasses.replace(src.params, lanes=lanes, num_frames=0)
        with CaptureWriter(folder, params, param_format="json") as w:
            for _ in range(copies):
                for block in pris:
                    w.write(block)
        out[f"{lanes}-lane complex"] = folder
    # the same 4-lane stream as the DCA1000's packets, recorded with their sequence numbers (1456 data bytes each)
    folder = work / "capture_4lane_packets"
    with CaptureWriter(folder, dataclasses.replace(src.params, num_frames=0), param_format="json",
                       packet_bytes=1456) as w:
        for _ in range(copies):
            for block in pris:
                w.write(block)
    out["4-lane complex, packets"] = folder
    return out


def time_read(path: Path) -> float:
    from autosar_cli.ingest.dca1000 import Dca1000Capture

    t = time.perf_counter()
    n = 0
    for _, block, _ in Dca1000Capture(path).blocks():
        n += len(block)
    return time.perf_counter() - t


def time_ingest(path: Path, out: Path) -> float:
    from autosar_cli.config import load_config
    from autosar_cli.ingest.pipeline import RadarCaptureOptions, ingest

    out.unlink(missing_ok=True)
    t = time.perf_counter()
    ingest([], out, config=load_config(), radar_captures=[path], allow_partial=True,
           radar_options=RadarCaptureOptions(start_ns=1_700_000_000 * 10**9))
    wall = time.perf_counter() - t
    out.unlink()
    return wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--copies", type=int, default=16)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--workdir", type=Path, default=None)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(dir=args.workdir) as tmp:
        work = Path(tmp)
        captures = build_captures(work, args.copies)
        rows = []
        for layout, path in captures.items():
            size = sum(f.stat().st_size for f in path.glob("*.bin"))
            for stage, fn in (("read", lambda p=path: time_read(p)),
                              ("ingest", lambda p=path: time_ingest(p, work / "drive.h5"))):
                fn()  # warm-up: page cache, lazy imports
                walls = [fn() for _ in range(args.repeat)]
                med = statistics.median(walls)
                rows.append({"layout": layout, "stage": stage, "capture_MB": round(size / 1e6, 1),
                             "repeat": args.repeat, "walls_s": [round(w, 3) for w in walls],
                             "median_wall_s": round(med, 3), "throughput_MB_s": round(size / 1e6 / med, 1)})
                print(f"{layout:16s} {stage:7s} {size / 1e6:8.1f} MB  {med:6.3f} s  {size / 1e6 / med:7.1f} MB/s")
    result = {"benchmark": "dca1000", "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                                                  "load_average_1min_after": round(os.getloadavg()[0], 2)},
              "target": {"throughput_MB_s": TARGET_MB_S},
              "command": f"python benches/bench_dca1000.py --copies {args.copies} --repeat {args.repeat}",
              "rows": rows}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "dca1000.json").write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
