"""``autosar run``: ingest -> navigate -> focus in one go, every product in one directory plus run.json.

run.json (format ``autosar-run`` version 1) records the inputs (path, size), the autosar version, the
config file, the method and focus parameters, per-stage wall times and summaries, and the outputs
(paths relative to the run directory), so ``autosar evaluate DIR`` can find everything.
"""

from __future__ import annotations

import json
import os
import platform
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from autosar_cli import __version__
from autosar_cli.config import Config
from autosar_cli.ingest.pipeline import ingest
from autosar_cli.nav.navigate import navigate
from autosar_cli.sar.focus import FocusOptions, focus
from autosar_cli.store.atomic import atomic_output
from autosar_cli.store.manifest import json_default, read_json_manifest
from autosar_cli.store.trajectory import write_trajectory

FORMAT = "autosar-run"
FORMAT_VERSION = 1
STAGES = ("ingest", "navigate", "focus")

#: Products inside a run directory.
DRIVE = "drive.h5"
TRAJECTORY = "trajectory.h5"
IMAGE = "image"  # image.tif, image.h5, image.png


class RunError(ValueError):
    """A run cannot start (e.g. the output directory holds another run and --overwrite was not given)."""


def run(logs: Sequence[str | Path], out_dir: str | Path, config: Config, *, method: str = "sar-min",
        options: FocusOptions | None = None, truth_path: str | Path | None = None, overwrite: bool = False,
        progress: Callable[[str, int, int], None] | None = None, command: str = "") -> dict[str, Any]:
    """Run the whole chain on ``logs`` into ``out_dir``; returns the manifest (also written as run.json).

    ``progress(stage, done, total)`` is called as each stage advances.
    """
    out = Path(out_dir)
    manifest_path = out / "run.json"
    if manifest_path.exists() and not overwrite:
        raise RunError(f"{out}: already holds a run (run.json); pass --overwrite to replace it")
    out.mkdir(parents=True, exist_ok=True)
    options = options or FocusOptions.from_config(config)
    inputs = [{"path": str(Path(p)), "size_bytes": _size(Path(p))} for p in logs]
    manifest: dict[str, Any] = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "autosar_version": __version__,
        "python": platform.python_version(), "command": command, "config": config.source, "inputs": inputs,
        "method": method, "focus_options": asdict(options), "stages": {}, "outputs": {},
    }

    def stage_progress(stage: str) -> Callable[[int, int], None]:
        return lambda done, total: progress(stage, done, total) if progress else None

    t = time.perf_counter()
    report = ingest([Path(p) for p in logs], out / DRIVE, config=config, progress=stage_progress("ingest"),
                    command=command)
    rep = report.to_dict()
    manifest["stages"]["ingest"] = {"wall_s": time.perf_counter() - t, "messages": rep.get("messages"),
                                    "bytes_read": rep.get("bytes_read"), "warnings": rep.get("warnings", [])}
    manifest["outputs"]["drive"] = DRIVE

    t = time.perf_counter()
    if progress:
        progress("navigate", 0, 1)
    traj = navigate(out / DRIVE, method, config, truth_path=truth_path)
    write_trajectory(out / TRAJECTORY, traj)
    if progress:
        progress("navigate", 1, 1)
    span = (traj.t_ns[-1] - traj.t_ns[0]) / 1e9
    manifest["stages"]["navigate"] = {"wall_s": time.perf_counter() - t, "method": traj.method,
                                      "samples": int(len(traj.t_ns)), "duration_s": float(span),
                                      "distance_m": float(np.sum(np.hypot(*np.diff(traj.rear_axle_enu, axis=0).T))),
                                      **{k: traj.info[k] for k in ("updates", "rejected") if k in traj.info}}
    manifest["outputs"]["trajectory"] = TRAJECTORY
    if traj.info.get("truth"):
        manifest["truth"] = traj.info["truth"]

    t = time.perf_counter()
    frep = focus(out / DRIVE, out / TRAJECTORY, out / IMAGE, config, options, overwrite=True,
                 progress=stage_progress("focus"), command=command)
    manifest["stages"]["focus"] = {"wall_s": time.perf_counter() - t, "timings_s": frep.timings_s,
                                   "grid_shape": list(frep.grid_shape), "frames_used": frep.frames_used,
                                   "frames_skipped": frep.frames_skipped,
                                   "backprojections": frep.backprojections,
                                   "backprojections_per_s": frep.backprojections_per_s}
    manifest["outputs"]["image"] = {k: os.path.relpath(v, out) for k, v in frep.outputs.items()}
    manifest["drive_s"] = frep.drive_s
    manifest["wall_s"] = sum(s["wall_s"] for s in manifest["stages"].values())
    manifest["fraction_of_drive"] = manifest["wall_s"] / frep.drive_s if frep.drive_s > 0 else None
    with atomic_output(manifest_path, overwrite=True) as tmp:
        tmp.write_text(json.dumps(manifest, indent=2, default=json_default) + "\n")
    return manifest


def read_manifest(run_dir: str | Path) -> dict[str, Any]:
    """run.json of a run directory, checked."""
    return read_json_manifest(Path(run_dir) / "run.json", FORMAT, "run", RunError)


def _size(p: Path) -> int:
    if p.is_dir():
        return sum(f.stat().st_size for f in p.rglob("*") if f.is_file())
    return p.stat().st_size if p.exists() else 0


