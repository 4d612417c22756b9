"""drive.h5: the HDF5 layout ingest writes and navigate/focus read (docs/FORMATS.md, format version 1).

Layout::

    /                      attrs: format="autosar-drive", format_version, autosar_version, created_utc,
                                  start_ns, end_ns, config_toml, config_path
    /provenance            attrs: command, report (JSON ingest report); dataset inputs (path, kind, size, sha256)
    /can/<MESSAGE>         t_ns + one float64 column per DBC signal (SI units, attr unit); attrs frame_id, ...
    /gnss/<source>/fix     t_ns, latitude_deg, longitude_deg, altitude_m, status, position_covariance (N, 9)
    /gnss/<source>/velocity              t_ns, velocity_enu (N, 3) m/s, velocity_covariance (N, 3) m²/s²
    /gnss/<source>/nmea_fix|nmea_velocity|nmea_heading   decoded NMEA sentences
    /imu/<source>          t_ns, angular_velocity (N, 3) rad/s, linear_acceleration (N, 3) m/s², orientation
                           (N, 4) xyzw, *_covariance (N, 9); body axes of the IMU frame
    /radar/<sensor>        t_ns (start of each PRI), frame_index, raw (N, tx, rx, sample, I/Q) int16 chunked
                           by frames and Blosc-LZ4 compressed; radar parameters and antenna geometry as attrs

Every series group has attrs ``topic``, ``source_file``, ``msgtype``, ``time_source`` ("header" or "log"),
and a ``gaps`` dataset ``(M, 2)`` int64 of (t_ns before, t_ns after) for every gap in the series
(radar: frame_index jumps). All ``t_ns`` are int64 ns since the Unix epoch, sorted, without duplicates.

Writing is atomic: :class:`DriveWriter` writes ``<stem>.partial-<pid>.h5`` and renames it on :meth:`commit`.
All HDF5 calls of a writer run on one background thread so that compression overlaps decoding.
"""

from __future__ import annotations

import json
import os
import queue
import threading
import zlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import h5py
import hdf5plugin  # noqa: F401  (registers the Blosc filter that raw radar cubes use)
import numpy as np
from numpy.typing import NDArray

from autosar_cli.store.atomic import partial_path
from autosar_cli.store.attr_checksum import attributes_damage, stamp_attributes
from autosar_cli.store.hdf5_read import DamagedFileError, dataset_errors, open_hdf5, read_dataset, read_rows
from autosar_cli.store.outputs import check_free_space, not_the_format

#: the msgtype attribute of a GNSS source read from an NMEA text capture (ingest writes it)
NMEA_TEXT_MSGTYPE = "nmea text"

FORMAT = "autosar-drive"
FORMAT_VERSION = 1
RADAR_CHUNK_FRAMES = 64
TABLE_CHUNK_ROWS = 4096

_STR = h5py.string_dtype()


# Every dataset carries Fletcher-32 checksums of its stored chunks (after compression), so a flipped byte
# is a read error naming the file and dataset instead of a silently different product.
def radar_compression() -> dict[str, Any]:
    """HDF5 filter of raw radar cubes: Blosc + LZ4 + bit shuffle.

    Measured on simulated ScanBrick frames (benches/bench_ingest.py): ~1 GB/s compression, size ratio
    0.66; byte shuffle gave 0.75 at ~0.65 GB/s, Blosc2 0.80 at ~0.37 GB/s, zstd-1 0.54 at ~0.35 GB/s.
    """
    return dict(hdf5plugin.Blosc(cname="lz4", clevel=5, shuffle=hdf5plugin.Blosc.BITSHUFFLE))


