"""Benchmark a measurement beside the product: the track's local scale from each reflector's range over its pass.

Usage: python benches/bench_af_range_history.py [--drives urban:0,urban:1] [--half-beam-deg 70]
                                                [--append] [--output benches/results/af_range_history.json]

Why: the autofocus's points are seen over +-28 deg of broadside, where a range error bends the phase history as a
speed error does (the curvature is v^2 / R), so their scale comes from the phases against a held motion, and on
urban they disagree (docs/AUTOFOCUS.md, step 5). The radar, looking 45 deg forward with a 120 deg beam, sees each
reflector from ~26 m ahead to broadside. Over that pass the range falls by metres while the track moves
along, so the range's rate against the track's travel is the local scale, with no angle measured.

For every drive (``simulate --dynamics full``, ``ingest``, ``navigate --method sar-min``) and along two tracks,
SAR-MIN's and the truth's (the radar's true motion, the noise floor):

* each corner reflector's echoes over +-``--half-beam-deg`` of broadside (12 channels, ``sar.phase_history``),
  its position from the truth's mapped rigidly onto the track (as its first image would place it);
* every 0.1 s block of pulses summed coherently along the track's predicted phase, its range envelope's peak
  (``range_offsets``, within +-``--search-bins``, 3 by default); blocks weaker than 0.3 of the reflector's
  median, or peaking at the search's edge, left out;
* per reflector, least squares with 3.5 sigma rejection: its horizontal shift and the track's stretch about it,
  ``path offset = 2 u . (along) * stretch * (s - s_j) - 2 u . shift`` (u the line of sight, s the travel);
* against it, the track's local stretch from the truth: the slope of its aligned along-track error against the
  true travel over the same blocks (positive: the track too long there).

``--range-doppler``: an echo's Doppler shifts its beat frequency, so its envelope sits ``(dp/dt) f_c / slope`` of
path away (1 cm of path at 5 m/s straight ahead, 0 at broadside), which over a pass reads as a stretch; this
takes it out. Rows: one per reflector and track. The summary per drive: the radar's stretch less the truth's, RMS,
and their correlation, along SAR-MIN's track; the RMS along the truth's track (the measurement's own noise). Without
truth, in the product, the points would come from the first image; the fit frees their horizontal positions.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_paper import RESULTS, cli  # noqa: E402

BLOCK_S = 0.1
MIN_RELATIVE_POWER = 0.3
REJECT_SIGMA = 3.5
MIN_BLOCKS = 8


def reflector_stretches(drive: Path, traj: Any, truth: Any, config: Any, half_beam_deg: float,
                        search_bins: float, range_doppler: bool) -> list[dict[str, Any]]:
    """Per corner reflector: the radar's local stretch of ``traj`` and the truth's (both dimensionless)."""
    from autosar_cli.config import SPEED_OF_LIGHT
    from autosar_cli.evaluate.alignment import fit_se2
    from autosar_cli.evaluate.trajectory_metrics import common_instants, radar_track, trajectory_errors
    from autosar_cli.nav.trajectory import cumulative_travel
    from autosar_cli.sar.focus import FocusOptions
    from autosar_cli.sar.phase_history import frame_geometry, gather_phase_histories, pair_antennas, range_offsets
    from autosar_cli.store.drive import radar_times

    crs = truth.targets.corner_reflectors
    true_points = truth.targets_above_road(crs)
    frames = radar_times(drive)
    t = common_instants(traj, truth.trajectory, frames)
    onto = fit_se2(radar_track(truth.trajectory, t, config), radar_track(traj, t, config))
    points = true_points.copy()
    points[:, :2] = onto.apply(true_points[:, :2])
    hist = gather_phase_histories(drive, traj, config, points, FocusOptions(), half_beam_deg=half_beam_deg,
                                  window_bins=int(2 * search_bins) + 18, channels=12)
    tx, rx = pair_antennas(hist, traj, config)
    pulse_t = hist.frame_t_ns[hist.frame]
    block = ((pulse_t - pulse_t.min()) // int(BLOCK_S * 1e9)).astype(np.int64)
    key = hist.point * (block.max() + 1) + block
    keys, group = np.unique(key, return_inverse=True)
    point_of = keys // (block.max() + 1)
    offset, power, _ = range_offsets(dataclasses.replace(hist, point=group), tx, rx, points[point_of], len(keys),
                                     half_bins=search_bins)
    centre, _, along = frame_geometry(traj, hist.frame_t_ns, config)
    n = np.bincount(group)

    def mean(a: np.ndarray) -> np.ndarray:
        return np.stack([np.bincount(group, a[:, k]) for k in range(a.shape[1])], -1) / n[:, None]

    c, a = mean(centre[hist.frame]), mean(along[hist.frame])
    velocity = mean(np.gradient(centre, hist.frame_t_ns.astype(np.float64) * 1e-9, axis=0)[hist.frame])
    tg = (np.bincount(group, (pulse_t - pulse_t.min()).astype(np.float64)) / n).astype(np.int64) + pulse_t.min()
    los = c - points[point_of]
    los /= np.linalg.norm(los, axis=1, keepdims=True)
    travel = cumulative_travel(radar_track(traj, traj.t_ns, config))
    s = np.interp(tg.astype(np.float64), traj.t_ns.astype(np.float64), travel)
    if range_doppler:  # the echo's Doppler shifts its beat frequency: the envelope sits (dp/dt) f_c / slope further
        centre_hz = hist.cycles_per_m * SPEED_OF_LIGHT  # the carrier at the ADC window's centre, as focus takes it
        offset = offset - 2 * np.einsum("ij,ij->i", los, velocity) * centre_hz / config.radar.slope_hz_per_s
    rows = []
    for j in range(len(points)):
        m = point_of == j
        if not m.any():
            continue
        rel = power[m] / np.median(power[m])
        keep = (np.abs(offset[m]) < (search_bins - 0.5) * hist.bin_m) & (rel > MIN_RELATIVE_POWER)
        design = np.column_stack([2 * np.einsum("ij,ij->i", los[m], a[m]) * (s[m] - s[m].mean()),
                                  -2 * los[m][:, 0], -2 * los[m][:, 1]])
        for _ in range(5):
            if keep.sum() < MIN_BLOCKS:
                break
            x, *_ = np.linalg.lstsq(design[keep], offset[m][keep], rcond=None)
            resid = offset[m] - design @ x
            sigma = 1.4826 * float(np.median(np.abs(resid[keep])))
            keep &= np.abs(resid) < REJECT_SIGMA * max(sigma, 1e-5)
        if keep.sum() < MIN_BLOCKS:
            continue
        x, *_ = np.linalg.lstsq(design[keep], offset[m][keep], rcond=None)
        times = np.sort(tg[m][keep])
        err = trajectory_errors(traj, truth.trajectory, np.zeros(3), times)
        true_stretch = float(np.polyfit(err.distance_m, err.aligned_along, 1)[0])
        rows.append({"reflector": int(crs[j]), "blocks": int(keep.sum()), "of_blocks": int(m.sum()),
                     "span_m": round(float(np.ptp(s[m][keep])), 1),
                     "radar_stretch_pct": round(-100 * float(x[0]), 4),
                     "truth_stretch_pct": round(100 * true_stretch, 4),
                     "resid_mm": round(1e3 * sigma, 2)})
    return rows


def drive_rows(scenario: str, seed: int, work: Path, half_beam_deg: float, search_bins: float,
               range_doppler: bool) -> list[dict[str, Any]]:
    """Simulate, ingest and navigate one drive in ``work`` (emptied after), and measure it."""
    log = work / f"{scenario}_s{seed}.mcap"
    cli("simulate", "--scenario", scenario, "--seed", str(seed), "--dynamics", "full", "-o", str(log), "--overwrite")
    drive, nav = work / "drive.h5", work / "sarmin.h5"
    cli("ingest", str(log), "-o", str(drive), "--overwrite")
    cli("navigate", str(drive), "-o", str(nav), "--overwrite")
    rows = measured_rows(drive, nav, Path(str(log) + ".truth.h5"), half_beam_deg, search_bins, range_doppler)
    for p in work.iterdir():
        p.unlink()
    return [{"scenario": scenario, "seed": seed, **r} for r in rows]


def measured_rows(drive: Path, nav: Path, truth_path: Path, half_beam_deg: float, search_bins: float,
                  range_doppler: bool = False) -> list[dict[str, Any]]:
    """The rows of one drive: ``drive`` (drive.h5), SAR-MIN's ``nav`` (trajectory.h5) and the truth sidecar."""
    from autosar_cli.config import load_config
    from autosar_cli.evaluate.evaluation import load_truth
    from autosar_cli.evaluate.trajectory_metrics import radar_track_scale
    from autosar_cli.store.drive import radar_times
    from autosar_cli.store.trajectory import read_trajectory

    config = load_config()
    est = read_trajectory(nav, covariance=False)
    truth = load_truth(truth_path, est.origin, config)
    rows = []
    for name, traj in (("sar-min", est), ("truth", truth.trajectory)):
        start = time.perf_counter()
        scale = radar_track_scale(traj, truth.trajectory, radar_times(drive), config)
        for r in reflector_stretches(drive, traj, truth, config, half_beam_deg, search_bins, range_doppler):
            rows.append({"track": name, "track_scale_pct": round(100 * scale, 4), "half_beam_deg": half_beam_deg,
                         "search_bins": search_bins, "range_doppler": range_doppler,
                         **r, "time_s": round(time.perf_counter() - start, 1)})
    return rows


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    def key_of(r: dict[str, Any]) -> tuple[Any, ...]:
        return r["scenario"], r["seed"], r["half_beam_deg"], r.get("search_bins", 3.0), r.get("range_doppler", False)

    for key in sorted({key_of(r) for r in rows}):
        these = [r for r in rows if key_of(r) == key]
        nav = [r for r in these if r["track"] == "sar-min"]
        ref = [r for r in these if r["track"] == "truth"]
        radar = np.array([r["radar_stretch_pct"] for r in nav])
        true = np.array([r["truth_stretch_pct"] for r in nav])
        label = f"{key[0]}:{key[1]} ({key[2]:g} deg, +-{key[3]:g} bins{', range-Doppler' if key[4] else ''})"
        out[label] = {
            "reflectors": len(nav),
            "sarmin_truth_stretch_rms_pct": round(float(np.sqrt(np.mean(true ** 2))), 4) if nav else None,
            "sarmin_radar_less_truth_rms_pct": round(float(np.sqrt(np.mean((radar - true) ** 2))), 4) if nav else None,
            "sarmin_correlation": round(float(np.corrcoef(radar, true)[0, 1]), 3) if len(nav) > 2 else None,
            "truth_track_radar_rms_pct": round(float(np.sqrt(np.mean(
                np.array([r["radar_stretch_pct"] for r in ref]) ** 2))), 4) if ref else None,
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drives", default="urban:0,urban:1")
    ap.add_argument("--half-beam-deg", type=float, default=70.0)
    ap.add_argument("--search-bins", type=float, default=3.0, help="the envelope's peak is sought within +- this")
    ap.add_argument("--range-doppler", action="store_true",
                    help="take out the envelope's shift by the echo's Doppler (path rate x centre frequency / slope)")
    ap.add_argument("--append", action="store_true", help="add the rows to the output's")
    ap.add_argument("--output", type=Path, default=RESULTS / "af_range_history.json")
    args = ap.parse_args()
    rows: list[dict[str, Any]] = json.loads(args.output.read_text())["rows"] if args.append else []
    with tempfile.TemporaryDirectory() as tmp:
        for item in args.drives.split(","):
            scenario, seed = item.split(":")
            new = drive_rows(scenario, int(seed), Path(tmp), args.half_beam_deg, args.search_bins, args.range_doppler)
            rows.extend(new)
            print(json.dumps(summary(new)), flush=True)
    result = {"benchmark": "af_range_history", "summary": summary(rows), "rows": rows}
    args.output.write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result["summary"], indent=1))


if __name__ == "__main__":
    main()
