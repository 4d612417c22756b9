"""Navigation on a real robot's recording (../shared/realdata/robot_localization/test1.bag: a Clearpath Husky's
GNSS fixes at 2.5 Hz, its IMU at 30 Hz, mounted with its y axis up, and its wheel odometry, which autosar does not
ingest and which is here the independent reference), and the mounting and start that such a drive needs.

The Husky is no car, and its drive.h5 has no wheel speeds, steering, GNSS velocity or radar: what is checked is what
a drive logged on other sensors than the simulator's must get right, against a sensor the processor never reads.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from conftest import realdata
from typer.testing import CliRunner

from autosar_cli.cli import app
from autosar_cli.config import DEFAULT_CONFIG, Config, ConfigError, config_from_dict, load_config
from autosar_cli.config_sketch import config_sketch
from autosar_cli.ingest.pipeline import ingest
from autosar_cli.nav.baselines import fix_velocity
from autosar_cli.nav.frames import levelling_pitch_roll_deg, mounting_rotation, sensor_to_body
from autosar_cli.nav.inputs import Measurements, NavInputError, can_gnss_streams, read_imu
from autosar_cli.nav.navigate import navigate
from autosar_cli.nav.sarmin import FIRST_MOVE_SIGMAS, _first_move
from autosar_cli.store.drive import Drive

HUSKY = ("robot_localization", "test1.bag")
ODOM = "/husky_velocity_controller/odom"


#: the shipped worked example: only what differs from the default config (``base = "default"``)
HUSKY_CONFIG = DEFAULT_CONFIG.parent / "examples" / "husky_test1.toml"


def _husky_config(mounting_ypr_deg: tuple[float, float, float]) -> Config:
    """The worked example's config (the Husky's topics; its IMU 6-DoF at 30 Hz; its GNSS at 2.5 Hz with the 0.8 m
    its fixes state; both at the robot's centre), its IMU turned by ``mounting_ypr_deg`` instead of its own."""
    config = load_config(HUSKY_CONFIG)
    imu = dataclasses.replace(config.sensors["imu_cog_a"], mounting_ypr_deg=mounting_ypr_deg)
    return dataclasses.replace(config, sensors={**config.sensors, "imu_cog_a": imu})


def test_the_worked_example_changes_only_what_it_says() -> None:
    """configs/examples/husky_test1.toml names only what differs from the default: the rest is the default's (the
    IMU's error tables, the DBC beside the default config), what it names replaces it."""
    example, default = load_config(HUSKY_CONFIG), load_config()
    imu, imu0 = example.sensors["imu_cog_a"], default.sensors["imu_cog_a"]
    assert (imu.topic, imu.dof, imu.rate_hz, imu.mounting_ypr_deg) == ("/imu/data", 6, 30.0, (0.0, 0.0, 90.0))
    assert imu.gyro == imu0.gyro and imu.accel == imu0.accel
    assert example.sensors["gnss_cog"].gnss.horizontal_std_m == 0.8
    assert example.sensors["gnss_cog"].gnss.velocity_std_mps == default.sensors["gnss_cog"].gnss.velocity_std_mps
    assert example.navigation.gyros == ("imu_cog_a",) and example.vehicle.cog_to_rear_axle_m == 0.0
    assert example.dbc_path == default.dbc_path and example.dbc_path.exists()
    assert example.files == (str(HUSKY_CONFIG.resolve()), str(DEFAULT_CONFIG.resolve()))
    assert example.can.roles == {}
    assert dataclasses.replace(example, sensors=default.sensors, navigation=default.navigation, vehicle=default.vehicle,
                               source="", bases=(), can=default.can) == dataclasses.replace(default, source="")


@pytest.fixture(scope="module")
def husky_drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("husky_nav") / "drive.h5"
    ingest([realdata(*HUSKY)], out, config=_husky_config((0.0, 0.0, 90.0)), allow_partial=True)
    return out


