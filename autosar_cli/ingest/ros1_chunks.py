"""ROS1 bag v2.0 read record by record, as ``rosbag reindex`` does: no index needed.

Used when a bag's index is missing or damaged (a truncated or killed recording, a flipped byte): the
file is scanned from the start (bag header, chunk records, the connection and message-data records
inside each decompressed chunk), so every intact chunk is kept. A chunk whose record header is damaged
is skipped by resynchronising on the next plausible chunk header; a chunk that does not decompress is
skipped whole (unless its data length alone was damaged: read by its data's own end); a record inside a chunk that
does not read is skipped to the next record found by its header, and so is the message before it whose length does
not lead to a record (:func:`_records`); a message whose length runs over a record the index places, or over a
connection record (which the index does not place), is read up to that record; a chunk cut by the
file's end keeps the messages whose bytes are all there (its data decoded as far as it goes: lz4 and bz2
decode a stream's prefix). So does the chunk a killed ``rosbag record`` left open: its header's sizes still 0
(filled in when a chunk closes), its messages after it as records of their own (uncompressed) or its
compressed stream running to the file's end; ``rosbag reindex`` drops that chunk. Each loss is reported once,
with its byte offsets in the file.
"""

from __future__ import annotations

import bisect
import bz2
import mmap
import struct
from collections.abc import Collection, Generator, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace

ROS1_MAGIC = b"#ROSBAG V2.0\n"
OP_MSG_DATA = 0x02
OP_BAG_HEADER = 0x03
OP_CHUNK = 0x05
OP_CONNECTION = 0x07
_MAX_HEADER = 1 << 20  # a record header is a few hundred bytes; anything near this is garbage
_U32 = struct.Struct("<I")
_CHUNK_OP = b"op=\x05"
_CONNECTION_OP = b"op=\x07"
Buffer = bytes | mmap.mmap  #: the whole bag (an mmap of the file, or bytes in tests)


class RecordError(ValueError):
    """A record's framing or header cannot be parsed."""


@dataclass(frozen=True, slots=True)
class Ros1Connection:
    conn_id: int
    topic: str
    msgtype: str  #: as the bag spells it ("pkg/Name")
    msgdef: str
    md5sum: str = ""  #: of the message definition, as the bag states it


@dataclass(frozen=True, slots=True)
class Ros1Message:
    conn_id: int
    t_ns: int
    data: bytes
    chunk_offset: int  #: file offset of the chunk record holding it
    offset: int = -1  #: its record's offset in the chunk's decompressed data (as the index gives it); -1: none


@dataclass
class ScanReport:
    """What the scan kept and lost (offsets are file byte offsets)."""

    chunks_read: int = 0
    lost: list[str] = field(default_factory=list)  #: one line per damaged region


def parse_fields(blob: bytes) -> dict[str, bytes]:
    """The ``name=value`` fields of a record header (or of a connection record's data)."""
    fields: dict[str, bytes] = {}
    pos, n = 0, len(blob)
    while pos < n:
        if pos + 4 > n:
            raise RecordError("header field size cut off")
        (size,) = _U32.unpack_from(blob, pos)
        pos += 4
        if pos + size > n:
            raise RecordError("header field runs past the header")
        name, sep, value = bytes(blob[pos:pos + size]).partition(b"=")
        if not sep:
            raise RecordError("header field without '='")
        fields[name.decode("ascii", "replace")] = value
        pos += size
    return fields


def parse_header(blob: bytes) -> dict[str, bytes]:
    """The fields of one record header, which must have a one-byte ``op``."""
    fields = parse_fields(blob)
    if "op" not in fields or len(fields["op"]) != 1:
        raise RecordError("record header has no op field")
    return fields


def read_record(buf: Buffer, pos: int) -> tuple[dict[str, bytes], int, int]:
    """(header fields, data start, data end) of the record at ``pos`` in ``buf``."""
    n = len(buf)
    if pos + 4 > n:
        raise RecordError("record header length cut off")
    (hlen,) = _U32.unpack_from(buf, pos)
    if hlen > _MAX_HEADER or pos + 4 + hlen + 4 > n:
        raise RecordError(f"record header of {hlen} bytes runs past the end")
    fields = parse_header(buf[pos + 4:pos + 4 + hlen])
    dpos = pos + 4 + hlen
    (dlen,) = _U32.unpack_from(buf, dpos)
    if dpos + 4 + dlen > n:
        raise RecordError(f"record data of {dlen} bytes runs past the end")
    return fields, dpos + 4, dpos + 4 + dlen


