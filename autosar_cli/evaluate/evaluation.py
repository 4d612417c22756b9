"""One image + the trajectory it was focused along, evaluated against the truth (in memory, no files written).

Inputs are expressed in the image's ENU frame: the truth trajectory and targets are re-expressed in the
image's geodetic origin. Without a truth sidecar only the truth-free image metrics (entropy, contrast)
are computed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from autosar_cli.config import Config
from autosar_cli.evaluate.alignment import Se2
from autosar_cli.evaluate.image_quality import (
    Straightness,
    data_mask,
    image_contrast,
    image_entropy,
    line_straightness,
)
from autosar_cli.evaluate.reflectors import (
    ReflectorMetrics,
    ReflectorPatches,
    focus_patches,
    measure_reflectors,
    predict_image_positions,
    summarise_reflectors,
)
from autosar_cli.evaluate.trajectory_metrics import (
    TrajectoryErrors,
    TrajectoryMetrics,
    common_instants,
    local_alignments,
    trajectory_errors,
    trajectory_metrics,
)
from autosar_cli.nav.baselines import from_truth
from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.nav.trajectory import (
    Trajectory,
    phase_centre_lever_arm,
    radar_side,
    radar_track,
    zero_doppler_times,
)
from autosar_cli.sar.focus import FocusOptions, drive_radar_config, focus_images
from autosar_cli.sar.grid import FocusGrid, track_distance, track_lattice
from autosar_cli.sim.scene import KINDS
from autosar_cli.sim.truth import TruthTargets, open_truth, read_targets
from autosar_cli.store.drive import Drive, radar_times
from autosar_cli.store.image import FocusedImage
from autosar_cli.store.manifest import product_status

#: Scene lines whose straightness is measured (kinds of autosar_cli.sim.scene.KINDS).
LINE_KINDS = ("facade", "kerb")
#: The image metrics are measured on the product's grid with this many times finer pixels.
METRICS_OVERSAMPLE = 2
#: The far swath, where entropy and contrast are also reported: pixels at least this fraction of the radar's
#: maximum range from the radar's track. Its processed apertures (range x the beam's width 2 psi_max, 0.64-1.29 m
#: at 4 cm resolution) are long enough for centimetre navigation errors to defocus; the near swath's (~10 cm
#: at 2-3 m) only shift, and there the brightest scatterers' radiometry sets the entropy (docs/EVALUATION.md).
FAR_SWATH_FRACTION = 0.5
#: Lattice (m) on which a pixel's distance to the track is measured for the far swath (nearest lattice point).
FAR_SWATH_LATTICE_M = 0.25
#: Power of the range whose inverse a point's focused intensity follows, which the range-normalised entropy and
#: contrast undo: 1/R^4 per pulse (two-way spreading) times R^2 of coherent gain over a processed aperture that grows
#: as R. Measured on the 15 corner reflectors (all one size) of test1-3: peak intensity ~ R^-2.3, the antenna
#: pattern adding the rest.
RANGE_LAW_EXPONENT = 2.0


@dataclass
class Truth:
    """The simulator's ground truth in an image's ENU frame."""

    path: Path
    trajectory: Trajectory
    targets: TruthTargets
    road_z_m: float = 0.0  #: ENU z of the road surface (the truth's origin) in this frame

    def targets_above_road(self, indices: NDArray[np.int64]) -> NDArray[np.float64]:
        """Target positions (N, 3) with z measured from the road, as the processing's geometry assumes (the
        frame's own z = 0 comes from a GNSS height and may be off by decimetres)."""
        p = np.array(self.targets.position_enu[indices], dtype=np.float64)
        p[:, 2] -= self.road_z_m
        return p


