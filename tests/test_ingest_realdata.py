"""``autosar ingest`` and ``autosar info`` on real third-party recordings (../shared/realdata).

Every expected number is worked out here by an independent reader (rosbags' AnyReader, raw ``struct``
unpacking, python-can + cantools, mcap_ros2, gpsd's decoded ``.chk``), never taken from the ingest output.
"""

from __future__ import annotations

import dataclasses
import json
import math
import struct
from collections import Counter
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import can
import cantools
import numpy as np
import pytest
import yaml
from conftest import realdata
from reference import crc8_j1850
from typer.testing import CliRunner

from autosar_cli.cli import app
from autosar_cli.config import Config, load_config
from autosar_cli.ingest.pipeline import IngestError, IngestReport, ingest
from autosar_cli.store.drive import Drive

runner = CliRunner()
DEG = math.pi / 180.0
HUSKY = ("robot_localization", "test1.bag")
ODOM = "/husky_velocity_controller/odom"
CSS_FILES = ("2F6913DB_00000004_00000001.MF4", "2F6913DB_00001089_00000001-63BEF5CD.MF4",
             "2F6913DB_00001089_00000002-63BEFDF9.MF4")
ROS2_BAGS = ("rosbag2_py_mcap_talker", "rosbag2_tests_mcap_cdr_test")


@pytest.fixture(scope="module")
def config() -> Config:
    return load_config()


def _stream(report: IngestReport | dict[str, Any], path: str) -> dict[str, Any]:
    streams = report.streams if isinstance(report, IngestReport) else report["streams"]
    return next(s for s in streams if s["path"] == path)


def _accounted(st: dict[str, Any]) -> int:
    """Messages of a stream the report accounts for: written + dropped + skipped."""
    return st["written"] + st["duplicates"] + st["late_dropped"] + sum(st["skipped"].values())


def _no_output(out: Path) -> bool:
    return not out.exists() and not out.with_name(out.name + ".partial").exists()


# ------------------------------------------------------------------------------ ROS1: robot_localization
@pytest.fixture(scope="module")
def husky(tmp_path_factory: pytest.TempPathFactory, config: Config) -> tuple[IngestReport, Path]:
    out = tmp_path_factory.mktemp("husky") / "drive.h5"
    return ingest([realdata(*HUSKY)], out, config=config, allow_partial=True), out


@pytest.fixture(scope="module")
def husky_msgs() -> dict[str, list[Any]]:
    """/fix and /imu/data of test1.bag as rosbags' AnyReader decodes them, in bag order."""
    from rosbags.highlevel import AnyReader

    out: dict[str, list[Any]] = {"/fix": [], "/imu/data": []}
    with AnyReader([realdata(*HUSKY)]) as reader:
        conns = [c for c in reader.connections if c.topic in out]
        for conn, _, raw in reader.messages(connections=conns):
            out[conn.topic].append(reader.deserialize(raw, conn.msgtype))
    return out


def _stamp(m: Any) -> int:
    return int(m.header.stamp.sec) * 1_000_000_000 + int(m.header.stamp.nanosec)


def _first_raw(topic: str) -> tuple[int, bytes]:
    """(header stamp ns, payload after the ROS1 Header) of the first message on ``topic``, by hand."""
    from rosbags.rosbag1 import Reader

    with Reader(realdata(*HUSKY)) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        data = next(reader.messages(connections=conns))[2]
    _, sec, nsec, n = struct.unpack_from("<IIII", data, 0)  # seq, stamp, len(frame_id)
    return sec * 1_000_000_000 + nsec, data[16 + n:]


