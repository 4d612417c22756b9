"""Bytes added to or lost from an MDF4 file before its last blocks: the links past that place mended in a copy.

Every block after that place lies the same number of bytes off where the file's links (absolute byte offsets) say,
and the reader finds no block where the first of them points. The blocks themselves are intact: found by their ids in
the file's bytes, the links that point to no block, or to a block of a kind they may not name (another block moved to
where theirs lay), but lie one common shift off a block of their kind are moved by it in a copy
(:func:`write_mended`), never onto a block an intact link names (one before the place, which did not move). In an
unfinalised file, whose blocks come before its data, only where the shift moves a data group's data link onto a
data block (else the damage is a zeroed run of blocks, which :mod:`.mdf4_mend` reads past); a finalised file
(asammdf's) writes its data first and the blocks that describe them after, so no data link moves there. Every
other link past the first block moved points where its block lay too (one that found a block of its kind there,
the next of a run of channel groups, skipped the groups between): it moves with them. The block the place lies in
is torn: its id is cleared in the copy, so that its group is left out; in a finalised file it is the last block a
link names before the first moved (bytes added may hold copies of block headers, which no link names). Where that
is a finalised file's data block (its records, or their data bytes), its bytes after the place are put back where
they lay instead: the copy takes the bytes added out, or puts zeros in for those lost, at the place its records
show (the fewest damaged records, :mod:`.mdf4_sorted`'s checks), so that every block after it lies where its links
say, and the records at the place are left out. Records checked by their times alone (no data offsets) may rise
as true ones do when read off their boundaries: the search also counts those that break the bits the block's first
and last records hold alike, and a whole number of records added or lost, which leaves every record whole but the
one at the place (two records' bytes joined, which no check tells), tears the block. A count not
a multiple of 8 leaves the blocks off the 8-byte boundaries asammdf finds an unfinalised file's blocks on: the copy
puts zero bytes before the first moved block. Blocks the lost bytes held stay lost: the groups they break are then
left out as for any damaged block.
"""

from __future__ import annotations

import mmap
import re
import struct
from dataclasses import dataclass

import numpy as np

from .mdf4_layout import HEAD, PAST_ANY_FILE, FileBytes, blocks
from .mdf4_sorted import checked_by_offsets, constant_bits, odd_records, records_touching, sorted_damage

#: a block's header as it lies in the file: its id and 4 reserved zero bytes
_HEADER = re.compile(rb"##[A-Z]{2}\x00\x00\x00\x00")
#: of the links that find no block of their kind, the share one shift must bring to a block (the rest: blocks the
#: lost bytes held, or links damaged on their own)
_AGREEING = 0.5


#: what a block's links may point to, by the block's id and the link's place (MDF 4.1); a link not listed may
#: point to any block
_TARGETS: dict[bytes, tuple[frozenset[bytes], ...]] = {
    b"##HD": tuple(map(frozenset, ([b"##DG"], [b"##FH"], [b"##CH"], [b"##AT"], [b"##EV"], [b"##MD", b"##TX"]))),
    b"##DG": tuple(map(frozenset, ([b"##DG"], [b"##CG"], [b"##DT", b"##DL", b"##DZ", b"##HL", b"##RD"],
                                   [b"##MD", b"##TX"]))),
    b"##CG": tuple(map(frozenset, ([b"##CG"], [b"##CN"], [b"##TX"], [b"##SI"], [b"##SR"], [b"##MD", b"##TX"]))),
    b"##CN": tuple(map(frozenset, ([b"##CN"], [b"##CA", b"##CN"], [b"##TX"], [b"##SI"], [b"##CC"]))),
    b"##SI": tuple(map(frozenset, ([b"##TX"], [b"##TX"], [b"##MD", b"##TX"]))),
    b"##FH": tuple(map(frozenset, ([b"##FH"], [b"##MD"]))),
    b"##DL": (frozenset([b"##DL"]),),
}
#: blocks a data group's data link names
_DATA_BLOCKS = frozenset([b"##DT", b"##DL", b"##DZ", b"##HL", b"##RD"])
#: the file's header block, right after its identification block: never marked torn (the file has no other)
_HEADER_BLOCK = 64
#: the shifts whose links' kinds are checked, of those that land the most links on blocks no intact link names
_CANDIDATES = 16
#: blocks of records or their data bytes, whose bytes after the place are put back where they lay (a finalised file)
_PLAIN_DATA = frozenset([b"##DT", b"##SD"])
#: the places tried in each round of the search for where, inside a data block, bytes were added or lost
_PLACES_PER_ROUND = 64
#: bytes either side of the places a round of the search tries whose records it checks too (after the first round,
#: which checks every record)
_SEARCH_MARGIN = 4096
_ODD_RECORD_BYTES = 64  #: what a record breaking its group's alike bits weighs in the search, as damaged bytes


