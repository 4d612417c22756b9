"""Decode NMEA 0183 sentences (GGA, RMC, VTG, HDT, ZDA) into ingest records.

pynmeagps does the framing, the field typing and the sentence definitions; this module adds what a
log needs on top of it: checksum and junk handling that never raises, dates for GGA (which carries only a
time of day), reception vs. fix times, unit conversion (knots -> m/s) and the course/heading conversion
to the project's ENU convention (:func:`autosar_cli.nav.frames.heading_from_course_deg`).

Times and dates
    * ``stamp_ns`` given (a ROS message/header stamp): every record's ``t_ns`` is ``stamp_ns``. A GGA
      before any RMC/ZDA takes its date from ``stamp_ns`` (the day that puts the fix within 12 h of it).
    * ``stamp_ns`` None (a plain text capture): GGA/RMC records get ``t_ns = fix_time_ns``; VTG/HDT (no time
      field) get the fix time of the last GGA/RMC (the epoch they belong to), or are skipped as "no time".
      GGAs (and the VTG/HDT of their epochs) seen before the first RMC/ZDA are held back and returned,
      dated, by the ``feed`` call that learns the date (at most :data:`MAX_HELD`; overflow is "no date").
    * Once a date is known, each dated fix becomes the reference for the next: a GGA time of day more than
      12 h before (after) the reference is on the next (previous) day, so midnight rollovers are handled.

Fields
    * Latitude/longitude are parsed from the raw ``(d)ddmm.mmmm...`` strings (pynmeagps rounds its degrees
      to 1e-10; the Unicore UM981 writes 8-decimal minutes), signed by N/S and E/W.
    * ``altitude_m`` = GGA altitude (MSL) + geoid separation; an empty separation counts as 0 (receivers
      without a geoid model report the ellipsoidal height there). Empty altitude or HDOP -> NaN, empty
      satellite count -> -1.

Skipped input is counted in ``NmeaDecoder.skipped`` (reason -> count), never raised: "bad checksum",
"no checksum", "malformed" (its checksum holds, its fields do not parse), "unparseable" (no sentence at all),
"unsupported <TYPE>" (e.g. "unsupported GSV", "unsupported PUBX"), "no fix"
(GGA quality 0 or empty position, RMC status V, VTG mode N or no speed, HDT/ZDA empty), "no time",
"no date".
"""

from __future__ import annotations

import math
import re
from collections import Counter, deque
from collections.abc import Iterator
from dataclasses import dataclass, replace
from datetime import date, time
from pathlib import Path
from typing import Any

from pynmeagps import NMEAReader
from pynmeagps.exceptions import NMEAMessageError, NMEAParseError, NMEATypeError
from pynmeagps.nmeahelpers import calc_checksum, get_parts
from pynmeagps.nmeatypes_core import GET, VALCKSUM

from autosar_cli.ingest.records import UNKNOWN_TIME, NmeaFix, NmeaHeading, NmeaRecord, NmeaVelocity
from autosar_cli.nav.frames import heading_from_course_deg

MPS_PER_KNOT = 1852.0 / 3600.0  #: exact: 1 international knot = 1852 m/h
MPS_PER_KMH = 1000.0 / 3600.0
DAY_NS = 86_400 * 10**9
HALF_DAY_NS = DAY_NS // 2
MAX_HELD = 1000  #: records held back waiting for a date (text logs); older ones are dropped as "no date"
SUPPORTED = frozenset({"GGA", "RMC", "VTG", "HDT", "ZDA"})

_EPOCH_ORDINAL = date(1970, 1, 1).toordinal()
_HEADER = re.compile(r"[A-Z0-9]{3,}")


