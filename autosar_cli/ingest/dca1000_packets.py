"""What a DCA1000 lost: its packets as recorded, and the zero-filled stretches of post-processed captures.

The DCA1000EVM sends the ADC data over UDP in packets of a 10-byte header (the packet's sequence number, uint32
little-endian from 1, and the count of data bytes sent before it, uint48) and a fixed amount of data (1456 bytes by
default; the last packet may hold less). A recorder stores either the packets as they came (``<name>_Raw_<k>.bin``
with sequence numbers on), where a lost packet is missing and the byte counts say where, or, after mmWave Studio's
post-processing (``Packet_Reorder_Zerofill``), the data alone (``adc_data.bin``), where a lost packet is a stretch
of zeros. Both are found here, so that the reader leaves the PRIs they touch out rather than hand on zeros as echoes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

HEADER_BYTES = 10
MAX_PACKET_DATA = 1462  #: the DCA1000's largest data per packet (its user guide: 48-1462 bytes)
#: a run of at least this many zero int16 values is a lost packet's zero fill: the smallest packet a lost one may be
#: split into by a block edge, half of 1456 bytes, is 364 values, and real ADC noise never gives 256 zeros in a row
ZERO_RUN_VALUES = 256


def _u48(b: NDArray[np.uint8]) -> NDArray[np.int64]:
    """Little-endian uint48 from (n, 6) bytes."""
    wide = np.zeros((len(b), 8), dtype=np.uint8)
    wide[:, :6] = b
    return wide.view("<u8").reshape(-1).astype(np.int64)


def packet_data_bytes(head: bytes) -> int | None:
    """The data bytes per packet if ``head`` (a file's first bytes) starts with a chain of three DCA1000 packet
    headers (sequence numbers rising, byte counts advancing by that much data per packet), else None."""
    b = np.frombuffer(head, dtype=np.uint8)
    if len(b) < 3 * HEADER_BYTES + 2 * 48:
        return None
    seq0 = int(b[:4].view("<u4")[0])
    count0 = int(_u48(b[4:10].reshape(1, 6))[0])
    if not 1 <= seq0 < 1 << 31:
        return None
    for length in range(48, MAX_PACKET_DATA + 1):
        ok = True
        for k in (1, 2):
            at = k * (HEADER_BYTES + length)
            if at + HEADER_BYTES > len(b):
                ok = False
                break
            seq = int(b[at:at + 4].view("<u4")[0])
            count = int(_u48(b[at + 4:at + 10].reshape(1, 6))[0])
            if not (seq0 < seq <= seq0 + 64 * k and count - count0 == (seq - seq0) * length):
                ok = False
                break
        if ok:
            return length
    return None


@dataclass
class PacketIndex:
    """The packets of a recorded DCA1000 stream, in stream order (by byte count), and what is missing.

    ``file``, ``offset`` (of the data in that file), ``start`` (stream byte) and ``length`` per packet;
    ``lost``: (k, 2) stream byte ranges no packet holds; ``total_bytes``: the stream's end."""

    files: list[Path]
    data_bytes: int
    file: NDArray[np.int64]
    offset: NDArray[np.int64]
    start: NDArray[np.int64]
    length: NDArray[np.int64]
    lost: NDArray[np.int64]
    total_bytes: int
    duplicates: int
    late: int
    warnings: list[str]

    @classmethod
    def build(cls, files: list[Path], data_bytes: int) -> PacketIndex:
        """Index every packet of ``files`` (one recording, in order); a stretch that breaks the packet layout is
        left out with a warning naming its file and offset, as is everything after it in that file."""
        step = HEADER_BYTES + data_bytes
        parts: list[tuple[NDArray[np.int64], ...]] = []
        warnings: list[str] = []
        seq_origin = count_origin = None
        for k, path in enumerate(files):
            size = path.stat().st_size
            raw = np.memmap(path, dtype=np.uint8, mode="r") if size else np.zeros(0, np.uint8)
            n = size // step
            heads = np.asarray(raw[:n * step]).reshape(n, step)[:, :HEADER_BYTES] if n else np.zeros((0, 10), np.uint8)
            seq = heads[:, :4].copy().view("<u4").reshape(-1).astype(np.int64)
            count = _u48(heads[:, 4:10])
            offsets = np.arange(n, dtype=np.int64) * step + HEADER_BYTES
            lengths = np.full(n, data_bytes, dtype=np.int64)
            tail = size - n * step
            if tail > HEADER_BYTES:  # the recording's last packet, shorter, or one cut by the end of the file
                h = np.asarray(raw[n * step:n * step + HEADER_BYTES])
                seq = np.append(seq, int(h[:4].view("<u4")[0]))
                count = np.append(count, _u48(h[4:10].reshape(1, 6)))
                offsets = np.append(offsets, n * step + HEADER_BYTES)
                lengths = np.append(lengths, tail - HEADER_BYTES)
            if seq_origin is None and len(seq):
                seq_origin, count_origin = int(seq[0]), int(count[0])
            # every packet but the last holds data_bytes, so a packet's byte count follows from its sequence number
            if seq_origin is not None:
                bad = np.flatnonzero((count - count_origin != (seq - seq_origin) * data_bytes) | (seq < 1))
                if len(bad):
                    j = int(bad[0])
                    warnings.append(f"{path}: byte {int(offsets[j]) - HEADER_BYTES} is no DCA1000 packet of "
                                    f"{data_bytes} data bytes (sequence {int(seq[j])}, byte count {int(count[j])}): "
                                    f"the rest of the file ({size - int(offsets[j]) + HEADER_BYTES} bytes) left out")
                    seq, count, offsets, lengths = seq[:j], count[:j], offsets[:j], lengths[:j]
            if 0 < tail <= HEADER_BYTES:
                warnings.append(f"{path}: the last {tail} bytes hold no whole packet header: left out")
            parts.append((np.full(len(seq), k, dtype=np.int64), offsets, count, lengths))
        file, offset, start, length = (np.concatenate([p[i] for p in parts]) for i in range(4))
        order = np.argsort(start, kind="stable")
        # a packet that arrives after one from later in the stream came out of order (UDP may reorder)
        late = int(np.count_nonzero(start < np.maximum.accumulate(np.concatenate([[-1], start[:-1]]))))
        file, offset, start, length = file[order], offset[order], start[order], length[order]
        repeat = np.concatenate([[False], start[1:] == start[:-1]])
        duplicates = int(np.count_nonzero(repeat))
        file, offset, start, length = file[~repeat], offset[~repeat], start[~repeat], length[~repeat]
        end = start + length
        covered_to = np.concatenate([[0], end[:-1]])
        gap = start > covered_to
        lost = np.stack([covered_to[gap], start[gap]], axis=-1).reshape(-1, 2)
        total = int(end[-1]) if len(end) else 0
        return cls(list(files), data_bytes, file, offset, start, length, lost, total, duplicates, late, warnings)

    @property
    def packets(self) -> int:
        return len(self.start)

    @property
    def lost_packets(self) -> int:
        """Packets missing (their data bytes over the packet size, rounded up)."""
        return int(np.sum(-(-(self.lost[:, 1] - self.lost[:, 0]) // self.data_bytes))) if len(self.lost) else 0

    def read(self, a: int, out: NDArray[np.uint8]) -> None:
        """Stream bytes [a, a + len(out)) into ``out``; bytes no packet holds are 0."""
        b = a + len(out)
        out[:] = 0
        i0 = int(np.searchsorted(self.start + self.length, a, side="right"))
        i1 = int(np.searchsorted(self.start, b, side="left"))
        maps: dict[int, np.memmap] = {}
        i = i0
        while i < i1:
            # a run of packets that lie back to back in one file and in the stream: one strided copy
            f, j = int(self.file[i]), i + 1
            step = HEADER_BYTES + self.data_bytes
            while (j < i1 and self.file[j] == f and self.offset[j] == self.offset[j - 1] + step
                   and self.start[j] == self.start[j - 1] + self.data_bytes and self.length[j - 1] == self.data_bytes):
                j += 1
            raw = maps.get(f)
            if raw is None:
                raw = maps[f] = np.memmap(self.files[f], dtype=np.uint8, mode="r")
            first = int(self.offset[i]) - HEADER_BYTES
            n = j - i
            if n == 1:
                data = raw[first + HEADER_BYTES:first + HEADER_BYTES + int(self.length[i])]
            else:
                last_len = int(self.length[j - 1])
                rows = np.asarray(raw[first:first + (n - 1) * step]).reshape(n - 1, step)[:, HEADER_BYTES:]
                tail_at = first + (n - 1) * step + HEADER_BYTES
                data = np.concatenate([rows.reshape(-1), raw[tail_at:tail_at + last_len]])
            s0 = int(self.start[i])
            lo, hi = max(a, s0), min(b, s0 + len(data))
            out[lo - a:hi - a] = data[lo - s0:hi - s0]
            i = j


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
