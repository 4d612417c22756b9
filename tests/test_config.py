"""Typed config: the default file loads with the paper's numbers; bad files are rejected naming the key."""

from __future__ import annotations

import contextlib
import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from autosar_cli.config import DEFAULT_CONFIG, ConfigError, load_config


def test_default_config_has_the_reference_hardware():
    c = load_config()
    assert c.vehicle.wheelbase_m == 2.82 and c.vehicle.steering_ratio == 11.8
    r = c.radar
    assert (r.num_tx, r.num_rx, r.num_samples) == (3, 4, 540)
    assert r.slope_hz_per_s * r.num_samples / r.sample_rate_hz == pytest.approx(3e9)
    assert r.range_resolution_m == pytest.approx(0.04997, abs=1e-4)
    # the 8 virtual phase centres of Tx0/Tx2 x 4 Rx are lambda/4 apart along the antenna row
    lam = r.wavelength_m
    mids = sorted((t[1] + q[1]) / 2 for t in (r.tx_positions_m[0], r.tx_positions_m[2]) for q in r.rx_positions_m)
    assert all(math.isclose(b - a, lam / 4, rel_tol=1e-12) for a, b in zip(mids, mids[1:], strict=False))
    assert r.tx_start_offsets_s == pytest.approx((0.0, 60e-6, 120e-6))
    assert c.dbc_path.exists()
    assert set(c.sensors_of_kind("imu")) == {"imu_cog_a", "imu_cog_b", "ins_cog", "ins_radar"}
    assert c.can.role_signal("yaw_rate.orc") == ("ORC_1", "YAW_RATE")


def _write_variant(tmp_path: Path, pattern: str, replacement: str) -> Path:
    text = DEFAULT_CONFIG.read_text()
    new, n = re.subn(pattern, replacement, text, count=1, flags=re.MULTILINE)
    assert n == 1, pattern
    p = tmp_path / "variant.toml"
    p.write_text(new)
    (tmp_path / "autosar_giulia.dbc").write_text((DEFAULT_CONFIG.parent / "autosar_giulia.dbc").read_text())
    return p


def test_a_board_with_more_antennas_than_the_radar_uses(tmp_path: Path) -> None:
    """``tx_channels`` picks the board's rows the radar uses, in the cube's order: Tx 0 and 2 of the three."""
    r = load_config(_write_variant(tmp_path, r"^num_tx = 3$", "num_tx = 2\ntx_channels = [0, 2]")).radar
    board = load_config().radar
    assert r.tx_in_use == (0, 2) and r.rx_in_use == (0, 1, 2, 3)
    np.testing.assert_array_equal(r.tx_positions_m, np.asarray(board.tx_positions_m)[[0, 2]])
    assert r.tx_start_offsets_s == (0.0, 60e-6)  # chirp slots of the two in use
    assert r.using_channels((2, 1), (3,)).tx_positions_m == tuple(board.tx_positions_m[k] for k in (2, 1))


