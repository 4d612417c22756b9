"""``autosar compare``: one drive focused with several navigation methods, side by side (paper Fig. 10/11).

The log is ingested once (``OUT/drive.h5``). Every method (none, ins, sar-min, truth by default) is
navigated, focused and evaluated into ``OUT/<method>/`` (trajectory.h5, image.tif/.h5/.png, run.json
pointing at ``../drive.h5``, and the evaluation report: metrics.json, report.md, figures), then:

- ``compare.png``: the images one above the other, same dB colour scale relative to the maximum over all
  methods (paper Fig. 10);
- ``across_track.png``: each method's across-track deviation from the straight line through its own track
  (paper Fig. 11), and its across-track error vs the truth after the SE(2) alignment;
- ``compare_chips.png``: the fine patch of every reflector (columns) for every method (rows);
- ``compare.md`` and ``compare.json``: the comparison tables.

All images share one grid: the automatic grid of the true trajectory (without truth, SAR-MIN's, else the
first method's), moved into each method's frame by the inverse of its SE(2) alignment, so every panel shows
the same piece of the scene and entropy / contrast are computed over the same area. One pass over the
radar data per method serves the full image and the reflector patches. Methods that need the truth
(``truth``) are skipped with a note when the log has no truth sidecar, and so is a method whose inputs the
drive lacks (e.g. ``ins`` without the radar's IMU).
"""

from __future__ import annotations

import os
import platform
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

import numpy as np

from autosar_cli import __version__
from autosar_cli.config import Config
from autosar_cli.evaluate.alignment import Se2
from autosar_cli.evaluate.evaluation import (
    LINE_KINDS,
    Evaluation,
    Truth,
    evaluate_image,
    load_truth,
    metrics_grid,
    product_pixels,
)
from autosar_cli.evaluate.figures import plot_across_track, plot_images_side_by_side, plot_reflector_chips
from autosar_cli.evaluate.reflectors import ReflectorPatches, focus_patches, predict_image_positions
from autosar_cli.evaluate.report import (
    METRICS,
    degraded_markdown,
    fmt,
    markdown_table,
    write_report,
    write_text,
)
from autosar_cli.evaluate.report import PRODUCTS as REPORT_PRODUCTS
from autosar_cli.evaluate.trajectory_metrics import common_instants, trajectory_errors
from autosar_cli.ingest.pipeline import IngestOptions, carry_warnings, chain_hint, ingest
from autosar_cli.nav.inputs import NavInputError
from autosar_cli.nav.navigate import METHODS as NAV_METHODS
from autosar_cli.nav.navigate import default_truth_path, navigate
from autosar_cli.nav.trajectory import Trajectory, phase_centre_lever_arm, with_mounting_yaw
from autosar_cli.run import FORMAT as RUN_FORMAT
from autosar_cli.run import FORMAT_VERSION as RUN_FORMAT_VERSION
from autosar_cli.sar.autofocus import TrackAutofocus, estimate_track_scale, scale_track
from autosar_cli.sar.autofocus_stage import autofocus_residual_motion
from autosar_cli.sar.focus import (
    FocusOptions,
    auto_grid,
    brightest_pixel,
    channels_incoherent_warning,
    coarse_pixel_warning,
    drive_radar_config,
    focus_images,
    unfocused_radars,
)
from autosar_cli.sar.grid import FocusGrid
from autosar_cli.sar.range_compression import range_null_m
from autosar_cli.sim.truth import truth_radar_mismatch
from autosar_cli.store.drive import Drive, radar_times
from autosar_cli.store.image import FocusedImage, write_image
from autosar_cli.store.manifest import json_safe, product_status, write_json
from autosar_cli.store.outputs import check_free_space, check_output, check_products, input_bytes, output_directory
from autosar_cli.store.trajectory import write_trajectory

