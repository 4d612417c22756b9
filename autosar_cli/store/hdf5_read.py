"""Reading HDF5 products: h5py's errors (a file cut short or not HDF5 at all, a missing dataset, a Fletcher-32
checksum or a decompression failure) become one line naming the file and the dataset."""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import h5py
import numpy as np


class DamagedFileError(ValueError):
    """A dataset of an autosar HDF5 file is missing or cannot be read back intact."""


def open_hdf5(path: Path, error: type[Exception]) -> h5py.File:
    """``path`` opened for reading; ``error`` where it cannot be: one cut short (an interrupted copy, a full disk)
    says by how much, one absent or a directory says so, anything else that it is not an HDF5 file."""
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        if isinstance(exc, FileNotFoundError) or not Path(path).exists():
            raise error(f"{path}: no such file or directory") from exc
        if Path(path).is_dir():
            raise error(f"{path}: a directory, not an HDF5 file") from exc
        cut = re.search(r"truncated file: eof = (\d+), .*stored_eof = (\d+)", str(exc))
        if cut:
            raise error(f"{path}: cut short: {cut[1]} of the {cut[2]} bytes its HDF5 superblock declares (an "
                        "interrupted copy or a full disk); make it again") from exc
        raise error(f"{path}: not an HDF5 file ({exc})") from exc


@contextmanager
def dataset_errors(path: str | Path, dataset: str) -> Iterator[None]:
    """Re-raise h5py's errors inside the block as DamagedFileError naming ``path`` and ``dataset``."""
    try:
        yield
    except KeyError:
        raise DamagedFileError(f"{path}: dataset {dataset} is missing") from None
    except OSError as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise DamagedFileError(f"{path}: dataset {dataset} is damaged and cannot be read ({reason})") from exc


def read_dataset(f: h5py.File | h5py.Group, name: str, path: str | Path | None = None) -> Any:
    """``f[name][()]``, with errors naming the file and the dataset."""
    where = path if path is not None else f.file.filename
    with dataset_errors(where, f"{f.name.rstrip('/')}/{name}"):
        return f[name][()]


def read_rows(ds: h5py.Dataset, start: int, stop: int) -> np.ndarray:
    """``ds[start:stop]``, with errors naming the file and the dataset."""
    with dataset_errors(ds.file.filename, ds.name):
        return ds[start:stop]
