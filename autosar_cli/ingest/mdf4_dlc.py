"""The DLC-to-length table of an MDF4 CAN log, checked against the CAN standard it states.

In ASAM MDF bus logging, a frame's ``DataLength`` channel (``CAN_DataFrame``, ``CAN_ErrorFrame``,
``CAN_RemoteFrame``) is its DLC, converted to a byte count by a value-to-value table (a CANedge's: DLC 0-15 to
0-8, 12, 16, 20, 24, 32, 48, 64). python-can's reader takes that many bytes of the frame's data field, so a table
with damaged values (bytes overwritten, no checksum) reads every frame of a damaged DLC with other bytes, without a
word. ISO 11898-1 fixes the table: DLC 0-8 is that many bytes; 9-15 is 8 for a classic frame and the CAN FD length
for an FD frame. A table on such a channel that says otherwise is damage; the reader's copy gets the standard's
values (the convention for 9-15 the table's intact entries show, CAN FD's where none does).
"""

from __future__ import annotations

import math
import mmap
import struct
from dataclasses import dataclass

from .mdf4_layout import Block, block

#: bytes of a frame of each DLC, CAN FD (ISO 11898-1:2015)
FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)
CLASSIC_MAX_BYTES = 8  #: a classic frame's DLC 9-15 still carries 8 bytes
_LENGTH_CHANNELS = (b"CAN_DataFrame.DataLength", b"CAN_ErrorFrame.DataLength", b"CAN_RemoteFrame.DataLength")
_CN_NAME, _CN_CONVERSION = 2, 4  #: a CN block's links to its name (##TX) and its conversion (##CC)
_TABLE_TYPES = (4, 5)  #: cc_type: value to value, with or without interpolation
_CC_FIXED = struct.Struct("<BBHHHdd")  #: type, precision, flags, ref count, value count, physical range
_MIN_ENTRIES = 9  #: a table that covers a classic frame's DLC 0-8


@dataclass(frozen=True)
class TableMend:
    """What a reader's copy changes in the damaged DLC tables, and why."""

    patches: tuple[tuple[int, int], ...]  #: (byte, the 8 bytes the copy puts there, as a little-endian integer)
    reason: str  #: one clause naming the tables' bytes


def damaged_length_tables(buf: mmap.mmap, found: list[Block]) -> TableMend | None:
    """The DLC tables of the file's ``DataLength`` channels (among the blocks ``found``) that ISO 11898-1 says are
    damaged, and the standard's values for a reader's copy; None where every such table is whole."""
    patches: list[tuple[int, int]] = []
    said: list[str] = []
    seen: set[int] = set()
    for _, ident, _, links in found:
        if ident != b"##CN" or len(links) <= _CN_CONVERSION or not links[_CN_CONVERSION]:
            continue
        cc = links[_CN_CONVERSION]
        if cc in seen or _name(buf, links[_CN_NAME]) not in _LENGTH_CHANNELS:
            continue
        seen.add(cc)
        judged = _judged_table(buf, cc)
        if judged is not None:
            patches += judged[0]
            said.append(judged[1])
    if not said:
        return None
    return TableMend(tuple(patches), "; ".join(said))


def _name(buf: mmap.mmap, tx: int) -> bytes | None:
    """The text of the ##TX block at ``tx`` (None where it is none)."""
    try:
        ident, length, _, data = block(buf, tx) if tx else (b"", 0, (), 0)
    except ValueError:
        return None
    if ident != b"##TX":
        return None
    return bytes(buf[data:min(tx + length, len(buf))]).split(b"\0", 1)[0]


def _judged_table(buf: mmap.mmap, cc: int) -> tuple[list[tuple[int, int]], str] | None:
    """(patches, clause) where the table of the ##CC block at ``cc`` breaks the standard; None where it keeps it
    or is no value-to-value table (another conversion is not judged)."""
    try:
        ident, length, _, data = block(buf, cc)
    except ValueError:
        return None  # a damaged block is the chains' mending's
    if ident != b"##CC" or data + _CC_FIXED.size > len(buf):
        return None
    kind, precision, flags, refs, count, _, _ = _CC_FIXED.unpack_from(buf, data)
    if kind not in _TABLE_TYPES:
        return None
    values_at = data + _CC_FIXED.size
    held = (cc + length - values_at) // 8  # the values the block's length holds
    pairs = held // 2
    if not _MIN_ENTRIES <= pairs <= len(FD_LENGTHS) or values_at + 16 * pairs > len(buf):
        return None  # no DLC table's shape: not judged
    table = struct.unpack_from(f"<{2 * pairs}d", buf, values_at)
    keys, lengths = table[0::2], table[1::2]
    fd = _fd_convention(keys, lengths)
    wanted = [float(v) for k in range(pairs) for v in (k, _length(k, fd))]
    patches = [(values_at + 8 * i, _bits(v)) for i, (v, was) in enumerate(zip(wanted, table, strict=True))
               if not (v == was)]  # NaN differs
    if count != 2 * pairs:
        patches.insert(0, (data, int.from_bytes(struct.pack("<BBHHH", kind, precision, flags, refs, 2 * pairs),
                                                "little")))
    if not patches:
        return None
    wrong = [k for k in range(pairs) if not (keys[k] == k and lengths[k] == _length(k, fd))]
    shown = ", ".join(f"DLC {k} read as {_shown(lengths[k])} bytes" if keys[k] == k
                      else f"its entry for DLC {k} keyed {_shown(keys[k])}" for k in wrong[:2])
    more = f" and {len(wrong) - 2} more" if len(wrong) > 2 else ""
    count_said = f"{count} values said for {2 * pairs}" if count != 2 * pairs else ""
    what = "; ".join(s for s in (f"{shown}{more}" if wrong else "", count_said) if s)
    return patches, (f"the DLC-to-length table of its DataLength channel (conversion block at byte {cc}) damaged "
                     f"({what}): read with ISO 11898-1's")


def _fd_convention(keys: tuple[float, ...], lengths: tuple[float, ...]) -> bool:
    """Whether the table's intact entries for DLC 9-15 give the CAN FD lengths (else a classic frame's 8)."""
    long_codes = [(int(k), n) for k, n in zip(keys, lengths, strict=True)
                  if math.isfinite(k) and k == int(k) and _MIN_ENTRIES <= k < len(FD_LENGTHS)]
    fd = sum(1 for k, n in long_codes if n == FD_LENGTHS[k])
    return fd >= sum(1 for _, n in long_codes if n == CLASSIC_MAX_BYTES)


def _length(dlc: int, fd: bool) -> int:
    return FD_LENGTHS[dlc] if fd or dlc <= CLASSIC_MAX_BYTES else CLASSIC_MAX_BYTES


def _bits(value: float) -> int:
    return int.from_bytes(struct.pack("<d", value), "little")


def _shown(value: float) -> str:
    return f"{value:.3g}" if math.isfinite(value) else str(value)
