"""The GNSS receiver's latency, measured against a 6-DoF IMU: how late its samples are stamped.

SAR-MIN moves every sample to the instant it refers to by its sensor's stated ``latency_s``. A GNSS receiver's is
taken on trust, and its error is costly: where a receiver's velocity refers to 0 or 150 ms before its stamp instead
of the table's 50 ms, the rear-slip and wheel-lag fits read the velocity's lag as tyre slip and SAR-MIN puts test1-3's
reflectors 5.4-15.2 cm off (1.2-1.4 cm at the true latency).

The measurement needs no model of the car (its slip and wheel lag cannot enter): the antenna's velocity is the
IMU's, integrated, plus the lever arm's motion between them. So the GNSS velocity at its instants ``t_k`` is compared
with

    v(t_k - d) = integral_0^(t_k - d) R(psi) (M f + b) dt + omega R(psi) J r + tilt + slow(t_k)

``f`` the IMU's horizontal specific force (body axes) less gravity by the body's attitude where it is given,
``psi`` the heading from the IMU's own yaw rate (its constant and drift fitted to the GNSS course), ``M`` a 2 x 2
matrix (the IMU's scales and misalignment; it also takes a constant heading error), ``b`` the accelerometers' biases,
``r`` the antenna from the IMU, ``tilt`` the antenna's motion from the IMU as the body rolls and pitches, ``slow`` a
cosine series up to :data:`CUTOFF_HZ` per axis (the initial velocity, the grade, the biases' slow integral). ``d``,
the latency's change from the table, is the one that leaves the least residual (a search over ±:data:`SEARCH_S`,
refined by a parabola); its std comes from the chi-square profile's curvature over ±:data:`PROFILE_SPAN_S`, and the
fit is ambiguous where another delay, away from the best one's dip, fits within :data:`SIGNIFICANT` std.

What measures ``d`` is the change of the car's acceleration vector, ``d`` times it against the GNSS velocity's noise
(0.03 m/s per sample): on test1-3 (12-26 s) the std is 15-25 ms, and test1, which accelerates on a straight road,
is often ambiguous. The policy (whether the samples move) is in :mod:`.navigate`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import cumulative_trapezoid

from autosar_cli.nav.attitude import GRAVITY_MPS2, BodyAttitude, tilt_offsets
from autosar_cli.nav.inputs import Measurements, NavInputs

Array = NDArray[np.float64]

#: The slow part fitted beside the unknowns reaches this frequency (Hz). test3 seed 42's true GNSS velocity (no noise),
#: 0 / 50 ms late: 0.1 Hz reads +10 / +15 ms too late (below it the attitude takes the wheels' acceleration, which
#: lags), 0.15 Hz -0.5 / +0.2 ms, 0.2 Hz -0.3 / +1.3 ms.
CUTOFF_HZ = 0.2
#: The latency's change from the table is searched for within ± this (s), on a grid of :data:`SEARCH_STEP_S`.
SEARCH_S = 0.4
SEARCH_STEP_S = 0.01
#: The std is the profile's curvature over +- this (s) about its minimum. GNSS noise drawn 30 times onto test3 seed
#: 42's true velocity: the fit scatters by 16.2 ms, the std states 15.2 (median; 13.2 over +-0.04 s).
PROFILE_SPAN_S = 0.06
#: GNSS velocity samples above this speed (m/s) set the heading's constant and drift: the course is noise below it.
MIN_SPEED_MPS = 1.0
#: A latency elsewhere that fits within this many std of the best makes the fit ambiguous.
SIGNIFICANT = 3.0
#: what a fit whose best latency lies at its search's edge says first
EDGE = "the best fit lies at the search's edge"
#: A drive with fewer GNSS velocity samples than this (or over less than :data:`MIN_SPAN_S`) is not measured.
MIN_SAMPLES = 50
MIN_SPAN_S = 5.0
#: The slow part is fitted over segments of at most this long (s).
SEGMENT_S = 60.0


@dataclass(frozen=True)
class GnssLatencyFit:
    """How much later than its table states the GNSS samples refer to: ``change_s`` (s; a sample stamped ``t``
    refers to ``t - latency_s - change_s``)."""

    imu: str  #: the IMU it was measured against
    table_latency_s: float  #: the GNSS sensor's stated latency
    change_s: float  #: fitted latency minus the table's
    std_s: float  #: its standard deviation (inf where the search found no minimum inside its span)
    samples: int  #: GNSS velocity samples compared
    accel_change_rms_mps2: float  #: RMS of the high-passed horizontal acceleration: how much the drive shows
    residual_rms_mps: float  #: the velocities' residual after the fit
    #: where another latency fits within SIGNIFICANT std of the best, away from its dip (or the best is at the search's
    #: edge): which; "" where the fit is unambiguous
    ambiguous: str = ""
    #: the chi-square of the table's latency over the best one's: how much worse the table fits
    table_chi2: float = 0.0
    applied: bool = False
    reason: str = ""

    def to_dict(self) -> dict[str, object]:
        """The fields, an unbounded std as None (JSON has no infinity)."""
        return {k: None if isinstance(v, float) and not math.isfinite(v) else v for k, v in asdict(self).items()}


def _heading(inputs: NavInputs, t: Array, yaw_rate: Array) -> Array:
    """The heading (rad, ENU) at the IMU's instants ``t``: its yaw rate integrated, with the constant and the
    drift (the gyro's bias) that bring it nearest the GNSS course above :data:`MIN_SPEED_MPS`."""
    vel = inputs.gnss_velocity
    assert vel is not None
    integrated = cumulative_trapezoid(yaw_rate, t, initial=0.0)
    moving = (np.hypot(*vel.z.T) > MIN_SPEED_MPS) & (vel.t >= t[0]) & (vel.t <= t[-1])
    if moving.sum() < 2:
        return integrated
    course = np.unwrap(np.arctan2(vel.z[moving, 1], vel.z[moving, 0]))
    offset = course - np.interp(vel.t[moving], t, integrated)
    # the course wraps where the integral does not: bring each offset to the first's turn
    offset = offset[0] + np.angle(np.exp(1j * (offset - offset[0])))
    design = np.stack([np.ones(moving.sum()), vel.t[moving] - t[0]], axis=-1)
    coef, *_ = np.linalg.lstsq(design, offset, rcond=None)
    return integrated + coef[0] + coef[1] * (t - t[0])


def _slow_projection(t: Array) -> Callable[[Array], Array]:
    """The projection off the slow part: ``(2N, ...)`` rows (E, N interleaved at the instants ``t`` (N,)) less their
    least-squares fit by a cosine series up to :data:`CUTOFF_HZ` per axis, over segments of at most
    :data:`SEGMENT_S` (the cost grows with the segment's length cubed)."""
    count = max(1, int(math.ceil((t[-1] - t[0]) / SEGMENT_S)))
    edges = np.searchsorted(t, np.linspace(t[0], t[-1], count + 1)[1:-1])
    bases = []
    for rows in np.split(np.arange(len(t)), edges):
        ts = t[rows]
        span = max(float(ts[-1] - ts[0]), 1e-9)
        orders = np.arange(int(math.ceil(2.0 * span * CUTOFF_HZ)) + 1)
        series = np.cos(np.pi * orders[None, :] * ((ts - ts[0]) / span)[:, None])
        slow = np.zeros((2 * len(ts), 2 * len(orders)))
        slow[0::2, :len(orders)], slow[1::2, len(orders):] = series, series
        bases.append((slice(2 * rows[0], 2 * rows[-1] + 2), np.linalg.qr(slow)[0]))

    def project(x: Array) -> Array:
        out = np.array(x, dtype=np.float64, copy=True)
        for rows, q in bases:
            out[rows] -= q @ (q.T @ out[rows])
        return out

    return project


def fit_gnss_latency(inputs: NavInputs, table_latency_s: float = 0.0,
                     attitude: BodyAttitude | None = None) -> GnssLatencyFit | None:
    """The GNSS latency's change from ``table_latency_s`` (the one ``inputs``' GNSS times were corrected by) against
    the drive's 6-DoF IMU (``inputs.attitude_imu``); with the body's ``attitude`` (that IMU's,
    :func:`.attitude.estimate_attitude`) its specific force less gravity, and the antenna's motion from the IMU as
    the body rolls and pitches. None without that IMU or a GNSS velocity, or with fewer than :data:`MIN_SAMPLES`
    velocities over :data:`MIN_SPAN_S` inside the IMU's span."""
    imu, vel = inputs.attitude_imu, inputs.gnss_velocity
    if imu is None or vel is None or len(imu.t) < 10:
        return None
    inside = (vel.t >= imu.t[0] + SEARCH_S) & (vel.t <= imu.t[-1] - SEARCH_S)
    tg, z = vel.t[inside], vel.z[inside]
    if len(tg) < MIN_SAMPLES or tg[-1] - tg[0] < MIN_SPAN_S:
        return None
    t, yaw_rate = imu.t, imu.angular_velocity[:, 2]
    psi = _heading(inputs, t, yaw_rate)
    east, north = np.stack([np.cos(psi), np.sin(psi)], -1), np.stack([-np.sin(psi), np.cos(psi)], -1)
    f = imu.specific_force[:, :2]
    r = np.asarray(inputs.gnss_lever_m) - np.asarray(imu.lever_arm_m)  # antenna from the IMU, body
    r_enu = east * r[0] + north * r[1]
    lever_velocity = yaw_rate[:, None] * np.stack([-r_enu[:, 1], r_enu[:, 0]], axis=-1)
    if attitude is not None:
        roll, pitch = np.interp(t, attitude.t, attitude.roll), np.interp(t, attitude.t, attitude.pitch)
        f = np.stack([f[:, 0] + GRAVITY_MPS2 * np.sin(pitch),
                      f[:, 1] - GRAVITY_MPS2 * np.cos(pitch) * np.sin(roll)], axis=-1)
        lever_velocity = lever_velocity + np.gradient(tilt_offsets(roll, pitch, psi, r), t, axis=0)
    # each unknown's velocity (N, 2): M's four entries (body axis i from force j), then the two biases
    accelerations = [axis * src[:, None] for axis in (east, north) for src in (f[:, 0], f[:, 1], np.ones_like(t))]
    columns = [cumulative_trapezoid(a, t, axis=0, initial=0.0) for a in accelerations]

    # the slow part of both sides, a cosine series up to CUTOFF_HZ per axis over each segment of at most SEGMENT_S, is
    # a nuisance fitted beside the unknowns: a high-pass with no edges (a filter's transient at a 12 s drive's ends had
    # swung test1's d by 180 ms). It is the same at every delay, so it is projected out once per segment
    project = _slow_projection(tg)

    stacked = np.stack([*columns, lever_velocity], axis=1)  # (N_imu, 7, 2)

    def at(delay: float) -> Array:
        """Every column and the lever's velocity at the GNSS instants less ``delay``, linearly interpolated (N, 7, 2):
        one search for all of them."""
        when = np.clip(tg - delay, t[0], t[-1])
        i = np.clip(np.searchsorted(t, when, side="right"), 1, len(t) - 1)
        w = ((when - t[i - 1]) / (t[i] - t[i - 1]))[:, None, None]
        return stacked[i - 1] * (1.0 - w) + stacked[i] * w

    measured = z.reshape(-1)

    def regression(delay: float) -> tuple[float, Array, Array, Array]:
        values = at(delay)
        design = project(values[:, :-1].transpose(0, 2, 1).reshape(-1, len(columns)))
        y = project(measured - values[:, -1].reshape(-1))
        coef, *_ = np.linalg.lstsq(design, y, rcond=None)
        res = y - design @ coef
        return float(res @ res), coef, design, y

    delays = np.arange(-SEARCH_S, SEARCH_S + SEARCH_STEP_S / 2, SEARCH_STEP_S)
    sse = np.array([regression(float(d))[0] for d in delays])
    k = int(np.argmin(sse))
    _, coef, design, y = regression(float(delays[k]))
    res = (y - design @ coef).reshape(-1, 2)
    # the profile's chi-square: the residual's variance at the minimum, its samples counted as independent ones
    # (lag-1 correlation rho per axis: N (1 - rho) / (1 + rho))
    rho = float(np.clip(np.mean([np.corrcoef(res[:-1, i], res[1:, i])[0, 1] for i in range(2)]), 0.0, 0.999))
    independent = res.size * (1.0 - rho) / (1.0 + rho)
    chi2 = (sse - sse[k]) / sse[k] * independent
    std, best, ambiguous = math.inf, float(delays[k]), ""
    if 0 < k < len(delays) - 1:
        s0, s1, s2 = chi2[k - 1:k + 2]
        best = float(delays[k] + SEARCH_STEP_S * 0.5 * (s0 - s2) / (s0 - 2.0 * s1 + s2))
        # the std from a parabola through the profile over +-PROFILE_SPAN_S, chi2 = (d - best)^2 / std^2: the
        # profile is rough on the scale of the IMU's samples (the road's vibration is in both velocities), and its
        # curvature there, or the linearised regression's, stated 10-12 ms where the fit scatters by 16 ms
        near = np.abs(delays - delays[k]) <= PROFILE_SPAN_S + 1e-9
        curvature = np.polyfit(delays[near] - delays[k], chi2[near], 2)[0]
        std = math.sqrt(1.0 / curvature) if curvature > 0 else math.inf
    # another delay that fits nearly as well, away from the minimum's own dip: the drive does not pin it down
    minima = [i for i in range(len(delays)) if (i == 0 or chi2[i] <= chi2[i - 1])
              and (i == len(delays) - 1 or chi2[i] <= chi2[i + 1]) and i != k]
    rivals = [i for i in minima if chi2[i] < SIGNIFICANT**2 and abs(delays[i] - best) > SIGNIFICANT * std]
    if rivals:
        i = min(rivals, key=lambda i: chi2[i])
        ambiguous = (f"a latency {delays[i] * 1000:+.0f} ms from the table's fits within {SIGNIFICANT:g} std too "
                     f"(chi-square {chi2[i]:.1f})")
    elif k in (0, len(delays) - 1):
        ambiguous = f"{EDGE}, {best * 1000:+.0f} ms from the table's"
    elif not math.isfinite(std):
        ambiguous = f"the fit's profile is flat about its best, {best * 1000:+.0f} ms from the table's"
    # the IMU's own velocity (M the identity) less its slow part, differentiated: the acceleration that measures d
    undelayed = at(0.0)
    fast = project((undelayed[:, 0] + undelayed[:, 4]).reshape(-1))
    accel = np.gradient(fast.reshape(-1, 2), tg, axis=0)
    return GnssLatencyFit(imu.name, table_latency_s, best, std, int(len(tg)),
                          float(np.sqrt(np.mean(np.sum(accel**2, axis=-1)))), float(np.sqrt(np.mean(res**2))),
                          ambiguous=ambiguous, table_chi2=float(chi2[int(np.argmin(np.abs(delays)))]))


def delayed_gnss(inputs: NavInputs, change_s: float) -> NavInputs:
    """``inputs`` with every GNSS sample (fix, velocity, climb, heading) moved ``change_s`` earlier: to the instant
    it refers to where the receiver's latency is its table's plus ``change_s``."""

    def moved(m: Measurements | None) -> Measurements | None:
        return None if m is None else replace(m, t=m.t - change_s)

    return replace(inputs, gnss_position=moved(inputs.gnss_position), gnss_velocity=moved(inputs.gnss_velocity),
                   gnss_climb=moved(inputs.gnss_climb), gnss_heading=moved(inputs.gnss_heading))
