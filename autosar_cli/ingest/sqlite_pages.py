"""Rows of a damaged sqlite3 file, read from its table-leaf pages without the b-tree above them.

A truncated or damaged rosbag2 ``.db3`` can lose the interior b-tree pages that lead to rows which are
themselves intact (sqlite allocates interior pages late, so a truncation often cuts them off). Reading
every page that parses as a table leaf (and the overflow chains of its cells) recovers those rows, the
way ``sqlite3 .recover`` does. See https://www.sqlite.org/fileformat2.html for the layout.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator

_TABLE_LEAF = 0x0D
Value = int | float | bytes | str | None


class _Bad(ValueError):
    pass


def _varint(buf: bytes, pos: int) -> tuple[int, int]:
    v = 0
    for i in range(8):
        if pos + i >= len(buf):
            raise _Bad("varint cut off")
        b = buf[pos + i]
        v = (v << 7) | (b & 0x7F)
        if b < 0x80:
            return v, pos + i + 1
    if pos + 8 >= len(buf):
        raise _Bad("varint cut off")
    return (v << 8) | buf[pos + 8], pos + 9


def _record(payload: bytes) -> list[Value]:
    hsize, pos = _varint(payload, 0)
    if hsize > len(payload):
        raise _Bad("record header runs past the record")
    types = []
    while pos < hsize:
        t, pos = _varint(payload, pos)
        types.append(t)
    out: list[Value] = []
    pos = hsize
    for t in types:
        if t == 0:
            out.append(None)
        elif 1 <= t <= 6:
            n = (1, 2, 3, 4, 6, 8)[t - 1]
            out.append(int.from_bytes(payload[pos:pos + n], "big", signed=True))
            pos += n
        elif t == 7:
            out.append(struct.unpack(">d", payload[pos:pos + 8])[0])
            pos += 8
        elif t in (8, 9):
            out.append(t - 8)
        elif t >= 12:
            n = (t - 12) // 2
            raw = payload[pos:pos + n]
            out.append(raw if t % 2 == 0 else raw.decode("utf-8", "replace"))
            pos += n
        else:
            raise _Bad(f"reserved serial type {t}")
        if pos > len(payload):
            raise _Bad("record values run past the record")
    return out


def table_leaf_rows(data: bytes) -> Iterator[tuple[int, list[Value]]]:
    """(rowid, column values) of every cell of every page of ``data`` (a whole sqlite3 file) that parses as
    a table leaf; cells whose overflow chain is broken are left out. Order: page order, then cell order."""
    if len(data) < 100:
        return
    page_size = int.from_bytes(data[16:18], "big")
    page_size = 65536 if page_size == 1 else page_size
    if page_size < 512:
        return
    usable = page_size - data[20]
    max_local = usable - 35
    min_local = (usable - 12) * 32 // 255 - 23
    npages = len(data) // page_size
    for page in range(npages):
        base = page * page_size
        head = base + (100 if page == 0 else 0)
        if data[head] != _TABLE_LEAF:
            continue
        ncells = int.from_bytes(data[head + 3:head + 5], "big")
        if ncells == 0 or head + 8 + 2 * ncells > base + page_size:
            continue
        for i in range(ncells):
            ptr = int.from_bytes(data[head + 8 + 2 * i:head + 10 + 2 * i], "big")
            try:
                yield _cell(data, base, base + ptr, page_size, usable, max_local, min_local, npages)
            except (_Bad, IndexError, struct.error):
                continue


def _cell(data: bytes, base: int, pos: int, page_size: int, usable: int, max_local: int, min_local: int,
          npages: int) -> tuple[int, list[Value]]:
    if not base < pos < base + page_size:
        raise _Bad("cell pointer outside its page")
    size, pos = _varint(data, pos)
    rowid, pos = _varint(data, pos)
    if size <= max_local:
        local = size
    else:
        k = min_local + (size - min_local) % (usable - 4)
        local = k if k <= max_local else min_local
    if pos + local > base + page_size:
        raise _Bad("cell runs past its page")
    parts = [data[pos:pos + local]]
    got = local
    if local < size:
        nxt = int.from_bytes(data[pos + local:pos + local + 4], "big")
        while got < size:
            if not 1 <= nxt <= npages:
                raise _Bad("overflow chain leaves the file")
            ob = (nxt - 1) * page_size
            take = min(usable - 4, size - got)
            parts.append(data[ob + 4:ob + 4 + take])
            got += take
            nxt = int.from_bytes(data[ob:ob + 4], "big")
    return rowid, _record(b"".join(parts))