def _u32(fields: dict[str, bytes], name: str) -> int:
    v = fields.get(name)
    if v is None or len(v) != 4:
        raise RecordError(f"record header field {name!r} missing or malformed")
    return int(_U32.unpack(v)[0])


def _time_ns(fields: dict[str, bytes]) -> int:
    v = fields.get("time")
    if v is None or len(v) != 8:
        raise RecordError("message record without a valid time")
    sec, nsec = struct.unpack("<II", v)
    if nsec >= 1_000_000_000:
        raise RecordError(f"message time has {nsec} ns")
    return sec * 1_000_000_000 + nsec


def _connection(fields: dict[str, bytes], data: bytes) -> Ros1Connection:
    conn = parse_fields(bytes(data))
    topic = fields.get("topic", b"").decode("utf-8")
    return Ros1Connection(_u32(fields, "conn"), topic, conn.get("type", b"").decode("utf-8"),
                          conn.get("message_definition", b"").decode("utf-8"),
                          conn.get("md5sum", b"").decode("ascii", "replace"))


def chunk_connections(buf: Buffer, pos: int, wanted: Iterable[int] | None = None) -> dict[int, Ros1Connection]:
    """The connection records inside the chunk record at ``pos`` (a connection's first copy, written before its
    first message), by connection id, read up to the last of ``wanted`` (None: all); none where the chunk or a record
    before them does not read."""
    found: dict[int, Ros1Connection] = {}
    left = None if wanted is None else set(wanted)
    try:
        fields, dstart, dend = read_record(buf, pos)
        if fields["op"][0] != OP_CHUNK:
            return found
        data = _decompress(fields.get("compression", b"").decode("ascii", "replace"), buf[dstart:dend],
                           _u32(fields, "size"))
        at = 0
        while at < len(data):
            inner, istart, iend = read_record(data, at)
            if inner["op"][0] == OP_CONNECTION:
                c = _connection(inner, data[istart:iend])
                found.setdefault(c.conn_id, c)
                if left is not None:
                    left.discard(c.conn_id)
                    if not left:  # the records after them are messages
                        break
            at = iend
    except Exception:  # any codec or record error: the copies read so far; reading the chunk says what broke
        pass
    return found


def chunk_copies(buf: Buffer, first_chunks: Iterable[tuple[int, int]]) -> dict[int, tuple[Ros1Connection, int]]:
    """Each connection's copy in its first chunk, and that chunk's byte offset; ``first_chunks``: (connection id,
    byte offset of the first chunk holding its messages). Each chunk is decompressed once."""
    by_chunk: dict[int, list[int]] = {}
    for conn_id, pos in first_chunks:
        by_chunk.setdefault(pos, []).append(conn_id)
    found: dict[int, tuple[Ros1Connection, int]] = {}
    for pos, ids in sorted(by_chunk.items()):
        copies = chunk_connections(buf, pos, ids)
        for conn_id in ids:
            if conn_id in copies:
                found[conn_id] = (copies[conn_id], pos)
    return found


