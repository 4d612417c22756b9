"""Checksums of the GeoTIFF autosar writes, which TIFF itself does not carry, and their check.

A GeoTIFF's tiles are deflate streams (zlib: Adler-32), so damaged pixels mostly fail to decode; but its tags carry
no checksum, and a byte flipped in the tie point or pixel scale moves the whole map without a word. autosar's
GeoTIFF holds three tags of its own:

- ``autosar_georeference_crc32``: CRC-32 of its affine transform (six numbers, ``repr``) and EPSG code;
- ``autosar_columns_crc32``: the CRC-32 of each column of band 1 (float32, little-endian, top to bottom),
  zlib-compressed and base64-encoded, so that a check names the damaged columns;
- ``autosar_columns_tag_crc32``: CRC-32 of that tag's text (a damaged tag is told from damaged pixels).

:func:`verify_geotiff` reads the band tile by tile and checks them all (``autosar info image.tif --verify``).
"""

from __future__ import annotations

import base64
import zlib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import rasterio
from numpy.typing import NDArray
from rasterio import Affine

GEOREFERENCE_TAG = "autosar_georeference_crc32"
COLUMNS_TAG = "autosar_columns_crc32"
COLUMNS_TAG_CHECK = "autosar_columns_tag_crc32"


def column_crc32(block: NDArray[np.float32], prior: NDArray[np.uint32] | None = None) -> NDArray[np.uint32]:
    """CRC-32 of each column of ``block`` (rows, cols) as float32 little-endian bytes, top to bottom, continuing
    ``prior`` (the CRCs of the rows above, one per column)."""
    values = np.ascontiguousarray(np.asarray(block, dtype="<f4").T)
    start = np.zeros(values.shape[0], np.uint32) if prior is None else prior
    return np.array([zlib.crc32(values[j], int(start[j])) for j in range(values.shape[0])], np.uint32)


def georeference_crc32(transform: Affine, epsg: int | None) -> int:
    """CRC-32 of a transform's six numbers and an EPSG code, as text."""
    return zlib.crc32(repr((tuple(float(v) for v in transform[:6]), epsg)).encode())


def checksum_tags(columns: NDArray[np.uint32], transform: Affine, epsg: int) -> dict[str, str]:
    """The three tags of a GeoTIFF whose band's columns have CRCs ``columns``, georeferenced by ``transform`` in
    EPSG ``epsg``."""
    text = base64.b64encode(zlib.compress(np.asarray(columns, "<u4").tobytes(), 9)).decode("ascii")
    return {GEOREFERENCE_TAG: str(georeference_crc32(transform, epsg)), COLUMNS_TAG: text,
            COLUMNS_TAG_CHECK: str(zlib.crc32(text.encode("ascii")))}


@dataclass
class TiffVerification:
    """What :func:`verify_geotiff` found in a GeoTIFF autosar wrote."""

    path: str
    columns: int = 0
    tiles: int = 0  #: tiles (or strips) read
    checksummed: bool = True  #: it carries autosar's checksum tags (False: nothing to check it against)
    georeference_intact: bool = True
    tags_intact: bool = True  #: the columns' checksum tag itself
    unreadable: list[str] = field(default_factory=list)  #: tiles that do not decode: "rows a-b, columns c-d: why"
    damaged_columns: list[tuple[int, int]] = field(default_factory=list)  #: runs of columns [first, last + 1)

    @property
    def intact(self) -> bool:
        return (self.checksummed and self.georeference_intact and self.tags_intact and not self.unreadable
                and not self.damaged_columns)

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "intact": self.intact}


def verify_geotiff(path: Path) -> TiffVerification:
    """Read every tile of band 1 of the GeoTIFF at ``path`` and check it, its georeference and its checksum tags
    against what autosar wrote. OSError where the file cannot be opened as a GeoTIFF."""
    found = TiffVerification(str(path))
    try:
        src_ctx = rasterio.open(path)
    except rasterio.errors.RasterioIOError as exc:
        raise OSError(f"{path}: not a GeoTIFF rasterio can open ({' '.join(str(exc).split())})") from exc
    with src_ctx as src:
        tags = src.tags()
        found.columns = src.width
        crcs = np.zeros(src.width, np.uint32)
        broken = np.zeros(src.width, bool)
        for _, window in src.block_windows(1):
            found.tiles += 1
            c0, c1 = int(window.col_off), int(window.col_off + window.width)
            try:
                block = src.read(1, window=window)
            except rasterio.errors.RasterioIOError as exc:
                why = " ".join(str(exc.__cause__ or exc).split())  # GDAL's own error, not rasterio's summary
                found.unreadable.append(f"rows {int(window.row_off)}-{int(window.row_off + window.height) - 1}, "
                                        f"columns {c0}-{c1 - 1}: {why}")
                broken[c0:c1] = True
                continue
            crcs[c0:c1] = column_crc32(block, crcs[c0:c1])
        if not all(k in tags for k in (GEOREFERENCE_TAG, COLUMNS_TAG, COLUMNS_TAG_CHECK)):
            found.checksummed = False
            return found
        epsg = src.crs.to_epsg() if src.crs is not None else None
        found.georeference_intact = tags[GEOREFERENCE_TAG] == str(georeference_crc32(src.transform, epsg))
        written = _written_columns(tags, src.width)
    if written is None:
        found.tags_intact = False
        return found
    differs = (crcs != written) & ~broken
    edges = np.flatnonzero(np.diff(np.r_[0, differs.astype(np.int8), 0]))
    found.damaged_columns = [(int(a), int(b)) for a, b in zip(edges[0::2], edges[1::2], strict=True)]
    return found


def _written_columns(tags: dict[str, str], width: int) -> NDArray[np.uint32] | None:
    """The columns' CRCs the tags hold, or None where the tag is damaged (its own CRC, its encoding, its length)."""
    text = tags[COLUMNS_TAG]
    if tags[COLUMNS_TAG_CHECK] != str(zlib.crc32(text.encode("ascii", "replace"))):
        return None
    try:
        raw = zlib.decompress(base64.b64decode(text, validate=True))
    except (ValueError, zlib.error):
        return None
    if len(raw) != 4 * width:
        return None
    return np.frombuffer(raw, "<u4").astype(np.uint32)
