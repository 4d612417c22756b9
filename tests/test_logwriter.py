"""Log writers (mcap, ROS 1 bag, rosbag2) checked with independent readers.

Each format gets a few hundred messages of every sensor type at known rates, then is opened with a
reader that shares no code with the writer path under test (mcap + mcap_ros2 for .mcap, rosbags
AnyReader for bags, rosbags rosbag2.Reader + AnyReader for rosbag2 directories).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from autosar_cli import msgs
from autosar_cli.sim.logwriter import LogWriter, open_log_writer, partial_path

T0_NS = 1_700_000_000_123_456_789
NUM_TX, NUM_RX, NUM_SAMPLES = 3, 4, 540
RAW_LEN = NUM_TX * NUM_RX * NUM_SAMPLES * 2
TX_OFFSETS = [0.0, 6e-5, 1.2e-4]


@dataclass(frozen=True)
class Stream:
    topic: str
    msgtype: str
    rate_hz: float
    count: int
    offset_ns: int

    def time_ns(self, i: int) -> int:
        return T0_NS + self.offset_ns + round(i * 1e9 / self.rate_hz)


STREAMS = (
    Stream("/radar/raw", msgs.RAW_FRAME, 1000.0, 300, 0),
    Stream("/can/from_can_bus", msgs.CAN_FRAME, 500.0, 300, 250_000),
    Stream("/gnss/fix", msgs.NAV_SAT_FIX, 10.0, 200, 1_000_000),
    Stream("/imu/data", msgs.IMU, 200.0, 300, 500_000),
    Stream("/gnss/fix_velocity", msgs.TWIST_WITH_COVARIANCE_STAMPED, 10.0, 200, 1_500_000),
    Stream("/gnss/vel", msgs.TWIST_STAMPED, 10.0, 200, 1_600_000),
    Stream("/gnss/nmea_sentence", msgs.NMEA_SENTENCE, 20.0, 200, 2_000_000),
)


def raw_data(i: int) -> np.ndarray:
    return np.random.default_rng(1000 + i).integers(-32768, 32768, RAW_LEN, dtype=np.int16)


def can_id(i: int) -> int:
    return (0x0DE, 0x106, 0x122, 0x0FE)[i % 4]


def can_data(i: int) -> np.ndarray:
    return np.random.default_rng(2000 + i).integers(0, 256, 8, dtype=np.uint8)


def lat_lon(i: int) -> tuple[float, float]:
    return 45.0 + i * 1e-6, 7.0 + i * 2e-6


def make_msg(ts, msgtype: str, i: int, t_ns: int) -> object:
    """A message of ``msgtype`` built from ``ts`` whose field values are a function of ``i``."""
    T = ts.types
    hdr = msgs.header(ts, t_ns, "base_link")
    vec3 = T["geometry_msgs/msg/Vector3"]
    if msgtype == msgs.RAW_FRAME:
        return T[msgtype](
            header=msgs.header(ts, t_ns, "radar"),
            frame_index=i,
            start_frequency_hz=77.0e9,
            slope_hz_per_s=3.0e13,
            sample_rate_hz=1.0e7,
            tx_start_offsets_s=np.array(TX_OFFSETS),
            num_tx=NUM_TX,
            num_rx=NUM_RX,
            num_samples=NUM_SAMPLES,
            data=raw_data(i),
        )
    if msgtype == msgs.CAN_FRAME:
        return T[msgtype](
            header=hdr, id=can_id(i), is_rtr=False, is_extended=False, is_error=False, dlc=8, data=can_data(i)
        )
    if msgtype == msgs.NAV_SAT_FIX:
        lat, lon = lat_lon(i)
        return T[msgtype](
            header=hdr,
            status=T[msgs.NAV_SAT_STATUS](status=0, service=1),
            latitude=lat,
            longitude=lon,
            altitude=250.0 + i * 0.01,
            position_covariance=np.diag([0.01, 0.01, 0.04]).ravel(),
            position_covariance_type=2,
        )
    if msgtype == msgs.IMU:
        return T[msgtype](
            header=hdr,
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=np.full(9, -1.0),
            angular_velocity=vec3(x=0.0, y=0.0, z=0.001 * i),
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=vec3(x=0.01 * i, y=0.0, z=9.81),
            linear_acceleration_covariance=np.zeros(9),
        )
    if msgtype == msgs.TWIST_WITH_COVARIANCE_STAMPED:
        twist = T["geometry_msgs/msg/Twist"](
            linear=vec3(x=10.0 + 0.1 * i, y=0.0, z=0.0), angular=vec3(0.0, 0.0, 0.0)
        )
        return T[msgtype](
            header=hdr,
            twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.eye(6).ravel()),
        )
    if msgtype == msgs.TWIST_STAMPED:
        twist = T["geometry_msgs/msg/Twist"](
            linear=vec3(x=10.0 + 0.1 * i, y=0.5, z=0.0), angular=vec3(0.0, 0.0, 0.0)
        )
        return T[msgtype](header=hdr, twist=twist)
    if msgtype == msgs.NMEA_SENTENCE:
        return T[msgtype](
            header=hdr, sentence=f"$GPGGA,{i:06d}.00,4500.000,N,00700.000,E,1,08,0.9,250.0,M,,,,*47"
        )
    raise AssertionError(msgtype)


def schedule(streams=STREAMS) -> list[tuple[int, str, int]]:
    """All (time, topic, index) of ``streams`` merged in time order (ties: stream order)."""
    events = [(s.time_ns(i), k, s.topic, i) for k, s in enumerate(streams) for i in range(s.count)]
    return [(t, topic, i) for t, _, topic, i in sorted(events)]


def write_sample(path: Path, fmt: str, streams=STREAMS, **kwargs) -> None:
    with open_log_writer(path, fmt, **kwargs) as w:
        assert isinstance(w, LogWriter)
        for s in streams:
            w.add_topic(s.topic, s.msgtype)
        by_topic = {s.topic: s for s in streams}
        for t, topic, i in schedule(streams):
            w.write(topic, t, make_msg(w.typestore, by_topic[topic].msgtype, i, t))
        assert w.message_counts == {s.topic: s.count for s in streams}
    assert path.exists()
    assert not partial_path(path).exists()


def _u8(value) -> list[int]:
    if isinstance(value, bytes | bytearray):
        return list(value)
    return [int(x) for x in value]


def check_decoded(topic: str, msgtype: str, i: int, t_ns: int, m) -> None:
    """Compare decoded message ``m`` (any reader's object) with what :func:`make_msg` wrote."""
    stamp_ns = m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
    assert stamp_ns == t_ns, topic
    if msgtype == msgs.RAW_FRAME:
        assert m.frame_index == i
        assert (m.num_tx, m.num_rx, m.num_samples) == (NUM_TX, NUM_RX, NUM_SAMPLES)
        assert m.header.frame_id == "radar"
        np.testing.assert_array_equal(np.asarray(m.tx_start_offsets_s, dtype=np.float64), TX_OFFSETS)
        data = np.asarray(m.data)
        assert data.shape == (RAW_LEN,)
        np.testing.assert_array_equal(data.astype(np.int16), raw_data(i))
    elif msgtype == msgs.CAN_FRAME:
        assert m.id == can_id(i) and m.dlc == 8 and not m.is_extended
        assert _u8(m.data) == can_data(i).tolist()
    elif msgtype == msgs.NAV_SAT_FIX:
        assert (m.latitude, m.longitude) == lat_lon(i)
        assert m.position_covariance_type == 2
    elif msgtype == msgs.IMU:
        assert m.linear_acceleration.x == 0.01 * i and m.angular_velocity.z == 0.001 * i
    elif msgtype == msgs.TWIST_WITH_COVARIANCE_STAMPED:
        assert m.twist.twist.linear.x == 10.0 + 0.1 * i
        np.testing.assert_array_equal(np.asarray(m.twist.covariance), np.eye(6).ravel())
    elif msgtype == msgs.TWIST_STAMPED:
        assert (m.twist.linear.x, m.twist.linear.y) == (10.0 + 0.1 * i, 0.5)
    elif msgtype == msgs.NMEA_SENTENCE:
        assert m.sentence.startswith(f"$GPGGA,{i:06d}.00,")
    else:
        raise AssertionError(msgtype)


class Collector:
    """Checks one reader's stream of (topic, msgtype, log_time, decoded message)."""

    def __init__(self, streams=STREAMS) -> None:
        self.streams = {s.topic: s for s in streams}
        self.seen: dict[str, list[int]] = {s.topic: [] for s in streams}

    def add(self, topic: str, msgtype: str, log_time_ns: int, m) -> None:
        s = self.streams[topic]
        assert msgtype == s.msgtype, (topic, msgtype)
        i = len(self.seen[topic])
        assert log_time_ns == s.time_ns(i), topic
        check_decoded(topic, msgtype, i, log_time_ns, m)
        self.seen[topic].append(log_time_ns)

    def finish(self) -> None:
        for topic, s in self.streams.items():
            times = self.seen[topic]
            assert len(times) == s.count, topic
            assert times[0] == s.time_ns(0) and times[-1] == s.time_ns(s.count - 1), topic


def normalize(msgtype: str) -> str:
    """ROS 1 readers report ``pkg/Name``; compare as ``pkg/msg/Name``."""
    pkg, *_, name = msgtype.split("/")
    return f"{pkg}/msg/{name}"


def read_mcap(path: Path, streams=STREAMS) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    col = Collector(streams)
    by_topic = {s.topic: s for s in streams}
    sequences: dict[str, list[int]] = {}
    last_t = -1
    with path.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        assert header.profile == "ros2"
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        assert summary.statistics.message_count == sum(s.count for s in streams)
        assert {c.topic for c in summary.channels.values()} == {s.topic for s in streams}
        for ch in summary.channels.values():
            assert ch.message_encoding == "cdr"
            schema = summary.schemas[ch.schema_id]
            assert schema.encoding == "ros2msg"
            assert schema.name == by_topic[ch.topic].msgtype
            assert summary.statistics.channel_message_counts[ch.id] == by_topic[ch.topic].count
        for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=False):
            assert message.publish_time == message.log_time
            assert message.log_time >= last_t  # written in time order
            last_t = message.log_time
            sequences.setdefault(channel.topic, []).append(message.sequence)
            col.add(channel.topic, schema.name, message.log_time, decoded)
    col.finish()
    for topic, seq in sequences.items():
        assert seq == list(range(len(seq))), topic


