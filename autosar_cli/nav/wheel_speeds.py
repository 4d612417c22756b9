"""What the wheel speeds get wrong, fitted to each drive: their lag, and rolling radii that change with load.

SAR-MIN's wheel model (``models.wheel_speeds``) is the no-slip bicycle with one constant scale per wheel. A real
car's wheel speeds differ from it in three ways that bend the track:

* **Lag.** An ABS ECU divides a few tone-ring pitches by the time their edges took (``N`` edges of a ring of
  ``Z`` teeth on a wheel of radius ``r``), at the next CAN cycle: each value is the mean speed over the last
  ``N 2 pi r / Z`` metres and describes the instant about ``c / v`` before its stamp,
  ``c = (N + 1) / 2 * 2 pi r / Z`` (0.15 m for 6 edges of a 48-tooth ring on a 0.33 m wheel). Under acceleration
  ``a`` the speed then reads ``a c / v`` low. In urban's stop and go that alone bent the track by 38 cm.
  After a standstill the first values' window still reaches back across it (the edges before the stop): they
  read far below the truth until the wheel has turned a window's length again (urban's pull-away: 4 cm lost in
  0.7 s), so :func:`without_restart_windows` leaves them out.
* **Longitudinal slip and load transfer.** A driven or braked tyre turns faster or slower than it rolls, in
  proportion to its force over its load, and the axle the acceleration loads rolls on a smaller radius. Both
  make an axle's speed read ``(1 + k a)`` times the truth, ``k`` differing between drive (a > 0) and braking
  (a < 0): on the simulator's rear-driven car 1.4 % per m/s^2 on the rear axle under drive.
* **Lateral load transfer.** In a turn the outer wheels carry more load and roll on a smaller radius: the right
  wheel reads ``(1 + g a_y)``, the left ``(1 - g a_y)`` times the truth (``a_y = v omega``, left turns positive;
  ``g = f m h s / (T k_z R)`` with ``f`` the deflection's share in the rolling radius, ``h`` the CoG height,
  ``s`` the axle's share of the transfer, ``T`` the track, ``k_z`` the tyre's vertical stiffness: ~0.1 % per
  m/s^2). The wheels then show a yaw rate 1-2 % larger than the gyros in every turn; the filter, which trusts
  both, put the wheels' common scale 0.3 % off on test3 (16 cm over the drive, with the steering left out).

:func:`fit_wheel_speeds` needs no data sheet. Against the GNSS velocity (moved to the rear axle with the gyros'
yaw rate) it regresses each axle's mean speed on the speed (a scale), ``-a / v`` (the lag, one ``c`` for all
wheels) and ``a v`` split at ``a = 0`` (the slip gains); against the gyros it regresses each axle's right-left
difference, less the bicycle's, on a constant (the gyros' bias), the speed (the two scales' difference) and
``a_y`` times the axle's speed (the load gain). The lateral regressor takes the gyros' yaw rate of the windows
either side of each sample, the bicycle's difference that of the window at it: their noise is independent, so it
does not correlate the residual with the regressor (with one yaw rate in both, test1's straight drive gave
g = -3.8 % at "15 sigma"). A drive that does not excite a term (steady speed: no ``c`` nor ``k``; straight: no
``g``) gives it a large std, and navigate leaves it out (``nav.navigate.wheel_speeds_corrected``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from autosar_cli.types import Trajectory

from .inputs import Measurements, NavInputs

Array = NDArray[np.float64]

ACCEL_WINDOW_S = 0.2  # the wheels' acceleration: a running mean of their speed over this, differentiated
GYRO_WINDOW_S = 0.1  # the gyros' white noise averaged down; a turn's yaw rate changes more slowly
MAX_DELAY_S = 0.5  # a sample is never moved further: below ~0.3 m/s the ECU's window spans its timeout
LAG_SHOWN = 3.0  #: the drive's own lag fit must be this many std above 0 for the sensor's stated window to join it
SLIP_GAINS = ("front_drive", "front_brake", "rear_drive", "rear_brake")
LOAD_GAINS = ("front", "rear")


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
    fitted_m: float | None = None  #: the drive's own fit, where ``c`` also rests on the sensor's stated window ...
    fitted_std_m: float | None = None
    prior_m: float | None = None  #: ... that window (None: none stated)
    prior_std_m: float | None = None
    restart_rows_dropped: int = 0  #: rows whose ECU window reached back across a standstill (left out)
    unread_rows_dropped: int = 0  #: rows a wheel's moved samples do not span (:func:`lag_compensated_wheels`)

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


@dataclass(frozen=True)
class WheelRadiusFit:
    """Each axle's speed error per m/s^2 of acceleration (slip and longitudinal load, :data:`SLIP_GAINS`) and of
    lateral acceleration (right wheel +, left -, :data:`LOAD_GAINS`), fractions, with their 1-sigma; ``applied``:
    the gains the wheel speeds were corrected by (the rest taken as 0)."""

    slip_gain: dict[str, float]
    slip_gain_std: dict[str, float]
    load_gain: dict[str, float]
    load_gain_std: dict[str, float]
    accel_rms_mps2: float  #: the car's acceleration about its mean: what makes the slip gains observable
    lateral_accel_rms_mps2: float  #: and the load gains
    applied: dict[str, float] = field(default_factory=dict)
    reason: str = ""

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


def running_mean(t: Array, y: Array, window_s: float) -> tuple[Array, Array] | None:
    """Means of ``y`` over ``window_s`` of samples, placed at their samples' mean time (so a window is never
    off-centre, which would show as a lag); None when too short."""
    if len(t) < 2:
        return None
    k = max(int(round(window_s / float(np.median(np.diff(t))))), 1)
    if len(t) < k:
        return None
    kernel = np.full(k, 1.0 / k)
    return np.convolve(t, kernel, "valid"), np.convolve(y, kernel, "valid")


def wheel_acceleration(wheels: Measurements, at: Array) -> Array:
    """The car's acceleration (m/s^2) at ``at`` (s): the four wheels' mean speed over ``ACCEL_WINDOW_S``,
    differentiated; 0 where the wheels are too few."""
    mean = running_mean(wheels.t, np.mean(wheels.z, axis=1), ACCEL_WINDOW_S)
    if mean is None or len(mean[0]) < 2:
        return np.zeros(np.shape(at))
    return np.interp(at, mean[0], np.gradient(mean[1], mean[0]))


def raw_gyro_yaw_rate(inputs: NavInputs, at: Array) -> Array:
    """The gyros' mean yaw rate (rad/s, biases included) at ``at`` (s, any shape), each averaged over
    ``GYRO_WINDOW_S``; NaN outside their span, 0 everywhere without gyros."""
    rates = []
    for g in inputs.gyros:
        mean = running_mean(g.t, g.z[:, 0], GYRO_WINDOW_S)
        if mean is not None:
            rates.append(np.interp(at, *mean, left=np.nan, right=np.nan))
    if not rates:
        return np.zeros(np.shape(at))
    return np.mean(rates, axis=0)


def _effective_covariance(design: Array, res: Array, groups: int = 1) -> Array:
    """Covariance of least-squares coefficients, counting the residual's serial correlation (lag-1 rho:
    N (1 - rho) / (1 + rho) independent samples); inf on the diagonal where the design is rank-deficient.

    ``groups`` > 1: the rows are that many stacked blocks of the same instants (the longitudinal fit's rear and
    front axles), whose residuals share the instant's GNSS speed error: the covariance is the sandwich of the
    instants' summed scores (a cluster per instant; counting the rows as independent made the lag's std ~1.4 times
    too small), with rho that of the instants' summed residuals."""
    n, p = design.shape
    normal = design.T @ design
    if n <= p or np.linalg.matrix_rank(normal) < p:
        return np.diag(np.full(p, np.inf))

    def serial(r: Array) -> float:
        rho = float(np.clip(np.corrcoef(r[:-1], r[1:])[0, 1], 0.0, 0.999)) if r.std() > 0 else 0.0
        return max(len(r) * (1.0 - rho) / (1.0 + rho), p + 1.0)

    inverse = np.linalg.inv(normal)
    if groups == 1:
        return float(np.mean(res**2)) * n / serial(res) * inverse
    m = n // groups
    score = (design * res[:, None]).reshape(groups, m, p).sum(axis=0)
    return m / serial(res.reshape(groups, m).sum(axis=0)) * inverse @ (score.T @ score) @ inverse