FORMAT = "autosar-compare"
FORMAT_VERSION = 1
DEFAULT_METHODS = ("none", "ins", "sar-min", "truth")
#: SAR-MIN with its track's scale measured by the radar on the corner reflectors (sar/autofocus.py); it needs the
#: truth's reflector list to know where they are, and costs ~20 wide-beam focusings
SARMIN_SCALED = "sar-min+scale"
#: SAR-MIN corrected by the residual-motion autofocus (sar/autofocus_stage.py) on the bright isolated points of its
#: own image: no truth needed
SARMIN_AUTOFOCUS = "sar-min+af"
DERIVED = (SARMIN_SCALED, SARMIN_AUTOFOCUS)  # made from SAR-MIN's track, which is navigated for them
COMPARE_METHODS = (*NAV_METHODS, *DERIVED)
NEEDS_TRUTH = ("truth", SARMIN_SCALED)
DRIVE = "drive.h5"
#: what each method's directory holds (as ``autosar run`` writes it, and its evaluation)
#: a comparison's own files beside its drive.h5 and method directories
OWN_PRODUCTS = ("compare.png", "across_track.png", "compare_chips.png", "compare.md", "compare.json")
METHOD_PRODUCTS = ("trajectory.h5", "image.tif", "image.h5", "image.png", "run.json", *REPORT_PRODUCTS)

Progress = Callable[[str, int, int], None]


class CompareError(ValueError):
    """A comparison cannot start (unknown method, existing output without --overwrite, ...)."""


def parse_methods(spec: str | Sequence[str]) -> list[str]:
    """``"none,ins,sar-min,truth"`` (or a sequence) -> the list of methods, checked, duplicates removed."""
    items = spec.split(",") if isinstance(spec, str) else list(spec)
    methods: list[str] = []
    for m in (s.strip() for s in items):
        if not m:
            continue
        if m not in COMPARE_METHODS:
            raise CompareError(f"--methods: unknown method {m!r} (choose from {', '.join(COMPARE_METHODS)})")
        if m not in methods:
            methods.append(m)
    if not methods:
        raise CompareError("--methods: give at least one method")
    return methods


def transform_grid(grid: FocusGrid, motion: Se2) -> FocusGrid:
    """``grid`` moved rigidly by ``motion`` (same shape and pixel; origin and axes transformed)."""
    r = motion.rotation
    origin = motion.apply(np.asarray(grid.origin))
    along, across = r @ np.asarray(grid.along), r @ np.asarray(grid.across)
    return replace(grid, origin=(float(origin[0]), float(origin[1])), along=(float(along[0]), float(along[1])),
                   across=(float(across[0]), float(across[1])))


def compare(logs: Sequence[str | Path], out_dir: str | Path, config: Config, *,
            methods: Sequence[str] = DEFAULT_METHODS, truth_path: str | Path | None = None,
            options: FocusOptions | None = None, overwrite: bool = False, progress: Progress | None = None,
            command: str = "", ingest_options: IngestOptions | None = None, can_logs: Sequence[str | Path] = (),
            nmea_logs: Sequence[str | Path] = ()) -> dict[str, Any]:
    """Compare navigation methods on one drive; returns the comparison (also written as compare.json).
    ``logs``, ``can_logs``, ``nmea_logs`` and ``ingest_options`` as for :func:`autosar_cli.run.run`."""
    out = Path(out_dir)
    if (out / "compare.json").exists() and not overwrite:
        raise CompareError(f"{out}: already holds a comparison (compare.json); pass --overwrite to replace it")
    ingest_options = ingest_options or IngestOptions()
    given = [*logs, *can_logs, *nmea_logs]  # every input read into the drive (as the manifests list them)
    read = [*given, *([truth_path] if truth_path else []), *config.files, *ingest_options.files()]
    methods = parse_methods(methods)
    check_output(out, read, overwrite=overwrite, directory=True)
    check_products(out, [DRIVE, *OWN_PRODUCTS], read, overwrite=overwrite, manifest="compare.json")
    for m in methods:  # each method's directory: a run's products and its evaluation's (its own metrics.json)
        check_products(out / m, METHOD_PRODUCTS, read, overwrite=overwrite, manifest=METRICS)
    check_free_space(out / DRIVE, input_bytes(given), "the drive")
    if truth_path is not None and not Path(truth_path).is_file():
        raise CompareError(f"{truth_path}: no such truth sidecar")
    products = [out / name for name in (DRIVE, *OWN_PRODUCTS)] + [out / m / name for m in methods
                                                                   for name in METHOD_PRODUCTS]
    with output_directory(out, products, manifest=out / "compare.json"):  # a comparison that fails leaves none
        return _compare(logs, out, config, methods, truth_path, options or FocusOptions.from_config(config),
                        progress, command, ingest_options, can_logs, nmea_logs, given)