class _Skip(Exception):
    """Internal: the sentence is skipped for ``reason``."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


@dataclass(slots=True)
class _Held:
    """A record waiting for a date: ``tod_ns`` (ns since midnight UTC) of its epoch."""

    tod_ns: int
    record: NmeaRecord
    timed: bool  #: the record carries the fix time itself (GGA/RMC) rather than only t_ns (VTG/HDT)


def date_ns(d: date) -> int:
    """Midnight UTC of date ``d`` in ns since the Unix epoch."""
    return (d.toordinal() - _EPOCH_ORDINAL) * DAY_NS


def time_of_day_ns(t: time) -> int:
    """Time of day (UTC) in ns since midnight."""
    return ((t.hour * 60 + t.minute) * 60 + t.second) * 10**9 + t.microsecond * 1000


def nearest_instant(tod_ns: int, ref_ns: int) -> int:
    """The instant (ns since epoch) with time of day ``tod_ns`` nearest to ``ref_ns`` (within +-12 h)."""
    t = ref_ns - ref_ns % DAY_NS + tod_ns
    if t - ref_ns > HALF_DAY_NS:
        t -= DAY_NS
    elif ref_ns - t > HALF_DAY_NS:
        t += DAY_NS
    return t


def parse_dmm(raw: str, hemisphere: str, is_lat: bool) -> float | None:
    """Signed degrees from an NMEA ``(d)ddmm.mmmm...`` string and N/S/E/W; None if the field is empty.

    Keeps every digit of the minutes (unlike pynmeagps, which rounds degrees to 1e-10). A leading minus
    (Unicore writes "-0214.41..." in GLL) is ignored: the hemisphere gives the sign.
    """
    raw = raw.strip().lstrip("-")
    if not raw:
        return None
    if hemisphere not in (("N", "S") if is_lat else ("E", "W")):
        raise _Skip("malformed")
    dp = raw.find(".")
    if dp < 0:
        dp = len(raw)
    if dp < 3 or not raw[: dp - 2].isdigit():
        raise _Skip("malformed")
    try:
        minutes = float(raw[dp - 2 :])
    except ValueError:
        raise _Skip("malformed") from None
    deg = int(raw[: dp - 2])
    if not 0.0 <= minutes < 60.0 or deg > (90 if is_lat else 180):
        raise _Skip("malformed")
    value = deg + minutes / 60.0
    return -value if hemisphere in ("S", "W") else value


def _num(value: Any) -> float:
    """A pynmeagps decimal field as float: NaN for an empty ("") or missing field (or "nan"/"inf")."""
    return float(value) if isinstance(value, int | float) and math.isfinite(value) else math.nan


def _course_rad(course_deg: Any) -> float:
    """ENU course (rad, from East, CCW) from a GNSS course field (deg, from North, CW); NaN if empty."""
    c = _num(course_deg)
    return math.nan if math.isnan(c) else float(heading_from_course_deg(c))


class NmeaDecoder:
    """Stateful decoder of one NMEA stream (keeps the last date seen so GGA times get a date).

    Feed sentences in stream order; one decoder per receiver. ``skipped`` counts what was not decoded.
    """

    def __init__(self, anchor_ns: int | None = None) -> None:
        self.skipped: Counter[str] = Counter()
        self.sentences: Counter[str] = Counter()  #: supported sentences parsed, by type (ZDA included)
        #: an instant on the drive's day, from other streams: dates a capture that never carries one
        self.anchor_ns = anchor_ns
        self.anchored = 0  #: records dated by ``anchor_ns``
        self._ref_ns: int | None = None  # last dated instant (RMC/ZDA, then each dated GGA): the date source
        self._epoch: tuple[int, int | None] | None = None  # last GGA/RMC: (time of day ns, fix time ns or None)
        self._held: deque[_Held] = deque()

    # ------------------------------------------------------------------ public API
    def feed(self, sentence: str | bytes, stamp_ns: int | None = None) -> list[NmeaRecord]:
        """Decode one sentence. stamp_ns: reception time (log/header stamp, ns since epoch) or None for a
        text log without stamps, in which case records' t_ns is the fix time.
        Returns 0..n records; never raises on bad input (counts it in `skipped`)."""
        out: list[NmeaRecord] = []
        try:
            kind, msg = self._parse(sentence)
            self.sentences[kind] += 1
            if kind == "GGA":
                self._gga(msg, stamp_ns, out)
            elif kind == "RMC":
                self._rmc(msg, stamp_ns, out)
            elif kind == "VTG":
                self._vtg(msg, stamp_ns, out)
            elif kind == "HDT":
                self._hdt(msg, stamp_ns, out)
            else:
                self._zda(msg, out)
        except _Skip as skip:
            self.skipped[skip.reason] += 1
        return out

    def flush(self) -> list[NmeaRecord]:
        """Records still held back at end of stream. A record is only ever held for want of a date: with an
        ``anchor_ns`` they are dated by it (the day that puts the first within 12 h of it) and returned;
        without one they are dropped and counted as "no date"."""
        out: list[NmeaRecord] = []
        if self._held and self.anchor_ns is not None:
            self.anchored = len(self._held)
            self._learn_date(nearest_instant(self._held[0].tod_ns, self.anchor_ns), out)
        if self._held:
            self.skipped["no date"] += len(self._held)
            self._held.clear()
        return out

    # ------------------------------------------------------------------ parsing
    def _parse(self, sentence: str | bytes) -> tuple[str, Any]:
        """(sentence type, pynmeagps message) of a supported sentence; raises _Skip otherwise."""
        if isinstance(sentence, bytes):
            start = sentence.rfind(b"$")
            try:
                text = sentence[max(start, 0) :].decode("ascii")
            except UnicodeDecodeError:
                raise _Skip("unparseable") from None
        else:
            text = sentence[max(sentence.rfind("$"), 0) :]
        text = text.strip()
        if not text.startswith("$") or not text.isascii():
            raise _Skip("unparseable")
        if "*" not in text:
            raise _Skip("no checksum")
        try:
            content, talker, msgid, _, checksum = get_parts(text)
        except NMEAMessageError:
            raise _Skip("unparseable") from None
        if checksum.strip().upper() != calc_checksum(content):
            raise _Skip("bad checksum")
        if not _HEADER.fullmatch(talker + msgid):
            raise _Skip("malformed")
        if talker == "P" or msgid not in SUPPORTED:
            raise _Skip(f"unsupported {'P' + msgid if talker == 'P' else msgid}")
        try:
            msg = NMEAReader.parse(text, msgmode=GET, validate=VALCKSUM)
        except (NMEAMessageError, NMEAParseError, NMEATypeError, ValueError):
            raise _Skip("malformed") from None
        if msg is None:
            raise _Skip("malformed")
        return msgid, msg

    @staticmethod
    def _tod(msg: Any) -> int | None:
        """Time of day (ns since midnight UTC) of the sentence's time field; None if empty/invalid."""
        t = getattr(msg, "time", "")
        return time_of_day_ns(t) if isinstance(t, time) else None

    @staticmethod
    def _latlon(msg: Any, index: int) -> tuple[float, float] | None:
        """(lat, lon) in signed degrees from the raw payload fields at ``index``..``index + 3``."""
        payload: list[str] = msg.payload
        if len(payload) < index + 4:
            return None
        lat = parse_dmm(payload[index], payload[index + 1], is_lat=True)
        lon = parse_dmm(payload[index + 2], payload[index + 3], is_lat=False)
        return None if lat is None or lon is None else (lat, lon)

    # ------------------------------------------------------------------ dates
    def _resolve(self, tod_ns: int, stamp_ns: int | None) -> int | None:
        """Fix instant (ns) for a time of day: from the known date (rollover-aware), else from stamp_ns."""
        if self._ref_ns is not None:
            return nearest_instant(tod_ns, self._ref_ns)
        if stamp_ns is not None:
            return nearest_instant(tod_ns, stamp_ns)
        return None

    def _learn_date(self, instant_ns: int, out: list[NmeaRecord]) -> None:
        """A sentence carried a full date+time: make it the reference and release the held records."""
        self._ref_ns = instant_ns
        while self._held:
            h = self._held.popleft()
            fix = nearest_instant(h.tod_ns, instant_ns)
            out.append(replace(h.record, t_ns=fix, fix_time_ns=fix) if h.timed else replace(h.record, t_ns=fix))
        if self._epoch is not None and self._epoch[1] is None:
            self._epoch = (self._epoch[0], nearest_instant(self._epoch[0], instant_ns))

    def _hold(self, tod_ns: int, record: NmeaRecord, timed: bool) -> None:
        if len(self._held) >= MAX_HELD and self.anchor_ns is None:
            self._held.popleft()
            self.skipped["no date"] += 1
        self._held.append(_Held(tod_ns, record, timed))

    def _emit_timed(self, record: NmeaFix | NmeaVelocity, tod: int, fix: int | None, stamp_ns: int | None,
                    out: list[NmeaRecord]) -> None:
        """Emit a GGA/RMC record with its fix time, or hold it (text log, date unknown)."""
        if fix is None:
            self._hold(tod, record, timed=True)
            return
        if self._ref_ns is not None:  # dated by RMC/ZDA (not by a stamp): chain the date on to the next fix
            self._ref_ns = fix
        out.append(replace(record, t_ns=fix if stamp_ns is None else stamp_ns, fix_time_ns=fix))

    def _emit_untimed(self, record: NmeaVelocity | NmeaHeading, stamp_ns: int | None,
                      out: list[NmeaRecord]) -> None:
        """Emit a VTG/HDT record: t_ns = stamp, else the epoch's fix time; held/skipped if that is unknown."""
        if stamp_ns is not None:
            out.append(replace(record, t_ns=stamp_ns))
        elif self._epoch is None:
            raise _Skip("no time")
        elif self._epoch[1] is None:
            self._hold(self._epoch[0], record, timed=False)
        else:
            out.append(replace(record, t_ns=self._epoch[1]))

    # ------------------------------------------------------------------ sentence handlers
    def _gga(self, msg: Any, stamp_ns: int | None, out: list[NmeaRecord]) -> None:
        tod = self._tod(msg)
        fix = None if tod is None else self._resolve(tod, stamp_ns)
        self._epoch = None if tod is None else (tod, fix)
        quality = getattr(msg, "quality", "")
        latlon = self._latlon(msg, 1)
        if not isinstance(quality, int) or quality == 0 or latlon is None:
            raise _Skip("no fix")
        if tod is None:
            raise _Skip("no time")
        alt, sep = _num(getattr(msg, "alt", "")), _num(getattr(msg, "sep", ""))
        num_sv = getattr(msg, "numSV", "")
        record = NmeaFix(t_ns=UNKNOWN_TIME, fix_time_ns=UNKNOWN_TIME, latitude_deg=latlon[0], longitude_deg=latlon[1],
                         altitude_m=alt + (0.0 if math.isnan(sep) else sep), quality=quality,
                         num_satellites=num_sv if isinstance(num_sv, int) else -1,
                         hdop=_num(getattr(msg, "HDOP", "")))
        self._emit_timed(record, tod, fix, stamp_ns, out)

    def _rmc(self, msg: Any, stamp_ns: int | None, out: list[NmeaRecord]) -> None:
        tod = self._tod(msg)
        d = getattr(msg, "date", "")
        valid = getattr(msg, "status", "") == "A"
        fix: int | None
        if valid and tod is not None and isinstance(d, date):
            fix = date_ns(d) + tod
            self._learn_date(fix, out)
        else:  # void (its date may be a receiver's unset clock) or no date: like a GGA
            fix = None if tod is None else self._resolve(tod, stamp_ns)
        self._epoch = None if tod is None else (tod, fix)
        if not valid:
            raise _Skip("no fix")
        if tod is None:
            raise _Skip("no time")
        speed = _num(getattr(msg, "spd", ""))
        if math.isnan(speed):
            raise _Skip("no fix")
        latlon = self._latlon(msg, 2) or (math.nan, math.nan)
        record = NmeaVelocity(t_ns=UNKNOWN_TIME, fix_time_ns=UNKNOWN_TIME, speed_mps=speed * MPS_PER_KNOT,
                              course_rad=_course_rad(getattr(msg, "cog", "")), latitude_deg=latlon[0],
                              longitude_deg=latlon[1])
        self._emit_timed(record, tod, fix, stamp_ns, out)

    def _vtg(self, msg: Any, stamp_ns: int | None, out: list[NmeaRecord]) -> None:
        knots, kmh = _num(getattr(msg, "sogn", "")), _num(getattr(msg, "sogk", ""))
        speed = knots * MPS_PER_KNOT if not math.isnan(knots) else kmh * MPS_PER_KMH
        if getattr(msg, "posMode", "") == "N" or math.isnan(speed):
            raise _Skip("no fix")
        record = NmeaVelocity(t_ns=UNKNOWN_TIME, fix_time_ns=UNKNOWN_TIME, speed_mps=speed,
                              course_rad=_course_rad(getattr(msg, "cogt", "")))
        self._emit_untimed(record, stamp_ns, out)

    def _hdt(self, msg: Any, stamp_ns: int | None, out: list[NmeaRecord]) -> None:
        heading = _course_rad(getattr(msg, "headingT", ""))
        if math.isnan(heading):
            raise _Skip("no fix")
        self._emit_untimed(NmeaHeading(t_ns=UNKNOWN_TIME, heading_rad=heading), stamp_ns, out)

    def _zda(self, msg: Any, out: list[NmeaRecord]) -> None:
        tod = self._tod(msg)
        ymd = (getattr(msg, "year", ""), getattr(msg, "month", ""), getattr(msg, "day", ""))
        if tod is None or not all(isinstance(v, int) for v in ymd):
            raise _Skip("no fix")
        try:
            d = date(*ymd)
        except ValueError:
            raise _Skip("malformed") from None
        self._learn_date(date_ns(d) + tod, out)


