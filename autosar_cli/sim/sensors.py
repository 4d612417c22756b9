"""Automotive sensor error models: what each on-board sensor of the config reports for a true motion.

Every function takes the truth motion, the sensor's config and its own random generator and returns
format-neutral samples (numpy arrays) plus the true error states, for the log writers and the truth
sidecar. Times are float64 seconds from the drive start; ``t_meas`` is the instant a value refers to,
``t_stamp`` = t_meas + latency is the header stamp the device gives it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from autosar_cli.config import AccelErrors, Config, GyroErrors, SensorConfig
from autosar_cli.nav.frames import course_deg_from_heading
from autosar_cli.sim.dynamics import FullMotion, rolled_wheel_angle
from autosar_cli.sim.trajectory import TruthMotion

Motion = TruthMotion | FullMotion
WHEEL_GRID_S = 0.002  # the kinematic wheels' rotation sampled this finely for their ECU's edges


@dataclass
class SensorSamples:
    """Samples of one sensor. ``values`` maps a quantity name to an (N,) or (N, k) array; ``truth`` holds
    the true values and error states (biases, scale errors) for the sidecar."""

    name: str
    kind: str
    t_meas: NDArray[np.float64]
    t_stamp: NDArray[np.float64]
    values: dict[str, NDArray[np.float64]]
    truth: dict[str, NDArray[np.float64]] = field(default_factory=dict)

    def select(self, keep: NDArray[np.bool_]) -> SensorSamples:
        """The samples where ``keep`` (N,) is true."""
        return SensorSamples(self.name, self.kind, self.t_meas[keep], self.t_stamp[keep],
                             {k: v[keep] for k, v in self.values.items()}, {k: v[keep] for k, v in self.truth.items()})


def sample_times(rate_hz: float, duration_s: float, rng: np.random.Generator, latency_s: float,
                 aligned: bool = False) -> NDArray[np.float64]:
    """Measurement instants at rate_hz with a random phase (or aligned to whole periods), leaving room for
    the latency before the end of the drive."""
    period = 1.0 / rate_hz
    phase = 0.0 if aligned else rng.uniform(0.0, period)
    n = int(np.floor((duration_s - latency_s - phase) / period)) + 1
    return phase + period * np.arange(max(n, 0))


def gauss_markov(n: int, dt: float, sigma: float, tau: float, rng: np.random.Generator) -> NDArray[np.float64]:
    """First-order Gauss-Markov sequence (stationary, std sigma, correlation time tau)."""
    if n == 0 or sigma == 0.0:
        return np.zeros(n)
    a = np.exp(-dt / tau)
    w = rng.standard_normal(n) * sigma * np.sqrt(1.0 - a * a)
    w[0] = rng.standard_normal() * sigma
    from scipy.signal import lfilter

    return lfilter([1.0], [1.0, -a], w)


def correlated(white: NDArray[np.float64], dt: float, tau: float) -> NDArray[np.float64]:
    """Unit white draws ``white`` (N, ...) made a stationary first-order Gauss-Markov sequence along axis 0 with
    correlation time ``tau`` (s) at spacing ``dt`` (s), each sample still of unit std; ``white`` itself where ``tau``
    is 0 (the same draws either way, so the rest of the drive's random streams do not move)."""
    if tau <= 0.0 or len(white) == 0:
        return white
    from scipy.signal import lfilter

    a = math.exp(-dt / tau)
    gain = math.sqrt(1.0 - a * a)
    # the first sample is the stationary one itself: its state (1 - gain) w0 makes y0 = w0
    return lfilter([gain], [1.0, -a], white, axis=0, zi=((1.0 - gain) * white[:1]))[0]


def turn_on_bias(nominal: float, rng: np.random.Generator, size: int | None = None) -> NDArray[np.float64]:
    """Turn-on bias: magnitude uniform in [0.5, 1.5] x nominal, random sign."""
    mag = rng.uniform(0.5, 1.5, size) * nominal
    return np.asarray(np.where(rng.random(size) < 0.5, -mag, mag), dtype=np.float64)


def gyro_errors(n: int, rate_hz: float, model: GyroErrors, axes: int,
                rng: np.random.Generator) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(bias (n, axes), white noise (n, axes)) in rad/s."""
    dt = 1.0 / rate_hz
    b0 = np.deg2rad(turn_on_bias(model.turn_on_bias_dps, rng, axes))
    drift = np.stack([gauss_markov(n, dt, np.deg2rad(model.bias_instability_dps), model.bias_tau_s, rng)
                      for _ in range(axes)], -1)
    noise = rng.standard_normal((n, axes)) * np.deg2rad(model.noise_density_dps_rthz) * np.sqrt(rate_hz)
    return b0[None, :] + drift, noise


def accel_errors(n: int, rate_hz: float, model: AccelErrors, axes: int,
                 rng: np.random.Generator) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(bias (n, axes), white noise (n, axes)) in m/s^2."""
    dt = 1.0 / rate_hz
    b0 = turn_on_bias(model.turn_on_bias_mps2, rng, axes)
    drift = np.stack([gauss_markov(n, dt, model.bias_instability_mps2, model.bias_tau_s, rng)
                      for _ in range(axes)], -1)
    noise = rng.standard_normal((n, axes)) * model.noise_density_mps2_rthz * np.sqrt(rate_hz)
    return b0[None, :] + drift, noise


def imu(motion: Motion, name: str, s: SensorConfig, rng: np.random.Generator) -> SensorSamples:
    """Body-frame gyro (rad/s) and accelerometer (m/s^2) of a strapdown IMU at its lever arm.

    A 3-DoF unit measures yaw rate and longitudinal/lateral acceleration: the other axes are NaN. On the full
    model each unit sits on the body with a small mounting misalignment (drawn once, after the other
    errors), so its axes see roll and pitch rates and gravity: measured = M (true) + bias + noise.
    """
    assert s.gyro is not None and s.accel is not None
    t = sample_times(s.rate_hz, motion.duration_s, rng, s.latency_s)
    n = t.size
    if isinstance(motion, FullMotion):
        true_gyro = motion.body_rates(t)
    else:
        true_gyro = np.zeros((n, 3))
        true_gyro[:, 2] = motion.states(t)["yaw_rate"]
    true_accel = motion.specific_force_body(t, s.lever_arm_m)
    gb, gn = gyro_errors(n, s.rate_hz, s.gyro, 3, rng)
    ab, an = accel_errors(n, s.rate_hz, s.accel, 3, rng)
    extra: dict[str, NDArray[np.float64]] = {}
    if isinstance(motion, FullMotion):
        lo, hi = motion.dyn.imu_misalignment_deg
        angles = np.deg2rad(rng.uniform(lo, hi, 3) * np.where(rng.random(3) < 0.5, -1.0, 1.0))
        if "imu_misalignment" not in motion.dyn.components:
            angles = np.zeros(3)
        mis = misalignment_matrix(angles)
        extra = {"misalignment_rad": angles}
        gyro = true_gyro @ mis.T + gb + gn
        accel = true_accel @ mis.T + ab + an
    else:
        gyro = true_gyro + gb + gn
        accel = true_accel + ab + an
    if s.kind == "imu" and s.dof == 3:
        gyro[:, :2] = np.nan
        accel[:, 2] = np.nan
    return SensorSamples(name, s.kind, t, t + s.latency_s, {"angular_velocity": gyro, "linear_acceleration": accel},
                         {"angular_velocity": true_gyro, "linear_acceleration": true_accel, "gyro_bias": gb,
                          "accel_bias": ab, **extra})


def misalignment_matrix(angles_rad: NDArray[np.float64]) -> NDArray[np.float64]:
    """Body -> sensor axes (3, 3) of a unit mounted with small rotation angles (rad) about body x, y, z."""
    return np.asarray(Rotation.from_euler("xyz", angles_rad).as_matrix().T)


def can_imu(motion: Motion, name: str, s: SensorConfig, rng: np.random.Generator) -> SensorSamples:
    """Yaw rate (rad/s) and longitudinal/lateral acceleration (m/s^2) of an ECU on CAN (ESC, ORC)."""
    full = imu(motion, name, s, rng)
    v = full.values
    return SensorSamples(
        name, s.kind, full.t_meas, full.t_stamp,
        {f"yaw_rate.{name}": v["angular_velocity"][:, 2], f"accel_long.{name}": v["linear_acceleration"][:, 0],
         f"accel_lat.{name}": v["linear_acceleration"][:, 1]},
        {f"yaw_rate.{name}": full.truth["angular_velocity"][:, 2], "gyro_bias": full.truth["gyro_bias"][:, 2],
         f"accel_long.{name}": full.truth["linear_acceleration"][:, 0],
         f"accel_lat.{name}": full.truth["linear_acceleration"][:, 1],
         "accel_bias": full.truth["accel_bias"][:, :2]},
    )


def wheel_speeds(motion: Motion, config: Config, name: str, s: SensorConfig,
                 rng: np.random.Generator) -> SensorSamples:
    """Rolling speed (m/s) of each wheel: ground speed of its centre, scaled by a per-wheel radius error."""
    assert s.wheel is not None
    v = config.vehicle
    t = sample_times(s.rate_hz, motion.duration_s, rng, s.latency_s)
    a = v.wheelbase_m - v.cog_to_rear_axle_m
    b = v.cog_to_rear_axle_m
    wheels = {"fl": (a, v.track_front_m / 2), "fr": (a, -v.track_front_m / 2),
              "rl": (-b, v.track_rear_m / 2), "rr": (-b, -v.track_rear_m / 2)}
    scale = 1.0 + rng.standard_normal(4) * s.wheel.radius_scale_error_std
    if isinstance(motion, FullMotion):
        return _tone_ring_wheel_speeds(motion, config, name, s, t, scale, rng)
    values, truth = {}, {}
    for i, (wheel, (x, y)) in enumerate(wheels.items()):
        centre = (x, y, -v.cog_height_m)
        true = np.linalg.norm(motion.point(t, centre).velocity, axis=1)
        noise = rng.standard_normal(t.size) * s.wheel.noise_std_mps
        if config.simulation.kinematic_ecu_window:
            reported = _ecu_window_speed(motion, centre, config, t)
            # the ECU's 0 is its "no edge" value, not a measurement
            values[f"wheel_speed_{wheel}"] = np.where(reported != 0.0, reported * scale[i] + noise, 0.0)
        else:
            values[f"wheel_speed_{wheel}"] = true * scale[i] + noise
        truth[f"wheel_speed_{wheel}"] = true
    truth["scale_factor"] = scale
    return SensorSamples(name, s.kind, t, t + s.latency_s, values, truth)


def _ecu_window_speed(motion: Motion, centre: tuple[float, float, float], config: Config,
                      t: NDArray[np.float64]) -> NDArray[np.float64]:
    """What an ABS ECU reports at ``t`` (s) for a wheel whose centre sits at ``centre`` (m, body frame) and rolls
    without slip: its mean speed (m/s) over the last edges of a perfect tone ring ([vehicle_dynamics]), the window
    the wheel sensor's table states as ``lag_distance_m`` (``simulation.kinematic_ecu_window``). The car rolled at
    its initial speed for a second before the log, so that the ECU has edges at t = 0."""
    dyn, radius = config.vehicle_dynamics, config.vehicle.wheel_radius_m
    grid = np.arange(0.0, motion.duration_s + WHEEL_GRID_S, WHEEL_GRID_S)
    ground = np.linalg.norm(motion.point(grid, centre).velocity, axis=1)
    grid, angle = rolled_wheel_angle(grid, ground / radius)
    speed, _ = tone_ring_speed(grid, angle, t, np.zeros(dyn.tone_ring_teeth), dyn.edges_per_speed_estimate,
                               dyn.wheel_speed_timeout_s, radius)
    return speed


def tone_ring_speed(t_grid: NDArray[np.float64], wheel_angle: NDArray[np.float64], t_samples: NDArray[np.float64],
                    tooth_error: NDArray[np.float64], edges_per_estimate: int, timeout_s: float,
                    radius_m: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Wheel speed (m/s) an ABS ECU computes at t_samples (s) from a tone ring's edges, and the edge times.

    wheel_angle (rad, non-decreasing) on t_grid (s); tooth_error (teeth,): each edge's position error as a
    fraction of the pitch. The ECU takes the newest edge before each sample and the one edges_per_estimate
    teeth earlier, assumes a perfect ring, and reports 0 when no edge came for timeout_s.
    """
    teeth = tooth_error.size
    pitch = 2.0 * np.pi / teeth
    first = int(np.floor(wheel_angle[0] / pitch)) + 1
    last = int(np.floor(wheel_angle[-1] / pitch)) - 1
    j = np.arange(first, max(last, first))
    edge_t = np.interp((j + tooth_error[j % teeth]) * pitch, wheel_angle, t_grid)
    k = np.searchsorted(edge_t, t_samples, side="right") - 1
    ok = (k >= edges_per_estimate) & (t_samples - edge_t[np.maximum(k, 0)] <= timeout_s) if edge_t.size else (
        np.zeros(t_samples.size, dtype=bool))
    speed = np.zeros(t_samples.size)
    kk = k[ok]
    speed[ok] = edges_per_estimate * pitch * radius_m / (edge_t[kk] - edge_t[kk - edges_per_estimate])
    return speed, edge_t


def _tone_ring_wheel_speeds(motion: FullMotion, config: Config, name: str, s: SensorConfig,
                            t: NDArray[np.float64], scale: NDArray[np.float64],
                            rng: np.random.Generator) -> SensorSamples:
    """Full model: each wheel's rotation through its tone ring's edges; the ECU's nominal radius is the
    config's times the wheel's scale error (a tyre whose real size differs from the nominal)."""
    dyn = motion.dyn
    values, truth = {}, {}
    radius = config.vehicle.wheel_radius_m * scale
    ground = {}
    for i, wheel in enumerate(("fl", "fr", "rl", "rr")):
        err = rng.standard_normal(dyn.tone_ring_teeth) * dyn.tooth_pitch_error_std
        if "wheel_ticks" in dyn.components:
            speed, _ = tone_ring_speed(motion.wheel_t, motion.wheel_angle[:, i], t, err,
                                       dyn.edges_per_speed_estimate, dyn.wheel_speed_timeout_s, float(radius[i]))
        else:  # the wheel's rotation rate itself, with the kinematic model's white noise
            speed = (np.interp(t, motion.t, motion.wheel_rate[:, i]) * radius[i]
                     + rng.standard_normal(t.size) * s.wheel.noise_std_mps)
        values[f"wheel_speed_{wheel}"] = speed
        ground[wheel] = np.linalg.norm(motion.point(t, motion.wheel_positions[i]).velocity, axis=1)
        truth[f"wheel_speed_{wheel}"] = ground[wheel]
        truth[f"tooth_error_{wheel}"] = err
    truth["scale_factor"] = scale
    return SensorSamples(name, s.kind, t, t + s.latency_s, values, truth)


def steering(motion: Motion, config: Config, name: str, s: SensorConfig,
             rng: np.random.Generator) -> SensorSamples:
    """Steering-wheel angle (rad) = ratio x kinematic road-wheel angle + offset + noise, and its rate."""
    assert s.steering is not None
    v = config.vehicle
    t = sample_times(s.rate_hz, motion.duration_s, rng, s.latency_s)
    true = v.steering_ratio * motion.road_wheel_angle(t, v.wheelbase_m)
    offset = np.deg2rad(rng.standard_normal() * s.steering.offset_std_deg)
    angle = true + offset + rng.standard_normal(t.size) * np.deg2rad(s.steering.noise_std_deg)
    h = 1e-3
    rate = (v.steering_ratio * (motion.road_wheel_angle(t + h, v.wheelbase_m)
                                - motion.road_wheel_angle(t - h, v.wheelbase_m)) / (2 * h))
    return SensorSamples(name, s.kind, t, t + s.latency_s,
                         {"steering_wheel_angle": angle, "steering_wheel_rate": rate},
                         {"steering_wheel_angle": true, "offset": np.array([offset])})


def gnss(motion: Motion, name: str, s: SensorConfig, rng: np.random.Generator) -> SensorSamples:
    """Antenna position (ENU, m) with time-correlated + white errors, ENU velocity (m/s), true heading
    (deg from North, clockwise) and course over ground; fixes at whole multiples of the period (UTC)."""
    assert s.gnss is not None
    e = s.gnss
    t = sample_times(s.rate_hz, motion.duration_s, rng, s.latency_s, aligned=True)
    n, dt = t.size, 1.0 / s.rate_hz
    k = motion.point(t, s.lever_arm_m)
    err = np.stack([gauss_markov(n, dt, e.horizontal_std_m, e.correlation_time_s, rng),
                    gauss_markov(n, dt, e.horizontal_std_m, e.correlation_time_s, rng),
                    gauss_markov(n, dt, e.vertical_std_m, e.correlation_time_s, rng)], -1)
    err += rng.standard_normal((n, 3)) * e.white_std_m * np.array([1.0, 1.0, 2.0])
    vel = k.velocity + correlated(rng.standard_normal((n, 3)), dt, e.velocity_correlation_time_s) \
        * e.velocity_std_mps * np.array([1.0, 1.0, 1.5])
    heading = motion.states(t)["heading"]
    true_heading_deg = course_deg_from_heading(heading)
    heading_deg = np.mod(true_heading_deg + rng.standard_normal(n) * e.heading_std_deg, 360.0)
    cog_deg = np.mod(np.rad2deg(np.arctan2(vel[:, 0], vel[:, 1])), 360.0)
    # drawn for every instant first, so that an outage or a reflection leaves the other samples' errors as they were
    for start, duration, east, north in e.multipath:
        err[(t >= start) & (t < start + duration), :2] += (east, north)
    keep = np.ones(n, dtype=bool)
    for start, duration in e.outages:
        keep &= ~((t >= start) & (t < start + duration))
    samples = SensorSamples(
        name, s.kind, t, t + s.latency_s,
        {"position_enu": k.position + err, "velocity_enu": vel, "heading_deg": heading_deg, "course_deg": cog_deg},
        {"position_enu": k.position, "velocity_enu": k.velocity, "heading_deg": true_heading_deg,
         "position_error": err},
    )
    return samples if keep.all() else samples.select(keep)