def radar_layout(frame_shape: tuple[int, ...]) -> dict[str, Any]:
    """Chunks and chunk cache of a raw radar cube whose frames are ``frame_shape`` (tx, rx, sample, I/Q).

    One chunk per channel: ``RADAR_CHUNK_FRAMES`` frames of one Tx-Rx pair (138 kB on the ScanBrick), so that
    focus reads only the channels it uses: the image's 8 of 12 in 0.81 of the time 32 whole frames per chunk
    took, the autofocus's 2 in 0.22; writing takes 1.05 times as long (benches/bench_radar_read.py). The cache
    holds two rows of every channel's chunks, so that an append that ends inside a row leaves its chunks in
    memory for the next, not written half full and read back (h5py's 1 MiB holds 7 of the ScanBrick's 12:
    appends of 100 frames took 1.24 times as long with it as with this cache).
    """
    n_tx, n_rx, *sample = frame_shape
    row_bytes = RADAR_CHUNK_FRAMES * n_tx * n_rx * int(np.prod(sample)) * np.dtype(np.int16).itemsize
    return {"chunks": (RADAR_CHUNK_FRAMES, 1, 1, *sample), "rdcc_nbytes": max(1 << 20, 2 * row_bytes)}


class DriveFormatError(ValueError):
    """A file is not a drive.h5 this version can read; the message names the file and the problem."""


@dataclass(frozen=True, slots=True)
class Column:
    """One column of a table: dtype and the shape of one row (() for scalars)."""

    dtype: Any
    shape: tuple[int, ...] = ()
    unit: str = ""


class _HdfThread:
    """Runs every HDF5 call of one file on a single worker thread, in submission order.

    The queue is bounded so that a slow disk throttles the decoder instead of filling memory.
    An exception on the worker is re-raised on the next submit, wait or close.
    """

    def __init__(self, max_pending: int = 8) -> None:
        self._queue: queue.Queue[tuple[Callable[[], Any], threading.Event | None] | None] = queue.Queue(max_pending)
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="drive-writer", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                return
            fn, done = item
            if self._error is None:
                try:
                    fn()
                except BaseException as exc:  # handed to the submitting thread
                    self._error = exc
            if done is not None:
                done.set()

    def _raise(self) -> None:
        if self._error is not None:
            err, self._error = self._error, None
            raise err

    def submit(self, fn: Callable[[], Any]) -> None:
        self._raise()
        self._queue.put((fn, None))

    def call(self, fn: Callable[[], Any]) -> Any:
        """Run ``fn`` on the worker after everything queued before it; return its result."""
        box: list[Any] = []
        done = threading.Event()
        self._queue.put((lambda: box.append(fn()), done))
        done.wait()
        self._raise()
        return box[0]

    def close(self) -> None:
        self._queue.put(None)
        self._thread.join()
        self._raise()


class Table:
    """Appendable columns of equal length in one HDF5 group (rows = time samples)."""

    def __init__(self, writer: DriveWriter, path: str, columns: Mapping[str, Column], attrs: Mapping[str, Any]):
        self._writer = writer
        self.path = path
        self.columns = dict(columns)
        self.rows = 0  # rows appended (written or pending)
        self._written = 0
        self._pending: list[dict[str, np.ndarray]] = []
        self._pending_rows = 0
        writer._tables.append(self)
        writer._hdf.submit(lambda: self._create(writer._file, attrs))

    def _create(self, f: h5py.File, attrs: Mapping[str, Any]) -> None:
        g = f.require_group(self.path)
        for name, col in self.columns.items():
            ds = g.create_dataset(name, shape=(0, *col.shape), maxshape=(None, *col.shape), dtype=col.dtype,
                                  chunks=(TABLE_CHUNK_ROWS, *col.shape), compression="gzip", compression_opts=1,
                                  shuffle=True, fletcher32=True)
            if col.unit:
                ds.attrs["unit"] = col.unit
        _set_attrs(g, attrs)

    def append(self, data: Mapping[str, np.ndarray]) -> None:
        """Append rows; ``data`` has one array per column, all of the same length.

        Rows are held until a whole HDF5 chunk can be written: appending a few rows at a time to a
        compressed chunk would rewrite (decompress and recompress) it on every call.
        """
        n = len(data["t_ns"])
        if n == 0:
            return
        self._pending.append({k: np.asarray(data[k], dtype=self.columns[k].dtype) for k in self.columns})
        self._pending_rows += n
        self.rows += n
        if self._pending_rows >= TABLE_CHUNK_ROWS:
            self.flush()

    def flush(self) -> None:
        """Write the rows held back by :meth:`append`."""
        if not self._pending:
            return
        if len(self._pending) == 1:
            arrays = self._pending[0]
        else:
            arrays = {k: np.concatenate([p[k] for p in self._pending]) for k in self.columns}
        n = self._pending_rows
        self._pending, self._pending_rows = [], 0
        start = self._written
        self._written += n
        f = self._writer._file

        def write() -> None:
            self._writer.ensure_space(sum(a.nbytes for a in arrays.values()))
            g = f[self.path]
            for name, arr in arrays.items():
                ds = g[name]
                ds.resize(start + n, axis=0)
                ds[start:] = arr

        self._writer._hdf.submit(write)

    def set_attrs(self, attrs: Mapping[str, Any]) -> None:
        f = self._writer._file
        self._writer._hdf.submit(lambda: _set_attrs(f[self.path], attrs))

    def write_dataset(self, name: str, data: np.ndarray) -> None:
        f = self._writer._file
        arr = np.asarray(data)
        checksum = arr.ndim > 0 and arr.size > 0  # Fletcher-32 needs a chunked, so non-empty, dataset
        self._writer._hdf.submit(lambda: f[self.path].create_dataset(name, data=arr, fletcher32=checksum))