class NmeaLogReader:
    """Records of a text NMEA capture (one sentence per line, no stamps: ``t_ns`` is the fix time).

    Skips blank lines and ``#`` comment lines; binary junk and sentences run together on one line are split
    at ``$`` and the junk counted as "unparseable". Iterating decodes the file anew with a fresh
    :class:`NmeaDecoder`; ``skipped`` is that decoder's counter (complete once iteration has finished,
    including records dropped as "no date" at the end).
    """

    def __init__(self, path: Path, anchor_ns: int | None = None) -> None:
        self.path = Path(path)
        self.anchor_ns = anchor_ns
        self._decoder = NmeaDecoder(anchor_ns)
        self.damaged_lines = 0  #: lines holding a sentence with a bad or no checksum, or bytes that are no sentence
        self.damaged_bytes = 0  #: their length
        self.first_damage_byte: int | None = None  #: where the first of them starts in the file

    @property
    def skipped(self) -> Counter[str]:
        """Reason -> count of what the latest (or current) iteration did not decode."""
        return self._decoder.skipped

    @property
    def decoder(self) -> NmeaDecoder:
        """The latest (or current) iteration's decoder: its ``sentences`` and ``anchored`` counts."""
        return self._decoder

    def __iter__(self) -> Iterator[NmeaRecord]:
        decoder = self._decoder = NmeaDecoder(self.anchor_ns)
        self.damaged_lines, self.damaged_bytes, self.first_damage_byte = 0, 0, None
        at = 0
        with self.path.open("rb") as f:
            for raw in f:
                start, at = at, at + len(raw)
                line = raw.strip()
                if not line or line.startswith(b"#"):
                    continue
                unended = not raw.endswith(b"\n")  # only ever the file's last line
                damaged = _damage(decoder.skipped)
                for part in re.split(rb"(?=\$)", line):
                    if part.strip():
                        before = decoder.skipped.copy() if unended else None
                        yield from decoder.feed(part)
                        if before is not None and _broken(decoder.skipped - before):
                            # the file's last line, without its end, broken: a capture cut short
                            decoder.skipped = before
                            decoder.skipped["cut off by the file's end"] += 1
                if _damage(decoder.skipped) > damaged:
                    self.damaged_lines += 1
                    self.damaged_bytes += len(raw)
                    self.first_damage_byte = start if self.first_damage_byte is None else self.first_damage_byte
        yield from decoder.flush()


