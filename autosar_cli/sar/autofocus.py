"""What the radar can measure that the navigation sensors cannot: the track's along-track scale.

SAR-MIN's speed scale comes from GNSS velocity (3 cm/s of white noise at 10 Hz pins 25 s of driving to
~0.04 %, docs/EVALUATION.md, "Decisions"). A speed error eps leaves a range error of about
``x^2 eps / R`` at along-track offset x of an aperture: nothing over the product's narrow processed beam, but a
large fraction of a wavelength at the edge of a wide one (±28 deg at 9 m: ~lambda/4 for eps = 0.09 %). So the
peaks of bright point scatterers focused with a wide beam are sharpest when the track is scaled right.

:func:`estimate_track_scale` sweeps the scale, focuses a small patch around each given point with a wide beam
for each scale, and fits the optimum of the summed sharpness (:func:`point_sharpness`). The points must be
isolated point-like scatterers: here the corner reflectors of a simulated drive's truth (compare's
``sar-min+scale``). The truth-free autofocus, which measures the scale together with the residual motion from the
phase histories of a first image's bright points, is :mod:`autosar_cli.sar.residual_motion`.

Why sharpness and not the peak: the scale moves each point's response by ``scale`` times its distance from
the track's centre (13 mm per 0.03 % at 45 m), so the patch's pixels sample it at a different sub-pixel
offset for every scale tried, and the highest pixel of a 2 mm response on 1 mm pixels varies by up to ~1 dB
with that offset: as much as the defocus being measured. With the peak, the truth's own track on test2
(seed 1) came out at −0.020 … +0.054 % depending on the beam and the sweep's steps; with the sharpness at
−0.003 … −0.001 % (each reflector within ±0.009 %).
"""

from __future__ import annotations

