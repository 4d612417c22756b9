"""Records that the ingest readers and decoders hand to the ingest pipeline.

Times are int64 nanoseconds since the Unix epoch (UTC). Angles follow the project's ENU convention
(``heading``/``course``: angle from East, counter-clockwise, radians): GNSS courses "from North,
clockwise" are converted once, by the NMEA decoder, through :mod:`autosar_cli.nav.frames`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC, datetime

#: Marks an unknown time (e.g. an NMEA fix time before any sentence carried the date).
UNKNOWN_TIME = -1


@dataclass(frozen=True, slots=True)
class CanRecord:
    """One CAN frame as recorded (by a ROS driver or a standalone CAN logger)."""

    t_ns: int  #: reception time, ns since the Unix epoch
    frame_id: int  #: arbitration ID without flag bits
    is_extended: bool
    dlc: int  #: data length code as recorded (may disagree with len(data) on a faulty logger)
    data: bytes
    is_error: bool = False
    is_remote: bool = False
    channel: str = ""  #: bus name/number as the logger calls it ("" if unknown)


@dataclass(frozen=True, slots=True)
class NmeaFix:
    """Position of one GGA sentence."""

    t_ns: int  #: when it was received (log/header stamp); for a text log without stamps, the fix time
    fix_time_ns: int  #: UTC instant the fix refers to, or UNKNOWN_TIME if the date is not known yet
    latitude_deg: float
    longitude_deg: float
    altitude_m: float  #: ellipsoidal height = altitude above mean sea level + geoid separation
    quality: int  #: GGA fix quality (0 = no fix, 1 = GPS, 2 = DGPS, 4 = RTK fixed, 5 = RTK float, ...)
    num_satellites: int
    hdop: float


@dataclass(frozen=True, slots=True)
class NmeaVelocity:
    """Ground speed and course of one RMC or VTG sentence."""

    t_ns: int
    fix_time_ns: int  #: RMC: its fix instant; VTG (no time field): UNKNOWN_TIME
    speed_mps: float
    course_rad: float  #: course over ground in ENU convention (from East, counter-clockwise); NaN if absent
    #: RMC's position (signed deg; a receiver sending RMC alone gives its fixes only there); NaN for VTG
    latitude_deg: float = math.nan
    longitude_deg: float = math.nan


@dataclass(frozen=True, slots=True)
class NmeaHeading:
    """True heading of one HDT sentence (dual-antenna receivers)."""

    t_ns: int
    heading_rad: float  #: ENU convention (from East, counter-clockwise)


NmeaRecord = NmeaFix | NmeaVelocity | NmeaHeading


@dataclass(frozen=True, slots=True)
class CutShort:
    """Where and why a log file looks cut short (a copy, a card or a disk that ran out mid-write)."""

    reason: str  #: one clause naming the byte
    whole_bytes: int | None = None  #: the file up to the record or line the end cuts: what a reader can take whole
    damaged: bool = False  #: not cut but damaged inside (a link to no block): ``reason`` says where
    #: damaged byte ranges [start, end) left out, what follows each read on (a reader's copy without them)
    holes: tuple[tuple[int, int], ...] = ()
    #: (byte, value) of the 8-byte fields a reader's copy changes (MDF4: links, so that the chains of its groups step
    #: over the damaged ones; a damaged DLC table's values, as a little-endian integer)
    patches: tuple[tuple[int, int], ...] = ()
    #: (byte, count): zero bytes a reader's copy inserts before that byte, ahead of the patches (MDF4: blocks that
    #: bytes added or lost moved off their 8-byte boundaries put back on them)
    inserted: tuple[int, int] | tuple[()] = ()


#: places of damage a report names one by one; beyond, the first two, the count of the others and the last
SAID_AT_MOST = 4


def places_said(said: list[str]) -> str:
    """The places of damage a walk of a file found, ``said`` one clause each, as one clause list for one line."""
    if len(said) > SAID_AT_MOST:
        said = [*said[:2], f"{len(said) - 3} more places damaged as these", said[-1]]
    return "; ".join(said)


def utc_text(t_ns: int, timespec: str = "seconds") -> str:
    """A time (ns since the Unix epoch) as ISO 8601 UTC, to ``timespec``, for a report's line."""
    return datetime.fromtimestamp(t_ns / 1e9, UTC).isoformat(timespec=timespec)
