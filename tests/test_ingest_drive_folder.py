"""A drive folder: one directory holding a drive's inputs of several kinds, read as those inputs given one by one.

The drive is the simulated ci drive (seed 7); the CAN and NMEA captures beside it are written here (known counts).
Before drive folders, such a directory was taken for a rosbag2 bag killed before its metadata.yaml: its MCAP was read
and every other file left unread without a word.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import realdata
from test_ingest_mixed import candump, drive_content, drive_start_s, eps3, gga, work  # noqa: F401  (fixtures)
from typer.testing import CliRunner

from autosar_cli.cli import app
from autosar_cli.config import Config, load_config
from autosar_cli.ingest.inputs import classify_input, drive_folder, sort_inputs
from autosar_cli.ingest.pipeline import ingest
from autosar_cli.sim.simulate import SimulationResult
from autosar_cli.store.drive import Drive

runner = CliRunner()


@pytest.fixture(scope="module")
def cfg() -> Config:
    return load_config()


@pytest.fixture(scope="module")
def folder(ci_mcap: SimulationResult, work: Path, drive_start_s: float) -> Path:  # noqa: F811
    """The ci MCAP (hard-linked: an input is never copied where a link does), a candump CAN log of 20 EPS_3 frames,
    an NMEA capture of 5 fixes, a note, a folder of photos and an earlier run's drive.h5 beside them."""
    d = work / "drive_2026-12-07"
    d.mkdir()
    os.link(ci_mcap.log_path, d / "ros.mcap")
    candump(d / "can.log", [eps3(drive_start_s + 0.2 + 0.01 * i) for i in range(20)])
    (d / "gnss.nmea").write_text("\n".join(gga(drive_start_s + 0.5 + k) for k in range(5)) + "\n")
    (d / "README.txt").write_text("drive of 7 December, test track\n")
    (d / "photos").mkdir()
    (d / "photos" / "mount.jpg").write_bytes(b"\xff\xd8\xff")
    return d


def test_a_drive_folder_reads_as_its_inputs_given_one_by_one(folder: Path, work: Path, cfg: Config) -> None:  # noqa: F811
    found = drive_folder(folder)
    assert found is not None and classify_input(folder) == "drive"
    assert found.inputs == {"log": [folder / "ros.mcap"], "can": [folder / "can.log"],
                            "nmea": [folder / "gnss.nmea"], "radar": []}
    assert found.left_out == [folder / "README.txt", folder / "photos"]
    by_folder = ingest([folder], work / "by_folder.h5", config=cfg)
    by_file = ingest([folder / "ros.mcap"], work / "by_file.h5", config=cfg, can_logs=[folder / "can.log"],
                     nmea_logs=[folder / "gnss.nmea"])
    assert [w for w in by_folder.warnings if w not in by_file.warnings] == [
        f"{folder}: not read, none of them a log, CAN log, NMEA capture or DCA1000 capture: README.txt, photos/"]
    assert [(i["path"], i["kind"]) for i in by_folder.inputs] == [
        (str(folder / "ros.mcap"), "log"), (str(folder / "can.log"), "can"), (str(folder / "gnss.nmea"), "nmea")]
    got = drive_content(work / "by_folder.h5")
    assert got["can/EPS_3/t_ns"][0] == (20,) and got["gnss/gnss/nmea_fix/t_ns"][0] == (5,)
    assert got == drive_content(work / "by_file.h5")  # every dataset, the radar cube's among them


def test_a_folder_inside_a_drive_folder_gives_its_inputs(ci_mcap: SimulationResult, work: Path, cfg: Config,  # noqa: F811
                                                        drive_start_s: float) -> None:  # noqa: F811
    """A CAN logger's files in a folder of their own (split in two), a folder of notes beside them."""
    d = work / "nested_drive"
    (d / "can" / "2F6913DB").mkdir(parents=True)
    (d / "misc").mkdir()
    os.link(ci_mcap.log_path, d / "ros.mcap")
    frames = [eps3(drive_start_s + 0.2 + 0.01 * i) for i in range(20)]
    candump(d / "can" / "2F6913DB" / "00000001.log", frames[:10])
    candump(d / "can" / "2F6913DB" / "00000002.log", frames[10:])
    (d / "misc" / "notes.txt").write_text("tyres changed\n")
    found = drive_folder(d)
    assert found is not None and found.inputs["can"] == [d / "can" / "2F6913DB" / f"0000000{k}.log" for k in (1, 2)]
    assert found.left_out == [d / "misc"] and found.warning() is not None and found.warning().endswith(": misc/")
    ingest([d], work / "nested.h5", config=cfg)
    with Drive(work / "nested.h5") as drive:
        assert len(drive.h5["can/EPS_3/t_ns"]) == 20