class RadarCube(Table):
    """A radar group: t_ns and frame_index columns plus the raw (frame, tx, rx, sample, I/Q) int16 cube."""

    def __init__(self, writer: DriveWriter, path: str, frame_shape: tuple[int, int, int], attrs: Mapping[str, Any]):
        self.frame_shape = (*frame_shape, 2)
        super().__init__(writer, path, {"t_ns": Column(np.int64), "frame_index": Column(np.int64)}, attrs)
        shape = self.frame_shape

        self._raw: h5py.Dataset | None = None  # open from creation to the commit, on the HDF thread only

        def create() -> None:
            self._raw = writer._file[path].create_dataset(
                "raw", shape=(0, *shape), maxshape=(None, *shape), dtype=np.int16, fletcher32=True,
                **radar_layout(shape), **radar_compression())

        writer._hdf.submit(create)

    def append_frames(self, t_ns: np.ndarray, frame_index: np.ndarray, raw: np.ndarray) -> None:
        """Append frames; ``raw`` (n, tx, rx, sample, 2) int16 is handed over (do not modify it afterwards)."""
        start = self.rows
        self.append({"t_ns": t_ns, "frame_index": frame_index})
        n = len(raw)

        def write() -> None:
            self._writer.ensure_space(raw.nbytes)
            ds = self._raw
            assert ds is not None  # create() ran first, on the same thread
            ds.resize(start + n, axis=0)
            ds[start:] = raw

        self._writer._hdf.submit(write)


def _set_attrs(obj: h5py.HLObject, attrs: Mapping[str, Any]) -> None:
    for key, value in attrs.items():
        if isinstance(value, dict | list):
            numeric = np.asarray(value) if isinstance(value, list) and value else None
            value = numeric if numeric is not None and numeric.dtype.kind in "iuf" else json.dumps(value)
        obj.attrs[key] = value