@pytest.mark.parametrize(
    ("pattern", "replacement", "key"),
    [
        (r"^wheelbase_m = .*$", "wheelbase_m = -2.82", "vehicle.wheelbase_m"),
        (r"^slope_hz_per_s = .*$", "slope_hz_per_s = 70.0e12", "radar.bandwidth_hz"),
        (r"^lever_arm_m = \[2.20, -0.75, 0.0\].*$", "lever_arm_m = [2.20, nan, 0.0]", "radar.mounting.lever_arm_m"),
        (r"^wheelbase_m = .*$", "wheelbase_m = 2.82\nwheel_base = 2.9", "vehicle.wheel_base"),
        (r"^noise_density_dps_rthz = 0.008", "noise_dnsity_dps_rthz = 0.008", "sensors.imu_cog_a.gyro.noise_dnsity"),
        (r"^dof = 3 ", "dof = 4 ", "sensors.imu_cog_a.dof"),
        (r"^prf_hz = .*$", 'prf_hz = "fast"', "radar.prf_hz"),
        (r"^num_tx = 3$", "num_tx = 2", "radar.tx_channels"),
        (r"^max_step_s = .*$", "max_step_s = 1e-9", "navigation.max_step_s"),
        (r"^bias_tau_s = 100.0", "bias_tau_s = 0.0", "sensors.esc.gyro.bias_tau_s"),
        (r"^cross_range_resolution_m = .*$", "cross_range_resolution_m = 1e-9", "processing.cross_range_resolution_m"),
        (r"^num_tx = 3$", "num_tx = 2\ntx_channels = [0, 3]", "radar.tx_channels"),
        (r"^num_tx = 3$", "num_tx = 2\ntx_channels = [2, 2]", "radar.tx_channels"),
        (r"^num_tx = 3$", "num_tx = 3\ntx_channels = [0, 2]", "radar.tx_channels"),
        (r"^num_rx = 4$", "num_rx = 4\nrx_channels = [0, 1, 2, 4]", "radar.rx_channels"),
        (r'^"yaw_rate.orc" = .*$', '"yaw_rate.orc" = "ORC_1_YAW"', "can.roles.yaw_rate.orc"),
        (r"^max_range_m = .*$", "max_range_m = 40.0", "radar.max_range_m"),
        (r"^range_window = .*$", 'range_window = "kaiser"', "processing.range_window"),
        (r"^attitude_imu = .*$", 'attitude_imu = "imu_cog_a"', "navigation.attitude_imu"),
        (r"^roll_axis_height_m = .*$", "roll_axis_height_m = 0.9", "vehicle.roll_axis_height_m"),
        (r"^outages = \[\]", "outages = [[12.0, -3.0]]", "sensors.gnss_cog.gnss.outages[0]"),
        (r"^multipath = \[\]", "multipath = [[12.0, 3.0, 1.0]]", "sensors.gnss_cog.gnss.multipath[0]"),
        (r"^channel_phase_std_deg = .*$", "channel_phase_std_deg = -30.0", "simulation.channel_phase_std_deg"),
        (r"^autofocus_channel_gains = .*$", 'autofocus_channel_gains = "yes"', "processing.autofocus_channel_gains"),
        (r"^radar_clock_offset_s = .*$", "radar_clock_offset_s = 5.0", "simulation.radar_clock_offset_s"),
        (r"^clock_offset_s = .*$", "clock_offset_s = -3.0", "radar.clock_offset_s"),
        (r"^clock_drift_ppm = .*$", "clock_drift_ppm = 2500.0", "radar.clock_drift_ppm"),
        (r"^radar_clock_drift_ppm = .*$", 'radar_clock_drift_ppm = "fast"', "simulation.radar_clock_drift_ppm"),
        (r"^drive_front_fraction = .*$", "drive_front_fraction = 1.5", "vehicle_dynamics.drive_front_fraction"),
        (r"^brake_front_fraction = .*$", "brake_front_fraction = -0.2", "vehicle_dynamics.brake_front_fraction"),
        (r"^road_reflection = .*$", "road_reflection = -1.0", "simulation.road_reflection"),
        (r"^tyre_vertical_stiffness_n_per_m = .*$", "tyre_vertical_stiffness_n_per_m = 0.0",
         "vehicle_dynamics.tyre_vertical_stiffness_n_per_m"),
        (r"^mass_kg = .*$", "mass_kg = -1600.0", "vehicle_dynamics.mass_kg"),
        (r"^driver_preview_s = .*$", "driver_preview_s = -0.3", "vehicle_dynamics.driver_preview_s"),
    ],
)
def test_bad_values_are_rejected_naming_the_key(tmp_path, pattern, replacement, key):
    path = _write_variant(tmp_path, pattern, replacement)
    with pytest.raises(ConfigError) as exc:
        load_config(path)
    msg = str(exc.value)
    assert str(path) in msg
    assert key in msg, msg


@pytest.mark.parametrize(("text", "said"), [
    ("[vehicle]\nwheelbse_m = 2.8\n", "vehicle.wheelbse_m: unknown key (did you mean wheelbase_m?)"),
    ("wheelbase_m = 2.8\n", "wheelbase_m: unknown key (a key of [vehicle])"),
    ("[radar]\nwheelbase_m = 2.8\n", "radar.wheelbase_m: unknown key (a key of [vehicle])"),
    ("[vehicle]\ncolour = 2.8\n", "vehicle.colour: unknown key"),
    # a table of its own for the focus's keys (the CLI's command is focus; its keys are [processing]'s)
    ("[focus]\npixel_m = 0.05\nchannels = 12\n", "focus: unknown key (its keys belong in [processing])"),
    ("[focuss]\npixel_m = 0.05\n", "focuss: unknown key (its keys belong in [processing])"),
    ("[focus]\npixel_m = 0.05\nwheelbase_m = 2.8\n", "focus: unknown key"),
])
def test_an_unknown_key_names_the_key_it_likely_is(tmp_path: Path, text: str, said: str) -> None:
    path = tmp_path / "layer.toml"
    path.write_text('base = "default"\n' + text)
    with pytest.raises(ConfigError) as exc:
        load_config(path)
    assert str(exc.value) == f"{path}: {said}"


