"""The rear tyres' slip angle, fitted to a drive: how far the rear axle's course turns from the body's heading.

In a turn the rear tyres carry the lateral force at a slip angle alpha = g v omega (g = m a / (L C_r) for a linear
tyre, rad per m/s^2 of lateral acceleration): the rear axle moves along psi - alpha, psi the body's heading that
the gyros integrate. A filter that moves the rear axle along psi drifts sideways by v alpha: 3 mrad RMS on test3's
S-bends at 0.44 m/s^2 RMS, 1.1 cm per 3.7 m of travel, which its GNSS corrects only slowly.

The GNSS velocity sees it. On a pass of SAR-MIN (whose heading follows the gyros: 0.5 mrad RMS from the body's
heading on test3 seed 2, against 2.9 from the rear axle's course), the antenna's measured velocity across the
body, minus what the pass predicts with the gain it used, is -v sin(dg v omega): a least-squares fit of those
residuals on -v^2 omega (and a constant, the heading's mean offset) gives dg and its std from the residuals'
scatter. The policy (whether the filter runs again with it) is in :mod:`.navigate`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from autosar_cli.nav import models as m
from autosar_cli.nav.inputs import NavInputs

Array = NDArray[np.float64]

#: GNSS velocity samples slower than this (m/s) are left out: the course is noise there.
MIN_SPEED_MPS = 1.0


@dataclass(frozen=True)
class RearSlipFit:
    """The rear-slip gain g (rad per m/s^2 of lateral acceleration) a drive shows."""

    gain: float  #: fitted g (the pass's own plus the increment the residuals show)
    std: float  #: its standard deviation
    samples: int  #: GNSS velocity samples used
    lateral_accel_rms_mps2: float  #: RMS of v omega over them
    residual_rms_mps: float  #: the across-body velocity residuals' RMS after the fit
    applied: bool = False
    reason: str = ""

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


def fit_rear_slip(inputs: NavInputs, t: Array, x: Array, gnss_lever_xy: tuple[float, float],
                  gain_used: float) -> RearSlipFit | None:
    """The rear-slip gain from the GNSS velocity against a SAR-MIN pass (states ``x`` (K, n) at ``t`` (K,), s since
    the inputs' t0) that used ``gain_used``; ``gnss_lever_xy``: the antenna from the rear axle (m, body frame).
    None without a GNSS velocity or with fewer than 20 samples above :data:`MIN_SPEED_MPS`."""
    vel = inputs.gnss_velocity
    if vel is None:
        return None
    inside = (vel.t >= t[0]) & (vel.t <= t[-1])
    tv, z = vel.t[inside], vel.z[inside]
    states = np.stack([np.interp(tv, t, x[:, k]) for k in (m.V, m.OMEGA)], axis=-1)
    psi = np.interp(tv, t, np.unwrap(x[:, m.PSI]))
    moving = states[:, 0] >= MIN_SPEED_MPS
    if moving.sum() < 20:
        return None
    tv, z, psi, states = tv[moving], z[moving], psi[moving], states[moving]
    X = np.zeros((len(tv), x.shape[1]))
    X[:, m.V], X[:, m.OMEGA], X[:, m.PSI] = states[:, 0], states[:, 1], psi
    predicted = m.point_velocity(X, gnss_lever_xy, gain_used)
    d = z - predicted
    across = -np.sin(psi) * d[:, 0] + np.cos(psi) * d[:, 1]
    v, w = states[:, 0], states[:, 1]
    design = np.stack([np.ones_like(v), -v * v * w], axis=-1)
    coef, *_ = np.linalg.lstsq(design, across, rcond=None)
    resid = across - design @ coef
    dof = max(len(across) - 2, 1)
    sigma2 = float(resid @ resid) / dof
    cov = sigma2 * np.linalg.inv(design.T @ design)
    return RearSlipFit(gain_used + float(coef[1]), math.sqrt(max(float(cov[1, 1]), 0.0)), int(len(tv)),
                       float(np.sqrt(np.mean((v * w) ** 2))), math.sqrt(sigma2))