def test_ros1_fix_rows_equal_independent_decode(husky: tuple[IngestReport, Path],
                                                husky_msgs: dict[str, list[Any]]) -> None:
    report, out = husky
    fixes = husky_msgs["/fix"]
    assert len(fixes) == 989
    valid = [m for m in fixes if m.status.status >= 0 and math.isfinite(m.latitude) and math.isfinite(m.longitude)]
    valid.sort(key=_stamp)
    st = _stream(report, "gnss/gnss/fix")
    assert st["received"] == 989 and _accounted(st) == 989
    assert st["skipped"].get("no fix", 0) == 989 - len(valid)
    assert st["written"] == len(valid) == 989  # every fix of this bag has status >= 0
    with Drive(out) as drive:
        assert drive.gnss_sources() == ["gnss"]
        s = drive.series("gnss/gnss/fix")
        attrs = dict(drive.h5["gnss/gnss/fix"].attrs)
    assert len(s["t_ns"]) == len(valid)
    np.testing.assert_array_equal(s["t_ns"], [_stamp(m) for m in valid])
    np.testing.assert_array_equal(s["latitude_deg"], [m.latitude for m in valid])
    np.testing.assert_array_equal(s["longitude_deg"], [m.longitude for m in valid])
    np.testing.assert_array_equal(s["altitude_m"], [m.altitude for m in valid])
    np.testing.assert_array_equal(s["status"], [m.status.status for m in valid])
    np.testing.assert_array_equal(s["position_covariance"], [m.position_covariance for m in valid])
    assert (attrs["topic"], attrs["msgtype"], attrs["time_source"]) == ("/fix", "sensor_msgs/msg/NavSatFix", "header")

    # the first fix, unpacked by hand: NavSatStatus (int8, uint16), then latitude, longitude, altitude
    stamp, body = _first_raw("/fix")
    status, _ = struct.unpack_from("<bH", body, 0)
    lat, lon, _ = struct.unpack_from("<3d", body, 3)
    assert (status, lat, lon) == (1, pytest.approx(42.375812, abs=1e-9), pytest.approx(-71.147394667, abs=1e-9))
    assert (s["t_ns"][0], s["latitude_deg"][0], s["longitude_deg"][0]) == (stamp, lat, lon)


def test_ros1_imu_rows_equal_independent_decode(husky: tuple[IngestReport, Path],
                                                husky_msgs: dict[str, list[Any]]) -> None:
    report, out = husky
    imus = husky_msgs["/imu/data"]
    stamps = [_stamp(m) for m in imus]
    assert len(imus) == 11865
    assert all(a < b for a, b in zip(stamps, stamps[1:], strict=False))  # in order: nothing to drop or reorder
    st = _stream(report, "imu/imu_data")
    assert st["received"] == 11865 and _accounted(st) == 11865
    assert (st["written"], st["duplicates"], st["late_dropped"], st["reordered"]) == (11865, 0, 0, 0)
    with Drive(out) as drive:
        assert drive.imu_sources() == ["imu_data"]
        s = drive.series("imu/imu_data")
    np.testing.assert_array_equal(s["t_ns"], stamps)
    w = [(m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z) for m in imus]
    a = [(m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z) for m in imus]
    q = [(m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w) for m in imus]
    np.testing.assert_array_equal(s["angular_velocity"], w)
    np.testing.assert_array_equal(s["linear_acceleration"], a)
    np.testing.assert_array_equal(s["orientation"], q)
    np.testing.assert_array_equal(s["angular_velocity_covariance"], [m.angular_velocity_covariance for m in imus])

    # the first message by hand: orientation (4 f8), its covariance (9 f8), then the angular velocity
    stamp, body = _first_raw("/imu/data")
    wx, wy, wz = struct.unpack_from("<3d", body, 4 * 8 + 9 * 8)
    assert stamp == s["t_ns"][0]
    assert (wx, wy, wz) == tuple(s["angular_velocity"][0])
    assert wx == pytest.approx(0.0254694670, abs=1e-9)


def test_ros1_odometry_skipped_and_radar_missing(husky: tuple[IngestReport, Path]) -> None:
    report, out = husky
    assert {"topic": ODOM, "msgtype": "nav_msgs/msg/Odometry", "reason": "not a sensor stream",
            "messages": 3952} in report.skipped_channels
    assert report.partial
    assert any("no radar stream" in w for w in report.warnings)
    assert report.messages == 989 + 11865 + 3952
    with Drive(out) as drive:
        assert drive.report()["skipped_channels"] == report.skipped_channels


def test_ros1_without_allow_partial_refuses(tmp_path: Path, config: Config) -> None:
    bag = realdata(*HUSKY)
    out = tmp_path / "drive.h5"
    with pytest.raises(IngestError, match="radar") as exc:
        ingest([bag], out, config=config)
    assert str(bag) in str(exc.value) and "--allow-partial" in str(exc.value)
    assert _no_output(out)
    r = runner.invoke(app, ["ingest", str(bag), "-o", str(out)])
    assert r.exit_code == 1 and "Traceback" not in r.output
    assert r.stderr.startswith("error:") and "radar" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert _no_output(out)


