"""The ``autosar`` command line: one small function per command, no logic beyond argument handling."""

from __future__ import annotations

import difflib
import errno
import gc
import inspect
import os
import re
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext
from enum import StrEnum
from pathlib import Path
from typing import Annotated, Any

import typer
import typer.core
from rich.console import Console
from rich.markup import escape
from rich.progress import (
    BarColumn,
    DownloadColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
    TransferSpeedColumn,
)
from rich.table import Column, Table

from autosar_cli import __version__, exit_interrupted
from autosar_cli.config import CAN_LOG_SUFFIXES, LOG_SUFFIXES, NMEA_SUFFIXES, Config
from autosar_cli.disk_full import disk_full_said, reports_held
from autosar_cli.disk_full import is_disk_full as _disk_full
from autosar_cli.interrupts import Terminated, interrupts_held
from autosar_cli.store.manifest import product_status, strict_json


class _FlagsShownBare:
    """Help that shows a flag as it is given (``--overwrite``), not beside a type (``--overwrite <bool>``); a
    required argument in the usage line as a name alone (``autosar info [OPTIONS] PATH``, not typer's ``{PATH}``); a
    64-bit range as such, not as its 20 digits."""

    def collect_usage_pieces(self, ctx: Any) -> list[str]:
        pieces = super().collect_usage_pieces(ctx)  # type: ignore[misc]
        return [re.sub(r"^\{([^{}]+)\}", r"\1", piece) for piece in pieces]

    def get_params(self, ctx: Any) -> list[Any]:
        params = super().get_params(ctx)  # type: ignore[misc]
        for param in params:
            if isinstance(param, typer.core.TyperOption) and param.is_flag and param.metavar is None:
                param.metavar = ""  # typer shows a parameter's metavar, where it has one, in place of its type
            elif isinstance(param, typer.core.TyperOption) and param.max == 2**64 - 1:
                param._get_number_range_help_str = lambda low=param.min: f"{low}<=x<2^64"  # type: ignore[method-assign]
            elif isinstance(param, typer.core.TyperArgument):
                shown = param.display_type(ctx)
                if shown and shown.startswith("<list["):  # an argument given many times: as an option's is shown
                    label = f"<{shown[6:-2].lower()}>..."
                    param.display_type_rich = lambda ctx, label=label: label  # type: ignore[method-assign]
        return params


    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        try:
            return super().parse_args(ctx, args)  # type: ignore[misc, no-any-return]
        except typer.BadParameter as exc:
            exc.message = _said_plainly(exc.message)
            raise
        except Exception as exc:  # click's NoSuchOption (typer's own copy of click names it nowhere public)
            if getattr(exc, "option_name", None) == "--debug":  # "No such option: --debug (Possible options: --dbc)"
                exc.message = f"--debug goes before the command: autosar --debug {ctx.info_name} ..."  # type: ignore
                exc.possibilities = None  # type: ignore[attr-defined]
            raise


def _said_plainly(message: str) -> str:
    """A choice's refusal as typer's validation words it ("Value error, 'sarmin' is not one of 'sar-min', ...")
    without the validator's prefix, and with the choice it likely meant."""
    message = message.removeprefix("Value error, ")
    m = re.fullmatch(r"(\'[^']*\') is not one of ((?:\'[^']*\'(?:, )?)+)\.?", message)
    if m:
        given, choices = m.group(1).strip("'"), re.findall(r"'([^']*)'", m.group(2))
        near = difflib.get_close_matches(given.lower(), choices, n=1, cutoff=0.6)
        if near:
            message = f"{message.rstrip('.')}: did you mean {near[0]!r}?"
    return message


class _Group(_FlagsShownBare, typer.core.TyperGroup):
    pass


class _Command(_FlagsShownBare, typer.core.TyperCommand):
    pass


app = typer.Typer(
    cls=_Group,
    name="autosar",
    help="Navigation-aided automotive SAR: recorded drives in, centimetre-accurate radar maps out.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
err = Console(stderr=True)
out = Console()

#: ``undo_on_failure``: what a failing command undoes (the directories its outputs' gate made), in :func:`_errors`
_state: dict[str, Any] = {"debug": False, "undo_on_failure": [], "disk_filled": False}

ConfigOpt = Annotated[
    Path | None, typer.Option("--config", "-c", metavar="FILE",
                              help="TOML config (default: configs/giulia_scanbrick.toml).")
]
OverwriteOpt = Annotated[bool, typer.Option("--overwrite", help="Replace existing outputs.")]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print a machine-readable JSON summary on stdout.")]
RadarStartOpt = Annotated[str | None, typer.Option(
    "--radar-start", metavar="TIME", help="Start of a DCA1000 capture's first frame: ns since the Unix epoch or ISO "
                                          "8601 (UTC); default: the first message of --radar-sync in the logs.")]
RadarSyncOpt = Annotated[str, typer.Option("--radar-sync", metavar="TOPIC", help="Topic whose first message stamps a "
                                           "DCA1000 capture's first frame.")]
RadarOverrideOpt = Annotated[bool, typer.Option("--radar-override", help="Where the recording's radar parameters "
                                                "contradict the config's, keep the recording's (warned) instead of "
                                                "stopping.")]
RadarStreamOpt = Annotated[str | None, typer.Option("--radar-stream", metavar="NAME", help="The drive's radar "
                                                   "stream to focus (/radar/NAME; default: its first). Its "
                                                   "mounting is the config's \\[radar].")]
RadarCaptureOpt = Annotated[Path | None, typer.Option("--radar", metavar="CAPTURE", help="TI DCA1000 capture of "
                                                     "the drive (see `autosar ingest`).")]
DbcOpt = Annotated[Path | None, typer.Option("--dbc", metavar="FILE", help="CAN database (default: the config's).")]
CanLogOpt = Annotated[list[Path] | None, typer.Option(
    "--can-log", metavar="FILE", help="Standalone CAN log (repeatable).")]
NmeaOpt = Annotated[list[Path] | None, typer.Option(
    "--nmea", metavar="FILE", help="NMEA text capture (repeatable).")]
AllowUnverifiedOpt = Annotated[bool, typer.Option(
    "--allow-unverified", help="Read the MCAP chunks whose CRC fails (the damage is somewhere in them; each is "
                               "named) rather than leave them out.")]
TimeOffsetOpt = Annotated[list[str] | None, typer.Option(
    "--time-offset", metavar="PATH=SECONDS",
    help="Shift a CAN or NMEA log's times: SECONDS added to each (negative: earlier; repeatable).")]
AllowTimeGapOpt = Annotated[bool, typer.Option(
    "--allow-time-gap", help="Ingest inputs that lie more than --max-time-gap apart as recorded.")]
MaxTimeGapOpt = Annotated[float, typer.Option(
    "--max-time-gap", min=0.0, metavar="SECONDS", help="Seconds inputs may lie apart before they are refused.")]
AutofocusOpt = Annotated[bool, typer.Option("--autofocus", help="Before focusing, correct the track by the motion "
                                            "the radar itself measures: the phase histories of a first image's "
                                            "bright isolated points (residual motion across track and up, and the "
                                            "track's scale). The trajectory is then named METHOD+af; where nothing "
                                            "can be measured the navigated track is kept and run.json says why.")]


#: suffixes of files, which a directory (a rosbag2 bag, a run, a report) is not named with
_FILE_SUFFIXES = (*LOG_SUFFIXES, *NMEA_SUFFIXES, *CAN_LOG_SUFFIXES, ".h5", ".hdf5", ".tif", ".tiff", ".png", ".json",
                  ".md", ".yaml", ".toml", ".csv", ".bin")


class Scenario(StrEnum):
    ci = "ci"
    test1 = "test1"
    test2 = "test2"
    test3 = "test3"
    urban = "urban"


class Dynamics(StrEnum):
    kinematic = "kinematic"
    full = "full"


class NavMethod(StrEnum):
    sar_min = "sar-min"
    ins = "ins"
    gnss = "gnss"
    none = "none"
    truth = "truth"


class LogFormat(StrEnum):
    mcap = "mcap"
    ros1 = "ros1"
    ros2 = "ros2"
    dca1000 = "dca1000"


def _lit(value: object) -> str:
    """``value`` as literal text in rich markup: a path or reason holding "[name]" is printed, not taken for a style."""
    return escape(str(value))


def _ingest_options(dbc: Path | None, radar_start: str | None, radar_sync: str, radar_override: bool,
                    allow_unverified: bool, time_offset: list[str] | None, allow_time_gap: bool,
                    max_time_gap: float) -> Any:
    """The ingest options of ``autosar ingest``, ``run``, ``compare`` and ``batch`` as the library takes them."""
    from autosar_cli.ingest.pipeline import IngestOptions, RadarCaptureOptions, parse_time_ns, parse_time_offsets

    radar = RadarCaptureOptions(parse_time_ns(radar_start) if radar_start is not None else None, radar_sync,
                                radar_override)
    return IngestOptions(dbc, radar, parse_time_offsets(time_offset or []), max_time_gap, allow_time_gap,
                         allow_unverified)


def _version(value: bool) -> None:
    if value:
        out.print(f"autosar {__version__}")
        raise typer.Exit()


@app.callback()
def main_options(
    debug: Annotated[bool, typer.Option("--debug", help="Show full tracebacks on errors.")] = False,
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True,
                                          help="Print the version and exit.")] = False,
) -> None:
    _state["debug"] = debug
    if debug:  # libtiff's own messages (store/libtiff_messages.py), as libtiff words them
        import logging

        libtiff = logging.getLogger("autosar_cli.libtiff")
        shown = logging.StreamHandler(sys.stderr)
        shown.setFormatter(logging.Formatter("%(message)s"))
        libtiff.addHandler(shown)
        libtiff.setLevel(logging.DEBUG)


