"""TI mmWave raw ADC captures recorded with a DCA1000EVM: parameters, layouts, streaming reader and writer.

A capture is a flat binary of int16 ADC values (mmWave Studio's post-processed ``adc_data.bin``, or its
split files ``<base>_0.bin``, ``<base>_1.bin`` … read as one stream) plus the parameters it was recorded
with: mmWave Studio's ``*.mmwave.json`` (+ ``*.setup.json``) or an mmWave SDK ``.cfg``. Layouts follow
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

import json
import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from decimal import Decimal
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .sources import LogReadError

ADC_FORMATS = ("real", "complex1x", "complex2x")  #: by TI's adcOutputFmt / b2AdcOutFmt code 0, 1, 2
ADC_BITS = (12, 14, 16)  #: by TI's numADCBits / b2AdcBits code 0, 1, 2
LANE_SLOTS_4 = 4  # a 4-lane capture always carries four lanes


class CaptureError(LogReadError):
    """A DCA1000 capture or its parameter file cannot be used; the message names the file and the problem."""


def _scaled(text: str | float | int, exponent: int) -> float:
    """A decimal in some unit, scaled by 10**exponent with one correct rounding (77 GHz -> exactly 77e9)."""
    return float(f"{text!r}e{exponent}" if isinstance(text, float) else f"{text}e{exponent}")


def _in_unit(value: float, exponent: int) -> str:
    """``value`` (SI) as exact decimal text in a unit of 10**exponent; :func:`_scaled` reads it back exactly."""
    return format(Decimal(repr(float(value))).scaleb(-exponent).normalize(), "f")


@dataclass(frozen=True)
class CaptureParams:
    """What a DCA1000 capture's parameter file states (SI units)."""

    profile_start_frequency_hz: float  #: at the start of the ramp (TI's startFreq)
    slope_hz_per_s: float
    sample_rate_hz: float
    num_samples: int
    adc_start_s: float  #: ADC start time after the ramp start
    chirp_period_s: float  #: idle time + ramp end time: one chirp slot
    rx_channels: tuple[int, ...]  #: enabled Rx indices, ascending
    chirp_tx: tuple[int, ...]  #: Tx index of each chirp of one loop, in transmit order
    num_loops: int
    num_frames: int  #: 0: until stopped
    frame_period_s: float
    adc_format: str  #: one of ADC_FORMATS
    lanes: int  #: LVDS lanes, 2 or 4
    source: str = ""  #: the parameter file
    adc_bits: int = 16  #: 12 or 14: samples are not sign-extended in the file (SWRA581)

    @property
    def start_frequency_hz(self) -> float:
        """RF frequency at the first ADC sample (the drive's convention)."""
        if self.adc_start_s == 0.0:
            return self.profile_start_frequency_hz
        return self.profile_start_frequency_hz + self.slope_hz_per_s * self.adc_start_s

    @property
    def tx_order(self) -> tuple[int, ...]:
        """Tx indices of the drive's Tx axis (ascending)."""
        return tuple(sorted(self.chirp_tx))

    @property
    def num_tx(self) -> int:
        return len(self.chirp_tx)

    @property
    def num_rx(self) -> int:
        return len(self.rx_channels)

    @property
    def complex(self) -> bool:
        return self.adc_format != "real"

    @property
    def tx_start_offsets_s(self) -> tuple[float, ...]:
        """Start of each Tx's chirp (drive Tx order) relative to the start of its loop (s)."""
        slot = {tx: k for k, tx in enumerate(self.chirp_tx)}
        return tuple(slot[tx] * self.chirp_period_s for tx in self.tx_order)

    @property
    def loop_period_s(self) -> float:
        return self.num_tx * self.chirp_period_s

    @property
    def prf_hz(self) -> float:
        """PRIs per second (loops per frame over the frame period)."""
        return self.num_loops / self.frame_period_s

    @property
    def bandwidth_hz(self) -> float:
        """Swept during the ADC window: slope x num_samples / sample rate."""
        return self.slope_hz_per_s * self.num_samples / self.sample_rate_hz

    @property
    def chirp_values(self) -> int:
        """int16 values of one chirp in the file."""
        slots = LANE_SLOTS_4 if self.lanes == 4 else self.num_rx
        return self.num_samples * slots * (2 if self.complex else 1)

    @property
    def frame_bytes(self) -> int:
        return 2 * self.chirp_values * self.num_tx * self.num_loops

    def describe_layout(self) -> str:
        return (f"{self.num_loops} loops x {self.num_tx} chirps x {self.num_rx} Rx x {self.num_samples} samples, "
                f"{self.adc_format}, {self.lanes}-lane = {self.frame_bytes} bytes a frame")

    def check(self) -> None:
        src = self.source or "DCA1000 parameters"
        if self.lanes not in (2, 4):
            raise CaptureError(f"{src}: {self.lanes} LVDS lanes; a DCA1000 capture has 2 or 4")
        if self.lanes == 4 and max(self.rx_channels, default=0) >= LANE_SLOTS_4:
            raise CaptureError(f"{src}: Rx {max(self.rx_channels)} has no lane in a 4-lane capture")
        if self.adc_bits not in ADC_BITS:
            raise CaptureError(f"{src}: {self.adc_bits}-bit ADC, expected one of {', '.join(map(str, ADC_BITS))}")
        if self.adc_format not in ADC_FORMATS:
            raise CaptureError(f"{src}: ADC format {self.adc_format!r}, expected one of {', '.join(ADC_FORMATS)}")
        if not self.rx_channels or not self.chirp_tx:
            raise CaptureError(f"{src}: no Rx or no chirp enabled")
        if len(set(self.chirp_tx)) != len(self.chirp_tx):
            raise CaptureError(f"{src}: chirp table transmits Tx {list(self.chirp_tx)}; TDM-MIMO needs each Tx "
                               "once per loop")
        if self.lanes == 2 and self.complex and self.num_samples % 2:
            raise CaptureError(f"{src}: {self.num_samples} complex samples; the 2-lane layout pairs samples, so "
                               "it needs an even count")
        for name in ("slope_hz_per_s", "sample_rate_hz", "chirp_period_s", "frame_period_s"):
            if not getattr(self, name) > 0:
                raise CaptureError(f"{src}: {name} must be positive, got {getattr(self, name)}")
        if self.num_samples < 1 or self.num_loops < 1:
            raise CaptureError(f"{src}: needs at least one sample and one loop")
        if self.loop_period_s * self.num_loops > self.frame_period_s * (1 + 1e-9):
            raise CaptureError(f"{src}: {self.num_loops} loops of {self.num_tx} chirps of {self.chirp_period_s} s "
                               f"do not fit in the frame period {self.frame_period_s} s")


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


