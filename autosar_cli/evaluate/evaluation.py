"""One image + the trajectory it was focused along, evaluated against the truth (in memory, no files written).

Inputs are expressed in the image's ENU frame: the truth trajectory and targets are re-expressed in the
image's geodetic origin. Without a truth sidecar only the truth-free image metrics (entropy, contrast)
are computed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

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
    summarise_reflectors,
)
from autosar_cli.evaluate.trajectory_metrics import (
    TrajectoryErrors,
    TrajectoryMetrics,
    common_instants,
    phase_centre_lever_arm,
    trajectory_errors,
    trajectory_metrics,
)
from autosar_cli.nav.baselines import from_truth
from autosar_cli.nav.trajectory import Trajectory
from autosar_cli.sar.focus import FocusOptions
from autosar_cli.sim.scene import KINDS
from autosar_cli.sim.truth import TruthTargets, read_targets
from autosar_cli.store.drive import Drive
from autosar_cli.store.image import FocusedImage

#: Scene lines whose straightness is measured (kinds of autosar_cli.sim.scene.KINDS).
LINE_KINDS = ("facade", "kerb")


@dataclass
class Truth:
    """The simulator's ground truth in an image's ENU frame."""

    path: Path
    trajectory: Trajectory
    targets: TruthTargets


def load_truth(path: str | Path, image: FocusedImage, config: Config) -> Truth:
    """Read a truth sidecar and re-express its trajectory and targets in ``image``'s origin."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{p}: no such truth sidecar")
    return Truth(p, from_truth(str(p), image.origin, config), read_targets(p, image.origin))


@dataclass(frozen=True)
class ImageMetrics:
    """Truth-free focus quality of the full image, plus the straightness of known lines (with truth)."""

    pixels: int  #: pixels that received pulses
    entropy: float  #: nats, -sum p ln p of the normalised intensity
    contrast: float  #: std(I) / mean(I)
    straightness: dict[str, Straightness] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"pixels": self.pixels, "entropy": self.entropy, "contrast": self.contrast,
                "straightness": {k: v.to_dict() for k, v in self.straightness.items()}}


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
    range_dir: tuple[float, float] = (0.0, 1.0)
    notes: list[str] = field(default_factory=list)
    inputs: dict[str, str] = field(default_factory=dict)

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
                             "entropy": self.image_metrics.entropy, "contrast": self.image_metrics.contrast}
        s.update(summarise_reflectors(self.reflectors))
        for kind in LINE_KINDS:
            st = self.image_metrics.straightness.get(kind)
            s[f"straightness_{kind}_m"] = st.rms_residual_m if st else nan
        return s

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready metrics (metrics.json)."""
        d: dict[str, Any] = {"format": "autosar-evaluation", "format_version": 1, "method": self.method,
                             "inputs": dict(self.inputs), "truth": str(self.truth.path) if self.truth else None,
                             "summary": self.summary(), "image": self.image_metrics.to_dict(),
                             "trajectory": self.trajectory_metrics.to_dict() if self.trajectory_metrics else None,
                             "alignment": self.alignment.to_dict() if self.errors else None,
                             "range_direction": list(self.range_dir),
                             "reflectors": [r.to_dict() for r in self.reflectors], "notes": list(self.notes)}
        return d


def radar_times(drive_path: str | Path) -> NDArray[np.int64]:
    """Frame start times (ns) of a drive's radar."""
    with Drive(drive_path) as d:
        return np.asarray(d.radar().t_ns, dtype=np.int64)


def options_from_image(image: FocusedImage, config: Config) -> FocusOptions:
    """The focus options an image was made with (from its parameters; config defaults for anything missing)."""
    names = {f.name for f in fields(FocusOptions)}
    return FocusOptions.from_config(config, **{k: v for k, v in image.params.items() if k in names})


