"""Standalone CAN logs (Vector ASC/BLF, PEAK TRC, SocketCAN candump -L, ASAM MDF4) read with python-can.

:func:`read_can_log` streams :class:`~autosar_cli.ingest.records.CanRecord` in file order. Its time
``t_ns`` is python-can's float ``timestamp`` in seconds rounded to the nearest ns, converted without
the product ``timestamp * 1e9`` (a float near 1.6e18, only 256 ns apart). python-can's float seconds
are themselves 0.24 us apart at present-day epochs, so ``t_ns`` is within 0.12 us of what the file
stores, whatever its resolution.

What python-can 4.6 gives as the timestamp, per format (all Unix seconds unless stated):

- ``.mf4`` (``MF4Reader``): absolute. Header start time (asammdf, UTC-aware) + the per-frame offset in
  seconds. The real CANedge files are from 2022/2023 (t = 1.64e9 / 1.67e9 s); their clock is the
  logger's RTC, which may be off GNSS time by tens of seconds.
- ``.blf`` (``BLFReader``): absolute. Header start SYSTEMTIME (1 ms resolution) + object offsets of
  1 ns or 10 us. python-can takes the SYSTEMTIME as UTC; Vector tools write local time, so a BLF
  recorded by CANoe is shifted by the recording PC's UTC offset (python-can issue #2010).
- ``.asc`` (``ASCReader``): the file holds offsets in seconds (1 us) from the ``Begin Triggerblock``
  (or ``date``) header date, which has 1 ms resolution and no time zone. Read with
  ``relative_timestamp=False`` so python-can adds that date, parsed as *local time of the reading
  machine*; a date it cannot parse is a :class:`CanLogError`. A file without a header date keeps
  offsets from the measurement start (t_ns near 0; logged as a warning). python-can ignores the
  header's ``timestamps relative`` (each time since the event before): such a file's times are summed as its lines
  are fed to the reader (:func:`.text_lines.summed_time`), from each ``Begin Triggerblock``.
- ``.trc`` (``TRCReader``): ``$STARTTIME`` (days since 1899-12-30, taken as UTC) + offsets in ms with
  1 us resolution (v1.1+). Version 1.0 files and files without ``$STARTTIME`` give offsets from the
  measurement start (warning logged).
- ``.log`` (``CanutilsLogReader``, ``candump -L``): absolute, as recorded (1 us).

Text logs are read as cp1252 (what Windows tools write, e.g. a German CANoe date "Mär"); python-can
skips text lines it does not recognise (comments, statistics), except in candump logs; a damaged line is left out
and counted, the lines after it read (:mod:`.text_lines`).
Damage python-can passes over silently: a BLF cut short often just ends early, so the file size in its
header is checked after the last frame (:class:`CanLogError` if the file is shorter); an MDF4 cut short
ends early too, or stops at the record the cut breaks and loses the frames before it, so its blocks and,
in an unfinalised file (a CAN logger's), its last data block's records are walked first
(:mod:`.mdf4_blocks`): the records before the cut are read from a temporary copy that ends there, then
:class:`CanLogError` names the cut. Damage inside an MDF4's records (either kind of file: :mod:`.mdf4_sorted` for a
finalised one) is read past from a copy without the damaged records; damage to its blocks, from a copy whose chains
leave the damaged groups out (:mod:`.mdf4_mend`). A BLF damaged inside (python-can stops at the first log container
that does not inflate) is read from a copy of its intact containers (:mod:`.blf_damage`). :class:`CanLogError`
names what was left out.

Channels are named as the file numbers them: python-can makes ASC and BLF channels 0-based
(file channel 1 -> 0) but not TRC or MF4; that shift is undone here so that "1" means CAN 1 in every
format (MF4 ``BusChannel``, TRC bus, ASC/BLF channel). candump interface names ("can0") stay as they are.
"""

from __future__ import annotations

import contextlib
import gc
import io
import logging
import math
import os
import re
import shutil
import sys
import tempfile
import traceback
from collections.abc import Callable, Iterator
from contextlib import ExitStack
from pathlib import Path
from typing import IO

import can
from can.io.generic import MessageReader

