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

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter, filtfilt

from autosar_cli.nav.inputs import ImuSamples

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

    def to_dict(self) -> dict[str, float | str]:
        return {"imu": self.imu, "roll_mean_mrad": float(1e3 * self.roll.mean()),
                "roll_std_mrad": float(1e3 * self.roll.std()), "pitch_mean_mrad": float(1e3 * self.pitch.mean()),
                "pitch_std_mrad": float(1e3 * self.pitch.std())}


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
