"""Benchmark the channel phase of the autofocus's used points on drives whose scatterers all stand still.

The channel phase (the phase between the histories' first and last channel: the virtual array's ends, apart along
the road) tells a scatterer crossing the beam from a still one; the autofocus leaves out a used point above
``AutofocusOptions.max_channel_phase_rad``.

Usage: python benches/bench_af_movers.py [--drives test1:0,...,urban:9] [--keep DIR]
                                         [--output benches/results/af_movers.json]

Per drive (``simulate --dynamics full``, ``ingest``, ``navigate``; with ``--keep`` kept in DIR/<scenario><seed>, the
log removed once ingested, and used again): the product's autofocus (``autofocus_residual_motion``, the config's
options) along SAR-MIN's track, then its candidate points' histories over +-28 deg (2 channels, as its phase fit
gathers them) along the track it made, and each point's channel phase and coherence
(:func:`~autosar_cli.sar.phase_history.channel_phase`). Each row: the points the product used (the phases' fit's
or the slow motion's) and the others, their phase and coherence; the summary: the largest |phase| of a used point
over all drives, at any coherence and where the channels agree as well as the autofocus's test asks, and how many
unused candidates lie beyond a few limits. A limit above every used point's drops none
of them: on these drives a screen at it leaves the product as it is. The default drives: the 40 (test1-3, urban,
seeds 0-9), ~1 min each.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_paper import RESULTS, cli  # noqa: E402

LIMITS_RAD = (0.3, 0.5, 1.0)


def prepared(scenario: str, seed: int, work: Path) -> Path:
    """``work`` holding the drive's log.mcap.truth.h5, drive.h5 and SAR-MIN's sarmin.h5 (the log itself removed)."""
    work.mkdir(parents=True, exist_ok=True)
    log, drive, nav = work / "log.mcap", work / "drive.h5", work / "sarmin.h5"
    if not nav.exists():
        cli("simulate", "--scenario", scenario, "--seed", str(seed), "--dynamics", "full", "-o", str(log),
            "--overwrite")
        cli("ingest", str(log), "-o", str(drive), "--overwrite")
        cli("navigate", str(drive), "-o", str(nav), "--overwrite")
        log.unlink()
    return work


def drive_row(work: Path) -> dict[str, Any]:
    """The product's autofocus on ``work``'s drive, and its candidates' channel phases along the track it made."""
    from autosar_cli.config import load_config
    from autosar_cli.sar.autofocus_stage import autofocus_residual_motion
    from autosar_cli.sar.focus import FocusOptions
    from autosar_cli.sar.phase_history import channel_phase, gather_phase_histories, pair_antennas
    from autosar_cli.sar.residual_motion import AutofocusOptions
    from autosar_cli.store.trajectory import read_trajectory

    config = load_config()
    focus, opts = FocusOptions.from_config(config), AutofocusOptions.from_config(config)
    drive = work / "drive.h5"
    result = autofocus_residual_motion(drive, read_trajectory(work / "sarmin.h5"), config, focus, opts)
    points = result.points_enu
    used = np.asarray(result.points_used, dtype=bool).copy()
    slow = result.slow_motion
    if slow is not None and slow.points_used is not None and len(slow.points_used) == len(points):
        used |= np.asarray(slow.points_used, dtype=bool)
    hist = gather_phase_histories(drive, result.trajectory, config, points, focus, half_beam_deg=opts.half_beam_deg,
                                  window_bins=opts.window_bins, channels=opts.channels)
    phase, coherence = channel_phase(hist, *pair_antennas(hist, result.trajectory, config), points, len(points))
    return {"applied": result.applied, "points": len(points), "used": int(used.sum()),
            "used_max_abs_phase_rad": round(float(np.max(np.abs(phase[used]), initial=0.0)), 3),
            "used_min_coherence": round(float(np.min(coherence[used], initial=1.0)), 3),
            "phase_rad": np.round(phase, 3).tolist(), "coherence": np.round(coherence, 3).tolist(),
            "used_mask": used.tolist()}


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    from autosar_cli.sar.residual_motion import AutofocusOptions

    least = AutofocusOptions().min_channel_coherence
    used_max = max((r["used_max_abs_phase_rad"] for r in rows), default=0.0)
    coherent = [abs(p) for r in rows for p, c, u in zip(r["phase_rad"], r["coherence"], r["used_mask"], strict=True)
                if u and c >= least]
    unused = [abs(p) for r in rows for p, u in zip(r["phase_rad"], r["used_mask"], strict=True) if not u]
    return {"drives": len(rows), "used_points": sum(r["used"] for r in rows),
            "used_max_abs_phase_rad": used_max,
            # those whose channels agree as well as the autofocus's test asks (AutofocusOptions.min_channel_coherence)
            "min_channel_coherence": least, "used_coherent_max_abs_phase_rad": max(coherent, default=0.0),
            "worst_drive": max(rows, key=lambda r: r["used_max_abs_phase_rad"])["drive"] if rows else None,
            "unused_points": len(unused),
            "unused_beyond": {f"{lim:g}": int(sum(p > lim for p in unused)) for lim in LIMITS_RAD}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drives", default=",".join(f"{s}:{n}" for s in ("test1", "test2", "test3", "urban")
                                                 for n in range(10)))
    ap.add_argument("--keep", type=Path, default=None)
    ap.add_argument("--output", type=Path, default=RESULTS / "af_movers.json")
    args = ap.parse_args()
    rows = []
    for item in args.drives.split(","):
        scenario, seed = item.split(":")
        with tempfile.TemporaryDirectory() as tmp:
            work = prepared(scenario, int(seed), (args.keep / f"{scenario}{seed}") if args.keep else Path(tmp))
            row = {"drive": item, **drive_row(work)}
        rows.append(row)
        print(f"{item}: {row['used']} of {row['points']} points used, their |channel phase| <= "
              f"{row['used_max_abs_phase_rad']:.3f} rad (coherence >= {row['used_min_coherence']:.2f})", flush=True)
        out = {"benchmark": "af_movers", "summary": summary(rows), "rows": rows}
        args.output.write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(summary(rows), indent=1))


if __name__ == "__main__":
    main()
