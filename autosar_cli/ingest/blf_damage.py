"""Damage inside a BLF file (Vector's binary logging format): its damaged log containers left out, the others read.

A BLF is a file header (``LOGG``, its own size, the file's size) and a run of objects, each ``LOBJ``, its header's
size and version, the object's size (the next one begins after it and ``size % 4`` bytes of padding) and type. A
CAN logger's objects are log containers: each a zlib stream (or stored bytes) of inner objects (CAN frames, bus
statistics ...) that run on from one container into the next. python-can reads the containers in turn and stops
at the first whose header is broken or whose stream does not inflate (zlib checks its own stream): every frame
after it was lost; a damaged stream that did not fail it read as zlib made it. Here each container is inflated in
turn (its stream to its end and its checksum); a damaged one, or bytes that hold no object where the next should
begin, are a hole that reaches to the next container that inflates, or to the file's end; a container whose
stated size its stream belies is read to its stream's end. What a damaged stream gives before zlib fails is kept:
its whole objects in time order, less the last two. A file whose end cuts its last container, and is otherwise
whole, is python-can's: it reads that container as far as its stream goes. The reader reads a copy
(:func:`write_blf_without`): each container stored uncompressed, holding whole inner objects (the one a hole
breaks left out), and the file's size in its header the copy's. A file header damaged where python-can looks
(``LOGG``, its size: it refuses the file, or skips every object) is rebuilt in the copy, its other fields kept. A
start time damaged so that it is no date, python-can reads as 0: in a file whose every container is whole it is
the header's stop time less the last object's time (python-can and Vector write the stop time as the last
object's, to the millisecond); else the frames' times are offsets from the measurement's start, which the reader
says.
"""

from __future__ import annotations

import mmap
import struct
import zlib
from collections import deque
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

from can.io.blf import systemtime_to_timestamp, timestamp_to_systemtime

from .records import CutShort, places_said

_FILE_HEADER = struct.Struct("<4sL")  #: "LOGG", the header's size
_FILE_SIZE_AT = 16  #: the header's 8-byte file size
#: the header's 8-byte "uncompressed size": its own size plus each log container's object and container headers
#: and inflated bytes (what the file would hold uncompressed)
_UNCOMPRESSED_SIZE_AT = 24
#: the header's start and stop times (Windows SYSTEMTIME: year, month, weekday, day, hour, minute, second, ms)
_START_AT, _STOP_AT = 40, 56
_SYSTEMTIME = struct.Struct("<8H")
_HEADER_SIZE = 144  #: the file header's size as Vector's and python-can's writers make it
_OBJECT = struct.Struct("<4sHHLL")  #: "LOBJ", header size, header version, object size, object type
_CONTAINER = struct.Struct("<H6xL4x")  #: a log container's compression method and inflated size
_LOG_CONTAINER = 10
_STORED, _DEFLATED = 0, 2
#: an inner object's bytes (a CAN FD frame's is under 200): beyond, a "LOBJ" found after a hole is taken for data
_MAX_INNER_OBJECT = 1 << 16
_SCAN_BYTES = 1 << 24  #: how far past damage the next container is sought
_PADDING = 8  #: bytes a writer may leave after a container's stream
_INFLATE_STEP = 256  #: bytes of a damaged stream inflated at a time
#: an inner object's header: the base, then its flags (its time's unit) and time (the same place in versions 1, 2)
_INNER_HEADER = struct.Struct("<4sHHLLL4xQ")
_TEN_MICROSECONDS, _NANOSECONDS = 1, 2


