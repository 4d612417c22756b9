"""The road's grade along the drive, from the GNSS vertical velocity, and where it puts the radar.

SAR-MIN's track is planar: the rear axle's ground point, the body level. On a graded road the body tilts with it,
and a point ``H`` above the road sits ``H sin(theta)`` behind (uphill) the ground point below it horizontally,
``theta`` the grade's angle. Where the grade changes along the road (its vertical curvature ``theta'``) that offset
changes with travel, so the radar's horizontal speed differs from the ground track's by ``-H theta'`` of it: on
test1 with the simulator's road (a 1 % grade over a 120 m wavelength, theta' up to 5e-4 /m) and the radar 0.5 m up,
0.03 %. The residual-motion autofocus measured that on the simulator's exact, planar truth track: it scaled it by
+0.04 % at 4 sigma with the road's effects alone, by 0.00 % without (``benches/bench_af_truth.py``), and applied it
to the whole drive, where the curvature differs.

:func:`grade` fits the grade as a cubic spline in travelled distance (knots every ``KNOT_M``) to the GNSS vertical
velocity over the speed, weighted by the speed squared (the velocity's noise is the same at every speed), and keeps
it only where its variation along the drive is shown: its fit beats a constant grade by more than the chi-square
quantile at 3 sigma, the noise measured from the residuals. A constant grade moves every point alike and is left
out. :func:`grade_correction` gives the trajectory the offset as its :class:`~autosar_cli.types.MotionCorrection`:
``-H sin(theta(t))`` along the heading. Vertically nothing: the scene beside the car rises with the same road, so the
radar's height above it stays what the planar model says.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import BSpline
from scipy.special import chdtri

from autosar_cli.types import MotionCorrection, Trajectory

from .inputs import NavInputs

Array = NDArray[np.float64]

KNOT_M = 20.0  #: knot spacing of the grade's spline: a road's vertical curves are hundreds of metres in radius
MIN_SPEED_MPS = 1.0  #: vertical velocities below this speed say little of the grade and are left out
SIGNIFICANCE = 0.9973  #: the spline must beat a constant grade at this probability (3 sigma) to be applied


@dataclass(frozen=True)
class GradeFit:
    """The grade's fit to one drive: whether its variation shows, and what it rests on."""

    shown: bool
    samples: int
    knots: int
    chi2_gain: float  #: how much better than a constant grade the spline fits (in units of the noise variance)
    chi2_threshold: float
    variation_rms_rad: float  #: the fitted grade about its mean, RMS
    noise_mps: float  #: the vertical velocity's noise measured from the residuals

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


def grade(inputs: NavInputs, trajectory: Trajectory) -> tuple[Array | None, GradeFit | None]:
    """The road's grade (rad, uphill positive) at the trajectory's samples where the drive shows it varying (None
    where not), and the fit (None without vertical velocities above ``MIN_SPEED_MPS`` over two knot spans)."""
    vz = inputs.gnss_vertical_velocity
    if vz is None or len(trajectory.t_ns) < 2:
        return None, None
    t_traj = (trajectory.t_ns - inputs.t0_ns) / 1e9
    step = np.diff(t_traj) * 0.5 * (np.abs(trajectory.speed[1:]) + np.abs(trajectory.speed[:-1]))
    travel = np.concatenate([[0.0], np.cumsum(step)])
    inside = (vz.t >= t_traj[0]) & (vz.t <= t_traj[-1])
    speed = np.interp(vz.t[inside], t_traj, np.abs(trajectory.speed))
    use = speed >= MIN_SPEED_MPS
    s = np.interp(vz.t[inside][use], t_traj, travel)
    if use.sum() < 10 or s[-1] - s[0] < 2 * KNOT_M:
        return None, None
    y = vz.z[inside][use, 0] / speed[use]
    w = speed[use] ** 2
    spans = max(int(np.ceil((s[-1] - s[0]) / KNOT_M)), 1)
    inner = np.linspace(s[0], s[-1], spans + 1)
    knots = np.concatenate([[inner[0]] * 3, inner, [inner[-1]] * 3])
    design = BSpline.design_matrix(np.clip(s, inner[0], inner[-1]), knots, 3).toarray()
    sw = np.sqrt(w)
    coef, *_ = np.linalg.lstsq(design * sw[:, None], y * sw, rcond=None)
    chi2_spline = float(np.sum(w * (y - design @ coef) ** 2))
    chi2_const = float(np.sum(w * (y - np.sum(w * y) / np.sum(w)) ** 2))
    dof = len(y) - design.shape[1]
    noise_var = chi2_spline / max(dof, 1)  # of the vertical velocity (y * speed), m^2/s^2
    gain = (chi2_const - chi2_spline) / max(noise_var, 1e-12)
    threshold = float(chdtri(design.shape[1] - 1, 1.0 - SIGNIFICANCE))
    fitted = BSpline(knots, coef, 3)(np.clip(travel, inner[0], inner[-1]))
    fit = GradeFit(bool(gain > threshold), int(len(y)), int(design.shape[1]), float(gain), threshold,
                   float(np.std(fitted)), float(np.sqrt(noise_var)))
    return (fitted if fit.shown else None), fit


def grade_correction(trajectory: Trajectory, theta: Array, height_m: float, std_m: float = 0.002
                     ) -> MotionCorrection:
    """The horizontal offset of a body point ``height_m`` above the road from the planar track, ``-H sin(theta)``
    along the heading, at the trajectory's samples; ``theta`` (K,) rad from :func:`grade`, ``std_m`` its stated
    1-sigma."""
    back = -height_m * np.sin(theta)
    offset = np.stack([back * np.cos(trajectory.heading), back * np.sin(trajectory.heading),
                       np.zeros_like(back)], axis=-1)
    std = np.zeros_like(offset)
    std[:, :2] = std_m
    return MotionCorrection(trajectory.t_ns.copy(), offset, std)
