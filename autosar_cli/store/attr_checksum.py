"""A checksum over every attribute of an HDF5 file autosar writes (root ``attrs_crc32``).

Datasets carry Fletcher-32 checksums per chunk, but HDF5 keeps attributes in object headers that no checksum
covers: a flipped byte in a trajectory's ``origin_lat_deg``, an image's geotransform or a radar's start frequency
read as a different value, and moved the image 870 m without a word. The writer stamps the CRC-32 of every
attribute (its object's path, its name, its stored bytes, read back from the file), the reader and ``autosar info
--verify`` check it. A file without the stamp (written before it) is read unchecked.
"""

from __future__ import annotations

import os
import zlib

import h5py
import numpy as np

ATTRS_CRC = "attrs_crc32"


def attributes_crc32(f: h5py.File) -> int:
    """CRC-32 of every attribute of ``f`` but the stamp, in path and name order, as stored."""
    objects: list[tuple[str, h5py.AttributeManager]] = [("/", f.attrs)]
    f.visititems(lambda name, obj: objects.append((name, obj.attrs)))
    crc = 0
    for path, attrs in sorted(objects, key=lambda item: item[0]):
        for key in sorted(attrs):
            if path == "/" and key == ATTRS_CRC:
                continue
            value = np.asarray(attrs[key])
            crc = zlib.crc32(f"{path}\0{key}\0{value.dtype.str}\0".encode(), crc)
            crc = zlib.crc32(value.tobytes() if value.dtype != object else repr(value.tolist()).encode(), crc)
    return crc


def stamp_attributes(f: h5py.File) -> None:
    """Store the CRC of ``f``'s attributes, once every other attribute is written."""
    f.attrs[ATTRS_CRC] = np.uint32(attributes_crc32(f))


#: what :func:`attributes_damage` found of each file, by its identity: a drive is opened many times in one run
#: (27 ms a check on the ci drive)
_FOUND: dict[tuple[int, int, int, int], str | None] = {}


def attributes_damage(f: h5py.File) -> str | None:
    """What is wrong with ``f``'s attributes (None: they hold their stamp, or it has none)."""
    try:
        st = os.stat(f.filename)
        key = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)
    except OSError:
        return _attributes_damage(f)
    if key not in _FOUND:
        _FOUND[key] = _attributes_damage(f)
    return _FOUND[key]


def _attributes_damage(f: h5py.File) -> str | None:
    try:
        if ATTRS_CRC not in f.attrs:
            return None
        stored, found = int(f.attrs[ATTRS_CRC]), attributes_crc32(f)
    except (OSError, ValueError, TypeError, RuntimeError) as exc:  # a header HDF5's own checksum finds damaged
        return f"its attributes cannot be read ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})"
    if stored != found:
        return "its attributes fail their checksum (a flipped byte in its georeference, grid or parameters?)"
    return None


__all__ = ["ATTRS_CRC", "attributes_crc32", "attributes_damage", "stamp_attributes"]
