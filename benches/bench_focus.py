"""Benchmark `autosar focus`: kernel throughput, end-to-end time on test1, peak memory vs drive length.

Usage: python benches/bench_focus.py [--repeat 5] [--workdir DIR] [--kernel-only] [--against DIR]

1. Kernel, fixed synthetic case (like the peers' published benchmarks): 512 pulses, 256 range bins,
   256 x 256 grid at 4 cm, 1 channel (one Tx/Rx pair), side-looking at 2-12 m ground range, 4 mm
   between pulses. Two windows: every pulse for every pixel (the peers' count, 33.6 M back-projections,
   with up to 70 deg of squint and range migration across 20 bins), and the stripmap window of focus
   (rho = 4 cm). Throughput = pixels x pulses x channels summed / s of ``backproject_block`` (the data
   already in the kernel's layout), median of ``--repeat`` runs, with numba's threads and with 1. Beside it,
   a straightforward numba loop on the same case (float64 distances, cos/sin per sample) as this host's
   yardstick, and the kernel's speed-up over it.
2. test1 (simulated, seed 1, MCAP, ingested, SAR-MIN trajectory): ``autosar focus`` with 8 channels,
   4 cm pixels, full swath, in a fresh process per run: wall time (median) of the focus call (numba's
   start-up and the writing included) and of the whole process (interpreter start and imports too, what
   the command takes), each as a fraction of the drive's duration; the call's split, kernel throughput,
   and peak RSS of the process.
3. The same drive four times over (radar frames repeated, trajectory repeated and translated end to
   start so the car drives on): peak RSS must not grow beyond the larger image; and the same focused in
   8 tiles, written tile by tile (peak RSS must stay near the one-drive figure).
A host reference (a fixed FFT workload) is timed before and after, since this host's speed varies by
tens of per cent from minute to minute. ``--against DIR`` (another checkout, e.g. ``git worktree add DIR REV``)
measures 1 and 2 there too, alternating with this one (the kernel case in a process of each checkout in turn,
``--repeat`` times; test1's focus runs interleaved), and records each figure's ratio this / against.
Writes benches/results/focus.json.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from checkouts import in_checkout, revision

import autosar_cli  # noqa: F401  (first: lets numba use 512-bit vectors, see autosar_cli/__init__.py)

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benches" / "results"
C = 299_792_458.0


def _straightforward_tdbp():  # noqa: ANN202 - a numba dispatcher, compiled on first use
    """The issue's "straightforward numba loop": pixels in parallel, every pulse in turn, exact float64 distances,
    linear interpolation, the carrier phase by cos/sin. Timed on the fixed case as this host's yardstick (the
    issue quotes ~0.2 G/s for it on its machine), so the kernel's figure can be read as a ratio too."""
    import numba

    @numba.njit(parallel=True, fastmath=True)
    def tdbp(re, im, tx, rx, pix, range0, bin_inv, cycles_per_m, out_re, out_im):  # pragma: no cover - compiled
        n_bins = re.shape[0]
        for k in numba.prange(pix.shape[0]):
            sr = 0.0
            si = 0.0
            for p in range(tx.shape[0]):
                path = (math.sqrt((pix[k, 0] - tx[p, 0]) ** 2 + (pix[k, 1] - tx[p, 1]) ** 2
                                  + (pix[k, 2] - tx[p, 2]) ** 2)
                        + math.sqrt((pix[k, 0] - rx[p, 0]) ** 2 + (pix[k, 1] - rx[p, 1]) ** 2
                                    + (pix[k, 2] - rx[p, 2]) ** 2))
                fi = (path - range0) * bin_inv
                ib = int(math.floor(fi))
                if ib < 0 or ib + 1 >= n_bins:
                    continue
                fr = fi - ib
                s_re = re[ib, p] + fr * (re[ib + 1, p] - re[ib, p])
                s_im = im[ib, p] + fr * (im[ib + 1, p] - im[ib, p])
                ph = 2.0 * math.pi * path * cycles_per_m
                c = math.cos(ph)
                s = math.sin(ph)
                sr += s_re * c + s_im * s
                si += s_im * c - s_re * s
            out_re[k] = sr
            out_im[k] = si

    return tdbp


