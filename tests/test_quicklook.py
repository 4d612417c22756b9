"""The image fills its figures: the PNG quicklook of the ci and test1 drives, and compare's panels."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from autosar_cli.config import load_config
from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.nav.trajectory import antenna_lever_arms
from autosar_cli.sar.focus import FocusOptions
from autosar_cli.sar.grid import FocusGrid, track_grid
from autosar_cli.sim.scenario import build_scenario
from autosar_cli.store.image import FocusedImage, write_image
from autosar_cli.store.quicklook import PanelGrid, tile_layout

ORIGIN = GeodeticOrigin(45.06, 7.66, 240.0)
PARAMS = {"method": "backprojection", "pixel_m": 0.04}


def drive_grid(scenario: str) -> FocusGrid:
    """The automatic focus grid along the scenario's true radar track (no focusing needed for its shape)."""
    config = load_config()
    options = FocusOptions.from_config(config)
    motion = build_scenario(scenario, config).motion
    track = motion.point(np.linspace(0.0, motion.duration_s, 400), antenna_lever_arms(config)[0][0]).position
    side = 1.0 if math.sin(math.radians(config.radar.mounting.yaw_deg)) > 0 else -1.0
    return track_grid(track[:, :2], side=side, pixel_m=options.pixel_m, height_m=options.height_m,
                      antenna_height_m=float(track[:, 2].mean()), max_range_m=config.radar.max_range_m)


