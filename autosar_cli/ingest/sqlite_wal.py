"""An sqlite3 file as its write-ahead log leaves it: the pages of every transaction the log committed.

rosbag2's ``resilient`` storage preset writes its ``.db3`` in WAL mode: committed transactions go to
``<file>-wal`` first and reach the file itself only at a checkpoint (every ~1000 pages, and when the writer
closes). A recording that was killed leaves its last transactions in that log, which a read-only, immutable
open of the file never sees (and a plain open would write beside the input to recover). So the log is read
here as sqlite's recovery reads it (https://www.sqlite.org/fileformat2.html#walformat): frames whose salts
match the log header's and whose cumulative checksums hold, up to the last commit frame; each page's latest
such frame replaces it in a copy of the file, in memory.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

_WAL_MAGIC = (0x377F0682, 0x377F0683)  # the checksums' words little- / big-endian
_HEADER = struct.Struct(">8I")
_FRAME = struct.Struct(">6I")


@dataclass(frozen=True)
class WalImage:
    """The file's bytes with the log's committed pages in place, and what the log held."""

    image: bytes  #: the database as of the log's last commit (legacy journal mode: it is no WAL file any more)
    frames_applied: int  #: frames up to the last commit frame
    frames_left: int  #: intact frames after it: a transaction that never committed


def _checksum(data: bytes, s0: int, s1: int, big_endian: bool) -> tuple[int, int]:
    """sqlite's WAL checksum of ``data`` (a multiple of 8 bytes) continued from ``(s0, s1)``."""
    words = struct.unpack(f"{'>' if big_endian else '<'}{len(data) // 4}I", data)
    mask = 0xFFFFFFFF
    for i in range(0, len(words), 2):
        s0 = (s0 + words[i] + s1) & mask
        s1 = (s1 + words[i + 1] + s0) & mask
    return s0, s1


def apply_wal(db: bytes, wal: bytes) -> WalImage | None:
    """``db`` (the main file's bytes) as the log ``wal`` (its ``-wal`` file's bytes) leaves it; None where the
    log holds no committed frame (empty, reset, or its header does not hold)."""
    if len(wal) < _HEADER.size:
        return None
    magic, _, page_size, _, salt0, salt1, c0, c1 = _HEADER.unpack_from(wal, 0)
    if magic not in _WAL_MAGIC or page_size < 512 or page_size & (page_size - 1):
        return None
    big = magic == _WAL_MAGIC[1]
    if _checksum(wal[:24], 0, 0, big) != (c0, c1):
        return None
    s0, s1 = c0, c1
    pending: dict[int, int] = {}
    committed: dict[int, int] = {}
    n_pages, applied, seen = 0, 0, 0
    pos = _HEADER.size
    while pos + _FRAME.size + page_size <= len(wal):
        page_no, commit_pages, f_salt0, f_salt1, f_c0, f_c1 = _FRAME.unpack_from(wal, pos)
        if (f_salt0, f_salt1) != (salt0, salt1) or page_no == 0:
            break
        s0, s1 = _checksum(wal[pos:pos + 8], s0, s1, big)
        s0, s1 = _checksum(wal[pos + _FRAME.size:pos + _FRAME.size + page_size], s0, s1, big)
        if (s0, s1) != (f_c0, f_c1):
            break
        seen += 1
        pending[page_no] = pos + _FRAME.size
        if commit_pages:
            committed.update(pending)
            pending.clear()
            n_pages, applied = commit_pages, seen
        pos += _FRAME.size + page_size
    if not applied:
        return None
    image = bytearray(db[:n_pages * page_size].ljust(n_pages * page_size, b"\0"))
    for page_no, at in committed.items():
        if page_no <= n_pages:
            image[(page_no - 1) * page_size:page_no * page_size] = wal[at:at + page_size]
    image[18:20] = b"\x01\x01"  # file format read / write versions: rollback journal, not WAL
    image[28:32] = n_pages.to_bytes(4, "big")  # its size in pages, valid for its change counter
    image[92:96] = image[24:28]
    return WalImage(bytes(image), applied, seen - applied)
