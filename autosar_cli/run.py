"""``autosar run``: ingest -> navigate [-> autofocus] -> focus in one go, every product in one directory plus
run.json.

The optional autofocus stage corrects the navigated track by what the radar itself measures
(:func:`autosar_cli.sar.autofocus_stage.autofocus_residual_motion`: the phase-centre motion that makes the phase
histories of a first image's bright isolated points coherent, and the track's along-track scale where they measure
it; docs/AUTOFOCUS.md). Where it cannot measure, the navigated track is kept and run.json says why.

run.json (format ``autosar-run`` version 1) records the inputs (path, size), the autosar version, the
config file, how the inputs were read (``ingest_options``: DBC, time offsets, ...), the method and focus
parameters, per-stage wall times and summaries, and the outputs (paths relative to the run directory), so
``autosar evaluate DIR`` can find everything. Its ``status`` is ``ok`` or ``degraded`` once the run has finished;
until then it is ``unfinished``, and a run that fails or is stopped once its drive is written leaves ``failed`` or
``interrupted`` (with its ``error``) beside the products it finished, so that no run directory looks complete that
is not.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import pickle
import platform
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from autosar_cli import __version__
from autosar_cli.config import Config
from autosar_cli.disk_full import disk_full_said, is_disk_full
from autosar_cli.interrupts import Terminated
from autosar_cli.sar.grid import GridError, check_image_size
from autosar_cli.store.atomic import stale_partials
from autosar_cli.store.manifest import product_status, read_json_manifest, write_json
from autosar_cli.store.outputs import (
    check_free_space,
    check_output,
    check_products,
    input_bytes,
    output_directory,
)

if TYPE_CHECKING:
    from autosar_cli.ingest.pipeline import IngestOptions
    from autosar_cli.sar.focus import FocusOptions

FORMAT = "autosar-run"
FORMAT_VERSION = 1
STAGES = ("ingest", "navigate", "autofocus", "focus")  #: in order; autofocus only when asked for

#: Products inside a run directory.
DRIVE = "drive.h5"
TRAJECTORY = "trajectory.h5"
IMAGE = "image"  # image.tif, image.h5, image.png
#: run.json's ``status`` of a run that has not finished (see the module docstring)
UNFINISHED = ("unfinished", "failed", "interrupted")


class RunError(ValueError):
    """A run cannot start (e.g. the output directory holds another run and --overwrite was not given)."""


def run(logs: Sequence[str | Path], out_dir: str | Path, config: Config, *, method: str = "sar-min",
        options: FocusOptions | None = None, truth_path: str | Path | None = None, autofocus: bool = False,
        overwrite: bool = False,
        progress: Callable[[str, int, int], None] | None = None, command: str = "",
        fork_ingest: bool = False, ingest_options: IngestOptions | None = None,
        can_logs: Sequence[str | Path] = (), nmea_logs: Sequence[str | Path] = (),
        radar_captures: Sequence[str | Path] = (), replace_unfinished: bool = False) -> dict[str, Any]:
    """Run the whole chain on ``logs`` into ``out_dir``; returns the manifest (also written as run.json).

    ``autofocus``: scale the navigated track by the radar's own measure of it before focusing (the trajectory
    written is then named ``METHOD+af``, its scale in its info and in the manifest's ``autofocus`` stage).
    ``progress(stage, done, total)`` is called as each stage advances. ``fork_ingest``: ingest in a forked child
    process while this one imports the later stages (see :func:`_ingest_beside_imports`; the ``autosar run``
    command sets it, library callers such as ``autosar batch``'s workers keep one process). ``logs`` may hold
    CAN logs, NMEA captures and a DCA1000 capture, as for ``autosar ingest``; ``can_logs``, ``nmea_logs`` and
    ``radar_captures``: CAN logs, NMEA captures and DCA1000 captures given as such (``autosar ingest``'s
    ``--can-log``, ``--nmea`` and ``--radar``), not told by their content (one that is not what it is given as is
    refused; a capture may be named by its parameter file). ``ingest_options``
    (:class:`autosar_cli.ingest.pipeline.IngestOptions`) reads them all: the DBC, the capture's start, time offsets.
    ``replace_unfinished``: autosar's products in ``out_dir`` where its run.json is missing or says the run did not
    finish are replaced as with ``overwrite`` (a batch's retry of a drive finds its first attempt's).
    """
    out = Path(out_dir)
    manifest_path = out / "run.json"
    status = _status(manifest_path) if manifest_path.exists() else None  # run.json read once
    unfinished = not manifest_path.exists() or status in UNFINISHED
    if manifest_path.exists() and not overwrite and not (replace_unfinished and unfinished):
        said = f"run.json: {status}" if unfinished else "run.json"
        raise RunError(f"{out}: already holds a run ({said}); pass --overwrite to replace it")
    # every check that needs no data before the ingest starts: outputs (never an input, only autosar's replaced)
    # and the image's size
    given = [*logs, *can_logs, *nmea_logs, *radar_captures]  # every input read into the drive
    inputs = [*given, *([truth_path] if truth_path else []), *config.files,
              *(ingest_options.files() if ingest_options else [])]
    check_output(out, inputs, overwrite=overwrite, directory=True)
    check_products(out, [DRIVE, TRAJECTORY, "run.json", f"{IMAGE}.tif", f"{IMAGE}.h5", f"{IMAGE}.png"], inputs,
                   overwrite=overwrite or (replace_unfinished and unfinished))
    if method == "truth":
        _check_truth(truth_path, given)
    from autosar_cli.ingest.pipeline import capture_files

    # a capture named by its parameter file is its data files too
    read_files = {str(p): [Path(p)] for p in given} | {str(p): capture_files(Path(p)) for p in radar_captures}
    check_free_space(out / DRIVE, input_bytes(f for files in read_files.values() for f in files), "the drive")
    if options is None:  # the config's automatic grid (focus's own modules are imported beside the ingest)
        try:
            check_image_size(config.processing.pixel_m, max_range_m=config.radar.max_range_m)
        except GridError as exc:
            raise RunError(f"grid: {exc}") from None
    else:
        from autosar_cli.sar.focus import check_request

        check_request(options, out / IMAGE, True, inputs, config)
    inputs = [{"path": os.path.abspath(p), "size_bytes": input_bytes(read_files[str(p)])}  # found from anywhere
              for p in given]
    manifest: dict[str, Any] = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "autosar_version": __version__,
        "python": platform.python_version(), "command": command, "config": config.source, "inputs": inputs,
        "method": method, "autofocus": autofocus, "focus_options": None, "stages": {}, "outputs": {},
        "ingest_options": ingest_options.to_dict() if ingest_options else None,
    }

    def stage_progress(stage: str) -> Callable[[int, int], None]:
        return lambda done, total: progress(stage, done, total) if progress else None

    with output_directory(out):
        write_json(manifest_path, {**manifest, "status": "unfinished"})
        try:
            t = time.perf_counter()
            rep = _ingest_beside_imports([Path(p) for p in logs], out / DRIVE, config, stage_progress("ingest"),
                                         command, fork=fork_ingest, ingest_options=ingest_options,
                                         autofocus=autofocus, can_logs=[Path(p) for p in can_logs],
                                         nmea_logs=[Path(p) for p in nmea_logs],
                                         radar_captures=[Path(p) for p in radar_captures])
            manifest["stages"]["ingest"] = {"wall_s": time.perf_counter() - t, "messages": rep.get("messages"),
                                            "bytes_read": rep.get("bytes_read"), "warnings": rep.get("warnings", [])}
            manifest["outputs"]["drive"] = DRIVE
            write_json(manifest_path, {**manifest, "status": "unfinished"})
            _run_after_ingest(manifest, out, config, method, options, truth_path, autofocus, command,
                              stage_progress, progress)
        except BaseException as exc:
            _mark_stopped(exc, manifest, manifest_path)
            raise
    write_json(manifest_path, manifest)
    return manifest


def _mark_stopped(exc: BaseException, manifest: dict[str, Any], manifest_path: Path) -> None:
    """run.json of a run that ``exc`` stopped: none where it kept no drive (an ingest writes whole or nothing),
    else ``failed`` or ``interrupted`` with the error, beside what it finished; the ingest's warnings go with the
    error (what it found wrong may be the cause)."""
    from autosar_cli.ingest.pipeline import carry_warnings

    if not (manifest_path.parent / DRIVE).exists():
        manifest_path.unlink(missing_ok=True)
        return
    carry_warnings(exc, manifest["stages"].get("ingest", {}).get("warnings", []))
    if isinstance(exc, KeyboardInterrupt):
        status, error = "interrupted", "terminated" if isinstance(exc, Terminated) else "interrupted"
    else:
        status, error = "failed", str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if is_disk_full(exc):  # as the command says it, not in HDF5's words
            error = disk_full_said(exc, manifest_path.parent)
    with contextlib.suppress(Exception):  # best effort: the disk may be what failed
        write_json(manifest_path, {**manifest, "status": status, "error": error})


def mark_interrupted(run_dir: Path) -> None:
    """run.json of a run whose process was stopped from outside (a batch's worker, closed with its cluster), as the
    run marks its own at an interrupt: ``interrupted`` where it kept a drive, else gone with the run's folder (its
    partial files, their writer gone, with it). A run.json that does not say ``unfinished`` is left as it is."""
    path = run_dir / "run.json"
    try:
        manifest = read_manifest(run_dir)
    except RunError:
        return
    if manifest.get("status") != "unfinished":
        return
    _mark_stopped(KeyboardInterrupt(), {k: v for k, v in manifest.items() if k != "status"}, path)
    if not path.exists():
        for partial in stale_partials(run_dir):
            partial.unlink(missing_ok=True)
        with contextlib.suppress(OSError):
            run_dir.rmdir()  # only where empty: nothing of the user's goes


def not_finished(manifest: dict[str, Any]) -> str | None:
    """"the run did not finish (STATUS: ERROR)" for a run.json whose run has not finished, else None."""
    if manifest.get("status") not in UNFINISHED:
        return None
    error = f": {manifest['error']}" if manifest.get("error") else ""
    return f"the run did not finish ({manifest['status']}{error})"


def _status(manifest_path: Path) -> str | None:
    """run.json's ``status``; None where it cannot be read."""
    try:
        return str(read_manifest(manifest_path.parent).get("status"))
    except RunError:
        return None


def _check_truth(truth_path: str | Path | None, given: Sequence[str | Path]) -> None:
    """Refuse, before the ingest, a truth sidecar that is none (another file, not HDF5, missing), or, where none is
    given, inputs with none beside them (navigate's default, :func:`~autosar_cli.sim.truth.truth_sidecar_of`):
    navigate would, after the ingest's minutes. Whether it is this recording's truth needs the drive (navigate checks
    that)."""
    from autosar_cli.sim.truth import open_truth, truth_sidecar_of

    if truth_path is None and any(Path(p).is_dir() for p in given):
        return  # a drive folder's sidecar lies beside one of the files in it: navigate looks among those
    if truth_path is None and (truth_path := truth_sidecar_of(given)) is None:
        raise RunError(f"{', '.join(str(p) for p in given)}: no truth sidecar (<log>.truth.h5) beside the inputs; "
                       "give --truth LOG.truth.h5")
    try:
        with open_truth(truth_path):
            pass
    except ValueError as exc:
        raise RunError(str(exc)) from None


def _run_after_ingest(manifest: dict[str, Any], out: Path, config: Config, method: str,
                      options: FocusOptions | None, truth_path: str | Path | None, autofocus: bool, command: str,
                      stage_progress: Callable[[str], Callable[[int, int], None]],
                      progress: Callable[[str, int, int], None] | None) -> None:
    """The stages after the ingest, each adding its summary and outputs to ``manifest`` (finished by the end)."""
    from autosar_cli.nav.navigate import REPORTED_INFO, navigate
    from autosar_cli.sar.focus import FocusOptions, drive_radar_config, focus
    from autosar_cli.store.trajectory import write_trajectory

    options = options or FocusOptions.from_config(config)
    config = drive_radar_config(config, out / DRIVE, options.radar)  # a radar ingested with --radar-override
    manifest["focus_options"] = asdict(options)
    t = time.perf_counter()
    if progress:
        progress("navigate", 0, 1)
    traj = navigate(out / DRIVE, method, config, truth_path=truth_path)
    if not autofocus:
        write_trajectory(out / TRAJECTORY, traj)
    if progress:
        progress("navigate", 1, 1)
    span = (traj.t_ns[-1] - traj.t_ns[0]) / 1e9
    manifest["stages"]["navigate"] = {"wall_s": time.perf_counter() - t, "method": traj.method,
                                      "samples": int(len(traj.t_ns)), "duration_s": float(span),
                                      "distance_m": float(np.sum(np.hypot(*np.diff(traj.rear_axle_enu, axis=0).T))),
                                      **{k: traj.info[k] for k in REPORTED_INFO if k in traj.info}}
    if autofocus:
        from autosar_cli.sar.autofocus_stage import autofocus_residual_motion

        t = time.perf_counter()
        if progress:
            progress("autofocus", 0, 1)
        focused = autofocus_residual_motion(out / DRIVE, traj, config, options)
        if focused.applied:
            traj = focused.labelled(f"{traj.method}+af")
        elif focused.channel_gains is not None:  # the track kept, the channels measured: the image undoes them
            options = replace(options, channel_gains=focused.channel_gains)
        write_trajectory(out / TRAJECTORY, traj)
        if progress:
            progress("autofocus", 1, 1)
        manifest["stages"]["autofocus"] = {"wall_s": time.perf_counter() - t, "summary": focused.summary(),
                                           **focused.to_dict(), "method": traj.method}
    manifest["outputs"]["trajectory"] = TRAJECTORY
    if traj.info.get("truth"):
        manifest["truth"] = traj.info["truth"]

    t = time.perf_counter()
    frep = focus(out / DRIVE, out / TRAJECTORY, out / IMAGE, config, options, overwrite=True,
                 progress=stage_progress("focus"), command=command)
    manifest["stages"]["focus"] = {"wall_s": time.perf_counter() - t, "timings_s": frep.timings_s,
                                   "grid_shape": list(frep.grid_shape),
                                   "grid_enu_m": list(frep.grid_enu_m) if frep.grid_enu_m is not None else None,
                                   "frames_used": frep.frames_used,
                                   "frames_skipped": frep.frames_skipped,
                                   "backprojections": frep.backprojections,
                                   "backprojections_per_s": frep.backprojections_per_s, "warnings": frep.warnings}
    manifest["outputs"]["image"] = {k: os.path.relpath(v, out) for k, v in frep.outputs.items()}
    manifest["drive_s"] = frep.drive_s
    manifest["wall_s"] = sum(s["wall_s"] for s in manifest["stages"].values())
    manifest["fraction_of_drive"] = manifest["wall_s"] / frep.drive_s if frep.drive_s > 0 else None
    manifest["warnings"] = run_warnings(manifest)
    manifest["status"] = product_status(manifest["warnings"])


def run_warnings(manifest: dict[str, Any]) -> list[str]:
    """What a run warned about (ingest: a truncated or damaged log, dropped data; navigate: the GNSS mostly gated
    out; focus: another radar of the drive left unfocused; autofocus not applied): a run with any is ``degraded``
    (run.json's ``status``, batch.json's drive record), not plain ``ok``."""
    st = manifest.get("stages", {})
    warnings = [str(w) for w in st.get("ingest", {}).get("warnings", [])]
    warnings += [str(w) for w in st.get("navigate", {}).get("warnings", [])]
    warnings += [str(w) for w in st.get("focus", {}).get("warnings", [])]
    af = st.get("autofocus")
    if af and not af.get("applied", True):
        warnings.append(f"autofocus: {af.get('summary', 'not applied')}")
    return warnings


def _prepare_later_stages(autofocus: bool = False) -> None:
    """Import navigation and focus's modules (numba, rasterio, h5py, scipy.special: ~0.4 s of one CPU), load
    their kernels from numba's cache (~0.3 s that their first calls would otherwise take) and the quicklook's
    imports; with ``autofocus``, the autofocus's too."""
    import autosar_cli.nav.navigate  # noqa: F401
    import autosar_cli.sar.focus  # noqa: F401
    import autosar_cli.store.trajectory  # noqa: F401
    from autosar_cli.kernel_cache import load_cached_kernels
    from autosar_cli.nav import sarmin_kernel
    from autosar_cli.sar import backprojection, range_compression, range_fft, stripmap
    from autosar_cli.store.image import preload_quicklook

    load_cached_kernels(sarmin_kernel, backprojection, range_fft, range_compression, stripmap)
    if autofocus:
        import autosar_cli.sar.autofocus_stage  # noqa: F401
        from autosar_cli.sar import history_kernel

        load_cached_kernels(history_kernel)
    preload_quicklook()  # matplotlib's imports; a first draw here measured no gain (its CPU slows the ingest)


def _fork_context() -> Any:
    """multiprocessing's fork context where a child can be forked from this process safely, else None (no fork
    on this platform; macOS, where fork is unsafe; a daemonic process, e.g. a Dask worker, which may have none)."""
    if not sys.platform.startswith("linux") or multiprocessing.current_process().daemon:
        return None
    try:
        return multiprocessing.get_context("fork")
    except ValueError:
        return None


def _ingest_beside_imports(logs: list[Path], drive: Path, config: Config, progress: Callable[[int, int], None],
                           command: str, *, fork: bool, ingest_options: IngestOptions | None = None,
                           autofocus: bool = False, can_logs: Sequence[Path] = (), nmea_logs: Sequence[Path] = (),
                           radar_captures: Sequence[Path] = ()) -> dict[str, Any]:
    """Ingest ``logs`` (and ``can_logs``, ``nmea_logs``, ``radar_captures``: read as such) into ``drive``; returns the
    ingest report as a dict.

    With ``fork``, the ingest runs in a forked child while this process imports the later stages: ingest is
    Python work holding its process's GIL (~1.4 of the 2 CPUs with its writer thread), so those imports could
    not run beside it in a thread (tried: they only moved into ingest's time) but can in a second process.
    Meanwhile this process also loads the later stages' kernels from numba's cache, which their first calls
    would otherwise pay (``autofocus``: the autofocus's among them). Progress and the report (or the error) come
    back through a pipe.
    """
    ctx = _fork_context() if fork else None
    if ctx is None:
        return _ingest(logs, drive, config, progress, command, ingest_options, can_logs, nmea_logs, radar_captures)
    receive, send = ctx.Pipe(duplex=False)
    sys.stdout.flush()
    sys.stderr.flush()
    child = ctx.Process(target=_ingest_child, args=(send, logs, drive, config, command, ingest_options, can_logs,
                                                    nmea_logs, radar_captures), name="autosar-ingest")
    child_pid: list[int] = []
    forwarded: list[bool] = []
    restore_sigint = _forward_sigint_to(child_pid, forwarded)
    try:  # from before the fork: a Ctrl-C at any moment after it reaches the child or is passed on below
        child.start()
        child_pid.append(child.pid)
        send.close()
        _prepare_later_stages(autofocus)
        while True:
            try:
                kind, *payload = receive.recv()
            except EOFError:
                child.join()
                raise RunError(f"{drive}: the ingest process ended without a report (exit code {child.exitcode})")\
                    from None
            if kind == "progress":
                progress(*payload)
            elif kind == "report":
                return payload[0]
            else:
                exc, remote = payload
                exc.__cause__ = _RemoteTraceback(remote)
                raise exc
    except BaseException:
        if child.is_alive() and not forwarded:  # e.g. a kill of this process alone: the child aborts its drive too
            os.kill(child.pid, signal.SIGINT)
        raise
    finally:
        restore_sigint()
        receive.close()
        if child.is_alive():
            child.join(timeout=5.0)
        if child.is_alive():
            child.terminate()
            child.join()


def _forward_sigint_to(child_pid: list[int], forwarded: list[bool]) -> Callable[[], None]:
    """Until the returned function is called, Ctrl-C reaches the ingest child (``child_pid``, once it is
    known) at once, and then this process as before: a KeyboardInterrupt raised here can be swallowed (in a
    destructor, while kernels load), but the child's abort still comes back through the pipe as its error.
    ``forwarded`` gets an entry when it has been. The child, forked with this handler, has no pid in its copy
    of the list and just raises. Only from the main thread (else a no-op)."""
    if threading.current_thread() is not threading.main_thread():
        return lambda: None
    previous = signal.getsignal(signal.SIGINT)

    def forward(signum: int, frame: Any) -> None:
        if child_pid and not forwarded:  # once: a second SIGINT could interrupt the child's own clean-up
            forwarded.append(True)
            with contextlib.suppress(ProcessLookupError):
                os.kill(child_pid[0], signal.SIGINT)
        if callable(previous):
            previous(signum, frame)
        elif previous != signal.SIG_IGN:
            raise KeyboardInterrupt

    signal.signal(signal.SIGINT, forward)
    return lambda: signal.signal(signal.SIGINT, previous)


class _RemoteTraceback(Exception):
    """The ingest child's traceback, chained to the error it raised (shown with ``--debug``)."""

    def __str__(self) -> str:
        return "\n" + str(self.args[0])


def _ingest(logs: list[Path], drive: Path, config: Config, progress: Callable[[int, int], None], command: str,
            options: IngestOptions | None, can_logs: Sequence[Path] = (), nmea_logs: Sequence[Path] = (),
            radar_captures: Sequence[Path] = ()) -> dict[str, Any]:
    from autosar_cli.ingest.pipeline import IngestOptions, chain_hint, ingest

    return ingest(logs, drive, config=config, can_logs=can_logs, nmea_logs=nmea_logs, radar_captures=radar_captures,
                  progress=progress,
                  command=command, partial_hint=chain_hint("a run"),
                  **(options or IngestOptions()).ingest_kwargs()).to_dict()


def _stop_once() -> Callable[[], None]:
    """In the forked ingest: the first SIGINT or SIGTERM raises a KeyboardInterrupt, any later one is let be. A
    signal to the whole process group (a terminal's Ctrl-C, `timeout`, a service manager) reaches the ingest and
    then its parent's forward of the same signal: raised again, or taken by the command's handler (cli._stop) for
    a second interrupt, it ended the ingest inside its clean-up, its partial file left. Returns the check its
    progress calls: an interrupt swallowed on the way (in a destructor) stops it there."""
    came: list[int] = []

    def stop(signum: int, frame: Any) -> None:
        if not came:
            came.append(signum)
            raise KeyboardInterrupt

    def check() -> None:
        if came:
            raise KeyboardInterrupt

    if threading.current_thread() is threading.main_thread():
        for s in (signal.SIGINT, signal.SIGTERM):
            signal.signal(s, stop)
    return check


def _ingest_child(send: Any, logs: list[Path], drive: Path, config: Config, command: str,
                  options: IngestOptions | None = None, can_logs: Sequence[Path] = (),
                  nmea_logs: Sequence[Path] = (), radar_captures: Sequence[Path] = ()) -> None:
    """The forked ingest: progress at most every 0.1 s (the parent reads only after its imports), then the
    report, or the error (its class if it pickles, else a RunError with its message) and its traceback."""
    last = [0.0]
    stopped = _stop_once()
    hook = sys.unraisablehook  # a swallowed interrupt: unsaid, and raised by the next progress report instead

    def unraisable(unraisable: Any) -> None:
        if not issubclass(unraisable.exc_type, KeyboardInterrupt):
            (hook or sys.__unraisablehook__)(unraisable)

    sys.unraisablehook = unraisable

    def progress(done: int, total: int) -> None:
        stopped()
        now = time.perf_counter()
        if now - last[0] >= 0.1 or done >= total:
            last[0] = now
            send.send(("progress", done, total))

    try:
        send.send(("report", _ingest(logs, drive, config, progress, command, options, can_logs, nmea_logs,
                                     radar_captures)))
    except BaseException as exc:  # noqa: BLE001 - every failure goes back to the parent
        remote = traceback.format_exc()
        try:
            pickle.loads(pickle.dumps(exc))
        except Exception:  # noqa: BLE001 - an exception that does not survive pickling
            exc = RunError(str(exc) or type(exc).__name__)
        send.send(("error", exc, remote))
    finally:
        send.close()


def read_manifest(run_dir: str | Path) -> dict[str, Any]:
    """run.json of a run directory, checked."""
    return read_json_manifest(Path(run_dir) / "run.json", FORMAT, "run", RunError)