# ------------------------------------------------------------------------------------ parameter files
def _mask_bits(mask: int | str) -> tuple[int, ...]:
    m = int(mask, 0) if isinstance(mask, str) else int(mask)
    return tuple(i for i in range(32) if m >> i & 1)


def _chirp_tx(src: str, table: dict[int, int], first: int, last: int) -> tuple[int, ...]:
    """Tx of chirps first..last of the chirp table (chirp index -> Tx enable mask)."""
    out = []
    for c in range(first, last + 1):
        if c not in table:
            raise CaptureError(f"{src}: frame uses chirp {c}, which no chirp configuration defines")
        bits = _mask_bits(table[c])
        if len(bits) != 1:
            raise CaptureError(f"{src}: chirp {c} enables Tx mask {table[c]:#x}; TDM-MIMO needs one Tx a chirp")
        out.append(bits[0])
    return tuple(out)


def parse_sdk_cfg(path: Path) -> CaptureParams:
    """An mmWave SDK CLI configuration (profileCfg, chirpCfg, frameCfg, channelCfg, adcCfg, adcbufCfg)."""
    src = str(path)
    cmds: dict[str, list[list[str]]] = {}
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        words = line.split("%", 1)[0].split()
        if words:
            cmds.setdefault(words[0], []).append(words[1:])

    def one(name: str, n: int) -> list[str]:
        if name not in cmds:
            raise CaptureError(f"{src}: no {name} line")
        args = cmds[name][0]
        if len(args) < n:
            raise CaptureError(f"{src}: {name} has {len(args)} values, expected at least {n}")
        return args

    try:
        rx_mask, tx_mask = (int(v, 0) for v in one("channelCfg", 2)[:2])
        prof = one("profileCfg", 11)
        frame = one("frameCfg", 5)
        table: dict[int, int] = {}
        for args in cmds.get("chirpCfg", []):
            if len(args) < 8:
                raise CaptureError(f"{src}: chirpCfg has {len(args)} values, expected 8")
            for c in range(int(args[0]), int(args[1]) + 1):
                table[c] = int(args[7], 0)
        adc_bits_code, adc_fmt = (int(v) for v in one("adcCfg", 2)[:2])
        if "adcbufCfg" in cmds:
            buf = one("adcbufCfg", 4)
            if (adc_fmt == 0) != (int(buf[1]) == 1):
                raise CaptureError(f"{src}: adcCfg says {ADC_FORMATS[adc_fmt]} but adcbufCfg says "
                                   f"{'real' if int(buf[1]) == 1 else 'complex'}")
            if int(buf[3]) == 0:
                raise CaptureError(f"{src}: adcbufCfg asks for interleaved channels; DCA1000 captures are read "
                                   "non-interleaved")
        params = CaptureParams(
            profile_start_frequency_hz=_scaled(prof[1], 9), slope_hz_per_s=_scaled(prof[7], 12),
            sample_rate_hz=_scaled(prof[10], 3), num_samples=int(prof[9]), adc_start_s=_scaled(prof[3], -6),
            chirp_period_s=_scaled(format(Decimal(prof[2]) + Decimal(prof[4]), "f"), -6),
            rx_channels=_mask_bits(rx_mask), chirp_tx=_chirp_tx(src, table, int(frame[0]), int(frame[1])),
            num_loops=int(frame[2]), num_frames=int(frame[3]), frame_period_s=_scaled(frame[4], -3),
            adc_format=ADC_FORMATS[adc_fmt] if 0 <= adc_fmt < 3 else str(adc_fmt), lanes=2, source=src,
            adc_bits=ADC_BITS[adc_bits_code] if 0 <= adc_bits_code < 3 else adc_bits_code)
    except (ValueError, IndexError) as exc:
        raise CaptureError(f"{src}: unreadable value ({exc})") from None
    if set(params.chirp_tx) - set(_mask_bits(tx_mask)):
        raise CaptureError(f"{src}: chirps use Tx {sorted(set(params.chirp_tx))} but channelCfg enables "
                           f"{list(_mask_bits(tx_mask))}")
    params.check()
    return params


