"""A text CAN log's lines fed to python-can's reader, so that a line it cannot read costs that line, not the rest.

python-can's ASC, TRC and candump readers read their file line by line, the header's lines first (the start
date, the number base, the columns), and raise at the first frame line they cannot parse (a damaged byte, a line
cut short): every frame after it was lost; and they skip a line of zeroed or overwritten bytes that no pattern of
theirs matches without a word. :class:`LineFeed` hands them the file's lines one at a time, holding back (and
counting) a line with bytes no text log holds (:func:`damaged_lines`, found in the file's bytes first), and keeps
the lines before the first frame; where the reader fails, a new reader is given those header lines again and then
the file's lines after the one it failed on (:meth:`LineFeed.after_damage`), and that line is counted too. An
ASC's times count from the date of the trigger block they lie in: the last ``Begin Triggerblock`` line read is given
again after the header.

The ASC and TRC readers also skip, without a word, a frame line damaged where their pattern looks (a letter in the
time, the direction's ``Rx`` overwritten, a byte in the blanks between columns): a line no frame came from that is
shaped as the frame lines read before it (blank and non-blank at the same places but for two,
:func:`shaped_as_a_frame`) is counted as a damaged frame line (:meth:`LineFeed.frame_read`). A writer's other
events (comments, statistics, status lines) and the header's lines are shaped otherwise and pass. A line shaped as
no frame line read before it is judged again at the end, against every shape read (a message sent once a second, a
time with one digit more, may show a shape first after the damaged line).
"""

from __future__ import annotations

import mmap
import re
from collections.abc import Iterator
from pathlib import Path
from typing import IO

#: bytes no text log holds: NUL and other control bytes (zeroed or overwritten bytes; not the bytes cp1252 has no
#: character for, which a UTF-8 comment holds)
_DAMAGED = re.compile(rb"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")
#: header lines kept for a new reader (a log's header is a few lines; beyond, frames were read before the first)
_MAX_HEADER_LINES = 1000
#: lines no frame came from and not shaped as the frame lines read so far, kept to be judged again at the end
#: against every shape read (a message sent once a second, or a time with one digit more, takes a shape first seen
#: after the damaged line)
_DOUBTFUL_KEPT = 10000
#: places where a damaged frame line's blanks and non-blanks may differ from a whole one's (one byte overwritten
#: turns a blank into a non-blank or splits a column: one place; two bytes side by side: two)
_SHAPE_SLACK = 2
_NON_BLANK = re.compile(r"\S")


def _shape(line: str) -> str:
    """Where ``line`` has blanks (" ") and non-blanks ("x"), trailing blanks and line end left off."""
    return _NON_BLANK.sub("x", line.rstrip())


def shaped_as_a_frame(line: str, *frame_lines: dict[int, str]) -> bool:
    """True where ``line`` has its blanks and non-blanks where a line of ``frame_lines`` (frame lines read, by their
    length) has them, but for at most :data:`_SHAPE_SLACK` places (a longer line's extra characters counted)."""
    shape = _shape(line)
    if not shape:
        return False
    for length in range(len(line) - _SHAPE_SLACK, len(line) + _SHAPE_SLACK + 1):
        for by_length in frame_lines:
            if (frame_line := by_length.get(length)) is None:
                continue
            other = _shape(frame_line)
            places = abs(len(shape) - len(other)) + sum(a != b for a, b in zip(shape, other, strict=False))
            if places <= _SHAPE_SLACK:
                return True
    return False


