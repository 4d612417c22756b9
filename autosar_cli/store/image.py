"""Focused-image products: OUT.tif (GeoTIFF, dB), OUT.h5 (format ``autosar-image`` v1), OUT.png (quicklook).

The image is complex, (rows, cols) = (n_across, n_along) on a :class:`FocusGrid` in the local ENU frame
of a :class:`GeodeticOrigin`. The GeoTIFF is georeferenced in the WGS-84 UTM zone of that origin with an
affine transform fitted to the exact ENU -> geodetic -> UTM conversion (residual reported, sub-mm over a
few hundred metres). Every file is written atomically (``<stem>.partial-<pid><suffix>``, then renamed). See
docs/FORMATS.md.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import shutil
import warnings
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import rasterio
from numpy.typing import NDArray
from rasterio import Affine
from rasterio.crs import CRS
from rasterio.windows import Window

from autosar_cli import __version__
from autosar_cli.store.atomic import already_exists, atomic_output
from autosar_cli.store.attr_checksum import attributes_damage, stamp_attributes
from autosar_cli.store.hdf5_read import open_hdf5, read_dataset
from autosar_cli.store.libtiff_messages import route_libtiff_messages
from autosar_cli.store.manifest import json_default
from autosar_cli.store.outputs import SMALL_FILE_MARGIN_BYTES, check_free_space, not_the_format
from autosar_cli.store.quicklook import draw_quicklook, preload_quicklook  # noqa: F401  (focus, run preload it)
from autosar_cli.store.tif_checksum import checksum_tags, column_crc32, verify_geotiff
from autosar_cli.types import FocusGrid, GeodeticOrigin

FORMAT = "autosar-image"
FORMAT_VERSION = 1
DB_UNITS = "dB, 20 log10 |complex image|"
PRODUCT_SUFFIXES = (".tif", ".h5", ".png")
_JSON_KEYS = "_json_keys"  #: attribute of /params listing the parameters stored as JSON text


class ImageFormatError(ValueError):
    """Not an image.h5 this version reads; the message names the file and the problem."""


@dataclass
class FocusedImage:
    """A focused complex image on ``grid`` (ENU of ``origin``) with its processing parameters and provenance."""

    image: NDArray[np.complex64]  #: (rows, cols) = grid.shape, linear complex amplitude (arbitrary units)
    grid: FocusGrid
    origin: GeodeticOrigin
    params: dict[str, Any]  #: processing parameters, JSON-serialisable values
    provenance: dict[str, Any] = field(default_factory=dict)  #: inputs, command line, ... (JSON-serialisable)

    def __post_init__(self) -> None:
        if self.image.ndim != 2 or self.image.shape != self.grid.shape:
            raise ValueError(f"image shape {self.image.shape} does not match the grid shape {self.grid.shape} "
                             "(rows = n_across, cols = n_along)")


def product_paths(base: Path) -> dict[str, Path]:
    """The three product paths for ``base``: {'tif', 'h5', 'png'}.

    A product suffix on ``base`` (``.tif``, ``.tiff``, ``.h5``, ``.png``) is replaced; any other suffix is
    kept (``run.v2`` -> ``run.v2.tif``), so dotted names do not lose their last part.
    """
    base = Path(base)
    if base.suffix.lower() in (*PRODUCT_SUFFIXES, ".tiff"):
        base = base.with_suffix("")
    return {s[1:]: base.with_name(base.name + s) for s in PRODUCT_SUFFIXES}


def utm_geotransform(grid: FocusGrid, origin: GeodeticOrigin) -> tuple[Affine, int, float]:
    """Affine raster -> UTM transform of ``grid``, its EPSG code, and the max fit residual (m).

    The transform maps raster (col, row) of pixel *corners* (GDAL convention: (0, 0) is the outer corner
    of pixel (0, 0), its centre is (0.5, 0.5)) to UTM easting, northing (m) in the zone of ``origin``.
    It is the least-squares fit over a 5 x 5 lattice of raster points spanning the image (corners, edge
    midpoints, centre, ...) converted exactly ENU -> geodetic -> UTM; the conversion is not exactly affine
    (grid convergence, scale factor, earth curvature), the residual is the largest misfit on the lattice.
    """
    epsg = origin.utm_epsg()
    u, v = np.meshgrid(np.linspace(0.0, grid.n_along, 5), np.linspace(0.0, grid.n_across, 5))
    u, v = u.ravel(), v.ravel()
    utm = origin.enu_to_utm(grid.pixel_enu(v - 0.5, u - 0.5), epsg)  # raster corner coords -> pixel indices
    uc, vc, centre = u - u.mean(), v - v.mean(), utm.mean(axis=0)  # centred for conditioning (UTM ~ 1e6 m)
    design = np.column_stack([uc, vc, np.ones_like(uc)])
    coef, *_ = np.linalg.lstsq(design, utm - centre, rcond=None)  # (3, 2): rows a|d, b|e, offset
    residual = float(np.max(np.hypot(*(design @ coef - (utm - centre)).T)))
    (a, d), (b, e), (c0, f0) = coef
    c = centre[0] + c0 - a * u.mean() - b * v.mean()
    f = centre[1] + f0 - d * u.mean() - e * v.mean()
    return Affine(float(a), float(b), float(c), float(d), float(e), float(f)), epsg, residual


def magnitude_db(image: NDArray[np.complexfloating[Any, Any]]) -> NDArray[np.float32]:
    """20 log10 |z| (absolute dB) as float32; NaN where |z| is 0 or not finite."""
    mag = np.abs(image)
    with np.errstate(divide="ignore", invalid="ignore"):
        db = (20.0 * np.log10(mag)).astype(np.float32)
    db[~np.isfinite(db)] = np.nan
    return db


class ImageWriter:
    """Writes the three products of a grid column strip by column strip, so the image never has to be whole
    in memory (focus in tiles): each strip goes into the GeoTIFF (dB, windowed write) and image.h5 (complex
    hyperslab) at once, and into a max-pooled dB copy the size of the quicklook (at most ~1200 x 1400).

    Use as a context manager::

        with ImageWriter(base, grid, origin, overwrite=True) as w:
            for col0, strip in strips:          # any order, each column exactly once
                w.write_columns(col0, strip)
            w.set_metadata(params, provenance)
        w.paths  # {'tif', 'h5', 'png'}

    The files are written to temporary siblings and renamed onto their names only when the block exits
    without an exception, every column written and the metadata set; otherwise the temporaries are deleted
    and no product is left looking complete. GDAL's block cache is bounded (``gdal_cache_mb``) so the
    GeoTIFF's dirty blocks do not grow with the image either.
    """

    def __init__(self, base: Path, grid: FocusGrid, origin: GeodeticOrigin, *, overwrite: bool = False,
                 dynamic_range_db: float = 50.0, gdal_cache_mb: int = 64) -> None:
        self.paths = product_paths(base)
        self.grid = grid
        self.origin = origin
        self.overwrite = overwrite
        self.dynamic_range_db = dynamic_range_db
        self.gdal_cache_mb = gdal_cache_mb
        rows, cols = grid.shape
        self._pool = max(1, int(np.ceil(max(rows / 1200, cols / 1400))))
        f = self._pool
        self._pooled = np.full((-(-rows // f), -(-cols // f)), np.nan, np.float32)  # absolute dB, NaN = none yet
        self._written = np.zeros(cols, bool)
        self._column_crc32 = np.zeros(cols, np.uint32)  #: of the GeoTIFF's columns as written (its checksum tags)
        self._params_json: dict[str, str] | None = None
        self._params: dict[str, Any] = {}
        self._provenance_json = "{}"
        self._stack: ExitStack | None = None

    def __enter__(self) -> ImageWriter:
        if not self.overwrite:
            for p in self.paths.values():
                if p.exists():
                    raise FileExistsError(already_exists(p))
        rows, cols = self.grid.shape
        # complex64 image.h5 + float32 GeoTIFF (uncompressed bounds; the quicklook is small)
        check_free_space(self.paths["h5"], rows * cols * (8 + 4), "the image", SMALL_FILE_MARGIN_BYTES)
        self.transform, self.epsg, self.residual = utm_geotransform(self.grid, self.origin)
        self.crs = CRS.from_epsg(self.epsg)
        stack = ExitStack()
        try:
            self._tmp = {k: stack.enter_context(atomic_output(p, self.overwrite)) for k, p in self.paths.items()}
            stack.enter_context(rasterio.Env(GDAL_CACHEMAX=self.gdal_cache_mb))
            route_libtiff_messages()  # a write the disk refuses is this writer's error to tell, not libtiff's print
            # after the GeoTIFF is closed, within the bounded block cache, before the products come into place
            stack.push(self._read_back_geotiff)
            self._tif = stack.enter_context(_open_geotiff(self._tmp["tif"], self.grid, self.transform, self.crs))
            self._h5 = stack.enter_context(h5py.File(self._tmp["h5"], "w"))
            self._image_ds = _create_h5(self._h5, self.grid, self.origin, self.transform, self.epsg, self.crs,
                                        self.residual)
        except BaseException:
            stack.close()
            raise
        self._stack = stack
        return self

    def write_columns(self, col0: int, strip: NDArray[np.complexfloating[Any, Any]]) -> None:
        """Columns [col0, col0 + n) of the complex image: ``strip`` (rows, n), linear amplitude."""
        rows, cols = self.grid.shape
        strip = np.asarray(strip, dtype=np.complex64)
        n = strip.shape[1] if strip.ndim == 2 else -1
        if strip.ndim != 2 or strip.shape[0] != rows or col0 < 0 or col0 + n > cols:
            raise ValueError(f"column strip of shape {strip.shape} at column {col0} does not fit the grid "
                             f"{self.grid.shape} (rows = n_across, cols = n_along)")
        if self._written[col0: col0 + n].any():
            raise ValueError(f"columns {col0}..{col0 + n - 1}: some were written already")
        db = magnitude_db(strip)
        try:
            self._tif.write(db, 1, window=Window(col0, 0, n, rows))
        except rasterio.errors.RasterioIOError as exc:  # "Write failed. See previous exception for details."
            raise self._tif_refused(f"columns {col0}-{col0 + n - 1} could not be written: "
                                    f"{str(exc.__cause__ or exc).splitlines()[0]}") from exc
        self._column_crc32[col0: col0 + n] = column_crc32(db)
        self._image_ds[:, col0: col0 + n] = strip
        self._pool_into(np.where(strip == 0, np.float32(-np.inf), db), col0)
        self._written[col0: col0 + n] = True

    def set_metadata(self, params: dict[str, Any], provenance: dict[str, Any] | None = None) -> None:
        """Processing parameters and provenance (JSON-serialisable; TypeError here if not)."""
        self._params_json = {k: _to_json(v) for k, v in params.items()}
        self._params = dict(params)
        self._provenance_json = _to_json(provenance or {})

    def _pool_into(self, db: NDArray[np.float32], col0: int) -> None:
        """Max-pool ``db`` (exact zeros -inf, non-finite NaN) into the quicklook copy; NaN only where all are."""
        f = self._pool
        rows, n = db.shape
        r2 = -(-rows // f) * f
        if r2 != rows:
            db = np.concatenate([db, np.full((r2 - rows, n), np.nan, np.float32)])
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN pools stay NaN
            by_rows = np.nanmax(db.reshape(r2 // f, f, n), axis=1)
            cells = (col0 + np.arange(n)) // f
            starts = np.flatnonzero(np.r_[True, cells[1:] != cells[:-1]])
            pooled = np.fmax.reduceat(by_rows, starts, axis=1)
            sl = self._pooled[:, cells[starts]]
            self._pooled[:, cells[starts]] = np.fmax(sl, pooled)

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        stack, self._stack = self._stack, None
        if stack is None:
            return
        if exc_type is None:
            try:
                self._finish()
            except BaseException as err:
                self._abandon()
                stack.__exit__(type(err), err, err.__traceback__)  # deletes the temporaries, re-raises
                raise
        if exc_type is not None:
            self._abandon()
        stack.__exit__(exc_type, exc, tb)  # closes the files, then renames them (or deletes them on error)

    def _read_back_geotiff(self, exc_type: Any, exc: Any, tb: Any) -> bool:
        """Read the closed GeoTIFF back against the columns' checksums: libtiff's writes that the disk refused as it
        closed raise nothing through rasterio (its errors only logged), and the cut file came into place as if
        whole. OSError (ENOSPC where the disk is full) then, so that no product comes into place."""
        if exc_type is not None:
            return False
        try:
            found = verify_geotiff(self._tmp["tif"])
        except OSError:
            what = "it does not open"
        else:
            if found.intact:
                return False
            what = (f"{len(found.unreadable)} tile(s) unreadable" if found.unreadable
                    else f"columns {found.damaged_columns[0][0]}-{found.damaged_columns[0][1] - 1} differ"
                    if found.damaged_columns else "its checksum tags missing or damaged")
        raise self._tif_refused(f"the GeoTIFF did not read back as written ({what})")

    def _tif_refused(self, what: str) -> OSError:
        """The GeoTIFF's failure ``what`` as an OSError naming it: ENOSPC where its disk is (all but) full, whose
        write libtiff refused (rasterio says only "Write failed"), else EIO."""
        full = shutil.disk_usage(self._tmp["tif"].parent).free < SMALL_FILE_MARGIN_BYTES
        failed = OSError(f"{self.paths['tif']}: {what}" + ("; the disk is full" if full else ""))
        failed.errno = errno.ENOSPC if full else errno.EIO  # the message alone, as str() gives it
        return failed

    def _abandon(self) -> None:
        """Empty the partial image.h5 before it is closed and deleted: closing flushes HDF5's caches, and on a full
        disk that fails half-way, leaving the file half closed for the library's own clean-up at exit, which then
        crashed the process (SIGSEGV, after the command's error line)."""
        with contextlib.suppress(OSError):
            os.truncate(self._tmp["h5"], 0)

    def _finish(self) -> None:
        if not self._written.all():
            missing = np.flatnonzero(~self._written)
            raise ValueError(f"{self.paths['h5']}: image incomplete, {missing.size} columns never written "
                             f"(first {missing[0]})")
        if self._params_json is None:
            raise ValueError(f"{self.paths['h5']}: processing parameters never set")
        self._tif.update_tags(**_tif_tags(self._params_json, self._provenance_json))
        self._tif.update_tags(**checksum_tags(self._column_crc32, self.transform, self.epsg))
        self._tif.update_tags(1, units=DB_UNITS)
        self._tif.set_band_description(1, "magnitude_db")
        self._tif.set_band_unit(1, "dB")
        _write_params(self._h5.create_group("params"), self._params)
        self._h5.create_group("provenance").attrs["json"] = self._provenance_json
        stamp_attributes(self._h5)  # the grid and georeference, which no dataset checksum covers
        draw_quicklook(self._tmp["png"], self._pooled, self._pool, self.grid, dynamic_range_db=self.dynamic_range_db)


def write_image(base: Path, img: FocusedImage, *, overwrite: bool = False,
                dynamic_range_db: float = 50.0) -> dict[str, Path]:
    """Write ``base``.tif, .h5 and .png (see :func:`product_paths`), each atomically; return {'tif', 'h5', 'png'}.

    Raises FileExistsError before writing anything if any of them exists and ``overwrite`` is false, and
    TypeError if a parameter or the provenance is not JSON-serialisable. (:class:`ImageWriter` writes the
    same products strip by strip.)
    """
    writer = ImageWriter(base, img.grid, img.origin, overwrite=overwrite, dynamic_range_db=dynamic_range_db)
    writer.set_metadata(img.params, img.provenance)  # fail early on unserialisable values
    with writer:
        writer.write_columns(0, img.image)
    return writer.paths


def read_image(path: Path) -> FocusedImage:
    """Read an image.h5 back; raises ImageFormatError for anything that is not one this version reads."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    with open_hdf5(path, ImageFormatError) as f:
        fmt = f.attrs.get("format")
        if fmt != FORMAT:
            raise ImageFormatError(not_the_format(path, fmt, FORMAT))
        version = int(f.attrs.get("format_version", -1))
        if version != FORMAT_VERSION:
            raise ImageFormatError(f"{path}: image format version {version}, this autosar {__version__} reads "
                                   f"version {FORMAT_VERSION}")
        if (why := attributes_damage(f)) is not None:
            raise ImageFormatError(f"{path}: {why}; damaged image.h5")
        try:
            a = f.attrs
            origin = GeodeticOrigin(float(a["origin_lat_deg"]), float(a["origin_lon_deg"]),
                                    float(a["origin_height_m"]))
            grid = FocusGrid.from_attrs(dict(f["grid"].attrs))
            image = np.asarray(read_dataset(f, "image", path), dtype=np.complex64)
            params = _read_params(f["params"])
            provenance = json.loads(f["provenance"].attrs["json"]) if "provenance" in f else {}
        except KeyError as exc:
            raise ImageFormatError(f"{path}: incomplete image.h5, missing {exc}") from exc
    try:
        return FocusedImage(image, grid, origin, params, provenance)
    except ValueError as exc:
        raise ImageFormatError(f"{path}: {exc}") from exc


def _to_json(value: Any) -> str:
    """JSON text of ``value`` (numpy scalars and arrays become numbers and lists)."""
    return json.dumps(value, default=json_default)


def _open_geotiff(path: Path, grid: FocusGrid, transform: Affine, crs: CRS) -> Any:
    """One float32 band of 20 log10 |z| (dB, NaN nodata), tiled, deflate, open for (windowed) writing."""
    rows, cols = grid.shape
    profile: dict[str, Any] = {
        "driver": "GTiff", "width": cols, "height": rows, "count": 1, "dtype": "float32", "crs": crs,
        "transform": transform, "nodata": np.nan, "compress": "deflate", "predictor": 3, "zlevel": 1,
    }
    if rows >= 16 and cols >= 16:  # GeoTIFF tiles are multiples of 16 pixels
        profile.update(tiled=True, blockxsize=min(256, cols // 16 * 16), blockysize=min(256, rows // 16 * 16))
    return rasterio.open(path, "w", **profile)


def _tif_tags(params_json: dict[str, str], provenance_json: str) -> dict[str, str]:
    """GeoTIFF dataset tags: units, autosar version, one ``param_<name>`` JSON tag per parameter, provenance."""
    return {"units": DB_UNITS, "autosar_version": __version__, "autosar_format": "autosar-image-db",
            **{f"param_{k}": v for k, v in params_json.items()}, "provenance": provenance_json}


def _create_h5(f: h5py.File, g: FocusGrid, origin: GeodeticOrigin, transform: Affine, epsg: int, crs: CRS,
               residual: float) -> h5py.Dataset:
    """image.h5 skeleton: attributes, pixel-centre axes, grid; returns the (empty) complex image dataset."""
    rows, cols = g.shape
    f.attrs.update({
        "format": FORMAT, "format_version": FORMAT_VERSION, "autosar_version": __version__,
        "origin_lat_deg": origin.lat_deg, "origin_lon_deg": origin.lon_deg,
        "origin_height_m": origin.height_m, "utm_epsg": epsg,
        "geotransform": np.asarray(transform.to_gdal(), dtype=np.float64), "geotransform_residual_m": residual,
        "crs_wkt": crs.to_wkt(),
    })
    # ~256 x 256 chunks that tile the image evenly (edge chunks are stored whole). Uncompressed: shuffle + lzf
    # saved 6 % of test1's 6.7 MB (a complex image is noise-like in its low bits) for 0.13 s of writing and
    # 0.06 s of reading; raw it takes 0.02 s and 0.01 s (measured)
    chunks = (-(-rows // -(-rows // 256)), -(-cols // -(-cols // 256)))
    ds = f.create_dataset("image", shape=(rows, cols), dtype=np.complex64, chunks=chunks, fletcher32=True)
    ds.attrs.update({"units": "linear complex amplitude (arbitrary)", "axes": "rows = across, cols = along"})
    f["along_m"] = np.arange(cols, dtype=np.float64) * g.pixel_m
    f["across_m"] = np.arange(rows, dtype=np.float64) * g.pixel_m
    for name, axis in (("along_m", "along"), ("across_m", "across")):
        f[name].attrs["description"] = (f"pixel-centre distance from pixel (0, 0)'s centre along grid/{axis}, "
                                        "m; ENU = grid/origin_enu_m + along_m * along + across_m * across")
    f.create_group("grid").attrs.update(g.to_attrs())
    return ds


def _write_params(group: h5py.Group, params: dict[str, Any]) -> None:
    """Scalars (bool, int, float, str) as native attributes, everything else as JSON text listed in _json_keys."""
    if _JSON_KEYS in params:
        raise ValueError(f"processing parameter name {_JSON_KEYS!r} is reserved")
    json_keys = []
    for k, v in params.items():
        if isinstance(v, np.generic):
            v = v.item()
        if isinstance(v, bool | str | float) or (isinstance(v, int) and -2**63 <= v < 2**63):
            group.attrs[k] = v
        else:
            group.attrs[k] = _to_json(v)
            json_keys.append(k)
    group.attrs[_JSON_KEYS] = json.dumps(json_keys)


def _read_params(group: h5py.Group) -> dict[str, Any]:
    json_keys = set(json.loads(group.attrs.get(_JSON_KEYS, "[]")))
    out: dict[str, Any] = {}
    for k, v in group.attrs.items():
        if k == _JSON_KEYS:
            continue
        out[k] = json.loads(v) if k in json_keys else (v.item() if isinstance(v, np.generic) else v)
    return out