def write_sdk_cfg(path: Path, p: CaptureParams) -> None:
    """An mmWave SDK configuration stating ``p`` (SDK devices stream over 2 LVDS lanes)."""
    if p.lanes != 2:
        raise CaptureError(f"{path}: an mmWave SDK .cfg describes 2-lane captures; write {p.lanes} lanes as JSON")
    tx_mask = sum(1 << t for t in p.chirp_tx)
    rx_mask = sum(1 << r for r in p.rx_channels)
    fmt = ADC_FORMATS.index(p.adc_format)
    ramp = _ramp_end_us(p)
    idle = format(Decimal(_in_unit(p.chirp_period_s, -6)) - ramp, "f")
    lines = [
        "% DCA1000 capture parameters (mmWave SDK CLI format), written by autosar",
        "sensorStop", "flushCfg", "dfeDataOutputMode 1",
        f"channelCfg {rx_mask} {tx_mask} 0",
        f"adcCfg {ADC_BITS.index(p.adc_bits)} {fmt}",
        f"adcbufCfg -1 {1 if fmt == 0 else 0} 1 1 1",
        f"profileCfg 0 {_in_unit(p.profile_start_frequency_hz, 9)} {idle} {_in_unit(p.adc_start_s, -6)} {ramp} "
        f"0 0 {_in_unit(p.slope_hz_per_s, 12)} 0 {p.num_samples} {_in_unit(p.sample_rate_hz, 3)} 0 0 30",
        *(f"chirpCfg {c} {c} 0 0 0 0 0 {1 << t}" for c, t in enumerate(p.chirp_tx)),
        f"frameCfg 0 {p.num_tx - 1} {p.num_loops} {p.num_frames} {_in_unit(p.frame_period_s, -3)} 1 0",
        "lvdsStreamCfg -1 0 1 0", "sensorStart", "",
    ]
    path.write_text("\n".join(lines), encoding="utf-8")


def _ramp_end_us(p: CaptureParams) -> Decimal:
    """Ramp end time (us): the ADC window after the ADC start, rounded up to whole microseconds."""
    need = (p.adc_start_s + p.num_samples / p.sample_rate_hz) * 1e6
    period = Decimal(_in_unit(p.chirp_period_s, -6))
    return min(Decimal(int(np.ceil(need - 1e-9))), period)


