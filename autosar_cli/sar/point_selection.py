"""The autofocus's points: bright, isolated, point-like scatterers of a coarse first image along the navigated track.

They are ranked by reflectivity (:func:`select_points`): 3-12 m from the track for the scale and the motion, 12-16 m
for the motion only (:func:`candidate_points`), and, for the fast motion, many more out to the radar's range
(:func:`points_and_scatterers`). A point that is no point scatterer after all is dropped by its fits
(:mod:`autosar_cli.sar.residual_motion`, :mod:`autosar_cli.sar.pass_ranges`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from autosar_cli.config import MAX_CROSS_RANGE_RESOLUTION_M, Config
from autosar_cli.nav.trajectory import radar_track, zero_doppler_times
from autosar_cli.sar.fast_motion import FastMotionOptions, closest_approach_ns
from autosar_cli.sar.focus import FocusOptions
from autosar_cli.sar.residual_motion import AutofocusOptions
from autosar_cli.store.drive import radar_times
from autosar_cli.types import FocusGrid, Trajectory

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ImagePeaks:
    """What :func:`select_points` measures on a first image's pixels, whatever its bands and limits."""

    intensity: Array  #: |z|^2
    local_max: NDArray[np.bool_]  #: the brightest within 1 m
    concentration: Array  #: the share of the 7 x 7 pixels' intensity around it

    @classmethod
    def of(cls, image: NDArray[np.complexfloating], grid: FocusGrid) -> ImagePeaks:
        from scipy.ndimage import maximum_filter, uniform_filter

        intensity = np.abs(np.asarray(image).astype(np.complex128)) ** 2
        size = max(3, 2 * int(round(0.5 / grid.pixel_m)) + 1)
        local_max = (intensity == maximum_filter(intensity, size=size)) & (intensity > 0.0)
        concentration = intensity / np.maximum(uniform_filter(intensity, size=7) * 49.0, np.finfo(np.float64).tiny)
        return cls(intensity, local_max, concentration)


def select_points(image: NDArray[np.complexfloating], grid: FocusGrid, range_m: Array, opts: AutofocusOptions,
                  *, band_m: tuple[float, float] | None = None, per_segment: int = 2, min_concentration: float = 0.2,
                  within_db: float = 15.0, peaks: ImagePeaks | None = None) -> Array:
    """Bright, isolated, point-like pixels (P, 3) (ENU m, on the grid's plane) of a first image for the phase
    histories: local maxima (within 1 m) between ``band_m`` (default ``opts.min_range_m``, ``opts.max_range_m``)
    from the track (``range_m``, per pixel) that hold ``min_concentration`` of the intensity of the 7 x 7 pixels
    around them, ranked by |z|^2 R^2 (reflectivity, not nearness); of those within ``within_db`` of the most
    reflective, the ``per_segment`` best in every ``opts.point_spacing_m`` of the grid's along axis. ``peaks``:
    ``image``'s, where already measured (:class:`ImagePeaks`).

    Why reflectivity: in the simulated scenes and on real roads, corner reflectors, poles and sign posts stand
    10 dB or more above the brightest speckle of distributed clutter, whose peak-to-background ratio alone does
    not tell it apart (test1: 28-30 dB for both). A point that is not a point scatterer after all is dropped by its
    phase fit."""
    peaks = peaks or ImagePeaks.of(image, grid)
    low, high = band_m or (opts.min_range_m, opts.max_range_m)
    score = np.where(peaks.local_max & (range_m >= low) & (range_m <= high)
                     & (peaks.concentration >= min_concentration), peaks.intensity * range_m**2, 0.0)
    if not np.any(score > 0):
        return np.zeros((0, 3))
    score[score < score.max() * 10 ** (-within_db / 10)] = 0.0
    cols = max(1, int(round(opts.point_spacing_m / grid.pixel_m)))
    # the best per_segment of each segment's scored pixels: by segment, then by score, highest first
    r, c = np.nonzero(score > 0)
    segment = c // cols
    order = np.lexsort((-score[r, c], segment))
    r, c, segment = r[order], c[order], segment[order]
    keep = np.arange(len(segment)) - np.searchsorted(segment, segment) < per_segment
    return grid.pixel_enu(r[keep], c[keep])


