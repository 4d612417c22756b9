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


def test_beat_kernel_matches_float64_reference_with_moving_targets():
    """Cyclists and cars riding past a moving radar (up to 10 m/s each way), among still scatterers: the kernel's
    movers, at their chirps' start and end and linear between, against their exact position at every sample."""
    rng = np.random.default_rng(4)
    frames = 3
    geo = _geometry(rng, frames, (5.0, 0.0, 0.0))
    targets = np.column_stack([rng.uniform(1, 26, 40), rng.uniform(-12, 12, 40), rng.uniform(0, 2, 40)])
    rcs = rng.uniform(0.01, 10, 40)
    velocity = np.zeros((40, 3))
    velocity[::3] = rng.uniform(-10, 10, (14, 3))  # every third moves, interleaved with the still ones
    starts = 0.25 + np.arange(frames)[:, None] * 1e-3 + np.array([0.0, 40e-6, 80e-6])[None, :]
    fast = synthesize_beat(*geo, targets, rcs, **KW, target_velocity=velocity, chirp_start_s=starts)
    ref = beat_reference(*geo, targets, rcs, **KW, target_velocity=velocity, chirp_start_s=starts)
    err_db = 10 * np.log10(np.sum(np.abs(fast - ref) ** 2) / np.sum(np.abs(ref) ** 2))
    assert err_db < -45.0, f"relative error {err_db:.1f} dB"
    still = synthesize_beat(*geo, targets, rcs, **KW)
    assert 10 * np.log10(np.sum(np.abs(still - ref) ** 2) / np.sum(np.abs(ref) ** 2)) > -10.0  # they do move


@pytest.mark.parametrize("moving", [False, True])
def test_beat_kernel_matches_float64_reference_by_way_of_the_road(moving):
    """A road that reflects (Gamma -0.6) beneath targets up to 2 m high, some on it, some retroreflectors; a still
    radar, or one moving at 5 m/s among targets some of which move: the kernel's four paths per target against the
    reference's, each leg written out on its own."""
    rng = np.random.default_rng(5)
    frames = 3
    geo = _geometry(rng, frames, (5.0, 0.0, 0.0) if moving else (0.0, 0.0, 0.0))
    n = 40
    road = rng.uniform(-0.05, 0.05, n)
    targets = np.column_stack([rng.uniform(1, 26, n), rng.uniform(-12, 12, n), road + rng.uniform(0, 2, n)])
    targets[::5, 2] = road[::5]  # on the road: their image is themselves
    rcs = rng.uniform(0.01, 10, n)
    retro = np.zeros(n, bool)
    retro[1::4] = True
    extra = {}
    if moving:
        velocity = np.zeros((n, 3))
        velocity[::3] = rng.uniform(-10, 10, (14, 3)) * [1, 1, 0]
        extra = dict(target_velocity=velocity, chirp_start_s=0.25 + np.arange(frames)[:, None] * 1e-3
                     + np.array([0.0, 40e-6, 80e-6])[None, :])
    road_kw = dict(road_reflection=-0.6, road_height=road, retroreflector=retro)
    fast = synthesize_beat(*geo, targets, rcs, **KW, **extra, **road_kw)
    ref = beat_reference(*geo, targets, rcs, **KW, **extra, **road_kw)
    err_db = 10 * np.log10(np.sum(np.abs(fast - ref) ** 2) / np.sum(np.abs(ref) ** 2))
    assert err_db < (-45.0 if moving else -90.0), f"relative error {err_db:.1f} dB"
    direct = beat_reference(*geo, targets, rcs, **KW, **extra)
    # the road's paths carry -19 / -21 dB of the echoes (the near, high targets' images lie far below the beam)
    assert 10 * np.log10(np.sum(np.abs(direct - ref) ** 2) / np.sum(np.abs(ref) ** 2)) > -25.0


def test_a_point_over_a_reflecting_road_lobes_as_the_two_ray_model():
    """A still point 0.5 m above a level road, a radar 0.8 m above it, 5-20 m apart: the first ADC sample's
    amplitude over the direct path's alone is the two-ray propagation factor F^2 = |1 + Gamma (r/r') e^(jk(r'-r))|^2
    (Skolnik, Radar Handbook, ch. 26: power F^4; r, r' the direct and the mirrored one-way ranges, k at the first
    sample's frequency), lobing through deep nulls; a trihedral, which returns each ray the way it came, gives
    |1 + Gamma^2 (r/r')^2 e^(2jk(r'-r))|."""
    gamma, height, mount = -0.7, 0.5, 0.8
    # near-isotropic in elevation, so both rays see one pattern; a slow ramp, whose residual video phase
    # (K tau dtau, 0.008 rad at 75 MHz/us) is not the rays'
    kw = dict(KW, beamwidth_el_deg=179.99, slope_hz_per_s=75e9)
    ranges = np.linspace(5.0, 20.0, 301)
    at = np.array([[0.0, 0.0, mount]])
    geo = (at[None], at[None], at[None, None], at[None, None], at, np.eye(3)[None])
    k = 2 * np.pi * 77e9 / 299792458.0
    for retro in (False, True):
        measured, factor = [], []
        for x in ranges:
            point = np.array([[x, 0.0, height]])
            road = dict(road_reflection=gamma, road_height=np.zeros(1), retroreflector=np.array([retro]))
            both = synthesize_beat(*geo, point, np.array([1.0]), **kw, **road)[0, 0, 0, 0]
            alone = synthesize_beat(*geo, point, np.array([1.0]), **kw)[0, 0, 0, 0]
            measured.append(abs(both) / abs(alone))
            r, r_img = np.hypot(x, mount - height), np.hypot(x, mount + height)
            ray = gamma * r / r_img * np.exp(1j * k * (r_img - r))
            factor.append(abs(1 + ray**2) if retro else abs(1 + ray) ** 2)
        measured, factor = np.array(measured), np.array(factor)
        assert np.max(np.abs(measured - factor)) < 0.01
        # lobes and nulls, both seen: (1 -+ |Gamma|)^2, or 1 -+ Gamma^2 for the trihedral
        assert factor.min() < (0.55 if retro else 0.15) and factor.max() > (1.45 if retro else 2.5)


