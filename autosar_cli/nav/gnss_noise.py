"""How noisy a drive's GNSS is, measured from its own fixes and velocities, against the receiver's error table.

SAR-MIN weighs each fix and velocity by the GNSS sensor's table (``white_std_m``, ``velocity_std_mps``). A receiver
noisier than its table is trusted more than it should be: its gates throw good samples out (24 of test3 seed 30's
440 with both noises twice the table's), and the fits made against its velocity are judged by the wrong yardstick
(below). On that drive SAR-MIN's worst reflector went from 3.5 to 9.3 cm and its RPE across 1 m from 0.75 to 2.97 mm.

The white part of that noise shows in the samples alone. A car's motion is smooth over a few 0.1 s samples: the
third (divided) difference of a 10 Hz stream removes its position, speed and acceleration, leaving ``sqrt(20)``
times the white noise per axis on a regular stream (the binomial weights 1, -3, 3, -1) plus the jerk's ``dt^3``
share, well below a millimetre. The slow (Gauss-Markov) part of the position error cancels the same way. The
spread is taken robustly (the median absolute deviation), so an odd jump does not read as noise.

Only a receiver noisier than its table changes anything: its sigma is raised to what the drive shows. One quieter
than its table keeps the table: a few hundred samples of one drive do not outweigh a datasheet, and a receiver's
own smoothing makes its fixes look quieter than they are. The policy's threshold is :data:`MIN_RATIO`.

The fits made against the GNSS velocity (the wheel speeds' lag and radii, the rear tyres' slip) are taken where
their std is within a bound: what the table's velocity noise allows on a drive that excites the term enough. A
noisier velocity widens every fit's std by its factor, so those bounds widen with it
(:func:`with_fit_bounds_widened`): on test3 seed 30 above, the rear-slip gain fitted 0.0097 +- 0.0025 rad per m/s^2
was otherwise refused (bound 0.002) and the track navigated with none: RPE across 1 m 2.97 mm, 1.30 with it.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np
from numpy.typing import NDArray

from autosar_cli.config import Config
from autosar_cli.nav.inputs import Measurements, NavInputs

Array = NDArray[np.float64]

#: the order of the differences: the third removes position, speed and acceleration
ORDER = 3
#: a difference spanning a sample interval longer than this times the median is dropped (a gap in the stream)
MAX_GAP_RATIO = 1.5
#: fewer differences than this (per axis) measure nothing
MIN_DIFFERENCES = 40
#: the measured white noise must exceed the table's by this factor before the table is raised: with ~120
#: differences per axis (a 13 s drive at 10 Hz, two axes) the estimate's own spread is ~8 %, so 1.4 is ~5 of it
MIN_RATIO = 1.4
#: the GNSS velocity's errors count as correlated (warned of; carried as states where asked) where their long-run
#: factor is at least this much (a successive correlation of 0.51, ~0.15 s at 10 Hz): white, the 40 drives of seeds
#: 0-9 read -0.31 ... 0.30 (120-480 pairs; urban's turns leave some in the wheels' model of the speed)
MIN_CORRELATION_FACTOR = 1.75
#: the largest successive correlation taken (a long-run factor of ~14)
MAX_CORRELATION = 0.99
#: the share of a correlated velocity's sigma its samples keep as white noise, the rest carried as a state
WHITE_SHARE = 0.2


@dataclass(frozen=True)
class WhiteNoise:
    """The white noise one GNSS stream shows, against its table."""

    stream: str  #: "position" or "velocity"
    table_std: float  #: the sigma SAR-MIN would use (m or m/s, per axis)
    measured_std: float  #: what the stream's third differences show (same unit)
    differences: int  #: how many differences measured it (all axes)
    applied: bool = False
    reason: str = ""

    @property
    def ratio(self) -> float:
        return self.measured_std / self.table_std if self.table_std > 0 else math.inf

    def to_dict(self) -> dict[str, object]:
        return asdict(self) | {"ratio": self.ratio}


def unit_differences(t: Array, z: Array, order: int = ORDER) -> Array:
    """The ``order``-th divided differences (D, k) of samples ``z`` (N, k) at times ``t`` (N,) (s), each scaled to
    unit gain for white noise (on a regular stream, the plain differences over ``sqrt(C(2 order, order))``); those
    spanning a gap (:data:`MAX_GAP_RATIO`) or a non-finite sample are left out."""
    t = np.asarray(t, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64).reshape(len(t), -1)
    if len(t) <= order:
        return np.zeros((0, z.shape[1]))
    dt = np.diff(t)
    typical = float(np.median(dt))
    steady = (dt > 0) & (dt <= MAX_GAP_RATIO * typical)
    # a difference is usable where every interval it spans is a regular one
    spans = np.lib.stride_tricks.sliding_window_view(steady, order).all(axis=1)
    tw = np.lib.stride_tricks.sliding_window_view(t, order + 1)[spans]  # (D, order + 1)
    zw = np.lib.stride_tricks.sliding_window_view(z, order + 1, axis=0)[spans]  # (D, k, order + 1)
    # divided-difference weights 1 / prod_{j != i} (t_i - t_j): they cancel any polynomial below degree `order`
    gaps = (tw[:, :, None] - tw[:, None, :]) / typical
    gaps[:, np.arange(order + 1), np.arange(order + 1)] = 1.0
    w = 1.0 / np.prod(gaps, axis=2)
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    d = np.einsum("dki,di->dk", zw, w)
    return d[np.isfinite(d).all(axis=1)]


def _mad(x: Array) -> float:
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


def _robust_std(d: Array) -> float:
    """The spread of differences ``d`` (D, k), RMS over the axes of each one's median absolute deviation."""
    return float(np.sqrt(np.mean([_mad(d[:, k]) ** 2 for k in range(d.shape[1])])))