def _compare(logs: Sequence[str | Path], out: Path, config: Config, methods: list[str],
             truth_path: str | Path | None, options: FocusOptions, progress: Progress | None, command: str,
             ingest_options: IngestOptions, can_logs: Sequence[str | Path], nmea_logs: Sequence[str | Path],
             given: list[str | Path]) -> dict[str, Any]:
    """:func:`compare` once its outputs are checked (``given``: every input read into the drive)."""
    tick = progress or (lambda stage, done, total: None)
    timings: dict[str, float] = {}
    notes: list[str] = []

    t0 = time.perf_counter()
    report = ingest([Path(p) for p in logs], out / DRIVE, config=config, command=command,
                    can_logs=[Path(p) for p in can_logs], nmea_logs=[Path(p) for p in nmea_logs],
                    progress=lambda done, total: tick("ingest", done, total),
                    partial_hint=chain_hint("a comparison"), **ingest_options.ingest_kwargs())
    timings["ingest"] = time.perf_counter() - t0
    warnings = [str(w) for w in report.warnings]  # a damaged log, dropped data: every product is degraded
    try:
        return _compare_drive(out, config, methods, truth_path, options, command, tick, timings, notes, given,
                              list(warnings))
    except BaseException as exc:
        carry_warnings(exc, warnings)
        raise