def chain_break(buf: Buffer, pos: int, offsets: Iterable[int]) -> str | None:
    """Where the records of the uncompressed chunk record at ``pos`` do not follow one another by their lengths to
    its data's end, or where one of ``offsets`` (its messages' offsets in its data, as the bag's index gives them) is
    not where a record starts; None where they do and it is (or the chunk is compressed: its codec checks its data).

    Read through its index, a message's data length is trusted: damaged, it would give a message cut short or run
    on into the next record's bytes, which nothing else checks in an uncompressed chunk. One run on to exactly the end
    of the connection record after it (which the index does not place) chains too: the connection record's bytes
    inside a record's data tell it (:func:`_connection_within`)."""
    try:
        fields, dstart, dend = read_record(buf, pos)
    except (RecordError, UnicodeDecodeError) as exc:
        return f"its record does not read ({exc})"
    if fields.get("compression", b"") != b"none":
        return None
    starts, at = set(), dstart
    while at < dend:
        if at + 4 > dend:
            return f"a record at byte {at} is cut by its data's end"
        (hlen,) = _U32.unpack_from(buf, at)
        if at + 8 + hlen > dend:
            return f"the record at byte {at} has a header length ({hlen}) running past its data's end"
        (dlen,) = _U32.unpack_from(buf, at + 4 + hlen)
        if at + 8 + hlen + dlen > dend:
            return f"the record at byte {at} has a data length ({dlen}) running past its data's end"
        inside = _connection_within(buf, at + 8 + hlen, at + 8 + hlen + dlen, {})
        if inside is not None:
            return (f"the record at byte {at} has a data length ({dlen}) running over a connection record, at byte "
                    f"{inside}")
        starts.add(at - dstart)
        at += 8 + hlen + dlen
    stray = sorted(set(offsets) - starts)
    if stray:
        return f"its index puts a message at byte {dstart + stray[0]}, where its records' lengths put none"
    return None


def normalise_topic(name: str) -> str:
    """Topic name as rosbags spells it (repeated and trailing slashes dropped)."""
    return f'{"/" * name.startswith("/")}{"/".join(x for x in name.split("/") if x)}'


def _decompress(compression: str, data: bytes, size: int) -> bytes:
    """A whole chunk's data, decompressed to the ``size`` its header states."""
    out, _ = _decode_stream(compression, data, None)
    if len(out) != size:
        raise RecordError(f"chunk decompresses to {len(out)} bytes, its header says {size}")
    return out


def _decode_stream(compression: str, data: bytes, size: int | None) -> tuple[bytes, int]:
    """A chunk's data decoded from the start of ``data``, which may run past its end or stop before it, as far as
    it goes (lz4 and bz2 decode a stream's prefix and stop at its end), at most ``size`` bytes (None: all of it);
    and how many bytes of ``data`` it took."""
    if compression == "none":
        out = bytes(data[:size] if size is not None else data)
        return out, len(out)
    if compression == "bz2":
        stream = bz2.BZ2Decompressor()
    elif compression == "lz4":
        import lz4.frame

        stream = lz4.frame.LZ4FrameDecompressor()
    else:
        raise RecordError(f"unknown chunk compression {compression!r}")
    out = stream.decompress(data)
    taken = len(data) - len(stream.unused_data or b"") if stream.eof else len(data)  # lz4: None when none
    return (out[:size] if size is not None else out), taken


def _chunk_stream(buf: Buffer, pos: int) -> tuple[dict[str, bytes], bytes, int] | None:
    """The chunk record at ``pos`` whose data length field does not fit the file, read by its data instead: its
    header fields, its data decoded from where it starts as far as it goes (:func:`_decode_stream`, up to its
    ``size``), and where that data ended in ``buf``; None if no chunk record starts there."""
    n = len(buf)
    try:
        (hlen,) = _U32.unpack_from(buf, pos)
        if hlen > _MAX_HEADER or pos + 4 + hlen + 4 > n:
            return None
        fields = parse_header(buf[pos + 4:pos + 4 + hlen])
        if fields["op"][0] != OP_CHUNK:
            return None
        dstart = pos + 4 + hlen + 4
        data, taken = _decode_stream(fields.get("compression", b"").decode("ascii", "replace"), buf[dstart:n],
                                     _u32(fields, "size"))
    except Exception:  # any codec or header error: nothing of it can be kept
        return None
    return fields, data, dstart + taken


def _next_chunk(buf: Buffer, start: int) -> int | None:
    """Offset of the next record after ``start`` that parses as a whole chunk record, or None."""
    at = start
    while (hit := buf.find(_CHUNK_OP, at)) >= 0:
        # the op field sits somewhere in the header: try the record starts a short header allows
        for pos in range(max(start, hit - 256), hit - 3):
            try:
                fields, _, _ = read_record(buf, pos)
            except (RecordError, UnicodeDecodeError, struct.error):
                continue
            if fields["op"][0] == OP_CHUNK and "compression" in fields and "size" in fields:
                return pos
        at = hit + 1
    return None


