"""The steering's relation to the yaw rate, fitted to the drive's own turns: understeer gradient and yaw lag.

A real car steers more than the kinematic bicycle's ``atan(L omega / v)`` in a turn: the linear single-track
model's steady state adds ``K a_y`` with ``a_y = v omega`` (K = m / L (b / C_f - a / C_r), rad per m/s^2). And its
yaw rate lags the steering: ``delta ~ G (omega + tau omega')`` with ``G = L / v + K v``. SAR-MIN's steering update
is the kinematic steady state (``models.road_wheel_angle``). Per sample the steering measures the yaw rate ~30x
more precisely than a gyro, and with the gyros it measures the speed (``v = omega G``), so a car that does not
steer as the model says bends the track and sets the wheels' scale: on test3 with tyre slip (seed 0) the scale
came out 0.71 % long with the steering, 0.01 % without it. :func:`fit_understeer` measures K and the lag on a
pass without the steering, by regressing the steering on the gyros' yaw rate and its rate of change; where
either is shown, SAR-MIN leaves the steering out (``nav.navigate.sarmin_with_fits``). Navigating with the
fitted K and the steering moved by the lag was tried: on urban with tyre slip its track was 28.9 cm off after a
rigid alignment, 20.4 cm with the kinematic model, 8.3 cm without the steering.

The fit's yaw rate is the gyros' own (their mean, less the first pass's bias estimates, averaged over
``GYRO_WINDOW_S``), not the filter's, which follows the steering.

Why not a filter state: the steering update's regressor ``v omega`` would be the filter's own yaw rate, whose
error is correlated with the innovation it multiplies. On a straight drive (test1, ``omega`` < 1.2 mrad/s) that
errors-in-variables drift took K to -0.036 at "13 sigma".
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from . import models as m
from .inputs import NavInputs
from .wheel_speeds import GYRO_WINDOW_S, running_mean

Array = NDArray[np.float64]



@dataclass(frozen=True)
class UndersteerFit:
    """K fitted to one drive's steering (rad per m/s^2), its 1-sigma, the yaw lag, and what they rest on."""

    gradient: float
    std: float
    #: the regression's, counting its correlated residual and the first pass's speed scale (see fit_understeer)
    yaw_lag_coefficient_s2: float  #: T in delta = ... + T omega' (rad per rad/s^2)
    yaw_lag_coefficient_std_s2: float
    yaw_lag_s: float  #: T / G at the drive's median speed: how far the steering leads the yaw rate
    samples: int  #: steering samples above the steering model's minimum speed
    effective_samples: float  #: after the residual's serial correlation
    lateral_accel_rms_mps2: float  #: about its mean: the excitation that makes K observable
    residual_rms_rad: float
    #: the slope of the steering against the kinematic angle atan(L omega / v) alone: 1 plus understeer's K v^2 / L
    gain: float = 1.0
    gain_std: float = 0.0
    gain_speed_mps: float = 0.0  #: the speed whose K v^2 / L the gain holds: RMS, weighted as the slope weighs
    #: the gyros' yaw rate about its mean, RMS, and the steering's correlation with the kinematic angle: on a straight
    #: drive the gyros' errors are most of the kinematic angle's variation, and the gain reads ~0 (test1: 0.00 +- 0.01,
    #: the correlation ~0, the yaw rate 0.5 mrad/s RMS)
    yaw_rate_rms_radps: float = 0.0
    gain_correlation: float = 0.0
    steering_left_out: bool = False  #: the fit showed another steering: SAR-MIN navigated without it
    reason: str = ""

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


def gyro_yaw_rate(inputs: NavInputs, t: Array, x: Array, at: Array) -> Array:
    """Mean yaw rate (rad/s) of the gyros at times ``at`` (s, any shape): each gyro less its bias state
    ``x[:, 5 + i]`` at ``t``, as running means over ``GYRO_WINDOW_S`` of samples placed at their samples' mean
    time (so a window is never off-centre, which would show as a yaw lag), interpolated; NaN outside a gyro's
    span."""
    rates = []
    for i, g in enumerate(inputs.gyros):
        corrected = g.z[:, 0] - np.interp(g.t, t, x[:, m.N_KINEMATIC + i])
        mean = running_mean(g.t, corrected, GYRO_WINDOW_S)
        if mean is not None:
            rates.append(np.interp(at, *mean, left=np.nan, right=np.nan))
    if not rates:
        return np.full(np.shape(at), np.nan)
    stacked = np.stack(rates)
    seen = np.isfinite(stacked).sum(axis=0)
    return np.where(seen > 0, np.nansum(stacked, axis=0) / np.maximum(seen, 1), np.nan)


