"""Damage to an MDF4 file's block structure: the groups it breaks left out of a copy's chains, so that the reader
(asammdf) reads every other group's records.

A logger describes more channel groups than it records into (a CANedge file of 2023: 73, three of which hold
records; their blocks are 60 % of its one-minute file). A link that points to no block, or a block cut off in its
links or running past the file's end, is damage; a channel group is damaged where its own block is, or any block
it reaches through its channels, names, conversions and sources. Such a group is left out of its data group's
chain, and with it a group whose channel points into its bytes (variable-length data); a data group whose own
block or data block is damaged, or which keeps no channel group, is left out of the file's chain. A damaged block
that only describes (a comment, a unit, a source, an acquisition name, a sample reduction, a conversion's name) is
unlinked where a link names it, and its group kept: the reader needs none of them for a record (a link that points
past the file's end or off a block's alignment is damaged itself, and its block with it). A comment, file
history or attachment of the file's header that is damaged is unlinked. Where a group's own block is damaged, the
chain after it is lost with it: the groups after it are found again by their blocks' ids in the file's bytes
outside its data blocks (a file with one data group: its channel groups; with several: the data groups), each
read whole, of the shape its intact neighbours have and with a record id not taken, and chained in the order they
lie. The copy differs from the file only in the links of these chains (:func:`write_mended`); records that the
groups left out hold are damage in the data, which :mod:`.mdf4_blocks` reads past.
"""

from __future__ import annotations

import mmap
import shutil
import struct
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from .mdf4_layout import CG_DATA, HEAD, block

_HEADER = 64  #: the ##HD block's byte: right after the identification block
_HD_LINKS = 6  #: dg, fh, ch, at, ev, md
_DG_LINKS = 4  #: next dg, first cg, data, md
_CG_LINKS = 6  #: next cg, first cn, acquisition name, acquisition source, first sr, md
_GROUPS = (b"##DG", b"##CG")  #: blocks a group's links may reach that are groups of their own: checked, not entered
#: the links of each block that reading a record follows (MDF 4.1: a channel group's next group and first channel;
#: a channel's next channel, composition, name, conversion and data; a conversion's references from its fifth link
#: on, its texts and scales); a block not listed only describes (a source, a sample reduction, a text), none needed
_NEEDED_LINKS: dict[bytes, frozenset[int] | range] = {
    b"##CG": frozenset((0, 1)), b"##CN": frozenset((0, 1, 2, 4, 5)), b"##CC": range(4, 1 << 16),
    b"##CA": range(1 << 16), b"##DL": range(1 << 16), b"##HL": range(1 << 16)}
#: blocks whose declared length an unfinalised file leaves "to be updated": its last data block runs to the end
_OPEN_LENGTH = (b"##DT",)


@dataclass(frozen=True)
class Mend:
    """What a copy of a file with a damaged block structure changes, and why."""

    patches: tuple[tuple[int, int], ...]  #: (byte of a link, the value the copy gives it)
    reason: str  #: one clause: the groups left out and found again, naming the bytes


def mend_chains(buf: mmap.mmap) -> Mend | None:
    """The links to change so that the file's intact groups chain again without its damaged ones; None where the
    header is damaged, or no data group with a channel group is left."""
    try:
        return _mend(buf)
    except (ValueError, struct.error):  # a block read whole on the way proves damaged after all: not mended
        return None