def effective_std(design: Array, res: Array) -> Array:
    """1-sigma of least-squares coefficients (see :func:`_effective_covariance`)."""
    return np.sqrt(np.diag(_effective_covariance(design, res)))


def _front_speeds(v: Array, w: Array, wheelbase_m: float, track_m: float) -> tuple[Array, Array]:
    """The bicycle's front-left and front-right wheel-centre speeds (m/s) at rear-axle speed v and yaw rate w."""
    lat = w * wheelbase_m
    return np.hypot(v - w * track_m / 2, lat), np.hypot(v + w * track_m / 2, lat)


def _with_lag_prior(coef: Array, cov: Array, prior_m: float, prior_std_m: float, always: bool = False
                   ) -> tuple[Array, Array, tuple[float, float] | None]:
    """The longitudinal coefficients and their covariance conditioned on the wheel sensor's stated window
    ``prior_m`` +- ``prior_std_m`` as one more measurement of c (index 2): every coefficient correlated with c (the
    slip gains: -a / v and a v are alike at a steady speed) moves with it. Only where the drive's own c is
    ``LAG_SHOWN`` std above 0 (``always``: wherever it does not contradict the window) and within 3 combined std of
    the window; then also c and its std fitted alone, else None (and the fit unchanged)."""
    c, c_std = float(coef[2]), float(np.sqrt(cov[2, 2]))
    if not (prior_std_m > 0 and np.isfinite(c_std) and (always or c > LAG_SHOWN * c_std)
            and abs(c - prior_m) <= 3.0 * np.hypot(c_std, prior_std_m)):
        return coef, cov, None
    gain = cov[:, 2] / (cov[2, 2] + prior_std_m**2)
    return coef + gain * (prior_m - c), cov - np.outer(gain, cov[2]), (c, c_std)


