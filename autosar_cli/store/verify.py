"""The check of a stored file autosar wrote against its own checksums, whatever its kind: one entry point for
``autosar info PATH --verify``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from autosar_cli.store.hdf5_read import verify
from autosar_cli.store.png_check import verify_png
from autosar_cli.store.tif_checksum import verify_geotiff

#: the files autosar writes with checksums: HDF5 (Fletcher-32 per chunk), GeoTIFF (its tags), PNG (its own)
VERIFIED_SUFFIXES = (".h5", ".hdf5", ".tif", ".tiff", ".png")


def verify_file(path: Path) -> dict[str, Any]:
    """What reading every stored chunk, tile or PNG chunk of ``path`` found, as a dict with ``intact`` among it.
    ValueError where the file is no HDF5 file autosar wrote; OSError where it cannot be read."""
    suffix = path.suffix.lower()
    if suffix in (".tif", ".tiff"):
        return verify_geotiff(path).to_dict()
    if suffix == ".png":
        return verify_png(path).to_dict()
    return verify(path, ValueError).to_dict()
