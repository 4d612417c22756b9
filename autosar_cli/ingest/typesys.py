"""Message deserializers per channel, built from the definitions embedded in the log.

A channel's embedded definition wins (it describes the bytes as they were written). Where a log has
none, or it cannot be parsed (e.g. a service-event schema holding ``---``), the project's built-in
definitions (:func:`autosar_cli.msgs.typestore_for`) are used for the types ingest knows; any other
channel is skipped with a warning. A bad channel never takes the whole log down.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from autosar_cli.msgs import typestore_for

from .sources import Channel

Deserializer = Callable[[bytes | memoryview], Any]


class SchemaError(ValueError):
    """A channel cannot be decoded; the message says why."""


class _SameAsBuiltin(Exception):
    pass


class MessageTypes:
    """Caches one deserializer per (encoding, type, definition)."""

    def __init__(self) -> None:
        self._cache: dict[tuple[str, str, str], Deserializer] = {}
        self._parsed: dict[tuple[str, str], Any] = {}
        self.warnings: list[str] = []

    def _parse(self, schema: str, msgtype: str) -> Any:
        """Types of an embedded definition (cached), or the exception parsing it raised."""
        key = (schema, msgtype)
        if key not in self._parsed:
            try:
                self._parsed[key] = get_types_from_msg(schema, msgtype)
            except Exception as exc:  # rosbags raises several types for bad text
                self._parsed[key] = exc
        return self._parsed[key]

    def is_builtin(self, channel: Channel) -> bool:
        """True if the channel is CDR and its embedded definition (if any) equals the built-in one."""
        if channel.encoding != "cdr":
            return False
        builtin = typestore_for(2)
        if channel.msgtype not in builtin.types:
            return False
        if not channel.schema or channel.schema_encoding not in ("ros2msg", ""):
            return not channel.schema
        embedded = self._parse(channel.schema, channel.msgtype)
        if isinstance(embedded, Exception):  # the deserializer falls back to the built-in definition anyway
            return True
        return all(name not in builtin.fielddefs or builtin.fielddefs[name] == fields
                   for name, fields in embedded.items())

    def deserializer(self, channel: Channel) -> Deserializer:
        key = (channel.encoding, channel.msgtype, channel.schema)
        if key not in self._cache:
            self._cache[key] = self._build(channel)
        return self._cache[key]

    def _build(self, ch: Channel) -> Deserializer:
        if ch.encoding not in ("cdr", "ros1"):
            raise SchemaError(f"message encoding {ch.encoding!r} is not supported (cdr, ros1)")
        ros_version = 1 if ch.encoding == "ros1" else 2
        store = None
        if ch.schema and ch.schema_encoding in ("ros2msg", "ros1msg", ""):
            try:
                parsed = self._parse(ch.schema, ch.msgtype)
                if isinstance(parsed, Exception):
                    raise parsed
                if self.is_builtin(ch):  # same definition: the cached built-in store serves it
                    raise _SameAsBuiltin
                store = get_typestore(Stores.EMPTY)
                store.register(parsed)
                if ch.msgtype not in store.types:
                    raise SchemaError(f"definition does not define {ch.msgtype}")
            except _SameAsBuiltin:
                store = None
            except Exception as exc:  # rosbags raises several types for bad text
                store = None
                builtin = typestore_for(ros_version)
                if ch.msgtype not in builtin.types:
                    raise SchemaError(f"unparseable embedded definition ({_one_line(exc)})") from exc
                self.warnings.append(f"topic {ch.topic}: unparseable embedded definition of {ch.msgtype} "
                                     f"({_one_line(exc)}); using the built-in one")
        if store is None:
            store = typestore_for(ros_version)
            if ch.msgtype not in store.types:
                raise SchemaError(f"no definition of {ch.msgtype}")
        typename = ch.msgtype
        if ros_version == 1:
            deser1 = store.deserialize_ros1
            return lambda data: deser1(data, typename)
        deser2 = store.deserialize_cdr
        return lambda data: deser2(data, typename)


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())[:200] or type(exc).__name__
