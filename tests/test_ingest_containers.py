"""Container variants ingest must read: MCAP with lz4 / no compression, unindexed and unchunked MCAP,
MCAP with the ros1 profile, rosbag2 with MCAP storage. Each must give the same drive as the simulator's
own zstd MCAP of the same drive."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, IndexType, Writer
from rosbags.rosbag1 import Reader as Ros1Reader
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Rosbag2Writer

from autosar_cli.config import load_config
from autosar_cli.ingest.pipeline import ingest
from autosar_cli.ingest.sources import LogReadError, container_of, open_source
from autosar_cli.msgs import typestore_for
from autosar_cli.store.drive import Drive

CFG = load_config()
SERIES = ("radar/scanbrick_w43", "imu/imu_cog_a", "gnss/gnss_cog/fix", "gnss/gnss_cog/nmea_fix", "can/ABS_1")


def _copy_mcap(src: Path, dst: Path, **writer_args: object) -> None:
    with open(src, "rb") as f, open(dst, "wb") as out:
        w = Writer(out, **writer_args)  # type: ignore[arg-type]
        w.start(profile="ros2", library="test")
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for schema, channel, msg in make_reader(f).iter_messages(log_time_order=False):
            if schema.id not in schemas:
                schemas[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = w.register_channel(channel.topic, channel.message_encoding, schemas[schema.id])
            w.add_message(channels[channel.id], msg.log_time, msg.data, msg.publish_time)
        w.finish()


def _ros1_mcap(bag: Path, dst: Path) -> None:
    """An MCAP with the ros1 profile (ros1msg schemas, ros1-encoded messages) from a ROS1 bag."""
    with Ros1Reader(bag) as reader, open(dst, "wb") as out:
        w = Writer(out, compression=CompressionType.LZ4)
        w.start(profile="ros1", library="test")
        ids = {}
        for conn in reader.connections:
            name = conn.msgtype.replace("/msg/", "/")
            sid = w.register_schema(name, "ros1msg", conn.msgdef.data.encode())
            ids[conn.id] = w.register_channel(conn.topic, "ros1", sid)
        for conn, t, data in reader.messages():
            w.add_message(ids[conn.id], t, data, t)
        w.finish()


def _rosbag2_mcap(src: Path, dst: Path) -> None:
    """A rosbag2 directory with MCAP storage written by rosbags, from the simulator's MCAP."""
    ts = typestore_for(2)
    with open(src, "rb") as f, Rosbag2Writer(dst, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {}
        for schema, channel, msg in make_reader(f).iter_messages(log_time_order=False):
            if channel.id not in conns:
                conns[channel.id] = w.add_connection(channel.topic, schema.name, typestore=ts)
            w.write(conns[channel.id], msg.log_time, msg.data)


VARIANTS: dict[str, Callable[[Path, Path, Path], None]] = {
    "lz4": lambda m, b, d: _copy_mcap(m, d, compression=CompressionType.LZ4),
    "uncompressed": lambda m, b, d: _copy_mcap(m, d, compression=CompressionType.NONE),
    "unindexed": lambda m, b, d: _copy_mcap(m, d, index_types=IndexType.NONE, use_summary_offsets=False,
                                            use_statistics=False, repeat_channels=False, repeat_schemas=False),
    "unchunked": lambda m, b, d: _copy_mcap(m, d, use_chunking=False),
    "ros1-profile": lambda m, b, d: _ros1_mcap(b, d),
    "rosbag2-mcap": lambda m, b, d: _rosbag2_mcap(m, d),
}


@pytest.fixture(scope="module")
def reference(ci_mcap, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ref") / "drive.h5"
    ingest([ci_mcap.log_path], out, config=CFG)
    return out


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_container_variant_gives_the_same_drive(variant: str, ci_mcap, ci_ros1, reference: Path,
                                                tmp_path: Path) -> None:
    src = tmp_path / ("bag2" if variant == "rosbag2-mcap" else f"{variant}.mcap")
    bag = ci_ros1.log_path  # same seed: the ROS1 log holds the same drive
    VARIANTS[variant](ci_mcap.log_path, bag, src)
    out = tmp_path / "drive.h5"
    report = ingest([src], out, config=CFG)
    assert not [w for w in report.warnings if "damaged" in w or "declares" in w], report.warnings
    with Drive(out) as d, Drive(reference) as ref:
        for path in SERIES:
            got, want = d.series(path), ref.series(path)
            assert set(got) == set(want), path
            for key in want:
                np.testing.assert_array_equal(got[key], want[key], err_msg=f"{variant}: {path}/{key}")
        np.testing.assert_array_equal(d.radar().raw[::97], ref.radar().raw[::97])


@pytest.mark.parametrize(("name", "holds"), [("drive_log", "mcap"), ("drive.bag", "mcap"), ("drive.mcap", "ros1"),
                                             ("drive", "ros1"), ("drive.log", "mcap"), ("drive.txt", "ros1")])
def test_a_log_is_read_by_what_it_holds_not_by_its_name(name: str, holds: str, ci_mcap, ci_ros1, reference: Path,
                                                        tmp_path: Path) -> None:
    """An MCAP saved without its suffix or a bag renamed is opened by its first bytes and gives the same drive, also
    under a name a CAN log or an NMEA capture has (.log, .txt); a file no reader recognises is refused in one line
    naming it."""
    src = tmp_path / name
    shutil.copyfile(ci_mcap.log_path if holds == "mcap" else ci_ros1.log_path, src)
    assert container_of(src) == holds
    out = tmp_path / "drive.h5"
    ingest([src], out, config=CFG)
    with Drive(out) as d, Drive(reference) as ref:
        for path in SERIES:
            got, want = d.series(path), ref.series(path)
            for key in want:
                np.testing.assert_array_equal(got[key], want[key], err_msg=f"{name}: {path}/{key}")
    other = tmp_path / "notes"
    other.write_text("not a log\n")
    with pytest.raises(LogReadError, match=r"notes: unknown log container \(expected .mcap, .bag or a rosbag2"):
        container_of(other)


@pytest.mark.parametrize("name", ["old.bag", "old_log"])
def test_a_bag_of_an_older_format_is_named_as_such(name: str, tmp_path: Path) -> None:
    """A ROS1 bag of format 1.2 (before 2010) is refused in one line that names its format and the conversion,
    not as "version 102" (the bag reader's own words)."""
    bag = tmp_path / name
    bag.write_bytes(b"#ROSBAG V1.2\n" + bytes(64))
    with pytest.raises(LogReadError, match=r"a ROS1 bag of format '1.2'; only format 2.0 is read"):
        list(open_source(bag).messages())