def _compare_drive(out: Path, config: Config, methods: list[str], truth_path: str | Path | None,
                   options: FocusOptions, command: str, tick: Progress, timings: dict[str, float], notes: list[str],
                   given: list[str | Path], warnings: list[str]) -> dict[str, Any]:
    """:func:`compare` once its drive is ingested (``warnings``: what the ingest warned of)."""
    unfocused = unfocused_radars(out / DRIVE, options)  # another radar of the drive: in no image
    warnings += unfocused
    config = drive_radar_config(config, out / DRIVE, options.radar)  # a radar ingested with --radar-override

    with Drive(out / DRIVE) as d:
        truth_path = truth_path or default_truth_path(d)
        if truth_path is not None and (why := truth_radar_mismatch(truth_path, d)):
            raise CompareError(why)
    skipped: dict[str, str] = {}
    if truth_path is None:
        for m in methods:
            if m in NEEDS_TRUTH:
                skipped[m] = "no truth sidecar next to the log (give --truth LOG.truth.h5)"
        notes.append("no truth sidecar: trajectory and reflector metrics need one; only entropy and contrast "
                     "are compared")
    t0 = time.perf_counter()
    trajectories: dict[str, Trajectory] = {}
    wanted = [m for m in methods if m not in skipped]
    nav_wanted = [m for m in wanted if m not in DERIVED]
    if any(m in DERIVED for m in wanted) and "sar-min" not in nav_wanted:
        nav_wanted.append("sar-min")  # their base; compared only if asked for
    for i, m in enumerate(nav_wanted):
        tick("navigate", i, len(nav_wanted))
        try:
            trajectories[m] = navigate(out / DRIVE, m, config, truth_path=truth_path)
        except NavInputError as exc:  # e.g. no radar IMU for the INS: compare the others
            skipped[m] = str(exc).splitlines()[0]
    tick("navigate", len(nav_wanted), len(nav_wanted))
    timings["navigate"] = time.perf_counter() - t0
    run_methods = [m for m in methods if m not in skipped
                   and (m in trajectories or (m in DERIVED and "sar-min" in trajectories))]
    autofocus: dict[str, Any] | None = None  # what the autofocus measured, applied or not
    if SARMIN_AUTOFOCUS in run_methods:
        t0 = time.perf_counter()
        tick("autofocus sar-min's residual motion", 0, 1)
        focused = autofocus_residual_motion(out / DRIVE, trajectories["sar-min"], config, options)
        tick("autofocus sar-min's residual motion", 1, 1)
        timings["autofocus"] = time.perf_counter() - t0
        autofocus = {k: v for k, v in focused.to_dict().items() if k != "points_enu"}
        if focused.channel_gains is not None:  # a property of the radar: every method's image undoes them
            options = replace(options, channel_gains=focused.channel_gains)
        if focused.radar_mounting_yaw_deg is not None:  # and is focused along the boresight the points agreed on
            config = with_mounting_yaw(config, focused.radar_mounting_yaw_deg)
        if not focused.applied:
            run_methods.remove(SARMIN_AUTOFOCUS)
            skipped[SARMIN_AUTOFOCUS] = f"SAR-MIN's {focused.summary()}"
        else:
            trajectories[SARMIN_AUTOFOCUS] = focused.labelled(SARMIN_AUTOFOCUS)
            notes.append(f"{SARMIN_AUTOFOCUS}: SAR-MIN's {focused.summary()}")
    if not run_methods:
        raise CompareError("no method left to compare: " + "; ".join(f"{k}: {v}" for k, v in skipped.items()))

    first = trajectories.get(run_methods[0]) or trajectories["sar-min"]  # sar-min+scale: made from sar-min below
    truth: Truth | None = None
    if truth_path is not None:
        truth = load_truth(truth_path, first.origin, config)
    base_traj = truth.trajectory if truth is not None else trajectories.get("sar-min", first)
    base_grid = auto_grid(out / DRIVE, base_traj, config, options)
    range_dir = base_grid.across

    alignments: dict[str, Se2] = {m: Se2() for m in run_methods}
    centres: dict[str, np.ndarray] = {}
    has_reflectors = truth is not None and len(truth.targets.corner_reflectors) > 0
    names = truth.targets.corner_reflector_names() if has_reflectors and truth else []
    true_cr = truth.targets.position_enu[truth.targets.corner_reflectors] if has_reflectors and truth else None
    if truth is not None:
        t_radar = radar_times(out / DRIVE, options.radar, options.radar_clock_offset_s, options.radar_clock_drift_ppm)
        lever = phase_centre_lever_arm(config)

        def register(m: str) -> None:
            t = common_instants(trajectories[m], truth.trajectory, t_radar)
            alignments[m] = trajectory_errors(trajectories[m], truth.trajectory, lever, t).alignment
            if has_reflectors:
                centres[m] = predict_image_positions(trajectories[m], truth.trajectory,
                                                     truth.targets_above_road(truth.targets.corner_reflectors),
                                                     config, t, options.height_m)

        for m in run_methods:
            if m != SARMIN_SCALED:
                register(m)
        if SARMIN_SCALED in run_methods:
            if not has_reflectors:
                run_methods.remove(SARMIN_SCALED)
                skipped[SARMIN_SCALED] = "the truth lists no corner reflector to measure the scale on"
            else:
                if "sar-min" not in centres:
                    register("sar-min")
                t0 = time.perf_counter()
                tick("measure sar-min's track scale on the reflectors", 0, 1)
                est = estimate_track_scale(out / DRIVE, trajectories["sar-min"], config, centres["sar-min"])
                tick("measure sar-min's track scale on the reflectors", 1, 1)
                timings["track_scale"] = time.perf_counter() - t0
                focused = TrackAutofocus(scale_track(trajectories["sar-min"], est.scale), est, centres["sar-min"],
                                         points_label="corner reflectors")
                trajectories[SARMIN_SCALED] = focused.labelled(SARMIN_SCALED)
                register(SARMIN_SCALED)
                notes.append(f"{SARMIN_SCALED}: SAR-MIN's {focused.summary()}")

    # The truth trajectory's reflector patches are every method's peak-loss reference: focus them first.
    order = sorted(run_methods, key=lambda m: m != "truth")
    reference: ReflectorPatches | None = None
    if has_reflectors and "truth" not in run_methods and truth is not None:
        t0 = time.perf_counter()
        tick("focus reference patches (truth)", 0, 1)
        reference = focus_patches(out / DRIVE, truth.trajectory, config, options, names, true_cr)[0]
        tick("focus reference patches (truth)", 1, 1)
        timings["reference_patches"] = time.perf_counter() - t0

    evaluations: dict[str, Evaluation] = {}
    own: dict[str, list[str]] = {}  # what each method's navigation and focus warned of beyond the drive's warnings
    for m in order:
        traj = trajectories[m]
        mdir = out / m
        mdir.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        label = f"focus {m}"
        tick(label, 0, 1)
        # the metrics grid over the registered product grid; the product is every other of its pixels (its own
        # grid moved by half a metrics pixel): focusing it again would add a fifth to the pass
        fine = metrics_grid(transform_grid(base_grid, alignments[m].inverse()))
        if has_reflectors:
            patches, (metrics_image,), res = focus_patches(out / DRIVE, traj, config, options, names, true_cr,
                                                           alignments[m], predicted_xy=centres[m], extra_grids=[fine])
        else:
            res = focus_images(out / DRIVE, traj, config, options, grids=[fine])
            (metrics_image,), patches = res.images, None
        tick(label, 1, 1)
        metrics_image.params["pixel_m"] = metrics_image.grid.pixel_m
        image = product_pixels(metrics_image)
        image.params["grid"] = "auto, registered" if truth is not None else "auto"
        image.params["grid_reference"] = base_traj.method
        # what the image lacks (frames of a damaged drive or outside the track, a gap it bridges, a coarse pixel),
        # with it as focus keeps it: the method's run.json, its evaluation and compare.json say degraded
        # and, as focus checks it on its image, whether the product's brightest point adds its channels coherently
        incoherent = channels_incoherent_warning(out / DRIVE, traj, config, options, image.grid,
                                                 brightest_pixel(image.image), len(image.params["channel_pairs"]))
        focus_warnings = list(dict.fromkeys([*_product_pixel_warnings(res.warnings, metrics_image, image, options),
                                             *unfocused, *([incoherent] if incoherent else [])]))
        image.provenance.update({"drive": str(out / DRIVE), "trajectory": str(mdir / "trajectory.h5"),
                                 "command": command, "warnings": focus_warnings})
        nav_warnings = [str(w) for w in traj.info.get("warnings", [])]
        own[m] = [w for w in dict.fromkeys([*nav_warnings, *focus_warnings]) if w not in warnings]
        focus_s = time.perf_counter() - t0
        write_trajectory(mdir / "trajectory.h5", traj)
        outputs = write_image(mdir / "image", image, overwrite=True)
        _write_method_manifest(mdir, given, config, m, traj, truth_path, options, res, focus_s, outputs, command,
                               [*warnings, *own[m]], nav_warnings, focus_warnings)
        timings[f"focus_{m}"] = focus_s
        t0 = time.perf_counter()
        tick(f"evaluate {m}", 0, 1)
        if m == "truth" and patches is not None:
            reference = patches
        ev = evaluate_image(image, traj, out / DRIVE, config, truth, metrics_image=metrics_image, patches=patches,
                            reference_patches=reference,
                            range_dir=range_dir,
                            inputs={"image": str(outputs["h5"]), "trajectory": str(mdir / "trajectory.h5"),
                                    "drive": str(out / DRIVE), "config": config.source})
        write_report(ev, mdir, overwrite=True)
        evaluations[m] = ev
        tick(f"evaluate {m}", 1, 1)
        timings[f"evaluate_{m}"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    tick("figures", 0, 1)
    shown = list(run_methods)
    figures = {"compare": plot_images_side_by_side([(m, evaluations[m].image) for m in shown],
                                                   out / "compare.png").name,
               "across_track": plot_across_track([trajectories[m] for m in shown], out / "across_track.png",
                                                 [evaluations[m].errors for m in shown
                                                  if evaluations[m].errors is not None]).name}
    chip_rows = [(m, p, evaluations[m].reflectors) for m in shown if (p := evaluations[m].patches) is not None]
    if chip_rows:
        figures["compare_chips"] = plot_reflector_chips(chip_rows, out / "compare_chips.png").name
    tick("figures", 1, 1)
    timings["figures"] = time.perf_counter() - t0

    # a warning every method gave (a coarse pixel, the drive's damaged frames) is the comparison's, said once; the
    # others name their method
    common = [w for w in dict.fromkeys(w for m in run_methods for w in own[m]) if all(w in own[m] for m in run_methods)]
    shared = [*warnings, *common]
    warnings = [*shared, *(method_warning(m, w) for m in run_methods for w in own[m] if w not in common)]
    result: dict[str, Any] = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "autosar_version": __version__, "command": command,
        "inputs": [os.path.abspath(p) for p in given], "config": config.source,
        "truth": os.path.abspath(truth_path) if truth_path else None,
        "methods": run_methods, "skipped": skipped, "notes": notes,
        "status": product_status(warnings), "warnings": warnings,
        "grid": {"reference_trajectory": base_traj.method, "shape": list(base_grid.shape),
                 "pixel_m": base_grid.pixel_m, "range_direction": list(range_dir)},
        "results": {m: {**_method_result(evaluations[m]), "status": product_status([*shared, *own[m]]),
                        "warnings": [w for w in own[m] if w not in common]} for m in run_methods},
        "autofocus": autofocus,
        "timings_s": timings, "outputs": {**figures, "markdown": "compare.md",
                                          "methods": {m: m for m in run_methods}},
    }
    result["wall_s"] = sum(timings.values())
    write_text(out / "compare.md", compare_markdown(result, evaluations, figures))
    write_json(out / "compare.json", result)
    return json_safe(result)