def scan_bag(buf: Buffer, report: ScanReport, connections: dict[int, Ros1Connection],
             index_offsets: Mapping[int, Sequence[int]] | None = None) -> Iterator[Ros1Message]:
    """Every message of every intact chunk of the bag ``buf``, in file order.

    ``connections`` is filled as connection records are met (they precede their first message).
    ``index_offsets``: chunk byte offset -> its message records' offsets in its data, ascending, where the bag's
    index gives them (a scan that follows a read through the index): a message whose data length runs over one of
    them is read up to it (:func:`_records`).
    """
    if buf[:len(ROS1_MAGIC)] != ROS1_MAGIC:
        raise RecordError("not a ROS1 bag v2.0 (bad magic)")
    pos = len(ROS1_MAGIC)
    n = len(buf)
    unclosed = _Unclosed()
    try:
        yield from _scan(buf, pos, n, report, connections, unclosed, index_offsets or {})
    finally:
        unclosed.close(report)


@dataclass
class _Unclosed:
    """An uncompressed chunk ``rosbag record`` had not closed: its messages follow its header as records of their
    own (the writer fills in the sizes when it closes the chunk)."""

    pos: int | None = None
    kept: int = 0

    def open(self, pos: int, report: ScanReport) -> None:
        self.close(report)
        self.pos = pos

    def close(self, report: ScanReport) -> None:
        if self.pos is not None:
            report.lost.append(f"chunk at byte {self.pos}: its writer never closed it (its header's sizes are 0: the "
                               f"recording stopped first); the {self.kept} whole messages after it kept")
        self.pos, self.kept = None, 0


def _scan(buf: Buffer, pos: int, n: int, report: ScanReport, connections: dict[int, Ros1Connection],
          unclosed: _Unclosed, index_offsets: Mapping[int, Sequence[int]]) -> Iterator[Ros1Message]:
    while pos < n:
        try:
            fields, dstart, dend = read_record(buf, pos)
            op = fields["op"][0]
        except (RecordError, UnicodeDecodeError) as exc:
            stream = _chunk_stream(buf, pos)
            if stream is not None and len(stream[1]) == _u32(stream[0], "size"):
                # its data length field is damaged: its data, whole, places its end; reading goes on after it
                report.lost.append(f"chunk at byte {pos}: its data length does not fit ({exc}); its data ends at "
                                   f"byte {stream[2]}: read by that")
                report.chunks_read += 1
                yield from _records(stream[1], pos, stream[2], report, connections, index_offsets.get(pos, ()))
                pos = stream[2]
                continue
            nxt = _next_chunk(buf, pos + 1)
            if stream is not None and nxt is None:  # the file's end cuts this chunk: its whole messages are kept
                kept = yield from _records(stream[1], pos, n, report, connections, cut=True)
                report.lost.append(f"bytes {pos}-{n}: a chunk the file's end cuts ({exc}); its first {kept} "
                                   f"messages kept, from {len(stream[1])} of its {_u32(stream[0], 'size')} bytes")
                return
            end = nxt if nxt is not None else n
            if nxt is None and unclosed.pos is not None:  # the record the recording was writing when it stopped
                report.lost.append(f"bytes {pos}-{n}: the open chunk's last record, cut by the file's end ({exc})")
            else:
                report.lost.append(f"bytes {pos}-{end} unreadable ({exc})")
            if nxt is None:
                return
            pos = nxt
            continue
        if op == OP_CHUNK and dend == dstart and fields.get("size") == bytes(4):
            compression = fields.get("compression", b"").decode("ascii", "replace")
            if compression == "none":
                unclosed.open(pos, report)
            else:  # a compressed stream to the file's end: what it decodes to
                yield from _unclosed_compressed(buf, pos, dstart, n, compression, report, connections)
                return
        elif op == OP_CHUNK:
            unclosed.close(report)
            dend = yield from _chunk(buf, pos, fields, dstart, dend, report, connections, index_offsets.get(pos, ()))
        elif op == OP_MSG_DATA and unclosed.pos is not None:
            try:
                conn = _u32(fields, "conn")
                if conn not in connections:
                    raise RecordError(f"message on undeclared connection {conn}")
                msg = Ros1Message(conn, _time_ns(fields), bytes(buf[dstart:dend]), unclosed.pos)
            except (RecordError, UnicodeDecodeError) as exc:
                report.lost.append(f"message record at byte {pos} unreadable ({exc})")
            else:
                unclosed.kept += 1
                yield msg
        elif op == OP_CONNECTION:
            try:
                c = _connection(fields, buf[dstart:dend])
                connections.setdefault(c.conn_id, c)
            except (RecordError, UnicodeDecodeError) as exc:
                report.lost.append(f"connection record at byte {pos} unreadable ({exc})")
        pos = dend


