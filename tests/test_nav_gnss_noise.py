"""The GNSS white noise a drive shows (nav.gnss_noise) against closed forms: smooth motion plus known noise."""

from __future__ import annotations

import numpy as np

from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.nav.gnss_noise import MIN_RATIO, gnss_noise_checked, white_noise_std
from autosar_cli.nav.inputs import Measurements, NavInputs


def _drive_positions(t: np.ndarray) -> np.ndarray:
    """A car's antenna (ENU m) on a 13 s S-bend: 8 m/s along, braking at 0.5 m/s^2, weaving 1.5 m at 0.15 Hz."""
    along = 8.0 * t - 0.25 * t**2
    across = 1.5 * np.sin(2 * np.pi * 0.15 * t)
    return np.stack([along, across], axis=-1)


def test_white_noise_is_measured_on_a_smooth_drive_and_nothing_on_a_noise_free_one() -> None:
    rng = np.random.default_rng(4)
    t = np.arange(0.0, 13.0, 0.1) + rng.normal(0.0, 0.002, 130)  # a receiver's stamps jitter by ms
    clean = _drive_positions(t)
    assert white_noise_std(t, clean)[0] < 1e-3  # the motion's own third differences: below a millimetre
    estimates = []
    for seed in range(200):
        noisy = clean + np.random.default_rng(seed).normal(0.0, 0.03, clean.shape)
        estimates.append(white_noise_std(t, noisy)[0])
    estimates = np.array(estimates)
    assert abs(np.median(estimates) / 0.03 - 1.0) < 0.03  # unbiased within 3 %
    assert np.std(estimates) / 0.03 < 0.12  # ~8-10 % spread on one 13 s drive
    assert np.max(estimates) / 0.03 < MIN_RATIO  # the table is never raised for a receiver that meets it


def test_a_gap_leaves_out_the_differences_across_it() -> None:
    t = np.concatenate([np.arange(0.0, 8.0, 0.1), np.arange(11.0, 19.0, 0.1)])  # 3 s without fixes
    z = _drive_positions(t) + np.random.default_rng(1).normal(0.0, 0.05, (len(t), 2))
    std, n = white_noise_std(t, z)
    assert n == 2 * (len(t) - 3 - 3)  # N - 3 third differences, less the 3 that span the gap
    assert abs(std / 0.05 - 1.0) < 0.15
    assert np.isnan(white_noise_std(t[:30], z[:30])[0])  # too few to measure


def test_only_a_receiver_noisier_than_its_table_is_reweighed() -> None:
    t = np.arange(0.0, 13.0, 0.1)
    rng = np.random.default_rng(2)
    pos = _drive_positions(t)
    vel = np.gradient(pos, t, axis=0)
    inputs = NavInputs(0, GeodeticOrigin(45.0, 9.0, 100.0))
    inputs.gnss_position = Measurements("gnss", t, pos + rng.normal(0.0, 0.06, pos.shape), np.full(2, 0.03))
    inputs.gnss_velocity = Measurements("gnss", t, vel + rng.normal(0.0, 0.02, vel.shape), np.full(2, 0.03))
    checked, info = gnss_noise_checked(inputs)
    assert info["position"]["applied"] and 1.7 < info["position"]["ratio"] < 2.3
    assert abs(checked.gnss_position.sigma[0] - info["position"]["measured_std"]) < 1e-12
    assert not info["velocity"]["applied"]  # quieter than its table: the table stays
    assert checked.gnss_velocity is inputs.gnss_velocity
    off, info_off = gnss_noise_checked(inputs, enabled=False)
    assert off.gnss_position is inputs.gnss_position and not info_off["position"]["applied"]
    assert "is off" in info_off["position"]["reason"]


def test_the_fits_against_a_noisier_gnss_velocity_take_wider_bounds() -> None:
    from autosar_cli.config import load_config
    from autosar_cli.nav.gnss_noise import with_fit_bounds_widened

    config = load_config()
    nav = config.navigation
    assert with_fit_bounds_widened(config, {"velocity": {"applied": False, "ratio": 1.2}}) is config
    assert with_fit_bounds_widened(config, {"position": {"applied": True, "ratio": 2.0}}) is config  # velocity only
    wide = with_fit_bounds_widened(config, {"velocity": {"applied": True, "ratio": 1.96}}).navigation
    assert wide.rear_slip_max_std_rad_per_mps2 == 1.96 * nav.rear_slip_max_std_rad_per_mps2
    assert wide.wheel_lag_max_std_m == 1.96 * nav.wheel_lag_max_std_m
    assert wide.wheel_radius_gain_max_std_per_mps2 == 1.96 * nav.wheel_radius_gain_max_std_per_mps2
    assert wide.understeer_max_std_rad_per_mps2 == nav.understeer_max_std_rad_per_mps2  # fitted against the gyros