@contextmanager
def _errors(writing: Path | None = None, kernels: bool = True) -> Iterator[None]:
    """Turn expected failures into a one-line message and exit code 1 (tracebacks only with --debug).

    ``writing``: the command's output, named when a full disk (ENOSPC) says no file of its own. Inside, Ctrl-C
    is a KeyboardInterrupt (writers clean up, then "interrupted", 130); outside, the console script's
    start-up handler (autosar_cli.exit_interrupted) says the same and exits at once. ``kernels``: the command
    runs numba kernels, and numba is imported before the body, under that start-up handler: a KeyboardInterrupt
    inside numba's own import makes its extension modules print a traceback and fail with ImportError (exit 1)."""
    quick_exit = signal.getsignal(signal.SIGINT) is exit_interrupted
    if quick_exit and kernels:
        import numba  # noqa: F401
    _state["stopped_by"], _state["raised_again"] = None, False
    if quick_exit:
        signal.signal(signal.SIGINT, _stop)
    quick_term = signal.getsignal(signal.SIGTERM) is exit_interrupted
    if quick_term:
        signal.signal(signal.SIGTERM, _stop)
    unraisable_hook = sys.unraisablehook
    sys.unraisablehook = _interrupt_again(unraisable_hook)
    undo_on_failure: list[Callable[[], None]] = []
    _state["undo_on_failure"] = undo_on_failure
    try:
        # h5py's reports of a full disk from its destructors (tracebacks) are the error's to say, in one line
        with nullcontext() if _state["debug"] else reports_held():
            yield
    except (typer.Exit, typer.Abort):
        raise
    except KeyboardInterrupt as exc:
        _undo(undo_on_failure)
        raise typer.Exit(_said_stopped(_signal_of(exc))) from None
    except Exception as exc:
        _undo(undo_on_failure)
        if (signum := _state["stopped_by"]) is not None and not _state["debug"]:
            # the interrupt was swallowed (a destructor, a C extension's import) and this error followed from it
            raise typer.Exit(_said_stopped(signum)) from None
        if _disk_full(exc):
            _state["disk_filled"] = True
        if _state["debug"]:
            raise
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        for warning in (w for w in getattr(exc, "warnings", ()) if w not in msg):  # what went wrong before it
            err.print(f"[yellow]warning:[/] {escape(warning)}", highlight=False, soft_wrap=True)
        if _disk_full(exc) and "no space left on the device" not in msg:
            # HDF5's own message is lines of its internals, naming the output's partial file at best
            msg = disk_full_said(exc, writing)
        elif writing is not None and _not_writable(exc, writing):
            refused = "its partial file could not be kept" if exc.errno == errno.ENOENT else os.strerror(exc.errno)  # type: ignore[union-attr]
            msg = f"{writing}: cannot be written there ({refused})"
        # escaped: a message quoting a value such as [inf] or a path with brackets is not rich markup
        err.print(f"[red]error:[/] {escape(msg)}", highlight=False, soft_wrap=True)
        raise typer.Exit(1) from None
    finally:
        sys.unraisablehook = unraisable_hook
        if quick_exit:
            signal.signal(signal.SIGINT, exit_interrupted)
        if quick_term:
            signal.signal(signal.SIGTERM, exit_interrupted)


def _not_writable(exc: BaseException, output: Path) -> bool:
    """Whether ``exc`` is the file system refusing the command's ``output``: the output itself, a folder on its way,
    or a partial file of it (``<stem>...partial...`` beside it, or inside it where it is a directory), named by the
    OS's error or by h5py's words ("name = '...'"); a read-only or locked folder, no permission."""
    if not isinstance(exc, OSError) or exc.errno not in (errno.EPERM, errno.EACCES, errno.EROFS, errno.ENOENT):
        return False
    named = exc.filename or (m.group(1) if (m := re.search(r"name = '([^']*)'", str(exc))) else None)
    if not named:
        return False
    path, out = Path(os.path.abspath(named)), Path(os.path.abspath(output))
    partial = ".partial" in path.name and (
        (path.parent == out.parent and path.name.startswith(out.with_suffix("").name + ".")) or out in path.parents)
    return partial or (exc.errno != errno.ENOENT and (path == out or path in out.parents))


def _signal_of(exc: KeyboardInterrupt) -> int:
    """The signal a KeyboardInterrupt stands for: SIGTERM for :class:`Terminated`, else SIGINT."""
    return signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT


def _said_stopped(signum: int) -> int:
    """Say that the command stopped on ``signum`` ("terminated" on SIGTERM, else "interrupted"); its exit code."""
    err.print(f"[red]error:[/] {'terminated' if signum == signal.SIGTERM else 'interrupted'}")
    return 128 + signum


def _stop(signum: int, frame: Any) -> None:
    """SIGINT and SIGTERM handler of a command's body: noted (an error that follows an interrupt swallowed on the
    way is the interrupt's), then raised as KeyboardInterrupt (:class:`Terminated` for SIGTERM). A second one while
    the first's clean-up runs ends the process at once: raised inside h5py's clean-up, it left h5py's lock held and
    the command hung; its partial files are then the next command's to remove (store.atomic)."""
    if _state.get("stopped_by") is not None and not _state.pop("raised_again", False):
        exit_interrupted(signum, frame)
    _state["stopped_by"] = signum
    raise Terminated if signum == signal.SIGTERM else KeyboardInterrupt


def _undo(steps: list[Callable[[], None]]) -> None:
    for step in reversed(steps):
        step()


def _interrupt_again(hook: Callable[[Any], None]) -> Callable[[Any], None]:
    """An unraisable-exception hook that raises a Ctrl-C swallowed in a destructor (or a callback) again, where
    it can stop the command, instead of printing "Exception ignored ..." and going on."""

    def interrupt_again(unraisable: Any) -> None:
        if unraisable.exc_type in (KeyboardInterrupt, Terminated):  # raised from here it would be unraisable again
            stop = signal.SIGTERM if unraisable.exc_type is Terminated else signal.SIGINT
            _state["raised_again"] = True  # the same interrupt, not a second one
            threading.Timer(0.01, signal.raise_signal, (stop,)).start()  # a moment later
            return
        hook(unraisable)

    return interrupt_again


def _not_a_log(path: Path, wanted: str, maker: str) -> None:
    """Refuse a drive log given where autosar's own file ``wanted`` is read, naming the command (``maker``, LOG for
    the log's name) that makes one of it."""
    from autosar_cli.ingest.sources import begins_as_a_container, is_log_directory
    from autosar_cli.store.outputs import is_autosar_product

    # a run written into the log's own directory holds the log, and is still a run
    if begins_as_a_container(path) or (path.is_dir() and is_log_directory(path) and not is_autosar_product(path)):
        raise ValueError(f"{path}: a drive log, not {wanted}: `{maker.replace('LOG', str(path))}` makes one")


def _an_input_file(path: Path, wanted: str, in_run: str) -> None:
    """Refuse a directory (or nothing) given where the file ``wanted`` is read, before the output is checked against
    it; a run directory's file of that name (``in_run``: drive.h5, trajectory.h5) is named as the one to give."""
    if not (path.exists() or path.is_symlink()):
        raise ValueError(f"{path}: no such file or directory")
    if path.is_dir():
        what = "a run directory" if (path / "run.json").is_file() else "a directory"
        give = f": give {path / in_run}" if (path / in_run).is_file() else ""
        raise ValueError(f"{path}: {what}, not {wanted}{give}")


def _a_directory_not_named_as_a_file(output: Path, what: str) -> None:
    """Refuse a directory output named as a file is (`run -o a.txt` made a directory a.txt holding run.json), unless
    it is one already (a run written there before, for --overwrite or --resume) or a file is there: the output gate
    names what it is (an input of the command, a file autosar did not write)."""
    if output.suffix.lower() in _FILE_SUFFIXES and not output.exists():
        raise typer.BadParameter(f"{output}: a file's name ({output.suffix}) for the directory {what} writes; name it "
                                 f"{output.with_suffix('')}")


def _an_hdf5_name(output: Path, what: str) -> None:
    """Refuse an HDF5 output (``what``: ingest's drive.h5) not named .h5 or .hdf5: `ingest -o t.txt` wrote HDF5 that
    `info` then read as an NMEA capture ("none of its 994 NMEA 0183 sentences could be read") and `info --verify`
    refused, as other tools, which go by the name, do."""
    suffix = output.suffix.lower()
    if suffix not in (".h5", ".hdf5"):
        named = f"a {output.suffix} name" if suffix else "a name without .h5"
        fixed = output.with_suffix(".h5") if suffix[1:].isalpha() else output.with_name(output.name + ".h5")
        raise typer.BadParameter(f"{output}: {named} for {what}, an HDF5 file; name it {fixed}")


def _load_config(path: Path | None) -> Any:
    from autosar_cli.config import load_config

    return load_config(path)


def _prepare_output(path: Path, overwrite: bool, inputs: list[Path | str | None],
                    replaces_directory: bool = False, ours: bool = False) -> None:
    """Pass ``path`` through the output gate (store.outputs: never an input, --overwrite only replaces what
    autosar made; ``ours``: an existing file there is autosar's, as the product it goes with says); a file is then
    replaced atomically by its writer, a directory (rosbag2) removed here."""
    from autosar_cli.store.outputs import check_output, make_directories, remove_product_directory

    check_output(path, [p for p in inputs if p], overwrite=overwrite, replaces_directory=replaces_directory,
                 ours=ours)
    if path.is_dir():
        remove_product_directory(path)
    _state["undo_on_failure"].append(make_directories(path.parent))


