"""MCAP reader: one sequential pass, chunks decompressed on worker threads ahead of the decoder.

Works on indexed and unindexed files (the records are read in file order with
:class:`mcap.stream_reader.StreamReader`; the summary, when there is one, only supplies the message
counts to check against). Damage is contained:

- a chunk that fails to decompress or whose CRC does not match is skipped with a warning naming its
  file offset, and reading goes on with the next record;
- a broken record structure (truncated file, garbage length) ends the read with a warning naming the
  offset; everything before it has been delivered.

Only a file that is not MCAP at all (bad magic) raises :class:`~.sources.LogReadError`.
"""

from __future__ import annotations

import struct
import zlib
from collections import deque
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from io import BytesIO
from pathlib import Path

from mcap.data_stream import ReadDataStream
from mcap.exceptions import InvalidMagic
from mcap.records import Channel as McapChannel
from mcap.records import Chunk, Message, Schema
from mcap.stream_reader import StreamReader

from .sources import Channel, LogReadError, RawMessage, ReadStats, normalise_type

_OP_SCHEMA = 0x03
_OP_CHANNEL = 0x04
_OP_MESSAGE = 0x05
_MSG_HEAD = struct.Struct("<HIQQ")  # channel_id, sequence, log_time, publish_time
_RECORD_HEAD = struct.Struct("<BQ")
_PREFETCH = 4


class _BadChunk(Exception):
    pass


def _decompress(chunk: Chunk) -> bytes:
    """Chunk payload, decompressed and CRC-checked (runs on a worker thread; the codecs release the GIL)."""
    try:
        if chunk.compression == "zstd":
            import zstandard

            data = zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
        elif chunk.compression == "lz4":
            import lz4.frame

            data = lz4.frame.decompress(chunk.data)
        elif chunk.compression == "":
            data = chunk.data
        else:
            raise _BadChunk(f"unsupported chunk compression {chunk.compression!r}")
    except _BadChunk:
        raise
    except Exception as exc:
        raise _BadChunk(f"chunk does not decompress ({exc})") from exc
    if len(data) != chunk.uncompressed_size:
        raise _BadChunk(f"chunk decompresses to {len(data)} bytes, header says {chunk.uncompressed_size}")
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise _BadChunk("chunk CRC mismatch")
    return data


class McapSource:
    container = "mcap"

    def __init__(self, path: Path, declared: dict[str, int] | None = None) -> None:
        self.path = Path(path)
        self.stats = ReadStats(bytes_total=self.path.stat().st_size)
        self._schemas: dict[int, Schema] = {}
        self._channels: dict[int, Channel] = {}
        self._declared = declared  # per-topic counts from a rosbag2 metadata.yaml
        self._summary_counts: dict[int, int] = {}

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
            summary = None
        if summary is None or summary.statistics is None:
            if self._declared is None:
                self.stats.warnings.append(f"{self.path}: no MCAP summary (unindexed or truncated file); "
                                           "reading sequentially")
            return
        self._summary_counts = dict(summary.statistics.channel_message_counts)

    def _records(self, f: object) -> Iterator[RawMessage]:
        reader = StreamReader(f, emit_chunks=True, record_size_limit=self.stats.bytes_total)  # type: ignore[arg-type]
        pending: deque[tuple[int, Future[bytes]]] = deque()
        offset = 0
        with ThreadPoolExecutor(2, thread_name_prefix="mcap-chunk") as pool:
            records = reader.records
            while True:
                try:
                    record = next(records)
                except StopIteration:
                    break
                except InvalidMagic as exc:
                    if offset == 0:
                        raise LogReadError(f"{self.path}: not an MCAP file (bad magic)") from exc
                    self.stats.warnings.append(f"{self.path}: damaged MCAP after byte {offset}: bad end magic; "
                                               "everything before it was read")
                    break
                except Exception as exc:  # the record structure is broken: keep what came before
                    if offset == 0:
                        raise LogReadError(f"{self.path}: not a readable MCAP file ({exc})") from exc
                    self.stats.warnings.append(
                        f"{self.path}: damaged or truncated MCAP after byte {offset} of {self.stats.bytes_total} "
                        f"({type(exc).__name__}: {exc}); everything before it was read")
                    break
                offset = f.tell()  # type: ignore[attr-defined]
                if isinstance(record, Chunk):
                    pending.append((offset, pool.submit(_decompress, record)))
                    if len(pending) > _PREFETCH:
                        yield from self._chunk_messages(*pending.popleft())
                    continue
                while pending:
                    yield from self._chunk_messages(*pending.popleft())
                if isinstance(record, Schema):
                    self._schemas[record.id] = record
                elif isinstance(record, McapChannel):
                    self._add_channel(record)
                elif isinstance(record, Message):
                    msg = self._message(record.channel_id, record.log_time, record.data)
                    if msg is not None:
                        yield msg
                self.stats.bytes_read = offset
            while pending:
                yield from self._chunk_messages(*pending.popleft())
        self.stats.bytes_read = max(self.stats.bytes_read, offset)

    def _chunk_messages(self, end_offset: int, future: Future[bytes]) -> Iterator[RawMessage]:
        try:
            data = future.result()
        except _BadChunk as exc:
            self.stats.warnings.append(f"{self.path}: chunk ending at byte {end_offset} skipped: {exc}")
            return
        view = memoryview(data)
        pos, n = 0, len(data)
        unpack_head, unpack_msg = _RECORD_HEAD.unpack_from, _MSG_HEAD.unpack_from
        try:
            while pos < n:
                opcode, length = unpack_head(view, pos)
                body = pos + 9
                pos = body + length
                if pos > n:
                    raise ValueError("record runs past the end of the chunk")
                if opcode == _OP_MESSAGE:
                    channel_id, _, log_time, _ = unpack_msg(view, body)
                    msg = self._message(channel_id, log_time, view[body + 22:pos])
                    if msg is not None:
                        yield msg
                elif opcode == _OP_SCHEMA:
                    schema = Schema.read(ReadDataStream(BytesIO(view[body:pos])))
                    self._schemas[schema.id] = schema
                elif opcode == _OP_CHANNEL:
                    self._add_channel(McapChannel.read(ReadDataStream(BytesIO(view[body:pos]))))
        except (struct.error, ValueError, UnicodeDecodeError) as exc:
            self.stats.warnings.append(f"{self.path}: chunk ending at byte {end_offset} is corrupt ({exc}); "
                                       "the rest of it was skipped")
        self.stats.bytes_read = end_offset

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

    def _message(self, channel_id: int, log_time: int, data: bytes | memoryview) -> RawMessage | None:
        channel = self._channels.get(channel_id)
        if channel is None:
            self.stats.warnings.append(f"{self.path}: message on undeclared channel {channel_id} skipped")
            return None
        self.stats.messages += 1
        counts = self.stats.counts
        counts[channel.key] = counts.get(channel.key, 0) + 1
        return RawMessage(channel, log_time, data)

    def _check_counts(self) -> None:
        for ch in self._channels.values():
            got = self.stats.counts.get(ch.key, 0)
            if ch.declared_count is not None and got < ch.declared_count:
                self.stats.warnings.append(f"{self.path}: topic {ch.topic}: {got} of the {ch.declared_count} "
                                           "messages the index declares could be read")

    @property
    def channels(self) -> list[Channel]:
        return list(self._channels.values())
