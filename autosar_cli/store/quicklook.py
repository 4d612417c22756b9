"""Figures of focused images that fill the page: the PNG quicklook, and the panels `compare` draws.

A focused image is rarely near square: a short drive gives a tall one (the ci drive: 26 m of range across
2.4 m of travel, 11:1) and a long drive a strip (test2: 1:4). Drawn in one piece at equal scale, either
leaves the image a sliver of the figure. So the image is cut into tiles along its long side and the tiles
are set beside each other (a tall image: near range on the left) or under each other (a long strip: the
start of the drive on top), all at one scale in metres. :func:`tile_layout` picks the number of tiles, and
for several images the panel grid, that give the image the largest share of the figure, margins for the
tick labels, titles and the dB colour bar included. :class:`PanelGrid` places the report figures' equal panels
(reflector chips, trajectory errors) on fixed margins the same way.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from autosar_cli.store.atomic import atomic_output
from autosar_cli.types import FocusGrid

#: figure margins (inches): tick labels and axis label on the left and bottom, colour bar on the right, title
LEFT_IN, RIGHT_IN, BOTTOM_IN, TOP_IN = 0.7, 1.0, 0.5, 0.35
#: gaps between tiles (inches): each tile carries its own tick labels; a panel title adds PANEL_TITLE_IN
GAP_X_IN, GAP_Y_IN, PANEL_TITLE_IN = 0.5, 0.45, 0.25
#: the block of tiles fits in this box (inches) at most
MAX_WIDTH_IN, MAX_HEIGHT_IN = 10.0, 7.5
MAX_TILES = 6


@dataclass(frozen=True)
class TileLayout:
    """How n images of ``shape`` (rows, cols) pixels are cut and placed on a figure."""

    shape: tuple[int, int]  #: (rows, cols) of each image (pixels of the drawn array)
    tiles: int  #: pieces per image
    tall: bool  #: True: rows are cut and the pieces stand side by side; False: columns cut, pieces stacked
    panel_rows: int
    panel_cols: int
    inch_per_px: float
    titled: bool  #: every panel has a title line above it

    @property
    def tile_px(self) -> tuple[int, int]:
        """(rows, cols) of a full tile."""
        rows, cols = self.shape
        return (-(-rows // self.tiles), cols) if self.tall else (rows, -(-cols // self.tiles))

    @property
    def grid_px(self) -> tuple[int, int]:
        """Tiles in the figure as (rows, cols)."""
        per_r, per_c = (1, self.tiles) if self.tall else (self.tiles, 1)
        return self.panel_rows * per_r, self.panel_cols * per_c

    @property
    def figure_in(self) -> tuple[float, float]:
        """Figure (width, height) in inches."""
        (th, tw), (gr, gc) = self.tile_px, self.grid_px
        title = PANEL_TITLE_IN * self.panel_rows if self.titled else 0.0
        w = LEFT_IN + gc * tw * self.inch_per_px + (gc - 1) * GAP_X_IN + RIGHT_IN
        h = BOTTOM_IN + gr * th * self.inch_per_px + (gr - 1) * GAP_Y_IN + title + TOP_IN
        return max(w, 4.0), h

    def image_fraction(self, n_images: int) -> float:
        """Share of the figure's area that the image pixels cover."""
        w, h = self.figure_in
        return n_images * self.shape[0] * self.shape[1] * self.inch_per_px**2 / (w * h)

    def tiles_of(self, panel: int) -> list[tuple[slice, slice, tuple[float, float, float, float]]]:
        """Panel ``panel``'s tiles: (rows, cols) of the image each shows, and its axes rectangle as a figure
        fraction (left, bottom, width, height)."""
        rows, cols = self.shape
        th, tw = self.tile_px
        fig_w, fig_h = self.figure_in
        s = self.inch_per_px
        title = PANEL_TITLE_IN if self.titled else 0.0
        prow, pcol = divmod(panel, self.panel_cols)
        out = []
        for j in range(self.tiles):
            if self.tall:
                r = slice(j * th, min(rows, (j + 1) * th))
                c = slice(0, cols)
                gx, gy = pcol * self.tiles + j, prow
            else:
                r = slice(0, rows)
                c = slice(j * tw, min(cols, (j + 1) * tw))
                gx, gy = pcol, prow * self.tiles + j
            n_title = prow + 1 if self.titled else 0  # title lines above this tile's grid row and it
            top = TOP_IN + gy * (th * s + GAP_Y_IN) + n_title * title
            left = LEFT_IN + gx * (tw * s + GAP_X_IN)
            w, h = (c.stop - c.start) * s, (r.stop - r.start) * s
            bottom = fig_h - top - th * s  # a short last tile sits on its row's baseline
            out.append((r, c, (left / fig_w, bottom / fig_h, w / fig_w, h / fig_h)))
        return out