@contextmanager
def _progress(label: str, enabled: bool = True, in_bytes: bool = False) -> Iterator[Callable[[int, int], None]]:
    if not enabled or not err.is_terminal:
        yield lambda done, total: None
        return
    counts = (DownloadColumn(), TransferSpeedColumn()) if in_bytes else (MofNCompleteColumn(),)
    with Progress(TextColumn("[bold]{task.description}"), BarColumn(), *counts, TimeElapsedColumn(),
                  TimeRemainingColumn(), console=err, transient=True) as bar:
        task = bar.add_task(label, total=None)

        def update(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        yield update


@app.command(cls=_Command)
def simulate(
    output: Annotated[Path, typer.Option("--output", "-o", metavar="LOG",
                                         help="Log to write, named as --format writes it: .mcap, .bag (ros1), "
                                              "or a rosbag2 directory (ros2).")],
    scenario: Annotated[Scenario, typer.Option("--scenario", "-s", help="Drive to simulate.")] = Scenario.ci,
    fmt: Annotated[LogFormat | None, typer.Option(
        "--format", "-f", help="Log container (default: ros1 for a .bag, else mcap); dca1000: an MCAP of the "
                               "navigation plus the radar as a TI DCA1000 capture in <log stem>.dca1000/ (ingest "
                               "with --radar).")] = None,
    seed: Annotated[int, typer.Option("--seed", min=0, max=2**64 - 1, metavar="N",  # numpy's seeds: 64 bits
                                      help="Random seed: same seed, same bytes.")] = 0,
    dynamics: Annotated[Dynamics | None, typer.Option(
        "--dynamics", help="Vehicle model: kinematic bicycle or full 3-D dynamics (default: the config's "
                           "simulation.dynamics, full in the default config).")] = None,
    config: ConfigOpt = None,
    overwrite: OverwriteOpt = False,
    as_json: JsonOpt = False,
) -> None:
    """Write a realistic synthetic drive log (radar, CAN, GNSS, IMUs) plus a ground-truth sidecar <log>.truth.h5."""
    with _errors(output):
        from autosar_cli.sim.simulate import capture_dir_for
        from autosar_cli.sim.simulate import simulate as run_simulation
        from autosar_cli.sim.truth import truth_path_for

        suffix = output.suffix.lower()
        default = "" if fmt else " (the default but for a .bag)"
        fmt = fmt or (LogFormat.ros1 if suffix == ".bag" else LogFormat.mcap)
        want = {LogFormat.ros1: ".bag", LogFormat.ros2: ""}.get(fmt, ".mcap")
        if want and suffix != want:  # other tools go by the name; nor would --overwrite replace a log named otherwise
            named = f"a {output.suffix} name" if suffix else f"a name without {want}"
            fixed = output.with_suffix(want) if suffix[1:].isalpha() else output.with_name(output.name + want)
            raise typer.BadParameter(f"{output}: {named} for a --format {fmt.value} log{default}; name it {fixed}"
                                     + (", or give the --format it names" if suffix in (".bag", ".mcap") else ""))
        if not want and suffix in _FILE_SUFFIXES:
            raise typer.BadParameter(f"{output}: a {output.suffix} name for a --format ros2 log, which is a "
                                     f"directory (rosbag2); name it {output.with_suffix('')}"
                                     + (", or give the --format it names" if suffix in (".bag", ".mcap") else ""))
        cfg = _load_config(config)
        _prepare_output(output, overwrite, [cfg.source], replaces_directory=fmt is LogFormat.ros2)
        _prepare_output(truth_path_for(output), overwrite, [cfg.source])
        if fmt == LogFormat.dca1000:
            _prepare_output(capture_dir_for(output), overwrite, [cfg.source], replaces_directory=True)
        with _progress(f"simulate {scenario.value}", not as_json) as update:
            result = run_simulation(scenario.value, output, fmt=fmt.value, seed=seed, config=cfg, progress=update,
                                    dynamics=dynamics.value if dynamics else None, overwrite=overwrite)
        summary = {
            "log": str(result.log_path), "truth": str(result.truth_path), "scenario": result.scenario,
            "seed": result.seed, "format": result.format, "duration_s": round(result.duration_s, 3),
            "radar_frames": result.radar_frames, "messages": result.message_counts,
            "elapsed_s": round(result.elapsed_s, 2),
        }
        if result.radar_capture is not None:
            summary["radar_capture"] = str(result.radar_capture)
        if as_json:
            out.print_json(strict_json(summary))
        else:
            out.print(f"wrote [bold]{_lit(result.log_path)}[/] ({result.duration_s:.1f} s drive, "
                      f"{result.radar_frames} radar frames, {sum(result.message_counts.values())} messages) "
                      f"in {result.elapsed_s:.1f} s")
            out.print(f"truth  [bold]{_lit(result.truth_path)}[/]")
            if result.radar_capture is not None:
                out.print(f"radar  [bold]{_lit(result.radar_capture)}[/] (DCA1000 capture: autosar ingest "
                          f"{result.log_path} --radar {result.radar_capture})")


@app.command(cls=_Command)
def ingest(
    ctx: typer.Context,
    logs: Annotated[list[Path] | None, typer.Argument(
        metavar="LOG",
        help=f"Drive logs: .mcap, .bag, rosbag2 directories; CAN logs ({' '.join(CAN_LOG_SUFFIXES)}), NMEA text "
             "captures and DCA1000 captures are recognised too; a drive folder reads as the inputs it holds.")] = None,
    output: Annotated[Path, typer.Option("--output", "-o", metavar="FILE",
                                         help="drive.h5 to write.")] = Path("drive.h5"),
    config: ConfigOpt = None,
    dbc: DbcOpt = None,
    can_log: CanLogOpt = None,
    nmea: NmeaOpt = None,
    radar: Annotated[Path | None, typer.Option("--radar", metavar="CAPTURE", help="TI DCA1000 capture (its "
                                               "directory or a .bin of it: adc_data.bin, or a split series such as "
                                               "the raw mode's adc_data_Raw_0.bin, _1.bin … or <name>_0.bin …, read "
                                               "as one stream; with its *.mmwave.json, .cfg or .lua beside it, or "
                                               "that file itself) joining the logs' navigation.")] = None,
    radar_start: RadarStartOpt = None,
    radar_sync: RadarSyncOpt = "/dca1000/sync",
    radar_override: RadarOverrideOpt = False,
    allow_partial: Annotated[bool, typer.Option("--allow-partial",
                                                help="Write a drive without radar or without navigation.")] = False,
    allow_unverified: AllowUnverifiedOpt = False,
    time_offset: TimeOffsetOpt = None,
    allow_time_gap: AllowTimeGapOpt = False,
    max_time_gap: MaxTimeGapOpt = 3600.0,
    overwrite: OverwriteOpt = False,
    as_json: JsonOpt = False,
) -> None:
    """Decode CAN (with a DBC), GNSS, IMU and raw radar frames of drive logs into one drive.h5, streaming."""
    with _errors(output, kernels=False):
        from autosar_cli.ingest.inputs import an_output_given_as_a_log
        from autosar_cli.ingest.pipeline import ingest_sorted, sort_inputs

        if getattr(ctx.get_parameter_source("output"), "name", "") == "DEFAULT":  # `ingest LOG drive.h5`, no -o
            an_output_given_as_a_log(logs or [])
        cfg = _load_config(config)
        options = _ingest_options(dbc, radar_start, radar_sync, radar_override, allow_unverified, time_offset,
                                  allow_time_gap, max_time_gap)
        given = sort_inputs(logs or [], can_log or [], nmea or [], [radar] if radar else [])
        # a capture's folder may take the drive beside its data; a log's or a drive folder's may not
        _prepare_output(output, overwrite, [*(logs or []), *(p for p, kind in given.all() if kind != "radar"), dbc,
                                            cfg.source])
        _an_hdf5_name(output, "the drive.h5 ingest writes")
        from autosar_cli.store.outputs import check_free_space, input_bytes

        check_free_space(output, input_bytes([p for p, _ in given.all()]), "the drive")
        with _progress("ingest", not as_json, in_bytes=True) as update:
            report = ingest_sorted(given, output, config=cfg, allow_partial=allow_partial, progress=update,
                                   command=" ".join(sys.argv), **options.ingest_kwargs())
        d = {**report.to_dict(), "status": product_status(report.warnings)}
        if as_json:
            out.print_json(strict_json(d))
            return
        out.print(f"wrote [bold]{_lit(output)}[/]: {d['duration_s']:.2f} s of drive, {report.messages} messages read, "
                  f"{report.bytes_read / 1e6:.1f} MB in {report.wall_s:.1f} s ({d['throughput_mb_s']:.0f} MB/s)")
        table = Table("stream", "written", "rate (Hz)", "gaps", "dropped / repaired")
        for st in report.streams:
            span = (st["last_ns"] - st["first_ns"]) / 1e9
            rate = (st["written"] - 1) / span if span > 0 else 0.0
            notes = [f"{k} {st[k]}" for k in ("duplicates", "late_dropped", "time_jumps", "stamp_outliers",
                                                      "reordered") if st.get(k)]
            notes += [f"{k} {v}" for k, v in st["skipped"].items()]
            if st.get("missing_frames"):
                notes.append(f"missing frames {st['missing_frames']}")
            if st.get("full_scale_frames"):
                notes.append(f"clipped frames {st['full_scale_frames']}")
            table.add_row(st["path"], str(st["written"]), f"{rate:.1f}", str(st["gaps"]), ", ".join(notes))
        out.print(table)
        can = report.can
        problems = {k: sum(v.values()) if isinstance(v, dict) else v for k in (
            "unknown_ids", "impossible_ids", "dlc_mismatch", "checksum_errors", "counter_errors", "error_frames",
            "remote_frames", "out_of_range", "other_bus") if (v := can.get(k))}
        if can.get("frames"):
            out.print(f"CAN: {can['frames']} frames, {can['decoded']} decoded"
                      + "".join(f", {k.replace('_', ' ')} {v}" for k, v in problems.items()))
        if can.get("missing_roles") and not can.get("frames"):  # with frames, a warning names them
            out.print(f"no CAN frames in this log: the config's {len(can['missing_roles'])} CAN roles go unused")
        for sk in report.skipped_channels:
            out.print(f"skipped {sk['topic']} ({sk['msgtype']}): {_lit(sk['reason'])}", highlight=False)
        if degraded := _degraded(report.warnings, "its /provenance report"):
            out.print(f"{_lit(output)}:{degraded}")


@app.command(cls=_Command)
def navigate(
    drive: Annotated[Path, typer.Argument(metavar="DRIVE", help="drive.h5 written by `autosar ingest`.")],
    output: Annotated[Path, typer.Option("--output", "-o", metavar="FILE",
                                         help="trajectory.h5 to write.")] = Path("trajectory.h5"),
    method: Annotated[NavMethod, typer.Option("--method", "-m", help="sar-min (UKF fusion, paper Sec. II-B), ins "
                                              "(radar IMU + its GNSS, Sec. II-A), gnss (GNSS only), none (straight "
                                              "line), truth (simulator sidecar).")]
    = NavMethod.sar_min,
    no_smooth: Annotated[bool, typer.Option("--no-smooth", help="Filter only (no RTS smoother).")] = False,
    truth: Annotated[Path | None, typer.Option("--truth", metavar="FILE", help="Truth sidecar for --method truth "
                                               "(default: <log>.truth.h5 of the drive's input log).")] = None,
    plot: Annotated[bool, typer.Option("--plot", help="Also write OUTPUT.png: track, across-track deviation, "
                                       "speed, heading, yaw rate, gyro biases.")] = False,
    config: ConfigOpt = None,
    overwrite: OverwriteOpt = False,
    as_json: JsonOpt = False,
) -> None:
    """Estimate the vehicle trajectory of a drive (SAR-MIN UKF + RTS smoother, or a baseline)."""
    with _errors(output):
        import numpy as np

        from autosar_cli.nav.navigate import REPORTED_INFO
        from autosar_cli.nav.navigate import navigate as run_navigate
        from autosar_cli.store.trajectory import write_trajectory

        _not_a_log(drive, "a drive.h5", "autosar ingest LOG -o drive.h5")
        cfg = _load_config(config)
        _an_input_file(drive, "a drive.h5", "drive.h5")  # before the output is checked against it
        from autosar_cli.store.outputs import is_autosar_product

        plotted = output.is_file() and is_autosar_product(output)  # its plot beside it is autosar's too
        _prepare_output(output, overwrite, [drive, truth, cfg.source])
        _an_hdf5_name(output, "the trajectory.h5 navigate writes")
        if plot:
            _prepare_output(output.with_suffix(".png"), overwrite, [drive, truth, cfg.source], ours=plotted)
        traj = run_navigate(drive, method.value, cfg, smooth=not no_smooth, truth_path=truth)
        figure, drawn = None, None
        if plot:
            from autosar_cli.nav.plot import plot_trajectory
            from autosar_cli.store.atomic import partial_path

            figure = output.with_suffix(".png")
            drawn = plot_trajectory(traj, partial_path(figure))
        try:
            with interrupts_held():  # the trajectory and its plot come into place together: stopped between
                write_trajectory(output, traj)  # them, the new track stood beside the former's plot
                if drawn is not None:
                    os.replace(drawn, figure)
        finally:
            if drawn is not None:
                drawn.unlink(missing_ok=True)
        span = (traj.t_ns[-1] - traj.t_ns[0]) / 1e9
        dist = float(np.sum(np.hypot(*np.diff(traj.rear_axle_enu, axis=0).T)))
        summary = {"trajectory": str(output), "method": traj.method, "samples": len(traj.t_ns),
                   "duration_s": round(span, 3), "distance_m": round(dist, 3),
                   "elapsed_s": round(traj.info["elapsed_s"], 3),
                   **{k: traj.info[k] for k in REPORTED_INFO if k in traj.info},
                   **({"plot": str(figure)} if figure else {})}
        if as_json:
            out.print_json(strict_json(summary))
            return
        out.print(f"wrote [bold]{_lit(output)}[/]: {traj.method}, {len(traj.t_ns)} samples over {span:.2f} s, "
                  f"{dist:.1f} m travelled, in {traj.info['elapsed_s']:.1f} s")
        if traj.info.get("rejected"):
            updates = traj.info.get("updates", {})
            out.print("gated out: " + ", ".join(f"{k} {v} of {v + updates.get(k, 0)} updates"
                                                for k, v in traj.info["rejected"].items()))
        for w in traj.info.get("warnings", []):
            err.print(f"[yellow]warning:[/] {escape(w)}", highlight=False, soft_wrap=True)
        for stream, noise in traj.info.get("gnss_noise", {}).items():
            if noise.get("applied"):
                out.print(f"GNSS {stream} noise: {_lit(noise['reason'])}")
        if (slow := traj.info.get("gnss_slow_error", {})).get("applied"):
            out.print(f"GNSS slow error: {_lit(slow['reason'])}")
        correlation = traj.info.get("gnss_velocity_correlation", {})
        if correlation.get("applied"):
            out.print(f"GNSS velocity: {_lit(correlation['reason'])}")
        elif correlation.get("correlated"):
            err.print(f"[yellow]warning:[/] GNSS velocity: {escape(correlation['reason'])}", highlight=False,
                      soft_wrap=True)
        if (start := traj.info.get("before_first_fix", {})).get("applied"):
            err.print(f"[yellow]start:[/] {escape(start['reason'])} (its heading +- "
                      f"{start['heading_std_rad'] * 1000:.1f} mrad at the drive's start)", highlight=False,
                      soft_wrap=True)
        for gap in traj.info.get("gnss_gaps", []):
            at = (gap["start_ns"] - int(traj.t_ns[0])) / 1e9
            end = at + gap["duration_s"]
            err.print(f"[yellow]GNSS:[/] no fix over {gap['duration_s']:.1f} s ({at:.1f}-{end:.1f} s into the track): "
                      "the track there rests on the wheel speeds and gyros", highlight=False, soft_wrap=True)
        if traj.info.get("can_latency", {}).get("applied"):
            delay = traj.info["can_latency"]
            err.print(f"[yellow]CAN latency:[/] {escape(delay['reason'])} (+- {delay['std_s'] * 1000:.1f} ms, against "
                      f"{', '.join(delay['imu_gyros'])})", highlight=False, soft_wrap=True)
        if traj.info.get("gnss_latency", {}).get("applied"):
            latency = traj.info["gnss_latency"]
            err.print(f"[yellow]GNSS latency:[/] {escape(latency['reason'])} (+- {latency['std_s'] * 1000:.0f} ms, "
                      f"against imu/{latency['imu']})", highlight=False, soft_wrap=True)
        if "understeer" in traj.info and not traj.info["understeer"].get("refused"):  # a refusal is a warning
            out.print(_lit(traj.info["understeer"]["reason"]))  # with the steering (which K) or without, and why
        if traj.info.get("wheel_scale", {}).get("applied"):
            err.print(f"[yellow]wheels:[/] {escape(traj.info['wheel_scale']['reason'])}", highlight=False,
                      soft_wrap=True)
        if traj.info.get("wheel_lag", {}).get("applied"):
            lag = traj.info["wheel_lag"]
            out.print(f"wheel speeds moved back by {lag['lag_distance_m']:.3f} +- {lag['std_m']:.2g} m / speed")
        if traj.info.get("wheel_radii", {}).get("applied"):
            gains = traj.info["wheel_radii"]["applied"]
            out.print("wheel speeds divided by their fitted gains (% per m/s^2): "
                      + ", ".join(f"{k} {100 * v:.3g}" for k, v in gains.items()))
        for line in standstill_lines(traj.info, int(traj.t_ns[0])):
            out.print(line)
        heading = traj.info.get("gnss_heading")
        if heading:
            out.print(f"GNSS heading fused ({heading['samples']} samples), its offset {heading['offset_deg']:+.3f} +- "
                      f"{heading['offset_std_deg']:.3f} deg" if heading["applied"] else
                      f"GNSS heading not fused: {heading['reason']}")
        attitude = traj.info.get("attitude", {})
        if attitude.get("applied"):
            height = attitude.get("height", {})
            out.print(f"radar moved by the body's roll and pitch ({attitude['offset_rms_mm']:.1f} mm RMS); "
                      + (f"its height along the road over {height['range_m']:.2f} m, the IMU's pitch bias "
                         f"{attitude['pitch_bias_mrad']:+.1f} +- {attitude['pitch_bias_std_mrad']:.1f} mrad out"
                         if height.get("applied") else height.get("reason", "")))
        if figure:
            out.print(f"figure [bold]{_lit(figure)}[/]")


def standstill_lines(info: dict[str, Any], t0_ns: int) -> list[str]:
    """One line per standstill SAR-MIN held at a zero yaw rate, and per one it refused (the wheels at 0 while the
    gyros turn: a creeping turn), its span in s from ``t0_ns`` (the trajectory's first instant)."""
    def span(ns: list[int]) -> str:
        return f"{(ns[0] - t0_ns) / 1e9:.1f}-{(ns[1] - t0_ns) / 1e9:.1f} s"

    lines = [f"standstill {span(ns)}: yaw rate held at 0" for ns in info.get("standstill_ns", [])]
    lines += [f"wheels at 0 over {span(r['span_ns'])} while the gyros turn {r['yaw_rate_dps']:+.3f} +- "
              f"{r['std_dps']:.3f} deg/s: a creeping turn, not held as a standstill"
              for r in info.get("standstill_refused", [])]
    return lines


class Channels(StrEnum):
    eight = "8"
    twelve = "12"


@app.command(cls=_Command)
def focus(
    drive: Annotated[Path, typer.Argument(metavar="DRIVE", help="drive.h5 written by `autosar ingest`.")],
    trajectory: Annotated[Path, typer.Option("--trajectory", "-t", metavar="FILE", help="trajectory.h5 written by "
                                             "`autosar navigate`.")],
    output: Annotated[Path, typer.Option("--output", "-o", metavar="BASE",
                                         help="Output base name: writes BASE.tif (GeoTIFF, dB, "
                                         "UTM), BASE.h5 (complex image) and BASE.png (quicklook).")] = Path("image"),
    pixel: Annotated[float | None, typer.Option("--pixel", metavar="METRES",
                                                help="Pixel spacing in metres (default: the config's "
                                                "processing.pixel_m, 0.04 in the default config).")]
    = None,
    resolution: Annotated[float | None, typer.Option("--resolution", metavar="METRES",
                                                     help="Cross-range resolution rho in metres: the "
                                                     "processed beam is lambda/(4 rho) wide (default: the "
                                                     "config's processing.cross_range_resolution_m, 0.04 in the "
                                                     "default config).")]
    = None,
    channels: Annotated[Channels | None, typer.Option("--channels", help="8: Tx0 + Tx2 with the 4 Rx, whose "
                                                      "channels' phase centres (Tx-Rx midpoints) lie lambda/4 apart "
                                                      "in one row; 12: all Tx-Rx pairs (default: the config's "
                                                      "processing.channels, 8 in the default config).")] = None,
    height: Annotated[float | None, typer.Option("--height", metavar="METRES",
                                                 help="Focusing plane height, ENU metres above the "
                                                 "road at the origin (default: the config's "
                                                 "processing.focus_height_m, 0.5 in the default config).")] = None,
    grid: Annotated[str, typer.Option("--grid", metavar="auto|X0,Y0,X1,Y1", help="'auto' (along the trajectory on the "
                                      "radar side, ground range 0.5 m to R_max) or x0,y0,x1,y1 in ENU "
                                      "metres.")] = "auto",
    radar_stream: RadarStreamOpt = None,
    tiles: Annotated[int, typer.Option("--tiles", min=1, metavar="N",
                                       help="Focus the grid in N tiles along the track, one "
                                       "after the other (same image; each holds only its tile in memory, but "
                                       "re-reads the pulses).")] = 1,
    config: ConfigOpt = None,
    overwrite: OverwriteOpt = False,
    as_json: JsonOpt = False,
) -> None:
    """Focus the radar with time-domain back-projection (stripmap, coherent MIMO sum) into georeferenced images."""
    with _errors(output):
        from autosar_cli.sar.focus import FocusOptions
        from autosar_cli.sar.focus import focus as run_focus

        _not_a_log(drive, "a drive.h5", "autosar ingest LOG -o drive.h5")
        _not_a_log(trajectory, "a trajectory.h5", "autosar run LOG -o DIR")
        cfg = _load_config(config)
        options = FocusOptions.from_config(cfg, pixel_m=pixel, resolution_m=resolution, height_m=height, grid=grid,
                                           channels=int(channels.value) if channels else None, radar=radar_stream)
        _an_input_file(drive, "a drive.h5", "drive.h5")  # before the output is checked against them
        _an_input_file(trajectory, "a trajectory.h5", "trajectory.h5")
        from autosar_cli.store.outputs import make_directories

        _state["undo_on_failure"].append(make_directories(output.parent))  # as ingest and navigate make theirs
        with _progress("focusing", enabled=not as_json) as progress:
            if tiles > 1:
                from autosar_cli.sar.tiles import focus_tiled

                report = focus_tiled(drive, trajectory, output, cfg, options, tiles=tiles, overwrite=overwrite,
                                     progress=progress, command=" ".join(sys.argv))
            else:
                report = run_focus(drive, trajectory, output, cfg, options, overwrite=overwrite, progress=progress,
                                   command=" ".join(sys.argv))
        summary = {**report.to_dict(), "status": product_status(report.warnings)}
        if as_json:
            out.print_json(strict_json(summary))
            return
        rows, cols = report.grid_shape
        wall = summary["wall_s"]
        out.print(f"wrote [bold]{_lit(report.outputs['tif'])}[/], {_lit(report.outputs['h5'])}, "
                  f"{_lit(report.outputs['png'])}: "
                  f"{rows} x {cols} pixels at {options.pixel_m * 100:g} cm, {report.frames_used} frames, "
                  f"{report.backprojections / 1e9:.2f} G back-projections in {wall:.1f} s "
                  f"({wall / max(report.drive_s, 1e-9):.2f} x the drive's {report.drive_s:.1f} s)")
        for reason, n in report.frames_skipped.items():
            err.print(f"[yellow]skipped[/] {n} frames: {_lit(reason)}", highlight=False)
        if degraded := _degraded(report.warnings, f"{Path(report.outputs['h5']).name}'s provenance"):
            out.print(f"{_lit(report.outputs['h5'])}:{degraded}")


@app.command(cls=_Command)
def run(
    logs: Annotated[list[Path], typer.Argument(
        metavar="LOG", help="Drive log(s): .mcap, .bag, rosbag2 directory (and CAN/NMEA log files, or a drive "
                            "folder holding them), as for `autosar ingest`.")],
    output: Annotated[Path, typer.Option("--output", "-o", metavar="DIR",
                                         help="Run directory: drive.h5, trajectory.h5, "
                                         "image.tif/.h5/.png and run.json.")],
    method: Annotated[NavMethod, typer.Option("--method", "-m", help="Navigation method (see `autosar navigate`).")]
    = NavMethod.sar_min,
    truth: Annotated[Path | None, typer.Option("--truth", metavar="FILE",
                                               help="Truth sidecar for --method truth (default: <log>.truth.h5 "
                                                    "of the drive's input log).")] = None,
    radar: RadarCaptureOpt = None,
    radar_start: RadarStartOpt = None,
    radar_sync: RadarSyncOpt = "/dca1000/sync",
    radar_override: RadarOverrideOpt = False,
    radar_stream: RadarStreamOpt = None,
    autofocus: AutofocusOpt = False,
    dbc: DbcOpt = None,
    can_log: CanLogOpt = None,
    nmea: NmeaOpt = None,
    allow_unverified: AllowUnverifiedOpt = False,
    time_offset: TimeOffsetOpt = None,
    allow_time_gap: AllowTimeGapOpt = False,
    max_time_gap: MaxTimeGapOpt = 3600.0,
    config: ConfigOpt = None,
    overwrite: OverwriteOpt = False,
    as_json: JsonOpt = False,
) -> None:
    """Ingest, navigate and focus a drive in one go; every product in one directory plus a run.json manifest."""
    with _errors(output):
        _a_directory_not_named_as_a_file(output, "`autosar run`")
        from autosar_cli.run import run as run_chain
        from autosar_cli.sar.focus import FocusOptions

        cfg = _load_config(config)
        options = FocusOptions.from_config(cfg, radar=radar_stream)
        with _stages(not as_json) as update:
            manifest = run_chain(logs, output, cfg, method=method.value, radar_captures=[radar] if radar else [],
                                 options=options, truth_path=truth, autofocus=autofocus, overwrite=overwrite,
                                 progress=update, command=" ".join(sys.argv), fork_ingest=True,
                                 can_logs=can_log or [], nmea_logs=nmea or [],
                                 ingest_options=_ingest_options(dbc, radar_start, radar_sync, radar_override,
                                                                allow_unverified, time_offset, allow_time_gap,
                                                                max_time_gap))
        if as_json:
            out.print_json(strict_json(manifest))
            return
        table = Table("stage", "wall (s)", "summary")
        st = manifest["stages"]
        table.add_row("ingest", f"{st['ingest']['wall_s']:.2f}", f"{st['ingest']['messages']} messages")
        latency = st["navigate"].get("gnss_latency", {})
        table.add_row("navigate", f"{st['navigate']['wall_s']:.2f}",
                      f"{st['navigate']['method']}, {st['navigate']['distance_m']:.1f} m"
                      + (f", GNSS latency {1000 * (latency['table_latency_s'] + latency['change_s']):.0f} ms "
                         f"(its table {1000 * latency['table_latency_s']:g})" if latency.get("applied") else ""))
        if "autofocus" in st:
            table.add_row("autofocus", f"{st['autofocus']['wall_s']:.2f}", st["autofocus"]["summary"])
        table.add_row("focus", f"{st['focus']['wall_s']:.2f}",
                      f"{st['focus']['grid_shape'][0]} x {st['focus']['grid_shape'][1]} px, "
                      f"{st['focus']['backprojections'] / 1e9:.2f} G back-projections")
        out.print(table)
        degraded = _degraded(manifest["warnings"], "run.json")  # a damaged log, dropped data, no autofocus
        out.print(f"wrote [bold]{_lit(output)}[/] (run.json, drive.h5, trajectory.h5, image.tif/.h5/.png) in "
                  f"{manifest['wall_s']:.1f} s = {manifest['fraction_of_drive']:.2f} x the drive's "
                  f"{manifest['drive_s']:.1f} s{degraded}")


def _degraded(warnings: list[str], record: str | None) -> str:
    """Each warning of a product made from a damaged input on stderr; what the command's last line adds when
    there is any (``record``: the file that keeps them, where one does)."""
    for w in warnings:
        err.print(f"[yellow]warning:[/] {escape(w)}", highlight=False, soft_wrap=True)
    n = len(warnings)
    kept = f", in {record}" if record else ""
    return f" [yellow]degraded[/] ({n} warning{'' if n == 1 else 's'} above{kept})" if warnings else ""


@contextmanager
def _stages(enabled: bool = True) -> Iterator[Callable[[str, int, int], None]]:
    """Progress bars on stderr, one per stage: yields ``update(stage, done, total)``."""
    if not enabled or not err.is_terminal:
        yield lambda stage, done, total: None
        return
    with Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  console=err, transient=True) as bar:
        tasks: dict[str, Any] = {}

        def update(stage: str, done: int, total: int) -> None:
            if stage not in tasks:
                tasks[stage] = bar.add_task(stage, total=total)
            bar.update(tasks[stage], completed=done, total=total)

        yield update