def read_anyreader(paths: list[Path], streams=STREAMS) -> None:
    from rosbags.highlevel import AnyReader

    col = Collector(streams)
    by_topic = {s.topic: s for s in streams}
    with AnyReader(paths) as reader:
        assert {c.topic for c in reader.connections} == {s.topic for s in streams}
        for c in reader.connections:
            assert normalize(c.msgtype) == by_topic[c.topic].msgtype
            assert c.msgcount == by_topic[c.topic].count
        for conn, t, raw in reader.messages():
            col.add(conn.topic, normalize(conn.msgtype), t, reader.deserialize(raw, conn.msgtype))
    col.finish()


def read_rosbag2(path: Path, streams=STREAMS) -> None:
    from rosbags.rosbag2 import Reader

    ts = msgs.typestore_for(2)
    col = Collector(streams)
    with Reader(path) as reader:
        assert reader.message_count == sum(s.count for s in streams)
        assert {c.topic: c.msgcount for c in reader.connections} == {s.topic: s.count for s in streams}
        for c in reader.connections:
            qos = c.ext.offered_qos_profiles
            assert len(qos) == 1 and qos[0].reliability.name == "RELIABLE"
            assert qos[0].history.name == "KEEP_LAST" and qos[0].durability.name == "VOLATILE"
        for conn, t, raw in reader.messages():
            col.add(conn.topic, conn.msgtype, t, ts.deserialize_cdr(raw, conn.msgtype))
    col.finish()