def test_info_ros1_counts(husky: tuple[IngestReport, Path]) -> None:
    bag = str(realdata(*HUSKY))
    r = runner.invoke(app, ["info", bag])
    assert r.exit_code == 0, r.output
    rows = {line.split("│")[1].strip(): line for line in r.stdout.splitlines() if line.count("│") > 3}
    assert "989" in rows["/fix"].split("│")[3] and "11865" in rows["/imu/data"].split("│")[3]
    r = runner.invoke(app, ["info", bag, "--json"])
    assert r.exit_code == 0, r.output
    got = {s["topic"]: (s["msgtype"], s["count"]) for s in json.loads(r.stdout)["streams"]}
    assert got == {"/fix": ("sensor_msgs/msg/NavSatFix", 989), "/imu/data": ("sensor_msgs/msg/Imu", 11865),
                   ODOM: ("nav_msgs/msg/Odometry", 3952)}
    # the drive's own info repeats its ingest's warnings as the ingest's (they read as if info had written it anew)
    r = runner.invoke(app, ["info", str(husky[1])])
    warned = [line for line in r.stderr.splitlines() if line.startswith("warning:")]
    assert r.exit_code == 0 and any("no radar stream; written anyway (--allow-partial)" in w for w in warned), r.stderr
    assert all(w.startswith("warning: at ingest: ") for w in warned), warned


# ------------------------------------------------------------------------------ MDF4: CSS Electronics
@pytest.fixture(scope="module")
def css(tmp_path_factory: pytest.TempPathFactory, config: Config) -> tuple[IngestReport, Path]:
    files = [realdata("css-electronics", f) for f in CSS_FILES]
    out = tmp_path_factory.mktemp("css") / "drive.h5"
    # the three loggings lie a year apart: ingested as recorded, which the time-gap check must be told
    report = ingest([], out, config=config, dbc=realdata("css-electronics", "gnss.dbc"), can_logs=files,
                    allow_partial=True, allow_time_gap=True)
    return report, out


def test_a_role_names_one_of_two_frame_ids_a_dbc_gives_one_name(tmp_path: Path, config: Config) -> None:
    """gnss.dbc names frame ids 0x3 and 0x13 both gnss_pos; the three files hold both. A role by the message's
    name is then ambiguous and says so; by its group's name (gnss_pos_0x13) it is that one. Before, the name led to
    the DBC's first (0x3) whatever the log held, and a group's name to nothing."""
    roles = {"latitude.a": "gnss_pos.Latitude", "latitude.b": "gnss_pos_0x13.Latitude"}
    cfg = dataclasses.replace(config, can=dataclasses.replace(config.can, roles=roles))
    report = ingest([], tmp_path / "drive.h5", config=cfg, dbc=realdata("css-electronics", "gnss.dbc"),
                    can_logs=[realdata("css-electronics", f) for f in CSS_FILES], allow_partial=True,
                    allow_time_gap=True)
    assert report.can["roles"] == {"latitude.b": "gnss_pos_0x13/Latitude"}
    assert report.can["missing_roles"] == ["latitude.a (gnss_pos is gnss_pos_0x3 and gnss_pos_0x13: name one)"]
    one = ingest([], tmp_path / "one.h5", config=cfg, dbc=realdata("css-electronics", "gnss.dbc"),
                 can_logs=[realdata("css-electronics", CSS_FILES[1])], allow_partial=True)
    assert one.can["roles"] == {"latitude.a": "gnss_pos_0x13/Latitude", "latitude.b": "gnss_pos_0x13/Latitude"}


@pytest.fixture(scope="module")
def css_frames() -> list[can.Message]:
    """All frames of the three MF4 files, read with python-can alone."""
    frames: list[can.Message] = []
    for name in CSS_FILES:
        with can.MF4Reader(realdata("css-electronics", name)) as reader:
            frames.extend(reader)
    return frames


@pytest.fixture(scope="module")
def gnss_db() -> cantools.database.can.Database:
    return cantools.database.load_file(realdata("css-electronics", "gnss.dbc"))


def test_css_mf4_groups_named_by_frame_id(css: tuple[IngestReport, Path], css_frames: list[can.Message],
                                          gnss_db: cantools.database.can.Database) -> None:
    known = {m.frame_id: m.name for m in gnss_db.messages}
    seen = {f.arbitration_id for f in css_frames if f.arbitration_id in known}
    assert seen == set(range(1, 10)) | set(range(17, 26))
    with Drive(css[1]) as drive:
        assert drive.can_messages() == sorted(f"{known[i]}_0x{i:X}" for i in seen)  # e.g. gnss_pos_0x13