def _cm(value: float | None, scale: float = 100.0, digits: int = 1) -> str:
    return "–" if value is None else f"{value * scale:.{digits}f}"


@app.command(cls=_Command)
def evaluate(
    source: Annotated[Path, typer.Argument(metavar="RUN", help="A run directory (run.json; from `autosar run` or a "
                                           "method directory of `autosar compare`) or an image.h5.")],
    output: Annotated[Path, typer.Option("--output", "-o", metavar="DIR",
                                         help="Report directory: metrics.json, report.md, "
                                         "trajectory_error.png, reflector_chips.png.")],
    truth: Annotated[Path | None, typer.Option("--truth", metavar="FILE",
                                               help="Truth sidecar LOG.truth.h5 (default: the run's, or "
                                               "<log>.truth.h5 next to the drive's input log).")] = None,
    config: Annotated[Path | None, typer.Option("--config", "-c", metavar="FILE",
                                                help="TOML config (default: the one the run "
                                                "used).")] = None,
    overwrite: OverwriteOpt = False,
    as_json: JsonOpt = False,
) -> None:
    """Evaluate a focused run against the truth: trajectory errors, corner reflectors (position, peak loss, IRW,
    PSLR, ISLR on fine patches), entropy, contrast, straightness of the facade and kerb."""
    with _errors(output):
        _a_directory_not_named_as_a_file(output, "`autosar evaluate`")
        from autosar_cli.evaluate.report import evaluate_run

        _not_a_log(source, "a run directory or image.h5", "autosar run LOG -o DIR")
        cfg = _load_config(config) if config else None
        with _stages(not as_json) as update:
            result = evaluate_run(source, output, truth, config=cfg, overwrite=overwrite, progress=update)
        if as_json:
            out.print_json(strict_json(result))
            return
        s = result["summary"]
        table = Table("metric", "value")
        table.add_row("method", str(s["method"]))
        if result.get("truth"):
            table.add_row("absolute RMSE / after SE(2) alignment", f"{_cm(s['abs_rmse_m'])} / "
                          f"{_cm(s['aligned_rmse_m'], digits=2)} cm")
            table.add_row("RPE across, 1 m / 10 m", f"{_cm(s['rpe_1m_across_m'], 1e3, 2)} / "
                          f"{_cm(s['rpe_10m_across_m'], 1e3, 2)} mm")
            table.add_row("reflectors: aligned error mean / max", f"{_cm(s['aligned_error_mean_m'], digits=2)} / "
                          f"{_cm(s['aligned_error_max_m'], digits=2)} cm ({s['reflectors']} reflectors)")
            table.add_row("reflectors: peak loss mean / max", f"{_cm(s['peak_loss_mean_db'], 1)} / "
                          f"{_cm(s['peak_loss_max_db'], 1)} dB")
        table.add_row("entropy / contrast", f"{_cm(s['entropy'], 1, 4)} nats / {_cm(s['contrast'], 1, 1)}")
        table.add_row("range-normalised: entropy / contrast",
                      f"{_cm(s.get('entropy_rn'), 1, 4)} nats / {_cm(s.get('contrast_rn'), 1, 1)}")
        table.add_row("far swath: entropy / contrast",
                      f"{_cm(s.get('entropy_far'), 1, 4)} nats / {_cm(s.get('contrast_far'), 1, 1)}")
        for kind in ("facade", "kerb"):
            if s.get(f"straightness_{kind}_m") is not None:
                table.add_row(f"{kind} straightness (RMS)", f"{_cm(s[f'straightness_{kind}_m'], digits=2)} cm")
        out.print(table)
        degraded = _degraded(result["input_warnings"], "metrics.json")
        out.print(f"wrote [bold]{_lit(output)}[/] ({', '.join(Path(p).name for p in result['outputs'].values())})"
                  f"{degraded}")
        for note in result.get("notes", []):
            err.print(f"[yellow]note:[/] {_lit(note)}", highlight=False, soft_wrap=True)