from autosar_cli.config import CAN_LOG_SUFFIXES
from autosar_cli.ingest import mf4_support
from autosar_cli.ingest.blf_damage import blf_damage, holds_every_container, write_blf_without
from autosar_cli.ingest.mdf4_blocks import mdf4_cut, write_without_holes
from autosar_cli.ingest.mdf4_mend import write_mended
from autosar_cli.ingest.records import CanRecord, CutShort
from autosar_cli.ingest.text_lines import LineFeed, damaged_lines

__all__ = ["CAN_LOG_SUFFIXES", "CanLogError", "first_frame_ns", "is_can_log", "read_can_log"]

log = logging.getLogger(__name__)

#: Formats whose python-can reader numbers channels from 0 where the file numbers them from 1.
_ZERO_BASED_CHANNELS = (".asc", ".blf")
_CANDUMP_LINE = re.compile(r"\(\s*\d+(?:\.\d*)?\)\s+\S+\s+[0-9A-Fa-f]{1,8}#")
#: a whole ASC classic frame line with a DLC of 9-15 and its 8 data bytes (CANalyzer's "Length = ..." after them)
_ASC_CLASSIC_LONG_DLC = re.compile(r"\s*\d+\.\d+\s+\d+\s+[0-9A-Fa-f]+x?\s+[RT]x\s+[dD]\s+[9A-Fa-f]"
                                   r"(?:\s+[0-9A-Fa-f]{2}){8}(?:\s+Length\s*=.*)?\s*$")
_SNIFF_BYTES = 4096
_FORMAT_NAMES = {".blf": "BLF", ".asc": "ASC", ".trc": "TRC", ".log": "candump -L", ".mf4": "MDF4"}
#: formats of which an empty file is no log (a text log of no line is one of no frame)
_BINARY = (".blf", ".mf4")
#: the bytes of a BLF file's header python-can reads before anything else
_BLF_HEADER_READ = 72


class CanLogError(RuntimeError):
    """One-line message naming the file and the problem (and where in the file, where known)."""


#: a binary CAN log by its first bytes, whatever its name says: its suffix as read
_CAN_LOG_MAGIC = ((b"MDF     ", ".mf4"), (b"UnFinMF ", ".mf4"), (b"LOGG", ".blf"))


def _suffix(path: Path) -> str:
    """The suffix a CAN log is read by: an MDF4 or BLF file's own, by its first bytes (a logger's file renamed, e.g.
    .bag, was read as what its name said), else its name's."""
    head = b""
    try:
        if Path(path).is_file():  # a pipe's open would wait for a writer
            with Path(path).open("rb") as f:
                head = f.read(8)
    except OSError:
        pass
    return next((suffix for magic, suffix in _CAN_LOG_MAGIC if head.startswith(magic)), path.suffix.lower())


def _first_line(path: Path) -> str | None:
    """First non-blank line of a text file (within its first 4 KiB), or None if unreadable/empty."""
    try:
        with path.open("rb") as f:
            head = f.read(_SNIFF_BYTES)
    except OSError:
        return None
    for line in head.decode("latin-1").splitlines():
        if line.strip():
            return line.strip()
    return None


def is_can_log(path: Path) -> bool:
    """True for a CAN log suffix (any case); a ``.log`` must also start like ``candump -L`` output.

    ``.log`` is shared with NMEA captures, so its first non-blank line must read
    ``(<seconds>) <interface> <hex id>#...``; an unreadable ``.log`` is not a CAN log.
    """
    path = Path(path)
    suffix = _suffix(path)
    if suffix not in CAN_LOG_SUFFIXES:
        return False
    if suffix != ".log":
        return True
    line = _first_line(path)
    return line is not None and _CANDUMP_LINE.match(line) is not None


def _one_line(exc: BaseException) -> str:
    """Exception type and message on one line."""
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


