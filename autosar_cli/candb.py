"""CAN database loading and FCA Giorgio (Alfa Romeo Giulia) CAN framing.

Loading tolerates the one real defect of opendbc's ``fca_giorgio.dbc``: a message ID above
0x7FF written without the extended-frame bit 31, which cantools refuses. Framing encodes
physical values with cantools, then fills in the rolling ``COUNTER`` and the Giorgio CRC8
``CHECKSUM`` (SAE J1850 polynomial 0x1D, init 0x00, over all bytes but the last, then a final
XOR that depends on the frame ID).

Quantisation: cantools converts a physical value ``v`` to raw as
``round((v - offset) / scale)`` with Python's built-in ``round`` (round to nearest, ties to
even; ``LinearConversion.numeric_scaled_to_raw``). :func:`encode_frame` uses that same
conversion, so a value decodes back within half a quantisation step, and clips the result to
the range the raw bit field can hold. The DBC ``[min|max]`` is not used for clipping: the
opendbc layouts store raw bounds there (e.g. ``[0|16383]`` for a steering angle that is
negative when turning right).
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import cantools
from cantools.database.can import Database, Signal

__all__ = [
    "DBC_UNITS",
    "DbcError",
    "FrameCheck",
    "check_frame",
    "encode_frame",
    "si_factor",
    "si_unit",
    "to_dbc_unit",
    "giorgio_checksum",
    "j1850_crc8",
    "load_dbc",
]

_EXTENDED_BIT = 0x8000_0000
_MAX_STANDARD_ID = 0x7FF
_MAX_EXTENDED_ID = 0x1FFF_FFFF

_BO_LINE = re.compile(r"^[ \t]*BO_[ \t]+(\d+)[ \t]+(\w+)", re.MULTILINE)
# Statements that name a message by its numeric ID right after their keyword(s).
_ID_REFERENCE = re.compile(
    r"^([ \t]*(?:BO_|BO_TX_BU_|VAL_|SIG_VALTYPE_|SIG_GROUP_|SG_MUL_VAL_|SIG_TYPE_REF_"
    r'|CM_[ \t]+(?:BO_|SG_)|BA_[ \t]+"[^"]*"[ \t]+(?:BO_|SG_))[ \t]+)(\d+)\b',
    re.MULTILINE,
)

_J1850_POLY = 0x1D
_GIORGIO_FINAL_XOR = {0xDE: 0x10, 0x106: 0xF6, 0x122: 0xF1}
_GIORGIO_DEFAULT_XOR = 0x0A


#: DBC units that are not SI -> (factor to SI, SI unit). Degrees and km/h live only at this edge.
DBC_UNITS: dict[str, tuple[float, str]] = {
    "deg": (math.pi / 180.0, "rad"),
    "°": (math.pi / 180.0, "rad"),
    "degree": (math.pi / 180.0, "rad"),
    "degrees": (math.pi / 180.0, "rad"),
    "deg/s": (math.pi / 180.0, "rad/s"),
    "°/s": (math.pi / 180.0, "rad/s"),
    "deg/sec": (math.pi / 180.0, "rad/s"),
    "degree/s": (math.pi / 180.0, "rad/s"),
    "degrees/s": (math.pi / 180.0, "rad/s"),
    "km/h": (1.0 / 3.6, "m/s"),
    "kph": (1.0 / 3.6, "m/s"),
    "kmh": (1.0 / 3.6, "m/s"),
    "km/hr": (1.0 / 3.6, "m/s"),
    "mph": (0.44704, "m/s"),
    "km": (1000.0, "m"),
    "m/s2": (1.0, "m/s^2"),
    "m/s²": (1.0, "m/s^2"),
    "g": (9.80665, "m/s^2"),
}


def si_unit(unit: str | None) -> tuple[float, str]:
    """(factor, SI unit) that converts a value in a DBC signal's declared unit to SI (1, unit if unknown).

    Latitude/longitude keep degrees (they are coordinates, not angles of the vehicle): see :func:`si_factor`.
    """
    return DBC_UNITS.get((unit or "").strip().lower(), (1.0, (unit or "").strip()))


_GEODETIC = re.compile(r"^(lat|latitude|lon|lng|long|longitude)(_?deg)?$", re.IGNORECASE)


def si_factor(signal_name: str, unit: str | None) -> tuple[float, str]:
    """Like :func:`si_unit`, but geodetic coordinates (Latitude, LON_DEG, ...) stay in degrees."""
    if _GEODETIC.match(signal_name.strip()):
        return 1.0, (unit or "").strip()
    return si_unit(unit)


def to_dbc_unit(value_si: float, unit: str | None) -> float:
    """Convert an SI value (rad, rad/s, m/s, m/s^2) to the unit a DBC signal declares (deg, deg/s, km/h)."""
    return float(value_si) / si_unit(unit)[0]


class DbcError(ValueError):
    """A DBC file cannot be read or parsed."""


def _parse(text: str) -> Database:
    """Parse DBC text in cantools' strict mode. Its log lines on names or frame ids given twice are held back:
    :func:`_reuse_warnings` says what they mean for the drive, once per file."""
    log = logging.getLogger("cantools.database.can.database")
    was = log.disabled
    log.disabled = True
    try:
        db = cantools.database.load_string(text, database_format="dbc", strict=True)
    finally:
        log.disabled = was
    if not isinstance(db, Database):  # pragma: no cover - 'dbc' always gives a CAN database
        raise TypeError("not a CAN database")
    return db


#: a parser's message quotes the line it failed on: of a binary file, kilobytes of it
_REASON_CHARS = 160

#: what a file given as the DBC is by its first bytes, where it is a log (``--dbc`` and ``--can-log`` swapped)
_NOT_A_DBC = ((b"MDF     ", "an MDF4 log"), (b"UnFinMF ", "an MDF4 log"), (b"LOGG", "a BLF log"),
              (b"\x89MCAP", "an MCAP log"), (b"#ROSBAG", "a ROS 1 bag"), (b"SQLite format 3", "a rosbag2 database"))


#: a text log by its first line: (what it is, the line's pattern)
_TEXT_LOGS = (("an ASC CAN log", re.compile(rb"^(date |base hex)")),
              ("a TRC CAN log", re.compile(rb"^;\$FILEVERSION")),
              ("a candump CAN log", re.compile(rb"^\(\d+\.\d+\)\s+\S+\s+[0-9A-Fa-f]+#")),
              ("an NMEA capture", re.compile(rb"^[$!][A-Z]{5},")))


def _other_kind(head: bytes) -> str | None:
    """What a file given as the DBC is by its first bytes, where it is a log (``--dbc`` and ``--can-log`` swapped)."""
    if kind := next((what for magic, what in _NOT_A_DBC if head.startswith(magic)), None):
        return kind
    first = next((line.strip() for line in head.splitlines() if line.strip() and not line.startswith(b"#")), b"")
    return next((what for what, pattern in _TEXT_LOGS if pattern.match(first)), None)


def _reason(exc: BaseException) -> str:
    """One-line description of a cantools load failure (its underlying cause), cut short and printable."""
    cause = exc.__cause__ or exc
    said = " ".join(str(cause).split()) or type(cause).__name__
    said = "".join(c if c.isprintable() else "?" for c in said)
    return said if len(said) <= _REASON_CHARS else said[:_REASON_CHARS] + "..."


def _read_text(path: Path) -> str:
    """Read a DBC file as UTF-8, falling back to cp1252 (the usual DBC encoding)."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise DbcError(f"{path}: cannot read: {exc.strerror or exc}") from exc
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("cp1252", errors="replace")


