"""Benchmark the slow motion's block length on drives whose road reflects, against the truth: what the passes fit.

Usage: python benches/bench_pass_blocks.py [--drives urban:1,urban:2] [--simulation road_reflection=-0.8] [--append]

Each drive is simulated with the full vehicle (``--simulation``: entries of [simulation], as bench_paper.py takes
them; "" for none) and ingested, then navigated (SAR-MIN). Along each track, the truth's and SAR-MIN's, the first
image's points (as the autofocus takes them) give their passes' blocks of each ``--blocks`` length (s), and the slow
motion's fit (:func:`autosar_cli.sar.pass_ranges.fit_blocks`) is measured against the truth: the correction's RMS
(along the truth track, which needs none, all of it is error), the radar track's along-track error RMS after an
SE(2) alignment to the truth's (SAR-MIN's, and corrected), and the navigation's drive and brake slip gains as the
passes fit them. Along SAR-MIN's at the first block length, each used point is also left out in turn: how far the
brake gain moves without it (in its std) and the along-track error then. Rows to benches/results/pass_blocks.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_paper import cli, config_copy  # noqa: E402

from autosar_cli.config import load_config  # noqa: E402
from autosar_cli.evaluate.evaluation import load_truth  # noqa: E402
from autosar_cli.evaluate.trajectory_metrics import common_instants, trajectory_errors  # noqa: E402
from autosar_cli.nav.navigate import navigate  # noqa: E402
from autosar_cli.nav.trajectory import phase_centre_lever_arm  # noqa: E402
from autosar_cli.sar import pass_ranges  # noqa: E402
from autosar_cli.sar.channel_calibration import with_stated_gains  # noqa: E402
from autosar_cli.sar.focus import FocusOptions  # noqa: E402
from autosar_cli.sar.point_selection import candidate_points  # noqa: E402
from autosar_cli.sar.residual_motion import AutofocusOptions  # noqa: E402
from autosar_cli.types import Trajectory  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"


def fit_record(fit: pass_ranges.SlowMotion, along_error_mm: Any) -> dict[str, Any]:
    """The figures of one fit: points used, the correction's RMS, the corrected track's along-track error, the slip
    gains (per mil per m/s^2) and the scale (%)."""
    if not fit.applied:
        return {"applied": False, "reason": fit.reason}
    gains = {mode: [round(1e3 * float(v), 2), round(1e3 * float(s), 2)]
             for mode, v, s in zip(("drive", "brake"), fit.slip_gain_error, fit.slip_gain_error_std, strict=False)}
    record = fit.to_dict()
    return {"applied": True, "points_used": record["points_used"], "residual_mm": record["residual_mm"],
            "correction_rms_mm": record["correction"]["rms_mm"],  # type: ignore[index]
            "along_error_mm": along_error_mm(fit.trajectory), "slip_gains_per_mil": gains,
            "scale_pct": [round(100 * fit.scale, 4), round(100 * fit.scale_std, 4)]}


def measure(drive: Path, truth_path: Path, config_path: Path, blocks_s: list[float]) -> dict[str, Any]:
    config = load_config(config_path)
    sarmin = navigate(drive, "sar-min", config)
    truth = load_truth(truth_path, sarmin.origin, config)
    focus = with_stated_gains(drive, FocusOptions.from_config(config))
    af = AutofocusOptions.from_config(config)
    instants = common_instants(sarmin, truth.trajectory)[::10]
    lever = phase_centre_lever_arm(config)

    def along_error_mm(track: Trajectory) -> float:
        e = trajectory_errors(track, truth.trajectory, lever, instants)
        return round(1e3 * float(np.sqrt(np.mean(e.aligned_along ** 2))), 2)

    out: dict[str, Any] = {"sarmin_along_error_mm": along_error_mm(sarmin)}
    for name, track in (("truth", truth.trajectory), ("sar-min", sarmin)):
        points = candidate_points(drive, track, config, focus, af)
        histories = pass_ranges.pass_histories(drive, track, config, points, focus, pass_ranges.PassOptions())
        for block_s in blocks_s:
            opts = pass_ranges.PassOptions(block_s=block_s)
            blocks = pass_ranges.pass_blocks(drive, track, config, points, focus, opts, histories)
            fit = pass_ranges.fit_blocks(blocks, track, config, opts)
            out[f"{name} {block_s:g} s"] = fit_record(fit, along_error_mm)
            if name != "sar-min" or block_s != blocks_s[0] or not fit.applied or len(fit.slip_gain_error) < 2:
                continue
            left_out = []
            for j in np.flatnonzero(fit.points_used):
                kept = dataclasses.replace(blocks, usable=blocks.usable & (blocks.point != j))
                without = pass_ranges.fit_blocks(kept, track, config, opts)
                if without.applied:
                    moved = abs(float(without.slip_gain_error[1] - fit.slip_gain_error[1])) / float(
                        fit.slip_gain_error_std[1])
                    left_out.append({"point": int(j), "brake_gain_moved_std": round(moved, 1),
                                     "along_error_mm": along_error_mm(without.trajectory)})
            out[f"sar-min {block_s:g} s, each point left out"] = left_out
    return out


def summary(rows: list[dict[str, Any]]) -> dict[str, str]:
    """Per road (``simulation``): its drives, and per fit the along-track error (mm) of each in turn ("refused" where
    the fit was) and the scatter of its points' paths about it
    (:attr:`~autosar_cli.sar.pass_ranges.SlowMotion.residual_m`), joined by " / "."""
    out: dict[str, str] = {}
    for row in rows:
        road = row["simulation"] or "no road reflection"
        fits = {k: v for k, v in row.items() if isinstance(v, dict) and "applied" in v}
        cells = {f"{road}, drives": f"{row['scenario']} seed {row['seed']}",
                 f"{road}, SAR-MIN: along-track error (mm)": f"{row['sarmin_along_error_mm']:g}"}
        cells |= {f"{road}, {k}: along-track error (mm)": f"{v['along_error_mm']:g}" if v["applied"] else "refused"
                  for k, v in fits.items()}
        cells |= {f"{road}, {k}: the points' scatter about the fit (mm)": f"{v['residual_mm']:g}" if v["applied"]
                  else "-" for k, v in fits.items()}
        for key, value in cells.items():
            out[key] = f"{out[key]} / {value}" if key in out else value
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drives", default="urban:1,urban:2", help="scenario:seed,...")
    ap.add_argument("--simulation", default="road_reflection=-0.8", help="entries of [simulation]; '' for none")
    ap.add_argument("--blocks", default="0.1,0.2", help="block lengths (s), the product's first")
    ap.add_argument("--workdir", type=Path, default=None)
    ap.add_argument("--output", type=Path, default=RESULTS / "pass_blocks.json")
    ap.add_argument("--append", action="store_true", help="add to --output's rows")
    args = ap.parse_args()
    blocks_s = [float(b) for b in args.blocks.split(",")]
    work = args.workdir or Path(tempfile.mkdtemp(prefix="pass_blocks_"))
    work.mkdir(parents=True, exist_ok=True)
    config = config_copy(None, None, work, simulation=args.simulation or None)
    old = json.loads(args.output.read_text()) if args.append and args.output.exists() else {"note": "", "rows": []}
    rows, note = old["rows"], "; ".join(n for n in (old["note"], " ".join(sys.argv[1:])) if n)
    for item in args.drives.split(","):
        scenario, seed = item.split(":")
        log = work / f"{scenario}_s{seed}.mcap"
        drive = work / f"{scenario}_s{seed}.h5"
        if not drive.exists():
            cli("simulate", "--scenario", scenario, "--seed", seed, "--dynamics", "full", "--output", str(log),
                "--overwrite", "--config", str(config))
            cli("ingest", str(log), "-o", str(drive), "--overwrite", "--config", str(config))
        row = {"scenario": scenario, "seed": int(seed), "simulation": args.simulation,
               **measure(drive, Path(f"{log}.truth.h5"), config, blocks_s)}
        print(json.dumps(row))
        rows.append(row)
        args.output.write_text(json.dumps({"benchmark": "pass_blocks", "note": note, "summary": summary(rows),
                                           "rows": rows},
                                          indent=1) + "\n")


if __name__ == "__main__":
    main()
