"""`autosar batch` on dask.distributed and focus in tiles: same products as one drive / one piece alone."""

from __future__ import annotations

import json
import logging
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import simulated
from typer.testing import CliRunner

from autosar_cli import batch as batch_mod
from autosar_cli.batch import BatchError, drive_names, read_batch, run_batch
from autosar_cli.cli import app
from autosar_cli.config import load_config
from autosar_cli.ingest.pipeline import IngestOptions, RadarCaptureOptions
from autosar_cli.run import run
from autosar_cli.sar.focus import FocusOptions
from autosar_cli.sar.grid import FocusGrid
from autosar_cli.sar.tiles import GridTile, focus_tiled, plan_grid, split_grid
from autosar_cli.store.image import read_image

runner = CliRunner()


@pytest.fixture(scope="module")
def logs(sim_dir: Path, ci_mcap, tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Two simulated ci drives (seeds 7 and 8) and a corrupt one (the first 64 kB of a ci log)."""
    work = tmp_path_factory.mktemp("batch_logs")
    other = simulated(sim_dir, "ci", "mcap", 8)
    a, b = work / "drive_a.mcap", work / "drive_b.mcap"
    shutil.copy(ci_mcap.log_path, a)
    shutil.copy(other.log_path, b)
    corrupt = work / "corrupt.mcap"
    corrupt.write_bytes(Path(ci_mcap.log_path).read_bytes()[:64_000])
    return [a, b, corrupt]


@pytest.fixture(scope="module")
def solo(logs: list[Path], tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """`autosar run` of each good drive alone, in this process: the reference products."""
    cfg = load_config()
    root = tmp_path_factory.mktemp("solo")
    for log in logs[:2]:
        run([log], root / log.stem, cfg)
    return {log.stem: root / log.stem for log in logs[:2]}


def test_batch_local_cluster_two_workers(logs, solo, tmp_path):
    out = tmp_path / "batch"
    r = runner.invoke(app, ["batch", *map(str, logs), "-o", str(out), "--workers", "2", "--retries", "1"])
    assert r.exit_code == 1, r.output  # one drive failed
    manifest = read_batch(out)
    assert manifest["cluster"]["kind"] == "local" and manifest["cluster"]["workers"] == 2
    assert manifest["cluster"]["numba_threads_per_task"] >= 1
    recs = {d["name"]: d for d in manifest["drives"]}
    assert list(recs) == ["drive_a", "drive_b", "corrupt"]
    assert (manifest["ok"], manifest["failed"]) == (2, 1)
    for name in ("drive_a", "drive_b"):
        assert recs[name]["status"] == "ok" and recs[name]["attempts"] == 1
        got = read_image(out / name / "image.h5")
        ref = read_image(solo[name] / "image.h5")
        assert got.grid == ref.grid
        # the same bits, whether a kernel was compiled in this process or loaded from numba's cache
        np.testing.assert_array_equal(got.image, ref.image, err_msg=name)
        assert json.loads((out / name / "run.json").read_text())["outputs"]["image"]["h5"] == "image.h5"
    bad = recs["corrupt"]
    assert bad["status"] == "failed" and "corrupt.mcap" in bad["error"]
    assert bad["attempts"] == 1  # a bad log is not retried
    assert "corrupt.mcap" in r.output  # reported on the console too
    # the batch's directory given where a run's goes: what it is and the runs it holds
    r = runner.invoke(app, ["evaluate", str(out), "-o", str(tmp_path / "evaluated")])
    assert r.exit_code == 1 and r.stderr.count("\n") == 1, r.output
    assert (f"{out}: no run.json, so not a run directory but a batch (batch.json); its runs: {out / 'drive_a'}, "
            f"{out / 'drive_b'}") in r.stderr, r.stderr


def test_batch_refuses_existing_and_bad_arguments(tmp_path, logs):
    # an input, or a file, as the batch's folder: the output gate's words (a raw "[Errno 17] File exists")
    for output, said in ((logs[0], "is an input of this command"), (tmp_path / "a_file", "exists and is not a dir")):
        (tmp_path / "a_file").write_text("the user's")
        r = runner.invoke(app, ["batch", str(logs[0]), "-o", str(output)])
        assert r.exit_code == 1 and r.stderr.count("\n") == 1 and f"{output}: {said}" in r.stderr, r.output
    (tmp_path / "batch.json").write_text("{}")
    with pytest.raises(BatchError, match="already holds a batch"):
        run_batch(logs, tmp_path, load_config())
    # one drive given twice (here by two spellings of its path) was run twice and counted as two
    with pytest.raises(BatchError, match=r"\(log 2 of 2\): the same drive as log 1 .*; give each drive once"):
        run_batch([logs[0], logs[0].parent / "." / logs[0].name], tmp_path / "twice", load_config())
    assert not (tmp_path / "twice").exists()
    with pytest.raises(BatchError, match="no drive logs"):
        run_batch([], tmp_path / "x", load_config())
    with pytest.raises(BatchError, match="either --scheduler"):
        run_batch(logs, tmp_path / "x", load_config(), scheduler="tcp://127.0.0.1:1", workers=2)


def test_drive_names_unique():
    assert drive_names(["a/x.mcap", "b/x.mcap", "c/x", "d/y.bag", "x-2.mcap"]) == ["x", "x-2", "x-3", "y", "x-2-2"]


@pytest.fixture(scope="module")
def thread_cluster():
    """An in-process cluster, one worker with one thread (monkeypatches reach its tasks)."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None,
                      silence_logs=logging.ERROR) as cluster:
        yield cluster


