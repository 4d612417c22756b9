"""``autosar evaluate``: a run directory (or an image.h5) in, a report directory out.

The report directory gets ``metrics.json`` (format ``autosar-evaluation`` v1: every number of
:class:`~autosar_cli.evaluate.evaluation.Evaluation`, NaN written as null), ``report.md`` (tables) and PNG
figures: ``trajectory_error.png`` (error vs truth over time and distance, across-track component, the
aligned track's deviation from a straight line) and ``reflector_chips.png`` (the fine patch of every
reflector in dB with the expected position marked). Every file is written atomically.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from autosar_cli.config import Config, load_config
from autosar_cli.evaluate.evaluation import Evaluation, evaluate_image, load_truth
from autosar_cli.evaluate.figures import plot_reflector_chips, plot_trajectory_errors
from autosar_cli.nav.navigate import default_truth_path
from autosar_cli.run import RunError, not_finished, read_manifest
from autosar_cli.sim.truth import truth_path_for, truth_radar_mismatch
from autosar_cli.store.atomic import atomic_output
from autosar_cli.store.drive import Drive
from autosar_cli.store.image import read_image
from autosar_cli.store.manifest import json_safe, write_json
from autosar_cli.store.outputs import check_output, check_products, output_directory, what_autosar_wrote
from autosar_cli.store.trajectory import read_trajectory

METRICS = "metrics.json"
REPORT = "report.md"
TRAJECTORY_FIGURE = "trajectory_error.png"
CHIPS_FIGURE = "reflector_chips.png"
PRODUCTS = (METRICS, REPORT, TRAJECTORY_FIGURE, CHIPS_FIGURE)  #: what an evaluation writes into its directory


class EvaluateError(ValueError):
    """The inputs of an evaluation cannot be found or read; the message names the file and the problem."""


@dataclass
class RunInputs:
    """What an evaluation reads: the image, the trajectory it was focused along, the drive, config, truth."""

    image_path: Path
    trajectory_path: Path
    drive_path: Path
    config: Config
    truth_path: Path | None
    manifest: dict[str, Any] | None = None


def _existing(path_text: str, *bases: Path) -> Path | None:
    p = Path(path_text)
    for cand in [p] + [b / p for b in bases if not p.is_absolute()]:
        if cand.is_file():
            return cand
    return None


def resolve_inputs(source: str | Path, truth_path: str | Path | None = None,
                   config: Config | None = None) -> RunInputs:
    """Find the image, trajectory, drive, config and truth of a run directory (via run.json) or an image.h5
    (via its provenance). Default truth: run.json's ``truth``, else ``<log>.truth.h5`` of the drive's input log."""
    src = Path(source)
    manifest = None
    if src.is_dir():
        try:
            manifest = read_manifest(src)
        except RunError as exc:
            raise EvaluateError(str(exc)) from None
        if unfinished := not_finished(manifest):
            raise EvaluateError(f"{src / 'run.json'}: {unfinished}; run it again with --overwrite")
        outs = manifest.get("outputs", {})
        try:
            image = src / outs["image"]["h5"]
            traj = src / outs["trajectory"]
            drive = src / outs["drive"]
        except (KeyError, TypeError):
            raise EvaluateError(f"{src / 'run.json'}: the run is incomplete (no image, trajectory or drive "
                                "output recorded)") from None
        config_text = manifest.get("config") or ""
    elif src.is_file():
        if src.suffix.lower() in (".tif", ".tiff", ".json") and (product := what_autosar_wrote(src)) is not None:
            raise EvaluateError(f"{src}: {product}" + ("" if "evaluate" in product else
                                                          "; evaluate reads a run directory or an image.h5"))
        try:
            prov = read_image(src).provenance
        except (OSError, ValueError) as exc:
            raise EvaluateError(str(exc)) from None
        image = src
        found_traj = _existing(str(prov.get("trajectory", "")), src.parent)
        found_drive = _existing(str(prov.get("drive", "")), src.parent)
        if found_traj is None or found_drive is None:
            raise EvaluateError(f"{src}: its provenance names no readable trajectory.h5 / drive.h5 "
                                f"(trajectory {prov.get('trajectory')!r}, drive {prov.get('drive')!r}); "
                                "evaluate the run directory instead")
        traj, drive = found_traj, found_drive
        config_text = str(prov.get("config") or "")
    else:
        raise EvaluateError(f"{src}: no such run directory or image.h5")
    for p, what in ((image, "image"), (traj, "trajectory"), (drive, "drive")):
        if not p.is_file():
            raise EvaluateError(f"{p}: the {what} of {src} is missing")
    if config is None:
        config = load_config(config_text) if config_text and Path(config_text).is_file() else load_config()
    with Drive(drive) as d:
        truth = _find_truth(truth_path, manifest, d)
        if truth is not None and (why := truth_radar_mismatch(truth, d)):
            raise EvaluateError(why)
    return RunInputs(image, traj, drive, config, truth, manifest)


def _find_truth(explicit: str | Path | None, manifest: dict[str, Any] | None, drive: Drive) -> Path | None:
    if explicit is not None:
        p = Path(explicit)
        if not p.is_file():
            raise EvaluateError(f"{p}: no such truth sidecar")
        return p
    if manifest and manifest.get("truth") and Path(manifest["truth"]).is_file():
        return Path(manifest["truth"])
    found = default_truth_path(drive)
    if found is not None:
        return found
    for item in (manifest or {}).get("inputs", []):
        cand = truth_path_for(Path(item.get("path", "")))
        if cand.is_file():
            return cand
    return None


def evaluate_run(source: str | Path, out_dir: str | Path, truth_path: str | Path | None = None, *,
                 config: Config | None = None, overwrite: bool = False,
                 progress: Callable[[str, int, int], None] | None = None) -> dict[str, Any]:
    """Evaluate a run directory or an image.h5 against the truth and write the report into ``out_dir``.

    Returns the metrics (as in metrics.json) plus ``outputs`` (paths written).
    """
    out = Path(out_dir)
    if (out / METRICS).exists() and not overwrite:
        raise EvaluateError(f"{out}: already holds an evaluation ({METRICS}); pass --overwrite to replace it")
    inputs = resolve_inputs(source, truth_path, config)
    read = [p for p in (inputs.image_path, inputs.trajectory_path, inputs.drive_path, inputs.truth_path) if p]
    check_output(out, read, overwrite=overwrite, directory=True)
    check_products(out, PRODUCTS, read, overwrite=overwrite, manifest=METRICS)
    if progress:
        progress("evaluate", 0, 1)
    image = read_image(inputs.image_path)
    traj = read_trajectory(inputs.trajectory_path)
    truth = load_truth(inputs.truth_path, image.origin, inputs.config) if inputs.truth_path else None
    ev = evaluate_image(image, traj, inputs.drive_path, inputs.config, truth,
                        inputs={"source": str(source), "image": str(inputs.image_path),
                                "trajectory": str(inputs.trajectory_path), "drive": str(inputs.drive_path),
                                "config": inputs.config.source})
    result = write_report(ev, out, overwrite=overwrite)
    if progress:
        progress("evaluate", 1, 1)
    return result


# ------------------------------------------------------------------------------------------------ writing

def write_text(path: Path, text: str, *, overwrite: bool = True) -> Path:
    with atomic_output(path, overwrite) as tmp:
        tmp.write_text(text)
    return path


def fmt(value: float | None, scale: float = 1.0, digits: int = 2, signed: bool = False) -> str:
    """A number for a Markdown table; '–' for None / NaN."""
    if value is None or not math.isfinite(value):
        return "–"
    return f"{value * scale:{'+' if signed else ''}.{digits}f}"


def markdown_table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def reflector_table(ev: Evaluation) -> str:
    """Markdown table of the reflector metrics of one evaluation."""
    rows = [[m.name, fmt(m.aligned_error_m, 100), f"{fmt(m.aligned_error_range_m, 100, signed=True)} / "
             f"{fmt(m.aligned_error_cross_m, 100, signed=True)}", fmt(m.local_aligned_error_m, 100),
             fmt(m.absolute_error_m, 100),
             fmt(m.peak_loss_db, signed=True), fmt(m.irw_range_m, 100), fmt(m.irw_cross_m, 100),
             f"{fmt(m.pslr_range_db, digits=1)} / {fmt(m.pslr_cross_db, digits=1)}",
             f"{fmt(m.islr_range_db, digits=1)} / {fmt(m.islr_cross_db, digits=1)}"] for m in ev.reflectors]
    return markdown_table(["reflector", "aligned error (cm)", "range / cross (cm)", "local alignment (cm)",
                           "absolute error (cm)",
                           "peak loss (dB)", "IRW range (cm)", "IRW cross (cm)", "PSLR r / c (dB)",
                           "ISLR r / c (dB)"], rows)


def degraded_markdown(warnings: list[str], what: str) -> str:
    """The list of a damaged input's warnings that heads a report ("" when there is none)."""
    if not warnings:
        return ""
    return (f"**Degraded input:** {what} made from what could be read of the drive.\n\n"
            + "".join(f"- {w}\n" for w in warnings) + "\n")


