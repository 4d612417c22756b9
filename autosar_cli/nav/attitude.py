"""Body roll and pitch from a 6-DoF IMU, and the radar's horizontal motion they cause.

SAR-MIN's track is planar: it places the radar by the rear axle's position and heading alone. A real body rolls
in turns and on uneven roads, and pitches with acceleration, braking and the road's grade; a radar mounted
r_z above the axis the body turns about then moves sideways by about -r_z phi and fore-aft by r_z theta. On the
full-model drives that is 3.4 mm RMS of horizontal radar motion (test3 seed 2), up to 1 cm, at the body's
1.3-1.7 Hz modes: the length of a synthetic aperture at 27 m.

The attitude is a zero-phase complementary estimate (a smoother, as the drive is processed after the fact):

* above the crossover (:data:`CROSSOVER_HZ`) the IMU's roll and pitch rates integrated through the Euler-rate
  equations: 0.03 mrad from the truth on test3 seed 2 above 0.5 Hz;
* below it the direction of gravity in the specific force, once the trajectory's own acceleration at the IMU
  is taken out (dv/dt and v omega of the rear axle carried to the IMU's lever arm, and the rotational
  acceleration about the roll axis from the differentiated rates): sin(theta) = (a_x - f_x) / g,
  sin(phi) = (f_y - a_y) / (g cos(theta)), with f = R^T (a + g z) in body axes (x forward, y left, z up;
  roll then pitch then yaw, ISO 8855).

The crossover trades the gyros' slow errors (turn-on bias, mounting misalignment that couples the yaw rate
into the roll and pitch rates) against the accelerometers' fast ones (the road's and the suspension's own
accelerations, noise). What the estimate keeps of each is a constant: an accelerometer's bias or misalignment
tilts the estimate by a steady angle (11 mrad of roll on test3 seed 2), a fixed sideways offset of the radar.

The body turns about an axis ``roll_axis_height_m`` above the road under the CoG (the suspension's roll
centre): the radar's lever from there is its lever from the CoG plus (0, 0, cog_height - roll_axis_height).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import cumulative_trapezoid
from scipy.signal import butter, filtfilt

from autosar_cli.nav.inputs import ImuSamples, Measurements

Array = NDArray[np.float64]

GRAVITY_MPS2 = 9.80665
#: Crossover (Hz) between the gyros' integrated rates (above) and the gravity direction (below). On test3 seed 2:
#: 0.76 / 0.47 mrad RMS roll / pitch error at 0.1 Hz, 0.87 / 0.75 at 0.05 Hz, 0.99 / 0.52 at 0.5 Hz.
CROSSOVER_HZ = 0.1
#: The trajectory's speed and yaw rate are smoothed below this before they are differentiated (Hz).
KINEMATICS_HZ = 5.0


@dataclass(frozen=True)
class BodyAttitude:
    """Roll and pitch of the body over time (rad; roll about x forward, pitch about y left)."""

    imu: str
    t: Array  #: (N,) s since the navigation's t0, uniform
    roll: Array  #: (N,) rad
    pitch: Array  #: (N,) rad
    #: the IMU's pitch bias taken out of ``pitch`` (rad; :func:`pitch_bias`), its std; NaN where not measured
    pitch_bias: float = math.nan
    pitch_bias_std: float = math.nan
    pitch_bias_samples: int = 0  #: the GNSS climb rates it was measured on

    def to_dict(self) -> dict[str, float | str]:
        out: dict[str, float | str] = {
            "imu": self.imu, "roll_mean_mrad": float(1e3 * self.roll.mean()),
            "roll_std_mrad": float(1e3 * self.roll.std()), "pitch_mean_mrad": float(1e3 * self.pitch.mean()),
            "pitch_std_mrad": float(1e3 * self.pitch.std())}
        if math.isfinite(self.pitch_bias):
            out.update(pitch_bias_mrad=1e3 * self.pitch_bias, pitch_bias_std_mrad=1e3 * self.pitch_bias_std)
        return out


def _zero_phase_lowpass(x: Array, cutoff_hz: float, rate_hz: float) -> Array:
    """Second-order Butterworth low-pass applied forwards and backwards along axis 0 (Gustafsson's initial
    conditions: no edge transient where the drive starts and ends)."""
    b, a = butter(2, min(cutoff_hz / (0.5 * rate_hz), 0.99))
    return np.asarray(filtfilt(b, a, x, axis=0, method="gust"))


def _integral(rate: Array, dt: float) -> Array:
    return np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * dt)])


def estimate_attitude(imu: ImuSamples, t: Array, speed: Array, yaw_rate: Array, *, cog_to_rear_axle_m: float,
                      cog_height_m: float, roll_axis_height_m: float,
                      crossover_hz: float = CROSSOVER_HZ) -> BodyAttitude | None:
    """Roll and pitch over the IMU's samples inside the trajectory's span ``t`` (s since t0), from the IMU and the
    rear axle's ``speed`` (m/s) and ``yaw_rate`` (rad/s) (the module's docstring); None with fewer than 10 s of
    samples (the crossover needs several periods)."""
    inside = (imu.t >= t[0]) & (imu.t <= t[-1])
    ti = imu.t[inside]
    if len(ti) < 2 or ti[-1] - ti[0] < 1.0 / crossover_hz:
        return None
    dt = float(np.median(np.diff(ti)))
    grid = np.arange(ti[0], ti[-1] + 0.5 * dt, dt)  # uniform, for the filters; dropped samples are interpolated
    w = np.stack([np.interp(grid, ti, imu.angular_velocity[inside, k]) for k in range(3)], axis=-1)
    f = np.stack([np.interp(grid, ti, imu.specific_force[inside, k]) for k in range(3)], axis=-1)
    rate = 1.0 / dt
    v = _zero_phase_lowpass(np.interp(grid, t, speed), KINEMATICS_HZ, rate)
    om = _zero_phase_lowpass(np.interp(grid, t, yaw_rate), KINEMATICS_HZ, rate)
    v_dot, om_dot = np.gradient(v, dt), np.gradient(om, dt)
    # the IMU's acceleration in the yaw frame: the rear axle's (no sideways slip) carried to its lever arm
    x = imu.lever_arm_m[0] + cog_to_rear_axle_m
    y = imu.lever_arm_m[1]
    a_x = v_dot - om**2 * x - om_dot * y
    a_y = v * om + om_dot * x - om**2 * y
    # and the body's own rotation about the roll axis below it
    h = imu.lever_arm_m[2] + cog_height_m - roll_axis_height_m
    w_dot = np.gradient(w, dt, axis=0)
    a_x = a_x + w_dot[:, 1] * h
    a_y = a_y - w_dot[:, 0] * h
    pitch_g = np.arcsin(np.clip((a_x - f[:, 0]) / GRAVITY_MPS2, -1.0, 1.0))
    roll_g = np.arcsin(np.clip((f[:, 1] - a_y) / (GRAVITY_MPS2 * np.cos(pitch_g)), -1.0, 1.0))
    roll = _zero_phase_lowpass(roll_g, crossover_hz, rate)
    pitch = _zero_phase_lowpass(pitch_g, crossover_hz, rate)
    p, q, r = w.T
    for _ in range(3):  # the Euler rates depend on the attitude itself: a few passes settle it
        roll_rate = p + (q * np.sin(roll) + r * np.cos(roll)) * np.tan(pitch)
        pitch_rate = q * np.cos(roll) - r * np.sin(roll)
        gyro_roll, gyro_pitch = _integral(roll_rate, dt), _integral(pitch_rate, dt)
        roll = gyro_roll + _zero_phase_lowpass(roll_g - gyro_roll, crossover_hz, rate)
        pitch = gyro_pitch + _zero_phase_lowpass(pitch_g - gyro_pitch, crossover_hz, rate)
    return BodyAttitude(imu.name, grid, roll, pitch)


def tilt_offsets(roll: Array, pitch: Array, heading: Array, lever_from_axis: Array) -> Array:
    """Horizontal ENU displacement (N, 2) (m) of a body point whose lever arm from the roll axis is
    ``lever_from_axis`` (3,) (m, body frame) when the body rolls by ``roll`` and pitches by ``pitch`` (N,) (rad)
    at ``heading`` (N,) (rad, ENU from East CCW): (R_y(pitch) R_x(roll) - I) lever, rotated by the heading."""
    lx, ly, lz = np.asarray(lever_from_axis, dtype=np.float64)
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    dx = cp * lx + sp * sr * ly + sp * cr * lz - lx
    dy = cr * ly - sr * lz - ly
    ch, sh = np.cos(heading), np.sin(heading)
    return np.stack([ch * dx - sh * dy, sh * dx + ch * dy], axis=-1)


def tilt_heights(roll: Array, pitch: Array, lever_from_axis: Array) -> Array:
    """Vertical displacement (N,) (m) of the body point ``lever_from_axis`` (3,) (m, body frame, from the roll
    axis) as the body rolls by ``roll`` and pitches by ``pitch`` (N,) (rad): the z row of
    (R_y(pitch) R_x(roll) - I) lever. A radar ahead of the axis drops as the nose pitches down (pitch > 0)."""
    lx, ly, lz = np.asarray(lever_from_axis, dtype=np.float64)
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    return -sp * lx + cp * sr * ly + cp * cr * lz - lz


def climb(t: Array, speed: Array, pitch: Array) -> Array:
    """Height (N,) (m) gained since ``t[0]`` (s) by the roll axis moving at ``speed`` (N,) (m/s) along the body's
    x axis pitched by ``pitch`` (N,) (rad, nose down > 0): the integral of -v sin(pitch) dt. The body's pitch on its
    suspension (about 2 deg/g under acceleration) counts as grade: k (v1^2 - v0^2) / 2, 3 cm from 0 to 4 m/s."""
    return np.asarray(cumulative_trapezoid(-np.asarray(speed) * np.sin(pitch), t, initial=0.0))


#: Below this speed (m/s) a GNSS climb rate says too little of the pitch to take part in its bias.
PITCH_BIAS_MIN_SPEED_MPS = 1.0

#: Half-span (s) of :func:`road_slope`'s average: the GNSS climb's noise (~0.05 m/s) to ~0.2 % of slope at 8 m/s,
#: short against a road's grade (wavelengths of 100 m and more: 12 s at 8 m/s).
SLOPE_HALF_SPAN_S = 1.0


def road_slope(climb_rate: Measurements, velocity: Measurements, t: Array,
               half_span_s: float = SLOPE_HALF_SPAN_S) -> Array:
    """The road's slope (N,) (rise over horizontal run) at times ``t`` (N,) (s, the measurements' clock): the mean,
    over the samples within ``half_span_s``, of a GNSS receiver's vertical velocity ``climb_rate`` (m/s) over its
    horizontal speed (``velocity``, (n, 2) ENU m/s), less the samples more than 4 robust std (1.4826 x the median
    absolute deviation) from their median; 0 where fewer than 3 samples there move faster than
    :data:`PITCH_BIAS_MIN_SPEED_MPS`. It needs no attitude, so no IMU's mounting error enters it. Not a plain mean,
    for a receiver's vertical velocity has outliers: one of 5 m/s among 21 samples at 10 m/s would read as a 2.4 %
    grade. Not the median, which on white noise scatters 1.25 times as much."""
    t = np.asarray(t, dtype=np.float64)
    speed = np.interp(climb_rate.t, velocity.t, np.hypot(velocity.z[:, 0], velocity.z[:, 1]))
    moving = speed > PITCH_BIAS_MIN_SPEED_MPS
    tc, slope = climb_rate.t[moving], climb_rate.z[moving, 0] / speed[moving]
    out = np.zeros_like(t)
    if len(tc) < 3:
        return out
    lo, hi = np.searchsorted(tc, t - half_span_s), np.searchsorted(tc, t + half_span_s, side="right")
    enough = hi - lo >= 3
    # the times share few windows (the samples' own, ~10 a second): one mean per window
    windows, which = np.unique(np.stack([lo[enough], hi[enough]], axis=1), axis=0, return_inverse=True)
    means = np.array([_robust_mean(slope[a:b]) for a, b in windows])
    out[enough] = means[which.ravel()]
    return out


def _robust_mean(x: Array, k: float = 4.0) -> float:
    """The mean of ``x`` less the values more than ``k`` robust std from its median (all of them where the median
    absolute deviation is 0)."""
    med = float(np.median(x))
    spread = 1.4826 * float(np.median(np.abs(x - med)))
    return float(np.mean(x[np.abs(x - med) <= k * spread])) if spread > 0 else float(np.mean(x))


def pitch_bias(att: BodyAttitude, speed: Array, climb_rate: Measurements,
               antenna_from_axis: Array) -> tuple[float, float, int]:
    """The constant error of ``att``'s pitch (rad), its std and the samples used, from a GNSS receiver's vertical
    velocity ``climb_rate`` (its antenna at ``antenna_from_axis`` (3,), m body frame from the roll axis):
    d/dt [climb + tilt_heights] = -v sin(pitch - b) + ..., linearised in b and solved by weighted least squares
    over the fixes above :data:`PITCH_BIAS_MIN_SPEED_MPS` (``speed`` (N,) m/s at ``att.t``).

    An IMU mounted 0.3-1 deg off (the simulator's range) tilts the pitch by as much, which the gravity direction
    cannot tell from the road's mean grade: integrated over 80 m it lifts the track by 0.4-1.4 m. The GNSS's
    vertical velocity, white at a few cm/s per fix, sees the grade itself. The std is scaled by the fit's reduced
    chi-square where that exceeds 1. NaNs where fewer than 10 fixes qualify."""
    tk = climb_rate.t
    inside = (tk >= att.t[0]) & (tk <= att.t[-1])
    v = np.interp(tk[inside], att.t, speed)
    use = v >= PITCH_BIAS_MIN_SPEED_MPS
    if use.sum() < 10:
        return math.nan, math.nan, int(use.sum())
    tk, v, measured = tk[inside][use], v[use], climb_rate.z[inside, 0][use]
    dt = float(np.median(np.diff(att.t)))

    def residual(b: float) -> tuple[Array, Array]:
        """The climb rates' residual with the pitch less b, and its derivative in b."""
        pitch = att.pitch - b
        tilt_rate = np.interp(tk, att.t, np.gradient(tilt_heights(att.roll, pitch, antenna_from_axis), dt))
        p = np.interp(tk, att.t, pitch)
        return measured - (-v * np.sin(p) + tilt_rate), v * np.cos(p)

    bias = 0.0
    for _ in range(2):  # sin(pitch - b) is nearly linear in b: two steps settle it
        r, slope = residual(bias)
        bias += float(np.sum(slope * r) / np.sum(slope**2))
    r, slope = residual(bias)
    sigma = float(climb_rate.sigma[0])
    chi2 = float(np.sum((r / sigma) ** 2)) / max(len(tk) - 1, 1)
    std = sigma / float(np.sqrt(np.sum(slope**2))) * math.sqrt(max(chi2, 1.0))
    return bias, std, len(tk)


def without_pitch_bias(att: BodyAttitude, bias: float, std: float, samples: int) -> BodyAttitude:
    """``att`` with ``bias`` (rad) taken out of its pitch and recorded (NaN: recorded as not measured)."""
    pitch = att.pitch - bias if math.isfinite(bias) else att.pitch
    return replace(att, pitch=pitch, pitch_bias=bias, pitch_bias_std=std, pitch_bias_samples=samples)
