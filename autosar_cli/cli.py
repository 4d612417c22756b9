"""The ``autosar`` command line: one small function per command, no logic beyond argument handling."""

from __future__ import annotations

import json
import shutil
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from enum import StrEnum
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from rich.table import Table

from autosar_cli import __version__

app = typer.Typer(
    name="autosar",
    help="Navigation-aided automotive SAR: recorded drives in, centimetre-accurate radar maps out.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
err = Console(stderr=True)
out = Console()

_state: dict[str, Any] = {"debug": False}

ConfigOpt = Annotated[
    Path | None, typer.Option("--config", "-c", help="TOML config (default: configs/giulia_scanbrick.toml).")
]
OverwriteOpt = Annotated[bool, typer.Option("--overwrite", help="Replace existing outputs.")]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print a machine-readable JSON summary on stdout.")]


class Scenario(StrEnum):
    ci = "ci"
    test1 = "test1"
    test2 = "test2"
    test3 = "test3"


class LogFormat(StrEnum):
    mcap = "mcap"
    ros1 = "ros1"
    ros2 = "ros2"


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


@contextmanager
def _errors() -> Iterator[None]:
    """Turn expected failures into a one-line message and exit code 1 (tracebacks only with --debug)."""
    try:
        yield
    except (typer.Exit, typer.Abort):
        raise
    except KeyboardInterrupt:
        err.print("[red]error:[/] interrupted")
        raise typer.Exit(130) from None
    except Exception as exc:
        if _state["debug"]:
            raise
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        err.print(f"[red]error:[/] {msg}", highlight=False, soft_wrap=True)
        raise typer.Exit(1) from None


def _load_config(path: Path | None) -> Any:
    from autosar_cli.config import load_config

    return load_config(path)


def _prepare_output(path: Path, overwrite: bool) -> None:
    if path.exists():
        if not overwrite:
            raise FileExistsError(f"{path}: already exists (use --overwrite to replace it)")
        if path.is_dir():
            shutil.rmtree(path)
        else:
            path.unlink()
    path.parent.mkdir(parents=True, exist_ok=True)


@contextmanager
def _progress(label: str, enabled: bool = True) -> Iterator[Callable[[int, int], None]]:
    if not enabled or not err.is_terminal:
        yield lambda done, total: None
        return
    with Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  TimeRemainingColumn(), console=err, transient=True) as bar:
        task = bar.add_task(label, total=None)

        def update(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        yield update


@app.command()
def simulate(
    output: Annotated[Path, typer.Option("--output", "-o", help="Log to write (.mcap, .bag, or a rosbag2 directory).")],
    scenario: Annotated[Scenario, typer.Option("--scenario", "-s", help="Drive to simulate.")] = Scenario.ci,
    fmt: Annotated[LogFormat, typer.Option("--format", "-f", help="Log container.")] = LogFormat.mcap,
    seed: Annotated[int, typer.Option("--seed", help="Random seed: same seed, same bytes.")] = 0,
    config: ConfigOpt = None,
    overwrite: OverwriteOpt = False,
    as_json: JsonOpt = False,
) -> None:
    """Write a realistic synthetic drive log (radar, CAN, GNSS, IMUs) plus a ground-truth sidecar <log>.truth.h5."""
    with _errors():
        from autosar_cli.sim.simulate import simulate as run_simulation
        from autosar_cli.sim.truth import truth_path_for

        cfg = _load_config(config)
        _prepare_output(output, overwrite)
        _prepare_output(truth_path_for(output), overwrite)
        with _progress(f"simulate {scenario.value}", not as_json) as update:
            result = run_simulation(scenario.value, output, fmt=fmt.value, seed=seed, config=cfg, progress=update)
        summary = {
            "log": str(result.log_path), "truth": str(result.truth_path), "scenario": result.scenario,
            "seed": result.seed, "format": result.format, "duration_s": round(result.duration_s, 3),
            "radar_frames": result.radar_frames, "messages": result.message_counts,
            "elapsed_s": round(result.elapsed_s, 2),
        }
        if as_json:
            out.print_json(json.dumps(summary))
        else:
            out.print(f"wrote [bold]{result.log_path}[/] ({result.duration_s:.1f} s drive, {result.radar_frames} radar "
                      f"frames, {sum(result.message_counts.values())} messages) in {result.elapsed_s:.1f} s")
            out.print(f"truth  [bold]{result.truth_path}[/]")


@app.command()
def info(
    path: Annotated[Path, typer.Argument(help="A drive log (.mcap, .bag, rosbag2 directory).")],
    as_json: JsonOpt = False,
) -> None:
    """Summarise a log: streams, message types, counts, rates and time span."""
    with _errors():
        from autosar_cli.ingest.inspect import summarize_log

        summary = summarize_log(path)
        if as_json:
            out.print_json(json.dumps(summary.to_dict()))
            return
        d = summary.to_dict()
        out.print(f"[bold]{path}[/]  {summary.container}, {summary.size_bytes / 1e6:.1f} MB, "
                  f"{d['duration_s']:.2f} s")
        table = Table("topic", "type", "count", "rate (Hz)")
        for s in summary.streams:
            table.add_row(s.topic, s.msgtype, str(s.count), f"{s.rate_hz:.1f}")
        out.print(table)


def main() -> None:
    """Console-script entry point."""
    try:
        app()
    except SystemExit as exc:
        sys.exit(exc.code)


if __name__ == "__main__":
    main()
