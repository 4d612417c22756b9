"""Benchmark the autofocus's fast-motion stage: the across-track motion above 2 Hz from many scatterers.

Usage: python benches/bench_af_high_band.py [--drives test1:0,test2:1,test3:8] [--cut-hz 2]
                                            [--simulation KEY=VALUE,...] [--vertical | --elevation]
                                            [--fast KEY=VALUE,...] [--dynamics kinematic] [--append]
                                            [--output benches/results/af_high_band.json]

The stage (``autosar_cli.sar.fast_motion``, last in ``run --autofocus`` where the config's
``processing.autofocus_fast_motion`` is on; docs/AUTOFOCUS.md) takes the motion the
product's few isolated points (3-16 m from the track, which on test1 see 61 % of the drive) miss: the far swath's
entropy lacks the across-track motion above 0.5 Hz where they do not see (bench_af_oracle.py). For every drive
(``simulate --dynamics full``): ``compare --methods sar-min,sar-min+af,truth`` with the autofocus without the stage
(``AutofocusOptions.fast_motion`` off), then with it. Rows: far-swath entropy against the truth image's, worst
reflector, peak loss; the stage's histories, coverage and time; and how its correction compares with the truth's
(the radar's true across-track motion less the track's before the stage) in 2-5 and 5-30 Hz, over the frames it
covers; ``table`` has one line per drive of the main figures. ``--simulation``: entries of the simulator's
[simulation] section for these drives (the processor keeps the config's), recorded in their rows; ``--append``: add
the rows to the output's. ``--vertical`` / ``--elevation`` (not in the product): the stage's fit, along the track
without it and on its scatterers there, with a vertical motion too: common to all histories with unknown gains, or
each history's gain measured by the array's raised Tx (``high_band_motion``). The committed file:
``--drives test1:0,test2:1,test3:8,test1:1,test2:0,test3:1``, then ``--drives test1:1,test3:1 --simulation
vibration_vertical_rms_m=0.0 --append`` (the radar case's vertical vibration off), then the six again with
``--elevation --append``, then ``--drives test1:2,test2:2,test3:2,test1:3,test2:3,test3:3,test1:4,test2:4,test3:4
--append`` and ``--drives urban:1,urban:2 --append`` (the stage as this bench's function then: the file's note); then
the product's: ``--drives test1:0,test2:1,test3:1 [--fast ...] --append``, ``--drives test1:1 --dynamics kinematic
--append``, ``--drives test1:0,urban:2,test3:1,test2:1,urban:7 --append`` (the halves' mean), then ``--drives
test1:0,test3:1,urban:7 --append`` and ``--drives test2:1,urban:2 --append``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"
#: (Tx, Rx) pairs of ``--elevation``: four of the lambda/4 row (Tx0, Tx2), then Tx1's four, each lambda/2 above the
#: one four before it at the same place along the row (the config's array: Tx1 at y = lambda, z = lambda/2)
ELEVATION_PAIRS = [(0, 2), (0, 3), (2, 0), (2, 1), (1, 0), (1, 1), (1, 2), (1, 3)]


def bright_scatterers(drive: Path, traj: Any, config: Any) -> Any:
    """(S, 3) ENU m: the fast-motion stage's scatterers on the first image along ``traj``."""
    from autosar_cli.sar.fast_motion import FastMotionOptions
    from autosar_cli.sar.focus import FocusOptions
    from autosar_cli.sar.point_selection import points_and_scatterers
    from autosar_cli.sar.residual_motion import AutofocusOptions

    return points_and_scatterers(drive, traj, config, FocusOptions.from_config(config),
                                 AutofocusOptions.from_config(config), FastMotionOptions())[1]


