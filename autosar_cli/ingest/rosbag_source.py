"""ROS1 bags and rosbag2 directories, read with rosbags (and the MCAP reader for MCAP storage).

rosbag2 traps handled here (see the real-data notes in docs/FORMATS.md):

- rosbags' rosbag2 ``Reader`` matches connections on topic, type *and* QoS; when ``metadata.yaml`` and
  the storage disagree on a topic's QoS it silently yields nothing of that topic. Every topic's count is
  therefore checked against ``metadata.yaml``; the topics rosbags yielded nothing of are read directly
  from the sqlite3 storage with SQL instead.
- MCAP storage files are plain MCAP: they are read with :class:`~.mcap_source.McapSource`, which decodes
  per channel, so one unparseable embedded schema cannot take the whole bag down.

A ROS1 bag writes each connection record twice: inside the chunk that holds the connection's first message, and in
the index section after the chunks, which rosbags reads. A byte damaged in one copy (the type's name, its md5sum,
its message definition or the topic) makes it disagree with the other (:func:`reconcile`). Each copy is judged by
what it says of itself: whether its md5sum is that of its message definition (read as the type it names), and
whether it is that of the known type of its name (:func:`autosar_cli.msgs.typestore_for`). The copy that bears out
more of the two is read, the chunk's where they bear out as many (``rosbag reindex`` reads that one; the messages
lie beside it), and a warning names the connection, what each copy says and which was read. A connection that
names a type no one knows whose md5sum is a known type's, that type's name at most :data:`NEAR_MISS` letters from
its own (both copies damaged, or a bag read chunk by chunk with one copy), is read as that type, with a warning
(:func:`near_known_type`): else its stream would be skipped as no sensor stream.
"""

from __future__ import annotations

import functools
import mmap
import os
import sqlite3
import tempfile
from collections import Counter
from collections.abc import Iterator
from pathlib import Path, PurePath
from typing import Any
from urllib.parse import quote

import yaml
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from autosar_cli.msgs import typestore_for

from .mcap_source import MCAP_MAGIC, McapSource
from .ros1_chunks import RecordError, Ros1Connection, Ros1Message, ScanReport, chain_break, chunk_copies, scan_bag
from .ros1_chunks import normalise_topic as ros1_topic
from .sources import (
    Channel,
    LogReadError,
    LogSource,
    RawMessage,
    ReadStats,
    normalise_type,
    register_container,
)
from .sqlite_pages import table_leaf_rows
from .sqlite_wal import apply_wal

NEAR_MISS = 2  #: letters (inserted, lost or changed) by which a damaged type's name misses the known one


def _differences(a: Ros1Connection, b: Ros1Connection) -> list[tuple[str, str, str]]:
    """(field, a's, b's) of each field the two copies state differently."""
    pairs = (("topic", ros1_topic(a.topic), ros1_topic(b.topic)),
             ("type", normalise_type(a.msgtype), normalise_type(b.msgtype)),
             ("md5sum", a.md5sum, b.md5sum))
    out = [(name, x, y) for name, x, y in pairs if x != y]
    if a.msgdef != b.msgdef:
        out.append(("message definition", *(f"whose md5 is {md5}" if (md5 := definition_md5(c.msgtype, c.msgdef))
                                             else "that does not parse" for c in (a, b))))
    return out


@functools.lru_cache(maxsize=256)
def definition_md5(msgtype: str, msgdef: str) -> str | None:
    """The ROS1 md5sum of the message definition ``msgdef`` read as type ``msgtype``, or None where it does not
    parse as that."""
    name = normalise_type(msgtype)
    try:
        store = get_typestore(Stores.EMPTY)
        store.register(get_types_from_msg(msgdef, name))
        return store.generate_msgdef(name, ros_version=1)[1]
    except Exception:  # rosbags raises several types for bad text
        return None


@functools.lru_cache(maxsize=256)
def known_md5(msgtype: str) -> str | None:
    """The ROS1 md5sum of the known type ``msgtype``, or None where no type of that name is known."""
    store = typestore_for(1)
    name = normalise_type(msgtype)
    if name not in store.types:
        return None
    try:
        return store.generate_msgdef(name, ros_version=1)[1]
    except Exception:  # a known type whose definition rosbags cannot hash: nothing to tell by
        return None


def _consistency(c: Ros1Connection) -> int:
    """How many of its own statements a copy bears out: its md5sum is its definition's, and its type's."""
    return int(definition_md5(c.msgtype, c.msgdef) == c.md5sum) + int(known_md5(c.msgtype) == c.md5sum)


def _said(differences: list[tuple[str, str, str]], which: int) -> str:
    """What one copy (1: the first given to :func:`_differences`, 2: the other) says where they differ."""
    return ", ".join(f"{d[0]} {d[which]}" for d in differences)


