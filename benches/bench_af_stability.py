"""Benchmark how far the autofocus's track moves when SAR-MIN's track it starts from moves by a nanometre.

Usage: python benches/bench_af_stability.py [--drives urban:0,urban:8] [--keep DIR] [--shift-nm 1]
                                            [--output benches/results/af_stability.json] [--before FILE]

Per drive (``simulate --dynamics full``, ``ingest``, ``navigate`` as bench_af_pass_ranges makes them; with ``--keep``
the files stay in DIR/<scenario><seed> and are used again): the product's autofocus (``autofocus_residual_motion``,
the config's options) along SAR-MIN's track and along the same track moved east by ``--shift-nm``; the radar's
phase centre on both corrected tracks at 20 000 instants, and how far apart they are, less the shift (largest and
RMS, mm), with each run's points used and time. A fit that is a smooth function of its input moves by about the
shift; one whose iterations stop wherever their cap falls moves by what its points leave undetermined (±1.65 mm),
and a drive near the 2 cm line crosses it on another host's last bits. ``--before``: the output of a run of this bench
on other code (a worktree, side by side), its figures added to each row and the summary as ``before_*``."""

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
from bench_af_pass_ranges import kept_drive  # noqa: E402
from bench_paper import RESULTS  # noqa: E402


def drive_row(work: Path, shift_m: float) -> dict[str, Any]:
    """The phase centre's move between the autofocus along ``work``'s sarmin.h5 and along it shifted east."""
    from autosar_cli.config import load_config
    from autosar_cli.nav.trajectory import phase_centre_lever_arm
    from autosar_cli.sar.autofocus_stage import autofocus_residual_motion
    from autosar_cli.sar.focus import FocusOptions
    from autosar_cli.store.trajectory import read_trajectory

    config = load_config()
    est = read_trajectory(work / "sarmin.h5")
    moved = replace(est, rear_axle_enu=est.rear_axle_enu + np.array([shift_m, 0.0]))
    t = np.linspace(est.t_ns[0], est.t_ns[-1], 20000).astype(np.int64)
    lever = phase_centre_lever_arm(config)[None]
    centres, row = [], {}
    for name, track in (("as_navigated", est), ("shifted", moved)):
        start = time.perf_counter()
        res = autofocus_residual_motion(work / "drive.h5", track, config, FocusOptions.from_config(config))
        row[f"{name}_s"] = round(time.perf_counter() - start, 1)
        row[f"{name}_points_used"] = int(res.points_used.sum())
        row[f"{name}_summary"] = res.summary()
        centres.append(res.trajectory.body_points(t, lever)[:, 0])
    move = np.linalg.norm(centres[1] - centres[0] - np.array([shift_m, 0.0, 0.0]), axis=-1)
    row["move_max_mm"] = float(f"{1e3 * move.max():.3g}")
    row["move_rms_mm"] = float(f"{1e3 * np.sqrt(np.mean(move**2)):.3g}")
    return row


def moves_summary(moves: list[float], prefix: str = "") -> dict[str, float | int]:
    """The largest of the drives' largest moves (mm) and how many exceed 0.1 mm, keys named with ``prefix``."""
    return {f"{prefix}move_max_mm": max(moves), f"{prefix}drives_moved_over_0.1mm": sum(m > 0.1 for m in moves)}


def with_before(rows: list[dict[str, Any]], summary: dict[str, Any], before: dict[str, Any]) -> None:
    """``before``'s (another run's output) moves beside each of ``rows`` of the same drive, and in ``summary``."""
    theirs = {(r["scenario"], r["seed"]): r for r in before["rows"]}
    for row in rows:
        other = theirs.get((row["scenario"], row["seed"]))
        if other is not None:
            row["before_move_max_mm"], row["before_move_rms_mm"] = other["move_max_mm"], other["move_rms_mm"]
            row["before_points_used"] = [other["as_navigated_points_used"], other["shifted_points_used"]]
    moves = [r["before_move_max_mm"] for r in rows if "before_move_max_mm" in r]
    if moves:
        summary.update(moves_summary(moves, "before_"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drives", default="urban:0,urban:8", help="scenario:seed,...")
    ap.add_argument("--keep", type=Path, default=None, help="keep (and use again) each drive's files under this")
    ap.add_argument("--shift-nm", type=float, default=1.0, help="the shift of SAR-MIN's track, east (nm)")
    ap.add_argument("--output", type=Path, default=RESULTS / "af_stability.json")
    ap.add_argument("--before", type=Path, default=None, help="this bench's output on other code, to compare with")
    ap.add_argument("--note", default="", help="how these rows were run")
    args = ap.parse_args()
    before = json.loads(args.before.read_text()) if args.before else None
    rows: list[dict[str, Any]] = []
    args.output.parent.mkdir(parents=True, exist_ok=True)
    for item in args.drives.split(","):
        scenario, seed = item.split(":")
        with tempfile.TemporaryDirectory() as tmp:
            work = kept_drive(scenario, int(seed), (args.keep / f"{scenario}{seed}") if args.keep else Path(tmp))
            row = {"scenario": scenario, "seed": int(seed), **drive_row(work, 1e-9 * args.shift_nm)}
        rows.append(row)
        print(json.dumps({k: row[k] for k in ("scenario", "seed", "move_max_mm", "move_rms_mm",
                                              "as_navigated_points_used", "shifted_points_used")}), flush=True)
        moves = [r["move_max_mm"] for r in rows]
        summary = {"drives": len(rows), **moves_summary(moves), "move_max_median_mm": float(np.median(moves))}
        if before is not None:
            with_before(rows, summary, before)
        result = {"benchmark": "af_stability", "shift_nm": args.shift_nm, "note": args.note, "summary": summary,
                  "rows": rows}
        args.output.write_text(json.dumps(result, indent=1) + "\n")  # after every drive: a stopped run keeps it
    print(json.dumps(result["summary"], indent=1))


if __name__ == "__main__":
    main()