@pytest.fixture(scope="module")
def odometry() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Husky's wheel odometry (header stamp ns, forward speed m/s, yaw rate rad/s), read by rosbags."""
    from rosbags.highlevel import AnyReader

    t, v, w = [], [], []
    with AnyReader([realdata(*HUSKY)]) as reader:
        for con, _, raw in reader.messages(connections=[c for c in reader.connections if c.topic == ODOM]):
            msg = reader.deserialize(raw, con.msgtype)
            t.append(msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec)
            v.append(msg.twist.twist.linear.x)
            w.append(msg.twist.twist.angular.z)
    return np.array(t), np.array(v), np.array(w)


def test_the_drive_keeps_every_layer_of_its_config(husky_drive: Path) -> None:
    """drive.h5's provenance holds the worked example's text and its base's, each named: the drive can be made
    again from it."""
    import h5py

    with h5py.File(husky_drive) as f:
        text = f.attrs["config_toml"]
    assert f"# autosar config layer: {HUSKY_CONFIG.resolve()}\n{HUSKY_CONFIG.read_text()}" in text
    assert f"# autosar config layer: {DEFAULT_CONFIG.resolve()}\n{DEFAULT_CONFIG.read_text()}" in text


def test_an_imu_mounted_turned_is_refused_with_where_its_gravity_reads(husky_drive: Path) -> None:
    """The Husky's IMU reads gravity on its y axis: as the config mounts it (axes on the body's) its z gyro is not
    the yaw rate, which navigate says rather than fusing a yaw rate of about nothing."""
    with Drive(husky_drive) as drive:
        with pytest.raises(NavInputError) as info:
            read_imu(drive, "imu_cog_a", _husky_config((0.0, 0.0, 0.0)))
    msg = str(info.value)
    assert "imu/imu_cog_a" in msg and "gravity 89 deg from the body's up" in msg and "mounting_ypr_deg" in msg
    assert "[-0.22, 9.79, 0.09]" in msg  # the median specific force as recorded
    assert "levels it at about [yaw, 1.3, 89.5]" in msg  # the worked example's [0, 0, 90]
    with pytest.raises(NavInputError, match="gravity 89 deg"):
        navigate(husky_drive, "sar-min", _husky_config((0.0, 0.0, 0.0)))


def test_the_mounting_turns_the_real_imus_yaw_rate_onto_the_body(husky_drive: Path, odometry) -> None:
    """Rolled 90 deg (its y onto the body's z), the IMU's yaw rate follows the wheel odometry's, which autosar does
    not read: correlation 0.85, against about none for its own z axis."""
    t_odo, _, w_odo = odometry
    with Drive(husky_drive) as drive:
        imu = read_imu(drive, "imu_cog_a", _husky_config((0.0, 0.0, 90.0)))
        recorded = drive.series("imu/imu_cog_a")
    raw = recorded["angular_velocity"]
    inside = (t_odo > imu["t_ns"][0]) & (t_odo < imu["t_ns"][-1])
    turned = np.interp(t_odo[inside], imu["t_ns"], imu["angular_velocity"][:, 2])
    as_recorded = np.interp(t_odo[inside], imu["t_ns"], raw[:, 2])
    assert np.corrcoef(turned, w_odo[inside])[0, 1] > 0.8  # 0.85: the IMU at 30 Hz, the odometry smoothed at 10
    assert abs(np.corrcoef(as_recorded, w_odo[inside])[0, 1]) < 0.3
    np.testing.assert_allclose(imu["linear_acceleration"][:, 2], recorded["linear_acceleration"][:, 1], atol=1e-9)