@app.command(cls=_Command)
def compare(
    logs: Annotated[list[Path], typer.Argument(metavar="LOG", help="Drive log(s), as for `autosar run`.")],
    output: Annotated[Path, typer.Option("--output", "-o", metavar="DIR",
                                         help="Comparison directory: drive.h5, one directory "
                                         "per method, compare.png, across_track.png, compare_chips.png (with a "
                                         "truth), compare.md, compare.json.")],
    methods: Annotated[str, typer.Option("--methods", metavar="M1,M2,...", help="Comma-separated navigation methods "
                                         "(sar-min, ins, gnss, none, truth; sar-min+scale: SAR-MIN with its track's "
                                         "scale measured by the radar on the truth's corner reflectors, ~20 wide-beam "
                                         "focusings; "
                                         "sar-min+af: SAR-MIN corrected by the residual-motion autofocus, as "
                                         "`autosar run --autofocus`, no truth needed).")] = "none,ins,sar-min,truth",
    truth: Annotated[Path | None, typer.Option("--truth", metavar="FILE",
                                               help="Truth sidecar (default: <log>.truth.h5).")] = None,
    radar: RadarCaptureOpt = None,
    radar_start: RadarStartOpt = None,
    radar_sync: RadarSyncOpt = "/dca1000/sync",
    radar_override: RadarOverrideOpt = False,
    dbc: DbcOpt = None,
    can_log: CanLogOpt = None,
    nmea: NmeaOpt = None,
    allow_unverified: AllowUnverifiedOpt = False,
    time_offset: TimeOffsetOpt = None,
    allow_time_gap: AllowTimeGapOpt = False,
    max_time_gap: MaxTimeGapOpt = 3600.0,
    config: ConfigOpt = None,
    overwrite: OverwriteOpt = False,
    as_json: JsonOpt = False,
) -> None:
    """Focus one drive with several navigation methods and compare them side by side (paper Fig. 10/11)."""
    with _errors(output):
        _a_directory_not_named_as_a_file(output, "`autosar compare`")
        from autosar_cli.evaluate.compare import DRIVE, parse_methods
        from autosar_cli.evaluate.compare import compare as run_compare

        cfg = _load_config(config)
        chosen = parse_methods(methods)
        with _stages(not as_json) as update:
            result = run_compare([*logs, *([radar] if radar else [])], output, cfg, methods=chosen, truth_path=truth,
                                 overwrite=overwrite, progress=update, command=" ".join(sys.argv),
                                 can_logs=can_log or [], nmea_logs=nmea or [],
                                 ingest_options=_ingest_options(dbc, radar_start, radar_sync, radar_override,
                                                                allow_unverified, time_offset, allow_time_gap,
                                                                max_time_gap))
        if as_json:
            out.print_json(strict_json(result))
            return
        # one column per method, so that it fits an 80-column terminal; contrasts and the rest are in compare.md
        summaries = {m: result["results"][m]["summary"] for m in result["methods"]}
        table = Table("", *(Column(m, no_wrap=True, justify="right") for m in summaries))
        rows: list[tuple[str, Callable[[dict[str, Any]], str]]] = [
            ("abs RMSE (cm)", lambda s: _cm(s["abs_rmse_m"])),
            ("RPE 1 m across (mm)", lambda s: _cm(s["rpe_1m_across_m"], 1e3, 2)),
            ("reflector error mean / max (cm)",
             lambda s: f"{_cm(s['aligned_error_mean_m'], digits=2)} / {_cm(s['aligned_error_max_m'], digits=2)}"),
            ("peak loss mean / max (dB)",
             lambda s: f"{_cm(s['peak_loss_mean_db'], 1)} / {_cm(s['peak_loss_max_db'], 1)}"),
            ("entropy (nats)", lambda s: _cm(s["entropy"], 1, 4)),
            ("range-normalised entropy", lambda s: _cm(s.get("entropy_rn"), 1, 4)),
            ("far swath entropy", lambda s: _cm(s.get("entropy_far"), 1, 4)),
        ]
        for label, cell in rows:
            table.add_row(label, *(cell(s) for s in summaries.values()))
        out.print(table)
        written = [DRIVE, "compare.json", *(v for v in result["outputs"].values() if isinstance(v, str))]
        degraded = _degraded(result["warnings"], "compare.json")
        out.print(f"wrote [bold]{_lit(output)}[/] ({', '.join(written)}; per method: "
                  f"{', '.join(m + '/' for m in result['methods'])}) in {result['wall_s']:.1f} s{degraded}")
        for m, why in result["skipped"].items():
            err.print(f"[yellow]skipped[/] {m}: {_lit(why)}", highlight=False, soft_wrap=True)
        for note in result["notes"]:
            err.print(f"[yellow]note:[/] {_lit(note)}", highlight=False, soft_wrap=True)


