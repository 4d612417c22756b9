"""Time series assembly: stamp choice, time-jump repair, reordering, duplicates, gaps and statistics.

Every decoded stream goes through one :class:`Series` before it reaches drive.h5:

1. Stamp: the header stamp (sensor time) when it is set, else the log (recording) time.
2. Time jumps: the median of ``header − log`` over the first messages is the stream's clock offset. A
   message whose offset differs from it by more than ``max_clock_step_s`` has a broken stamp (sensor
   clock jump, uninitialised header): its time becomes ``log time + offset`` and it is counted.
3. Reordering: a bounded buffer (``window`` messages) puts slightly out-of-order messages back in
   order. A message older than what has already been written is dropped and counted ("late"); one with
   the same time as its neighbour is a duplicate, dropped and counted. A message more than ``max_clock_step_s``
   after the one before it is held until the next: if that one is more than ``max_clock_step_s`` before it, the
   held one's stamp is an outlier (a damaged byte; the stream's own clock has no second one to repair it from),
   dropped and counted; else it opened a real gap and is taken.
4. Gaps: a step longer than ``gap_factor`` × the stream's typical period is recorded.
5. Inputs: the rows each input file gave (:meth:`Series.end_input`), by which ingest refuses two inputs whose
   rows of one stream interleave (two recordings of it, or one sensor recorded twice on other clocks; the same
   messages twice are duplicates, dropped).

Memory is bounded by the window and the flush size, whatever the length of the log.
"""

from __future__ import annotations

import bisect
import math
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from operator import itemgetter
from typing import Any

import numpy as np

_KEY = itemgetter(0)
_OFFSET_SAMPLES = 8


@dataclass
class SeriesStats:
    """What happened to the messages of one stream (reported by ingest, stored in drive.h5)."""

    received: int = 0
    written: int = 0
    log_time_used: int = 0
    reordered: int = 0
    duplicates: int = 0
    late_dropped: int = 0
    time_jumps: int = 0
    stamp_outliers: int = 0
    gaps: list[tuple[int, int]] = field(default_factory=list)
    skipped: Counter[str] = field(default_factory=Counter)
    clock_offset_ns: int = 0
    first_ns: int = 0
    last_ns: int = 0
    #: the header stamps' nanoseconds field held microseconds (:func:`stamps_hold_microseconds`), read as such
    stamps_in_microseconds: bool = False
    #: how fast the header stamps run against the log times (ppm) and its 1-sigma (:class:`ClockRate`); None
    #: where too few messages carry a header stamp
    clock_rate_ppm: float | None = None
    clock_rate_std_ppm: float | None = None

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {k: v for k, v in self.__dict__.items() if k not in ("gaps", "skipped")}
        d["gaps"] = len(self.gaps)
        d["largest_gap_s"] = max(((b - a) / 1e9 for a, b in self.gaps), default=0.0)
        d["skipped"] = dict(self.skipped)
        return d


def stamps_hold_microseconds(pairs: list[tuple[int | None, int]]) -> bool:
    """Whether a stream's first (header stamp, log time) pairs (ns) carry microseconds in the stamps' nanoseconds
    field (a driver's bug): every sub-second part under 1 ms, and the stamps read as microseconds keep an offset from
    the log times ten times steadier than as given, over more than 1 ms of it. Its samples were written each second
    within that second's first millisecond, then a 999 ms gap, without a word."""
    stamped = [(h, lg) for h, lg in pairs if h and h > 0]
    if len(stamped) < 4:
        return False
    h = np.array([p[0] for p in stamped], dtype=np.int64)
    log = np.array([p[1] for p in stamped], dtype=np.int64)
    sub = h % 1_000_000_000
    if sub.max() >= 1_000_000:
        return False
    as_given, as_microseconds = np.ptp(h - log), np.ptp(h + sub * 999 - log)
    return bool(as_given > 1_000_000 and 10 * as_microseconds < as_given)