def test_sarmin_starts_from_the_fixes_alone_on_a_real_robot(husky_drive: Path, odometry) -> None:
    """No GNSS velocity, no wheel speeds: SAR-MIN takes its start course and speed from the fixes' first move. Its
    speed then follows the wheel odometry's (median 0.12 m/s off at 0.9 m/s; from a course of 0 +- pi it drove
    the robot backwards, 1.88 m/s off), its yaw rate too (0.44 deg/s), and the fixes all pass its gate."""
    t_odo, v_odo, w_odo = odometry
    traj = navigate(husky_drive, "sar-min", _husky_config((0.0, 0.0, 90.0)))
    inside = (t_odo > traj.t_ns[0]) & (t_odo < traj.t_ns[-1])
    speed = np.interp(t_odo[inside], traj.t_ns, traj.speed)
    assert np.median(np.abs(speed - v_odo[inside])) < 0.25
    yaw_rate = np.interp(t_odo[inside], traj.t_ns, traj.yaw_rate)
    assert np.degrees(np.median(np.abs(yaw_rate - w_odo[inside]))) < 0.8  # 0.44 deg/s
    assert np.median(speed) > 0.5
    assert traj.info["updates"]["gnss_pos"] > 950 and "gnss_pos" not in traj.info["rejected"]


def test_the_first_move_of_fixes_alone_is_their_course_and_speed() -> None:
    """Closed form: fixes standing 10 s, then moving at 2 m/s on a course of 30 deg: the first move clear of
    FIRST_MOVE_SIGMAS x their noise starts at the last standing fix and ends at the first that far, its course
    and speed the move's, its time the move's middle; fixes that never move so far give none."""
    t = np.arange(0.0, 30.0, 0.5)
    course = math.radians(30.0)
    s = 2.0 * np.clip(t - 10.0, 0.0, None)
    z = np.stack([s * math.cos(course), s * math.sin(course)], axis=1)
    pos = Measurements("gnss", t, z, np.array([0.1, 0.1]))
    need = FIRST_MOVE_SIGMAS * math.hypot(0.1, 0.5)
    t_start, psi, psi_std, (speed, _) = _first_move(pos, 0.5)
    k = int(np.argmax(s > need))
    j = int(np.flatnonzero(s[k] - s[:k] > need)[-1])
    assert t_start == pytest.approx(0.5 * (t[j] + t[k]))
    assert psi == pytest.approx(course, abs=1e-12)
    assert speed == pytest.approx((s[k] - s[j]) / (t[k] - t[j]))
    assert psi_std == pytest.approx(math.sqrt(2.0) * 0.1 / (s[k] - s[j]) + 0.05)
    assert _first_move(Measurements("gnss", t, np.zeros_like(z) + 0.3, np.array([0.1, 0.1])), 0.5) is None


def test_sensor_to_body_is_the_mounting_rotation_and_keeps_a_3dof_yaw_rate() -> None:
    v = np.array([[0.1, -0.2, 9.8], [1.0, 2.0, 3.0]])
    ypr = (20.0, -5.0, 90.0)
    np.testing.assert_allclose(sensor_to_body(v, ypr), v @ mounting_rotation(*ypr).T, atol=1e-12)
    yaw_only = sensor_to_body(np.array([[np.nan, np.nan, 0.3]]), (45.0, 0.0, 0.0))
    assert np.isnan(yaw_only[0, :2]).all() and yaw_only[0, 2] == 0.3  # the yaw rate survives the missing axes
    np.testing.assert_array_equal(sensor_to_body(v, (0.0, 0.0, 0.0)), v)


def _with_mounting(sensor: str, mounting: list[float]) -> Config:
    """The default config with ``sensor``'s mounting_ypr_deg set, built and validated from its TOML."""
    raw = tomllib.loads(DEFAULT_CONFIG.read_text())
    raw["sensors"][sensor]["mounting_ypr_deg"] = mounting
    return config_from_dict(raw)


def test_the_levelling_pitch_and_roll_turn_gravity_onto_up() -> None:
    """Closed form: for gravity read along any direction, the suggested pitch and roll turn it onto +z."""
    rng = np.random.default_rng(3)
    for g in [*rng.normal(size=(20, 3)), np.array([0.0, 0.0, -9.8]), np.array([9.8, 0.0, 0.0])]:
        turned = sensor_to_body(g[None], (0.0, *levelling_pitch_roll_deg(g)))[0]
        np.testing.assert_allclose(turned, [0.0, 0.0, np.linalg.norm(g)], atol=1e-12)


