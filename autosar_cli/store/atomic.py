"""Atomic product files: write to a temporary sibling, rename onto the final name only when complete.

The sibling's name carries the writing process's id (``out.partial-<pid>.tif``), so a partial file left by a
killed process is recognised as stale (its process is gone) and removed by the next autosar command writing
that product (:func:`remove_stale_partials`, called by the output gate) or listed by ``autosar info``.
"""

from __future__ import annotations

import hashlib
import os
import re
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

NAME_MAX = 255  #: bytes in one file name on the usual file systems
#: ``<stem>.partial-<pid><suffix>``; ``.partial`` without a pid: older autosar and the simulator's log writer
PARTIAL_NAME = re.compile(r"\.partial(?:-(?P<pid>\d+))?(?:\.[^.]*)?$")


def partial_path(path: Path, pid: int | None = None) -> Path:
    """The temporary sibling of ``path``: ``<stem>.partial-<pid><suffix>`` (``out.tif`` ->
    ``out.partial-4242.tif``). A name too long for that is replaced by a digest of it (the suffix kept)."""
    path = Path(path)
    pid = os.getpid() if pid is None else pid
    name = f"{path.stem}.partial-{pid}{path.suffix}"
    if len(os.fsencode(name)) > NAME_MAX:
        suffix = path.suffix if len(os.fsencode(path.suffix)) <= 16 else ""
        name = f"{hashlib.sha256(os.fsencode(path.name)).hexdigest()[:32]}.partial-{pid}{suffix}"
    return path.with_name(name)


def stale_partials(folder: Path) -> list[Path]:
    """Partial files in ``folder`` whose writing process has ended (or that name none), sorted."""
    try:
        entries = list(Path(folder).iterdir())
    except OSError:
        return []
    stale = []
    for p in entries:
        m = PARTIAL_NAME.search(p.name)
        if m is not None and (m["pid"] is None or not _process_alive(int(m["pid"]))):
            stale.append(p)
    return sorted(stale)


def remove_stale_partials(path: Path, keep: Iterable[Path] = ()) -> list[Path]:
    """Delete the partial files of ended autosar processes writing the product ``path`` (``<stem>.partial-<pid>
    <suffix>`` beside it; never one whose process runs, nor one of ``keep``: the command's inputs); returns them.
    Any other file of that name pattern, another product's or the user's, stays."""
    path = Path(path)
    stem, suffix = partial_path(path, 0).name.rsplit(".partial-0", 1)  # the stem, or the digest of a long name
    own = re.compile(re.escape(stem) + r"\.partial-\d+" + re.escape(suffix) + "$")
    kept = {_same_file_key(k) for k in keep}
    removed = []
    for p in stale_partials(path.parent):
        if not own.match(p.name) or p.is_dir() or p.is_symlink() or _same_file_key(p) in kept:
            continue
        try:
            p.unlink()
            removed.append(p)
        except OSError:
            pass
    return removed


def _same_file_key(path: Path) -> tuple[int, int] | Path:
    """What tells a file from another: its device and inode where it exists, else its absolute path."""
    try:
        st = Path(path).stat()
        return (st.st_dev, st.st_ino)
    except OSError:
        return Path(os.path.abspath(path))


def _process_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    except OSError:
        return False
    return True


def already_exists(path: Path | str) -> str:
    """The refusal to replace an existing product without --overwrite: one wording for every command."""
    return f"{path}: already exists; pass --overwrite to replace it"


@contextmanager
def atomic_output(path: Path, overwrite: bool) -> Iterator[Path]:
    """Yield a temporary path to write ``path``'s content to; on success it replaces ``path`` (os.replace).

    On any exception the temporary file is deleted and the exception re-raised, so ``path`` is either
    absent, the previous complete file, or the new complete file. Raises FileExistsError up front if
    ``path`` exists and ``overwrite`` is false. The temporary name keeps the suffix, so writers that
    pick their format from it (GDAL, matplotlib) still see the right one.
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise FileExistsError(already_exists(path))
    tmp = partial_path(path)
    try:
        yield tmp
        with open(tmp, "rb+") as fh:  # flush to disk before the rename makes the file visible
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