@dataclass(frozen=True)
class Shift:
    """Links to move where the blocks after a place in the file lie ``by`` bytes off where they point."""

    by: int  #: bytes added (> 0) or lost (< 0)
    after: int  #: the least target (the file's byte before the shift) of the links moved
    patches: tuple[tuple[int, int], ...]  #: (byte of a link, the value the copy gives it; a torn block's id: 0)
    dangling: int  #: links that found no block of their kind
    torn: int | None = None  #: the block the place lies in or after, marked damaged in the copy
    #: (byte, count): zero bytes the copy inserts before that byte, the first moved block's, so that the blocks
    #: after it lie on 8-byte boundaries again; the patches are the copy's (positions and values past it moved).
    #: A negative count: bytes the copy takes out from that byte on
    inserted: tuple[int, int] | tuple[()] = ()
    #: the data block the place lies in, whose bytes after it the copy puts back where they lay (``inserted``, no
    #: patches: every block after it then lies where its links say)
    data_block: int | None = None
    #: the copy's records (byte ranges, whole records) the place breaks, left out whether or not a check shows it
    holes: tuple[tuple[int, int], ...] = ()

    @property
    def reason(self) -> str:
        what = "added" if self.by > 0 else "lost"
        if self.data_block is not None and self.inserted:
            done = "taken out" if self.by > 0 else "put back as zeros"
            return (f"{abs(self.by)} bytes {what} inside the data block at byte {self.data_block}, found near byte "
                    f"{self.inserted[0]} by its records: {done} there, so that every block after it lies where its "
                    f"links say ({self.dangling} found no block of their kind); the records there left out "
                    f"({sum(b - a for a, b in self.holes)} bytes)")
        moved = len(self.patches) - (self.torn is not None)
        torn = f"; the block at byte {self.torn} before them torn" if self.torn is not None else ""
        return (f"{abs(self.by)} bytes {what} before byte {self.after + max(self.by, 0)}: {moved} links moved by "
                f"{self.by:+d} to the blocks they name ({self.dangling} found no block of their kind){torn}")


def block_starts(buf: mmap.mmap) -> list[int]:
    """Bytes where a block's header lies whole: its id, reserved bytes, a length and links within the file."""
    starts = []
    for found in _HEADER.finditer(buf):
        pos = found.start()
        if pos + HEAD.size > len(buf):
            continue
        _, length, n_links = HEAD.unpack_from(buf, pos)
        if length >= HEAD.size + 8 * n_links and pos + HEAD.size + 8 * n_links <= len(buf):
            starts.append(pos)
    return starts


