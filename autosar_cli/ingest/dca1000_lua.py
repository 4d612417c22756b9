"""mmWave Studio's Lua scripts as a DCA1000 capture's parameters: the ``ar1.*`` calls that configured the device.

mmWave Studio writes its JSON only from version 2; older captures, and scripted ones, keep the Lua script that ran
(TI's ``DataCaptureDemo_xWR.lua`` and its kin). The calls read, by their positional arguments as mmWave Studio
takes them (a 3-Tx device: AWR1243, xWR1443, xWR1642, xWR1843, xWR6843):

- ``ChanNAdcConfig(tx0, tx1, tx2, rx0, rx1, rx2, rx3, bits, fmt, iqSwap)``: the enabled channels, the ADC's bits
  (0, 1, 2: 12, 14, 16) and output format (0, 1, 2: real, complex 1x, complex 2x);
- ``ProfileConfig(id, startFreq GHz, idle us, adcStart us, rampEnd us, 3 x (Tx backoff, Tx phase), slope MHz/us,
  txStart us, samples, sampleRate ksps, hpf1, hpf2, rxGain)``;
- ``ChirpConfig(start, end, profile, startFreqVar, slopeVar, idleVar, adcStartVar, tx0, tx1, tx2)``, one or more;
- ``FrameConfig(start, end, frames, loops, period ms, triggerDelay[, dummyChirps], triggerSelect)``;
- ``LVDSLaneConfig(format, lane1, lane2, lane3, lane4, msbFirst, packetEndPulse, crc)``: the lanes;
- ``DataPathConfig(interface, transferFmtPkt0, transferFmtPkt1)``: ADC data alone (0x1) is read;
- ``CaptureCardConfig_Mode(logMode, lvdsMode, transferMode, captureMode, dataFormatMode, ...)``: how the DCA1000
  logged (1: raw), checked as a DCA1000 configuration is.

Arguments are numbers, or names the script assigns a number once (``start_freq = 77``); anything else, a call
given twice with other arguments (a script that configures several devices by branch), or advanced frames and
continuous streaming, is a one-line error naming the line.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation
from pathlib import Path

from .dca1000_params import (
    ADC_BITS,
    ADC_FORMATS,
    CaptureError,
    CaptureParams,
    _chirp_tx,
    _same_chirps,
    _scaled,
    check_dca1000_logging,
)

_BLOCK_COMMENT = re.compile(r"--\[(=*)\[.*?\]\1\]", re.S)
_LINE_COMMENT = re.compile(r"--[^\n]*")
_CALL = re.compile(r"\bar1\.(\w+)\s*\(([^()]*)\)")
_ASSIGNMENT = re.compile(r"^[ \t]*(?:local[ \t]+)?([A-Za-z_]\w*)[ \t]*=[ \t]*([^\n=]+?)[ \t]*;?[ \t]*$", re.M)
#: calls that configure frames other than the chirp frames read here
_UNREAD_WAVEFORMS = {"AdvanceFrameConfig": "advanced frames of sub-frames",
                     "ContStrConfig": "continuous streaming", "ContStrModConfig": "continuous streaming"}
#: arguments each call must have (FrameConfig: with or without its dummy-chirp count)
_ARITY = {"ChanNAdcConfig": (10,), "ProfileConfig": (18,), "ChirpConfig": (10,), "FrameConfig": (7, 8),
          "LVDSLaneConfig": (8,), "DataPathConfig": (3,), "CaptureCardConfig_Mode": (5, 6, 7)}


@dataclass(frozen=True)
class _Call:
    line: int
    args: tuple[Decimal, ...]


def _number(text: str) -> Decimal | None:
    text = text.strip()
    try:
        return Decimal(int(text, 16)) if text.lower().startswith(("0x", "-0x")) else Decimal(text)
    except (ValueError, InvalidOperation):
        return None


def _calls(path: Path) -> dict[str, list[_Call]]:
    """Every ``ar1.NAME(...)`` call of the script read here, by name, its arguments evaluated."""
    src = str(path)
    text = _BLOCK_COMMENT.sub(lambda m: "\n" * m.group(0).count("\n"), path.read_text(encoding="utf-8",
                                                                                      errors="replace"))
    text = _LINE_COMMENT.sub("", text)
    values: dict[str, set[Decimal]] = {}
    for name, value in _ASSIGNMENT.findall(text):
        if (number := _number(value)) is not None:
            values.setdefault(name, set()).add(number)
    calls: dict[str, list[_Call]] = {}
    for m in _CALL.finditer(text):
        name, line = m.group(1), text.count("\n", 0, m.start()) + 1
        if name in _UNREAD_WAVEFORMS:
            raise CaptureError(f"{src}: line {line}: ar1.{name} configures {_UNREAD_WAVEFORMS[name]}; only frames of "
                               "chirps (ar1.FrameConfig) are read")
        if name not in _ARITY:
            continue
        args = []
        for arg in (a.strip() for a in m.group(2).split(",")):
            number = _number(arg)
            if number is None and len(values.get(arg, ())) == 1:
                number = next(iter(values[arg]))
            if number is None:
                why = "assigned several values" if arg in values else "no number the script assigns"
                raise CaptureError(f"{src}: line {line}: ar1.{name} argument {arg!r}: {why}")
            args.append(number)
        if len(args) not in _ARITY[name]:
            raise CaptureError(f"{src}: line {line}: ar1.{name} has {len(args)} arguments, expected "
                               f"{' or '.join(map(str, _ARITY[name]))} (a 3-Tx device's mmWave Studio)")
        calls.setdefault(name, []).append(_Call(line, tuple(args)))
    return calls


def _optional(src: str, calls: dict[str, list[_Call]], name: str) -> _Call | None:
    """The one configuration ``name`` sets (the same call repeated is one), None where the script makes no such call."""
    found = calls.get(name, [])
    if len({c.args for c in found}) > 1:
        raise CaptureError(f"{src}: ar1.{name} with other arguments on lines {', '.join(str(c.line) for c in found)}"
                           "; keep the call of this capture's device")
    return found[0] if found else None


def _one(src: str, calls: dict[str, list[_Call]], name: str) -> tuple[Decimal, ...]:
    """The arguments of the one configuration ``name`` sets, which the script must make."""
    if (call := _optional(src, calls, name)) is None:
        raise CaptureError(f"{src}: no ar1.{name} call")
    return call.args


def parse_studio_lua(path: Path) -> CaptureParams:
    """The capture parameters an mmWave Studio Lua script sets (see the module docstring)."""
    src = str(path)
    try:
        calls = _calls(path)
    except OSError as exc:
        raise CaptureError(f"{src}: cannot be read ({exc.strerror or exc})") from None
    chan, prof, frame = (_one(src, calls, name) for name in ("ChanNAdcConfig", "ProfileConfig", "FrameConfig"))
    if chan[9]:
        raise CaptureError(f"{src}: ar1.ChanNAdcConfig swaps I and Q (iqSwap {chan[9]}); the DCA1000 layouts read "
                           "here put I first")
    if (path_cfg := _optional(src, calls, "DataPathConfig")) is not None and path_cfg.args[1] != 1:
        raise CaptureError(f"{src}: ar1.DataPathConfig sends transferFmtPkt0 {int(path_cfg.args[1]):#x}: the capture "
                           "holds more than ADC data; only ADC data (0x1) is read")
    lanes_cfg = _optional(src, calls, "LVDSLaneConfig")
    mode = _optional(src, calls, "CaptureCardConfig_Mode")
    if lanes_cfg is not None:
        lanes = int(sum(1 for v in lanes_cfg.args[1:5] if v))
    elif mode is not None and int(mode.args[1]) in (1, 2):
        lanes = 4 if int(mode.args[1]) == 1 else 2
    else:
        raise CaptureError(f"{src}: no ar1.LVDSLaneConfig or ar1.CaptureCardConfig_Mode: the LVDS lanes are not "
                           "stated")
    table: dict[int, int] = {}
    shape: dict[int, tuple[int, tuple[float, ...]]] = {}
    defined: dict[int, _Call] = {}
    for call in calls.get("ChirpConfig", []):
        a = call.args
        for c in range(int(a[0]), int(a[1]) + 1):
            mask, chirp = sum(1 << k for k in range(3) if a[7 + k]), (int(a[2]), tuple(float(v) for v in a[3:7]))
            if c in defined and (table[c], shape[c]) != (mask, chirp):
                raise CaptureError(f"{src}: chirp {c} configured otherwise on lines {defined[c].line} and {call.line} "
                                   "(ar1.ChirpConfig); keep the calls of this capture's device")
            table[c], shape[c], defined[c] = mask, chirp, call
    first, last = int(frame[0]), int(frame[1])
    _same_chirps(src, shape, first, last, int(prof[0]))
    bits, fmt = int(chan[7]), int(chan[8])
    params = CaptureParams(
        profile_start_frequency_hz=_scaled(str(prof[1]), 9), slope_hz_per_s=_scaled(str(prof[11]), 12),
        sample_rate_hz=_scaled(str(prof[14]), 3), num_samples=int(prof[13]), adc_start_s=_scaled(str(prof[3]), -6),
        chirp_period_s=_scaled(str(prof[2] + prof[4]), -6),
        rx_channels=tuple(r for r in range(4) if chan[3 + r]), chirp_tx=_chirp_tx(src, table, first, last),
        num_loops=int(frame[3]), num_frames=int(frame[2]), frame_period_s=_scaled(str(frame[4]), -3),
        hardware_trigger=int(frame[-1]) == 2,
        adc_format=ADC_FORMATS[fmt] if 0 <= fmt < 3 else str(fmt), lanes=lanes, source=src,
        adc_bits=ADC_BITS[bits] if 0 <= bits < 3 else bits)
    if set(params.chirp_tx) - {k for k in range(3) if chan[k]}:
        raise CaptureError(f"{src}: chirps use Tx {sorted(set(params.chirp_tx))} but ar1.ChanNAdcConfig enables "
                           f"{[k for k in range(3) if chan[k]]}")
    params.check()
    if mode is not None:
        m = mode.args
        check_dca1000_logging(f"{src}: line {mode.line}: ar1.CaptureCardConfig_Mode's ",
                              {"dataLoggingMode": "raw" if m[0] == 1 else f"{int(m[0])} (not raw)",
                               "lvdsMode": int(m[1]), "dataFormatMode": int(m[4])}, path.name, params)
    return params
