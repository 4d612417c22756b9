"""Focus quality of a whole image: entropy, contrast, and the straightness of known straight lines.

Entropy and contrast need no truth (a sharper image concentrates its energy in fewer pixels: lower
entropy, higher contrast); they are computed over the pixels that received pulses (|z| > 0). The
straightness of a line the scene knows to be straight (a facade, a kerb) shows the across-track motion
errors that the navigation left in the image (paper Fig. 10: the facade "follows the lateral motion").
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from autosar_cli.store.image import FocusedImage

Array = NDArray[np.float64]


def data_mask(image: NDArray[np.complexfloating[Any, Any]]) -> NDArray[np.bool_]:
    """Pixels that received pulses (a pixel no processed beam reached stays exactly 0)."""
    return np.abs(image) > 0


def _intensity(image: NDArray[Any], mask: NDArray[np.bool_] | None) -> Array:
    z = np.asarray(image)
    if mask is None:
        mask = data_mask(z) if np.iscomplexobj(z) else np.ones(z.shape, bool)
    return (np.abs(z[mask]).astype(np.float64)) ** 2 if np.iscomplexobj(z) else np.asarray(z[mask], np.float64)


def image_entropy(image: NDArray[Any], mask: NDArray[np.bool_] | None = None) -> float:
    """Shannon entropy (nats) of the normalised intensity: H = -sum p ln p, p = |z|^2 / sum |z|^2.

    ``image``: complex (intensity |z|^2) or real (taken as intensity). Over ``mask`` (default: the pixels
    with data). A uniform image of N pixels gives ln N; a single bright pixel gives 0.
    """
    i = _intensity(image, mask)
    total = i.sum()
    if total <= 0:
        return math.nan
    p = i[i > 0] / total
    return float(-np.sum(p * np.log(p)))


def image_contrast(image: NDArray[Any], mask: NDArray[np.bool_] | None = None) -> float:
    """Contrast std(I) / mean(I) of the intensity I = |z|^2 (dimensionless) over ``mask`` (default: data pixels)."""
    i = _intensity(image, mask)
    m = i.mean() if i.size else 0.0
    return float(i.std() / m) if m > 0 else math.nan


@dataclass(frozen=True)
class LineFit:
    """Weighted total-least-squares line through points (ENU m)."""

    centre: tuple[float, float]
    direction: tuple[float, float]  #: unit vector along the line
    rms_residual_m: float  #: weighted RMS perpendicular distance of the points to the line
    n_points: int


def fit_line(xy: ArrayLike, weights: ArrayLike | None = None) -> LineFit:
    """Fit a straight line to points (N, 2) minimising the weighted sum of squared perpendicular distances."""
    p = np.asarray(xy, dtype=np.float64)[:, :2]
    if len(p) < 2:
        raise ValueError("fit_line: need at least two points")
    w = np.ones(len(p)) if weights is None else np.asarray(weights, dtype=np.float64)
    w = w / w.sum()
    c = w @ p
    d = p - c
    cov = (d * w[:, None]).T @ d
    vals, vecs = np.linalg.eigh(cov)
    u = vecs[:, 1]  # largest eigenvalue: direction of the line
    n = np.array([-u[1], u[0]])
    resid = d @ n
    return LineFit((float(c[0]), float(c[1])), (float(u[0]), float(u[1])), float(np.sqrt(np.sum(w * resid**2))),
                   len(p))


@dataclass(frozen=True)
class Straightness:
    """How straight a known straight line of the scene appears in the image."""

    name: str  #: e.g. "facade", "kerb"
    rms_residual_m: float  #: RMS perpendicular residual of the traced line about its best straight fit
    n_columns: int  #: image columns that contributed a point (after outlier rejection)
    length_m: float  #: extent of the traced points along the line
    offset_m: float  #: intensity-weighted mean distance from the expected line (m, + = left of the along axis)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def trace_line(img: FocusedImage, line_xy: ArrayLike, *, half_width_m: float = 0.3,
               min_columns: int = 5) -> tuple[Array, Array, Array]:
    """Trace a straight scene line in the image: for every image column crossing the expected line, the
    brightest data pixel within ``half_width_m`` (perpendicular) of it.

    ``line_xy``: (N, 2+) points of the expected line (ENU m in the image's frame, e.g. the truth scatterers
    mapped by the alignment); the line is their least-squares fit, limited to their extent. Returns the
    traced pixel positions (K, 2) (ENU m), their intensities |z|^2 (K,), and their signed distances to the
    expected line (K,) (m, positive to the left of the grid's along axis). K = 0 when fewer than
    ``min_columns`` columns cross it.
    """
    pts = np.asarray(line_xy, dtype=np.float64)[:, :2]
    fit = fit_line(pts)
    grid = img.grid
    c, u = np.asarray(fit.centre), np.asarray(fit.direction)
    if u @ np.asarray(grid.along) < 0:
        u = -u
    n = np.array([-u[1], u[0]])  # left of the image's along axis
    s = (pts - c) @ u
    s0, s1 = s.min(), s.max()
    # pixel (r, c) lies at origin + (c along + r across) pixel: distances to the line are separable sums
    o = np.asarray(grid.origin) - c
    rows_i, cols_i = np.arange(grid.n_across), np.arange(grid.n_along)
    along, across = np.asarray(grid.along) * grid.pixel_m, np.asarray(grid.across) * grid.pixel_m
    d_perp = (o @ n + rows_i * (across @ n))[:, None] + (cols_i * (along @ n))[None, :]
    d_along = (o @ u + rows_i * (across @ u))[:, None] + (cols_i * (along @ u))[None, :]
    inten = np.abs(img.image).astype(np.float64) ** 2
    score = np.where((np.abs(d_perp) <= half_width_m) & (d_along >= s0) & (d_along <= s1), inten, -1.0)
    del d_along
    rows = np.argmax(score, axis=0)
    has = score[rows, cols_i] > 0
    if has.sum() < min_columns:
        return np.zeros((0, 2)), np.zeros(0), np.zeros(0)
    rows, cols = rows[has], cols_i[has]
    return grid.pixel_enu(rows, cols)[:, :2], inten[rows, cols], d_perp[rows, cols]


def line_straightness(img: FocusedImage, line_xy: ArrayLike, name: str, *, half_width_m: float = 0.3,
                      reject_sigma: float = 3.0) -> Straightness:
    """Straightness of the scene line through ``line_xy`` (see :func:`trace_line`): RMS perpendicular residual
    (intensity weighted) of the traced points about their own intensity-weighted straight fit (m); NaN if the
    line is not seen.

    Columns where something else is brighter than the line inside the +-``half_width_m`` band (the end of a
    parked car crossing the kerb line, or clutter in the gaps between a kerb's scatterers) give outliers:
    points farther than ``reject_sigma`` robust standard deviations (1.4826 x the median absolute deviation
    of the residuals, unweighted: the outliers are few but often bright; at least half a pixel) from their
    median are dropped and the line refitted, up to five times. ``n_columns`` counts the points kept.
    """
    xy, inten, dist = trace_line(img, line_xy, half_width_m=half_width_m)
    if len(xy) < 2:
        return Straightness(name, math.nan, int(len(xy)), 0.0, math.nan)
    keep = np.ones(len(xy), bool)
    for _ in range(5):
        fit = fit_line(xy[keep], inten[keep])
        u = np.asarray(fit.direction)
        resid = (xy - np.asarray(fit.centre)) @ np.array([-u[1], u[0]])
        centre = float(np.median(resid[keep]))
        sigma = 1.4826 * float(np.median(np.abs(resid[keep] - centre)))
        new = np.abs(resid - centre) <= max(reject_sigma * sigma, 0.5 * img.grid.pixel_m)
        if new.sum() < 2 or np.array_equal(new, keep):
            break
        keep = new
    fit = fit_line(xy[keep], inten[keep])
    s = (xy[keep] - np.asarray(fit.centre)) @ np.asarray(fit.direction)
    w = inten[keep] / inten[keep].sum()
    return Straightness(name, fit.rms_residual_m, int(keep.sum()), float(s.max() - s.min()),
                        float(np.sum(w * dist[keep])))
