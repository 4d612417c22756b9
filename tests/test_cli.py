"""The command line: help, JSON output, one-line errors with non-zero exit codes, no tracebacks."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import realdata
from typer.testing import CliRunner

from autosar_cli.cli import app

runner = CliRunner()


@pytest.mark.parametrize("command", [[], ["simulate"], ["info"]])
def test_help(command):
    r = runner.invoke(app, [*command, "--help"])
    assert r.exit_code == 0
    assert "Usage" in r.output


def test_every_commands_flags_read_as_they_are_given_not_as_taking_a_value():
    # typer puts a flag beside "<bool>", which reads as if --overwrite took a value; values show what they take
    from typer.main import get_command

    for name in ["", *get_command(app).commands]:
        r = runner.invoke(app, [*name.split(), "--help"], env={"COLUMNS": "200"}, terminal_width=200)
        assert r.exit_code == 0, r.output
        assert "<bool>" not in r.output, name
    r = runner.invoke(app, ["run", "--help"], env={"COLUMNS": "200"}, terminal_width=200)
    rows = {ln.split()[1]: ln.split()[2] for ln in r.output.splitlines() if ln.startswith("│    --")}
    assert rows["--overwrite"] == "Replace" and rows["--max-time-gap"] == "SECONDS"


def test_an_argument_given_many_times_is_shown_as_what_each_is_not_as_a_python_type():
    from typer.main import get_command

    for name in get_command(app).commands:
        r = runner.invoke(app, [name, "--help"], env={"COLUMNS": "200"}, terminal_width=200)
        assert "list[" not in r.output, name
    r = runner.invoke(app, ["ingest", "--help"], env={"COLUMNS": "200"}, terminal_width=200)
    assert any(ln.split()[1:3] == ["LOG", "<path>..."] for ln in r.output.splitlines() if ln.startswith("│ ")), r.output


@pytest.mark.parametrize(("args", "meant"), [(["run", "x.mcap", "--method", "sarmin"], "'sar-min'"),
                                             (["simulate", "-o", "x.mcap", "-s", "tset2"], "'test2'"),
                                             (["simulate", "-o", "x.mcap", "--dynamics", "ful"], "'full'"),
                                             (["simulate", "-o", "x.mcap", "-s", "zzz"], None)])
def test_a_misspelt_choice_is_refused_with_the_one_it_likely_meant(args, meant, tmp_path):
    r = runner.invoke(app, args, env={"COLUMNS": "300"}, terminal_width=300)
    assert r.exit_code == 2
    text = " ".join(r.output.replace("│", " ").split())
    assert "Value error" not in text and f"{args[-1]!r} is not one of" in text
    assert (f"did you mean {meant}?" in text) if meant else "did you mean" not in text
    assert not (tmp_path / "x.mcap").exists()


def test_the_command_list_wraps_each_summary_at_the_terminal_not_the_docstring():
    r = runner.invoke(app, ["--help"], env={"COLUMNS": "200"}, terminal_width=200)
    assert r.exit_code == 0
    lines = {ln.split()[1]: ln for ln in r.output.splitlines() if ln.startswith("│ ") and len(ln.split()) > 2}
    # evaluate's docstring breaks its first paragraph after "IRW,": at 200 columns the summary is one line
    assert "(position, peak loss, IRW, PSLR, ISLR on fine patches)" in lines["evaluate"]
    assert "dask.distributed cluster; exit code 1" in lines["batch"]


def _commands_and_params(command, path=()):
    yield path, "help", command.help or ""
    for param in command.params:
        yield path, param.name, getattr(param, "help", None) or ""
    for name, sub in getattr(command, "commands", {}).items():
        yield from _commands_and_params(sub, (*path, name))


def test_no_help_text_loses_a_bracketed_word_to_rich_markup():
    # typer renders help through rich: an unescaped "[radar]" is taken for a style tag and vanishes from --help
    from rich.markup import render
    from typer.main import get_command

    lost = [(" ".join(path), name) for path, name, text in _commands_and_params(get_command(app))
            if render(text).plain != text.replace("\\[", "[")]
    assert lost == []
    r = runner.invoke(app, ["focus", "--help"], env={"COLUMNS": "300"}, terminal_width=300)
    assert "config's [radar]" in r.output


def test_focus_help_names_the_config_key_of_each_default_and_its_value():
    """--pixel, --resolution, --channels and --height said 'config default 0.04' without the key: a user wanting
    the value in their config could not find it (the [processing] table, not a [focus] one)."""
    import re

    from autosar_cli.config import load_config

    r = runner.invoke(app, ["focus", "--help"], env={"COLUMNS": "300"}, terminal_width=300)
    text = " ".join(r.output.replace("│", " ").split())
    said = dict(re.findall(r"the config's processing\.(\w+), ([0-9.]+) in the default config", text))
    processing = load_config().processing
    assert said == {"pixel_m": "0.04", "cross_range_resolution_m": "0.04", "channels": "8", "focus_height_m": "0.5"}
    assert {key: float(v) for key, v in said.items()} == {key: float(getattr(processing, key)) for key in said}


def test_a_path_holding_a_bracketed_word_is_printed_as_it_is(tmp_path):
    log = tmp_path / "run[a]" / "gps[raw].log"
    log.parent.mkdir()
    log.symlink_to(realdata("gpsd", "neo-m8n.log"))
    r = runner.invoke(app, ["info", str(log)], env={"COLUMNS": "300"}, terminal_width=300)
    assert r.exit_code == 0, r.output
    assert r.output.replace("\n", "").startswith(f"{log}  NMEA text")  # rich wraps at its console's width


def test_simulate_json_and_info(tmp_path):
    log = tmp_path / "ci.bag"
    r = runner.invoke(app, ["simulate", "-s", "ci", "-f", "ros1", "--seed", "5", "-o", str(log), "--json"])
    assert r.exit_code == 0, r.output
    summary = json.loads(r.stdout)
    assert summary["radar_frames"] == summary["messages"]["/scanbrick/raw_frames"] > 900
    assert (tmp_path / "ci.bag.truth.h5").exists()
    r = runner.invoke(app, ["info", str(log), "--json"])
    assert r.exit_code == 0, r.output
    info = json.loads(r.stdout)
    rates = {s["topic"]: s["rate_hz"] for s in info["streams"]}
    assert rates["/scanbrick/raw_frames"] == pytest.approx(990.0, rel=0.01)
    assert rates["/imu/cog_a"] == pytest.approx(500.0, rel=0.01)
    assert rates["/received_messages"] == pytest.approx(400.0, rel=0.02)  # ROS1 CAN topic, 4 ids x 100 Hz

    # the same output again without --overwrite: refused, one line, exit 1, nothing touched
    before = log.stat().st_mtime_ns
    r = runner.invoke(app, ["simulate", "-s", "ci", "-f", "ros1", "-o", str(log)])
    assert r.exit_code == 1
    assert r.stderr.strip().count("\n") == 0 and "already exists" in r.stderr and "--overwrite" in r.stderr
    assert log.stat().st_mtime_ns == before
    # a .bag named MCAP log: other tools refuse it as a bag, and nothing said so; the name gives the container
    r = runner.invoke(app, ["simulate", "-s", "ci", "-f", "mcap", "-o", str(tmp_path / "mcap.bag")])
    assert r.exit_code == 1 and "mcap.bag: a .bag name for a --format mcap log" in r.stderr
    assert not (tmp_path / "mcap.bag").exists()


def test_errors_are_one_line_without_traceback(tmp_path):
    bad_cfg = tmp_path / "bad.toml"
    bad_cfg.write_text("[vehicle]\nwheelbase_m = -1\n")
    r = runner.invoke(app, ["simulate", "-o", str(tmp_path / "x.mcap"), "--config", str(bad_cfg)])
    assert r.exit_code == 1
    assert "Traceback" not in r.output and str(bad_cfg) in r.stderr
    r = runner.invoke(app, ["info", str(tmp_path / "missing.mcap")])
    assert r.exit_code == 1 and "no such file" in r.stderr
    # a negative seed is named as the option (numpy's "expected non-negative integer" named nothing)
    r = runner.invoke(app, ["simulate", "-o", str(tmp_path / "x.mcap"), "--seed", "-1"])
    assert r.exit_code == 2 and "--seed" in r.output and not (tmp_path / "x.mcap").exists()
    # one past numpy's 64 bits: h5py's "Object dtype dtype('O') has no native HDF5 equivalent" after simulating
    r = runner.invoke(app, ["simulate", "-o", str(tmp_path / "x.mcap"), "--seed", str(2**64)])
    assert r.exit_code == 2 and "--seed" in r.output and not (tmp_path / "x.mcap").exists()
    # a corrupt MCAP: error names the file, no traceback, via the real console script
    corrupt = tmp_path / "corrupt.mcap"
    corrupt.write_bytes(b"\x89MCAP0\r\n" + bytes(range(256)) * 4)
    p = subprocess.run([sys.executable, "-m", "autosar_cli.cli", "info", str(corrupt)], capture_output=True, text=True)
    assert p.returncode == 1
    assert str(corrupt) in p.stderr and "Traceback" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1


def test_console_script_exit_codes_and_complete_products(tmp_path):
    """Through the real entry point (which freezes the collector before the interpreter shuts down): a command
    that succeeds exits 0 with its product complete and readable, a bad option exits 2 (typer's usage error)."""
    log = tmp_path / "ci.mcap"
    p = subprocess.run([sys.executable, "-m", "autosar_cli.cli", "simulate", "--scenario", "ci", "--seed", "2", "-o",
                        str(log), "--json"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    sim = json.loads(p.stdout)
    assert sim["radar_frames"] > 900 and Path(sim["truth"]).is_file()
    r = runner.invoke(app, ["info", str(log), "--json"])
    assert r.exit_code == 0
    counts = {s["topic"]: s["count"] for s in json.loads(r.stdout)["streams"]}
    assert counts == sim["messages"]  # every message the simulator wrote is in the file
    p = subprocess.run([sys.executable, "-m", "autosar_cli.cli", "simulate", "--no-such-option"], capture_output=True,
                       text=True)
    assert p.returncode == 2


def test_navigate_says_which_standstills_it_held_and_which_it_refused() -> None:
    """One console line per standstill SAR-MIN held (its span from the track's start) and per one it refused as a
    creeping turn, with the gyros' rate (run.json's stages.navigate.standstill_ns / standstill_refused)."""
    from autosar_cli.cli import standstill_lines

    t0 = 1_600_000_000_000_000_000
    info = {"standstill_ns": [[t0 + 30_100_000_000, t0 + 35_600_000_000]],
            "standstill_refused": [{"span_ns": [t0 + 61_000_000_000, t0 + 64_250_000_000], "yaw_rate_dps": 0.0978,
                                    "std_dps": 0.002}]}
    assert standstill_lines(info, t0) == [
        "standstill 30.1-35.6 s: yaw rate held at 0",
        "wheels at 0 over 61.0-64.2 s while the gyros turn +0.098 +- 0.002 deg/s: a creeping turn, not held as a "
        "standstill"]
    assert standstill_lines({}, t0) == []


def test_info_on_a_narrow_terminal_gives_each_stream_and_type_whole(ci_mcap):
    """`autosar info` on 80 columns (a pipe's width) cut names short, "scanbrick_msgs/msg/RawFr…", where the table is
    what tells a user the names their config must give: a long name is folded onto a second line, whole."""
    r = runner.invoke(app, ["info", str(ci_mcap.log_path)], env={"COLUMNS": "80"})
    assert r.exit_code == 0, r.output
    assert "\u2026" not in r.stdout
    cells = [[c.strip() for c in line.split("\u2502")[1:3]] for line in r.stdout.splitlines() if "\u2502" in line]
    joined = [("".join(c[0] for c in cells[i:i + 2]), "".join(c[1] for c in cells[i:i + 2])) for i in range(len(cells))]
    assert ("/scanbrick/raw_frames", "scanbrick_msgs/msg/RawFrame") in joined or \
        ("/scanbrick/raw_frames", "scanbrick_msgs/msg/RawFrame") in [tuple(c) for c in cells], r.stdout


def test_info_with_a_config_checks_it_and_says_which_of_its_topics_the_log_holds(ci_mcap, tmp_path):
    """`autosar info LOG --config mine.toml` read no config at all (a missing or misspelt one passed): it is checked
    as every command checks it, and the topics it pins are told apart: those in the log, those not."""
    r = runner.invoke(app, ["info", str(ci_mcap.log_path), "--config", str(tmp_path / "none.toml")])
    assert r.exit_code == 1 and "none.toml: config file not found" in r.stderr
    mine = tmp_path / "mine.toml"
    mine.write_text('base = "default"\n[sensors.gnss_cog]\nvelocity_topic = "/ins_cog/fix_velocityy"\n')
    r = runner.invoke(app, ["info", str(ci_mcap.log_path), "--config", str(mine), "--json"])
    assert r.exit_code == 0, r.output
    pinned = json.loads(r.stdout)["config_topics"]
    assert pinned["not_in_logs"] == [{"topic": "/ins_cog/fix_velocityy", "key": "sensors.gnss_cog.velocity_topic"}]
    assert {"topic": "/imu/cog_a", "key": "sensors.imu_cog_a.topic"} in pinned["in_logs"]
    assert len(pinned["in_logs"]) == 9


@pytest.mark.parametrize("args", [["navigate", ".", "-o", "t.h5"], ["focus", ".", "-t", "t.h5", "-o", "i"],
                                  ["evaluate", ".", "-o", "report"]])
def test_the_current_directory_given_as_a_product_is_named_not_a_python_repr(args, tmp_path, monkeypatch):
    """`autosar navigate .` in a folder holding a log was "error: PosixPath('.') has an empty name" (the truth
    sidecar's name taken of "."): it says what the folder is, and the command that makes what was wanted."""
    (tmp_path / "drive").mkdir()
    (tmp_path / "drive" / "x.mcap").write_bytes(b"\x89MCAP0\r\n")
    monkeypatch.chdir(tmp_path / "drive")
    r = runner.invoke(app, args)
    assert r.exit_code == 1, r.output
    assert "PosixPath" not in r.output and r.stderr.startswith("error: .: a drive log, not "), r.stderr


def test_a_run_directory_or_a_folder_given_as_a_drive_is_said_before_the_output(ci_run, tmp_path, monkeypatch):
    """`autosar navigate RUN_DIR` said "RUN_DIR: a directory, not an HDF5 file" without naming the drive.h5 in it,
    and `autosar navigate .. -o t.h5` "t.h5: lies inside the input ..", where `..` is no drive.h5 at all: the input is
    checked first, and a run directory's own drive.h5 or trajectory.h5 named."""
    r = runner.invoke(app, ["navigate", str(ci_run), "-o", str(tmp_path / "t.h5")], env={"COLUMNS": "300"})
    assert r.exit_code == 1 and r.stderr == f"error: {ci_run}: a run directory, not a drive.h5: give " \
        f"{ci_run / 'drive.h5'}\n", r.output
    r = runner.invoke(app, ["focus", str(ci_run / "drive.h5"), "-t", str(ci_run), "-o", str(tmp_path / "i")],
                      env={"COLUMNS": "300"})
    assert r.exit_code == 1 and r.stderr == f"error: {ci_run}: a run directory, not a trajectory.h5: give " \
        f"{ci_run / 'trajectory.h5'}\n", r.output
    (tmp_path / "sub").mkdir()
    monkeypatch.chdir(tmp_path / "sub")
    r = runner.invoke(app, ["navigate", "..", "-o", "t.h5"])
    assert r.exit_code == 1 and r.stderr == "error: ..: a directory, not a drive.h5\n", r.output
    r = runner.invoke(app, ["navigate", "gone.h5", "-o", "t.h5"])
    assert r.exit_code == 1 and r.stderr == "error: gone.h5: no such file or directory\n", r.output
    assert not list(tmp_path.rglob("t.h5")) and not list(tmp_path.rglob("i.*"))


def test_a_drive_h5_given_without_o_is_said_to_want_it(tmp_path, monkeypatch):
    """`autosar ingest LOG drive.h5` (the -o forgotten) said 'drive.h5: no such file or directory', an input it
    had never been meant as; now it says the output is named with -o, nothing written (not the default drive.h5)."""
    monkeypatch.chdir(tmp_path)
    log = Path(__file__).resolve().parents[1] / "sample_logs" / "ci_seed1.mcap"
    r = runner.invoke(app, ["ingest", str(log), "new.h5"], env={"COLUMNS": "300"})
    assert r.exit_code == 1 and r.stderr == ("error: new.h5: no such file or directory; an output is named with -o "
                                             "(`-o new.h5`), every name without it is an input\n"), r.output
    r = runner.invoke(app, ["ingest", str(log), "new.mcap"], env={"COLUMNS": "300"})  # a log's name: as it was
    assert r.exit_code == 1 and r.stderr == "error: new.mcap: no such file or directory\n", r.output
    assert list(tmp_path.iterdir()) == []


def test_a_missing_h5_log_beside_an_output_given_is_not_said_to_want_o(tmp_path, monkeypatch):
    """The hint that an output is named with -o is for an ingest that was given none: `ingest LOG a.h5 -o b.h5`,
    `run LOG a.h5 -o DIR` and `batch LOG a.h5 -o DIR` were told to give `-o a.h5`, an -o they had given (run's and
    batch's a directory); a missing a.h5 there is what any missing input is."""
    monkeypatch.chdir(tmp_path)
    log = Path(__file__).resolve().parents[1] / "sample_logs" / "ci_seed1.mcap"
    for args in (["ingest", str(log), "a.h5", "-o", "b.h5"], ["run", str(log), "a.h5", "-o", "out"]):
        r = runner.invoke(app, args, env={"COLUMNS": "300"})
        assert r.exit_code == 1 and r.stderr == "error: a.h5: no such file or directory\n", (args, r.output)
    r = runner.invoke(app, ["ingest", str(log), "new.hdf5"], env={"COLUMNS": "300"})  # -o forgotten, .hdf5 too
    assert r.exit_code == 1 and r.stderr == ("error: new.hdf5: no such file or directory; an output is named with -o "
                                             "(`-o new.hdf5`), every name without it is an input\n"), r.output
    assert list(tmp_path.iterdir()) == []


def test_a_log_given_as_the_radar_capture_is_named_for_what_it_is(tmp_path, ci_mcap):
    """`--radar drive.mcap` was read as a capture's parameter file and refused as "error: .: expected adc_data.bin
    or ... found no .bin file", naming the folder "." and not the file: the file is named, with what it is."""
    log, notes, out = tmp_path / "drive.mcap", tmp_path / "notes.log", tmp_path / "d.h5"
    log.write_bytes(b"\x89MCAP0\r\n")
    notes.write_text("not a radar's\n")
    r = runner.invoke(app, ["ingest", str(log), "--radar", str(log), "-o", str(out)])
    assert r.exit_code == 1 and r.stderr.startswith(f"error: {log}: an MCAP log, not a DCA1000 capture: give it as a "
                                                    "LOG, without --radar"), r.stderr
    r = runner.invoke(app, ["ingest", str(ci_mcap.log_path), "--radar", str(notes), "-o", str(out)])
    assert r.exit_code == 1 and r.stderr.startswith(f"error: {notes}: not a DCA1000 capture (taken for its parameter "
                                                    "file, no ADC data lies beside it"), r.stderr
    assert not out.exists()


def test_a_dbc_or_an_unknown_file_given_as_a_log_says_what_is_read(tmp_path):
    """A DBC given as LOG was "unknown log container (expected .mcap, .bag or a rosbag2 directory (or its .db3))",
    which named neither --dbc nor the CAN logs, NMEA and DCA1000 captures that ingest and info read too."""
    dbc, npy = tmp_path / "car.dbc", tmp_path / "frame.npy"
    dbc.write_text('VERSION ""\n')
    npy.write_bytes(b"\x93NUMPY")
    for command in (["info", str(dbc)], ["ingest", str(dbc), "-o", str(tmp_path / "d.h5")]):
        r = runner.invoke(app, command)
        assert r.exit_code == 1 and r.stderr == f"error: {dbc}: a CAN database (DBC), not a log: give it with --dbc\n"
    r = runner.invoke(app, ["info", str(npy)], env={"COLUMNS": "300"}, terminal_width=300)
    assert r.exit_code == 1 and r.stderr.strip().endswith(
        "(or its .db3); nor is it a CAN log (.blf .asc .trc .log .mf4), an NMEA text capture or a DCA1000 capture)")
    assert not (tmp_path / "d.h5").exists()


def test_info_of_a_product_other_than_a_drive_says_what_reads_it_not_how_to_ingest(tmp_path):
    """`autosar info trajectory.h5` said "not a drive.h5 ...; `autosar ingest LOG -o drive.h5` makes one", advice
    for a user who has no log to hand; `info RUN_DIR` said "0 stale partial file(s)" alone. Each names what the file
    is and the info that reads it (--verify, the run's drive.h5)."""
    import h5py

    traj, run = tmp_path / "trajectory.h5", tmp_path / "run"
    with h5py.File(traj, "w") as f:
        f.attrs["format"] = "autosar-trajectory"
    r = runner.invoke(app, ["info", str(traj)])
    assert r.exit_code == 1 and r.stderr == (
        f"error: {traj}: a trajectory.h5 autosar wrote (`autosar focus --trajectory` reads it); `autosar info` lists "
        f"a log's or a drive.h5's streams, `autosar info {traj} --verify` checks this file's checksums\n"), r.stderr
    run.mkdir()
    (run / "run.json").write_text(json.dumps({"format": "autosar-run", "status": "ok"}))
    r = runner.invoke(app, ["info", str(run)])
    # the console folds its lines at a width another test may have set: compared with its folds undone
    assert r.exit_code == 0 and " ".join(r.stdout.split()) == " ".join([
        f"{run}: 0 stale partial file(s)",
        f"{run}: a run directory autosar wrote (`autosar evaluate` reads it); `autosar info {run / 'drive.h5'}` lists "
        f"its drive's streams, `autosar info {run} --verify` checks its products"]), r.stdout


def test_info_of_a_folder_holding_a_capture_alone_says_what_it_holds_and_what_to_give(tmp_path):
    """A drive's folder whose only content is its DCA1000 capture's folder: `info` said "0 stale partial file(s)",
    as of an empty folder, and `ingest` "a directory but not a rosbag2 bag (no metadata.yaml, ...)". It is a drive
    folder of that capture: info summarises the capture and names the log it lacks, and ingest asks for that log."""
    from test_ingest_dca1000 import sdk_cfg

    drive = tmp_path / "drive"
    capture = sdk_cfg(drive / "radar")
    r = runner.invoke(app, ["info", str(drive)], env={"COLUMNS": "300"}, terminal_width=300)
    def bare(text: str) -> str:  # rich wraps a long path anywhere, whatever the width asked for
        return "".join(text.split())

    text = bare(r.stdout)
    assert r.exit_code == 0, r.output
    assert bare(f"{drive} a drive folder: 1 input") in text and bare(f"{capture} TI DCA1000 capture") in text, text
    assert bare(f"{drive}: a DCA1000 capture and no log: the log recorded with it holds the drive's navigation and "
                f"the triggers that time its frames; give it too: `autosar ingest LOG --radar {capture} -o drive.h5`"
                ) in text
    assert "stale partial" not in text
    r = runner.invoke(app, ["ingest", str(drive), "-o", str(tmp_path / "d.h5")])
    assert r.exit_code == 1 and r.stderr.count("\n") == 1 and r.stderr.startswith(
        f"error: {capture}: a DCA1000 capture and no log, so no start time for its frames"), r.stderr
    assert f"give it too (autosar ingest LOG --radar {capture})" in r.stderr and not (tmp_path / "d.h5").exists()
    empty = tmp_path / "empty"
    empty.mkdir()
    r = runner.invoke(app, ["info", str(empty)], env={"COLUMNS": "300"}, terminal_width=300)
    assert r.exit_code == 0 and " ".join(r.stdout.split()) == (
        f"{empty}: holds no log, CAN log, NMEA capture or DCA1000 capture (`autosar info` summarises one of those, a "
        "folder of them or a drive.h5); 0 stale partial file(s)"), r.stdout


@pytest.mark.parametrize(("args", "said"), [
    (["-o", "a.txt"], "a.txt: a .txt name for a --format mcap log (the default but for a .bag); name it a.mcap"),
    (["-o", "drive"], "drive: a name without .mcap for a --format mcap log (the default but for a .bag); name it "
                      "drive.mcap"),
    (["-f", "ros1", "-o", "a.txt"], "a.txt: a .txt name for a --format ros1 log; name it a.bag"),
    (["-f", "dca1000", "-o", "a.txt"], "a.txt: a .txt name for a --format dca1000 log; name it a.mcap"),
    (["-f", "ros2", "-o", "a.mcap"], "a.mcap: a .mcap name for a --format ros2 log, which is a directory (rosbag2); "
                                     "name it a, or give the --format it names")])
def test_simulate_to_a_name_of_another_kind_of_file_is_refused_with_the_name_to_give(args, said, tmp_path,
                                                                                     monkeypatch):
    """`simulate -o a.txt` wrote an MCAP named a.txt (a logging line said "suffix-based readers will miss it"), which
    a second `simulate -o a.txt --overwrite` refused to replace ("a file autosar did not write"); `-f ros2 -o
    a.mcap` made a directory a.mcap holding a.mcap.db3. Each is refused in one line naming the name to give."""
    monkeypatch.chdir(tmp_path)
    r = runner.invoke(app, ["simulate", *args])
    assert r.exit_code == 1 and r.stderr == f"error: {said}\n", r.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("name", "said"), [
    ("t.txt", "t.txt: a .txt name for the drive.h5 ingest writes, an HDF5 file; name it t.h5"),
    ("drive", "drive: a name without .h5 for the drive.h5 ingest writes, an HDF5 file; name it drive.h5"),
    ("drive.v2", "drive.v2: a .v2 name for the drive.h5 ingest writes, an HDF5 file; name it drive.v2.h5")],
    ids=["txt", "no suffix", "dotted"])
def test_a_drive_named_as_another_kind_of_file_is_refused_with_the_name_to_give(
        name: str, said: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`ingest -o t.txt` wrote a drive.h5 named t.txt, which `info` then read as an NMEA capture ("none of its 994
    NMEA 0183 sentences could be read") and `info --verify` refused. It is refused in one line naming the name to
    give, as simulate's wrong names are, nothing written; .H5 is taken."""
    source = str(Path(__file__).resolve().parents[1] / "sample_logs" / "ci_seed1.mcap")
    monkeypatch.chdir(tmp_path)
    r = runner.invoke(app, ["ingest", source, "-o", name])
    assert r.exit_code == 1 and r.stderr == f"error: {said}\n", r.stderr
    assert list(tmp_path.iterdir()) == []
    if name == "t.txt":
        r = runner.invoke(app, ["ingest", source, "-o", "drive.H5"])
        assert r.exit_code == 0 and (tmp_path / "drive.H5").is_file(), r.stderr
        # so is a trajectory (`navigate -o tr.txt` wrote one, which `info` read as an NMEA capture as well)
        r = runner.invoke(app, ["navigate", "drive.H5", "-o", "tr.txt"])
        assert r.exit_code == 1 and r.stderr == ("error: tr.txt: a .txt name for the trajectory.h5 navigate writes, "
                                                 "an HDF5 file; name it tr.h5\n"), r.stderr
        assert sorted(p.name for p in tmp_path.iterdir()) == ["drive.H5"]


def test_usage_lines_show_arguments_as_named_and_a_seeds_range_as_64_bits():
    """typer 0.29 writes a required argument in braces (`Usage: autosar info [OPTIONS] {PATH}`, read as a set or a
    placeholder to fill in with its braces), `--seed` beside `[0<=x<=18446744073709551615]`, and focus's
    `--trajectory` as `<path>` where every other file option says FILE."""
    from typer.main import get_command

    for name in ["", *get_command(app).commands]:
        r = runner.invoke(app, [*name.split(), "--help"], env={"COLUMNS": "200"}, terminal_width=200)
        assert r.exit_code == 0 and "{" not in r.output and "}" not in r.output, (name, r.output)
    usage = {name: next(ln.strip() for ln in runner.invoke(app, [name, "--help"], terminal_width=200).output
                        .splitlines() if "Usage:" in ln) for name in ("info", "run", "ingest", "focus")}
    assert usage == {"info": "Usage: autosar info [OPTIONS] PATH", "run": "Usage: autosar run [OPTIONS] LOG...",
                     "ingest": "Usage: autosar ingest [OPTIONS] [LOG]...",
                     "focus": "Usage: autosar focus [OPTIONS] DRIVE"}
    r = runner.invoke(app, ["info"])
    assert r.exit_code == 2 and r.output.startswith("Usage: autosar info [OPTIONS] PATH\n")
    r = runner.invoke(app, ["simulate", "--help"], env={"COLUMNS": "200"}, terminal_width=200)
    assert "N [0<=x<2^64]" in r.output and "18446744073709551615" not in r.output
    r = runner.invoke(app, ["focus", "--help"], env={"COLUMNS": "200"}, terminal_width=200)
    assert any(ln.split()[2:5] == ["--trajectory", "-t", "FILE"] for ln in r.output.splitlines()), r.output


@pytest.mark.parametrize(("command", "output"), [("run", "a.txt"), ("evaluate", "report.md"), ("compare", "x.json"),
                                                 ("batch", "runs.h5")])
def test_a_directory_output_named_as_a_file_is_refused_with_the_name_to_give(command, output, tmp_path, monkeypatch):
    """`run -o a.txt` made a directory a.txt holding run.json and the products (as did evaluate, compare and batch
    of theirs): each is refused in one line, before any input is read, naming the directory's name to give. A
    directory of that name already there (written before, for --overwrite or --resume) is not refused for its name."""
    monkeypatch.chdir(tmp_path)
    r = runner.invoke(app, [command, "nope.mcap", "-o", output])
    stem = output.rsplit(".", 1)[0]
    assert r.exit_code == 1 and r.stderr == (f"error: {output}: a file's name (.{output.rsplit('.', 1)[1]}) for the "
                                             f"directory `autosar {command}` writes; name it {stem}\n"), r.stderr
    assert list(tmp_path.iterdir()) == []
    (tmp_path / output).mkdir()
    r = runner.invoke(app, [command, "nope.mcap", "-o", output])
    assert r.exit_code == 1 and "a file's name" not in r.stderr and "nope.mcap" in r.stderr, r.stderr


def test_an_empty_mcap_is_named_with_what_it_is(tmp_path):
    """A zero-byte .mcap (a recorder that never wrote, a copy that failed): ingest and run said "error: cannot mmap
    an empty file", naming no file; info "cannot read mcap log: cannot mmap an empty file"."""
    empty = tmp_path / "drive.mcap"
    empty.write_bytes(b"")
    for args in (["ingest", str(empty), "-o", str(tmp_path / "d.h5")], ["run", str(empty), "-o", str(tmp_path / "r")],
                 ["info", str(empty)]):
        r = runner.invoke(app, args)
        assert r.exit_code == 1 and r.stderr == f"error: {empty}: an empty file (0 bytes), no MCAP log in it\n", args
    assert sorted(p.name for p in tmp_path.iterdir()) == ["drive.mcap"]


@pytest.mark.parametrize("name, data, said", [
    ("bus.blf", b"", "an empty file (0 bytes), no BLF log in it: it holds no CAN frames"),
    ("bus.blf", b"LOGG", "truncated BLF log, no frame read: the file ends inside its file header (4 bytes), it holds "
                         "no CAN frames"),
    ("bus.mf4", b"", "an empty file (0 bytes), no MDF4 log in it: it holds no CAN frames")],
    ids=["empty blf", "blf of its magic alone", "empty mf4"])
def test_an_empty_binary_can_log_is_named_with_what_it_is(tmp_path: Path, name: str, data: bytes, said: str) -> None:
    """A zero-byte .blf said "cannot open BLF log: ValueError: cannot mmap an empty file", one of 4 bytes "error:
    unpack requires a buffer of 72 bytes" (python-can's words); a zero-byte .mf4 quoted asammdf's. Given as the log,
    as a --can-log beside one, to run and to info: one line naming the file, exit 1, nothing written."""
    can_log = tmp_path / name
    can_log.write_bytes(data)
    sample = Path(__file__).resolve().parents[1] / "sample_logs" / "ci_seed1.mcap"
    for args in (["ingest", str(can_log), "-o", str(tmp_path / "d.h5")],
                 ["ingest", str(sample), "--can-log", str(can_log), "-o", str(tmp_path / "d.h5")],
                 ["run", str(can_log), "-o", str(tmp_path / "r")], ["info", str(can_log)]):
        r = runner.invoke(app, args)
        assert r.exit_code == 1 and r.stderr == f"error: {can_log}: {said}\n", (args, r.stderr)
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


def test_debug_given_after_the_command_says_where_it_goes():
    """`autosar ingest LOG --debug` said "No such option: --debug (Possible options: --dbc)", pointing at the CAN
    database; --debug is autosar's own option: it says it goes before the command."""
    r = runner.invoke(app, ["run", "x.mcap", "-o", "r", "--debug"], env={"COLUMNS": "200"}, terminal_width=200)
    assert r.exit_code == 2 and "--debug goes before the command: autosar --debug run ..." in r.output, r.output
    assert "--dbc" not in r.output
    r = runner.invoke(app, ["run", "x.mcap", "-o", "r", "--dbug"], env={"COLUMNS": "200"}, terminal_width=200)
    assert r.exit_code == 2 and "No such option: --dbug" in r.output


def test_python_dash_m_autosar_cli_is_the_command() -> None:
    """`python -m autosar_cli` (the package, as a newcomer types it) said "No module named autosar_cli.__main__"."""
    import subprocess
    import sys

    from autosar_cli import __version__

    ok = subprocess.run([sys.executable, "-m", "autosar_cli", "--version"], capture_output=True, text=True, timeout=120)
    assert (ok.returncode, ok.stdout.strip()) == (0, f"autosar {__version__}"), ok.stderr
    bad = subprocess.run([sys.executable, "-m", "autosar_cli", "info", "/no/such/log.mcap"], capture_output=True,
                         text=True, timeout=120)
    assert (bad.returncode, bad.stderr) == (1, "error: /no/such/log.mcap: no such file or directory\n")