def test_a_3dof_imu_may_only_be_turned_in_yaw() -> None:
    assert _with_mounting("imu_cog_a", [10.0, 0.0, 0.0]).sensors["imu_cog_a"].mounting_ypr_deg == (10.0, 0.0, 0.0)
    assert _with_mounting("ins_cog", [0.0, 3.0, 90.0]).sensors["ins_cog"].mounting_ypr_deg == (0.0, 3.0, 90.0)
    with pytest.raises(ConfigError, match="imu_cog_a.mounting_ypr_deg: a 3-DoF IMU"):
        _with_mounting("imu_cog_a", [0.0, 2.0, 0.0])
    with pytest.raises(ConfigError, match=r"gnss_cog.mounting_ypr_deg: a gnss sensor reads no mounting_ypr_deg key "
                                          r"\(an imu sensor's\)"):
        _with_mounting("gnss_cog", [1.0, 0.0, 0.0])
    with pytest.raises(ConfigError, match="ins_cog.mounting_ypr_deg"):
        _with_mounting("ins_cog", [0.0, math.nan, 0.0])


def test_the_gnss_baseline_takes_the_fixes_own_velocity_where_none_is_logged(husky_drive: Path, odometry) -> None:
    """The Husky's receiver logs fixes alone: the gnss baseline's speed is their central differences over 2 s,
    which follow the wheel odometry's; the straight line runs from the first fix to the last; the INS, which
    needs the receiver's velocity, says so."""
    t_odo, v_odo, _ = odometry
    config = _husky_config((0.0, 0.0, 90.0))
    gnss = navigate(husky_drive, "gnss", config)
    inside = (t_odo > gnss.t_ns[0]) & (t_odo < gnss.t_ns[-1])
    assert len(gnss.t_ns) == 989
    assert np.median(np.abs(np.interp(t_odo[inside], gnss.t_ns, gnss.speed) - v_odo[inside])) < 0.2
    line = navigate(husky_drive, "none", config)
    np.testing.assert_allclose(line.rear_axle_enu[[0, -1]], gnss.rear_axle_enu[[0, -1]], atol=1e-9)
    ins = dataclasses.replace(config, navigation=dataclasses.replace(config.navigation, ins_imu="imu_cog_a",
                                                                     ins_gnss="gnss_cog"))
    with pytest.raises(NavInputError, match="the INS baseline needs the GNSS velocity gnss/gnss_cog/velocity"):
        navigate(husky_drive, "ins", ins)


def test_the_fixes_own_velocity_is_their_central_difference() -> None:
    """Closed form: fixes at 4 Hz on a circle of 20 m at 0.25 rad/s: the velocity over 2 s (4 fixes either side) is
    the chord's, |v| = 5 sin(0.25) / 0.25 m/s along the tangent; one-sided at the ends; its std sqrt(2) sigma / 2."""
    t = np.arange(0.0, 20.0, 0.25)
    z = 20.0 * np.stack([np.cos(0.25 * t), np.sin(0.25 * t)], axis=1)
    vel = fix_velocity(Measurements("gnss", t, z, np.array([0.3, 0.3])))
    mid = slice(4, -4)
    np.testing.assert_allclose(np.hypot(*vel.z[mid].T), 5.0 * math.sin(0.25) / 0.25, rtol=1e-12)
    tangent = np.stack([-np.sin(0.25 * t), np.cos(0.25 * t)], axis=1)
    np.testing.assert_allclose(np.einsum("ij,ij->i", vel.z[mid], tangent[mid]), np.hypot(*vel.z[mid].T), rtol=1e-12)
    np.testing.assert_allclose(vel.z[0], (z[4] - z[0]) / 1.0, rtol=1e-12)
    np.testing.assert_allclose(vel.sigma, math.sqrt(2.0) * 0.3 / 2.0)