def _unclosed_compressed(buf: Buffer, pos: int, dstart: int, n: int, compression: str, report: ScanReport,
                         connections: dict[int, Ros1Connection]) -> Iterator[Ros1Message]:
    """The whole messages of the compressed chunk at ``pos`` whose writer never closed it: its stream runs from
    ``dstart`` to the file's end ``n``."""
    try:
        data, _ = _decode_stream(compression, buf[dstart:n], None)
    except Exception as exc:  # any codec error: nothing of it can be kept
        report.lost.append(f"bytes {pos}-{n}: a chunk its writer never closed, which does not decompress ({exc})")
        return
    kept = yield from _records(data, pos, n, report, connections, cut=True)
    report.lost.append(f"bytes {pos}-{n}: a chunk its writer never closed (its header's sizes are 0: the recording "
                       f"stopped first); its first {kept} messages kept, from {len(data)} bytes")


def _chunk(buf: Buffer, pos: int, fields: dict[str, bytes], dstart: int, dend: int, report: ScanReport,
           connections: dict[int, Ros1Connection], starts: Sequence[int]) -> Generator[Ros1Message, None, int]:
    """The messages of the chunk record at ``pos`` whose data its length field puts at ``dstart``-``dend``; returns
    where the record after it starts: where its data, decoded from its start to the size its header states, ends,
    should the length field disagree (a damaged length, or an uncompressed chunk's, which nothing else checks)."""
    compression = fields.get("compression", b"").decode("ascii", "replace")
    try:
        size = _u32(fields, "size")
        data, taken = _decode_stream(compression, buf[dstart:dend], None)
        if len(data) != size:
            raise RecordError(f"chunk decompresses to {len(data)} bytes, its header says {size}")
    except Exception as exc:  # any codec error: the chunk is lost unless its data length alone was wrong
        read = _uncompressed_read_by(buf, pos, dstart, dend) if compression == "none" else _read_by_stream(buf, pos)
        if read is None:
            report.lost.append(f"chunk at bytes {pos}-{dend} skipped: it does not decompress ({exc})")
            return dend
        if compression == "none" and read[1] == dend:
            report.lost.append(f"chunk at byte {pos}: its size field does not fit its data ({exc}); a record follows "
                               f"its data length, at byte {dend}: read by that")
        else:
            report.lost.append(f"chunk at byte {pos}: its data length does not fit its data ({exc}); its data ends "
                               f"at byte {read[1]}: read by that")
        data, dend = read
    else:
        if compression != "none" and dstart + taken != dend:  # a stream ending before its stated length
            report.lost.append(f"chunk at byte {pos}: its data length says it ends at byte {dend}, its compressed "
                               f"data ends at byte {dstart + taken}: read by that")
            dend = dstart + taken
    report.chunks_read += 1
    yield from _records(data, pos, dend, report, connections, starts)
    return dend


def _read_by_stream(buf: Buffer, pos: int) -> tuple[bytes, int] | None:
    """The compressed chunk record at ``pos`` whose data does not decompress within its data length, read by its
    stream instead: its data, decoded whole to the size its header states, and where the stream ends in ``buf``;
    None where it does not decode to that size (its data is what is damaged)."""
    stream = _chunk_stream(buf, pos)
    if stream is None or len(stream[1]) != _u32(stream[0], "size"):
        return None
    return stream[1], stream[2]