class _MF4Reader(can.MF4Reader):
    """MF4Reader that closes the file it opened when asammdf rejects the file, and keeps asammdf's working copy
    of an unfinalised log (the whole file, made in the system's temporary folder and left there when the read
    failed) in a folder of its own, removed with the reader."""

    def __init__(self, file: Path) -> None:
        from asammdf.blocks.options import GLOBAL_OPTIONS

        self._scratch = tempfile.TemporaryDirectory(prefix="autosar-mf4-")
        previous = GLOBAL_OPTIONS["temporary_folder"]
        GLOBAL_OPTIONS["temporary_folder"] = self._scratch.name  # read once, as the MDF object is made
        try:
            super().__init__(file)
        except BaseException as exc:
            opened = getattr(self, "file", None)
            if opened is not None:
                opened.close()
            _release_half_built(exc)
            self._scratch.cleanup()
            raise
        finally:
            GLOBAL_OPTIONS["temporary_folder"] = previous

    def stop(self) -> None:
        try:
            super().stop()
        finally:
            self._scratch.cleanup()


def _release_half_built(exc: BaseException) -> None:
    """Free now the MDF4 object a failed open left half built, which ``exc``'s frames hold: its ``__del__`` raises
    (AttributeError: no ``_file``), and run by the garbage collector at a later moment it can fall inside
    ``compile()`` (numpy parsing the dtypes of the next file opened), where CPython 3.11 then fails that whole file
    ("SystemError: AST constructor recursion depth mismatch"). Its own error, printed by the interpreter, is held
    back: the open's error is the one the user gets."""
    hook = sys.unraisablehook
    sys.unraisablehook = lambda raised: None if isinstance(raised.exc_value, AttributeError) else hook(raised)
    try:
        traceback.clear_frames(exc.__traceback__)
        gc.collect()
    finally:
        sys.unraisablehook = hook


def _open_reader(path: Path, stack: ExitStack, shown: Path) -> MessageReader:
    """Open the python-can reader of the file's format; files we open are closed by ``stack``. ``shown``: the
    user's file, which ``path`` may be a cut copy of."""
    suffix = _suffix(path)
    if suffix == ".mf4":
        mf4_support.ensure()
        # Given a file object, MF4Reader copies the whole file into memory; given a path, asammdf
        # reads it block by block.
        return stack.enter_context(_MF4Reader(path))
    if suffix == ".blf":
        return stack.enter_context(can.BLFReader(stack.enter_context(path.open("rb"))))
    if suffix == ".log" and (first := _first_line(path)) is not None and _CANDUMP_LINE.match(first) is None:
        raise CanLogError(f"{shown}: not a candump -L log (first line {first[:40]!r})")
    text: IO[str] = stack.enter_context(path.open("r", encoding="cp1252", errors="replace"))
    marks = ("Begin Trigger", "begin trigger") if suffix == ".asc" else ()  # an ASC's "Begin Triggerblock <date>"
    feed = LineFeed(text, damaged_lines(path), marks, judge_skipped=suffix != ".log",
                    relative_times=suffix == ".asc" and _asc_times_relative(path))
    return stack.enter_context(_text_reader(suffix, feed))


_ASC_BASE = re.compile(rb"^\s*base\s+(?:hex|dec)\s+timestamps\s+(absolute|relative)", re.IGNORECASE | re.MULTILINE)


def _asc_times_relative(path: Path) -> bool:
    """Whether an ASC log's header says ``timestamps relative``: each event's time is the time since the event
    before, which python-can reads as the time since the start (every frame within the first second or so)."""
    with open(path, "rb") as f:
        found = _ASC_BASE.search(f.read(_SNIFF_BYTES))
    return found is not None and found.group(1).lower() == b"relative"


def _text_reader(suffix: str, feed: LineFeed) -> MessageReader:
    """python-can's reader of a text log of ``suffix``, reading ``feed``."""
    if suffix == ".asc":
        return can.ASCReader(feed, relative_timestamp=False)
    if suffix == ".trc":
        return can.TRCReader(feed)
    return can.CanutilsLogReader(feed)


def _relative_start(reader: MessageReader) -> bool:
    """True if the reader found no start date, so its times are offsets from the measurement start."""
    if isinstance(reader, can.ASCReader):
        return reader.start_time == 0.0
    if isinstance(reader, can.TRCReader):
        return reader.start_time is None
    if isinstance(reader, can.BLFReader):  # python-can's time of a start that is no date (a damaged header)
        return reader.start_timestamp == 0
    return False