def _fake_manifest() -> dict:
    return {"stages": {"ingest": {"wall_s": 0.1}, "navigate": {"wall_s": 0.1},
                       "focus": {"wall_s": 0.1, "grid_shape": [2, 3], "frames_used": 5, "backprojections": 7}},
            "outputs": {"drive": "drive.h5", "image": {"h5": "image.h5"}}, "drive_s": 1.0}


def test_batch_existing_scheduler_retries_transient_errors(thread_cluster, tmp_path, monkeypatch):
    calls: dict[str, int] = {}
    autofocus: set[bool] = set()

    def flaky_run(logs, out_dir, config, **kw):
        name = Path(out_dir).name
        calls[name] = calls.get(name, 0) + 1
        autofocus.add(kw["autofocus"])
        if name == "broken" or calls[name] == 1:
            raise OSError(f"{logs[0]}: transient I/O error (attempt {calls[name]})")
        return _fake_manifest()

    monkeypatch.setattr(batch_mod, "run", flaky_run)
    m = run_batch([tmp_path / "flaky.mcap", tmp_path / "broken.mcap"], tmp_path / "out", load_config(),
                  scheduler=thread_cluster.scheduler_address, retries=2, autofocus=True)
    assert autofocus == {True} and m["autofocus"] is True  # `autosar batch --autofocus` reaches every drive's run
    recs = {d["name"]: d for d in m["drives"]}
    assert m["cluster"]["kind"] == "external"
    assert recs["flaky"]["status"] == "ok" and recs["flaky"]["attempts"] == 2
    assert recs["broken"]["status"] == "failed" and recs["broken"]["attempts"] == 3
    assert "broken.mcap: transient I/O error (attempt 3)" in recs["broken"]["error"]
    assert calls == {"flaky": 2, "broken": 3}


def test_batch_reads_every_drive_with_its_ingest_options(thread_cluster, tmp_path, monkeypatch):
    seen = []

    def fake_run(logs, out_dir, config, **kw):
        seen.append(kw["ingest_options"])
        return _fake_manifest()

    monkeypatch.setattr(batch_mod, "run", fake_run)
    logs = [tmp_path / "a.mcap", tmp_path / "b.mcap"]
    for log in logs:
        log.write_bytes(b"")
    dbc = Path("configs/autosar_giulia.dbc")
    r = runner.invoke(app, ["batch", *map(str, logs), "-o", str(tmp_path / "out"), "--scheduler",
                            thread_cluster.scheduler_address, "--dbc", str(dbc), "--allow-unverified",
                            "--allow-time-gap", "--max-time-gap", "60", "--radar-sync", "/dca/sync"])
    assert r.exit_code == 0, r.output
    want = IngestOptions(dbc.resolve(), RadarCaptureOptions(None, "/dca/sync", False), {}, 60.0, True, True)
    assert seen == [want, want]  # the DBC where the workers find it, as the logs
    r = runner.invoke(app, ["batch", *map(str, logs), "-o", str(tmp_path / "out2"), "--dbc", str(tmp_path / "no.dbc")])
    assert r.exit_code == 1 and r.stderr.strip() == f"error: {tmp_path / 'no.dbc'}: no such file or directory"
    assert len(seen) == 2 and not (tmp_path / "out2").exists()  # refused before any drive, not once per drive


