"""What a DCA1000 lost: its packets as recorded, and the zero-filled stretches of post-processed captures.

The DCA1000EVM sends the ADC data over UDP in packets of a 10-byte header (the packet's sequence number, uint32
little-endian from 1, and the count of data bytes sent before it, uint48) and a fixed amount of data (1456 bytes by
default; the last packet may hold less). A recorder stores either the packets as they came (``<name>_Raw_<k>.bin``
with sequence numbers on), where a lost packet is missing and the byte counts say where, or, after mmWave Studio's
post-processing (``Packet_Reorder_Zerofill``), the data alone (``adc_data.bin``), where a lost packet is a stretch
of zeros. Both are found here, so that the reader leaves the PRIs they touch out rather than hand on zeros as echoes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

HEADER_BYTES = 10
MAX_PACKET_DATA = 1462  #: the DCA1000's largest data per packet (its user guide: 48-1462 bytes)
#: a run of at least this many zero int16 values is a lost packet's zero fill: the smallest packet a lost one may be
#: split into by a block edge, half of 1456 bytes, is 364 values, and real ADC noise never gives 256 zeros in a row
ZERO_RUN_VALUES = 256


def header_fields(heads: NDArray[np.uint8]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(sequence numbers, data bytes sent before) of (n, 10) packet headers: uint32 and uint48, little-endian."""
    h = np.asarray(heads, dtype=np.int64).reshape(-1, HEADER_BYTES)
    seq = h[:, 0] | h[:, 1] << 8 | h[:, 2] << 16 | h[:, 3] << 24
    count = h[:, 4] | h[:, 5] << 8 | h[:, 6] << 16 | h[:, 7] << 24 | h[:, 8] << 32 | h[:, 9] << 40
    return seq, count


def packet(sequence: int, sent: int, data: bytes | memoryview) -> bytes:
    """One DCA1000 packet: its header (``sequence`` from 1, ``sent`` data bytes before it), then ``data``."""
    return sequence.to_bytes(4, "little") + sent.to_bytes(6, "little") + bytes(data)