def parse_studio_json(path: Path) -> CaptureParams:
    """mmWave Studio's ``*.mmwave.json`` (its ``*.setup.json`` twin is not needed for the layout)."""
    src = str(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        dev = doc["mmWaveDevices"]
        dev = dev[0] if isinstance(dev, list) else dev
        rf = dev["rfConfig"]
        chan = rf["rlChanCfg_t"]
        prof = rf["rlProfiles"][0]["rlProfileCfg_t"]
        frame = rf["rlFrameCfg_t"]
        table: dict[int, int] = {}
        for entry in rf.get("rlChirps", []):
            c = entry["rlChirpCfg_t"]
            for i in range(int(c["chirpStartIdx"]), int(c["chirpEndIdx"]) + 1):
                table[i] = _mask_int(c["txEnable"])
        fmt = int(rf["rlAdcOutCfg_t"]["fmt"]["b2AdcOutFmt"])
        bits = int(rf["rlAdcOutCfg_t"]["fmt"].get("b2AdcBits", 2))
        lane_en = dev.get("rawDataCaptureConfig", {}).get("rlDevLaneEnable_t", {}).get("laneEn", "0xF")
        params = CaptureParams(
            profile_start_frequency_hz=_scaled(prof["startFreqConst_GHz"], 9),
            slope_hz_per_s=_scaled(prof["freqSlopeConst_MHz_usec"], 12),
            sample_rate_hz=_scaled(prof["digOutSampleRate"], 3), num_samples=int(prof["numAdcSamples"]),
            adc_start_s=_scaled(prof["adcStartTimeConst_usec"], -6),
            chirp_period_s=_scaled(format(Decimal(repr(float(prof["idleTimeConst_usec"])))
                                          + Decimal(repr(float(prof["rampEndTime_usec"]))), "f"), -6),
            rx_channels=_mask_bits(chan["rxChannelEn"]),
            chirp_tx=_chirp_tx(src, table, int(frame["chirpStartIdx"]), int(frame["chirpEndIdx"])),
            num_loops=int(frame["numLoops"]), num_frames=int(frame["numFrames"]),
            frame_period_s=_scaled(float(frame["framePeriodicity_msec"]), -3),
            adc_format=ADC_FORMATS[fmt] if 0 <= fmt < 3 else str(fmt), lanes=len(_mask_bits(lane_en)), source=src,
            adc_bits=ADC_BITS[bits] if 0 <= bits < 3 else bits)
    except CaptureError:
        raise
    except (OSError, ValueError, KeyError, IndexError, TypeError) as exc:
        raise CaptureError(f"{src}: not a usable mmWave Studio configuration ({type(exc).__name__}: {exc})") from None
    params.check()
    return params


def _mask_int(v: int | str) -> int:
    return int(v, 0) if isinstance(v, str) else int(v)


def write_studio_json(base: Path, p: CaptureParams) -> tuple[Path, Path]:
    """``<base>.mmwave.json`` + ``<base>.setup.json`` stating ``p``; returns both paths."""
    ramp = _ramp_end_us(p)
    idle = Decimal(_in_unit(p.chirp_period_s, -6)) - ramp
    rf = {
        "rlChanCfg_t": {"rxChannelEn": hex(sum(1 << r for r in p.rx_channels)),
                        "txChannelEn": hex(sum(1 << t for t in p.chirp_tx)), "cascading": 0},
        "rlAdcOutCfg_t": {"fmt": {"b2AdcBits": ADC_BITS.index(p.adc_bits),
                                  "b2AdcOutFmt": ADC_FORMATS.index(p.adc_format)}},
        "rlProfiles": [{"rlProfileCfg_t": {
            "profileId": 0, "startFreqConst_GHz": float(_in_unit(p.profile_start_frequency_hz, 9)),
            "idleTimeConst_usec": float(idle), "adcStartTimeConst_usec": float(_in_unit(p.adc_start_s, -6)),
            "rampEndTime_usec": float(ramp), "freqSlopeConst_MHz_usec": float(_in_unit(p.slope_hz_per_s, 12)),
            "numAdcSamples": p.num_samples, "digOutSampleRate": float(_in_unit(p.sample_rate_hz, 3))}}],
        "rlChirps": [{"rlChirpCfg_t": {"chirpStartIdx": c, "chirpEndIdx": c, "profileId": 0,
                                       "txEnable": hex(1 << t)}} for c, t in enumerate(p.chirp_tx)],
        "rlFrameCfg_t": {"chirpStartIdx": 0, "chirpEndIdx": p.num_tx - 1, "numLoops": p.num_loops,
                         "numFrames": p.num_frames, "framePeriodicity_msec": float(_in_unit(p.frame_period_s, -3)),
                         "triggerSelect": 1, "frameTriggerDelay": 0.0},
    }
    doc = {"configGenerator": {"createdBy": "autosar"}, "mmWaveDevices": [{
        "mmWaveDeviceId": 0, "rfConfig": rf,
        "rawDataCaptureConfig": {"rlDevDataFmtCfg_t": {"iqSwapSel": 0, "chInterleave": 0},
                                 "rlDevLaneEnable_t": {"laneEn": hex((1 << p.lanes) - 1)}}}]}
    mm = base.with_name(base.name + ".mmwave.json")
    setup = base.with_name(base.name + ".setup.json")
    mm.write_text(json.dumps(doc, indent=2), encoding="utf-8")
    setup.write_text(json.dumps({"configUsed": mm.name, "mmWaveDevice": "awr1243", "DCA1000Config": {
        "dataLoggingMode": "raw", "lvdsMode": 1 if p.lanes == 4 else 2},
        "capturedFiles": {"fileBasePath": ".", "files": [{"processedFileName": "adc_data.bin"}]}}, indent=2),
        encoding="utf-8")
    return mm, setup


def load_params(path: Path) -> CaptureParams:
    """Parameters from a ``.cfg`` or ``*.mmwave.json`` file."""
    if path.name.endswith(".mmwave.json"):
        return parse_studio_json(path)
    return parse_sdk_cfg(path)


# ------------------------------------------------------------------------------------------- capture
_SPLIT = re.compile(r"^(.*)_(\d+)\.bin$")


def is_capture(path: Path) -> bool:
    """A DCA1000 capture: a directory or .bin file with a parameter file (.cfg / .mmwave.json) beside it."""
    if not (path.is_dir() or path.suffix.lower() == ".bin"):
        return False
    try:
        find_capture(path)
    except CaptureError:
        return False
    return True


def find_capture(path: Path) -> tuple[list[Path], Path]:
    """(data files in stream order, parameter file) of a capture directory, data file or parameter file."""
    if path.is_file() and path.suffix.lower() != ".bin":  # the parameter file names its capture's folder
        path = path.parent
    folder = path if path.is_dir() else path.parent
    params = sorted(folder.glob("*.mmwave.json")) or sorted(folder.glob("*.cfg"))
    if not params:
        raise CaptureError(f"{path}: no DCA1000 parameter file (*.mmwave.json or mmWave SDK *.cfg) beside it")
    if len(params) > 1:
        raise CaptureError(f"{path}: several parameter files ({', '.join(p.name for p in params)}); keep one")
    if path.is_file():
        m = _SPLIT.match(path.name)
        files = _split_series(folder, m.group(1)) if m else [path]
        return files, params[0]
    if (folder / "adc_data.bin").exists():
        return [folder / "adc_data.bin"], params[0]
    bases = sorted({m.group(1) for p in folder.glob("*_*.bin") if (m := _SPLIT.match(p.name))})
    if len(bases) == 1:
        return _split_series(folder, bases[0]), params[0]
    bins = sorted(folder.glob("*.bin"))
    if len(bins) == 1:
        return bins, params[0]
    raise CaptureError(f"{path}: expected adc_data.bin or one series of split files <name>_0.bin, <name>_1.bin …, "
                       f"found {', '.join(p.name for p in bins) or 'no .bin file'}")


def _split_series(folder: Path, base: str) -> list[Path]:
    files: list[Path] = []
    while (folder / f"{base}_{len(files)}.bin").exists():
        files.append(folder / f"{base}_{len(files)}.bin")
    if not files:
        raise CaptureError(f"{folder / base}_0.bin: the split series must start at _0.bin")
    return files


class Dca1000Capture:
    """A capture opened for streaming: its parameters, frame count and a block iterator over its PRIs."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.files, self.param_file = find_capture(self.path)
        self.params = load_params(self.param_file)
        self.warnings: list[str] = []
        self.bytes_total = sum(f.stat().st_size for f in self.files)
        p = self.params
        name = self.files[0] if len(self.files) == 1 else f"{self.files[0]} (+{len(self.files) - 1} split files)"
        group = 2 * (2 if p.complex else 1) * (LANE_SLOTS_4 if p.lanes == 4 else 2)
        if self.bytes_total < p.frame_bytes or self.bytes_total % group:
            raise CaptureError(f"{name}: {self.bytes_total} bytes fit no frame layout of {self.param_file.name}: "
                               f"expected whole frames of {p.describe_layout()}")
        self.num_frames, self.partial_bytes = divmod(self.bytes_total, p.frame_bytes)
        if p.num_frames and self.num_frames > p.num_frames:
            raise CaptureError(f"{name}: holds {self.num_frames} frames but {self.param_file.name} configures "
                               f"{p.num_frames} ({p.describe_layout()})")
        if self.partial_bytes:
            self.warnings.append(f"{name}: trailing partial frame left out ({self.partial_bytes} of "
                                 f"{p.frame_bytes} bytes, 1 frame)")

    @property
    def num_pris(self) -> int:
        return self.num_frames * self.params.num_loops

    def pri_times_ns(self, start_ns: int) -> NDArray[np.int64]:
        """Start of every PRI (ns since the epoch): frame periodicity, then loop period within a frame."""
        p = self.params
        frames = np.arange(self.num_frames, dtype=np.float64)
        frame_t = np.round(frames * (p.frame_period_s * 1e9)).astype(np.int64)
        loop_t = np.round(np.arange(p.num_loops) * (p.loop_period_s * 1e9)).astype(np.int64)
        return start_ns + (frame_t[:, None] + loop_t[None, :]).reshape(-1)

    def blocks(self, frames_per_block: int = 64) -> Iterator[tuple[int, NDArray[np.int16]]]:
        """(first PRI index, PRIs (n, tx, rx, sample, I/Q) int16) for consecutive blocks of whole frames."""
        p = self.params
        frame_values = p.frame_bytes // 2
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
                yield done * p.num_loops, frames_to_pris(buf[: n * frame_values].reshape(n, frame_values), p)
                done += n
        finally:
            f.close()


class CaptureWriter:
    """Writes PRI blocks as a DCA1000 capture in ``folder`` (use as a context manager).

    ``param_format``: "cfg" (mmWave SDK) or "json" (mmWave Studio pair). ``split_bytes`` > 0 writes split
    files ``adc_data_Raw_<k>.bin`` of at most that size (frames may straddle files, as in a real capture),
    else ``adc_data.bin``. Blocks must hold whole frames (a multiple of ``num_loops`` PRIs).
    """

    def __init__(self, folder: Path, params: CaptureParams, *, param_format: str = "cfg",
                 split_bytes: int = 0) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        if param_format == "json":
            write_studio_json(folder / "capture", params)
        else:
            write_sdk_cfg(folder / "capture.cfg", params)
        self.folder, self.params, self.split_bytes = folder, params, split_bytes
        self.files: list[Path] = []
        self._out: Any = None
        self._room = 0

    def write(self, pris: NDArray[np.int16]) -> None:
        """PRIs (n, tx, rx, sample, I/Q) int16, n a multiple of the loops per frame."""
        data = memoryview(pris_to_frames(pris, self.params)).cast("B")
        while len(data):
            if self._out is None or (self.split_bytes and self._room == 0):
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
        if self._out is not None:
            self._out.close()
            self._out = None

    def __enter__(self) -> CaptureWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def write_capture(folder: Path, params: CaptureParams, pris: Iterable[NDArray[np.int16]], *,
                  param_format: str = "cfg", split_bytes: int = 0) -> list[Path]:
    """Write PRI blocks as a capture (see :class:`CaptureWriter`); returns the data files."""
    with CaptureWriter(folder, params, param_format=param_format, split_bytes=split_bytes) as w:
        for block in pris:
            w.write(block)
    return w.files


def params_from_radar(radar: Any, *, lanes: int = 4, adc_format: str = "complex1x",
                      chirp_tx: tuple[int, ...] | None = None, num_frames: int = 0) -> CaptureParams:
    """Capture parameters that state a configured radar (``config.RadarConfig``): one loop per frame."""
    p = CaptureParams(
        profile_start_frequency_hz=radar.start_frequency_hz, slope_hz_per_s=radar.slope_hz_per_s,
        sample_rate_hz=radar.sample_rate_hz, num_samples=radar.num_samples, adc_start_s=0.0,
        chirp_period_s=radar.chirp_period_s, rx_channels=tuple(range(radar.num_rx)),
        chirp_tx=chirp_tx or tuple(range(radar.num_tx)), num_loops=1, num_frames=num_frames,
        frame_period_s=1.0 / radar.prf_hz, adc_format=adc_format, lanes=lanes)
    p.check()
    return p
