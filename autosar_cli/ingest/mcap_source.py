"""MCAP reader: one sequential pass, chunks decompressed on worker threads ahead of the decoder.

Works on indexed and unindexed files: records are read in file order (the summary, when there is one,
only supplies the message counts to check against). The record framing (opcode, length) and the
chunk/message headers are parsed here with :mod:`struct`; schema and channel records with the ``mcap``
library's record classes. ``mcap.stream_reader.StreamReader`` did the same job ~3x slower on a
radar-heavy log (it parses every message index entry and reads field by field), which alone took a
quarter of the ingest time budget. Damage is contained:

- a chunk that fails to decompress or whose CRC does not match is skipped with a warning naming its
  file offset, and reading goes on with the next record; a chunk whose CRC alone fails (it decompresses to its
  size) is read when asked (``keep_unverified``: ``autosar ingest --allow-unverified``), with a warning: the
  damage is somewhere in its bytes, and a CRC does not say where;
- a broken record structure (truncated file, garbage length) ends the read with a warning naming the
  offset; everything before it has been delivered;
- a chunk cut by the file's end (a copy or a disk that ran out mid-write) gives up the messages whose bytes
  are all there: its compressed data decoded as far as it goes (zstd and lz4 decode a stream's prefix), the
  records parsed up to the one the cut breaks. Its CRC cannot be checked; the warning says so.

Only a file that is not MCAP at all (bad magic) raises :class:`~.sources.LogReadError`.
"""

from __future__ import annotations

import mmap
import re
import struct
import zlib
from collections import deque
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from io import BytesIO
from pathlib import Path
from typing import BinaryIO

from mcap.data_stream import ReadDataStream
from mcap.records import Channel as McapChannel
from mcap.records import Chunk, Schema

from .records import utc_text
from .sources import Channel, LogReadError, RawMessage, ReadStats, normalise_type, register_container

MCAP_MAGIC = b"\x89MCAP0\r\n"
_OP_FOOTER = 0x02
_OP_SCHEMA = 0x03
_OP_CHANNEL = 0x04
_OP_MESSAGE = 0x05
_OP_CHUNK = 0x06
_OP_MESSAGE_INDEX = 0x07
_CHUNK_HEAD = struct.Struct("<QQQII")  # start time, end time, uncompressed size, crc, compression length
_MSG_HEAD = struct.Struct("<HIQQ")  # channel_id, sequence, log_time, publish_time
_RECORD_HEAD = struct.Struct("<BQ")
_PREFETCH = 4


_OP_NAMES = {_OP_SCHEMA: "schema", _OP_CHANNEL: "channel", _OP_MESSAGE: "message"}
_LAST_OPCODE = 0x0F  # opcodes 0x10-0x7F are reserved; 0x80-0xFF are private records, skipped by length
#: a record header whose opcode is defined and whose length fits in 32 bits (as every real record's does)
_PLAUSIBLE_HEAD = re.compile(rb"(?=[\x01-\x0f\x80-\xff][\x00-\xff]{4}\x00\x00\x00\x00)")


class _BadChunk(Exception):
    pass


class _CrcMismatch(_BadChunk):
    """A chunk that decompresses to its stated size but fails its CRC: ``data``, the bytes it decompressed to."""

    def __init__(self, data: bytes) -> None:
        super().__init__("its CRC does not match")
        self.data = data


def _listed(records: list[bytes] | None) -> set[tuple[int, int, int]] | None:
    """(channel id, log time, record offset in the chunk's payload) of every entry of a chunk's message index
    records; None where it has none, or one does not parse."""
    if not records:
        return None
    out: set[tuple[int, int, int]] = set()
    try:
        for body in records:
            channel_id, size = struct.unpack_from("<HI", body, 0)
            out.update((channel_id, t, o) for t, o in struct.iter_unpack("<QQ", body[6:6 + size]))
    except struct.error:
        return None
    return out


def _message_records(data: bytes) -> int:
    """The message records in a chunk's payload, as far as its framing goes."""
    pos, n, found = 0, len(data), 0
    while pos + 9 <= n:
        opcode, length = _RECORD_HEAD.unpack_from(data, pos)
        pos += 9 + length
        found += pos <= n and opcode == _OP_MESSAGE
    return found


