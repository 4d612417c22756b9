"""The simulated drive logs are valid MCAP / ROS1 bag / ROS2 bag files that third-party readers decode
(mcap + mcap_ros2, rosbags AnyReader and rosbag2.Reader; none of our reading code), with the expected
topics, types, counts and rates, the same content in every format, NMEA and NavSatFix consistent with each
other and with the truth sidecar, and byte-identical output for the same seed."""

from __future__ import annotations

import filecmp
import tomllib
from collections import defaultdict
from datetime import UTC, datetime, timedelta
from pathlib import Path

import h5py
import numpy as np
import pymap3d
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from pynmeagps import NMEAReader
from pynmeagps.nmeatypes_core import VALCKSUM
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader as Rosbag2Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from autosar_cli.sim.simulate import simulate

REPO = Path(__file__).resolve().parents[1]
TOML = REPO / "configs" / "giulia_scanbrick.toml"

RADAR = "/scanbrick/raw_frames"
# topic -> (message type, rate of distinct header stamps in Hz)
NAV_TOPICS = {
    RADAR: ("scanbrick_msgs/msg/RawFrame", 990.0),
    "/imu/cog_a": ("sensor_msgs/msg/Imu", 500.0),
    "/imu/cog_b": ("sensor_msgs/msg/Imu", 500.0),
    "/ins_radar/imu": ("sensor_msgs/msg/Imu", 250.0),
    "/ins_cog/imu": ("sensor_msgs/msg/Imu", 100.0),
    "/ins_cog/fix": ("sensor_msgs/msg/NavSatFix", 10.0),
    "/ins_cog/fix_velocity": ("geometry_msgs/msg/TwistWithCovarianceStamped", 10.0),
    "/ins_cog/nmea": ("nmea_msgs/msg/Sentence", 10.0),  # GGA, RMC, VTG, HDT per fix, same stamp
    "/ins_radar/fix": ("sensor_msgs/msg/NavSatFix", 2.5),
    "/ins_radar/vel": ("geometry_msgs/msg/TwistStamped", 2.5),
}
CAN_TOPIC = {"mcap": "/from_can_bus", "ros1": "/received_messages", "ros2": "/from_can_bus"}
CAN_IDS = {0xEE: "ABS_1", 0xDE: "EPS_1", 0xFE: "ABS_2", 0xD2: "ORC_1"}  # 100 Hz each
IMU_SENSORS = {"/imu/cog_a": ("imu_cog_a", 3), "/imu/cog_b": ("imu_cog_b", 3),
               "/ins_cog/imu": ("ins_cog", 6), "/ins_radar/imu": ("ins_radar", 6)}
GNSS_SENSORS = {"/ins_cog/fix": "gnss_cog", "/ins_radar/fix": "gnss_radar"}
NMEA_ORDER = ["GNGGA", "GNRMC", "GNVTG", "GNHDT"]
KNOTS_PER_MPS = 1.0 / 0.514444


def expected_topics(fmt: str) -> dict[str, tuple[str, float]]:
    return {**NAV_TOPICS, CAN_TOPIC[fmt]: ("can_msgs/msg/Frame", 400.0)}


def stamp_ns(msg) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


class Log:
    """One decoded log: per topic its type, log times, header stamps and messages (radar: first only)."""

    def __init__(self) -> None:
        self.types: dict[str, str] = {}
        self.log: dict[str, list[int]] = defaultdict(list)
        self.stamp: dict[str, list[int]] = defaultdict(list)
        self.msgs: dict[str, list] = defaultdict(list)
        self.radar_index: list[int] = []
        self.radar_data_len: set[int] = set()

    def add(self, topic: str, msgtype: str, log_ns: int, msg) -> None:
        assert self.types.setdefault(topic, msgtype) == msgtype
        self.log[topic].append(log_ns)
        self.stamp[topic].append(stamp_ns(msg))
        if topic == RADAR:
            self.radar_index.append(int(msg.frame_index))
            self.radar_data_len.add(len(msg.data))
            if len(self.radar_index) == 1:
                self.msgs[topic].append(msg)
        else:
            self.msgs[topic].append(msg)

    def finish(self) -> Log:
        self.log = {k: np.array(v, dtype=np.int64) for k, v in self.log.items()}
        self.stamp = {k: np.array(v, dtype=np.int64) for k, v in self.stamp.items()}
        return self


