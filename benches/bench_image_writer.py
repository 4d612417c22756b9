"""Benchmark the product writer's memory: a large image written strip by strip vs whole.

Usage: python benches/bench_image_writer.py [--rows 1500] [--cols 20000] [--strips 16]

A (rows x cols) complex64 image (default 1500 x 20000 = 240 MB, a 60 m x 800 m scene at 4 cm) is made
strip by strip from a seeded generator, as tiles of ``focus --tiles`` arrive, and written with
:class:`~autosar_cli.store.image.ImageWriter` (GeoTIFF + image.h5 + quicklook); for comparison the same
image is assembled whole and written with ``write_image``. Each case runs in a fresh process; its peak
RSS, the RSS of the bare process (imports only) and the wall time are reported. Writes
benches/results/image_writer.json.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"

CHILD = r"""
import json, resource, sys, time
import numpy as np
from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.sar.grid import FocusGrid
from autosar_cli.store.image import FocusedImage, ImageWriter, write_image
mode, out, rows, cols, n_strips = sys.argv[1], sys.argv[2], *map(int, sys.argv[3:6])
grid = FocusGrid((0.0, 0.0), (1.0, 0.0), (0.0, -1.0), 0.04, cols, rows, 0.0)
origin = GeodeticOrigin(45.06, 7.66, 240.0)
bounds = np.linspace(0, cols, n_strips + 1).astype(int)
def strip(k):
    rng = np.random.default_rng(k)
    n = bounds[k + 1] - bounds[k]
    z = rng.standard_normal((rows, n), np.float32) + 1j * rng.standard_normal((rows, n), np.float32)
    return z.astype(np.complex64)
base_rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
t = time.perf_counter()
if mode == "strips":
    with ImageWriter(out, grid, origin, overwrite=True) as w:
        for k in range(n_strips):
            w.write_columns(int(bounds[k]), strip(k))
        w.set_metadata({"bench": True})
else:
    image = np.concatenate([strip(k) for k in range(n_strips)], axis=1)
    write_image(out, FocusedImage(image, grid, origin, {"bench": True}), overwrite=True)
print(json.dumps({"mode": mode, "wall_s": round(time.perf_counter() - t, 2), "imports_rss_mb": round(base_rss, 1),
                  "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)}))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=1500)
    ap.add_argument("--cols", type=int, default=20000)
    ap.add_argument("--strips", type=int, default=16)
    args = ap.parse_args()
    image_mb = args.rows * args.cols * 8 / 1e6
    result: dict[str, object] = {"benchmark": "image_writer", "rows": args.rows, "cols": args.cols,
                                 "strips": args.strips, "image_mb": round(image_mb, 1),
                                 "strip_mb": round(image_mb / args.strips, 1)}
    with tempfile.TemporaryDirectory() as tmp:
        for mode in ("strips", "whole"):
            res = subprocess.run([sys.executable, "-c", CHILD, mode, str(Path(tmp) / mode), str(args.rows),
                                  str(args.cols), str(args.strips)], check=True, capture_output=True, text=True)
            row = json.loads(res.stdout.strip().splitlines()[-1])
            row["growth_mb"] = round(row["peak_rss_mb"] - row["imports_rss_mb"], 1)
            print(json.dumps(row))
            result[mode] = row
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "image_writer.json").write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