def test_a_receding_target_has_the_doppler_and_range_rate_of_its_speed():
    """A lone scatterer receding from a still radar at 0.5 m/s from 10 m: from frame to frame (1 ms) its first
    sample's phase turns by 2 v f0 / c per second (the Doppler, 256.9 Hz), and its beat frequency rises by
    K 2 v / c per second."""
    frames, pri = 16, 1e-3
    zero = np.zeros((frames, 1, 3))
    geo = (zero, zero, np.zeros((frames, 1, 1, 3)), np.zeros((frames, 1, 1, 3)), np.zeros((frames, 3)),
           np.tile(np.eye(3), (frames, 1, 1)))
    starts = np.arange(frames)[:, None] * pri
    out = synthesize_beat(*geo, np.array([[10.0, 0.0, 0.0]]), np.array([4.0]), **KW,
                          target_velocity=np.array([[0.5, 0.0, 0.0]]), chirp_start_s=starts)[:, 0, 0]
    turns = np.unwrap(np.angle(out[:, 0])) / (2 * np.pi)
    doppler_hz = np.polyfit(starts[:, 0], turns, 1)[0]
    c = 299792458.0
    assert doppler_hz == pytest.approx(2 * 0.5 * 77e9 / c, rel=1e-3)
    spec = np.abs(np.fft.fft(out, 540 * 64, axis=1))
    f_beat = np.argmax(spec, axis=1) * 13.5e6 / (540 * 64)
    rate = np.polyfit(starts[:, 0], f_beat, 1)[0]
    assert rate == pytest.approx(75e12 * 2 * 0.5 / c, rel=0.05)


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
    # ~5.4 m/s: the ~19.5 km/h up to which the radar images unambiguously (docs/SIMULATION.md, Scenarios)
    v_max_imaging = 990 * 8 * (cfg.radar.wavelength_m / 4) * np.cos(np.pi / 4)
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


def test_the_configs_cyclists_ride_along_the_path_after_the_scene(tmp_path):
    """simulation.cyclists adds riders last (the scene's other scatterers keep their draws and order), each moving
    along the path's heading at its speed; the truth sidecar keeps their velocities, in the frame of an origin."""
    from dataclasses import replace

    from autosar_cli.nav.geodesy import GeodeticOrigin
    from autosar_cli.sim.scene import KINDS
    from autosar_cli.sim.truth import TruthWriter, read_targets

    cfg = load_config()
    still = build_scenario("test1", cfg).scene  # test1 drives west: along u is -x
    riders = replace(cfg, simulation=replace(cfg.simulation, cyclists=((15.0, -6.5, 3.0), (45.0, -7.5, -4.0))))
    scene = build_scenario("test1", riders).scene
    n = len(still.position)
    np.testing.assert_array_equal(scene.position[:n], still.position)
    assert still.velocity_enu is None and not still.moving.any()
    moving = scene.moving
    assert not moving[:n].any() and moving[n:].all() and np.all(scene.kind[n:] == KINDS.index("cyclist"))
    np.testing.assert_allclose(scene.velocity_enu[n:n + 9], [[-3.0, 0.0, 0.0]] * 9, atol=1e-12)
    np.testing.assert_allclose(scene.velocity_enu[n + 9:], [[4.0, 0.0, 0.0]] * 9, atol=1e-12)
    sim = cfg.simulation
    origin = GeodeticOrigin(sim.origin_lat_deg, sim.origin_lon_deg, sim.origin_height_m)
    truth = TruthWriter(tmp_path / "t.truth.h5", {"origin_lat_deg": sim.origin_lat_deg,
                                                  "origin_lon_deg": sim.origin_lon_deg,
                                                  "origin_height_m": sim.origin_height_m}, 3, 4)
    truth.write_targets(scene)
    truth.close()
    got = read_targets(tmp_path / "t.truth.h5", origin)
    np.testing.assert_allclose(got.velocity_enu, scene.velocity_enu, atol=1e-6)