_DAMAGE = ("bad checksum", "no checksum", "malformed", "unparseable")


def nothing_read(reader: NmeaLogReader) -> str | None:
    """Why a capture just iterated gave nothing (no sentence decoded, none of a kind not decoded), else None:
    every line that looks like a sentence damaged, or nothing like one at all."""
    dec = reader.decoder
    if dec.sentences or any(k.startswith("unsupported") for k in dec.skipped):
        return None
    sentences = dec.skipped["bad checksum"] + dec.skipped["no checksum"] + dec.skipped["malformed"]
    if not sentences:
        return "no NMEA 0183 sentence in this file"
    counts = ", ".join(f"{dec.skipped[r]} {r}" for r in _DAMAGE if dec.skipped[r])
    return (f"none of its {sentences} NMEA 0183 sentences could be read ({counts}; the first damaged line at byte "
            f"{reader.first_damage_byte}): damaged throughout")


def _damage(skipped: Counter[str]) -> int:
    """How many of the skipped sentences were damaged (not merely of a kind not decoded, or without a fix)."""
    return sum(skipped[r] for r in _DAMAGE)


def _broken(reasons: Counter[str]) -> bool:
    """Whether a sentence skipped for ``reasons`` was damaged, not merely of a kind not decoded."""
    return bool(reasons) and not any(r.startswith("unsupported") for r in reasons)


def read_nmea_log(path: Path) -> Iterator[NmeaRecord]:
    """Records of a text NMEA capture; use :class:`NmeaLogReader` directly to see what was skipped."""
    return iter(NmeaLogReader(path))
