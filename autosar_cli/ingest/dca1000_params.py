"""Parameters of a TI DCA1000 capture: what its mmWave Studio JSON or mmWave SDK ``.cfg`` states, in SI units.

Reads and writes mmWave Studio's ``*.mmwave.json`` (+ ``*.setup.json``) and mmWave SDK CLI configurations
(``channelCfg``, ``adcCfg``, ``adcbufCfg``, ``profileCfg``, ``chirpCfg``, ``frameCfg``). Unit conversions
go through decimal text, so a value written and read back is the same float (77 GHz -> exactly 77e9).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
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
    #: frames start on an external trigger (triggerSelect 2), not every frame period: their times come from the
    #: frame-trigger topic, one message per frame
    hardware_trigger: bool = False
    #: the SDK's ``compRangeBiasAndRxChanPhase`` coefficients (re, im) per (Tx, Rx) of the device, Tx-major, 4 Rx
    #: each: what TI multiplies each virtual channel by to calibrate it (() where the file states none)
    channel_compensation: tuple[tuple[float, float], ...] = ()
    range_bias_m: float = 0.0  #: its range bias (m): not applied, ingest warns where it is not 0

    @property
    def start_frequency_hz(self) -> float:
        """RF frequency at the first ADC sample (the drive's convention)."""
        if self.adc_start_s == 0.0:
            return self.profile_start_frequency_hz
        return self.profile_start_frequency_hz + self.slope_hz_per_s * self.adc_start_s

    def channel_gains(self) -> NDArray[np.complex128] | None:
        """The front end's complex gain (num_tx, num_rx) per channel of the drive's axes (Tx ascending, the enabled
        Rx): the inverse of :attr:`channel_compensation`; None where it states none, or only 1 (no correction)."""
        coeff = np.array([complex(re, im) for re, im in self.channel_compensation]).reshape(-1, 4)
        if not coeff.size or np.allclose(coeff, 1.0):
            return None
        return 1.0 / coeff[np.ix_(self.tx_order, self.rx_channels)]

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


_WAVEFORMS = {"2": "continuous wave", "3": "advanced frames of sub-frames"}  #: dfeDataOutputMode not read


def _same_chirps(src: str, shape: dict[int, tuple[int, tuple[float, ...]]], first: int, last: int,
                 profile_id: int) -> None:
    """Chirps first..last must all be the profile read, unvaried: focusing takes one start frequency, slope,
    idle and ADC start time for every pulse. ``shape``: chirp index -> (profile id, (start frequency, slope, idle
    time, ADC start time) variations)."""
    for c in range(first, last + 1):
        if c not in shape:
            continue  # _chirp_tx names it
        pid, variations = shape[c]
        if pid != profile_id:
            raise CaptureError(f"{src}: chirp {c} uses profile {pid}, not profile {profile_id} whose parameters are "
                               "read; one profile for every chirp is read")
        if any(variations):
            raise CaptureError(f"{src}: chirp {c} varies its profile (start frequency, slope, idle time, ADC start "
                               f"time by {', '.join(f'{v:g}' for v in variations)}); chirps that differ are not read")


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
        shape: dict[int, tuple[int, tuple[float, ...]]] = {}
        for args in cmds.get("chirpCfg", []):
            if len(args) < 8:
                raise CaptureError(f"{src}: chirpCfg has {len(args)} values, expected 8")
            for c in range(int(args[0]), int(args[1]) + 1):
                table[c] = int(args[7], 0)
                shape[c] = int(args[2]), tuple(float(v) for v in args[3:7])
        _same_chirps(src, shape, int(frame[0]), int(frame[1]), int(prof[0]))
        if "dfeDataOutputMode" in cmds and one("dfeDataOutputMode", 1)[0] != "1":
            mode = one("dfeDataOutputMode", 1)[0]
            raise CaptureError(f"{src}: dfeDataOutputMode {mode} ({_WAVEFORMS.get(mode, 'unknown')}); only frames "
                               "of chirps (frameCfg, dfeDataOutputMode 1) are read")
        adc_bits_code, adc_fmt = (int(v) for v in one("adcCfg", 2)[:2])
        if "adcbufCfg" in cmds:
            buf = one("adcbufCfg", 4)
            if (adc_fmt == 0) != (int(buf[1]) == 1):
                raise CaptureError(f"{src}: adcCfg says {ADC_FORMATS[adc_fmt]} but adcbufCfg says "
                                   f"{'real' if int(buf[1]) == 1 else 'complex'}")
            if int(buf[3]) == 0:
                raise CaptureError(f"{src}: adcbufCfg asks for interleaved channels; DCA1000 captures are read "
                                   "non-interleaved")
        if "lvdsStreamCfg" in cmds:  # <subFrameIdx> <enableHeader> <dataFmt> <enableSW>
            args = one("lvdsStreamCfg", 4)
            header, data_fmt, software = (int(v) for v in args[1:4])
            found = (["no ADC data"] if data_fmt == 0 else ["chirp parameters or quality data"] if data_fmt > 1
                     else []) + (["HSI headers"] if header else []) + (["the processing chain's output"] if software
                                                                        else [])
            if found:
                raise CaptureError(f"{src}: lvdsStreamCfg {' '.join(args)} streams {', '.join(found)}; only ADC "
                                   "data without headers (lvdsStreamCfg -1 0 1 0) is read")
        params = CaptureParams(
            profile_start_frequency_hz=_scaled(prof[1], 9), slope_hz_per_s=_scaled(prof[7], 12),
            sample_rate_hz=_scaled(prof[10], 3), num_samples=int(prof[9]), adc_start_s=_scaled(prof[3], -6),
            chirp_period_s=_scaled(format(Decimal(prof[2]) + Decimal(prof[4]), "f"), -6),
            rx_channels=_mask_bits(rx_mask), chirp_tx=_chirp_tx(src, table, int(frame[0]), int(frame[1])),
            num_loops=int(frame[2]), num_frames=int(frame[3]), frame_period_s=_scaled(frame[4], -3),
            hardware_trigger=len(frame) > 5 and int(frame[5]) == 2,
            adc_format=ADC_FORMATS[adc_fmt] if 0 <= adc_fmt < 3 else str(adc_fmt), lanes=2, source=src,
            adc_bits=ADC_BITS[adc_bits_code] if 0 <= adc_bits_code < 3 else adc_bits_code)
        if "compRangeBiasAndRxChanPhase" in cmds:  # <rangeBias> <Re(0,0)> <Im(0,0)> ... <Re(T-1,R-1)> <Im(T-1,R-1)>
            values = [float(v) for v in one("compRangeBiasAndRxChanPhase", 1)[1:]]
            pairs = list(zip(values[0::2], values[1::2], strict=False))
            if len(values) % 8 or len(values) // 8 <= max(params.chirp_tx):
                raise CaptureError(f"{src}: compRangeBiasAndRxChanPhase has {len(values) + 1} values, expected 1 + "
                                   "2 x 4 Rx x the device's Tx (17 or 25)")
            if any(re == 0.0 and im == 0.0 for re, im in pairs):
                raise CaptureError(f"{src}: compRangeBiasAndRxChanPhase zeroes a channel: it cannot be undone")
            params = replace(params, channel_compensation=tuple(pairs),
                             range_bias_m=float(one("compRangeBiasAndRxChanPhase", 1)[0]))
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
        f"frameCfg 0 {p.num_tx - 1} {p.num_loops} {p.num_frames} {_in_unit(p.frame_period_s, -3)} "
        f"{2 if p.hardware_trigger else 1} 0",
        "lvdsStreamCfg -1 0 1 0",
        *([f"compRangeBiasAndRxChanPhase 0.0 {' '.join(f'{re:g} {im:g}' for re, im in p.channel_compensation)}"]
          if p.channel_compensation else []),
        "sensorStart", "",
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
        if isinstance(dev, list) and len(dev) > 1:
            raise CaptureError(f"{src}: a cascade of {len(dev)} mmWave devices; one device's capture is read")
        dev = dev[0] if isinstance(dev, list) else dev
        rf = dev["rfConfig"]
        chan = rf["rlChanCfg_t"]
        prof = rf["rlProfiles"][0]["rlProfileCfg_t"]
        frame = rf["rlFrameCfg_t"]
        table: dict[int, int] = {}
        shape: dict[int, tuple[int, tuple[float, ...]]] = {}
        for entry in rf.get("rlChirps", []):
            c = entry["rlChirpCfg_t"]
            for i in range(int(c["chirpStartIdx"]), int(c["chirpEndIdx"]) + 1):
                table[i] = _mask_int(c["txEnable"])
                shape[i] = int(c.get("profileId", 0)), tuple(float(c.get(k, 0)) for k in (
                    "startFreqVar_MHz", "freqSlopeVar_KHz_usec", "idleTimeVar_usec", "adcStartTimeVar_usec"))
        _same_chirps(src, shape, int(frame["chirpStartIdx"]), int(frame["chirpEndIdx"]),
                     int(prof.get("profileId", 0)))
        waveform = rf.get("waveformType", "legacyFrameChirp")
        if waveform != "legacyFrameChirp":
            raise CaptureError(f"{src}: rfConfig.waveformType is {waveform!r}; only frames of chirps "
                               "(legacyFrameChirp, rlFrameCfg_t) are read")
        fmt = int(rf["rlAdcOutCfg_t"]["fmt"]["b2AdcOutFmt"])
        bits = int(rf["rlAdcOutCfg_t"]["fmt"].get("b2AdcBits", 2))
        capture = dev.get("rawDataCaptureConfig", {})
        lane_en = capture.get("rlDevLaneEnable_t", {}).get("laneEn", "0xF")
        data_fmt = capture.get("rlDevDataFmtCfg_t", {})
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
            hardware_trigger=int(frame.get("triggerSelect", 1)) == 2,
            frame_period_s=_scaled(float(frame["framePeriodicity_msec"]), -3),
            adc_format=ADC_FORMATS[fmt] if 0 <= fmt < 3 else str(fmt), lanes=len(_mask_bits(lane_en)), source=src,
            adc_bits=ADC_BITS[bits] if 0 <= bits < 3 else bits)
        # the layouts read here (TI's SWRA581): I before Q; 4 lanes carry the channels interleaved (a lane per
        # Rx), 2 lanes each Rx's samples of a chirp in turn (non-interleaved). Another would read as wrong samples.
        if _mask_int(data_fmt.get("iqSwapSel", 0)):
            raise CaptureError(f"{src}: rlDevDataFmtCfg_t.iqSwapSel is 1 (Q before I); the DCA1000 layouts read "
                               "here put I first")
        packet0 = _mask_int(capture.get("rlDevDataPathCfg_t", {}).get("transferFmtPkt0", 1))
        if packet0 != 1:
            raise CaptureError(f"{src}: rlDevDataPathCfg_t.transferFmtPkt0 is {packet0:#x}: the capture holds more "
                               "than ADC data (chirp parameters, chirp quality); only ADC data (0x1) is read")
        expected = 0 if params.lanes == 4 else 1
        interleave = _mask_int(data_fmt.get("chInterleave", expected))
        if interleave != expected:
            raise CaptureError(f"{src}: rlDevDataFmtCfg_t.chInterleave is {interleave} on a {params.lanes}-lane "
                               f"device; its DCA1000 layout is {('interleaved', 'non-interleaved')[expected]} "
                               f"({expected})")
    except CaptureError:
        raise
    except (OSError, ValueError, KeyError, IndexError, TypeError) as exc:
        raise CaptureError(f"{src}: not a usable mmWave Studio configuration ({type(exc).__name__}: {exc})") from None
    params.check()
    return params


