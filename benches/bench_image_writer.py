"""Benchmark the product writer's memory: a large image written strip by strip vs whole.

Usage: python benches/bench_image_writer.py [--rows 1500] [--cols 20000] [--strips 16] [--rounds 5]

A (rows x cols) complex64 image (default 1500 x 20000 = 240 MB, a 60 m x 800 m scene at 4 cm) is made
strip by strip from a seeded generator, as tiles of ``focus --tiles`` arrive, and written with
:class:`~autosar_cli.store.image.ImageWriter` (GeoTIFF + image.h5 + quicklook); for comparison the same
image is assembled whole and written with ``write_image``. Each case runs in a fresh process; its peak
RSS, the RSS of the bare process (imports only) and the wall time are reported. The GeoTIFF's column checksums
(``store/tif_checksum.py``) are timed side by side: ``--rounds`` alternated strip-by-strip writes with them and
without (``column_crc32`` and the writer's read-back of the closed GeoTIFF made no-ops; ABBA order, in one process,
the strips made beforehand), medians and their ratio; and ``autosar info image.tif
--verify``'s check of the written GeoTIFF (``verify_geotiff``). Writes benches/results/image_writer.json.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"

CHILD = r"""
import json, resource, sys, time
from pathlib import Path
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
if mode == "verify":
    from autosar_cli.store.tif_checksum import verify_geotiff
    assert verify_geotiff(Path(out).with_suffix(".tif")).intact
elif mode.startswith("checksums"):  # "checksums:ROUNDS": with and without them, ABBA, in this one process
    import autosar_cli.store.image as image_module
    with_them, read_back = image_module.column_crc32, image_module.ImageWriter._read_back_geotiff
    without = lambda db, prior=None: np.zeros(db.shape[1], np.uint32)
    strips = [strip(k) for k in range(n_strips)]
    walls = {"with": [], "without": []}
    for r in range(int(mode.split(":")[1])):
        for case in (("with", "without") if r % 2 == 0 else ("without", "with")):
            image_module.column_crc32 = with_them if case == "with" else without
            # the read-back before the products come into place checks those checksums: without them, without it
            image_module.ImageWriter._read_back_geotiff = read_back if case == "with" else lambda *a: False
            t0 = time.perf_counter()
            with ImageWriter(out, grid, origin, overwrite=True) as w:
                for k in range(n_strips):
                    w.write_columns(int(bounds[k]), strips[k])
                w.set_metadata({"bench": True})
            walls[case].append(time.perf_counter() - t0)
    print(json.dumps({case: sorted(v) for case, v in walls.items()}))
    sys.exit(0)
elif mode == "strips":
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
    ap.add_argument("--rounds", type=int, default=5,
                    help="alternated writes with and without column checksums (and the GeoTIFF's read-back)")
    args = ap.parse_args()
    image_mb = args.rows * args.cols * 8 / 1e6
    result: dict[str, object] = {"benchmark": "image_writer", "rows": args.rows, "cols": args.cols,
                                 "strips": args.strips, "image_mb": round(image_mb, 1),
                                 "strip_mb": round(image_mb / args.strips, 1)}
    with tempfile.TemporaryDirectory() as tmp:
        def child(mode: str, out: str) -> dict[str, float]:
            res = subprocess.run([sys.executable, "-c", CHILD, mode, str(Path(tmp) / out), str(args.rows),
                                  str(args.cols), str(args.strips)], check=True, capture_output=True, text=True)
            row = json.loads(res.stdout.strip().splitlines()[-1])
            row["growth_mb"] = round(row["peak_rss_mb"] - row["imports_rss_mb"], 1)
            print(json.dumps(row))
            return row
        for mode in ("strips", "whole"):
            result[mode] = child(mode, mode)
        res = subprocess.run([sys.executable, "-c", CHILD, f"checksums:{args.rounds}", str(Path(tmp) / "ab"),
                              str(args.rows), str(args.cols), str(args.strips)], check=True, capture_output=True,
                             text=True)
        walls = json.loads(res.stdout.strip().splitlines()[-1])
        print(json.dumps(walls))
        checked, unchecked = float(np.median(walls["with"])), float(np.median(walls["without"]))
        verify = [child("verify", "strips")["wall_s"] for _ in range(3)]
        result["column_checksums"] = {"rounds": args.rounds, "median_wall_s": round(checked, 3),
                                      "median_wall_without_s": round(unchecked, 3),
                                      "ratio": round(checked / unchecked, 3),
                                      "verify_median_wall_s": float(np.median(verify))}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "image_writer.json").write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