def report_markdown(ev: Evaluation, figures: dict[str, str]) -> str:
    """report.md of one evaluation."""
    parts = [f"# Evaluation: {ev.method}\n\n",
             markdown_table(["input", "path"], [[k, f"`{v}`"] for k, v in ev.inputs.items()]
                            + [["truth", f"`{ev.truth.path}`" if ev.truth else "none"]])]
    parts.append("\n" + degraded_markdown(ev.input_warnings, "the image is"))
    scale = ev.trajectory.info.get("track_scale")
    if scale is not None:  # autosar run --autofocus, compare's sar-min+scale / sar-min+af
        n = len(ev.trajectory.info.get("autofocus_points_enu", []))
        measured = f" (on {n} points)" if n else ""
        parts.append(f"\nThe navigated track's distances were scaled by {scale * 100:+.4f} % before focusing: the "
                     f"radar's own measure of the odometry's scale{measured}.\n")
    tm = ev.trajectory_metrics
    if tm is not None:
        a = ev.alignment
        parts += ["\n## Trajectory vs truth (radar phase centre, radar frame times)\n\n",
                  markdown_table(["metric", "value"], [
                      ["samples / duration / distance",
                       f"{tm.samples} / {tm.duration_s:.1f} s / {tm.distance_m:.1f} m"],
                      ["absolute horizontal RMSE (max)", f"{fmt(tm.abs_rmse_m, 100)} cm ({fmt(tm.abs_max_m, 100)} cm)"],
                      ["absolute RMSE along / across", f"{fmt(tm.abs_rmse_along_m, 100)} / "
                                                       f"{fmt(tm.abs_rmse_across_m, 100)} cm"],
                      ["RPE over 1 m, RMS along / across", f"{fmt(tm.rpe_1m_along_m, 1000)} / "
                                                           f"{fmt(tm.rpe_1m_across_m, 1000)} mm"],
                      ["RPE over 10 m, RMS along / across", f"{fmt(tm.rpe_10m_along_m, 1000)} / "
                                                            f"{fmt(tm.rpe_10m_across_m, 1000)} mm"],
                      ["SE(2) alignment (estimate -> truth)", f"{a.to_dict()['angle_deg']:.4f} deg, "
                                                              f"({a.translation[0]:.3f}, {a.translation[1]:.3f}) m"],
                      ["RMSE after alignment (max), across", f"{fmt(tm.aligned_rmse_m, 100)} cm "
                                                             f"({fmt(tm.aligned_max_m, 100)} cm), "
                                                             f"{fmt(tm.aligned_rmse_across_m, 100)} cm"],
                      ["absolute error over its stated std, RMS along / across (1: that std holds)",
                       f"{fmt(tm.position_z_along_rms, digits=2)} / {fmt(tm.position_z_across_rms, digits=2)}"]])]
    if ev.reflectors:
        parts += ["\n## Corner reflectors (1 m patches of 5 mm pixels)\n\n",
                  "Aligned error: distance of the peak from where the reflector should appear in this image "
                  "(the truth moved by the inverse SE(2) alignment); range / cross: its signed components; local "
                  "alignment: the same with the alignment fitted on the 10 m of track around the reflector only. "
                  "Peak loss: peak of the truth-trajectory image minus this peak.\n\n",
                  reflector_table(ev)]
    im = ev.image_metrics
    px = f"{im.pixel_m * 100:g} cm pixels" if math.isfinite(im.pixel_m) else "–"
    rows = [["pixels with data", f"{im.pixels} ({px})"], ["entropy (nats)", fmt(im.entropy, digits=4)],
            ["contrast std(I)/mean(I)", fmt(im.contrast, digits=2)]]
    if im.far_swath:
        rows.append([f"far swath (>= {im.far_swath['min_range_m']:.1f} m from the radar's track, "
                     f"{im.far_swath['pixels']} pixels): entropy / contrast",
                     f"{fmt(im.far_swath['entropy'], digits=4)} / {fmt(im.far_swath['contrast'], digits=2)}"])
    if im.range_normalised:
        rows.append([f"range-normalised (|z|² R^{im.range_normalised['exponent']:g}, R from the radar's track): "
                     "entropy / contrast", f"{fmt(im.range_normalised['entropy'], digits=4)} / "
                                           f"{fmt(im.range_normalised['contrast'], digits=2)}"])
    if im.product:
        rows.append([f"product image ({im.product['pixel_m'] * 100:g} cm pixels): entropy / contrast",
                     f"{fmt(im.product['entropy'], digits=4)} / {fmt(im.product['contrast'], digits=2)}"])
    rows += [[f"straightness of the {k} (RMS residual)", f"{fmt(s.rms_residual_m, 100)} cm over "
              f"{s.length_m:.1f} m ({s.n_columns} columns)"] for k, s in im.straightness.items()]
    parts += ["\n## Image (the product's grid at half its pixel: intensity sampled at its Nyquist rate)\n\n",
              markdown_table(["metric", "value"], rows)]
    if figures:
        parts.append("\n## Figures\n\n" + "\n".join(f"![{k}]({v})" for k, v in figures.items()) + "\n")
    if ev.notes:
        parts.append("\n## Notes\n\n" + "\n".join(f"- {n}" for n in ev.notes) + "\n")
    return "".join(parts)


