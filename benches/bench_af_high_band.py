"""Benchmark an experimental stage after the autofocus: the across-track motion above 2 Hz from many scatterers.

Usage: python benches/bench_af_high_band.py [--drives test1:0,test2:1,test3:8] [--cut-hz 2]
                                            [--simulation KEY=VALUE,...] [--vertical | --elevation] [--append]
                                            [--output benches/results/af_high_band.json]

Many: bright scatterers over the whole drive, the facade's pillars included. The product's autofocus fits a few
isolated points (3-16 m from the track), which on test1 see 61 % of the drive; the far swath's entropy lacks the
across-track motion above 0.5 Hz where they do not see (bench_af_oracle.py). Here, after it, along its track
(``sar-min+af``):

* the scatterers: local maxima of a coarse first image out to the radar's range, four per 1.5 m of travel, within
  25 dB of the most reflective, holding 10 % of their 7 x 7 neighbourhood (the product: two, 15 dB, 20 %, 12 m);
* each one's history over +-28 deg (2 channels, ``sar.phase_history``), low-passed along the pulses (31-pulse Hann)
  and taken every 10 pulses: a pulse's range sample holds every scatterer at that range in the real beam, and
  for a point on a wall the wall's mirror image about broadside is one, at twice the point's Doppler. Samples
  where that Doppler aliases to within 80 Hz of the point's own are left out;
* the phase steps of each history, less their own average over 0.6 s (a column's scatterers interfere slowly as
  the aspect turns; each scatterer keeps its own slow phase), fit by a correction across track on 10 ms nodes
  (0.3 mm prior, 1 mm per node change), each history weighted by its own residual, histories worse than
  0.5 rad RMS dropped; the fit's part above ``--cut-hz`` is added to the track.

For every drive (``simulate --dynamics full``): ``compare --methods sar-min,sar-min+af,truth`` with the product's
autofocus, then with this stage after it. Rows: far-swath entropy against the truth image's, worst reflector, peak
loss; the stage's scatterers, coverage and time; and how its correction compares with the truth's (the radar's
true across-track motion less ``sar-min+af``'s) in 2-5 and 5-30 Hz, over the frames it covers; ``table`` has
one line per drive of the main figures. ``--simulation``: entries of the simulator's [simulation] section for
these drives (the processor keeps the config's), recorded in their rows; ``--append``: add the rows to the
output's. ``--elevation``: the fit takes the vertical motion too, each history's gain measured by the array's
raised Tx (``high_band_motion``). The committed file: ``--drives test1:0,test2:1,test3:8,test1:1,test2:0,test3:1``,
then ``--drives test1:1,test3:1 --simulation vibration_vertical_rms_m=0.0 --append`` (the radar case's vertical
vibration off), then the six again with ``--elevation --append`` (its times under a second benchmark's load), then
``--drives test1:2,test2:2,test3:2,test1:3,test2:3,test3:3,test1:4,test2:4,test3:4 --append`` and ``--drives
urban:1,urban:2 --append``.
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
    """(P, 3) ENU m: the stage's scatterers on a coarse image along ``traj`` (the module's docstring): the
    autofocus's own candidate selection, out to the radar's range and less strict."""
    from autosar_cli.sar.focus import FocusOptions
    from autosar_cli.sar.residual_motion import AutofocusOptions, candidate_points

    return candidate_points(drive, traj, config, FocusOptions.from_config(config),
                            AutofocusOptions(max_range_m=config.radar.max_range_m - 1.0), per_segment=4,
                            min_concentration=0.1, within_db=25.0)


def _moving_average_removal(segment: Any, half: int) -> Any:
    """Sparse (M, M): each sample less the mean of the samples of its segment within ``half`` of it."""
    import scipy.sparse as sp

    m = len(segment)
    starts = np.flatnonzero(np.r_[True, segment[1:] != segment[:-1]])
    first = np.repeat(starts, np.diff(np.r_[starts, m]))
    last = np.repeat(np.r_[starts[1:], m], np.diff(np.r_[starts, m]))
    idx = np.arange(m)
    lo, hi = np.maximum(idx - half, first), np.minimum(idx + half + 1, last)
    count = hi - lo
    rows = np.repeat(idx, count)
    cols = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count) + np.repeat(lo, count)
    average = sp.csr_matrix((np.repeat(1.0 / count, count), (rows, cols)), shape=(m, m))
    return sp.identity(m, format="csr") - average


def high_band_motion(drive: Path, traj: Any, config: Any, points: Any, cut_hz: float, node_s: float = 0.01,
                     taps: int = 31, every: int = 10, alias_hz: float = 80.0, window_s: float = 0.6,
                     prior_m: float = 3e-4, step_m: float = 1e-3, max_rms_rad: float = 0.5,
                     vertical: bool = False, elevation: bool = False) -> dict[str, Any]:
    """The across-track correction (m, on ``node_s`` nodes from the track's start) above ``cut_hz`` that the
    histories of ``points`` measure along ``traj``; the histories used, and the share of the nodes they cover.
    ``vertical``: the fit also takes a vertical motion common to all histories, which each history sees with its
    own unknown gain (the sine of its elevation, its scatterer's height unknown): alternately the two motions with
    the gains held and each gain with the motions held; only the across-track motion is returned. ``elevation``:
    that vertical motion with each history's gain measured by the array (``ELEVATION_PAIRS``: Tx1 sits lambda/2
    above Tx0 and Tx2, so of two channels at one place along the row, one raised, the back-projected phases differ
    by pi times the sine of the elevation of what the history holds less its pixel's; one gain per history), one
    linear fit of both motions."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla
    from scipy.ndimage import convolve1d
    from scipy.signal import butter, sosfiltfilt

    from autosar_cli.sar.focus import FocusOptions
    from autosar_cli.sar.phase_history import focus_history, frame_geometry, gather_phase_histories, pair_antennas

    hist = gather_phase_histories(drive, traj, config, points, FocusOptions.from_config(config), half_beam_deg=28.0,
                                  window_bins=32, channels=2, pairs=ELEVATION_PAIRS if elevation else None)
    antennas = pair_antennas(hist, traj, config)
    half = len(ELEVATION_PAIRS) // 2
    z, los = focus_history(hist, *antennas, points, slice(0, half) if elevation else slice(None))
    raised = focus_history(hist, *antennas, points, slice(half, None))[0] if elevation else None
    t0 = int(traj.t_ns[0])
    t_f = (hist.frame_t_ns - t0) / 1e9
    prf = 1.0 / float(np.median(np.diff(t_f)))
    speed = np.interp(hist.frame_t_ns, traj.t_ns, np.abs(traj.speed))
    _, f_across, f_along = frame_geometry(traj, hist.frame_t_ns, config)
    taper = np.hanning(taps + 2)[1:-1]
    taper /= taper.sum()
    times, steps, gains, segment, up_gain = [], [], [], [], []
    for j in range(len(points)):
        sel = np.flatnonzero(hist.point == j)
        sel = sel[np.argsort(hist.frame[sel])]
        for run in np.split(sel, np.flatnonzero(np.diff(hist.frame[sel]) != 1) + 1):
            if len(run) < 3 * taps:
                continue
            zr = np.nan_to_num(z[run])
            low = convolve1d(zr.real, taper, mode="constant") + 1j * convolve1d(zr.imag, taper, mode="constant")
            keep = np.arange(taps, len(run) - taps, every)
            f, u = hist.frame[run][keep], los[run][keep]
            mirror = 4.0 * speed[f] * np.einsum("nk,nk->n", u, f_along[f]) * hist.cycles_per_m
            alias = np.abs((mirror + prf / 2) % prf - prf / 2)
            ok = (alias > alias_hz) | (np.abs(mirror) < alias_hz / 4)
            a = np.flatnonzero(ok[1:] & ok[:-1])
            if len(a) < 5:
                continue
            g = np.einsum("nk,nk->n", u, f_across[f])
            times.append(np.stack([t_f[f][a], t_f[f][a + 1]], -1))
            gains.append(np.stack([g[a], g[a + 1]], -1))
            steps.append(np.angle(low[keep][a + 1] * np.conj(low[keep][a])))
            segment.append(np.full(len(a), len(segment)))
            if raised is not None:
                up_gain.append(np.angle(np.nansum(raised[run] * np.conj(z[run]))) / math.pi)
    n_nodes = int(math.ceil((int(traj.t_ns[-1]) - t0) / 1e9 / node_s)) + 1
    nodes_ns = t0 + np.round(np.arange(n_nodes) * node_s * 1e9).astype(np.int64)
    if not steps:
        return {"nodes_ns": nodes_ns, "correction_m": np.zeros(n_nodes), "histories": 0, "used": 0, "coverage": 0.0,
                "seen": np.zeros(n_nodes, dtype=bool)}
    t, step, gain, seg = (np.concatenate(v) for v in (times, steps, gains, segment))
    kappa = 4.0 * math.pi * hist.cycles_per_m
    m = len(step)

    def design_of(g: Any) -> Any:  # step = kappa (g_b e_b - g_a e_a), e the motion the correction undoes
        cols, vals = [], []
        for end, sign in ((0, -1.0), (1, 1.0)):
            pos = np.clip(t[:, end] / node_s, 0.0, n_nodes - 1.000001)
            n0 = np.floor(pos).astype(np.int64)
            cols += [n0, n0 + 1]
            vals += [sign * kappa * g[:, end] * (1 - (pos - n0)), sign * kappa * g[:, end] * (pos - n0)]
        return sp.csr_matrix((np.concatenate(vals), (np.tile(np.arange(m), 4), np.concatenate(cols))),
                             shape=(m, n_nodes))

    detrend = _moving_average_removal(seg, max(1, int(round(0.5 * window_s * prf / every))))
    data, model = detrend @ step, (detrend @ design_of(gain)).tocsr()
    change = sp.diags([np.ones(n_nodes - 1), -np.ones(n_nodes - 1)], [1, 0], shape=(n_nodes - 1, n_nodes))
    prior = (sp.identity(n_nodes) / prior_m**2 + change.T @ change / step_m**2).tocsc()
    n_seg = len(steps)
    used = np.ones(n_seg, dtype=bool)
    var = np.full(n_seg, 0.3**2)
    # the vertical: its unit-gain design (each step's vertical line-of-sight change is the history's own gain)
    unit = (detrend @ design_of(np.ones_like(gain))).tocsr() if vertical or elevation else None
    prior_both = (sp.block_diag([prior, sp.identity(n_nodes) / 3e-3**2 + change.T @ change / step_m**2]).tocsc()
                  if vertical or elevation else None)
    if elevation and unit is not None:  # the gains measured: one linear fit of both motions
        model = sp.hstack([model, unit.multiply(np.asarray(up_gain)[seg][:, None])]).tocsr()
        prior, unit = prior_both, None
    h = np.full(n_seg, 0.1)
    e_up = np.zeros(n_nodes)
    for _ in range(12 if vertical else 5):
        w = used[seg] / var[seg]
        if unit is None:
            x = spla.spsolve((model.T @ model.multiply(w[:, None])).tocsc() + prior, model.T @ (w * data))
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
        bad = used & (rms > max_rms_rad)
        if not bad.any() and unit is None:
            break
        used &= ~bad
    seen = np.zeros(n_nodes, dtype=bool)
    for s in np.flatnonzero(used):
        span = t[seg == s, 0]
        seen[int(span.min() / node_s):int(span.max() / node_s) + 1] = True
    high = -sosfiltfilt(butter(4, cut_hz, "highpass", fs=1.0 / node_s, output="sos"), e)
    gains_used = np.asarray(up_gain)[used] if elevation else np.zeros(0)
    return {"nodes_ns": nodes_ns, "correction_m": high, "histories": n_seg, "used": int(used.sum()),
            "coverage": float(seen.mean()), "seen": seen,
            "up_gain": [round(float(np.median(gains_used)), 4), round(float(gains_used.std()), 4)]
            if len(gains_used) else None}


def with_high_band(cut_hz: float, record: dict[str, Any], vertical: bool = False, prior_m: float = 3e-4,
                   elevation: bool = False) -> Any:
    """A replacement for compare's ``autofocus_residual_motion``: the product's, then this stage."""
    from autosar_cli.sar.phase_history import frame_geometry
    from autosar_cli.sar.residual_motion import autofocus_residual_motion
    from autosar_cli.types import MotionCorrection

    def corrected(drive: Path, traj: Any, config: Any, *args: Any, **kwargs: Any) -> Any:
        result = autofocus_residual_motion(drive, traj, config, *args, **kwargs)
        track = result.trajectory
        start = time.perf_counter()
        points = bright_scatterers(drive, track, config)
        stage = high_band_motion(drive, track, config, points, cut_hz, vertical=vertical, prior_m=prior_m,
                                 elevation=elevation)
        _, across, _ = frame_geometry(track, stage["nodes_ns"], config)
        base = track.correction.at(stage["nodes_ns"]) if track.correction is not None else np.zeros_like(across)
        moved = MotionCorrection(stage["nodes_ns"], base + stage["correction_m"][:, None] * across,
                                 np.zeros_like(across))
        record.update(stage, points=len(points), wall_s=time.perf_counter() - start, track=track)
        return dataclasses.replace(result, trajectory=dataclasses.replace(track, correction=moved))

    return corrected


def against_truth(truth_path: Path, record: dict[str, Any], config: Any) -> dict[str, Any]:
    """The stage's correction against the truth's (the radar's true across-track motion less the track's), per
    band, over the nodes it covers: RMS of each and of their difference (mm), and their correlation."""
    import h5py
    from scipy.signal import butter, sosfiltfilt

    from autosar_cli.sar.phase_history import frame_geometry

    with h5py.File(truth_path) as f:
        t, centres = f["radar/t_ns"][:], f["radar/phase_centre_enu"][:].mean(axis=(1, 2))
    nodes = record["nodes_ns"]
    true_centre = np.stack([np.interp(nodes, t, centres[:, k]) for k in range(3)], -1)
    centre, across, _ = frame_geometry(record["track"], nodes, config)
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
            cli("simulate", "--scenario", scenario, "--seed", seed, "--dynamics", "full", "--output", str(log),
                *sim_config)
            row: dict[str, Any] = {"scenario": scenario, "seed": int(seed), "simulation": args.simulation,
                                   "vertical": args.vertical, "elevation": args.elevation, "prior_mm": args.prior_mm}
            record: dict[str, Any] = {}
            stage = with_high_band(args.cut_hz, record, args.vertical, 1e-3 * args.prior_mm, args.elevation)
            for case, autofocus in (("autofocus", None), ("with_high_band", stage)):
                r = drive_row(scenario, int(seed), run_case(log, Path(tmp) / case, autofocus), 0.0, 0.0)
                af = r["sar-min+af"]
                row[case] = {"far_entropy_vs_truth_pct": r["entropy_far"]["vs_truth_pct"]["sar-min+af"],
                             "worst_reflector_cm": af["reflector_error_max_cm"],
                             "peak_loss_max_db": af["peak_loss_max_db"], "within_2cm_1db": af["within_2cm_1db"]}
            row["stage"] = {"scatterers": record["points"], "histories": record["histories"], "used": record["used"],
                            "coverage": round(record["coverage"], 3), "wall_s": round(record["wall_s"], 1),
                            "correction_rms_mm": round(1e3 * float(record["correction_m"].std()), 4),
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