FORMATS = [
    pytest.param("mcap", {}, id="mcap"),
    pytest.param("ros1", {}, id="ros1"),
    pytest.param("ros2", {}, id="ros2-sqlite3"),
    pytest.param("ros2", {"storage": "mcap"}, id="ros2-mcap"),
]
SUFFIX = {"mcap": ".mcap", "ros1": ".bag", "ros2": ""}


def out_path(tmp_path: Path, fmt: str, name: str = "drive") -> Path:
    return tmp_path / f"{name}{SUFFIX[fmt]}"


def verify(path: Path, fmt: str, streams=STREAMS) -> None:
    if fmt == "mcap":
        read_mcap(path, streams)
    elif fmt == "ros1":
        read_anyreader([path], streams)
    else:
        read_rosbag2(path, streams)
        read_anyreader([path], streams)


@pytest.mark.parametrize(("fmt", "kwargs"), FORMATS)
def test_roundtrip_independent_readers(tmp_path: Path, fmt: str, kwargs: dict) -> None:
    path = out_path(tmp_path, fmt)
    write_sample(path, fmt, **kwargs)
    verify(path, fmt)
    if fmt == "ros2":
        storage = kwargs.get("storage", "sqlite3")
        suffix = ".db3" if storage == "sqlite3" else ".mcap"
        assert sorted(p.name for p in path.iterdir()) == sorted(["metadata.yaml", f"drive{suffix}"])
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]