def _mend(buf: mmap.mmap) -> Mend | None:
    """:func:`mend_chains`, raising where a block it reads is damaged in a way its checks did not see."""
    unfinished = buf[:8] == b"UnFinMF "
    ident, _, hd_links, _ = block(buf, _HEADER)
    if ident != b"##HD" or len(hd_links) < _HD_LINKS:
        return None
    patches: dict[int, int] = {}
    said: list[str] = []
    unlinked: dict[int, int] = {}  # links to damaged blocks no record needs
    for i in range(1, _HD_LINKS):  # the file's history, channel hierarchy, attachments, events, comment: unneeded
        if hd_links[i] and _reached_groups(buf, _HEADER, range(i, i + 1), unfinished, unlinked) is None:
            unlinked[_link(_HEADER, i)] = 0
    dgs, dg_break = _chain(buf, hd_links[0], b"##DG", _DG_LINKS)
    data = [_data_range(buf, dg, unfinished) for dg in dgs]
    if dg_break is not None:
        more = _found(buf, b"##DG", dgs, _DG_LINKS, [r for r in data if r is not None])
        said.append(f"the data groups' chain broken at byte {dg_break}, {len(more)} found again after it")
        dgs += more
        data += [_data_range(buf, dg, unfinished) for dg in more]
    kept_dgs: list[int] = []
    left: list[int] = []  # channel groups left out
    alone: list[int] = []  # data groups left out with the channel groups they held
    for dg, dt in zip(dgs, data, strict=True):
        _, _, dg_links, dg_data = block(buf, dg)
        if dg_links[2] and dt is None:
            said.append(f"the data group at byte {dg} left out (its data block at byte {dg_links[2]} damaged)")
            continue
        cgs, cg_break = _chain(buf, dg_links[1], b"##CG", _CG_LINKS)
        if cg_break is not None and len(dgs) == 1 and buf[dg_data]:  # one data group, its groups told by record ids
            more = _found(buf, b"##CG", cgs, _CG_LINKS, [r for r in data if r is not None])
            said.append(f"the channel groups' chain broken at byte {cg_break}, {len(more)} found again after it")
            cgs += more
        elif cg_break is not None:
            left.append(cg_break)
        kept = _whole_groups(buf, cgs, unfinished, unlinked)
        left += [cg for cg in cgs if cg not in kept]
        if not kept or (cg_break is not None and not buf[dg_data]):  # a sorted group without its channels
            alone.append(dg)
            continue
        kept_dgs.append(dg)
        _chain_to(patches, dg, 1, kept)
        if dg_links[3] and _reached_groups(buf, dg, range(3, 4), unfinished, unlinked) is None:  # its comment
            unlinked[_link(dg, 3)] = 0
    if not kept_dgs:
        return None
    _chain_to(patches, _HEADER, 0, kept_dgs)
    unlinked = {at: v for at, v in unlinked.items() if at not in patches}
    if unlinked:
        said.append(f"{_count(len(unlinked), 'link')} to damaged blocks no record needs (comments, sources, names) "
                    "unlinked")
        patches.update(unlinked)
    if left:
        at = ", ".join(str(pos) for pos in left[:3]) + (" ..." if len(left) > 3 else "")
        with_them = f" (and the {_count(len(alone), 'data group')} that held them)" if alone else ""
        whose = "its blocks damaged (at byte" if len(left) == 1 else "their blocks damaged (at bytes"
        said.insert(0, f"{_count(len(left), 'channel group')}{with_them} left out, {whose} {at})")
    patches = {at: v for at, v in patches.items() if struct.unpack_from("<Q", buf, at)[0] != v}
    if not patches:
        return None
    return Mend(tuple(sorted(patches.items())), "; ".join(said))


def _count(n: int, thing: str) -> str:
    return f"{n} {thing}{'' if n == 1 else 's'}"


def write_mended(path: Path, dest: Path, mend: tuple[tuple[int, int], ...],
                 inserted: tuple[int, int] | tuple[()] = ()) -> None:
    """Copy the MDF4 file at ``path`` to ``dest`` with ``inserted`` (byte, count: zero bytes put before that byte;
    a negative count, bytes taken out from it on) and the links ``mend`` changes (byte of the copy, value)."""
    if inserted:
        at, count = inserted
        with open(path, "rb") as src, open(dest, "wb") as out:
            out.write(src.read(at))
            out.write(bytes(max(count, 0)))
            src.seek(max(-count, 0), 1)
            shutil.copyfileobj(src, out)
    else:
        shutil.copyfile(path, dest)
    with open(dest, "r+b") as out:
        for at, value in mend:
            out.seek(at)
            out.write(struct.pack("<Q", value))


def _link(pos: int, i: int) -> int:
    """The byte of link ``i`` of the block at ``pos``."""
    return pos + HEAD.size + 8 * i


def _chain_to(patches: dict[int, int], owner: int, link: int, chain: list[int]) -> None:
    """Link ``owner``'s link ``link`` to ``chain``'s first block, and each block of it to the next (link 0)."""
    patches[_link(owner, link)] = chain[0]
    for here, after in zip(chain, [*chain[1:], 0], strict=True):
        patches[_link(here, 0)] = after