def load_truth(path: str | Path, origin: GeodeticOrigin, config: Config) -> Truth:
    """Read a truth sidecar and re-express its trajectory and targets in the ENU frame of ``origin`` (an
    image's or a drive's). The trajectory carries the radar's true motion (``from_truth(radar_motion=True)``):
    the alignment, the trajectory errors and the peak-loss reference follow the phase centres the echoes came
    from, not the planar track of the car; and, where the simulator put them on, the front end's true channel
    gains (``from_truth``)."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{p}: no such truth sidecar")
    with open_truth(p) as f:
        road = GeodeticOrigin(float(f.attrs["origin_lat_deg"]), float(f.attrs["origin_lon_deg"]),
                              float(f.attrs["origin_height_m"]))
    road_z = float(origin.to_enu(road.lat_deg, road.lon_deg, road.height_m)[2])
    return Truth(p, from_truth(str(p), origin, config, radar_motion=True), read_targets(p, origin), road_z)


@dataclass(frozen=True)
class ImageMetrics:
    """Truth-free focus quality of the full image, plus the straightness of known lines (with truth).

    Measured on the product's grid at half its pixel (2 cm by default): the 4 cm product samples the
    intensity of a ~3.5 cm response below its Nyquist rate, so its entropy moves by several per cent when
    the grid shifts by half a pixel; at 2 cm it moves by a few tenths of a per cent. The product's own
    values are kept in ``product``.
    """

    pixels: int  #: pixels that received pulses
    pixel_m: float  #: pixel of the grid measured
    entropy: float  #: nats, -sum p ln p of the normalised intensity
    contrast: float  #: std(I) / mean(I)
    straightness: dict[str, Straightness] = field(default_factory=dict)
    product: dict[str, float] = field(default_factory=dict)  #: pixel_m, entropy, contrast of the product image
    #: min_range_m, pixels, entropy, contrast over the far swath (:data:`FAR_SWATH_FRACTION`); empty if not measured
    far_swath: dict[str, float] = field(default_factory=dict)
    #: exponent, entropy, contrast of the range-normalised intensity |z|^2 R^exponent (:data:`RANGE_LAW_EXPONENT`) over
    #: the same pixels as ``entropy``; empty if not measured
    range_normalised: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"pixels": self.pixels, "pixel_m": self.pixel_m, "entropy": self.entropy, "contrast": self.contrast,
                "straightness": {k: v.to_dict() for k, v in self.straightness.items()}, "product": self.product,
                "far_swath": self.far_swath, "range_normalised": self.range_normalised}


@dataclass
class Evaluation:
    """Everything measured on one image (see :func:`evaluate_image`)."""

    method: str
    image: FocusedImage
    trajectory: Trajectory
    image_metrics: ImageMetrics
    truth: Truth | None = None
    errors: TrajectoryErrors | None = None
    trajectory_metrics: TrajectoryMetrics | None = None
    reflectors: list[ReflectorMetrics] = field(default_factory=list)
    patches: ReflectorPatches | None = None
    reference_patches: ReflectorPatches | None = None
    metrics_image: FocusedImage | None = None  #: the product's grid at half its pixel (entropy, contrast, lines)
    range_dir: tuple[float, float] = (0.0, 1.0)
    notes: list[str] = field(default_factory=list)
    inputs: dict[str, str] = field(default_factory=dict)
    #: the drive's ingest warnings (a damaged log, ...) and the image's own (frames left out of it)
    input_warnings: list[str] = field(default_factory=list)

    @property
    def alignment(self) -> Se2:
        return self.errors.alignment if self.errors is not None else Se2()

    def summary(self) -> dict[str, Any]:
        """Flat headline numbers (m, dB, nats) for tables; NaN where not measured."""
        tm = self.trajectory_metrics
        nan = math.nan
        s: dict[str, Any] = {"method": self.method,
                             "abs_rmse_m": tm.abs_rmse_m if tm else nan,
                             "aligned_rmse_m": tm.aligned_rmse_m if tm else nan,
                             "rpe_1m_across_m": tm.rpe_1m_across_m if tm else nan,
                             "rpe_10m_across_m": tm.rpe_10m_across_m if tm else nan,
                             "entropy": self.image_metrics.entropy, "contrast": self.image_metrics.contrast,
                             "entropy_far": self.image_metrics.far_swath.get("entropy", nan),
                             "contrast_far": self.image_metrics.far_swath.get("contrast", nan),
                             "entropy_rn": self.image_metrics.range_normalised.get("entropy", nan),
                             "contrast_rn": self.image_metrics.range_normalised.get("contrast", nan)}
        s.update(summarise_reflectors(self.reflectors))
        for kind in LINE_KINDS:
            st = self.image_metrics.straightness.get(kind)
            s[f"straightness_{kind}_m"] = st.rms_residual_m if st else nan
        return s

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready metrics (metrics.json)."""
        d: dict[str, Any] = {"format": "autosar-evaluation", "format_version": 1, "method": self.method,
                             "inputs": dict(self.inputs), "truth": str(self.truth.path) if self.truth else None,
                             "track_scale": self.trajectory.info.get("track_scale"), "summary": self.summary(),
                             "image": self.image_metrics.to_dict(),
                             "trajectory": self.trajectory_metrics.to_dict() if self.trajectory_metrics else None,
                             "alignment": self.alignment.to_dict() if self.errors else None,
                             "range_direction": list(self.range_dir),
                             "reflectors": [r.to_dict() for r in self.reflectors], "notes": list(self.notes),
                             "status": product_status(self.input_warnings),
                             "input_warnings": list(self.input_warnings)}
        return d