def agg_figure(figsize_in: tuple[float, float], dpi: float) -> Any:
    """A matplotlib Figure of ``figsize_in`` (width, height) inches on an Agg canvas; no pyplot state is touched."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize_in, dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def save_png(fig: Any, path: str | Path) -> Path:
    """Write ``fig`` as a PNG at its own dpi, atomically (a partial file, then renamed); returns the path."""
    path = Path(path)
    with atomic_output(path, overwrite=True) as tmp:
        fig.savefig(tmp, format="png", dpi=fig.dpi)
    return path


@dataclass(frozen=True)
class PanelGrid:
    """``n_rows`` x ``n_cols`` equal panels of ``panel_in`` (width, height) inches, with fixed margins and gaps
    (inches) that hold the tick labels, axis labels and titles. What matplotlib's constrained layout finds,
    without measuring every tick label first: a 4 x 5 panel figure drew in half the time."""

    n_rows: int
    n_cols: int
    panel_in: tuple[float, float]
    left_in: float = 0.75
    right_in: float = 0.25
    bottom_in: float = 0.55
    top_in: float = 0.35
    gap_x_in: float = 0.9
    gap_y_in: float = 0.75

    @property
    def figure_in(self) -> tuple[float, float]:
        """Figure (width, height) in inches."""
        w, h = self.panel_in
        return (self.left_in + self.n_cols * w + (self.n_cols - 1) * self.gap_x_in + self.right_in,
                self.bottom_in + self.n_rows * h + (self.n_rows - 1) * self.gap_y_in + self.top_in)

    def rect(self, row: int, col: int) -> tuple[float, float, float, float]:
        """Panel (row, col)'s axes (left, bottom, width, height) as figure fractions; row 0 on top."""
        fig_w, fig_h = self.figure_in
        w, h = self.panel_in
        left = self.left_in + col * (w + self.gap_x_in)
        bottom = fig_h - self.top_in - (row + 1) * h - row * self.gap_y_in
        return left / fig_w, bottom / fig_h, w / fig_w, h / fig_h

    def right_strip(self, width_in: float, pad_in: float = 0.15) -> tuple[float, float, float, float]:
        """A strip ``width_in`` wide in the right margin, ``pad_in`` from the panels, as tall as they are (a
        colour bar's axes)."""
        fig_w, fig_h = self.figure_in
        left = fig_w - self.right_in + pad_in
        return left / fig_w, self.bottom_in / fig_h, width_in / fig_w, 1.0 - (self.bottom_in + self.top_in) / fig_h

    def figure(self, dpi: float = 90) -> tuple[Any, NDArray[np.object_]]:
        """An :func:`agg_figure` of this size and its axes (n_rows, n_cols)."""
        fig = agg_figure(self.figure_in, dpi)
        axes = np.empty((self.n_rows, self.n_cols), dtype=object)
        for i in range(self.n_rows):
            for j in range(self.n_cols):
                axes[i, j] = fig.add_axes(self.rect(i, j))
        return fig, axes


