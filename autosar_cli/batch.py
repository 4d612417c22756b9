"""``autosar batch``: one ``autosar run`` per drive, as Dask tasks on a dask.distributed cluster.

Each drive log becomes one task (:func:`run_drive`) that runs :func:`autosar_cli.run.run` into
``DIR/<drive>/`` and returns a small status record; the products are exactly those of ``autosar run`` on
that log alone. The cluster is a :class:`~distributed.LocalCluster` of ``workers`` processes (one task
thread each) unless ``scheduler`` names an existing one (then logs and DIR must be reachable at the same
paths from every worker).

Failures: a drive whose input is bad (corrupt or missing log, no usable data: the ``ValueError`` family and
the ingest errors, whose messages name the file) ends at once as a ``failed`` record and never stops the
other drives. Anything else (an ``OSError`` on a shared file system, ``MemoryError``, a worker that
died) is raised so that Dask retries the task ``retries`` times, on any worker; if it still fails, the
drive's record is ``failed`` with the last error. ``DIR/batch.json`` (format ``autosar-batch`` v1) keeps
every record, the cluster (scheduler address, dashboard link), and the timings.

Threads: every worker runs one task at a time (``threads_per_worker=1``) and its numba kernels with
``numba_threads`` threads (default: cores // workers for a local cluster, so 2 workers on 2 cores do
not oversubscribe; set per task with ``numba.set_num_threads``, and as ``NUMBA_NUM_THREADS`` in the
environment of local workers). A worker process compiles or loads the cached kernels once and keeps
them for all its drives.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import os
import platform
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from autosar_cli import __version__
from autosar_cli.config import Config
from autosar_cli.disk_full import disk_full_said, drop_disk_full_reports, is_disk_full, reports_held
from autosar_cli.ingest.canlog import CanLogError
from autosar_cli.ingest.inputs import drive_folder
from autosar_cli.ingest.pipeline import IngestError, IngestOptions
from autosar_cli.ingest.sources import LogReadError
from autosar_cli.interrupts import interrupts_held
from autosar_cli.run import mark_interrupted, run, run_warnings
from autosar_cli.sar.focus import FocusOptions
from autosar_cli.store.manifest import product_status, read_json_manifest, strict_json, write_json
from autosar_cli.store.outputs import DiskFullError, check_output, input_problem

FORMAT = "autosar-batch"
FORMAT_VERSION = 1
MANIFEST = "batch.json"
DEFAULT_RETRIES = 2

#: Errors that say the drive itself is bad, or its output's disk full: retrying cannot help, the drive is reported
#: failed at once (a full disk was tried three times, each attempt writing until the disk refused it again).
INPUT_ERRORS: tuple[type[BaseException], ...] = (
    ValueError, LookupError, IngestError, LogReadError, CanLogError, EOFError, FileNotFoundError,
    FileExistsError, IsADirectoryError, NotADirectoryError, PermissionError, DiskFullError,
)


class BatchError(ValueError):
    """A batch cannot start (no logs, DIR holds another batch, bad worker count); the message says why."""


def drive_names(logs: Sequence[str | Path]) -> list[str]:
    """One directory name per log: its name without the container suffix, made unique with -2, -3, ..."""
    names: list[str] = []
    seen: dict[str, int] = {}
    for log in logs:
        p = Path(log)
        base = p.stem if p.suffix.lower() in (".mcap", ".bag", ".db3") else p.name
        base = base or "drive"
        seen[base] = seen.get(base, 0) + 1
        name = base if seen[base] == 1 else f"{base}-{seen[base]}"
        while name in names:  # e.g. logs named "a-2" and "a", "a"
            seen[base] += 1
            name = f"{base}-{seen[base]}"
        names.append(name)
    return names


def _worker_address() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return f"{platform.node()}:{os.getpid()} (no worker)"


def _reporter(topic: str | None, name: str, min_interval_s: float = 0.25) -> Callable[[str, int, int], None]:
    """``progress(stage, done, total)`` that sends throttled events to the client (via the scheduler)."""
    if topic is None:
        return lambda stage, done, total: None
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError):
        return lambda stage, done, total: None
    last: dict[str, float] = {}

    def send(stage: str, done: int, total: int) -> None:
        now = time.monotonic()
        if done < total and now - last.get(stage, 0.0) < min_interval_s:
            return
        last[stage] = now
        worker.log_event(topic, {"drive": name, "stage": stage, "done": int(done), "total": int(total)})

    return send


def run_drive(name: str, logs: Sequence[str], out_dir: str, config: Config, *, method: str = "sar-min",
              options: FocusOptions | None = None, truth_path: str | None = None, autofocus: bool = False,
              overwrite: bool = False, ingest_options: IngestOptions | None = None,
              numba_threads: int | None = None, progress_topic: str | None = None,
              command: str = "", can_logs: Sequence[str] = (), nmea_logs: Sequence[str] = (),
              radar_captures: Sequence[str] = ()) -> dict[str, Any]:
    """The Dask task of one drive: :func:`autosar_cli.run.run` into ``out_dir``; returns its status record.
    ``can_logs``, ``nmea_logs``, ``radar_captures``: read as such, as ``run`` reads them.

    Input errors (:data:`INPUT_ERRORS`) give a ``failed`` record; any other exception propagates so that
    Dask retries the task.
    """
    if numba_threads:
        import numba

        numba.set_num_threads(max(1, min(int(numba_threads), numba.config.NUMBA_NUM_THREADS)))
    report = _reporter(progress_topic, name)
    report("start", 0, 1)
    record: dict[str, Any] = {"name": name, "logs": [str(p) for p in [*logs, *can_logs, *nmea_logs, *radar_captures]],
                              "output": str(out_dir),
                              "worker": _worker_address()}
    t0 = time.perf_counter()
    try:
        manifest = _run_said_full(out_dir, lambda: run(
            logs, out_dir, config, method=method, options=options, truth_path=truth_path, autofocus=autofocus,
            overwrite=overwrite, progress=report, command=command,
            ingest_options=ingest_options, can_logs=can_logs, nmea_logs=nmea_logs, radar_captures=radar_captures,
            replace_unfinished=True))  # a retry finds the products of its attempt before
    except INPUT_ERRORS as exc:
        record.update(status="failed", error=_message(exc), error_type=type(exc).__name__,
                      warnings=[str(w) for w in getattr(exc, "warnings", [])], wall_s=time.perf_counter() - t0)
        report("failed", 1, 1)
        return record
    record.update(_finished_run(manifest), wall_s=time.perf_counter() - t0)
    report("done", 1, 1)
    return record


def _run_said_full(out_dir: str, run_it: Callable[[], dict[str, Any]]) -> dict[str, Any]:
    """``run_it()``; a full disk raised as DiskFullError naming the run (``out_dir``). h5py's objects of the files
    the disk refused are released when the worker lets the error go, or at a later collection (forced, the worker
    crashed), after :func:`reports_held`: their reports of the full disk are dropped in this worker from then on."""
    try:
        with reports_held():  # h5py's tracebacks of a full disk on the worker's stderr: its error says it
            return run_it()
    except Exception as exc:
        if not is_disk_full(exc):
            raise
        said = disk_full_said(exc, out_dir)
        drop_disk_full_reports()  # those of its files released later, in this process, are said by it too
    raise DiskFullError(said)


def _finished_run(manifest: dict[str, Any]) -> dict[str, Any]:
    """What a drive's record says of its finished run, from its run.json."""
    st = manifest["stages"]
    warnings = run_warnings(manifest)
    return {"status": product_status(warnings), "error": None, "warnings": warnings,
            "drive_s": manifest.get("drive_s"), "stages_s": {k: v["wall_s"] for k, v in st.items()},
            "grid_shape": st["focus"]["grid_shape"], "frames_used": st["focus"]["frames_used"],
            "backprojections": st["focus"]["backprojections"],
            "outputs": {"run": "run.json", **{k: v for k, v in manifest["outputs"].items() if k != "image"},
                        **{f"image_{k}": v for k, v in manifest["outputs"].get("image", {}).items()}}}