def test_css_mf4_values_equal_cantools(css: tuple[IngestReport, Path], css_frames: list[can.Message],
                                       gnss_db: cantools.database.can.Database) -> None:
    by_id: dict[int, list[can.Message]] = {}
    for f in css_frames:
        by_id.setdefault(f.arbitration_id, []).append(f)
    with Drive(css[1]) as drive:
        for msg in gnss_db.messages:
            group = f"can/{msg.name}_0x{msg.frame_id:X}"
            frames = by_id[msg.frame_id]
            s = drive.series(group)
            units = {k: drive.h5[group][k].attrs.get("unit") for k in s}
            np.testing.assert_allclose(s["t_ns"] / 1e9, [f.timestamp for f in frames], rtol=0, atol=1e-6)
            decoded = [msg.decode(bytes(f.data), decode_choices=False) for f in frames]
            for sig in msg.signals:
                if sig.unit == "km":
                    continue  # see test_css_kilometres_become_metres
                angle = sig.unit in ("deg", "deg/s") and sig.name not in ("Latitude", "Longitude")
                assert units[sig.name] == ({"deg": "rad", "deg/s": "rad/s"}[sig.unit] if angle else sig.unit or None)
                expected = [float(d[sig.name]) * (DEG if angle else 1.0) for d in decoded]
                np.testing.assert_allclose(s[sig.name], expected, rtol=1e-12, atol=0, err_msg=f"{group}/{sig.name}")
        for group in ("can/gnss_imu_0x9", "can/gnss_imu_0x19"):
            assert drive.h5[group]["AngularRateZ"].attrs["unit"] == "rad/s"
        imu = drive.series("can/gnss_imu_0x19")
        pos, old_pos = drive.series("can/gnss_pos_0x13"), drive.series("can/gnss_pos_0x3")
        speed = drive.series("can/gnss_speed_0x17")["Speed"]
        assert drive.h5["can/gnss_pos_0x13/Latitude"].attrs["unit"] == "deg"  # geodetic coordinates keep degrees
        times = {g: drive.series(f"can/gnss_time_{g}") for g in ("0x2", "0x12")}
    raw = [gnss_db.get_message_by_frame_id(25).decode(bytes(f.data))["AngularRateZ"] for f in by_id[25]]
    np.testing.assert_allclose(imu["AngularRateZ"], np.asarray(raw) * math.pi / 180, rtol=1e-12)
    assert np.all(np.abs(pos["Latitude"] - 56.071) < 0.002) and np.all(np.abs(pos["Longitude"] - 10.1605) < 0.001)
    assert np.all(np.abs(old_pos["Latitude"] - 56.1517) < 0.001)  # the 2022 file: another place near Aarhus
    assert 0.0 <= speed.min() and 5.0 < speed.max() < 10.0  # m/s: a vehicle moving at walking-to-city speeds
    for t in times.values():  # MF4 absolute times agree with the module's GNSS epoch within the RTC's drift
        assert abs(np.median(t["Epoch"] - t["t_ns"] / 1e9)) < 60.0


def test_css_mf4_unknown_ids_counted(css: tuple[IngestReport, Path], css_frames: list[can.Message],
                                     gnss_db: cantools.database.can.Database) -> None:
    known = {m.frame_id for m in gnss_db.messages}
    unknown = Counter(f"0x{f.arbitration_id:X}" for f in css_frames if f.arbitration_id not in known)
    assert unknown["0x7BB"] == 169 + 74 + 38 and unknown["0x10"] == 291  # diagnostics on CAN 1, 0x10 on CAN 2
    assert {f.channel for f in css_frames if f.arbitration_id >= 0x700} == {1}
    can_report = css[0].can
    assert can_report["unknown_ids"] == dict(unknown)
    assert can_report["frames"] == len(css_frames) == 5588 + 4024 + 3587
    assert can_report["decoded"] == len(css_frames) - sum(unknown.values())
    assert can_report["checksum_errors"] == {} and can_report["dlc_mismatch"] == {}