def _product_pixel_warnings(warnings: list[str], metrics_image: FocusedImage, image: FocusedImage,
                            options: FocusOptions) -> list[str]:
    """``warnings`` of the focus of ``metrics_image`` (half the product's pixel), its pixel warning (if any) for the
    product's pixel instead, as focusing the product alone would give (:func:`coarse_pixel_warning`)."""
    p = metrics_image.params
    null = range_null_m(sample_rate_hz=p["sample_rate_hz"], slope_hz_per_s=p["slope_hz_per_s"],
                        num_samples=p["num_samples"], window=options.window)
    fine = coarse_pixel_warning(metrics_image.grid.pixel_m, options.resolution_m, null)
    coarse = coarse_pixel_warning(image.grid.pixel_m, options.resolution_m, null)
    return [w for w in warnings if w != fine] + ([coarse] if coarse else [])


def method_warning(method: str, warning: str) -> str:
    """``warning`` of one method's navigation or focus as the comparison lists it: naming the method unless it
    does (focus names a trajectory it was given as ``<METHOD trajectory>``)."""
    return warning if f"<{method} trajectory>" in warning else f"{method}: {warning}"


def _method_result(ev: Evaluation) -> dict[str, Any]:
    return {"summary": ev.summary(),
            "trajectory": ev.trajectory_metrics.to_dict() if ev.trajectory_metrics else None,
            "alignment": ev.alignment.to_dict() if ev.errors is not None else None,
            "image": ev.image_metrics.to_dict(),
            "reflectors": [r.to_dict() for r in ev.reflectors]}


