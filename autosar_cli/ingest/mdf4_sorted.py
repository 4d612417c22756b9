"""Damaged records in a finalised MDF4 file's sorted groups, which asammdf reads until they break it.

A finalised file (``MDF     ``, as asammdf, a CAN logger's converter or a measurement tool writes one) keeps each
channel group in its own data group: its ``##DT`` block holds the group's fixed-size records one after another,
and a variable-length channel (a CAN frame's data bytes) holds in each record an offset into the group's ``##SD``
block, where a 4-byte length and that many bytes stand. No byte of a fixed record can be told damaged by itself,
but an offset can: one that points to no whole length and bytes inside the SD block, and, where the SD block holds
its records' data in their order (what every writer does: checked on the group's own records), one that does
not begin where the record before it ends nor end where the next begins, or a length that does not end where the
next record's data begin. asammdf reads such a group in blocks of 1000 records until the damage breaks it (a
SystemError, an array-shape mismatch, or an allocation of terabytes for a length read from damaged bytes): the
records before that block and every one after it were lost. Here each damaged record is a hole (its bytes), and
the reader reads a copy whose data block holds the others (:func:`write_sorted_without`).
"""

from __future__ import annotations

import bisect
import struct
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .mdf4_layout import (
    CG_DATA,
    HEAD,
    MASTER_CHANNEL,
    MAX_VLSD_BYTES,
    ORDERED_TYPES,
    VLSD_CHANNEL,
    VLSD_GROUP,
    Block,
    Field,
    FileBytes,
    block,
    channels,
    data_blocks,
    fields_at,
)

#: the share of a group's records whose data follow on from the record before's, from which its SD block is taken as
#: written in their order (every writer's: near 1; a writer that shares or shuffles data: near 0)
_IN_ORDER = 0.5
#: a time out of order is damaged where it lies beyond its in-order neighbours' by more than this many of the group's
#: median steps (a writer may stamp a frame a step or two early; a time base that starts at 0 puts a zeroed stamp
#: only as many steps below its neighbours as records came before them)
_STEP_SLACK = 10
#: a group's first and last records whose alike bits a record read off its boundaries breaks (:func:`constant_bits`)
_CONSTANT_ROWS = 256


def _sorted_groups(buf: FileBytes, found: list[Block]) -> list[tuple[int, int, int, int, int]]:
    """(CG block's data byte, its first channel, DT block, first record's byte, record bytes) of each sorted group
    with a plain ``##DT`` block: one group, no record id, fixed-size records."""
    out = []
    for dg, dt in data_blocks(found):
        _, _, dg_links, dg_data = block(buf, dg)
        if buf[dg_data] != 0 or not dg_links[1]:
            continue
        _, _, cg_links, cg_data = block(buf, dg_links[1])
        _, _, flags, _, data_bytes, inval_bytes = CG_DATA.unpack_from(buf, cg_data)
        ident, _, _, records = block(buf, dt)
        if cg_links[0] or flags & VLSD_GROUP or ident != b"##DT" or data_bytes + inval_bytes == 0:
            continue
        out.append((cg_data, cg_links[1], dt, records, data_bytes + inval_bytes))
    return out