#: ``DCA1000Config.lvdsMode``: the LVDS lanes the DCA1000 takes in
DCA_LVDS_LANES = {1: 4, 2: 2}
#: ``DCA1000Config.dataFormatMode``: the bits of the LVDS words it takes in (TI's DCA1000 CLI user guide)
DCA_FORMAT_BITS = {1: 12, 2: 14, 3: 16}
#: a JSON beside a capture larger than this is no DCA1000 configuration (not read)
_CONFIG_JSON_MAX_BYTES = 1 << 20


def _dca1000_section(path: Path) -> dict[str, Any] | None:
    """The ``DCA1000Config`` table of a JSON file, or None where it holds none or does not read."""
    try:
        if path.stat().st_size > _CONFIG_JSON_MAX_BYTES:
            return None
        section = json.loads(path.read_text(encoding="utf-8")).get("DCA1000Config")
    except (OSError, ValueError, AttributeError):
        return None  # not needed for the layout
    return section if isinstance(section, dict) else None


def dca1000_configs(param_file: Path) -> list[tuple[Path, dict[str, Any]]]:
    """The DCA1000's own configurations beside a capture's parameter file, with their ``DCA1000Config``: every JSON
    there that holds one (mmWave Studio's ``*.setup.json``, the DCA1000 CLI's ``cf.json``)."""
    found = [(p, _dca1000_section(p)) for p in sorted(param_file.parent.glob("*.json"))
             if not p.name.endswith(".mmwave.json")]
    return [(p, section) for p, section in found if section is not None]


