"""Benchmark what a perfect autofocus would give: SAR-MIN's track corrected by the truth's own motion, per axis.

Usage: python benches/bench_af_oracle.py [--scenario test1] [--seed 0] [--cutoff-hz 0.5]

``autosar simulate`` (full vehicle), then ``compare --methods sar-min,sar-min+af,truth`` once per case, with the
autofocus inside compare replaced by an oracle: SAR-MIN's track plus the part of its phase-centre error (the
sidecar's true phase centres less SAR-MIN's, per frame) above ``--cutoff-hz`` (zero-phase Butterworth high-pass),
along the axes named (``across``, ``up``, ``along``, or all three); the case ``autofocus`` is the product's own,
and ``autofocus_seen`` / ``autofocus_unseen`` are it plus the truth's across-track part above ``--cutoff-hz`` of
what it leaves, on the frames its points see / do not see (``ResidualMotion.seen_t_ns``).
A figure of the far-swath entropy with, say, the across-track axis alone close to the truth image's says that
axis, in that band, is what the image lacks; the RMS of that part is what an autofocus would have to measure.
Prints one line per case and writes benches/results/af_oracle.json; ``--cutoff-hz 4 --output
benches/results/af_oracle_4hz.json``: the band of the radar case's vibration alone.
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

RESULTS = Path(__file__).resolve().parent / "results"
CASES = {"none": (), "across": ("across",), "up": ("up",), "along": ("along",), "all": ("across", "up", "along"),
         "autofocus": None, "autofocus_seen": "seen", "autofocus_unseen": "unseen"}


def oracle(truth_path: Path, axes: tuple[str, ...], cutoff_hz: float) -> Any:
    """A replacement for compare's ``autofocus_residual_motion``: the truth's correction on ``axes``."""
    import h5py
    from scipy.signal import butter, sosfiltfilt

    from autosar_cli.sar.phase_history import frame_geometry
    from autosar_cli.sar.residual_motion import ResidualMotion
    from autosar_cli.types import MotionCorrection

    def corrected(drive: Path, traj: Any, config: Any, *_: Any, **__: Any) -> ResidualMotion:
        with h5py.File(truth_path) as f:
            t, pc = f["radar/t_ns"][:], f["radar/phase_centre_enu"][:].mean(axis=(1, 2))
        keep = (t >= traj.t_ns[0]) & (t <= traj.t_ns[-1])
        t, pc = t[keep], pc[keep]
        centre, across, along = frame_geometry(traj, t, config)
        error = pc - centre
        part = np.zeros_like(error)
        for name, unit in (("across", across), ("along", along)):
            if name in axes:
                part += np.sum(error * unit, axis=1)[:, None] * unit
        if "up" in axes:
            part[:, 2] = error[:, 2]
        rate = 1e9 / float(np.median(np.diff(t)))
        part = sosfiltfilt(butter(4, cutoff_hz, "highpass", fs=rate, output="sos"), part, axis=0)
        base = traj.correction.at(t) if traj.correction is not None else np.zeros_like(part)
        measured = MotionCorrection(t, part, np.zeros_like(part))
        moved = dataclasses.replace(traj, correction=MotionCorrection(t, base + part, np.zeros_like(part)))
        return ResidualMotion(moved, measured, np.zeros((0, 3)), np.zeros(0, bool), np.zeros(0), 0.0, 1.0, 1.0, 0)

    return corrected


def autofocus_then_oracle(truth_path: Path, where: str, cutoff_hz: float) -> Any:
    """A replacement for compare's ``autofocus_residual_motion``: the product's, then the truth's across-track part
    above ``cutoff_hz`` of what it leaves, on the frames its points see (``where`` "seen") or do not see ("unseen")."""
    from autosar_cli.sar.autofocus_stage import autofocus_residual_motion
    from autosar_cli.types import MotionCorrection

    def corrected(drive: Path, traj: Any, config: Any, *args: Any, **kwargs: Any) -> Any:
        result = autofocus_residual_motion(drive, traj, config, *args, **kwargs)
        track = result.trajectory
        part = oracle(truth_path, ("across",), cutoff_hz)(drive, track, config).correction  # at the truth's frames
        assert part is not None
        t = part.t_ns
        seen = np.isin(t, result.seen_t_ns)
        keep = seen if where == "seen" else ~seen
        base = track.correction.at(t) if track.correction is not None else np.zeros((len(t), 3))
        added = np.where(keep[:, None], part.offset_enu, 0.0)
        correction = MotionCorrection(t, base + added, np.zeros_like(added))
        return dataclasses.replace(result, trajectory=dataclasses.replace(track, correction=correction))

    return corrected


def run_case(log: Path, out: Path, autofocus: Any = None) -> dict[str, Any]:
    """compare, in this process, with ``autofocus`` in the place of the product's ``autofocus_residual_motion``
    (None: the product's own)."""
    import autosar_cli.evaluate.compare as compare_module
    from autosar_cli.cli import app

    saved = compare_module.autofocus_residual_motion
    if autofocus is not None:
        compare_module.autofocus_residual_motion = autofocus
    try:
        args = ["compare", str(log), "-o", str(out), "--methods", "sar-min,sar-min+af,truth", "--overwrite"]
        try:
            app(args, standalone_mode=False)
        except SystemExit as exc:
            if exc.code:
                raise
    finally:
        compare_module.autofocus_residual_motion = saved
    return json.loads((out / "compare.json").read_text())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="test1")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cutoff-hz", type=float, default=0.5)
    ap.add_argument("--output", type=Path, default=RESULTS / "af_oracle.json")
    args = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_paper import cli, drive_row

    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "drive.mcap"
        cli("simulate", "--scenario", args.scenario, "--seed", str(args.seed), "--dynamics", "full", "--output",
            str(log))
        truth_path = log.with_name(log.name + ".truth.h5")
        for case, axes in CASES.items():
            fix = (None if axes is None else autofocus_then_oracle(truth_path, axes, args.cutoff_hz)
                   if isinstance(axes, str) else oracle(truth_path, axes, args.cutoff_hz))
            comparison = run_case(log, Path(tmp) / case, fix)
            row = drive_row(args.scenario, args.seed, comparison, 0.0, 0.0)
            af = row.get("sar-min+af", {})
            rows.append({"case": case,
                         "far_entropy_above_truth_pct": row["entropy_far"]["vs_truth_pct"].get("sar-min+af"),
                         "worst_reflector_cm": af.get("reflector_error_max_cm"),
                         "peak_loss_max_db": af.get("peak_loss_max_db"),
                         "correction_rms_mm": (comparison.get("autofocus") or {}).get("correction", {}).get("rms_mm")})
            print(rows[-1], flush=True)
    result = {"benchmark": "af_oracle", "scenario": args.scenario, "seed": args.seed, "dynamics": "full",
              "cutoff_hz": args.cutoff_hz}
    # one figure per case under each measure: a line of BENCHMARKS.md each, not a table
    result |= {key: {r["case"]: r[key] for r in rows} for key in rows[0] if key != "case"}
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
