"""Corner reflectors: position error (aligned and absolute), peak loss, IRW, PSLR, ISLR on fine patches.

Why fine patches: the default 4 cm pixels sample a ~3.5 cm response below Nyquist, so a peak read off
the full image scatters by 1-2 dB depending on where the reflector falls between pixel centres. Every
reflector is therefore re-focused on its own 1 m x 1 m patch of 5 mm pixels (one pass over the radar
data serves all patches, and the full image too: :func:`autosar_cli.sar.focus.focus_images`), then
analysed with band-limited upsampling (:mod:`autosar_cli.evaluate.point_target`).

Why aligned positions: the absolute position of an estimated trajectory is GNSS-limited (decimetres)
and shifts the whole image rigidly. With T the rigid SE(2) motion that best maps the estimated radar
phase-centre track onto the true one, a reflector at true position p should appear at T^-1(p) in the
image focused along the estimate; the aligned error is the distance of the peak from there. The
absolute error (distance from p itself) is reported too.

Where the response is searched: around T^-1(p), and, when it differs by more than
:data:`SEPARATE_M`, also around the zero-Doppler prediction of where the estimated trajectory puts it
(:func:`predict_image_positions`): a trajectory with large along-track errors (the straight line at
constant speed while the car accelerates) images a reflector metres from T^-1(p), often still
focused. The brighter of the two peaks is the reflector's response, so the peak loss measures
defocusing and the aligned error measures the displacement, instead of both reading "nothing here".
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from autosar_cli.config import Config
from autosar_cli.evaluate.alignment import Se2
from autosar_cli.evaluate.point_target import PointTargetMetrics, analyse_point_target
from autosar_cli.nav.trajectory import Trajectory, radar_side, reference_track, zero_doppler_times
from autosar_cli.sar.focus import FocusOptions, FocusResult, focus_images
from autosar_cli.sar.grid import FocusGrid, box_grid
from autosar_cli.store.image import FocusedImage

Array = NDArray[np.float64]

PATCH_SIZE_M = 1.0  #: side of the fine patch around each reflector
PATCH_PIXEL_M = 0.005  #: pixel of the fine patches
SEARCH_M = 0.4  #: the peak is searched within +- this of each patch centre
SEPARATE_M = 0.25  #: a second patch is focused at the zero-Doppler prediction when it is this far from T^-1(p)
ANALYSIS_M = 0.4  #: side of the window upsampled around the peak for widths, PSLR and ISLR
UPSAMPLE = 4  #: band-limited upsampling of that window (5 mm -> 1.25 mm)


@dataclass
class ReflectorPatches:
    """Fine images around every corner reflector, focused along one trajectory: one or two candidate patches
    per reflector (around T^-1(true), and around the zero-Doppler prediction when it lies elsewhere)."""

    method: str  #: trajectory method the patches were focused with
    names: list[str]  #: reflector names (CR1, ...)
    true_enu: Array  #: (C, 3) true positions, ENU m of the image's origin
    expected_xy: Array  #: (C, 2) T^-1(true): where each should appear in this trajectory's image, ENU m
    candidates: list[list[FocusedImage]]  #: per reflector, the patches searched (the first centred on expected_xy)
    local_expected_xy: Array | None = None  #: (C, 2) the same with the local alignment (:func:`local_alignments`)

    def centre_xy(self, image: FocusedImage) -> tuple[float, float]:
        """ENU centre (m) of a patch."""
        c = image.grid.pixel_enu(0.5 * (image.grid.n_across - 1), 0.5 * (image.grid.n_along - 1))
        return (float(c[0]), float(c[1]))


def reflector_grids(centres_xy: ArrayLike, *, height_m: float, size_m: float = PATCH_SIZE_M,
                    pixel_m: float = PATCH_PIXEL_M) -> list[FocusGrid]:
    """One north-up ``size_m`` square box grid of ``pixel_m`` pixels centred on each point (C, 2) (ENU m)."""
    h = 0.5 * size_m
    return [box_grid(x - h, y - h, x + h, y + h, pixel_m=pixel_m, height_m=height_m)
            for x, y in np.asarray(centres_xy, dtype=np.float64)[:, :2]]


def predict_image_positions(estimate: Trajectory, truth: Trajectory, true_enu: ArrayLike, config: Config,
                            t_ns: ArrayLike, height_m: float) -> Array:
    """Where each target (C, 3) (ENU m; z above the road) appears in the image focused along ``estimate``
    (C, 2), to first order.

    Zero-Doppler mapping: the instant t0 at which the true radar reference passes the target
    (:func:`zero_doppler_times`) and the slant range R0 then; the target focuses where the estimated
    reference at t0 sees slant range R0 perpendicular to its estimated velocity, on the radar side, on the
    focusing plane. For a trajectory that is right up to a rigid motion this is the rigidly moved target;
    for one with large along-track errors (e.g. ``none``, constant speed while the car accelerates) it
    follows the response metres along the track. ``t_ns``: candidate instants (the radar frame times).
    """
    true = np.asarray(true_enu, dtype=np.float64).reshape(-1, 3)
    t = np.asarray(t_ns, dtype=np.int64)
    t = t[(t >= max(truth.t_ns[0], estimate.t_ns[0])) & (t <= min(truth.t_ns[-1], estimate.t_ns[-1]))]
    side = radar_side(config)
    t0 = zero_doppler_times(truth, true, config, t)
    c0, _ = reference_track(truth, t0, config)
    ce, ve = reference_track(estimate, t0, config)
    out = np.empty((len(true), 2))
    rise = estimate.height_offset(t0)  # the focusing surface there (sar.focus)
    for i, p in enumerate(true):
        r0 = float(np.linalg.norm(p - c0[i]))
        u = ve[i, :2] / max(float(np.linalg.norm(ve[i, :2])), 1e-9)
        n = side * np.array([-u[1], u[0]])
        g = math.sqrt(max(r0**2 - (ce[i, 2] - height_m - rise[i]) ** 2, 0.0))
        out[i] = ce[i, :2] + g * n
    return out


def focus_patches(drive_path: str | Path, trajectory: Trajectory, config: Config, options: FocusOptions,
                  names: list[str], true_enu: ArrayLike, alignment: Se2 | None = None, *,
                  predicted_xy: ArrayLike | None = None, extra_grids: list[FocusGrid] | None = None,
                  size_m: float = PATCH_SIZE_M) -> tuple[ReflectorPatches, list[FocusedImage], FocusResult]:
    """Focus the candidate patches of every reflector along ``trajectory`` in one pass over the radar data.

    Each reflector should appear at ``alignment.inverse()`` (default: identity) of its true position: a patch
    is centred there; ``predicted_xy`` (C, 2) (:func:`predict_image_positions`) adds a second patch where
    it lies more than :data:`SEPARATE_M` away. ``extra_grids`` (e.g. the full image's grid) are focused in
    the same pass and returned second. ``options``: the full image's options (range processing, channels,
    resolution, focusing height); the patch grids carry their own pixel (:data:`PATCH_PIXEL_M`).
    """
    true = np.asarray(true_enu, dtype=np.float64).reshape(-1, 3)
    alignment = alignment or Se2()
    expected = alignment.inverse().apply(true[:, :2])
    pred = None if predicted_xy is None else np.asarray(predicted_xy, dtype=np.float64).reshape(-1, 2)
    centres: list[NDArray[np.float64]] = []
    owner: list[int] = []
    for i, e in enumerate(expected):
        centres.append(e)
        owner.append(i)
        if pred is not None and np.hypot(*(pred[i] - e)) > SEPARATE_M:
            centres.append(pred[i])
            owner.append(i)
    grids = reflector_grids(np.array(centres), height_m=options.height_m, size_m=size_m)
    extra = list(extra_grids or [])
    res = focus_images(drive_path, trajectory, config, options, grids=extra + grids)
    candidates: list[list[FocusedImage]] = [[] for _ in expected]
    for i, img in zip(owner, res.images[len(extra):], strict=True):
        img.params["pixel_m"] = img.grid.pixel_m  # each grid carries its own pixel; the options' is the full image's
        img.params["grid"] = "reflector patch"
        candidates[i].append(img)
    patches = ReflectorPatches(trajectory.method, list(names), true, expected, candidates)
    return patches, res.images[:len(extra)], res


@dataclass(frozen=True)
class ReflectorMetrics:
    """One corner reflector in one image (metres, dB; ENU of the image's origin)."""

    name: str
    true_enu: tuple[float, float, float]
    expected_xy: tuple[float, float]  #: T^-1(true): where it should appear in this image
    patch_centre_xy: tuple[float, float]  #: centre of the patch the peak was found in
    peak_xy: tuple[float, float]  #: interpolated peak
    aligned_error_m: float  #: |peak - expected|
    aligned_error_range_m: float  #: signed component along the range direction (away from the track)
    aligned_error_cross_m: float  #: signed component along cross-range (90 deg CCW from range)
    absolute_error_m: float  #: |peak - true|
    local_aligned_error_m: float  #: |peak - T_local^-1(true)|, aligned on the track around the reflector only
    peak_db: float  #: 20 log10 |peak| (arbitrary but common units)
    reference_peak_db: float | None  #: the same reflector focused along the true trajectory
    peak_loss_db: float | None  #: reference_peak_db - peak_db
    #: |aligned error - the truth image's own|: how far the trajectory moved the peak from where the true trajectory
    #: puts it (which the scene's own physics, a road's multipath, can move off the true position); None without a
    #: reference. The alignment's rotation of that own offset (< 1e-3 rad of a few cm) is neglected.
    reference_error_m: float | None
    irw_range_m: float  #: -3 dB impulse response width in range
    irw_cross_m: float  #: ... in cross-range
    pslr_range_db: float
    pslr_cross_db: float
    islr_range_db: float
    islr_cross_db: float

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _brightest(patches: ReflectorPatches, i: int, rd: NDArray[np.float64], search_m: float, analysis_m: float,
               factor: int) -> tuple[FocusedImage, PointTargetMetrics] | None:
    """The candidate patch of reflector ``i`` with the brightest peak within ``search_m`` of its centre."""
    best: tuple[FocusedImage, PointTargetMetrics] | None = None
    for img in patches.candidates[i]:
        if not np.any(img.image):  # no pulse reached this patch
            continue
        centre = patches.centre_xy(img)
        m = analyse_point_target(img, np.r_[centre, patches.true_enu[i, 2]], name=patches.names[i], range_dir=rd,
                                 search_m=search_m, patch_m=analysis_m, factor=factor)
        if best is None or m.peak_db > best[1].peak_db:
            best = (img, m)
    return best


def measure_reflectors(patches: ReflectorPatches, range_dir: ArrayLike,
                       reference: ReflectorPatches | None = None, *, search_m: float = SEARCH_M,
                       analysis_m: float = ANALYSIS_M, factor: int = UPSAMPLE) -> list[ReflectorMetrics]:
    """Analyse every reflector: the brightest peak over its candidate patches (each searched within ``search_m``
    of its centre), its position error relative to where the reflector should appear, widths, PSLR, ISLR;
    ``reference``: the patches focused along the true trajectory (for the peak loss).

    ``range_dir``: horizontal unit vector of ground range (the auto grid's across axis: perpendicular to the
    mean track, away from it).
    """
    rd = np.asarray(range_dir, dtype=np.float64)[:2]
    rd = rd / np.linalg.norm(rd)
    cd = np.array([-rd[1], rd[0]])
    ref_db: dict[str, float] = {}
    ref_offset: dict[str, NDArray[np.float64]] = {}  # each reference peak less where the reference expects it
    if reference is not None:
        for i, name in enumerate(reference.names):
            found = _brightest(reference, i, rd, search_m, analysis_m, factor)
            if found is not None:
                ref_db[name] = found[1].peak_db
                ref_offset[name] = np.asarray(found[1].peak_enu)[:2] - reference.expected_xy[i]
    out = []
    nan = math.nan
    for i, name in enumerate(patches.names):
        true, xy = patches.true_enu[i], patches.expected_xy[i]
        ref = ref_db.get(name)
        found = _brightest(patches, i, rd, search_m, analysis_m, factor)
        if found is None:  # nothing to measure
            out.append(ReflectorMetrics(name, (float(true[0]), float(true[1]), float(true[2])),
                                        (float(xy[0]), float(xy[1])), (nan, nan), (nan, nan), nan, nan, nan, nan,
                                        nan, nan, ref, None, None, nan, nan, nan, nan, nan, nan))
            continue
        img, m = found
        peak = np.asarray(m.peak_enu)
        d = peak - xy
        out.append(ReflectorMetrics(
            name=name, true_enu=(float(true[0]), float(true[1]), float(true[2])),
            expected_xy=(float(xy[0]), float(xy[1])), patch_centre_xy=patches.centre_xy(img),
            peak_xy=(float(peak[0]), float(peak[1])),
            aligned_error_m=float(np.hypot(*d)), aligned_error_range_m=float(d @ rd),
            aligned_error_cross_m=float(d @ cd), absolute_error_m=float(np.hypot(*(peak - true[:2]))),
            local_aligned_error_m=(float(np.hypot(*(peak - patches.local_expected_xy[i])))
                                   if patches.local_expected_xy is not None else nan),
            peak_db=m.peak_db, reference_peak_db=ref, peak_loss_db=None if ref is None else ref - m.peak_db,
            reference_error_m=float(np.hypot(*(d - ref_offset[name]))) if name in ref_offset else None,
            irw_range_m=m.range_cut.width_m, irw_cross_m=m.cross_range_cut.width_m,
            pslr_range_db=m.range_cut.pslr_db, pslr_cross_db=m.cross_range_cut.pslr_db,
            islr_range_db=m.range_cut.islr_db, islr_cross_db=m.cross_range_cut.islr_db))
    return out


def chosen_patch(patches: ReflectorPatches, metrics: ReflectorMetrics) -> FocusedImage:
    """The candidate patch the peak of ``metrics`` was found in (the first candidate if none was)."""
    cands = patches.candidates[patches.names.index(metrics.name)]
    for img in cands:
        if np.allclose(patches.centre_xy(img), metrics.patch_centre_xy, atol=1e-6):
            return img
    return cands[0]


def summarise_reflectors(metrics: list[ReflectorMetrics]) -> dict[str, float]:
    """Mean / max of the aligned error, the absolute error and the peak loss, and the largest error against the truth
    image's peak, over the reflectors (NaN if none)."""

    def stat(values: list[float], fn: Any) -> float:
        v = [x for x in values if x is not None and math.isfinite(x)]
        return float(fn(v)) if v else math.nan

    aligned = [m.aligned_error_m for m in metrics]
    local = [m.local_aligned_error_m for m in metrics]
    absolute = [m.absolute_error_m for m in metrics]
    loss = [m.peak_loss_db for m in metrics if m.peak_loss_db is not None]
    reference = [m.reference_error_m for m in metrics if m.reference_error_m is not None]
    return {"reflectors": len(metrics), "aligned_error_mean_m": stat(aligned, np.mean),
            "aligned_error_max_m": stat(aligned, np.max), "local_aligned_error_mean_m": stat(local, np.mean),
            "local_aligned_error_max_m": stat(local, np.max), "absolute_error_mean_m": stat(absolute, np.mean),
            "reference_error_max_m": stat(reference, np.max), "peak_loss_mean_db": stat(loss, np.mean),
            "peak_loss_max_db": stat(loss, np.max)}
