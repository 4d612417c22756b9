"""MDF4 files as bytes: their blocks, the links between them and the fields of their records (ASAM MDF 4.1/4.2),
for the checks of :mod:`.mdf4_blocks` and :mod:`.mdf4_sorted` that asammdf does not make."""

from __future__ import annotations

import mmap
import re
import struct
from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

HEAD = struct.Struct("<4s4xQQ")  #: a block's id, length and link count
_BLOCK_ID = re.compile(rb"##[A-Z]{2}")
VLSD_GROUP = 1  #: cg_flags: a variable-length signal data group
VLSD_CHANNEL = 1  #: cn_type: its record holds an offset into a VLSD group's or an SD block's bytes
MASTER_CHANNEL = 2  #: cn_type: the record's time
ORDERED_TYPES = (0, 4)  #: cn_data_type: unsigned integer, float, little-endian
MAX_VLSD_BYTES = 1 << 16  #: a logger's variable-length record (a CAN FD frame's data: 64 bytes) is far shorter
PAST_ANY_FILE = 1 << 40  #: bytes no MDF4 file reaches: a link or length beyond is damage, not a cut
CG_DATA = struct.Struct("<QQHH4xII")  #: a CG block's record id, cycle count, flags, path separator, bytes, inval bytes

#: a field of a record: (its first byte after the record id, its bytes), an unsigned little-endian integer
Field = tuple[int, int]
#: a block as :func:`blocks` finds it: (byte, id, length, links)
Block = tuple[int, bytes, int, tuple[int, ...]]
#: a file's bytes as the readers here take them: mapped, or a copy made in memory
FileBytes = mmap.mmap | bytes


def block(buf: FileBytes, pos: int) -> tuple[bytes, int, tuple[int, ...], int]:
    """(id, length, links, data offset) of the block at ``pos``; ValueError where its header or links are cut, or
    where ``pos`` lies beyond any file (a damaged link, not a cut)."""
    if pos > PAST_ANY_FILE:
        raise ValueError(f"a link points to byte {pos}, past any file: damaged there")
    if pos + HEAD.size > len(buf):
        raise ValueError(f"block header at byte {pos} cut off")
    ident, length, n_links = HEAD.unpack_from(buf, pos)
    if not _BLOCK_ID.fullmatch(ident):
        raise ValueError(f"no block at byte {pos}, where a link points (it reads {ident!r}): damaged there")
    data = pos + HEAD.size + 8 * n_links
    if data > PAST_ANY_FILE:
        raise ValueError(f"{ident.decode('latin-1')} block at byte {pos} says it has {n_links} links, more than any "
                         "file holds: damaged there")
    if data > len(buf):
        raise ValueError(f"{ident.decode('latin-1')} block at byte {pos} cut off in its links")
    return ident, length, struct.unpack_from(f"<{n_links}Q", buf, pos + HEAD.size), data


def blocks(buf: FileBytes) -> Iterator[Block]:
    """(byte, id, length, links) of every block the file's links reach from its header, as found; ValueError
    where one is cut off or a link points to no block."""
    todo, seen = [64], set()
    while todo:
        pos = todo.pop()
        if pos in seen:
            continue
        seen.add(pos)
        ident, length, links, _ = block(buf, pos)
        yield pos, ident, length, links
        todo.extend(link for link in links if link)


def data_blocks(found: list[Block]) -> list[tuple[int, int]]:
    """(DG block, its data block) of each data group among ``found`` that has data."""
    return [(pos, links[2]) for pos, ident, _, links in found if ident == b"##DG" and len(links) > 2 and links[2]]


def fields_at(raw: NDArray[np.uint8], at: NDArray[np.int64], size: int, is_float: bool = False
              ) -> NDArray[np.uint64] | NDArray[np.float64]:
    """The fields of ``size`` bytes at bytes ``at`` of ``raw``: little-endian unsigned integers (uint64), or with
    ``is_float`` floats of 4 or 8 bytes (float64)."""
    if is_float and size in (4, 8):
        return np.ascontiguousarray(raw[at[:, None] + np.arange(size)]).view(f"<f{size}").ravel().astype(np.float64)
    out = np.zeros(len(at), np.uint64)
    for k in range(size):  # little-endian, whatever the width
        out |= raw[at + k].astype(np.uint64) << np.uint64(8 * k)
    return out


def field(buf: FileBytes | bytearray, at: int, size: int) -> int:
    """The unsigned little-endian integer of ``size`` bytes at byte ``at``."""
    return int.from_bytes(buf[at:at + size], "little")


def channels(buf: FileBytes, cn: int) -> list[tuple[int, int, Field | None, int]]:
    """(channel type, data type, field where whole bytes hold its value, data link) of the channels from ``cn``
    on, their compositions' included."""
    out, todo, seen = [], [cn], set()
    while todo:
        pos = todo.pop()
        if not pos or pos in seen:
            continue
        seen.add(pos)
        ident, _, links, data = block(buf, pos)
        if ident != b"##CN":
            continue
        todo += [links[0], links[1]]  # the next channel, its composition
        kind, _, data_type, bit_offset, byte_offset, bit_count = struct.unpack_from("<BBBBII", buf, data)
        whole = bit_offset == 0 and bit_count % 8 == 0 and 0 < bit_count <= 64
        out.append((kind, data_type, (byte_offset, bit_count // 8) if whole else None,
                    links[5] if len(links) > 5 else 0))
    return out