def test_the_config_sketch_of_a_drive_ingested_as_configured_is_the_config(tmp_path: Path, ci_mcap) -> None:
    """The simulated ci drive, ingested with the default config: its sketch pins every stream to the sensor it was
    ingested as, the same topics, degrees of freedom and rates (measured), no IMU turned, the default's gyros."""
    drive = tmp_path / "ci.h5"
    ingest([ci_mcap.log_path], drive, config=load_config())
    sketch = tmp_path / "sketch.toml"
    sketch.write_text(config_sketch(drive, load_config()))
    cfg, default = load_config(sketch), load_config()
    for name in ("gnss_cog", "gnss_radar", "imu_cog_a", "imu_cog_b", "ins_cog", "ins_radar"):
        s, s0 = cfg.sensors[name], default.sensors[name]
        assert (s.topic, s.velocity_topic, s.dof, s.mounting_ypr_deg) == (s0.topic, s0.velocity_topic, s0.dof,
                                                                        (0.0, 0.0, 0.0)), name
        assert s.rate_hz == pytest.approx(s0.rate_hz, rel=0.02), name
    assert cfg.navigation == default.navigation and cfg.radar == default.radar


def test_the_config_sketch_of_a_real_robot_navigates_it(husky_drive: Path, tmp_path: Path, odometry) -> None:
    """The Husky's bag ingested with the default config (its streams named by their topics: gnss/gnss,
    imu/imu_data), sketched: /fix as the default's GNSS, fixes alone; /imu/data a 6-DoF IMU at 30 Hz levelled by
    [0, 1.3, 89.5]; its gyro fused. With what a log cannot show given (the robot's reference point, the antenna's
    lever arm, the fixes' stated 0.8 m), it navigates the robot as the worked example does."""
    as_default = tmp_path / "default.h5"
    ingest([realdata(*HUSKY)], as_default, config=load_config(), allow_partial=True)
    sketch = tmp_path / "sketch.toml"
    sketch.write_text(config_sketch(as_default, load_config()))
    cfg = load_config(sketch)
    assert cfg.can.roles == {}  # the default's, which a robot without CAN has not, unset
    gnss, imu = cfg.sensors["gnss_cog"], cfg.sensors["ins_cog"]
    assert (gnss.topic, gnss.velocity_topic, gnss.rate_hz) == ("/fix", "", 2.5)
    assert (imu.topic, imu.dof, imu.rate_hz, imu.mounting_ypr_deg) == ("/imu/data", 6, 30.0, (0.0, 1.3, 89.5))
    assert cfg.navigation.gyros == ("ins_cog",) and cfg.navigation.attitude_imu == "ins_cog"
    assert (cfg.navigation.ins_imu, cfg.navigation.ins_gnss) == ("ins_cog", "gnss_cog")  # the base's are absent
    table = dataclasses.replace(gnss.gnss, horizontal_std_m=0.8, white_std_m=0.3)
    cfg = dataclasses.replace(cfg, vehicle=dataclasses.replace(cfg.vehicle, cog_to_rear_axle_m=0.0), sensors={
        **cfg.sensors, "gnss_cog": dataclasses.replace(gnss, lever_arm_m=(0.0, 0.0, 0.5), latency_s=0.0, gnss=table),
        "ins_cog": dataclasses.replace(imu, lever_arm_m=(0.0, 0.0, 0.0))})
    drive = tmp_path / "sketched.h5"
    ingest([realdata(*HUSKY)], drive, config=cfg, allow_partial=True)
    traj = navigate(drive, "sar-min", cfg)
    with pytest.raises(NavInputError, match="the INS baseline needs the GNSS velocity gnss/gnss_cog/velocity"):
        navigate(drive, "ins", cfg)  # the sketched IMU and receiver: what it lacks is the receiver's velocity
    t_odo, v_odo, _ = odometry
    inside = (t_odo > traj.t_ns[0]) & (t_odo < traj.t_ns[-1])
    assert np.median(np.abs(np.interp(t_odo[inside], traj.t_ns, traj.speed) - v_odo[inside])) < 0.25  # 0.12
    r = CliRunner().invoke(app, ["info", str(realdata(*HUSKY)), "--config-sketch"])
    assert r.exit_code != 0 and "--config-sketch reads a drive.h5 or a TI DCA1000 capture; ingest the log first" \
        in r.output
    r = CliRunner().invoke(app, ["info", str(as_default), "--config-sketch"])
    assert r.exit_code == 0 and tomllib.loads(r.stdout) == tomllib.loads(sketch.read_text())