def longitudinal_regression(wheels: Measurements, ts: Array, v: Array, w: Array, a: Array, wheelbase_m: float,
                            v_design: Array | None = None) -> tuple[Array, Array]:
    """The design (2 N, 7) and data (2 N,) of :func:`_fit_longitudinal` at the instants ``ts`` (s): both axles' mean
    wheel speed less the rear axle's speed ``v`` (m/s; the front's from it and the yaw rate ``w``, rad/s), on
    [s_rear, s_front, c, k_front_drive, k_front_brake, k_rear_drive, k_rear_brake] with ``a`` the car's
    acceleration (m/s^2). ``v_design``: the rear axle's speed the design is built from (default ``v``); a speed
    whose noise is in the data too biases the fit (errors in variables: :func:`_fit_longitudinal`)."""
    vd = v if v_design is None else v_design
    vf, vf_design = np.hypot(v, w * wheelbase_m), np.hypot(vd, w * wheelbase_m)
    rear = np.interp(ts, wheels.t, 0.5 * (wheels.z[:, 2] + wheels.z[:, 3]))
    front = np.interp(ts, wheels.t, 0.5 * (wheels.z[:, 0] + wheels.z[:, 1]))
    zero = np.zeros_like(v)
    drive, brake = np.maximum(a, 0.0), np.minimum(a, 0.0)
    design = np.vstack([np.stack([vd, zero, -a / vd, zero, zero, drive * vd, brake * vd], axis=1),
                        np.stack([zero, vf_design, -a / vf_design, drive * vf_design, brake * vf_design, zero, zero],
                                 axis=1)])
    return design, np.concatenate([rear - v, front - vf])


def _longitudinal_problem(inputs: NavInputs, lever_rear_m: tuple[float, float], wheelbase_m: float,
                          min_speed_mps: float) -> tuple[Array, Array, Array, Array, Array] | None:
    """The GNSS instants (s) :func:`_fit_longitudinal` uses, the rear axle's speed there (m/s), the car's
    acceleration (m/s^2), and :func:`longitudinal_regression`'s design and data; None with fewer than 10."""
    wheels, gnss = inputs.wheels, inputs.gnss_velocity
    assert wheels is not None and gnss is not None
    inside = (gnss.t > wheels.t[0] + ACCEL_WINDOW_S) & (gnss.t < wheels.t[-1] - ACCEL_WINDOW_S)
    ts, vel = gnss.t[inside], gnss.z[inside]
    w = np.nan_to_num(raw_gyro_yaw_rate(inputs, ts))
    lx, ly = lever_rear_m
    # the antenna moves at (v - w ly, w lx) in the body frame
    v = np.sqrt(np.maximum(np.sum(vel**2, axis=1) - (w * lx) ** 2, 0.0)) + w * ly
    # the design takes the rear wheels' own speed: with the GNSS speed's noise in both the design and the data the
    # lag came out biased (errors in variables, leaking through -a / v and a v, collinear with the speed): on test3's
    # full vehicle 0.23 m low over 60 draws of that noise
    # (test_nav_models.py::test_the_gnss_speeds_noise_neither_biases_the_wheel_lag_nor_hides_in_its_std)
    v_wheels = np.interp(ts, wheels.t, 0.5 * (wheels.z[:, 2] + wheels.z[:, 3]))
    use = (v >= min_speed_mps) & (v_wheels >= min_speed_mps)
    if use.sum() < 10:
        return None
    ts, v, w, v_wheels = ts[use], v[use], w[use], v_wheels[use]
    a = wheel_acceleration(wheels, ts)
    design, y = longitudinal_regression(wheels, ts, v, w, a, wheelbase_m, v_design=v_wheels)
    return ts, v, a, design, y


def gnss_speed_residual(inputs: NavInputs, lever_rear_m: tuple[float, float], wheelbase_m: float,
                        min_speed_mps: float = 1.0) -> tuple[Array, Array] | None:
    """What the wheel speeds' longitudinal fit (:func:`_fit_longitudinal`) leaves at each GNSS instant (s) while
    moving: the rear axle's (m/s; no steering in its geometry), the GNSS speed's error and the wheels' own noise; None
    without wheel speeds, GNSS velocity or 10 samples above ``min_speed_mps``."""
    if inputs.wheels is None or inputs.gnss_velocity is None or len(inputs.wheels.t) < 3:
        return None
    problem = _longitudinal_problem(inputs, lever_rear_m, wheelbase_m, min_speed_mps)
    if problem is None:
        return None
    ts, _, _, design, y = problem
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    return ts, (y - design @ coef)[:len(ts)]


