"""Inputs are never harmed: an output is never an input nor inside one, --overwrite replaces only what autosar
made, and bad output paths give one line."""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import sys
from pathlib import Path
from typing import Any

import h5py
import pytest
from conftest import ci_run_console
from typer.testing import CliRunner

from autosar_cli.cli import app

runner = CliRunner()


def _console_script() -> str | None:
    """The `autosar` console script of this interpreter's environment (make test runs .venv/bin/python without
    .venv/bin on PATH), else the one on PATH."""
    beside = Path(sys.executable).parent / "autosar"
    return str(beside) if beside.exists() else shutil.which("autosar")


def _as_from_a_terminal() -> None:
    """A child's SIGINT as a terminal's Ctrl-C finds it: a runner started in the background (``cmd &`` in a
    script) hands its children SIGINT ignored, and a program started so rightly keeps it ignored."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.fixture
def sigint_reaches_python():
    """SIGINT as Python sets it up in a process started from a terminal, for the tests that raise one in this
    process: a runner started in the background (``cmd &`` in a script, a CI job's step) hands pytest SIGINT
    ignored, and there the signal never reached the code under test (4 tests failed so)."""
    import signal

    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


def _one_line_error(r, *fragments: str) -> None:
    assert r.exit_code == 1, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:"), r.output
    assert "Traceback" not in r.output
    for fragment in fragments:
        assert fragment in r.output.replace("\n", ""), r.output


def _foreign(path: Path, content: bytes = b"not autosar's\n") -> bytes:
    path.write_bytes(content)
    return content


def test_ingest_output_same_as_its_log_is_refused(tmp_path: Path) -> None:
    log = tmp_path / "s.mcap"
    content = _foreign(log, b"\x89MCAP0\r\n" + bytes(range(256)))
    r = runner.invoke(app, ["ingest", str(log), "-o", str(log), "--overwrite"])
    _one_line_error(r, "is an input")
    assert log.read_bytes() == content


def test_navigate_output_same_as_its_drive_is_refused(tmp_path: Path) -> None:
    drive = tmp_path / "y.h5"
    with h5py.File(drive, "w") as f:
        f.attrs["format"] = "autosar-drive"
    before = drive.read_bytes()
    r = runner.invoke(app, ["navigate", str(drive), "-o", str(drive), "--overwrite"])
    _one_line_error(r, "is an input")
    assert drive.read_bytes() == before


def test_focus_output_base_whose_h5_is_the_drive_is_refused(tmp_path: Path) -> None:
    drive, traj = tmp_path / "x.h5", tmp_path / "t.h5"
    for path, fmt in ((drive, "autosar-drive"), (traj, "autosar-trajectory")):
        with h5py.File(path, "w") as f:
            f.attrs["format"] = fmt
    before = drive.read_bytes()
    r = runner.invoke(app, ["focus", str(drive), "-t", str(traj), "-o", str(tmp_path / "x"), "--overwrite"])
    _one_line_error(r, "x.h5", "is an input")
    assert drive.read_bytes() == before


def test_overwrite_never_replaces_a_directory_or_a_foreign_file(tmp_path: Path) -> None:
    log = tmp_path / "log.mcap"
    _foreign(log)
    tree = tmp_path / "somedir"
    (tree / "sub").mkdir(parents=True)
    keep = _foreign(tree / "sub" / "precious.txt")
    r = runner.invoke(app, ["ingest", str(log), "-o", str(tree), "--overwrite"])
    _one_line_error(r, str(tree), "is a directory")
    assert (tree / "sub" / "precious.txt").read_bytes() == keep
    (tree / "run.json").write_text('{"format": "autosar-run"}')  # even a run directory autosar made
    r = runner.invoke(app, ["ingest", str(log), "-o", str(tree), "--overwrite"])
    _one_line_error(r, str(tree), "is a directory")
    assert (tree / "sub" / "precious.txt").read_bytes() == keep

    foreign = tmp_path / "notes.h5"
    keep = _foreign(foreign)
    r = runner.invoke(app, ["ingest", str(log), "-o", str(foreign), "--overwrite"])
    _one_line_error(r, str(foreign), "autosar did not write")
    assert foreign.read_bytes() == keep


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes are POSIX")
def test_an_input_that_is_a_pipe_a_link_loop_or_a_directory_is_one_line(tmp_path: Path) -> None:
    """A named pipe given as a log blocked every command on a writer that never came (killed by a timeout, no
    word); a symbolic link loop was Python's "Symlink loop from ..."; a directory given as an NMEA log, its
    "[Errno 21]". Each is now one line naming the input, before anything is read or written."""
    import threading

    fifo = tmp_path / "log.mcap"
    os.mkfifo(fifo)
    done = threading.Event()

    def end_each_read() -> None:  # a reader that opens the pipe (the check gone) reads its end, not forever
        while not done.wait(0.01):
            with contextlib.suppress(OSError):  # ENXIO: no reader has it open
                os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))

    threading.Thread(target=end_each_read, daemon=True).start()
    (tmp_path / "loop_a").symlink_to(tmp_path / "loop_b")
    (tmp_path / "loop_b").symlink_to(tmp_path / "loop_a")
    out = tmp_path / "out"
    try:
        for args in (["info", str(fifo)], ["ingest", str(fifo), "-o", str(out / "d.h5")],
                     ["navigate", str(fifo), "-o", str(out / "t.h5")], ["run", str(fifo), "-o", str(out)],
                     ["compare", str(fifo), "-o", str(out)], ["simulate", "-o", str(out / "s.mcap"), "--config",
                                                               str(fifo)]):
            _one_line_error(runner.invoke(app, args), str(fifo), "not a regular file (a pipe, socket or device)")
    finally:
        done.set()
    loop = tmp_path / "loop_a"
    for args in (["info", str(loop)], ["ingest", str(loop), "-o", str(out / "d.h5")]):
        r = runner.invoke(app, args)
        assert r.exit_code == 1 and r.stderr.startswith(f"error: {loop}: ") and "loop" in r.stderr.lower(), r.stderr
    folder = tmp_path / "nmea"
    folder.mkdir()
    _one_line_error(runner.invoke(app, ["ingest", "--nmea", str(folder), "-o", str(out / "d.h5")]), str(folder),
                    "a directory, not an NMEA log file")
    assert not out.exists()


def test_a_log_and_a_product_given_for_each_other_say_what_they_are(ci_mcap, ci_run: Path, tmp_path: Path) -> None:
    """A drive.h5 given to run was "unknown log container (expected .mcap, ...)", a log given to navigate "not an
    HDF5 file (Unable to synchronously open file ...)": each says what it is and the command that makes what is
    wanted, before anything is written."""
    log, out = ci_mcap.log_path, tmp_path / "out"
    for args, product in ((["run", str(ci_run / "drive.h5"), "-o", str(out)], "a drive.h5 autosar wrote (`autosar "
                           "navigate` and `autosar focus` read it), not a log"),
                          (["ingest", str(ci_run / "trajectory.h5"), "-o", str(out / "d.h5")], "a trajectory.h5 "
                           "autosar wrote (`autosar focus --trajectory` reads it), not a log"),
                          (["compare", str(ci_run / "image.h5"), "-o", str(out)], "an image.h5 autosar wrote")):
        _one_line_error(runner.invoke(app, args), f"error: {args[1]}: {product}")
    for args, wanted in ((["navigate", str(log), "-o", str(out / "t.h5")],
                          f"a drive log, not a drive.h5: `autosar ingest {log} -o drive.h5` makes one"),
                         (["focus", str(ci_run / "drive.h5"), "-t", str(log), "-o", str(out / "i")],
                          f"a drive log, not a trajectory.h5: `autosar run {log} -o DIR` makes one"),
                         (["evaluate", str(log), "-o", str(out)],
                          f"a drive log, not a run directory or image.h5: `autosar run {log} -o DIR`")):
        _one_line_error(runner.invoke(app, args), f"error: {log}: {wanted}")
    drive, trajectory = ci_run / "drive.h5", ci_run / "trajectory.h5"
    for args, wanted in ((["focus", str(trajectory), "-t", str(trajectory), "-o", str(out / "i")],
                          f"{trajectory}: not a drive.h5 (it is a trajectory.h5 autosar wrote); `autosar ingest LOG "
                          "-o drive.h5` makes one"),
                         (["focus", str(drive), "-t", str(drive), "-o", str(out / "i")],
                          f"{drive}: not a trajectory.h5 (it is a drive.h5 autosar wrote); `autosar navigate "
                          "drive.h5 -o trajectory.h5` makes one")):
        _one_line_error(runner.invoke(app, args), f"error: {wanted}")
    assert not out.exists()
    # a run written into the log's own directory holds the log (read as a rosbag2 bag of its .mcap), and is a run
    beside = tmp_path / "drive"
    beside.mkdir()
    (beside / log.name).symlink_to(log)
    shutil.copy(ci_run / "run.json", beside / "run.json")
    r = runner.invoke(app, ["evaluate", str(beside), "-o", str(out)])
    assert r.exit_code == 1 and "a drive log" not in r.stderr and str(beside / "image.h5") in r.stderr, r.stderr


def test_output_whose_parent_is_a_file_names_it(tmp_path: Path) -> None:
    log = tmp_path / "log.mcap"
    _foreign(log)
    blocker = tmp_path / "afile"
    _foreign(blocker)
    r = runner.invoke(app, ["ingest", str(log), "-o", str(blocker / "drive.h5")])
    _one_line_error(r, str(blocker), "is a file, not a directory")
    assert "Errno" not in r.output


def test_run_refuses_foreign_products_and_inputs_inside_before_ingesting(tmp_path: Path) -> None:
    log = tmp_path / "rundir" / "log.mcap"
    log.parent.mkdir()
    keep = _foreign(log)
    r = runner.invoke(app, ["run", str(log), "-o", str(tmp_path / "rundir" / "log.mcap" / "out")])
    _one_line_error(r, "log.mcap")
    foreign = _foreign(tmp_path / "rundir" / "drive.h5")
    r = runner.invoke(app, ["run", str(log), "-o", str(tmp_path / "rundir"), "--overwrite"])
    _one_line_error(r, "drive.h5", "autosar did not write")
    assert (tmp_path / "rundir" / "drive.h5").read_bytes() == foreign and log.read_bytes() == keep


@pytest.mark.parametrize("pixel", ["1e-6", "nan", "-0.04"])
def test_run_refuses_an_impossible_grid_before_ingest(tmp_path: Path, pixel: str) -> None:
    log = tmp_path / "log.mcap"
    _foreign(log)  # never read: the grid is refused first
    cfg = tmp_path / "cfg.toml"
    base = Path(__file__).resolve().parents[1] / "configs" / "giulia_scanbrick.toml"
    text = base.read_text()
    assert "pixel_m = 0.04" in text
    cfg.write_text(text.replace("pixel_m = 0.04", f"pixel_m = {pixel}"))
    shutil.copy(base.parent / "autosar_giulia.dbc", tmp_path)
    r = runner.invoke(app, ["run", str(log), "-o", str(tmp_path / "out"), "-c", str(cfg)])
    _one_line_error(r, "pixel")
    assert not (tmp_path / "out" / "drive.h5").exists()


@pytest.mark.parametrize(("pattern", "replacement", "shown"), [
    (r"^speed_noise_mps2 = 0\.3", "speed_noise_mps2 = nan", "navigation.speed_noise_mps2: must be finite, got nan"),
    (r"^gate_probability = 0\.9999", "gate_probability = -1", "navigation.gate_probability"),
    (r"^position_noise_m = 0\.002", "position_noise_m = -0.002", "got -0.002"),
    (r"^yaw_deg = -45\.0", "yaw_deg = inf", "radar.mounting.yaw_deg: must be finite, got inf"),
])
def test_config_values_out_of_range_are_shown_in_one_line(tmp_path: Path, pattern: str, replacement: str,
                                                          shown: str) -> None:
    import re

    base = Path(__file__).resolve().parents[1] / "configs" / "giulia_scanbrick.toml"
    text, n = re.subn(pattern, replacement, base.read_text(), count=1, flags=re.MULTILINE)
    assert n == 1
    cfg = tmp_path / "cfg.toml"
    cfg.write_text(text)
    shutil.copy(base.parent / "autosar_giulia.dbc", tmp_path)
    r = runner.invoke(app, ["navigate", str(tmp_path / "drive.h5"), "-o", str(tmp_path / "t.h5"), "-c", str(cfg)])
    _one_line_error(r, str(cfg), shown)


def test_non_utf8_config_names_the_file(tmp_path: Path) -> None:
    cfg = tmp_path / "latin1.toml"
    cfg.write_bytes("# Fahrzeug: Giulia, Geschwindigkeit in km/h, Lenkübersetzung\n".encode("latin-1"))
    r = runner.invoke(app, ["navigate", str(tmp_path / "drive.h5"), "-c", str(cfg)])
    _one_line_error(r, str(cfg), "UTF-8")


def _disk_with_free_bytes(monkeypatch: pytest.MonkeyPatch, folder: Path, capacity: int) -> None:
    """Pretend ``folder``'s file system holds ``capacity`` bytes, less what its files already take."""
    import autosar_cli.store.outputs as outputs

    real = outputs.shutil.disk_usage

    def disk_usage(path):  # type: ignore[no-untyped-def]
        if Path(path).resolve() != folder.resolve():
            return real(path)
        used = sum(f.stat().st_size for f in folder.iterdir() if f.is_file())
        return shutil._ntuple_diskusage(capacity, used, max(capacity - used, 0))  # type: ignore[attr-defined]

    monkeypatch.setattr(outputs.shutil, "disk_usage", disk_usage)


def test_full_disk_is_one_line_and_leaves_no_partial(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, ci_mcap) -> None:
    out = tmp_path / "small"
    out.mkdir()
    _disk_with_free_bytes(monkeypatch, out, 5 * 2**20)
    r = runner.invoke(app, ["ingest", str(ci_mcap.log_path), "-o", str(out / "drive.h5")])
    _one_line_error(r, str(out / "drive.h5"), "no space left")
    assert list(out.iterdir()) == []


def test_disk_filling_while_the_drive_is_written(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, ci_mcap) -> None:
    """The estimate passes (the run's own check is skipped) but the disk fills up half way: the drive writer's
    thread refuses the next write, the error reaches run's parent process, nothing partial is left."""
    import autosar_cli.run as run_module

    out = tmp_path / "run"
    out.mkdir()
    _disk_with_free_bytes(monkeypatch, out, 28 * 2**20)  # the ci drive is ~18 MB; 16 MB kept in hand
    monkeypatch.setattr(run_module, "input_bytes", lambda paths: 0)
    r = runner.invoke(app, ["run", str(ci_mcap.log_path), "-o", str(out)])
    _one_line_error(r, str(out / "drive.h5"), "no space left")
    assert [p.name for p in out.iterdir()] == []


def test_a_disk_filling_while_the_evaluation_is_written_leaves_no_part_of_it(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, ci_run: Path) -> None:
    """The disk fills up at evaluate's second figure: the output named (it said a bare "[Errno 28] No space left on
    device"), the first figure and the directory evaluate made removed again (it left them)."""
    import errno

    import autosar_cli.evaluate.report as report_module

    def full_disk(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(report_module, "plot_reflector_chips", full_disk)
    out = tmp_path / "reports" / "ci"
    r = runner.invoke(app, ["evaluate", str(ci_run), "-o", str(out)])
    _one_line_error(r, f"{out}: no space left on the device")
    assert list(tmp_path.iterdir()) == []


def test_numba_cache_falls_back_to_a_temporary_directory(tmp_path: Path) -> None:
    import tempfile

    from autosar_cli.kernel_cache import fallback_cache_dir

    blocker = tmp_path / "a_file"
    blocker.write_text("x")  # nothing can be created below a regular file, not even by root
    read_only_install = blocker / "site-packages" / "autosar_cli"
    env = {"HOME": str(blocker / "home")}
    got = fallback_cache_dir(read_only_install, env)
    assert got is not None and got.parent == Path(tempfile.gettempdir())
    assert fallback_cache_dir(read_only_install, {"HOME": str(tmp_path)}) is None  # the home's cache is writable
    assert fallback_cache_dir(tmp_path / "autosar_cli", env) is None  # the install is writable
    assert fallback_cache_dir(read_only_install, {**env, "NUMBA_CACHE_DIR": str(tmp_path)}) is None



def _interpreter_start_s() -> float:
    """How long this environment's interpreter (the console script's) takes to start (its site, before any of
    autosar's code runs) on this host now: the longest of three bare starts (under load they vary)."""
    import subprocess
    import time

    times = []
    for _ in range(3):
        t = time.perf_counter()
        subprocess.run([sys.executable, "-c", "pass"], check=True)
        times.append(time.perf_counter() - t)
    return max(times)


@pytest.mark.parametrize("delay_s", [0.05, 0.15, 0.4, 1.5])
def test_ctrl_c_at_any_moment_is_one_line_and_exit_130(tmp_path: Path, delay_s: float) -> None:
    """SIGINT while the command imports (the first 0.2 s) or while it simulates: "interrupted", 130, no trace.
    Counted from when the interpreter has started: before, Python's own start-up (site) runs, which no program can
    handle a signal in, and which takes 20-50 ms on an idle host and longer on a loaded one."""
    import signal
    import subprocess
    import time

    script = _console_script()
    if script is None:
        pytest.skip("the autosar console script is not installed")
    start_s = _interpreter_start_s()
    for _ in range(3):
        # test1 (a 13 s drive) is still being simulated at 1.5 s where the default scenario may be done
        proc = subprocess.Popen([script, "simulate", "--scenario", "test1", "-o", str(tmp_path / "s.mcap")],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                preexec_fn=_as_from_a_terminal)
        time.sleep(start_s + delay_s)
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=60)
        before_autosar = (proc.returncode == -signal.SIGINT and not stderr.strip()) or (
            "Traceback" in stderr and not re.search(r'File "[^"]*[/\\\\]autosar_cli[/\\\\]', stderr))
        if not before_autosar:
            break
        # killed, or a traceback through no line of autosar's package: the signal came while Python itself started
        # or looked for the package (a host under load, e.g. the other pytest-xdist worker's kernels, can take
        # longer than the starts measured); again, later
        start_s *= 2.0
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    assert stderr.strip().endswith("interrupted"), stderr
    assert not [p.name for p in tmp_path.iterdir()]  # no log, no truth, no partial


def test_numba_is_imported_before_a_kernel_command_takes_ctrl_c_as_an_exception() -> None:
    """Ctrl-C inside numba's own import makes its extension modules print a traceback and fail with ImportError
    (`autosar simulate` once exited 1 so at 0.4 s): a command that runs kernels imports numba while the console
    script's quick exit still holds, and only then turns Ctrl-C into a KeyboardInterrupt; `info` does not."""
    import subprocess

    code = (
        "import signal, sys\n"
        "from autosar_cli import exit_interrupted\n"
        "signal.signal(signal.SIGINT, exit_interrupted)\n"
        "from autosar_cli.cli import _errors, _stop\n"
        "before = 'numba' in sys.modules\n"
        "with _errors(kernels=False):\n"
        "    plain = 'numba' in sys.modules\n"
        "with _errors():\n"
        "    inside = signal.getsignal(signal.SIGINT) is _stop\n"
        "    print(before, plain, 'numba' in sys.modules, inside)\n"
        "print(signal.getsignal(signal.SIGINT) is exit_interrupted)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["False", "False", "True", "True", "True"], (out.stdout, out.stderr)


def test_stale_partial_of_a_killed_ingest_is_listed_and_removed_by_the_next_command(tmp_path: Path,
                                                                                    ci_mcap) -> None:
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "out"
    out.mkdir()
    proc = subprocess.Popen([sys.executable, "-c", "from autosar_cli.cli import main; main()", "ingest",
                             str(ci_mcap.log_path), "-o", str(out / "drive.h5")], stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while not list(out.glob("*.partial*")) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    left = [p.name for p in out.iterdir()]
    assert left == [f"drive.partial-{proc.pid}.h5"]
    alive = out / f"other.partial-{os.getpid()}.h5"  # a writer still at work: never touched
    alive.write_bytes(b"x")

    r = runner.invoke(app, ["info", str(out), "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["stale_partials"] == [str(out / left[0])]

    log = tmp_path / "not_a_log.mcap"
    _foreign(log)
    r = runner.invoke(app, ["ingest", str(log), "-o", str(out / "drive.h5")])  # fails on the log, after the gate
    assert r.exit_code == 1
    assert sorted(p.name for p in out.iterdir()) == [alive.name]


def test_files_named_as_partials_that_are_not_the_outputs_own_are_never_removed(tmp_path: Path, ci_mcap) -> None:
    """The gate removed every stale ``*.partial-<n>.*`` beside an output: a user's log so named, the command's own
    input among them (ingest then read a file it had just deleted), or another product's. Now only the output's
    own partials go (``drive.partial-<n>.h5`` for drive.h5), and never an input."""
    import shutil

    dead = 2**22 + 17  # above any pid this machine gives
    given = tmp_path / f"rec.partial-{dead}.mcap"
    shutil.copy(ci_mcap.log_path, given)
    beside = [tmp_path / f"b.partial-{dead + 1}.mcap", tmp_path / f"out.partial-{dead + 4}.txt"]
    for p in beside:
        p.write_bytes(b"a user's file")
    own = tmp_path / f"out.partial-{dead + 2}.h5"
    own.write_bytes(b"left by a killed ingest")
    r = runner.invoke(app, ["ingest", str(given), "-o", str(tmp_path / "out.h5")])
    assert r.exit_code == 0, r.output
    assert given.is_file() and all(p.read_bytes() == b"a user's file" for p in beside) and not own.exists()
    kept = tmp_path / f"drive.partial-{dead + 3}.h5"  # stale, of the output's name, but the input itself
    kept.write_bytes(b"not a log")
    r = runner.invoke(app, ["ingest", str(kept), "-o", str(tmp_path / "drive.h5")])
    assert r.exit_code == 1 and kept.read_bytes() == b"not a log", r.output


def test_a_255_byte_file_name_is_written_through_its_partial(tmp_path: Path) -> None:
    from autosar_cli.store.atomic import atomic_output

    target = tmp_path / ("t" * 252 + ".h5")
    assert len(target.name.encode()) == 255
    with atomic_output(target, overwrite=False) as tmp:
        assert len(tmp.name.encode()) <= 255 and tmp.suffix == ".h5"
        tmp.write_bytes(b"content")
    assert target.read_bytes() == b"content" and [p.name for p in tmp_path.iterdir()] == [target.name]


def test_batch_record_of_a_drive_with_ingest_warnings_is_degraded(tmp_path: Path, monkeypatch) -> None:
    """run.json of a truncated log carries the ingest's warning; batch.json must too, and not say plain ok."""
    import autosar_cli.batch as batch_mod
    from autosar_cli.config import load_config

    truncated = "drive.mcap: the log ends inside a chunk at byte 1048576 (truncated); kept the 812 messages before it"

    def fake_run(logs, out_dir, config, **kw):  # the parts of a real run.json that batch reads
        warnings = [truncated] if "truncated" in str(logs[0]) else []
        return {"stages": {"ingest": {"wall_s": 0.1, "warnings": warnings}, "navigate": {"wall_s": 0.1},
                           "focus": {"wall_s": 0.1, "grid_shape": [2, 3], "frames_used": 5, "backprojections": 7}},
                "outputs": {"drive": "drive.h5", "image": {"h5": "image.h5"}}, "drive_s": 1.0}

    monkeypatch.setattr(batch_mod, "run", fake_run)
    cfg = load_config()
    bad = batch_mod.run_drive("t", [str(tmp_path / "truncated.mcap")], str(tmp_path / "t"), cfg)
    good = batch_mod.run_drive("g", [str(tmp_path / "good.mcap")], str(tmp_path / "g"), cfg)
    assert (bad["status"], bad["warnings"]) == ("degraded", [truncated])
    assert (good["status"], good["warnings"]) == ("ok", [])


def _cut_log(ci_mcap, tmp_path: Path) -> Path:
    """The ci log cut at 60 % of its bytes, its truth sidecar beside it."""
    log = tmp_path / "cut.mcap"
    data = ci_mcap.log_path.read_bytes()
    log.write_bytes(data[: int(0.6 * len(data))])
    shutil.copyfile(ci_mcap.truth_path, tmp_path / "cut.mcap.truth.h5")
    return log


def test_run_of_a_truncated_log_says_it_is_degraded(ci_mcap, ci_run: Path, tmp_path: Path) -> None:
    """`autosar run` on a log cut at 60 % keeps what was intact and makes its products, but does not look
    complete: the ingest's damage warning on stderr, "degraded" on its last line, and run.json's status and
    warnings say so (before, only run.json's ingest stage held it); so does its evaluation (metrics.json,
    report.md, the console); the whole log's run (conftest's ci_run) says ok."""
    log = _cut_log(ci_mcap, tmp_path)
    r = runner.invoke(app, ["run", str(log), "-o", str(tmp_path / "cut")])
    assert r.exit_code == 0, r.output
    manifest = json.loads((tmp_path / "cut" / "run.json").read_text())
    assert manifest["status"] == "degraded"
    damage = [w for w in manifest["warnings"] if "damaged MCAP at byte" in w]
    assert len(damage) == 1 and damage[0] in r.stderr.replace("\n", "")
    assert manifest["warnings"] == manifest["stages"]["ingest"]["warnings"]
    assert "degraded" in r.stdout[r.stdout.rindex("wrote"):]
    ev = runner.invoke(app, ["evaluate", str(tmp_path / "cut"), "-o", str(tmp_path / "cut_eval")])
    assert ev.exit_code == 0, ev.output
    metrics = json.loads((tmp_path / "cut_eval" / "metrics.json").read_text())
    assert (metrics["status"], metrics["input_warnings"]) == ("degraded", manifest["stages"]["ingest"]["warnings"])
    assert "Degraded input" in (tmp_path / "cut_eval" / "report.md").read_text()
    assert damage[0] in ev.stderr.replace("\n", "") and "degraded" in ev.stdout[ev.stdout.rindex("wrote"):]
    manifest = json.loads((ci_run / "run.json").read_text())
    assert (manifest["status"], manifest["warnings"]) == ("ok", [])
    whole = ci_run_console(ci_run)
    assert json.loads(whole["stdout"])["status"] == "ok" and "warning" not in whole["stderr"]


def test_compare_of_a_truncated_log_says_it_is_degraded(ci_mcap, tmp_path: Path) -> None:
    """`autosar compare` on the cut log: compare.json, compare.md, each method's run.json and the console say
    the images are made from a damaged log."""
    log = _cut_log(ci_mcap, tmp_path)
    r = runner.invoke(app, ["compare", str(log), "-o", str(tmp_path / "cmp"), "--methods", "none,sar-min"])
    assert r.exit_code == 0, r.output
    result = json.loads((tmp_path / "cmp" / "compare.json").read_text())
    assert result["status"] == "degraded" and any("damaged MCAP at byte" in w for w in result["warnings"])
    for m in ("none", "sar-min"):
        method = json.loads((tmp_path / "cmp" / m / "run.json").read_text())
        assert (method["status"], method["warnings"]) == ("degraded", result["warnings"])
    assert "Degraded input" in (tmp_path / "cmp" / "compare.md").read_text()
    assert all(w in r.stderr.replace("\n", "") for w in result["warnings"])
    assert "degraded" in r.stdout[r.stdout.rindex("wrote"):]


def test_full_disk_refuses_the_image_before_writing_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import numpy as np

    from autosar_cli.nav.geodesy import GeodeticOrigin
    from autosar_cli.sar.grid import FocusGrid
    from autosar_cli.store.image import FocusedImage, write_image
    from autosar_cli.store.outputs import DiskFullError

    grid = FocusGrid((0.0, 0.0), (1.0, 0.0), (0.0, -1.0), 0.04, 400, 300, 0.0)
    image = FocusedImage(np.ones(grid.shape, np.complex64), grid, GeodeticOrigin(45.06, 7.66, 240.0), {})
    _disk_with_free_bytes(monkeypatch, tmp_path, 2**20 + 1_000_000)  # 400 x 300 x 12 B = 1.44 MB needed
    with pytest.raises(DiskFullError, match=r"image\.h5: no space left on the device: the image needs about"):
        write_image(tmp_path / "image", image)
    assert list(tmp_path.iterdir()) == []
    _disk_with_free_bytes(monkeypatch, tmp_path, 2**20 + 2_000_000)
    assert set(write_image(tmp_path / "image", image)) == {"tif", "h5", "png"}


def test_compare_output_inside_its_rosbag2_log_is_refused(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    r = runner.invoke(app, ["compare", str(bag), "-o", str(bag / "cmp")])
    _one_line_error(r, "lies inside the input")
    assert [p.name for p in bag.iterdir()] == ["metadata.yaml"]


def test_enospc_without_a_file_name_names_the_output(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The log writers' own ENOSPC ("[Errno 28] No space left on device") names no file: the command does."""
    import errno

    import autosar_cli.sim.simulate as sim_mod

    def full_disk(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(sim_mod, "simulate", full_disk)
    r = runner.invoke(app, ["simulate", "-o", str(tmp_path / "s.mcap")])
    _one_line_error(r, f"{tmp_path / 's.mcap'}: no space left on the device")


def test_a_missing_dataset_names_the_file_and_the_dataset(tmp_path: Path, ci_mcap) -> None:
    import h5py

    drive = tmp_path / "drive.h5"
    r = runner.invoke(app, ["ingest", str(ci_mcap.log_path), "-o", str(drive)])
    assert r.exit_code == 0, r.output
    with h5py.File(drive, "r+") as f:
        del f["gnss/gnss_cog/fix/latitude_deg"]
    r = runner.invoke(app, ["navigate", str(drive), "-o", str(tmp_path / "t.h5")])
    _one_line_error(r, f"{drive}: dataset /gnss/gnss_cog/fix/latitude_deg is missing")
    assert "synchronously" not in r.output


def _child_writing(pid: int, directory: Path) -> int | None:
    """The child of ``pid`` that holds a partial file in ``directory`` open, or None (from Linux's /proc).
    Each child is stopped (SIGSTOP) while it is looked at, and the one returned is left stopped."""
    import signal

    children: list[int] = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        with contextlib.suppress(OSError):
            children += [int(c) for c in (task / "children").read_text().split()]
    for child in children:
        try:
            os.kill(child, signal.SIGSTOP)
            while Path(f"/proc/{child}/stat").read_text().rsplit(")", 1)[1].split()[0] not in "TtZX":
                pass  # SIGSTOP takes effect asynchronously (Z, X: the child has ended)
            for fd in Path(f"/proc/{child}/fd").iterdir():
                with contextlib.suppress(OSError):
                    target = Path(os.readlink(fd))
                    if target.parent == directory and ".partial" in target.name:
                        return child
            os.kill(child, signal.SIGCONT)
        except (ProcessLookupError, FileNotFoundError):  # a child that has ended meanwhile
            continue
    return None


def _sigint_pending(pid: int) -> bool:
    """Whether a SIGINT sent to the process ``pid`` waits for it (its shared pending set, from /proc)."""
    import signal

    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("ShdPnd:"):
            return bool(int(line.split()[1], 16) & (1 << (int(signal.SIGINT) - 1)))
    return False


def _signal_run_while_its_ingest_writes(log: Path, out: Path, send: Any, **popen: Any) -> tuple[Any, str]:
    """`autosar run LOG -o OUT`, its forked ingest stopped while it holds its partial file open; ``send(pid)``
    signals the run, the ingest goes on once its parent has passed a SIGINT on (the signal and the forward both
    before it then). Returns the finished process and its stderr."""
    import signal
    import subprocess
    import time

    script = _console_script()
    if script is None or not Path("/proc/self/task").is_dir():
        pytest.skip("needs the autosar console script and Linux's /proc")
    proc = subprocess.Popen([script, "run", str(log), "-o", str(out)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, **popen)
    deadline = time.monotonic() + 60
    child = None
    try:
        while child is None and time.monotonic() < deadline:
            child = _child_writing(proc.pid, out)
            time.sleep(0.005)
        assert child is not None, "the forked ingest never wrote its partial file"
        send(proc.pid)
        while not _sigint_pending(child) and time.monotonic() < deadline:  # the parent has forwarded it
            time.sleep(0.005)
        assert _sigint_pending(child), "the parent did not pass the SIGINT on to its ingest"
    finally:
        if child is not None:
            os.kill(child, signal.SIGCONT)
    _, stderr = proc.communicate(timeout=60)
    return proc, stderr


def test_ctrl_c_during_runs_ingest_stops_its_child_without_leaving_a_partial(tmp_path: Path, ci_mcap) -> None:
    """The interrupt lands while the forked ingest is writing, every time: the ingest (the child holding the
    partial file open) is stopped while it is found, stays stopped until its parent has passed the SIGINT on,
    and then goes on only to abort. Without that, an ingest of the short ci drive could finish in between."""
    import signal

    out = tmp_path / "run"
    proc, stderr = _signal_run_while_its_ingest_writes(
        ci_mcap.log_path, out, lambda pid: os.kill(pid, signal.SIGINT),  # to the parent alone, as `kill -INT` does
        preexec_fn=_as_from_a_terminal)
    assert proc.returncode == 130 and stderr.strip() == "error: interrupted", stderr
    assert not list(out.glob("*partial*")) and not (out / "drive.h5").exists()


@pytest.mark.parametrize("fmt,suffix", [("mcap", ".mcap"), ("ros1", ".bag")])
def test_simulate_overwrite_replaces_its_own_log_once_the_new_one_is_complete(tmp_path: Path, fmt: str,
                                                                                 suffix: str) -> None:
    log = tmp_path / f"ci{suffix}"
    args = ["simulate", "-s", "ci", "--seed", "3", "-f", fmt, "--dynamics", "kinematic", "-o", str(log)]
    assert runner.invoke(app, args).exit_code == 0
    first = log.read_bytes()
    _one_line_error(runner.invoke(app, args), "already exists")
    r = runner.invoke(app, [*args, "--overwrite"])
    assert r.exit_code == 0, r.output
    assert log.read_bytes() == first  # the same seed again, written over the first
    assert not list(tmp_path.glob("*partial*"))


@pytest.mark.usefixtures("sigint_reaches_python")
def test_a_ctrl_c_while_a_kernel_runs_is_raised_once_it_has_returned() -> None:
    """interrupts_held: a SIGINT inside the block is noted, not raised, and raised as KeyboardInterrupt after it
    (a KeyboardInterrupt raised while numba boxed run_filter's result crashed navigate: SIGSEGV); the handler
    before it is back; without a SIGINT nothing is raised."""
    import signal

    from autosar_cli.interrupts import interrupts_held

    before = signal.getsignal(signal.SIGINT)
    finished = []
    with pytest.raises(KeyboardInterrupt):
        with interrupts_held():
            signal.raise_signal(signal.SIGINT)
            finished.append(True)  # what the kernel would do after the signal came
    assert finished == [True] and signal.getsignal(signal.SIGINT) is before
    with interrupts_held():
        pass
    assert signal.getsignal(signal.SIGINT) is before


def test_a_signal_held_while_the_block_fails_is_raised_not_lost() -> None:
    """interrupts_held: a SIGTERM or SIGINT noted while the block then fails (a process group's SIGTERM also ends the
    LocalCluster's nanny the block starts: "Nanny failed to start") is raised as its KeyboardInterrupt, the block's
    error as its cause; before, the error went on alone and `autosar batch` under `timeout` exited 1 with "error:
    Nanny failed to start." instead of 143 "terminated" (hunt/ kill campaign, 1 of 1 at 2 s). Without a signal the
    error goes on as it is."""
    import signal

    from autosar_cli.interrupts import Terminated, interrupts_held

    def stop(signum: int, frame: object) -> None:  # as cli._stop
        raise Terminated if signum == signal.SIGTERM else KeyboardInterrupt

    before = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        for signum, raised in ((signal.SIGTERM, Terminated), (signal.SIGINT, KeyboardInterrupt)):
            with pytest.raises(raised) as stopped:
                with interrupts_held():
                    signal.raise_signal(signum)
                    raise RuntimeError("Nanny failed to start.")
            assert isinstance(stopped.value.__cause__, RuntimeError)
            assert signal.getsignal(signum) is stop
        with pytest.raises(RuntimeError, match="Nanny"):
            with interrupts_held():
                raise RuntimeError("Nanny failed to start.")
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        with pytest.raises(RuntimeError, match="Nanny"):  # an ignored signal changes nothing
            with interrupts_held():
                signal.raise_signal(signal.SIGTERM)
                raise RuntimeError("Nanny failed to start.")
    finally:
        for s, handler in before.items():
            signal.signal(s, handler)


@pytest.mark.usefixtures("sigint_reaches_python")
def test_sarmins_kernel_finishes_before_a_ctrl_c_stops_navigate(monkeypatch: pytest.MonkeyPatch, ci_mcap,  # noqa: ANN001
                                                                  tmp_path: Path) -> None:
    """A SIGINT arriving while SAR-MIN's compiled filter runs stops navigate with KeyboardInterrupt only after
    the filter has returned its result whole."""
    import signal

    from autosar_cli.config import load_config
    from autosar_cli.ingest.pipeline import ingest
    from autosar_cli.nav import sarmin_kernel
    from autosar_cli.nav.navigate import navigate

    cfg = load_config()
    drive = tmp_path / "drive.h5"
    ingest([ci_mcap.log_path], drive, config=cfg)
    kernel, returned = sarmin_kernel.run_filter, []

    def interrupted_filter(*args):  # noqa: ANN002, ANN202
        signal.raise_signal(signal.SIGINT)  # as if Ctrl-C came while the compiled loop ran
        out = kernel(*args)
        returned.append(len(out))
        return out

    monkeypatch.setattr(sarmin_kernel, "run_filter", interrupted_filter)
    with pytest.raises(KeyboardInterrupt):
        navigate(drive, "sar-min", cfg)
    assert returned == [9]


def test_simulate_overwrite_replaces_only_a_directory_the_simulator_wrote(tmp_path: Path, ci_run: Path) -> None:
    """`simulate -f ros2 --overwrite` removed any directory holding one of autosar's manifests, and everything in it:
    a run written into the log's own folder, the log and the user's notes with it. Now it replaces a simulated bag
    holding only what the simulator writes, and refuses a run's directory or a bag holding a file of the user's."""
    import shutil

    run_dir = tmp_path / "d3"
    shutil.copytree(ci_run, run_dir, ignore=shutil.ignore_patterns("*.console.json"))
    (run_dir / "my_notes.txt").write_text("precious")
    (tmp_path / "d3.truth.h5").symlink_to(ci_run / "drive.h5")  # an autosar HDF5 where the sidecar would be
    before = sorted(p.name for p in run_dir.iterdir())
    r = runner.invoke(app, ["simulate", "-s", "ci", "-f", "ros2", "-o", str(run_dir), "--overwrite"])
    _one_line_error(r, str(run_dir), "simulator did not write")
    assert sorted(p.name for p in run_dir.iterdir()) == before
    bag = tmp_path / "bag"
    r = runner.invoke(app, ["simulate", "-s", "ci", "-f", "ros2", "-o", str(bag)])
    assert r.exit_code == 0, r.output
    (bag / "notes.txt").write_text("mine")
    r = runner.invoke(app, ["simulate", "-s", "ci", "-f", "ros2", "-o", str(bag), "--overwrite"])
    _one_line_error(r, str(bag), "holds notes.txt")
    (bag / "notes.txt").unlink()
    r = runner.invoke(app, ["simulate", "-s", "ci", "-f", "ros2", "-o", str(bag), "--overwrite", "--seed", "3"])
    assert r.exit_code == 0, r.output



def test_navigate_plot_passes_the_output_gate(tmp_path: Path, ci_run: Path) -> None:
    """`navigate --plot` wrote OUTPUT.png past the gate: over a user's PNG without --overwrite, and over the drive
    itself where the drive was named OUTPUT.png. Both are refused before anything is written."""
    import shutil

    user = tmp_path / "tp.png"
    user.write_text("user png")
    r = runner.invoke(app, ["navigate", str(ci_run / "drive.h5"), "-o", str(tmp_path / "tp.h5"), "--plot"])
    _one_line_error(r, str(user), "autosar did not write")  # at once: "already exists" advised a refused --overwrite
    assert user.read_text() == "user png" and not (tmp_path / "tp.h5").exists()
    r = runner.invoke(app, ["navigate", str(ci_run / "drive.h5"), "-o", str(tmp_path / "tp.h5"), "--plot",
                            "--overwrite"])
    _one_line_error(r, str(user), "autosar did not write")
    drive = tmp_path / "x.png"
    shutil.copy(ci_run / "drive.h5", drive)
    r = runner.invoke(app, ["navigate", str(drive), "-o", str(tmp_path / "x.h5"), "--plot"])
    _one_line_error(r, str(drive), "is an input of this command")
    assert drive.read_bytes()[:8] == b"\x89HDF\r\n\x1a\n"


def test_evaluate_compare_and_run_never_replace_a_users_file_in_their_directory(tmp_path: Path, ci_run: Path,
                                                                               ci_mcap) -> None:
    """evaluate and compare checked only their manifest (metrics.json, compare.json): a user's report.md or
    compare.png in the directory was replaced without a word; run replaced a drive.h5 that a separate ingest wrote
    there without --overwrite. Each is refused before anything is written; --overwrite replaces only autosar's."""
    import shutil

    evu = tmp_path / "evu"
    evu.mkdir()
    (evu / "report.md").write_text("user")
    r = runner.invoke(app, ["evaluate", str(ci_run), "-o", str(evu)])
    _one_line_error(r, str(evu / "report.md"), "autosar did not write")
    r = runner.invoke(app, ["evaluate", str(ci_run), "-o", str(evu), "--overwrite"])
    _one_line_error(r, str(evu / "report.md"), "autosar did not write")
    assert sorted(p.name for p in evu.iterdir()) == ["report.md"] and (evu / "report.md").read_text() == "user"
    cmpu = tmp_path / "cmpu"
    cmpu.mkdir()
    (cmpu / "compare.png").write_text("user")
    r = runner.invoke(app, ["compare", str(ci_mcap.log_path), "-o", str(cmpu)])
    _one_line_error(r, str(cmpu / "compare.png"), "autosar did not write")
    assert sorted(p.name for p in cmpu.iterdir()) == ["compare.png"]
    (cmpu / "compare.png").unlink()
    (cmpu / "sar-min").mkdir()
    (cmpu / "sar-min" / "report.md").write_text("user")  # a method's evaluation writes its report.md there
    r = runner.invoke(app, ["compare", str(ci_mcap.log_path), "-o", str(cmpu), "--methods", "sar-min"])
    _one_line_error(r, str(cmpu / "sar-min" / "report.md"), "autosar did not write")
    keep = tmp_path / "keep"
    keep.mkdir()
    shutil.copy(ci_run / "drive.h5", keep / "drive.h5")
    r = runner.invoke(app, ["run", str(ci_mcap.log_path), "-o", str(keep)])
    _one_line_error(r, str(keep / "drive.h5"), "already exists")
    assert sorted(p.name for p in keep.iterdir()) == ["drive.h5"]


@pytest.mark.parametrize("how", ["console script", "python -m"])
def test_sigterm_stops_a_command_as_ctrl_c_does(tmp_path: Path, ci_mcap, how: str) -> None:
    """SIGTERM (`timeout`'s, a service manager's stop) ended the command at once: exit 143 without a word, its
    partial file left behind (under `python -m autosar_cli.cli` still). Now it stops as at Ctrl-C: "terminated",
    exit 143, the partial file removed."""
    import signal
    import subprocess
    import sys
    import time

    script = _console_script()
    if script is None and how == "console script":
        pytest.skip("the autosar console script is not installed")
    command = [script] if how == "console script" else [sys.executable, "-m", "autosar_cli.cli"]
    out = tmp_path / "out"
    proc = subprocess.Popen([*command, "ingest", str(ci_mcap.log_path), "-o", str(out / "drive.h5")],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not list(tmp_path.glob("out/*.partial*")) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.01)
    proc.send_signal(signal.SIGTERM)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 143, stderr
    assert stderr.strip().endswith("terminated") and "Traceback" not in stderr, stderr
    assert not out.exists() or not list(out.iterdir())


def test_an_error_that_follows_a_swallowed_ctrl_c_is_reported_as_the_interrupt() -> None:
    """A Ctrl-C swallowed on its way (a C extension's import turned it into "initialization failed", matplotlib
    returned without writing the PNG its atomic writer then could not open) ended the command with that error's
    line and exit 1. The error that follows an interrupt is reported as the interrupt: "interrupted", 130."""
    import subprocess

    code = (
        "import os, signal, time, typer\n"
        "from autosar_cli import exit_interrupted\n"
        "signal.signal(signal.SIGINT, exit_interrupted)\n"
        "from autosar_cli.cli import _errors\n"
        "try:\n"
        "    with _errors(kernels=False):\n"
        "        try:\n"
        "            os.kill(os.getpid(), signal.SIGINT)\n"
        "            time.sleep(1)\n"
        "        except KeyboardInterrupt:\n"
        "            pass\n"
        "        open('/nonexistent/image.partial-1.png', 'rb+')\n"
        "except typer.Exit as exc:\n"
        "    print(exc.exit_code)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.stdout.split() == ["130"], (out.stdout, out.stderr)
    assert out.stderr.strip() == "error: interrupted", out.stderr


def test_a_second_ctrl_c_during_the_clean_up_ends_the_command_at_once() -> None:
    """Two Ctrl-Cs 30 ms apart during focus once hung the command for good: the second, raised inside h5py's
    clean-up of the first, left h5py's lock held. The second now ends the process at once ("interrupted", 130)."""
    import subprocess

    for held in ("", "    with interrupts_held():  # the first while a kernel runs, raised after it\n"):
        code = (
            "import os, signal, time\n"
            "from autosar_cli import exit_interrupted\n"
            "signal.signal(signal.SIGINT, exit_interrupted)\n"
            "from autosar_cli.cli import _errors\n"
            "from autosar_cli.interrupts import interrupts_held\n"
            "with _errors(kernels=False):\n"
            "  try:\n"
            + held +
            "        os.kill(os.getpid(), signal.SIGINT)\n"
            "        time.sleep(1)\n"
            "  finally:  # a writer's clean-up, interrupted again\n"
            "    os.kill(os.getpid(), signal.SIGINT)\n"
            "    try:\n"
            "        time.sleep(1)\n"
            "    except KeyboardInterrupt:  # swallowed where it hung: h5py's lock left held\n"
            "        time.sleep(30)\n"
        )
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=20)
        assert out.returncode == 130 and out.stderr.strip() == "error: interrupted", (held, out.returncode,
                                                                                      out.stderr)


@pytest.mark.parametrize("stop", ["SIGTERM", "SIGINT"])
def test_a_signal_to_the_whole_process_group_stops_runs_forked_ingest_once(tmp_path: Path, ci_mcap, stop: str) -> None:
    """`timeout`, a service manager and a terminal signal the whole process group: run's forked ingest got the
    signal, then its parent's forward of it, took that for a second interrupt and ended inside its clean-up, its
    partial file left (4 of 4 with SIGTERM). The ingest takes the first alone; one line, no partial file."""
    import signal

    out = tmp_path / "run"
    proc, stderr = _signal_run_while_its_ingest_writes(
        ci_mcap.log_path, out, lambda pid: os.killpg(pid, getattr(signal, stop)), start_new_session=True)
    code, said = (143, "terminated") if stop == "SIGTERM" else (130, "interrupted")
    assert proc.returncode == code and stderr.strip() == f"error: {said}", (proc.returncode, stderr)
    assert not list(out.glob("*partial*")) and not (out / "drive.h5").exists(), sorted(out.iterdir())


def test_a_process_the_command_spawns_keeps_pythons_signal_handlers() -> None:
    """batch's Dask workers are spawned with the command's argv, and imported autosar_cli as the command does:
    each installed the command's quick exit, and a SIGTERM to the group printed "error: terminated" once per
    worker. A spawned process (named before its script runs) installs none and ignores SIGTERM, as it does SIGINT
    (the command stops its workers: killed by the group's SIGTERM, the scheduler and the workers left logged their
    lost connections, tracebacks and all, before "error: terminated"); the command installs its."""
    import subprocess

    code = (
        "import multiprocessing, signal, sys\n"
        "sys.argv[0] = '/venv/bin/autosar'\n"
        "multiprocessing.current_process().name = sys.argv[1]\n"
        "import autosar_cli\n"
        "print(signal.getsignal(signal.SIGTERM) is autosar_cli.exit_interrupted,"
        " signal.getsignal(signal.SIGTERM) == signal.SIG_IGN)\n"
    )
    said = [subprocess.run([sys.executable, "-c", code, name], capture_output=True, text=True, timeout=60).stdout
            for name in ("Dask Worker process (from Nanny)", "MainProcess")]
    assert [s.strip() for s in said] == ["False True", "True False"], said


def test_navigate_replaces_its_own_plot_beside_an_output_of_any_name(tmp_path: Path, ci_run: Path) -> None:
    """`navigate -o tr.hdf5 --plot --overwrite` again: its own tr.png was refused as "a file autosar did not write" (a
    PNG counted as autosar's only beside an .h5 of its name); the plot beside autosar's trajectory is its own."""
    for _ in range(2):
        r = runner.invoke(app, ["navigate", str(ci_run / "drive.h5"), "-o", str(tmp_path / "tr.hdf5"), "--plot",
                                "--overwrite"])
        assert r.exit_code == 0, r.output
    assert (tmp_path / "tr.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("tiles", ["1", "2"])
def test_an_image_no_pulse_reaches_is_refused(tmp_path: Path, ci_run: Path, tiles: str) -> None:
    """`focus --resolution 1e300` wrote an all-zero image, exit 0, no word (its beam +-0 deg held no pulse), and
    `--resolution 1000` one of single pulses (332 of 40443 pixels lit): a resolution coarser than 1 m is refused,
    and an image no pulse reaches (a box 500 m off the drive, or on the side the radar does not look to) is one
    line, which said nothing of where the track lies: it gives the track's ENU box, the side the radar looks to
    and the box --grid auto covers."""
    for resolution in ("1e300", "1000", "1.5"):
        r = runner.invoke(app, ["focus", str(ci_run / "drive.h5"), "-t", str(ci_run / "trajectory.h5"), "-o",
                                str(tmp_path / "x"), "--resolution", resolution, "--tiles", tiles])
        _one_line_error(r, f"cross-range resolution {float(resolution):g} m: coarser than 1 m")
    for grid in ("500,500,501,501", "2,0,5,3"):  # the ci drive's radar looks right of its track, heading east
        r = runner.invoke(app, ["focus", str(ci_run / "drive.h5"), "-t", str(ci_run / "trajectory.h5"), "-o",
                                str(tmp_path / "x"), "--grid", grid, "--tiles", tiles])
        _one_line_error(r, "no radar pulse reaches a pixel within the processed beam")
        assert re.search(r"the image would be empty: the radar's track spans x 2\.\d to 4\.\d m, y -0\.\d to -0\.\d m "
                         r"\(ENU\) and it looks to the right \(radar.mounting.yaw_deg -45\); --grid auto covers "
                         r"2\.\d,-27\.\d,6\.\d,-1\.\d$", r.stderr.replace("\n", "")), r.stderr
    assert not list(tmp_path.iterdir())


def test_focus_makes_the_folder_of_its_output(tmp_path: Path, ci_run: Path) -> None:
    """`focus -o new/dir/x` failed after focusing, naming its own partial file ("No such file or directory:
    x.partial-<pid>.png"); it makes the folder, as ingest and navigate do, and removes it again on failure."""
    out = tmp_path / "new" / "dir" / "x"
    r = runner.invoke(app, ["focus", str(ci_run / "drive.h5"), "-t", str(ci_run / "trajectory.h5"), "-o", str(out)])
    assert r.exit_code == 0 and (out.parent / "x.tif").exists(), r.output
    r = runner.invoke(app, ["focus", str(ci_run / "drive.h5"), "-t", str(ci_run / "trajectory.h5"), "-o",
                            str(tmp_path / "other" / "x"), "--grid", "500,500,501,501"])  # no pulse reaches it
    assert r.exit_code == 1 and not (tmp_path / "other").exists(), r.output


def test_an_image_larger_than_the_machines_memory_is_refused_before_allocating_it(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, ci_run: Path) -> None:
    """`--pixel 0.0001` passed the 64 GiB grid limit with 47.7 GiB and ended in numpy's "Unable to allocate 47.7
    GiB for an array with shape ..."; focus now compares the image with the machine's memory and
    names the way out; the tiled focus, which holds one tile at a time, is not refused for it (ci's image: 323 kB,
    its eighth 40 kB, the memory made 64 kB)."""
    import autosar_cli.sar.focus as focus_module

    monkeypatch.setattr(focus_module, "physical_memory_bytes", lambda: 2**16)
    args = ["focus", str(ci_run / "drive.h5"), "-t", str(ci_run / "trajectory.h5")]
    r = runner.invoke(app, [*args, "-o", str(tmp_path / "whole")])
    _one_line_error(r, "the image needs", "GiB, more than this machine's 6.1e-05 GiB of memory",
                    "focus in tiles (--tiles)")
    assert list(tmp_path.iterdir()) == []
    r = runner.invoke(app, [*args, "-o", str(tmp_path / "tiled"), "--tiles", "8"])
    assert r.exit_code == 0, r.output


def test_an_output_folder_that_refuses_writing_is_named(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                         ci_run: Path) -> None:
    """A locked folder (chattr +i, a read-only mount): h5py's own words naming a partial file ("[Errno 1] Unable
    to synchronously create file (unable to open file: name = 'ro/t.partial-26078.h5', ...") or the bare OS error
    ("[Errno 1] Operation not permitted: 'ro/r'"); now the command's output and why."""
    import errno

    import autosar_cli.store.trajectory as trajectory_module

    out = tmp_path / "locked" / "t.h5"

    def refused(path, *args, **kwargs):  # type: ignore[no-untyped-def]
        raise OSError(errno.EPERM, f"Unable to synchronously create file (unable to open file: name = "
                                   f"'{out.with_suffix('')}.partial-26078.h5', errno = 1, error message = "
                                   "'Operation not permitted', flags = 13, o_flags = 242)")

    monkeypatch.setattr(trajectory_module, "write_trajectory", refused)
    r = runner.invoke(app, ["navigate", str(ci_run / "drive.h5"), "-o", str(out)])
    _one_line_error(r, f"error: {out}: cannot be written there (Operation not permitted)")

    import autosar_cli.evaluate.report as report_module

    def locked(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise PermissionError(errno.EPERM, "Operation not permitted", str(tmp_path / "locked" / "e"))

    monkeypatch.setattr(report_module, "output_directory", locked)
    r = runner.invoke(app, ["evaluate", str(ci_run), "-o", str(tmp_path / "locked" / "e")])
    _one_line_error(r, f"error: {tmp_path / 'locked' / 'e'}: cannot be written there (Operation not permitted)")
    # an input that cannot be read is not the output, though its folder is named as the output is (drive1/ drive1.h5)
    from autosar_cli.cli import _not_writable

    unreadable = PermissionError(errno.EACCES, "Permission denied", str(tmp_path / "drive1" / "ci.mcap"))
    assert not _not_writable(unreadable, tmp_path / "drive1.h5")
    assert not _not_writable(unreadable, Path("."))
    assert _not_writable(PermissionError(errno.EACCES, "Permission denied", str(tmp_path / "drive1.partial-7.h5")),
                         tmp_path / "drive1.h5")


def test_autosars_geotiff_manifest_or_run_directory_given_as_a_log_or_image_says_what_it_is(ci_run: Path,
                                                                                            tmp_path: Path) -> None:
    """`evaluate image.tif` (the GeoTIFF is "the image") gave h5py's "file signature not found"; a run.json or a run
    directory given as a log, "unknown log container" or "not a rosbag2 bag": each says what it is."""
    out = tmp_path / "out"
    tif = ci_run / "image.tif"
    _one_line_error(runner.invoke(app, ["evaluate", str(tif), "-o", str(out)]),
                    f"error: {tif}: an image.tif autosar wrote (the GeoTIFF to view; `autosar evaluate` reads the "
                    "image.h5 beside it)")
    _one_line_error(runner.invoke(app, ["evaluate", str(ci_run / "run.json"), "-o", str(out)]),
                    f"error: {ci_run / 'run.json'}: a run.json autosar wrote (the manifest of the directory it is in); "
                    "evaluate reads a run directory or an image.h5")
    for given in (tif, ci_run / "run.json", ci_run):
        r = runner.invoke(app, ["ingest", str(given), "-o", str(out / "d.h5")])
        _one_line_error(r, f"error: {given}: a")
        assert "autosar wrote" in r.output and "not a log" in r.output, r.output
    assert not out.exists()


def test_a_set_of_products_the_block_replaced_in_part_goes_whole(tmp_path: Path) -> None:
    """`compare --overwrite` or `evaluate --overwrite` stopped (Ctrl-C, an error) after replacing some of a former
    run's products left the old compare.json / metrics.json saying "ok" beside the new drive, images or figures
    (a helper's kill hunt: `compare b.mcap -o cmp --overwrite` over a's, SIGINT at 9 s). Now the manifest is set
    aside first (a set killed part way has none, and still reads as autosar's to the next --overwrite), and a failed
    block that replaced any product removes the whole set; one that replaced none keeps it, its manifest put back."""
    from autosar_cli.store.outputs import check_products, output_directory, set_aside

    out = tmp_path / "cmp"
    names = ["compare.json", "drive.h5", "none/run.json", "none/image.h5"]

    def former() -> list[Path]:
        for name in names:
            (out / name).parent.mkdir(parents=True, exist_ok=True)
            (out / name).write_text(f"a's {name}")
        (out / "notes.txt").write_text("the user's")
        return [out / name for name in names]

    products = former()
    with pytest.raises(KeyboardInterrupt), output_directory(out, products, manifest=out / "compare.json"):
        assert not (out / "compare.json").exists()  # a set without its manifest is no whole one, even killed
        (out / "drive.h5").write_text("b's drive")
        raise KeyboardInterrupt
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file()) == ["notes.txt"]

    products = former()
    with pytest.raises(RuntimeError), output_directory(out, products, manifest=out / "compare.json"):
        raise RuntimeError("refused before writing")
    assert all(p.read_text().startswith("a's") for p in products)  # nothing replaced: the former set stays whole
    assert not set_aside(out / "compare.json").exists()

    # killed part way (no handler runs): the set has no manifest, and the next --overwrite may still replace it
    (out / "compare.json").write_text('{"format": "autosar-compare"}')
    (out / "compare.json").rename(set_aside(out / "compare.json"))
    (out / "drive.h5").write_text("b's drive")
    check_products(out, ["drive.h5", "compare.md"], [], overwrite=True, manifest="compare.json")
    with output_directory(out, products, manifest=out / "compare.json"):
        (out / "compare.json").write_text("c's")
    assert (out / "compare.json").read_text() == "c's" and not set_aside(out / "compare.json").exists()

    products = former()
    with pytest.raises(RuntimeError), output_directory(out, [*products, out / "ins" / "run.json"]):
        (out / "ins").mkdir()
        (out / "ins" / "run.json").write_text("b's")
        raise RuntimeError("broke while writing only what was not there")
    assert all(p.read_text().startswith("a's") for p in products) and not (out / "ins").exists()


@pytest.mark.usefixtures("sigint_reaches_python")
def test_a_simulation_stopped_as_its_log_comes_into_place_puts_its_truth_there_too(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`simulate -o sim.mcap --seed 5 --overwrite` over seed 0's, Ctrl-C the moment the new log was renamed into
    place: the whole seed-5 log stood beside seed 0's truth (or none, without --overwrite), and evaluating its run
    said "the truth of another recording" (a helper's kill hunt). The log, its truth (and a capture) now come into
    place together: the Ctrl-C is acted on after both."""
    import signal

    from autosar_cli.sim import logwriter
    from autosar_cli.sim.simulate import simulate
    from autosar_cli.sim.truth import open_truth

    log = tmp_path / "sim.mcap"
    simulate("ci", log, seed=0)
    publish = logwriter._BaseWriter._publish

    def then_ctrl_c(self):  # type: ignore[no-untyped-def]
        publish(self)
        signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(logwriter._BaseWriter, "_publish", then_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        simulate("ci", log, seed=5, overwrite=True)
    with open_truth(tmp_path / "sim.mcap.truth.h5") as f:
        assert int(f.attrs["seed"]) == 5
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sim.mcap", "sim.mcap.truth.h5"]


@pytest.mark.usefixtures("sigint_reaches_python")
def test_a_trajectory_stopped_as_it_comes_into_place_brings_its_plot(ci_run: Path, tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """`navigate --plot --overwrite`, Ctrl-C the moment the new trajectory.h5 was in place: it stood beside the
    former track's plot (a helper's kill hunt: the ins plot beside a sar-min track). The plot is drawn first and
    both come into place together; the Ctrl-C is acted on after (exit 130), and no partial stays."""
    import hashlib
    import signal

    import autosar_cli.store.trajectory as trajectory_module
    from autosar_cli.store.trajectory import read_trajectory

    out = tmp_path / "traj.h5"
    r = runner.invoke(app, ["navigate", str(ci_run / "drive.h5"), "-o", str(out), "--method", "none", "--plot"])
    assert r.exit_code == 0, r.output
    former = hashlib.sha256((tmp_path / "traj.png").read_bytes()).hexdigest()
    write = trajectory_module.write_trajectory

    def then_ctrl_c(*args, **kwargs):  # type: ignore[no-untyped-def]
        write(*args, **kwargs)
        signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(trajectory_module, "write_trajectory", then_ctrl_c)
    r = runner.invoke(app, ["navigate", str(ci_run / "drive.h5"), "-o", str(out), "--method", "gnss", "--plot",
                            "--overwrite"])
    assert r.exit_code == 130, r.output
    assert read_trajectory(out).method == "gnss"
    assert hashlib.sha256((tmp_path / "traj.png").read_bytes()).hexdigest() != former
    assert sorted(p.name for p in tmp_path.iterdir()) == ["traj.h5", "traj.png"]


def test_a_disk_that_fills_as_the_image_is_closed_is_an_error_not_a_crash(tmp_path: Path) -> None:
    """The disk filling after the image's last strip: HDF5's close flushes its caches, fails half-way on the full
    disk and left image.h5 half closed; the library's own clean-up at exit then crashed the process (SIGSEGV after
    the command's error line: a helper's kill hunt, `run` and `compare` on a 40 MB tmpfs). Here the image is written
    on a 40 MB tmpfs (mounted for the test: skipped where that is not allowed) in a process of its own: the error
    comes out as an OSError, the process ends normally, and no partial stays."""
    import subprocess
    import sys

    disk = tmp_path / "small"
    disk.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=40m", "tmpfs", str(disk)], capture_output=True)
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({mounted.stderr.decode().strip()[:80]})")
    script = f"""
import os, numpy as np
from pathlib import Path
from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.sar.grid import box_grid
from autosar_cli.store.image import ImageWriter
grid = box_grid(0, 0, 64, 64, pixel_m=0.04, height_m=0.5)
writer = ImageWriter(Path({str(disk / 'img')!r}), grid, GeodeticOrigin(45.0, 9.0, 100.0))
writer.set_metadata({{"a": 1}})
try:
    with writer:
        for col in range(0, grid.shape[1], 256):
            n = min(256, grid.shape[1] - col)
            writer.write_columns(col, np.full((grid.shape[0], n), 1 + 1j, np.complex64))
        st = os.statvfs({str(disk)!r})
        with open({str(disk / 'fill')!r}, "wb") as f:
            f.write(bytes(st.f_bavail * st.f_frsize))
except OSError as exc:
    print("refused:", exc.errno)
"""
    try:
        r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
        left = sorted(p.name for p in disk.iterdir())
    finally:
        subprocess.run(["umount", str(disk)], capture_output=True)
    assert r.returncode == 0, r.stderr[-500:]
    assert "refused: 28" in r.stdout and left == ["fill"]


@pytest.mark.parametrize("command", ["ingest", "focus"])
def test_a_disk_that_fills_as_hdf5_writes_ends_the_command_with_its_error_not_a_crash(
        tmp_path: Path, ci_mcap, ci_run: Path, command: str) -> None:
    """The free-space estimate passed (another program filling the disk after it): HDF5's write fails, the command
    says so in one line, and then the process crashed in the interpreter's shutdown (SIGSEGV, exit 139: the library
    left the file it could not flush half closed), `ingest` on a 2 MB tmpfs; `focus` on a 250 kB one said "error:
    Can't close dataset (file write failed: time = ..." (HDF5's RuntimeError, its text cut at its first line). Now
    exit 1, the output named, nothing left. The console script's main() in a process of its own, on a tmpfs
    mounted for the test (skipped where that is not allowed)."""
    import subprocess

    disk = tmp_path / "small"
    disk.mkdir()
    size, out, args = {"ingest": ("2m", disk / "drive.h5", [str(ci_mcap.log_path)]),
                       "focus": ("250k", disk / "img", [str(ci_run / "drive.h5"), "-t",
                                                        str(ci_run / "trajectory.h5")])}[command]
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(disk)], capture_output=True)
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({mounted.stderr.decode().strip()[:80]})")
    script = f"""
import sys
import autosar_cli.store.outputs as outputs
outputs.shutil.disk_usage = lambda p: outputs.shutil._ntuple_diskusage(10**12, 0, 10**12)  # every estimate passes
from autosar_cli.cli import main
sys.argv = ["autosar", {command!r}, *{args!r}, "-o", {str(out)!r}]
main()
"""
    try:
        r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
        left = sorted(p.name for p in disk.iterdir())
    finally:
        subprocess.run(["umount", str(disk)], capture_output=True)
    said = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert (r.returncode, said) == (1, [f"error: {out}: no space left on the device"]), r.stderr[-800:]
    assert left == []


#: the free-space estimates (store.outputs.check_free_space) see a huge disk, in every process the command starts
#: (run's ingest child, batch's Dask workers); every other look at the disk sees it as it is
_ESTIMATES_PASS = """
import shutil, sys
_real = shutil.disk_usage
def _disk_usage(path):
    usage = _real(path)
    if sys._getframe(1).f_code.co_name == "check_free_space":
        return shutil._ntuple_diskusage(usage.total + 10**12, usage.used, usage.free + 10**12)
    return usage
shutil.disk_usage = _disk_usage
"""


@pytest.mark.parametrize("case", ["navigate", "focus-tif", "focus-tiles", "compare-sar-min", "run-navigate",
                                  "run-focus", "batch"])
def test_a_disk_that_fills_at_any_stage_ends_each_command_with_one_line(tmp_path: Path, ci_mcap, ci_run: Path,
                                                                         case: str) -> None:
    """A tmpfs that fills as each stage writes (its size from the ci run's products): h5py printed two tracebacks
    per object it released ("Exception ignored in: 'h5py._objects.ObjectID.__dealloc__'", 12 lines on `navigate`
    and `run` filling in the trajectory, 45 on `compare` in sar-min's, 25 from a batch's worker), libtiff printed
    "_tiffWriteProc: No space left on device." (2-3 lines; `focus --tiles 2`, `run` in the image), `focus` on 40 kB
    said "error: Write failed. See previous exception for details." (rasterio's words), and a batch's record said
    "[Errno 28] Unable to synchronously create file (file write failed: time = ..." Now the one line naming the
    output (a batch: its drive's failed line), exit 1, no partial file left; a run keeps what it finished and its
    run.json says the same line. The console script in a process of its own, as a user runs it."""
    import subprocess

    size = {p.name: p.stat().st_size for p in ci_run.iterdir()}
    drive, track = size["drive.h5"], size["trajectory.h5"]
    disk = tmp_path / "small"
    log, run_args = str(ci_mcap.log_path), [str(ci_run / "drive.h5"), "-t", str(ci_run / "trajectory.h5")]
    bytes_, out, args = {
        "navigate": (track // 2, disk / "trajectory.h5", ["navigate", str(ci_run / "drive.h5")]),
        "focus-tif": (40_000, disk / "img", ["focus", *run_args]),
        "focus-tiles": (250_000, disk / "img", ["focus", *run_args, "--tiles", "2"]),
        "compare-sar-min": (drive + track // 2 + 2 * 2**20, disk / "cmp", ["compare", log]),
        "run-navigate": (drive + track // 2, disk / "run", ["run", log]),
        "run-focus": (drive + track + 200_000, disk / "run", ["run", log]),
        "batch": (drive + track // 2, disk / "bat", ["batch", log, "-w", "1"]),
    }[case]
    (tmp_path / "patch").mkdir()
    (tmp_path / "patch" / "sitecustomize.py").write_text(_ESTIMATES_PASS)
    disk.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={bytes_}", "tmpfs", str(disk)], capture_output=True)
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({mounted.stderr.decode().strip()[:80]})")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path / "patch"), str(Path(__file__).parents[1])]),
           "COLUMNS": "300"}
    try:
        r = subprocess.run([sys.executable, "-m", "autosar_cli", *args, "-o", str(out)], capture_output=True,
                           text=True, timeout=300, env=env, cwd=tmp_path)
        left = sorted(str(p.relative_to(disk)) for p in disk.rglob("*"))
        manifest = json.loads(m.read_text()) if (m := out / "run.json").is_file() else None
        batch = json.loads(m.read_text()) if (m := out / "batch.json").is_file() else None
    finally:
        subprocess.run(["umount", str(disk)], capture_output=True)
    said = [ln for ln in r.stderr.splitlines() if ln.strip()]
    full = f"{out}: no space left on the device"
    if case == "batch":
        from autosar_cli.batch import drive_names

        name = drive_names([log])[0]
        assert said[:2] == [said[0], said[1]] and said[0].startswith("local cluster ") and said[1].startswith(
            "dashboard: "), r.stderr[-800:]
        assert (r.returncode, said[2:]) == (1, [f"failed: {name}: {out / name}: no space left on the device"]
                                            ), r.stderr[-800:]
        assert batch is not None and batch["drives"][0]["error"] == f"{out / name}: no space left on the device"
        assert batch["drives"][0]["attempts"] == 1  # not retried: each attempt filled the disk again
        assert not [p for p in left if ".partial" in p], left
        return
    assert (r.returncode, said) == (1, [f"error: {full}"]), r.stderr[-1500:]
    if case.startswith("run"):  # the products it finished kept, the run said failed in the same words
        assert manifest is not None and (manifest["status"], manifest["error"]) == ("failed", full)
        assert {"run/drive.h5", "run/run.json"} <= set(left) and not [p for p in left if ".partial" in p], left
    else:
        assert left == []


def test_hdf5s_runtime_error_of_a_full_disk_is_said_as_one(capsys: pytest.CaptureFixture[str]) -> None:
    """h5py raises a close the full disk refused as a RuntimeError whose text is HDF5's (its first line, as the
    error line was: "Can't close dataset (file write failed: time = Tue Dec  8 01:54:41 2026"): said as a full
    disk naming the output, and the process marked to end without the interpreter's shutdown."""
    import typer

    from autosar_cli import cli

    text = ("Can't close dataset (file write failed: time = Tue Dec  8 01:54:41 2026\n, filename = "
            "'/x/img.partial-20512.h5', file descriptor = 6, errno = 28, error message = 'No space left on device', "
            "buf = 0x5568cb13ea14, total write size = 48368, bytes this sub-write = 48368, offset = 77824)")
    try:
        with pytest.raises(typer.Exit) as stopped, cli._errors(Path("/x/img"), kernels=False):
            raise RuntimeError(text)
        assert stopped.value.exit_code == 1 and cli._state["disk_filled"]
    finally:
        cli._state["disk_filled"] = False
    assert capsys.readouterr().err == "error: /x/img: no space left on the device\n"
    with pytest.raises(typer.Exit), cli._errors(Path("/x/img"), kernels=False):
        raise RuntimeError("Can't close dataset (a failure of another kind)")
    assert not cli._state["disk_filled"] and "no space" not in capsys.readouterr().err


def test_every_command_refuses_an_existing_product_in_the_same_words(tmp_path: Path, ci_mcap, ci_run: Path) -> None:
    """ingest and navigate said "t.h5: already exists (use --overwrite to replace it)", focus "image.tif already
    exists; pass --overwrite to replace it": one wording, the file named first as in every other error."""
    for product, copy in (("drive.h5", "d.h5"), ("trajectory.h5", "t.h5"), ("image.tif", "i.tif")):
        shutil.copy(ci_run / product, tmp_path / copy)
    for args, refused in ((["ingest", str(ci_mcap.log_path), "-o", str(tmp_path / "d.h5")], "d.h5"),
                          (["navigate", str(ci_run / "drive.h5"), "-o", str(tmp_path / "t.h5")], "t.h5"),
                          (["focus", str(ci_run / "drive.h5"), "-t", str(ci_run / "trajectory.h5"), "-o",
                            str(tmp_path / "i")], "i.tif")):
        r = runner.invoke(app, args, env={"COLUMNS": "300"})
        _one_line_error(r)
        assert r.stderr == f"error: {tmp_path / refused}: already exists; pass --overwrite to replace it\n", args
