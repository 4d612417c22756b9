"""The CAN bus's delay beyond its tables, measured against the IMUs' yaw rate (nav/can_latency.py)."""

from __future__ import annotations

import numpy as np
import pytest


def _inputs(delay_s: float, turning: bool, seed: int = 0):  # noqa: ANN202
    """Two IMU gyros (500 Hz, 0.01 rad/s noise) and two CAN gyros (100 Hz, 0.005 rad/s noise, scale +1 % / -0.5 %,
    biases 0.01 / -0.02 rad/s) stamped ``delay_s`` late, over 40 s of a car weaving (0.3 rad/s at 0.15 Hz) or going
    straight."""
    from autosar_cli.nav.geodesy import GeodeticOrigin
    from autosar_cli.nav.inputs import Measurements, NavInputs

    rng = np.random.default_rng(seed)

    def yaw_rate(t: np.ndarray) -> np.ndarray:
        return 0.3 * np.sin(2 * np.pi * 0.15 * t) if turning else np.zeros_like(t)

    t_imu = np.arange(0.0, 40.0, 0.002)
    t_can = np.arange(0.0, 40.0, 0.01) + 0.0037
    gyros = [Measurements(name, t_imu, (yaw_rate(t_imu) + rng.normal(0, 0.01, t_imu.size))[:, None], np.array([0.01]))
             for name in ("imu_a", "imu_b")]
    gyros += [Measurements(name, t_can + delay_s, (scale * yaw_rate(t_can) + bias
                                                   + rng.normal(0, 0.005, t_can.size))[:, None], np.array([0.005]))
              for name, scale, bias in (("esc", 1.01, 0.01), ("orc", 0.995, -0.02))]
    return NavInputs(0, GeodeticOrigin(45.0, 7.0, 0.0), gyros=gyros)


@pytest.mark.parametrize("delay_s", [0.0, 0.04, -0.025])
def test_the_can_gyros_delay_against_the_imus_is_found_within_its_std(delay_s: float) -> None:
    """Weaving: the delay comes back within 1 ms and within 3 of the std it states (each gyro's own scale and bias
    beside it); moved back by it, the CAN samples line up with the IMUs' (the fit then reads 0 within 1 ms)."""
    from autosar_cli.nav.can_latency import delayed_can, fit_can_latency

    inputs = _inputs(delay_s, turning=True)
    fit = fit_can_latency(inputs, ["esc", "orc"], ["imu_a", "imu_b"])
    assert fit is not None and fit.can_gyros == ("esc", "orc") and fit.yaw_acceleration_rms_radps2 > 0.1
    assert abs(fit.delay_s - delay_s) < 1e-3 and abs(fit.delay_s - delay_s) < 3 * fit.std_s + 1e-4, fit
    assert fit.std_s < 1e-3
    again = fit_can_latency(delayed_can(inputs, fit.delay_s, ["esc", "orc"]), ["esc", "orc"], ["imu_a", "imu_b"])
    assert again is not None and abs(again.delay_s) < 1e-3


def test_a_straight_drive_leaves_the_delay_unmeasured_and_navigate_keeps_the_tables() -> None:
    """Going straight the yaw rate does not change: the drive's yaw acceleration is below the minimum that measures
    the delay, and the CAN signals stay where their tables put them."""
    import dataclasses

    from autosar_cli.config import load_config
    from autosar_cli.nav.navigate import MIN_YAW_ACCELERATION_RADPS2, can_latency_corrected

    inputs = _inputs(0.04, turning=False)
    base = load_config()
    sensors = {"esc": base.sensors["esc"], "orc": base.sensors["orc"], "imu_a": base.sensors["imu_cog_a"],
               "imu_b": base.sensors["imu_cog_b"]}
    cfg = dataclasses.replace(base, sensors=sensors)
    out, info = can_latency_corrected(inputs, cfg)
    assert out is inputs and not info["applied"]
    assert info["yaw_acceleration_rms_radps2"] < MIN_YAW_ACCELERATION_RADPS2 and "hardly turns" in info["reason"]
    moved, info = can_latency_corrected(_inputs(0.04, turning=True), cfg)
    assert info["applied"] and abs(info["delay_s"] - 0.04) < 1e-3
    assert np.allclose(moved.gyros[2].t, inputs.gyros[2].t - info["delay_s"])
    assert np.array_equal(moved.gyros[0].t, inputs.gyros[0].t)


def test_navigate_moves_a_late_can_bus_back(tmp_path) -> None:  # noqa: ANN001
    """test3 by the simulator's full car (seed 0) whose whole CAN bus (wheels, steering, ESC and ORC yaw rates) is
    stamped 40 ms later than the tables say: navigate measures 40 ms (within 2 ms) and moves it back."""
    import dataclasses

    from conftest import full_car_drive

    from autosar_cli.config import load_config
    from autosar_cli.nav.navigate import navigate

    late = {name: dataclasses.replace(s, latency_s=s.latency_s + 0.04) for name, s in load_config().sensors.items()
            if s.kind in ("wheel_speeds", "steering", "can_imu")}
    assert len(late) == 4
    drive, _, cfg = full_car_drive(tmp_path, "test3", late)
    info = navigate(drive, "sar-min", cfg).info["can_latency"]
    assert info["applied"] and abs(info["delay_s"] - 0.04) < 0.002, info