def _where(reader: MessageReader, frames: int) -> str:
    """Position of a failure: frames read so far, plus the byte offset for BLF."""
    where = f"after {frames} frame{'' if frames == 1 else 's'}"
    if isinstance(reader, can.BLFReader):
        try:
            where += f", near byte {reader.file.tell()}"
        except (OSError, ValueError):
            pass
    return where


def read_can_log(path: Path, warn: Callable[[str], None] = log.warning) -> Iterator[CanRecord]:
    """Stream the frames of a standalone CAN log in file order (never load the whole file into a list).

    Raises :class:`CanLogError` at once for an unsupported suffix or a missing file. A file that
    cannot be parsed raises it from the iterator, after the frames read before the damage. ``warn`` is told,
    one line each, what is read but doubtful (a log without a start date, a reader that went on past an error).
    """
    path = Path(path)
    if _suffix(path) not in CAN_LOG_SUFFIXES:
        raise CanLogError(
            f"{path}: unsupported CAN log format {path.suffix or '(no suffix)'!r} "
            f"(supported: {', '.join(CAN_LOG_SUFFIXES)}, any case)"
        )
    if not path.is_file():
        raise CanLogError(f"{path}: no such file" if not path.exists() else f"{path}: not a file")
    return _records(path, warn)


def first_frame_ns(path: Path) -> int | None:
    """The time (ns) of a CAN log's first frame, read as :func:`read_can_log` reads it (its damage checks, then the
    reader's first frame), or None where no frame is read: how ingest puts a logger's split files in time order."""
    try:
        frames = read_can_log(path, lambda said: None)
    except CanLogError:
        return None
    try:
        return next(frames).t_ns
    except (StopIteration, CanLogError):
        return None
    finally:
        frames.close()


def _records(path: Path, warn: Callable[[str], None]) -> Iterator[CanRecord]:
    """Generator behind :func:`read_can_log`: the reader is closed when it ends or is closed."""
    suffix = _suffix(path)
    kind = _FORMAT_NAMES[suffix]
    to_channel: Callable[[object], str] = _channel_from_one if suffix in _ZERO_BASED_CHANNELS else _channel
    frames = 0
    size = path.stat().st_size
    if size == 0 and suffix in _BINARY:  # python-can's "cannot mmap an empty file" named no file
        raise CanLogError(f"{path}: an empty file (0 bytes), no {kind} log in it: it holds no CAN frames")
    if suffix == ".blf" and size < _BLF_HEADER_READ:  # python-can's "unpack requires a buffer of 72 bytes"
        raise CanLogError(f"{path}: truncated BLF log, no frame read: the file ends inside its file header ({size} "
                          "bytes), it holds no CAN frames")
    # asammdf prints the traceback of an error to stdout before it raises it or reads on: held back (it would break
    # --json's output), the error is ours to word
    printed = io.StringIO()
    quiet = (lambda: contextlib.redirect_stdout(printed)) if suffix == ".mf4" else contextlib.nullcontext
    with ExitStack() as stack:
        cut: CutShort | None = None
        try:
            # python-can already reads a BLF's cut container as far as its zlib stream goes; what it stops at inside
            # is blf_damage's
            cut = mdf4_cut(path) if suffix == ".mf4" else blf_damage(path) if suffix == ".blf" \
                else _text_cut(path, suffix)
            with quiet():
                source, cut = _mended(path, cut, stack)
                source = _whole_records(source, cut, stack)
                reader = _open_reader(source, stack, path)
                messages = iter(reader)
        except CanLogError:
            raise
        except Exception as exc:  # python-can/asammdf raise many types; the user needs file + reason
            if cut is not None:  # what our walk of its structure found says more than the reader's own error
                raise CanLogError(f"{path}: {'damaged' if cut.damaged else 'truncated'} {kind} log, no frame read: "
                                  f"{cut.reason} (the reader: {_one_line(exc)})") from exc
            raise CanLogError(f"{path}: cannot open {kind} log: {_one_line(exc)}") from exc
        feed = reader.file if isinstance(getattr(reader, "file", None), LineFeed) else None
        while True:
            try:
                with quiet():
                    msg = next(messages)
            except StopIteration:
                break
            except Exception as exc:
                if feed is not None and feed.after_damage():  # a text log: read on from the next line
                    reader = stack.enter_context(_text_reader(suffix, feed))
                    messages = iter(reader)
                    continue
                raise CanLogError(f"{path}: cannot read {kind} log {_where(reader, frames)}: {_one_line(exc)}"
                                  f"{_cut_note(cut)}") from exc
            if frames == 0 and _relative_start(reader):
                warn(f"{path}: no start date in the header; times are offsets from the measurement start")
            if feed is not None:
                if frames == 0:
                    feed.first_frame()
                # "d 8 F2 F2 F2 F2 2" is left out
                whole = len(msg.data) == msg.dlc or _holds_its_bytes(msg, feed.last_line())
                feed.frame_read(whole)
                if not whole:
                    continue
                if not msg.is_fd and msg.dlc > 8:  # the classic frame's code, which python-can read as a length
                    msg.dlc = can.util.len2dlc(msg.dlc)
            frames += 1
            yield CanRecord(
                t_ns=_to_ns(msg.timestamp),
                frame_id=msg.arbitration_id,
                is_extended=msg.is_extended_id,
                dlc=msg.dlc,
                data=bytes(msg.data),
                is_error=msg.is_error_frame,
                is_remote=msg.is_remote_frame,
                channel=to_channel(msg.channel),
            )
        if feed is not None:
            feed.end()
        _check_complete(source, reader, frames, path)
        errors = [ln for ln in printed.getvalue().splitlines() if ln and not ln.startswith((" ", "Traceback"))]
        if errors:
            warn(f"{path}: the {kind} reader went on past {len(errors)} error(s) of its own, the last: {errors[-1]}")
        said = [cut.reason] if cut else []
        if feed is not None and feed.damaged:
            lines = ", ".join(map(str, sorted(feed.damaged)[:3])) + (" ..." if len(feed.damaged) > 3 else "")
            said.insert(0, f"{len(feed.damaged)} line{'s' if len(feed.damaged) > 1 else ''} no frame could be read "
                           f"from left out (line {lines}), the lines after read")
        if said:
            damaged = (cut is not None and cut.damaged) or bool(feed and feed.damaged)
            # a cut: every frame read lies before it
            before = cut is not None and not (cut.holes or cut.patches or cut.inserted)
            raise CanLogError(f"{path}: {'damaged' if damaged else 'truncated'} {kind} log: {'; '.join(said)}; "
                              f"{frames} frames read{' before it' if before else ''}")