def candidate_points(drive_path: str | Path, trajectory: Trajectory, config: Config, focus: FocusOptions,
                     opts: AutofocusOptions, **select: Any) -> Array:
    """:func:`select_points` (``select``: its keyword options) on a first image along ``trajectory``: the product's
    grid, but only out to ``opts.max_range_m`` + 1 m, at twice the product's resolution and 1.5 times its pixel,
    from ``opts.channels`` channels (on test2 1/45 of the product's back-projections, and a quarter of its range
    compression; the fit refines each point's position)."""
    return points_and_scatterers(drive_path, trajectory, config, focus, opts, None, **select)[0]


def points_and_scatterers(drive_path: str | Path, trajectory: Trajectory, config: Config, focus: FocusOptions,
                          opts: AutofocusOptions, fast: FastMotionOptions | None, **select: Any
                          ) -> tuple[Array, Array, NDArray[np.int64]]:
    """The autofocus's points (:func:`candidate_points`) and, unless ``fast`` is None, the fast-motion stage's
    scatterers (:mod:`autosar_cli.sar.fast_motion`) on one first image out to the radar's range. The grid's rows
    start at the track whatever its range, and the pixels within ``opts.max_range_m`` + 1 m hold the same values as
    on the shorter image (only the last rows, where its range cuts pulses off, differ), so the points are those of
    :func:`candidate_points`: (P, 3) and (S, 3), ENU m, and the scatterers' closest approach (S,) (ns)."""
    from autosar_cli.sar.focus import auto_grid, focus_images
    from autosar_cli.sar.grid import track_distance

    def ranged(max_range_m: float) -> Config:
        return replace(config, radar=replace(config.radar, max_range_m=min(config.radar.max_range_m, max_range_m)))

    near = ranged(opts.max_range_m + 1.0)
    far = config if fast is not None else near
    coarse = replace(focus, resolution_m=min(2.0 * focus.resolution_m, MAX_CROSS_RANGE_RESOLUTION_M),
                     pixel_m=1.5 * focus.pixel_m, channels=opts.channels)
    grid = auto_grid(drive_path, trajectory, far, coarse)
    image = focus_images(drive_path, trajectory, far, coarse, grids=[grid]).images[0].image
    t_radar = radar_times(drive_path, focus.radar, focus.radar_clock_offset_s, focus.radar_clock_drift_ppm)
    t_radar = t_radar[(t_radar >= trajectory.t_ns[0]) & (t_radar <= trajectory.t_ns[-1])]
    # every 8th pulse (~3 cm apart at 30 km/h): the distance of a pixel 3 m away is off by < 0.1 mm
    track = radar_track(trajectory, t_radar[::8], config)
    distance = track_distance(grid, track)
    rows = auto_grid(drive_path, trajectory, near, coarse).n_across if fast is not None else grid.n_across
    # the scale's points as they would be alone, and the motion's beyond them (ranked by reflectivity, the farther
    # would take the nearer's places)
    bands = [(opts.min_range_m, opts.scale_max_range_m), (opts.scale_max_range_m, opts.max_range_m)]
    near_peaks = ImagePeaks.of(image[:rows], grid)
    points = np.concatenate([select_points(image[:rows], grid, distance[:rows], opts, band_m=b, peaks=near_peaks,
                                           **select) for b in bands if b[1] > b[0]])
    scatterers, t_zero = np.zeros((0, 3)), np.zeros(0, np.int64)
    if fast is not None:
        wide = replace(opts, max_range_m=config.radar.max_range_m - 1.0)
        bands = [(wide.min_range_m, wide.scale_max_range_m), (wide.scale_max_range_m, wide.max_range_m)]
        far_peaks = ImagePeaks.of(image, grid)
        scatterers = np.concatenate([select_points(image, grid, distance, wide, band_m=b, per_segment=fast.per_segment,
                                                   min_concentration=fast.min_concentration,
                                                   within_db=fast.within_db, peaks=far_peaks) for b in bands])
        if len(scatterers):
            t_zero = closest_approach_ns(track, t_radar[::8], scatterers)
            scatterers[:, 2] += trajectory.height_offset(t_zero)
    if len(points):  # on the focusing surface, as focus put them (sar.focus)
        points[:, 2] += trajectory.height_offset(zero_doppler_times(trajectory, points, config, t_radar))
    return points, scatterers, t_zero