def write_report(ev: Evaluation, out_dir: str | Path, *, overwrite: bool = False) -> dict[str, Any]:
    """Write metrics.json, report.md and the figures of ``ev`` into ``out_dir``; return the metrics + outputs."""
    out = Path(out_dir)
    if (out / METRICS).exists() and not overwrite:
        raise EvaluateError(f"{out}: already holds an evaluation ({METRICS}); pass --overwrite to replace it")
    figures: dict[str, str] = {}
    metrics = ev.to_dict()
    with output_directory(out, [out / name for name in PRODUCTS], manifest=out / METRICS):  # all or none
        if ev.errors is not None:
            figures["trajectory error"] = plot_trajectory_errors(ev.errors, out / TRAJECTORY_FIGURE).name
        if ev.patches is not None and ev.reflectors:
            rows = [(ev.method, ev.patches, ev.reflectors)]
            figures["reflector chips"] = plot_reflector_chips(rows, out / CHIPS_FIGURE).name
        metrics["outputs"] = {"metrics": METRICS, "report": REPORT,
                              **{k.replace(" ", "_"): v for k, v in figures.items()}}
        write_text(out / REPORT, report_markdown(ev, figures))
        write_json(out / METRICS, metrics)
    metrics["outputs"] = {k: str(out / v) for k, v in metrics["outputs"].items()}
    return json_safe(metrics)