def kernel_case(repeat: int) -> list[dict[str, object]]:
    import numba

    from autosar_cli.sar.backprojection import PulseBlock, backproject_block
    from autosar_cli.sar.stripmap import processed_half_width, stripmap_windows

    rng = np.random.default_rng(0)
    n_p, n_b, n = 512, 256, 256
    x = (np.arange(n_p) - n_p / 2) * 0.004
    tx = np.stack([x, np.zeros(n_p), np.full(n_p, 0.5)], axis=1)
    rx = tx + np.array([0.0019, 0.0, 0.0])
    prof = (rng.standard_normal((1, n_b, n_p)) + 1j * rng.standard_normal((1, n_b, n_p))).astype(np.complex64)
    block = PulseBlock.from_profiles(prof, np.stack([tx, rx]), [[0, 1]], range0_m=3.5, bin_m=0.1,
                                     cycles_per_m=78.5e9 / C)
    gx, gy = np.meshgrid((np.arange(n) - n / 2) * 0.04, -2.0 - np.arange(n) * 0.04)
    pix = np.stack([gx.ravel(), gy.ravel(), np.full(n * n, 0.5)], axis=1)
    full = np.tile([0, n_p], (n * n, 1))
    strip = stripmap_windows(pix, tx, np.tile([1.0, 0.0, 0.0], (n_p, 1)),
                             processed_half_width(C / 78.5e9, 0.04), side=-1.0)
    rows = []
    for name, win in (("all pulses for every pixel", full), ("stripmap window, rho 4 cm", strip)):
        bps = int(np.sum(win[:, 1] - win[:, 0]))
        for threads in (numba.config.NUMBA_NUM_THREADS, 1):
            numba.set_num_threads(threads)
            backproject_block(block, pix, win)
            walls = []
            for _ in range(repeat):
                t = time.perf_counter()
                backproject_block(block, pix, win)
                walls.append(time.perf_counter() - t)
            wall = statistics.median(walls)
            rows.append({"case": f"fixed 512 x 256 bins x 256^2 px, 1 channel: {name}", "threads": threads,
                         "backprojections": bps, "median_s": round(wall, 4), "walls_s": [round(w, 4) for w in walls],
                         "bp_per_s": round(bps / wall / 1e9, 3)})
            print(json.dumps(rows[-1]))
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    # the yardstick: a straightforward numba loop on the same case (every pulse for every pixel)
    tdbp = _straightforward_tdbp()
    re_, im_ = np.ascontiguousarray(prof[0].real), np.ascontiguousarray(prof[0].imag)
    out_re, out_im = np.zeros(len(pix)), np.zeros(len(pix))
    args = (re_, im_, tx, rx, pix, 3.5, 10.0, 78.5e9 / C, out_re, out_im)
    tdbp(*args)
    walls = []
    for _ in range(repeat):
        t = time.perf_counter()
        tdbp(*args)
        walls.append(time.perf_counter() - t)
    wall = statistics.median(walls)
    bps = len(pix) * n_p
    mine = next(r for r in rows if r["threads"] == numba.config.NUMBA_NUM_THREADS)
    rows.append({"case": "fixed case, all pulses: straightforward numba loop (float64 distances, cos/sin)",
                 "threads": numba.config.NUMBA_NUM_THREADS, "backprojections": bps, "median_s": round(wall, 4),
                 "walls_s": [round(w, 4) for w in walls], "bp_per_s": round(bps / wall / 1e9, 3),
                 "kernel_speedup": round(wall / mine["median_s"], 2)})
    print(json.dumps(rows[-1]))
    return rows