def test_batch_reads_each_drives_can_and_nmea_logs_with_it(thread_cluster, tmp_path, monkeypatch):
    """`--can-log` and `--nmea` once per log, in the logs' order: each drive's run reads its own with its log, and a
    `--time-offset` goes to the drive that holds its log (batch had neither: a CAN log was a drive of its own)."""
    seen = {}

    def fake_run(logs, out_dir, config, **kw):
        seen[Path(out_dir).name] = ([Path(p).name for p in [*logs, *kw["can_logs"], *kw["nmea_logs"]]],
                                    kw["ingest_options"].time_offsets)
        kinds[Path(out_dir).name] = [[Path(p).name for p in kw[k]] for k in ("can_logs", "nmea_logs")]
        return _fake_manifest()

    kinds = {}
    monkeypatch.setattr(batch_mod, "run", fake_run)
    for name in ("a.mcap", "b.mcap", "a.asc", "b.asc", "a.nmea", "b.nmea"):
        (tmp_path / name).write_bytes(b"")
    args = ["batch", str(tmp_path / "a.mcap"), str(tmp_path / "b.mcap"), "--scheduler",
            thread_cluster.scheduler_address, "--can-log", str(tmp_path / "a.asc"), "--can-log",
            str(tmp_path / "b.asc"), "--nmea", str(tmp_path / "a.nmea"), "--nmea", str(tmp_path / "b.nmea")]
    r = runner.invoke(app, [*args, "-o", str(tmp_path / "out"), "--time-offset", f"{tmp_path / 'b.asc'}=7200"])
    assert r.exit_code == 0, r.output
    assert seen == {"a": (["a.mcap", "a.asc", "a.nmea"], {}),
                    "b": (["b.mcap", "b.asc", "b.nmea"], {(tmp_path / "b.asc").resolve(): 7200.0})}
    # read as what they are given as (a log given as --can-log is refused, as by `run --can-log`)
    assert kinds == {"a": [["a.asc"], ["a.nmea"]], "b": [["b.asc"], ["b.nmea"]]}
    for extra, message in ((["--can-log", str(tmp_path / "a.asc")], "--can-log given 3 times for 2 logs; give one "
                            "CAN log per log"),
                           (["--time-offset", f"{tmp_path / 'c.asc'}=1"], f"--time-offset {tmp_path / 'c.asc'}: not "
                            "one of the drives' --can-log or --nmea logs, nor a CAN or NMEA log of a drive folder")):
        r = runner.invoke(app, [*args, *extra, "-o", str(tmp_path / "out2")])
        assert r.exit_code == 1 and r.stderr.strip() == f"error: {message}", r.stderr
    assert len(seen) == 2 and not (tmp_path / "out2").exists()


def test_batch_takes_drive_folders_and_the_time_offsets_of_their_logs(thread_cluster, tmp_path, monkeypatch):
    """A drive folder (its log, its CAN logger's two split files) is one drive named after it, run on the folder; a
    `--time-offset` of one of its CAN logs was refused as naming no drive's --can-log."""
    seen = {}

    def fake_run(logs, out_dir, config, **kw):
        seen[Path(out_dir).name] = ([Path(p).name for p in logs], kw["ingest_options"].time_offsets)
        return _fake_manifest()

    monkeypatch.setattr(batch_mod, "run", fake_run)
    folder = tmp_path / "drive_7"
    folder.mkdir()
    for name in ("ros.mcap", "00000001.MF4", "00000002.MF4"):
        (folder / name).write_bytes(b"")
    (tmp_path / "b.mcap").write_bytes(b"")
    r = runner.invoke(app, ["batch", str(folder), str(tmp_path / "b.mcap"), "--scheduler",
                            thread_cluster.scheduler_address, "-o", str(tmp_path / "out"), "--time-offset",
                            f"{folder / '00000002.MF4'}=-3.5"])
    assert r.exit_code == 0, r.output
    assert seen == {"drive_7": (["drive_7"], {(folder / "00000002.MF4").resolve(): -3.5}), "b": (["b.mcap"], {})}