def _write_method_manifest(mdir: Path, logs: Sequence[str | Path], config: Config, method: str, traj: Trajectory,
                           truth_path: str | Path | None, options: FocusOptions, res: Any, focus_s: float,
                           outputs: dict[str, Path], command: str, warnings: list[str], nav_warnings: list[str],
                           focus_warnings: list[str]) -> None:
    """A run.json (format autosar-run) for a method directory, so ``autosar evaluate OUT/<method>`` works;
    ``warnings``: the ingest's, the navigation's and the focus's (as in `autosar run`'s), ``nav_warnings`` and
    ``focus_warnings`` those stages' own."""
    manifest = {
        "format": RUN_FORMAT, "format_version": RUN_FORMAT_VERSION, "autosar_version": __version__,
        "python": platform.python_version(), "command": command, "config": config.source,
        "inputs": [{"path": str(p)} for p in logs], "method": method, "focus_options": asdict(options),
        "stages": {"navigate": {"method": traj.method, "samples": int(len(traj.t_ns)),
                                "elapsed_s": traj.info.get("elapsed_s"), "warnings": nav_warnings},
                   "focus": {"wall_s": focus_s, "timings_s": res.timings_s, "frames_used": res.frames_used,
                             "frames_skipped": res.frames_skipped, "backprojections": res.backprojections,
                             "warnings": focus_warnings}},
        "outputs": {"drive": os.path.join("..", DRIVE), "trajectory": "trajectory.h5",
                    "image": {k: os.path.relpath(v, mdir) for k, v in outputs.items()}},
        "drive_s": res.drive_s, "comparison": "..", "status": product_status(warnings), "warnings": warnings,
    }
    if truth_path is not None:
        manifest["truth"] = str(truth_path)
    write_json(mdir / "run.json", manifest)