SMALL = tuple(
    Stream(s.topic, s.msgtype, s.rate_hz, 12, s.offset_ns) for s in STREAMS if s.msgtype != msgs.TWIST_STAMPED
)


@pytest.mark.parametrize(
    ("fmt", "kwargs"),
    [
        pytest.param("mcap", {"compression": "lz4"}, id="mcap-lz4"),
        pytest.param("mcap", {"compression": "none"}, id="mcap-none"),
        pytest.param("ros1", {"compression": "bz2"}, id="ros1-bz2"),
        pytest.param("ros1", {"compression": "none"}, id="ros1-none"),
        pytest.param("ros2", {"compression": "none"}, id="ros2-sqlite3-none"),
        pytest.param("ros2", {"compression": "none", "storage": "mcap"}, id="ros2-mcap-none"),
    ],
)
def test_compression_variants(tmp_path: Path, fmt: str, kwargs: dict) -> None:
    path = out_path(tmp_path, fmt)
    write_sample(path, fmt, SMALL, **kwargs)
    verify(path, fmt, SMALL)


def test_plain_mcap_is_readable_as_rosbag2_storage_file(tmp_path: Path) -> None:
    from rosbags.rosbag2 import Reader

    path = out_path(tmp_path, "mcap")
    write_sample(path, "mcap", SMALL)
    ts = msgs.typestore_for(2)
    col = Collector(SMALL)
    with Reader(path) as reader:
        for conn, t, raw in reader.messages():
            col.add(conn.topic, conn.msgtype, t, ts.deserialize_cdr(raw, conn.msgtype))
    col.finish()


def _files(path: Path) -> dict[str, bytes]:
    if path.is_file():
        return {path.name: path.read_bytes()}
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


@pytest.mark.parametrize(("fmt", "kwargs"), FORMATS)
def test_deterministic_bytes(tmp_path: Path, fmt: str, kwargs: dict) -> None:
    a = out_path(tmp_path / "a", fmt)
    b = out_path(tmp_path / "b", fmt)
    a.parent.mkdir()
    b.parent.mkdir()
    write_sample(a, fmt, SMALL, **kwargs)
    write_sample(b, fmt, SMALL, **kwargs)
    fa, fb = _files(a), _files(b)
    assert fa.keys() == fb.keys()
    for name in fa:
        assert fa[name] == fb[name], name
    if fmt == "ros2":
        assert "metadata.yaml" in fa and len(fa) == 2


