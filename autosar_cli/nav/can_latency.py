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
leaves it unmeasured. A CAN clock seconds off (a CAN logger's set wrong) lies beyond that search:
:func:`fit_can_clock` looks for it over ±:data:`CLOCK_SEARCH_S` first. The policy (whether the samples move) is in
:mod:`.navigate`.
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
#: a CAN clock off the IMUs' by more than the delay's search (a CAN logger's clock set wrong) is searched for within
#: +- this (s), on the compared samples' step
CLOCK_SEARCH_S = 30.0
#: ... and taken where the IMUs' yaw rate leaves at most this fraction of the CAN's unexplained there (1 - R^2: a drive
#: that turns, which both gyros see alike), and at most this fraction of what it leaves within +-SEARCH_S
CLOCK_MAX_UNEXPLAINED = 0.25
CLOCK_COST_RATIO = 0.25
#: the search fits every this-many-th lag of the compared samples' step first, then every lag about the best
COARSE_STEPS = 4


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


def fit_can_clock(inputs: NavInputs, can_gyros: list[str], imu_gyros: list[str]) -> float | None:
    """How late (s) the CAN gyros' yaw rate runs against the IMUs' where that lies beyond the delay's search
    (+-:data:`SEARCH_S`), found over +-:data:`CLOCK_SEARCH_S`: a CAN log whose logger's clock was set wrong, every CAN
    signal that much off; None where the best fit lies within the search, or is not decisive (it leaves over
    :data:`CLOCK_MAX_UNEXPLAINED` of the CAN yaw rate's variance unexplained: a drive that hardly turns; or over
    :data:`CLOCK_COST_RATIO` of what the best within the search leaves). Both sides averaged over
    :data:`TURN_WINDOW_S`, each CAN gyro fitted with its own scale and bias at every lag, over the samples whose lagged
    instant the IMUs cover (at least half)."""
    can = [g for g in inputs.gyros if g.name in can_gyros]
    means = [running_mean(g.t, g.z[:, 0], TURN_WINDOW_S) for g in inputs.gyros if g.name in imu_gyros]
    means = [mean for mean in means if mean is not None and len(mean[0]) > 2]
    if not can or not means:
        return None
    lo, hi = max(float(m[0][0]) for m in means), min(float(m[0][-1]) for m in means)
    if hi - lo <= 0:
        return None
    ref_t = np.arange(lo, hi, COMPARE_STEP_S / 5)
    ref_z = np.mean([np.interp(ref_t, *mean) for mean in means], axis=0)
    series = [_every(mean, COMPARE_STEP_S) for g in can
              if (mean := running_mean(g.t, g.z[:, 0], TURN_WINDOW_S)) is not None and len(mean[0]) > 2]
    if sum(len(t) for t, _ in series) < MIN_SAMPLES / 5:  # compared every COMPARE_STEP_S, not at the bus's rate
        return None
    steps = int(round(CLOCK_SEARCH_S / COMPARE_STEP_S))
    grid = np.arange(-steps, steps + 1) * COMPARE_STEP_S
    near = np.abs(grid) <= SEARCH_S + COMPARE_STEP_S / 2
    cost = np.full(len(grid), np.inf)

    def fit_at(ks: Array) -> None:
        """``cost`` at the lags ``grid[ks]`` not fitted yet."""
        for k in ks[np.isinf(cost[ks])]:
            d = grid[k]
            sse, syy, n, needed = 0.0, 0.0, 0, 0
            for t, z in series:
                keep = (t - d >= lo) & (t - d <= hi)
                needed += len(t)
                if keep.sum() < 3:
                    continue
                x, y = np.interp(t[keep] - d, ref_t, ref_z), z[keep]
                x, y = x - x.mean(), y - y.mean()
                sxx = float(x @ x)
                syy += float(y @ y)
                sse += float(y @ y) - (float(x @ y) ** 2 / sxx if sxx > 0 else 0.0)
                n += int(keep.sum())
            if 2 * n >= needed and syy > 0:
                cost[k] = sse / syy  # the part of the CAN yaw rate the IMUs' leaves unexplained there
            else:
                cost[k] = np.nan  # fitted, not measured: too few samples overlap

    # every COARSE_STEPS-th lag and those within the delay's search, then every lag about the coarse best: the
    # yaw rate's turns last seconds, so its basin spans several coarse steps
    fit_at(np.flatnonzero(near | (np.arange(len(grid)) % COARSE_STEPS == steps % COARSE_STEPS)))
    if np.isfinite(cost).any():
        k = int(np.nanargmin(np.where(np.isinf(cost), np.nan, cost)))
        fit_at(np.arange(max(k - COARSE_STEPS, 0), min(k + COARSE_STEPS + 1, len(grid))))
    cost = np.where(np.isfinite(cost), cost, np.inf)
    if not np.isfinite(cost).any():
        return None
    best = int(np.argmin(cost))
    if near[best] or not (cost[best] <= CLOCK_COST_RATIO * np.min(cost[near])
                          and cost[best] <= CLOCK_MAX_UNEXPLAINED):
        return None
    return float(grid[best])


def wheels_late_against_gnss(inputs: NavInputs, late_s: float) -> bool:
    """Whether the wheel speeds fit the GNSS speed with ``late_s`` (s) removed from their stamps much better than as
    stamped (leave at most :data:`CLOCK_COST_RATIO` of what they leave unexplained so): the CAN is off the GNSS too,
    not the IMUs off both (a drive whose speed changes little, or no GNSS velocity: False)."""
    wheels, vel = inputs.wheels, inputs.gnss_velocity
    if wheels is None or vel is None or len(wheels.t) < 2:
        return False
    gnss_speed = np.hypot(vel.z[:, 0], vel.z[:, 1])
    unexplained = []
    for d in (0.0, late_s):
        keep = (vel.t >= wheels.t[0] - d) & (vel.t <= wheels.t[-1] - d) & np.isfinite(gnss_speed)
        if keep.sum() < 10:
            return False
        x, y = np.interp(vel.t[keep] + d, wheels.t, wheels.z.mean(axis=1)), gnss_speed[keep]
        x, y = x - x.mean(), y - y.mean()
        sxx, syy = float(x @ x), float(y @ y)
        if sxx <= 0 or syy <= 0:
            return False
        unexplained.append(1.0 - float(x @ y) ** 2 / (sxx * syy))
    return unexplained[1] <= CLOCK_COST_RATIO * unexplained[0]


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