def shifted_links(buf: mmap.mmap) -> Shift | None:
    """The shift that brings most of the links pointing to no block to one, and the links it moves; None where no
    shift brings half of them to a block, or every link points to one."""
    starts = block_starts(buf)
    known = set(starts)
    ids = {pos: bytes(buf[pos:pos + 4]) for pos in starts}
    dangling: list[tuple[int, int, int, int]] = []  # (its block, its place there, byte of the link, its value)
    links = {pos: struct.unpack_from(f"<{HEAD.unpack_from(buf, pos)[2]}Q", buf, pos + HEAD.size) for pos in starts}
    # a link points to no block, or to one of a kind it may not name (another block moved to where its own lay)
    intact = {(pos, k) for pos in starts for k, link in enumerate(links[pos])
              if link in known and _lands_right(ids, pos, k, link)}
    for pos in starts:
        for k, link in enumerate(links[pos]):
            # beyond any file: a damaged value, not a moved one
            if link and (pos, k) not in intact and link < PAST_ANY_FILE:
                dangling.append((pos, k, pos + HEAD.size + 8 * k, link))
    if not dangling:
        return None
    # every block start less every dangling link's value: the shift is the difference most of them share (each
    # link gives it one vote; a regular run of blocks gives others some)
    targets, starts_at = np.asarray([d[3] for d in dangling], np.int64), np.asarray(starts, np.int64)
    shifts, votes = np.unique(np.subtract.outer(starts_at, targets), return_counts=True)
    votes[shifts == 0] = 0
    # a block an intact link names lies where it lay: the moved blocks are named only by the links that moved with
    # them (a run of channel blocks at one spacing lands many shifts' links on blocks, and lost bytes' links on the
    # blocks before them)
    named = {links[pos][k] for pos, k in intact}
    # first by how many links land on a block no intact link names (whole arrays), then by the kinds they land on
    named_at = np.asarray(sorted(named), np.int64)
    tried = shifts[votes >= _AGREEING * votes.max()]
    rough = np.asarray([np.isin(targets + by, starts_at).sum() - 2 * np.isin(targets + by, named_at).sum()
                        for by in tried.tolist()])
    best: tuple[int, int] | None = None  # (links it lands on a block of a kind they may name, the shift)
    for by in tried[np.argsort(rough)[::-1][:_CANDIDATES]].tolist():
        score = sum(_lands_right(ids, owner, k, link + by) - 2 * (link + by in named)
                    for owner, k, _, link in dangling)
        best = max(best, (score, by)) if best is not None else (score, by)
    if best is None or best[0] <= 0:
        return None
    by = best[1]
    moved = [(at, link + by) for owner, k, at, link in dangling
             if link + by not in named and _lands_right(ids, owner, k, link + by)]
    finalised = buf[:8] != b"UnFinMF "
    # bytes added or lost before an unfinalised file's data move the data: a shift none of whose data groups' data
    # links it moves onto a data block is damage in the blocks (a zeroed run of them), which the mending reads past
    if len(moved) < max(2, _AGREEING * len(dangling)) or not finalised and not any(
            ids[owner] == b"##DG" and k == 2 and ids.get(link + by) in _DATA_BLOCKS for owner, k, _, link in dangling):
        return None
    # the place lies in the last block before the first that moved, or between the two: that block's bytes after
    # it moved, or were lost; it is marked damaged in the copy (its id cleared), so that its group is left out
    first_moved = min(value for _, value in moved)
    # every link to a block past the place points where that block lay, also one that finds another block of its
    # kind there (a run of channel groups at one spacing): it moves with the rest
    since, moving = first_moved - by, {at for at, _ in moved}
    moved += [(pos + HEAD.size + 8 * k, link + by) for pos, k in intact
              if since <= (link := links[pos][k]) and pos + HEAD.size + 8 * k not in moving
              and _lands_right(ids, pos, k, link + by)]
    torn = max((pos for pos in (named if finalised else starts) if pos < first_moved), default=None)
    if finalised and torn is not None and ids[torn] in _PLAIN_DATA:
        # a finalised file's records, or their data bytes: those after the place put back where they lay
        put = _put_back_place(buf, torn, by, first_moved)
        if put is not None:
            return Shift(by, put[0], (), len(dangling), None, (put[0], -by), torn, put[1])
    if torn is not None and torn > _HEADER_BLOCK:
        moved.append((torn, 0))
    # blocks lie on 8-byte boundaries (asammdf finds an unfinalised file's blocks by their ids there): zero bytes
    # before the first moved block put them back on theirs, and the links past it move by as many
    pad = -by % 8
    moved = [(at + pad if at >= first_moved else at, value + pad if value >= first_moved else value)
             for at, value in moved]
    return Shift(by, min(link for *_, link in dangling if link + by in known), tuple(moved), len(dangling), torn,
                 (first_moved, pad) if pad else ())