def read_mcap(path: Path) -> Log:
    out = Log()
    last_log = -1
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, msg in reader.iter_decoded_messages(log_time_order=False):
            assert channel.message_encoding == "cdr" and schema.encoding == "ros2msg"
            # the writer merges streams: log times are non-decreasing in file order
            assert message.log_time >= last_log
            last_log = message.log_time
            out.add(channel.topic, schema.name, message.log_time, msg)
    return out.finish()


def read_any(path: Path) -> Log:
    out = Log()
    with AnyReader([path]) as reader:
        for conn, log_ns, raw in reader.messages():
            out.add(conn.topic, conn.msgtype, log_ns, reader.deserialize(raw, conn.msgtype))
        out.counts = {c.topic: c.msgcount for c in reader.connections}
    return out.finish()


@pytest.fixture(scope="module")
def config() -> dict:
    with open(TOML, "rb") as f:
        return tomllib.load(f)


@pytest.fixture(scope="module")
def logs(ci_mcap, ci_ros1, ci_ros2) -> dict[str, tuple]:
    return {"mcap": (ci_mcap, read_mcap(ci_mcap.log_path)),
            "ros1": (ci_ros1, read_any(ci_ros1.log_path)),
            "ros2": (ci_ros2, read_any(ci_ros2.log_path))}


@pytest.fixture(scope="module")
def truth(ci_mcap) -> dict:
    with h5py.File(ci_mcap.truth_path) as t:
        sensors = {name: {k: t[f"sensors/{name}/{k}"][()] for k in t[f"sensors/{name}"]} for name in t["sensors"]}
        return {"attrs": dict(t.attrs), "sensors": sensors,
                "trajectory": {k: t[f"trajectory/{k}"][()] for k in t["trajectory"]},
                "radar_t_ns": t["radar/t_ns"][()]}


# ------------------------------------------------------------------------------------------ structure
@pytest.mark.parametrize("fmt", ["mcap", "ros1", "ros2"])
def test_topics_types_counts(logs, fmt):
    result, log = logs[fmt]
    expected = expected_topics(fmt)
    assert log.types == {t: ty for t, (ty, _) in expected.items()}
    counts = {t: len(v) for t, v in log.stamp.items()}
    assert counts == result.message_counts
    if fmt != "mcap":
        assert log.counts == result.message_counts  # bag index / metadata agree
    # one radar frame per PRI, contiguous, the whole cube in each
    assert log.radar_index == list(range(len(log.radar_index)))
    assert log.radar_data_len == {3 * 4 * 540 * 2}
    assert abs(len(log.radar_index) - result.duration_s * 990.0) < 3
    # 4 NMEA sentences per fix
    assert counts["/ins_cog/nmea"] == 4 * counts["/ins_cog/fix"] == 4 * counts["/ins_cog/fix_velocity"]
    assert counts["/ins_radar/fix"] == counts["/ins_radar/vel"]


@pytest.mark.parametrize("fmt", ["mcap", "ros1", "ros2"])
def test_rates_from_header_stamps(logs, fmt):
    result, log = logs[fmt]
    for topic, (_, rate_hz) in expected_topics(fmt).items():
        stamps = log.stamp[topic]
        if topic == CAN_TOPIC[fmt]:
            ids = np.array([m.id for m in log.msgs[topic]])
            assert set(ids.tolist()) == set(CAN_IDS)
            groups = [stamps[ids == i] for i in CAN_IDS]
        else:
            groups = [stamps]
        for s in groups:
            u = np.unique(s)
            if topic.endswith("/nmea"):
                assert np.all(np.unique(s, return_counts=True)[1] == 4)
            else:
                assert len(u) == len(s), f"{topic}: repeated header stamps"
            assert np.all(np.diff(s) >= 0), f"{topic}: stamps go back in log order"
            assert len(u) >= 2, topic
            rate = (len(u) - 1) / ((u[-1] - u[0]) * 1e-9)
            per_id = rate_hz / len(groups)
            assert rate == pytest.approx(per_id, rel=0.01), f"{topic}: {rate:.4f} Hz, expected {per_id}"
            # the samples cover the drive
            assert len(u) == pytest.approx(result.duration_s * per_id, abs=2.0), topic
        # logged a little after the header stamp (transport delay), never before
        delay = log.log[topic] - stamps
        assert delay.min() >= 0 and delay.max() <= 2_000_000, f"{topic}: log - stamp {delay.min()}..{delay.max()}"


def test_radar_stamps_match_truth(logs, truth):
    for fmt, (_, log) in logs.items():
        assert np.array_equal(log.stamp[RADAR], truth["radar_t_ns"]), fmt