def compare_markdown(result: dict[str, Any], evaluations: dict[str, Evaluation], figures: dict[str, str]) -> str:
    """compare.md: the per-method table, the per-reflector table, the figures and notes."""
    methods = result["methods"]
    parts = ["# Navigation comparison\n\n",
             f"Log: {', '.join(f'`{p}`' for p in result['inputs'])}; truth: "
             f"{'`' + result['truth'] + '`' if result['truth'] else 'none'}; grid: the automatic grid of the "
             f"{result['grid']['reference_trajectory']} trajectory ({result['grid']['shape'][0]} x "
             f"{result['grid']['shape'][1]} pixels of {result['grid']['pixel_m'] * 100:g} cm)"
             + (", registered into each method's frame by its SE(2) alignment" if result["truth"] else "")
             + ".\n\n"]
    own = {m: result["results"][m].get("warnings", []) for m in methods}
    named = {method_warning(m, w) for m in methods for w in own[m]}
    parts.append(degraded_markdown([w for w in result.get("warnings", []) if w not in named], "every image below is"))
    if named:
        parts.append("**Degraded images:** what navigating and focusing along these methods' trajectories warned "
                     "of.\n\n" + "".join(f"- {method_warning(m, w)}\n" for m in methods for w in own[m]) + "\n")
    rows = []
    for m in methods:
        s = evaluations[m].summary()
        rows.append([m, fmt(s["abs_rmse_m"], 100), fmt(s["aligned_rmse_m"], 100), fmt(s["rpe_1m_across_m"], 1000),
                     fmt(s["rpe_10m_across_m"], 1000), fmt(s["aligned_error_mean_m"], 100),
                     fmt(s["aligned_error_max_m"], 100), fmt(s["local_aligned_error_max_m"], 100),
                     fmt(s["reference_error_max_m"], 100), fmt(s["peak_loss_mean_db"], signed=True),
                     fmt(s["peak_loss_max_db"], signed=True), fmt(s["entropy"], digits=4),
                     fmt(s["contrast"], digits=1), fmt(s["entropy_rn"], digits=4), fmt(s["entropy_far"], digits=4),
                     fmt(s["contrast_far"], digits=1)]
                    + [fmt(s[f"straightness_{k}_m"], 100) for k in LINE_KINDS])
    parts.append(markdown_table(["method", "abs RMSE (cm)", "aligned RMSE (cm)", "RPE 1 m across (mm)",
                                 "RPE 10 m across (mm)", "reflector aligned error mean (cm)", "max (cm)",
                                 "max, local alignment (cm)", "max, from the truth image's (cm)",
                                 "peak loss mean (dB)", "max (dB)", "entropy (nats)", "contrast",
                                 "range-normalised entropy (nats)", "far swath entropy (nats)", "far swath contrast"]
                                + [f"{k} straightness (cm)" for k in LINE_KINDS], rows))
    names = [r.name for r in next(iter(evaluations.values())).reflectors]
    if names:
        parts.append("\nPer reflector: aligned position error (cm; in brackets with the local alignment on the 10 m "
                     "of track around the reflector) / peak loss vs the truth-trajectory image (dB).\n\n")
        by = {m: {r.name: r for r in evaluations[m].reflectors} for m in methods}
        rows = [[n] + [f"{fmt(by[m][n].aligned_error_m, 100)} ({fmt(by[m][n].local_aligned_error_m, 100)}) / "
                       f"{fmt(by[m][n].peak_loss_db, signed=True)}" if n in by[m] else "–" for m in methods]
                for n in names]
        parts.append(markdown_table(["reflector", *methods], rows))
    parts.append("\n" + "\n".join(f"![{k}]({v})" for k, v in figures.items()) + "\n")
    notes = list(result["notes"]) + [f"{m} skipped: {why}" for m, why in result["skipped"].items()]
    if notes:
        parts.append("\n## Notes\n\n" + "\n".join(f"- {n}" for n in notes) + "\n")
    parts.append(f"\nPer-method reports: {', '.join(f'[{m}]({m}/report.md)' for m in methods)}.\n")
    return "".join(parts)
