"""Whether each frame of an unfinalised MDF4 file reads its own data bytes: the offsets its fixed records hold into
their VLSD group's records, checked against where those records lie.

A CAN logger (the CANedge) writes each frame as its fixed record and then its data-bytes record (a VLSD group's:
a 4-byte length and that many bytes); the fixed record's offset counts the VLSD group's bytes (lengths and data)
from the file's first record, so the n-th frame's offset is where its own data-bytes record lies among them, and
no data-bytes record is read by two frames. asammdf reads each frame's data bytes at its offset: a frame lost or
written twice (its two records) moves every record after it against the offsets (a length read from inside a
record: an allocation of terabytes, every frame lost), and a damaged offset that lands on another record reads
that frame's bytes without a word. Here each frame is paired with the data-bytes record after it, and its offset
less that record's place (its step) is compared with the frame before's:

* an offset that points into data bytes a frame before it reads (a frame written twice, or its offset damaged
  back) leaves the frame out;
* a step unlike the frame before's is records lost or added where the frames after it keep the new step (the frame
  read, the copy's offsets from it on lessened to where the copy has its records), else a damaged offset (the frame
  left out);
* a fixed record with no data-bytes record before the next frame's, or a data-bytes record no frame points to, is
  left out.

What is left out is a hole in the reader's copy (:func:`~.mdf4_blocks.write_without_holes`, which lessens the
offsets after each hole to where the copy has the records). A layout that pairs its records otherwise (where over a
tenth of the frames would be found damaged) is not judged.
"""

from __future__ import annotations

import heapq
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .mdf4_layout import Field, fields_at

_JUDGED_BELOW = 10  #: a layout is judged where fewer than one frame in this many would be found damaged


@dataclass(frozen=True)
class _Frame:
    fixed: int  #: byte of its fixed record
    fixed_end: int  #: byte after it
    offset: int  #: its data offset
    data: int  #: byte of its data-bytes record
    data_end: int  #: byte after it
    place: int  #: where that record lies among its group's bytes, as the offsets count them
    segment: int  #: which run of records the walk read it in (a hole it left out lies between two)


@dataclass
class OffsetDamage:
    """What the check found: one clause each (``said``), and the byte ranges [start, end) a copy leaves out
    (``holes``; an empty one where the offsets after it are lessened to the copy's bytes)."""

    said: list[str]
    holes: list[tuple[int, int]]


def offset_damage(raw: NDArray[np.uint8], id_size: int, sizes: Mapping[int, int | None],
                  offsets: Mapping[int, tuple[int, Field]], fixed: NDArray[np.int64], vlsd: NDArray[np.int64],
                  segments: NDArray[np.int64]) -> OffsetDamage:
    """The frames among the fixed records at bytes ``fixed`` and the VLSD records at bytes ``vlsd`` (each sorted,
    every one whole) whose offsets (``offsets``: a fixed record's id -> its VLSD group's id and the offset's field)
    do not point to the data-bytes record after them. ``segments``: the bytes where the walk read on after a hole
    (the first: its first record), from which a group's places are counted afresh."""
    out = OffsetDamage([], [])
    if not len(fixed) or not len(vlsd):
        return out
    fixed_ids = _ids(raw, fixed, id_size, sizes)
    vlsd_ids = _ids(raw, vlsd, id_size, sizes)
    vlsd_bytes = fields_at(raw, vlsd + id_size, 4).astype(np.int64) + 4
    for group in sorted({v for v, _ in offsets.values()}):
        parents = [rid for rid, (v, _) in offsets.items() if v == group]
        mine = np.isin(fixed_ids, parents)
        claims, claim_ids = fixed[mine], fixed_ids[mine]
        points = np.zeros(len(claims), np.uint64)  # each fixed record's data offset
        claim_ends = claims + id_size
        for rid in parents:
            of = claim_ids == rid
            byte, size = offsets[rid][1]
            points[of] = fields_at(raw, claims[of] + id_size + byte, size)
            claim_ends[of] += sizes[rid] or 0
        ours = vlsd_ids == group
        data, data_bytes = vlsd[ours], vlsd_bytes[ours]
        segment = np.searchsorted(segments, data, "right") - 1
        before = np.cumsum(data_bytes) - data_bytes
        first = np.searchsorted(segment, segment)  # each record's segment's first record
        place = before - before[first]
        if _intact(claims, points, data, place, segment, first):
            continue
        _judge(out, claims.tolist(), claim_ends.tolist(), points.tolist(), data.tolist(),
               (data + id_size + data_bytes).tolist(), place.tolist(), segment.tolist(), id_size,
               len(claims))
    return out


def _ids(raw: NDArray[np.uint8], at: NDArray[np.int64], id_size: int, sizes: Mapping[int, int | None]
         ) -> NDArray[np.uint64]:
    return fields_at(raw, at, id_size) if id_size else np.full(len(at), next(iter(sizes)), dtype=np.uint64)