def _holds_its_bytes(msg: can.Message, line: str) -> bool:
    """Whether a frame read from a text log's ``line`` holds the data bytes its DLC states. A classic frame's DLC
    9-15 states 8 bytes (a CANalyzer log's "d D 55 AA 01 02 03 04 05 06"), which python-can's ASC reader reads as
    the CAN FD length that code means: whole where its line is such a frame's (not a damaged line python-can reads
    so: in 'Rx " d 8 9C ...' it takes "d" for the DLC and "8" for a data byte)."""
    if msg.is_remote_frame or msg.is_error_frame or len(msg.data) == msg.dlc:
        return True
    if msg.is_fd or msg.dlc <= 8 or len(msg.data) != 8:
        return False
    return _ASC_CLASSIC_LONG_DLC.match(line) is not None


def _cut_note(cut: CutShort | None) -> str:
    return "" if cut is None else f" ({cut.reason})" if cut.damaged else f" (cut short: {cut.reason})"


def _text_cut(path: Path, suffix: str) -> CutShort | None:
    """Where a text log's end cuts its last line (every writer ends its lines; python-can skips a broken TRC line
    without a word and reads a broken candump line as a frame with fewer data bytes), or where an ASC log that
    began a trigger block ends without closing it."""
    size = path.stat().st_size
    with open(path, "rb") as f:
        f.seek(max(0, size - 4096))
        tail = f.read()
    last = tail.rfind(b"\n")
    partial = tail[last + 1:]
    if partial.strip() and not (suffix == ".asc" and partial.strip().lower().startswith(b"end triggerblock")):
        whole = size - len(partial) if last >= 0 or size <= len(tail) else None
        if whole is None:  # no line end in the last 4 KiB: no line to keep there
            return CutShort(f"the file ends inside a line of over {len(tail)} bytes")
        return CutShort(f"its last line is cut off ({len(partial)} bytes after the last line end)", whole)
    if suffix == ".asc" and b"end triggerblock" not in tail.lower() and _begins_trigger_block(path):
        return CutShort("it ends without the End TriggerBlock its Begin Triggerblock opened")
    return None