_DATA_END = _RECORD_HEAD.pack(0x0F, 4)  # opcode and length of the DataEnd record the summary section follows
_SUMMARY_TRIES = 4


def _summary_by_its_data_end(path: Path) -> tuple[dict[int, Schema], dict[int, McapChannel], dict[int, int]] | None:
    """The summary's schemas, channels and message counts of a file whose footer's summary offset misses it (a
    block of bytes added or lost before it): after the last DataEnd record whose following records parse as far
    as the footer. None where no such section is found."""
    from mcap.records import Footer, Statistics
    from mcap.stream_reader import StreamReader

    if path.stat().st_size < 2 * len(MCAP_MAGIC):  # no summary between two magics (an empty file maps not at all)
        return None
    with open(path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        if buf[-len(MCAP_MAGIC):] != MCAP_MAGIC:
            return None
        pos = len(buf)
        for _ in range(_SUMMARY_TRIES):  # a DataEnd's bytes inside an uncompressed chunk are not the record
            pos = buf.rfind(_DATA_END, 0, pos)
            if pos < 0:
                return None
            schemas: dict[int, Schema] = {}
            channels: dict[int, McapChannel] = {}
            counts: dict[int, int] = {}
            try:
                for rec in StreamReader(BytesIO(buf[pos + _RECORD_HEAD.size + 4:]), skip_magic=True).records:
                    if isinstance(rec, Schema):
                        schemas[rec.id] = rec
                    elif isinstance(rec, McapChannel):
                        channels[rec.id] = rec
                    elif isinstance(rec, Statistics):
                        counts = dict(rec.channel_message_counts)
                    elif isinstance(rec, Footer):
                        return (schemas, channels, counts) if channels else None
            except Exception:  # not the summary: the mcap library raises what it meets
                continue
    return None


def _framing_problem(opcode: int, length: int, offset: int, total: int) -> str:
    """Why the record header at ``offset`` cannot be a real one ("" if it can)."""
    if opcode == 0 or _LAST_OPCODE < opcode < 0x80:
        return f"invalid record opcode {opcode:#04x}"
    if length > total - offset - 9:
        return f"record of {length} bytes runs past the end of the file (truncated or damaged length)"
    if opcode == _OP_FOOTER and offset + 9 + length + len(MCAP_MAGIC) != total:
        return "footer record before the end of the file"
    return ""


def _next_record(path: Path, start: int, total: int) -> int | None:
    """Offset of the first plausible record at or after ``start``: a sane header whose successor's header is
    sane too (or which ends where the closing magic starts); chunk records must parse as chunks."""
    with open(path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        for m in _PLAUSIBLE_HEAD.finditer(buf, start):
            pos = m.start()
            opcode, length = _RECORD_HEAD.unpack_from(buf, pos)
            if _framing_problem(opcode, length, pos, total):
                continue
            end = pos + 9 + length
            if opcode == _OP_CHUNK:
                try:
                    _parse_chunk(buf[pos + 9:end])
                except (struct.error, ValueError, UnicodeDecodeError):
                    continue
            if end + 9 <= total:
                op2, len2 = _RECORD_HEAD.unpack_from(buf, end)
                if _framing_problem(op2, len2, end, total):
                    continue
            elif end != total - len(MCAP_MAGIC):
                continue
            return pos
    return None


def _chunk_header(body: bytes) -> tuple[int, int, str, int, int]:
    """(uncompressed size, CRC, compression, where its records start in ``body``, their length) of a chunk
    record's body (only its header need be there)."""
    _, _, size, crc, clen = _CHUNK_HEAD.unpack_from(body, 0)
    pos = _CHUNK_HEAD.size
    compression = body[pos:pos + clen].decode("ascii")
    (nrec,) = struct.unpack_from("<Q", body, pos + clen)
    return size, crc, compression, pos + clen + 8, nrec


def _chunk_records_end(f: BinaryIO, offset: int, total: int) -> int | None:
    """Where the chunk record at ``offset`` ends by its own records length, or None where its header does not parse
    as a chunk's (a known compression, a length that could be real)."""
    f.seek(offset + 9)
    try:
        _, _, compression, records, nrec = _chunk_header(f.read(min(4096, max(0, total - offset - 9))))
    except (struct.error, UnicodeDecodeError):
        return None
    if compression not in ("", "zstd", "lz4") or nrec >= 1 << 40:
        return None
    return offset + 9 + records + nrec


def _parse_chunk(body: bytes, cut: bool = False) -> Chunk:
    """A chunk record's body; ``cut``: it may end before its records do (they are then its prefix)."""
    size, crc, compression, pos, nrec = _chunk_header(body)
    if pos + nrec > len(body) and not cut:
        raise ValueError("chunk records run past the chunk")
    return Chunk(compression=compression, data=memoryview(body)[pos:pos + nrec], message_end_time=0,
                 message_start_time=0, uncompressed_crc=crc, uncompressed_size=size)


def _decode(chunk: Chunk, prefix: bool = False) -> bytes:
    """A chunk's payload decompressed; ``prefix``: its data may be cut, and what it gives is decoded (zstd and lz4
    decode a stream's prefix), at most its uncompressed size."""
    try:
        if chunk.compression == "zstd":
            import zstandard

            zstd = zstandard.ZstdDecompressor()
            data = (zstd.decompressobj().decompress(chunk.data) if prefix
                    else zstd.decompress(chunk.data, max_output_size=chunk.uncompressed_size))
        elif chunk.compression == "lz4":
            import lz4.frame

            lz4_stream = lz4.frame.LZ4FrameDecompressor()
            data = lz4_stream.decompress(chunk.data) if prefix else lz4.frame.decompress(chunk.data)
        elif chunk.compression == "":
            data = bytes(chunk.data) if prefix else chunk.data
        else:
            raise _BadChunk(f"unsupported chunk compression {chunk.compression!r}")
    except _BadChunk:
        raise
    except Exception as exc:
        raise _BadChunk(f"chunk does not decompress ({exc})") from exc
    return data[:chunk.uncompressed_size] if prefix else data


def _decompress(chunk: Chunk) -> bytes:
    """Chunk payload, decompressed and CRC-checked (runs on a worker thread; the codecs release the GIL)."""
    data = _decode(chunk)
    if len(data) != chunk.uncompressed_size:
        raise _BadChunk(f"chunk decompresses to {len(data)} bytes, header says {chunk.uncompressed_size}")
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise _CrcMismatch(data)
    return data


class McapSource:
    container = "mcap"

    def __init__(self, path: Path, declared: dict[str, int] | None = None, keep_unverified: bool = False) -> None:
        self.path = Path(path)
        #: read the messages of a chunk whose CRC alone fails (the damage unlocated in them), with a warning
        self.keep_unverified = keep_unverified
        self.stats = ReadStats(bytes_total=self.path.stat().st_size)
        self._schemas: dict[int, Schema] = {}
        self._channels: dict[int, Channel] = {}
        self._declared = declared  # per-topic counts from a rosbag2 metadata.yaml
        self._summary_counts: dict[int, int] = {}
        #: the summary's schemas and channels: stand-ins for records damaged in the data section
        self._summary_records: tuple[dict[int, Schema], dict[int, McapChannel]] = ({}, {})
        self._undeclared = 0
        #: the message index records that follow each chunk (by the byte its record ends at), kept while the chunk
        #: waits to be read when a chunk whose CRC fails is to be read too
        self._indexes: dict[int, list[bytes]] = {}

    # -- public -------------------------------------------------------------------------------------
    def messages(self) -> Iterator[RawMessage]:
        with open(self.path, "rb") as f:
            self._read_summary(f)
            f.seek(0)
            yield from self._records(f)
        self._check_counts()

    # -- internals ----------------------------------------------------------------------------------
    def _read_summary(self, f: object) -> None:
        """Message counts per channel from the summary section, if the file has an intact one."""
        from mcap.reader import SeekingReader

        try:
            summary = SeekingReader(f).get_summary()  # type: ignore[arg-type]
        except Exception:
            found = _summary_by_its_data_end(self.path)
            if found is not None:
                self._summary_records, self._summary_counts = found[:2], found[2]
                self.stats.warnings.append(f"{self.path}: the footer's summary offset misses the summary (bytes "
                                           "added or lost before it); its schemas and channels found by its "
                                           "DataEnd record, the chunk indexes not used")
            return
        if summary is None or summary.statistics is None:
            # no counts to check the messages against: the file's end tells a finished writer (its footer) from a
            # cut one (:meth:`_records`)
            return
        self._summary_counts = dict(summary.statistics.channel_message_counts)
        self._summary_records = (summary.schemas, summary.channels)

    def _records(self, f: BinaryIO) -> Iterator[RawMessage]:
        """Outer records in file order; chunks go to the worker threads, message indexes are skipped.

        A record that does not parse costs only itself; a broken framing (garbage opcode or length) is
        resynchronised on the next plausible record (:func:`_next_record`).
        """
        magic = f.read(8)
        if not magic:
            raise LogReadError(f"{self.path}: an empty file (0 bytes), no MCAP log in it")
        if magic != MCAP_MAGIC:
            raise LogReadError(f"{self.path}: not an MCAP file (bad magic)")
        pending: deque[tuple[int, Future[bytes]]] = deque()
        total = self.stats.bytes_total
        offset = 8
        # where to look for the next record if the one at ``offset`` is garbage: a record other than a chunk
        # (whose header was checked) may itself have carried the bad length that led here
        resync_from = offset
        with ThreadPoolExecutor(1, thread_name_prefix="mcap-chunk") as pool:
            while True:
                head = f.read(9)
                if len(head) < 9:
                    if offset < total:
                        self._damaged(offset, "file ends inside a record header (truncated)")
                    else:  # the cut fell between two records
                        self._damaged(offset, "file ends without its footer (truncated, or its writer never "
                                      "finished)")
                    break
                opcode, length = _RECORD_HEAD.unpack(head)
                framing = _framing_problem(opcode, length, offset, total)
                # a chunk running past the file's end: its own records length tells a damaged length field (the
                # chunk fits: read it by that, go on after it) from a cut file (keep what the cut left of it)
                records_end = _chunk_records_end(f, offset, total) if framing and opcode == _OP_CHUNK else None
                if records_end is not None and records_end <= total:
                    self.stats.warnings.append(
                        f"{self.path}: damaged MCAP: the chunk at byte {offset} says it is {length} bytes long, its "
                        f"records end at byte {records_end}: read by them")
                    f.seek(offset + 9)
                    length = records_end - offset - 9
                elif records_end is not None:
                    while pending:
                        yield from self._chunk_messages(*pending.popleft())
                    yield from self._cut_chunk(f, offset, framing)
                    break
                elif framing:
                    nxt = _next_record(self.path, resync_from + 1, total)
                    if nxt is None:
                        self._damaged(offset, framing)
                        break
                    if nxt < offset:
                        framing = f"the record at byte {resync_from} has a bad length ({framing} at byte {offset})"
                    self._skipped(resync_from, nxt, framing)
                    f.seek(nxt)
                    offset = resync_from = nxt
                    continue
                if opcode == _OP_FOOTER:
                    break
                if opcode == _OP_CHUNK:
                    body = f.read(length)
                    try:
                        chunk = _parse_chunk(body)
                    except (struct.error, ValueError, UnicodeDecodeError) as exc:
                        self._skipped(offset, offset + 9 + length, f"bad chunk header ({exc})")
                        resync_from = offset
                    else:
                        resync_from = offset + 9 + length
                        pending.append((offset + 9 + length, pool.submit(_decompress, chunk)))
                        if len(pending) > _PREFETCH:
                            yield from self._chunk_messages(*pending.popleft())
                elif opcode in (_OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE):
                    while pending:
                        yield from self._chunk_messages(*pending.popleft())
                    body = f.read(length)
                    try:
                        msg = self._inner_record(opcode, memoryview(body), 0, length)
                    except Exception as exc:  # mcap's record parsers raise whatever the bytes provoke
                        self._skipped(offset, offset + 9 + length, f"unreadable {_OP_NAMES[opcode]} record "
                                      f"({type(exc).__name__}: {exc})")
                        msg = None
                    if msg is not None:
                        yield msg
                elif opcode == _OP_MESSAGE_INDEX and self.keep_unverified and pending:
                    self._indexes.setdefault(pending[-1][0], []).append(f.read(length))
                elif length < 1 << 20:  # message indexes etc.: reading is cheaper than a buffered seek
                    f.read(length)
                else:  # attachments, large metadata: not needed here
                    f.seek(length, 1)
                if opcode != _OP_CHUNK:
                    resync_from = offset
                offset += 9 + length
                self.stats.bytes_read = offset
            while pending:
                yield from self._chunk_messages(*pending.popleft())

    def _damaged(self, offset: int, what: str) -> None:
        if offset <= len(MCAP_MAGIC):  # not a single record is readable: not a usable MCAP at all
            raise LogReadError(f"{self.path}: not a readable MCAP file ({what} at byte {offset})")
        self.stats.warnings.append(f"{self.path}: damaged MCAP at byte {offset} of {self.stats.bytes_total}: {what}; "
                                   "everything before it was read")

    def _skipped(self, start: int, end: int, what: str) -> None:
        self.stats.warnings.append(f"{self.path}: damaged MCAP: bytes {start}-{end} skipped: {what}; reading "
                                   "went on after them")

    def _cut_chunk(self, f: BinaryIO, offset: int, framing: str) -> Iterator[RawMessage]:
        """The whole messages of the chunk record at ``offset`` that the file's end cuts (``framing``: why its
        record does not fit), then the warning that names what was kept."""
        f.seek(offset + 9)
        body = f.read()
        try:
            chunk = _parse_chunk(body, cut=True)
            data = _decode(chunk, prefix=True)
        except (struct.error, ValueError, UnicodeDecodeError, _BadChunk):
            self._damaged(offset, framing)
            return
        whole = len(data) == chunk.uncompressed_size and (not chunk.uncompressed_crc
                                                          or zlib.crc32(data) == chunk.uncompressed_crc)
        kept = 0
        for msg in self._records_of(data, offset + 9 + len(body), cut=not whole):
            kept += 1
            yield msg
        checked = "checked against its CRC" if whole else "its CRC could not be checked"
        self.stats.warnings.append(
            f"{self.path}: damaged MCAP at byte {offset} of {self.stats.bytes_total}: a chunk whose {framing}: "
            f"{kept} whole messages kept from {len(data)} of its {chunk.uncompressed_size} bytes ({checked}); "
            "everything before it was read")
        self.stats.bytes_read = self.stats.bytes_total

    def _chunk_messages(self, end_offset: int, future: Future[bytes]) -> Iterator[RawMessage]:
        index = self._indexes.pop(end_offset, None)
        try:
            data = future.result()
        except _CrcMismatch as exc:
            if not self.keep_unverified:
                self.stats.warnings.append(
                    f"{self.path}: damaged MCAP: chunk ending at byte {end_offset} skipped: {exc} (its "
                    f"{_message_records(exc.data)} messages; autosar ingest --allow-unverified keeps them)")
                return
            listed = _listed(index)
            unlisted = [0]
            kept, first, last = 0, None, None
            for msg in self._records_of(exc.data, end_offset, listed=listed, unlisted=unlisted):
                kept += 1
                first = msg.log_ns if first is None else min(first, msg.log_ns)
                last = msg.log_ns if last is None else max(last, msg.log_ns)
                yield msg
            span = (f" logged {utc_text(first, 'milliseconds')} to {utc_text(last, 'milliseconds')}"
                    .replace("+00:00", "Z") if first is not None and last is not None else "")
            checked = (f", checked against its message index ({unlisted[0]} it does not list left out)"
                       if listed is not None else ", no message index to check them against")
            self.stats.warnings.append(
                f"{self.path}: damaged MCAP: chunk ending at byte {end_offset} read although {exc} "
                f"(--allow-unverified): its {kept} messages{span} kept{checked}; one or more of their bytes not as "
                "written")
            return
        except _BadChunk as exc:
            self.stats.warnings.append(f"{self.path}: damaged MCAP: chunk ending at byte {end_offset} skipped: {exc}")
            return
        yield from self._records_of(data, end_offset)

    def _records_of(self, data: bytes, end_offset: int, cut: bool = False,
                    listed: set[tuple[int, int, int]] | None = None, unlisted: list[int] | None = None
                    ) -> Iterator[RawMessage]:
        """The records of a chunk's payload ``data`` (whose record ends at file byte ``end_offset``); ``cut``: the
        payload is a prefix, and the record it breaks off is where it ends, not damage. ``listed``: the (channel id,
        log time, record offset) its message index gives; a message it does not list is left out, counted in
        ``unlisted[0]``."""
        view = memoryview(data)
        pos, n = 0, len(data)
        unpack_head, unpack_msg = _RECORD_HEAD.unpack_from, _MSG_HEAD.unpack_from
        channels = self._channels
        counts = self.stats.counts
        try:
            while pos < n:
                if cut and pos + 9 > n:
                    break
                opcode, length = unpack_head(view, pos)
                at, body = pos, pos + 9
                pos = body + length
                if pos > n:
                    if cut:
                        break
                    raise ValueError("record runs past the end of the chunk")
                if opcode == _OP_MESSAGE:  # the hot path, inlined
                    channel_id, _, log_time, _ = unpack_msg(view, body)
                    if listed is not None and (channel_id, log_time, at) not in listed:
                        unlisted[0] += 1  # type: ignore[index]
                        continue
                    channel = channels.get(channel_id) or self._summary_channel(channel_id)
                    if channel is None:
                        self._undeclared += 1
                        continue
                    counts[channel.key] = counts.get(channel.key, 0) + 1
                    yield RawMessage(channel, log_time, view[body + 22:pos])
                else:
                    self._inner_record(opcode, view, body, pos)
        except (struct.error, ValueError, UnicodeDecodeError) as exc:
            self.stats.warnings.append(f"{self.path}: chunk ending at byte {end_offset} is corrupt ({exc}); "
                                       "the rest of it was skipped")
        self.stats.bytes_read = end_offset

    def _summary_channel(self, channel_id: int) -> Channel | None:
        """The channel as the summary declares it, when its record in the data section was lost."""
        schemas, channels = self._summary_records
        ch = channels.get(channel_id)
        if ch is None:
            return None
        if ch.schema_id not in self._schemas and ch.schema_id in schemas:
            self._schemas[ch.schema_id] = schemas[ch.schema_id]
        self._add_channel(ch)
        return self._channels[channel_id]

    def _add_channel(self, ch: McapChannel) -> None:
        schema = self._schemas.get(ch.schema_id)
        name = schema.name if schema else ""
        encoding = {"cdr": "cdr", "ros1": "ros1"}.get(ch.message_encoding, ch.message_encoding)
        schema_text = ""
        if schema is not None:
            try:
                schema_text = bytes(schema.data).decode("utf-8")
            except UnicodeDecodeError:
                schema_text = ""
        declared = self._summary_counts.get(ch.id)
        if self._declared is not None:
            declared = self._declared.get(ch.topic)
        self._channels[ch.id] = Channel((str(self.path), ch.id), ch.topic, normalise_type(name), encoding,
                                        schema_text, schema.encoding if schema else "", declared)

    def _inner_record(self, opcode: int, view: memoryview, start: int, end: int) -> RawMessage | None:
        """Schema, channel or (unchunked) message record; anything else is ignored."""
        if opcode == _OP_SCHEMA:
            schema = Schema.read(ReadDataStream(BytesIO(view[start:end])))
            self._schemas[schema.id] = schema
        elif opcode == _OP_CHANNEL:
            self._add_channel(McapChannel.read(ReadDataStream(BytesIO(view[start:end]))))
        elif opcode == _OP_MESSAGE:
            channel_id, _, log_time, _ = _MSG_HEAD.unpack_from(view, start)
            channel = self._channels.get(channel_id) or self._summary_channel(channel_id)
            if channel is None:
                self._undeclared += 1
                return None
            self.stats.counts[channel.key] = self.stats.counts.get(channel.key, 0) + 1
            return RawMessage(channel, log_time, view[start + 22:end])
        return None

    def _check_counts(self) -> None:
        self.stats.messages = sum(self.stats.counts.values())
        if self._undeclared:
            self.stats.warnings.append(f"{self.path}: {self._undeclared} messages on undeclared channels skipped")
        for ch in self._channels.values():
            got = self.stats.counts.get(ch.key, 0)
            if ch.declared_count is not None and got < ch.declared_count:
                self.stats.warnings.append(f"{self.path}: topic {ch.topic}: {got} of the {ch.declared_count} "
                                           "messages the index declares could be read")


register_container("mcap", ".mcap", lambda path: not path.is_dir() and path.suffix.lower() == ".mcap", McapSource,
                   magic=MCAP_MAGIC)
