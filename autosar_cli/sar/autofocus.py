"""What the radar can measure that the navigation sensors cannot: the track's along-track scale.

SAR-MIN's speed scale comes from GNSS velocity (3 cm/s of white noise at 10 Hz pins 25 s of driving to
~0.04 %, docs/EVALUATION.md "test2: the odometry's scale"). A speed error eps leaves a range error of about
``x^2 eps / R`` at along-track offset x of an aperture: nothing over the product's narrow processed beam, but a
large fraction of a wavelength at the edge of a wide one (±28 deg at 9 m: ~lambda/4 for eps = 0.09 %). So the
peaks of bright point scatterers focused with a wide beam are sharpest when the track is scaled right.

:func:`estimate_track_scale` sweeps the scale, focuses a small patch around each given point with a wide beam
for each scale, and fits the optimum of the summed peaks. The points must be isolated point-like scatterers
(e.g. corner reflectors); finding them without help is not done here.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from autosar_cli.config import Config
from autosar_cli.nav.trajectory import Trajectory
from autosar_cli.sar.focus import FocusOptions, focus_images
from autosar_cli.sar.grid import box_grid

Array = NDArray[np.float64]

#: Scales tried by default: -0.30 % to +0.30 % in 0.03 % steps (GNSS leaves ~0.04 % 1 sigma on a 25 s drive).
DEFAULT_SCALES = np.arange(-30, 31, 3) * 1e-4


def scale_track(trajectory: Trajectory, scale: float, centre_xy: ArrayLike | None = None) -> Trajectory:
    """``trajectory`` with its distances multiplied by ``1 + scale``: rear-axle positions (ENU m) about
    ``centre_xy`` (default: their mean) and speeds; headings and yaw rates unchanged (the same path shape,
    driven ``1 + scale`` times faster). Filter states and covariances are dropped (they no longer match)."""
    xy = trajectory.rear_axle_enu
    c = xy.mean(axis=0) if centre_xy is None else np.asarray(centre_xy, dtype=np.float64)
    return replace(trajectory, rear_axle_enu=c + (1.0 + scale) * (xy - c), speed=trajectory.speed * (1.0 + scale),
                   state=None, covariance=None)


@dataclass(frozen=True)
class TrackScaleEstimate:
    """Result of :func:`estimate_track_scale`."""

    scale: float  #: the optimum of the summed peaks (dimensionless; multiply distances by 1 + scale)
    point_scales: Array  #: (P,) the optimum of each point's own peak
    scales: Array  #: (S,) the scales tried
    peaks_db: Array  #: (S, P) each point's peak (dB of |z|) per scale tried


def _parabola_peak(x: Array, y: Array) -> float:
    """Abscissa of the vertex of a parabola through the five samples around the largest ``y`` (the largest
    sample's abscissa if the fit is not concave)."""
    k = int(np.argmax(y))
    lo, hi = max(0, k - 2), min(len(x), k + 3)
    if hi - lo < 3:
        return float(x[k])
    a, b, _ = np.polyfit(x[lo:hi], y[lo:hi], 2)
    return float(-b / (2.0 * a)) if a < 0 else float(x[k])


def estimate_track_scale(drive_path: str | Path, trajectory: Trajectory, config: Config, points_xy: ArrayLike, *,
                         scales: ArrayLike = DEFAULT_SCALES, resolution_m: float = 0.002,
                         patch_m: float = 0.06, pixel_m: float = 0.001) -> TrackScaleEstimate:
    """Along-track scale of ``trajectory`` that focuses the point scatterers at ``points_xy`` (P, 2; ENU m, where
    the unscaled trajectory images them) best.

    For each of ``scales`` the track is scaled about its mean position (:func:`scale_track`) and each point is
    focused on a ``patch_m`` square of ``pixel_m`` pixels centred where the scaled track puts it, with a processed
    beam of half-width lambda / (4 ``resolution_m``) (2 mm: ±28 deg). The estimate is the vertex of a parabola
    through the summed peaks (dB) around their largest; each point's own optimum is returned too. One focusing
    pass per scale (each reads and range-compresses the frames that see the points).
    """
    pts = np.atleast_2d(np.asarray(points_xy, dtype=np.float64))[:, :2]
    s_grid = np.asarray(scales, dtype=np.float64)
    if pts.size == 0 or s_grid.size < 3:
        raise ValueError("estimate_track_scale: need at least one point and three scales")
    centre = trajectory.rear_axle_enu.mean(axis=0)
    options = FocusOptions.from_config(config, resolution_m=resolution_m, pixel_m=pixel_m)
    h = 0.5 * patch_m
    peaks = np.empty((s_grid.size, len(pts)))
    for i, s in enumerate(s_grid):
        moved = centre + (1.0 + s) * (pts - centre)
        grids = [box_grid(x - h, y - h, x + h, y + h, pixel_m=pixel_m, height_m=options.height_m) for x, y in moved]
        images = focus_images(drive_path, scale_track(trajectory, float(s), centre), config, options,
                              grids=grids).images
        peaks[i] = [np.abs(im.image).max() for im in images]
    peaks_db = 20.0 * np.log10(np.maximum(peaks, np.finfo(np.float64).tiny))
    per_point = np.array([_parabola_peak(s_grid, peaks_db[:, j]) for j in range(len(pts))])
    return TrackScaleEstimate(_parabola_peak(s_grid, peaks_db.sum(axis=1)), per_point, s_grid, peaks_db)