def kernel_side_by_side(against: Path, repeat: int) -> tuple[list[dict[str, object]], dict[str, object]]:
    """The kernel case in a process of this checkout and of ``against`` in turn, ``repeat`` times: this
    checkout's rows (each the median over its processes' medians) and the other's, with the ratio of the two."""
    runs: dict[str, list[list[dict[str, object]]]] = {"this": [], "against": []}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(repeat):
            for name, source in (("this", ROOT), ("against", against)):
                runs[name].append(in_checkout(__file__, source, ["--repeat", str(repeat)], Path(tmp) / f"{name}{r}"))

    def merged(rows_per_run: list[list[dict[str, object]]]) -> list[dict[str, object]]:
        out = []
        for i, row in enumerate(rows_per_run[0]):
            medians = [rows[i]["median_s"] for rows in rows_per_run]
            out.append({**row, "median_s": round(statistics.median(medians), 4), "process_medians_s": medians,
                        "bp_per_s": round(row["backprojections"] / statistics.median(medians) / 1e9, 3)})
        return out

    this, other = merged(runs["this"]), merged(runs["against"])
    for mine, theirs in zip(this, other, strict=True):
        mine["ratio_to_against"] = round(mine["median_s"] / theirs["median_s"], 3)
        print(json.dumps({"case": mine["case"], "threads": mine["threads"], "ratio": mine["ratio_to_against"]}))
    return this, {"revision": revision(against), "kernel": other}


CHILD = r"""
import json, resource, sys, time
from autosar_cli.config import load_config
from autosar_cli.sar.focus import FocusOptions, focus
from autosar_cli.sar.tiles import focus_tiled
cfg = load_config()
tiles = int(sys.argv[4])
t = time.perf_counter()
if tiles > 1:
    rep = focus_tiled(sys.argv[1], sys.argv[2], sys.argv[3], cfg, FocusOptions.from_config(cfg), tiles=tiles,
                      overwrite=True)
else:
    rep = focus(sys.argv[1], sys.argv[2], sys.argv[3], cfg, FocusOptions.from_config(cfg), overwrite=True)
wall = time.perf_counter() - t
d = rep.to_dict()
d["focus_wall_s"] = wall
d["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps(d))
"""


def run_focus(drive: Path, traj: Path, out: Path, tiles: int = 1, source: Path | None = None) -> dict[str, object]:
    """Focus in a fresh process (with ``source``'s package where given): the focus call's wall time
    (``focus_wall_s``) and the whole process's (``process_wall_s``: interpreter start, imports, the call and the
    exit, as ``autosar focus`` takes)."""
    env = {**os.environ, "PYTHONPATH": str(source)} if source is not None else None
    t = time.perf_counter()
    res = subprocess.run([sys.executable, "-c", CHILD, str(drive), str(traj), str(out), str(tiles)], check=True,
                         capture_output=True, text=True, env=env, cwd=source)
    d = json.loads(res.stdout.strip().splitlines()[-1])
    d["process_wall_s"] = time.perf_counter() - t
    return d


