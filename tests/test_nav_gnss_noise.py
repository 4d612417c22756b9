"""The GNSS white noise a drive shows (nav.gnss_noise) against closed forms: smooth motion plus known noise."""

from __future__ import annotations

import numpy as np
import pytest

from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.nav.gnss_noise import (
    MIN_RATIO,
    MIN_REPORTED_RATIO,
    gnss_noise_checked,
    gnss_slow_error_checked,
    white_noise_std,
)
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


def test_only_a_receiver_stating_more_than_its_table_raises_the_slow_error() -> None:
    """The slow error's std is raised to what the receiver states less the fixes' white sigma, in quadrature, where
    the statement exceeds the table's total by MIN_REPORTED_RATIO; otherwise, and where nothing is stated, the slow
    error is off, or the estimate is off, the inputs are left as they are, with the reason."""
    t = np.arange(0.0, 13.0, 0.1)
    inputs = NavInputs(0, GeodeticOrigin(45.0, 9.0, 100.0), gnss_error_std_m=0.25, gnss_error_time_s=60.0)
    inputs.gnss_position = Measurements("gnss", t, _drive_positions(t), np.full(2, 0.03))
    table = float(np.hypot(0.25, 0.03))
    for reported, applied in ((0.5, True), (table, False), (MIN_REPORTED_RATIO * table * 0.999, False),
                              (float("nan"), False)):
        inputs.gnss_reported_std_m = reported
        checked, info = gnss_slow_error_checked(inputs)
        assert info["applied"] == applied, info["reason"]
        assert info["table_std_m"] == pytest.approx(table, rel=1e-12)
        if applied:
            assert checked.gnss_error_std_m == pytest.approx(np.sqrt(0.5**2 - 0.03**2), rel=1e-12)
            assert checked.gnss_position is inputs.gnss_position  # the white sigma is the white test's
        else:
            assert checked is inputs
    assert "no covariance" in info["reason"]
    inputs.gnss_reported_std_m = 0.5
    assert not gnss_slow_error_checked(inputs, enabled=False)[1]["applied"]
    white = NavInputs(0, GeodeticOrigin(45.0, 9.0, 100.0), gnss_reported_std_m=0.5)
    assert "no slow error" in gnss_slow_error_checked(white)[1]["reason"]


def test_navigate_takes_the_slow_error_a_receiver_states_and_its_position_std_holds(tmp_path) -> None:  # noqa: ANN001
    """test1's full car, its receiver's slow error twice the table's (0.5 m; it states so in its fixes' covariance,
    as the simulator's does): SAR-MIN takes 0.5 m and states the position's std by it. With the table's 0.25 m the
    error over the std was 1.93 / 1.82 RMS (along / across) over the 40 drives of bench_nav_seeds.py; with it, the
    std the covariance states is about twice the table's here."""
    from conftest import full_car_drive, with_gnss_errors

    from autosar_cli.nav.navigate import navigate

    drive, _, cfg = full_car_drive(tmp_path, "test1", with_gnss_errors(horizontal_std_m=0.5))
    traj = navigate(drive, "sar-min", cfg)
    info = traj.info["gnss_slow_error"]
    assert info["applied"], info["reason"]
    assert info["reported_std_m"] == pytest.approx(np.hypot(0.5, 0.03), rel=1e-6)
    assert info["slow_std_m"] == pytest.approx(0.5, rel=1e-6)
    i = traj.state_names.index("px")
    std = float(np.sqrt(np.median(traj.covariance[:, i, i])))
    assert 0.4 < std < 0.55, std  # the table's: 0.23 m
    from typer.testing import CliRunner

    from autosar_cli.cli import app

    result = CliRunner().invoke(app, ["navigate", str(drive), "-o", str(tmp_path / "trajectory.h5")])
    assert result.exit_code == 0, result.output
    said = " ".join(result.output.split())
    assert "GNSS slow error: the receiver states 0.501 m, 1.99 times the table's 0.252 m" in said


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


def _gauss_markov(n: int, rho: float, rng: np.random.Generator) -> np.ndarray:
    """A stationary first-order Gauss-Markov sequence of unit std, successive samples correlated by ``rho``."""
    from autosar_cli.sim.sensors import correlated

    return correlated(rng.standard_normal(n), 1.0, -1.0 / np.log(rho)) if rho > 0 else rng.standard_normal(n)


def test_the_long_run_factor_is_how_much_more_a_correlated_mean_scatters() -> None:
    from autosar_cli.nav.gnss_noise import VelocityCorrelation

    rng = np.random.default_rng(3)
    means = [np.mean(_gauss_markov(500, 0.82, rng)) for _ in range(2000)]
    factor = VelocityCorrelation(0.82, 500, 0.1).long_run_factor  # sqrt(1.82 / 0.18) = 3.18
    assert abs(factor - np.sqrt(1.82 / 0.18)) < 1e-12
    assert abs(np.std(means) / (factor / np.sqrt(500)) - 1.0) < 0.08  # independent samples: 1 / sqrt(500)
    assert VelocityCorrelation(0.0, 500, 0.1).correlation_time_s == 0.0
    assert abs(VelocityCorrelation(np.exp(-0.2), 500, 0.1).correlation_time_s - 0.5) < 1e-12