def _fit_longitudinal(inputs: NavInputs, lever_rear_m: tuple[float, float], wheelbase_m: float,
                      min_speed_mps: float, window_always: bool = False
                      ) -> tuple[Array, Array, int, float, float, float, tuple[float, float] | None] | None:
    """Coefficients [s_rear, s_front, c, k_front_drive, k_front_brake, k_rear_drive, k_rear_brake] of both axles'
    mean speed less the GNSS speed at the rear axle, their stds, samples, a / v RMS, a RMS, residual RMS, and the
    lag fitted alone (c, std) where the wheel sensor's stated window conditions them (:func:`_with_lag_prior`)."""
    problem = _longitudinal_problem(inputs, lever_rear_m, wheelbase_m, min_speed_mps)
    if problem is None:
        return None
    ts, v, a, design, y = problem
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    res = y - design @ coef
    coef, cov, alone = _with_lag_prior(coef, _effective_covariance(design, res, groups=2),
                                        *inputs.wheel_lag_prior_m, always=window_always)
    std = np.sqrt(np.diag(cov))
    return (coef, std, len(ts), float(np.std(a / v)), float(np.std(a)), float(np.sqrt(np.mean(res**2))),
            alone)


def _fit_lateral(inputs: NavInputs, wheelbase_m: float, tracks_m: tuple[float, float],
                 min_speed_mps: float) -> tuple[Array, Array, float] | None:
    """Load gains (front, rear) of the axles' right-left speed difference against the gyros, their stds and the
    lateral acceleration's RMS."""
    wheels = inputs.wheels
    assert wheels is not None
    if not inputs.gyros:
        return None
    h = GYRO_WINDOW_S
    t = wheels.t
    w, w_after, w_before = raw_gyro_yaw_rate(inputs, np.stack([t, t + h, t - h]))
    v = 0.5 * (wheels.z[:, 2] + wheels.z[:, 3])
    use = (v >= min_speed_mps) & np.isfinite(w) & np.isfinite(w_after) & np.isfinite(w_before)
    if use.sum() < 10:
        return None
    v, w, z = v[use], w[use], wheels.z[use]
    w_side = 0.5 * (w_after[use] + w_before[use])
    a_y = v * w_side
    gains, stds = np.empty(2), np.empty(2)
    for i, (left, right) in enumerate(((0, 1), (2, 3))):
        track = tracks_m[i]
        if i == 0:
            model_l, model_r = _front_speeds(v, w, wheelbase_m, track)
            side_l, side_r = _front_speeds(v, w_side, wheelbase_m, track)
        else:
            model_l, model_r = v - w * track / 2, v + w * track / 2
            side_l, side_r = v - w_side * track / 2, v + w_side * track / 2
        y = (z[:, right] - z[:, left]) - (model_r - model_l)
        design = np.stack([np.ones_like(v), v, a_y * (side_l + side_r)], axis=1)
        coef, *_ = np.linalg.lstsq(design, y, rcond=None)
        gains[i], stds[i] = coef[2], effective_std(design, y - design @ coef)[2]
    return gains, stds, float(np.std(a_y))


def fit_wheel_speeds(inputs: NavInputs, lever_rear_m: tuple[float, float], wheelbase_m: float,
                     tracks_m: tuple[float, float], min_speed_mps: float = 1.0, window_always: bool = False
                     ) -> tuple[WheelLagFit | None, WheelRadiusFit | None]:
    """The wheel speeds' lag and their slip and load gains (see the module's docstring), fitted to the drive.

    ``lever_rear_m``: the GNSS antenna's (x, y) from the rear axle's centre (m, body frame); ``tracks_m``: front
    and rear track (m). None for what the inputs cannot show: no wheel speeds or GNSS velocity (the lag and slip),
    no gyros (the load gains), or fewer than 10 samples above ``min_speed_mps``. ``window_always``: the wheel
    sensor's stated window joins the lag fit wherever the drive does not contradict it, not only where it shows a
    lag (:func:`_with_lag_prior`).
    """
    wheels = inputs.wheels
    if wheels is None or len(wheels.t) < 3:
        return None, None
    longitudinal = (_fit_longitudinal(inputs, lever_rear_m, wheelbase_m, min_speed_mps, window_always)
                    if inputs.gnss_velocity is not None else None)
    lateral = _fit_lateral(inputs, wheelbase_m, tracks_m, min_speed_mps)
    lag = None
    nan = {name: float("nan") for name in SLIP_GAINS}
    slip, slip_std, accel_rms = dict(nan), dict(nan), float("nan")
    if longitudinal is not None:
        coef, std, samples, a_over_v_rms, accel_rms, rms, alone = longitudinal
        prior = (inputs.wheel_lag_prior_m if inputs.wheel_lag_prior_m[1] > 0 else (None, None))
        lag = WheelLagFit(float(coef[2]), float(std[2]), samples, a_over_v_rms, rms,
                          fitted_m=alone[0] if alone else None, fitted_std_m=alone[1] if alone else None,
                          prior_m=prior[0], prior_std_m=prior[1])
        slip = {name: float(c) for name, c in zip(SLIP_GAINS, coef[3:], strict=True)}
        slip_std = {name: float(s) for name, s in zip(SLIP_GAINS, std[3:], strict=True)}
    load = {name: float("nan") for name in LOAD_GAINS}
    load_std, lateral_rms = dict(load), float("nan")
    if lateral is not None:
        load = {name: float(g) for name, g in zip(LOAD_GAINS, lateral[0], strict=True)}
        load_std = {name: float(s) for name, s in zip(LOAD_GAINS, lateral[1], strict=True)}
        lateral_rms = lateral[2]
    radii = (WheelRadiusFit(slip, slip_std, load, load_std, accel_rms, lateral_rms)
             if longitudinal is not None or lateral is not None else None)
    return lag, radii