def repeat_drive(drive: Path, traj_path: Path, times: int, out_drive: Path, out_traj: Path) -> None:
    """The drive ``times`` over: radar frames repeated, the trajectory translated end to start each time."""
    import h5py

    from autosar_cli.store.drive import radar_compression
    from autosar_cli.store.trajectory import read_trajectory, write_trajectory

    traj = read_trajectory(traj_path)
    with h5py.File(drive, "r") as src, h5py.File(out_drive, "w") as dst:
        dst.attrs.update(src.attrs)
        name = next(iter(src["radar"]))
        g = src["radar"][name]
        t = g["t_ns"][()]
        span = int(t[-1] - t[0] + (t[1] - t[0]))
        d = dst.require_group("radar").create_group(name)
        d.attrs.update(g.attrs)
        d["t_ns"] = np.concatenate([t + k * span for k in range(times)])
        d["frame_index"] = np.concatenate([g["frame_index"][()] + k * len(t) for k in range(times)])
        raw = g["raw"]
        out = d.create_dataset("raw", (len(t) * times, *raw.shape[1:]), raw.dtype, chunks=raw.chunks,
                               **radar_compression())
        for k in range(times):
            for i in range(0, len(t), 1024):
                block = raw[i: i + 1024]
                out[k * len(t) + i: k * len(t) + i + len(block)] = block
    # translate each copy so it starts where the previous one ended (in time and space)
    k_in = (traj.t_ns >= t[0]) & (traj.t_ns <= t[0] + span)
    base_t = traj.t_ns[k_in]
    rot = traj.heading[k_in][-1] - traj.heading[k_in][0]
    parts = {k: [] for k in ("t", "xy", "psi", "v", "w")}
    xy0 = traj.rear_axle_enu[k_in] - traj.rear_axle_enu[k_in][0]
    pos, psi0 = traj.rear_axle_enu[k_in][0].copy(), 0.0
    for k in range(times):
        c, s = math.cos(psi0), math.sin(psi0)
        parts["t"].append(base_t + k * span)
        parts["xy"].append(pos + xy0 @ np.array([[c, s], [-s, c]]))
        parts["psi"].append(traj.heading[k_in] + psi0)
        parts["v"].append(traj.speed[k_in])
        parts["w"].append(traj.yaw_rate[k_in])
        pos = parts["xy"][-1][-1]
        psi0 += rot
    traj.t_ns = np.concatenate(parts["t"])
    keep = np.r_[True, np.diff(traj.t_ns) > 0]
    traj.t_ns = traj.t_ns[keep]
    traj.rear_axle_enu = np.concatenate(parts["xy"])[keep]
    traj.heading = np.concatenate(parts["psi"])[keep]
    traj.speed = np.concatenate(parts["v"])[keep]
    traj.yaw_rate = np.concatenate(parts["w"])[keep]
    traj.state = traj.covariance = None
    write_trajectory(out_traj, traj)