def check_dca1000_configs(param_file: Path, params: CaptureParams) -> list[Path]:
    """The DCA1000's configurations beside ``param_file`` must have logged what ``params`` reads
    (:func:`check_dca1000_logging`); returns them."""
    configs = dca1000_configs(param_file)
    for path, dca in configs:
        check_dca1000_logging(f"{path}: DCA1000Config.", dca, param_file.name, params)
    return [path for path, _ in configs]


def check_dca1000_logging(where: str, dca: dict[str, Any], param_name: str, params: CaptureParams) -> None:
    """How a DCA1000 was set to log (``dca``: ``dataLoggingMode``, ``lvdsMode``, ``dataFormatMode``, each optional)
    against what ``params`` reads: raw data (multi mode splits it into per-type files), over as many LVDS lanes as
    the device sends, in words of its ADC's bits: another would read as wrong samples. ``where`` opens each
    message (the file and its table)."""
    mode = dca.get("dataLoggingMode", "raw")
    if str(mode).lower() != "raw":
        raise CaptureError(f"{where}dataLoggingMode is {mode!r}; only raw captures (one stream of ADC data) are read")
    lvds = dca.get("lvdsMode")
    if lvds is not None and DCA_LVDS_LANES.get(_int_or_none(lvds)) != params.lanes:
        logged = DCA_LVDS_LANES.get(_int_or_none(lvds))
        raise CaptureError(f"{where}lvdsMode is {lvds} ({logged or 'no known'} lanes) but the device of {param_name} "
                           f"sends {params.lanes}")
    fmt = dca.get("dataFormatMode")
    if fmt is not None and DCA_FORMAT_BITS.get(_int_or_none(fmt)) != params.adc_bits:
        logged = DCA_FORMAT_BITS.get(_int_or_none(fmt))
        words = f"{logged}-bit" if logged else "no known"
        raise CaptureError(f"{where}dataFormatMode is {fmt} ({words} words) but {param_name} gives "
                           f"{params.adc_bits}-bit ADC samples")