def sorted_damage(buf: FileBytes, found: list[Block], within: tuple[int, int] | None = None, in_order: bool = False
                  ) -> tuple[str, tuple[tuple[int, int], ...]] | None:
    """Why and where (byte ranges of whole records) the sorted groups of the finalised file ``buf`` (its blocks
    ``found``) hold damaged records; None where none do. ``within`` (bytes start to end): only the records that lie
    there, or whose data bytes in an SD block do, are checked (each check then among them alone). ``in_order``: the
    groups' times and data bytes are taken as kept in order however many records fall out of it (a copy whose
    records may be read off their boundaries; else a group mostly out of order is taken as written so)."""
    holes: list[tuple[int, int]] = []
    said: list[str] = []
    for cg_data, cn, dt, records, size in _sorted_groups(buf, found):
        _, cycles, *_ = CG_DATA.unpack_from(buf, cg_data)
        _, length, _, _ = block(buf, dt)
        n = min(cycles, (length - HEAD.size) // size)
        if n != cycles and within is None:  # the records it claims beyond its block: a hole where no record is
            said.append(f"the group of the data block at byte {dt} says it has {cycles} records, the block holds "
                        f"{n}")
            holes.append((records + n * size, records + cycles * size))
        first, stop = (0, n) if within is None else _rows_within(buf, cn, records, size, n, within)
        if stop <= first:
            continue
        records += first * size
        n = stop - first
        rows = np.frombuffer(buf, np.uint8, n * size, records).reshape(n, size)
        bad = np.zeros(n, dtype=bool)
        for kind, data_type, place, _ in channels(buf, cn):
            if kind == MASTER_CHANNEL and data_type in ORDERED_TYPES and place is not None:
                bad |= out_of_order(_column(rows, place, is_float=data_type != 0), in_order)
        for place, sd_block in _sd_channels(buf, cn):
            bad |= ~_whole_data(rows, place, _sd_bytes(buf, sd_block), in_order)
        if bad.any():
            broken, bad = bad, _with_neighbours(bad)
            said.append(f"{int(broken.sum())} of the {n} records of the data block at byte {dt} are damaged (a data "
                        f"offset to no whole data bytes, or a time out of order; the first at byte "
                        f"{records + int(np.argmax(broken)) * size}): those and the records either side of them left "
                        f"out ({int(bad.sum())})")
            holes += _runs(bad, records, size)
    return ("; ".join(said), tuple(holes)) if said else None


def checked_by_offsets(buf: FileBytes, found: list[Block], data_block: int) -> bool:
    """Whether every sorted group of the finalised file ``buf`` whose records, or whose data bytes, the block at
    ``data_block`` holds keeps its data bytes in an SD block: each record's offset into it tells a record read off
    its boundaries (a time alone does not: one read off them may rise as well as a true one)."""
    groups = []
    for _, cn, dt, _, _ in _sorted_groups(buf, found):
        sds = [sd_block for _, sd_block in _sd_channels(buf, cn)]
        if dt == data_block or data_block in sds:
            groups.append(bool(sds))
    return bool(groups) and all(groups)


def _sd_channels(buf: FileBytes, cn: int) -> list[tuple[Field, int]]:
    """(the offset's field in a record, the SD block) of each channel, from the one at ``cn`` on, whose records hold
    an offset into an ``##SD`` block (not a list of them, nor a VLSD group: what these checks do not read)."""
    return [(place, link) for kind, _, place, link in channels(buf, cn)
            if kind == VLSD_CHANNEL and place is not None and link and block(buf, link)[0] == b"##SD"]


def _sd_bytes(buf: FileBytes, sd_block: int) -> NDArray[np.uint8]:
    """The data of the ``##SD`` block at ``sd_block``: each record's 4-byte length and that many bytes."""
    _, length, _, data = block(buf, sd_block)
    return np.frombuffer(buf, np.uint8, length - HEAD.size, data)


def _with_neighbours(broken: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """(N,) the records ``broken`` marks and those either side of each: the damaged bytes may reach into them."""
    bad = broken.copy()
    bad[:-1] |= broken[1:]
    bad[1:] |= broken[:-1]
    return bad


def _rows_within(buf: FileBytes, cn: int, records: int, size: int, n: int, within: tuple[int, int]
                 ) -> tuple[int, int]:
    """The first and past the last of a group's ``n`` records (of ``size`` bytes from byte ``records``, its first
    channel at ``cn``) that lie in bytes ``within``, or whose data bytes in an SD block begin there."""
    start, end = within
    first, stop = max(0, (start - records) // size), min(n, max(0, -((records - end) // size)))
    rows = np.frombuffer(buf, np.uint8, n * size, records).reshape(n, size)
    for place, sd_block in _sd_channels(buf, cn):
        at = block(buf, sd_block)[3] + _column(rows, place).astype(np.int64)
        there = np.flatnonzero((at >= start) & (at < end))
        if there.size:
            first, stop = (int(there[0]), int(there[-1]) + 1) if stop <= first else \
                (min(first, int(there[0])), max(stop, int(there[-1]) + 1))
    return first, stop


@dataclass(frozen=True)
class AlikeBits:
    """The bits every record of one sorted group holds alike (:func:`constant_bits`), and where its records lie."""

    cn: int  #: the group's first channel
    records: int  #: byte of its first record
    size: int  #: bytes per record
    count: int  #: records its data block holds
    mask: NDArray[np.uint8]  #: (size,) the bits alike
    value: NDArray[np.uint8]  #: (size,) their value


def constant_bits(buf: FileBytes, found: list[Block], data_block: int, rows_of: FileBytes, by: int,
                  count: int = _CONSTANT_ROWS) -> list[AlikeBits]:
    """The bits alike of each sorted group of ``buf`` (its blocks ``found``) whose records the block at
    ``data_block`` holds: the bits its first and last ``count`` records all hold alike (a writer's unused bits, a
    time's high bytes, an identifier's unused high bits). They are read in ``rows_of``, the file whose bytes after a
    place inside the block moved by ``by``: its first records lie before that place, its last ``by`` bytes on, both
    on their boundaries."""
    out = []
    for _, cn, dt, records, size in _sorted_groups(buf, found):
        n = (block(buf, dt)[1] - HEAD.size) // size
        k = min(count, n // 2)
        if dt != data_block or k < 2:
            continue
        rows = np.concatenate([np.frombuffer(rows_of, np.uint8, k * size, at).reshape(k, size)
                               for at in (records, records + (n - k) * size + by)])
        ones, zeros = np.bitwise_and.reduce(rows, axis=0), np.bitwise_or.reduce(rows, axis=0)
        mask = ~(ones ^ zeros)  # bits the same in every one
        out.append(AlikeBits(cn, records, size, n, mask, ones & mask))
    return out


def odd_records(buf: FileBytes, bits: list[AlikeBits], within: tuple[int, int] | None = None) -> int:
    """How many records of the groups ``bits`` describes, in ``buf`` (laid out as the file they were read from),
    hold another value in a bit their first and last records all hold alike: a record read off its boundaries does,
    nearly always; ``within`` as for :func:`sorted_damage`."""
    odd = 0
    for g in bits:
        first, stop = (0, g.count) if within is None else _rows_within(buf, g.cn, g.records, g.size, g.count, within)
        if stop > first:
            rows = np.frombuffer(buf, np.uint8, (stop - first) * g.size, g.records + first * g.size)
            odd += int(np.any((rows.reshape(-1, g.size) & g.mask) != g.value, axis=1).sum())
    return odd


def records_touching(buf: FileBytes, found: list[Block], start: int, end: int) -> tuple[tuple[int, int], ...]:
    """Byte ranges of the records of the finalised file ``buf``'s sorted groups (its blocks ``found``) that lie in
    bytes ``start`` to ``end``, or whose data bytes in an SD block do, with the records either side of them: the
    records a known place of damage (``start`` = ``end``: a single byte) breaks, whether or not a check shows it."""
    holes: list[tuple[int, int]] = []
    for _, cn, dt, records, size in _sorted_groups(buf, found):
        _, length, _, _ = block(buf, dt)
        n = (length - HEAD.size) // size
        at = records + np.arange(n, dtype=np.int64) * size
        bad = (at <= max(end - 1, start)) & (at + size > start)
        rows = np.frombuffer(buf, np.uint8, n * size, records).reshape(n, size)
        for place, sd_block in _sd_channels(buf, cn):
            # each record's data: a 4-byte length and that many bytes, up to where the next record's begin
            _, sd_length, _, sd_data = block(buf, sd_block)
            first = sd_data + _column(rows, place).astype(np.int64)
            last = np.r_[first[1:], sd_data + sd_length - HEAD.size] - 1
            bad |= (first <= max(end - 1, start)) & (np.maximum(last, first + 4) >= start)
        holes += _runs(_with_neighbours(bad), records, size)
    return tuple(holes)


def _whole_data(rows: NDArray[np.uint8], place: tuple[int, int], sd: NDArray[np.uint8], in_order: bool = False
                ) -> NDArray[np.bool_]:
    """(N,) whether each record's offset (``place``: its byte and bytes in the records ``rows`` (N, record bytes))
    points to a whole length and data in ``sd`` (the SD block's data), and, where the SD block holds the records'
    data in their order, begins where the record before it ends or ends where the next begins (a damaged offset),
    and ends where the next record's data begin (a damaged length); ``in_order``: the SD block taken as in order."""
    n = len(rows)
    if n == 0 or len(sd) < 4:
        return np.zeros(n, dtype=bool)
    offsets = _column(rows, place).astype(np.int64)
    inside = (offsets >= 0) & (offsets + 4 <= len(sd))
    at = np.where(inside, offsets, 0)
    lengths = np.zeros(n, np.int64)
    for k in range(4):
        lengths |= sd[at + k].astype(np.int64) << (8 * k)
    whole = inside & (lengths <= MAX_VLSD_BYTES) & (at + 4 + lengths <= len(sd))
    ends = at + 4 + lengths
    follows = np.r_[offsets[0] == 0, ends[:-1] == offsets[1:]]  # from where the one before ends
    leads = np.r_[ends[:-1] == offsets[1:], ends[-1] <= len(sd)]  # to where the next begins
    if n < 2 or not in_order and np.mean(follows & leads) < _IN_ORDER:
        return whole
    anchored = whole & (follows | leads)
    # a length is checked against the next record's offset where that offset is the file's own
    return anchored & (leads | ~np.r_[anchored[1:], True])


def out_of_order(times: NDArray[np.float64 | np.uint64], in_order: bool = False) -> NDArray[np.bool_]:
    """(N,) which records' ``times`` lie outside the longest run of them that rises (a group's records are in time
    order: a damaged time stands out of it; a run of equal times, as zeroed records have, counts once), and beyond
    the times of that run's records either side by ``_STEP_SLACK`` median steps (so equal stamps of frames logged
    together stay); none where half or more of the steps fall (a group not kept in time order), unless ``in_order``."""
    n = len(times)
    if n < 2 or not np.any(times[1:] < times[:-1]) or not in_order and np.mean(times[1:] >= times[:-1]) < _IN_ORDER:
        return np.zeros(n, dtype=bool)
    # the longest rising subsequence (patience sorting): tails[k] ends the best run of length k + 1
    tails: list[float] = []
    ends: list[int] = []
    before = np.full(n, -1)
    for i, t in enumerate(times.tolist()):
        k = bisect.bisect_left(tails, t)
        before[i] = ends[k - 1] if k else -1
        if k == len(tails):
            tails.append(t)
            ends.append(i)
        else:
            tails[k], ends[k] = t, i
    outside = np.ones(n, dtype=bool)
    i = ends[-1]
    while i >= 0:
        outside[i] = False
        i = before[i]
    # only a time far outside its in-order neighbours' (a writer may stamp a frame a step or two early)
    ordered = np.flatnonzero(~outside)
    steps = np.diff(times[ordered].astype(np.float64))
    slack = _STEP_SLACK * float(np.median(steps[steps > 0])) if np.any(steps > 0) else 0.0
    t = times.astype(np.float64)
    k = np.searchsorted(ordered, np.arange(n))
    low = np.where(k > 0, t[ordered[np.maximum(k - 1, 0)]], -np.inf)
    high = np.where(k < len(ordered), t[ordered[np.minimum(k, len(ordered) - 1)]], np.inf)
    return outside & ((t < low - slack) | (t > high + slack))


def _column(rows: NDArray[np.uint8], place: tuple[int, int], is_float: bool = False
            ) -> NDArray[np.uint64] | NDArray[np.float64]:
    """(N,) the field ``place`` (its byte and bytes) of each record in ``rows`` (N, record bytes)
    (:func:`~.mdf4_layout.fields_at`)."""
    byte, size = place
    return fields_at(rows.reshape(-1), np.arange(len(rows), dtype=np.int64) * rows.shape[1] + byte, size, is_float)


def _runs(bad: NDArray[np.bool_], start: int, size: int) -> list[tuple[int, int]]:
    """Byte ranges of the runs of ``bad`` records (each ``size`` bytes, the first at byte ``start``)."""
    edges = np.flatnonzero(np.diff(np.r_[0, bad.astype(np.int8), 0]))
    return [(start + int(a) * size, start + int(b) * size) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def write_sorted_without(buf: FileBytes, dest_bytes: bytearray, holes: tuple[tuple[int, int], ...],
                         found: list[Block]) -> None:
    """Take ``holes`` (whole records) out of the sorted groups' data blocks in ``dest_bytes`` (a copy of ``buf``):
    each group's other records moved up in its data block, the block's length and the group's record count
    lessened, the bytes freed at its end zeroed (no link points there)."""
    for cg_data, _, dt, records, size in _sorted_groups(buf, found):
        _, length, _, _ = block(buf, dt)
        _, cycles, *_ = CG_DATA.unpack_from(buf, cg_data)
        n = min(cycles, (length - HEAD.size) // size)
        mine = [(a, b) for a, b in holes if records <= a < records + n * size]
        keep = np.ones(n, dtype=bool)
        for a, b in mine:
            keep[(a - records) // size:(b - records) // size] = False
        if keep.all() and n == cycles:
            continue
        rows = np.frombuffer(buf, np.uint8, n * size, records).reshape(n, size)[keep]
        dest_bytes[records:records + n * size] = rows.tobytes() + bytes((n - len(rows)) * size)
        struct.pack_into("<Q", dest_bytes, dt + 8, HEAD.size + len(rows) * size)
        struct.pack_into("<Q", dest_bytes, cg_data + 8, len(rows))