def _intact(claims: NDArray[np.int64], points: NDArray[np.uint64], data: NDArray[np.int64], place: NDArray[np.int64],
            segment: NDArray[np.int64], first: NDArray[np.int64]) -> bool:
    """Whether each fixed record is followed by its data-bytes record before the next one and points to it: by the
    places counted from the file's first record, or (after a hole) by one step through each run."""
    if len(claims) != len(data) or not (claims < data).all() or not (data[:-1] < claims[1:]).all():
        return False
    step = points - place.astype(np.uint64)  # wraps alike where an offset is damaged past 2^63
    return bool((step[segment == 0] == 0).all() and (step == step[first]).all())


def _judge(out: OffsetDamage, claims: list[int], claim_ends: list[int], points: list[int], data: list[int],
           data_ends: list[int], place: list[int], segment: list[int], id_size: int, n_claims: int) -> None:
    """The slow path, for a group whose offsets do not all agree: each frame judged against the frame before it
    read (and the frame after it, where its step differs), what is left out added to ``out``."""
    frames: list[_Frame] = []
    missing: list[tuple[int, int]] = []  # fixed records with no data-bytes record
    stray: list[tuple[int, int]] = []  # data-bytes records no frame points to
    open_: int | None = None
    for at, kind, i in heapq.merge(((c, 0, i) for i, c in enumerate(claims)), ((d, 1, i) for i, d in enumerate(data))):
        if kind == 0:
            if open_ is not None:
                missing.append((claims[open_], claim_ends[open_]))
            open_ = i
        elif open_ is None:
            stray.append((at, data_ends[i]))
        else:
            frames.append(_Frame(claims[open_], claim_ends[open_], points[open_], at, data_ends[i], place[i],
                                 segment[i]))
            open_ = None
    if open_ is not None:
        missing.append((claims[open_], claim_ends[open_]))

    twice: list[tuple[int, int | None]] = []  # (frame, the frame whose data bytes it points to)
    damaged: list[tuple[int, int]] = []  # (frame, its step against the frame before's)
    steps: list[tuple[int, int]] = []
    read: dict[int, int] = {}  # offset -> the frame read there
    step = ahead = end = 0  # the last frame read's step, the least offset the next may have, its record's end
    run = 0
    for i, f in enumerate(frames):
        mine = f.offset - f.place
        gap = f.place - end  # bytes of records left out since the last frame read
        if f.segment != run:  # after a hole the walk left out: the copy's offsets start there afresh
            run = f.segment
        elif f.offset < ahead:
            twice.append((f.fixed, read.get(f.offset)))
            continue
        elif not (mine == step or (gap and mine == step - gap)):
            after = frames[i + 1] if i + 1 < len(frames) and frames[i + 1].segment == run else None
            if after is None or after.offset - after.place != mine:
                damaged.append((f.fixed, mine - step))
                continue
            steps.append((f.fixed, mine - step))
        step, ahead, end = mine, f.offset + f.data_end - f.data - id_size, f.place + f.data_end - f.data - id_size
        read[f.offset] = f.fixed
    found = len(twice) + len(damaged) + len(steps) + len(missing) + len(stray)
    if found * _JUDGED_BELOW >= max(n_claims, 1):  # not a layout of a frame and then its data bytes
        return
    by_fixed = {f.fixed: f for f in frames}
    for at, _ in twice + damaged:
        out.holes += [(at, by_fixed[at].fixed_end), (by_fixed[at].data, by_fixed[at].data_end)]
    out.holes += [(at, at) for at, _ in steps] + missing + stray
    said: list[tuple[int, str]] = []  # (the first byte it names, a clause)
    if twice:
        at, other = twice[0]
        whose = (f"those of the frame at byte {other}" if other is not None
                 else "inside those of a frame before it")
        said.append((at, f"{_count(len(twice), 'frame')} whose data offset points to data bytes another frame "
                          f"reads left out ({_bytes([a for a, _ in twice])}; the first's point to {whose})"))
    if damaged:
        at, by = damaged[0]
        said.append((at, f"{_count(len(damaged), 'frame')} whose data offset points past or before its data-bytes "
                         f"record, the frames either side to their own (a damaged offset), left out "
                         f"({_bytes([a for a, _ in damaged])}; the first's by {by:+d} bytes)"))
    for at, by in steps:
        said.append((at, f"the frame at byte {at} and those after it point {abs(by)} bytes "
                         f"{'past' if by > 0 else 'before'} their data-bytes records ({abs(by)} bytes of data-bytes "
                         f"records {'lost' if by > 0 else 'added'} before it): read at their own"))
    if missing:
        said.append((missing[0][0], f"{_count(len(missing), 'frame')} with no data-bytes record before the next "
                                    f"frame left out ({_bytes([a for a, _ in missing])})"))
    if stray:
        said.append((stray[0][0], f"{_count(len(stray), 'data-bytes record')} no frame points to left out "
                                  f"({_bytes([a for a, _ in stray])})"))
    out.said += [clause for _, clause in sorted(said)]

def _count(n: int, what: str) -> str:
    return f"{n} {what}{'' if n == 1 else 's'}"


def _bytes(at: list[int]) -> str:
    """"byte 1" or "bytes 1, 2, 3 ...": the first three."""
    shown = ", ".join(map(str, at[:3])) + (" ..." if len(at) > 3 else "")
    return f"byte {shown}" if len(at) == 1 else f"bytes {shown}"