def high_band_motion(drive: Path, traj: Any, config: Any, points: Any, cut_hz: float, prior_m: float = 3e-4,
                     vertical: bool = False, elevation: bool = False) -> dict[str, Any]:
    """The product's fast-motion fit (``autosar_cli.sar.fast_motion``) with a vertical motion too, along ``traj``:
    the across-track correction (m, on its nodes) above ``cut_hz``, the histories used and the share of the nodes
    they cover. ``vertical``: a vertical motion common to all histories, which each history sees with its own
    unknown gain (the sine of its elevation, its scatterer's height unknown): alternately the two motions with the
    gains held and each gain with the motions held; only the across-track motion is returned. ``elevation``: that
    vertical motion with each history's gain measured by the array (``ELEVATION_PAIRS``: Tx1 sits lambda/2 above Tx0
    and Tx2, so of two channels at one place along the row, one raised, the back-projected phases differ by pi times
    the sine of the elevation of what the history holds less its pixel's; one gain per history), one linear fit of
    both motions."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla
    from scipy.signal import butter, sosfiltfilt

    from autosar_cli.sar.fast_motion import (
        FastMotionOptions,
        history_steps,
        moving_average_removal,
        node_prior,
        step_design,
    )
    from autosar_cli.sar.focus import FocusOptions
    from autosar_cli.sar.phase_history import focus_history, gather_phase_histories, pair_antennas

    opts = FastMotionOptions(cut_hz=cut_hz, prior_m=prior_m)
    hist = gather_phase_histories(drive, traj, config, points, FocusOptions.from_config(config),
                                  half_beam_deg=opts.half_beam_deg, window_bins=opts.window_bins, channels=2,
                                  pairs=ELEVATION_PAIRS if elevation else None)
    antennas = pair_antennas(hist, traj, config)
    half = len(ELEVATION_PAIRS) // 2
    z, los = focus_history(hist, *antennas, points, slice(0, half) if elevation else slice(None))
    hs = history_steps(hist, z, los, traj, config, opts)
    t0 = int(traj.t_ns[0])
    n_nodes = int(math.ceil((int(traj.t_ns[-1]) - t0) / 1e9 / opts.node_s)) + 1
    nodes_ns = t0 + np.round(np.arange(n_nodes) * opts.node_s * 1e9).astype(np.int64)
    if not hs.runs:
        return {"nodes_ns": nodes_ns, "correction_m": np.zeros(n_nodes), "histories": 0, "used": 0, "coverage": 0.0,
                "seen": np.zeros(n_nodes, dtype=bool)}
    up_gain = []
    if elevation:
        raised = focus_history(hist, *antennas, points, slice(half, None))[0]
        up_gain = [np.angle(np.nansum(raised[run] * np.conj(z[run]))) / math.pi for run in hs.runs]
    kappa = 4.0 * math.pi * hist.cycles_per_m
    seg, n_seg = hs.segment, hs.n_histories
    detrend = moving_average_removal(seg, max(1, int(round(0.5 * opts.window_s * hs.prf_hz / opts.every))))
    data = detrend @ hs.step
    model = (detrend @ step_design(hs.t, hs.gain, n_nodes, opts.node_s, kappa)).tocsr()
    # the vertical: its unit-gain design (each step's vertical line-of-sight change is the history's own gain)
    unit = (detrend @ step_design(hs.t, np.ones_like(hs.gain), n_nodes, opts.node_s, kappa)).tocsr()
    prior_both = sp.block_diag([node_prior(n_nodes, opts.prior_m, opts.step_m),
                                node_prior(n_nodes, 3e-3, opts.step_m)]).tocsc()
    if elevation:  # the gains measured: one linear fit of both motions
        model = sp.hstack([model, unit.multiply(np.asarray(up_gain)[seg][:, None])]).tocsr()
    used = np.ones(n_seg, dtype=bool)
    var = np.full(n_seg, 0.3**2)
    h = np.full(n_seg, 0.1)
    for _ in range(12 if vertical else opts.iterations):
        w = used[seg] / var[seg]
        if elevation:
            x = spla.spsolve((model.T @ model.multiply(w[:, None])).tocsc() + prior_both, model.T @ (w * data))
            fit, e = model @ x, x[:n_nodes]
        else:
            both = sp.hstack([model, unit.multiply(h[seg][:, None])]).tocsr()
            x = spla.spsolve((both.T @ both.multiply(w[:, None])).tocsc() + prior_both, both.T @ (w * data))
            e, e_up = x[:n_nodes], x[n_nodes:]
            q = unit @ e_up
            r = data - model @ e
            h = np.bincount(seg, r * q, n_seg) / np.maximum(np.bincount(seg, q * q, n_seg), 1e-30)
            # the gauge: h e_up is what the data fix; the gains' RMS is held at 0.1
            c = 0.1 / max(float(np.sqrt(np.mean(h[used] ** 2))), 1e-12)
            h, e_up = h * c, e_up / c
            fit = model @ e + h[seg] * (unit @ e_up)
        rms = np.sqrt(np.bincount(seg, (data - fit) ** 2, n_seg) / np.maximum(np.bincount(seg, minlength=n_seg), 1))
        var = np.maximum(rms, 0.02) ** 2
        bad = used & (rms > opts.max_rms_rad)
        if not bad.any() and elevation:
            break
        used &= ~bad
    seen = np.zeros(n_nodes, dtype=bool)
    for s in np.flatnonzero(used):
        span = hs.t[seg == s, 0]
        seen[int(span.min() / opts.node_s):int(span.max() / opts.node_s) + 1] = True
    high = -sosfiltfilt(butter(4, cut_hz, "highpass", fs=1.0 / opts.node_s, output="sos"), e)
    gains_used = np.asarray(up_gain)[used] if elevation else np.zeros(0)
    return {"nodes_ns": nodes_ns, "correction_m": high, "histories": n_seg, "used": int(used.sum()),
            "coverage": float(seen.mean()), "seen": seen,
            "up_gain": [round(float(np.median(gains_used)), 4), round(float(gains_used.std()), 4)]
            if len(gains_used) else None}


def with_high_band(cut_hz: float, record: dict[str, Any], vertical: bool = False, prior_m: float = 3e-4,
                   elevation: bool = False, fast: dict[str, Any] | None = None) -> Any:
    """A replacement for compare's ``autofocus_residual_motion``: the product's without its fast-motion stage,
    then ``high_band_motion`` with a vertical motion (``vertical`` or ``elevation``); or else the product's own, the
    stage recorded (``fast``: its options other than the defaults)."""
    from autosar_cli.sar.autofocus_stage import autofocus_residual_motion
    from autosar_cli.sar.fast_motion import FastMotionOptions
    from autosar_cli.sar.phase_history import frame_geometry
    from autosar_cli.types import MotionCorrection

    def corrected(drive: Path, traj: Any, config: Any, *args: Any, **kwargs: Any) -> Any:
        start = time.perf_counter()
        if not (vertical or elevation):
            options = FastMotionOptions(**{"cut_hz": cut_hz, "prior_m": prior_m, **(fast or {})})
            result = autofocus_residual_motion(drive, traj, config, *args, opts=autofocus_options(config, True),
                                               fast=options, **kwargs)
            stage = result.fast_motion
            nodes = stage.correction.t_ns
            centre, across, _ = frame_geometry(result.trajectory, nodes, config)
            offset = stage.correction.offset_enu
            # the track before the stage, as against_truth compares with it
            record.update(nodes_ns=nodes, correction_m=np.sum(offset * across, axis=1), histories=stage.histories,
                          used=stage.histories_used, coverage=stage.coverage, seen=stage.seen, centre=centre - offset,
                          across=across, points=stage.histories, wall_s=time.perf_counter() - start,
                          reliability=stage.reliability, halves_correlation=stage.halves_correlation)
            return result
        result = autofocus_residual_motion(drive, traj, config, *args, opts=autofocus_options(config, False),
                                           **kwargs)
        track = result.trajectory
        points = bright_scatterers(drive, track, config)
        stage = high_band_motion(drive, track, config, points, cut_hz, vertical=vertical, prior_m=prior_m,
                                 elevation=elevation)
        centre, across, _ = frame_geometry(track, stage["nodes_ns"], config)
        base = track.correction.at(stage["nodes_ns"]) if track.correction is not None else np.zeros_like(across)
        moved = MotionCorrection(stage["nodes_ns"], base + stage["correction_m"][:, None] * across,
                                 np.zeros_like(across))
        record.update(stage, points=len(points), wall_s=time.perf_counter() - start, centre=centre, across=across)
        return dataclasses.replace(result, trajectory=dataclasses.replace(track, correction=moved))

    return corrected


def autofocus_options(config: Any, fast: bool) -> Any:
    """The config's autofocus options with the fast-motion stage on or off."""
    from autosar_cli.sar.residual_motion import AutofocusOptions

    return dataclasses.replace(AutofocusOptions.from_config(config), fast_motion=fast)


