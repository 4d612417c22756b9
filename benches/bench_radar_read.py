"""Benchmark the raw radar cube's chunk layout: one chunk per channel (the drive writer's) against whole frames
per chunk (drives written before), side by side.

Usage: python benches/bench_radar_read.py [--drive DRIVE.h5] [--scenario test2] [--seed 1] [--repeat 5]

Takes a drive's raw cube (default: test2 seed 1, full dynamics, simulated and ingested by
``bench_af_pass_ranges.kept_drive``), writes it into two scratch files with the writer's compression and
checksums: the writer's layout (``store.drive.radar_layout``: 64 frames of one channel per chunk, a chunk cache of
two chunk rows) and whole frames, 32 per chunk, as drives were written before (h5py's default cache). Then,
alternating the layouts in each of ``--repeat`` rounds, times writing the cube in blocks of 128 frames as ingest
appends a log's frames, and reading it back in blocks of 512 frames (focus's) with :meth:`RadarStream.frames`:
every channel, the product image's 8 and the autofocus's 2 (``sar.focus.channel_pairs``). Prints medians and the
per-channel layout's time over the whole-frame one's; writes benches/results/radar_read.json.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from autosar_cli.ingest.decoders import RadarDecoder
from autosar_cli.sar.focus import channel_pairs
from autosar_cli.store.drive import Drive, RadarStream, radar_compression, radar_layout

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_af_pass_ranges import kept_drive  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
WRITE_FRAMES = RadarDecoder.BLOCK  #: ingest's appends of RawFrame messages
READ_FRAMES = 512
WHOLE_FRAME_CHUNK_FRAMES = 32  #: the chunks of drives written before per-channel chunks


def write_cube(path: Path, raw: h5py.Dataset, layout: dict[str, Any]) -> float:
    """Copy ``raw`` into a fresh file at ``path`` in ingest's appends, chunked as ``layout`` says (create_dataset's
    keywords); the seconds spent in the appends."""
    shape = raw.shape[1:]
    spent = 0.0
    with h5py.File(path, "w", libver="latest") as f:
        ds = f.create_dataset("raw", shape=(0, *shape), maxshape=(None, *shape), dtype=np.int16, fletcher32=True,
                              **layout, **radar_compression())
        for start in range(0, len(raw), WRITE_FRAMES):
            block = raw[start:start + WRITE_FRAMES]
            t = time.perf_counter()
            ds.resize(start + len(block), axis=0)
            ds[start:] = block
            spent += time.perf_counter() - t
        t = time.perf_counter()
    return spent + time.perf_counter() - t  # the close flushes the last chunks


def read_cube(path: Path, pairs: list[tuple[int, int]] | None) -> float:
    """Seconds to read the cube at ``path`` in focus's blocks, the channels ``pairs`` (None: whole frames)."""
    with h5py.File(path, "r") as f:
        radar = RadarStream("bench", np.zeros(0, np.int64), np.zeros(0, np.int64), f["raw"], {})
        t = time.perf_counter()
        for start in range(0, len(radar.raw), READ_FRAMES):
            radar.frames(start, start + READ_FRAMES, pairs)
        return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drive", type=Path, default=None, help="a drive.h5 (default: simulate one)")
    ap.add_argument("--scenario", default="test2")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--output", type=Path, default=RESULTS / "radar_read.json")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        drive = args.drive or kept_drive(args.scenario, args.seed, work / "drive") / "drive.h5"
        with Drive(drive) as d:
            source = d.radar().raw
            n_tx, n_rx = source.shape[1:3]
            layouts = {"per_channel": radar_layout(source.shape[1:]),
                       "whole_frame": {"chunks": (WHOLE_FRAME_CHUNK_FRAMES, *source.shape[1:])}}
            reads = {"all_12": None, "image_8": channel_pairs(n_tx, n_rx, 8),
                     "autofocus_2": channel_pairs(n_tx, n_rx, 2)}
            times: dict[str, dict[str, list[float]]] = {k: {op: [] for op in ("write", *reads)} for k in layouts}
            for i in range(args.repeat):
                order = list(layouts) if i % 2 == 0 else list(layouts)[::-1]
                for name in order:
                    path = work / f"{name}.h5"
                    times[name]["write"].append(write_cube(path, source, layouts[name]))
                    for op, pairs in reads.items():
                        times[name][op].append(read_cube(path, pairs))
                    print(f"round {i + 1} {name}: " + ", ".join(f"{op} {v[-1]:.3f} s" for op, v in
                                                                  times[name].items()), flush=True)
            shape, mb = list(source.shape), source.size * 2 / 1e6
    medians = {k: {op: round(statistics.median(v), 4) for op, v in ops.items()} for k, ops in times.items()}
    result = {"benchmark": "radar_read", "drive": str(args.drive) if args.drive else f"{args.scenario} seed "
              f"{args.seed}", "cube_shape": shape, "cube_mb": round(mb, 1), "repeat": args.repeat,
              **{f"median_{k}_s": v for k, v in medians.items()},
              "ratio_per_channel_to_whole_frame": {op: round(medians["per_channel"][op] / medians["whole_frame"][op],
                                                             3) for op in medians["per_channel"]}}
    print(json.dumps(result, indent=2))
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