def test_css_kilometres_become_metres(css: tuple[IngestReport, Path], css_frames: list[can.Message],
                                      gnss_db: cantools.database.can.Database) -> None:
    msg = gnss_db.get_message_by_frame_id(22)
    km = [msg.decode(bytes(f.data))["DistanceTotal"] for f in css_frames if f.arbitration_id == 22]
    assert max(km) > 0
    with Drive(css[1]) as drive:
        assert drive.h5["can/gnss_odo_0x16/DistanceTotal"].attrs["unit"] == "m"
        np.testing.assert_allclose(drive.series("can/gnss_odo_0x16")["DistanceTotal"], np.asarray(km) * 1000.0)


def test_css_can_stream_names_only_its_own_file(css: tuple[IngestReport, Path]) -> None:
    assert _stream(css[0], "can/gnss_pos_0x3")["topics"] == [f"file:{CSS_FILES[0]}"]
    assert _stream(css[0], "can/gnss_pos_0x13")["topics"] == [f"file:{CSS_FILES[1]}", f"file:{CSS_FILES[2]}"]


# ------------------------------------------------------------------------------ opendbc: FCA Giorgio
@pytest.fixture(scope="module")
def giorgio(tmp_path_factory: pytest.TempPathFactory, config: Config) -> tuple[IngestReport, Path, list[Any]]:
    """The 12 real Giulia payloads written 10 ms apart into a BLF log, ingested with the real DBC."""
    frames = json.loads(realdata("opendbc", "giorgio_frames.json").read_text())
    tmp = tmp_path_factory.mktemp("giorgio")
    blf = tmp / "giulia.blf"
    with can.BLFWriter(str(blf)) as writer:
        for i, f in enumerate(frames):
            data = bytes.fromhex(f["data_hex"])
            writer.on_message_received(can.Message(timestamp=1_700_000_000 + 0.01 * i, arbitration_id=f["frame_id"],
                                                   is_extended_id=False, dlc=len(data), data=data, channel=0))
    out = tmp / "drive.h5"
    report = ingest([], out, config=config, dbc=realdata("opendbc", "fca_giorgio.dbc"), can_logs=[blf],
                    allow_partial=True)
    return report, out, frames


def test_giorgio_checksums_and_dbc_repair(giorgio: tuple[IngestReport, Path, list[Any]]) -> None:
    report, _, frames = giorgio
    xor = {0xDE: 0x10, 0x106: 0xF6, 0x122: 0xF1}
    bad = [f["data_hex"] for f in frames
           if crc8_j1850(bytes.fromhex(f["data_hex"])[:-1]) ^ xor.get(f["frame_id"], 0x0A)
           != bytes.fromhex(f["data_hex"])[-1]]
    assert bad == ["7bf0026e"]  # the known bad checksum of upstream's EPS_3 sample
    assert report.can["checksum_errors"] == {"EPS_3": 1}
    assert (report.can["frames"], report.can["decoded"]) == (12, 11)
    assert report.can["counter_errors"] == {} and report.can["unknown_ids"] == {}
    assert any("506855454" in w and "extended" in w for w in report.warnings)


def test_giorgio_values_in_si(giorgio: tuple[IngestReport, Path, list[Any]]) -> None:
    _, out, frames = giorgio
    text = realdata("opendbc", "fca_giorgio.dbc").read_text()
    # cantools refuses the file as published (see README); mark the one extended ID by hand to read the units
    db = cantools.database.load_string(text.replace("BO_ 506855454 ", f"BO_ {506855454 | 0x8000_0000} "))
    good = [f for f in frames if f["data_hex"] != "7bf0026e"]
    with Drive(out) as drive:
        assert drive.can_messages() == ["ABS_2", "EPS_1", "EPS_2", "EPS_3"]
        for name in drive.can_messages():
            rows = [f for f in good if f["message"] == name]
            s = drive.series(f"can/{name}")
            np.testing.assert_allclose(s["t_ns"] / 1e9, [1_700_000_000 + 0.01 * frames.index(f) for f in rows],
                                       rtol=0, atol=1e-6)
            msg = db.get_message_by_name(name)
            for sig in msg.signals:
                vals = [f["decoded"][sig.name] for f in rows]
                vals = [sig.conversion.choice_to_number(v) if isinstance(v, str) else v for v in vals]
                factor = DEG if sig.unit in ("deg", "deg/s") else 1.0
                np.testing.assert_allclose(s[sig.name], np.asarray(vals, dtype=float) * factor, rtol=1e-12,
                                           atol=1e-12, err_msg=f"{name}.{sig.name}")
        assert drive.series("can/EPS_3")["EPS_TORQUE"].tolist() == [-77.0, -79.0]
        assert drive.h5["can/EPS_1/STEERING_RATE"].attrs["unit"] == "rad/s"
        _, angle = drive.can_role("steering_wheel_angle")
        _, yaw = drive.can_role("yaw_rate.esc")
    np.testing.assert_allclose(angle, [math.radians(-119.9)] * 3, rtol=1e-12)
    np.testing.assert_allclose(yaw, [0.0586, 0.0586, 0.0572], rtol=1e-9)  # already rad/s in the DBC