class ClockRate:
    """A streaming least-squares line of a stream's header stamps less its log times against its log times: how
    fast the clock that stamps the messages runs against the logger's (ppm), in O(1) memory. The log times carry
    the transfer's jitter, which the line averages out over the drive; a logger that falls further behind under
    load looks the same as a fast clock, which is why ingest reports the rate and applies nothing."""

    MIN_MESSAGES = 16
    MIN_SPAN_S = 0.5

    def __init__(self) -> None:
        self._ref: tuple[int, int] | None = None
        self.n = 0
        self._sums = [0.0] * 5  # x, y, xx, xy, yy: plain floats, a message's cost stays under a microsecond

    def add(self, header_ns: int, log_ns: int) -> None:
        if self._ref is None:
            self._ref = (log_ns, header_ns - log_ns)
        x = (log_ns - self._ref[0]) / 1e9  # s since the first
        y = float(header_ns - log_ns - self._ref[1])  # ns, small: the first offset taken out
        sums = self._sums
        sums[0] += x
        sums[1] += y
        sums[2] += x * x
        sums[3] += x * y
        sums[4] += y * y
        self.n += 1

    def fit(self) -> tuple[float, float] | None:
        """(rate, its std) in ppm, or None with fewer than MIN_MESSAGES or a span under MIN_SPAN_S."""
        n = self.n
        if n < self.MIN_MESSAGES:
            return None
        sx, sy, sxx, sxy, syy = self._sums
        vxx = sxx - sx * sx / n
        if vxx <= 0 or math.sqrt(12 * vxx / n) < self.MIN_SPAN_S:
            return None
        slope = (sxy - sx * sy / n) / vxx  # ns per s
        residual = max(syy - sy * sy / n - slope * (sxy - sx * sy / n), 0.0) / (n - 2)
        std = math.sqrt(max(residual, 0.25) / vxx)  # at least the stamps' ns rounding
        return slope / 1e3, std / 1e3


