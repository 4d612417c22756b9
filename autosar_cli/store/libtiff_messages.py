"""libtiff's own messages, logged rather than printed.

GDAL's GeoTIFF driver reports what libtiff says of a file it opened through its own handlers (as GDAL errors,
which rasterio raises or logs), but a write or seek its I/O layer saw fail (``_tiffWriteProc``, ``_tiffSeekProc``:
the disk full) goes to libtiff's process-wide handler, whose default prints it on stderr ("_tiffWriteProc: No space
left on device."): two or three such lines stood ahead of the command's one-line error. :func:`route_libtiff_messages`
gives that handler (and the warning handler) to the logger ``autosar_cli.libtiff`` at DEBUG level, which
``autosar --debug`` shows on stderr, in libtiff's words. The failure itself is told by the image writer, which
reads the closed GeoTIFF back (store/image.py).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import sys
from pathlib import Path

LOG = logging.getLogger("autosar_cli.libtiff")

#: libtiff's TIFFErrorHandler and TIFFWarningHandler: (module, format, va_list)
_HANDLER_TYPE = ctypes.CFUNCTYPE(None, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_void_p)
_routed: dict[str, object] = {}  # the libraries routed, and the callbacks (kept alive while libtiff holds them)


def _said(module: bytes | None, fmt: bytes | None, args: int | None) -> None:
    """libtiff's message as its default handler words it ("module: text."), logged at DEBUG level."""
    text = (fmt or b"").decode(errors="replace")
    libc = _routed.get("libc")
    if isinstance(libc, ctypes.CDLL) and fmt:
        buf = ctypes.create_string_buffer(1024)
        libc.vsnprintf(buf, len(buf), fmt, ctypes.c_void_p(args))
        text = buf.value.decode(errors="replace")
    LOG.debug("%s%s.", f"{module.decode(errors='replace')}: " if module else "", text)


def _gdals_libtiffs() -> list[str]:
    """The libtiff libraries loaded in this process beside rasterio's GDAL (Pillow's own libtiff left alone)."""
    try:
        maps = Path("/proc/self/maps").read_text().splitlines()
    except OSError:  # not Linux: rasterio's bundled libraries
        import rasterio

        root = Path(rasterio.__file__).parent
        return [str(p) for d in (root.parent / "rasterio.libs", root / ".dylibs") for p in sorted(d.glob("libtiff*"))]
    found = {line.split(maxsplit=5)[-1] for line in maps if "libtiff" in line and "/" in line}
    return sorted(p for p in found if "pillow" not in p.lower() and "/PIL/" not in p)


def route_libtiff_messages() -> int:
    """Give libtiff's process-wide error and warning handlers to :data:`LOG`, in each libtiff GDAL has loaded (once
    per library; import rasterio first). Returns how many libraries are routed."""
    if "libc" not in _routed:
        libc_name = ctypes.util.find_library("c") or ("libc.so.6" if sys.platform.startswith("linux") else None)
        libc = ctypes.CDLL(libc_name)
        libc.vsnprintf.argtypes = [ctypes.c_char_p, ctypes.c_size_t, ctypes.c_char_p, ctypes.c_void_p]
        _routed["libc"], _routed["handler"] = libc, _HANDLER_TYPE(_said)
    for path in _gdals_libtiffs():
        if path in _routed:
            continue
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for setter in (lib.TIFFSetErrorHandler, lib.TIFFSetWarningHandler):
            setter.argtypes, setter.restype = [_HANDLER_TYPE], ctypes.c_void_p
            setter(_routed["handler"])
        _routed[path] = lib
    return sum(1 for key in _routed if key not in ("libc", "handler"))