def _begins_trigger_block(path: Path) -> bool:
    with open(path, "rb") as f:
        return b"begin triggerblock" in f.read(_SNIFF_BYTES).lower()


def _mended(path: Path, cut: CutShort | None, stack: ExitStack) -> tuple[Path, CutShort | None]:
    """``path`` and ``cut``, or where damage to an MDF4 file's blocks leaves groups to read, a temporary copy whose
    links step over the damaged ones (:func:`write_mended`), or whose DLC table is the standard's, and what the
    copy's records then lack. Three rounds: a copy whose links moved with bytes added or lost may still reach blocks
    the lost bytes held, whose groups a second copy leaves out, and a damaged DLC table is found once the blocks
    are whole."""
    if cut is None or not (cut.patches or cut.inserted):
        return path, cut
    scratch = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="autosar-canlog-")))
    source, said = path, []
    for round_ in range(3):
        copy = scratch / f"{round_}_{path.name}"
        write_mended(source, copy, cut.patches, cut.inserted)
        said.append(cut.reason)
        rest = mdf4_cut(copy)
        if rest is None:
            return copy, CutShort("; ".join(said), damaged=True, holes=cut.holes, patches=cut.patches,
                                  inserted=cut.inserted)
        if not (rest.patches or rest.inserted):  # the records a put-back place broke, and those the checks show
            return copy, CutShort("; ".join([*said, rest.reason]), rest.whole_bytes, damaged=True,
                                  holes=cut.holes + rest.holes, patches=cut.patches, inserted=cut.inserted)
        source, cut = copy, rest
    return path, CutShort(said[0], damaged=True)  # the copy's links still reach damage: not mended


def _whole_records(path: Path, cut: CutShort | None, stack: ExitStack) -> Path:
    """``path``, or where the end of a log cuts a record or line, a temporary copy of it up to there (asammdf stops
    at a broken MDF4 record, or reads a shape it cannot reshape and loses the frames before it; python-can skips a
    broken TRC line or reads a broken candump line as a shorter frame); where damage inside an MDF4 file leaves
    records to read after it, a copy without the damaged bytes (:func:`write_without_holes`); inside a BLF, a copy
    of its intact containers (:func:`write_blf_without`)."""
    if cut is None or (cut.whole_bytes is None and not cut.holes):
        return path
    copy = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="autosar-canlog-"))) / path.name
    if cut.holes:
        if _suffix(path) == ".blf":
            write_blf_without(path, copy)
        else:
            write_without_holes(path, copy, cut)
        return copy
    shutil.copyfile(path, copy)
    os.truncate(copy, cut.whole_bytes)
    return copy


def _check_complete(read: Path, reader: MessageReader, frames: int, path: Path) -> None:
    """Raise for a BLF shorter than its header says: python-can often ends such a file silently. ``read``: the
    file read, ``path`` or a copy of it."""
    if isinstance(reader, can.BLFReader):
        try:
            size = read.stat().st_size
        except OSError:
            return
        if size < reader.file_size:
            if holds_every_container(read):  # a cut file lacks some: its header's file size is what is damaged
                raise CanLogError(f"{path}: damaged BLF log: its header says {reader.file_size} bytes, the file has "
                                  f"{size} and every log container its uncompressed size counts; {frames} frames "
                                  "read")
            raise CanLogError(
                f"{path}: truncated BLF log: header says {reader.file_size} bytes, file has {size} "
                f"({frames} frames read before the cut)"
            )


def _to_ns(seconds: float) -> int:
    """Float seconds to the nearest integer ns (the whole seconds split off exactly first)."""
    whole = math.floor(seconds)
    return whole * 1_000_000_000 + round((seconds - whole) * 1e9)


def _channel(channel: object) -> str:
    """python-can channel as text ("" if unknown)."""
    return "" if channel is None else str(channel)


def _channel_from_one(channel: object) -> str:
    """Channel of a reader that counts from 0, as the file counts it (from 1)."""
    return str(channel + 1) if isinstance(channel, int) else _channel(channel)