@pytest.mark.parametrize(("fmt", "kwargs"), FORMATS)
def test_exception_leaves_no_output(tmp_path: Path, fmt: str, kwargs: dict) -> None:
    path = out_path(tmp_path, fmt)
    with pytest.raises(RuntimeError, match="boom"), open_log_writer(path, fmt, **kwargs) as w:
        w.add_topic("/radar/raw", msgs.RAW_FRAME)
        for i in range(5):
            w.write("/radar/raw", T0_NS + i, make_msg(w.typestore, msgs.RAW_FRAME, i, T0_NS + i))
        assert partial_path(path).exists()
        assert not path.exists()
        raise RuntimeError("boom")
    assert not path.exists()
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("fmt", "kwargs"), FORMATS)
def test_refuses_to_overwrite(tmp_path: Path, fmt: str, kwargs: dict) -> None:
    path = out_path(tmp_path, fmt)
    if fmt == "ros2":
        path.mkdir()
        (path / "keep.txt").write_text("x")
    else:
        path.write_bytes(b"keep")
    with pytest.raises(FileExistsError):
        open_log_writer(path, fmt, **kwargs)
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]
    if fmt == "ros2":
        assert (path / "keep.txt").read_text() == "x"
    else:
        assert path.read_bytes() == b"keep"


def test_stale_partial_is_replaced(tmp_path: Path) -> None:
    path = out_path(tmp_path, "mcap")
    partial_path(path).write_bytes(b"left over by a killed run")
    write_sample(path, "mcap", SMALL)
    read_mcap(path, SMALL)


def test_misuse_is_reported(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="log format"):
        open_log_writer(tmp_path / "x", "rosbag3")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="compression"):
        open_log_writer(tmp_path / "x", "ros2", compression="lz4")
    with pytest.raises(ValueError, match="storage"):
        open_log_writer(tmp_path / "x", "ros2", storage="leveldb")  # type: ignore[arg-type]
    path = out_path(tmp_path, "mcap")
    with open_log_writer(path, "mcap") as w:
        with pytest.raises(ValueError, match="unknown message type"):
            w.add_topic("/x", "foo_msgs/msg/Bar")
        w.add_topic("/radar/raw", msgs.RAW_FRAME)
        w.add_topic("/radar/raw", msgs.RAW_FRAME)  # repeat: no-op
        with pytest.raises(ValueError, match="already added"):
            w.add_topic("/radar/raw", msgs.IMU)
        with pytest.raises(KeyError, match="add_topic"):
            w.write("/nope", T0_NS, make_msg(w.typestore, msgs.IMU, 0, T0_NS))
        with pytest.raises(TypeError, match="carries"):
            w.write("/radar/raw", T0_NS, make_msg(w.typestore, msgs.IMU, 0, T0_NS))
        w.write("/radar/raw", T0_NS, make_msg(w.typestore, msgs.RAW_FRAME, 0, T0_NS))
    with pytest.raises(RuntimeError, match="closed"):
        w.write("/radar/raw", T0_NS, make_msg(w.typestore, msgs.RAW_FRAME, 0, T0_NS))
    w.close()  # idempotent
    with open_log_writer(out_path(tmp_path, "ros1"), "ros1") as w1:
        w1.add_topic("/radar/raw", msgs.RAW_FRAME)
        ros2_msg = make_msg(msgs.typestore_for(2), msgs.RAW_FRAME, 0, T0_NS)  # header without seq
        with pytest.raises(TypeError, match="writer.typestore"):
            w1.write("/radar/raw", T0_NS, ros2_msg)
        assert w1.message_counts == {"/radar/raw": 0}


def test_typestores_and_headers() -> None:
    ts1, ts2 = msgs.typestore_for(1), msgs.typestore_for(2)
    assert msgs.typestore_for(2) is ts2
    for ts in (ts1, ts2):
        for name in (*msgs.CUSTOM_TYPES, msgs.NAV_SAT_FIX, msgs.IMU, msgs.TWIST_STAMPED):
            assert name in ts.types
    h1 = msgs.header(ts1, 1_500_000_000_000_000_007, "radar")
    h2 = msgs.header(ts2, 1_500_000_000_000_000_007, "radar")
    assert h1.seq == 0 and not hasattr(h2, "seq")
    assert (h2.stamp.sec, h2.stamp.nanosec, h2.frame_id) == (1_500_000_000, 7, "radar")
    with pytest.raises(ValueError):
        msgs.typestore_for(3)