def test_a_folder_of_a_bags_storage_files_alone_is_still_that_bag(ci_mcap: SimulationResult, work: Path) -> None:  # noqa: F811
    """ros2 bag record writes metadata.yaml last: a folder of its storage files alone is a bag, a stray note in it
    changes nothing; a bag with its metadata.yaml is a bag whatever lies beside its files."""
    bag = work / "killed_bag"
    bag.mkdir()
    os.link(ci_mcap.log_path, bag / "killed_bag_0.mcap")
    (bag / "notes.txt").write_text("not a GNSS capture\n")
    assert drive_folder(bag) is None and classify_input(bag) == "log"
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (bag / "extra.log").write_text("(1700000000.000000) can0 122#00000011\n")
    assert drive_folder(bag) is None and classify_input(bag) == "log"


def test_a_folder_of_a_simulated_log_and_its_truth_is_that_log_and_finds_its_truth(ci_mcap: SimulationResult,  # noqa: F811
                                                                                    work: Path, cfg: Config) -> None:  # noqa: F811
    """`autosar simulate -o sims/ci.mcap` then `autosar ingest sims/` (as the bundled sample_logs/ is): the folder
    was read as a rosbag2 bag killed before its metadata.yaml, warned of as 'a recording that did not finish' (the
    drive degraded) and its truth sidecar not found (`navigate -m truth`: 'no truth sidecar found')."""
    d = work / "sims"
    d.mkdir()
    os.link(ci_mcap.log_path, d / "ci.mcap")
    os.link(ci_mcap.truth_path, d / "ci.mcap.truth.h5")
    # notes beside it (the bundled folder's README.md made its run degraded: "not read")
    for name in ("README.md", "NOTES.HTML", "setup.pdf"):
        (d / name).write_bytes(b"# notes\n")
    found = drive_folder(d)
    assert found is not None and found.inputs["log"] == [d / "ci.mcap"] and found.left_out == []
    report = ingest([d], work / "sims.h5", config=cfg)
    assert report.warnings == [] and [i["path"] for i in report.inputs] == [str(d / "ci.mcap")]
    (d / "speeds.csv").write_text("t,v\n0,1\n")  # a table may be data: still named
    assert drive_folder(d).warning() == (f"{d}: not read, none of them a log, CAN log, NMEA capture or DCA1000 "
                                         "capture: speeds.csv")
    (d / "speeds.csv").unlink()
    from autosar_cli.nav.navigate import navigate

    truth = navigate(work / "sims.h5", "truth", cfg)  # the sidecar beside the folder's log
    travelled = float(np.linalg.norm(np.diff(truth.rear_axle_enu, axis=0), axis=1).sum())
    assert len(truth.t_ns) == 991 and 2.3 < travelled < 2.5, (len(truth.t_ns), travelled)
    ingest([d / "ci.mcap"], work / "sims_file.h5", config=cfg)
    assert drive_content(work / "sims.h5") == drive_content(work / "sims_file.h5")


def test_a_captures_files_beside_its_navigation_log_are_read_as_that_capture(tmp_path: Path) -> None:
    """A DCA1000 capture's files (data and parameter file) lying in the folder beside the MCAP: the folder was
    taken for the capture alone and its MCAP, the capture's navigation and clock, went unread."""
    r = runner.invoke(app, ["simulate", "-s", "ci", "--seed", "7", "-f", "dca1000", "--dynamics", "kinematic",
                            "-o", str(tmp_path / "sim" / "ci.mcap"), "--json"])
    assert r.exit_code == 0, r.output
    capture = Path(json.loads(r.stdout)["radar_capture"])
    flat = tmp_path / "flat"
    flat.mkdir()
    os.link(tmp_path / "sim" / "ci.mcap", flat / "ci.mcap")
    for f in capture.iterdir():
        os.link(f, flat / f.name)
    (flat / "adc_data_Raw_LogFile.csv").write_text("a DCA1000's own record of the capture\n")
    given = sort_inputs([flat])
    assert given.by_kind == {"log": [flat / "ci.mcap"], "can": [], "nmea": [], "radar": [flat]}
    assert given.warnings == []  # the DCA1000's record of its capture is the capture's, not a stray file
    r = runner.invoke(app, ["ingest", str(flat), "-o", str(tmp_path / "flat.h5"), "--json"])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["ingest", str(tmp_path / "sim" / "ci.mcap"), "--radar", str(capture), "-o",
                            str(tmp_path / "apart.h5"), "--json"])
    assert r.exit_code == 0, r.output
    with Drive(tmp_path / "flat.h5") as a, Drive(tmp_path / "apart.h5") as b:
        assert a.radar().raw.shape == b.radar().raw.shape
        assert np.array_equal(a.radar().t_ns, b.radar().t_ns)


