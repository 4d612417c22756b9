"""Benchmark the autofocus with and without the slow motion from the points' passes (AutofocusOptions.slow_motion).

Usage: python benches/bench_af_pass_ranges.py [--drives urban:0,urban:1] [--keep DIR] [--append]
                                              [--output benches/results/af_pass_ranges.json]
                                              [--passes wheel_gaps=0,step_along=0.001,...] [--product-only]
                                              [--navigation gnss_heading=true]

Per drive (``simulate --dynamics full``, ``ingest``, ``navigate``; with ``--keep`` the files stay in
DIR/<scenario><seed> and are used again): the corner reflectors focused (patches only, the product's options, one pass
over the radar data each) along SAR-MIN's track, along ``sar-min+af`` as the product makes it, along the slow motion
alone (``sar.pass_ranges``) and along ``sar-min+af`` with the slow motion first; each one's worst reflector after the
whole-track alignment and its worst peak loss against the truth track's patches, as ``compare`` measures them. Also
the slow motion's points, residual, correction and time; with ``--product-only``, SAR-MIN's track scale error too
(``radar_track_scale``), which the slow motion's ``scale`` estimates. The summary per scenario: drives within 2 cm and
1 dB, median and worst reflector, without and with; and the RMS of that scale's error over its std
(``slow_scale_z_rms``, where the rows have it). ``--navigation``: SAR-MIN's own settings otherwise than the config's
(entries of [navigation], as bench_paper's), the drive navigated again with them (``sarmin_nav_<entries>.h5`` beside
the drive's): ``--navigation gnss_heading=true --output benches/results/af_gnss_heading.json``."""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_paper import RESULTS, cli, config_copy, variant_tag  # noqa: E402

WITHIN_CM, WITHIN_DB = 2.0, 1.0
TRACKS = ("sar-min", "sar-min+af", "slow", "slow+af")


def reflector_errors(drive: Path, traj: Any, truth: Any, config: Any, reference: Any = None) -> tuple[dict, Any]:
    """Worst aligned reflector error (cm) and worst peak loss (dB, against ``reference``'s patches) of the image
    along ``traj``, and its patches (the reference, when ``traj`` is the truth's)."""
    from autosar_cli.evaluate.reflectors import focus_patches, measure_reflectors, predict_image_positions
    from autosar_cli.evaluate.trajectory_metrics import common_instants, trajectory_errors
    from autosar_cli.nav.trajectory import phase_centre_lever_arm
    from autosar_cli.sar.focus import FocusOptions
    from autosar_cli.store.drive import radar_times

    t = common_instants(traj, truth.trajectory, radar_times(drive))
    alignment = trajectory_errors(traj, truth.trajectory, phase_centre_lever_arm(config), t).alignment
    crs = truth.targets.corner_reflectors
    options = FocusOptions.from_config(config)
    centres = predict_image_positions(traj, truth.trajectory, truth.targets_above_road(crs), config, t,
                                      options.height_m)
    patches, _, _ = focus_patches(drive, traj, config, options, truth.targets.corner_reflector_names(),
                                  truth.targets.position_enu[crs], alignment, predicted_xy=centres)
    metrics = measure_reflectors(patches, (0.0, 1.0), reference)
    errors = [100 * m.aligned_error_m for m in metrics]
    losses = [m.peak_loss_db for m in metrics if m.peak_loss_db is not None]
    return ({"worst_cm": round(max(errors), 2), "peak_loss_max_db": round(max(losses), 2) if losses else None,
             "errors_cm": [round(e, 2) for e in errors]}, patches)