def product_without_fast(drive: Path, traj: Any, config: Any, *args: Any, **kwargs: Any) -> Any:
    """A replacement for compare's ``autofocus_residual_motion``: the product's without its fast-motion stage."""
    from autosar_cli.sar.autofocus_stage import autofocus_residual_motion

    return autofocus_residual_motion(drive, traj, config, *args, opts=autofocus_options(config, False), **kwargs)


def against_truth(truth_path: Path, record: dict[str, Any], config: Any) -> dict[str, Any]:
    """The stage's correction against the truth's (the radar's true across-track motion less the track's), per
    band, over the nodes it covers: RMS of each and of their difference (mm), and their correlation."""
    import h5py
    from scipy.signal import butter, sosfiltfilt


    with h5py.File(truth_path) as f:
        t, centres = f["radar/t_ns"][:], f["radar/phase_centre_enu"][:].mean(axis=(1, 2))
    nodes = record["nodes_ns"]
    true_centre = np.stack([np.interp(nodes, t, centres[:, k]) for k in range(3)], -1)
    centre, across = record["centre"], record["across"]
    truth = np.sum((true_centre - centre) * across, axis=1)
    out = {}
    seen = record["seen"]
    for lo, hi in ((2.0, 5.0), (5.0, 30.0)):
        sos = butter(4, [lo, hi], "bandpass", fs=1e9 / float(np.median(np.diff(nodes))), output="sos")
        a, b = sosfiltfilt(sos, truth)[seen], sosfiltfilt(sos, record["correction_m"])[seen]
        out[f"{lo:g}-{hi:g}_hz"] = {"truth_rms_mm": round(1e3 * a.std(), 4), "measured_rms_mm": round(1e3 * b.std(), 4),
                                    "error_rms_mm": round(1e3 * (a - b).std(), 4),
                                    "correlation": round(float(np.corrcoef(a, b)[0, 1]), 3)}
    return out