def white_noise_std(t: Array, z: Array, order: int = ORDER) -> tuple[float, int]:
    """The white noise (per axis, the unit of ``z``) of samples ``z`` (N, k) at times ``t`` (N,) (s) of a smooth
    motion, from the robust spread of their ``order``-th divided differences (:func:`unit_differences`); and how
    many were used. NaN with fewer than :data:`MIN_DIFFERENCES` per axis."""
    d = unit_differences(t, z, order)
    if len(d) < MIN_DIFFERENCES:
        return math.nan, int(d.size)
    return _robust_std(d), int(d.size)


@dataclass(frozen=True)
class VelocityCorrelation:
    """How the GNSS velocity's error correlates from one sample to the next, and what SAR-MIN made of it."""

    correlation: float  #: between successive samples' errors (first-order Gauss-Markov), 0 for white noise
    pairs: int  #: how many successive pairs measured it
    spacing_s: float  #: the velocity stream's sample interval (s)
    applied: bool = False
    sigma_mps: float = math.nan  #: the velocity's white sigma SAR-MIN weighs each sample by (m/s, per axis)
    reason: str = ""

    @property
    def long_run_factor(self) -> float:
        """How much more the mean of many samples scatters than that of as many independent ones:
        sqrt((1 + rho) / (1 - rho))."""
        rho = min(max(self.correlation, 0.0), MAX_CORRELATION)
        return math.sqrt((1.0 + rho) / (1.0 - rho))

    @property
    def correlation_time_s(self) -> float:
        return -self.spacing_s / math.log(self.correlation) if 0 < self.correlation < 1 else 0.0

    def to_dict(self) -> dict[str, object]:
        """The fields and the derived figures; an unmeasured correlation (and its factor) as None, JSON having no
        NaN."""
        measured = math.isfinite(self.correlation)
        return asdict(self) | {"correlation": self.correlation if measured else None,
                               "long_run_factor": self.long_run_factor if measured else None,
                               "correlation_time_s": self.correlation_time_s}


def successive_correlation(t: Array, r: Array) -> tuple[float, int]:
    """The correlation of ``r`` (N,) between samples one regular interval apart (times ``t`` (N,), s; pairs across
    a gap left out), robust to a minority of outlying pairs, and how many pairs; NaN with fewer than
    :data:`MIN_DIFFERENCES`."""
    t, r = np.asarray(t, dtype=np.float64), np.asarray(r, dtype=np.float64)
    if len(t) < 3:
        return math.nan, 0
    dt = np.diff(t)
    regular = np.abs(dt - np.median(dt)) <= 0.25 * np.median(dt)
    a, b = r[:-1][regular], r[1:][regular]
    if len(a) < MIN_DIFFERENCES:
        return math.nan, int(len(a))
    # robust (Gnanadesikan-Kettenring): from the spreads of the sums and differences, each a median absolute
    # deviation, so that a few seconds the wheels' model misses (urban's turns and brakings) do not read as noise
    plus, minus = _mad(a + b) ** 2, _mad(a - b) ** 2
    return float((plus - minus) / (plus + minus)) if plus + minus > 0 else 0.0, int(len(a))


