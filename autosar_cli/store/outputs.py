"""The one gate every output passes before anything is written.

An output is never an input, nor inside one, nor a directory holding one that ``--overwrite`` would replace.
``--overwrite`` replaces only what autosar made, recognised by its own metadata: an HDF5 file whose root
attribute ``format`` starts with ``autosar-``, a GeoTIFF with autosar's ``autosar_format`` tag, a JSON
manifest with such a ``format``, a directory holding one of autosar's manifests (run.json, batch.json,
compare.json, metrics.json), a quicklook PNG beside its image.h5, or a simulated log beside its truth sidecar.
Anything else is refused with one line.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import shutil
import stat
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from autosar_cli.store.atomic import already_exists, remove_stale_partials

AUTOSAR_FORMAT_PREFIX = "autosar-"
DIRECTORY_MANIFESTS = ("run.json", "batch.json", "compare.json", "metrics.json")
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


class OutputError(ValueError):
    """An output that must not be written: an input, inside one, or something autosar did not make."""


def check_output(path: str | Path, inputs: Iterable[str | Path] = (), *, overwrite: bool,
                 directory: bool = False, replaces_directory: bool = False, ours: bool = False) -> None:
    """Refuse ``path`` as an output unless writing it harms nothing; raises OutputError/FileExistsError.

    ``inputs``: every file or directory the command reads. ``directory``: the output is a directory that
    autosar fills (a run); else a file, or with ``replaces_directory`` a directory written whole (a
    simulated rosbag2 log). ``ours``: an existing file at ``path`` is autosar's though it carries no metadata of
    its own (a report's Markdown or plot, named by the autosar manifest beside it).
    """
    path = Path(path)
    _check_parent(path)
    inputs = list(inputs)
    target = _resolved(path)
    for inp in inputs:
        problem = input_problem(Path(inp))
        if problem is not None and (Path(inp).exists() or Path(inp).is_symlink()):  # a missing one: its command's
            raise OutputError(f"{inp}: {problem}")
        source = _resolved(Path(inp))
        if target == source or (path.exists() and Path(inp).exists() and os.path.samefile(path, inp)):
            raise OutputError(f"{path}: is an input of this command; choose another output")
        if source in target.parents:
            raise OutputError(f"{path}: lies inside the input {inp}; choose an output outside it")
        if target in source.parents and path.exists() and not directory:
            raise OutputError(f"{path}: holds the input {inp}; choose another output")
    if not directory:
        remove_stale_partials(path, keep=[Path(p) for p in inputs])
    if not (path.exists() or path.is_symlink()):
        return
    if directory:
        if not path.is_dir():
            raise OutputError(f"{path}: exists and is not a directory")
        return  # a run directory: its products are checked one by one (check_products)
    if path.is_dir() and not replaces_directory:
        raise OutputError(f"{path}: is a directory; the output is a file")
    # another's file before the advice to pass --overwrite, which would not replace it either
    if not (ours and path.is_file() and not path.is_symlink()) and not is_autosar_product(path):
        what = "a directory" if path.is_dir() else "a file"
        raise OutputError(f"{path}: is {what} autosar did not write (no autosar metadata); refusing to replace "
                          f"it, even with --overwrite")
    if not overwrite:
        raise FileExistsError(already_exists(path))


def input_problem(path: Path) -> str | None:
    """Why ``path`` cannot be read as an input (a file, or a directory such as a rosbag2 bag), or None: a pipe or
    a device would be read without end, or block on a writer that never comes."""
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        return "no such file or directory"
    except OSError as exc:  # a symbolic link loop, a path through a file, no permission
        return f"cannot be read: {exc.strerror}"
    if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        return "not a regular file (a pipe, socket or device); give the recorded file"
    return None


def _resolved(path: Path) -> Path:
    try:
        return path.resolve()
    except (RuntimeError, OSError):  # Python 3.11 raises RuntimeError for a loop, 3.13 OSError
        raise OutputError(f"{path}: a symbolic link loop (it leads to itself)") from None


def check_products(directory: Path, names: Iterable[str], inputs: Iterable[str | Path], *, overwrite: bool,
                   manifest: str | None = None) -> None:
    """check_output for each of ``names`` inside ``directory`` (a run's, an evaluation's products); where
    ``directory``'s ``manifest`` (metrics.json, compare.json) is autosar's, the files named are taken as its own
    (a report's Markdown and plots carry no metadata of their own), else an existing one is the user's."""
    inputs = list(inputs)
    ours = manifest is not None and any(_json_format(m) for m in (Path(directory) / manifest,
                                                                  set_aside(Path(directory) / manifest)))
    for name in names:
        check_output(directory / name, inputs, overwrite=overwrite, ours=ours)


def make_directories(path: Path) -> Callable[[], None]:
    """Make the directory ``path`` and its missing parents for a command's products; returns what removes again
    those it made where nothing has been written in them (after the command failed)."""
    made = [p for p in (path, *path.parents) if not (p.exists() or p.is_symlink())]  # the deepest first
    path.mkdir(parents=True, exist_ok=True)

    def undo() -> None:
        for directory in made:
            with contextlib.suppress(OSError):  # not empty: what is in it stays, and so do its parents
                directory.rmdir()

    return undo


@contextlib.contextmanager
def output_directory(path: Path, products: Iterable[Path] = (), manifest: Path | None = None) -> Iterator[None]:
    """Make the directory ``path`` (and its parents) for a command's products, and remove again those this made
    where the block fails and nothing has been written in them (a failed ingest, which writes atomically).
    ``products``: files that make one whole with the others (a comparison's, a report's); where the block fails,
    those it wrote are removed, and where it had replaced any that were there before (``--overwrite``), all of
    them are: a set part old, part new would read as one whole. The folders among them the block made are removed,
    left empty; nothing else is touched. ``manifest``: the product that says the set is whole (compare.json,
    metrics.json); one there before is set aside (:func:`set_aside`) for the block, so a set the block does not
    finish (a SIGKILL, a power cut) has none, yet reads as autosar's to the next ``--overwrite``; it is put back
    where the block fails having replaced nothing else."""
    products = list(products)
    before = {p: _signature(p) for p in products if p != manifest}
    folders = sorted({p.parent for p in products if before.get(p) is None and not p.parent.exists()},
                     key=lambda p: len(p.parts), reverse=True)
    aside = set_aside(manifest) if manifest is not None else None
    moved = False  # the manifest this block set aside (one left aside by a killed block is no whole set's)
    undo = make_directories(path)
    try:
        if manifest is not None and aside is not None and (manifest.exists() or manifest.is_symlink()):
            os.replace(manifest, aside)
            moved = True
        yield
    except BaseException:
        replaced = any(_signature(p) != was for p, was in before.items() if was is not None)
        for product in products:
            if replaced or (product == manifest or before[product] is None):
                with contextlib.suppress(OSError):
                    product.unlink(missing_ok=True)
        if aside is not None and manifest is not None:
            with contextlib.suppress(OSError):
                if moved and not replaced:
                    os.replace(aside, manifest)
                elif replaced:
                    aside.unlink(missing_ok=True)
        for folder in folders:
            with contextlib.suppress(OSError):  # not empty: what is in it stays
                folder.rmdir()
        undo()
        raise
    if aside is not None:
        with contextlib.suppress(OSError):
            aside.unlink(missing_ok=True)


def set_aside(manifest: Path) -> Path:
    """Where :func:`output_directory` keeps a set's former manifest while the set is written again."""
    return manifest.with_name(f".{manifest.name}.former")


def _signature(path: Path) -> tuple[int, int, int] | None:
    """(inode, modification time ns, size) of the file at ``path``, None where there is none: whether a block
    replaced or rewrote it."""
    try:
        st = os.stat(path, follow_symlinks=False)
    except OSError:
        return None
    return st.st_ino, st.st_mtime_ns, st.st_size


#: what the simulator writes inside a directory it writes whole: a rosbag2 log's storage and metadata, a DCA1000
#: capture's data and parameter files
_SIMULATED_FILES = re.compile(r"(metadata\.yaml|.+\.(db3|mcap)|adc_data(_Raw_\d+)?\.bin|capture\.(mmwave|setup)\.json"
                              r"|capture\.cfg)")


def remove_product_directory(path: Path) -> None:
    """Delete a directory autosar's simulator wrote whole (a simulated rosbag2 log or DCA1000 capture, its truth
    sidecar beside it) that holds nothing else: never a run's directory, nor one holding a file of the user's."""
    if not is_autosar_product(path):
        raise OutputError(f"{path}: is a directory autosar's simulator did not write; refusing to delete it, even "
                          "with --overwrite")
    if others := sorted(p.name for p in path.iterdir() if not (p.is_file() and _SIMULATED_FILES.fullmatch(p.name))):
        raise OutputError(f"{path}: holds {others[0]}, which autosar's simulator did not write; refusing to delete "
                          "it, even with --overwrite")
    shutil.rmtree(path)


def is_autosar_product(path: Path) -> bool:
    """Whether ``path`` carries autosar's own metadata (see the module docstring)."""
    path = Path(path)
    if path.is_dir():
        if any(_json_format(path / m) for m in DIRECTORY_MANIFESTS):
            return True
        if path.suffix == ".dca1000":  # a simulated DCA1000 capture beside its navigation MCAP
            return _hdf5_format(_truth_sidecar(path.with_suffix(".mcap"))) == "autosar-truth"
        return _hdf5_format(_truth_sidecar(path)) == "autosar-truth"  # a simulated rosbag2 log
    suffix = path.suffix.lower()
    if _hdf5_format(path):
        return True
    if suffix in (".tif", ".tiff"):
        return _tif_is_autosar(path)
    if suffix == ".json":
        return _json_format(path)
    if suffix == ".png":
        return bool(_hdf5_format(path.with_suffix(".h5")))
    if suffix in (".mcap", ".bag"):
        return _hdf5_format(_truth_sidecar(path)) == "autosar-truth"
    return False


def _check_parent(path: Path) -> None:
    for parent in path.parents:
        if parent.exists() or parent.is_symlink():
            if not parent.is_dir():
                raise OutputError(f"{path}: cannot be written, {parent} is a file, not a directory")
            return


def _truth_sidecar(log: Path) -> Path:
    # "." or "..": its name is the directory's own (Path(".").name is "", which with_name refuses)
    log = Path(os.path.abspath(log))
    return log.with_name(log.name + ".truth.h5") if log.name else log / ".truth.h5"


def _hdf5_format(path: Path) -> str | None:
    """The ``format`` attribute of an HDF5 file written by autosar (``autosar-drive``, ...), else None."""
    try:
        with open(path, "rb") as fh:
            if fh.read(8) != HDF5_SIGNATURE:
                return None
        import h5py

        with h5py.File(path, "r") as f:
            fmt = f.attrs.get("format")
    except (OSError, ValueError):
        return None
    fmt = fmt.decode() if isinstance(fmt, bytes) else fmt
    return fmt if isinstance(fmt, str) and fmt.startswith(AUTOSAR_FORMAT_PREFIX) else None


#: autosar's HDF5 files by their format: what each is, and what reads it
_HDF5_READERS = {
    "autosar-drive": ("a drive.h5", "`autosar navigate` and `autosar focus` read it"),
    "autosar-trajectory": ("a trajectory.h5", "`autosar focus --trajectory` reads it"),
    "autosar-image": ("an image.h5", "`autosar evaluate` reads it"),
    "autosar-truth": ("a simulated drive's truth sidecar", "the log beside it is the drive"),
}


#: the command that writes each of autosar's HDF5 files
_HDF5_WRITERS = {
    "autosar-drive": "`autosar ingest LOG -o drive.h5` makes one",
    "autosar-trajectory": "`autosar navigate drive.h5 -o trajectory.h5` makes one",
    "autosar-image": "`autosar focus drive.h5 -t trajectory.h5 -o image` makes one",
}


def not_the_format(path: Path, fmt: object, wanted: str) -> str:
    """The error of an HDF5 file of format ``fmt`` given where one of format ``wanted`` goes: what it is, and the
    command that writes the one wanted."""
    fmt = fmt.decode() if isinstance(fmt, bytes) else fmt
    got = _HDF5_READERS.get(fmt) if isinstance(fmt, str) else None
    what = f"it is {got[0]} autosar wrote" if got else f"format attribute {fmt!r}"
    return f"{path}: not {_HDF5_READERS[wanted][0]} ({what}); {_HDF5_WRITERS[wanted]}"


def what_autosar_wrote(path: Path) -> str | None:
    """Of a file or run directory autosar wrote, what it is and what reads it ("a drive.h5: `autosar navigate` ..."),
    to say where it is given as something else (a log, an image.h5); None for any other."""
    if path.is_dir():
        run = path / "run.json"
        return "a run directory autosar wrote (`autosar evaluate` reads it)" if run.is_file() and _json_format(run) \
            else None
    fmt = _hdf5_format(path)
    if fmt is None:
        if path.suffix.lower() in (".tif", ".tiff") and path.is_file() and _tif_is_autosar(path):
            return "an image.tif autosar wrote (the GeoTIFF to view; `autosar evaluate` reads the image.h5 beside it)"
        if path.suffix.lower() == ".json" and path.is_file() and _json_format(path):
            return f"a {path.name} autosar wrote (the manifest of the directory it is in)"
        return None
    name, reader = _HDF5_READERS.get(fmt, (f"an {fmt} file", ""))
    return f"{name} autosar wrote" + (f" ({reader})" if reader else "")


def _json_format(path: Path) -> bool:
    try:
        manifest = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    fmt = manifest.get("format") if isinstance(manifest, dict) else None
    return isinstance(fmt, str) and fmt.startswith(AUTOSAR_FORMAT_PREFIX)


def _tif_is_autosar(path: Path) -> bool:
    try:
        import rasterio

        with rasterio.open(path) as src:
            return str(src.tags().get("autosar_format", "")).startswith(AUTOSAR_FORMAT_PREFIX)
    except Exception:  # noqa: BLE001 - anything rasterio cannot read is not autosar's
        return False


class DiskFullError(OSError):
    """Not enough free space for an output; its message names the file and the sizes."""

    def __init__(self, message: str) -> None:
        super().__init__(errno.ENOSPC, message)
        self.message = message

    def __str__(self) -> str:
        return self.message

    def __reduce__(self) -> tuple[type, tuple[str]]:  # crosses the pipe from run's ingest child
        return (DiskFullError, (self.message,))


#: Free space kept in hand beyond an estimate: HDF5 flushes its metadata and chunk caches (1 MiB a dataset)
#: at close, and a drive has dozens of datasets; a file written whole and closed at once needs less.
SPACE_MARGIN_BYTES = 16 * 2**20
SMALL_FILE_MARGIN_BYTES = 2**20


def check_free_space(path: str | Path, needed_bytes: float, what: str = "",
                     margin_bytes: int = SPACE_MARGIN_BYTES) -> None:
    """Raise DiskFullError unless the file system of ``path`` has ``needed_bytes`` + ``margin_bytes`` free."""
    path = Path(path)
    folder = next((p for p in (path.parent, *path.parent.parents) if p.is_dir()), Path("."))
    free = shutil.disk_usage(folder).free
    if free < needed_bytes + margin_bytes:
        raise DiskFullError(f"{path}: no space left on the device: {what or 'writing it'} needs about "
                            f"{(needed_bytes + margin_bytes) / 1e6:.1f} MB, {free / 1e6:.1f} MB are free")


def input_bytes(paths: Iterable[str | Path]) -> int:
    """Total size of input files and directories (an upper bound of what ingesting them writes)."""
    total = 0
    for p in map(Path, paths):
        if p.is_dir():
            total += sum(f.stat().st_size for f in p.rglob("*") if f.is_file())
        elif p.exists():
            total += p.stat().st_size
    return total