def test_rosbag2_reader_with_embedded_definitions(ci_ros2):
    """The plain rosbag2 Reader sees the same connections, and the definitions embedded in the bag (not the
    project's .msg files) are enough to deserialise every message, custom types included."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    with Rosbag2Reader(ci_ros2.log_path) as reader:
        conns = {c.topic: c for c in reader.connections}
        assert {t: c.msgtype for t, c in conns.items()} == {t: ty for t, (ty, _) in expected_topics("ros2").items()}
        assert {t: c.msgcount for t, c in conns.items()} == ci_ros2.message_counts
        assert reader.message_count == sum(ci_ros2.message_counts.values())
        for c in reader.connections:
            if c.msgtype not in store.types:
                text = c.msgdef.data
                types = get_types_from_msg(text.split("=" * 80)[0], c.msgtype)
                for block in text.split("=" * 80)[1:]:
                    head, _, body = block.strip().partition("\n")
                    name = head.removeprefix("MSG: ").strip()
                    if "/msg/" not in name:
                        name = name.replace("/", "/msg/")
                    if name not in store.types:
                        types.update(get_types_from_msg(body, name))
                store.register(types)
        seen: dict[str, list[int]] = defaultdict(list)
        for conn, _, raw in reader.messages():
            seen[conn.topic].append(stamp_ns(store.deserialize_cdr(raw, conn.msgtype)))
    assert {t: len(v) for t, v in seen.items()} == ci_ros2.message_counts
    with AnyReader([ci_ros2.log_path]) as any_reader:
        for conn, _, raw in any_reader.messages(connections=[c for c in any_reader.connections
                                                             if c.topic == "/ins_cog/nmea"]):
            assert stamp_ns(any_reader.deserialize(raw, conn.msgtype)) in seen["/ins_cog/nmea"]


def _fields(topic: str, m) -> tuple:
    """Comparable content of a message (ROS1 vs ROS2 differ only in the header)."""
    if topic in IMU_SENSORS:
        return tuple(np.r_[[getattr(m.angular_velocity, a) for a in "xyz"],
                           [getattr(m.linear_acceleration, a) for a in "xyz"]].round(15).tolist())
    if topic in GNSS_SENSORS:
        return (m.latitude, m.longitude, m.altitude, [float(x) for x in m.position_covariance], m.status.status)
    if topic.endswith("/nmea"):
        return (m.sentence,)
    if topic == "/ins_cog/fix_velocity":
        v = m.twist.twist.linear
        return (v.x, v.y, v.z, [float(x) for x in m.twist.covariance])
    if topic == "/ins_radar/vel":
        v = m.twist.linear
        return (v.x, v.y, v.z)
    if topic == RADAR:
        return (m.frame_index, bytes(np.asarray(m.data, dtype=np.int16).tobytes()))
    return (m.id, m.dlc, bytes(bytearray(m.data)), m.is_extended, m.is_rtr, m.is_error)  # CAN


def test_same_content_in_every_format(logs):
    ref_result, ref = logs["mcap"]
    for fmt in ("ros1", "ros2"):
        _, log = logs[fmt]
        for topic in expected_topics("mcap"):
            other = CAN_TOPIC[fmt] if topic == CAN_TOPIC["mcap"] else topic
            assert np.array_equal(ref.stamp[topic], log.stamp[other]), (fmt, topic)
            a = [str(_fields(topic, m)) for m in ref.msgs[topic]]  # str: NaN == NaN
            b = [str(_fields(topic, m)) for m in log.msgs[other]]
            assert a == b, (fmt, topic)
            assert [m.header.frame_id for m in ref.msgs[topic]] == [m.header.frame_id for m in log.msgs[other]]


# ------------------------------------------------------------------------------------------ IMU
def test_imu_dof_convention_and_values(logs, truth, config):
    _, log = logs["mcap"]
    for topic, (sensor, dof) in IMU_SENSORS.items():
        s = config["sensors"][sensor]
        assert s["dof"] == dof and s["topic"] == topic
        msgs = log.msgs[topic]
        gyro = np.array([[m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z] for m in msgs])
        acc = np.array([[m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z]
                        for m in msgs])
        assert all(m.orientation_covariance[0] == -1.0 for m in msgs)  # REP 145: no orientation
        assert all(m.header.frame_id == s["frame_id"] for m in msgs)
        if dof == 3:  # yaw rate + longitudinal / lateral acceleration only
            assert np.all(np.isnan(gyro[:, :2])) and np.all(np.isnan(acc[:, 2]))
            gyro_axes, acc_axes = [2], [0, 1]
        else:
            gyro_axes, acc_axes = [0, 1, 2], [0, 1, 2]
        assert np.all(np.isfinite(gyro[:, gyro_axes])) and np.all(np.isfinite(acc[:, acc_axes]))
        t = truth["sensors"][sensor]
        assert np.array_equal(t["stamp_ns"], log.stamp[topic])
        latency_ns = round(s["latency_s"] * 1e9)
        assert np.all(np.abs(t["stamp_ns"] - t["t_ns"] - latency_ns) <= 1)
        sg = np.deg2rad(s["gyro"]["noise_density_dps_rthz"]) * np.sqrt(s["rate_hz"])
        sa = s["accel"]["noise_density_mps2_rthz"] * np.sqrt(s["rate_hz"])
        rg = (gyro - t["angular_velocity"] - t["gyro_bias"])[:, gyro_axes]
        ra = (acc - t["linear_acceleration"] - t["accel_bias"])[:, acc_axes]
        assert np.max(np.abs(rg)) < 5 * sg and np.max(np.abs(ra)) < 5 * sa, topic
        assert np.std(rg) == pytest.approx(sg, rel=0.25) and np.std(ra) == pytest.approx(sa, rel=0.25), topic
        # the gravity is in the specific force: z of a 6-DoF unit reads ~ +9.8 m/s^2 (+ bias + noise)
        if dof == 6:
            assert np.all(np.abs(acc[:, 2] - 9.81) < 0.5)


# ------------------------------------------------------------------------------------------ GNSS
def test_navsatfix_matches_truth_enu(logs, truth, config):
    _, log = logs["mcap"]
    a = truth["attrs"]
    for topic, sensor in GNSS_SENSORS.items():
        t = truth["sensors"][sensor]
        msgs = log.msgs[topic]
        assert np.array_equal(log.stamp[topic], t["stamp_ns"])
        lat = np.array([m.latitude for m in msgs])
        lon = np.array([m.longitude for m in msgs])
        alt = np.array([m.altitude for m in msgs])
        e, n, u = pymap3d.geodetic2enu(lat, lon, alt, a["origin_lat_deg"], a["origin_lon_deg"], a["origin_height_m"])
        enu = np.stack([e, n, u], -1)
        expected = t["position_enu"] + t["position_error"]
        assert np.max(np.abs(enu - expected)) < 1e-3, topic
        # the error is really there, of the configured size (GM std 0.25..0.6 m + white)
        assert np.max(np.abs(t["position_error"])) > 0.01
        assert np.max(np.abs(t["position_error"][:, :2])) < 5 * config["sensors"][sensor]["gnss"]["horizontal_std_m"]
        # the true antenna position is the CoG trajectory + the lever arm (within the motion in 1 ms)
        tr = truth["trajectory"]
        k = np.searchsorted(tr["t_ns"], t["t_ns"])
        assert np.array_equal(tr["t_ns"][k], t["t_ns"])
        lever = np.asarray(config["sensors"][sensor]["lever_arm_m"])
        h = tr["heading"][k]
        c, s = np.cos(h), np.sin(h)
        offset = np.stack([c * lever[0] - s * lever[1], s * lever[0] + c * lever[1], np.full_like(h, lever[2])], -1)
        assert np.max(np.abs(tr["position_enu"][k] + offset - t["position_enu"])) < 0.01, topic
        # fixes at whole multiples of the period, UTC
        period_ns = round(1e9 / config["sensors"][sensor]["rate_hz"])
        assert np.all(t["t_ns"] % period_ns == 0)


def test_gnss_velocity(logs, truth, config):
    _, log = logs["mcap"]
    for topic, sensor in (("/ins_cog/fix_velocity", "gnss_cog"), ("/ins_radar/vel", "gnss_radar")):
        t = truth["sensors"][sensor]
        msgs = log.msgs[topic]
        lin = [m.twist.twist.linear if hasattr(m.twist, "twist") else m.twist.linear for m in msgs]
        v = np.array([[x.x, x.y, x.z] for x in lin])
        sigma = config["sensors"][sensor]["gnss"]["velocity_std_mps"] * np.array([1.0, 1.0, 1.5])
        assert np.all(np.abs(v - t["velocity_enu"]) < 5 * sigma), topic
        assert np.all(np.linalg.norm(t["velocity_enu"][:, :2], axis=1) > 1.0)  # ci drives at ~2.4 m/s


def nmea_checksum_ok(sentence: str) -> bool:
    body, star, cs = sentence.partition("*")
    assert sentence.startswith("$") and star == "*" and len(cs) == 2
    x = 0
    for ch in body[1:]:
        x ^= ord(ch)
    return f"{x:02X}" == cs


def test_nmea_sentences(logs, truth, config):
    _, log = logs["mcap"]
    sentences = [m.sentence for m in log.msgs["/ins_cog/nmea"]]
    stamps = log.stamp["/ins_cog/nmea"]
    fixes = log.msgs["/ins_cog/fix"]
    vels = log.msgs["/ins_cog/fix_velocity"]
    t = truth["sensors"]["gnss_cog"]
    heading_std = config["sensors"]["gnss_cog"]["gnss"]["heading_std_deg"]
    assert len(sentences) == 4 * len(fixes) == 4 * len(t["t_ns"])
    hdt_err = []
    for i, fix in enumerate(fixes):
        group = sentences[4 * i: 4 * i + 4]
        assert np.all(stamps[4 * i: 4 * i + 4] == stamp_ns(fix))
        for s in group:
            assert nmea_checksum_ok(s), s
        # a corrupted checksum is caught by both checks
        bad = group[3][:-1] + ("0" if group[3][-1] != "0" else "1")
        assert not nmea_checksum_ok(bad)
        with pytest.raises(Exception, match="checksum"):
            NMEAReader.parse(bad, validate=VALCKSUM)
        gga, rmc, vtg, hdt = (NMEAReader.parse(s, validate=VALCKSUM) for s in group)
        assert [m.talker + m.msgID for m in (gga, rmc, vtg, hdt)] == NMEA_ORDER
        # GGA: high-precision position equal to the NavSatFix, MSL altitude + separation = ellipsoidal
        assert gga.lat == pytest.approx(fix.latitude, abs=1e-8)  # 1e-8 deg ~ 1 mm
        assert gga.lon == pytest.approx(fix.longitude, abs=1e-8)
        assert gga.NS == "N" and gga.EW == "E" and gga.quality == 2
        assert gga.alt + gga.sep == pytest.approx(fix.altitude, abs=5e-4 + 1e-9)
        # UTC time of the fix = its measurement instant (the header stamp adds the latency)
        t_fix = datetime.fromtimestamp(0, UTC) + timedelta(microseconds=int(t["t_ns"][i]) // 1000)
        for m in (gga, rmc):
            got = datetime.combine(t_fix.date(), m.time, tzinfo=UTC)
            assert abs((got - t_fix).total_seconds()) < 0.01, (m.time, t_fix)
        assert rmc.date == t_fix.date() == datetime(2021, 2, 10).date()
        assert rmc.status == "A"
        assert rmc.lat == gga.lat and rmc.lon == gga.lon
        # speed and course over ground from the velocity message
        v = fix_v = vels[i].twist.twist.linear
        speed = np.hypot(fix_v.x, fix_v.y)
        course = np.rad2deg(np.arctan2(v.x, v.y)) % 360.0
        assert rmc.spd == pytest.approx(speed * KNOTS_PER_MPS, abs=5e-4 + 1e-9)
        assert vtg.sogn == rmc.spd
        assert vtg.sogk == pytest.approx(speed * 3.6, abs=5e-4 + 1e-9)
        assert (rmc.cog - course + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=5e-3 + 1e-9)
        assert vtg.cogt == rmc.cog
        # HDT: true heading with the configured noise
        hdt_err.append((hdt.headingT - t["heading_deg"][i] + 180.0) % 360.0 - 180.0)
    hdt_err = np.array(hdt_err)
    assert np.all(np.abs(hdt_err) < 5 * heading_std), hdt_err
    # noise really added, of about the configured size (chi-square bounds for ~10 samples)
    assert 0.3 * heading_std < np.std(hdt_err) < 2.0 * heading_std
    # truth heading: deg from North, clockwise, of the vehicle's ENU heading
    tr = truth["trajectory"]
    k = np.searchsorted(tr["t_ns"], t["t_ns"])
    assert np.allclose((90.0 - np.rad2deg(tr["heading"][k])) % 360.0, t["heading_deg"], atol=1e-6)


# ------------------------------------------------------------------------------------------ determinism
def _sim(tmp: Path, sub: str, fmt: str, seed: int):
    ext = {"mcap": ".mcap", "ros1": ".bag", "ros2": ""}[fmt]
    d = tmp / sub
    d.mkdir()
    return simulate("ci", d / f"ci{ext}", fmt=fmt, seed=seed)


def _same_files(a: Path, b: Path) -> None:
    if a.is_dir():
        names = sorted(p.name for p in a.iterdir())
        assert names == sorted(p.name for p in b.iterdir()) and names
        for name in names:
            assert filecmp.cmp(a / name, b / name, shallow=False), name
    else:
        assert filecmp.cmp(a, b, shallow=False), a.name


@pytest.fixture(scope="module")
def seeded_mcap(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("determinism")
    return _sim(tmp, "a", "mcap", 3), _sim(tmp, "b", "mcap", 3), _sim(tmp, "c", "mcap", 4)


def test_mcap_same_seed_is_byte_identical(seeded_mcap):
    a, b, _ = seeded_mcap
    assert a.log_path.stat().st_size > 1_000_000
    _same_files(a.log_path, b.log_path)
    _same_files(a.truth_path, b.truth_path)
    assert a.message_counts == b.message_counts


def _first_radar_frame(path: Path):
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, _, _, msg in reader.iter_decoded_messages(topics=[RADAR]):
            return msg
    raise AssertionError("no radar frame")


def test_other_seed_changes_noise_not_scene(seeded_mcap):
    a, _, c = seeded_mcap
    fa, fc = _first_radar_frame(a.log_path), _first_radar_frame(c.log_path)
    assert fa.frame_index == fc.frame_index == 0 and stamp_ns(fa) == stamp_ns(fc)
    da, dc = np.asarray(fa.data, dtype=np.int16), np.asarray(fc.data, dtype=np.int16)
    assert da.shape == dc.shape
    # thermal noise and the radar-case vibration (both seeded) change almost every sample ...
    assert np.mean(da != dc) > 0.5
    # ... but not the scene: the vibration (~1 mm) moves echo phases, not range bins, so the range
    # profiles (|FFT| per channel) of the two seeds are nearly identical
    prof = [np.abs(np.fft.fft((d[0::2] + 1j * d[1::2]).reshape(3, 4, 540) * np.hanning(540), axis=-1))
            for d in (da.astype(np.float64), dc.astype(np.float64))]
    assert np.corrcoef(prof[0].ravel(), prof[1].ravel())[0, 1] > 0.99
    with h5py.File(a.truth_path) as ta, h5py.File(c.truth_path) as tc:
        assert ta.attrs["seed"] == 3 and tc.attrs["seed"] == 4
        # identical scene and drive
        for key in ("targets/position_enu", "targets/rcs_m2", "targets/kind", "trajectory/position_enu",
                    "trajectory/heading", "trajectory/speed", "radar/t_ns", "sensors/gnss_cog/t_ns",
                    "sensors/gnss_cog/position_enu"):
            assert np.array_equal(ta[key][()], tc[key][()]), key
        # different sensor error states
        for key in ("sensors/wheel_speeds/scale_factor", "sensors/steering/offset", "sensors/esc/gyro_bias",
                    "sensors/orc/gyro_bias", "sensors/imu_cog_a/gyro_bias", "sensors/gnss_cog/position_error",
                    "radar/vibration_enu"):
            x, y = ta[key][()], tc[key][()]
            n = min(len(x), len(y))  # sample counts may differ: random sampling phase per seed
            assert n >= 1 and not np.any(x[:n] == y[:n]), key
    # and the logged fixes (same instants) differ
    fix = {}
    for r in (a, c):
        with open(r.log_path, "rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            fix[r.seed] = [(stamp_ns(m), m.latitude) for *_, m in reader.iter_decoded_messages(topics=["/ins_cog/fix"])]
    assert [s for s, _ in fix[3]] == [s for s, _ in fix[4]]
    assert all(la != lc for (_, la), (_, lc) in zip(fix[3], fix[4], strict=True))


@pytest.mark.parametrize("fmt", ["ros1", "ros2"])
def test_bag_same_seed_is_byte_identical(tmp_path, fmt):
    a, b = _sim(tmp_path, "a", fmt, 5), _sim(tmp_path, "b", fmt, 5)
    if fmt == "ros2":
        assert a.log_path.is_dir() and (a.log_path / "metadata.yaml").exists()
    _same_files(a.log_path, b.log_path)
    _same_files(a.truth_path, b.truth_path)
