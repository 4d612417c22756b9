"""TI mmWave raw ADC captures recorded with a DCA1000EVM: layouts, streaming reader and writer.

A capture is a flat binary of int16 ADC values (mmWave Studio's post-processed ``adc_data.bin``, or its
split files ``<base>_0.bin``, ``<base>_1.bin`` … read as one stream) plus the parameters it was recorded
with: mmWave Studio's ``*.mmwave.json`` (+ ``*.setup.json``) or Lua script, or an mmWave SDK ``.cfg``. Layouts follow
TI's application note "mmWave sensor raw data capture using the DCA1000" (SWRA581):

* 4-lane LVDS (xWR12xx/14xx, e.g. the AWR1243): one lane per Rx, all four lanes always present (unused
  ones hold zeros). Complex: per ADC sample, I of lanes 1-4 then Q of lanes 1-4 (8 values); real: per
  sample the 4 lanes.
* 2-lane LVDS (xWR16xx/18xx/68xx): per chirp, each enabled Rx's samples in turn. Complex: pairs of
  samples as I(n), I(n+1), Q(n), Q(n+1); real: one value per sample.

Complex 1x and complex 2x differ only in the device's filtering, not in the layout. Real samples are
stored as I with Q = 0. One TI frame holds ``num_loops`` loops of the chirp table; each loop (one chirp
per Tx, TDM-MIMO) becomes one PRI of the drive, with the Tx axis in ascending Tx index order.
"""

from __future__ import annotations

import glob
import re
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .dca1000_lua import parse_studio_lua
from .dca1000_packets import (
    HEADER_BYTES,
    MAX_PACKET_DATA,
    ZERO_RUN_VALUES,
    PacketIndex,
    edge_zeros,
    packet,
    packet_data_bytes,
    within,
    zero_runs,
)
from .dca1000_params import (
    ADC_BITS,
    ADC_FORMATS,
    LANE_SLOTS_4,
    CaptureError,
    CaptureParams,
    check_dca1000_configs,
    params_from_radar,
    parse_sdk_cfg,
    parse_studio_json,
    write_sdk_cfg,
    write_studio_json,
)

__all__ = ["ADC_BITS", "ADC_FORMATS", "CaptureError", "CaptureParams", "CaptureWriter", "Dca1000Capture",
           "decode_chirps", "encode_chirps", "find_capture", "frames_to_pris", "is_capture", "params_from_radar",
           "pris_to_frames", "write_capture"]


# --------------------------------------------------------------------------------------- chirp layout
def decode_chirps(values: NDArray[np.int16], p: CaptureParams) -> NDArray[np.int16]:
    """File values (n, chirp_values) -> (n, rx, sample, I/Q) int16 in the drive's layout."""
    n, r, s = len(values), p.num_rx, p.num_samples
    out = np.empty((n, r, s, 2), dtype=np.int16)
    if p.lanes == 4:
        lanes = list(p.rx_channels)
        if p.complex:
            v = values.reshape(n, s, 2, LANE_SLOTS_4)
            out[...] = v[:, :, :, lanes].transpose(0, 3, 1, 2)
        else:
            out[..., 0] = values.reshape(n, s, LANE_SLOTS_4)[:, :, lanes].transpose(0, 2, 1)
            out[..., 1] = 0
    elif p.complex:
        out.reshape(-1)[...] = _swap_middle_pair(values).reshape(-1)
    else:
        out[..., 0] = values.reshape(n, r, s)
        out[..., 1] = 0
    return out


def _swap_middle_pair(values: NDArray[np.int16]) -> NDArray[np.int16]:
    """I(n) I(n+1) Q(n) Q(n+1) <-> I(n) Q(n) I(n+1) Q(n+1): the middle two of every four int16 values swapped,
    as 64-bit words (a 2x2 transpose in numpy's strided copy ran at a third of the speed)."""
    w = np.ascontiguousarray(values).reshape(-1).view("<u8")
    swapped = (w & np.uint64(0xFFFF00000000FFFF)) | ((w >> np.uint64(16)) & np.uint64(0xFFFF0000)) \
        | ((w & np.uint64(0xFFFF0000)) << np.uint64(16))
    return swapped.view(np.int16)