def options_from_image(image: FocusedImage, config: Config) -> FocusOptions:
    """The focus options an image was made with (from its parameters; config defaults for anything missing)."""
    names = {f.name for f in fields(FocusOptions)}
    return FocusOptions.from_config(config, **{k: v for k, v in image.params.items() if k in names})


def _is_box(spec: str) -> bool:
    try:
        return len([float(v) for v in spec.split(",")]) == 4
    except ValueError:
        return False


def range_direction(image: FocusedImage, trajectory: Trajectory, config: Config) -> tuple[float, float]:
    """Horizontal unit vector of ground range: the auto grid's across axis (perpendicular to the mean track,
    on the radar side). For an explicit box grid (``x0,y0,x1,y1``) it is derived from the track the same way."""
    if not _is_box(str(image.params.get("grid", "auto"))):
        a = np.asarray(image.grid.across, dtype=np.float64)
    else:
        xy = trajectory.rear_axle_enu
        _, _, vt = np.linalg.svd(xy - xy.mean(axis=0), full_matrices=False)
        along = vt[0] if np.dot(vt[0], xy[-1] - xy[0]) > 0 else -vt[0]
        left = np.array([-along[1], along[0]])
        side = radar_side(config)
        a = left * side
    return (float(a[0]), float(a[1]))


def metrics_grid(grid: FocusGrid, oversample: int = METRICS_OVERSAMPLE) -> FocusGrid:
    """The product grid's area with ``oversample`` times finer pixels (same axes, same outer edges)."""
    px = grid.pixel_m / oversample
    corner = np.asarray(grid.origin) - 0.5 * grid.pixel_m * (np.asarray(grid.along) + np.asarray(grid.across))
    origin = corner + 0.5 * px * (np.asarray(grid.along) + np.asarray(grid.across))
    return replace(grid, origin=(float(origin[0]), float(origin[1])), pixel_m=px, n_along=grid.n_along * oversample,
                   n_across=grid.n_across * oversample)


def _moved_diagonally(g: FocusGrid, d_m: float, **changes: Any) -> FocusGrid:
    """``g`` with its origin moved ``d_m`` along and ``d_m`` across (its own axes), and ``changes``."""
    origin = np.asarray(g.origin) + d_m * (np.asarray(g.along) + np.asarray(g.across))
    return replace(g, origin=(float(origin[0]), float(origin[1])), **changes)


def product_pixels(metrics: FocusedImage, oversample: int = METRICS_OVERSAMPLE) -> FocusedImage:
    """The product-pixel image inside ``metrics`` (an image on :func:`metrics_grid`): every ``oversample``-th
    pixel from ``oversample // 2`` on, along and across, on its own grid of ``oversample`` times the pixel.

    Each pixel is focused on its own, so these are the values the product's grid focuses to once moved onto
    them: half a metrics pixel along and across where ``oversample`` is even (1 cm for the 4 cm product),
    not at all where it is odd. Lets one pass give the product and its metrics image without focusing the
    product's pixels twice."""
    g, k = metrics.grid, oversample // 2
    grid = _moved_diagonally(g, k * g.pixel_m, pixel_m=g.pixel_m * oversample,
                             n_along=len(range(k, g.n_along, oversample)),
                             n_across=len(range(k, g.n_across, oversample)))
    image = np.ascontiguousarray(metrics.image[k::oversample, k::oversample])
    params = {**metrics.params, "pixel_m": grid.pixel_m, "metrics_oversample": oversample}
    return FocusedImage(image, grid, metrics.origin, params, dict(metrics.provenance))