def test_a_log_without_can_is_told_its_roles_go_unused_in_one_line(tmp_path: Path) -> None:
    """The Husky's bag holds no CAN: ingested with the default config, its twelve CAN roles are one line, not a list of
    what a log without CAN cannot hold; with a config that unsets them, not a word."""
    r = CliRunner().invoke(app, ["ingest", str(realdata(*HUSKY)), "-o", str(tmp_path / "d.h5"), "--allow-partial"])
    assert r.exit_code == 0 and "no CAN frames in this log: the config's 12 CAN roles go unused" in r.output
    assert "CAN roles not found" not in r.output
    r = CliRunner().invoke(app, ["ingest", str(realdata(*HUSKY)), "-o", str(tmp_path / "e.h5"), "--allow-partial",
                                 "--config", str(HUSKY_CONFIG)])
    assert r.exit_code == 0 and "CAN roles" not in r.output


# ------------------------------------------------------------------ a real car's GNSS receiver and IMU on CAN
CSS_CONFIG = DEFAULT_CONFIG.parent / "examples" / "css_canedge_gnss.toml"
CSS_FILES = ("2F6913DB_00001089_00000001-63BEF5CD.MF4", "2F6913DB_00001089_00000002-63BEFDF9.MF4")


def _css_drive(out: Path, config: Config) -> Path:
    ingest([], out, config=config, dbc=realdata("css-electronics", "gnss.dbc"),
           can_logs=[realdata("css-electronics", f) for f in CSS_FILES], allow_partial=True)
    return out


@pytest.fixture(scope="module")
def css_drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _css_drive(tmp_path_factory.mktemp("css_nav") / "drive.h5", load_config(CSS_CONFIG))


def test_a_car_navigated_from_its_can_loggers_gnss_and_imu(css_drive: Path) -> None:
    """A CANedge's GNSS module on CAN (kind can_gnss; 1 Hz fixes, a 10 Hz yaw rate in steps of 0.25 deg/s): SAR-MIN's
    heading while moving is within 1.2 deg (median, 3.1 deg p90) of the module's own fused heading, its speed 0.18 m/s
    from the module's, neither of which it reads; 12 of 251 fixes gated."""
    import h5py

    traj = navigate(css_drive, "sar-min", load_config(CSS_CONFIG))
    assert traj.info["rejected"].get("gnss_pos", 0) < 0.1 * traj.info["updates"]["gnss_pos"]
    assert "warnings" not in traj.info
    with h5py.File(css_drive) as f:
        att, spd = f["can/gnss_attitude_0x15"], f["can/gnss_speed_0x17"]
        t_att, heading, valid = att["t_ns"][()], att["Heading"][()], att["AttitudeValid"][()]
        t_spd, speed = spd["t_ns"][()], spd["Speed"][()]
    inside = (t_att > traj.t_ns[0]) & (t_att < traj.t_ns[-1]) & (valid > 0)
    moving = np.abs(np.interp(t_att[inside], traj.t_ns, traj.speed)) > 1.0
    psi = np.interp(t_att[inside], traj.t_ns, np.unwrap(traj.heading))
    off = np.degrees(np.abs(np.angle(np.exp(1j * (psi - (np.pi / 2 - heading[inside]))))))[moving]
    assert moving.sum() > 50 and np.median(off) < 2.0 and np.percentile(off, 90) < 5.0
    inside = (t_spd > traj.t_ns[0]) & (t_spd < traj.t_ns[-1]) & (speed > 1.0)
    assert np.median(np.abs(np.abs(np.interp(t_spd[inside], traj.t_ns, traj.speed)) - speed[inside])) < 0.4