def radius_corrected_wheels(inputs: NavInputs, gains: dict[str, float]) -> Measurements:
    """The wheel speeds divided by their fitted slip and load factors; ``gains``: the :data:`SLIP_GAINS` and
    ``load_front`` / ``load_rear`` to apply (absent: 0)."""
    wheels = inputs.wheels
    assert wheels is not None
    a = wheel_acceleration(wheels, wheels.t)
    a_y = np.mean(np.abs(wheels.z[:, 2:]), axis=1) * np.nan_to_num(raw_gyro_yaw_rate(inputs, wheels.t))
    drive, brake = np.maximum(a, 0.0), np.minimum(a, 0.0)
    factor = np.ones_like(wheels.z)
    for i, axle in enumerate(("front", "rear")):
        longitudinal = 1.0 + gains.get(f"{axle}_drive", 0.0) * drive + gains.get(f"{axle}_brake", 0.0) * brake
        g = gains.get(f"load_{axle}", 0.0) * a_y
        factor[:, 2 * i] = longitudinal * (1.0 - g)
        factor[:, 2 * i + 1] = longitudinal * (1.0 + g)
    return Measurements(wheels.name, wheels.t, wheels.z / factor, wheels.sigma)


def restart_window_m(fit: WheelLagFit) -> float:
    """How far a wheel turns before its ECU's window is clear of a standstill (m): the window spans ``N`` pitches
    and ``c = (N + 1) / 2`` of them, so ``N`` pitches are ``2 c N / (N + 1)``, at most ``2 c``."""
    return 2.0 * fit.lag_distance_m


def without_restart_windows(wheels: Measurements, window_m: float) -> tuple[Measurements, int]:
    """The wheel samples less those whose ECU window still reaches back across a standstill, and how many rows
    went: on each wheel, the non-zero values after a 0 (the ECU's "no edge" value) until that wheel's own
    reported speed, integrated over time, reaches ``window_m`` (m). A reported speed below the truth makes this
    drop more, never less. A row goes where any wheel's value goes (the filter updates all four together)."""
    v = np.abs(wheels.z)
    stopped = v == 0.0
    dt = np.diff(wheels.t, prepend=wheels.t[0])
    travel = np.cumsum(v * dt[:, None], axis=0)
    # the travel at each wheel's last 0 so far (travel does not decrease, so the running maximum is the last)
    at_stop = np.maximum.accumulate(np.where(stopped, travel, -np.inf), axis=0)
    restarting = ~stopped & (travel - at_stop < window_m)
    keep = ~restarting.any(axis=1)
    dropped = int(np.sum(~keep))
    if not dropped:
        return wheels, 0
    return Measurements(wheels.name, wheels.t[keep], wheels.z[keep], wheels.sigma), dropped


#: the wheels' speed over the GNSS's, above 2 m/s, outside which they are refused: a tyre's rolling radius is off by a
#: few per cent, a unit error far more (km/h read as m/s: 3.6)
MAX_WHEEL_SCALE_ERROR = 0.2
SCALE_MIN_SPEED_MPS = 2.0
#: ... beyond which the wheel speeds are divided by it before the filter, whose four scale states start at 1 with the
#: table's std (0.4 %): their mean is off by 0.2 % std, a drive's slip moves the median by a few 0.1 %. A wheel scale
#: 3 / 5 / 10 % off left urban seed 1's track 4.1 / 6.1 / 9.2 cm RMS across once aligned (0.9 as recorded).
MIN_WHEEL_SCALE_CORRECTION = 0.015


def wheel_gnss_speed_ratio(inputs: NavInputs) -> tuple[float, int] | None:
    """The wheel speeds' mean over the four wheels against the GNSS's horizontal speed: the median ratio where the
    GNSS reads above ``SCALE_MIN_SPEED_MPS``, and over how many samples (at least 10); None where there is too
    little to compare."""
    wheels, vel = inputs.wheels, inputs.gnss_velocity
    if wheels is None or vel is None or len(wheels.t) < 2:
        return None
    gnss_speed = np.hypot(vel.z[:, 0], vel.z[:, 1])
    inside = (gnss_speed > SCALE_MIN_SPEED_MPS) & (vel.t >= wheels.t[0]) & (vel.t <= wheels.t[-1])
    if inside.sum() < 10:
        return None
    return float(np.median(np.interp(vel.t[inside], wheels.t, wheels.z.mean(axis=1)) / gnss_speed[inside])), \
        int(inside.sum())


