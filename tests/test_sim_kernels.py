"""Simulator kernels against straightforward references: beat synthesis, truth kinematics, scenarios."""

from __future__ import annotations

import numpy as np
import pytest
from reference import beat_reference

from autosar_cli.config import load_config
from autosar_cli.sim.echo import synthesize_beat
from autosar_cli.sim.scenario import SCENARIOS, build_scenario

KW = dict(start_frequency_hz=77e9, slope_hz_per_s=75e12, sample_rate_hz=13.5e6, num_samples=540,
          amplitude_lsb=1500.0, beamwidth_az_deg=120.0, beamwidth_el_deg=60.0)


def _geometry(rng, frames, velocity):
    origin = np.array([0.0, 0.0, 0.5]) + np.arange(frames)[:, None] * np.array([0.005, 0.0, 0.0])
    rot = np.tile(np.eye(3), (frames, 1, 1))
    tx0 = origin[:, None, :] + rng.normal(0, 0.004, (frames, 3, 3))
    rx0 = origin[:, None, None, :] + rng.normal(0, 0.004, (frames, 3, 4, 3))
    move = np.asarray(velocity) * 40e-6
    return tx0, tx0 + move, rx0, rx0 + move, origin, rot


@pytest.mark.parametrize(("velocity", "limit_db"), [((0.0, 0.0, 0.0), -90.0), ((5.0, 0.0, 0.0), -45.0)])
def test_beat_kernel_matches_float64_reference(velocity, limit_db):
    rng = np.random.default_rng(3)
    geo = _geometry(rng, 3, velocity)
    targets = np.column_stack([rng.uniform(1, 26, 40), rng.uniform(-12, 12, 40), rng.uniform(0, 2, 40)])
    rcs = rng.uniform(0.01, 10, 40)
    fast = synthesize_beat(*geo, targets, rcs, **KW)
    ref = beat_reference(*geo, targets, rcs, **KW)
    err_db = 10 * np.log10(np.sum(np.abs(fast - ref) ** 2) / np.sum(np.abs(ref) ** 2))
    assert err_db < limit_db, f"relative error {err_db:.1f} dB"


def test_beat_of_single_target_has_the_range_frequency():
    """A lone scatterer at 10 m on boresight: a tone at f = K * 2R / c, amplitude A sqrt(rcs) / R^2."""
    zero = np.zeros((1, 1, 3))
    geo = (zero, zero, np.zeros((1, 1, 1, 3)), np.zeros((1, 1, 1, 3)), np.zeros((1, 3)), np.eye(3)[None])
    out = synthesize_beat(*geo, np.array([[10.0, 0.0, 0.0]]), np.array([4.0]), **KW)[0, 0, 0]
    spec = np.abs(np.fft.fft(out, 540 * 16))
    f = np.argmax(spec) * 13.5e6 / (540 * 16)
    assert f == pytest.approx(75e12 * 20.0 / 299792458.0, rel=2e-4)
    assert np.abs(out).mean() == pytest.approx(1500.0 * 2.0 / 100.0, rel=1e-5)
    # behind the antenna plane or beyond the IF band: nothing received
    for p in ([-5.0, 0.0, 0.0], [27.5, 0.0, 0.0]):
        assert np.abs(synthesize_beat(*geo, np.array([p]), np.array([4.0]), **KW)).max() == 0


def test_truth_kinematics_are_consistent_derivatives():
    cfg = load_config()
    motion = build_scenario("test3", cfg).motion
    t = np.linspace(1.0, motion.duration_s - 1.0, 500)
    h = 1e-4
    lever = (2.2, -0.75, 0.0)
    k, kp, km = motion.point(t, lever), motion.point(t + h, lever), motion.point(t - h, lever)
    assert np.abs((kp.position - km.position) / (2 * h) - k.velocity).max() < 1e-6
    assert np.abs((kp.velocity - km.velocity) / (2 * h) - k.acceleration).max() < 1e-4
    s, sp, sm = motion.states(t), motion.states(t + h), motion.states(t - h)
    assert np.abs((sp["heading"] - sm["heading"]) / (2 * h) - s["yaw_rate"]).max() < 1e-7
    # rear axle moves along the heading (kinematic bicycle: no lateral slip)
    rear = motion.point(t, (-cfg.vehicle.cog_to_rear_axle_m, 0.0, 0.0)).velocity
    lateral = -np.sin(s["heading"]) * rear[:, 0] + np.cos(s["heading"]) * rear[:, 1]
    assert np.abs(lateral).max() < 1e-9


@pytest.mark.parametrize("name", SCENARIOS)
def test_scenarios_are_plausible_drives(name):
    cfg = load_config()
    sc = build_scenario(name, cfg)
    m = sc.motion
    t = np.linspace(0, m.duration_s, 4001)
    st = m.states(t)
    v_max_imaging = 990 * 8 * (cfg.radar.wavelength_m / 4) * np.cos(np.pi / 4)  # ~5.4 m/s (DESIGN.md)
    assert st["speed"].max() < v_max_imaging
    assert st["speed"].min() > 1.0 or name == "urban"  # urban stops for 6 s and goes
    assert np.abs(st["accel"]).max() < 3.0
    assert np.abs(st["yaw_rate"] * st["speed"]).max() < 3.0  # lateral acceleration, m/s^2
    assert len(sc.scene.corner_reflectors) >= 3
    if name == "test1":  # ~50 m E -> W, speed rising to ~18 km/h, ~0.5 m drift to the left (south)
        d = st["position"][-1] - st["position"][0]
        assert d[0] == pytest.approx(-50.0, abs=0.5) and d[1] == pytest.approx(-0.5, abs=0.1)
        assert st["speed"].max() * 3.6 == pytest.approx(18.0, abs=1.0)
    if name == "test2":  # ~120 m W -> E with a +-1 m double curve
        assert st["position"][-1, 0] - st["position"][0, 0] == pytest.approx(120.0, abs=0.5)
        assert st["position"][:, 1].max() == pytest.approx(1.0, abs=0.05)
        assert st["position"][:, 1].min() == pytest.approx(-1.0, abs=0.05)