def encode_chirps(iq: NDArray[np.int16], p: CaptureParams) -> NDArray[np.int16]:
    """(n, rx, sample, I/Q) int16 -> file values (n, chirp_values); the inverse of :func:`decode_chirps`."""
    n, s = iq.shape[0], p.num_samples
    if p.lanes == 4:
        lanes = list(p.rx_channels)
        if p.complex:
            v = np.zeros((n, s, 2, LANE_SLOTS_4), dtype=np.int16)
            v[:, :, :, lanes] = iq.transpose(0, 2, 3, 1)
        else:
            v = np.zeros((n, s, LANE_SLOTS_4), dtype=np.int16)
            v[:, :, lanes] = iq[..., 0].transpose(0, 2, 1)
    elif p.complex:
        v = _swap_middle_pair(iq)
    else:
        v = np.ascontiguousarray(iq[..., 0])
    return v.reshape(n, -1)


def frames_to_pris(values: NDArray[np.int16], p: CaptureParams) -> NDArray[np.int16]:
    """(frames, frame values) -> (frames * loops, tx, rx, sample, I/Q): chirps regrouped by Tx index."""
    n = len(values) * p.num_loops
    if p.adc_bits != 16:  # sign-extend: a 12/14-bit sample sits in the low bits of its int16
        values = values.copy()
        values[values >= 1 << (p.adc_bits - 1)] -= np.int16(1 << p.adc_bits)
    chirps = decode_chirps(values.reshape(n * p.num_tx, p.chirp_values), p).reshape(n, p.num_tx, p.num_rx,
                                                                                  p.num_samples, 2)
    order = [p.chirp_tx.index(tx) for tx in p.tx_order]
    return chirps if order == list(range(p.num_tx)) else chirps[:, order]