# ------------------------------------------------------------------------------ NMEA: gpsd neo-m8n
@pytest.fixture(scope="module")
def neo(tmp_path_factory: pytest.TempPathFactory, config: Config) -> tuple[IngestReport, Path]:
    out = tmp_path_factory.mktemp("neo") / "drive.h5"
    return ingest([], out, config=config, nmea_logs=[realdata("gpsd", "neo-m8n.log")], allow_partial=True), out


def test_nmea_fixes_equal_gpsd(neo: tuple[IngestReport, Path]) -> None:
    report, out = neo
    lines = realdata("gpsd", "neo-m8n.log").read_text().splitlines()
    gga = [ln.split(",") for ln in lines if ln[3:6] == "GGA"]
    assert len(gga) == 23 and all(g[6] != "0" for g in gga)
    with Drive(out) as drive:
        assert drive.gnss_sources() == ["neo_m8n"]
        s = drive.series("gnss/neo_m8n/nmea_fix")
    assert len(s["t_ns"]) == 23
    # the date comes from RMC (180315); the .chk's year is gpsd's regression-test fake, so compare times of day
    assert s["t_ns"][0] == int(datetime(2015, 3, 18, 17, 19, 26, tzinfo=UTC).timestamp()) * 1_000_000_000
    tod = {int(t // 1_000_000_000) % 86400: i for i, t in enumerate(s["t_ns"])}
    tpvs = [json.loads(ln) for ln in realdata("gpsd", "neo-m8n.log.chk").read_text().splitlines() if '"TPV"' in ln]
    timed = [t for t in tpvs if "time" in t]
    assert len(timed) == 22
    for k, tpv in enumerate(timed):
        when = datetime.fromisoformat(tpv["time"].replace("Z", "+00:00"))
        i = tod[when.hour * 3600 + when.minute * 60 + when.second]
        if k == 0:
            assert i == 0  # the first fix of the drive is gpsd's first timed TPV
        assert s["latitude_deg"][i] == pytest.approx(tpv["lat"], abs=1e-9)
        assert s["longitude_deg"][i] == pytest.approx(tpv["lon"], abs=1e-9)
        assert s["altitude_m"][i] == pytest.approx(tpv["altHAE"], abs=1e-6)  # MSL + geoid separation
    st = _stream(report, "gnss/neo_m8n/nmea_fix")
    talkers = Counter(ln[3:6] for ln in lines if ln.startswith("$"))
    assert st["skipped"] == {f"unsupported {k}": talkers[k] for k in ("GSV", "GLL", "GSA")}


def test_nmea_log_through_cli(tmp_path: Path) -> None:
    out = tmp_path / "drive.h5"
    r = runner.invoke(app, ["ingest", str(realdata("gpsd", "neo-m8n.log")), "-o", str(out), "--allow-partial",
                            "--json"])
    assert r.exit_code == 0, r.output
    assert _stream(json.loads(r.stdout), "gnss/neo_m8n/nmea_fix")["written"] == 23  # .log sniffed as NMEA


# ------------------------------------------------------------------------------ rosbag2: no sensor streams
def _declared(bag: Path) -> dict[str, tuple[str, int]]:
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    return {t["topic_metadata"]["name"]: (t["topic_metadata"]["type"], t["message_count"])
            for t in meta["topics_with_message_count"]}


@pytest.mark.parametrize("name", ROS2_BAGS)
def test_rosbag2_without_sensors_is_refused(name: str, tmp_path: Path, config: Config) -> None:
    bag = realdata("ros2-rosbag2", name)
    out = tmp_path / "drive.h5"
    with pytest.raises(IngestError, match="no known sensor streams") as exc:
        ingest([bag], out, config=config, allow_partial=True)
    assert str(bag) in str(exc.value)
    assert all(topic in str(exc.value) for topic, (_, n) in _declared(bag).items() if n)
    assert _no_output(out)
    r = runner.invoke(app, ["ingest", str(bag), "-o", str(out), "--allow-partial"])
    assert r.exit_code == 1 and "Traceback" not in r.output
    assert len(r.stderr.strip().splitlines()) == 1 and r.stderr.startswith("error:")
    assert "no known sensor streams" in r.stderr and str(bag) in r.stderr
    assert _no_output(out)


@pytest.mark.parametrize("name", ROS2_BAGS)
def test_rosbag2_info_matches_metadata(name: str) -> None:
    bag = realdata("ros2-rosbag2", name)
    r = runner.invoke(app, ["info", str(bag), "--json"])
    assert r.exit_code == 0, r.output
    info = json.loads(r.stdout)
    assert info["container"] == "rosbag2" and info["warnings"] == []
    got = {s["topic"]: (s["msgtype"], s["count"]) for s in info["streams"]}
    assert got == {t: v for t, v in _declared(bag).items() if v[1]}  # topics without messages are not listed
    r = runner.invoke(app, ["info", str(bag)])
    assert r.exit_code == 0 and all(t in r.stdout for t in got)


def _assert_same(a: Any, b: Any, where: str) -> None:
    """Field by field: a rosbags message (dataclass) equals an mcap_ros2 one (ROS constants skipped)."""
    if dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            if not (f.name.isupper() or f.name.startswith("_") or f.name == "structure_needs_at_least_one_member"):
                _assert_same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, list) and a and dataclasses.is_dataclass(a[0]):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_same(x, y, f"{where}[{i}]")
    elif isinstance(b, bytes):  # mcap_ros2 gives byte/uint8 arrays as bytes, rosbags as numpy arrays
        assert np.asarray(a).astype(np.uint8).tobytes() == b, where
    else:
        assert np.array_equal(np.asarray(a), np.asarray(b)), where


@pytest.mark.parametrize("name", ROS2_BAGS)
def test_rosbag2_embedded_schemas_decode_like_mcap_ros2(name: str) -> None:
    """typesys builds deserializers from the bags' ros2msg schemas; they agree with mcap_ros2's decoder."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    from autosar_cli.ingest.sources import open_source
    from autosar_cli.ingest.typesys import MessageTypes

    bag = realdata("ros2-rosbag2", name)
    types = MessageTypes()
    ours = [(m.channel.topic, types.deserializer(m.channel)(m.data)) for m in open_source(bag).messages()]
    assert types.warnings == []
    with open(next(bag.glob("*.mcap")), "rb") as f:
        ref = [(c.topic, m) for _, c, _, m in make_reader(f, decoder_factories=[DecoderFactory()])
               .iter_decoded_messages()]
    assert [t for t, _ in ours] == [t for t, _ in ref] and len(ours) == sum(n for _, n in _declared(bag).values())
    for (topic, a), (_, b) in zip(ours, ref, strict=True):
        _assert_same(a, b, topic)


# ------------------------------------------------------------------ autosar info on standalone logs
def test_info_on_a_can_log_counts_frames_per_channel_and_id() -> None:
    mf4 = realdata("css-electronics", "2F6913DB_00000004_00000001.MF4")
    with can.MF4Reader(str(mf4)) as reader:
        expected = Counter((str(m.channel), m.arbitration_id) for m in reader)
    r = runner.invoke(app, ["info", str(mf4), "--json"])
    assert r.exit_code == 0, r.output
    got = {s["topic"]: s["count"] for s in json.loads(r.stdout)["streams"]}
    assert sum(got.values()) == sum(expected.values()) == 5588
    assert got["ch2 0x9"] == expected[("2", 9)] == 4724  # gnss_imu


def test_info_on_an_nmea_capture_counts_decoded_records() -> None:
    log = realdata("gpsd", "neo-m8n.log")
    r = runner.invoke(app, ["info", str(log), "--json"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    got = {s["topic"]: s["count"] for s in d["streams"]}
    assert got == {"NmeaFix": 23, "NmeaVelocity": 46}  # 23 GGA; 23 RMC + 23 VTG
    assert any("GSV ×157" in w for w in d["warnings"])