def blf_damage(path: Path) -> CutShort | None:
    """Where damage inside the BLF file at ``path`` leaves containers to read after it (its holes), or None."""
    with open(path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        if len(buf) < _HEADER_SIZE or (buf[:4] != b"LOGG" and _next_container(buf, 0) is None):
            return None  # no BLF: python-can's error says so
        holes: list[tuple[int, int]] = []
        said: list[str] = []
        why = _header(buf)[1]
        if why is not None:  # a hole of no bytes: the reader's copy, whose header is rebuilt
            holes.append((0, 0))
            said.append(f"its file header {why}: rebuilt, its fields after the first 8 bytes kept")
        if _start_lost(buf) and _whole(buf)[1] is not None:
            holes.append((0, 0))
            said.append("its file header's start time is no date: taken from its stop time less its last object's "
                        "time (to 1 ms)")
        for pos, end, inner, why in _walk(buf):
            if why is None:
                continue
            if inner is not None:  # read on: a container whose stated size its stream belies
                holes.append((end, end))
                said.append(f"the container at byte {pos} {why}: read to there")
            elif end is None:  # the file's end cuts it: python-can reads it as far as its stream goes
                if holes:
                    said.append(f"the container at byte {pos} {why}: read as far as it goes")
            elif end == len(buf):  # its frames would be what zlib made of damaged bytes until it failed
                holes.append((pos, end))
                said.append(f"the container at byte {pos} {why}: damaged there, no container after it, bytes {pos} "
                            f"to {end} left out")
            else:
                holes.append((pos, end))
                said.append(f"the container at byte {pos} {why}: damaged there, bytes {pos} to {end} left out and "
                            "the containers after them read")
    if not holes:
        return None
    return CutShort(places_said(said), damaged=True, holes=tuple(holes))


def holds_every_container(path: Path) -> bool:
    """Whether the BLF file at ``path`` holds every log container its header counts, each undamaged: the header's
    own size and each container's headers and inflated bytes sum to the uncompressed size it states (a file cut
    short lacks some)."""
    with open(path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        return len(buf) >= _HEADER_SIZE and _whole(buf)[0]


def write_blf_without(path: Path, dest: Path) -> None:
    """Write to ``dest`` the BLF file at ``path`` without its damaged containers (:func:`blf_damage`'s holes): its
    containers stored, each holding the inner objects whole (an object a hole breaks is left out), and its
    header's file size the copy's."""
    with open(path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf, open(dest, "wb") as out:
        first, why = _header(buf)
        out.write(buf[:first] if why is None else _FILE_HEADER.pack(b"LOGG", _HEADER_SIZE) + buf[8:_HEADER_SIZE])
        pending = b""  # inner bytes that begin an object the next container ends
        after_hole = False
        for pos, end, inner, why in _walk(buf):
            if why is not None and inner is None:
                inner = _partial(buf, pos, len(buf) if end is None else end)  # as far as its stream goes
                if end is not None:  # damaged: the frames its stream gave in time order, less the last two
                    stream = pending + (inner or b"")
                    _write_container(out, stream[:_in_time_order(stream)])
                    pending, after_hole = b"", True
                    continue
            if inner is None:
                continue
            if after_hole:  # the object the hole broke: its end here is left out with it
                pending, first = b"", _first_object(inner)
                inner, after_hole = (inner[first:] if first is not None else b""), False
            stream = pending + inner
            whole = _whole_objects(stream)
            pending = stream[whole:]
            _write_container(out, stream[:whole])
        out.flush()
        size = out.tell()
        start = _SYSTEMTIME.unpack_from(buf, _START_AT)
        if _start_lost(buf) and (last := _whole(buf)[1]) is not None:
            stop = systemtime_to_timestamp(_SYSTEMTIME.unpack_from(buf, _STOP_AT))
            start = timestamp_to_systemtime(stop - last / 1e9)
    with open(dest, "r+b") as fixed:
        fixed.seek(_FILE_SIZE_AT)
        fixed.write(struct.pack("<Q", size))
        fixed.seek(_START_AT)
        fixed.write(_SYSTEMTIME.pack(*start))


def _write_container(out: BinaryIO, inner: bytes) -> None:
    """A log container of ``inner`` (whole objects), stored, unless there are none."""
    if inner:
        body = _CONTAINER.pack(_STORED, len(inner)) + inner
        size = _OBJECT.size + len(body)
        out.write(_OBJECT.pack(b"LOBJ", _OBJECT.size, 1, size, _LOG_CONTAINER) + body + bytes(size % 4))


class _Cut(str):
    """Why an object is broken off: the file's end cuts it (its bytes so far are whole)."""


#: an object as :func:`_walk` gives it: (its byte, the byte after it (after damage: the next container that
#: inflates, the file's end if none; None: the end cuts it), a container's inner bytes (None: another object, or
#: damage), why it is damaged (with inner bytes: a stated size its stream belies))
Walked = tuple[int, int | None, bytes | None, str | None]


def _header(buf: mmap.mmap) -> tuple[int, str | None]:
    """The byte of the file's first object, and what is damaged in its header (None: nothing python-can reads: its
    signature and its size, which must end where an object begins)."""
    signature, size = _FILE_HEADER.unpack_from(buf, 0)
    if signature == b"LOGG" and (size == _HEADER_SIZE or (
            _HEADER_SIZE < size <= len(buf) and buf[size:size + 4] in (b"LOBJ", b""))):
        return size, None
    first = size if _HEADER_SIZE <= size < len(buf) and buf[size:size + 4] == b"LOBJ" else _HEADER_SIZE
    if signature != b"LOGG":
        return first, f"has no signature (it reads {bytes(signature)!r})"
    return first, f"says it holds {size} bytes"


def _start_lost(buf: mmap.mmap) -> bool:
    """Whether the header's start time is no date (python-can reads it as 0) where its stop time is one."""
    return systemtime_to_timestamp(_SYSTEMTIME.unpack_from(buf, _START_AT)) == 0 != \
        systemtime_to_timestamp(_SYSTEMTIME.unpack_from(buf, _STOP_AT))


def _whole(buf: mmap.mmap) -> tuple[bool, int | None]:
    """Whether every log container the header's uncompressed size counts is here, each undamaged, and if so the
    time (ns from the start) of the last inner object (None: an object's time in no unit known)."""
    first, why = _header(buf)
    total, pending, last = first, b"", None
    known = True
    for pos, _, inner, damaged in _walk(buf):
        if damaged is not None:
            return False, None
        if inner is None:
            continue
        total += _OBJECT.unpack_from(buf, pos)[1] + _CONTAINER.size + len(inner)
        stream = pending + inner
        whole = _whole_objects(stream)
        for _, time in _inner_objects(stream[:whole]):
            known, last = known and time is not None and time >= 0, time
        pending = stream[whole:]
    if why is not None or pending or total != struct.unpack_from("<Q", buf, _UNCOMPRESSED_SIZE_AT)[0]:
        return False, None
    return True, last if known else None


def _walk(buf: mmap.mmap) -> Iterator[Walked]:
    """The file's objects in turn, each damaged stretch as one, to the end or to a cut (its end None)."""
    pos = _header(buf)[0]
    while pos < len(buf):
        found = _object(buf, pos)
        if isinstance(found, str):
            after = _next_container(buf, pos + 1)
            if after is None:  # a cut, or damage to the end
                yield pos, None if isinstance(found, _Cut) else len(buf), None, found
                return
            yield pos, after, None, found
            pos = after
            continue
        yield pos, *found
        pos = found[0]


def _object(buf: mmap.mmap, pos: int) -> tuple[int, bytes | None, str | None] | str:
    """(the byte after it, a container's inner bytes, what was wrong with it) of the object at ``pos``, or why it
    is damaged: a header no object's, an object that runs past the end, a container that does not inflate (to its
    stream's end, the size it says). A container whose stream ends before its stated size does (past the file's
    end or not) is read to its stream's end."""
    if pos + _OBJECT.size > len(buf):
        return _Cut("is cut off in its header")
    signature, header_size, _, size, kind = _OBJECT.unpack_from(buf, pos)
    if signature != b"LOBJ" or size < header_size or header_size < _OBJECT.size:
        return f"has no object header (it reads {bytes(buf[pos:pos + 4])!r})"
    past = _Cut(f"says it holds {size} bytes, past the file's end")
    if kind != _LOG_CONTAINER:
        return past if pos + size > len(buf) else (pos + size + size % 4, None, None)
    body = pos + header_size
    if body + _CONTAINER.size > min(pos + size, len(buf)):
        return past if pos + size > len(buf) else "does not inflate"
    method, inflated_size = _CONTAINER.unpack_from(buf, body)
    data = buf[body + _CONTAINER.size:min(pos + size, len(buf))]
    if method == _STORED:
        return past if pos + size > len(buf) else (pos + size + size % 4, bytes(data), None)
    inflate = zlib.decompressobj()
    try:
        inner = inflate.decompress(data) if method == _DEFLATED else b""
    except zlib.error:
        return "does not inflate"
    if method != _DEFLATED or not inflate.eof or len(inner) != inflated_size:
        return past if pos + size > len(buf) else "does not inflate"
    if pos + size <= len(buf) and len(inflate.unused_data) <= _PADDING:
        return pos + size + size % 4, inner, None
    whole = header_size + _CONTAINER.size + len(data) - len(inflate.unused_data)  # its stream says where it ends
    return pos + whole + whole % 4, inner, f"says it holds {size} bytes, its stream {whole}"


def _partial(buf: mmap.mmap, pos: int, end: int) -> bytes | None:
    """The inner bytes of a broken container (cut by the file's end, or damaged: its bytes up to ``end``) as far as
    its stream inflates; None where its header is no container's."""
    if pos + _OBJECT.size > len(buf):
        return None
    signature, header_size, _, size, kind = _OBJECT.unpack_from(buf, pos)
    body = pos + header_size + _CONTAINER.size
    if signature != b"LOBJ" or kind != _LOG_CONTAINER or body > min(end, len(buf)):
        return None
    method = _CONTAINER.unpack_from(buf, pos + header_size)[0]
    data = buf[body:min(pos + size, end, len(buf))]
    if method == _STORED:
        return bytes(data)
    if method != _DEFLATED:
        return None
    inflate, out = zlib.decompressobj(), []
    for at in range(0, len(data), _INFLATE_STEP):  # in steps: zlib gives nothing of a call that fails
        try:
            out.append(inflate.decompress(data[at:at + _INFLATE_STEP]))
        except zlib.error:
            break
    return b"".join(out)


def _in_time_order(stream: bytes) -> int:
    """The bytes of ``stream`` (beginning with an object) that hold whole objects whose times do not fall, less
    the last two such: what a damaged stream gave before zlib failed, whose end may already be the damage's."""
    ends, last = [], -1
    for end, time in _inner_objects(stream):
        if time is None or time < last:
            break
        ends.append(end)
        last = time
    return ends[-3] if len(ends) > 2 else 0


def _next_container(buf: mmap.mmap, pos: int) -> int | None:
    """The byte of the first log container from ``pos`` on (within :data:`_SCAN_BYTES`) that inflates."""
    stop = min(len(buf), pos + _SCAN_BYTES)
    at = buf.find(b"LOBJ", pos, stop)
    while at >= 0:
        if at + _OBJECT.size <= len(buf) and _OBJECT.unpack_from(buf, at)[4] == _LOG_CONTAINER \
                and not isinstance(_object(buf, at), str):
            return at
        at = buf.find(b"LOBJ", at + 1, stop)
    return None


def _whole_objects(stream: bytes) -> int:
    """The bytes of ``stream`` (beginning with an object) that hold whole objects."""
    last = deque((end for end, _ in _inner_objects(stream)), maxlen=1)
    return last[0] if last else 0


def _inner_objects(stream: bytes) -> Iterator[tuple[int, int | None]]:
    """(the byte after it, its time in ns: -1 in a unit not known, None where its header holds none) of each whole
    inner object of ``stream``, from its start."""
    pos = 0
    while True:
        at = stream.find(b"LOBJ", pos, pos + 8)  # objects are padded to 4 bytes (or 8: python-can's search)
        if at < 0 or at + _OBJECT.size > len(stream):
            return
        _, header_size, _, size, _ = _OBJECT.unpack_from(stream, at)
        if size < _OBJECT.size or at + size > len(stream):
            return
        time = None
        if _INNER_HEADER.size <= header_size <= size:
            flags, stamp = _INNER_HEADER.unpack_from(stream, at)[5:]
            time = stamp * 10_000 if flags == _TEN_MICROSECONDS else stamp if flags == _NANOSECONDS else -1
        yield at + size, time
        pos = at + size


def _first_object(data: bytes) -> int | None:
    """Where the first inner object that begins in ``data`` lies (the bytes before it end an object from a
    container left out): an ``LOBJ`` whose size fits and after which the next object begins, or the data end."""
    at = data.find(b"LOBJ")
    while at >= 0:
        if at + _OBJECT.size <= len(data):
            header_size, size = _OBJECT.unpack_from(data, at)[1], _OBJECT.unpack_from(data, at)[3]
            end = at + size
            if _OBJECT.size <= header_size <= size <= _MAX_INNER_OBJECT and (
                    end + 4 > len(data) or data.find(b"LOBJ", end, end + 8) >= 0):
                return at
        at = data.find(b"LOBJ", at + 1)
    return None