def load_dbc(path: str | Path) -> tuple[Database, list[str]]:
    """Load a DBC file; repair standard-frame IDs > 0x7FF by setting the extended-frame bit.

    Returns the database and human-readable warnings about repairs. Raises DbcError with a
    one-line message naming the file when the file cannot be read or parsed.
    """
    path = Path(path)
    try:
        with open(path, "rb") as f:  # before the whole: a log given by mistake may be gigabytes
            head = f.read(4096)
    except OSError:
        head = b""  # _read_text names why
    if kind := _other_kind(head):
        raise DbcError(f"{path}: {kind}, not a DBC (--dbc takes the CAN database, --can-log a CAN log)")
    text = _read_text(path)
    try:
        db = _parse(text)
    except cantools.database.UnsupportedDatabaseFormatError as exc:
        first = exc
    else:
        return _nonempty(db, path), _reuse_warnings(db, path)
    bad = {
        int(frame_id): name
        for frame_id, name in _BO_LINE.findall(text)
        if _MAX_STANDARD_ID < int(frame_id) <= _MAX_EXTENDED_ID
    }
    if not bad:
        raise DbcError(f"{path}: {_reason(first)}") from first

    def set_extended(match: re.Match[str]) -> str:
        frame_id = int(match.group(2))
        if frame_id not in bad:
            return match.group(0)
        return f"{match.group(1)}{frame_id | _EXTENDED_BIT}"

    try:
        db = _parse(_ID_REFERENCE.sub(set_extended, text))
    except cantools.database.UnsupportedDatabaseFormatError as exc:
        raise DbcError(f"{path}: {_reason(exc)}") from exc
    warnings = [
        f"{path.name}: message {frame_id} (0x{frame_id:X}) {name} > 0x7FF without the "
        "extended-frame bit; loaded as extended"
        for frame_id, name in sorted(bad.items())
    ]
    return _nonempty(db, path), warnings + _reuse_warnings(db, path)