class Series:
    """Ordered, de-duplicated rows of one stream, flushed in batches to ``sink``.

    ``sink(t_ns, rows)`` receives int64 times and the list of row objects in time order.
    """

    def __init__(self, sink: Callable[[np.ndarray, list[Any]], None], *, window: int = 512, flush_rows: int = 4096,
                 max_clock_step_s: float = 1.0, gap_factor: float = 5.0) -> None:
        self._sink = sink
        self.window = window
        self.flush_rows = flush_rows
        self.max_step_ns = int(max_clock_step_s * 1e9)
        self.gap_factor = gap_factor
        self.stats = SeriesStats()
        self._pending: list[tuple[int | None, int, Any]] = []
        self._offset: int | None = None
        self._buf: list[tuple[int, Any]] = []
        self._out_t: list[int] = []
        self._out_rows: list[Any] = []
        self._last_t: int | None = None
        self._period: float | None = None
        self._input_span: list[int] = []  #: [first, last] time of the rows taken since the last input ended
        self._input_rows = 0
        self._ahead: tuple[int, Any] | None = None  #: a row stamped far after the one before it, until the next
        self.inputs: list[tuple[str, int, int, int]] = []  #: (input, first, last row time ns, rows) it gave
        self.clock_rate = ClockRate()

    def push(self, header_ns: int | None, log_ns: int, row: Any) -> None:
        """Add one message: its header stamp (None or 0 if it has none), log time (ns) and decoded row."""
        self.stats.received += 1
        if self._offset is None:
            self._pending.append((header_ns, log_ns, row))
            if len(self._pending) >= _OFFSET_SAMPLES:
                self._settle_offset()
            return
        self._add(self._stamp(self._microseconds_read(header_ns), log_ns), row)

    def _microseconds_read(self, header_ns: int | None) -> int | None:
        """``header_ns`` with its sub-second part read as microseconds where the stream's stamps carry them."""
        if not self.stats.stamps_in_microseconds or not header_ns or header_ns <= 0:
            return header_ns
        return header_ns + header_ns % 1_000_000_000 * 999

    def _settle_offset(self) -> None:
        self.stats.stamps_in_microseconds = stamps_hold_microseconds([(h, lg) for h, lg, _ in self._pending])
        self._pending = [(self._microseconds_read(h), lg, row) for h, lg, row in self._pending]
        offsets = [h - lg for h, lg, _ in self._pending if h]
        self._offset = int(np.median(offsets)) if offsets else 0
        self.stats.clock_offset_ns = self._offset
        pending, self._pending = self._pending, []
        for h, lg, row in pending:
            self._add(self._stamp(h, lg), row)

    def _stamp(self, header_ns: int | None, log_ns: int) -> int:
        if not header_ns or header_ns <= 0:
            self.stats.log_time_used += 1
            return log_ns
        assert self._offset is not None
        if abs(header_ns - log_ns - self._offset) > self.max_step_ns:
            self.stats.time_jumps += 1
            return log_ns + self._offset
        self.clock_rate.add(header_ns, log_ns)
        return header_ns

    def _add(self, t: int, row: Any) -> None:
        ahead = self._ahead
        if ahead is not None:
            self._ahead = None
            if t < ahead[0] - self.max_step_ns:
                self.stats.stamp_outliers += 1
            else:
                self._take(*ahead)
        newest = self._buf[-1][0] if self._buf else self._last_t
        if newest is not None and t > newest + self.max_step_ns:
            self._ahead = (t, row)
            return
        self._take(t, row)

    def _take_ahead(self) -> None:
        """The row held ahead, taken: no row came after it to tell an outlier from a gap."""
        if self._ahead is not None:
            ahead, self._ahead = self._ahead, None
            self._take(*ahead)

    def _take(self, t: int, row: Any) -> None:
        buf = self._buf
        if self._last_t is not None and t <= self._last_t:
            if t == self._last_t:
                self.stats.duplicates += 1
            else:
                self.stats.late_dropped += 1
            return
        if not buf or t > buf[-1][0]:
            buf.append((t, row))
        else:
            i = bisect.bisect_left(buf, t, key=_KEY)
            if i < len(buf) and buf[i][0] == t:
                self.stats.duplicates += 1
                return
            self.stats.reordered += 1
            buf.insert(i, (t, row))
        span = self._input_span
        if span:
            span[0], span[1] = min(span[0], t), max(span[1], t)
        else:
            span[:] = [t, t]
        self._input_rows += 1
        if len(buf) >= 2 * self.window:
            self._emit(self.window)

    def _emit(self, n: int) -> None:
        head, self._buf = self._buf[:n], self._buf[n:]
        for t, row in head:
            self._out_t.append(t)
            self._out_rows.append(row)
        if head:
            self._last_t = head[-1][0]
        if len(self._out_t) >= self.flush_rows:
            self._flush()

    def _flush(self) -> None:
        if not self._out_t:
            return
        t = np.asarray(self._out_t, dtype=np.int64)
        rows, self._out_t, self._out_rows = self._out_rows, [], []
        self._track(t)
        self._sink(t, rows)

    def _track(self, t: np.ndarray) -> None:
        s = self.stats
        prev = np.concatenate([[s.last_ns], t]) if s.written else t
        dts = np.diff(prev)
        if self._period is None and len(dts):
            # The first flush holds flush_rows rows (or the whole stream): a robust typical period.
            self._period = float(np.median(dts))
        if self._period:
            big = np.flatnonzero(dts > self.gap_factor * self._period)
            s.gaps.extend((int(prev[i]), int(prev[i + 1])) for i in big)
        if s.written == 0:
            s.first_ns = int(t[0])
        s.written += len(t)
        s.last_ns = int(t[-1])

    def end_input(self, name: str) -> None:
        """The rows taken since the last call came from the input ``name`` (a file)."""
        if self._offset is None and self._pending:  # an input of fewer rows than the offset takes: its own
            self._settle_offset()
        self._take_ahead()
        if self._input_rows:
            self.inputs.append((name, self._input_span[0], self._input_span[1], self._input_rows))
        self._input_span, self._input_rows = [], 0

    def interleaved(self, min_overlap_ns: int) -> tuple[str, str, int, int] | None:
        """Two inputs whose rows of this stream interleave over more than ``min_overlap_ns`` (two recordings of
        it): (first input, second input, overlap start, end ns), else None. Cross-file reordering at a split
        recording's boundary stays below it."""
        for k, (a, a0, a1, _) in enumerate(self.inputs):
            for b, b0, b1, _ in self.inputs[k + 1:]:
                if b != a and min(a1, b1) - max(a0, b0) > min_overlap_ns:
                    return a, b, max(a0, b0), min(a1, b1)
        return None

    def finish(self) -> SeriesStats:
        """Write out everything still buffered; returns the statistics."""
        if self._offset is None:
            self._settle_offset()
        self._take_ahead()
        self._emit(len(self._buf))
        self._flush()
        rate = self.clock_rate.fit()
        if rate is not None:
            self.stats.clock_rate_ppm, self.stats.clock_rate_std_ppm = rate
        return self.stats