def _int_or_none(value: Any) -> int | None:
    try:
        return _mask_int(value)
    except (ValueError, TypeError):
        return None


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
                         "triggerSelect": 2 if p.hardware_trigger else 1, "frameTriggerDelay": 0.0},
    }
    doc = {"configGenerator": {"createdBy": "autosar"}, "mmWaveDevices": [{
        "mmWaveDeviceId": 0, "rfConfig": rf,
        "rawDataCaptureConfig": {"rlDevDataFmtCfg_t": {"iqSwapSel": 0, "chInterleave": 0 if p.lanes == 4 else 1},
                                 "rlDevLaneEnable_t": {"laneEn": hex((1 << p.lanes) - 1)}}}]}
    mm = base.with_name(base.name + ".mmwave.json")
    setup = base.with_name(base.name + ".setup.json")
    mm.write_text(json.dumps(doc, indent=2), encoding="utf-8")
    setup.write_text(json.dumps({"configUsed": mm.name, "mmWaveDevice": "awr1243", "DCA1000Config": {
        "dataLoggingMode": "raw", "lvdsMode": 1 if p.lanes == 4 else 2},
        "capturedFiles": {"fileBasePath": ".", "files": [{"processedFileName": "adc_data.bin"}]}}, indent=2),
        encoding="utf-8")
    return mm, setup


def params_from_radar(radar: Any, *, lanes: int = 4, adc_format: str = "complex1x",
                      chirp_tx: tuple[int, ...] | None = None, num_frames: int = 0) -> CaptureParams:
    """Capture parameters that state a configured radar (``config.RadarConfig``): one loop per frame."""
    p = CaptureParams(
        profile_start_frequency_hz=radar.start_frequency_hz, slope_hz_per_s=radar.slope_hz_per_s,
        sample_rate_hz=radar.sample_rate_hz, num_samples=radar.num_samples, adc_start_s=0.0,
        chirp_period_s=radar.chirp_period_s, rx_channels=tuple(sorted(radar.rx_in_use)),
        chirp_tx=chirp_tx or tuple(radar.tx_in_use), num_loops=1, num_frames=num_frames,
        frame_period_s=1.0 / radar.prf_hz, adc_format=adc_format, lanes=lanes)
    p.check()
    return p