def pris_to_frames(pris: NDArray[np.int16], p: CaptureParams) -> NDArray[np.int16]:
    """(frames * loops, tx, rx, sample, I/Q) -> file values (frames, frame values); inverse of the above."""
    slot = [p.tx_order.index(tx) for tx in p.chirp_tx]
    chirps = pris[:, slot].reshape(-1, p.num_rx, p.num_samples, 2)
    values = encode_chirps(chirps, p).reshape(-1, p.frame_bytes // 2)
    return values & np.int16((1 << p.adc_bits) - 1) if p.adc_bits != 16 else values


# ------------------------------------------------------------------------------------------- capture
_SPLIT = re.compile(r"^(.*)_(\d+)\.bin$")


#: a capture's parameter files, by preference: mmWave Studio's JSON, an mmWave SDK CLI config, a Studio Lua script
_PARAM_GLOBS = ("*.mmwave.json", "*.cfg", "*.lua")


def is_capture(path: Path) -> bool:
    """A DCA1000 capture: a directory or .bin file with a parameter file (.mmwave.json / .cfg / .lua) beside it."""
    if not (path.is_dir() or path.suffix.lower() == ".bin"):
        return False
    try:
        find_capture(path)
    except CaptureError:
        return False
    return True


def capture_problem(path: Path) -> str | None:
    """Why a directory holding ADC data (``*.bin``) or mmWave Studio's parameters (``*.mmwave.json``) is not read as a
    capture; None where it is one, or holds neither (a folder's ``.cfg`` or ``.lua`` may be any tool's)."""
    if not path.is_dir() or not any(next(path.glob(g), None) for g in ("*.bin", "*.mmwave.json")):
        return None
    try:
        find_capture(path)
    except CaptureError as exc:
        return str(exc)
    return None


def find_capture(path: Path) -> tuple[list[Path], Path]:
    """(data files in stream order, parameter file) of a capture directory, data file or parameter file (which is
    then the one read, whatever else lies beside it)."""
    named = None
    if path.is_file() and path.suffix.lower() != ".bin":  # the parameter file names its capture's folder
        named, path = path, path.parent
    folder = path if path.is_dir() else path.parent
    params = [named] if named else next((found for g in _PARAM_GLOBS if (found := sorted(folder.glob(g)))), [])
    if not params:
        raise CaptureError(f"{path}: no DCA1000 parameter file (*.mmwave.json, mmWave SDK *.cfg or mmWave Studio "
                           "*.lua) beside it")
    if len(params) > 1:
        raise CaptureError(f"{path}: several parameter files ({', '.join(p.name for p in params)}); give the "
                           "capture's as CAPTURE, or keep one")
    if path.is_file():
        m = _SPLIT.match(path.name)
        files = _split_series(folder, m.group(1)) if m else [path]
        return files, params[0]
    if (folder / "adc_data.bin").exists():  # mmWave Studio's post-processed data, beside its raw adc_data_Raw_<k>
        others = [b.name for b in sorted(folder.glob("*.bin")) if b.name != "adc_data.bin"
                  and not re.fullmatch(r"adc_data_Raw_\d+\.bin", b.name)]
        if others:
            raise CaptureError(f"{path}: adc_data.bin and {', '.join(others)}: the data of two captures? Give the "
                               "capture's .bin file as CAPTURE")
        if differs := _not_its_raw_twin(folder):
            raise CaptureError(f"{path}: adc_data.bin is not adc_data_Raw_0.bin's data ({differs}): the data of two "
                               "recordings (mmWave Studio run again into this folder)? Give the capture's .bin file as "
                               "CAPTURE")
        return [folder / "adc_data.bin"], params[0]
    bases = sorted({m.group(1) for p in folder.glob("*_*.bin") if (m := _SPLIT.match(p.name))})
    if len(bases) == 1:
        series = _split_series(folder, bases[0])
        if others := [b.name for b in sorted(folder.glob("*.bin")) if b not in series]:
            raise CaptureError(f"{path}: {', '.join(others)} beside the split series {bases[0]}_<k>.bin: the data of "
                               "two captures? Give the capture's .bin file as CAPTURE")
        return series, params[0]
    bins = sorted(folder.glob("*.bin"))
    if len(bins) == 1:
        return bins, params[0]
    if named is not None:  # "." (its folder) had named a file given as CAPTURE that is none of a capture's
        raise CaptureError(f"{named}: not a DCA1000 capture (taken for its parameter file, no ADC data lies beside it: "
                           f"expected adc_data.bin or one series of split files <name>_0.bin, <name>_1.bin …, found "
                           f"{', '.join(p.name for p in bins) or 'no .bin file'})")
    raise CaptureError(f"{path}: expected adc_data.bin or one series of split files <name>_0.bin, <name>_1.bin …, "
                       f"found {', '.join(p.name for p in bins) or 'no .bin file'}")


def _not_its_raw_twin(folder: Path) -> str | None:
    """Where ``folder``'s ``adc_data.bin`` is not mmWave Studio's post-processing of the ``adc_data_Raw_0.bin`` beside
    it (the first packet's data, or the first 4 KiB of data recorded without headers, not at its place in
    ``adc_data.bin``): which bytes differ; None where it is, or no raw twin lies beside it."""
    raw = folder / "adc_data_Raw_0.bin"
    if not raw.is_file():
        return None
    with open(raw, "rb") as f:
        head = f.read(4 * (HEADER_BYTES + MAX_PACKET_DATA))
    data_bytes = packet_data_bytes(head)
    if data_bytes:  # its first packet's data goes at the byte count its header gives
        at = int.from_bytes(head[4:HEADER_BYTES], "little")
        recorded = head[HEADER_BYTES:HEADER_BYTES + data_bytes]
    else:
        at, recorded = 0, head[:4096]
    with open(folder / "adc_data.bin", "rb") as f:
        f.seek(at)
        post = f.read(len(recorded))
    if post == recorded:
        return None
    i = next((k for k, (a, b) in enumerate(zip(post, recorded, strict=False)) if a != b), len(post))
    return f"stream byte {at + i} differs" if i < len(post) else f"it ends at byte {at + len(post)}, inside the " \
                                                               "raw file's first data"


def load_params(path: Path) -> tuple[CaptureParams, list[Path]]:
    """Parameters from a ``*.mmwave.json``, ``.cfg`` or mmWave Studio ``.lua`` file, checked against the DCA1000's
    configurations beside it; and those configurations."""
    if path.suffix.lower() == ".lua":
        params = parse_studio_lua(path)
    else:
        params = parse_studio_json(path) if path.name.endswith(".mmwave.json") else parse_sdk_cfg(path)
    return params, check_dca1000_configs(path, params)


def _split_series(folder: Path, base: str) -> list[Path]:
    """The split files ``<base>_<k>.bin`` present, by k (one missing in the middle leaves a gap: see
    :func:`missing_split_files`)."""
    indexed = sorted((int(m.group(2)), p) for p in folder.glob(f"{glob.escape(base)}_*.bin")
                     if (m := _SPLIT.match(p.name)) and m.group(1) == base)
    if not indexed or indexed[0][0] != 0:
        raise CaptureError(f"{folder / base}_0.bin: the split series must start at _0.bin")
    return [p for _, p in indexed]


def _split_number(path: Path) -> int:
    m = _SPLIT.match(path.name)
    return int(m.group(2)) if m else 0


def missing_split_files(files: list[Path]) -> list[int]:
    """Numbers of the split files missing between the first and the last of ``files`` (a series from
    :func:`_split_series`, which starts at 0)."""
    have = {_split_number(f) for f in files}
    return [k for k in range(max(have)) if k not in have]


def _zeros_beside(values: NDArray[np.int16], at: int, side: int, most: int = 3) -> int:
    """Zero values next to index ``at`` of ``values`` (up to ``most``): those before it (``side`` -1) or from it on
    (1); where a zero run found on aligned groups of four really starts or ends."""
    k = 0
    while k < most and 0 <= (i := at - k - 1 if side < 0 else at + k) < len(values) and values[i] == 0:
        k += 1
    return k


def _flag(damaged: NDArray[np.bool_], lo: int, hi: int, per_pri: int) -> None:
    """Flag the PRIs that [lo, hi) touches (offsets in the block, ``per_pri`` of them to a PRI; clipped to it)."""
    lo, hi = max(lo, 0), min(hi, len(damaged) * per_pri)
    if hi > lo:
        damaged[lo // per_pri:(hi - 1) // per_pri + 1] = True


class Dca1000Capture:
    """A capture opened for streaming: its parameters, frame count and a block iterator over its PRIs.

    The data files hold either the ADC data alone or the DCA1000's packets as recorded (found by their headers,
    :mod:`.dca1000_packets`). PRIs a lost packet touches, or a stretch of zeros where post-processing filled one,
    are flagged by :meth:`blocks`; ``damage`` counts them once the blocks are read, and ``warnings`` says so.
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.files, self.param_file = find_capture(self.path)
        self.params, self.config_files = load_params(self.param_file)  #: config_files: the DCA1000's, checked
        self.warnings: list[str] = []
        p = self.params
        with open(self.files[0], "rb") as f:
            data_bytes = packet_data_bytes(f.read(4 * (HEADER_BYTES + MAX_PACKET_DATA)))
        missing = missing_split_files(self.files)
        names = ", ".join(self.files[0].name.replace("_0.bin", f"_{k}.bin") for k in missing)
        if missing and data_bytes:  # the byte counts say where the later files' packets belong
            self.warnings.append(f"{self.files[0].parent}: split file{'s' if len(missing) > 1 else ''} {names} "
                                 f"missing: {'their' if len(missing) > 1 else 'its'} packets are lost")
        elif missing:  # the data alone: where the later files' data belongs is unknown without the missing one
            kept = self.files[:missing[0]]  # _0 … up to the first missing
            self.warnings.append(f"{self.files[0].parent}: split file {names.split(', ')[0]} missing: the "
                                 f"{len(self.files) - len(kept)} after it left out, for where their data belongs "
                                 f"is unknown without it")
            self.files = kept
        numbers = [_split_number(f) for f in self.files]
        gaps_before = tuple(k for k in range(1, len(numbers)) if numbers[k] != numbers[k - 1] + 1)
        self.packets = PacketIndex.build(self.files, data_bytes, gaps_before) if data_bytes else None
        if self.packets is not None:
            self.warnings.extend(self.packets.warnings)
            self.bytes_total = self.packets.total_bytes
        else:
            self.bytes_total = sum(f.stat().st_size for f in self.files)
        if self.bytes_total < p.frame_bytes:
            appended = f"; {self.packets.appended}" if self.packets is not None and self.packets.appended else ""
            raise CaptureError(f"{self.name}: {self.bytes_total} bytes fit no frame layout of {self.param_file.name}: "
                               f"expected whole frames of {p.describe_layout()}{appended}")
        self.num_frames, self.partial_bytes = divmod(self.bytes_total, p.frame_bytes)
        if p.num_frames and self.num_frames > p.num_frames:  # the recording's frames kept; what follows cannot be
            surplus = self.bytes_total - p.num_frames * p.frame_bytes  # told from a second recording appended
            extra = self.num_frames - p.num_frames
            part = f" and {self.partial_bytes} bytes" if self.partial_bytes else ""
            self.warnings.append(
                f"{self.name}: holds {self.num_frames} frames{part} but {self.param_file.name} configures "
                f"{p.num_frames} ({p.describe_layout()}): its first {p.num_frames} kept, the {surplus} bytes after "
                f"them left out ({extra} frame{'s' if extra > 1 else ''}{part}: a second recording appended, or "
                "numFrames not the recording's?)")
            self.num_frames, self.partial_bytes = p.num_frames, 0
        if self.partial_bytes:  # a recording cut short (a full disk, an interrupted copy) keeps its whole frames
            self.warnings.append(f"{self.name}: trailing partial frame left out ({self.partial_bytes} of "
                                 f"{p.frame_bytes} bytes, 1 frame)")
        if p.num_frames and self.num_frames < p.num_frames:  # cut at a frame's end, it looked whole
            self.warnings.append(f"{self.name}: holds {self.num_frames} of the {p.num_frames} frames "
                                 f"{self.param_file.name} configures: the capture stopped early or its file was cut "
                                 "short")
        self._check_word_bits()
        #: PRIs left out by :meth:`blocks`' flags, by cause, once the blocks are read
        self.damage = {"lost packets": 0, "zero-filled runs": 0, "PRIs": 0}

    def _check_word_bits(self, frames: int = 8) -> None:
        """The first ``frames`` frames' words must be samples of the ADC bits the parameters give: 12/14-bit ones lie
        in -2^(bits-1)..2^bits - 1 (sign-extended or not); 16-bit ones are signed, so words that are none negative,
        all below 2^14 and lie both near 0 and near the top of a 12/14-bit range (its negative samples, unextended)
        are narrower samples, which read as 16-bit would wrap every negative one. A quiet scene's 16-bit samples about
        a DC offset (150..449: none negative) lie near neither end."""
        p = self.params
        blocks = self._value_blocks(frames)
        _, values = next(blocks)
        blocks.close()
        lo, hi = int(values.min()), int(values.max())
        src = self.param_file.name
        bits = 12 if hi < 1 << 12 else 14
        if (p.adc_bits == 16 and lo >= 0 and 0 < hi < 1 << 14 and bool(np.any(values < 1 << (bits - 2)))
                and bool(np.any(values >= 3 << (bits - 2)))):
            raise CaptureError(f"{self.name}: {src} gives 16-bit ADC samples, but the first {len(values)} words are "
                               f"none negative and none above {hi}, near both 0 and 2^{bits}: unextended {bits}-bit "
                               "samples? State the ADC's bits (b2AdcBits, adcCfg's numADCBits)")
        if p.adc_bits != 16 and not -(1 << (p.adc_bits - 1)) <= lo <= hi < 1 << p.adc_bits:
            bad = int(np.flatnonzero((values < -(1 << (p.adc_bits - 1))) | (values >= 1 << p.adc_bits))[0])
            raise CaptureError(f"{self.name}: {src} gives {p.adc_bits}-bit ADC samples, but frame "
                               f"{bad // (p.frame_bytes // 2)} holds the word {int(values[bad])}, outside "
                               f"{-(1 << (p.adc_bits - 1))}..{(1 << p.adc_bits) - 1}: wider samples? State the ADC's "
                               "bits (b2AdcBits, adcCfg's numADCBits)")

    @property
    def name(self) -> str:
        """The data files, for messages."""
        return str(self.files[0]) if len(self.files) == 1 else f"{self.files[0]} (+{len(self.files) - 1} split files)"

    @property
    def num_pris(self) -> int:
        return self.num_frames * self.params.num_loops

    @property
    def whole_loops(self) -> int | None:
        """Loops of the chirp table the data holds (a trailing partial frame's included), None where it ends inside
        one."""
        loop_bytes = self.params.frame_bytes // self.params.num_loops
        read = self.num_frames * self.params.frame_bytes + self.partial_bytes  # the bytes of frames read
        return None if read % loop_bytes else read // loop_bytes

    @property
    def layout(self) -> str:
        """How the data files hold the stream, for ``autosar info``."""
        trigger = "; frames on a hardware trigger, timed by the sync topic at ingest" \
            if self.params.hardware_trigger else ""
        if self.packets is None:
            return "ADC data" + trigger
        k = self.packets
        other = f" ({len(k.conflicting)} with other data: their PRIs left out)" if len(k.conflicting) else ""
        return (f"DCA1000 packets of {k.data_bytes} data bytes: {k.packets} recorded, {k.lost_packets} lost, "
                f"{k.late} out of order, {k.duplicates} repeated{other}{trigger}")

    def frame_starts_ns(self, start_ns: int, period_s: float | None = None) -> NDArray[np.int64]:
        """Each frame's start (ns since the epoch) of a frame every ``period_s`` (None: the frame period) from
        ``start_ns``."""
        frames = np.arange(self.num_frames, dtype=np.float64)
        period = self.params.frame_period_s if period_s is None else period_s
        return int(start_ns) + np.round(frames * (period * 1e9)).astype(np.int64)

    def pri_times_ns(self, frame_starts_ns: NDArray[np.int64]) -> NDArray[np.int64]:
        """Start of every PRI (ns since the epoch): its frame's start (one per frame, :meth:`frame_starts_ns` for
        periodic frames), then the loop period within the frame."""
        p = self.params
        loop_t = np.round(np.arange(p.num_loops) * (p.loop_period_s * 1e9)).astype(np.int64)
        return (np.asarray(frame_starts_ns, dtype=np.int64)[:self.num_frames, None] + loop_t[None, :]).reshape(-1)

    def blocks(self, frames_per_block: int = 64
               ) -> Iterator[tuple[int, NDArray[np.int16], NDArray[np.bool_]]]:
        """(first PRI index, PRIs (n, tx, rx, sample, I/Q) int16, damaged (n,) bool) for consecutive blocks of whole
        frames. A damaged PRI holds bytes a lost packet should have: missing from the recorded packets, or a run of
        at least ``ZERO_RUN_VALUES`` zeros (post-processing's fill), a run across two blocks included."""
        p = self.params
        pri_values = p.frame_bytes // 2 // p.num_loops
        k = self.packets
        lost = np.concatenate([k.lost, k.conflicting]) if k is not None else np.zeros((0, 2), dtype=np.int64)
        self.damage = {"lost packets": k.lost_packets if k is not None else 0, "zero-filled runs": 0, "PRIs": 0}
        if k is not None and len(k.conflicting):
            self.damage["packets repeated with other data"] = len(k.conflicting)
        pending: tuple[int, NDArray[np.int16], NDArray[np.bool_]] | None = None
        pending_trail = 0
        for first, values in self._value_blocks(frames_per_block):
            n = len(values) // pri_values
            damaged = np.zeros(n, dtype=bool)
            a, b = 2 * first * pri_values, 2 * (first + n) * pri_values  # stream bytes of the block
            for lo, hi in lost[(lost[:, 1] > a) & (lost[:, 0] < b)]:  # stream bytes
                _flag(damaged, int(lo) - a, int(hi) - a, 2 * pri_values)
            runs = zero_runs(values)
            for lo, hi in runs:  # values; a run found on aligned groups of four may reach three zeros further
                lo, hi = int(lo) - _zeros_beside(values, int(lo), -1), int(hi) + _zeros_beside(values, int(hi), 1)
                _flag(damaged, lo, hi, pri_values)
            lead, trail = edge_zeros(values)
            # zeros where no packet was are lost packets, counted already
            self.damage["zero-filled runs"] += sum(not within(lost, a + 2 * int(lo), a + 2 * int(hi))
                                                   for lo, hi in runs)
            if pending is not None:
                if pending_trail and lead and pending_trail + lead >= ZERO_RUN_VALUES:
                    pending[2][-1] = damaged[0] = True
                    if pending_trail < ZERO_RUN_VALUES and lead < ZERO_RUN_VALUES and not within(lost, a - 2, a + 2):
                        self.damage["zero-filled runs"] += 1  # found on neither side alone
                self.damage["PRIs"] += int(pending[2].sum())
                yield pending
            pending = (first, frames_to_pris(values.reshape(-1, p.frame_bytes // 2), p), damaged)
            pending_trail = trail
        if pending is not None:
            self.damage["PRIs"] += int(pending[2].sum())
            yield pending
        if self.damage["PRIs"]:
            causes = [f"{v} {k}" for k, v in self.damage.items() if v and k != "PRIs"]
            self.warnings.append(f"{self.name}: {self.damage['PRIs']} of {self.num_pris} PRIs left out, they hold "
                                 f"data the DCA1000 lost ({', '.join(causes)})")

    def _value_blocks(self, frames_per_block: int) -> Iterator[tuple[int, NDArray[np.int16]]]:
        """(first PRI index, the file's int16 values of whole frames) in blocks of ``frames_per_block`` frames."""
        p = self.params
        frame_values = p.frame_bytes // 2
        if self.packets is not None:
            for done in range(0, self.num_frames, frames_per_block):
                n = min(frames_per_block, self.num_frames - done)
                buf = np.empty(n * p.frame_bytes, dtype=np.uint8)
                self.packets.read(done * p.frame_bytes, buf)
                yield done * p.num_loops, buf.view("<i2")
            return
        buf = np.empty(frames_per_block * frame_values, dtype=np.int16)
        view = memoryview(buf).cast("B")
        done = 0
        files = iter(self.files)
        f = open(next(files), "rb")  # noqa: SIM115 (closed below; files are chained)
        try:
            while done < self.num_frames:
                n = min(frames_per_block, self.num_frames - done)
                want, got = n * p.frame_bytes, 0
                while got < want:
                    k = f.readinto(view[got:want])
                    if not k:
                        f.close()
                        f = open(next(files), "rb")  # noqa: SIM115
                        continue
                    got += k
                yield done * p.num_loops, buf[: n * frame_values]
                done += n
        finally:
            f.close()


class CaptureWriter:
    """Writes PRI blocks as a DCA1000 capture in ``folder`` (use as a context manager).

    ``param_format``: "cfg" (mmWave SDK) or "json" (mmWave Studio pair). ``split_bytes`` > 0 writes split
    files ``adc_data_Raw_<k>.bin`` of at most that size (frames may straddle files, as in a real capture),
    else ``adc_data.bin``. ``packet_bytes`` > 0 writes the DCA1000's packets as a recorder with sequence numbers
    on stores them: each a 10-byte header and that many data bytes (the last packet fewer), whole in each file.
    Blocks must hold whole frames (a multiple of ``num_loops`` PRIs).
    """

    def __init__(self, folder: Path, params: CaptureParams, *, param_format: str = "cfg",
                 split_bytes: int = 0, packet_bytes: int = 0) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        if param_format == "json":
            write_studio_json(folder / "capture", params)
        else:
            write_sdk_cfg(folder / "capture.cfg", params)
        self.folder, self.params, self.split_bytes = folder, params, split_bytes
        self.packet_bytes = packet_bytes
        self.files: list[Path] = []
        self._out: Any = None
        self._room = 0
        self._unsent = bytearray()  # data not yet in a packet
        self._sent = 0  # data bytes in packets so far

    def write(self, pris: NDArray[np.int16]) -> None:
        """PRIs (n, tx, rx, sample, I/Q) int16, n a multiple of the loops per frame."""
        data = memoryview(pris_to_frames(pris, self.params)).cast("B")
        if not self.packet_bytes:
            self._store(data, whole=False)
            return
        stream = memoryview(bytes(self._unsent) + bytes(data))
        at = 0
        while len(stream) - at >= self.packet_bytes:
            self._packet(stream[at:at + self.packet_bytes])
            at += self.packet_bytes
        self._unsent = bytearray(stream[at:])

    def _packet(self, data: memoryview | bytearray) -> None:
        self._store(memoryview(packet(self._sent // self.packet_bytes + 1, self._sent, data)), whole=True)
        self._sent += len(data)

    def _store(self, data: memoryview, *, whole: bool) -> None:
        """Into the data files; ``whole``: kept in one file (a packet)."""
        while len(data):
            if self._out is None or (self.split_bytes and self._room < (len(data) if whole else 1)):
                if self._out is not None:
                    self._out.close()
                name = f"adc_data_Raw_{len(self.files)}.bin" if self.split_bytes else "adc_data.bin"
                self.files.append(self.folder / name)
                self._out = open(self.files[-1], "wb")  # noqa: SIM115 (closed in close())
                self._room = self.split_bytes
            k = min(self._room, len(data)) if self.split_bytes else len(data)
            self._out.write(data[:k])
            data = data[k:]
            self._room -= k

    def close(self) -> None:
        if self._unsent:
            self._packet(self._unsent)
            self._unsent = bytearray()
        if self._out is not None:
            self._out.close()
            self._out = None

    def __enter__(self) -> CaptureWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def write_capture(folder: Path, params: CaptureParams, pris: Iterable[NDArray[np.int16]], *,
                  param_format: str = "cfg", split_bytes: int = 0, packet_bytes: int = 0) -> list[Path]:
    """Write PRI blocks as a capture (see :class:`CaptureWriter`); returns the data files."""
    with CaptureWriter(folder, params, param_format=param_format, split_bytes=split_bytes,
                       packet_bytes=packet_bytes) as w:
        for block in pris:
            w.write(block)
    return w.files