def _put_back(data: FileBytes, at: int, count: int) -> bytes:
    """``data`` with ``count`` zero bytes put in before byte ``at``, or (``count`` < 0) ``-count`` bytes from ``at``
    taken out."""
    return data[:at] + (bytes(count) + data[at:] if count >= 0 else data[at - count:])


def _put_back_place(buf: mmap.mmap, data_block: int, by: int, first_moved: int
                    ) -> tuple[int, tuple[tuple[int, int], ...]] | None:
    """The byte inside the data block at ``data_block`` (the bytes after the place moved by ``by``, the next block now
    at ``first_moved``) where taking out the bytes added (``by`` > 0), or putting in zeros for those lost, leaves the
    fewest bytes of the file's sorted records damaged (:func:`~.mdf4_sorted.sorted_damage`, its groups taken as kept
    in order), and the copy's records there (:func:`~.mdf4_sorted.records_touching`: what is left of the bytes added,
    the zeros); None where the copy's blocks do not all parse (the lost bytes held some), or where records checked by
    their times alone (no data offsets) have no alike bits to count (:func:`~.mdf4_sorted.constant_bits`) or were
    added or lost whole. Damage grows with the distance from the place: the search narrows a grid of places round
    the best one, down to single bytes, checking after the first round only the records near the places it tries;
    where places apart are as good, the records between them are those left out."""
    lo, hi = data_block + HEAD.size, first_moved - max(by, 0)
    if hi < lo:
        return None
    copy = _put_back(buf, lo, -by)
    try:
        found = list(blocks(copy))
    except (ValueError, struct.error):
        return None
    # records checked by their times alone: those read off their boundaries may rise as true ones do, but break the
    # bits the block's first and last records hold alike; a number of whole records added or lost leaves every
    # record whole, but the one at the place joins two records' bytes, which no check tells from a true one
    by_offsets = checked_by_offsets(copy, found, data_block)
    alike = [] if by_offsets else constant_bits(copy, found, data_block, buf, by)
    if not (by_offsets or alike) or any(by % g.size == 0 for g in alike):
        return None

    within: tuple[int, int] | None = None  # the whole file in the first round, then the bytes the places reach

    def damaged(at: int) -> int:
        put = _put_back(buf, at, -by)
        damage = sorted_damage(put, found, within, in_order=True)
        odd = odd_records(put, alike, within) if alike else 0
        return (0 if damage is None else sum(end - start for start, end in damage[1])) + odd * _ODD_RECORD_BYTES

    while True:
        step = max(1, (hi - lo) // _PLACES_PER_ROUND)
        places = range(lo, hi + 1, step)
        damage = [damaged(at) for at in places]
        ties = [at for at, d in zip(places, damage, strict=True) if d == min(damage)]
        if step == 1 or ties[-1] - ties[0] > step:
            # places apart as good (bytes lost or added a whole number of equal records or data bytes long: those
            # between the place tried and the true one are read off by whole ones, which no check sees): the
            # place may lie anywhere between them, and every record there is left out
            first, last = max(lo, ties[0] - (step > 1) * step), min(hi, ties[-1] + (step > 1) * step)
            return ties[0], records_touching(_put_back(buf, ties[0], -by), found, first, last - min(by, 0))
        lo, hi = max(lo, ties[0] - step), min(hi, ties[0] + step)
        # the records whose place the next round's places can change, and more: those farther lie as they do
        within = (lo - _SEARCH_MARGIN, hi + max(-by, 0) + _SEARCH_MARGIN)


def _lands_right(ids: dict[int, bytes], owner: int, k: int, target: int) -> bool:
    """Whether link ``k`` of the block at ``owner``, pointing to ``target``, finds a block of a kind it may name."""
    found = ids.get(target)
    if found is None:
        return False
    kinds = _TARGETS.get(ids[owner], ())
    return k >= len(kinds) or found in kinds[k]