def _uncompressed_read_by(buf: Buffer, pos: int, dstart: int, dend: int) -> tuple[bytes, int] | None:
    """The uncompressed chunk record at ``pos`` whose data length (which puts its data at ``dstart``-``dend``) and
    size field disagree: two numbers alike, either of which may be the damaged one. Its data and where it ends, by
    the one a record follows (or the file's end); None where both or neither are followed by one."""
    by_size = _read_by_stream(buf, pos)
    size_holds = by_size is not None and _record_follows(buf, by_size[1])
    length_holds = dend <= len(buf) and _record_follows(buf, dend)
    if length_holds == size_holds:
        return None
    return (bytes(buf[dstart:dend]), dend) if length_holds else by_size


def _record_follows(buf: Buffer, pos: int) -> bool:
    """Whether a bag's record starts at ``pos`` (one whose header reads, with a known op), or the file ends there."""
    if pos == len(buf):
        return True
    try:
        fields, _, _ = read_record(buf, pos)
    except (RecordError, UnicodeDecodeError, struct.error):
        return False
    return fields["op"][0] in (OP_MSG_DATA, OP_BAG_HEADER, 0x04, OP_CHUNK, 0x06, OP_CONNECTION)


def _records(data: bytes, pos: int, dend: int, report: ScanReport, connections: dict[int, Ros1Connection],
             starts: Sequence[int] = (), cut: bool = False) -> Generator[Ros1Message, None, int]:
    """The messages of the decompressed ``data`` of the chunk record at bytes ``pos``-``dend``, returning how many;
    ``starts``: its message records' offsets in ``data`` as the bag's index gives them, ascending (none: no index);
    ``cut``: ``data`` is a prefix, and the record it breaks off ends it (the caller says what was kept).

    A record that does not read is skipped to the next record found by its header (:func:`_next_record`); so is the
    message before it whose data length does not lead to a record (the length itself damaged): each message is
    yielded once the record after it is found where its length says, as nothing else checks an uncompressed one.
    A message whose data length runs over a record the index places (and that reads there) is read up to that
    record: its length is what is damaged, and the record it ran over would be lost, the message read with its bytes
    (a length run on to exactly a later record's start leaves nothing else to tell). So is one whose length runs over
    a connection record (which the index does not place): to exactly its end or past it (:func:`_connection_cut`),
    or into it (the next record found is that connection record, inside the message's data)."""
    at, kept = 0, 0
    where = f"chunk at bytes {pos}-{dend}"
    pending: tuple[Ros1Message, int, int] | None = None  # (message, record start, data start), not yet yielded
    last: int | None = None  # where the data of the last record read starts (its length may be what is damaged)
    while at < len(data):
        if cut and not _whole_record(data, at):
            break
        try:
            inner, istart, iend = read_record(data, at)
        except (RecordError, UnicodeDecodeError) as exc:
            # the record after a message does not read: that message's length or this record is what is damaged
            nxt = _next_record(data, last if last is not None else at + 1, connections, cut)
            if pending is not None and nxt is not None and pending[2] <= nxt < at and _declared(data, nxt) is not None:
                # its length ran on into or past the connection record found next, inside its data (chained on to
                # the record after it): it ends where that record starts, read on from (else the message was left
                # out, or the connection record lost with the messages on its connection)
                report.lost.append(_run_over(where, pending[1], pending[0].conn_id, at - pending[2], data, nxt,
                                             nxt - pending[2], connections))
                kept += 1
                yield replace(pending[0], data=data[pending[2]:nxt])
                pending, at = None, nxt
                continue
            if pending is not None and (nxt is not None and nxt < at or not _header_like(data, at, nxt)):
                skipped_from = pending[1]
                topic = _topic(pending[0].conn_id, connections)
                why = (f"the message record at uncompressed offset {skipped_from} ({topic}) left out: its data length "
                       f"does not lead to the next record ({exc} at offset {at})")
            else:
                if pending is not None:
                    kept += 1
                    yield pending[0]
                skipped_from = at
                why = f"the record at uncompressed offset {at} unreadable ({exc})"
            pending = None
            if nxt is None:
                report.lost.append(f"{where} is corrupt after its first {kept} messages (uncompressed offset "
                                   f"{skipped_from}: {exc}); the rest of it was skipped")
                return kept
            report.lost.append(f"{where}: {why}; read on from the next record, at offset {nxt}")
            at = nxt
            continue
        if pending is not None:
            kept += 1
            yield pending[0]
            pending = None
        last = istart
        try:
            op = inner["op"][0]
            if op == OP_MSG_DATA and starts:
                iend = _index_cut(data, at, istart, iend, starts, connections, report, where)
            if op == OP_MSG_DATA:
                iend = _connection_cut(data, at, inner, istart, iend, connections, report, where)
                conn = _u32(inner, "conn")
                if conn not in connections:
                    raise RecordError(f"message on undeclared connection {conn}")
                pending = (Ros1Message(conn, _time_ns(inner), data[istart:iend], pos, at), at, istart)
            elif op == OP_CONNECTION:
                c = _connection(inner, data[istart:iend])
                connections.setdefault(c.conn_id, c)
        except (RecordError, UnicodeDecodeError) as exc:  # its framing holds: only this record is lost
            report.lost.append(f"{where}: the record at uncompressed offset {at} left out ({exc})")
        at = iend
    if pending is not None:
        kept += 1
        yield pending[0]
    return kept