def wheel_scale_error(inputs: NavInputs) -> str | None:
    """Why the wheel speeds cannot be this drive's: their ratio to the GNSS speed (:func:`wheel_gnss_speed_ratio`)
    off 1 by more than ``MAX_WHEEL_SCALE_ERROR``; else None (or where there is too little to compare)."""
    measured = wheel_gnss_speed_ratio(inputs)
    if measured is None or abs(measured[0] - 1.0) <= MAX_WHEEL_SCALE_ERROR:
        return None
    ratio, n = measured
    return (f"the wheel speeds read {ratio:.3f} times the GNSS speed ({n} samples above "
            f"{SCALE_MIN_SPEED_MPS:g} m/s): a unit or scale error in the DBC or the config (km/h read as m/s is 3.6), "
            "or another drive's CAN")


def wheel_scale_corrected(inputs: NavInputs) -> tuple[NavInputs, dict[str, Any]]:
    """``inputs`` with the wheel speeds divided by their ratio to the GNSS speed where it is off 1 by more than
    ``MIN_WHEEL_SCALE_CORRECTION`` (a tyre's radius or the DBC's factor off; the filter's scale states follow a few
    0.1 %), and what was found."""
    if inputs.wheels is None or inputs.gnss_velocity is None:
        return inputs, {"applied": False, "reason": f"no {'wheel speeds' if inputs.wheels is None else 'GNSS velocity'}"
                                                    " to compare"}
    measured = wheel_gnss_speed_ratio(inputs)
    if measured is None:
        return inputs, {"applied": False, "reason": "too little GNSS speed above "
                                                    f"{SCALE_MIN_SPEED_MPS:g} m/s to compare the wheels with"}
    ratio, n = measured
    if abs(ratio - 1.0) <= MIN_WHEEL_SCALE_CORRECTION:
        return inputs, {"applied": False, "ratio": round(ratio, 5), "samples": n,
                        "reason": f"within {MIN_WHEEL_SCALE_CORRECTION:.1%} of the GNSS speed: the filter's scale "
                                  "states take it"}
    if abs(ratio - 1.0) > MAX_WHEEL_SCALE_ERROR:  # a unit, not a scale: refused (wheel_scale_error), not mended
        return inputs, {"applied": False, "ratio": round(ratio, 5), "samples": n,
                        "reason": f"over {MAX_WHEEL_SCALE_ERROR:.0%} off the GNSS speed: not a tyre's scale"}
    w = inputs.wheels
    scaled = replace(inputs, wheels=Measurements(w.name, w.t, w.z / ratio, w.sigma / ratio))
    return scaled, {"applied": True, "ratio": round(ratio, 5), "samples": n,
                    "reason": f"the wheel speeds read {ratio:.4f} times the GNSS speed ({n} samples above "
                              f"{SCALE_MIN_SPEED_MPS:g} m/s; a tyre radius or the DBC's factor {ratio - 1:+.1%} off): "
                              "divided by that"}


STANDSTILL_MIN_S = 1.0  #: a standstill is all four wheels at 0 for at least this long
#: its start is moved on by this: the ECU reads 0 once no edge has come for its timeout, when the car stands
STANDSTILL_START_MARGIN_S = 0.1
#: and its end back by this: the ECU still reads 0 until the first edge after the car moves off (0.29 s at
#: 1 m/s^2 on a 48-tooth ring, 0.54 s at 0.3 m/s^2)
STANDSTILL_END_MARGIN_S = 0.5


def standstill_spans(wheels: Measurements | None, min_s: float = STANDSTILL_MIN_S,
                     start_margin_s: float = STANDSTILL_START_MARGIN_S,
                     end_margin_s: float = STANDSTILL_END_MARGIN_S) -> list[tuple[float, float]]:
    """The spans (s) where all four wheel speeds read 0 (the ECU's "no edge" value: exactly 0, where a reading of
    one step would be a wheel turning) for at least ``min_s``, less
    ``start_margin_s`` at their start and ``end_margin_s`` at their end. A car creeping for over a second below
    the ECU's lowest speed (a pitch per timeout: 0.14 m/s for 48 teeth and 0.3 s) reads as standing."""
    if wheels is None or len(wheels.t) < 2:
        return []
    stopped = np.all(wheels.z == 0.0, axis=1)
    edges = np.flatnonzero(np.diff(np.r_[0, stopped.astype(np.int8), 0]))
    spans = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        start, end = float(wheels.t[a]) + start_margin_s, float(wheels.t[b - 1]) - end_margin_s
        if float(wheels.t[b - 1] - wheels.t[a]) >= min_s and end > start:
            spans.append((start, end))
    return spans


