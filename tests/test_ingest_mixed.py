"""Mixed inputs (a drive log plus standalone CAN and NMEA captures) and plausibility checks at ingest.

The drive is the simulated ci drive (seed 7); the CAN and NMEA captures are written here with python-can
and by hand (NMEA checksums computed independently), so every expected count is known by construction.
"""

from __future__ import annotations

import json
import re
import shutil
from datetime import UTC, datetime
from functools import reduce
from pathlib import Path

import can
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer
from typer.testing import CliRunner

from autosar_cli.candb import giorgio_checksum
from autosar_cli.cli import app
from autosar_cli.config import Config, load_config
from autosar_cli.ingest.inspect import summarize
from autosar_cli.ingest.pipeline import IngestError, IngestReport, ingest
from autosar_cli.sim.simulate import SimulationResult
from autosar_cli.store.drive import Drive

YEAR_S = 365 * 86400
runner = CliRunner()


@pytest.fixture(scope="module")
def cfg() -> Config:
    return load_config()


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("mixed")


@pytest.fixture(scope="module")
def drive_start_s(ci_mcap: SimulationResult) -> float:
    with open(ci_mcap.log_path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None
    return summary.statistics.message_start_time / 1e9


def candump(path: Path, frames: list[can.Message]) -> Path:
    with can.CanutilsLogWriter(path) as w:
        for m in frames:
            w.on_message_received(m)
    return path


def nmea(body: str) -> str:
    """``$body*CS`` with the XOR checksum of ``body``."""
    return f"${body}*{reduce(lambda a, c: a ^ ord(c), body, 0):02X}"


def gga(t: float) -> str:
    hms = datetime.fromtimestamp(t, UTC).strftime("%H%M%S.%f")[:9]
    return nmea(f"GPGGA,{hms},4502.0000,N,00740.0000,E,1,12,0.8,250.0,M,48.0,M,,")


def run(inputs: list[Path], out: Path, cfg: Config, **kw: object) -> IngestReport:
    return ingest(inputs, out, config=cfg, **kw)  # type: ignore[arg-type]


# -------------------------------------------------------------------------------------- time gaps
def test_inputs_a_year_apart_are_refused_unless_shifted_or_allowed(ci_mcap: SimulationResult, work: Path,
                                                                   cfg: Config, drive_start_s: float) -> None:
    later = drive_start_s + YEAR_S
    log = candump(work / "later.log", [can.Message(timestamp=later + 0.01 * i, arbitration_id=0x555,
                                                   is_extended_id=False, data=bytes(8)) for i in range(20)])
    out = work / "gap.h5"
    with pytest.raises(IngestError) as exc:
        run([ci_mcap.log_path], out, cfg, can_logs=[log])
    msg = str(exc.value)
    assert str(log) in msg and "--allow-time-gap" in msg and "--time-offset" in msg
    assert "365.0 days" in msg, msg
    assert f"{log}=-{YEAR_S:.0f}" in msg, msg  # the offset that lines it up, to paste
    assert f"{ci_mcap.log_path}=" not in msg  # a container's stamps cannot be shifted: not proposed
    with pytest.raises(IngestError) as exc:  # an offset given already: the one proposed is the whole
        run([ci_mcap.log_path], out, cfg, can_logs=[log], time_offsets={log: 1000.0})
    assert f"{log}=-{YEAR_S:.0f}" in str(exc.value), str(exc.value)
    assert not out.exists() and not Path(f"{out}.partial").exists()

    allowed = run([ci_mcap.log_path], work / "gap_allowed.h5", cfg, can_logs=[log], allow_time_gap=True)
    assert any(str(log) in w and "--allow-time-gap" in w for w in allowed.warnings), allowed.warnings

    shifted = run([ci_mcap.log_path], work / "gap_shifted.h5", cfg, can_logs=[log],
                  time_offsets={log: -YEAR_S})
    assert not any("apart" in w or "away" in w or "shares no time" in w for w in shifted.warnings), shifted.warnings
    assert shifted.can["unknown_ids"]["0x555"] == 20


def test_a_log_an_hour_off_within_the_gap_allowed_is_warned_of(ci_mcap: SimulationResult, work: Path,
                                                               cfg: Config, drive_start_s: float) -> None:
    """A CAN log whose clock is off by a time zone's hour (an ASC's or BLF's local time) lies within the hour
    allowed of a short drive: nothing in it joins the drive, which ingest said nowhere. It is now warned of, with
    the shift that mends it."""
    log = candump(work / "an_hour_late.log", [can.Message(timestamp=drive_start_s + 3600 + 0.01 * i,
                                                          arbitration_id=0x555, is_extended_id=False, data=bytes(8))
                                              for i in range(20)])
    report = run([ci_mcap.log_path], work / "an_hour_late.h5", cfg, can_logs=[log])
    said = [w for w in report.warnings if "shares no time" in w]
    assert len(said) == 1 and said[0].startswith(f"{log} (") and f"after {ci_mcap.log_path}" in said[0]
    assert "--time-offset" in said[0] and "lies 60.0 min after" in said[0], said[0]


def test_cli_time_gap_options(ci_mcap: SimulationResult, work: Path, drive_start_s: float) -> None:
    log = candump(work / "cli_later.log", [can.Message(timestamp=drive_start_s + 7200 + i, arbitration_id=0x555,
                                                       data=bytes(8), is_extended_id=False) for i in range(3)])
    out = work / "cli_gap.h5"
    r = runner.invoke(app, ["ingest", str(ci_mcap.log_path), "--can-log", str(log), "-o", str(out)])
    assert r.exit_code != 0 and "--allow-time-gap" in r.stderr and "Traceback" not in r.output
    r = runner.invoke(app, ["ingest", str(ci_mcap.log_path), "--can-log", str(log), "-o", str(out),
                            "--max-time-gap", "10800"])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["ingest", str(ci_mcap.log_path), "--can-log", str(log), "-o", str(work / "cli2.h5"),
                            "--time-offset", f"{log}=-7200"])
    assert r.exit_code == 0, r.output