#: Imported on every worker before the first drive (the chain imports some of them on first use).
WARM_IMPORTS = ("autosar_cli.run", "autosar_cli.ingest.pipeline", "autosar_cli.ingest.mcap_source",
                "autosar_cli.ingest.nmea", "autosar_cli.nav.navigate", "autosar_cli.sar.focus",
                "autosar_cli.store.trajectory", "autosar_cli.nav.sarmin_kernel", "pyproj", "matplotlib.figure",
                "matplotlib.backends.backend_agg")


def _warm_worker() -> dict[str, Any]:
    """Run on every worker before the drives: import the chain once (so drive timings exclude it)."""
    import importlib

    import numba

    importlib.import_module("autosar_cli.run")  # must work: the tasks need it
    for name in WARM_IMPORTS[1:]:
        try:
            importlib.import_module(name)
        except ImportError:  # pragma: no cover - a module moved: warming is only an optimisation
            pass
    return {"pid": os.getpid(), "numba_threads": int(numba.config.NUMBA_NUM_THREADS)}


def _message(exc: BaseException) -> str:
    msg = str(exc).splitlines()[0] if str(exc) else ""
    return msg or type(exc).__name__


def _dashboard(client: Any) -> str | None:
    try:
        services = client.scheduler_info().get("services", {})
    except Exception:  # noqa: BLE001 - the link is a nicety
        return None
    return str(client.dashboard_link) if "dashboard" in services else None


