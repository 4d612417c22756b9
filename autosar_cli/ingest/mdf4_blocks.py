"""Whether an MDF4 file was cut: read from its block structure, which asammdf (python-can's MF4 reader) does
not check at the file's end.

A finalised file (``MDF     ``) declares every block's length, so a cut shows as a block that runs past the
file's end. An unfinalised one (``UnFinMF ``, what CAN loggers such as the CANedge write: its last data block's
length "to be updated", flag bit 2) runs its last ``##DT`` block to the file's end, so a cut shows only as a
record it breaks off: each record is its channel group's record id and then that group's fixed bytes, or,
for a VLSD group (variable-length signal data: a CAN frame's data bytes), a 4-byte length and that many bytes.
A cut that falls between two records cannot be told from a shorter recording. A record with no group's id, or a
length no logger's record has, is damage inside the file: the records before it are read from a copy that ends
there, less the last two frames (bytes damaged inside a record parse as well as any); the ones after it are not
(a frame's fixed record points into its data bytes' records by their offset, which a hole would shift). A link to
no block is damage to the file's structure. Layout: ASAM MDF 4.1/4.2.
"""

from __future__ import annotations

import mmap
import re
import struct
from collections import deque
from pathlib import Path

from .records import CutShort

_HEAD = struct.Struct("<4s4xQQ")  # block id, length, link count
_BLOCK_ID = re.compile(rb"##[A-Z]{2}")
_UNFINISHED_LAST_DT = 1 << 2  # id_unfin_flags: the last ##DT block's length is to be updated
_VLSD = 1  # cg_flags: a variable-length signal data group
_MAX_VLSD_BYTES = 1 << 16  # a logger's variable-length record (a CAN FD frame's data: 64 bytes) is far shorter
_DAMAGE_MARGIN = 2  # whole frames left out before a damaged record


def _block(buf: mmap.mmap, pos: int) -> tuple[bytes, int, tuple[int, ...], int]:
    """(id, length, links, data offset) of the block at ``pos``; ValueError where its header or links are cut."""
    if pos + _HEAD.size > len(buf):
        raise ValueError(f"block header at byte {pos} cut off")
    ident, length, n_links = _HEAD.unpack_from(buf, pos)
    if not _BLOCK_ID.fullmatch(ident):
        raise ValueError(f"no block at byte {pos}, where a link points (it reads {ident!r}): damaged there")
    data = pos + _HEAD.size + 8 * n_links
    if data > len(buf):
        raise ValueError(f"{ident.decode('latin-1')} block at byte {pos} cut off in its links")
    return ident, length, struct.unpack_from(f"<{n_links}Q", buf, pos + _HEAD.size), data