def _index_cut(data: bytes, at: int, istart: int, iend: int, starts: Sequence[int],
               connections: dict[int, Ros1Connection], report: ScanReport, where: str) -> int:
    """Where the data of the message record at ``at`` (its data at ``istart``-``iend`` by its length) ends: at the
    first record the index places (``starts``) inside that data, if one reads there, else at ``iend``."""
    i = bisect.bisect_right(starts, istart)
    if i == len(starts) or starts[i] >= iend or _record_end(data, starts[i], connections) is None:
        return iend
    if _connection_within(data, istart, starts[i], connections) is not None:
        return starts[i]  # it ran over a connection record first: :func:`_connection_cut` cuts it there, and says so
    report.lost.append(f"{where}: the message record at uncompressed offset {at} has a data length ({iend - istart} "
                       f"bytes) running over the record its index places at offset {starts[i]}: read up to that "
                       f"record ({starts[i] - istart} bytes)")
    return starts[i]


def _connection_cut(data: bytes, at: int, inner: dict[str, bytes], istart: int, iend: int,
                    connections: dict[int, Ros1Connection], report: ScanReport, where: str) -> int:
    """Where the data of the message record at ``at`` (header fields ``inner``, its data at ``istart``-``iend`` by
    its length, or up to the record the index places) ends: at the first connection record inside that data from
    which records chain to ``iend`` (:func:`_connection_within`), else at ``iend``."""
    inside = _connection_within(data, istart, iend, connections)
    if inside is None:
        return iend
    conn = _U32.unpack(inner["conn"])[0] if len(inner.get("conn", b"")) == 4 else -1
    (length,) = _U32.unpack_from(data, istart - 4)  # its data length field, which the index may have cut already
    report.lost.append(_run_over(where, at, conn, length, data, inside, inside - istart, connections))
    return inside


def _run_over(where: str, at: int, conn: int, length: int, data: bytes, inside: int, kept: int,
              connections: Mapping[int, Ros1Connection]) -> str:
    """The line saying the message record at ``at`` (on connection ``conn``, ``length`` bytes of data by its length
    field) runs over the connection record at ``inside`` and is read up to it (``kept`` bytes)."""
    fields = read_record(data, inside)[0]  # it reads: the caller found a connection record there
    over = fields.get("topic", b"").decode("utf-8", "replace")  # its own: the index may not know its connection
    return (f"{where}: the message record at uncompressed offset {at} ({_topic(conn, connections)}) has a data length "
            f"({length} bytes) running over the connection record of {over} at offset {inside}: read up to it "
            f"({kept} bytes)")


def _topic(conn: int, connections: Mapping[int, Ros1Connection]) -> str:
    """The topic of connection ``conn``, or its number where it is not known."""
    c = connections.get(conn)
    return c.topic if c is not None else f"connection {conn}"