def fit_understeer(inputs: NavInputs, t: Array, x: Array, wheelbase_m: float, min_speed_mps: float,
                   speed_scale_std: float = 0.0) -> UndersteerFit | None:
    """Least-squares K and T in ``z - atan(L omega / v) = c + K v omega + T omega'`` over the steering samples.

    ``t`` (K,) s and ``x`` (K, n): the first pass's SAR-MIN states (see :mod:`.models`); its speed and gyro
    biases are used, the yaw rate is the gyros' (:func:`gyro_yaw_rate`). The offset ``c`` stands in for the
    filter's steering offset, which was estimated together with the first pass's K; ``T omega'`` takes up
    the transient: the yaw rate lags the steering (on the simulator's full vehicle in an S-bend the steady-state
    model alone leaves 1.6 mrad RMS, this term 0.03 mrad; K itself moves by 1 %). The std counts the
    residual's serial correlation (lag-1 autocorrelation rho: N (1 - rho) / (1 + rho) independent samples), and
    the first pass's speed scale error (1-sigma ``speed_scale_std``, a fraction): the steering and the gyros
    together measure the speed (``v = omega G``), so at a steady speed a scale error eps reads as
    ``K = L eps / v^2`` (0.1 % at 4 m/s: 1.8e-4; on the kinematic test3 drives K came out 1.9-2.7e-4 at "9 sigma"
    without this term, and applying it took the steering's own measure of the speed away: scale -0.06 -> -0.11 %).
    None without usable steering.
    """
    st = inputs.steering
    if st is None or len(t) < 2 or not inputs.gyros:
        return None
    inside = (st.t >= t[0] + 2 * GYRO_WINDOW_S) & (st.t <= t[-1] - 2 * GYRO_WINDOW_S)
    ts, z = st.t[inside], st.z[inside, 0]
    v = np.interp(ts, t, x[:, m.V])
    # The kinematic part takes the yaw rate of the window at the sample, the regressors that of the windows
    # either side: their noise is independent, so it does not correlate the residual with a regressor (with one
    # yaw rate in both, -L sigma_w^2 / var(v omega) took K to -0.10 on a straight drive); it only shrinks K
    # towards 0 where the turns are too weak to show it.
    h = GYRO_WINDOW_S
    w, w_after, w_before = gyro_yaw_rate(inputs, t, x, np.stack([ts, ts + h, ts - h]))
    use = (v >= min_speed_mps) & np.isfinite(w) & np.isfinite(w_after) & np.isfinite(w_before)
    if use.sum() < 10:
        return None
    v, w, z = v[use], w[use], z[use]
    w_side, w_dot = 0.5 * (w_after[use] + w_before[use]), (w_after[use] - w_before[use]) / (2.0 * h)
    a = v * w_side
    r = z - np.arctan(wheelbase_m * w / v)
    design = np.stack([np.ones_like(a), a - a.mean(), w_dot - w_dot.mean()], axis=1)
    coef, *_ = np.linalg.lstsq(design, r, rcond=None)
    res = r - design @ coef
    n = len(r)
    rho = float(np.clip(np.corrcoef(res[:-1], res[1:])[0, 1], 0.0, 0.999)) if n > 2 and res.std() > 0 else 0.0
    n_eff = max(n * (1.0 - rho) / (1.0 + rho), 2.0)
    rms = float(np.sqrt(np.mean(res**2)))
    normal = design.T @ design
    v_mid = float(np.median(v))
    if np.linalg.matrix_rank(normal) == 3:
        std, lag_std = rms * np.sqrt(n / n_eff * np.diag(np.linalg.inv(normal))[1:])
        std = float(np.hypot(std, wheelbase_m * speed_scale_std / v_mid**2))
    else:
        std = lag_std = np.inf
    lag = float(coef[2]) / (wheelbase_m / v_mid + float(coef[1]) * v_mid)
    kinematic = np.arctan(wheelbase_m * w_side / v)
    gain, gain_std = steering_gain(z, kinematic)
    weight = (kinematic - kinematic.mean()) ** 2
    gain_speed = float(np.sqrt(np.sum(weight * v**2) / np.sum(weight))) if np.sum(weight) > 0 else v_mid
    return UndersteerFit(float(coef[1]), float(std), float(coef[2]), float(lag_std), lag, n, float(n_eff),
                         float(np.std(a)), rms, gain, gain_std, gain_speed, float(np.std(w_side)),
                         float(np.corrcoef(z, kinematic)[0, 1]) if np.std(z) > 0 and np.std(kinematic) > 0 else 0.0)


def steering_gain(z: Array, kinematic: Array) -> tuple[float, float]:
    """Least-squares slope (and its 1-sigma, counting the residual's serial correlation) of the road-wheel angle
    ``z`` (rad) against the kinematic bicycle's ``kinematic`` (rad) at the same samples, with an offset."""
    design = np.stack([np.ones_like(kinematic), kinematic - kinematic.mean()], axis=1)
    coef, *_ = np.linalg.lstsq(design, z, rcond=None)
    res = z - design @ coef
    spread = float(np.sum((kinematic - kinematic.mean()) ** 2))
    if spread <= 0 or len(z) < 3:
        return float(coef[1]), float("inf")
    rho = float(np.clip(np.corrcoef(res[:-1], res[1:])[0, 1], 0.0, 0.999)) if res.std() > 0 else 0.0
    return float(coef[1]), float(np.sqrt(np.mean(res**2) / spread * (1.0 + rho) / (1.0 - rho)))
