"""ROS1 bags and rosbag2 directories, read with rosbags (and the MCAP reader for MCAP storage).

rosbag2 traps handled here (see the real-data notes in docs/FORMATS.md):

- rosbags' rosbag2 ``Reader`` matches connections on topic, type *and* QoS; when ``metadata.yaml`` and
  the storage disagree on a topic's QoS it silently yields nothing of that topic. Every topic's count is
  therefore checked against ``metadata.yaml``; the topics rosbags yielded nothing of are read directly
  from the sqlite3 storage with SQL instead.
- MCAP storage files are plain MCAP: they are read with :class:`~.mcap_source.McapSource`, which decodes
  per channel, so one unparseable embedded schema cannot take the whole bag down.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from pathlib import Path, PurePath
from typing import Any

import yaml

from .mcap_source import McapSource
from .sources import (
    Channel,
    LogReadError,
    LogSource,
    RawMessage,
    ReadStats,
    normalise_type,
    register_container,
)


class Ros1BagSource:
    """ROS1 bag v2.0 (indexed). An unindexed or truncated bag is refused with the reason rosbags gives."""

    container = "ros1"

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.stats = ReadStats(bytes_total=self.path.stat().st_size)

    def messages(self) -> Iterator[RawMessage]:
        from rosbags.rosbag1 import Reader, ReaderError

        reader = Reader(self.path)
        try:
            reader.open()
        except ReaderError as exc:
            raise LogReadError(f"{self.path}: cannot open ROS1 bag: {exc} (a truncated or unindexed bag can be "
                               "repaired with `rosbag reindex`)") from exc
        try:
            channels = {}
            for conn in reader.connections:
                channels[conn.id] = Channel((str(self.path), conn.id), conn.topic, normalise_type(conn.msgtype),
                                            "ros1", conn.msgdef.data, "ros1msg", conn.msgcount)
            total = sum(c.msgcount for c in reader.connections) or 1
            it = reader.messages()
            n = 0
            while True:
                try:
                    conn, t_ns, data = next(it)
                except StopIteration:
                    break
                except Exception as exc:  # damaged chunk: keep what was read
                    self.stats.warnings.append(f"{self.path}: damaged ROS1 bag after {n} messages ({exc}); "
                                               "everything before it was read")
                    break
                n += 1
                ch = channels[conn.id]
                self.stats.counts[ch.key] = self.stats.counts.get(ch.key, 0) + 1
                self.stats.messages = n
                if n % 256 == 0:
                    self.stats.bytes_read = int(self.stats.bytes_total * n / total)
                yield RawMessage(ch, t_ns, data)
            self.stats.bytes_read = self.stats.bytes_total
        finally:
            reader.close()


def _read_metadata(path: Path) -> dict[str, Any]:
    meta_path = path / "metadata.yaml"
    try:
        meta = yaml.safe_load(meta_path.read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
        meta["relative_file_paths"]  # noqa: B018  (required key)
        meta["storage_identifier"]  # noqa: B018
    except (OSError, yaml.YAMLError, KeyError, TypeError) as exc:
        raise LogReadError(f"{meta_path}: not a valid rosbag2 metadata file ({exc})") from exc
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

    def messages(self) -> Iterator[RawMessage]:
        done = 0
        seen: dict[str, int] = {}
        for file in self.files:
            if not file.exists():
                self.stats.warnings.append(f"{self.path}: storage file {file.name} listed in metadata.yaml is missing")
                continue
            src = McapSource(file, declared={})
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

    def __init__(self, path: Path, meta: dict[str, Any]) -> None:
        self.path = path
        self.meta = meta
        self.files = [path / PurePath(p).name for p in meta["relative_file_paths"]]
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
        for msg in self._rosbags_messages():
            seen[msg.channel.topic] = seen.get(msg.channel.topic, 0) + 1
            yield msg
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
        _check_declared(self.path, self.declared, seen, self.stats)

    def _rosbags_messages(self) -> Iterator[RawMessage]:
        from rosbags.rosbag2 import Reader

        try:
            reader = Reader(self.path)
            reader.open()
        except Exception as exc:
            raise LogReadError(f"{self.path}: cannot open rosbag2 bag: {exc}") from exc
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

    def _sql_messages(self, topics: set[str]) -> Iterator[RawMessage]:
        """The messages of ``topics``, straight from the sqlite3 storage files."""
        import zstandard

        dctx = zstandard.ZstdDecompressor() if self.compressed else None
        for file in self.files:
            db = sqlite3.connect(f"file:{file}?mode=ro", uri=True)
            try:
                channels = {tid: ch for tid, ch in self._channels(db, file).items() if ch.topic in topics}
                if not channels:
                    continue
                marks = ",".join("?" * len(channels))
                for tid, t_ns, data in db.execute(f"SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN "
                                                  f"({marks}) ORDER BY id", tuple(channels)):
                    ch = channels[tid]
                    if dctx is not None:
                        data = dctx.decompress(data)
                    self.stats.messages += 1
                    self.stats.counts[ch.key] = self.stats.counts.get(ch.key, 0) + 1
                    yield RawMessage(ch, t_ns, data)
            except sqlite3.DatabaseError as exc:
                self.stats.warnings.append(f"{file}: damaged sqlite3 storage ({exc}); everything before it was read")
            finally:
                db.close()
        self.stats.bytes_read = self.stats.bytes_total


def open_rosbag2(path: Path) -> LogSource:
    meta = _read_metadata(path)
    storage = meta["storage_identifier"]
    if storage == "mcap":
        return Rosbag2McapSource(path, meta)
    if storage == "sqlite3":
        return Rosbag2SqliteSource(path, meta)
    raise LogReadError(f"{path}: rosbag2 storage {storage!r} is not supported (mcap, sqlite3)")


def _is_rosbag2(path: Path) -> bool:
    """A rosbag2 bag: its directory (with metadata.yaml) or that metadata.yaml itself."""
    return (path / "metadata.yaml").exists() if path.is_dir() else path.name == "metadata.yaml"


register_container("ros1", ".bag", lambda path: not path.is_dir() and path.suffix.lower() == ".bag", Ros1BagSource)
register_container("rosbag2", "a rosbag2 directory", _is_rosbag2,
                   lambda path: open_rosbag2(path.parent if path.name == "metadata.yaml" else path))