#: damaged chunks named one per line, beyond which a count stands for the rest
_DAMAGED_NAMED = 20


def _verify(path: Path, as_json: bool) -> None:
    """``autosar info PATH --verify``: every stored chunk of an autosar HDF5 file, or every tile of its GeoTIFF, read
    and checked against its checksums; of a directory (a run's), each such file in it, and of one holding runs (a
    comparison's methods, a batch's drives), each run's too."""
    from autosar_cli.store.verify import VERIFIED_SUFFIXES

    if path.is_dir():
        runs = sorted(p for p in path.iterdir() if (p / "run.json").is_file())
        folders = [path, *runs]
        files = sorted(p for folder in folders for p in folder.iterdir() if p.is_file()
                       and p.suffix.lower() in VERIFIED_SUFFIXES and ".partial-" not in p.name)
        if not files and not runs:
            raise typer.BadParameter(f"{path}: holds no file autosar writes with checksums (drive.h5, trajectory.h5, "
                                     "image.h5, image.tif, image.png)")
    elif path.suffix.lower() in VERIFIED_SUFFIXES:
        files, folders = [path], []
    else:
        raise typer.BadParameter(f"{path}: --verify reads a file autosar wrote (drive.h5, trajectory.h5, image.h5, "
                                 "image.tif, image.png) or a directory of them")
    found = [_checked(p, in_directory=path.is_dir()) for p in files]
    for folder in folders:
        if (folder / "run.json").exists():
            found += _run_outputs_checked(folder)
    if as_json:
        out.print_json(strict_json({"path": str(path), "files": found, "intact": all(f["intact"] for f in found)}
                                  if path.is_dir() else found[0]))
    else:
        for f in found:
            _print_checked(f)
    if not all(f["intact"] for f in found):
        raise typer.Exit(1)


def _run_outputs_checked(run_dir: Path) -> list[dict[str, Any]]:
    """A run directory's run.json, read, and each product it lists, there: an entry (not intact) for each that is
    not, so that a run missing a product, or with its manifest cut, is not called intact."""
    from autosar_cli.run import RunError, not_finished, read_manifest

    try:
        manifest = read_manifest(run_dir)
    except RunError as exc:
        return [{"path": str(run_dir / "run.json"), "error": str(exc), "intact": False}]
    outputs = manifest.get("outputs", {})
    if unfinished := not_finished(manifest):
        return [{"path": str(run_dir / "run.json"), "error": f"{run_dir / 'run.json'}: {unfinished}", "intact": False}]
    listed = [v for v in outputs.values() if isinstance(v, str)] + [
        v for group in outputs.values() if isinstance(group, dict) for v in group.values() if isinstance(v, str)]
    return [{"path": str(run_dir / name), "error": f"{run_dir / name}: listed in run.json but missing", "intact": False}
            for name in listed if not (run_dir / name).exists()]


def _checked(path: Path, in_directory: bool) -> dict[str, Any]:
    """What the check of one file found (``intact`` among it); in a directory, a file that cannot be opened as one
    autosar wrote is found so, not an error that ends the check."""
    from autosar_cli.store.verify import verify_file

    try:
        return verify_file(path)
    except (ValueError, OSError) as exc:
        if not in_directory:
            raise
        return {"path": str(path), "error": str(exc), "intact": False}