def test_missing_key_and_missing_file(tmp_path):
    path = _write_variant(tmp_path, r"^steering_ratio = .*$", "")
    with pytest.raises(ConfigError, match=r"vehicle\.steering_ratio: missing required key \(a config is complete, or "
                                          r"says base = \"default\""):
        load_config(path)
    partial = tmp_path / "partial.toml"
    partial.write_text("[radar]\nprf_hz = 500.0\n")  # a whole table missing is named as a table
    with pytest.raises(ConfigError, match=r"partial.toml: vehicle: missing required table"):
        load_config(partial)
    with pytest.raises(ConfigError, match="config file not found"):
        load_config(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[vehicle\nname = 1")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(bad)


def test_a_config_on_a_base_holds_only_what_differs(tmp_path: Path) -> None:
    """``base = "default"`` (or a path beside the config): tables merged key by key over the base's, values and arrays
    replaced, a chain of bases followed, the default's DBC found from a config elsewhere, its own DBC beside itself;
    a circle, a missing base and a base that is no path are named."""
    default = load_config()
    mine = tmp_path / "mine.toml"
    mine.write_text('base = "default"\n[vehicle]\nwheelbase_m = 2.9\n[navigation]\ngyros = ["esc"]\n'
                    '[sensors.gnss_cog.gnss]\nhorizontal_std_m = 0.5\n')
    cfg = load_config(mine)
    assert cfg.vehicle == replace(default.vehicle, wheelbase_m=2.9)
    assert cfg.navigation.gyros == ("esc",) and cfg.navigation.gnss == default.navigation.gnss
    assert cfg.sensors["gnss_cog"].gnss == replace(default.sensors["gnss_cog"].gnss, horizontal_std_m=0.5)
    assert cfg.sensors["gnss_cog"].topic == default.sensors["gnss_cog"].topic
    assert cfg.dbc_path == default.dbc_path and cfg.dbc_path.exists() and cfg.radar == default.radar
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "own.dbc").write_text("VERSION \"\"\n")
    on_mine = tmp_path / "sub" / "on_mine.toml"
    on_mine.write_text('base = "../mine.toml"\n[can]\ndbc = "own.dbc"\n[vehicle]\nsteering_ratio = 14.0\n')
    chained = load_config(on_mine)
    assert (chained.vehicle.wheelbase_m, chained.vehicle.steering_ratio) == (2.9, 14.0)
    assert chained.dbc_path == tmp_path / "sub" / "own.dbc"
    assert chained.files == (str(on_mine.resolve()), str(mine.resolve()), str(DEFAULT_CONFIG.resolve()))
    text = chained.text()  # provenance (drive.h5's config_toml): every layer, each named
    assert [ln for ln in text.splitlines() if ln.startswith("# autosar config layer: ")] == [
        f"# autosar config layer: {f}" for f in chained.files]
    assert 'steering_ratio = 14.0' in text and 'wheelbase_m = 2.9' in text and DEFAULT_CONFIG.read_text() in text
    assert default.files == (str(DEFAULT_CONFIG.resolve()),) and default.text() == DEFAULT_CONFIG.read_text()
    circle = tmp_path / "circle.toml"
    circle.write_text('base = "circle.toml"\n')
    with pytest.raises(ConfigError, match=r"circle.toml: base: .*circle.toml is this config or one it is the base of"):
        load_config(circle)
    (tmp_path / "gone.toml").write_text('base = "nowhere.toml"\n')
    with pytest.raises(ConfigError, match=r"gone.toml: base: .*nowhere.toml: config file not found"):
        load_config(tmp_path / "gone.toml")  # the file that names it, and where: the base's own file is not the user's
    (tmp_path / "num.toml").write_text("base = 3\n")
    with pytest.raises(ConfigError, match=r"num.toml: base: expected the path of the config this one changes"):
        load_config(tmp_path / "num.toml")


def test_a_layer_unsets_its_bases_can_roles_with_an_empty_string(tmp_path: Path) -> None:
    """TOML has no null: a role given as "" says the car has no such signal, so a layer for a car without the
    default's wheel speeds drops them (the rest of the base's roles and the layer's own stay)."""
    default = load_config()
    mine = tmp_path / "mine.toml"
    mine.write_text('base = "default"\n[can.roles]\nwheel_speed_fl = ""\n"yaw_rate.esc" = ""\n'
                    '"yaw_rate.orc" = "GNSS_IMU.RATE_Z"\n')
    roles = load_config(mine).can.roles
    assert roles == {**{r: ref for r, ref in default.can.roles.items() if r not in ("wheel_speed_fl", "yaw_rate.esc")},
                     "yaw_rate.orc": "GNSS_IMU.RATE_Z"}
    again = tmp_path / "again.toml"  # a layer above it may give the role back
    again.write_text('base = "mine.toml"\n[can.roles]\nwheel_speed_fl = "ABS_1.WHEEL_SPEED_FL"\n')
    assert load_config(again).can.roles["wheel_speed_fl"] == "ABS_1.WHEEL_SPEED_FL"
    bad = tmp_path / "bad.toml"
    bad.write_text('base = "default"\n[can.roles]\nwheel_speed_fl = "ABS_1"\n')
    with pytest.raises(ConfigError, match=r"can.roles.wheel_speed_fl: expected 'MESSAGE.SIGNAL', got 'ABS_1'"):
        load_config(bad)


def test_bench_configs_change_only_the_simulators_entries(tmp_path: Path) -> None:
    """benches/bench_paper.py's other car (``--car``), other radar (``--simulation``) and other sensors
    (``--sensors``) edit only the entries named, in their own sections, and refuse a name the section lacks."""
    import importlib.util

    source = Path(__file__).parents[1] / "benches" / "bench_paper.py"
    spec = importlib.util.spec_from_file_location("bench_paper", source)
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    base = load_config()
    path = bench.config_copy(None, None, tmp_path, car='roll_gradient_deg_per_g=7.0,road_class="B"',
                             simulation="vibration_horizontal_rms_m=0.25e-3")
    changed = load_config(path)
    assert changed.simulation is not None and base.simulation is not None
    assert changed.simulation.vibration_horizontal_rms_m == 0.25e-3
    assert changed.simulation.vibration_vertical_rms_m == base.simulation.vibration_vertical_rms_m
    assert changed.vehicle_dynamics.roll_gradient_deg_per_g == 7.0
    assert changed.vehicle_dynamics.road_class == "B"
    assert changed.navigation == base.navigation and changed.radar == base.radar
    with pytest.raises(SystemExit, match="not an entry of \\[simulation\\]"):
        bench.config_copy(None, None, tmp_path, simulation="vibration_rms_m=1.0")
    # a list value, nested too, keeps its commas
    path = bench.config_copy(None, None, tmp_path, simulation="cyclists=[[15.0,-6.5,3.0],[45.0,-7.5,-4.0]],"
                                                              "vibration_band_hz=[2.0,15.0]")
    riders = load_config(path).simulation
    assert riders is not None and riders.cyclists == ((15.0, -6.5, 3.0), (45.0, -7.5, -4.0))
    assert riders.vibration_band_hz == (2.0, 15.0)
    path = bench.config_copy(None, None, tmp_path, sensors="gnss_cog.gnss.velocity_std_mps=0.06,"
                                                           "wheel_speeds.wheel.noise_std_mps=0.016")
    sensors, before = load_config(path).sensors, base.sensors
    assert sensors["gnss_cog"].gnss is not None and before["gnss_cog"].gnss is not None
    assert sensors["gnss_cog"].gnss.velocity_std_mps == 0.06
    assert sensors["gnss_cog"].gnss.horizontal_std_m == before["gnss_cog"].gnss.horizontal_std_m
    assert sensors["gnss_radar"] == before["gnss_radar"]  # the same key in another sensor's table is left alone
    assert sensors["wheel_speeds"].wheel is not None and sensors["wheel_speeds"].wheel.noise_std_mps == 0.016
    with pytest.raises(SystemExit, match="not an entry of \\[sensors.gnss_cog.gnss\\]"):
        bench.config_copy(None, None, tmp_path, sensors="gnss_cog.gnss.speed_std_mps=1.0")
    # SAR-MIN's own settings (--navigation): the processor's section, the rest as it was
    changed = load_config(bench.config_copy(None, None, tmp_path, navigation="wheel_lag_window_always=true"))
    assert changed.navigation == replace(base.navigation, wheel_lag_window_always=True)
    assert changed.sensors == base.sensors and changed.vehicle_dynamics == base.vehicle_dynamics
    with pytest.raises(SystemExit, match="'gate' is not an entry of \\[navigation\\]"):
        bench.config_copy(None, None, tmp_path, navigation="gate=0.9")
    # what the processor is told of the radar (--radar), its mounting a table below [radar], beside the simulator's
    # copy, which keeps the config's radar: two files, neither overwriting the other
    told = bench.config_copy(None, None, tmp_path, radar="mounting.yaw_deg=-42.0")
    simulated = bench.config_copy(None, None, tmp_path)
    assert told != simulated
    assert load_config(told).radar.mounting.yaw_deg == -42.0
    assert load_config(simulated).radar == base.radar



def _numeric_lines() -> list[tuple[int, str]]:
    """(line index, dotted key) of every number the default config states, as written there."""
    out, section = [], ""
    for i, line in enumerate(Path(DEFAULT_CONFIG).read_text(encoding="utf-8").splitlines()):
        if line.startswith("["):
            section = line.strip("[] ")
        elif "=" in line and not line.lstrip().startswith("#"):
            key, value = (s.strip() for s in line.split("#")[0].split("=", 1))
            with contextlib.suppress(ValueError):
                float(value)
                out.append((i, f"{section}.{key}"))
    return out


def test_every_number_far_beyond_its_unit_is_rejected_naming_its_key(tmp_path: Path) -> None:
    """1e300 in place of each number of the default config (a typo, or a value in another unit): each is refused
    when the config is loaded, naming the key, where before the stages ran on some without a word (a wheelbase,
    a steering ratio, a gyro's noise) and failed on others with no key named ("float division by zero")."""
    lines = Path(DEFAULT_CONFIG).read_text(encoding="utf-8").splitlines()
    numbers = _numeric_lines()
    assert len(numbers) > 120
    (tmp_path / "autosar_giulia.dbc").write_text((DEFAULT_CONFIG.parent / "autosar_giulia.dbc").read_text())
    accepted = []
    for i, key in numbers:
        variant = list(lines)
        variant[i] = f"{key.rsplit('.', 1)[1]} = 1e300"
        path = tmp_path / "far.toml"
        path.write_text("\n".join(variant), encoding="utf-8")
        try:
            load_config(path)
        except ConfigError as exc:
            assert str(exc).startswith(f"{path}: {key}: "), str(exc)
        else:
            accepted.append(key)
    assert accepted == []


@pytest.mark.parametrize("replacement, key, said", [
    ("latency_s = -10.0", "sensors.wheel_speeds.latency_s",
     "-10.0 is more than 2 in magnitude (a sensor whose stamps lag its values by more is on another clock)"),
    ("wheelbase_m = 282.0", "vehicle.wheelbase_m", "282.0 is more than 20 in magnitude (no road vehicle's)"),
    ("bias_tau_s = 1e9", "sensors.esc.gyro.bias_tau_s",
     "1000000000.0 is more than 1e+07 in magnitude (beyond any car's, road's or sensor's in s)")],
    ids=["a latency", "a wheelbase in cm", "a time"])
def test_a_number_past_its_bound_says_the_bound_and_why(tmp_path: Path, replacement: str, key: str,
                                                        said: str) -> None:
    name = replacement.split(" =")[0]
    path = _write_variant(tmp_path, rf"^{name} = .*$", replacement)
    with pytest.raises(ConfigError) as exc:
        load_config(path)
    assert str(exc.value) == f"{path}: {key}: {said}: a typo, or another unit?"


def _layer(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "mine.toml"
    p.write_text('base = "default"\n' + text)
    return p


@pytest.mark.parametrize(("text", "said"), [
    # a misspelt role was a role nothing played: SAR-MIN ran without that wheel speed, status ok, no word
    ('[can.roles]\nwheel_speed_fll = "ABS_1.WHEEL_SPEED_FL"\n',
     r"can.roles.wheel_speed_fll: not a role \(did you mean wheel_speed_fl\?\)"),
    ('[can.roles]\n"yawrate.esc" = "ABS_2.YAW_RATE"\n',
     r"can.roles.yawrate.esc: 'yawrate' is not a quantity of a CAN sensor \(did you mean yaw_rate\?\)"),
    ('[can.roles]\n"yaw_rate.escc" = "ABS_2.YAW_RATE"\n',
     r"can.roles.yaw_rate.escc: 'escc' is no sensor of \[sensors\] \(did you mean esc\?\); the config's can_imu "
     r"sensors: esc, orc"),
    ('[can.roles]\n"latitude.esc" = "ABS_2.YAW_RATE"\n',
     r"can.roles.latitude.esc: 'esc' is a can_imu sensor, not a can_gnss"),
    # each name its own bias state: one gyro listed twice was fused as two independent ones
    ('[navigation]\ngyros = ["imu_cog_a", "imu_cog_a"]\n', r"navigation.gyros: 'imu_cog_a' listed 2 times"),
    ('[navigation]\ngyros = ["imu_cog_c"]\n', r"navigation.gyros: 'imu_cog_c' is no sensor of \[sensors\] "
                                               r"\(did you mean imu_cog_b\?\)"),
    ('[navigation]\ngyros = ["wheel_speeds"]\n', r"'wheel_speeds' is a wheel_speeds sensor, which has no gyro"),
    # a radar 1 km from the car: the image moved by a kilometre, turned, status ok
    ('[radar.mounting]\nlever_arm_m = [1000.0, -0.75, 0.0]\n',
     r"radar.mounting.lever_arm_m\[0\]: 1000.0 is more than 50 in magnitude"),
    ('[sensors.gnss_cog]\nlever_arm_m = [0.0, 0.0, 60.0]\n',
     r"sensors.gnss_cog.lever_arm_m\[2\]: 60.0 is more than 50"),
    # a radar on one side looking through the car at the other: the ci drive's reflectors imaged 1.50 m off with
    # y's sign turned, 4.3 m with x and y swapped (status ok, no word), mirrored with yaw's sign turned (warned after
    # the run: 19.5 dB under the channels' coherent gain)
    ('[radar.mounting]\nlever_arm_m = [2.20, 0.75, 0.0]\n',
     r"radar.mounting: the radar sits 0.75 m left of the car's centre line \(lever_arm_m\[1\] = 0.75; body y is to "
     r"the left\) yet looks to the right \(yaw_deg -45; > 0 left\), through the car: the sign of lever_arm_m's y or of "
     r"yaw_deg turned, or lever_arm_m's x and y swapped\?$"),
    ('[radar.mounting]\nlever_arm_m = [-0.75, 2.20, 0.0]\n', r"radar.mounting: the radar sits 2.20 m left of"),
    ('[radar.mounting]\nyaw_deg = 45.0\n', r"radar.mounting: the radar sits 0.75 m right of the car's centre line "
                                            r"\(lever_arm_m\[1\] = -0.75; .* yet looks to the left \(yaw_deg 45;"),
    # the steering ratio inverted: the steering read as 139 times the road-wheel angle (SAR-MIN's steering model)
    ('[vehicle]\nsteering_ratio = 0.0847\n',
     r"vehicle.steering_ratio: 0.0847 turns the road wheels 11.8 times as far as the steering wheel, which no car's do "
     r"\(it is the steering wheel's angle over the road wheels', 10-25 on cars\): inverted, 11.8\?$"),
    ('[vehicle]\nsteering_ratio = 0.9\n',
     r"vehicle.steering_ratio: 0.9 turns the road wheels 1.11 times .*: inverted\?$"),
    # a datasheet's chirp units: each was refused naming bandwidth_hz alone ("slope x ADC window = 0.003 Hz differs")
    ('[radar]\nslope_hz_per_s = 75.0\n',
     r"radar.slope_hz_per_s: 75 is likely in MHz/us, 7.5e\+13 Hz/s; radar.bandwidth_hz: slope x ADC window = 0.003 Hz "
     r"differs from bandwidth_hz = 3e\+09 Hz"),
    ('[radar]\nsample_rate_hz = 13.5\nslope_hz_per_s = 75.0\n',
     r"radar.slope_hz_per_s: 75 is likely in MHz/us, 7.5e\+13 Hz/s; radar.sample_rate_hz: 13.5 is likely in Msps, "
     r"1.35e\+07 Hz; radar.bandwidth_hz: slope x ADC window = 3000 Hz"),
    ('[radar]\nsample_rate_hz = 13500.0\n', r"radar.sample_rate_hz: 13500 is likely in ksps, 1.35e\+07 Hz; radar.band"),
    ('[radar]\nbandwidth_hz = 3.0\n', r"radar.bandwidth_hz: 3 is likely in GHz, 3e\+09 Hz; radar.bandwidth_hz: slope"),
    # all three in a datasheet's or TI mmWave Studio's units: each named in its own (sample rate and bandwidth were
    # named in ksps and GHz, or the sample rate or the slope not at all)
    ('[radar]\nslope_hz_per_s = 75.0\nsample_rate_hz = 13.5\nbandwidth_hz = 3000.0\n',
     r"radar.slope_hz_per_s: 75 is likely in MHz/us, 7.5e\+13 Hz/s; radar.sample_rate_hz: 13.5 is likely in Msps, "
     r"1.35e\+07 Hz; radar.bandwidth_hz: 3000 is likely in MHz, 3e\+09 Hz; "),
    ('[radar]\nslope_hz_per_s = 75.0\nsample_rate_hz = 13500.0\nbandwidth_hz = 3.0\n',
     r"radar.slope_hz_per_s: 75 is likely in MHz/us, 7.5e\+13 Hz/s; radar.sample_rate_hz: 13500 is likely in ksps, "
     r"1.35e\+07 Hz; radar.bandwidth_hz: 3 is likely in GHz, 3e\+09 Hz; "),
    ('[radar]\nslope_hz_per_s = 75.0\nsample_rate_hz = 13500.0\nbandwidth_hz = 3000.0\n',
     r"radar.slope_hz_per_s: 75 is likely in MHz/us, 7.5e\+13 Hz/s; radar.sample_rate_hz: 13500 is likely in ksps, "
     r"1.35e\+07 Hz; radar.bandwidth_hz: 3000 is likely in MHz, 3e\+09 Hz; "),
    # a carrier in GHz: refused blaming processing.cross_range_resolution_m (the wavelength 4 million times long)
    ('[radar]\nstart_frequency_hz = 77.0\n',
     r"radar.start_frequency_hz: 77 Hz is no FMCW radar's carrier \(1-300 GHz\): in GHz\? 77 GHz is 7.7e\+10 Hz$"),
    # the focusing plane in mm: focus failed after ingest and navigate, "no ground ... at height 500.0 m", no key
    ('[processing]\nfocus_height_m = 500.0\n',
     r"processing.focus_height_m: 500 m from the road .* \(at most 20 m\): in mm\? 500 mm is 0.5 m$"),
    # a gyro's rate given as its period: test1's ESC gyro trusted 100 times too much, the track 5.1 cm off, no word
    ('[sensors.esc]\nrate_hz = 0.01\n',
     r"sensors.esc.rate_hz: 0.01 Hz is no gyro's \(its yaw rate's noise per sample is noise_density_dps_rthz x "
     r"sqrt\(rate_hz\)\): a period in s \(0.01 s is 100 Hz\), or kHz\?$"),
    ('[sensors.imu_cog_a]\nrate_hz = 0.5\n', r"sensors.imu_cog_a.rate_hz: 0.5 Hz is no gyro's .* \(0.5 s is 2 Hz\)"),
    # the default's -45 deg in radians: a boresight along the track, the ci drive's reflectors 13.6 dB down
    ('[radar.mounting]\nyaw_deg = -0.785\n',
     r"radar.mounting.yaw_deg: -0.785 turns the boresight 0.8 deg off the car's x axis, along its track, which makes "
     r"no SAR image: a side-looking radar's is at least 10 deg off it \(-90: broadside to the right, \+90: to the "
     r"left\); in radians\? -0.785 rad is -45.0 deg$"),
    ('[radar.mounting]\nyaw_deg = 180.0\nlever_arm_m = [-2.0, 0.0, 0.0]\n',
     r"radar.mounting.yaw_deg: 180 turns the boresight 0.0 deg off the car's x axis, .* \+90: to the left\)$"),
    # a misspelt sensor's table: "missing required key (a config ... says base = "default" ...)" where it did
    ('[sensors.gnss_cgo]\ntopic = "/fix"\n',
     r"sensors.gnss_cgo: not one of \[sensors\] \(did you mean gnss_cog\?\); a new one needs kind"),
    # an image of single pulses (332 of 40443 pixels lit), exit 0
    ('[processing]\ncross_range_resolution_m = 1000.0\n',
     r"processing.cross_range_resolution_m: 1000.0 m is coarser than 1 m"),
    # numpy's "Unable to allocate 8.30 TiB" after the ingest and navigation had run
    ('[processing]\nrange_upsample = 1000000\n', r"processing.range_upsample: must lie in \[1, 64\], got 1000000"),
    # a key another kind of sensor reads: nothing read it, what it said was ignored
    ('[sensors.wheel_speeds]\ndof = 3\n', r"sensors.wheel_speeds.dof: a wheel_speeds sensor reads no dof key "
                                          r"\(an imu sensor's\); a wheel_speeds sensor's: latency_s, lever_arm_m, "
                                          r"rate_hz, wheel$"),
    ('[sensors.imu_cog_a.gnss]\nsigma_h_m = 0.5\n', r"sensors.imu_cog_a.gnss: an imu sensor reads no gnss table \(a "
                                                    r"can_gnss or gnss sensor's\)"),
    ('[sensors.gnss_cog]\nmounting_ypr_deg = [0.0, 0.0, 0.0]\n', r"sensors.gnss_cog.mounting_ypr_deg: a gnss sensor "
                                                                  r"reads no mounting_ypr_deg key"),
    # a latency in ms: the GNSS's 1 (ms) moved the ci drive's track 2.31 m, status ok; 2 was the bound
    ('[sensors.gnss_cog]\nlatency_s = 1.0\n',
     r"sensors.gnss_cog.latency_s: 1 s is no sensor's latency \(its stamps that long after the instant its values "
     r"refer to; under 1 s\): in ms\? If you meant 1 ms write 0.001$"),
    ('[sensors.imu_cog_a]\nlatency_s = 2.0\n', r"sensors.imu_cog_a.latency_s: 2 s .* If you meant 2 ms write 0.002$"),
])
def test_a_config_that_would_run_wrong_without_a_word_is_refused(tmp_path: Path, text: str, said: str) -> None:
    with pytest.raises(ConfigError, match=said):
        load_config(_layer(tmp_path, text))


def test_a_slow_nmea_receivers_latency_is_taken(tmp_path: Path) -> None:
    """An NMEA receiver at 4800 baud sends a fix's last sentences up to ~1 s after it: 0.8 s is a latency, not ms."""
    assert load_config(_layer(tmp_path, "[sensors.gnss_cog]\nlatency_s = 0.8\n")).sensors["gnss_cog"].latency_s == 0.8


@pytest.mark.parametrize("mounting", [
    'lever_arm_m = [1.0, 0.5, 0.9]\nyaw_deg = -60.0',  # a roof rack's, left of the centre line, looking right across
    'lever_arm_m = [0.0, 0.0, 0.0]\nyaw_deg = 90.0',  # on the centre line, looking left
    'lever_arm_m = [-2.0, -0.75, 0.0]\nyaw_deg = -135.0',  # the right rear corner, squinted back
])
def test_a_radar_mounted_as_real_cars_carry_them_is_taken(tmp_path: Path, mounting: str) -> None:
    """The lateral check refuses a radar on one side of the body looking through the car; one on the roof may look
    across it, and the centre line or a squint back is no mistake."""
    cfg = load_config(_layer(tmp_path, f"[radar.mounting]\n{mounting}\n"))
    assert cfg.radar.mounting.lever_arm_m[2] in (0.0, 0.9)


def test_the_roles_and_gyros_of_every_bundled_config_are_known() -> None:
    """The check above refuses none of the configs we ship (their roles and gyros are all read by the stages)."""
    for path in sorted((DEFAULT_CONFIG.parent).glob("**/*.toml")):
        cfg = load_config(path)
        assert cfg.navigation.gyros, path