def mdf4_cut(path: Path) -> CutShort | None:
    """Why the MDF4 file at ``path`` looks cut short, or None if it does not."""
    size = path.stat().st_size
    if size < 64:
        return CutShort(f"the file ends inside its 64-byte identification block ({size} bytes)")
    with open(path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        unfinished = buf[:8] == b"UnFinMF " and struct.unpack_from("<H", buf, 60)[0] & _UNFINISHED_LAST_DT
        todo, seen = [64], set()
        data_blocks: list[tuple[int, int]] = []  # (DG block, its DT block)
        try:
            while todo:
                pos = todo.pop()
                if pos in seen:
                    continue
                seen.add(pos)
                ident, length, links, _ = _block(buf, pos)
                if pos + length > size and not (unfinished and ident == b"##DT"):
                    return CutShort(f"its {ident.decode('latin-1')} block at byte {pos} runs past the end "
                                   f"({length} bytes)")
                if ident == b"##DG" and len(links) > 2 and links[2]:
                    data_blocks.append((pos, links[2]))
                todo.extend(link for link in links if link)
            if unfinished:
                for dg, dt in data_blocks:
                    cut = _cut_record(buf, dg, dt)
                    if cut:
                        return cut
        except (ValueError, struct.error) as exc:
            return CutShort(str(exc), damaged="cut off" not in str(exc))  # a block or record the end does not cut
    return None


def _cut_record(buf: mmap.mmap, dg: int, dt: int) -> CutShort | None:
    """The record an unfinalised file's end cuts in the data block ``dt`` of data group ``dg``, if any; what can
    be read whole ends where every VLSD group has as many records as the group whose channel points to it (a
    CAN frame's fixed record without its data bytes' record is one asammdf cannot shape)."""
    _, _, dg_links, dg_data = _block(buf, dg)
    dt_ident, _, _, records = _block(buf, dt)
    if dt_ident != b"##DT":  # a list or compressed block: not what a logger leaves open
        return None
    id_size = buf[dg_data]
    sizes: dict[int, int | None] = {}  # record id -> its bytes after the id (None: VLSD, length-prefixed)
    ids: dict[int, int] = {}  # CG block -> record id
    pointers: list[tuple[int, int]] = []  # (record id, the CG block one of its channels' data link points to)
    cg = dg_links[1]
    while cg:
        _, _, cg_links, cg_data = _block(buf, cg)
        record_id, _, flags, _, data_bytes, inval_bytes = struct.unpack_from("<QQHH4xII", buf, cg_data)
        sizes[record_id] = None if flags & _VLSD else data_bytes + inval_bytes
        ids[cg] = record_id
        pointers += [(record_id, link) for link in _channel_data_links(buf, cg_links[1])]
        cg = cg_links[0]
    pairs = [(ids[link], rid) for rid, link in pointers if link in ids and sizes[ids[link]] is None]
    id_format = {0: None, 1: "<B", 2: "<H", 4: "<I", 8: "<Q"}.get(id_size)
    if id_size and id_format is None:
        raise ValueError(f"data group at byte {dg} has a record id of {id_size} bytes")
    counts = dict.fromkeys(sizes, 0)
    end, pos, whole = len(buf), records, records
    # the ends of the last whole records: damage shows only where it breaks a record's id or length, so the
    # record or two before that may hold damaged bytes that parse (a frame's data bytes are not checked)
    wholes = deque([records], maxlen=_DAMAGE_MARGIN + 1)
    while pos < end:
        start = pos
        n: int | None = None
        if id_format is None:
            record_id = next(iter(sizes))
        elif pos + id_size <= end:
            (record_id,) = struct.unpack_from(id_format, buf, pos)
            pos += id_size
            if record_id not in sizes:
                return CutShort(f"record at byte {start} has an unknown record id {record_id}: damaged there, its "
                                f"{end - wholes[0]} bytes on from byte {wholes[0]} not read", wholes[0], damaged=True)
            n = sizes[record_id]
            if n is None and pos + 4 <= end:
                (n,) = struct.unpack_from("<I", buf, pos)
                pos += 4
                if n > _MAX_VLSD_BYTES and pos + n > end:  # no cut leaves a length no record has
                    return CutShort(f"record at byte {start} says it holds {n} bytes: damaged there, its "
                                    f"{end - wholes[0]} bytes on from byte {wholes[0]} not read", wholes[0],
                                    damaged=True)
        if n is None or pos + n > end:
            there = f"{end - start} of its {pos + n - start} bytes" if n is not None else f"{end - start} bytes"
            return CutShort(f"its last record at byte {start} is cut off ({there} there)", whole)
        pos += n
        counts[record_id] += 1
        if all(counts[vlsd] == counts[parent] for vlsd, parent in pairs):
            whole = pos
            wholes.append(pos)
    return None


def _channel_data_links(buf: mmap.mmap, cn: int) -> list[int]:
    """The data links (``cn_data``) of the channels from ``cn`` on, their compositions' included."""
    out, todo, seen = [], [cn], set()
    while todo:
        pos = todo.pop()
        if not pos or pos in seen:
            continue
        seen.add(pos)
        ident, _, links, _ = _block(buf, pos)
        if ident != b"##CN":
            continue
        todo += [links[0], links[1]]  # the next channel, its composition
        if len(links) > 5 and links[5]:
            out.append(links[5])
    return out