def _print_checked(found: dict[str, Any]) -> None:
    """One file's check as ``info --verify`` prints it: what is damaged on stderr, a summary line on stdout."""
    path = found["path"]
    if "error" in found:
        err.print(f"[red]error:[/] {_lit(found['error'])}", highlight=False, soft_wrap=True)
        return
    if "chunks" in found and "datasets" not in found:  # a PNG
        for line in found["damaged"]:
            err.print(f"[red]damaged:[/] {_lit(line)}", highlight=False, soft_wrap=True)
        state = "every chunk's CRC-32 and its pixels' stream hold" if found["intact"] else "not verified intact"
        out.print(f"[bold]{_lit(path)}[/]: {found['chunks']} chunks, {state}")
        return
    if "datasets" in found:  # an HDF5 file
        damaged = found["damaged"]
        for d in damaged[:_DAMAGED_NAMED]:
            at = f" at {list(d['at'])}" if d["at"] else ""
            if d["dataset"] == "attributes":
                err.print(f"[red]damaged:[/] {_lit(d['reason'])}", highlight=False, soft_wrap=True)
                continue
            err.print(f"[red]damaged:[/] {_lit(d['dataset'])} rows {d['rows'][0]}-{d['rows'][1] - 1}{at}: "
                      f"{_lit(d['reason'])}", highlight=False, soft_wrap=True)
        if len(damaged) > _DAMAGED_NAMED:
            err.print(f"[red]damaged:[/] {len(damaged) - _DAMAGED_NAMED} more chunks", highlight=False)
        if not damaged:
            out.print(f"[bold]{_lit(path)}[/]: {found['datasets']} datasets, {found['chunks']} stored chunks, every "
                      "checksum holds")
        else:
            chunks = [d for d in damaged if d["dataset"] != "attributes"]
            said = [f"{len(chunks)} of {found['chunks']} stored chunks damaged, in "
                    f"{len({d['dataset'] for d in chunks})} of {found['datasets']} datasets"] if chunks else []
            if len(chunks) < len(damaged):
                said.append("its attributes damaged")
            out.print(f"[bold]{_lit(path)}[/]: {'; '.join(said)}")
        return
    if found["intact"]:
        out.print(f"[bold]{_lit(path)}[/]: {found['tiles']} tiles, {found['columns']} columns, its georeference and "
                  "every column's checksum hold")
        return
    said = [*([] if found["checksummed"] else ["carries no autosar checksum: nothing to check it against"]),
            *([] if found["georeference_intact"] else ["its georeference (transform, CRS) is not the one written"]),
            *([] if found["tags_intact"] else ["its columns' checksum tag is damaged"]),
            *[f"tile at {u}" for u in found["unreadable"][:_DAMAGED_NAMED]],
            *[f"columns {a}-{b - 1} differ from those written" for a, b in found["damaged_columns"][:_DAMAGED_NAMED]]]
    for line in said:
        err.print(f"[red]damaged:[/] {_lit(line)}" if found["checksummed"] else f"[yellow]note:[/] {_lit(line)}",
                  highlight=False, soft_wrap=True)
    out.print(f"[bold]{_lit(path)}[/]: not verified intact")


@app.command(cls=_Command)
def info(
    path: Annotated[Path, typer.Argument(metavar="PATH", help="A drive log (.mcap, .bag, rosbag2 directory), a TI "
                                         "DCA1000 capture, a drive folder (each input it holds) or a drive.h5; or "
                                         "any directory, for its stale partial files.")],
    as_json: JsonOpt = False,
    config_sketch: Annotated[bool, typer.Option(
        "--config-sketch", help="Of a drive.h5: print a config (TOML, laid over --config) that pins its streams' "
        "topics to the config's sensors, for a log recorded on other topics (docs/LOGS.md); of a TI DCA1000 capture: "
        "the \\[radar] keys it states, for a config to ingest it with (docs/RADAR.md).")] = False,
    verify: Annotated[bool, typer.Option(
        "--verify", help="Of a file autosar wrote (drive.h5, trajectory.h5, image.h5, image.tif, image.png), or a "
        "run's directory of them: read every stored chunk or tile and check its checksum; exit 1 naming each "
        "damaged one.")] = False,
    config: ConfigOpt = None,
) -> None:
    """Summarise a log or drive.h5: streams, message types, counts, rates, time span and gaps; and list the
    partial files that killed autosar processes left beside it. --verify checks a stored file's checksums."""
    with _errors(kernels=False):
        from autosar_cli.store.outputs import _hdf5_format, input_problem, what_autosar_wrote

        if (problem := input_problem(path)) is not None and (path.exists() or path.is_symlink()):
            raise ValueError(f"{path}: {problem}")
        cfg = _load_config(config) if config is not None else None  # checked as every other command checks it
        if verify:
            _verify(path, as_json)
            return
        if config_sketch:
            from autosar_cli.config_sketch import capture_config_sketch, config_sketch
            from autosar_cli.ingest.dca1000 import is_capture

            if is_capture(path):
                sketch = capture_config_sketch
            elif path.suffix.lower() in (".h5", ".hdf5"):
                sketch = config_sketch
            else:
                raise typer.BadParameter(f"{path}: --config-sketch reads a drive.h5 or a TI DCA1000 capture; ingest "
                                         "the log first (autosar ingest LOG -o drive.h5, --allow-partial without a "
                                         "radar)")
            out.print(sketch(path, cfg or _load_config(None)), markup=False, highlight=False, soft_wrap=True, end="")
            return
        from autosar_cli.store.atomic import stale_partials

        stale = [str(p) for p in stale_partials(path if path.is_dir() else path.parent)]
        from autosar_cli.ingest.dca1000 import capture_problem, is_capture
        from autosar_cli.ingest.inputs import drive_folder
        from autosar_cli.ingest.inspect import summarize
        from autosar_cli.ingest.sources import is_log_directory

        folder = drive_folder(path)
        if path.is_dir() and not is_log_directory(path) and not is_capture(path) and folder is None:  # plain
            if (problem := capture_problem(path)) is not None:  # ADC data or a parameter file, not read as a capture
                raise ValueError(problem)
            if as_json:
                out.print_json(strict_json({"path": str(path), "stale_partials": stale}))
                return
            wrote = what_autosar_wrote(path)
            holds = "" if wrote is not None else (
                " holds no log, CAN log, NMEA capture or DCA1000 capture (`autosar info` summarises one of those, a "
                "folder of them or a drive.h5);")
            out.print(f"[bold]{_lit(path)}[/]:{holds} {len(stale)} stale partial file(s)"
                      + "".join(f"\n  {escape(p)}" for p in stale), highlight=False, soft_wrap=True)
            if wrote is not None:  # a run's directory: where its summary is
                out.print(f"{_lit(path)}: {_lit(wrote)}; `autosar info {_lit(path / 'drive.h5')}` lists its drive's "
                          f"streams, `autosar info {_lit(path)} --verify` checks its products", highlight=False,
                          soft_wrap=True)
            return
        if folder is None and path.is_file() and _hdf5_format(path) not in (None, "autosar-drive"):
            raise ValueError(f"{path}: {what_autosar_wrote(path)}; `autosar info` lists a log's or a drive.h5's "
                             f"streams, `autosar info {path} --verify` checks this file's checksums")
        inputs = [(p, kind) for kind, ps in folder.inputs.items() for p in ps] if folder else [(path, "")]
        summaries = [(p, kind, summarize(p)) for p, kind in inputs]
        said = folder.warning() if folder else None
        pinned = _pinned_in_logs(cfg, [summary for _, _, summary in summaries]) if cfg is not None else None
        if as_json:
            if folder is None:
                out.print_json(strict_json({**summaries[0][2].to_dict(), "stale_partials": stale,
                                            **({"config_topics": pinned} if pinned is not None else {})}))
            else:
                out.print_json(strict_json({"path": str(path), "drive_folder": [
                    {"kind": kind, **summary.to_dict()} for _, kind, summary in summaries],
                    "left_out": [str(p) for p in folder.left_out], "stale_partials": stale,
                    **({"config_topics": pinned} if pinned is not None else {})}))
            return
        if folder is not None:
            out.print(f"[bold]{_lit(path)}[/]  a drive folder: {len(inputs)} input{'s' * (len(inputs) != 1)}, each "
                      "read as if given on its own")
        for p, _, summary in summaries:
            _print_summary(p, summary)
        if folder is not None and folder.inputs["radar"] and not folder.inputs["log"]:
            capture = folder.inputs["radar"][0]
            out.print(f"{_lit(path)}: a DCA1000 capture and no log: the log recorded with it holds the drive's "
                      f"navigation and the triggers that time its frames; give it too: `autosar ingest LOG --radar "
                      f"{_lit(capture)} -o drive.h5` (or put the log in {_lit(path)})", highlight=False,
                      soft_wrap=True)
        if pinned is not None and pinned["in_logs"] + pinned["not_in_logs"]:
            out.print(f"{_lit(config)}: the topics it pins, in the logs: "
                      + (", ".join(f"{t['topic']} ({t['key']})" for t in pinned["in_logs"]) or "none")
                      + "; not in them: "
                      + (", ".join(f"{t['topic']} ({t['key']})" for t in pinned["not_in_logs"]) or "none"),
                      highlight=False, soft_wrap=True)
        if said:
            err.print(f"[yellow]warning:[/] {escape(said)}", highlight=False, soft_wrap=True)
        for p in stale:
            err.print(f"[yellow]stale partial file:[/] {escape(p)} (left by a killed autosar; the next command "
                      f"writing there removes it)", highlight=False, soft_wrap=True)


def _pinned_in_logs(cfg: Config, summaries: list[Any]) -> dict[str, list[dict[str, str]]] | None:
    """The topics ``cfg`` pins, those the logs summarised hold and those they do not; None where no summary is of a
    log with topics (a drive.h5's streams are named by sensor)."""
    topics = {s.topic for summary in summaries for s in summary.streams if s.topic.startswith("/")}
    if not topics:
        return None
    pinned = [{"topic": t, "key": key} for t, (_, _, key) in sorted(cfg.pinned_topics().items(), key=lambda i: i[1][2])]
    return {"in_logs": [p for p in pinned if p["topic"] in topics],
            "not_in_logs": [p for p in pinned if p["topic"] not in topics]}


def _print_summary(path: Path, summary: Any) -> None:
    """One log's summary (:class:`autosar_cli.ingest.inspect.LogSummary`): its streams, radar parameters, warnings."""
    d = summary.to_dict()
    out.print(f"[bold]{_lit(path)}[/]  {summary.container}, {summary.size_bytes / 1e6:.1f} MB, "
              f"{d['duration_s']:.2f} s")
    # a name cut short is no use to the config that must give it: folded onto a second line instead
    table = Table(Column("stream", overflow="fold"), Column("type", overflow="fold"), "count", "rate (Hz)", "gaps")
    for s in summary.streams:
        table.add_row(s.topic, s.msgtype, str(s.count), f"{s.rate_hz:.1f}", str(s.gaps))
    out.print(table)
    if summary.radar_parameters:
        radar = Table("radar parameter", "value", "from")
        for key, item in summary.radar_parameters.items():
            radar.add_row(key, str(item["value"]), item["source"])
        out.print(radar)
    for w in summary.warnings:
        err.print(f"[yellow]warning:[/] {escape(w)}", highlight=False, soft_wrap=True)