def reconcile(index: Ros1Connection, chunk: Ros1Connection | None, chunk_pos: int, where: str
              ) -> tuple[Ros1Connection, str | None]:
    """The copy of a connection record to read, of its index copy and its copy in the chunk at byte
    ``chunk_pos`` (None: none found), and the warning where they disagree (``where``: the bag)."""
    if chunk is None:
        return index, None
    differences = _differences(index, chunk)
    if not differences:
        return index, None
    chunk_score, index_score = _consistency(chunk), _consistency(index)
    read, other = ("the index's", "the chunk's") if index_score > chunk_score else ("the chunk's", "the index's")
    chosen = index if index_score > chunk_score else chunk
    reason = ("its md5sum is its definition's and its type's" if max(chunk_score, index_score) == 2 else
              "its md5sum is its definition's or its type's" if max(chunk_score, index_score) == 1 else
              "neither copy's md5sum is its definition's or its type's")
    if chunk_score == index_score:
        reason = f"both as consistent ({reason}): the copy beside the messages"
    topic = ros1_topic(chosen.topic)
    return chosen, (f"{where}: damaged ROS1 bag: connection {index.conn_id} ({topic}) disagrees with itself: its "
                    f"index copy says {_said(differences, 1)}, its copy in the chunk at byte {chunk_pos} "
                    f"{_said(differences, 2)}; {read} read ({reason}), {other} damaged")


def _distance(a: str, b: str, most: int) -> int:
    """The edit distance of ``a`` and ``b``, or ``most + 1`` where it is over ``most``."""
    if abs(len(a) - len(b)) > most:
        return most + 1
    row = list(range(len(b) + 1))
    for i, x in enumerate(a, 1):
        prev, row[0] = row[0], i
        for j, y in enumerate(b, 1):
            prev, row[j] = row[j], min(row[j] + 1, row[j - 1] + 1, prev + (x != y))
        if min(row) > most:
            return most + 1
    return row[-1]


def near_known_type(c: Ros1Connection, where: str) -> tuple[Ros1Connection, str | None]:
    """``c``, or where its type is none known but its md5sum is that of a known type whose name is at most
    :data:`NEAR_MISS` letters from its own, ``c`` as that type and the warning that says so."""
    name = normalise_type(c.msgtype)
    store = typestore_for(1)
    if not c.md5sum or name in store.types:
        return c, None
    near = [(d, known) for known in store.types if (d := _distance(name, known, NEAR_MISS)) <= NEAR_MISS]
    matches = sorted((d, known) for d, known in near if known_md5(known) == c.md5sum)
    if not matches or (len(matches) > 1 and matches[0][0] == matches[1][0]):
        return c, None
    d, known = matches[0]
    topic = ros1_topic(c.topic)
    return (Ros1Connection(c.conn_id, c.topic, known, c.msgdef, c.md5sum),
            f"{where}: damaged ROS1 bag: connection {c.conn_id} ({topic}) names type {c.msgtype}, which is none "
            f"known, but its md5sum {c.md5sum} is {known}'s, whose name it misses by {d} letter{'s' * (d > 1)}: "
            f"read as {known}")


def _index_entries(reader: Any) -> dict[tuple[int, int], tuple[int, int, int, int]]:
    """(chunk offset, record offset) -> (connection, t_ns, the chunk's first t_ns, its last t_ns + 1) of every
    message rosbags' open ``reader`` read from the bag's index."""
    spans = {i.pos: (i.start_time, i.end_time) for i in reader.chunk_infos}
    return {(e.chunk_pos, e.offset): (conn_id, e.time, *spans.get(e.chunk_pos, (0, 0)))
            for conn_id, entries in reader.indexes.items() for e in entries}


def _why(exc: Exception) -> str:
    """What rosbags raised, said (some of its errors carry no text)."""
    return f"{type(exc).__name__}: {exc}" if str(exc) else f"rosbags' {type(exc).__name__}"