@pytest.mark.parametrize(("scenario", "shape_like"), [("ci", "tall"), ("test1", "wide")])
def test_quicklook_image_fills_half_the_figure(scenario: str, shape_like: str, tmp_path: Path) -> None:
    grid = drive_grid(scenario)
    rows, cols = grid.shape
    assert (rows > 5 * cols) if shape_like == "tall" else (cols > rows)  # ci: ~11:1, test1: ~1:2
    # every pixel at -25 dB below one peak pixel: mid grey (0.5 of the 50 dB scale) wherever the image is drawn
    image = np.full(grid.shape, 10 ** (-25 / 20), np.complex64)
    image[rows // 2, cols // 2] = 1.0
    png = write_image(tmp_path / "scene", FocusedImage(image, grid, ORIGIN, PARAMS))["png"]
    pixels = np.asarray(Image.open(png).convert("RGB")).astype(int)
    grey = np.all(np.abs(pixels - 128) <= 1, axis=-1)  # the image; labels, ticks, colour bar are other colours
    filled = grey.mean()
    assert filled >= 0.5, f"{scenario}: image covers {filled:.0%} of the quicklook"
    # the layout's own account of its coverage is what the PNG shows
    assert tile_layout(grid.shape).image_fraction(1) == pytest.approx(filled, abs=0.03)


def test_layout_tiles_long_and_tall_images() -> None:
    tall = tile_layout((663, 61))  # ci: range across 26 m, 2.4 m of travel
    assert tall.tall and tall.tiles >= 2
    strip = tile_layout((700, 3000))  # test2: 120 m of travel
    assert not strip.tall and strip.tiles >= 2
    assert tile_layout((600, 1200)).tiles == 1  # test1 fits in one piece
    for layout in (tall, strip):
        covered = {(r, c) for p in range(1) for rs, cs, _ in layout.tiles_of(p)
                   for r in (rs.start, rs.stop - 1) for c in (cs.start, cs.stop - 1)}
        assert (0, 0) in covered and (layout.shape[0] - 1, layout.shape[1] - 1) in covered
        pieces = layout.tiles_of(0)
        assert sum((r.stop - r.start) * (c.stop - c.start) for r, c, _ in pieces) == layout.shape[0] * layout.shape[1]
        rects = [rect for _, _, rect in pieces]
        assert all(0.0 <= x and 0.0 <= y and x + w <= 1.0 and y + h <= 1.0 for x, y, w, h in rects)


def test_compare_panels_fill_the_figure() -> None:
    for shape in ((663, 61), (666, 1251), (709, 3000)):  # ci, test1, test2
        assert tile_layout(shape, 4, titled=True).image_fraction(4) >= 0.44, shape


def test_panel_grid_places_equal_panels_on_its_margins() -> None:
    """PanelGrid (the report figures' layout): every panel its size in inches, the gaps and margins as asked, row
    0 on top, the colour bar's strip right of the panels; the figure draws them in that place."""
    g = PanelGrid(2, 3, (2.0, 1.5), left_in=0.8, right_in=1.0, bottom_in=0.5, top_in=0.3, gap_x_in=0.4, gap_y_in=0.6)
    w, h = g.figure_in
    assert (w, h) == pytest.approx((0.8 + 3 * 2.0 + 2 * 0.4 + 1.0, 0.5 + 2 * 1.5 + 0.6 + 0.3))
    inches = {(i, j): np.multiply(g.rect(i, j), (w, h, w, h)) for i in range(2) for j in range(3)}
    assert inches[0, 0] == pytest.approx((0.8, 0.5 + 1.5 + 0.6, 2.0, 1.5))  # top left
    assert inches[1, 2] == pytest.approx((0.8 + 2 * 2.4, 0.5, 2.0, 1.5))  # bottom right
    strip = np.multiply(g.right_strip(0.15, pad_in=0.2), (w, h, w, h))
    assert strip == pytest.approx((w - 1.0 + 0.2, 0.5, 0.15, h - 0.8))
    fig, axes = g.figure(dpi=100)
    assert axes.shape == (2, 3) and tuple(fig.get_size_inches()) == pytest.approx((w, h))
    box = axes[1, 2].get_position().bounds
    assert box == pytest.approx(g.rect(1, 2))


@pytest.mark.parametrize(("shape", "pool"), [((64, 3000), 3), ((64, 1000), 1)])
def test_quicklook_axes_put_a_pooled_pixel_at_its_pixels_metres(shape: tuple[int, int], pool: int, tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """The quicklook max-pools pool x pool pixels into one drawn cell: the cell holding pixels k*pool ...
    k*pool + pool - 1 is drawn centred on their centre, ((k + 1/2) pool - 1/2) pixels from pixel (0, 0)'s, on the
    metre axes. A bright pixel in the middle of its cell (3000 columns at 4 cm pool by 3) sits on the axes at its own
    along and across metres, 60.04 m and 1.24 m (drawn at k pool pixels, 60.00 m and 1.20 m, it was (pool - 1) / 2
    pixels, 4 cm, towards pixel (0, 0): 28 cm on a 800 m drive's quicklook, pooled by 15)."""
    from autosar_cli.store import quicklook

    figures = []

    def keep(*args: object) -> object:
        figures.append(fig := real(*args))
        return fig

    real = quicklook.agg_figure
    monkeypatch.setattr(quicklook, "agg_figure", keep)
    grid = FocusGrid((0.0, 0.0), (1.0, 0.0), (0.0, -1.0), 0.04, shape[1], shape[0], 0.0)
    image = np.full(grid.shape, 1e-3, np.complex64)
    row, col = 31, 1501 if pool == 3 else 501  # the middle pixel of its 3 x 3 cell (pool 3)
    image[row, col] = 1.0
    write_image(tmp_path / "scene", FocusedImage(image, grid, ORIGIN, PARAMS))
    (fig,) = figures
    drawn = [(im.get_extent(), im.get_array()) for ax in fig.axes for im in ax.get_images()]
    assert sum(a.shape[1] for _, a in drawn) == -(-shape[1] // pool)  # the tiles side by side, pool x pool cells
    centres = []
    for (x0, x1, y0, y1), cells in drawn:
        i, j = np.nonzero(np.asarray(cells) == 0.0)  # the peak: 0 dB rel. peak (row 0 at the bottom, origin lower)
        centres += [(x0 + (jj + 0.5) * (x1 - x0) / cells.shape[1], y0 + (ii + 0.5) * (y1 - y0) / cells.shape[0])
                    for ii, jj in zip(i, j, strict=True)]
    (x, y), = centres
    assert x == pytest.approx(col * 0.04, abs=1e-6) and y == pytest.approx(row * 0.04, abs=1e-6), (x, y)
