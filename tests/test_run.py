"""`autosar run`'s ingest in a forked child (while the parent prepares the later stages) and the kernel cache
preloading that the parent does meanwhile."""

from __future__ import annotations

import pickle
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from autosar_cli.config import load_config
from autosar_cli.ingest.pipeline import IngestError
from autosar_cli.run import RunError, _fork_context, _ingest_beside_imports, _ingest_child

CFG = load_config()
needs_fork = pytest.mark.skipif(_fork_context() is None, reason="no fork on this platform")


def _radar(path: Path) -> tuple[np.ndarray, np.ndarray]:
    with h5py.File(path, "r") as f:
        g = f["radar"][next(iter(f["radar"]))]
        return g["t_ns"][()], g["raw"][::97]


@needs_fork
def test_forked_ingest_equals_the_ingest_in_this_process(ci_mcap, tmp_path: Path) -> None:
    seen: list[tuple[int, int]] = []
    forked = _ingest_beside_imports([ci_mcap.log_path], tmp_path / "forked.h5", CFG,
                                    lambda d, t: seen.append((d, t)), "test", fork=True)
    alone = _ingest_beside_imports([ci_mcap.log_path], tmp_path / "alone.h5", CFG, lambda d, t: None, "test",
                                   fork=False)
    for key in ("messages", "bytes_read", "start_ns", "end_ns", "warnings"):
        assert forked[key] == alone[key], key
    assert forked["messages"] > 1000
    t_f, raw_f = _radar(tmp_path / "forked.h5")
    t_a, raw_a = _radar(tmp_path / "alone.h5")
    assert len(t_f) > 100 and np.array_equal(t_f, t_a) and np.array_equal(raw_f, raw_a)
    # the child's progress reached the parent, ending with the whole log
    assert seen and seen[-1][0] == seen[-1][1] == forked["bytes_read"]


@needs_fork
def test_forked_ingest_raises_the_childs_error_with_its_traceback(tmp_path: Path) -> None:
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(np.random.default_rng(0).bytes(4096))
    with pytest.raises(IngestError, match="not an MCAP file") as info:
        _ingest_beside_imports([bad], tmp_path / "drive.h5", CFG, lambda d, t: None, "test", fork=True)
    assert "Traceback" in str(info.value.__cause__)  # the child's, shown with --debug
    assert not (tmp_path / "drive.h5").exists()


class _Unpicklable(RuntimeError):
    def __init__(self, message: str, extra: object) -> None:
        super().__init__(message)
        self.extra = extra

    def __reduce__(self):  # noqa: ANN204 - refuses pickling, like an exception holding an open file
        raise TypeError("cannot pickle")


def test_an_error_that_does_not_pickle_comes_back_as_a_run_error(monkeypatch: pytest.MonkeyPatch,
                                                                 tmp_path: Path) -> None:
    def failing_ingest(*args: object, **kwargs: object) -> None:
        raise _Unpicklable("bad.mcap: the reader broke", object())

    import autosar_cli.ingest.pipeline as pipeline

    monkeypatch.setattr(pipeline, "ingest", failing_ingest)
    sent: list[tuple[object, ...]] = []

    class Pipe:
        def send(self, msg: tuple[object, ...]) -> None:
            sent.append(pickle.loads(pickle.dumps(msg)))

        def close(self) -> None:
            pass

    # the forked child's own signal handlers and unraisable hook, set here in this process: put back after
    import signal

    monkeypatch.setattr(sys, "unraisablehook", sys.unraisablehook)
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        _ingest_child(Pipe(), [tmp_path / "bad.mcap"], tmp_path / "drive.h5", CFG, "test")
    finally:
        for signum, handler in handlers.items():
            signal.signal(signum, handler)
    kind, exc, remote = sent[-1]
    assert kind == "error" and isinstance(exc, RunError) and str(exc) == "bad.mcap: the reader broke"
    assert "_Unpicklable" in remote


