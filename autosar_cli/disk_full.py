"""A full disk told as one error: which exceptions say it, its one line, and h5py's reports of it held back.

HDF5 refuses a write of a full disk many times over as a command fails: the error the command raises, and, as h5py
releases the objects of the file it could not flush, the same failure again from each release. h5py's compiled
destructors report those twice, as a traceback through ``sys.excepthook`` (Cython's unraisable exception printed
in full) and as "Exception ignored in: 'h5py._objects.ObjectID.__dealloc__'" through ``sys.unraisablehook``:
two tracebacks per object ahead of the command's one-line error (12 to 67 lines of them, measured on `navigate`
and `compare` over a tmpfs that filled). Inside :func:`reports_held` they are kept, and dropped only where the
block ends by a full disk, which its own error then says; any other end shows them as they would have been.
"""

from __future__ import annotations

import errno
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import TracebackType
from typing import Any

#: HDF5's words for a write the disk refused: h5py raises a close's failure as a RuntimeError that holds them
HDF5_DISK_FULL = "errno = 28"


def is_disk_full(exc: BaseException | None) -> bool:
    """Whether ``exc`` is a write the full disk refused (ENOSPC, or HDF5's failed write in its text)."""
    return exc is not None and (
        (isinstance(exc, OSError) and exc.errno == errno.ENOSPC) or HDF5_DISK_FULL in str(exc))


def disk_full_said(exc: BaseException, output: str | Path | None) -> str:
    """The one line of a full disk: the file the error names, else ``output`` (what the command writes)."""
    return f"{getattr(exc, 'filename', None) or output or 'the output'}: no space left on the device"


@contextmanager
def reports_held() -> Iterator[None]:
    """Hold back the reports of full-disk errors that destructors could not raise (h5py's releases of a file the
    disk refused), in this thread and every other, for the block: dropped where the block raises a full disk (its
    error says it), else shown through the hooks they came to once it ends. Other reports pass at once."""
    held: list[Callable[[], None]] = []
    unraisable_hook, except_hook = sys.unraisablehook, sys.excepthook

    def hold_unraisable(unraisable: Any) -> None:
        if is_disk_full(unraisable.exc_value):
            held.append(lambda: unraisable_hook(unraisable))
        else:
            unraisable_hook(unraisable)

    def hold_printed(kind: type[BaseException], value: BaseException, tb: TracebackType | None) -> None:
        if is_disk_full(value):
            held.append(lambda: except_hook(kind, value, tb))
        else:
            except_hook(kind, value, tb)

    sys.unraisablehook, sys.excepthook = hold_unraisable, hold_printed
    said_by_the_error = False
    try:
        yield
    except BaseException as exc:
        said_by_the_error = is_disk_full(exc)
        raise
    finally:
        sys.unraisablehook, sys.excepthook = unraisable_hook, except_hook
        if not said_by_the_error:
            for show in held:
                show()


def drop_disk_full_reports() -> None:
    """From now on in this process, drop the reports of full-disk errors that destructors could not raise (once; a
    batch's worker, whose task said the full disk in its record, and whose h5py objects of it are released later)."""
    if getattr(sys.unraisablehook, "drops_disk_full", False):
        return
    unraisable_hook, except_hook = sys.unraisablehook, sys.excepthook

    def drop_unraisable(unraisable: Any) -> None:
        if not is_disk_full(unraisable.exc_value):
            unraisable_hook(unraisable)

    def drop_printed(kind: type[BaseException], value: BaseException, tb: TracebackType | None) -> None:
        if not is_disk_full(value):
            except_hook(kind, value, tb)

    drop_unraisable.drops_disk_full = True  # type: ignore[attr-defined]
    sys.unraisablehook, sys.excepthook = drop_unraisable, drop_printed