def test_split_grid_positions_bit_identical():
    grid = FocusGrid((12.345678, -3.21), (0.6, 0.8), (0.8, -0.6), 0.04, 61, 7, 0.5)
    tiles = split_grid(grid, 4)
    assert [t.n_along for t in tiles] == [15, 15, 16, 15] and all(isinstance(t, GridTile) for t in tiles)
    assert [t.col0 for t in tiles] == [0, 15, 30, 46]
    full = grid.positions()
    assert np.array_equal(np.concatenate([t.positions() for t in tiles], axis=1), full)
    rows, cols = tiles[2].enu_to_pixel(full[3, 33])
    assert (round(float(rows), 9), round(float(cols), 9)) == (3, 3)
    assert np.allclose(tiles[1].origin, full[0, 15, :2])
    assert len(split_grid(grid, 100)) == 61


def test_focus_in_four_tiles_equals_one_piece(solo, tmp_path, thread_cluster):
    d = solo["drive_a"]
    one = read_image(d / "image.h5")  # focused in one piece by `autosar run`
    cfg = load_config()
    assert plan_grid(d / "drive.h5", d / "trajectory.h5", cfg, FocusOptions.from_config(cfg)) == one.grid
    r = runner.invoke(app, ["focus", str(d / "drive.h5"), "-t", str(d / "trajectory.h5"), "-o",
                            str(tmp_path / "tiled"), "--tiles", "4", "--json"])
    assert r.exit_code == 0, r.output
    tiled = read_image(tmp_path / "tiled.h5")
    assert tiled.grid == one.grid and tiled.provenance["tiles"] == 4
    assert np.array_equal(tiled.image, one.image)  # bit for bit
    assert tiled.params["backprojections"] == one.params["backprojections"]
    # the same as Dask tasks
    from distributed import Client

    with Client(thread_cluster) as client:
        rep = focus_tiled(d / "drive.h5", d / "trajectory.h5", tmp_path / "dask", cfg, FocusOptions.from_config(cfg),
                          tiles=4, client=client)
    assert rep.grid_shape == one.grid.shape
    assert np.array_equal(read_image(tmp_path / "dask.h5").image, one.image)


def test_a_drives_retry_replaces_its_first_attempts_products(ci_mcap, tmp_path, monkeypatch):
    """A drive's task retried after an I/O error finds the drive.h5 its first attempt wrote: the retry failed on
    it ("already exists (use --overwrite ...)") once run stopped replacing products without --overwrite. A
    batch's run replaces autosar's products in a drive directory whose run.json says the run did not finish."""
    import autosar_cli.nav.navigate as nav_mod

    real = nav_mod.navigate
    attempts: list[int] = []

    def flaky(*args, **kw):
        attempts.append(1)
        if len(attempts) == 1:
            raise OSError("transient I/O error")
        return real(*args, **kw)

    monkeypatch.setattr(nav_mod, "navigate", flaky)
    out = tmp_path / "ci"
    with pytest.raises(OSError, match="transient"):  # not an input error: Dask retries it
        batch_mod.run_drive("ci", [str(ci_mcap.log_path)], str(out), load_config())
    assert (out / "drive.h5").exists() and json.loads((out / "run.json").read_text())["status"] == "failed"
    record = batch_mod.run_drive("ci", [str(ci_mcap.log_path)], str(out), load_config())
    assert record["status"] == "ok", record.get("error")
    # a finished drive is not replaced without --overwrite
    record = batch_mod.run_drive("ci", [str(ci_mcap.log_path)], str(out), load_config())
    assert record["status"] == "failed" and "already holds a run" in record["error"]