def velocity_decorrelated(inputs: NavInputs, residual: tuple[Array, Array] | None, enabled: bool = True,
                          carry: bool = True) -> tuple[NavInputs, dict[str, object]]:
    """The inputs with the GNSS velocity's error carried by SAR-MIN as two Gauss-Markov states where its samples'
    errors correlate by a long-run factor (:attr:`VelocityCorrelation.long_run_factor`) of at least
    :data:`MIN_CORRELATION_FACTOR`, measured on ``residual``: the instants (s) and what the wheel speeds leave of
    the GNSS speed there (:func:`~autosar_cli.nav.wheel_speeds.gnss_speed_residual`); and what was measured and
    done.

    SAR-MIN takes each sample's error as independent of the next. A receiver whose own filter smooths its Doppler
    velocity repeats its error over several samples; counted as independent, their mean is trusted by the long-run
    factor too much: the gyros' biases and the track's scale follow it, and the std they state (the autofocus's
    priors) is too small by that factor. Carried as a state (per axis, std ``sqrt(1 - WHITE_SHARE^2)`` of the
    samples' sigma, its correlation time the measured one; the samples keep ``WHITE_SHARE`` of their sigma as
    white noise), the slow part counts as much as it holds while the changes from sample to sample still measure
    the car's accelerations (weighing every sample by the long-run factor instead lost those: urban's stops moved
    its track along by up to 10 cm). The wheel speeds follow the car's speed well enough within a second that what
    they leave is the GNSS speed's error (its along-track part; the across one is taken to be alike, one filter in
    the receiver making both).

    With the states the scale rests on the speed's changes, where the tyres' slip acts: navigate then applies the
    wheels' measured slip gains even where the smoothed velocity shows them at under 3 std
    (:func:`~autosar_cli.nav.navigate.wheel_speeds_corrected`).

    ``carry`` False (``navigation.gnss_velocity_error_states = false``): measured and reported (``correlated``:
    navigate warns), the samples left independent."""
    vel = inputs.gnss_velocity
    if vel is None:
        return inputs, {"applied": False, "reason": "no GNSS velocity"}
    spacing = float(np.median(np.diff(vel.t))) if len(vel.t) > 1 else math.nan
    sigma = float(np.max(vel.sigma))
    if residual is None:
        return inputs, VelocityCorrelation(math.nan, 0, spacing, sigma_mps=sigma,
                                           reason="no wheel speeds or under 10 GNSS velocities while moving to "
                                                  "measure it against: the samples as independent").to_dict()
    rho, pairs = successive_correlation(*residual)
    fit = VelocityCorrelation(rho, pairs, spacing, sigma_mps=sigma)
    if not np.isfinite(rho):
        return inputs, replace(fit, reason=f"fewer than {MIN_DIFFERENCES} successive samples while moving: the "
                                           "samples as independent").to_dict()
    if not enabled:
        return inputs, replace(fit, reason="navigation.estimate_gnss_noise is off: the samples as "
                                           "independent").to_dict()
    factor = fit.long_run_factor
    if factor < MIN_CORRELATION_FACTOR:
        return inputs, replace(fit, reason=f"long-run factor {factor:.2f} below {MIN_CORRELATION_FACTOR:g}: the "
                                           "samples as independent").to_dict()
    if not carry:
        return inputs, replace(fit, reason=f"successive errors correlate by {rho:.2f}: SAR-MIN takes them as "
                                           f"independent (navigation.gnss_velocity_error_states is off), so the "
                                           f"scale and heading it states are ~{factor:.1f} times too confident"
                               ).to_dict() | {"correlated": True}
    # the state's own correlation: the white share dilutes what the samples show
    state_rho = min(rho / (1.0 - WHITE_SHARE**2), MAX_CORRELATION)
    error_std = sigma * math.sqrt(1.0 - WHITE_SHARE**2)
    time_s = -spacing / math.log(state_rho)
    carried = replace(inputs, gnss_velocity=replace(vel, sigma=vel.sigma * WHITE_SHARE),
                      gnss_velocity_error_std_mps=error_std, gnss_velocity_error_time_s=time_s)
    return carried, replace(
        fit, applied=True, sigma_mps=sigma * WHITE_SHARE,
        reason=f"successive errors correlate by {rho:.2f} (long-run factor {factor:.2f}): carried as a state of "
               f"{error_std:.3f} m/s over {time_s:.2f} s").to_dict() | {"correlated": True, "error_std_mps": error_std,
                                                                        "error_time_s": time_s}


