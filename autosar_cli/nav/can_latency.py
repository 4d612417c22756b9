"""The CAN bus's time offset, measured against the IMUs' yaw rate: how much later than their tables the CAN signals
are stamped.

A logger that stamps CAN frames on arrival, on another clock than the IMUs' and the GNSS's, puts every CAN signal
(wheel speeds, steering, the ECUs' yaw rates) late by one offset that no sensor table states. SAR-MIN takes the
tables' ``latency_s`` on trust; the whole bus 40 ms later than they say put test1's worst reflector along the track
1.48 -> 3.66 cm off (median of seeds 0-9, full vehicle; docs/SENSOR_ERRORS.md).

The measurement needs no model of the car: a CAN gyro and an IMU gyro measure the same yaw rate. At each CAN gyro
sample ``t`` (its table's latency removed)

    z(t) = (1 + s) omega_imu(t - d) + b

with ``omega_imu`` the IMUs' mean yaw rate, both sides averaged over :data:`TURN_WINDOW_S`, ``s`` and ``b``
each CAN gyro's own scale and bias. ``d``, the bus's delay beyond the tables, is the one that leaves the least
residual over a search of ±:data:`SEARCH_S`, refined by the linearised fit about it (``omega_imu'``'s coefficient),
whose std counts the residual's serial correlation. What measures it is the yaw rate's change: a straight drive
leaves it unmeasured. The policy (whether the samples move) is in :mod:`.navigate`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np
from numpy.typing import NDArray

from .inputs import Measurements, NavInputs
from .wheel_speeds import effective_std, running_mean

Array = NDArray[np.float64]

#: both yaw rates are averaged over this (s) before they are compared (see :func:`fit_can_latency`)
TURN_WINDOW_S = 0.25
#: the delay is searched for within ± this (s) on a grid of SEARCH_STEP_S
SEARCH_S = 0.2
SEARCH_STEP_S = 0.005
#: the averaged CAN samples are compared every this (s): closer ones, averaged over TURN_WINDOW_S, repeat each other
COMPARE_STEP_S = 0.05
#: fewer CAN gyro samples than this leave it unmeasured
MIN_SAMPLES = 500


@dataclass(frozen=True)
class CanLatencyFit:
    """How much later than their tables state the CAN signals refer to: ``delay_s`` (a sample stamped ``t`` refers to
    ``t - latency_s - delay_s``), its 1-sigma, and what it rests on."""

    delay_s: float
    std_s: float
    can_gyros: tuple[str, ...]  #: the CAN gyros compared
    imu_gyros: tuple[str, ...]  #: ... against these IMUs' mean
    samples: int
    yaw_acceleration_rms_radps2: float  #: how much the drive shows: the IMUs' yaw rate's change, RMS
    applied: bool = False
    reason: str = ""

    def to_dict(self) -> dict[str, object]:
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else list(v) if isinstance(v, tuple) else v)
                for k, v in asdict(self).items()}


def fit_can_latency(inputs: NavInputs, can_gyros: list[str], imu_gyros: list[str]) -> CanLatencyFit | None:
    """The CAN bus's delay beyond the tables, measured by the gyros named ``can_gyros`` against the mean of those named
    ``imu_gyros`` (see the module's docstring); None where either is missing or under :data:`MIN_SAMPLES`."""
    can = [g for g in inputs.gyros if g.name in can_gyros]
    imu = [g for g in inputs.gyros if g.name in imu_gyros]
    means = [running_mean(g.t, g.z[:, 0], TURN_WINDOW_S) for g in imu]
    means = [mean for mean in means if mean is not None and len(mean[0]) > 2]
    if not can or not means:
        return None
    lo = max(float(mean[0][0]) for mean in means) + SEARCH_S
    hi = min(float(mean[0][-1]) for mean in means) - SEARCH_S

    inside = [(g, (g.t > lo) & (g.t < hi)) for g in can]
    inside = [(g, keep) for g, keep in inside if keep.sum() > 2]
    if sum(int(keep.sum()) for _, keep in inside) < MIN_SAMPLES:
        return None

    # both sides averaged alike over TURN_WINDOW_S: what is left is the turns' yaw rate, which both gyros see alike;
    # faster content is their noise and the body's roll and pitch, which each one's mounting leaks differently
    means_can = [(g, running_mean(g.t[keep], g.z[keep, 0], TURN_WINDOW_S)) for g, keep in inside]
    smoothed = [(g, _every(mean, COMPARE_STEP_S)) for g, mean in means_can if mean is not None and len(mean[0]) > 2]
    if not smoothed:
        return None

    def reference(at: Array) -> Array:
        return np.mean([np.interp(at, *mean) for mean in means], axis=0)

    def residual(d: float) -> tuple[Array, list[Array]]:
        parts, designs = [], []
        for _, (t, z) in smoothed:
            design = np.stack([reference(t - d), np.ones_like(t)], axis=1)
            coef, *_ = np.linalg.lstsq(design, z, rcond=None)
            parts.append(z - design @ coef)
            designs.append(coef)
        return np.concatenate(parts), designs

    grid = np.arange(-SEARCH_S, SEARCH_S + SEARCH_STEP_S / 2, SEARCH_STEP_S)
    cost = [float(np.sum(residual(d)[0] ** 2)) for d in grid]
    best = float(grid[int(np.argmin(cost))])
    # refined by the linearised model about the best: z - fit(best) = -(1 + s) omega'(t - best) delta
    res, coefs = residual(best)
    # the delay's column beside each gyro's own scale and bias (a column pair per gyro, zero on the others' rows)
    h = 1e-3
    rows = []
    for i, ((_, (t, _)), coef) in enumerate(zip(smoothed, coefs, strict=True)):
        slope = (reference(t - best + h) - reference(t - best - h)) / (2 * h)
        row = np.zeros((len(t), 1 + 2 * len(smoothed)))
        row[:, 0], row[:, 1 + 2 * i], row[:, 2 + 2 * i] = -coef[0] * slope, reference(t - best), 1.0
        rows.append(row)
    blocks = np.concatenate(rows)
    coef, *_ = np.linalg.lstsq(blocks, res, rcond=None)
    std = float(effective_std(blocks, res - blocks @ coef)[0])
    accel = blocks[:, 0]
    return CanLatencyFit(best + float(coef[0]), std, tuple(g.name for g, _ in smoothed), tuple(g.name for g in imu),
                         int(len(res)), float(np.sqrt(np.mean(accel**2))))


def imus_moved(inputs: NavInputs, late_s: float, imus: list[str]) -> NavInputs:
    """``inputs`` with the gyros named ``imus`` and the 6-DoF IMU (where it is one of them) moved ``late_s`` (s)
    earlier: their stamps ran that late."""
    attitude = inputs.attitude_imu
    if attitude is not None and attitude.name in imus:
        attitude = replace(attitude, t=attitude.t - late_s)
    return replace(inputs, attitude_imu=attitude,
                   gyros=[replace(g, t=g.t - late_s) if g.name in imus else g for g in inputs.gyros])


def _every(samples: tuple[Array, Array], step_s: float) -> tuple[Array, Array]:
    """Every sample ``step_s`` (s) apart of ``samples`` (times s, values)."""
    t, z = samples
    k = max(int(round(step_s / float(np.median(np.diff(t))))), 1) if len(t) > 1 else 1
    return t[::k], z[::k]


def delayed_can(inputs: NavInputs, delay_s: float, can_gyros: list[str]) -> NavInputs:
    """``inputs`` with every CAN signal (wheel speeds, steering, the gyros named ``can_gyros``) moved ``delay_s`` (s)
    earlier: to the instants they refer to."""
    def moved(meas: Measurements | None) -> Measurements | None:
        return None if meas is None else replace(meas, t=meas.t - delay_s)

    return replace(inputs, wheels=moved(inputs.wheels), steering=moved(inputs.steering),
                   gyros=[moved(g) if g.name in can_gyros else g for g in inputs.gyros])  # type: ignore[misc]
