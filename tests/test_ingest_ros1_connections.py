"""A ROS1 bag's connection records, written twice (in the chunk beside the first message, and in the index
section rosbags reads), read from the copy that bears itself out where a damaged byte makes them disagree
(``autosar_cli/ingest/rosbag_source.py``: ``reconcile``).

robot_localization's test1.bag (../shared/realdata): 989 NavSatFix on /fix, its chunks lz4. One byte of the index
copy of /fix's record changed in a copy under tmp_path: its type's name (``NavSatFiy``: before, every fix skipped
as "not a sensor stream" in an info line), its md5sum, or its message definition (a field named ``matitude``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import realdata

from autosar_cli.config import Config, load_config
from autosar_cli.ingest.pipeline import IngestReport, ingest
from autosar_cli.ingest.ros1_chunks import Ros1Connection
from autosar_cli.ingest.rosbag_source import near_known_type, reconcile
from autosar_cli.store.drive import Drive

ROOT = Path(__file__).resolve().parents[1]
FIX = "gnss/gnss_cog/fix"
NAV_SAT_FIX_MD5 = "2d3a8cd499b9b4a0249fb98fd05cfa48"


@pytest.fixture(scope="module")
def config() -> Config:
    return load_config(ROOT / "configs/examples/husky_test1.toml")


@pytest.fixture(scope="module")
def undamaged(tmp_path_factory: pytest.TempPathFactory, config: Config) -> tuple[IngestReport, dict[str, np.ndarray]]:
    out = tmp_path_factory.mktemp("ros1") / "undamaged.h5"
    report = ingest([realdata("robot_localization", "test1.bag")], out, config=config, allow_partial=True)
    with Drive(out) as drive:
        return report, drive.series(FIX)


def _index_copy_damaged(bag: Path, out: Path, what: str) -> Path:
    """A copy of ``bag`` with one byte of the index copy of /fix's connection record changed (``what``)."""
    data = bytearray(bag.read_bytes())
    at = data.rindex(b"type=sensor_msgs/NavSatFix")  # the index copy: the chunk's is inside lz4 data
    record = data.rindex(b"op=\x07", 0, at)
    if what == "type":
        data[at + 25] = ord("y")  # NavSatFix -> NavSatFiy
    elif what == "md5sum":
        md5 = data.index(b"md5sum=", record) + len(b"md5sum=")
        data[md5] = ord("3") if data[md5] != ord("3") else ord("4")
    else:
        field = data.index(b"float64 latitude", record) + len(b"float64 ")
        data[field] = ord("m")
    out.write_bytes(bytes(data))
    return out


@pytest.mark.parametrize("what", ["type", "md5sum", "message definition"])
def test_a_damaged_index_copy_of_a_connection_gives_way_to_the_chunks(
        what: str, tmp_path: Path, config: Config, undamaged: tuple[IngestReport, dict[str, np.ndarray]]) -> None:
    """Every fix read as from the undamaged bag (989), the chunk's copy read, and one warning naming the
    connection, what each copy says and that the index's is damaged."""
    bag = _index_copy_damaged(realdata("robot_localization", "test1.bag"), tmp_path / "conn.bag", what)
    report = ingest([bag], tmp_path / "drive.h5", config=config, allow_partial=True)
    assert not [s for s in report.skipped_channels if s["topic"] == "/fix"], report.skipped_channels
    with Drive(tmp_path / "drive.h5") as drive:
        got = drive.series(FIX)
    want = undamaged[1]
    assert len(got["t_ns"]) == len(want["t_ns"]) == 989
    for column in ("t_ns", "latitude_deg", "longitude_deg", "altitude_m", "status"):
        np.testing.assert_array_equal(got[column], want[column])
    said = [w for w in report.warnings if "connection 2 (/fix) disagrees with itself" in w]
    assert len(said) == 1, report.warnings
    assert f"its index copy says {what}" in said[0] and "the chunk's read" in said[0], said[0]
    assert said[0].endswith("the index's damaged") and str(bag) in said[0]
    assert len(report.warnings) == len(undamaged[0].warnings) + 1


def _fix(msgtype: str = "sensor_msgs/NavSatFix", md5sum: str = NAV_SAT_FIX_MD5, msgdef: str | None = None
         ) -> Ros1Connection:
    from autosar_cli.msgs import typestore_for

    text = typestore_for(1).generate_msgdef("sensor_msgs/msg/NavSatFix", ros_version=1)[0] if msgdef is None \
        else msgdef
    return Ros1Connection(2, "/fix", msgtype, text, md5sum)


def test_a_damaged_chunk_copy_gives_way_to_the_index_and_a_near_miss_type_is_read_as_the_known_one() -> None:
    """Where the chunk's copy is the damaged one (a bag of uncompressed chunks), the index's is read; copies that
    agree say nothing. A type's name no one knows, a letter or two from a known type's whose md5sum it carries (both
    copies damaged, or a bag read without its index), is read as that type with a warning; a name further off, or
    another md5sum, stays as it is."""
    good, bad = _fix(), _fix("sensor_msgs/NavSatFiy")
    chosen, said = reconcile(good, bad, 4117, "x.bag")
    assert chosen == good and said is not None and "the index's read" in said and "the chunk's damaged" in said
    assert reconcile(good, good, 4117, "x.bag") == (good, None)
    assert reconcile(good, None, 0, "x.bag") == (good, None)
    named, renamed = near_known_type(bad, "x.bag")
    assert named.msgtype == "sensor_msgs/msg/NavSatFix" and renamed is not None
    assert "names type sensor_msgs/NavSatFiy, which is none known" in renamed and "by 1 letter:" in renamed
    for c in (good, _fix("my_msgs/GpsFix"), _fix("sensor_msgs/NavSatFiy", "0" * 32)):
        assert near_known_type(c, "x.bag") == (c, None)