@contextmanager
def _batch_progress(n_drives: int, enabled: bool = True) -> Iterator[Callable[[dict[str, Any]], None]]:
    """Progress on stderr for `autosar batch`: drives finished, and each running drive's stage."""
    if not enabled or not err.is_terminal:
        yield lambda event: None
        return
    with Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  console=err, transient=True) as bar:
        overall = bar.add_task("drives", total=n_drives)
        tasks: dict[str, Any] = {}
        finished: set[str] = set()

        def update(event: dict[str, Any]) -> None:
            name, stage = str(event.get("drive")), str(event.get("stage"))
            if stage == "finished":
                finished.add(name)
                bar.advance(overall)
                if name in tasks:
                    bar.remove_task(tasks.pop(name))
                return
            if name in finished:  # a worker's event that arrived after the drive's result
                return
            if name not in tasks:
                tasks[name] = bar.add_task(name, total=None)
            if stage in ("start", "done", "failed"):
                bar.update(tasks[name], description=f"{name}: {stage}", completed=0, total=None)
            else:
                bar.update(tasks[name], description=f"{name}: {stage}", completed=event.get("done", 0),
                           total=event.get("total"))

        yield update


@app.command(cls=_Command)
def batch(
    logs: Annotated[list[Path], typer.Argument(
        metavar="LOG", help="Drive logs, one drive each (.mcap, .bag, rosbag2 directory, or a drive folder "
                            "holding one drive's inputs).")],
    output: Annotated[Path, typer.Option("--output", "-o", metavar="DIR",
                                         help="Batch directory: one run directory per drive "
                                         "(named after its log, as `autosar run` writes it) and batch.json.")],
    scheduler: Annotated[str | None, typer.Option("--scheduler", metavar="ADDRESS", help="Address of a running Dask "
                                                  "scheduler (tcp://host:8786); default: a local cluster.")] = None,
    workers: Annotated[int | None, typer.Option("--workers", "-w", min=1, metavar="N",
                                                help="Worker processes of the local "
                                                "cluster (default: one per core, at most one per drive).")] = None,
    retries: Annotated[int, typer.Option("--retries", min=0, metavar="N",
                                         help="Retries of a drive after an unexpected error "
                                         "(worker died, I/O error); a bad log fails at once.")] = 2,
    numba_threads: Annotated[int | None, typer.Option("--numba-threads", min=1, metavar="N",
                                                      help="Numba threads per drive "
                                                      "(default: cores // workers on a local cluster, the "
                                                      "workers' own setting on an existing one).")] = None,
    method: Annotated[NavMethod, typer.Option("--method", "-m", help="Navigation method (see `autosar navigate`).")]
    = NavMethod.sar_min,
    radar: Annotated[list[Path] | None, typer.Option(
        "--radar", metavar="CAPTURE", help="TI DCA1000 capture of each drive, in the order of the logs (repeat once "
                                           "per log).")] = None,
    can_log: Annotated[list[Path] | None, typer.Option(
        "--can-log", metavar="FILE", help="CAN log of each drive, read with its log, in the order of the logs "
                                          "(repeat once per log).")] = None,
    nmea: Annotated[list[Path] | None, typer.Option(
        "--nmea", metavar="FILE", help="NMEA capture of each drive, read with its log, in the order of the logs "
                                       "(repeat once per log).")] = None,
    radar_start: Annotated[list[str] | None, typer.Option(
        "--radar-start", metavar="TIME", help="Start of each drive's DCA1000 capture's first frame, in the order of "
                                              "the logs (repeat once per log): ns since the Unix epoch or ISO 8601 "
                                              "(UTC); default: the first message of --radar-sync in its logs.")] = None,
    radar_sync: RadarSyncOpt = "/dca1000/sync",
    radar_override: RadarOverrideOpt = False,
    autofocus: AutofocusOpt = False,
    dbc: DbcOpt = None,
    allow_unverified: AllowUnverifiedOpt = False,
    time_offset: TimeOffsetOpt = None,
    allow_time_gap: AllowTimeGapOpt = False,
    max_time_gap: MaxTimeGapOpt = 3600.0,
    config: ConfigOpt = None,
    overwrite: OverwriteOpt = False,
    resume: Annotated[bool, typer.Option(
        "--resume", help="DIR holds a batch (one interrupted, or with failed drives): keep its drives that finished "
                         "from the same inputs, run the others.")] = False,
    as_json: JsonOpt = False,
) -> None:
    """Run many drives (`autosar run` each) as Dask tasks on a local or existing dask.distributed cluster;
    exit code 1 if any drive failed. Ctrl-C stops the batch and writes batch.json of what finished; `--resume`
    runs the rest."""
    with _errors(output, kernels=False):
        _a_directory_not_named_as_a_file(output, "`autosar batch`")
        from autosar_cli.batch import run_batch
        from autosar_cli.ingest.pipeline import parse_time_ns

        cfg = _load_config(config)

        def on_cluster(info: dict[str, Any]) -> None:
            if as_json:
                return
            threads = info["numba_threads_per_task"] or "the workers' default"
            err.print(f"{info['kind']} cluster {info['scheduler']}: {info['workers']} workers x "
                      f"{info['threads_per_worker']} task, numba threads per task {threads}", highlight=False)
            err.print(f"dashboard: {_lit(info['dashboard'])}" if info["dashboard"] else "dashboard: none",
                      highlight=False)

        with _batch_progress(len(logs), enabled=not as_json) as update, _said_of_interrupted_batch(output):
            manifest = run_batch(logs, output, cfg, method=method.value, autofocus=autofocus, scheduler=scheduler,
                                 workers=workers, retries=retries, numba_threads=numba_threads, overwrite=overwrite,
                                 radars=radar, can_logs=can_log, nmea_logs=nmea,
                                 radar_starts=[parse_time_ns(t) for t in radar_start] if radar_start else None,
                                 ingest_options=_ingest_options(dbc, None, radar_sync, radar_override,
                                                                allow_unverified, time_offset, allow_time_gap,
                                                                max_time_gap),
                                 progress=update, on_cluster=on_cluster, command=" ".join(sys.argv),
                                 resume=resume)
        if as_json:
            out.print_json(strict_json(manifest))
        else:
            table = Table("drive", "status", "attempts", "wall (s)", "worker", "result")
            status = {"ok": "[green]ok[/]", "degraded": "[yellow]degraded[/]", "failed": "[red]failed[/]",
                      "interrupted": "[red]interrupted[/]"}
            for r in manifest["drives"]:
                ok = r["status"] in ("ok", "degraded")
                result = (f"{r['grid_shape'][0]} x {r['grid_shape'][1]} px, {r['output']}/image.tif" if ok
                          else r["error"])
                table.add_row(r["name"], status[r["status"]], str(r.get("attempts") or ""),
                              f"{r['wall_s']:.1f}" if r.get("wall_s") is not None else "–", r.get("worker", "–"),
                              result)
            out.print(table)
            rate = manifest["drives_per_minute"]
            degraded = f" ({manifest['degraded']} degraded)" if manifest.get("degraded") else ""
            out.print(f"wrote [bold]{_lit(Path(output) / 'batch.json')}[/]: "
                      f"{manifest['ok'] + manifest.get('degraded', 0)} of {len(manifest['drives'])} drives done"
                      f"{degraded}" + (f", {manifest['kept']} kept from before" if manifest.get("kept") else "")
                      + f" in {manifest['wall_s']:.1f} s" + (f" ({rate:.1f} drives/min)" if rate else ""))
        for r in manifest["drives"]:
            if r["status"] == "failed":
                err.print(f"[red]failed:[/] {r['name']}: {escape(r['error'])}", highlight=False, soft_wrap=True)
            for w in r.get("warnings", []) if r["status"] == "degraded" else []:
                err.print(f"[yellow]degraded:[/] {r['name']}: {escape(w)}", highlight=False, soft_wrap=True)
        if manifest["failed"]:
            raise typer.Exit(1)


@contextmanager
def _said_of_interrupted_batch(output: Path) -> Iterator[None]:
    """At a Ctrl-C that stopped a batch, what its batch.json keeps: the drives done, how to run the rest."""
    try:
        yield
    except KeyboardInterrupt as exc:
        if (manifest := getattr(exc, "batch_manifest", None)) is not None:
            done, drives = manifest["ok"] + manifest["degraded"], len(manifest["drives"])
            said = ("every drive had finished" if manifest["status"] == "finished" else
                    f"interrupted, {done} of {drives} drives done; `autosar batch` with the same logs and --resume "
                    "runs the others")
            err.print(f"wrote {_lit(Path(output) / 'batch.json')}: {said}", highlight=False, soft_wrap=True)
        raise


# The command list shows each command's first docstring paragraph; rich keeps its line breaks, which wrap it at the
# source's width, not the terminal's: joined into one line here.
for _info in app.registered_commands:
    if _info.short_help is None and _info.callback is not None and _info.callback.__doc__:
        _info.short_help = " ".join(inspect.cleandoc(_info.callback.__doc__).split("\n\n")[0].split())


def main() -> None:
    """Console-script entry point."""
    try:
        from autosar_cli.ingest import mf4_support

        mf4_support.defer()  # python-can without asammdf and pandas (~0.35 s) until an .mf4 log is opened
        app()
        code: int | str | None = 0
    except SystemExit as exc:
        code = exc.code
    except KeyboardInterrupt as exc:
        code = _said_stopped(_signal_of(exc))
    except Exception:
        if not _state["disk_filled"]:
            raise
        import traceback

        traceback.print_exc()  # --debug's traceback of a full disk, the process then ended as below
        code = 1
    # The command is over and its products are closed. Frozen, the objects of numba, scipy, pandas and matplotlib
    # are no longer walked by the collections of the interpreter's shutdown: 0.7-0.8 s -> 0.1 s after
    # `autosar run` (measured). atexit handlers still run.
    gc.freeze()
    if _state["disk_filled"]:
        # an HDF5 file the full disk refused is left half closed by the library, whose objects' release in the
        # interpreter's shutdown then crashed the process (SIGSEGV, exit 139, after the error line): the
        # command's clean-up is done, so the process ends here, after the atexit handlers
        import atexit

        atexit._run_exitfuncs()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code if isinstance(code, int) else 1)
    sys.exit(code)


if __name__ == "__main__":
    from autosar_cli import install_interrupt_handlers

    install_interrupt_handlers()  # as the `autosar` console script has them: SIGTERM cleans up and says so
    main()