class Ros1BagSource:
    """ROS1 bag v2.0. Read through its index with rosbags; a bag whose index is missing or damaged, or
    whose chunks break while reading, is scanned chunk by chunk instead (:mod:`.ros1_chunks`), keeping
    every intact chunk."""

    container = "ros1"

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.stats = ReadStats(bytes_total=self.path.stat().st_size)
        self._yielded: Counter[tuple[int, int]] = Counter()  # (connection, t_ns) already delivered
        #: (chunk offset, record offset) -> (connection, t_ns, chunk's first t_ns, chunk's last t_ns + 1), as the
        #: index says, for the scan that follows a read through it
        self._indexed: dict[tuple[int, int], tuple[int, int, int, int]] = {}
        self._disagree: dict[str, list[str]] = {}  # how a record that disagrees with the index was read -> where
        #: the connections the index gives (each checked against its copy in a chunk), for the scan that follows a
        #: read through it: a chunk's own connection record may be what is damaged
        self._connections: dict[int, Ros1Connection] = {}

    def messages(self) -> Iterator[RawMessage]:
        from rosbags.rosbag1 import Reader, ReaderError

        reader = Reader(self.path)
        try:
            reader.open()
        except Exception as exc:  # rosbags raises struct.error too, where a length field is damaged
            head = _first_line(self.path)
            if head.startswith("#ROSBAG V") and head != "#ROSBAG V2.0":  # rosbags says "version 102" for V1.2
                raise LogReadError(f"{self.path}: a ROS1 bag of format {head[9:]!r}; only format 2.0 is read "
                                   "(ROS 1's `rosbag filter IN OUT True` rewrites it as 2.0)") from exc
            if isinstance(exc, ReaderError) and any(w in str(exc) for w in ("magic", "empty", "version")):
                raise LogReadError(f"{self.path}: not a readable ROS1 bag ({exc})") from exc
            self.stats.warnings.append(f"{self.path}: ROS1 bag index unusable ({_why(exc)}); read chunk by chunk as "
                                       "`rosbag reindex` does")
            yield from self._scan()
            return
        try:
            channels = self._index_channels(reader)
            broken = self._chunk_break(reader)
            if broken:  # its record lengths are what rosbags would trust: the scan reads it without them
                self.stats.warnings.append(f"{self.path}: ROS1 bag damaged: {broken}; read chunk by chunk as "
                                           "`rosbag reindex` does")
                self._indexed = _index_entries(reader)
                yield from self._scan()
                return
            total = sum(c.msgcount for c in reader.connections) or 1
            it = reader.messages()
            n = 0
            while True:
                try:
                    conn, t_ns, data = next(it)
                except StopIteration:
                    self.stats.bytes_read = self.stats.bytes_total
                    return
                except Exception as exc:  # damaged chunk (or index pointing at garbage): rescan the file
                    self.stats.warnings.append(f"{self.path}: ROS1 bag damaged after {n} messages read through "
                                               f"its index ({_why(exc)}); the rest read chunk by chunk")
                    self._indexed = _index_entries(reader)
                    break
                n += 1
                ch = channels[conn.id]
                self._yielded[(conn.id, t_ns)] += 1
                self.stats.counts[ch.key] = self.stats.counts.get(ch.key, 0) + 1
                self.stats.messages = n
                if n % 256 == 0:
                    self.stats.bytes_read = int(self.stats.bytes_total * n / total)
                yield RawMessage(ch, t_ns, data)
        finally:
            reader.close()
        yield from self._scan()

    def _against_index(self, msg: Ros1Message, conn: int, t_ns: int, first_ns: int, end_ns: int
                       ) -> Ros1Message | None:
        """The message whose record's connection or time disagrees with its entry in the index (one of the two copies
        damaged; nothing checks either): read at the time of the copy that lies in its chunk's time span (a third
        copy, in the chunk's info record; the record's where both or neither do), or left out where the connections
        disagree (its data may be another type's); noted for a warning."""
        where = f"the chunk at byte {msg.chunk_offset}, offset {msg.offset}"
        record_in, index_in = first_ns <= msg.t_ns < end_ns, first_ns <= t_ns < end_ns
        if conn != msg.conn_id:
            how, kept = "left out (their connections differ: which is damaged cannot be told)", None
        elif record_in == index_in:
            how = "read at the record's time (both lie in their chunk's span: which is damaged cannot be told)"
            kept = msg
            where += f": {msg.t_ns} ns, the index {t_ns} ns"
        elif record_in:
            how, kept = "read at the record's time, the index's lying outside its chunk's span", msg
        else:
            how = "read at the index's time, the record's lying outside its chunk's span"
            kept = Ros1Message(msg.conn_id, t_ns, msg.data, msg.chunk_offset, msg.offset)
        self._disagree.setdefault(how, []).append(where)
        return kept

    def _chunk_break(self, reader: Any) -> str | None:
        """The first uncompressed chunk whose records do not chain as their lengths and the index say
        (:func:`chain_break`), named; None if none."""
        offsets: dict[int, list[int]] = {}
        for entries in reader.indexes.values():
            for e in entries:
                offsets.setdefault(e.chunk_pos, []).append(e.offset)
        with open(self.path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
            for pos in sorted(reader.chunks):
                why = chain_break(buf, pos, offsets.get(pos, ()))
                if why:
                    return f"the chunk at byte {pos}: {why}"
        return None

    def _index_channels(self, reader: Any) -> dict[int, Channel]:
        """The channels of the connections rosbags' ``reader`` read from the bag's index, each checked against its
        copy in the first chunk holding its messages (:func:`reconcile`), by connection id."""
        first: dict[int, int] = {}
        for info in sorted(reader.chunk_infos, key=lambda i: i.pos):
            for conn_id in info.connection_counts:
                first.setdefault(conn_id, info.pos)
        with open(self.path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
            copies = chunk_copies(buf, first.items())
        channels = {}
        for conn in reader.connections:
            chunk, pos = copies.get(conn.id, (None, 0))
            c, disagree = reconcile(Ros1Connection(conn.id, conn.topic, conn.msgtype, conn.msgdef.data, conn.digest),
                                    chunk, pos, str(self.path))
            self._connections[conn.id] = c
            c, renamed = near_known_type(c, str(self.path))
            self.stats.warnings += [w for w in (disagree, renamed) if w]
            channels[conn.id] = Channel((str(self.path), conn.id), ros1_topic(c.topic), normalise_type(c.msgtype),
                                        "ros1", c.msgdef, "ros1msg", conn.msgcount)
        return channels

    def _index_offsets(self) -> dict[int, list[int]]:
        """Chunk byte offset -> its message records' offsets in its data, ascending, as the index gives them."""
        offsets: dict[int, list[int]] = {}
        for chunk_pos, offset in sorted(self._indexed):
            offsets.setdefault(chunk_pos, []).append(offset)
        return offsets

    def _scan(self) -> Iterator[RawMessage]:
        """Every message of every intact chunk not yet delivered through the index."""
        report = ScanReport()
        conns: dict[int, Ros1Connection] = dict(self._connections)
        channels: dict[int, Channel] = {}
        with open(self.path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
            try:
                for msg in scan_bag(buf, report, conns, self._index_offsets()):
                    said = self._indexed.get((msg.chunk_offset, msg.offset))
                    if said is not None and said[:2] != (msg.conn_id, msg.t_ns):
                        msg = self._against_index(msg, *said)
                        if msg is None:
                            continue
                    key = (msg.conn_id, msg.t_ns)
                    if self._yielded[key] > 0:
                        self._yielded[key] -= 1
                        continue
                    ch = channels.get(msg.conn_id)
                    if ch is None:
                        c, renamed = near_known_type(conns[msg.conn_id], str(self.path))
                        if renamed:
                            self.stats.warnings.append(renamed)
                        ch = channels[msg.conn_id] = Channel((str(self.path), c.conn_id), ros1_topic(c.topic),
                                                             normalise_type(c.msgtype), "ros1", c.msgdef, "ros1msg")
                    self.stats.messages += 1
                    self.stats.counts[ch.key] = self.stats.counts.get(ch.key, 0) + 1
                    self.stats.bytes_read = msg.chunk_offset
                    yield RawMessage(ch, msg.t_ns, msg.data)
            except RecordError as exc:
                raise LogReadError(f"{self.path}: not a readable ROS1 bag ({exc})") from exc
        self.stats.bytes_read = self.stats.bytes_total
        for lost in report.lost:
            self.stats.warnings.append(f"{self.path}: damaged ROS1 bag: {lost}")
        for how, where in self._disagree.items():
            self.stats.warnings.append(f"{self.path}: damaged ROS1 bag: {len(where)} message record"
                                       f"{'s' * (len(where) > 1)} whose connection or time disagrees with the index's "
                                       f"entry ({', '.join(where[:3])}{', ...' * (len(where) > 3)}): {how}")
        self.stats.warnings.append(f"{self.path}: {report.chunks_read} intact chunks read without the index "
                                   f"({self.stats.messages} messages in all)")


def _read_metadata(path: Path) -> dict[str, Any]:
    meta_path = path / "metadata.yaml"
    if not meta_path.exists():
        raise LogReadError(f"{path}: no metadata.yaml (ros2 bag record writes it last: a recording that did not "
                           "finish)")
    try:
        meta = yaml.safe_load(meta_path.read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
        meta["relative_file_paths"]  # noqa: B018  (required key)
        meta["storage_identifier"]  # noqa: B018
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError) as exc:  # ValueError: not UTF-8
        said = " ".join(str(exc).split())  # YAML's own message runs over lines, with a drawing of the place
        raise LogReadError(f"{meta_path}: not a valid rosbag2 metadata file ({said[:200]})") from exc
    return meta


def _declared_counts(meta: dict[str, Any]) -> dict[str, int]:
    out: dict[str, int] = {}
    for entry in meta.get("topics_with_message_count") or []:
        out[entry["topic_metadata"]["name"]] = int(entry.get("message_count", 0))
    return out


class Rosbag2McapSource:
    """A rosbag2 directory with MCAP storage: its files in order, counts checked against metadata.yaml."""

    container = "rosbag2"

    def __init__(self, path: Path, meta: dict[str, Any]) -> None:
        self.path = path
        self.files = [path / PurePath(p).name for p in meta["relative_file_paths"]]
        self.declared = _declared_counts(meta)
        self.stats = ReadStats(bytes_total=sum(p.stat().st_size for p in self.files if p.exists()))
        self.keep_unverified = False  #: as McapSource's, for each of its files

    def messages(self) -> Iterator[RawMessage]:
        done = 0
        seen: dict[str, int] = {}
        for file in self.files:
            if not file.exists():
                self.stats.warnings.append(f"{self.path}: storage file {file.name} listed in metadata.yaml is missing")
                continue
            src = McapSource(file, declared={}, keep_unverified=self.keep_unverified)
            for msg in src.messages():
                seen[msg.channel.topic] = seen.get(msg.channel.topic, 0) + 1
                self.stats.bytes_read = done + src.stats.bytes_read
                self.stats.messages += 1
                yield msg
            done += src.stats.bytes_total
            self.stats.warnings.extend(src.stats.warnings)
            self.stats.counts.update(src.stats.counts)
        self.stats.bytes_read = done
        _check_declared(self.path, self.declared, seen, self.stats)


def _check_declared(path: Path, declared: dict[str, int], seen: dict[str, int], stats: ReadStats) -> None:
    for topic, n in declared.items():
        if seen.get(topic, 0) < n:
            stats.warnings.append(f"{path}: topic {topic}: read {seen.get(topic, 0)} of the {n} messages "
                                  "metadata.yaml declares")


class Rosbag2SqliteSource:
    """A rosbag2 directory with sqlite3 storage, read with rosbags; direct SQL when rosbags comes up short."""

    container = "rosbag2"

    def __init__(self, path: Path, meta: dict[str, Any], *, direct: bool = False) -> None:
        self.path = path
        self.meta = meta
        self.files = [path / PurePath(p).name for p in meta["relative_file_paths"]]
        #: read these files with SQL, not the whole bag with rosbags (one storage file given on its own)
        self.direct = direct
        self.declared = _declared_counts(meta)
        self.stats = ReadStats(bytes_total=sum(p.stat().st_size for p in self.files if p.exists()))
        self.compressed = (meta.get("compression_mode") or "").lower() == "message"
        if (meta.get("compression_mode") or "").lower() == "file":
            raise LogReadError(f"{path}: file-compressed rosbag2 bags are not supported; decompress it first "
                               "(`ros2 bag convert` or `rosbags-convert`)")

    def _channels(self, db: sqlite3.Connection, file: Path) -> dict[int, Channel]:
        defs: dict[str, tuple[str, str]] = {}
        tables = {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        if "message_definitions" in tables:
            for topic_type, encoding, text in db.execute(
                    "SELECT topic_type, encoding, encoded_message_definition FROM message_definitions"):
                defs[topic_type] = (text, encoding)
        out = {}
        for tid, name, typ, fmt in db.execute("SELECT id, name, type, serialization_format FROM topics"):
            text, enc = defs.get(typ, ("", ""))
            out[tid] = Channel((str(file), tid), name, normalise_type(typ), "cdr" if fmt == "cdr" else fmt, text, enc,
                               self.declared.get(name))
        return out

    def messages(self) -> Iterator[RawMessage]:
        seen: dict[str, int] = {}
        for file in self.files:
            if not file.exists():
                self.stats.warnings.append(f"{self.path}: storage file {file.name} listed in metadata.yaml is missing")
        # rosbags reads the whole bag, and opens its files immutable: blind to a write-ahead log
        if self.direct or any(_wal_of(f) is not None for f in self.files):
            for msg in self._sql_messages(None):
                seen[msg.channel.topic] = seen.get(msg.channel.topic, 0) + 1
                yield msg
            _check_declared(self.path, self.declared, seen, self.stats)
            return
        yielded: Counter[tuple[str, int]] = Counter()  # (topic, t_ns) delivered by rosbags
        try:
            for msg in self._rosbags_messages():
                seen[msg.channel.topic] = seen.get(msg.channel.topic, 0) + 1
                yielded[(msg.channel.topic, msg.log_ns)] += 1
                yield msg
        except LogReadError:
            raise
        except Exception as exc:  # malformed pages, a bad compressed message: read row range by row range
            what = f"after {sum(seen.values())} messages" if seen else "when opened"
            said = " ".join(str(exc).split())[:200]  # one line: a YAML error draws the place over several
            self.stats.warnings.append(f"{self.path}: rosbags failed {what} ({type(exc).__name__}: {said}); "
                                       "the sqlite3 storage is read directly, row range by row range")
            for msg in self._sql_messages(None, skip=yielded):  # every topic the storage holds: metadata may lack some
                seen[msg.channel.topic] = seen.get(msg.channel.topic, 0) + 1
                yield msg
            _check_declared(self.path, self.declared, seen, self.stats)
            return
        # The QoS trap: rosbags matched no connection of these topics. Read them from the storage directly.
        unmatched = {t for t, n in self.declared.items() if n > 0 and t not in seen}
        if unmatched:
            if not seen:
                what = f"no message although metadata.yaml declares {sum(self.declared.values())}"
            else:
                what = (f"no message of {', '.join(sorted(unmatched))} although metadata.yaml declares "
                        f"{sum(self.declared[t] for t in unmatched)}")
            self.stats.warnings.append(f"{self.path}: rosbags yielded {what} (QoS mismatch); read the sqlite3 "
                                       "storage directly")
            for msg in self._sql_messages(unmatched):
                seen[msg.channel.topic] = seen.get(msg.channel.topic, 0) + 1
                yield msg
        # rosbags knows the topics metadata.yaml lists; a damaged or hand-edited one may leave some out
        unlisted = self._storage_topics() - set(self.declared) - set(seen)
        if unlisted:
            found: Counter[str] = Counter()
            for msg in self._sql_messages(unlisted):
                found[msg.channel.topic] += 1
                yield msg
            if found:
                self.stats.warnings.append(f"{self.path}: metadata.yaml does not list " + ", ".join(
                    f"{t} ({n} messages)" for t, n in sorted(found.items())) + "; read from the sqlite3 storage")
        _check_declared(self.path, self.declared, seen, self.stats)

    def _storage_topics(self) -> set[str]:
        """The topics the storage files' own tables hold."""
        out: set[str] = set()
        for file in self.files:
            if not file.exists():
                continue
            db = _read_only(file)
            try:
                out |= {name for (name,) in db.execute("SELECT name FROM topics")}
            except sqlite3.DatabaseError:
                pass  # rosbags read these files: a table it did not need is not this check's to judge
            finally:
                db.close()
        return out

    def _rosbags_messages(self) -> Iterator[RawMessage]:
        from rosbags.rosbag2 import Reader

        reader = Reader(self.path)
        reader.open()
        try:
            channels: dict[int, Channel] = {}
            for conn in reader.connections:
                text = conn.msgdef.data if conn.msgdef else ""
                encoding = ("ros2idl" if conn.msgdef.format.name == "IDL" else "ros2msg") if text else ""
                channels[conn.id] = Channel((str(self.path), conn.id), conn.topic, normalise_type(conn.msgtype),
                                            "cdr", text, encoding, conn.msgcount)
            total = sum(c.msgcount for c in reader.connections) or 1
            for conn, t_ns, data in reader.messages():
                ch = channels[conn.id]
                self.stats.messages += 1
                self.stats.counts[ch.key] = self.stats.counts.get(ch.key, 0) + 1
                if self.stats.messages % 256 == 0:
                    self.stats.bytes_read = int(self.stats.bytes_total * self.stats.messages / total)
                yield RawMessage(ch, t_ns, data)
            self.stats.bytes_read = self.stats.bytes_total
        finally:
            reader.close()

    def _sql_messages(self, topics: set[str] | None,
                      skip: Counter[tuple[str, int]] | None = None) -> Iterator[RawMessage]:
        """The messages of ``topics`` (None: all), straight from the sqlite3 storage files, less ``skip``.

        The files are opened immutable (nothing is written next to them, read-only media work) and read in
        row-id ranges, so a malformed page costs only the rows on it.
        """
        import zstandard

        dctx = zstandard.ZstdDecompressor() if self.compressed else None
        skip = skip if skip is not None else Counter()
        for file in self.files:
            if not file.exists():
                continue
            db = _open_storage(file, self.stats.warnings)
            try:
                try:
                    channels = {tid: ch for tid, ch in self._channels(db, file).items()
                                if topics is None or ch.topic in topics}
                except sqlite3.DatabaseError as exc:
                    raise LogReadError(f"{file}: cannot read the rosbag2 topics table ({exc})") from exc
                if not channels:
                    continue
                bad_rows: list[tuple[int, int]] = []
                bad_data: Counter[str] = Counter()
                for row_id, tid, t_ns, data in _rows(db, file, sum(self.declared.values()), bad_rows):
                    ch = channels.get(tid)
                    if ch is None:
                        continue
                    if skip[(ch.topic, t_ns)] > 0:
                        skip[(ch.topic, t_ns)] -= 1
                        continue
                    if dctx is not None:
                        try:
                            data = dctx.decompress(data)
                        except zstandard.ZstdError as exc:
                            if not bad_data:
                                self.stats.warnings.append(f"{file}: row {row_id} (topic {ch.topic}) does not "
                                                           f"decompress ({exc}); skipped")
                            bad_data[ch.topic] += 1
                            continue
                    self.stats.messages += 1
                    self.stats.counts[ch.key] = self.stats.counts.get(ch.key, 0) + 1
                    yield RawMessage(ch, t_ns, data)
                if bad_rows:
                    spans = ", ".join(f"{a}-{b}" for a, b in bad_rows[:8]) + (" ..." if len(bad_rows) > 8 else "")
                    n = sum(b - a + 1 for a, b in bad_rows)
                    self.stats.warnings.append(f"{file}: damaged sqlite3 storage: {n} message row ids unreadable "
                                               f"(ids {spans}); every other row was read")
                if bad_data:
                    self.stats.warnings.append(f"{file}: {sum(bad_data.values())} compressed messages do not "
                                               "decompress: " + ", ".join(f"{t} ×{n}" for t, n in bad_data.items()))
            finally:
                db.close()
        self.stats.bytes_read = self.stats.bytes_total


_ROW_BATCH = 512


_SQLITE_MAGIC = b"SQLite format 3\x00"


def _read_only(file: Path) -> sqlite3.Connection:
    """The sqlite3 file opened read-only and immutable: nothing is written beside it, read-only media work."""
    return sqlite3.connect(f"file:{quote(str(file.resolve()))}?mode=ro&immutable=1", uri=True)


def _open_storage(file: Path, warnings: list[str]) -> sqlite3.Connection:
    """The sqlite3 file opened read-only and immutable; with its write-ahead log's committed pages, where it has
    one (:mod:`.sqlite_wal`), and a truncated one padded, from a copy in memory.

    A truncated file's schema points at pages past its end, which makes sqlite refuse the whole file;
    padded with zero pages to the size its header declares, only the lost pages' rows are unreadable.
    """
    data = _with_wal(file, warnings)
    if data is None:
        db = _read_only(file)
    else:
        db = sqlite3.connect(":memory:")
        db.deserialize(data)
    try:
        db.execute("SELECT name FROM sqlite_master").fetchall()
        return db
    except sqlite3.DatabaseError as exc:
        db.close()
        reason = exc
    data = data if data is not None else file.read_bytes()
    if len(data) < 100 or not data.startswith(_SQLITE_MAGIC):
        raise LogReadError(f"{file}: not a readable sqlite3 file ({reason})")
    page_size = int.from_bytes(data[16:18], "big")
    page_size = 65536 if page_size == 1 else page_size
    pages = int.from_bytes(data[28:32], "big")
    declared = pages * page_size
    warnings.append(f"{file}: damaged sqlite3 storage: {len(data)} bytes, its header declares {declared} ({reason}); "
                    "read what its pages hold")
    try:
        return _padded_copy(data, max(declared, -(-len(data) // page_size) * page_size))
    except sqlite3.DatabaseError as exc:
        raise LogReadError(f"{file}: not a readable sqlite3 file ({exc})") from None


def _padded_copy(data: bytes, size: int) -> sqlite3.Connection:
    """``data`` padded with zero pages to ``size`` bytes (where the file system takes it), opened read-only: in a
    sparse temporary file, so that the padding takes neither memory nor disk, unlinked once open."""
    fd, name = tempfile.mkstemp(prefix="autosar-sqlite-", suffix=".db3")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            try:
                f.truncate(size)
            except OSError:  # a size no file here may have: the header's page count is itself damaged
                pass
        db = _read_only(Path(name))
        try:
            db.execute("SELECT name FROM sqlite_master").fetchall()  # opens the file before it is unlinked
        except sqlite3.DatabaseError:
            db.close()
            raise
        return db
    finally:
        os.unlink(name)


def _wal_of(file: Path) -> Path | None:
    """The non-empty write-ahead log beside a sqlite3 storage file, if there is one."""
    wal = file.with_name(file.name + "-wal")
    return wal if wal.is_file() and wal.stat().st_size > 0 else None


def _with_wal(file: Path, warnings: list[str]) -> bytes | None:
    """``file``'s bytes with its ``-wal`` log's committed transactions in place, if it has one that holds any."""
    wal = _wal_of(file)
    if wal is None:
        return None
    applied = apply_wal(file.read_bytes(), wal.read_bytes())
    if applied is None:
        warnings.append(f"{wal}: write-ahead log beside {file.name} holds no committed transaction; the file read "
                        "as it is")
        return None
    left = (f"; its last {applied.frames_left} frames, of a transaction that never committed, left out"
            if applied.frames_left else "")
    warnings.append(f"{file}: its write-ahead log {wal.name} held {applied.frames_applied} committed pages (a "
                    f"recording that stopped before its last checkpoint): read with them{left}")
    return applied.image


def _rows(db: sqlite3.Connection, file: Path, hint: int,
          bad: list[tuple[int, int]]) -> Iterator[tuple[int, int, int, bytes]]:
    """(id, topic_id, timestamp, data) of every readable message row, in id order; unreadable ids go to ``bad``.

    Rows the b-tree cannot reach (a malformed or missing interior page) are looked up in the file's
    table-leaf pages (:mod:`.sqlite_pages`). ``hint``: the message count metadata.yaml declares, the last
    id when the table's own end is unreadable.
    """
    try:
        (last,) = db.execute("SELECT max(id) FROM messages").fetchone()
    except sqlite3.DatabaseError:
        last = None
    leaves: dict[int, tuple[int, int, int, bytes]] | None = None
    if last is None or (hint and last > 4 * hint + _ROW_BATCH):  # unreadable, or a damaged b-tree's garbage
        last = hint
        if not hint:  # no declared count either: the highest id the leaf pages hold
            leaves = _message_leaves(file)
            last = max(leaves, default=0)
    query = "SELECT id, topic_id, timestamp, data FROM messages WHERE id >= ? AND id < ? ORDER BY id"
    for lo in range(0, last + 1, _ROW_BATCH):
        hi = min(lo + _ROW_BATCH, last + 1)
        try:
            yield from db.execute(query, (lo, hi)).fetchall()
            continue
        except sqlite3.DatabaseError:
            pass
        for i in range(max(lo, 1), hi):  # one by one: a bad page costs only its own rows
            try:
                yield from db.execute(query, (i, i + 1)).fetchall()
                continue
            except sqlite3.DatabaseError:
                pass
            if leaves is None:
                leaves = _message_leaves(file)
            if i in leaves:
                yield leaves[i]
            elif bad and bad[-1][1] == i - 1:
                bad[-1] = (bad[-1][0], i)
            else:
                bad.append((i, i))


def _message_leaves(file: Path) -> dict[int, tuple[int, int, int, bytes]]:
    """id -> row of every intact rosbag2 message row in the file's table-leaf pages."""
    out: dict[int, tuple[int, int, int, bytes]] = {}
    for rowid, v in table_leaf_rows(file.read_bytes()):
        # the messages table's shape: (id as rowid alias, topic_id, timestamp, data)
        if len(v) == 4 and v[0] is None and isinstance(v[1], int) and isinstance(v[2], int) and \
                isinstance(v[3], bytes):
            out.setdefault(rowid, (rowid, v[1], v[2], v[3]))
    return out


def open_rosbag2(path: Path) -> LogSource:
    try:
        meta = _read_metadata(path)
        lost = ""
    except LogReadError as exc:  # the storage files hold the messages: read them without it
        meta = _metadata_from_files(path, exc)
        lost = str(exc)
    storage = meta["storage_identifier"]
    found = _storage_by_magic([path / PurePath(p).name for p in meta.get("relative_file_paths") or []])
    mislabelled = found is not None and found != storage  # the files are what they are, whatever metadata says
    if mislabelled:
        said, storage = storage, found
        meta = {**meta, "storage_identifier": found}
    src: Rosbag2McapSource | Rosbag2SqliteSource
    if storage == "mcap":
        src = Rosbag2McapSource(path, meta)
    elif storage == "sqlite3":
        src = Rosbag2SqliteSource(path, meta)
    else:
        raise LogReadError(f"{path}: rosbag2 storage {storage!r} is not supported (mcap, sqlite3)")
    if lost:
        src.stats.warnings.append(f"{lost}; read its storage files {', '.join(p.name for p in src.files)} "
                                  "without it (no message counts to check against)")
    if mislabelled:
        src.stats.warnings.append(f"{path}: metadata.yaml says {said!r} storage, its files are {storage}: read "
                                  "as what they are")
    return src


def _storage_by_magic(files: list[Path]) -> str | None:
    """The storage the first of ``files`` there is holds, by its first bytes: "mcap", "sqlite3" or None."""
    for file in files:
        if file.is_file():
            with open(file, "rb") as f:
                head = f.read(16)
            return "mcap" if head.startswith(MCAP_MAGIC) else "sqlite3" if head.startswith(_SQLITE_MAGIC) else None
    return None


def _metadata_from_files(path: Path, exc: LogReadError) -> dict[str, Any]:
    """Stand-in metadata for a bag whose metadata.yaml is unreadable: its storage files, by suffix."""
    for suffix in (".db3", ".mcap"):
        files = sorted(path.glob(f"*{suffix}"))
        if files:
            return _storage_metadata(files)
    raise exc


def _storage_metadata(files: list[Path]) -> dict[str, Any]:
    """Stand-in metadata for storage files of one kind (``.db3`` or ``.mcap``) read without a metadata.yaml."""
    storage = "sqlite3" if files[0].suffix.lower() == ".db3" else "mcap"
    meta: dict[str, Any] = {"relative_file_paths": [f.name for f in files], "storage_identifier": storage}
    if storage == "sqlite3" and _first_payload(files[0]).startswith(_ZSTD_MAGIC):
        meta["compression_mode"], meta["compression_format"] = "message", "zstd"
    return meta


def open_rosbag2_file(path: Path) -> LogSource:
    """One sqlite3 storage file of a rosbag2 bag, read on its own (no metadata.yaml counts to check against);
    where its directory's metadata.yaml lists others, a warning says the bag has more."""
    src = Rosbag2SqliteSource(path.parent, _storage_metadata([path]), direct=True)
    try:
        listed = [PurePath(f).name for f in _read_metadata(path.parent)["relative_file_paths"]]
    except LogReadError:
        listed = []
    if len(listed) > 1 and path.name in listed:
        src.stats.warnings.append(f"{path}: one of the {len(listed)} storage files of the bag {path.parent}; give the "
                                  "directory to read them all")
    return src


_ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"


def _first_payload(file: Path) -> bytes:
    """The first message payload of a sqlite3 storage file (b"" if none can be read)."""
    db = _read_only(file)
    try:
        row = db.execute("SELECT data FROM messages ORDER BY id LIMIT 1").fetchone()
    except sqlite3.DatabaseError:
        row = None
    finally:
        db.close()
    return bytes(row[0]) if row else b""


def _first_line(path: Path) -> str:
    """A bag's version line (``#ROSBAG V2.0``), or what stands there."""
    with open(path, "rb") as f:
        return f.read(16).split(b"\n", 1)[0].decode("ascii", "replace")


def _is_rosbag2(path: Path) -> bool:
    """A rosbag2 bag: its directory (with metadata.yaml, or storage files without it: ``ros2 bag record`` writes it
    last, so a killed recording has none), that metadata.yaml itself, or one of its sqlite3 storage files."""
    if not path.is_dir():
        return path.name == "metadata.yaml" or path.suffix.lower() == ".db3"
    return (path / "metadata.yaml").exists() or any(any(path.glob(f"*{s}")) for s in (".db3", ".mcap"))


# any version: the reader says which it cannot read
register_container("ros1", ".bag", lambda path: not path.is_dir() and path.suffix.lower() == ".bag", Ros1BagSource,
                   magic=b"#ROSBAG V")
register_container("rosbag2", "a rosbag2 directory (or its .db3)", _is_rosbag2,
                   lambda path: open_rosbag2_file(path) if path.suffix.lower() == ".db3"
                   else open_rosbag2(path.parent if path.name == "metadata.yaml" else path))