def _chain(buf: mmap.mmap, first: int, ident: bytes, n_links: int) -> tuple[list[int], int | None]:
    """The blocks of a chain of ``ident`` blocks linked by their link 0, from ``first``, as far as they are
    intact; and the byte where a damaged one broke it (None: whole)."""
    out: list[int] = []
    pos = first
    while pos and pos not in out:
        try:
            found, _, links, _ = block(buf, pos)
        except (ValueError, struct.error):
            return out, pos
        if found != ident or len(links) < n_links:
            return out, pos
        out.append(pos)
        pos = links[0]
    return out, None


def _found(buf: mmap.mmap, ident: bytes, known: list[int], n_links: int, data: list[tuple[int, int]]) -> list[int]:
    """``ident`` blocks in the file's bytes outside its data blocks ``data`` that are not ``known``, of the length
    and link count the most of ``known`` have, in the order they lie."""
    shapes = Counter((length, len(links)) for length, links in (block(buf, pos)[1:3] for pos in known))
    shape = shapes.most_common(1)[0][0] if shapes else None
    out = []
    pos = buf.find(ident)
    while pos >= 0:
        inside = next((b for a, b in data if a <= pos < b), None)
        if inside is not None:
            pos = buf.find(ident, inside)
            continue
        if pos % 8 == 0 and pos not in known:
            try:
                _, length, links, _ = block(buf, pos)
            except (ValueError, struct.error):
                length, links = 0, ()
            if len(links) >= n_links and shape in (None, (length, len(links))):
                out.append(pos)
        pos = buf.find(ident, pos + 1)
    return out


def _data_range(buf: mmap.mmap, dg: int, unfinished: bool) -> tuple[int, int] | None:
    """The bytes of data group ``dg``'s data block (an unfinalised file's last runs to the end; none: (0, 0)), or
    None where that block is damaged."""
    links = block(buf, dg)[2]
    if not links[2]:
        return 0, 0
    try:
        ident, length, _, _ = block(buf, links[2])
    except (ValueError, struct.error):
        return None
    if unfinished and ident in _OPEN_LENGTH:
        return links[2], len(buf)
    return (links[2], links[2] + length) if links[2] + length <= len(buf) else None


def _whole_groups(buf: mmap.mmap, cgs: list[int], unfinished: bool, unlinked: dict[int, int]) -> list[int]:
    """Those of ``cgs`` whose blocks are whole, each with a record id no group before it took, less those whose
    channels point into a group left out; links to damaged blocks no record needs go into ``unlinked``."""
    reached: dict[int, list[int]] = {}
    ids: set[int] = set()
    for cg in cgs:
        record_id = CG_DATA.unpack_from(buf, block(buf, cg)[3])[0]
        groups = _reached_groups(buf, cg, range(1, _CG_LINKS), unfinished, unlinked)
        if groups is not None and record_id not in ids:
            ids.add(record_id)
            reached[cg] = groups
    while True:  # a group whose variable-length data lie in a group left out has no data bytes
        out = [cg for cg, groups in reached.items() if all(g in reached for g in groups)]
        if len(out) == len(reached):
            return [cg for cg in cgs if cg in reached]
        reached = {cg: reached[cg] for cg in out}


def _reached_groups(buf: mmap.mmap, owner: int, places: range, unfinished: bool, unlinked: dict[int, int]
                    ) -> list[int] | None:
    """The channel groups the blocks reached from the links ``places`` of the block at ``owner`` point to (not
    entered), or None where a block a record needs is damaged. A damaged block reached through a link no record
    needs (:data:`_NEEDED_LINKS`) is not: that link goes into ``unlinked`` (its byte: 0)."""
    groups: list[int] = []
    todo = [(owner, k, link) for k, link in enumerate(block(buf, owner)[2]) if k in places and link]
    seen: set[int] = set()
    while todo:
        holder, k, pos = todo.pop()
        try:
            ident, length, more, _ = block(buf, pos)
            whole = pos + length <= len(buf) or (unfinished and ident in _OPEN_LENGTH)
        except (ValueError, struct.error):
            whole = False
        if not whole:
            # a link into the file at a block's alignment names a damaged block; any other value is a damaged link,
            # its own block damaged with it
            if pos < len(buf) and pos % 8 == 0 and k not in _NEEDED_LINKS.get(bytes(buf[holder:holder + 4]), ()):
                unlinked[_link(holder, k)] = 0
                continue
            return None
        if pos in seen:
            continue
        seen.add(pos)
        if ident in _GROUPS:
            groups.append(pos)
            continue
        todo += [(pos, j, link) for j, link in enumerate(more) if link]
    return groups