def _declared(data: Buffer, at: int) -> int | None:
    """The connection id of the connection record at ``at``, if one reads there; else None."""
    try:
        inner, istart, iend = read_record(data, at)
        if inner["op"][0] != OP_CONNECTION:
            return None
        return _connection(inner, data[istart:iend]).conn_id
    except (RecordError, UnicodeDecodeError, struct.error):
        return None


def _connection_within(data: Buffer, start: int, end: int, connections: Mapping[int, Ros1Connection]) -> int | None:
    """The first byte offset in ``start``-``end`` (a message record's data, by its length) where a connection record
    starts from which records follow one another by their lengths to exactly ``end`` (connection records, and
    messages on ``connections`` or on those declared on the way); None where none does.

    The connection record is the one after the message, which the message's length ran on over (damaged): sensor
    data does not hold a chain of records by chance. The index places message records only, not connection records
    (``rosbag record`` writes each before its connection's first message, between other messages)."""
    at = start
    while (hit := data.find(_CONNECTION_OP, at, end)) >= 0:
        for pos in range(max(start, hit - 128), hit - 7):  # the op field lies in the record header's first bytes
            if _chains_to(data, pos, end, connections):
                return pos
        at = hit + 1
    return None


def _chains_to(data: Buffer, pos: int, end: int, connections: Mapping[int, Ros1Connection]) -> bool:
    """Whether a connection record starts at ``pos`` and records follow it by their lengths to exactly ``end``."""
    declared = _declared(data, pos)
    if declared is None:
        return False
    known = {declared}
    at = pos
    while at < end:
        nxt = _record_end(data, at, connections, known)
        if nxt is None or nxt > end:
            return False
        if (d := _declared(data, at)) is not None:
            known.add(d)
        at = nxt
    return at == end


def _header_like(data: bytes, at: int, end: int | None) -> bool:
    """Whether a record header, damaged, may start at ``at``: two of a message or connection record's field names
    lie where its first fields would, before ``end`` (where the next whole record starts; None: none does)."""
    head = bytes(data[at + 4:min(at + 68, len(data) if end is None else end)])
    return sum(name in head for name in (b"conn=", b"op=", b"time=", b"topic=")) >= 2


def _record_end(data: Buffer, at: int, connections: Mapping[int, Ros1Connection],
                declared: Collection[int] = ()) -> int | None:
    """Where the record at ``at`` ends, if a whole message record on a known connection (of ``connections``, or
    ``declared`` by the connection records before it) or a connection record starts there; else None."""
    try:
        inner, istart, iend = read_record(data, at)
        op = inner["op"][0]
        if op == OP_MSG_DATA:
            conn = _u32(inner, "conn")
            if conn not in connections and conn not in declared:
                return None
            _time_ns(inner)
        elif op == OP_CONNECTION:
            _connection(inner, data[istart:iend])
        else:
            return None
    except (RecordError, UnicodeDecodeError, struct.error):
        return None
    return iend


def _next_record(data: bytes, start: int, connections: dict[int, Ros1Connection], cut: bool) -> int | None:
    """The first offset from ``start`` where a record starts whose next record also reads (or that ends the data):
    two chained records are not met by chance inside a message's data."""
    at = start
    while (hit := data.find(b"op=", at)) >= 0:
        for pos in range(max(start, hit - 128), hit - 7):  # the op field lies in the record header's first bytes
            end = _record_end(data, pos, connections)
            declared = _declared(data, pos) if end is not None else None  # the message after it may be on it
            if end is not None and (end == len(data) or _record_end(data, end, connections,
                                                                    () if declared is None else (declared,)) is not None
                                    or cut and not _whole_record(data, end)):
                return pos
        at = hit + 1
    return None


def _whole_record(data: bytes, at: int) -> bool:
    """Whether ``data`` holds the whole record at ``at`` (its two lengths and what they count)."""
    if at + 4 > len(data):
        return False
    (hlen,) = _U32.unpack_from(data, at)
    if at + 4 + hlen + 4 > len(data):
        return False
    (dlen,) = _U32.unpack_from(data, at + 4 + hlen)
    return at + 8 + hlen + dlen <= len(data)