def product_metrics_grid(image: FocusedImage) -> FocusGrid:
    """The grid ``image``'s metrics are measured on: :func:`metrics_grid` of its grid, or, where ``image`` was
    taken from a metrics image (:func:`product_pixels`, as ``compare`` makes its products), that image's grid,
    so that `autosar evaluate` of a compared method measures what ``compare`` did."""
    oversample = image.params.get("metrics_oversample")
    if not oversample:
        return metrics_grid(image.grid)
    g, n = image.grid, int(oversample)
    px = g.pixel_m / n
    return _moved_diagonally(g, -((n // 2) * px), pixel_m=px, n_along=g.n_along * n, n_across=g.n_across * n)


def far_swath_mask(grid: FocusGrid, track_xy: ArrayLike, min_range_m: float,
                   lattice_m: float = FAR_SWATH_LATTICE_M) -> NDArray[np.bool_]:
    """Pixels (rows, cols) of ``grid`` at least ``min_range_m`` (horizontal) from the nearest point of the radar's
    track ``track_xy`` (M, 2) (ENU m, densely sampled: the distance is to its points). Each pixel takes the
    distance of the nearest point of a ``lattice_m`` lattice of the grid, so the edge is drawn to within
    ``lattice_m``."""
    step, dist = track_lattice(grid, track_xy, lattice_m, covering=False)
    far = dist >= min_range_m
    return np.repeat(np.repeat(far, step, axis=0), step, axis=1)[:grid.n_across, :grid.n_along]


def image_metrics(image: FocusedImage, truth: Truth | None, alignment: Se2,
                  product: FocusedImage | None = None, *, track_xy: ArrayLike | None = None,
                  max_range_m: float | None = None) -> ImageMetrics:
    """Entropy and contrast over the data pixels of ``image``, and over its far swath (pixels at least
    :data:`FAR_SWATH_FRACTION` x ``max_range_m`` from the radar's track ``track_xy`` (M, 2), ENU m in the
    image's frame; both needed) and over the range-normalised intensity |z|^2 R^2 (R: the pixel's distance from
    that track; :data:`RANGE_LAW_EXPONENT`), in which a scatterer counts by its reflectivity, not by how near the
    track it is; with truth, the straightness of the facade and kerb lines (their true
    scatterers mapped into the image by ``alignment.inverse()``) traced in ``product`` (the product image,
    whose own entropy and contrast are reported alongside; default: ``image``).

    Lines are traced in the product: at its 4 cm pixels a line of scatterers 10 cm apart (a kerb) leaves
    fewer empty columns for clutter and sidelobes to fill than at 2 cm."""
    mask = data_mask(image.image)
    far: dict[str, float] = {}
    range_normalised: dict[str, float] = {}
    if track_xy is not None and max_range_m is not None:
        min_range = FAR_SWATH_FRACTION * max_range_m
        far_mask = mask & far_swath_mask(image.grid, track_xy, min_range)
        far = {"min_range_m": min_range, "pixels": int(far_mask.sum()),
               "entropy": image_entropy(image.image, far_mask), "contrast": image_contrast(image.image, far_mask)}
        reflectivity = (np.abs(image.image[mask]).astype(np.float64) ** 2
                        * track_distance(image.grid, track_xy)[mask] ** RANGE_LAW_EXPONENT)
        range_normalised = {"exponent": RANGE_LAW_EXPONENT, "entropy": image_entropy(reflectivity),
                            "contrast": image_contrast(reflectivity)}
    straight: dict[str, Straightness] = {}
    if truth is not None:
        inv = alignment.inverse()
        for kind in LINE_KINDS:
            sel = truth.targets.kind == KINDS.index(kind)
            if sel.sum() >= 2:
                straight[kind] = line_straightness(product or image, inv.apply(truth.targets.position_enu[sel, :2]),
                                                   kind)
    raw: dict[str, float] = {}
    if product is not None:
        raw = {"pixel_m": product.grid.pixel_m, "entropy": image_entropy(product.image),
               "contrast": image_contrast(product.image)}
    return ImageMetrics(int(mask.sum()), image.grid.pixel_m, image_entropy(image.image, mask),
                        image_contrast(image.image, mask), straight, raw, far, range_normalised)


def evaluate_image(image: FocusedImage, trajectory: Trajectory, drive_path: str | Path, config: Config,
                   truth: Truth | None = None, *, metrics_image: FocusedImage | None = None,
                   patches: ReflectorPatches | None = None, reference_patches: ReflectorPatches | None = None,
                   range_dir: tuple[float, float] | None = None, inputs: dict[str, str] | None = None) -> Evaluation:
    """Evaluate ``image`` (the product), focused from ``drive_path`` along ``trajectory``, against ``truth``.

    Trajectory metrics at the radar frame times; the SE(2) alignment; every corner reflector on fine patches;
    entropy, contrast and straightness on ``metrics_image``: the product's grid at half its pixel
    (:func:`product_metrics_grid`). Whatever is not given is focused here, in one pass over the radar data
    (``metrics_image`` and ``patches`` along ``trajectory``; ``reference_patches``, the peak-loss reference,
    along the truth). Given patches must have been focused with this evaluation's alignment (e.g. by
    :func:`autosar_cli.evaluate.compare.compare`). ``range_dir``: the ground-range direction of the
    reflector cuts (default: :func:`range_direction`).
    """
    options = options_from_image(image, config)
    config = drive_radar_config(config, drive_path, options.radar)
    ev = Evaluation(trajectory.method, image, trajectory, ImageMetrics(0, math.nan, math.nan, math.nan),
                    range_dir=range_dir or range_direction(image, trajectory, config), inputs=dict(inputs or {}))
    with Drive(drive_path) as drive:
        ev.input_warnings = [str(w) for w in drive.report().get("warnings", [])]
    # what focusing left out of the image (a damaged drive's frames), as its provenance keeps it
    ev.input_warnings += [str(w) for w in image.provenance.get("warnings", []) if str(w) not in ev.input_warnings]
    frames = radar_times(drive_path, options.radar, options.radar_clock_offset_s, options.radar_clock_drift_ppm)
    fine = [product_metrics_grid(image)] if metrics_image is None else []
    if truth is None:
        if metrics_image is None:
            metrics_image = focus_images(drive_path, trajectory, config, options, grids=fine).images[0]
        ev.metrics_image = metrics_image
        ev.image_metrics = image_metrics(metrics_image, None, Se2(), image,
                                         track_xy=radar_track(trajectory, frames, config),
                                         max_range_m=config.radar.max_range_m)
        ev.notes.append("no truth sidecar: only the truth-free image metrics (entropy, contrast) are reported")
        return ev
    ev.truth = truth
    lever = phase_centre_lever_arm(config)
    t = common_instants(trajectory, truth.trajectory, frames)
    ev.errors = trajectory_errors(trajectory, truth.trajectory, lever, t)
    ev.trajectory_metrics = trajectory_metrics(trajectory, ev.errors)
    crs = truth.targets.corner_reflectors
    names = truth.targets.corner_reflector_names()
    true = truth.targets.position_enu[crs]
    if patches is None and len(crs):
        centres = predict_image_positions(trajectory, truth.trajectory, truth.targets_above_road(crs), config, t,
                                          options.height_m)
        patches, extra, _ = focus_patches(drive_path, trajectory, config, options, names, true, ev.alignment,
                                          predicted_xy=centres, extra_grids=fine)
        metrics_image = metrics_image or extra[0]
    elif metrics_image is None:
        metrics_image = focus_images(drive_path, trajectory, config, options, grids=fine).images[0]
    assert metrics_image is not None
    ev.metrics_image = metrics_image
    # the far swath measured from the true track moved into this image's frame: the same piece of the scene for
    # every method of a comparison, whatever its own track
    true_track = ev.alignment.inverse().apply(radar_track(truth.trajectory, frames, config))
    ev.image_metrics = image_metrics(metrics_image, truth, ev.alignment, image, track_xy=true_track,
                                     max_range_m=config.radar.max_range_m)
    if patches is None:
        ev.notes.append("the truth lists no corner reflector")
        return ev
    if reference_patches is None:
        if trajectory.method == "truth":
            reference_patches = patches
        else:
            reference_patches = focus_patches(drive_path, truth.trajectory, config, options, names, true)[0]
    t0 = zero_doppler_times(truth.trajectory, truth.targets_above_road(crs), config, t)
    patches.local_expected_xy = np.array([a.inverse().apply(p[:2]) for a, p in
                                          zip(local_alignments(ev.errors, t0), true, strict=True)])
    ev.patches, ev.reference_patches = patches, reference_patches
    ev.reflectors = measure_reflectors(patches, ev.range_dir, reference_patches)
    return ev