def measured_row(work: Path, passes: Any = None, product_only: bool = False, nav: str = "sarmin.h5") -> dict[str, Any]:
    """One drive's row from ``work``'s log.mcap(.truth.h5), drive.h5 and its navigation ``nav``; ``passes``: the slow
    motion's options (default PassOptions()); ``product_only``: only ``slow+af``, the product's track."""
    from autosar_cli.config import load_config
    from autosar_cli.evaluate.evaluation import load_truth
    from autosar_cli.evaluate.trajectory_metrics import radar_track_scale
    from autosar_cli.sar.autofocus_stage import residual_motion_of_points
    from autosar_cli.sar.focus import FocusOptions
    from autosar_cli.sar.pass_ranges import PassOptions, estimate_slow_motion
    from autosar_cli.sar.point_selection import candidate_points
    from autosar_cli.sar.residual_motion import AutofocusOptions, estimate_residual_motion
    from autosar_cli.store.drive import radar_times
    from autosar_cli.store.trajectory import read_trajectory

    config = load_config()
    drive = work / "drive.h5"
    est = read_trajectory(work / nav)  # its covariance sets the autofocus's scale prior, as in the product
    truth = load_truth(work / "log.mcap.truth.h5", est.origin, config)
    focus, opts = FocusOptions.from_config(config), AutofocusOptions()
    passes = passes or PassOptions()
    _, reference = reflector_errors(drive, truth.trajectory, truth, config)
    start = time.perf_counter()
    points = candidate_points(drive, est, config, focus, opts)
    points_s = time.perf_counter() - start
    if product_only:
        start = time.perf_counter()
        both = residual_motion_of_points(drive, est, config, points, focus, replace(opts, slow_motion=True), passes)
        row = {"points": len(points), "points_s": round(points_s, 1),
               "slow+af_s": round(time.perf_counter() - start, 1),
               "slow_motion": both.slow_motion.to_dict() if both.slow_motion else None,
               "slow+af_summary": both.summary(),
               # what the slow motion's scale estimates (bench_paper's sarmin_track_scale_pct)
               "sarmin_track_scale": radar_track_scale(est, truth.trajectory, radar_times(drive), config)}
        row["slow+af"], _ = reflector_errors(drive, both.trajectory, truth, config, reference)
        return row
    start = time.perf_counter()
    slow = estimate_slow_motion(drive, est, config, points, focus, passes)
    slow_s = time.perf_counter() - start
    start = time.perf_counter()
    product = estimate_residual_motion(drive, est, config, points, focus, opts)
    af_s = time.perf_counter() - start
    start = time.perf_counter()
    both = residual_motion_of_points(drive, est, config, points, focus, replace(opts, slow_motion=True), passes)
    both_s = time.perf_counter() - start
    tracks = {"sar-min": est, "sar-min+af": product.trajectory, "slow": slow.trajectory, "slow+af": both.trajectory}
    row: dict[str, Any] = {"points": len(points), "points_s": round(points_s, 1), "slow_s": round(slow_s, 1),
                           "af_s": round(af_s, 1), "slow+af_s": round(both_s, 1),
                           "slow_motion": slow.to_dict(), "slow_summary": slow.summary(),
                           "af_summary": product.summary(), "slow+af_summary": both.summary()}
    for name in TRACKS:
        row[name], _ = reflector_errors(drive, tracks[name], truth, config, reference)
    return row


def kept_drive(scenario: str, seed: int, work: Path) -> Path:
    """``work`` holding the full-dynamics drive's log.mcap.truth.h5, drive.h5 and SAR-MIN's sarmin.h5, made where
    missing."""
    work.mkdir(parents=True, exist_ok=True)
    log, drive, nav = work / "log.mcap", work / "drive.h5", work / "sarmin.h5"
    if not nav.exists():
        cli("simulate", "--scenario", scenario, "--seed", str(seed), "--dynamics", "full", "-o", str(log),
            "--overwrite")
        cli("ingest", str(log), "-o", str(drive), "--overwrite")
        cli("navigate", str(drive), "-o", str(nav), "--overwrite")
    return work


