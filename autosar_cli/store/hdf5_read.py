"""Reading HDF5 products: h5py's errors as one line naming the file and the dataset, and every chunk's checksum.

h5py's errors (a file cut short or not HDF5 at all, a missing dataset, a Fletcher-32 checksum or a decompression
failure) become one line naming the file and the dataset; :func:`verify` reads a whole file a stored chunk at a time
and names each one that fails (``autosar info --verify``)."""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import h5py
import hdf5plugin  # noqa: F401  (registers the Blosc filter of drive.h5's radar cube, which verify reads)
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
    except (OSError, RuntimeError) as exc:  # RuntimeError: HDF5 iterating a damaged object header's attributes
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


ATTRIBUTES = "attributes"  #: a ChunkDamage's dataset where the file's attributes fail their checksum


@dataclass(frozen=True)
class ChunkDamage:
    """A stored chunk of a dataset that fails its checksum or does not decompress."""

    dataset: str
    rows: tuple[int, int]  #: the rows it holds along the first axis (first, last + 1)
    at: tuple[int, ...]  #: its place along the other axes its chunks divide (a radar cube's Tx, Rx)
    reason: str  #: HDF5's error, its first line


@dataclass
class Verification:
    """What :func:`verify` found: every dataset of the file read a stored chunk at a time."""

    path: str
    datasets: int = 0
    chunks: int = 0  #: stored chunks read (a contiguous dataset counts as one)
    damaged: list[ChunkDamage] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "intact": not self.damaged}


def verify(path: Path, error: type[Exception]) -> Verification:
    """Read every stored chunk of every dataset of the HDF5 file at ``path``, so that each one's Fletcher-32
    checksum (and its decompression) is checked; ``error`` where the file cannot be opened (:func:`open_hdf5`)."""
    from autosar_cli.store.attr_checksum import attributes_damage

    found = Verification(str(path))
    with open_hdf5(path, error) as f:
        if (why := attributes_damage(f)) is not None:
            found.damaged.append(ChunkDamage(ATTRIBUTES, (0, 0), (), why))
        datasets: list[h5py.Dataset] = []
        f.visititems(lambda _, obj: datasets.append(obj) if isinstance(obj, h5py.Dataset) else None)
        for ds in datasets:
            found.datasets += 1
            pieces = list(ds.iter_chunks()) if ds.chunks is not None and ds.size else [()]
            for piece in pieces:
                found.chunks += 1
                try:
                    ds[piece]
                except OSError as exc:
                    rows = (piece[0].start, piece[0].stop) if piece and isinstance(piece[0], slice) else (0, len(ds))
                    at = tuple(s.start for s, n in zip(piece[1:], ds.chunks[1:], strict=False) if n == 1) \
                        if piece else ()
                    found.damaged.append(ChunkDamage(ds.name, rows, at, str(exc).splitlines()[0] if str(exc)
                                                     else type(exc).__name__))
    return found