def test_a_stopped_batch_keeps_what_finished_and_resume_runs_the_rest(thread_cluster, tmp_path, monkeypatch):
    """Ctrl-C (a KeyboardInterrupt in the client) after the first drive: batch.json is written ``interrupted`` with
    every drive's record; --resume keeps the drive that finished, and the one whose task went on on the existing
    cluster and finished after the stop (its run.json says so; resumed while it still runs, refused), and runs only
    the last. A drive whose log or settings changed is run again over its run; a drive added runs alone."""
    import threading

    ran: list[str] = []
    release, second_started = threading.Event(), threading.Event()

    def fake_run(logs, out_dir, config, **kw):
        name = Path(out_dir).name
        ran.append(name)
        Path(out_dir).mkdir(parents=True, exist_ok=True)
        if len(ran) == 2:  # running when the batch stops, as a run is: run.json unfinished
            (Path(out_dir) / "run.json").write_text(json.dumps({"format": "autosar-run", "status": "unfinished"}))
            second_started.set()
            release.wait(30)
        (Path(out_dir) / "run.json").write_text(json.dumps({"format": "autosar-run", "status": "ok",
                                                            **_fake_manifest()}))
        return _fake_manifest()

    def stop_after_the_first(event):
        if event.get("stage") == "finished":  # the first drive's record, in the client's thread, while one runs
            assert second_started.wait(30)
            raise KeyboardInterrupt

    monkeypatch.setattr(batch_mod, "run", fake_run)
    logs = [tmp_path / f"{n}.mcap" for n in "abc"]
    out = tmp_path / "out"
    cluster = thread_cluster.scheduler_address
    with pytest.raises(KeyboardInterrupt) as stopped:
        run_batch(logs, out, load_config(), scheduler=cluster, progress=stop_after_the_first)
    m = read_batch(out)
    # the one thread takes the drives in the order the scheduler gives (mostly a, b, c; not always)
    first, second = ran
    (third,) = {"a", "b", "c"} - {first, second}
    assert stopped.value.batch_manifest == m and m["status"] == "interrupted"
    drives = {d["name"]: d for d in m["drives"]}
    assert [d["name"] for d in m["drives"]] == ["a", "b", "c"]
    assert [drives[n]["status"] for n in (first, second, third)] == ["ok", "interrupted", "interrupted"]
    assert (m["ok"], m["interrupted"]) == (1, 2)
    assert drives[third]["attempts"] == 0 and drives[second]["logs"] == [str((tmp_path / f"{second}.mcap").resolve())]
    assert "may still finish" in drives[second]["error"]  # on an existing cluster, its task goes on
    with pytest.raises(BatchError, match=rf"out/{second}: its run may still be going on the cluster the batch stopped"):
        run_batch(logs, out, load_config(), scheduler=cluster, resume=True)
    release.set()
    for _ in range(300):  # the second's run finishes after the batch stopped
        if '"ok"' in (out / second / "run.json").read_text():
            break
        threading.Event().wait(0.1)
    with pytest.raises(BatchError, match=r"already holds a batch \(batch.json: interrupted, 1 of 3 drives done\); "
                                         "pass --resume"):
        run_batch(logs, out, load_config(), scheduler=cluster)
    with pytest.raises(BatchError, match="not both"):
        run_batch(logs, out, load_config(), scheduler=cluster, resume=True, overwrite=True)
    r = runner.invoke(app, ["batch", *map(str, logs), "-o", str(out), "--scheduler", cluster, "--resume"])
    assert r.exit_code == 0, r.output
    assert ran == [first, second, third]  # only the third ran again
    m = read_batch(out)
    assert m["status"] == "finished" and (m["ok"], m["kept"], m["interrupted"]) == (3, 2, 0)
    assert [d.get("kept", False) for d in m["drives"]] == [n != third for n in "abc"]
    assert "3 of 3 drives done, 2 kept from before" in " ".join(r.stdout.split())
    # another log under a's name: its run is replaced (run() refused it: "already holds a run"), b and c kept
    other = tmp_path / "elsewhere" / "a.mcap"
    other.parent.mkdir()
    m = run_batch([other, *logs[1:]], out, load_config(), scheduler=cluster, resume=True)
    assert ran[3:] == ["a"] and [d["status"] for d in m["drives"]] == ["ok"] * 3
    assert m["drives"][0]["logs"] == [str(other.resolve())] and m["kept"] == 2
    # other settings (here --autofocus): no drive is kept, each run again over its own
    m = run_batch([other, *logs[1:]], out, load_config(), scheduler=cluster, resume=True, autofocus=True)
    assert sorted(ran[4:]) == ["a", "b", "c"] and m["kept"] == 0 and m["ok"] == 3
    # the same settings again, from another working directory and a log list grown by one: only the new one runs
    extra = tmp_path / "d.mcap"
    monkeypatch.chdir(tmp_path / "elsewhere")
    m = run_batch([Path("a.mcap"), *logs[1:], extra], out, load_config(), scheduler=cluster, resume=True,
                  autofocus=True)
    assert ran[7:] == ["d"] and m["kept"] == 3
    with pytest.raises(BatchError, match="holds no batch"):
        run_batch(logs, tmp_path / "none", load_config(), scheduler=cluster, resume=True)