def standstill_yaw_rate(spans: list[tuple[float, float]], at: Array, std_radps: float) -> Measurements | None:
    """A zero yaw rate (rad/s, std ``std_radps`` each) at the instants ``at`` (s; the gyros' samples) within the
    standstills ``spans`` (s; :func:`standstill_spans`); None where there are none. A car standing on its tyres
    does not turn, while the gyros' biases, which nothing else pins there, would turn its heading: on urban's 6 s
    stop SAR-MIN's heading turned by 0.013 deg RMS (up to 0.025), a kink in its track that moves reflectors 100 m
    on by ~2 cm. At every gyro sample, for the filter's yaw rate moves freely between samples (its process noise
    is a turning car's), and where it is held each gyro sample measures its bias."""
    if not spans or std_radps <= 0.0:
        return None
    t = np.unique(at)
    inside = np.zeros(len(t), dtype=bool)
    for a, b in spans:
        inside |= (t >= a) & (t <= b)
    times = t[inside]
    return Measurements("standstill", times, np.zeros((len(times), 1)), np.array([std_radps]))


#: A standstill whose gyros, less their biases, turn faster than this over it is a car creeping below the wheel
#: speeds' lowest reading, not standing (rad/s; 0.01 deg/s, 0.05 deg over 5 s; urban's full-vehicle stops read
#: 0.0003-0.0032 deg/s, their std 0.002; a creeping turn leaves ~0.6 of its rate, the biases take the rest)
CREEP_YAW_RATE_RADPS = np.deg2rad(0.01)


def turning_standstills(spans: list[tuple[float, float]], gyros: list[Measurements], t: Array, omega: Array,
                        biases: Array, significant: float = 5.0) -> list[tuple[tuple[float, float], float, float]]:
    """The standstills ``spans`` (s) over which the gyros say the car turns: each gyro's samples there less the
    solution's yaw rate ``omega`` (rad/s) and that gyro's bias (``biases`` (K, G), rad/s; both at the solution's
    instants ``t``, s), averaged over the span and over the gyros by their samples' weight. Where that rate exceeds
    ``significant`` times its noise and :data:`CREEP_YAW_RATE_RADPS`, the span is returned with the rate and its
    std (rad/s). A car creeping below the ECU's lowest speed (0.14 m/s) reads 0 on all four wheels while it turns:
    held at 0, its heading would stop (a 1 deg/s turn over urban's 5.5 s span: 0.004 deg instead of 5.5), for the
    filter then gates the gyros out rather than the zero. The biases cannot take such a turn (their walk: 5e-4
    deg/s over 5 s), so it stays in the residual."""
    out = []
    for a, b in spans:
        weight = mean = 0.0
        for g, gyro in enumerate(gyros):
            inside = (gyro.t >= a) & (gyro.t <= b)
            n = int(inside.sum())
            if n == 0:
                continue
            at = gyro.t[inside]
            residual = gyro.z[inside, 0] - np.interp(at, t, omega) - np.interp(at, t, biases[:, g])
            w = n / float(gyro.sigma[0]) ** 2
            mean += w * float(residual.mean())
            weight += w
        if weight == 0.0:
            continue
        rate, std = mean / weight, 1.0 / np.sqrt(weight)
        if abs(rate) > max(significant * std, CREEP_YAW_RATE_RADPS):
            out.append(((a, b), rate, std))
    return out


def lag_compensated_wheels(wheels: Measurements, fit: WheelLagFit) -> Measurements:
    """The wheel speeds as of their rows' own instants: each wheel's samples move to the instants they describe,
    ``t - c / v_w`` (``v_w`` that sample's own speed, at most ``MAX_DELAY_S`` back; a standing wheel's stay), and its
    value at each row's ``t`` is read between them. Each wheel's ECU window is ``c`` of its own travel, so in a turn
    the inner wheel lags more than the outer: one move for the row, ``c`` over the mean speed, left their difference
    wrong by ``a c w T / v^2`` under acceleration (urban's right turn while braking: 6 mm/s, 1.2 % of it), which
    against the gyros reads as the wheels' common scale. A row goes where a wheel has no moved sample either side of
    it, two that were not neighbours (rows left out before), or a 0 (the ECU's "no edge") beside a speed."""
    t, z = wheels.t, wheels.z
    if len(t) < 2:
        return wheels
    gap = 2.5 * float(np.median(np.diff(t)))
    values = np.empty_like(z)
    keep = np.ones(len(t), dtype=bool)
    for w in range(z.shape[1]):
        v = np.abs(z[:, w])
        delay = np.where(v > 0, np.clip(fit.lag_distance_m / np.maximum(v, 1e-9), -MAX_DELAY_S, MAX_DELAY_S), 0.0)
        described = t - delay
        order = np.argsort(described, kind="stable")
        moved, stamp, value = described[order], t[order], z[order, w]
        k = np.clip(np.searchsorted(moved, t, side="right") - 1, 0, len(t) - 2)
        lo, hi = value[k], value[k + 1]
        frac = (t - moved[k]) / np.maximum(moved[k + 1] - moved[k], 1e-12)
        values[:, w] = lo + np.clip(frac, 0.0, 1.0) * (hi - lo)
        keep &= ((t >= moved[k]) & (t <= moved[k + 1]) & (np.abs(stamp[k + 1] - stamp[k]) <= gap)
                 & ((lo == 0.0) == (hi == 0.0)))
    return Measurements(wheels.name, t[keep], values[keep], wheels.sigma)