def _checked(stream: str, meas: Measurements | None, enabled: bool) -> tuple[Measurements | None, WhiteNoise | None]:
    if meas is None:
        return None, None
    table = float(np.max(meas.sigma))
    measured, n = white_noise_std(meas.t, meas.z)
    fit = WhiteNoise(stream, table, measured, n)
    if not np.isfinite(measured):
        return meas, replace(fit, reason=f"fewer than {MIN_DIFFERENCES} regular samples per axis: the table's")
    if not enabled:
        return meas, replace(fit, reason="navigation.estimate_gnss_noise is off: the table's")
    if fit.ratio < MIN_RATIO:
        return meas, replace(fit, reason=f"within {MIN_RATIO:g} times the table's: the table's")
    raised = replace(meas, sigma=np.maximum(meas.sigma, measured))
    return raised, replace(fit, applied=True,
                           reason=f"{fit.ratio:.2f} times the table's: weighed by what the drive shows")


def gnss_noise_checked(inputs: NavInputs, enabled: bool = True) -> tuple[NavInputs, dict[str, dict[str, object]]]:
    """The inputs with each GNSS stream's white sigma raised to what the drive shows where it is at least
    :data:`MIN_RATIO` times the table's (``enabled``: ``navigation.estimate_gnss_noise``), and what was measured
    per stream (position, velocity)."""
    position, pos_fit = _checked("position", inputs.gnss_position, enabled)
    velocity, vel_fit = _checked("velocity", inputs.gnss_velocity, enabled)
    info = {f.stream: f.to_dict() for f in (pos_fit, vel_fit) if f is not None}
    return replace(inputs, gnss_position=position, gnss_velocity=velocity), info


#: a receiver stating a horizontal std at least this times its table's total (slow and white) has its slow error's
#: std raised to match: it knows its own fix better than a datasheet does (0.1: what a covariance rounded for
#: transport can move it by, and no more)
MIN_REPORTED_RATIO = 1.1


def gnss_slow_error_checked(inputs: NavInputs, enabled: bool = True) -> tuple[NavInputs, dict[str, object]]:
    """The inputs with the GNSS's slow (Gauss-Markov) error std raised to what the receiver states for its own fixes
    (``inputs.gnss_reported_std_m``, per axis) where that is at least :data:`MIN_REPORTED_RATIO` times the table's
    total (the slow std and the fixes' white sigma in quadrature), and what was compared and why. The slow error does
    not show in the samples (it moves every fix alike, over a minute): only the receiver can say it is larger than its
    table, and the position's std SAR-MIN states holds only as far as that size is right (docs/NAVIGATION.md)."""
    slow, reported = inputs.gnss_error_std_m, inputs.gnss_reported_std_m
    white = float(np.max(inputs.gnss_position.sigma)) if inputs.gnss_position is not None else 0.0
    table = math.hypot(slow, white)
    info: dict[str, object] = {"table_std_m": table, "reported_std_m": None if math.isnan(reported) else reported,
                               "slow_std_m": slow, "applied": False}
    if inputs.gnss_error_time_s <= 0.0:
        return inputs, info | {"reason": "no slow error modelled (navigation.gnss_error_model)"}
    if math.isnan(reported):
        return inputs, info | {"reason": "the receiver states no covariance of a known type for its fixes: the table's"}
    if not enabled:
        return inputs, info | {"reason": "navigation.estimate_gnss_noise is off: the table's"}
    if reported < MIN_REPORTED_RATIO * table:
        return inputs, info | {"reason": f"the receiver states {reported:.3f} m, within {MIN_REPORTED_RATIO:g} times "
                                          f"the table's {table:.3f} m: the table's"}
    raised = math.sqrt(reported**2 - white**2)
    return replace(inputs, gnss_error_std_m=raised), info | {
        "slow_std_m": raised, "applied": True,
        "reason": f"the receiver states {reported:.3f} m, {reported / table:.2f} times the table's {table:.3f} m: its "
                  f"slow error taken at {raised:.3f} m"}


def with_fit_bounds_widened(config: Config, gnss_noise: dict[str, dict[str, object]]) -> Config:
    """``config`` whose bounds on the std of the fits made against the GNSS velocity (wheel lag, wheel radii, rear
    slip) are widened by the factor its sigma was raised by (``gnss_noise``: :func:`gnss_noise_checked`'s report);
    ``config`` itself where it was not raised."""
    velocity = gnss_noise.get("velocity", {})
    if not velocity.get("applied"):
        return config
    factor = float(velocity["ratio"])  # type: ignore[arg-type]
    nav = config.navigation
    return replace(config, navigation=replace(
        nav, wheel_lag_max_std_m=nav.wheel_lag_max_std_m * factor,
        wheel_radius_gain_max_std_per_mps2=nav.wheel_radius_gain_max_std_per_mps2 * factor,
        rear_slip_max_std_rad_per_mps2=nav.rear_slip_max_std_rad_per_mps2 * factor))
