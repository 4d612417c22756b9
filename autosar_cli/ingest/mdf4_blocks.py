"""Whether an MDF4 file was cut: read from its block structure, which asammdf (python-can's MF4 reader) does
not check at the file's end.

A finalised file (``MDF     ``) declares every block's length, so a cut shows as a block that runs past the
file's end. An unfinalised one (``UnFinMF ``, what CAN loggers such as the CANedge write: its last data block's
length "to be updated", flag bit 2) runs its last ``##DT`` block to the file's end, so a cut shows only as a
record it breaks off: each record is its channel group's record id and then that group's fixed bytes, or,
for a VLSD group (variable-length signal data: a CAN frame's data bytes), a 4-byte length and that many bytes.
A cut that falls between two records cannot be told from a shorter recording. A record with no group's id, or a
length no logger's record has, is damage inside the file: the records before it are read less the last two
frames (bytes damaged inside a record parse as well as any), and the records after it from the second record
of the first run that agrees again (:func:`_resync`: a frame's fixed record points into its data bytes' records
by their offset, counted from the file's first record; times do not fall): a copy without the damaged bytes, its
offsets after them lessened by the data bytes the copy lacks (:func:`write_without_holes`), is what the reader
reads. A link to no block is damage to the file's structure. A finalised file's groups are checked against their
data bytes by :mod:`.mdf4_sorted`.
"""

from __future__ import annotations

import mmap
import struct
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .mdf4_dlc import damaged_length_tables
from .mdf4_layout import (
    CG_DATA,
    MASTER_CHANNEL,
    MAX_VLSD_BYTES,
    ORDERED_TYPES,
    PAST_ANY_FILE,
    VLSD_CHANNEL,
    VLSD_GROUP,
    Block,
    Field,
    block,
    blocks,
    channels,
    data_blocks,
    field,
    fields_at,
)
from .mdf4_mend import mend_chains
from .mdf4_offsets import offset_damage
from .mdf4_shift import shifted_links
from .mdf4_sorted import out_of_order, sorted_damage, write_sorted_without
from .records import CutShort, places_said

_UNFINISHED_LAST_DT = 1 << 2  # id_unfin_flags: the last ##DT block's length is to be updated
_DAMAGE_MARGIN = 2  # whole frames left out before a damaged record
_RESYNC_RECORDS = 16  # fixed records that agree with themselves, after damage, before they are read again
_RESYNC_SCAN_BYTES = 1 << 20  # how far past damage such records are sought
_ID_FORMATS = {0: "", 1: "<B", 2: "<H", 4: "<I", 8: "<Q"}  # a record id's bytes -> its struct format