def tile_layout(shape: tuple[int, int], n_images: int = 1, *, titled: bool = False) -> TileLayout:
    """The tiling and panel grid (panels fill row by row) that give ``n_images`` images of ``shape`` (rows,
    cols; equal square pixels) the largest share of a figure no larger than MAX_WIDTH_IN x MAX_HEIGHT_IN
    of image; fewer tiles win near-ties (2 % of the figure per extra tile)."""
    rows, cols = shape
    best: tuple[float, TileLayout] | None = None
    for panel_cols in range(1, n_images + 1):
        panel_rows = -(-n_images // panel_cols)
        for tiles in range(1, MAX_TILES + 1):
            for tall in (True, False):
                if tiles == 1 and tall:
                    continue
                probe = TileLayout(shape, tiles, tall, panel_rows, panel_cols, 1.0, titled)
                (th, tw), (gr, gc) = probe.tile_px, probe.grid_px
                title = PANEL_TITLE_IN * panel_rows if titled else 0.0
                scale = min((MAX_WIDTH_IN - (gc - 1) * GAP_X_IN) / (gc * tw),
                            (MAX_HEIGHT_IN - (gr - 1) * GAP_Y_IN - title) / (gr * th))
                if scale <= 0:
                    continue
                layout = TileLayout(shape, tiles, tall, panel_rows, panel_cols, scale, titled)
                score = layout.image_fraction(n_images) - 0.02 * (tiles - 1)
                if best is None or score > best[0] + 1e-12:
                    best = (score, layout)
    assert best is not None, f"no layout for an image of {rows} x {cols} px"
    return best[1]


def _nice_length(x: float) -> float:
    """The 1-2-5 x 10^k value nearest ``x`` (> 0) on a log scale."""
    k = math.floor(math.log10(x))
    return min((m * 10.0**k for m in (1, 2, 5, 10)), key=lambda v: abs(math.log(v / x)))


def draw_tiled(fig: Any, layout: TileLayout, images: Sequence[tuple[str, NDArray[np.float32]]], pixel_m: float, *,
               vmin: float, cmap: Any, colorbar_label: str, title: str = "", pool: int = 1) -> list[Any]:
    """Draw dB images (rows, cols; row 0 at the bottom) on ``fig`` as ``layout`` places them, one colour scale
    [vmin, 0] and one colour bar; axes in metres from the image's pixel (0, 0)'s centre (``pixel_m`` per image
    pixel). ``pool``: each array cell (k, l) holds the image pixels k*pool ... k*pool + pool - 1 (and the same in
    columns), so it is drawn from pixel k*pool's outer edge to pixel (k + 1)*pool - 1's, centred on their centre.
    Returns every tile's axes (panel by panel)."""
    axes = []
    im = None
    for p, (label, db) in enumerate(images):
        for j, (r, c, rect) in enumerate(layout.tiles_of(p)):
            ax = fig.add_axes(rect)
            extent = ((c.start * pool - 0.5) * pixel_m, (c.stop * pool - 0.5) * pixel_m,
                      (r.start * pool - 0.5) * pixel_m, (r.stop * pool - 0.5) * pixel_m)
            # at most ~one image pixel per screen pixel (the quicklook is max-pooled first): drawn as is
            im = ax.imshow(db[r, c], origin="lower", extent=extent, cmap=cmap, vmin=vmin, vmax=0.0,
                           interpolation="nearest", aspect="auto")  # the rectangle already has the image's aspect
            ax.tick_params(labelsize=7)
            if layout.tall or j == layout.tiles - 1:
                ax.set_xlabel("along (m)", fontsize=8)
            if not layout.tall or j == 0:
                ax.set_ylabel("across (m)", fontsize=8)
            if j == 0 and label:
                ax.set_title(label, fontsize=9, loc="left")
            axes.append(ax)
    fig_w, fig_h = layout.figure_in
    block_top = 1.0 - (TOP_IN + (PANEL_TITLE_IN if layout.titled else 0.0)) / fig_h
    cax = fig.add_axes((1.0 - (RIGHT_IN - 0.15) / fig_w, BOTTOM_IN / fig_h, 0.15 / fig_w,
                        block_top - BOTTOM_IN / fig_h))
    fig.colorbar(im, cax=cax, label=colorbar_label)
    if title:
        fig.text(LEFT_IN / fig_w, 1.0 - 0.08 / fig_h, title, fontsize=9, va="top")
    return axes


def draw_quicklook(path: Path, pooled_db: NDArray[np.float32], pool: int, g: FocusGrid, *,
                   dynamic_range_db: float = 50.0) -> TileLayout:
    """PNG quicklook of the max-pooled (``pool`` x ``pool`` pixels) absolute dB image ``pooled_db`` of grid
    ``g``: dB relative to the image peak, clipped to [-dynamic_range_db, 0], tiled by :func:`tile_layout`.

    x: along-track metres from pixel (0, 0)'s centre, y: across metres, increasing upwards, so row 0 (near
    range for the automatic grid) is at the bottom. Exact zeros (-inf) show as the floor, pixels with no
    finite value blank. A scale bar (metres), a dB colour bar and a north arrow (the grid may be rotated
    and mirrored relative to a map) are drawn on the first tile. No pyplot state is touched.
    """
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    rows, cols = g.shape
    finite = np.isfinite(pooled_db)
    peak = float(pooled_db[finite].max()) if finite.any() else 0.0
    rel = np.clip(pooled_db - np.float32(peak), -dynamic_range_db, 0.0)
    layout = tile_layout(rel.shape)
    fig = agg_figure(layout.figure_in, 150)
    title = f"peak {peak:.1f} dB, {rows} x {cols} px at {g.pixel_m * 100:g} cm"
    if layout.tiles > 1:
        title += f", in {layout.tiles} tiles"
    ax = draw_tiled(fig, layout, [("", rel)], g.pixel_m, vmin=-dynamic_range_db, cmap="gray",
                    colorbar_label="dB (rel. peak)", title=title, pool=pool)[0]
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    width_m, height_m = x1 - x0, y1 - y0
    length = _nice_length(width_m / 4.0)
    label = f"{length:g} m" if length >= 1 else f"{length * 100:g} cm"
    ax.add_artist(AnchoredSizeBar(ax.transData, length, label, loc="lower right", color="yellow", frameon=False,
                                  size_vertical=min(width_m, height_m) / 150.0, pad=0.5, sep=4))
    north = np.array([g.along[1], g.across[1]])  # ENU north in the (along, across) plot axes
    if np.hypot(*north) > 1e-9:
        n = 24.0 * north / np.hypot(*north)  # arrow length in points (isotropic, unlike axes fraction)
        ax.annotate("N", xy=(0.12, 0.88), xycoords="axes fraction", xytext=(n[0], n[1]), textcoords="offset points",
                    color="yellow", fontsize=8, ha="center", va="center",
                    arrowprops={"arrowstyle": "<-", "color": "yellow", "shrinkA": 4, "shrinkB": 0})
    fig.savefig(path, format="png", pil_kwargs={"compress_level": 1})
    return layout


def preload_quicklook() -> None:
    """Import what the quicklook draws with (matplotlib: ~0.5 s), e.g. in a thread while focusing runs."""
    import matplotlib.backends.backend_agg  # noqa: F401
    import matplotlib.figure  # noqa: F401
    import mpl_toolkits.axes_grid1.anchored_artists  # noqa: F401