def drive_row(scenario: str, seed: int, keep: Path | None, passes: Any = None, product_only: bool = False,
              navigation: str = "") -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        work = kept_drive(scenario, seed, (keep / f"{scenario}{seed}") if keep else Path(tmp))
        drive, nav = work / "drive.h5", work / "sarmin.h5"
        if navigation:
            nav = work / f"sarmin_nav_{variant_tag(navigation)}.h5"
            if not nav.exists():
                cli("navigate", str(drive), "-o", str(nav), "--config",
                    str(config_copy(None, None, work, navigation=navigation)), "--overwrite")
        return {"scenario": scenario, "seed": seed, **measured_row(work, passes, product_only, nav.name)}


def within(entry: dict[str, Any]) -> bool:
    return entry["worst_cm"] <= WITHIN_CM and (entry["peak_loss_max_db"] or 0.0) <= WITHIN_DB


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for scenario in sorted({r["scenario"] for r in rows}):
        these = [r for r in rows if r["scenario"] == scenario]
        tracks = [name for name in TRACKS if all(name in r for r in these)]
        out[scenario] = {"drives": len(these), **{name: {
            f"within_{WITHIN_CM:g}cm_{WITHIN_DB:g}db": sum(within(r[name]) for r in these),
            "worst_median_cm": round(float(np.median([r[name]["worst_cm"] for r in these])), 2),
            "worst_max_cm": max(r[name]["worst_cm"] for r in these)} for name in tracks},
            **({"slow_s_median": round(float(np.median([r["slow_s"] for r in these])), 1)}
               if all("slow_s" in r for r in these) else {})}
        # the slow motion's stated scale against SAR-MIN's scale error: RMS 1 where its std says what it is worth
        z = [(r["slow_motion"]["scale"] - r["sarmin_track_scale"]) / r["slow_motion"]["scale_std"] for r in these
             if "sarmin_track_scale" in r and (r.get("slow_motion") or {}).get("scale_std")]
        if z:
            out[scenario]["slow_scale_z_rms"] = round(float(np.sqrt(np.mean(np.square(z)))), 2)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drives", default="urban:0,urban:1", help="scenario:seed,...")
    ap.add_argument("--keep", type=Path, default=None, help="keep (and use again) each drive's files under this")
    ap.add_argument("--append", action="store_true", help="add the rows to those of --output")
    ap.add_argument("--output", type=Path, default=RESULTS / "af_pass_ranges.json")
    ap.add_argument("--note", default="", help="how these rows were run (added to the file's note)")
    ap.add_argument("--passes", default="",
                    help="the slow motion's options (PassOptions fields), e.g. wheel_gaps=0,step_along=0.001")
    ap.add_argument("--product-only", action="store_true", help="measure only slow+af, the product's track")
    ap.add_argument("--navigation", default="",
                    help="SAR-MIN's own settings otherwise than the config's: [navigation] entries, e.g. "
                    "gnss_heading=true")
    args = ap.parse_args()
    from autosar_cli.sar.pass_ranges import PassOptions

    defaults = PassOptions()  # each value as its field's type (min_blocks is an int)
    passes = PassOptions(**{k: type(getattr(defaults, k))(float(v))
                            for k, v in (item.split("=") for item in args.passes.split(",") if item)})
    old = json.loads(args.output.read_text()) if args.append else {}
    rows: list[dict[str, Any]] = old.get("rows", [])
    note = "; ".join(n for n in (old.get("note", ""), args.note) if n)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    for item in args.drives.split(","):
        scenario, seed = item.split(":")
        row = drive_row(scenario, int(seed), args.keep, passes, args.product_only, args.navigation)
        row["passes"] = args.passes
        if args.navigation:
            row["navigation"] = args.navigation
        rows.append(row)
        print(json.dumps({k: row[k] for k in ("scenario", "seed", "slow_s", *TRACKS) if k in row}), flush=True)
        # after every drive, so that a stopped run keeps what it measured
        result = {"benchmark": "af_pass_ranges", "note": note, "summary": summary(rows), "rows": rows}
        args.output.write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result["summary"], indent=1))


if __name__ == "__main__":
    main()
