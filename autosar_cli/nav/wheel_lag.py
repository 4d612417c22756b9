"""How far behind their time stamps the wheel speeds are, fitted to the drive against the GNSS velocity.

An ABS ECU does not measure a wheel's speed at an instant: it divides a few tone-ring pitches by the time their
edges took (``N`` edges of a ring of ``Z`` teeth on a wheel of radius ``r``), at the next CAN cycle. So each value
is the mean speed over the last ``N 2 pi r / Z`` metres of travel, and it describes the instant about
``c / v`` before its time stamp, ``c = (N + 1) / 2 * 2 pi r / Z`` (half the window, plus half a pitch on average
since the newest edge): 0.15 m for 6 edges of a 48-tooth ring on a 0.33 m wheel, so 150 ms at 1 m/s. Under
acceleration ``a`` the speed then reads ``a c / v`` low. In urban's stop and go that bent SAR-MIN's track by
38 cm (tone-ring wheel speeds the only effect of the full vehicle model); with the samples moved to
``t - c / v``, 7 cm.

The fit needs no ECU data sheet: over the samples above ``min_speed_mps`` it regresses the rear wheels' mean
speed minus the GNSS speed on the GNSS speed (a common scale) and on ``-a / v`` (``a`` the wheels' own
acceleration over 0.2 s). A drive at steady speed cannot show ``c``: its std is then large and the samples stay.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from .inputs import Measurements, NavInputs

Array = NDArray[np.float64]

ACCEL_WINDOW_S = 0.2  # the wheels' acceleration: a running mean of their speed over this, differentiated
MAX_DELAY_S = 0.5  # a sample is never moved further: below ~0.3 m/s the ECU's window spans its timeout


@dataclass(frozen=True)
class WheelLagFit:
    """The wheel speeds' lag ``c / v`` fitted to one drive: ``c`` (m), its 1-sigma, and what it rests on."""

    lag_distance_m: float
    std_m: float
    samples: int  #: GNSS velocity samples above the minimum speed
    accel_over_speed_rms: float  #: a / v about its mean (1/s): the excitation that makes c observable
    residual_rms_mps: float
    applied: bool = False
    reason: str = ""

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


def fit_wheel_lag(inputs: NavInputs, min_speed_mps: float = 1.0) -> WheelLagFit | None:
    """Least-squares ``c`` in ``v_rear - v_gnss = s v_gnss - c a / v_gnss`` over the GNSS velocity samples
    (``v_rear`` the rear wheels' mean speed at each GNSS instant, m/s); None without wheels, GNSS velocity, or
    10 samples above ``min_speed_mps``."""
    wheels, gnss = inputs.wheels, inputs.gnss_velocity
    if wheels is None or gnss is None or len(wheels.t) < 3:
        return None
    rear = 0.5 * (wheels.z[:, 2] + wheels.z[:, 3])
    k = max(int(round(ACCEL_WINDOW_S / float(np.median(np.diff(wheels.t))))), 2)
    if len(rear) <= k:
        return None
    kernel = np.full(k, 1.0 / k)
    t_mean, v_mean = np.convolve(wheels.t, kernel, "valid"), np.convolve(rear, kernel, "valid")
    accel = np.gradient(v_mean, t_mean)
    v_gnss = np.hypot(gnss.z[:, 0], gnss.z[:, 1])
    use = (v_gnss >= min_speed_mps) & (gnss.t > t_mean[0]) & (gnss.t < t_mean[-1])
    if use.sum() < 10:
        return None
    vg, ts = v_gnss[use], gnss.t[use]
    a_over_v = np.interp(ts, t_mean, accel) / vg
    design = np.stack([vg, -a_over_v], axis=1)
    y = np.interp(ts, wheels.t, rear) - vg
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    res = y - design @ coef
    rms = float(np.sqrt(np.mean(res**2)))
    normal = design.T @ design
    std = rms * np.sqrt(np.linalg.inv(normal)[1, 1]) if np.linalg.matrix_rank(normal) == 2 else np.inf
    return WheelLagFit(float(coef[1]), float(std), int(use.sum()), float(np.std(a_over_v)), rms)


def lag_compensated_wheels(wheels: Measurements, fit: WheelLagFit) -> Measurements:
    """The wheel samples moved to the instants they describe, ``t - c / v`` (``v`` the sample's mean wheel speed,
    at most ``MAX_DELAY_S`` back; a standing car's samples stay), in time order."""
    v = np.mean(np.abs(wheels.z), axis=1)
    delay = np.where(v > 0, np.clip(fit.lag_distance_m / np.maximum(v, 1e-9), -MAX_DELAY_S, MAX_DELAY_S), 0.0)
    moved = wheels.t - delay
    order = np.argsort(moved, kind="stable")
    return Measurements(wheels.name, moved[order], wheels.z[order], wheels.sigma)