def test_cached_kernels_load_before_their_first_call(tmp_path: Path) -> None:
    """In a fresh process, the back-projection kernel's cached specialisation is loaded without a call, and the
    first call then compiles nothing (numba's cache of this checkout is filled by this process first)."""
    from autosar_cli.sar.backprojection import backproject

    prof = np.ones((1, 8, 32), np.complex64)
    ant = np.zeros((2, 32, 3))
    ant[:, :, 0] = np.arange(32) * 0.004
    args = dict(range0_m=0.0, bin_m=0.1, cycles_per_m=262.0)
    backproject(prof, ant, [[0, 1]], np.array([[0.05, -1.0, 0.0]]), np.array([[0, 32]]), **args)  # cached now
    code = (
        "import time\n"
        "from autosar_cli.kernel_cache import load_cached_kernels\n"
        "from autosar_cli.sar import backprojection as bp\n"
        "assert not bp._tdbp.overloads\n"
        "n = load_cached_kernels(bp)\n"
        "assert n >= 1 and bp._tdbp.overloads, n\n"
        "print(n)\n"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert res.returncode == 0, res.stderr
    assert int(res.stdout.strip()) >= 1


@pytest.mark.parametrize("stop", [RuntimeError("focus broke"), KeyboardInterrupt()])
def test_a_run_stopped_after_its_ingest_is_marked_unfinished(ci_mcap, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                             stop: BaseException) -> None:
    """A run that fails (or is interrupted) in focus kept its drive and trajectory without a run.json: `info
    --verify` called the directory intact and a rerun said only "pass --overwrite". Its run.json now says
    ``failed`` / ``interrupted`` with the error; `info --verify` and `evaluate` say the run did not finish, a rerun
    names why it refuses, and a batch's retry (``replace_unfinished``) replaces it."""
    import json

    from typer.testing import CliRunner

    import autosar_cli.sar.focus as focus_module
    from autosar_cli.cli import app
    from autosar_cli.run import run

    def broken_focus(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise stop

    out = tmp_path / "run"
    with monkeypatch.context() as m:
        m.setattr(focus_module, "focus", broken_focus)
        with pytest.raises(type(stop)):
            run([ci_mcap.log_path], out, CFG)
    status = "failed" if isinstance(stop, RuntimeError) else "interrupted"
    manifest = json.loads((out / "run.json").read_text())
    assert manifest["status"] == status and manifest["error"] == ("focus broke" if status == "failed" else status)
    assert manifest["outputs"] == {"drive": "drive.h5", "trajectory": "trajectory.h5"}
    assert sorted(p.name for p in out.iterdir()) == ["drive.h5", "run.json", "trajectory.h5"]
    said = f"the run did not finish ({status}: {manifest['error']})"
    r = CliRunner().invoke(app, ["info", str(out), "--verify"])
    assert r.exit_code == 1 and said in r.output.replace("\n", ""), r.output
    r = CliRunner().invoke(app, ["evaluate", str(out), "-o", str(tmp_path / "ev")])
    assert r.exit_code == 1 and said in r.stderr.replace("\n", ""), r.output
    with pytest.raises(RunError, match=f"already holds a run \\(run.json: {status}\\); pass --overwrite"):
        run([ci_mcap.log_path], out, CFG)
    assert json.loads((out / "run.json").read_text())["status"] == status  # untouched by the refusal
    manifest = run([ci_mcap.log_path], out, CFG, replace_unfinished=True)
    assert manifest["status"] == "ok" and json.loads((out / "run.json").read_text())["status"] == "ok"


def test_a_stage_failing_after_a_damaged_ingest_says_what_the_ingest_found(ci_mcap, tmp_path: Path) -> None:
    """The first 300 kB of a log: its ingest keeps 20 messages and warns of the cut; the navigation then finds no
    GNSS. `run` and `compare` said only the navigation's error (about their own drive.h5), and batch's record of
    the drive had no warnings: the cut, the cause, is now said before the error and kept in the record."""
    from typer.testing import CliRunner

    import autosar_cli.batch as batch_module
    from autosar_cli.cli import app

    cut = tmp_path / "cut.mcap"
    cut.write_bytes(Path(ci_mcap.log_path).read_bytes()[:300_000])
    damage = f"{cut}: damaged MCAP at byte"
    for args in (["run", str(cut), "-o", str(tmp_path / "run")], ["compare", str(cut), "-o", str(tmp_path / "cmp")]):
        r = CliRunner().invoke(app, args)
        lines = r.stderr.strip().splitlines()
        assert r.exit_code == 1 and len(lines) == 2, r.output
        assert lines[0].startswith(f"warning: {damage}") and lines[1].startswith("error: ") and "no GNSS" in lines[1]
    record = batch_module.run_drive("cut", [str(cut)], str(tmp_path / "batch" / "cut"), CFG)
    assert record["status"] == "failed" and "no GNSS" in record["error"]
    assert len(record["warnings"]) == 1 and record["warnings"][0].startswith(damage)


def test_a_run_stopped_as_its_ingest_ends_keeps_no_drive_unmarked(ci_mcap, tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """A stop that came after the ingest had written drive.h5 but before it reported back left the drive without a
    run.json (SIGTERM under `python -m`, 3 s into a run). run.json is now written first, as `unfinished`: such a
    run is marked `interrupted`; one whose ingest failed whole leaves nothing at all."""
    import json

    import autosar_cli.run as run_module

    real = run_module._ingest_beside_imports

    def ingest_then_stop(*args, **kwargs):  # type: ignore[no-untyped-def]
        real(*args, **kwargs)
        raise KeyboardInterrupt

    monkeypatch.setattr(run_module, "_ingest_beside_imports", ingest_then_stop)
    out = tmp_path / "run"
    with pytest.raises(KeyboardInterrupt):
        run_module.run([ci_mcap.log_path], out, CFG)
    assert sorted(p.name for p in out.iterdir()) == ["drive.h5", "run.json"]
    assert json.loads((out / "run.json").read_text())["status"] == "interrupted"

    def failing_ingest(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise IngestError("bad.mcap: unreadable")

    monkeypatch.setattr(run_module, "_ingest_beside_imports", failing_ingest)
    with pytest.raises(IngestError):
        run_module.run([ci_mcap.log_path], tmp_path / "none", CFG)
    assert not (tmp_path / "none").exists()


@pytest.mark.parametrize("given", ["a drive", "missing"])
def test_a_truth_sidecar_that_is_none_is_refused_before_the_ingest(given: str, ci_mcap, ci_run: Path,
                                                                   tmp_path: Path) -> None:
    """`run -m truth --truth FILE` where FILE is another of autosar's files or missing: refused after the whole
    ingest (minutes on a long drive), which left the run's directory with its drive.h5 and a failed run.json; now
    refused first, nothing written."""
    from autosar_cli.run import run

    truth = ci_run / "drive.h5" if given == "a drive" else tmp_path / "typo.truth.h5"
    said = "not an autosar truth sidecar but an autosar-drive file" if given == "a drive" else "no such truth sidecar"
    out = tmp_path / "run"
    with pytest.raises(RunError, match=f"^{truth}: {said}$"):
        run([ci_mcap.log_path], out, load_config(), method="truth", truth_path=truth)
    assert not out.exists()


def test_run_m_truth_with_no_sidecar_beside_its_log_is_refused_before_the_ingest(ci_mcap, tmp_path: Path) -> None:
    """`run -m truth` without --truth on a log with no <log>.truth.h5 beside it: the ingest ran whole, then navigate
    said 'out/drive.h5: no truth sidecar found', leaving drive.h5 and a failed run.json (the check before the ingest
    took only a --truth given); now refused first, nothing written."""
    import shutil

    from autosar_cli.run import run

    lone = tmp_path / "lone.mcap"
    shutil.copy(ci_mcap.log_path, lone)
    out = tmp_path / "run"
    with pytest.raises(RunError, match=f"^{lone}: no truth sidecar \\(<log>.truth.h5\\) beside the inputs; give "
                                       "--truth LOG.truth.h5$"):
        run([lone], out, load_config(), method="truth")
    assert not out.exists()


def test_run_json_gives_the_images_enu_box_as_focus_json_does(ci_run: Path) -> None:
    """`focus --json` gives the grid's ENU box (grid_enu_m: x0, y0, x1, y1, to choose a --grid by); run.json's focus
    stage gave its shape alone, so a run's user had to open image.h5 to find where the image lies."""
    import json

    from autosar_cli.sar.focus import grid_enu_box
    from autosar_cli.store.image import read_image

    focus = json.loads((ci_run / "run.json").read_text())["stages"]["focus"]
    grid = read_image(ci_run / "image.h5").grid
    assert focus["grid_enu_m"] == list(grid_enu_box(grid)) and focus["grid_shape"] == list(grid.shape)
    corners = grid.corners_enu()
    np.testing.assert_allclose(focus["grid_enu_m"], [*corners.min(axis=0), *corners.max(axis=0)], atol=1e-3)
