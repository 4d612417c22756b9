"""The GNSS latency against the 6-DoF IMU (nav.gnss_latency): a closed-form drive, and the simulator's full car."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from autosar_cli.config import load_config
from autosar_cli.ingest.pipeline import ingest
from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.nav.gnss_latency import delayed_gnss, fit_gnss_latency
from autosar_cli.nav.inputs import ImuSamples, Measurements, NavInputs
from autosar_cli.nav.navigate import navigate

IMU_LEVER = (0.0, 0.0, 0.3)
ANTENNA_LEVER = (-1.4, 0.2, 1.2)  # from the CoG, body axes: behind it, off the centre line


def _motion(t: np.ndarray, weave: bool) -> tuple[np.ndarray, ...]:
    """Closed form: speed (m/s) 8 +- 1 at 0.25 Hz and yaw rate (rad/s) 0.1 at 0.33 Hz (``weave``; else straight
    at 8 m/s), the heading their integral, the body's acceleration (m/s^2, forward and left)."""
    if not weave:
        z = np.zeros_like(t)
        return 8.0 + z, z, z, z, z
    w_v, w_r = 2 * np.pi * 0.25, 2 * np.pi / 3.0
    v = 8.0 + np.sin(w_v * t)
    yaw_rate = 0.1 * np.sin(w_r * t)
    heading = 0.1 / w_r * (1.0 - np.cos(w_r * t))
    return v, yaw_rate, heading, w_v * np.cos(w_v * t), v * yaw_rate


def _inputs(delay_s: float, weave: bool = True, seed: int = 0, duration_s: float = 30.0) -> NavInputs:
    """A drive whose GNSS velocity (10 Hz, 0.03 m/s white noise) refers to ``delay_s`` before its instants, and an
    IMU at the CoG (100 Hz) with the body's acceleration (a level body: its specific force is its acceleration)."""
    rng = np.random.default_rng(seed)
    ti = np.arange(0.0, duration_s, 0.01)
    _, yaw_rate, _, a_x, a_y = _motion(ti, weave)
    force = np.stack([a_x, a_y, np.full_like(ti, 9.80665)], axis=-1) + rng.normal(0.0, 0.01, (len(ti), 3))
    rates = np.stack([np.zeros_like(ti), np.zeros_like(ti), yaw_rate], axis=-1)
    imu = ImuSamples("imu", ti, rates, force, IMU_LEVER)
    tg = np.arange(0.5, duration_s - 0.5, 0.1)
    v, w, psi, _, _ = _motion(tg - delay_s, weave)
    r = np.array(ANTENNA_LEVER[:2]) - np.array(IMU_LEVER[:2])
    # the antenna's ground velocity: the CoG's (no slip) plus omega x r, in ENU
    body = np.stack([v - w * r[1], w * r[0]], axis=-1)
    enu = np.stack([np.cos(psi) * body[:, 0] - np.sin(psi) * body[:, 1],
                    np.sin(psi) * body[:, 0] + np.cos(psi) * body[:, 1]], axis=-1)
    velocity = Measurements("gnss", tg, enu + rng.normal(0.0, 0.03, enu.shape), np.array([0.03, 0.03]))
    return NavInputs(0, GeodeticOrigin(45.0, 7.0, 0.0), gnss_velocity=velocity, attitude_imu=imu,
                     gnss_lever_m=ANTENNA_LEVER)


def test_the_latency_is_found_on_a_weaving_drive_and_its_std_is_its_scatter() -> None:
    """Against the closed form: a velocity 80 ms late is found within 3 std (over 20 noise draws the fit's mean within
    5 ms, its scatter within 0.6-1.6 of the std it states), one on time reads 0 within 3 std, and none is ambiguous."""
    found = [fit_gnss_latency(_inputs(0.08, seed=seed)) for seed in range(20)]
    assert all(f is not None and not f.ambiguous for f in found)
    change = np.array([f.change_s for f in found if f])
    std = np.array([f.std_s for f in found if f])
    assert np.all(np.abs(change - 0.08) < 3 * std)
    assert abs(change.mean() - 0.08) < 0.005
    assert 0.6 < change.std() / np.median(std) < 1.6
    on_time = fit_gnss_latency(_inputs(0.0, seed=99))
    assert on_time is not None and abs(on_time.change_s) < 3 * on_time.std_s < 0.03


def test_a_drive_without_acceleration_does_not_pin_the_latency_down() -> None:
    """A straight drive at a steady speed: every delay fits alike, so the fit says it is ambiguous (or its std is
    unbounded); too short a drive is not measured at all."""
    fit = fit_gnss_latency(_inputs(0.08, weave=False))
    assert fit is not None and (fit.ambiguous or not np.isfinite(fit.std_s) or fit.std_s > 0.1)
    assert fit_gnss_latency(_inputs(0.08, duration_s=4.0)) is None


def test_delayed_gnss_moves_every_gnss_stream_and_nothing_else() -> None:
    inputs = _inputs(0.0)
    inputs.gnss_position = dataclasses.replace(inputs.gnss_velocity, name="fix")
    moved = delayed_gnss(inputs, 0.1)
    assert np.allclose(moved.gnss_velocity.t, inputs.gnss_velocity.t - 0.1)
    assert np.allclose(moved.gnss_position.t, inputs.gnss_position.t - 0.1)
    assert moved.attitude_imu is inputs.attitude_imu


@pytest.mark.parametrize("latency_s", [0.05, 0.25])
def test_navigate_moves_the_gnss_by_the_latency_the_full_car_shows(tmp_path, latency_s: float) -> None:  # noqa: ANN001
    """The simulator's full car on test3 (seed 5), its GNSS stamped 250 ms after the instant it refers to while the
    table says 50 ms: navigate finds the latency within 3 std and moves the samples; at the table's latency it
    finds nothing to move."""
    from autosar_cli.sim.simulate import simulate

    base = load_config()
    cfg = dataclasses.replace(base, radar=dataclasses.replace(base.radar, prf_hz=20.0))
    sensors = dict(cfg.sensors)
    sensors["gnss_cog"] = dataclasses.replace(sensors["gnss_cog"], latency_s=latency_s)
    sim = simulate("test3", tmp_path / "t3.mcap", seed=5, config=dataclasses.replace(cfg, sensors=sensors),
                   dynamics="full")
    drive = tmp_path / "t3.h5"
    ingest([sim.log_path], drive, config=cfg)
    info = navigate(drive, "sar-min", cfg).info["gnss_latency"]
    change = latency_s - cfg.sensors["gnss_cog"].latency_s
    assert abs(info["change_s"] - change) < 3 * info["std_s"]
    assert info["applied"] == (change > 0), info["reason"]
    if change > 0:  # the user is told, with the latency to set
        from typer.testing import CliRunner

        from autosar_cli.cli import app

        result = CliRunner().invoke(app, ["navigate", str(drive), "-o", str(tmp_path / "trajectory.h5")])
        assert result.exit_code == 0, result.output
        said = " ".join(result.output.split())
        assert "GNSS latency: the samples refer to" in said and "set [sensors.gnss_cog] latency_s" in said