def test_the_successive_correlation_reads_smoothed_noise_and_not_white_noise_or_a_burst() -> None:
    from autosar_cli.nav.gnss_noise import MIN_CORRELATION_FACTOR, successive_correlation

    t = np.arange(0.0, 13.0, 0.1)  # test1's 13 s at 10 Hz: the fewest samples a drive gives it
    smoothed = [successive_correlation(t, _gauss_markov(len(t), 0.82, np.random.default_rng(s)))[0]
                for s in range(200)]
    assert abs(np.median(smoothed) - 0.82) < 0.05
    white = np.array([successive_correlation(t, np.random.default_rng(s).standard_normal(len(t)))[0]
                      for s in range(200)])
    rho_limit = (MIN_CORRELATION_FACTOR**2 - 1.0) / (MIN_CORRELATION_FACTOR**2 + 1.0)  # 0.51
    assert abs(np.median(white)) < 0.05 and np.max(white) < rho_limit
    # 2 s of the wheels' model missing by 3 sigma (a braking into a turn) in white noise
    burst = np.random.default_rng(7).standard_normal(len(t)) + np.where((t > 5) & (t < 7), 3.0, 0.0)
    assert successive_correlation(t, burst)[0] < 0.3
    gap = np.concatenate([t[:60], t[60:] + 5.0])  # a pair across a gap is not a pair
    assert successive_correlation(gap, burst)[1] == len(t) - 2


def test_a_velocity_whose_errors_correlate_is_carried_as_a_gauss_markov_state() -> None:
    from autosar_cli.nav.gnss_noise import WHITE_SHARE, velocity_decorrelated

    t = np.arange(0.0, 40.0, 0.1)
    vel = np.gradient(_drive_positions(t), t, axis=0)
    inputs = NavInputs(0, GeodeticOrigin(45.0, 9.0, 100.0))
    inputs.gnss_velocity = Measurements("gnss", t, vel, np.full(2, 0.03))
    rng = np.random.default_rng(5)
    smoothed = 0.03 * _gauss_markov(len(t), np.exp(-0.1 / 0.5), rng)  # a receiver smoothing over 0.5 s
    carried, info = velocity_decorrelated(inputs, (t, smoothed))
    assert info["applied"] and 0.25 < info["correlation_time_s"] < 0.95, info  # 99 % of 500 draws: 0.26-0.92
    assert 2.3 < info["long_run_factor"] < 4.3  # sqrt(1.82 / 0.18) = 3.18; 99 % of draws 2.31-4.28
    # the error as a state of the samples' whole sigma less their white share, over the correlation it shows
    assert abs(carried.gnss_velocity.sigma[0] - WHITE_SHARE * 0.03) < 1e-12
    assert abs(carried.gnss_velocity_error_std_mps ** 2 + (WHITE_SHARE * 0.03) ** 2 - 0.03**2) < 1e-12
    rho_state = np.exp(-0.1 / carried.gnss_velocity_error_time_s)
    assert abs(rho_state * (1 - WHITE_SHARE**2) - info["correlation"]) < 1e-9
    assert np.array_equal(carried.gnss_velocity.z, vel)  # the samples themselves stay
    white, info = velocity_decorrelated(inputs, (t, 0.03 * rng.standard_normal(len(t))))
    assert not info["applied"] and white is inputs and "below" in info["reason"]
    kept, info = velocity_decorrelated(inputs, (t, smoothed), carry=False)  # measured, reported, not carried
    assert kept is inputs and info["correlated"] and not info["applied"] and "too confident" in info["reason"]
    off, info = velocity_decorrelated(inputs, (t, smoothed), enabled=False)
    assert off is inputs and "is off" in info["reason"]
    none, info = velocity_decorrelated(inputs, None)
    assert none is inputs and "no wheel speeds" in info["reason"]


@pytest.mark.parametrize("tau_s", [0.0, 0.5])
def test_navigate_weighs_the_velocity_of_a_receiver_that_smooths_it(tmp_path, tau_s: float) -> None:  # noqa: ANN001
    """The simulator's full car on test1 (seed 0), its receiver's velocity errors correlated over ``tau_s``:
    navigate measures that against the wheel speeds and carries it as a state (with the states off, it warns);
    white, it leaves the samples."""
    from conftest import full_car_drive, with_gnss_errors

    from autosar_cli.config import load_config
    from autosar_cli.nav.navigate import navigate

    drive, _, cfg = full_car_drive(tmp_path, "test1", with_gnss_errors(velocity_correlation_time_s=tau_s))
    traj = navigate(drive, "sar-min", cfg)
    info = traj.info["gnss_velocity_correlation"]
    assert info["applied"] == (tau_s > 0), info["reason"]
    assert ("gnss_velocity_error.east" in traj.state_names) == (tau_s > 0)
    if tau_s > 0:
        assert abs(info["correlation_time_s"] / tau_s - 1.0) < 0.3
        assert abs(info["error_time_s"] / tau_s - 1.0) < 0.4
        # the states off: measured and reported, the samples independent; the CLI warns
        from typer.testing import CliRunner

        from autosar_cli.cli import app
        from autosar_cli.config import DEFAULT_CONFIG

        default = DEFAULT_CONFIG.read_text()
        off = default.replace("gnss_velocity_error_states = true", "gnss_velocity_error_states = false")
        assert off != default
        (tmp_path / "off.toml").write_text(off)
        assert not navigate(drive, "sar-min", load_config(tmp_path / "off.toml")).info[
            "gnss_velocity_correlation"]["applied"]
        result = CliRunner().invoke(app, ["navigate", str(drive), "-o", str(tmp_path / "trajectory.h5"),
                                          "--config", str(tmp_path / "off.toml")])
        assert result.exit_code == 0, result.output
        said = " ".join(result.output.split())
        assert "GNSS velocity: successive errors correlate by" in said and "too confident" in said