# ------------------------------------------------------------------------------- two recordings
def split_mcap(log: Path, first: Path, second: Path, late_topic: str = "/imu/cog_a", late_s: float = 0.1) -> None:
    """``log``'s messages in two MCAPs, those logged before its middle time and the rest (a recorder's split),
    but for every other message of ``late_topic`` in the ``late_s`` before the middle: in the second, as if they
    had come late."""
    with open(log, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        middle = (summary.statistics.message_start_time + summary.statistics.message_end_time) // 2
        with open(first, "wb") as fa, open(second, "wb") as fb:
            writers = [Writer(fa), Writer(fb)]
            ids: list[dict[int, int]] = []
            for w in writers:
                w.start(profile="ros2", library="test")
                schemas = {k: w.register_schema(v.name, v.encoding, v.data) for k, v in summary.schemas.items()}
                ids.append({k: w.register_channel(c.topic, c.message_encoding, schemas[c.schema_id], c.metadata)
                            for k, c in summary.channels.items()})
            late = 0
            for _, channel, m in reader.iter_messages(log_time_order=True):
                k = int(m.log_time >= middle)
                if channel.topic == late_topic and middle - late_s * 1e9 <= m.log_time < middle:
                    late += 1
                    k = late % 2
                writers[k].add_message(ids[k][channel.id], m.log_time, m.data, m.publish_time, m.sequence)
            for w in writers:
                w.finish()


def test_two_recordings_of_a_stream_are_refused(ci_mcap: SimulationResult, sim_dir: Path, work: Path,
                                                cfg: Config) -> None:
    """Two logs whose rows of one stream interleave would make a drive of two recordings (ci seeds 7 and 8 share
    their clock: their IMUs at 1000 Hz, each one's GNSS where its stamps came first; before, rc 0 and no
    warning): refused in one line naming both logs and the stream. A recording split into two files by log time
    (the second's first messages stamped before the first's last) reads as the whole; the same log given twice is
    refused (its messages were dropped as duplicates, but its CAN frames counted twice in the drive's report)."""
    from conftest import simulated

    other = simulated(sim_dir, "ci", "mcap", 8).log_path
    out = work / "two.h5"
    with pytest.raises(IngestError) as exc:
        run([ci_mcap.log_path, other], out, cfg)
    msg = str(exc.value)
    assert msg.startswith(f"{other}: its ") and f"interleaves with {ci_mcap.log_path}'s over 0.9" in msg, msg
    assert "two recordings of one stream" in msg and not out.exists()
    whole = run([ci_mcap.log_path], work / "whole.h5", cfg)
    split_mcap(ci_mcap.log_path, work / "part0.mcap", work / "part1.mcap")
    parts = run([work / "part0.mcap", work / "part1.mcap"], work / "parts.h5", cfg)
    written = {s["path"]: s["written"] for s in whole.streams}
    assert {s["path"]: s["written"] for s in parts.streams} == written
    # what the check lets through: the late half of 0.1 s of imu_cog_a's 500 Hz put back in order
    assert {s["path"]: s["reordered"] for s in parts.streams if s["reordered"]} == {"imu/imu_cog_a": 25}
    with pytest.raises(IngestError, match="given twice; give each input once"):
        run([ci_mcap.log_path, ci_mcap.log_path], work / "twice.h5", cfg)
    assert not (work / "twice.h5").exists()


# ------------------------------------------------------------------------------------------- NMEA
def test_dateless_nmea_is_dated_by_the_other_streams(ci_mcap: SimulationResult, work: Path, cfg: Config,
                                                     drive_start_s: float) -> None:
    times = [drive_start_s + 0.5 + k for k in range(5)]
    text = work / "gga_only.nmea"
    text.write_text("\n".join(gga(t) for t in times) + "\n")
    out = work / "dateless.h5"
    report = run([ci_mcap.log_path], out, cfg, nmea_logs=[text])
    assert any(str(text) in w and "5 NMEA records dated" in w for w in report.warnings), report.warnings
    with Drive(out) as d:
        t = d.h5["gnss/gga_only/nmea_fix/t_ns"][()]
    want = np.round(np.array(times) * 100).astype(np.int64) * 10_000_000  # GGA keeps the time to 10 ms
    assert np.array_equal(t, want)


def test_nmea_option_on_a_file_without_nmea_is_an_error(ci_mcap: SimulationResult, work: Path,
                                                        cfg: Config) -> None:
    junk = work / "notes.txt"
    junk.write_text("this is a shopping list\nnot a GNSS capture\n")
    with pytest.raises(IngestError, match=re.escape(str(junk)) + ".*no NMEA 0183 sentence"):
        run([ci_mcap.log_path], work / "junk.h5", cfg, nmea_logs=[junk])


@pytest.mark.parametrize("option", ["can_logs", "nmea_logs"])
def test_a_drive_log_given_as_a_can_log_or_nmea_capture_says_how_to_give_it(ci_mcap: SimulationResult, work: Path,
                                                                           cfg: Config, option: str) -> None:
    """Was "unsupported CAN log format '.mcap'" and "no NMEA 0183 sentence in this file"."""
    what = "a CAN log file" if option == "can_logs" else "an NMEA log file"
    flag = "--can-log" if option == "can_logs" else "--nmea"
    with pytest.raises(IngestError) as exc:
        run([], work / "misplaced.h5", cfg, **{option: [ci_mcap.log_path]})
    assert str(exc.value) == f"{ci_mcap.log_path}: an MCAP log, not {what}: give it as a LOG, without {flag}"


def test_zda_sentences_are_counted(work: Path) -> None:
    text = work / "zda.nmea"
    text.write_text("\n".join([nmea("GPZDA,120000.00,27,11,2026,00,00"), gga(1_795_780_800.0),
                               nmea("GPZDA,120001.00,27,11,2026,00,00"), gga(1_795_780_801.0)]) + "\n")
    rows = {s.topic: s.count for s in summarize(text).streams}
    assert rows == {"NmeaFix": 2, "ZDA sentences": 2}


# -------------------------------------------------------------------------------------------- CAN
def test_can_log_with_no_id_in_the_dbc_names_frames_and_suggests_dbc(work: Path, cfg: Config) -> None:
    log = candump(work / "foreign.log", [can.Message(timestamp=1_795_780_800 + 0.01 * i, arbitration_id=0x600 + i % 3,
                                                     is_extended_id=False, data=bytes(8)) for i in range(57)])
    with pytest.raises(IngestError) as exc:
        run([], work / "foreign.h5", cfg, can_logs=[log])
    msg = str(exc.value)
    assert "57 CAN frames" in msg and "--dbc" in msg and "0x600" in msg, msg


def test_can_error_and_remote_frames_listed_and_counted(ci_mcap: SimulationResult, work: Path,
                                                        drive_start_s: float) -> None:
    t = drive_start_s + 1
    frames = [can.Message(timestamp=t + 0.001 * i, arbitration_id=0x123, is_extended_id=False, is_remote_frame=True,
                          dlc=8) for i in range(3)]
    frames += [can.Message(timestamp=t + 0.1 + 0.001 * i, is_error_frame=True, arbitration_id=0, dlc=0)
               for i in range(4)]
    log = candump(work / "errors.log", frames)
    rows = sorted((s.msgtype, s.count, s.topic.split(" ", 1)[1]) for s in summarize(log).streams)
    assert rows == [("CAN error frame", 4, "error frames"), ("CAN remote frame", 3, "0x123 remote")], rows
    r = runner.invoke(app, ["ingest", str(ci_mcap.log_path), "--can-log", str(log), "-o", str(work / "err.h5")])
    assert r.exit_code == 0, r.output
    assert re.search(r"CAN: 399 frames, 392 decoded.*error frames 4.*remote frames 3", r.stdout), r.stdout


def eps3(t: float) -> can.Message:
    """An EPS_3 frame (in the DBC, not in the ci drive) with its FCA Giorgio checksum."""
    body = bytes(4)
    return can.Message(timestamp=t, arbitration_id=0x122, is_extended_id=False,
                       data=body[:3] + bytes([giorgio_checksum(0x122, body)]))


def test_an_input_nothing_of_which_reaches_the_drive_is_named_with_why(ci_mcap: SimulationResult, work: Path,
                                                                       cfg: Config, drive_start_s: float) -> None:
    """An input given beside a drive log that adds nothing to the drive was read without a word: a CAN log whose IDs
    are not in the DBC, of error and remote frames only, empty, or with no frame line python-can reads; a log whose
    sensor messages cannot be decoded; a copy of the drive log (its rows all duplicates)."""
    t = drive_start_s + 0.2
    foreign = candump(work / "foreign_ids.log", [can.Message(timestamp=t + 0.01 * i, arbitration_id=0x555 + i % 2,
                                                             is_extended_id=False, data=bytes(8)) for i in range(20)])
    errors = candump(work / "only_errors.log", [can.Message(timestamp=t + 0.01 * i, is_error_frame=True,
                                                            arbitration_id=0, dlc=0) for i in range(4)])
    (empty := work / "empty.log").write_bytes(b"")
    (no_frame := work / "no_frame.asc").write_text("date Sun Dec 6 10:00:00.000 am 2026\nbase hex  timestamps "
                                                   "absolute\n   0.010000 1  555  Rx   d 2 01 02\n")
    known = candump(work / "eps3.log", [eps3(t + 0.01 * i) for i in range(20)])
    report = run([ci_mcap.log_path], work / "unused.h5", cfg, can_logs=[foreign, errors, empty, no_frame, known])
    said = {w.split(": nothing of it is in the drive: ")[0]: w.split(": nothing of it is in the drive: ")[1]
            for w in report.warnings if ": nothing of it is in the drive: " in w}
    assert said == {
        str(foreign): f"none of its 20 CAN frames decoded: 20 with an ID not in the DBC {cfg.dbc_path} (0x555, 0x556)",
        str(errors): "none of its 4 CAN frames decoded: 4 error frames",
        str(empty): "the file is empty",
        str(no_frame): "no CAN frame read from it (a file of its kind, but no frame python-can reads)",
    }, report.warnings
    with Drive(work / "unused.h5") as d:
        assert len(d.h5["can/EPS_3/t_ns"]) == 20  # the log whose frames the DBC decodes: no warning
    rows = {i["path"]: i["rows_in_drive"] for i in report.inputs}  # the report and drive.h5 say what each gave
    assert rows == {str(ci_mcap.log_path): sum(s["written"] for s in report.streams) - 20, str(foreign): 0,
                    str(errors): 0, str(empty): 0, str(no_frame): 0, str(known): 20}
    garbled = work / "garbled_fix.mcap"  # a receiver's fixes, every payload cut to 3 bytes
    with open(ci_mcap.log_path, "rb") as f, open(garbled, "wb") as g:

        w = Writer(g)
        w.start()
        channel = None
        for schema, ch, m in make_reader(f).iter_messages(topics=["/ins_cog/fix"]):
            if channel is None:
                channel = w.register_channel("/other/fix", ch.message_encoding,
                                             w.register_schema(schema.name, schema.encoding, schema.data))
            w.add_message(channel, m.log_time, m.data[:3], m.publish_time)
        w.finish()
    report = run([ci_mcap.log_path, garbled], work / "garbled.h5", cfg)
    said = [w for w in report.warnings if "nothing of it is in the drive" in w]
    assert said == [f"{garbled}: nothing of it is in the drive: 10 messages of its sensor streams could not be decoded "
                    "(the warning of undecodable messages names them)"], report.warnings
    copy = work / "copy_of_ci.mcap"  # the same recording under another name: its rows all duplicates
    shutil.copy(ci_mcap.log_path, copy)
    report = run([ci_mcap.log_path, copy], work / "copy.h5", cfg)
    said = [w for w in report.warnings if "nothing of it is in the drive" in w]
    assert len(said) == 1 and said[0].startswith(f"{copy}: nothing of it is in the drive: every row of it dropped: ")
    assert "the same as rows read before (duplicates)" in said[0], said


def test_run_reads_can_logs_beside_the_drive_log_with_ingests_options(ci_mcap: SimulationResult, work: Path,
                                                                      drive_start_s: float) -> None:
    """`autosar run` said it took CAN and NMEA logs "as for autosar ingest", then refused one as an unknown log
    container; and its errors named --time-offset, which it lacked."""
    log = candump(work / "eps3_late.log", [eps3(drive_start_s + 7200.2 + 0.01 * i) for i in range(20)])
    out = work / "run_with_can_log"
    r = runner.invoke(app, ["run", str(ci_mcap.log_path), str(log), "-o", str(out)])
    assert r.exit_code == 1 and "--time-offset" in r.stderr and "Traceback" not in r.output, r.output
    r = runner.invoke(app, ["run", str(ci_mcap.log_path), str(log), "-o", str(out), "--time-offset", f"{log}=-7200",
                            "--dbc", "configs/autosar_giulia.dbc", "--json"])
    assert r.exit_code == 0, r.output
    with Drive(out / "drive.h5") as d:
        t = d.h5["can/EPS_3/t_ns"][()]
    assert len(t) == 20 and abs(t[0] / 1e9 - (drive_start_s + 0.2)) < 1e-3
    manifest = json.loads(r.stdout)
    assert manifest["stages"]["ingest"]["warnings"] == []
    assert manifest["ingest_options"]["time_offsets"] == {str(log): -7200.0}  # run.json keeps how it read them
    assert manifest["ingest_options"]["dbc"] == "configs/autosar_giulia.dbc"


def test_compare_reads_can_logs_and_the_ingest_options_as_run_does(ci_mcap: SimulationResult, work: Path,
                                                                   drive_start_s: float) -> None:
    """`autosar compare` said it took logs "as for `autosar run`" and refused a CAN log as an unknown container; it
    had no --time-offset, --dbc or --radar."""
    log = candump(work / "eps3_late_compare.log", [eps3(drive_start_s + 7200.2 + 0.01 * i) for i in range(20)])
    out = work / "compare_with_can_log"
    r = runner.invoke(app, ["compare", str(ci_mcap.log_path), str(log), "-o", str(out), "--methods", "none",
                            "--time-offset", f"{log}=-7200", "--dbc", "configs/autosar_giulia.dbc"])
    assert r.exit_code == 0, r.output
    with Drive(out / "drive.h5") as d:
        t = d.h5["can/EPS_3/t_ns"][()]
    assert len(t) == 20 and abs(t[0] / 1e9 - (drive_start_s + 0.2)) < 1e-3


def drive_content(path: Path) -> dict[str, tuple[tuple[int, ...], str]]:
    """Every dataset of a drive.h5 but its provenance (which names the command): shape and a digest of its values."""
    import hashlib

    import h5py

    found: dict[str, tuple[tuple[int, ...], str]] = {}

    def visit(name: str, item: object) -> None:
        if isinstance(item, h5py.Dataset) and not name.startswith("provenance"):
            found[name] = (item.shape, hashlib.sha256(np.ascontiguousarray(item[()]).tobytes()).hexdigest())

    with h5py.File(path, "r") as f:
        f.visititems(visit)
    return found


def test_run_takes_can_log_and_nmea_options_as_ingest_does(ci_mcap: SimulationResult, work: Path,
                                                          drive_start_s: float) -> None:
    """`autosar run` took CAN logs and NMEA captures only among its LOGs (told by their content); ingest and batch
    had --can-log and --nmea. Given either way, the drive is the same, and run.json lists them as inputs."""
    log = candump(work / "eps3_for_options.log", [eps3(drive_start_s + 0.2 + 0.01 * i) for i in range(20)])
    text = work / "gga_for_options.nmea"
    text.write_text("\n".join(gga(drive_start_s + 0.5 + k) for k in range(5)) + "\n")
    by_option, by_content = work / "run_can_log_option", work / "run_can_log_positional"
    r = runner.invoke(app, ["run", str(ci_mcap.log_path), "--can-log", str(log), "--nmea", str(text),
                            "-o", str(by_option), "--json"])
    assert r.exit_code == 0, r.output
    manifest = json.loads(r.stdout)
    assert [i["path"] for i in manifest["inputs"]] == [str(ci_mcap.log_path), str(log), str(text)]
    r = runner.invoke(app, ["run", str(ci_mcap.log_path), str(log), str(text), "-o", str(by_content)])
    assert r.exit_code == 0, r.output
    got = drive_content(by_option / "drive.h5")
    assert got["can/EPS_3/t_ns"][0] == (20,) and got["gnss/gga_for_options/nmea_fix/t_ns"][0] == (5,), got.keys()
    assert got == drive_content(by_content / "drive.h5")


@pytest.mark.parametrize("command", ["run", "compare"])
def test_run_and_compare_refuse_a_drive_log_given_as_a_can_log(ci_mcap: SimulationResult, work: Path,
                                                               command: str) -> None:
    """--can-log of run and compare reads the file as a CAN log: an MCAP given so is refused with ingest's error. A
    file given with --nmea is an input, never the output."""
    out = work / f"{command}_mcap_as_can_log"
    r = runner.invoke(app, [command, str(ci_mcap.log_path), "--can-log", str(ci_mcap.log_path), "-o", str(out)])
    assert r.exit_code == 1 and "Traceback" not in r.output, r.output
    assert r.stderr.strip().splitlines() == [f"error: {ci_mcap.log_path}: an MCAP log, not a CAN log file: give it "
                                             "as a LOG, without --can-log"], r.stderr
    assert not out.exists()
    text = work / f"{command}_gga_as_output.nmea"
    text.write_text(gga(1_795_780_800.0) + "\n")
    r = runner.invoke(app, [command, str(ci_mcap.log_path), "--nmea", str(text), "-o", str(text)])
    assert r.exit_code == 1 and f"{text}: is an input of this command" in r.stderr, r.output
    assert text.read_text() == gga(1_795_780_800.0) + "\n"


@pytest.mark.parametrize("command", ["run", "compare"])
def test_run_and_compare_never_write_over_their_config(ci_mcap: SimulationResult, tmp_path: Path,
                                                       command: str) -> None:
    """The config a command reads is an input: `compare` did not count it, and `-o` naming it replaced it."""
    config = tmp_path / "mine.toml"
    config.write_text('base = "default"\n')
    r = runner.invoke(app, [command, str(ci_mcap.log_path), "--config", str(config), "-o", str(config),
                            "--overwrite"])
    assert r.exit_code == 1 and f"{config}: is an input of this command" in r.stderr, r.output
    assert config.read_text() == 'base = "default"\n'


def test_a_run_of_a_log_without_radar_names_the_ingest_that_writes_it(ci_mcap: SimulationResult, work: Path) -> None:
    """`autosar run` and `compare` have no --allow-partial (they focus the radar): their error said "use
    --allow-partial", and left an empty output directory."""
    log = work / "no_radar.mcap"
    with open(ci_mcap.log_path, "rb") as f, open(log, "wb") as g:
        w = Writer(g)
        w.start()
        ids: dict[int, int] = {}
        for schema, channel, m in make_reader(f).iter_messages():
            if schema is None or schema.name.endswith("RawFrame"):
                continue
            if channel.id not in ids:
                ids[channel.id] = w.register_channel(channel.topic, channel.message_encoding,
                                                     w.register_schema(schema.name, schema.encoding, schema.data))
            w.add_message(ids[channel.id], m.log_time, m.data, m.publish_time)
        w.finish()
    for command, what in (("run", "a run"), ("compare", "a comparison")):
        out = work / f"no_radar_{command}"
        r = runner.invoke(app, [command, str(log), "-o", str(out)])
        assert r.exit_code == 1 and "Traceback" not in r.output, r.output
        assert f"{log}: no radar stream ({what} needs radar and navigation; `autosar ingest --allow-partial` " \
            in r.stderr, r.stderr
        assert not out.exists()


# ----------------------------------------------------------------------------------- plausibility
def uncompressed_ros1(src: Path, dst: Path) -> Path:
    """The ROS1 bag ``src`` rewritten without chunk compression, so stored payload bytes can be flipped."""
    from rosbags.rosbag1 import Reader, Writer

    with Reader(src) as reader, Writer(dst) as writer:
        conns = {c.id: writer.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest)
                 for c in reader.connections}
        for c, t, data in reader.messages():
            writer.write(conns[c.id], t, data)
    return dst


