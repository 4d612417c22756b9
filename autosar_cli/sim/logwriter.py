"""Streaming, atomic, deterministic log writers for MCAP, ROS 1 bags and rosbag2 directories.

All three containers sit behind one small interface (:class:`LogWriter`)::

    with open_log_writer(Path("drive.mcap"), "mcap") as log:
        ts = log.typestore                                  # build messages with THIS type store
        log.add_topic("/radar/raw", msgs.RAW_FRAME)
        log.write("/radar/raw", t_ns, ts.types[msgs.RAW_FRAME](header=msgs.header(ts, t_ns, "radar"), ...))

Formats
    ``"mcap"``  one ``.mcap`` file, ``ros2`` profile, ``ros2msg`` schemas (full definition including
                dependencies), ``cdr`` channels, chunked (4 MiB), zstd/lz4/uncompressed chunks.
    ``"ros1"``  ROS 1 bag v2.0 (``rosbags.rosbag1.Writer``), ROS 1 serialisation, lz4/bz2/no chunk
                compression. Bag v2.0 has no zstd: the default ``compression="zstd"`` selects lz4.
    ``"ros2"``  rosbag2 directory, metadata version 9, CDR, storage ``sqlite3`` (default) or ``mcap``.
                ``compression="zstd"`` compresses per message (sqlite3, rosbag2 ``message`` mode) or
                per chunk (mcap storage); ``"none"`` disables it. rosbag2 knows no lz4/bz2.

Messages are rosbags message objects of the writer's type store: ``typestore_for(2)`` for ``mcap``
and ``ros2``, ``typestore_for(1)`` (headers with ``seq``) for ``ros1``; :attr:`LogWriter.typestore`
is that store (a message of the right type name from another store is accepted if it serialises).
A message of another type raises :class:`TypeError`.

Guarantees
    * Never overwrites: an existing output path raises :class:`FileExistsError`.
    * Atomic: output goes to the sibling ``<name>.partial`` (file, or for ``ros2`` a staging directory
      holding ``<name>/``) and is renamed to the final path only by :meth:`LogWriter.close`. An
      exception escaping the ``with`` block (or :meth:`LogWriter.abort`) removes the partial output.
    * Deterministic: the same topics and messages in the same order give byte-identical files
      (``.mcap``; ``.bag``; for ``ros2`` the ``.db3``/``.mcap`` storage file and ``metadata.yaml``).
      No writer used here records wall-clock time; only library version strings are embedded.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import shutil
import struct
from dataclasses import dataclass
from io import StringIO
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, Protocol, runtime_checkable

from autosar_cli.msgs import typestore_for

if TYPE_CHECKING:
    from types import TracebackType

    from rosbags.interfaces import Qos
    from rosbags.typesys.store import Typestore

log = logging.getLogger(__name__)

LogFormat = Literal["mcap", "ros1", "ros2"]
LOG_FORMATS: tuple[str, ...] = ("mcap", "ros1", "ros2")
Ros2Storage = Literal["sqlite3", "mcap"]

MCAP_CHUNK_SIZE = 4 * 1024 * 1024
ROS1_CHUNK_SIZE = 1024 * 1024  # rosbags' default; rosbag's own default is 768 KiB
PARTIAL_SUFFIX = ".partial"
_MAX_TIME_NS = 2**63 - 1

_COMPRESSIONS: dict[str, tuple[str, ...]] = {
    "mcap": ("zstd", "lz4", "none"),
    "ros1": ("zstd", "lz4", "bz2", "none"),
    "ros2": ("zstd", "none"),
}


@runtime_checkable
class LogWriter(Protocol):
    """A streaming writer of one log; use as a context manager (``close`` on success, else ``abort``)."""

    path: Path
    """Final output path (exists only after a successful :meth:`close`)."""
    ros_version: int
    """1 for ``ros1``; 2 for ``mcap`` and ``ros2``."""
    typestore: Typestore
    """Type store whose message classes :meth:`write` accepts (``typestore_for(ros_version)``)."""

    def add_topic(self, topic: str, msgtype: str) -> None:
        """Declare ``topic`` carrying ``msgtype`` (e.g. ``"sensor_msgs/msg/Imu"``); repeats are no-ops."""
        ...

    def write(self, topic: str, log_time_ns: int, msg: object) -> None:
        """Append ``msg`` (a message object of the topic's type) recorded at ``log_time_ns``."""
        ...

    def close(self) -> None:
        """Finish the container and move it to :attr:`path`; idempotent."""
        ...

    def abort(self) -> None:
        """Discard everything written; leaves nothing at :attr:`path`; idempotent."""
        ...

    def __enter__(self) -> LogWriter: ...

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...


def default_qos() -> list[Qos]:
    """Offered QoS written for every rosbag2 topic: reliable, keep_last 10, volatile, default timings."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    zero = QosTime(0, 0)  # 0 s = "unspecified" (infinite) deadline/lifespan/lease, as rclcpp defaults
    return [
        Qos(
            history=QosHistory.KEEP_LAST,
            depth=10,
            reliability=QosReliability.RELIABLE,
            durability=QosDurability.VOLATILE,
            deadline=zero,
            lifespan=zero,
            liveliness=QosLiveliness.AUTOMATIC,
            liveliness_lease_duration=zero,
            avoid_ros_namespace_conventions=False,
        )
    ]


def qos_yaml(profiles: list[Qos]) -> str:
    """The QoS list as rosbag2 (v9) stores it in its storage: a YAML string, as rosbags writes it."""
    from rosbags.rosbag2.metadata import dump_qos_v9
    from ruamel.yaml import YAML

    stream = StringIO()
    yaml = YAML(typ="safe")
    yaml.default_flow_style = False
    yaml.dump(dump_qos_v9(profiles), stream)
    return stream.getvalue().strip()


def partial_path(path: Path) -> Path:
    """The temporary sibling a writer for ``path`` writes to before :meth:`LogWriter.close`."""
    return path.with_name(path.name + PARTIAL_SUFFIX)


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    elif path.exists() or path.is_symlink():
        path.unlink()


@dataclass(eq=False)
class _Topic:
    name: str
    msgtype: str
    cls: type
    handle: Any
    count: int = 0


class _BaseWriter:
    """Shared bookkeeping: topic registry, type checks, partial/final path handling."""

    fmt: str
    ros_version: int

    def __init__(self, path: Path, replace: bool = False) -> None:
        self.path = Path(path)
        self._replace = replace  # a file at ``path`` (checked by the caller as one autosar wrote) is replaced
        if (self.path.exists() or self.path.is_symlink()) and not replace:
            raise FileExistsError(errno.EEXIST, "log output exists, refusing to overwrite", str(self.path))
        if not self.path.parent.is_dir():
            raise FileNotFoundError(errno.ENOENT, "output directory does not exist", str(self.path.parent))
        self._partial = partial_path(self.path)
        if self._partial.exists() or self._partial.is_symlink():
            log.warning("removing stale partial output %s (left by an interrupted run)", self._partial)
            _remove(self._partial)
        self.typestore: Typestore = typestore_for(self.ros_version)
        self._topics: dict[str, _Topic] = {}
        self._state = "open"

    # -- backend hooks
    def _add(self, topic: str, msgtype: str) -> Any:
        raise NotImplementedError

    def _write(self, t: _Topic, log_time_ns: int, msg: object) -> None:
        raise NotImplementedError

    def _finish(self) -> None:
        """Finalise the container inside the partial path."""
        raise NotImplementedError

    def _discard(self) -> None:
        """Release open handles without finalising."""
        raise NotImplementedError

    def _publish(self) -> None:
        """Move the finished partial output to the final path (never clobbering, unless told to replace)."""
        if self._replace and self.path.is_file():
            os.replace(self._partial, self.path)
            return
        if self.path.exists() or self.path.is_symlink():
            raise FileExistsError(
                errno.EEXIST,
                f"log output appeared while writing; finished log kept at {self._partial}",
                str(self.path),
            )
        try:  # hard link + unlink: atomic and fails instead of replacing a file created meanwhile
            os.link(self._partial, self.path)
        except OSError as err:
            if err.errno == errno.EEXIST:
                raise
            os.replace(self._partial, self.path)
        else:
            self._partial.unlink()

    # -- public API
    @property
    def topics(self) -> dict[str, str]:
        """``{topic: msgtype}`` in the order added."""
        return {name: t.msgtype for name, t in self._topics.items()}

    @property
    def message_counts(self) -> dict[str, int]:
        """``{topic: messages written so far}``."""
        return {name: t.count for name, t in self._topics.items()}

    def add_topic(self, topic: str, msgtype: str) -> None:
        self._check_open()
        if (existing := self._topics.get(topic)) is not None:
            if existing.msgtype != msgtype:
                raise ValueError(f"topic {topic!r} already added with type {existing.msgtype}, not {msgtype}")
            return
        try:
            cls = self.typestore.types[msgtype]
        except KeyError:
            raise ValueError(f"unknown message type {msgtype!r} for ROS {self.ros_version}") from None
        self._topics[topic] = _Topic(topic, msgtype, cls, self._add(topic, msgtype))

    def write(self, topic: str, log_time_ns: int, msg: object) -> None:
        if self._state != "open":
            self._check_open()
        try:
            t = self._topics[topic]
        except KeyError:
            raise KeyError(f"topic {topic!r} was not added (call add_topic first)") from None
        log_time_ns = int(log_time_ns)
        if not 0 <= log_time_ns <= _MAX_TIME_NS:
            raise ValueError(f"log time {log_time_ns} ns out of range")
        if type(msg) is t.cls:
            self._write(t, log_time_ns, msg)
        else:  # same type name from another type store is fine if it serialises; else explain
            if getattr(msg, "__msgtype__", None) != t.msgtype:
                raise TypeError(f"topic {topic!r} carries {t.msgtype}, got {type(msg).__qualname__}")
            try:
                self._write(t, log_time_ns, msg)
            except (AttributeError, TypeError, ValueError, struct.error) as err:
                raise TypeError(
                    f"cannot serialise {t.msgtype} for topic {topic!r} with the ROS {self.ros_version} type "
                    f"store; build messages with writer.typestore ({err})"
                ) from err
        t.count += 1

    def close(self) -> None:
        if self._state != "open":
            if self._state == "failed":
                raise RuntimeError(f"log writer for {self.path} failed; nothing was written")
            return
        try:
            self._finish()
        except BaseException:
            self.abort()
            raise
        self._state = "closed"
        self._publish()  # on failure the finished output stays at the partial path (named in the error)

    def abort(self) -> None:
        if self._state != "open":
            return
        self._state = "failed"
        try:
            with contextlib.suppress(Exception):
                self._discard()
        finally:
            _remove(self._partial)

    def _check_open(self) -> None:
        if self._state != "open":
            raise RuntimeError(f"log writer for {self.path} is {self._state}")

    def __enter__(self) -> _BaseWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.fmt} {str(self.path)!r} {self._state}>"


class McapLogWriter(_BaseWriter):
    """Plain MCAP file (``ros2`` profile, ``ros2msg`` schemas, ``cdr`` messages)."""

    fmt = "mcap"
    ros_version = 2

    def __init__(self, path: Path, *, compression: str = "zstd", chunk_size: int = MCAP_CHUNK_SIZE,
                 replace: bool = False) -> None:
        from mcap.writer import LIBRARY_IDENTIFIER, CompressionType, Writer

        super().__init__(path, replace)
        ctype = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
        self._schemas: dict[str, int] = {}
        self._qos_metadata = {"offered_qos_profiles": qos_yaml(default_qos())}
        self._file = open(self._partial, "xb", buffering=1024 * 1024)  # closed in _finish/_discard
        try:
            self._writer = Writer(self._file, chunk_size=chunk_size, compression=ctype[compression])
            self._writer.start(profile="ros2", library=f"autosar_cli logwriter; {LIBRARY_IDENTIFIER}")
        except BaseException:
            self.abort()
            raise

    def _add(self, topic: str, msgtype: str) -> Any:
        if (schema_id := self._schemas.get(msgtype)) is None:
            msgdef, _ = self.typestore.generate_msgdef(msgtype, ros_version=2)
            schema_id = self._writer.register_schema(name=msgtype, encoding="ros2msg", data=msgdef.encode())
            self._schemas[msgtype] = schema_id
        return self._writer.register_channel(
            topic=topic, message_encoding="cdr", schema_id=schema_id, metadata=dict(self._qos_metadata)
        )

    def _write(self, t: _Topic, log_time_ns: int, msg: object) -> None:
        data = self.typestore.serialize_cdr(msg, t.msgtype)
        self._writer.add_message(
            channel_id=t.handle,
            log_time=log_time_ns,
            data=data,
            publish_time=log_time_ns,
            sequence=t.count & 0xFFFFFFFF,
        )

    def _finish(self) -> None:
        self._writer.finish()
        self._file.close()

    def _discard(self) -> None:
        self._file.close()


class Ros1LogWriter(_BaseWriter):
    """ROS 1 bag v2.0."""

    fmt = "ros1"
    ros_version = 1

    def __init__(self, path: Path, *, compression: str = "zstd", chunk_size: int = ROS1_CHUNK_SIZE,
                 replace: bool = False) -> None:
        from rosbags.rosbag1 import Writer

        super().__init__(path, replace)
        try:
            self._writer = Writer(self._partial)
            self._writer.chunk_threshold = chunk_size
            if compression in ("zstd", "lz4"):  # bag v2.0 has no zstd
                self._writer.set_compression(Writer.CompressionFormat.LZ4)
            elif compression == "bz2":
                self._writer.set_compression(Writer.CompressionFormat.BZ2)
            self._writer.open()
        except BaseException:
            self.abort()
            raise

    def _add(self, topic: str, msgtype: str) -> Any:
        return self._writer.add_connection(topic, msgtype, typestore=self.typestore)

    def _write(self, t: _Topic, log_time_ns: int, msg: object) -> None:
        self._writer.write(t.handle, log_time_ns, self.typestore.serialize_ros1(msg, t.msgtype))

    def _finish(self) -> None:
        self._writer.close()

    def _discard(self) -> None:
        if getattr(self, "_writer", None) is not None:
            self._writer.abort()


class Ros2LogWriter(_BaseWriter):
    """rosbag2 directory (metadata v9, CDR) with sqlite3 or mcap storage.

    The partial output is a staging directory ``<name>.partial/`` holding the bag as ``<name>/``, so the
    storage file is already called ``<name>.db3`` (``.mcap``) when the bag directory is renamed into place.
    """

    fmt = "ros2"
    ros_version = 2

    def __init__(self, path: Path, *, compression: str = "zstd", storage: Ros2Storage = "sqlite3") -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

        plugins = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}
        if storage not in plugins:
            raise ValueError(f"rosbag2 storage must be one of {sorted(plugins)}, got {storage!r}")
        super().__init__(path)
        self.storage = storage
        self._qos = default_qos()
        self._partial.mkdir()
        try:
            self._writer = Writer(self._partial / self.path.name, version=9, storage_plugin=plugins[storage])
            # rosbags writes ``custom_data: null`` when empty; rosbag2 (yaml-cpp) expects a map there
            self._writer.set_custom_data("writer", "autosar_cli.sim.logwriter")
            if compression == "zstd":
                mode = CompressionMode.MESSAGE if storage == "sqlite3" else CompressionMode.STORAGE
                self._writer.set_compression(mode, CompressionFormat.ZSTD)
            self._writer.open()
        except BaseException:
            self.abort()
            raise

    def _add(self, topic: str, msgtype: str) -> Any:
        return self._writer.add_connection(
            topic,
            msgtype,
            typestore=self.typestore,
            serialization_format="cdr",
            offered_qos_profiles=self._qos,
        )

    def _write(self, t: _Topic, log_time_ns: int, msg: object) -> None:
        self._writer.write(t.handle, log_time_ns, self.typestore.serialize_cdr(msg, t.msgtype))

    def _finish(self) -> None:
        self._writer.close()

    def _discard(self) -> None:
        if getattr(self, "_writer", None) is not None:
            self._writer.abort()

    def _publish(self) -> None:
        if self.path.exists() or self.path.is_symlink():
            raise FileExistsError(
                errno.EEXIST,
                f"log output appeared while writing; finished bag kept in {self._partial}",
                str(self.path),
            )
        os.rename(self._partial / self.path.name, self.path)
        self._partial.rmdir()


def open_log_writer(
    path: Path,
    fmt: LogFormat,
    *,
    compression: str = "zstd",
    storage: Ros2Storage = "sqlite3",
    replace: bool = False,
) -> LogWriter:
    """Open a streaming writer of ``fmt`` (``"mcap"``, ``"ros1"``, ``"ros2"``) for ``path``.

    ``compression``: ``"zstd"`` (default: zstd chunks for mcap, lz4 chunks for ros1 bags, zstd per
    message / per chunk for ros2 sqlite3 / mcap storage), ``"lz4"`` (mcap, ros1), ``"bz2"`` (ros1),
    ``"none"``. ``storage`` applies to ``"ros2"`` only. Raises :class:`FileExistsError` if ``path``
    exists (unless ``replace``: a log file is then replaced when the new one is complete) and
    :class:`ValueError` for an unknown format or an unsupported compression.
    """
    path = Path(path)
    if fmt not in _COMPRESSIONS:
        raise ValueError(f"log format must be one of {', '.join(LOG_FORMATS)}, got {fmt!r}")
    if (want := {"mcap": ".mcap", "ros1": ".bag"}.get(fmt)) and path.suffix != want:
        # e.g. rosbags AnyReader treats any path not ending in .bag as a rosbag2 directory
        log.warning("%s log %s does not end in %s; suffix-based readers will miss it", fmt, path, want)
    if compression not in _COMPRESSIONS[fmt]:
        raise ValueError(
            f"compression {compression!r} not supported for {fmt} (choose {', '.join(_COMPRESSIONS[fmt])})"
        )
    if fmt == "mcap":
        return McapLogWriter(path, compression=compression, replace=replace)
    if fmt == "ros1":
        return Ros1LogWriter(path, compression=compression, replace=replace)
    return Ros2LogWriter(path, compression=compression, storage=storage)  # its directory: removed by the caller
