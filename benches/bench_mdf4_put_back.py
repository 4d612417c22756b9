"""Benchmark the put-back of a finalised MDF4's records checked by their times alone, with and without their alike bits.

Usage: python benches/bench_mdf4_put_back.py [--trials 120] [--seed 11] [--output benches/results/mdf4_put_back.json]

The 2023 CANedge file (``../shared/realdata/css-electronics``) finalised by asammdf (uncompressed: its records hold
their data bytes, no SD block, so no data offsets check them) gets, per trial, bytes lost or bytes of its own added
(1 B to 8 KiB, seeded) at a seeded place inside its records, and is read with ``read_can_log`` as ingest reads it,
twice in the same run: with the search's count of records that break the bits the block's first and last records
hold alike (``mdf4_sorted.constant_bits``, the product), and without it (``constant_bits`` giving none: the block
is torn, as before the count). Per mode: the frames read (of the undamaged file's, per trial), the frames the
undamaged file lacks (foreign: wrong and not reported), trials that read none, and seconds.
"""

from __future__ import annotations

import argparse
import json
import platform
import random
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

from checkouts import revision

HERE = Path(__file__).resolve().parent
REAL = HERE.parent.parent / "shared" / "realdata" / "css-electronics"
NAME = "2F6913DB_00001089_00000001-63BEF5CD.MF4"
SIZES = (1, 3, 8, 16, 24, 100, 1000, 4000, 4096, 8192)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=120)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--output", type=Path, default=HERE / "results" / "mdf4_put_back.json")
    args = ap.parse_args()
    sys.path.insert(0, str(HERE.parent))
    from asammdf import MDF

    from autosar_cli.ingest import mdf4_shift
    from autosar_cli.ingest.canlog import CanLogError, read_can_log
    from autosar_cli.ingest.mdf4_layout import HEAD, block, blocks
    from autosar_cli.ingest.mdf4_sorted import _sorted_groups

    tmp = Path(tempfile.mkdtemp(prefix="mdf4_put_back_"))
    src = tmp / "finalised.mf4"
    with MDF(REAL / NAME) as mdf:
        mdf.save(src, overwrite=True, compression=0)
    data = src.read_bytes()
    whole = Counter((r.t_ns, r.frame_id, r.data) for r in read_can_log(src))
    found = list(blocks(data))
    regions = [(g[3], g[3] + block(data, g[2])[1] - HEAD.size) for g in _sorted_groups(data, found)]
    product = mdf4_shift.constant_bits
    modes = {"with_alike_bits": product, "without": lambda *a, **k: []}
    totals = {m: {"frames_read": 0, "foreign_frames": 0, "none_read": 0, "seconds": 0.0} for m in modes}
    rng = random.Random(args.seed)
    for i in range(args.trials):
        lo, hi = rng.choice(regions)
        at, size = rng.randrange(lo, hi), rng.choice(SIZES + (rng.randrange(1, 8192),))
        if rng.random() < 0.5:
            damaged = data[:at] + data[at + size:]
        else:
            copied = rng.randrange(0, len(data) - size)
            damaged = data[:at] + data[copied:copied + size] + data[at:]
        path = tmp / f"trial{i}.mf4"
        path.write_bytes(damaged)
        for mode, bits in modes.items():
            mdf4_shift.constant_bits = bits
            t0 = time.perf_counter()
            got: list[tuple[int, int, bytes]] = []
            try:
                for r in read_can_log(path, warn=lambda w: None):  # the frames before the error too
                    got.append((r.t_ns, r.frame_id, r.data))
            except CanLogError:
                pass
            t = totals[mode]
            t["seconds"] += time.perf_counter() - t0
            t["frames_read"] += len(got)
            t["foreign_frames"] += sum((Counter(got) - whole).values())
            t["none_read"] += not got
        path.unlink()
    mdf4_shift.constant_bits = product
    for t in totals.values():
        t["share_read"] = round(t["frames_read"] / (args.trials * whole.total()), 4)
        t["seconds"] = round(t["seconds"], 1)
    result = {"benchmark": "mdf4_put_back", "revision": revision(HERE.parent), "trials": args.trials,
              "seed": args.seed, "frames_whole": whole.total(), "machine": platform.machine(),
              "python": platform.python_version(), **totals}
    args.output.write_text(json.dumps(result, indent=1) + "\n")
    for mode, t in totals.items():
        print(f"{mode}: {100 * t['share_read']:.1f} % of the frames read, {t['foreign_frames']} foreign, "
              f"{t['none_read']} trials none, {t['seconds']} s")


if __name__ == "__main__":
    main()