def mdf4_cut(path: Path) -> CutShort | None:
    """Why the MDF4 file at ``path`` looks cut short, or None if it does not."""
    size = path.stat().st_size
    if size < 64:
        return CutShort(f"the file ends inside its 64-byte identification block ({size} bytes)")
    with open(path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        unfinished = buf[:8] == b"UnFinMF " and struct.unpack_from("<H", buf, 60)[0] & _UNFINISHED_LAST_DT
        found: list[Block] = []
        try:
            for pos, ident, length, links in blocks(buf):
                if pos + length > size and not (unfinished and ident == b"##DT"):
                    why = f"its {ident.decode('latin-1')} block at byte {pos} runs past the end ({length} bytes)"
                    return _mended(buf, why) if length > PAST_ANY_FILE else CutShort(why)
                found.append((pos, ident, length, links))
            tables = damaged_length_tables(buf, found)
            if tables is not None:
                return CutShort(tables.reason, damaged=True, patches=tables.patches)
            if unfinished:
                for dg, dt in data_blocks(found):
                    cut = _cut_record(buf, dg, dt, last=all(pos <= dt for pos, *_ in found))
                    if cut:
                        return cut
            else:
                damage = sorted_damage(buf, found)
                if damage:
                    return CutShort(damage[0], damaged=True, holes=damage[1])
        except (ValueError, struct.error) as exc:
            if "cut off" in str(exc):  # the end cuts a block or record
                return CutShort(str(exc))
            return _mended(buf, str(exc))
    return None


def _mended(buf: mmap.mmap, why: str) -> CutShort:
    """Damage to the file's block structure (``why``): what a copy whose links move with the blocks where bytes
    were added or lost (:mod:`.mdf4_shift`), or whose chains leave the damaged groups out (:mod:`.mdf4_mend`),
    changes, where any intact group is left."""
    shift = shifted_links(buf)
    if shift is not None:
        return CutShort(f"{why}: {shift.reason}", damaged=True, patches=shift.patches, inserted=shift.inserted,
                        holes=shift.holes)
    mend = mend_chains(buf)
    if mend is None:
        return CutShort(why, damaged=True)
    return CutShort(f"{why}: {mend.reason}", damaged=True, patches=mend.patches)


@dataclass(frozen=True)
class _Records:
    """How the records of one data group's ``##DT`` block are laid out."""

    start: int  #: byte of the first record
    id_size: int  #: bytes of each record's id (0: one group, no id)
    sizes: dict[int, int | None]  #: record id -> its bytes after the id (None: VLSD, length-prefixed)
    pairs: list[tuple[int, int]]  #: (a VLSD group's record id, the group's whose channel points into it)
    #: record id -> (the VLSD record id its channel points into, that offset's field)
    offsets: dict[int, tuple[int, Field]]
    #: record id -> its time (master channel) where stored whole bytes of an unsigned integer or a float (whose
    #: bytes order as their value does where it is not negative)
    times: dict[int, Field]
    float_times: frozenset[int]  #: the record ids among ``times``' whose time is a float
    last: bool  #: no block lies after the records: a hole cut out of them moves no link


def _records_of(buf: mmap.mmap, dg: int, dt: int, last: bool) -> _Records | None:
    """The layout of data group ``dg``'s records in ``dt`` (``last``: no block lies after it); None where ``dt`` is
    no plain ``##DT`` block."""
    _, _, dg_links, dg_data = block(buf, dg)
    dt_ident, _, _, records = block(buf, dt)
    if dt_ident != b"##DT":  # a list or compressed block: not what a logger leaves open
        return None
    id_size = buf[dg_data]
    if id_size not in _ID_FORMATS:
        raise ValueError(f"data group at byte {dg} has a record id of {id_size} bytes")
    sizes: dict[int, int | None] = {}
    ids: dict[int, int] = {}  # CG block -> record id
    pointers: list[tuple[int, int, Field | None]] = []  # (record id, the CG block a channel points into, its field)
    times: dict[int, Field] = {}
    float_times: set[int] = set()
    cg = dg_links[1]
    while cg:
        _, _, cg_links, cg_data = block(buf, cg)
        record_id, _, flags, _, data_bytes, inval_bytes = CG_DATA.unpack_from(buf, cg_data)
        sizes[record_id] = None if flags & VLSD_GROUP else data_bytes + inval_bytes
        ids[cg] = record_id
        for kind, data_type, place, link in channels(buf, cg_links[1]):
            if link:
                pointers.append((record_id, link, place if kind == VLSD_CHANNEL else None))
            elif kind == MASTER_CHANNEL and data_type in ORDERED_TYPES and place is not None:
                times[record_id] = place
                if data_type:
                    float_times.add(record_id)
        cg = cg_links[0]
    vlsd = [(ids[link], rid, field) for rid, link, field in pointers if link in ids and sizes[ids[link]] is None]
    return _Records(records, id_size, sizes, [(v, rid) for v, rid, _ in vlsd],
                    {rid: (v, field) for v, rid, field in vlsd if field is not None}, times, frozenset(float_times),
                    last)


def _next_record(buf: mmap.mmap, pos: int, end: int, rec: _Records) -> tuple[int, int, int] | str:
    """(record id, byte after its id, byte after it) of the record at ``pos``, or why none is there: "id" (no
    group's), "length" (a VLSD length no logger's record has), "cut" (the end breaks it off)."""
    if not rec.id_size:
        record_id, body = next(iter(rec.sizes)), pos
    elif pos + rec.id_size > end:
        return "cut"
    else:
        (record_id,) = struct.unpack_from(_ID_FORMATS[rec.id_size], buf, pos)
        body = pos + rec.id_size
        if record_id not in rec.sizes:
            return "id"
    n = rec.sizes[record_id]
    if n is None:
        if body + 4 > end:
            return "cut"
        (n,) = struct.unpack_from("<I", buf, body)
        if n > MAX_VLSD_BYTES and body + 4 + n > end:  # no cut leaves a length no record has
            return "length"
        n += 4
    return (record_id, body, body + n) if body + n <= end else "cut"


def _cut_record(buf: mmap.mmap, dg: int, dt: int, last: bool) -> CutShort | None:
    """The record an unfinalised file's end cuts in the data block ``dt`` of data group ``dg``, if any, and the
    damaged bytes inside it; what can be read whole ends where every VLSD group has as many records as the group
    whose channel points to it (a CAN frame's fixed record without its data bytes' record is one asammdf cannot
    shape). After damage the records are read on from where they agree again (:func:`_resync`); where none do,
    nothing after the damage is read."""
    rec = _records_of(buf, dg, dt, last)
    if rec is None:
        return None
    end = len(buf)
    pos = start = rec.start
    # each VLSD group's offset (as the file counts its bytes) where the records read since the last hole begin
    base: dict[int, int] = {}
    counts = dict.fromkeys(rec.sizes, 0)
    holes: list[tuple[int, int]] = []
    said: list[str] = []
    fixed: list[int] = []  # where each fixed record read begins
    vlsd: list[int] = []  # where each VLSD record read begins
    segments = [pos]  # where the walk read on after each hole (the first: where it began)
    time = -1  # the time of the last record read before the last hole, as its field reads
    # the ends of the last whole records: damage shows only where it breaks a record's id or length, so the
    # record or two before that may hold damaged bytes that parse (a frame's data bytes are not checked)
    wholes = deque([pos], maxlen=_DAMAGE_MARGIN + 1)
    while pos < end:
        found = _next_record(buf, pos, end, rec)
        if found == "cut":
            said.append(f"its last record at byte {pos} is cut off ({_cut_there(buf, pos, rec)} there)")
            return _with_stamps(buf, rec, (fixed, vlsd, segments), said, holes, wholes[-1], damaged=bool(holes))
        if isinstance(found, str):
            what = ("has an unknown record id" if found == "id" else
                    f"says it holds {struct.unpack_from('<I', buf, pos + rec.id_size)[0]} bytes")
            kept_to = wholes[0]
            read, kept_time = _read_between(buf, start, kept_to, rec)
            kept = {v: base.get(v, 0) + read.get(v, 0) for v in {*base, *read}}
            again = _resync(buf, pos + 1, kept_to, kept, max(time, kept_time), rec) if rec.last else None
            if again is None:
                said.append(f"record at byte {pos} {what}: damaged there, its {end - kept_to} bytes on from byte "
                            f"{kept_to} not read")
                return _with_stamps(buf, rec, (fixed, vlsd, segments), said, holes, kept_to, damaged=True)
            said.append(f"record at byte {pos} {what}: damaged there, bytes {kept_to} to {again[0]} left out and "
                        f"the records after them read")
            pos, base, time = again
            holes.append((kept_to, pos))
            segments.append(pos)
            start = pos
            counts = dict.fromkeys(rec.sizes, 0)
            wholes = deque([pos], maxlen=_DAMAGE_MARGIN + 1)
            continue
        record_id, _, after = found
        if rec.sizes[record_id] is not None:
            fixed.append(pos)
        else:
            vlsd.append(pos)
        pos = after
        counts[record_id] += 1
        if all(counts[vlsd] == counts[parent] for vlsd, parent in rec.pairs):
            wholes.append(pos)
    return _with_stamps(buf, rec, (fixed, vlsd, segments), said, holes, None, damaged=bool(holes))


def _with_stamps(buf: mmap.mmap, rec: _Records, read: tuple[list[int], list[int], list[int]], said: list[str],
                 holes: list[tuple[int, int]], whole_bytes: int | None, damaged: bool) -> CutShort | None:
    """What the walk found (``said``, ``holes``, the bytes whole up to ``whole_bytes``); the frames whose data
    offsets do not point to their own data-bytes records (:func:`~.mdf4_offsets.offset_damage`), left out or read
    at their own; and the frames among the fixed records read whose times fall out of their group's order
    (:func:`~.mdf4_sorted.out_of_order`: a damaged stamp that parses), left out with the frames either side of
    them: a hole from the frame before each to the frame after it. ``read``: the bytes where the fixed and the
    VLSD records read begin, and where the walk began and read on after each hole. None where nothing was found."""
    fixed, vlsd, segments = read
    stop = len(buf) if whole_bytes is None else whole_bytes
    starts = _outside(np.array(fixed, dtype=np.int64), holes, stop)
    raw = np.frombuffer(buf, np.uint8)
    if rec.offsets and rec.last:  # holes are cut out of the file: no block may lie after them
        found = offset_damage(raw, rec.id_size, rec.sizes, rec.offsets, starts,
                              _outside(np.array(vlsd, dtype=np.int64), holes, stop),
                              np.array(segments, dtype=np.int64))
        if found.holes:
            said.extend(found.said)
            holes = _merged([*holes, *found.holes])
            starts = _outside(starts, holes, stop)
            damaged = True
    flagged = np.zeros(len(starts), dtype=bool)
    if len(starts) and rec.times and rec.last:
        ids = (fields_at(raw, starts, rec.id_size) if rec.id_size
               else np.full(len(starts), next(iter(rec.sizes)), dtype=np.uint64))
        for record_id, (byte, size) in rec.times.items():
            mine = np.flatnonzero(ids == record_id)
            flagged[mine] = out_of_order(fields_at(raw, starts[mine] + rec.id_size + byte, size,
                                                   record_id in rec.float_times))
    del raw  # a view of the file, which closes after this
    if flagged.any():
        bad = np.flatnonzero(flagged)
        ends = np.r_[starts[1:], stop]  # a frame: its fixed record and the data bytes after it
        said.append(f"{len(bad)} of the records read have a time out of their group's order (a damaged stamp; the "
                    f"first at byte {int(starts[bad[0]])}): their frames and those either side left out")
        holes = _merged([*holes, *((int(starts[max(i - 1, 0)]), int(ends[min(i + 1, len(starts) - 1)]))
                                   for i in bad.tolist())])
        damaged = True
    if not said:
        return None
    return CutShort(places_said(said), whole_bytes, damaged=damaged, holes=tuple(holes))


def _outside(starts: np.ndarray, holes: list[tuple[int, int]], stop: int) -> np.ndarray:
    """The records at bytes ``starts`` that begin before ``stop`` and in no hole [a, b)."""
    keep = starts < stop
    for a, b in holes:
        keep &= (starts < a) | (starts >= b)
    return starts[keep]


def _merged(ranges: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """``ranges`` [a, b) sorted, those that touch or overlap joined."""
    out: list[tuple[int, int]] = []
    for a, b in sorted(ranges):
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out


def _cut_there(buf: mmap.mmap, pos: int, rec: _Records) -> str:
    """How much of the record the file's end cuts at ``pos`` is there: "N of its M bytes" where its length can
    be read, else "N bytes"."""
    end = len(buf)
    length: int | None = None
    if pos + rec.id_size <= end:
        record_id = (struct.unpack_from(_ID_FORMATS[rec.id_size], buf, pos)[0] if rec.id_size
                     else next(iter(rec.sizes)))
        length = rec.sizes[record_id]
        if length is None and pos + rec.id_size + 4 <= end:
            length = 4 + struct.unpack_from("<I", buf, pos + rec.id_size)[0]
    return f"{end - pos} of its {rec.id_size + length} bytes" if length is not None else f"{end - pos} bytes"


def _resync(buf: mmap.mmap, after: int, kept_to: int, kept: dict[int, int], kept_time: int, rec: _Records
            ) -> tuple[int, dict[int, int], int] | None:
    """Where the records after damage found at ``after`` can be read again: the second record of the first run
    (:func:`_agreeing_run`) that goes on from what was kept up to ``kept_to``: its times from ``kept_time`` on, and
    each VLSD group's offset beyond ``kept`` (that group's offset there) by no more than the bytes left out (a
    frame's offset counts its group's bytes from the file's first record), so that records pasted from earlier in
    the file, or from elsewhere before a data offset, are not taken. Also each VLSD group's offset and the time
    there. None within ``_RESYNC_SCAN_BYTES``, or where the records have neither times nor offsets to check."""
    if not (rec.times or rec.offsets):
        return None
    for pos in range(after, min(len(buf), after + _RESYNC_SCAN_BYTES)):
        run = _agreeing_run(buf, pos, rec, kept_time)
        if run is not None and all(0 <= run[1][v] - kept.get(v, 0) <= run[0] - kept_to for v in run[1]):
            return run
    return None


def _agreeing_run(buf: mmap.mmap, pos: int, rec: _Records, not_before: int
                  ) -> tuple[int, dict[int, int], int] | None:
    """Whether the records from ``pos`` agree with themselves for ``_RESYNC_RECORDS`` fixed records (or at least
    two up to the file's end): each parses, each VLSD record follows the fixed one that points to it, at the
    offset it gives, and their times do not fall, from ``not_before`` on. The second fixed record's byte (the
    first may hold damaged bytes before its offset and time), each VLSD group's offset there and the time before
    it; None where the run breaks or has nothing to check."""
    end = len(buf)
    frames, checked, second = 0, 0, None
    expected: dict[int, int] = {}  # VLSD record id -> the offset its next record has
    pending: dict[int, int] = {}  # VLSD record id -> how many of its records the fixed ones point to ahead
    at_second: dict[int, int] = {}
    time = time_at_second = not_before
    while frames < _RESYNC_RECORDS:
        found = _next_record(buf, pos, end, rec)
        if isinstance(found, str):
            if found == "cut" and pos >= end and frames >= 2:
                break
            return None
        record_id, body, after = found
        if rec.sizes[record_id] is None:
            if not pending.get(record_id):
                return None
            pending[record_id] -= 1
            expected[record_id] += after - body
        else:
            if frames == 1:
                second, at_second, time_at_second = pos, dict(expected), time
            frames += 1
            if record_id in rec.times:
                now = field(buf, body + rec.times[record_id][0], rec.times[record_id][1])
                if now < time:
                    return None
                time, checked = now, checked + 1
            if record_id in rec.offsets:
                vlsd, (byte, size) = rec.offsets[record_id]
                offset = field(buf, body + byte, size)
                if expected.setdefault(vlsd, offset) != offset:
                    return None
                pending[vlsd] = pending.get(vlsd, 0) + 1
                checked += 1
        pos = after
    return (second, at_second, time_at_second) if second is not None and checked >= 2 else None


def _whole_records(buf: mmap.mmap, start: int, stop: int, rec: _Records) -> Iterator[tuple[int, int, int]]:
    """(record id, byte after its id, byte after it) of each whole record from ``start`` on, up to ``stop`` or the
    first that does not parse."""
    pos = start
    while pos < stop:
        found = _next_record(buf, pos, stop, rec)
        if isinstance(found, str):
            return
        yield found
        pos = found[2]


def _read_between(buf: mmap.mmap, start: int, stop: int, rec: _Records) -> tuple[dict[int, int], int]:
    """Each VLSD group's bytes (lengths and data) in the whole records from ``start`` to ``stop``, and the time of
    the last of them that has one (-1: none)."""
    out: dict[int, int] = {}
    time = -1
    for record_id, body, after in _whole_records(buf, start, stop, rec):
        if rec.sizes[record_id] is None:
            out[record_id] = out.get(record_id, 0) + after - body
        elif record_id in rec.times:
            time = field(buf, body + rec.times[record_id][0], rec.times[record_id][1])
    return out, time


def write_without_holes(path: Path, dest: Path, cut: CutShort) -> None:
    """Write to ``dest`` the MDF4 file at ``path`` without ``cut``'s holes, up to its ``whole_bytes``: each fixed
    record after a hole pointing into its VLSD group's bytes by an offset lessened by that group's bytes the copy
    lacks, so that the reader (asammdf) finds each frame's data bytes where the copy has them. Only for holes
    :func:`mdf4_cut` found (they lie in the last data block, after which no block lies); a finalised file's are
    whole records of its sorted groups (:func:`~.mdf4_sorted.write_sorted_without`)."""
    with open(path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        if buf[:8] != b"UnFinMF ":  # a finalised file's holes are records of its sorted groups
            copy = bytearray(buf)
            write_sorted_without(buf, copy, cut.holes, list(blocks(buf)))
            dest.write_bytes(copy)
            return
        rec = max((r for r in (_records_of(buf, dg, dt, True) for dg, dt in data_blocks(list(blocks(buf))))
                   if r is not None and r.start <= cut.holes[0][0]), key=lambda r: r.start)
        stop = len(buf) if cut.whole_bytes is None else cut.whole_bytes
        pieces = [(0, cut.holes[0][0])] + [(b, nxt[0] if nxt else stop)
                                           for (_, b), nxt in zip(cut.holes, [*cut.holes[1:], None], strict=True)]
        written, _ = _read_between(buf, rec.start, pieces[0][1], rec)
        with open(dest, "wb") as out:
            out.write(buf[:pieces[0][1]])
            for a, b in pieces[1:]:
                piece = bytearray(buf[a:b])
                shift: dict[int, int] = {}  # VLSD record id -> what this piece's offsets exceed the copy's by
                for record_id, body, after in _whole_records(buf, a, b, rec):
                    if rec.sizes[record_id] is None:
                        written[record_id] = written.get(record_id, 0) + after - body
                    elif record_id in rec.offsets:
                        vlsd, (byte, size) = rec.offsets[record_id]
                        at = body + byte - a
                        offset = field(piece, at, size)
                        moved = shift.setdefault(vlsd, offset - written.get(vlsd, 0))
                        piece[at:at + size] = (offset - moved).to_bytes(size, "little")
                out.write(piece)


