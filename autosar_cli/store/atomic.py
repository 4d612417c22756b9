"""Atomic product files: write to a temporary sibling, rename onto the final name only when complete."""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def partial_path(path: Path) -> Path:
    """The temporary sibling of ``path``: ``<stem>.partial<suffix>`` (``out.tif`` -> ``out.partial.tif``)."""
    return path.with_name(f"{path.stem}.partial{path.suffix}")


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
        raise FileExistsError(f"{path} already exists; pass --overwrite to replace it")
    tmp = partial_path(path)
    try:
        yield tmp
        with open(tmp, "rb+") as fh:  # flush to disk before the rename makes the file visible
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