def test_a_stopped_local_clusters_runs_are_marked(tmp_path):
    """A run whose worker stopped with the local cluster is marked as the run marks its own at Ctrl-C: interrupted
    where it kept a drive, else gone with its folder and its dead writer's partial file; nothing else changes."""
    from autosar_cli.run import mark_interrupted, read_manifest

    kept, empty, done, users = (tmp_path / n for n in ("kept", "empty", "done", "users"))
    for d, status in ((kept, "unfinished"), (empty, "unfinished"), (done, "ok"), (users, "unfinished")):
        d.mkdir()
        (d / "run.json").write_text(json.dumps({"format": "autosar-run", "status": status, "stages": {}}))
    (kept / "drive.h5").write_bytes(b"x")
    (empty / "drive.partial-4194303.h5").write_bytes(b"x")  # a pid no process has (above Linux's pid_max)
    (users / "notes.txt").write_text("the user's")
    for d in (kept, empty, done, users):
        mark_interrupted(d)
    assert read_manifest(kept)["status"] == "interrupted" and read_manifest(kept)["error"] == "interrupted"
    assert not empty.exists()
    assert read_manifest(done)["status"] == "ok"
    assert [p.name for p in users.iterdir()] == ["notes.txt"]


def test_ctrl_c_while_the_local_clusters_workers_start_is_one_line(ci_mcap, tmp_path):
    """Ctrl-C to the whole process group (a terminal's) while the workers import: each printed the traceback of
    whatever it was importing, and the half-started cluster an AssertionError at exit. The workers ignore SIGINT
    (the command stops them), and the command stops once its cluster is up: "interrupted", 130, nothing left.
    Sent once a worker has numpy loaded, in the midst of its imports (in its interpreter's own first tens of ms,
    before it has read autosar's package, Python's default handler still stands)."""
    import signal
    import subprocess
    import time

    from test_safety import _as_from_a_terminal, _console_script

    script = _console_script()
    if script is None:
        pytest.skip("the autosar console script is not installed")
    out = tmp_path / "out"
    other = tmp_path / "other.mcap"  # two drives, two workers
    shutil.copy(ci_mcap.log_path, other)
    proc = subprocess.Popen([script, "batch", str(ci_mcap.log_path), str(other), "-o", str(out),
                             "--workers", "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: (_as_from_a_terminal(), os.setpgrp()))
    importing = False
    deadline = time.monotonic() + 120
    while not importing and time.monotonic() < deadline and proc.poll() is None:
        for stat in Path("/proc").glob("[0-9]*/stat"):
            try:
                child = int(stat.read_text().rsplit(")", 1)[1].split()[1]) == proc.pid
                importing = importing or (child and "numpy" in (stat.parent / "maps").read_text())
            except OSError:
                continue
        time.sleep(0.02)
    assert importing, "no worker process was seen importing"
    os.killpg(proc.pid, signal.SIGINT)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    assert stderr.strip().endswith("error: interrupted"), stderr
    assert not out.exists()  # no drive had started: no batch.json, no folder


def test_drives_run_in_the_order_given(thread_cluster, tmp_path, monkeypatch):
    """On one thread the drives run as listed (submits within Dask's 60 ms tie in priority, and the scheduler then
    takes them in no set order)."""
    ran: list[str] = []

    def fake_run(logs, out_dir, config, **kw):
        ran.append(Path(out_dir).name)
        return _fake_manifest()

    monkeypatch.setattr(batch_mod, "run", fake_run)
    names = [f"d{i:02d}" for i in range(12)][::-1]
    m = run_batch([tmp_path / f"{n}.mcap" for n in names], tmp_path / "out", load_config(),
                  scheduler=thread_cluster.scheduler_address)
    assert m["ok"] == 12 and ran == names