class DriveWriter:
    """Writes one drive.h5 atomically: everything goes to its partial sibling (store.atomic.partial_path) until
    :meth:`commit`."""

    def __init__(self, path: str | Path, attrs: Mapping[str, Any]) -> None:
        self.path = Path(path)
        self.partial = partial_path(self.path)
        self.partial.unlink(missing_ok=True)
        self._tables: list[Table] = []
        self._closed = False
        try:
            self._file = h5py.File(self.partial, "w", libver="latest")
            self._hdf = _HdfThread()
            root = {"format": FORMAT, "format_version": FORMAT_VERSION, **attrs}
            self._hdf.call(lambda: _set_attrs(self._file, root))
        except BaseException:  # e.g. Ctrl-C as the file appears: the caller has no writer to abort yet
            self._closed = True
            try:
                if hasattr(self, "_hdf"):
                    self._hdf.close()
                if hasattr(self, "_file"):
                    self._file.close()
            finally:
                self.partial.unlink(missing_ok=True)
            raise

    def table(self, path: str, columns: Mapping[str, Column], attrs: Mapping[str, Any]) -> Table:
        return Table(self, path, columns, attrs)

    def radar(self, path: str, frame_shape: tuple[int, int, int], attrs: Mapping[str, Any]) -> RadarCube:
        return RadarCube(self, path, frame_shape, attrs)

    def set_attrs(self, path: str, attrs: Mapping[str, Any]) -> None:
        self._hdf.submit(lambda: _set_attrs(self._file.require_group(path), attrs))

    def write_inputs(self, inputs: list[dict[str, Any]]) -> None:
        """Provenance table of the input files (path, kind, size_bytes, sha256)."""
        dt = np.dtype([("path", _STR), ("kind", _STR), ("size_bytes", np.int64), ("sha256", _STR)])
        rows = np.array([(i["path"], i["kind"], i["size_bytes"], i["sha256"]) for i in inputs], dtype=dt)

        def write() -> None:
            g = self._file.require_group("provenance")
            g.create_dataset("inputs", data=rows)

        self._hdf.submit(write)

    def flush(self) -> None:
        """Wait until everything submitted so far is written."""
        self._hdf.call(lambda: None)

    def ensure_space(self, nbytes: int) -> None:
        """Before HDF5 writes ``nbytes``: raise DiskFullError if the disk cannot take them. HDF5 itself meets
        a full disk in its caches and destructors (errors ignored, then a crash at close), so it must not."""
        check_free_space(self.path, nbytes, "the drive")

    def commit(self) -> Path:
        """Finish writing and rename the partial file to its final name."""
        for table in self._tables:
            table.flush()
        self._hdf.call(lambda: self.ensure_space(0))  # room for what closing flushes
        self._hdf.call(lambda: stamp_attributes(self._file))  # the radar's parameters, the streams' attributes
        self._close()
        os.replace(self.partial, self.path)
        return self.path

    def abort(self) -> None:
        """Stop writing and delete the partial file (never leaves a file that looks complete)."""
        try:
            try:
                # emptied first: closing flushes HDF5's caches, which on a full disk must find room
                os.truncate(self.partial, 0)
            except OSError:
                pass
            try:
                self._close()
            except Exception:  # the original failure matters more than a follow-up one
                pass
        finally:  # even when a second Ctrl-C interrupts the closing
            self.partial.unlink(missing_ok=True)

    def _close(self) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            self._hdf.close()
        finally:
            self._file.close()