def range_direction(image: FocusedImage, trajectory: Trajectory, config: Config) -> tuple[float, float]:
    """Horizontal unit vector of ground range: the auto grid's across axis (perpendicular to the mean track,
    on the radar side). For an explicit box grid it is derived from the track the same way."""
    if str(image.params.get("grid", "auto")).strip().lower() == "auto":
        a = np.asarray(image.grid.across, dtype=np.float64)
    else:
        xy = trajectory.rear_axle_enu
        _, _, vt = np.linalg.svd(xy - xy.mean(axis=0), full_matrices=False)
        along = vt[0] if np.dot(vt[0], xy[-1] - xy[0]) > 0 else -vt[0]
        left = np.array([-along[1], along[0]])
        side = 1.0 if math.sin(math.radians(config.radar.mounting.yaw_deg)) > 0 else -1.0
        a = left * side
    return (float(a[0]), float(a[1]))


def image_metrics(image: FocusedImage, truth: Truth | None, alignment: Se2) -> ImageMetrics:
    """Entropy and contrast over the data pixels; with truth, the straightness of the facade and kerb lines
    (their true scatterers mapped into the image by ``alignment.inverse()``)."""
    mask = data_mask(image.image)
    straight: dict[str, Straightness] = {}
    if truth is not None:
        inv = alignment.inverse()
        for kind in LINE_KINDS:
            sel = truth.targets.kind == KINDS.index(kind)
            if sel.sum() >= 2:
                straight[kind] = line_straightness(image, inv.apply(truth.targets.position_enu[sel, :2]), kind)
    return ImageMetrics(int(mask.sum()), image_entropy(image.image, mask), image_contrast(image.image, mask),
                        straight)


def evaluate_image(image: FocusedImage, trajectory: Trajectory, drive_path: str | Path, config: Config,
                   truth: Truth | None = None, *, patches: ReflectorPatches | None = None,
                   reference_patches: ReflectorPatches | None = None,
                   inputs: dict[str, str] | None = None) -> Evaluation:
    """Evaluate ``image``, focused from ``drive_path`` along ``trajectory``, against ``truth``.

    Trajectory metrics at the radar frame times; the SE(2) alignment; every corner reflector on fine
    patches (focused here unless ``patches`` / ``reference_patches`` are given: they must have been
    focused with the same alignment, e.g. by :func:`autosar_cli.evaluate.compare.compare`); the image
    metrics. ``reference_patches``: the truth trajectory's patches (the peak-loss reference).
    """
    ev = Evaluation(trajectory.method, image, trajectory, image_metrics(image, None, Se2()),
                    range_dir=range_direction(image, trajectory, config), inputs=dict(inputs or {}))
    if truth is None:
        ev.notes.append("no truth sidecar: only the truth-free image metrics (entropy, contrast) are reported")
        return ev
    ev.truth = truth
    lever = phase_centre_lever_arm(config)
    t = common_instants(trajectory, truth.trajectory, radar_times(drive_path))
    ev.errors = trajectory_errors(trajectory, truth.trajectory, lever, t)
    ev.trajectory_metrics = trajectory_metrics(trajectory, ev.errors)
    ev.image_metrics = image_metrics(image, truth, ev.alignment)
    crs = truth.targets.corner_reflectors
    if len(crs) == 0:
        ev.notes.append("the truth lists no corner reflector")
        return ev
    names = truth.targets.corner_reflector_names()
    true = truth.targets.position_enu[crs]
    options = options_from_image(image, config)
    if patches is None:
        patches = focus_patches(drive_path, trajectory, config, options, names, true, ev.alignment)[0]
    if reference_patches is None:
        if trajectory.method == "truth":
            reference_patches = patches
        else:
            reference_patches = focus_patches(drive_path, truth.trajectory, config, options, names, true)[0]
    ev.patches, ev.reference_patches = patches, reference_patches
    ev.reflectors = measure_reflectors(patches, ev.range_dir, reference_patches)
    return ev