import math
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
    driven ``1 + scale`` times faster). Filter states and covariances are dropped (a trial scale; the one applied
    carries them: :func:`scaled_filter`)."""
    xy = trajectory.rear_axle_enu
    c = xy.mean(axis=0) if centre_xy is None else np.asarray(centre_xy, dtype=np.float64)
    return replace(trajectory, rear_axle_enu=c + (1.0 + scale) * (xy - c), speed=trajectory.speed * (1.0 + scale),
                   state=None, covariance=None)


def scaled_filter(trajectory: Trajectory, scale: float, centre_xy: ArrayLike, scale_std: float
                  ) -> tuple[Array | None, Array | None]:
    """The filter's state (K, n) and covariance (K, n, n) of ``trajectory`` scaled as :func:`scale_track` scales it
    about ``centre_xy`` (ENU m), the scale applied with its 1-sigma ``scale_std``: J x and, to first order,
    J P J^T + scale_std^2 g g^T, where J scales the rear axle's position (px, py) and the speed (v) by ``1 + scale``
    and g is their derivative by the scale. None where there is nothing to carry."""
    names = trajectory.state_names
    centre_xy = np.asarray(centre_xy, dtype=np.float64)
    if trajectory.state is None or not {"px", "py", "v"} <= set(names):
        return None, None
    i = [names.index("px"), names.index("py"), names.index("v")]
    state = trajectory.state.copy()
    gradient = np.column_stack([state[:, i[:2]] - centre_xy, state[:, i[2]]])  # (K, 3): d(px, py, v) / d scale
    state[:, i] += scale * gradient
    if trajectory.covariance is None:
        return state, None
    covariance = trajectory.covariance.copy()
    covariance[:, i, :] *= 1.0 + scale
    covariance[:, :, i] *= 1.0 + scale
    rows, cols = np.ix_(i, i)
    covariance[:, rows, cols] += scale_std**2 * gradient[:, :, None] * gradient[:, None, :]
    return state, covariance


@dataclass(frozen=True)
class TrackScaleEstimate:
    """Result of :func:`estimate_track_scale`."""

    scale: float  #: the optimum of the summed sharpness (dimensionless; multiply distances by 1 + scale)
    point_scales: Array  #: (P,) the optimum of each point's own sharpness
    scales: Array  #: (S,) the scales tried
    sharpness_db: Array  #: (S, P) each point's :func:`point_sharpness` (dB of |z|) per scale tried


def point_sharpness(patch: ArrayLike) -> float:
    """``sqrt(sum |z|^4 / sum |z|^2)`` of a complex image patch (same unit as |z|): the amplitude of its
    response weighted by intensity. It is the peak amplitude for a response confined to one pixel, falls as a
    response spreads, and, unlike the highest pixel, hardly depends on where the response falls between
    pixels once the pixels sample its intensity (pixel <= resolution / 2)."""
    p = np.abs(np.asarray(patch).astype(np.complex128)) ** 2
    energy = float(p.sum())
    return math.sqrt(float(np.sum(p * p)) / energy) if energy > 0.0 else 0.0


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
    through the summed sharpness (dB, :func:`point_sharpness`) around its largest; each point's own optimum is
    returned too. One focusing pass per scale (each reads and range-compresses the frames that see the points).
    """
    pts = np.atleast_2d(np.asarray(points_xy, dtype=np.float64))[:, :2]
    s_grid = np.asarray(scales, dtype=np.float64)
    if pts.size == 0 or s_grid.size < 3:
        raise ValueError("estimate_track_scale: need at least one point and three scales")
    centre = trajectory.rear_axle_enu.mean(axis=0)
    options = FocusOptions.from_config(config, resolution_m=resolution_m, pixel_m=pixel_m)
    h = 0.5 * patch_m
    sharp = np.empty((s_grid.size, len(pts)))
    for i, s in enumerate(s_grid):
        moved = centre + (1.0 + s) * (pts - centre)
        grids = [box_grid(x - h, y - h, x + h, y + h, pixel_m=pixel_m, height_m=options.height_m) for x, y in moved]
        images = focus_images(drive_path, scale_track(trajectory, float(s), centre), config, options,
                              grids=grids).images
        sharp[i] = [point_sharpness(im.image) for im in images]
    sharp_db = 20.0 * np.log10(np.maximum(sharp, np.finfo(np.float64).tiny))
    per_point = np.array([_parabola_peak(s_grid, sharp_db[:, j]) for j in range(len(pts))])
    return TrackScaleEstimate(_parabola_peak(s_grid, sharp_db.sum(axis=1)), per_point, s_grid, sharp_db)


@dataclass(frozen=True)
class TrackAutofocus:
    """A track scaled by the scale :func:`estimate_track_scale` measured on given points (compare's sar-min+scale)."""

    trajectory: Trajectory  #: the input scaled by ``estimate.scale`` (unchanged where ``reason`` says why not)
    estimate: TrackScaleEstimate | None  #: None where no point qualified
    points_xy: Array  #: (P, 2) the points measured, ENU m (where the unscaled track images them)
    reason: str = ""  #: why the track was left unscaled ("" when it was scaled)
    points_label: str = "corner reflectors"  #: what the points are, for :meth:`summary`

    @property
    def applied(self) -> bool:
        return not self.reason

    @property
    def scale(self) -> float:
        """The scale applied to the track (0 where none was)."""
        return self.estimate.scale if self.estimate is not None and self.applied else 0.0

    def labelled(self, method: str) -> Trajectory:
        """The (scaled) trajectory named ``method``, its info holding the scale and the points measured."""
        return replace(self.trajectory, method=method, info={**self.trajectory.info, "track_scale": self.scale,
                                                             "autofocus_points_enu": self.points_xy.tolist()})

    def summary(self) -> str:
        """One line: the scale applied and what measured it, or why none was."""
        est = self.estimate
        if est is None or not self.applied:
            return f"track not scaled: {self.reason}"
        return (f"distances scaled by {est.scale * 100:+.4f} %, the scale at which the {len(self.points_xy)} "
                f"{self.points_label} focus sharpest with a ±28° beam (each alone: "
                f"{', '.join(f'{v * 100:+.3f}' for v in est.point_scales)} %)")