class LineFeed:
    """The lines of an open text log as the file a python-can reader iterates, counted (``line``: lines of the
    file handed out so far, so the one a reader failed on)."""

    def __init__(self, file: IO[str], damaged_lines: frozenset[int] = frozenset(), marks: tuple[str, ...] = (),
                 judge_skipped: bool = True, relative_times: bool = False) -> None:
        """``damaged_lines``: the numbers of the file's lines to hold back (:func:`damaged_lines`); ``marks``: text
        of the lines that set the reader's clock on the way (an ASC's ``Begin Triggerblock``, whose date the times
        after it count from), the last of which is read again after the header; ``judge_skipped``: whether the
        lines the reader skips are judged (False for a reader that skips none: python-can's candump reader raises
        at a line it cannot read); ``relative_times``: each line's leading time is the time since the event before
        (an ASC whose header says ``timestamps relative``, which python-can reads as times since the start): it is
        handed out as their sum since the last mark (:func:`summed_time`)."""
        self._judge_skipped = judge_skipped
        self._file = file
        self._held_back = damaged_lines
        self._marks = marks
        self._last_mark: str | None = None
        self._replay: list[str] = []
        self._before_first: list[str] | None = []  # lines handed out before the reader's first frame
        self.header: list[str] | None = None  #: the lines before the first frame, once the reader gave one
        self.line = 0
        self.damaged: list[int] = []  #: the lines left out: held back, failed on, short of their bytes, skipped
        self._text = ""  # the last line of the file handed out
        self._claimed = True  # whether a frame came from it
        self._skipped: list[tuple[int, str]] = []  # the file's lines handed out since the last frame that gave none
        # the first and the last frame line read of each length: the log's frame shapes (a fixed-width writer's
        # counters and times take more digits and fewer blanks as the log goes on)
        self._first_frame_lines: dict[int, str] = {}
        self._frame_lines: dict[int, str] = {}
        self._doubtful: list[tuple[int, str]] = []
        self._relative = relative_times
        self._since_mark_ns = 0  # relative_times: the events' times summed since the last mark

    def __iter__(self) -> Iterator[str]:
        # a reader iterates anew after its header (ASC) and a new reader after damage: each picks up where the
        # file is, the header's lines first where they are to be read again
        if not self._claimed:  # the reader before left its last line for another (TRC: its header's end)
            self._skipped.append((self.line, self._text))
            self._claimed = True
        while self._replay:
            yield self._replay.pop(0)
        held_back, marks, judge_skipped = self._held_back, self._marks, self._judge_skipped
        for self.line, line in enumerate(self._file, self.line + 1):  # noqa: B020 (the count is the feed's)
            if held_back and self.line in held_back:  # no writer puts such bytes in a text log: not the writer's
                self.damaged.append(self.line)
                if self._relative:  # its event's time, where it reads, still counts for the events after it
                    _, self._since_mark_ns = summed_time(line, self._since_mark_ns)
                continue
            for mark in marks:
                if mark in line:
                    self._last_mark = line
                    self._since_mark_ns = 0
            if self._relative:
                line, self._since_mark_ns = summed_time(line, self._since_mark_ns)
            if self._before_first is not None:
                self._before_first.append(line)
                if len(self._before_first) > _MAX_HEADER_LINES:
                    self._before_first = None
            if not judge_skipped:
                yield line
                continue
            self._text, self._claimed = line, False
            yield line
            # the reader asks for the next line: no frame came from this one (a reader that failed on it asks a
            # new feed, and this is not reached)
            if not self._claimed:
                self._skipped.append((self.line, line))
                self._claimed = True
                if len(self._skipped) > _MAX_HEADER_LINES:  # a long run of other events: judged now, not held
                    self._judge(self._skipped)
                    self._skipped.clear()

    def first_frame(self) -> None:
        """The reader gave its first frame, read from the last line handed out: the lines before it are the
        header a new reader needs."""
        if self.header is None and self._before_first is not None:
            self.header = self._before_first[:-1]
        self._before_first = None

    def last_line(self) -> str:
        """The text of the last line of the file handed out."""
        return self._text

    def frame_read(self, whole: bool = True) -> None:
        """The reader gave a frame, read from the last line handed out (``whole``: False where it is short of its
        stated bytes, which counts that line): the lines since the frame before that no frame came from are judged
        (:func:`shaped_as_a_frame`)."""
        if not self._judge_skipped:
            if not whole:
                self.damaged.append(self.line)
            return
        self._claimed = True
        if whole:
            text = self._text
            length = len(text)
            self._frame_lines[length] = text
            if length not in self._first_frame_lines:
                self._first_frame_lines[length] = text
        else:
            self.damaged.append(self.line)
        if self._skipped:
            self._judge(self._skipped)
            self._skipped.clear()

    def end(self) -> None:
        """The reader read to the file's end: the lines after the last frame are judged, and the doubtful ones
        again, against every shape read."""
        self._judge(self._skipped)
        self._skipped.clear()
        doubtful, self._doubtful = self._doubtful, []
        self.damaged += [number for number, line in doubtful
                         if shaped_as_a_frame(line, self._frame_lines, self._first_frame_lines)]

    def _judge(self, lines: list[tuple[int, str]]) -> None:
        """Lines no frame came from: counted where shaped as a frame line read, else kept as doubtful."""
        for number, line in lines:
            if self._frame_lines and shaped_as_a_frame(line, self._frame_lines, self._first_frame_lines):
                self.damaged.append(number)
            elif len(self._doubtful) < _DOUBTFUL_KEPT:
                self._doubtful.append((number, line))

    def after_damage(self) -> bool:
        """After a reader failed on the last line handed out: count it, and feed the header's lines again before
        the file's next line (for a new reader); before the first frame, the header is the lines before that one.
        False where the reader failed again without a line of the file read since (nothing to go on from)."""
        if self.damaged and self.damaged[-1] == self.line or self.line == 0:
            return False
        if self.header is None:
            if self._before_first is None:
                return False
            self.header, self._before_first = self._before_first[:-1], None
        self.damaged.append(self.line)
        self._claimed = True
        self._replay = [*self.header, *([self._last_mark] if self._last_mark is not None else [])]
        return True

    def close(self) -> None:
        """What a python-can reader calls at its end: the file is the caller's to close."""


_LEADING_TIME = re.compile(r"^(\s*)(\d+)\.(\d+)(?=\s)")


def summed_time(line: str, before_ns: int) -> tuple[str, int]:
    """``line`` with its leading time (s, the time since the event before) replaced by ``before_ns`` plus it, and
    that sum (ns, added in integers: a drive's 10^5 events summed in floats drift); a line without one as it is."""
    found = _LEADING_TIME.match(line)
    if found is None:
        return line, before_ns
    lead, whole, fraction = found.groups()
    total = before_ns + int(whole) * 1_000_000_000 + int(fraction[:9].ljust(9, "0"))
    return f"{lead}{total // 1_000_000_000}.{total % 1_000_000_000:09d}{line[found.end():]}", total


def damaged_lines(path: Path) -> frozenset[int]:
    """The numbers (from 1) of the lines of the text log at ``path`` that hold bytes no text log holds: found in
    the file's bytes at once (a per-line search cost a text log's read 6-9 %)."""
    with open(path, "rb") as f:
        try:
            buf = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
        except ValueError:  # an empty file
            return frozenset()
        with buf:
            lines, line, before = set(), 1, 0
            for found in _DAMAGED.finditer(buf):
                line += buf[before:found.start()].count(b"\n")
                before = found.start()
                lines.add(line)
            return frozenset(lines)
