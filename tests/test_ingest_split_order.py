"""A CAN logger's split files of one drive, however they are given, are read in time order; what a stream's
reorder buffer still cannot put back is a warning naming the stream.

The CANedge files of ../shared/realdata/css-electronics (``00000001`` then ``00000002``, 170 s apart, not
overlapping): their 10 Hz ``gnss_imu_0x19`` holds 3528 frames read in time order; read as given, the second file
first, 1669 of the first file's were dropped as late with only a table cell saying so.
"""

from __future__ import annotations

from pathlib import Path

import can
import pytest
from conftest import realdata

from autosar_cli.config import Config, load_config
from autosar_cli.ingest.pipeline import IngestReport, ingest

ROOT = Path(__file__).resolve().parents[1]
FIRST, SECOND = "2F6913DB_00001089_00000001-63BEF5CD.MF4", "2F6913DB_00001089_00000002-63BEFDF9.MF4"
IMU = "can/gnss_imu_0x19"


@pytest.fixture(scope="module")
def config() -> Config:
    return load_config(ROOT / "configs/examples/css_canedge_gnss.toml")


def _ingest(out: Path, config: Config, logs: list[Path] = [], can_logs: list[Path] = []) -> IngestReport:  # noqa: B006
    return ingest(logs, out, config=config, dbc=realdata("css-electronics", "gnss.dbc"), can_logs=can_logs,
                  allow_partial=True)


def _written(report: IngestReport) -> dict[str, int]:
    return {s["path"]: s["written"] for s in report.streams}


def test_split_can_logs_out_of_time_order_lose_nothing(tmp_path: Path, config: Config) -> None:
    """Given second file first, or as a drive folder whose names sort against time, every stream keeps what the
    files in time order give (gnss_imu_0x19: 3528 rows; before, 1859 and no warning), nothing dropped as late,
    and the provenance lists them in the order read."""
    first, second = realdata("css-electronics", FIRST), realdata("css-electronics", SECOND)
    forward = _ingest(tmp_path / "forward.h5", config, can_logs=[first, second])
    assert _written(forward)[IMU] == 3528
    reverse = _ingest(tmp_path / "reverse.h5", config, can_logs=[second, first])
    assert _written(reverse) == _written(forward)
    assert all(s["late_dropped"] == 0 for s in reverse.streams)
    assert [i["path"] for i in reverse.inputs] == [str(first), str(second)]
    assert not any("late" in w for w in reverse.warnings), reverse.warnings
    folder = tmp_path / "drive"
    folder.mkdir()
    (folder / "a.MF4").symlink_to(second)  # a name that sorts before the earlier file's
    (folder / "b.MF4").symlink_to(first)
    from_folder = _ingest(tmp_path / "folder.h5", config, logs=[folder])
    assert _written(from_folder) == _written(forward)
    assert [Path(i["path"]).name for i in from_folder.inputs] == ["b.MF4", "a.MF4"]


def test_late_drops_are_a_warning_naming_the_stream(tmp_path: Path, config: Config) -> None:
    """One candump log holding the second file's frames before the first's: its fast stream's earlier frames come
    after more than the reorder buffer holds and are dropped as late: one warning line names the stream and the
    count, which makes the drive degraded (before: a table cell alone)."""
    frames: list[can.Message] = []
    for name in (SECOND, FIRST):
        with can.MF4Reader(realdata("css-electronics", name)) as reader:
            frames.extend(reader)
    log = tmp_path / "reversed.log"  # python-can's writer would stamp a frame older than the first as the first
    log.write_text("".join(f"({m.timestamp:.6f}) can{m.channel} "
                           f"{m.arbitration_id:0{8 if m.is_extended_id else 3}X}#{m.data.hex().upper()}\n"
                           for m in frames if not (m.is_error_frame or m.is_remote_frame)))
    report = _ingest(tmp_path / "one.h5", config, can_logs=[log])
    late = next(s for s in report.streams if s["path"] == IMU)["late_dropped"]
    assert late == 3528 - _written(report)[IMU] > 1000
    said = [w for w in report.warnings if w.startswith(f"{IMU}: {late} message(s) dropped as late")]
    assert len(said) == 1, report.warnings  # a warning: the drive is degraded
