"""The check of a PNG quicklook autosar wrote: PNG carries its own checksums (a CRC-32 after every chunk, the
Adler-32 of its zlib stream), which :func:`verify_png` reads (``autosar info image.png --verify``)."""

from __future__ import annotations

import struct
import zlib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

SIGNATURE = b"\x89PNG\r\n\x1a\n"
_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}  #: samples per pixel of each PNG colour type


@dataclass
class PngVerification:
    """What :func:`verify_png` found."""

    path: str
    chunks: int = 0
    damaged: list[str] = field(default_factory=list)  #: "CHUNK at byte N: why", or what the pixels' stream lacks

    @property
    def intact(self) -> bool:
        return not self.damaged

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "intact": self.intact}


def verify_png(path: Path) -> PngVerification:
    """Check every chunk's CRC-32 of the PNG at ``path``, and that its pixels' zlib stream inflates whole (its
    Adler-32) to the bytes its header's size says. OSError where it cannot be read."""
    found = PngVerification(str(path))
    data = Path(path).read_bytes()
    if not data.startswith(SIGNATURE):
        found.damaged.append("no PNG signature at byte 0")
        return found
    pos, pixels, header = len(SIGNATURE), [], None
    while pos + 12 <= len(data):
        length, kind = struct.unpack_from(">I4s", data, pos)
        end = pos + 12 + length
        name = kind.decode("latin-1")
        if end > len(data):
            found.damaged.append(f"{name} chunk at byte {pos}: says {length} bytes, the file ends "
                                 f"{len(data) - pos - 12} after its header")
            return found
        found.chunks += 1
        body = data[pos + 8:pos + 8 + length]
        if zlib.crc32(kind + body) != struct.unpack_from(">I", data, end - 4)[0]:
            found.damaged.append(f"{name} chunk at byte {pos}: its CRC-32 differs")
        if kind == b"IHDR" and length >= 13:
            header = struct.unpack_from(">IIBBBBB", body)
        elif kind == b"IDAT":
            pixels.append(body)
        elif kind == b"IEND":
            break
        pos = end
    else:
        found.damaged.append(f"no IEND chunk: the file ends at byte {len(data)}")
    if header is not None and header[6] == 0:  # not interlaced: its rows one after another
        width, height, depth, colour = header[:4]
        expected = height * (1 + -(-width * _CHANNELS.get(colour, 4) * depth // 8))
        try:
            inflated = zlib.decompress(b"".join(pixels))
        except zlib.error as exc:
            found.damaged.append(f"the pixels' zlib stream: {exc}")
        else:
            if len(inflated) != expected:
                found.damaged.append(f"the pixels' stream holds {len(inflated)} bytes, its header says {expected}")
    return found
