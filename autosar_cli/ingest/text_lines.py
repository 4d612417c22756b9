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


class LineFeed:
    """The lines of an open text log as the file a python-can reader iterates, counted (``line``: lines of the
    file handed out so far, so the one a reader failed on)."""

    def __init__(self, file: IO[str], damaged_lines: frozenset[int] = frozenset(), marks: tuple[str, ...] = ()
                 ) -> None:
        """``damaged_lines``: the numbers of the file's lines to hold back (:func:`damaged_lines`); ``marks``: text
        of the lines that set the reader's clock on the way (an ASC's ``Begin Triggerblock``, whose date the times
        after it count from), the last of which is read again after the header."""
        self._file = file
        self._held_back = damaged_lines
        self._marks = marks
        self._last_mark: str | None = None
        self._replay: list[str] = []
        self._before_first: list[str] | None = []  # lines handed out before the reader's first frame
        self.header: list[str] | None = None  #: the lines before the first frame, once the reader gave one
        self.line = 0
        self.damaged: list[int] = []  #: the lines left out: held back, failed on, short of their bytes

    def __iter__(self) -> Iterator[str]:
        # a reader iterates anew after its header (ASC) and a new reader after damage: each picks up where the
        # file is, the header's lines first where they are to be read again
        while self._replay:
            yield self._replay.pop(0)
        held_back, marks = self._held_back, self._marks
        for self.line, line in enumerate(self._file, self.line + 1):  # noqa: B020 (the count is the feed's)
            if held_back and self.line in held_back:  # no writer puts such bytes in a text log: not the writer's
                self.damaged.append(self.line)
                continue
            for mark in marks:
                if mark in line:
                    self._last_mark = line
            if self._before_first is not None:
                self._before_first.append(line)
                if len(self._before_first) > _MAX_HEADER_LINES:
                    self._before_first = None
            yield line

    def first_frame(self) -> None:
        """The reader gave its first frame, read from the last line handed out: the lines before it are the
        header a new reader needs."""
        if self.header is None and self._before_first is not None:
            self.header = self._before_first[:-1]
        self._before_first = None

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
        self._replay = [*self.header, *([self._last_mark] if self._last_mark is not None else [])]
        return True

    def close(self) -> None:
        """What a python-can reader calls at its end: the file is the caller's to close."""


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