def run_batch(logs: Sequence[str | Path], out_dir: str | Path, config: Config, *, method: str = "sar-min",
              autofocus: bool = False, options: FocusOptions | None = None, scheduler: str | None = None,
              workers: int | None = None, retries: int = DEFAULT_RETRIES, numba_threads: int | None = None,
              overwrite: bool = False, radars: Sequence[str | Path] | None = None,
              can_logs: Sequence[str | Path] | None = None, nmea_logs: Sequence[str | Path] | None = None,
              radar_starts: Sequence[int] | None = None, ingest_options: IngestOptions | None = None,
              progress: Callable[[dict[str, Any]], None] | None = None,
              on_cluster: Callable[[dict[str, Any]], None] | None = None, command: str = "",
              resume: bool = False) -> dict[str, Any]:
    """Run every log as its own drive into ``out_dir/<name>/`` on a Dask cluster; returns batch.json's content.

    ``scheduler``: address of an existing scheduler (``tcp://host:8786``); else a LocalCluster of
    ``workers`` processes (default: one per core, at most one per drive). ``progress(event)`` gets
    ``{"drive", "stage", "done", "total"}`` events from the workers (stage ``start``, ``ingest``,
    ``navigate``, ``autofocus`` (with ``autofocus``), ``focus``, ``done`` or ``failed``) and
    ``{"drive", "stage": "finished", "record"}`` once a drive's record is final. ``on_cluster(info)`` is called
    once the cluster is up (scheduler address, dashboard link, workers). Never raises for a failing drive: look
    at ``failed``. ``radars``, ``can_logs``, ``nmea_logs``: a DCA1000 capture, a CAN log, an NMEA capture per log
    (same order), read with it as one drive; ``radar_starts``: each drive's capture's first frame (ns since the
    epoch, same order), where its logs hold no sync topic. ``ingest_options``: how each drive is read
    (:class:`autosar_cli.ingest.pipeline.IngestOptions`: the DBC, the captures' start, damaged chunks, time gaps;
    a time offset goes to the drive that holds its log). ``resume``: ``out_dir`` holds a batch; its drives that
    finished (``ok``, ``degraded``) with the same inputs are kept as they are, the others run.

    Ctrl-C (a KeyboardInterrupt in this thread) stops the batch: the local cluster's workers with it, their runs
    marked ``interrupted`` (:func:`autosar_cli.run.mark_interrupted`); batch.json is written with ``status``
    ``interrupted`` and a record for every drive (``interrupted`` where it did not finish, ``attempts`` 0 where it
    never started), and the KeyboardInterrupt raised again, carrying that document as ``batch_manifest``.
    """
    if not logs:
        raise BatchError("no drive logs given")
    if retries < 0:
        raise BatchError(f"--retries {retries}: must be 0 or more")
    if workers is not None and workers < 1:
        raise BatchError(f"--workers {workers}: must be at least 1")
    if scheduler and workers:
        raise BatchError("give either --scheduler (an existing cluster) or --workers (a local one), not both")
    if resume and overwrite:
        raise BatchError("give either --resume (keep the drives the batch finished) or --overwrite, not both")
    #: each drive's inputs beside its log by kind (radar, can, nmea), as the workers find them
    companions: list[dict[str, list[str]]] = [{"radar": [], "can": [], "nmea": []} for _ in logs]
    for kind, option, what, given in (("radar", "--radar", "capture", radars),
                                      ("can", "--can-log", "CAN log", can_logs),
                                      ("nmea", "--nmea", "NMEA capture", nmea_logs)):
        if given and len(given) != len(logs):
            raise BatchError(f"{option} given {len(given)} times for {len(logs)} logs; give one {what} per log")
        for inputs, path in zip(companions, given or (), strict=False):
            inputs[kind].append(str(Path(path).resolve()))
    if radar_starts and len(radar_starts) != len(logs):
        raise BatchError(f"--radar-start given {len(radar_starts)} times for {len(logs)} logs; give each drive's "
                         "capture its own first frame's time, one per log")
    starts_ns = list(radar_starts) if radar_starts else [None] * len(logs)
    ingest_options = ingest_options or IngestOptions()
    if ingest_options.dbc is not None:  # every drive's: refused once, not per drive
        if (problem := input_problem(Path(ingest_options.dbc))) is not None:
            raise BatchError(f"{ingest_options.dbc}: {problem}")
        ingest_options = replace(ingest_options, dbc=Path(ingest_options.dbc).resolve())  # as the workers find it
    offsets = {str(Path(p).resolve()): s for p, s in ingest_options.time_offsets.items()}
    shiftable = [{*inputs["can"], *inputs["nmea"], *_folder_logs(Path(log))}  # the workers walk folders again
                 for log, inputs in zip(logs, companions, strict=True)] if offsets else [set() for _ in logs]
    if unknown := sorted(offsets.keys() - set().union(*shiftable)):
        raise BatchError(f"--time-offset {unknown[0]}: not one of the drives' --can-log or --nmea logs, nor a CAN "
                         "or NMEA log of a drive folder")
    #: what each drive's record lists as its inputs: its log, then those given with it (as run_drive lists them)
    paths = [str(Path(p).resolve()) for p in logs]
    drive_inputs = [[log, *inputs["can"], *inputs["nmea"], *inputs["radar"]]
                    for log, inputs in zip(paths, companions, strict=True)]
    seen: dict[tuple[str, ...], int] = {}
    for i, inputs in enumerate(drive_inputs):
        if (first := seen.setdefault(tuple(inputs), i)) != i:  # the same work twice, counted as two drives
            raise BatchError(f"{logs[i]} (log {i + 1} of {len(logs)}): the same drive as log {first + 1} "
                             f"({logs[first]}); give each drive once")
    out = Path(out_dir).resolve()
    if resume and not (out / MANIFEST).exists():
        raise BatchError(f"{out}: holds no batch ({MANIFEST}) to resume")
    if (out / MANIFEST).exists() and not overwrite and not resume:
        raise BatchError(f"{out}: already holds a batch ({_batch_said(out)}); pass --resume to run the drives it "
                         "did not finish, or --overwrite to replace it")
    read = [*logs, *(p for inputs in companions for kind in inputs.values() for p in kind), *config.files,
            *ingest_options.files()]
    check_output(out, read, overwrite=overwrite, directory=True)  # never an input, nor a file (its drives' folders)
    made = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    options = options or FocusOptions.from_config(config)
    names = drive_names(logs)
    drive_options = []  # each drive's ingest options: its own time offsets and capture start
    for own, start_ns in zip(shiftable, starts_ns, strict=True):
        o = replace(ingest_options, time_offsets={Path(p): offsets[p] for p in sorted(own) if p in offsets})
        drive_options.append(replace(o, radar=replace(o.radar, start_ns=start_ns)) if start_ns is not None else o)
    config_text = config.text()  # its files, read once
    settings = [_settings_digest(config_text, method, autofocus, options, o) for o in drive_options]
    resumed = _resumed(out, names, drive_inputs, settings) if resume else _Resumed()
    records = dict(resumed.kept)
    kept = list(records)

    from distributed import Client, LocalCluster, as_completed

    cores = os.cpu_count() or 1
    t_start = time.perf_counter()
    started_at = datetime.now(UTC)
    started = started_at.isoformat(timespec="seconds")
    cluster = client = None
    manifest_args: dict[str, Any] = {"command": command, "config": config.source, "method": method,
                                     "autofocus": autofocus, "options": options, "started": started,
                                     "cluster": None, "retries": retries}
    if len(kept) == len(names):  # nothing left to run: no cluster
        manifest = _batch_manifest(**manifest_args, records=[records[n] for n in names], wall_s=0.0,
                                   total_wall_s=time.perf_counter() - t_start, status="finished")
        write_json(out / MANIFEST, manifest)
        return manifest
    starts: dict[str, int] = {}
    t_submit = time.perf_counter()
    stopped: KeyboardInterrupt | None = None
    finished = False
    try:
        if scheduler:
            client = Client(scheduler, timeout="30s")
            kind = "external"
        else:
            n = workers or max(1, min(len(logs) - len(kept), cores))
            threads = numba_threads or max(1, cores // n)
            with interrupts_held():  # a cluster stopped half-started cannot be closed (and says so at exit)
                # Dask's own log lines (a worker's lost heartbeat as the batch stops) are not the command's: each
                # drive's failure is its record's, and the command says why it stopped
                cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                                       silence_logs=logging.CRITICAL, env={"NUMBA_NUM_THREADS": str(threads)})
            client = Client(cluster)
            kind = "local"
        if kind == "external" and not client.scheduler_info().get("workers"):
            try:
                client.wait_for_workers(1, timeout=60)
            except TimeoutError:
                raise BatchError(f"{scheduler}: the scheduler has no workers (waited 60 s)") from None
        try:
            warm = client.run(_warm_worker)
        except Exception as exc:  # noqa: BLE001 - e.g. a remote worker without autosar_cli installed
            raise BatchError(f"the Dask workers cannot run autosar: {_message(exc)}") from exc
        info = client.scheduler_info()
        worker_info = info.get("workers", {})
        if numba_threads is None and kind == "local":
            numba_threads = max(1, cores // max(1, len(worker_info)))
        cluster_info = {"kind": kind, "scheduler": str(client.scheduler.address), "dashboard": _dashboard(client),
                        "workers": len(worker_info),
                        "threads_per_worker": max((int(w.get("nthreads", 1)) for w in worker_info.values()),
                                                  default=None),
                        "numba_threads_per_task": numba_threads, "cores_here": cores,
                        "numba_threads_max": {str(k): v["numba_threads"] for k, v in warm.items()},
                        "start_s": round(time.perf_counter() - t_start, 3)}
        manifest_args["cluster"] = cluster_info
        if on_cluster is not None:
            on_cluster(cluster_info)
        topic = f"autosar-batch-{uuid.uuid4().hex[:12]}"

        def on_event(event: tuple[float, dict[str, Any]]) -> None:
            msg = event[1]
            if msg.get("stage") == "start":  # one per attempt of the drive's task
                starts[msg["drive"]] = starts.get(msg["drive"], 0) + 1
            if progress is not None:
                progress(msg)

        client.subscribe_topic(topic, on_event)
        for name in records:  # kept from the batch before
            if progress is not None:
                progress({"drive": name, "stage": "finished", "record": records[name]})
        t_submit = time.perf_counter()
        futures = {}
        for i, (name, log, inputs, these) in enumerate(zip(names, paths, companions, drive_options, strict=True)):
            if name in records:
                continue
            fut = client.submit(run_drive, name, [log], str(out / name), config, method=method,
                                options=options, autofocus=autofocus, overwrite=overwrite or name in resumed.replace,
                                ingest_options=these, numba_threads=numba_threads,
                                progress_topic=topic, command=command, can_logs=inputs["can"],
                                nmea_logs=inputs["nmea"], radar_captures=inputs["radar"], retries=retries, pure=False,
                                key=f"autosar-run-{name}-{topic[-12:]}",
                                priority=len(names) - i)  # in the order given: submits 60 ms apart tie otherwise
            futures[fut] = i
        for fut in as_completed(futures):
            name, inputs = names[futures[fut]], drive_inputs[futures[fut]]
            try:
                rec = fut.result()
                rec["attempts"] = max(1, starts.get(name, 0))
            except Exception as exc:  # noqa: BLE001 - a drive that failed after its retries
                rec = {"name": name, "logs": inputs, "output": str(out / name), "status": "failed",
                       "error": _message(exc), "error_type": type(exc).__name__,
                       "attempts": max(retries + 1, starts.get(name, 0))}
            rec["output"] = os.path.relpath(rec["output"], out)
            rec["settings_sha256"] = settings[futures[fut]]  # what --resume keeps it by
            records[name] = rec
            fut.release()
            if progress is not None:
                progress({"drive": name, "stage": "finished", "record": rec})
        client.unsubscribe_topic(topic)
        finished = True
    except KeyboardInterrupt as exc:
        stopped = exc
    finally:
        try:
            with interrupts_held():  # a Ctrl-C (another) while the workers stop is raised once they have
                if client is not None:
                    client.close()
                if cluster is not None:
                    cluster.close()
        except KeyboardInterrupt as exc:  # every drive may have finished: what they made is recorded all the same
            stopped = stopped or exc
        if made and not finished and not starts and not kept:  # stopped before any drive: nothing left
            with contextlib.suppress(OSError):
                out.rmdir()
    wall = time.perf_counter() - t_submit
    if stopped is not None:
        with interrupts_held():  # the record of what finished is written whole
            stopped.batch_manifest = None  # type: ignore[attr-defined]
            ran_any = bool(starts or records)  # else nothing to keep: no batch.json
            for name, inputs, these_settings in zip(names, drive_inputs, settings, strict=True):
                if name in records:
                    continue
                ran = starts.get(name, 0)
                if not ran and resumed.previous.get(name, {}).get("status") == "failed":  # as it was: not run now
                    records[name] = resumed.previous[name]
                    continue
                going = cluster is None and (ran or _written_since(out / name / "run.json", started_at))
                records[name] = {"name": name, "logs": inputs, "output": name, "status": "interrupted",
                                 "error": "interrupted; on the cluster its run may still finish (see its run.json)"
                                 if going else "interrupted", "attempts": ran,
                                 "settings_sha256": these_settings}
                if cluster is not None:  # its worker is gone with the cluster (its start may not have been heard)
                    mark_interrupted(out / name)
                # a run that finished after the Ctrl-C, before its worker stopped
                if (done := _finished_before_stop(out / name, started_at)) is not None:
                    records[name].update(done, attempts=max(1, ran))
            if ran_any:
                status = "interrupted" if any(r["status"] == "interrupted" for r in records.values()) else "finished"
                manifest = _batch_manifest(**manifest_args, records=[records[n] for n in names], wall_s=wall,
                                           total_wall_s=time.perf_counter() - t_start, status=status)
                write_json(out / MANIFEST, manifest)
                stopped.batch_manifest = manifest  # type: ignore[attr-defined]
        raise stopped
    manifest = _batch_manifest(**manifest_args, records=[records[n] for n in names], wall_s=wall,
                               total_wall_s=time.perf_counter() - t_start, status="finished")
    write_json(out / MANIFEST, manifest)
    return manifest


def _batch_manifest(records: list[dict[str, Any]], *, command: str, config: str | None, method: str,
                    autofocus: bool, options: FocusOptions, started: str, cluster: dict[str, Any] | None,
                    retries: int, wall_s: float, total_wall_s: float, status: str) -> dict[str, Any]:
    """batch.json's content: ``status`` ``finished`` or ``interrupted``, the drives' records and their counts."""
    count = {s: sum(r["status"] == s for r in records) for s in ("ok", "degraded", "failed", "interrupted")}
    done_here = sum(r["status"] in ("ok", "degraded") and not r.get("kept") for r in records)
    return {
        "format": FORMAT, "format_version": FORMAT_VERSION, "autosar_version": __version__,
        "python": platform.python_version(), "command": command, "config": config, "method": method,
        "autofocus": autofocus, "focus_options": asdict(options), "started": started, "cluster": cluster,
        "retries": retries, "status": status, "drives": records, **count,
        "kept": sum(bool(r.get("kept")) for r in records),
        "wall_s": wall_s, "total_wall_s": total_wall_s,
        "drives_per_minute": 60.0 * done_here / wall_s if wall_s > 0 and done_here else None,
    }


def _written_since(path: Path, since: datetime) -> bool:
    """Whether ``path`` was written at or after ``since`` (whole seconds, as batch.json's ``started``)."""
    try:
        return path.stat().st_mtime >= since.timestamp() - 1.0
    except OSError:
        return False


def _finished_before_stop(run_dir: Path, since: datetime) -> dict[str, Any] | None:
    """The record of a drive whose run finished while the batch that started at ``since`` stopped (its result never
    reached the client); None where its run.json is older (an earlier batch's run: this one never started it)."""
    from autosar_cli.run import RunError, read_manifest

    if not _written_since(run_dir / "run.json", since):
        return None
    try:
        manifest = read_manifest(run_dir)
        return _finished_run(manifest) if manifest.get("status") in ("ok", "degraded") else None
    except (RunError, KeyError, TypeError, AttributeError):
        return None


def _batch_said(out: Path) -> str:
    """How the batch in ``out`` ended, for the refusal to run over it: "batch.json: interrupted, 2 of 6 drives
    done", or just "batch.json" where it finished or cannot be read."""
    try:
        manifest = read_batch(out)
    except BatchError:
        return MANIFEST
    drives = manifest.get("drives") or []
    if manifest.get("status") != "interrupted" or not isinstance(drives, list):
        return MANIFEST
    done = sum(isinstance(r, dict) and r.get("status") in ("ok", "degraded") for r in drives)
    return f"{MANIFEST}: interrupted, {done} of {len(drives)} drives done"


@dataclass
class _Resumed:
    """What ``--resume`` takes from the batch before: the records it keeps, every record it had, and the drives
    whose folder holds another log's run (the log list changed under their name), replaced."""

    kept: dict[str, dict[str, Any]] = field(default_factory=dict)
    previous: dict[str, dict[str, Any]] = field(default_factory=dict)
    replace: set[str] = field(default_factory=set)


def _settings_digest(config_text: str, method: str, autofocus: bool, options: FocusOptions,
                     ingest_options: IngestOptions) -> str:
    """What makes a drive's products besides its inputs (the config's text, the method, the focus and ingest
    options: its own time offsets and capture start), as a digest: a resumed batch keeps a drive only of the same."""
    ingest = ingest_options.to_dict()
    said = {"config": config_text, "method": method, "autofocus": autofocus, "focus": asdict(options),
            "ingest": {**ingest, "time_offsets": sorted(ingest["time_offsets"].items())}}
    return hashlib.sha256(strict_json(said).encode()).hexdigest()


def _resumed(out: Path, names: list[str], drive_inputs: list[list[str]], settings: list[str]) -> _Resumed:
    """The batch in ``out`` as ``--resume`` takes it: each drive that finished there (``ok`` or ``degraded``) from
    the same inputs and settings (``settings``: each drive's :func:`_settings_digest`), whose run.json still says
    so, or that was ``interrupted`` and whose run.json says it finished after all (an existing cluster's worker goes
    on with a running task), kept and marked ``kept``; a drive whose folder holds a run of other inputs or settings
    is run again over it. Refused where a stopped drive's run may still be going on an existing cluster."""
    from autosar_cli.run import RunError, read_manifest

    before = read_batch(out)
    try:
        since = datetime.fromisoformat(str(before.get("started")))
    except ValueError:
        since = datetime.now(UTC)  # no start: no run of it is taken as finished after its stop
    external = (before.get("cluster") or {}).get("kind") == "external"
    got = _Resumed(previous={str(r.get("name")): r for r in before.get("drives") or [] if isinstance(r, dict)})
    for name, inputs, these in zip(names, drive_inputs, settings, strict=True):
        rec = got.previous.get(name)
        if rec is None:
            continue
        try:
            status = read_manifest(out / name).get("status")
        except RunError:
            status = None
        if rec.get("status") == "interrupted" and external and status == "unfinished":
            raise BatchError(f"{out / name}: its run may still be going on the cluster the batch stopped on "
                             f"(run.json: unfinished); wait for it to end and resume, or remove {out / name} to run "
                             "it again")
        if rec.get("logs") != inputs or rec.get("settings_sha256") != these:  # its run is the batch's, superseded
            got.replace.add(name)
        elif rec.get("status") == "interrupted":  # on an existing cluster its run may have finished after the stop
            if (finished := _finished_before_stop(out / name, since)) is not None:
                got.kept[name] = {**rec, **finished, "kept": True}
        elif rec.get("status") in ("ok", "degraded") and status == rec["status"]:
            got.kept[name] = {**rec, "kept": True}
    return got


def _folder_logs(log: Path) -> list[str]:
    """The CAN and NMEA logs of a drive folder (resolved, as the workers find them), none of any other log."""
    folder = drive_folder(log)
    return [str(p.resolve()) for p in folder.inputs["can"] + folder.inputs["nmea"]] if folder else []


def read_batch(out_dir: str | Path) -> dict[str, Any]:
    """batch.json of a batch directory, checked."""
    return read_json_manifest(Path(out_dir) / MANIFEST, FORMAT, "batch", BatchError)


__all__ = ["BatchError", "FORMAT", "INPUT_ERRORS", "drive_names", "read_batch", "run_batch", "run_drive"]