def test_info_of_a_drive_folder_summarises_each_input(folder: Path) -> None:
    r = runner.invoke(app, ["info", str(folder), "--json"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert [(Path(i["path"]).name, i["kind"]) for i in d["drive_folder"]] == [
        ("ros.mcap", "log"), ("can.log", "can"), ("gnss.nmea", "nmea")]
    can = d["drive_folder"][1]
    assert sum(s["count"] for s in can["streams"]) == 20
    assert [Path(p).name for p in d["left_out"]] == ["README.txt", "photos"]
    r = runner.invoke(app, ["info", str(folder)])
    assert r.exit_code == 0 and "a drive folder: 3 inputs" in " ".join(r.stdout.split())
    assert "not read, none of them a log" in " ".join(r.stderr.split())


def test_run_and_batch_take_a_drive_folder_and_mark_what_it_left_alone(folder: Path, work: Path) -> None:  # noqa: F811
    from autosar_cli.batch import drive_names

    out = work / "run_of_folder"
    r = runner.invoke(app, ["run", str(folder), "-o", str(out), "--json"])
    assert r.exit_code == 0, r.output
    manifest = json.loads((out / "run.json").read_text())
    assert manifest["status"] == "degraded"
    assert any("README.txt, photos/" in w for w in manifest["warnings"]), manifest["warnings"]
    assert drive_names([folder, folder.parent / "other" / "ros.mcap"]) == ["drive_2026-12-07", "ros"]
    shutil.rmtree(out)


def test_real_folders_sort_as_what_their_files_hold(tmp_path: Path, cfg: Config) -> None:
    """Two real third-party folders: a CANedge's three MF4 files beside their DBC and licence; gpsd's u-blox NMEA
    capture (opening with # comment lines) beside its expected decode and licence."""
    css = realdata("css-electronics", "gnss.dbc").parent
    found = drive_folder(css)
    assert found is not None and [p.name for p in found.inputs["can"]] == [
        "2F6913DB_00000004_00000001.MF4", "2F6913DB_00001089_00000001-63BEF5CD.MF4",
        "2F6913DB_00001089_00000002-63BEFDF9.MF4"]
    assert found.warning() == (f"{css}: not read, none of them a log, CAN log, NMEA capture or DCA1000 capture: "
                               "LICENSE, gnss.dbc (a CAN database is given with --dbc)")
    gpsd = realdata("gpsd", "neo-m8n.log").parent
    found = drive_folder(gpsd)
    assert found is not None and found.inputs["nmea"] == [gpsd / "neo-m8n.log"]
    assert [p.name for p in found.left_out] == ["COPYING", "neo-m8n.log.chk"]
    ingest([gpsd], tmp_path / "folder.h5", config=cfg, allow_partial=True)
    ingest([], tmp_path / "file.h5", config=cfg, nmea_logs=[gpsd / "neo-m8n.log"], allow_partial=True)
    with Drive(tmp_path / "folder.h5") as a, Drive(tmp_path / "file.h5") as b:
        fixes = [k for k in a.h5["gnss"] if "nmea_fix" in a.h5["gnss"][k]]
        assert fixes and all(np.array_equal(a.h5["gnss"][k]["nmea_fix/latitude_deg"][()],
                                            b.h5["gnss"][k]["nmea_fix/latitude_deg"][()]) for k in fixes)
        assert len(a.h5["gnss"][fixes[0]]["nmea_fix/t_ns"]) > 10


def test_a_pipe_in_a_drive_folder_is_left_out_not_opened(ci_mcap: SimulationResult, tmp_path: Path) -> None:
    """A named pipe among a drive folder's files was opened to be classified, and `info` and `ingest` waited on
    it for ever. It is left out and named, as any file that is no input is."""
    d = tmp_path / "D"
    d.mkdir()
    (d / ci_mcap.log_path.name).symlink_to(ci_mcap.log_path)
    shutil.copy(realdata("gpsd", "neo-m8n.log"), d / "gps.log")
    os.mkfifo(d / "notes")
    import threading

    result: list[object] = []
    walk = threading.Thread(target=lambda: result.append(drive_folder(d)), daemon=True)  # a reader waits for ever
    walk.start()
    walk.join(timeout=20)
    assert result, "the drive folder's walk waited on the pipe"
    found = result[0]
    assert found is not None and found.left_out == [d / "notes"]  # type: ignore[attr-defined]
    assert found.inputs["nmea"] == [d / "gps.log"]


def test_a_drive_folder_of_many_stray_files_names_ten_and_counts_the_rest(folder: Path, tmp_path: Path) -> None:
    """A drive folder holding thousands of stray files (a camera's frames beside the logs) named every one in a
    single warning line; it names the first ten and counts the others."""
    import shutil

    crowded = tmp_path / "crowded"
    shutil.copytree(folder, crowded)
    for k in range(25):
        (crowded / f"frame_{k:05d}.jpg").write_bytes(b"\xff\xd8\xff")
    found = drive_folder(crowded)
    assert found is not None and len(found.left_out) == 27
    names = [str(p.relative_to(crowded)) + ("/" if p.is_dir() else "") for p in found.left_out]
    assert found.warning() == (f"{crowded}: not read, none of them a log, CAN log, NMEA capture or DCA1000 capture: "
                               + ", ".join(names[:10]) + " and 17 more")


def test_a_loggers_mf4_renamed_is_read_as_the_can_log_it_is(tmp_path: Path) -> None:
    """A drive folder finds its inputs by what they hold: a CANedge MDF4 saved as .bag was read as a ROS 1 bag (the
    whole drive refused: "not a ROS1 bag v2.0 (bad magic)"), as .dat said "none of them a log ... " of it."""
    from autosar_cli.ingest.canlog import read_can_log
    from autosar_cli.ingest.inputs import classify_input, drive_folder

    mf4 = realdata("css-electronics", "2F6913DB_00000004_00000001.MF4")
    d = tmp_path / "drive"
    d.mkdir()
    shutil.copy(mf4, d / "x.bag")
    shutil.copy(mf4, d / "part3.dat")
    folder = drive_folder(d)
    assert folder is not None and sorted(p.name for p in folder.inputs["can"]) == ["part3.dat", "x.bag"]
    assert folder.inputs["log"] == [] and folder.left_out == []
    assert classify_input(d / "x.bag") == "can"
    frames = sum(1 for _ in read_can_log(d / "x.bag", lambda said: None))
    assert frames == sum(1 for _ in read_can_log(mf4, lambda said: None)) == 5588


def test_a_ros1_bag_in_a_folder_is_read_not_left_out_of_a_bag_the_folder_is_taken_for(tmp_path: Path) -> None:
    """A folder holding a ROS 1 bag alone was refused as "a directory but not a rosbag2 bag (no metadata.yaml, no
    .db3 or .mcap files)"; one holding a ROS 1 bag beside an MCAP was read as a rosbag2 bag of the MCAP, and the
    ROS 1 bag left unread without a word. A ROS 1 bag, a bag's own folder inside it, is no storage file of a rosbag2
    bag: the folder is a drive folder of them; a bag's storage files alone stay that bag."""
    one, two, storage = tmp_path / "one", tmp_path / "two", tmp_path / "killed"
    for d in (one, two, storage):
        d.mkdir()
    (one / "drive.bag").write_bytes(b"#ROSBAG V2.0\n")
    (two / "radar.bag").write_bytes(b"#ROSBAG V2.0\n")
    (two / "nav.mcap").write_bytes(b"\x89MCAP0\r\n")
    (storage / "killed_0.mcap").write_bytes(b"\x89MCAP0\r\n")
    (storage / "killed_1.mcap").write_bytes(b"\x89MCAP0\r\n")
    found = drive_folder(one)
    assert found is not None and found.inputs["log"] == [one / "drive.bag"] and classify_input(one) == "drive"
    found = drive_folder(two)
    assert found is not None and found.inputs["log"] == [two / "nav.mcap", two / "radar.bag"]
    assert sort_inputs([two]).by_kind["log"] == [two / "nav.mcap", two / "radar.bag"]
    assert drive_folder(storage) is None and classify_input(storage) == "log"