# --------------------------------------------------------------------------------------------- reading
@dataclass(frozen=True)
class RadarStream:
    """One radar of a drive: frame times (ns), frame indices, the lazily read raw cube and its parameters."""

    name: str
    t_ns: np.ndarray
    frame_index: np.ndarray
    raw: h5py.Dataset  #: (frame, tx, rx, sample, I/Q) int16; read it in blocks of frames (:meth:`frames`)
    attrs: dict[str, Any]

    def on_clock(self, late_s: float, drift_ppm: float = 0.0) -> RadarStream:
        """The stream with its frames' times on the navigation's clock, where its stamps run ``late_s`` (s) late
        and its clock ``drift_ppm`` fast from its first stamp on (:func:`stamps_on_navigation_clock`; itself where
        both are 0). A drift on frames ingest already timed by their triggers' period is a ValueError."""
        if not late_s and not drift_ppm:
            return self
        if drift_ppm and self.attrs.get("frame_clock_applied"):
            raise ValueError(f"radar {self.name}'s frames are timed by its triggers' period (its clock "
                             f"{float(self.attrs['frame_clock_drift_ppm']):+.1f} ppm fast, measured at ingest): "
                             f"radar.clock_drift_ppm = {drift_ppm:g} would take a drift out twice; state 0")
        first = int(self.t_ns[0]) if len(self.t_ns) else 0
        return replace(self, t_ns=stamps_on_navigation_clock(self.t_ns, first, late_s, drift_ppm),
                       attrs=chirp_on_navigation_clock(self.attrs, drift_ppm))

    def frames(self, start: int, stop: int, pairs: Sequence[tuple[int, int]] | None = None) -> np.ndarray:
        """Raw frames ``start:stop`` (n, tx, rx, sample, I/Q), or with ``pairs`` only those (Tx, Rx) channels
        (n, len(pairs), sample, I/Q); a damaged chunk (checksum, decompression) is an error naming file and
        dataset."""
        if pairs is None:
            return read_rows(self.raw, start, stop)
        n_tx, n_rx = self.raw.shape[1:3]
        if list(pairs) == [(t, r) for t in range(n_tx) for r in range(n_rx)]:
            raw = read_rows(self.raw, start, stop)
            return raw.reshape(len(raw), n_tx * n_rx, *raw.shape[3:])
        tx, rx = (np.array([p[i] for p in pairs], dtype=np.intp) for i in (0, 1))
        chunks = self.raw.chunks
        if chunks is None or chunks[1] * chunks[2] > 1:
            # a chunk holds several channels (drives written before chunks were per channel): reading a channel
            # decompresses its chunk whole, so the frames are read once and the channels taken from them
            return read_rows(self.raw, start, stop)[:, tx, rx]
        with dataset_errors(self.raw.file.filename, self.raw.name):
            return np.stack([self.raw[start:stop, t, r] for t, r in zip(tx, rx, strict=True)], axis=1)

    def intact_frames(self, start: int, stop: int, pairs: Sequence[tuple[int, int]] | None = None
                      ) -> tuple[np.ndarray, NDArray[np.bool_]]:
        """:meth:`frames` ``start:stop``, and which of them are intact (n,) bool: where a stored chunk of a channel
        read fails its checksum or does not decompress, the frames it holds are zeroed in every channel (its
        channels must agree) and not intact; the rest of a damaged drive is read."""
        try:
            return self.frames(start, stop, pairs), np.ones(stop - start, bool)
        except DamagedFileError:
            pass
        rows = self.raw.chunks[0] if self.raw.chunks is not None else 1
        shape = tuple(self.raw.shape[1:]) if pairs is None else (len(pairs), *self.raw.shape[3:])
        parts, intact = [], np.ones(stop - start, bool)
        for first in range(start - start % rows, stop, rows):  # a row of chunks at a time
            a, b = max(first, start), min(first + rows, stop)
            try:
                parts.append(self.frames(a, b, pairs))
            except DamagedFileError:
                parts.append(np.zeros((b - a, *shape), self.raw.dtype))
                intact[a - start:b - start] = False
        return np.concatenate(parts), intact

    def frame_crc32(self, i: int) -> int | None:
        """CRC-32 of frame ``i``'s int16 samples as the drive holds them (the simulator's truth keeps the same);
        None where its chunk is damaged (its checksum fails)."""
        try:
            return frame_crc32(read_rows(self.raw, i, i + 1)[0])
        except DamagedFileError:
            return None

    def fingerprint(self, frames: int = 16) -> dict[str, Any]:
        """The stream's name and the frame indices and CRC-32s of ``frames`` frames spread over it (those that
        can be read): what names the recording a product was made from (a trajectory's, :meth:`unmatched`)."""
        crcs = [(int(self.frame_index[i]), self.frame_crc32(int(i))) for i in self.spread(frames)]
        return {"stream": self.name, "frame_index": [i for i, c in crcs if c is not None],
                "crc32": [c for _, c in crcs if c is not None]}

    def spread(self, frames: int) -> NDArray[np.int64]:
        """Positions of ``frames`` frames spread evenly over the stream (fewer where it holds fewer)."""
        n = len(self.frame_index)
        return np.unique(np.linspace(0, n - 1, frames).astype(np.int64)) if n else np.zeros(0, np.int64)

    def unmatched(self, frame_index: Sequence[int], crc32: Sequence[int]) -> int:
        """How many of the frames given by index and CRC-32 (a :meth:`fingerprint`, or a truth's) this stream
        holds, where none of them matches its own frame of that index; 0 where one does (a cut, damaged or
        converted log of the same recording keeps intact frames) or where none can be compared."""
        own = np.asarray(self.frame_index)
        order = np.argsort(own, kind="stable")
        compared = 0
        for index, crc in zip(frame_index, crc32, strict=True):
            k = int(np.searchsorted(own[order], index))
            if k < len(own) and own[order[k]] == index and (mine := self.frame_crc32(int(order[k]))) is not None:
                compared += 1
                if mine == int(crc):
                    return 0
        return compared