def packets_of(data: bytes, data_bytes: int = 1456) -> list[bytes]:
    """``data`` as the DCA1000 sends it: packets of ``data_bytes`` (the last fewer), numbered from 1."""
    return [packet(k + 1, k * data_bytes, data[k * data_bytes:(k + 1) * data_bytes])
            for k in range(-(-len(data) // data_bytes))]


def _fits(heads: NDArray[np.uint8], origin: tuple[int, int], data_bytes: int) -> NDArray[np.bool_]:
    """Which (n, 10) headers fit a recording whose first packet is ``origin`` (sequence, byte count): every packet
    but the last holds ``data_bytes``, so a packet's byte count follows from its sequence number."""
    seq, count = header_fields(heads)
    return (seq >= 1) & (count - origin[1] == (seq - origin[0]) * data_bytes)


def packet_data_bytes(head: bytes) -> int | None:
    """The data bytes per packet if ``head`` (a file's first bytes) starts with a chain of three DCA1000 packet
    headers (sequence numbers rising, byte counts advancing by that much data per packet), else None."""
    b = np.frombuffer(head, dtype=np.uint8)
    if len(b) < 3 * HEADER_BYTES + 2 * 48:
        return None
    (seq0,), (count0,) = header_fields(b[:HEADER_BYTES])
    if not 1 <= seq0 < 1 << 31:
        return None
    for length in range(48, MAX_PACKET_DATA + 1):
        at = np.array([1, 2]) * (HEADER_BYTES + length)
        if at[-1] + HEADER_BYTES > len(b):
            return None
        heads = b[at[:, None] + np.arange(HEADER_BYTES)]
        seq, _ = header_fields(heads)
        if np.all(_fits(heads, (int(seq0), int(count0)), length)) and np.all(
                (seq > seq0) & (seq <= seq0 + 64 * np.array([1, 2]))):
            return length
    return None


class SplitFiles:
    """Files recorded one after the other, read as one byte stream (a packet may straddle two files)."""

    def __init__(self, files: list[Path]) -> None:
        self.files = list(files)
        self.bounds = np.concatenate([[0], np.cumsum([f.stat().st_size for f in files])]).astype(np.int64)
        self._maps: dict[int, np.memmap] = {}

    @property
    def size(self) -> int:
        return int(self.bounds[-1])

    def _map(self, k: int) -> NDArray[np.uint8]:
        if k not in self._maps:
            self._maps[k] = np.memmap(self.files[k], dtype=np.uint8, mode="r")
        return self._maps[k]

    def where(self, g: int) -> tuple[Path, int]:
        """The file and offset of stream byte ``g``."""
        k = int(np.searchsorted(self.bounds, g, side="right")) - 1
        return self.files[k], g - int(self.bounds[k])

    def read(self, g0: int, g1: int) -> NDArray[np.uint8]:
        """Stream bytes [g0, g1): a view into one file's map, or a copy where they straddle files."""
        k0 = int(np.searchsorted(self.bounds, g0, side="right")) - 1
        k1 = int(np.searchsorted(self.bounds, g1, side="left")) - 1
        if k0 == k1:
            return self._map(k0)[g0 - self.bounds[k0]:g1 - self.bounds[k0]]
        return np.concatenate([self._map(k)[max(g0, int(self.bounds[k])) - self.bounds[k]:
                                            min(g1, int(self.bounds[k + 1])) - self.bounds[k]]
                               for k in range(k0, k1 + 1)])

    def headers(self, at: NDArray[np.int64]) -> NDArray[np.uint8]:
        """(n, 10) the bytes at stream offsets ``at`` (ascending)."""
        out = np.empty((len(at), HEADER_BYTES), dtype=np.uint8)
        k = np.searchsorted(self.bounds, at, side="right") - 1
        inside = at + HEADER_BYTES <= self.bounds[k + 1]
        for f in np.unique(k[inside]):
            sel = inside & (k == f)
            local = at[sel] - self.bounds[f]
            out[sel] = self._map(int(f))[local[:, None] + np.arange(HEADER_BYTES)]
        for j in np.flatnonzero(~inside):
            out[j] = self.read(int(at[j]), int(at[j]) + HEADER_BYTES)
        return out


def _resync(rec: SplitFiles, x: int, origin: tuple[int, int], data_bytes: int) -> int | None:
    """The first stream offset after ``x`` where a packet header that fits the recording starts, and another one
    packet later (or the recording ends within a packet): where reading resumes after damage."""
    step = HEADER_BYTES + data_bytes
    y0, window = x + 1, 1 << 16
    while y0 + HEADER_BYTES <= rec.size:
        blob = np.asarray(rec.read(y0, min(rec.size, y0 + window + HEADER_BYTES - 1)))
        if len(blob) < HEADER_BYTES:
            return None
        for c in np.flatnonzero(_fits(sliding_window_view(blob, HEADER_BYTES), origin, data_bytes)):
            y = y0 + int(c)
            if y + step + HEADER_BYTES > rec.size or _fits(rec.headers(np.array([y + step])), origin,
                                                                 data_bytes)[0]:
                return y
        y0 += window
    return None


@dataclass
class PacketIndex:
    """The packets of a recorded DCA1000 stream, in stream order (by byte count), and what is missing.

    Per packet: ``offset`` of its data in the recording (its files as one stream), ``start`` (its byte count:
    where its data goes in the ADC stream) and ``length``; ``lost``: (k, 2) ADC stream byte ranges no packet
    holds; ``total_bytes``: the ADC stream's end."""

    recording: SplitFiles
    data_bytes: int
    offset: NDArray[np.int64]
    start: NDArray[np.int64]
    length: NDArray[np.int64]
    end: NDArray[np.int64]  #: start + length
    lost: NDArray[np.int64]
    total_bytes: int
    duplicates: int
    late: int
    warnings: list[str]
    appended: str = ""  #: where a second recording appended to this one starts (a warning), else ""
    #: (k, 2) ADC stream byte ranges of packets repeated with other data: either copy may be the damaged one
    conflicting: NDArray[np.int64] = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))

    @classmethod
    def build(cls, files: list[Path], data_bytes: int, gaps_before: tuple[int, ...] = ()) -> PacketIndex:
        """Index every packet of ``files`` (one recording, in order, split anywhere). A packet whose header breaks
        the layout (every packet but the last holds ``data_bytes``, so its byte count follows from its sequence
        number) ends the run of packets there, with a warning naming the file and offset; reading resumes at the
        next header that fits. ``gaps_before``: indices of the files a missing file came before (the grid breaks
        there, and resumes at the next header without a warning of its own)."""
        rec = SplitFiles(files)
        step = HEADER_BYTES + data_bytes
        parts: list[tuple[NDArray[np.int64], ...]] = []
        warnings: list[str] = []
        origin: tuple[int, int] | None = None
        g = 0
        # where a split file is missing the grid of packets breaks without damage: it resumes at the next header
        breaks = [int(rec.bounds[k]) for k in sorted(gaps_before)]
        while g + HEADER_BYTES <= rec.size:
            stop = next((b for b in breaks if b > g), rec.size)
            n = (stop - g) // step
            at = g + np.arange(n, dtype=np.int64) * step
            lengths = np.full(n, data_bytes, dtype=np.int64)
            tail = stop - (g + n * step)
            if tail > HEADER_BYTES:  # the recording's last packet (shorter), or one cut by the end of the data
                at = np.append(at, g + n * step)
                lengths = np.append(lengths, tail - HEADER_BYTES)
            heads = rec.headers(at)
            seq, count = header_fields(heads)
            if origin is None and len(seq):
                origin = int(seq[0]), int(count[0])
            bad = np.flatnonzero(~_fits(heads, origin, data_bytes)) if origin is not None \
                else np.zeros(0, dtype=np.int64)
            end = int(bad[0]) if len(bad) else len(at)
            parts.append((at[:end] + HEADER_BYTES, count[:end], lengths[:end]))
            if not len(bad):
                if stop == rec.size:
                    if 0 < tail <= HEADER_BYTES:
                        warnings.append(f"{rec.files[-1]}: the last {tail} bytes hold no whole packet header: "
                                        "left out")
                    break
                y = _resync(rec, stop - 1, origin, data_bytes) if origin is not None else None
                if y is None:
                    break
                g = y
                continue
            x = int(at[end])
            path, local = rec.where(x)
            # from inside the packet before: a header there ends that packet short (a recording's last packet, a
            # second recording appended after it, which :func:`_restart` finds, or a packet cut short)
            y = _resync(rec, int(at[end - 1]) + HEADER_BYTES if end else x, origin, data_bytes) \
                if origin is not None else None
            if y is not None and y < x:
                prev, cut = int(at[end - 1]), y - int(at[end - 1]) - HEADER_BYTES
                parts[-1][2][end - 1] = cut
                if int(seq[end - 1]) < int(header_fields(rec.headers(np.array([y])))[0][0]):  # the stream goes on
                    where, at_prev = rec.where(prev)
                    warnings.append(f"{where}: the packet at byte {at_prev} (sequence {int(seq[end - 1])}) holds "
                                    f"{cut} of {data_bytes} data bytes: the rest lost")
                g = y
                continue
            where = "to the end of the recording" if y is None else (
                f"up to byte {rec.where(y)[1]} of {rec.where(y)[0].name}" if rec.where(y)[0] != path
                else f"up to byte {y - x + local}")
            warnings.append(f"{path}: byte {local} is no DCA1000 packet of {data_bytes} data bytes (sequence "
                            f"{int(seq[end])}, byte count {int(count[end])}): left out {where}")
            if y is None:
                break
            g = y
        offset, start, length = (np.concatenate([p[i] for p in parts]) if parts else np.zeros(0, dtype=np.int64)
                                 for i in range(3))
        if stale := _another_recordings_file(rec, offset, start, length, data_bytes, gaps_before):
            warnings.append(stale)
        k = _restart(start, data_bytes)
        # a first recording of fewer packets than that: the second's repeat its byte counts, with other data
        short, other_data = _repeats_of_other_data(rec, offset[:k], start[:k], length[:k])
        if short is not None:
            k = short
        if other_data:
            path, local = rec.where(int(offset[other_data[0]]) - HEADER_BYTES)
            warnings.append(
                f"{path}: byte {local}: a packet repeats byte count {int(start[other_data[0]])} with other data: which "
                "copy holds the ADC's data cannot be told, the PRIs it touches left out" if len(other_data) == 1 else
                f"{path}: byte {local}: {len(other_data)} packets from here on repeat byte counts with other data: "
                "which copies hold the ADC's data cannot be told, the PRIs they touch left out")
        conflicting = np.array([[start[i], start[i] + length[i]] for i in other_data], dtype=np.int64).reshape(-1, 2)
        appended = ""
        if k is not None:  # a second recording appended: not this one's stream
            path, local = rec.where(int(offset[k]) - HEADER_BYTES)
            appended = (f"{path}: byte {local}: the DCA1000's packets start again (byte count {int(start[k])} after "
                        f"{int(start[:k].max())}): a second recording appended to the first, left out (split it off "
                        f"at that byte to read it)")
            warnings.append(appended)
            offset, start, length = offset[:k], start[:k], length[:k]
        order = np.argsort(start, kind="stable")
        # a packet that arrives after one from later in the stream came out of order (UDP may reorder)
        late = int(np.count_nonzero(start < np.maximum.accumulate(np.concatenate([[-1], start[:-1]]))))
        offset, start, length = offset[order], start[order], length[order]
        repeat = np.concatenate([[False], start[1:] == start[:-1]])
        duplicates = int(np.count_nonzero(repeat))
        offset, start, length = offset[~repeat], start[~repeat], length[~repeat]
        end_at = start + length
        covered_to = np.concatenate([[0], end_at[:-1]])
        gap = start > covered_to
        lost = np.stack([covered_to[gap], start[gap]], axis=-1).reshape(-1, 2)
        total = int(end_at[-1]) if len(end_at) else 0
        return cls(rec, data_bytes, offset, start, length, end_at, lost, total, duplicates, late, warnings,
                   appended, conflicting)

    @property
    def packets(self) -> int:
        return len(self.start)

    @property
    def lost_packets(self) -> int:
        """Packets missing (their data bytes over the packet size, rounded up)."""
        return int(np.sum(-(-(self.lost[:, 1] - self.lost[:, 0]) // self.data_bytes))) if len(self.lost) else 0

    def read(self, a: int, out: NDArray[np.uint8]) -> None:
        """ADC stream bytes [a, a + len(out)) into ``out``; bytes no packet holds are 0."""
        b = a + len(out)
        out[:] = 0
        step = HEADER_BYTES + self.data_bytes
        i = int(np.searchsorted(self.end, a, side="right"))
        i1 = int(np.searchsorted(self.start, b, side="left"))
        while i < i1:
            # a run of packets back to back in the recording and in the stream: one strided copy
            j = i + 1
            while (j < i1 and self.offset[j] == self.offset[j - 1] + step
                   and self.start[j] == self.start[j - 1] + self.data_bytes and self.length[j - 1] == self.data_bytes):
                j += 1
            first, n = int(self.offset[i]) - HEADER_BYTES, j - i
            blob = self.recording.read(first, int(self.offset[j - 1]) + int(self.length[j - 1]))
            rows = np.asarray(blob[:(n - 1) * step]).reshape(n - 1, step)[:, HEADER_BYTES:]
            data = np.concatenate([rows.reshape(-1), blob[(n - 1) * step + HEADER_BYTES:]])
            s0 = int(self.start[i])
            lo, hi = max(a, s0), min(b, s0 + len(data))
            out[lo - a:hi - a] = data[lo - s0:hi - s0]
            i = j


#: a packet that arrives more than this many packets behind the furthest one is no UDP reordering but a recording
#: that starts again (two appended in one file)
RESTART_PACKETS = 64
#: a packet repeated with other data is a damaged copy where one of this many packets after it goes past the furthest
#: byte count so far (the stream goes on; UDP may have sent the next ones late); a second recording stays behind
GOES_ON_PACKETS = 8


def _restart(start: NDArray[np.int64], data_bytes: int) -> int | None:
    """The index (recording order) of the first packet of a second recording appended to the first: its byte count
    ``start`` more than ``RESTART_PACKETS`` packets behind the furthest packet so far; None where there is none."""
    if len(start) < 2:
        return None
    behind = np.maximum.accumulate(start)[:-1] - start[1:] > RESTART_PACKETS * data_bytes
    k = np.flatnonzero(behind)
    return int(k[0]) + 1 if len(k) else None


def _another_recordings_file(rec: SplitFiles, offset: NDArray[np.int64], start: NDArray[np.int64],
                             length: NDArray[np.int64], data_bytes: int, gaps_before: tuple[int, ...]) -> str | None:
    """A warning where a split file starts with a packet more than ``RESTART_PACKETS`` packets past the furthest byte
    count before it (or past it at all after a packet of fewer bytes, a recording's last) while the file before ends
    at a packet's end: an earlier, longer recording's files that a
    recording run again into the folder did not overwrite (or that file's end lost: which cannot be told); None
    where no file does. ``gaps_before``: files a missing file came before (their jump is its packets)."""
    heads = offset - HEADER_BYTES  # ascending: recording order
    for j in range(1, len(rec.files)):
        b = int(rec.bounds[j])
        i = int(np.searchsorted(heads, b))
        if j in gaps_before or not 0 < i < len(heads) or heads[i] != b or offset[i - 1] + length[i - 1] != b:
            continue
        gap = int(start[i]) - int(np.max(start[:i] + length[:i]))
        # the DCA1000 sends a packet of fewer bytes last: after it, no packet of its recording comes
        if gap > RESTART_PACKETS * data_bytes or (gap > 0 and length[i - 1] < data_bytes):
            later = ", ".join(f.name for f in rec.files[j:])
            return (f"{rec.files[j]}: its first packet (byte count {int(start[i])}) lies {gap} bytes "
                    f"({gap / data_bytes:.1f} packets) past the last of {rec.files[j - 1].name}, which ends at a "
                    f"packet's edge{' (one of fewer bytes)' if length[i - 1] < data_bytes else ''}: an earlier, "
                    f"longer recording's files left beside this one's "
                    f"(mmWave Studio run again into the folder), or the end of {rec.files[j - 1].name} lost? Move "
                    f"{later} away if they are another recording's")
    return None


def _repeats_of_other_data(rec: SplitFiles, offset: NDArray[np.int64], start: NDArray[np.int64],
                           length: NDArray[np.int64]) -> tuple[int | None, list[int]]:
    """Packets whose byte count an earlier packet holds with other data: (the index, recording order, where a second
    recording starts, or None; the indices of the other repeats). A packet repeated by UDP is the same bytes; one
    with other data followed by :data:`GOES_ON_PACKETS` packets that stay behind the furthest so far was sent by a
    DCA1000 that started again, after a first recording of too few packets for :func:`_restart` to see: the second
    starts at the last packet before it (or it) whose byte count falls behind the one before. One alone, the stream
    going on past the furthest after it, is a damaged copy, and which of the two holds the data cannot be told."""
    if len(start) < 2 or bool(np.all(start[1:] > start[:-1])):  # in order: nothing repeated
        return None, []
    _, first, inverse = np.unique(start, return_index=True, return_inverse=True)
    earlier = first[inverse.reshape(-1)]
    damaged: list[int] = []
    for i in np.flatnonzero(earlier != np.arange(len(start))):
        j, n = int(earlier[i]), int(min(length[i], length[earlier[i]]))
        if not np.array_equal(rec.read(int(offset[i]), int(offset[i]) + n), rec.read(int(offset[j]),
                                                                                  int(offset[j]) + n)):
            if i == len(start) - 1 or np.any(start[i + 1:i + 1 + GOES_ON_PACKETS] > start[:i].max()):
                damaged.append(int(i))
                continue
            drops = np.flatnonzero(start[j + 1:i + 1] < start[j:i])
            k = j + 1 + int(drops[-1]) if len(drops) else int(i)
            return k, [d for d in damaged if d < k]
    return None, damaged


def zero_runs(values: NDArray[np.int16], min_values: int = ZERO_RUN_VALUES) -> NDArray[np.int64]:
    """(k, 2) [start, stop) value ranges of the runs of at least ``min_values`` zeros in ``values`` (1-D), found
    on aligned groups of four values (a run of n zeros holds n // 4 - 1 whole groups at least)."""
    n4 = len(values) // 4 * 4
    words = values[:n4].view("<i8") if values.flags.c_contiguous else np.ascontiguousarray(values[:n4]).view("<i8")
    min_words = min_values // 4 - 1
    zero = words == 0
    if np.count_nonzero(zero) < min_words:
        return np.zeros((0, 2), dtype=np.int64)
    edges = np.diff(zero.view(np.int8), prepend=0, append=0)
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    keep = stops - starts >= min_words
    return np.stack([starts[keep] * 4, stops[keep] * 4], axis=-1).astype(np.int64).reshape(-1, 2)


def within(ranges: NDArray[np.int64], lo: int, hi: int) -> bool:
    """Whether [lo, hi) lies inside one of ``ranges`` ((k, 2) [start, stop))."""
    return bool(np.any((ranges[:, 0] <= lo) & (ranges[:, 1] >= hi)))


def edge_zeros(values: NDArray[np.int16], cap: int = ZERO_RUN_VALUES) -> tuple[int, int]:
    """Zero values at the start and at the end of ``values`` (1-D), each counted up to ``cap``."""
    head, tail = values[:cap], values[::-1][:cap]
    nz_head, nz_tail = np.flatnonzero(head), np.flatnonzero(tail)
    return (int(nz_head[0]) if len(nz_head) else len(head)), (int(nz_tail[0]) if len(nz_tail) else len(tail))