def test_a_can_receivers_speed_and_course_are_its_velocity(tmp_path: Path) -> None:
    """With speed.<name> and course.<name> given (the module's Speed and Heading), the receiver's velocity is
    speed x (sin, cos) of the course at each speed sample (course interpolated, its up NaN); its fixes the rows
    where PositionValid reads 1, their altitude (another message) at their times; a receiver on CAN without its
    latitude role is named."""
    import h5py

    base = load_config(CSS_CONFIG)
    roles = {**base.can.roles, "speed.css_gnss": "gnss_speed.Speed", "course.css_gnss": "gnss_attitude.Heading"}
    drive = _css_drive(tmp_path / "drive.h5", dataclasses.replace(base, can=dataclasses.replace(base.can,
                                                                                                  roles=roles)))
    with Drive(drive) as d:
        fix, vel = can_gnss_streams(d, "css_gnss")
    with h5py.File(drive) as f:
        pos, spd, att = f["can/gnss_pos_0x13"], f["can/gnss_speed_0x17"], f["can/gnss_attitude_0x15"]
        ok = pos["PositionValid"][()] > 0.5
        np.testing.assert_array_equal(fix["latitude_deg"], pos["Latitude"][()][ok])
        alt = f["can/gnss_altitude_0x14"]  # another message, stamped 0.35 ms apart: at the fixes' times
        np.testing.assert_allclose(fix["altitude_m"], np.interp(pos["t_ns"][()], alt["t_ns"][()],
                                                                alt["Altitude"][()])[ok], atol=1e-9)
        course = np.interp(spd["t_ns"][()], att["t_ns"][()], np.unwrap(att["Heading"][()]))
        expect = spd["Speed"][()][:, None] * np.stack([np.sin(course), np.cos(course)], axis=1)
    assert vel is not None and np.isnan(vel["velocity_enu"][:, 2]).all()
    np.testing.assert_allclose(vel["velocity_enu"][:, :2], expect, atol=1e-12)
    gone = dataclasses.replace(base, can=dataclasses.replace(base.can, roles={
        k: v for k, v in base.can.roles.items() if not k.startswith("latitude.")}))
    with Drive(_css_drive(tmp_path / "no_lat.h5", gone)) as d, pytest.raises(NavInputError) as info:
        can_gnss_streams(d, "css_gnss")
    assert "css_gnss is on CAN (config kind can_gnss) but the drive has no CAN signal for latitude.css_gnss" in str(
        info.value)


def test_the_config_sketch_of_a_real_nmea_capture_is_a_config(tmp_path: Path) -> None:
    """Real NMEA captures given alone (pynmeagps's u-blox capture of one epoch; a Unicore UM981 standing still for
    10 s): the sketch of the first wrote its receiver's rate_hz as the 0.0 one fix measures, a config that the next
    command refused ('rate_hz: must be a positive finite number, got 0.0'); it takes the base's now, said so. Their
    gnss tracks are refused naming the drive (the reasons had named none: 'the vehicle never moves faster than 0.3
    m/s')."""
    for name, why in (("pygpsdata-nmea2", "need a GNSS velocity stream or at least two fixes"),
                      ("pygpsdata-um981", "the vehicle never moves faster than 0.3 m/s: no GNSS course")):
        drive = tmp_path / f"{name}.h5"
        ingest([], drive, config=load_config(), nmea_logs=[realdata("pynmeagps", f"{name}.log")], allow_partial=True)
        sketch = tmp_path / f"{name}.toml"
        sketch.write_text(config_sketch(drive, load_config()))
        cfg = load_config(sketch)
        receiver = cfg.sensors[name.replace("-", "_")]
        assert receiver.kind == "gnss" and receiver.rate_hz > 0, receiver
        gyroless = dataclasses.replace(cfg, navigation=dataclasses.replace(cfg.navigation, gyros=[]))
        with pytest.raises(NavInputError, match=f"^{drive}: .*{why}"):
            navigate(drive, "gnss", gyroless)
    said = "rate_hz = 10.0  # 1 sample(s): too few to measure, the base's"
    assert said in (tmp_path / "pygpsdata-nmea2.toml").read_text()