def table_row(row: dict[str, Any]) -> dict[str, Any]:
    """One drive's main figures: far-swath entropy and worst reflector without and with the stage, its histories
    used, its coverage, its correlation with the truth above 5 Hz and its time."""
    before, after, stage = row["autofocus"], row["with_high_band"], row["stage"]
    sim = f" [{row['simulation']}]" if row.get("simulation") else ""
    sim += " [vertical]" if row.get("vertical") else ""
    sim += " [elevation]" if row.get("elevation") else ""
    sim += f" [prior {row['prior_mm']:g} mm]" if row.get("prior_mm", 0.3) != 0.3 else ""
    sim += f" [{row['fast']}]" if row.get("fast") else ""
    sim += f" [{row['dynamics']}]" if row.get("dynamics") else ""
    return {"drive": f"{row['scenario']} s{row['seed']}{sim}",
            "far_entropy_pct": before["far_entropy_vs_truth_pct"],
            "far_entropy_with_pct": after["far_entropy_vs_truth_pct"],
            "worst_cm": before["worst_reflector_cm"], "worst_with_cm": after["worst_reflector_cm"],
            "used": stage["used"], "coverage": stage["coverage"],
            "corr_5_30_hz": stage["against_truth"]["5-30_hz"]["correlation"], "stage_s": stage["wall_s"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drives", default="test1:0,test2:1,test3:8", help="scenario:seed,...")
    ap.add_argument("--cut-hz", type=float, default=2.0)
    ap.add_argument("--simulation", default=None, help="[simulation] entries for the simulator, KEY=VALUE,...")
    ap.add_argument("--append", action="store_true", help="add the rows to those of --output")
    ap.add_argument("--vertical", action="store_true", help="the fit also takes a common vertical motion")
    ap.add_argument("--elevation", action="store_true",
                    help="... with each history's gain measured by the array's raised Tx (ELEVATION_PAIRS)")
    ap.add_argument("--prior-mm", type=float, default=0.3, help="prior std of the across-track correction (mm)")
    ap.add_argument("--dynamics", choices=("kinematic", "full"), default="full")
    ap.add_argument("--fast", default=None, help="the stage's options (FastMotionOptions), KEY=VALUE,...")
    ap.add_argument("--output", type=Path, default=RESULTS / "af_high_band.json")
    args = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_af_oracle import run_case
    from bench_paper import cli, config_copy, drive_row

    from autosar_cli.config import load_config

    config = load_config()
    rows = json.loads(args.output.read_text())["rows"] if args.append else []
    for drive in args.drives.split(","):
        scenario, seed = drive.split(":")
        with tempfile.TemporaryDirectory() as tmp:
            log = Path(tmp) / "drive.mcap"
            sim_config = (["--config", str(config_copy(None, None, Path(tmp), simulation=args.simulation))]
                          if args.simulation else [])
            cli("simulate", "--scenario", scenario, "--seed", seed, "--dynamics", args.dynamics, "--output", str(log),
                *sim_config)
            row: dict[str, Any] = {"scenario": scenario, "seed": int(seed), "simulation": args.simulation,
                                   "vertical": args.vertical, "elevation": args.elevation, "prior_mm": args.prior_mm,
                                   "fast": args.fast,
                                   **({"dynamics": args.dynamics} if args.dynamics != "full" else {})}
            record: dict[str, Any] = {}
            fast = ({k: json.loads(v) for k, v in (kv.split("=", 1) for kv in args.fast.split(","))}
                    if args.fast else None)
            stage = with_high_band(args.cut_hz, record, args.vertical, 1e-3 * args.prior_mm, args.elevation, fast)
            for case, autofocus in (("autofocus", product_without_fast), ("with_high_band", stage)):
                r = drive_row(scenario, int(seed), run_case(log, Path(tmp) / case, autofocus), 0.0, 0.0)
                af = r["sar-min+af"]
                row[case] = {"far_entropy_vs_truth_pct": r["entropy_far"]["vs_truth_pct"]["sar-min+af"],
                             "worst_reflector_cm": af["reflector_error_max_cm"],
                             "peak_loss_max_db": af["peak_loss_max_db"], "within_2cm_1db": af["within_2cm_1db"]}
            row["stage"] = {"scatterers": record["points"], "histories": record["histories"], "used": record["used"],
                            "coverage": round(record["coverage"], 3), "wall_s": round(record["wall_s"], 1),
                            "correction_rms_mm": round(1e3 * float(record["correction_m"].std()), 4),
                            "halves_correlation": record.get("halves_correlation"),
                            "reliability": record.get("reliability"),
                            # the used histories' measured vertical gain (--elevation): median and std
                            "up_gain": record.get("up_gain"),
                            "against_truth": against_truth(log.with_name(log.name + ".truth.h5"), record, config)}
        rows.append(row)
        print(json.dumps(row), flush=True)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps({"benchmark": "af_high_band", "cut_hz": args.cut_hz,
                                       "table": [table_row(r) for r in rows], "rows": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