def test_flipped_bytes_in_ros1_are_flagged(ci_ros1: SimulationResult, work: Path, cfg: Config) -> None:
    from rosbags.rosbag1 import Reader

    bag = uncompressed_ros1(ci_ros1.log_path, work / "plain.bag")
    with Reader(bag) as reader:
        msgs = [(c.topic, bytes(d)) for c, _, d in reader.messages()]
    radar = [d for tpc, d in msgs if tpc == "/scanbrick/raw_frames"]
    data = bytearray(bag.read_bytes())
    frame = radar[500]
    at = data.find(frame)
    assert at > 0 and data.find(frame, at + 1) < 0
    sample = at + len(frame) - 2 * 6000 + 1  # the high byte of one int16 sample, late in the frame
    data[sample] ^= 0x0C  # +-3072 counts: within the stream's peaks (~1700), far above this frame's crest
    (work / "flipped.bag").write_bytes(bytes(data))
    report = run([work / "flipped.bag"], work / "flipped.h5", cfg)
    with Drive(work / "flipped.h5") as d:
        idx = d.radar().frame_index
    hits = [w for w in report.warnings if "radar frames" in w]
    assert len(hits) == 1 and f"frame indices {idx[500]}" in hits[0] and hits[0].startswith("radar/"), hits
    clean = run([bag], work / "plain.h5", cfg)
    assert not any("radar frames" in w for w in clean.warnings), clean.warnings