def _intact_rows_of(ds: h5py.Dataset, intact: NDArray[np.bool_]) -> np.ndarray:
    """The rows of a table's column ``ds`` where ``intact``, read a stored chunk at a time (those that hold none
    are not read: a damaged chunk's rows are not intact)."""
    step = ds.chunks[0] if ds.chunks is not None else len(intact)
    parts = [read_rows(ds, a, a + step)[intact[a:a + step]] for a in range(0, len(intact), step)
             if intact[a:a + step].any()]
    return np.concatenate(parts) if parts else np.zeros((0, *ds.shape[1:]), ds.dtype)


def frame_crc32(frame: np.ndarray) -> int:
    """CRC-32 of one raw frame (tx, rx, sample, I/Q) int16, as its bytes lie in C order."""
    return zlib.crc32(np.ascontiguousarray(frame).tobytes())


class Drive:
    """Read access to a drive.h5 (use as a context manager)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._file = open_hdf5(self.path, DriveFormatError)
        try:
            fmt = self._file.attrs.get("format")
            version = self._file.attrs.get("format_version")
            attrs = dict(self._file.attrs)
        except (OSError, RuntimeError) as exc:  # its root's header fails HDF5's own checksum
            self._file.close()
            raise DriveFormatError(f"{self.path}: its attributes cannot be read ({str(exc).splitlines()[0]}); "
                                   "damaged drive.h5 (ingest its logs again)") from None
        if fmt != FORMAT:
            self._file.close()
            raise DriveFormatError(not_the_format(self.path, fmt, FORMAT))
        if version is None:
            self._file.close()
            raise DriveFormatError(f"{self.path}: has no format_version attribute (damaged drive.h5)")
        if int(version) > FORMAT_VERSION:
            self._file.close()
            raise DriveFormatError(f"{self.path}: drive format version {version} is newer than this autosar "
                                   f"reads ({FORMAT_VERSION})")
        self.attrs = attrs
        #: one line per table read whose damaged rows were left out (:meth:`columns`, and so :meth:`series`,
        #: :meth:`can_role`)
        self.damage: list[str] = []
        if (why := attributes_damage(self._file)) is not None:  # read on, as a damaged table is: the rest holds
            self.damage.append(f"{self.path}: {why}: a value the drive states may be wrong (ingest its logs again)")
        self._intact_rows: dict[str, NDArray[np.bool_]] = {}  # per damaged table read: its intact rows

    def __enter__(self) -> Drive:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._file.close()

    @property
    def h5(self) -> h5py.File:
        return self._file

    def _members(self, group: str) -> list[str]:
        return sorted(self._file[group]) if group in self._file else []

    def can_messages(self) -> list[str]:
        return self._members("can")

    def gnss_sources(self) -> list[str]:
        return self._members("gnss")

    def nmea_captures(self) -> list[str]:
        """The GNSS sources that are NMEA text captures: named by their files, no topic pins them to a sensor."""
        return [s for s in self.gnss_sources() if "nmea_fix" in self.h5["gnss"][s]
                and self.h5["gnss"][s]["nmea_fix"].attrs.get("msgtype") == NMEA_TEXT_MSGTYPE]

    def imu_sources(self) -> list[str]:
        return self._members("imu")

    def radar_names(self) -> list[str]:
        return self._members("radar")

    def radar_attrs(self, name: str | None = None) -> dict[str, Any]:
        """The attributes of radar stream ``name`` (the first where None; {} where the drive holds none)."""
        names = self.radar_names()
        if not names or (name is not None and name not in names):
            return {}
        with dataset_errors(self.path, f"radar/{name or names[0]}"):
            attrs = self._file["radar"][name or names[0]].attrs
            return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in attrs.items()}

    def series(self, path: str) -> dict[str, np.ndarray]:
        """All columns of a series group (``"imu/imu_cog_a"``, ``"gnss/gnss_cog/fix"``, ``"can/ABS_1"``)."""
        with dataset_errors(self.path, path):
            g = self._file[path]
        return self.columns(g, [k for k in g if isinstance(g[k], h5py.Dataset) and k != "raw"])

    def columns(self, group: h5py.Group | str, names: Sequence[str]) -> dict[str, np.ndarray]:
        """Columns ``names`` of a table (a series group, or its path). Where a stored chunk of any of the table's
        columns fails its checksum or does not decompress, its rows are left out of every column, so that the
        columns read at any time agree row for row, and :attr:`damage` says so (one line per table)."""
        if isinstance(group, str):
            with dataset_errors(self.path, group):
                group = self._file[group]
        intact = self._intact_rows.get(group.name)
        if intact is None:
            try:
                return {k: read_dataset(group, k, self.path) for k in names}
            except DamagedFileError as exc:
                intact = self._table_damage(group, exc)
        return {k: _intact_rows_of(group[k], intact) if group[k].shape[:1] == intact.shape
                else read_dataset(group, k, self.path) for k in names}

    def _table_damage(self, group: h5py.Group, error: DamagedFileError) -> NDArray[np.bool_]:
        """Which rows of the table ``group`` every column's stored chunks hold intact (kept for the next read);
        ``error``, the read's, where the trouble lies elsewhere (a column missing, a damaged dataset of its own)."""
        rows = len(group["t_ns"]) if "t_ns" in group else -1
        intact = np.ones(max(rows, 0), bool)
        for k in group:
            ds = group[k]
            if not isinstance(ds, h5py.Dataset) or ds.chunks is None or ds.shape[:1] != (rows,):
                continue
            for a in range(0, rows, ds.chunks[0]):
                try:
                    read_rows(ds, a, a + ds.chunks[0])
                except DamagedFileError:
                    intact[a:a + ds.chunks[0]] = False
        if intact.all():
            raise error
        if not intact.any():
            raise DamagedFileError(f"{self.path}: every stored chunk of {group.name} ({rows} rows) holds a damaged "
                                   "column: the table cannot be read")
        lost = np.flatnonzero(~intact)
        self.damage.append(f"{self.path}: rows {lost[0]}-{lost[-1]} of {group.name} ({len(lost)} of {rows}) failed "
                           "their checksum (the drive is damaged there): left out, a gap in that stream")
        self._intact_rows[group.name] = intact
        return intact

    def can_role(self, role: str, times: dict[str, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(t_ns, value in SI units) of a CAN signal by its role in the vehicle config (``wheel_speed_fl``), the rows
        that carry it; ``times``: each message's time stamps by its group, read once across calls."""
        roles = self.can_roles()
        if role not in roles:
            raise KeyError(f"{self.path}: no CAN signal has the role {role!r} (known: {', '.join(sorted(roles))})")
        message, signal = roles[role].split("/")
        with dataset_errors(self.path, f"can/{message}"):
            g = self._file["can"][message]
        times = {} if times is None else times
        if message not in times:
            times[message] = self.columns(g, ["t_ns"])["t_ns"]
        values = self.columns(g, [signal])[signal]
        selected = np.isfinite(values)  # a multiplexed signal is NaN in the rows of the message's other values
        return times[message][selected], values[selected]

    def can_roles(self) -> dict[str, str]:
        return json.loads(self._file["can"].attrs.get("roles", "{}")) if "can" in self._file else {}

    def radar(self, name: str | None = None) -> RadarStream:
        names = self.radar_names()
        if not names:
            raise DriveFormatError(f"{self.path}: no radar stream")
        name = name or names[0]
        if name not in names:
            raise DriveFormatError(f"{self.path}: no radar stream {name!r} (it holds {', '.join(names)})")
        with dataset_errors(self.path, f"radar/{name}/raw"):
            g = self._file["radar"][name]
            raw = g["raw"]
        attrs = self.radar_attrs(name)
        return RadarStream(name, read_dataset(g, "t_ns", self.path), read_dataset(g, "frame_index", self.path), raw,
                           attrs)

    def report(self) -> dict[str, Any]:
        """The ingest report stored in the provenance group."""
        return json.loads(self._file["provenance"].attrs.get("report", "{}"))


def radar_times(drive_path: str | Path, name: str | None = None, late_s: float = 0.0,
                drift_ppm: float = 0.0) -> NDArray[np.int64]:
    """Frame start times (ns) of a drive's radar stream ``name`` (None: its first) on the navigation's clock, where
    its stamps run ``late_s`` (s) late and ``drift_ppm`` fast (:meth:`RadarStream.on_clock`)."""
    with Drive(drive_path) as d:
        return np.asarray(d.radar(name).on_clock(late_s, drift_ppm).t_ns, dtype=np.int64)


def chirp_on_navigation_clock(attrs: Mapping[str, Any], drift_ppm: float) -> dict[str, Any]:
    """A radar's chirp attributes (``start_frequency_hz``, ``slope_hz_per_s``, ``sample_rate_hz``,
    ``tx_start_offsets_s``, ``prf_hz``, as configured) on the navigation's clock where the crystal they are all
    derived from runs ``drift_ppm`` fast: its frequencies that much higher, its slope by the square, its intervals
    shorter. The ranges a profile shows scale with it (100 ppm: 2 mm at 20 m). The attributes it changed are kept
    as configured under ``configured_<name>``."""
    out = dict(attrs)
    if not drift_ppm:
        return out
    rate = 1.0 + drift_ppm * 1e-6
    for name, power in (("start_frequency_hz", 1), ("slope_hz_per_s", 2), ("sample_rate_hz", 1), ("prf_hz", 1),
                        ("tx_start_offsets_s", -1)):
        if name in out:
            out[f"configured_{name}"] = out[name]
            value = np.asarray(out[name], dtype=np.float64) * rate ** power
            out[name] = value.tolist() if value.ndim else float(value)
    return out


def radar_clock_reading(t_ns: NDArray[np.int64], first_ns: int, late_s: float, drift_ppm: float
                        ) -> NDArray[np.int64]:
    """What a radar's clock reads (ns) at the navigation's instants ``t_ns`` (ns): the inverse of
    :func:`stamps_on_navigation_clock`, the clock reading ``first_ns`` at its first frame."""
    t = np.asarray(t_ns, dtype=np.int64)
    late_ns = int(round(late_s * 1e9))
    out = t + late_ns
    if drift_ppm:
        since_first = (t - (int(first_ns) - late_ns)).astype(np.float64)
        out = out + np.round(since_first * drift_ppm * 1e-6).astype(np.int64)
    return out


def stamps_on_navigation_clock(stamps_ns: NDArray[np.int64], first_ns: int, late_s: float,
                               drift_ppm: float) -> NDArray[np.int64]:
    """The navigation clock's instants (ns) of a radar's ``stamps_ns`` (ns, its clock): a clock that reads
    ``first_ns`` ``late_s`` (s) after the navigation's instant, and from then on counts ``1 + drift_ppm * 1e-6``
    seconds for each of the navigation's. The one definition of the radar's clock (with its inverse,
    :func:`radar_clock_reading`): the simulator's stamps invert it (sim.simulate), the truth's radar motion follows
    it (nav.baselines.from_truth)."""
    stamps = np.asarray(stamps_ns, dtype=np.int64)
    out = stamps - int(round(late_s * 1e9))
    if drift_ppm:
        rate = drift_ppm * 1e-6
        # int64 differences keep ns exact over a drive; the drift's share is at most 1e-3 of them
        elapsed = (stamps - int(first_ns)).astype(np.float64)
        out = out - np.round(elapsed * (rate / (1.0 + rate))).astype(np.int64)
    return out
