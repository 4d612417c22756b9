"""Report figures (PNG, matplotlib Agg): trajectory error, reflector chips, side-by-side images, across-track.

Every figure is written atomically (``<name>.partial-<pid>.png``, then renamed) and its path returned.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from autosar_cli.evaluate.reflectors import ReflectorMetrics, ReflectorPatches, chosen_patch
from autosar_cli.evaluate.trajectory_metrics import TrajectoryErrors
from autosar_cli.nav.plot import across_track_deviation
from autosar_cli.nav.trajectory import Trajectory
from autosar_cli.store.image import FocusedImage, magnitude_db
from autosar_cli.store.quicklook import PanelGrid, agg_figure, draw_tiled, save_png, tile_layout

#: Colours of the methods in every figure (paper Fig. 11: INS red, SAR-MIN blue).
COLOURS = {"truth": "black", "sar-min": "tab:blue", "ins": "tab:red", "gnss": "tab:orange", "none": "tab:gray"}


def _cmap(name: str) -> Any:
    """A copy of colour map ``name`` that draws NaN (pixels no pulse reached) in its lowest colour."""
    import matplotlib

    cmap = matplotlib.colormaps[name]
    return cmap.with_extremes(bad=cmap(0.0))


def plot_trajectory_errors(errors: TrajectoryErrors, path: str | Path) -> Path:
    """Error of the estimated phase-centre track vs the truth over time and distance: absolute (no alignment)
    with its along / across components, and after the rigid SE(2) alignment."""
    t, s = errors.t_s, errors.distance_m
    fig, panels = PanelGrid(1, 3, (4.55, 3.55)).figure()
    axes = panels[0]
    ax = axes[0]
    ax.plot(t, np.hypot(errors.error_along, errors.error_across) * 100, "k", lw=1, label="horizontal")
    ax.plot(t, errors.error_along * 100, lw=1, label="along")
    ax.plot(t, errors.error_across * 100, lw=1, label="across")
    ax.set(xlabel="time (s)", ylabel="error (cm)", title=f"{errors.method} - truth, absolute")
    ax.legend()
    ax = axes[1]
    ax.plot(s, errors.aligned_along * 100, lw=1, label="along")
    ax.plot(s, errors.aligned_across * 100, lw=1, label="across")
    a = errors.alignment
    ax.set(xlabel="distance travelled (m)", ylabel="error (cm)",
           title=f"after SE(2) alignment ({np.degrees(a.angle_rad):.3f} deg, "
                 f"{a.translation[0]:.2f}, {a.translation[1]:.2f} m)")
    ax.legend()
    ax = axes[2]
    for xy, label, colour in ((errors.ref_xy, "truth", "black"),
                              (a.apply(errors.est_xy), f"{errors.method} (aligned)",
                               COLOURS.get(errors.method, "tab:blue"))):
        along, across = across_track_deviation(xy)
        ax.plot(along, across * 100, lw=1, label=label, color=colour)
    ax.set(xlabel="along track (m)", ylabel="across track (cm)",
           title="radar track: deviation from the straight line")
    ax.legend()
    return save_png(fig, path)


def _chip_db(img: FocusedImage, ref_db: float) -> NDArray[np.float32]:
    return magnitude_db(img.image) - np.float32(ref_db)


def plot_reflector_chips(rows: Sequence[tuple[str, ReflectorPatches, Sequence[ReflectorMetrics]]],
                         path: str | Path, *, dynamic_range_db: float = 40.0) -> Path:
    """Fine patches of every reflector (columns) for one or more methods (rows), in dB relative to the brightest
    peak of that reflector over the rows (so peak losses show), north up, metres from the patch centre.

    The patch shown is the one the peak was found in. Marks: white ``x`` where the reflector should appear
    (T^-1 of the truth; outside the patch when the trajectory displaces the response by more), cyan ``+``
    the measured peak.
    """
    n_rows = len(rows)
    n_cols = max(len(p.names) for _, p, _ in rows) if rows else 0
    if n_rows == 0 or n_cols == 0:
        raise ValueError("no reflector patches to plot")
    shown: list[list[tuple[FocusedImage, ReflectorMetrics | None] | None]] = []
    for _, patches, metrics in rows:
        by_name = {m.name: m for m in metrics}
        line: list[tuple[FocusedImage, ReflectorMetrics | None] | None] = []
        for j in range(n_cols):
            if j >= len(patches.names):
                line.append(None)
                continue
            m = by_name.get(patches.names[j])
            line.append((chosen_patch(patches, m) if m is not None else patches.candidates[j][0], m))
        shown.append(line)
    peaks = [max((float(np.max(np.abs(c[0].image))) for line in shown if (c := line[j]) is not None), default=0.0)
             for j in range(n_cols)]
    ref = [20 * np.log10(r) if r > 0 else 0.0 for r in peaks]
    layout = PanelGrid(n_rows, n_cols, (2.0, 2.0), left_in=0.85, right_in=1.1, bottom_in=0.5, top_in=0.3,
                       gap_x_in=0.45, gap_y_in=0.5)
    fig, axes = layout.figure()
    im = None
    for i, ((label, patches, _), line) in enumerate(zip(rows, shown, strict=True)):
        for j, cell in enumerate(line):
            ax = axes[i, j]
            if cell is None:
                ax.axis("off")
                continue
            img, m = cell
            cx, cy = patches.centre_xy(img)
            ex, ey = patches.expected_xy[j]
            corners = img.grid.corners_enu()
            extent = (corners[:, 0].min() - cx, corners[:, 0].max() - cx, corners[:, 1].min() - cy,
                      corners[:, 1].max() - cy)
            im = ax.imshow(_chip_db(img, ref[j]), extent=extent, origin="upper", cmap=_cmap("viridis"),
                           vmin=-dynamic_range_db, vmax=0.0, interpolation="nearest")
            ax.plot([ex - cx], [ey - cy], "wx", ms=7, mew=1.5)
            ax.set_xlim(extent[0], extent[1])
            ax.set_ylim(extent[2], extent[3])
            title = patches.names[j]
            if m is not None and math.isfinite(m.aligned_error_m):
                ax.plot([m.peak_xy[0] - cx], [m.peak_xy[1] - cy], "c+", ms=9, mew=1.2)
                loss = "" if m.peak_loss_db is None else f", {m.peak_loss_db:+.1f} dB"
                title += f": {m.aligned_error_m * 100:.1f} cm{loss}"
            ax.set_title(title, fontsize=9)
            ax.tick_params(labelsize=7)
            if j == 0:
                ax.set_ylabel(f"{label}\nnorth (m)")
            if i == n_rows - 1:
                ax.set_xlabel("east (m)")
    if im is not None:
        fig.colorbar(im, cax=fig.add_axes(layout.right_strip(0.15)), label="dB (re brightest peak)")
    return save_png(fig, path)


def plot_images_side_by_side(images: Sequence[tuple[str, FocusedImage]], path: str | Path, *,
                             dynamic_range_db: float = 40.0) -> Path:
    """Full images with the same dB colour scale, relative to the maximum over all of them (paper Fig. 10),
    in the panel grid and tiles that let them fill the figure (:func:`~autosar_cli.store.quicklook.tile_layout`:
    a short drive's tall image is cut across range, a long drive's strip along track). Axes: metres along
    the grid (columns) and across it (rows, near range at the bottom)."""
    dbs = [magnitude_db(img.image) for _, img in images]
    top = max(float(np.nanmax(d)) for d in dbs)
    first = images[0][1].grid
    layout = tile_layout(first.shape, len(images), titled=True)
    fig = agg_figure(layout.figure_in, 110)
    panels = [(label, db - np.float32(top)) for (label, _), db in zip(images, dbs, strict=True)]
    draw_tiled(fig, layout, panels, first.pixel_m, vmin=-dynamic_range_db, cmap=_cmap("gray"),
               colorbar_label="dB (re maximum of all images)")
    return save_png(fig, path)


def plot_across_track(trajectories: Sequence[Trajectory], path: str | Path,
                      errors: Sequence[TrajectoryErrors] = ()) -> Path:
    """Across-track deviation of each method's rear-axle track from the straight line through its ends (paper
    Fig. 11), and, where given, each method's across-track error vs the truth after the SE(2) alignment."""
    n_panels = 2 if errors else 1
    fig, axes = PanelGrid(1, n_panels, (6.4, 3.6)).figure()
    ax = axes[0, 0]
    for tr in trajectories:
        along, across = across_track_deviation(tr.rear_axle_enu)
        ax.plot(along, across * 100, lw=1, label=tr.method, color=COLOURS.get(tr.method),
                ls="--" if tr.method == "truth" else "-")
    ax.set(xlabel="along track (m)", ylabel="across track (cm)",
           title="across-track motion: deviation from the straight line through the track")
    ax.legend()
    if errors:
        ax = axes[0, 1]
        for e in errors:
            ax.plot(e.distance_m, e.aligned_across * 100, lw=1, label=e.method, color=COLOURS.get(e.method),
                    ls="--" if e.method == "truth" else "-")
        ax.set(xlabel="distance travelled (m)", ylabel="across-track error (cm)",
               title="radar track - truth, after SE(2) alignment")
        ax.legend()
    return save_png(fig, path)