def test_can_values_outside_the_dbc_range_are_counted(ci_mcap: SimulationResult, work: Path, cfg: Config) -> None:
    dbc_text = cfg.dbc_path.read_text()
    dbc = work / "ranged.dbc"  # a physical range for one signal, which the ci drive (2.2-2.5 m/s) crosses
    dbc.write_text(dbc_text.replace("SG_ WHEEL_SPEED_FL : 7|13@0+ (0.017,0) [0|8191]",
                                    "SG_ WHEEL_SPEED_FL : 7|13@0+ (0.017,0) [0|2.3]"))
    assert dbc.read_text() != dbc_text
    report = run([ci_mcap.log_path], work / "ranged.h5", cfg, dbc=dbc)
    with Drive(work / "ranged.h5") as d:
        fl = d.h5["can/ABS_1/WHEEL_SPEED_FL"][()]
    n = int(np.count_nonzero(fl > 2.3))
    assert 0 < n < len(fl)
    assert report.can["out_of_range"] == {"ABS_1.WHEEL_SPEED_FL": n}
    assert any(f"ABS_1.WHEEL_SPEED_FL ×{n}" in w for w in report.warnings), report.warnings


def test_plausibility_is_silent_on_an_intact_drive(ci_mcap: SimulationResult, work: Path, cfg: Config) -> None:
    report = run([ci_mcap.log_path], work / "intact.h5", cfg)
    assert report.warnings == [] and report.can["out_of_range"] == {}
    assert "implausible_frames" not in {k for s in report.streams for k in s}