def _reuse_warnings(db: Database, path: Path) -> list[str]:
    """What a DBC's reused names and frame ids do: a name on several frame ids makes a stream per id
    (``NAME_0xID``, the name a CAN role gives to pick one); a frame id defined twice is decoded by its last
    definition alone."""
    out = []
    ids_of: dict[str, list[int]] = {}
    names_at: dict[tuple[int, bool], list[str]] = {}
    for m in db.messages:
        ids_of.setdefault(m.name, []).append(m.frame_id)
        names_at.setdefault((m.frame_id, m.is_extended_frame), []).append(m.name)
    shared = {name: ids for name, ids in ids_of.items() if len(ids) > 1}
    if shared:
        listed = "; ".join(f"{name} {' / '.join(f'0x{i:X}' for i in ids)}" for name, ids in list(shared.items())[:3])
        listed += f" and {len(shared) - 3} more" if len(shared) > 3 else ""
        out.append(f"{path.name}: {len(shared)} message names are given to several frame ids ({listed}): each id is "
                   "its own stream, NAME_0xID, which a CAN role names to pick one")
    for (frame_id, _), names in names_at.items():
        if len(names) > 1:
            out.append(f"{path.name}: frame id 0x{frame_id:X} is defined {len(names)} times ({', '.join(names)}): its "
                       f"frames are decoded as {names[-1]} alone")
    return out


def _nonempty(db: Database, path: Path) -> Database:
    """Reject a file that parses but defines no message."""
    if not db.messages:
        raise DbcError(f"{path}: no message (BO_) defined")
    return db


def _crc8_table(poly: int) -> tuple[int, ...]:
    """Lookup table of a non-reflected CRC-8 with the given polynomial."""
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ poly) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return tuple(table)


_J1850_TABLE = _crc8_table(_J1850_POLY)


def j1850_crc8(data: bytes) -> int:
    """CRC-8 with the SAE J1850 polynomial 0x1D, init 0x00, no final XOR (Giorgio variant)."""
    crc = 0x00
    for byte in data:
        crc = _J1850_TABLE[crc ^ byte]
    return crc


def giorgio_checksum(frame_id: int, data: bytes) -> int:
    """FCA Giorgio checksum of a frame: CRC8 of all bytes but the last, then a per-ID XOR."""
    return j1850_crc8(data[:-1]) ^ _GIORGIO_FINAL_XOR.get(frame_id, _GIORGIO_DEFAULT_XOR)


def _raw_limits(signal: Signal) -> tuple[int, int]:
    """Smallest and largest raw value the signal's bit field holds."""
    if signal.is_signed:
        return -(1 << (signal.length - 1)), (1 << (signal.length - 1)) - 1
    return 0, (1 << signal.length) - 1


def _to_raw(signal: Signal, value: float | str) -> int | float:
    """Physical value (or choice label) to raw, rounded by cantools, clipped to the bit field."""
    conversion = signal.conversion
    if isinstance(value, str):
        return conversion.choice_to_number(value)
    value = float(value)
    if math.isnan(value):
        raise ValueError(f"signal {signal.name}: value is NaN")
    if signal.is_float:
        return value
    lo, hi = _raw_limits(signal)
    ends = [float(conversion.raw_to_scaled(raw, decode_choices=False)) for raw in (lo, hi)]
    value = min(max(value, min(ends)), max(ends))  # keeps round() finite for +-inf
    return min(max(int(conversion.numeric_scaled_to_raw(value)), lo), hi)


def encode_frame(db: Database, message_name: str, values: Mapping[str, float | str], counter: int) -> bytes:
    """Encode a message's payload with COUNTER = counter % 16 and the Giorgio CHECKSUM.

    Signals not given are raw 0; out-of-range values are clipped (see module docstring).
    ``COUNTER`` and ``CHECKSUM`` in ``values`` are overridden. Unknown names raise KeyError.
    """
    message = db.get_message_by_name(message_name)
    unknown = set(values) - {s.name for s in message.signals}
    if unknown:
        raise KeyError(f"{message_name} has no signal {', '.join(sorted(unknown))}")
    raw: dict[str, int | float] = {s.name: 0 for s in message.signals}
    for name, value in values.items():
        raw[name] = _to_raw(message.get_signal_by_name(name), value)
    if "COUNTER" in raw:
        raw["COUNTER"] = counter % 16
    data = message.encode(raw, scaling=False, strict=False)
    if "CHECKSUM" in raw:
        raw["CHECKSUM"] = giorgio_checksum(message.frame_id, data)
        data = message.encode(raw, scaling=False, strict=False)
    return data


@dataclass(frozen=True, slots=True)
class FrameCheck:
    """Integrity facts of one received frame."""

    frame_id: int
    name: str
    counter: int | None
    checksum_ok: bool | None


def check_frame(db: Database, frame_id: int, data: bytes) -> FrameCheck:
    """Extract COUNTER and verify CHECKSUM (None where the message has none).

    Raises KeyError for an unknown frame ID and ValueError for a payload of the wrong length.
    """
    message = db.get_message_by_frame_id(frame_id)
    if len(data) != message.length:
        raise ValueError(f"{message.name}: {len(data)} bytes, expected {message.length}")
    raw = message.decode(data, decode_choices=False, scaling=False)
    counter = int(raw["COUNTER"]) if "COUNTER" in raw else None
    checksum_ok = None
    if "CHECKSUM" in raw:
        checksum_ok = int(raw["CHECKSUM"]) == giorgio_checksum(message.frame_id, data)
    return FrameCheck(message.frame_id, message.name, counter, checksum_ok)