def host_reference(repeat: int = 21) -> dict[str, object]:
    """A fixed workload (one thread: 512 FFTs of 2160 points, complex64), timed before and after the benchmark.

    This host's speed varies by tens of per cent from minute to minute; the ratio of this figure between two
    runs tells how much of a difference is the host's.
    """
    import scipy.fft

    x = np.random.default_rng(0).standard_normal((512, 2160)).astype(np.complex64)
    walls = []
    for _ in range(repeat):
        t = time.perf_counter()
        scipy.fft.fft(x, axis=-1, workers=1)
        walls.append(time.perf_counter() - t)
    return {"case": "host reference: 512 x 2160-point complex64 FFTs, 1 thread", "median_ms":
            round(statistics.median(walls) * 1e3, 3), "min_ms": round(min(walls) * 1e3, 3)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--workdir", type=Path, default=None)
    ap.add_argument("--kernel-only", action="store_true")
    ap.add_argument("--against", type=Path, default=None, help="another checkout, measured alternately")
    ap.add_argument("--worker", type=Path, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker is not None:  # the kernel case in this process's package, for --against
        args.worker.write_text(json.dumps(kernel_case(args.repeat)))
        return
    result: dict[str, object] = {"benchmark": "focus", "revision": revision(ROOT), "host_before": host_reference()}
    print(json.dumps(result["host_before"]))
    against = args.against.resolve() if args.against else None
    if against is None:
        result["kernel"] = kernel_case(args.repeat)
    else:
        result["kernel"], result["against"] = kernel_side_by_side(against, args.repeat)
    if not args.kernel_only:
        from autosar_cli.config import load_config
        from autosar_cli.ingest.pipeline import ingest
        from autosar_cli.nav.navigate import navigate
        from autosar_cli.store.trajectory import write_trajectory

        cfg = load_config()
        with tempfile.TemporaryDirectory() as tmp:
            work = args.workdir or Path(tmp)
            work.mkdir(parents=True, exist_ok=True)
            log = work / "test1_seed1.mcap"
            if not log.exists():
                subprocess.run([sys.executable, "-m", "autosar_cli.cli", "simulate", "--scenario", "test1", "--seed",
                                "1", "--output", str(log), "--overwrite"], check=True, capture_output=True)
            drive = work / "test1_seed1.drive.h5"
            if not drive.exists():
                ingest([log], drive, config=cfg)
            traj = work / "test1_seed1.sarmin.h5"
            if not traj.exists():
                write_trajectory(traj, navigate(drive, "sar-min", cfg))
            runs, other = [], []
            for source in (ROOT, against) if against is not None else ():
                run_focus(drive, traj, work / "image_warmup", source=source)  # each checkout's kernels compiled
            for _ in range(args.repeat):
                runs.append(run_focus(drive, traj, work / "image", source=ROOT))
                if against is not None:
                    other.append(run_focus(drive, traj, work / "image_against", source=against))
            walls = [r["focus_wall_s"] for r in runs]
            procs = [r["process_wall_s"] for r in runs]
            med = runs[int(np.argsort(walls)[len(walls) // 2])]
            row = {"case": "test1, 8 channels, 4 cm, full swath (autosar focus, fresh process per run)",
                   "drive_s": round(med["drive_s"], 2), "median_wall_s": round(statistics.median(walls), 3),
                   "walls_s": [round(w, 3) for w in walls],
                   "fraction_of_drive": round(statistics.median(walls) / med["drive_s"], 3),
                   "median_process_wall_s": round(statistics.median(procs), 3),
                   "process_walls_s": [round(w, 3) for w in procs],
                   "process_fraction_of_drive": round(statistics.median(procs) / med["drive_s"], 3),
                   "timings_s_of_median_run": {k: round(v, 3) for k, v in med["timings_s"].items()},
                   "backprojections": med["backprojections"],
                   "kernel_bp_per_s": round(med["backprojections_per_s"] / 1e9, 3),
                   "grid_shape": med["grid_shape"], "peak_rss_mb": round(max(r["peak_rss_mb"] for r in runs), 1)}
            print(json.dumps(row))
            result["test1"] = row
            if against is not None:
                theirs = [r["focus_wall_s"] for r in other]
                result["against"]["test1"] = {"median_wall_s": round(statistics.median(theirs), 3),
                                              "walls_s": [round(w, 3) for w in theirs],
                                              "ratio": round(statistics.median(walls) / statistics.median(theirs), 3)}
                print(json.dumps(result["against"]["test1"]))
            drive4, traj4 = work / "test1x4.drive.h5", work / "test1x4.traj.h5"
            if not (drive4.exists() and traj4.exists()):
                repeat_drive(drive, traj, 4, drive4, traj4)
            r4 = run_focus(drive4, traj4, work / "image4")
            row4 = {"case": "test1 four times over (radar repeated, trajectory continued)",
                    "drive_s": round(r4["drive_s"], 2), "wall_s": round(r4["focus_wall_s"], 3),
                    "process_wall_s": round(r4["process_wall_s"], 3),
                    "grid_shape": r4["grid_shape"], "peak_rss_mb": round(r4["peak_rss_mb"], 1),
                    "image_mb_1x": round(math.prod(row["grid_shape"]) * 8 / 1e6, 1),
                    "image_mb_4x": round(math.prod(r4["grid_shape"]) * 8 / 1e6, 1)}
            print(json.dumps(row4))
            result["test1x4"] = row4
            rt = run_focus(drive4, traj4, work / "image4t", tiles=8)
            rowt = {"case": "test1 four times over, focused in 8 tiles (focus_tiled, in-process)",
                    "wall_s": round(rt["focus_wall_s"], 3), "process_wall_s": round(rt["process_wall_s"], 3),
                    "grid_shape": rt["grid_shape"],
                    "peak_rss_mb": round(rt["peak_rss_mb"], 1),
                    "image_mb_tile": round(math.prod(rt["grid_shape"]) * 8 / 8 / 1e6, 1)}
            print(json.dumps(rowt))
            result["test1x4_tiles8"] = rowt
    result["host_after"] = host_reference()
    print(json.dumps(result["host_after"]))
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "focus.json").write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