@dataclass(frozen=True)
class WheelGap:
    """A span the wheel speeds do not cover (rows left out: an ECU window across a standstill, samples the lag
    moved away), and how far the track's along-track error may drift over it (m, 1-sigma): there only the GNSS
    velocity holds the speed, its noise ``sigma`` over the ``n`` fixes inside summing to ``sigma g / sqrt(n)``."""

    start_ns: int
    end_ns: int
    along_std_m: float

    def to_dict(self) -> dict[str, float | None]:
        """As JSON takes it: an unbounded drift is None."""
        return {**asdict(self), "along_std_m": self.along_std_m if np.isfinite(self.along_std_m) else None}


def wheel_gaps(wheels: Measurements | None, gnss_velocity: Measurements | None, t0_ns: int, min_gap_s: float = 0.1
               ) -> list[WheelGap]:
    """The spans longer than ``min_gap_s`` between the wheel rows the filter takes (``wheels``, s since ``t0_ns``;
    none without wheels), with their along-track drift (:class:`WheelGap`); with no GNSS velocity it is unbounded."""
    if wheels is None or len(wheels.t) < 2:
        return []
    t = wheels.t
    k = np.flatnonzero(np.diff(t) > min_gap_s)
    if gnss_velocity is not None and len(gnss_velocity.t) > 1:
        fix_s, sigma = float(np.median(np.diff(gnss_velocity.t))), float(np.max(gnss_velocity.sigma))
    else:
        fix_s, sigma = 1.0, float("inf")
    return [WheelGap(t0_ns + int(round(a * 1e9)), t0_ns + int(round(b * 1e9)),
                     sigma * (b - a) / np.sqrt(max((b - a) / fix_s, 1.0)))
            for a, b in zip(t[k], t[k + 1], strict=True)]


#: the speed is averaged over this before it is differentiated for :func:`slip_gain_drift` (the filter's speed
#: carries its wheels' noise; a braking lasts seconds)
SLIP_DRIFT_WINDOW_S = 0.5


def slip_gain_drift(trajectory: Trajectory, t_ns: NDArray[np.int64]) -> tuple[Array, Array]:
    """How far (m) along its track ``trajectory`` has moved by ``t_ns`` per unit error of its mean drive and mean
    brake slip gain (N, 2), and the std of those two errors (2,) that its navigation stated
    (``info["wheel_radii"]``: each axle's gain std, and the gain fitted but not applied in full where it was left
    out); (N, 0) and (0,) where it stated none, or a std of 0.

    A gain's error ``dk`` leaves the wheels' speed ``(1 + dk a)`` times the truth under acceleration ``a``, so the
    track, which follows the four wheels' mean, runs ``v a (dk_front + dk_rear) / 2`` fast, and by time ``t`` has
    gone ``dk`` times the integral of ``v a`` over the drive's (``a > 0``) or braking (``a < 0``) time further
    (both axles' ``dk`` in the mean): for a stop from 5 m/s, 12.5 m per unit, 2.2 cm at urban's brake gains' std
    (0.25 % per m/s^2 each).
    """
    radii = trajectory.info.get("wheel_radii") or {}
    gain, std = radii.get("slip_gain") or {}, radii.get("slip_gain_std") or {}
    applied = radii.get("applied") or {}
    if not all(name in gain and std.get(name) is not None and np.isfinite(std[name]) for name in SLIP_GAINS):
        return np.zeros((len(np.atleast_1d(t_ns)), 0)), np.zeros(0)
    variances = [sum(std[n] ** 2 + (gain[n] - applied.get(n, 0.0)) ** 2 for n in (f"front_{mode}", f"rear_{mode}"))
                 / 4.0 for mode in ("drive", "brake")]
    if not all(v > 0.0 for v in variances):  # a gain known exactly leaves nothing to fit
        return np.zeros((len(np.atleast_1d(t_ns)), 0)), np.zeros(0)
    mean = running_mean(trajectory.t, trajectory.speed, SLIP_DRIFT_WINDOW_S)
    if mean is None or len(mean[0]) < 2:
        return np.zeros((len(np.atleast_1d(t_ns)), 2)), np.sqrt(variances)
    tm, v = mean
    dv, v_mid = np.diff(v), 0.5 * (v[1:] + v[:-1])
    ramps = np.zeros((len(tm), 2))
    ramps[1:, 0] = np.cumsum(v_mid * np.maximum(dv, 0.0))
    ramps[1:, 1] = np.cumsum(v_mid * np.minimum(dv, 0.0))
    at = (np.asarray(t_ns, dtype=np.int64) - trajectory.t_ns[0]) / 1e9
    return np.column_stack([np.interp(at, tm, ramps[:, i]) for i in range(2)]), np.sqrt(variances)
