"""NMEA decoder: simulator round trip, gpsd's decoded regression output, real pynmeagps captures, edge cases."""

from __future__ import annotations

import json
import math
import re
from collections import Counter
from datetime import UTC, date, datetime, timedelta
from pathlib import Path
from typing import TypeVar

import pytest
from conftest import realdata
from pynmeagps.nmeahelpers import calc_checksum

from autosar_cli.ingest.nmea import MAX_HELD, MPS_PER_KNOT, NmeaDecoder, NmeaLogReader, read_nmea_log
from autosar_cli.ingest.records import UNKNOWN_TIME, NmeaFix, NmeaHeading, NmeaRecord, NmeaVelocity
from autosar_cli.sim.messages import GEOID_SEPARATION_M, nmea_sentences

T = TypeVar("T")


def ns(dt: datetime) -> int:
    """ns since the Unix epoch of an aware datetime (exact, no float)."""
    return (dt - datetime(1970, 1, 1, tzinfo=UTC)) // timedelta(microseconds=1) * 1000


def sentence(body: str) -> str:
    """'$' + body + '*' + checksum: a well-formed sentence with whatever payload the test needs."""
    return f"${body}*{calc_checksum(body)}"


def feed_all(dec: NmeaDecoder, sentences: list[str], stamp_ns: int | None = None) -> list[NmeaRecord]:
    return [r for s in sentences for r in dec.feed(s, stamp_ns)] + dec.flush()


def of_type(records: list[NmeaRecord], cls: type[T]) -> list[T]:
    return [r for r in records if isinstance(r, cls)]


# --------------------------------------------------------------------------- simulator round trip

# (course_deg from North CW, expected ENU rad from East CCW): course 90 (East) -> 0, 0 (North) -> +pi/2, ...
COURSES = [(90.0, 0.0), (0.0, math.pi / 2), (180.0, -math.pi / 2), (45.0, math.pi / 4), (271.23, -math.radians(181.23))]


@pytest.mark.parametrize(("course_deg", "course_enu"), COURSES)
@pytest.mark.parametrize(("lat", "lon"), [(48.123456789, 11.987654321), (-33.123456789, -70.98765432)])
def test_simulator_round_trip(lat: float, lon: float, course_deg: float, course_enu: float) -> None:
    """Precisions of the simulator's formatting: lat/lon 1e-7 arc-minutes (hpnmeamode: 8.3e-10 deg), MSL altitude
    1 mm, speed 0.001 kn, course 0.01 deg, heading 0.001 deg, time truncated to 10 ms (exact here)."""
    t = datetime(2024, 5, 6, 12, 34, 56, 780000, tzinfo=UTC)
    height, speed, heading_deg = 512.3456, 13.37, 12.345
    lines = nmea_sentences(t, lat, lon, height, speed, course_deg, heading_deg)
    assert [s[3:6] for s in lines] == ["GGA", "RMC", "VTG", "HDT"]

    # Text log (no stamps): the GGA comes before the first RMC, so it is held back and released by the RMC.
    dec = NmeaDecoder()
    assert dec.feed(lines[0]) == []
    recs = feed_all(dec, lines[1:])
    assert not dec.skipped
    fix, rmc, vtg, hdt = recs
    assert isinstance(fix, NmeaFix) and isinstance(rmc, NmeaVelocity)
    assert isinstance(vtg, NmeaVelocity) and isinstance(hdt, NmeaHeading)
    assert fix.fix_time_ns == fix.t_ns == rmc.fix_time_ns == rmc.t_ns == vtg.t_ns == hdt.t_ns == ns(t)
    assert vtg.fix_time_ns == UNKNOWN_TIME
    assert fix.latitude_deg == pytest.approx(lat, abs=1e-9)
    assert fix.longitude_deg == pytest.approx(lon, abs=1e-9)
    assert fix.altitude_m == pytest.approx(height, abs=5e-4)  # MSL + separation (47 m) = ellipsoidal
    assert (fix.quality, fix.num_satellites, fix.hdop) == (2, 14, 0.7)
    # 0.001 kn rounding, plus the simulator's 1/0.514444 kn per m/s (exact: 3600/1852) -- 1e-6 relative
    for v in (rmc, vtg):
        assert v.speed_mps == pytest.approx(speed, abs=0.0005 * MPS_PER_KNOT + 1e-6 * speed)
        assert math.remainder(v.course_rad - course_enu, 2 * math.pi) == pytest.approx(0.0, abs=math.radians(0.005))
    assert math.remainder(hdt.heading_rad - math.radians(90.0 - heading_deg), 2 * math.pi) == pytest.approx(
        0.0, abs=math.radians(0.0005))


def test_simulator_round_trip_with_stamps() -> None:
    """With reception stamps every t_ns is the stamp; GGA before any RMC takes its date from the stamp."""
    t = datetime(2024, 5, 6, 23, 59, 59, 900000, tzinfo=UTC)
    stamp = ns(t) + 250_000_000  # received 0.25 s later, already on 7 May
    dec = NmeaDecoder()
    recs = feed_all(dec, nmea_sentences(t, 52.5, 13.4, 40.0, 1.0, 90.0, 0.0), stamp_ns=stamp)
    assert [type(r) for r in recs] == [NmeaFix, NmeaVelocity, NmeaVelocity, NmeaHeading]
    assert all(r.t_ns == stamp for r in recs)
    fix, rmc = recs[0], recs[1]
    assert isinstance(fix, NmeaFix) and isinstance(rmc, NmeaVelocity)
    assert fix.fix_time_ns == rmc.fix_time_ns == ns(t)
    assert fix.altitude_m == pytest.approx(40.0, abs=5e-4)
    assert GEOID_SEPARATION_M != 0.0  # (else the altitude check would not test the MSL -> ellipsoid step)


# --------------------------------------------------------------------------- gpsd regression output

GPSD_ROLLOVER = timedelta(weeks=1024)


def test_gpsd_neo_m8n_matches_gpsd_decoding() -> None:
    """gpsd's expected TPVs (neo-m8n.log.chk) vs our decoding of the same capture (u-blox NEO-M8N, 2015-03-18).

    gpsd dates this capture 2034-11-01: exactly 1024 GPS weeks after the RMC date (180315) -- its GPS week
    rollover fix-up -- so TPV times are compared after subtracting 1024 weeks; times of day are identical.
    TPV 'alt' is altMSL; our altitude_m is ellipsoidal, i.e. 'altHAE' (= altMSL + geoidSep).
    """
    log = realdata("gpsd", "neo-m8n.log")
    reader = NmeaLogReader(log)
    recs = list(reader)
    fixes = {r.fix_time_ns: r for r in of_type(recs, NmeaFix)}
    rmc = {r.fix_time_ns: r for r in of_type(recs, NmeaVelocity) if r.fix_time_ns != UNKNOWN_TIME}
    assert len(fixes) == 23 and len(rmc) == 23
    assert reader.skipped == Counter({"unsupported GSV": 157, "unsupported GSA": 44, "unsupported GLL": 23})

    chk = realdata("gpsd", "neo-m8n.log.chk").read_text().splitlines()
    tpvs = [json.loads(line) for line in chk if line.startswith("{")]  # the rest echoes the input sentences
    tpvs = [o for o in tpvs if o["class"] == "TPV" and o["mode"] >= 2]
    assert len(tpvs) == 23
    assert "time" not in tpvs[0]  # gpsd's first TPV comes from a GLL before any date: nothing to match
    matched = 0
    for o in tpvs[1:]:
        t = datetime.fromisoformat(o["time"]) - GPSD_ROLLOVER
        fix = fixes[ns(t)]
        assert fix.latitude_deg == pytest.approx(o["lat"], abs=1e-9)  # gpsd prints 9 decimals
        assert fix.longitude_deg == pytest.approx(o["lon"], abs=1e-9)
        assert o["alt"] == o["altMSL"]
        assert fix.altitude_m == pytest.approx(o["altHAE"], abs=0.01)
        if "speed" in o:
            assert rmc[ns(t)].speed_mps == pytest.approx(o["speed"], abs=0.01)
        matched += 1
    # 22 epochs 17:19:26..47; the last GGA (17:19:48) ends the capture before gpsd closed its cycle.
    assert matched == 22
    assert min(fixes) == ns(datetime(2015, 3, 18, 17, 19, 26, tzinfo=UTC))


# --------------------------------------------------------------------------- pynmeagps real captures


def test_pynmeagps_ublox7() -> None:
    """u-blox 7 (UBX-G70xx) capture: TXT banner, one full epoch, then the next RMC."""
    reader = NmeaLogReader(realdata("pynmeagps", "pygpsdata-nmea2.log"))
    recs = list(reader)
    assert [type(r) for r in recs] == [NmeaVelocity, NmeaVelocity, NmeaFix, NmeaVelocity]
    fix = recs[2]
    assert isinstance(fix, NmeaFix)
    assert fix.t_ns == fix.fix_time_ns == ns(datetime(2021, 3, 7, 10, 29, 29, tzinfo=UTC))
    assert fix.latitude_deg == pytest.approx(53 + 27.04024 / 60, abs=1e-12)
    assert fix.longitude_deg == pytest.approx(-(2 + 14.41560 / 60), abs=1e-12)
    assert fix.altitude_m == pytest.approx(36.3 + 48.5, abs=1e-9)
    assert (fix.quality, fix.num_satellites, fix.hdop) == (1, 8, 1.16)
    rmc = recs[0]
    assert isinstance(rmc, NmeaVelocity) and rmc.fix_time_ns == fix.fix_time_ns
    assert rmc.speed_mps == pytest.approx(0.273 * 1852 / 3600)
    assert math.isnan(rmc.course_rad)  # empty course (standing still)
    assert recs[1].t_ns == fix.t_ns  # VTG: the time of its epoch
    assert reader.skipped == Counter({"unsupported TXT": 7, "unsupported GSV": 4, "unsupported GSA": 1,
                                      "unsupported GLL": 1})


def test_pynmeagps_all_sentence_types() -> None:
    """40 sentence types (standard, Garmin/u-blox proprietary, odd talkers IN/AN/II): only GGA/RMC/VTG/HDT/ZDA
    are decoded; everything else is counted, nothing raises."""
    reader = NmeaLogReader(realdata("pynmeagps", "pygpsdata-nmea4.log"))
    recs = list(reader)
    assert Counter(type(r).__name__ for r in recs) == Counter(NmeaFix=2, NmeaVelocity=2, NmeaHeading=1)
    fixes = of_type(recs, NmeaFix)
    assert all(f.fix_time_ns == ns(datetime(2021, 3, 6, 10, 36, 7, tzinfo=UTC)) for f in fixes)  # GN and IN talkers
    (hdt,) = of_type(recs, NmeaHeading)
    assert hdt.heading_rad == pytest.approx(math.radians(90.0 - 274.07 + 360.0))
    assert sum(reader.skipped.values()) == 57 - 6  # 57 sentences: 5 records + 1 ZDA (date only)
    assert reader.skipped["unsupported PUBX"] == 3
    assert reader.skipped["unsupported PGRME"] == reader.skipped["unsupported PGRMZ"] == 1
    assert reader.skipped["unsupported GSV"] == 9 and reader.skipped["unsupported GNS"] == 1
    assert reader.skipped["unsupported HDM"] == 2  # magnetic heading is not true heading
    assert all(k.startswith("unsupported ") for k in reader.skipped)


def test_pynmeagps_startup_burst() -> None:
    """Receiver start-up: void RMC, invalid VTG, empty GGA -> no records, all counted as 'no fix'."""
    reader = NmeaLogReader(realdata("pynmeagps", "pygpsdata-nmeastartup.log"))
    assert list(reader) == []
    assert reader.skipped == Counter({"no fix": 3, "unsupported GSA": 4, "unsupported GSV": 4, "unsupported GLL": 1})


def test_pynmeagps_um981_full_precision() -> None:
    """Unicore UM981: 8-decimal minutes (kept to the last digit), GGA before the first RMC (held, then dated)."""
    reader = NmeaLogReader(realdata("pynmeagps", "pygpsdata-um981.log"))
    recs = list(reader)
    assert [type(r) for r in recs] == [NmeaFix, NmeaVelocity, NmeaFix]
    first = recs[0]
    assert isinstance(first, NmeaFix)
    assert first.fix_time_ns == first.t_ns == ns(datetime(2026, 2, 24, 13, 0, 58, tzinfo=UTC))
    # 5327.03598945 N, 00214.41467156 W -> 53.450599824166..., -2.240244526 (to 1e-12 deg = 0.1 um)
    assert first.latitude_deg == pytest.approx(53.4505998241667, abs=1e-12)
    assert first.longitude_deg == pytest.approx(-2.240244526, abs=1e-12)
    assert first.altitude_m == pytest.approx(36.3017 + 51.6775, abs=1e-9)
    rmc = recs[1]
    assert isinstance(rmc, NmeaVelocity) and rmc.fix_time_ns == first.fix_time_ns
    assert rmc.course_rad == pytest.approx(math.radians(90.0 - 125.7))
    second = recs[2]
    assert isinstance(second, NmeaFix) and second.latitude_deg == pytest.approx(53 + 27.03598242 / 60, abs=1e-12)
    assert reader.skipped == Counter({"unsupported GLL": 2})  # GLL with a negative "-0214.41..." longitude


# --------------------------------------------------------------------------- edge cases

GGA = "GPGGA,{t},4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"
RMC = "GPRMC,{t},A,4807.038,N,01131.000,E,022.4,084.4,{d},003.1,W"


def test_bad_input_is_counted_not_raised() -> None:
    dec = NmeaDecoder()
    good = sentence(GGA.format(t="123519"))
    inputs: list[str | bytes] = [
        good[:-1] + ("0" if good[-1] != "0" else "1"),  # bad checksum
        good.split("*")[0],  # no checksum
        b"\xff\xfe\x00\x81garbage\xb5b\x01\x07",  # binary junk (e.g. UBX between sentences)
        b"\xb5b$GPGGA\xff,1*00",  # non-ASCII after the '$'
        "",
        "$*00",
        sentence("GPGGA,123519,4807.038,N,01131.000,E,x,08,0.9,545.4,M,46.9,M,,"),  # quality not an integer
        sentence("GPGGA,123519,48x7.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"),  # bad latitude
        sentence("GPGGA,123519,4807.038,Q,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"),  # bad hemisphere
        sentence("GPGSV,1,1,00,1"),
        sentence("PUBX,00,103607.00"),
        sentence("GPGGA,,,,,,0,00,99.99,,,,,,"),  # empty GGA
        sentence("GPGGA,123519,4807.038,N,01131.000,E,0,00,,,M,,M,,"),  # quality 0
        sentence("GPRMC,123519,V,4807.038,N,01131.000,E,,,230394,,"),  # void RMC
        sentence("GPVTG,,T,,M,,N,,K,N"),
        sentence("GPHDT,,T"),
        sentence("GPZDA,,,,,,"),
    ]
    for s in inputs:
        assert dec.feed(s) == []
    assert dec.flush() == []
    # malformed: the checksum holds but the fields do not parse (quality, latitude); unparseable: no sentence
    assert dec.skipped == Counter({"bad checksum": 1, "no checksum": 1, "malformed": 4, "unparseable": 3,
                                   "unsupported GSV": 1, "unsupported PUBX": 1, "no fix": 6})

    # Valid VTG/HDT in a text log before any GGA/RMC: nothing gives them a time.
    dec = NmeaDecoder()
    assert feed_all(dec, [sentence("GPVTG,054.7,T,034.4,M,005.5,N,010.2,K,A"), sentence("GPHDT,274.07,T")]) == []
    assert dec.skipped == Counter({"no time": 2})


def test_void_rmc_does_not_date_and_text_gga_is_held_until_rmc() -> None:
    dec = NmeaDecoder()
    assert dec.feed(sentence("GPRMC,123518,V,,,,,,,010180,,")) == []  # receiver clock, not to be trusted
    assert dec.feed(sentence(GGA.format(t="123519.25"))) == []  # held: no date yet
    assert dec.feed(sentence("GPVTG,084.4,T,,M,022.4,N,041.5,K,A")) == []  # held with its epoch (the GGA)
    assert dec.feed(sentence("GPHDT,90.0,T")) == []
    recs = dec.feed(sentence(RMC.format(t="123520.25", d="230394")))
    t0 = ns(datetime(1994, 3, 23, 12, 35, 19, 250000, tzinfo=UTC))
    fix, vtg, hdt, rmc = recs
    assert isinstance(fix, NmeaFix) and fix.t_ns == fix.fix_time_ns == t0
    assert fix.latitude_deg == pytest.approx(48 + 7.038 / 60) and fix.longitude_deg == pytest.approx(11 + 31 / 60)
    assert fix.altitude_m == pytest.approx(545.4 + 46.9)
    assert isinstance(vtg, NmeaVelocity) and vtg.t_ns == t0 and vtg.fix_time_ns == UNKNOWN_TIME
    assert vtg.speed_mps == pytest.approx(22.4 * 1852 / 3600) and vtg.course_rad == pytest.approx(math.radians(5.6))
    assert isinstance(hdt, NmeaHeading) and hdt.t_ns == t0 and hdt.heading_rad == pytest.approx(0.0)
    assert isinstance(rmc, NmeaVelocity) and rmc.t_ns == rmc.fix_time_ns == t0 + 1_000_000_000
    assert dec.skipped == Counter({"no fix": 1})


def test_zda_dates_held_gga() -> None:
    dec = NmeaDecoder()
    assert dec.feed(sentence(GGA.format(t="235959.50"))) == []
    (fix,) = dec.feed(sentence("GPZDA,000000.00,01,01,2025,00,00"))  # ZDA of the next second, after midnight
    assert fix.t_ns == ns(datetime(2024, 12, 31, 23, 59, 59, 500000, tzinfo=UTC))


def test_midnight_rollover() -> None:
    dec = NmeaDecoder()
    recs = feed_all(dec, [sentence(RMC.format(t="235959.00", d="311224")), sentence(GGA.format(t="235959.00")),
                          sentence(GGA.format(t="000000.00")), sentence(RMC.format(t="000000.00", d="010125")),
                          sentence(GGA.format(t="000001.00")), sentence(GGA.format(t="235959.90"))])
    new_year = ns(datetime(2025, 1, 1, tzinfo=UTC))
    assert [r.t_ns - new_year for r in recs] == [-10**9, -10**9, 0, 0, 10**9, -100_000_000]


def test_midnight_rollover_gga_only_after_one_rmc() -> None:
    """The date carries on from fix to fix: GGAs alone cross midnight (twice) after a single RMC."""
    dec = NmeaDecoder()
    times = ["230000", "235959", "060000", "120000", "180000", "000001"]
    recs = feed_all(dec, [sentence(RMC.format(t="225959", d="280224"))] + [sentence(GGA.format(t=t)) for t in times])
    days = [datetime.fromtimestamp(r.t_ns / 1e9, UTC).date() for r in of_type(recs, NmeaFix)]
    assert days == [date(2024, 2, 28)] * 2 + [date(2024, 2, 29)] * 3 + [date(2024, 3, 1)]


@pytest.mark.parametrize(("stamp", "expected"), [
    (datetime(2024, 5, 7, 0, 0, 1, tzinfo=UTC), datetime(2024, 5, 6, 23, 59, 59, tzinfo=UTC)),  # stamp after midnight
    (datetime(2024, 5, 6, 23, 59, 58, tzinfo=UTC), datetime(2024, 5, 6, 23, 59, 59, tzinfo=UTC)),
    (datetime(2024, 5, 6, 12, 0, 0, tzinfo=UTC), datetime(2024, 5, 6, 23, 59, 59, tzinfo=UTC)),  # 12 h: same day
])
def test_stamp_dates_gga_before_any_rmc(stamp: datetime, expected: datetime) -> None:
    dec = NmeaDecoder()
    (fix,) = dec.feed(sentence(GGA.format(t="235959")), stamp_ns=ns(stamp))
    assert isinstance(fix, NmeaFix)
    assert fix.t_ns == ns(stamp) and fix.fix_time_ns == ns(expected)
    (vtg,) = dec.feed(sentence("GPVTG,,T,,M,0.5,N,,K,A"), stamp_ns=ns(stamp) + 5)
    assert isinstance(vtg, NmeaVelocity)
    assert vtg.t_ns == ns(stamp) + 5 and vtg.fix_time_ns == UNKNOWN_TIME and math.isnan(vtg.course_rad)


def test_held_records_are_bounded() -> None:
    dec = NmeaDecoder()
    for i in range(MAX_HELD + 5):
        assert dec.feed(sentence(GGA.format(t=f"12{i // 60 % 60:02d}{i % 60:02d}"))) == []
    assert dec.skipped == Counter({"no date": 5})
    recs = dec.feed(sentence(RMC.format(t="130000", d="010624")))
    assert len(recs) == MAX_HELD + 1
    assert recs[0].t_ns == ns(datetime(2024, 6, 1, 12, 0, 5, tzinfo=UTC))  # the 5 oldest were dropped
    dec.feed(sentence(GGA.format(t="130001")))
    assert dec.flush() == [] and dec.skipped == Counter({"no date": 5})

    lost = NmeaDecoder()
    lost.feed(sentence(GGA.format(t="120000")))
    assert lost.flush() == [] and lost.skipped == Counter({"no date": 1})  # never dated


def test_a_capture_cut_inside_its_last_sentence_says_so(tmp_path: Path) -> None:
    """The real NEO-M8N capture cut inside its last sentence (a GGA): every record of the sentences before it, as
    from the whole file, and the broken one counted as cut off by the file's end (not as a sentence without
    checksum); the same capture without its final line end but whole reads as the whole file."""
    data = realdata("gpsd", "neo-m8n.log").read_bytes()
    whole = list(NmeaLogReader(realdata("gpsd", "neo-m8n.log")))
    cut = tmp_path / "cut.log"
    cut.write_bytes(data[:data.rindex(b"$GNGGA") + 30])
    reader = NmeaLogReader(cut)
    recs = list(reader)
    last_fix = max(r.fix_time_ns for r in of_type(whole, NmeaFix))
    assert recs == [r for r in whole if not (isinstance(r, NmeaFix) and r.fix_time_ns == last_fix)]
    assert reader.skipped["cut off by the file's end"] == 1 and "no checksum" not in reader.skipped
    unended = tmp_path / "unended.log"
    unended.write_bytes(data.rstrip(b"\r\n"))
    reader = NmeaLogReader(unended)
    assert list(reader) == whole and "cut off by the file's end" not in reader.skipped
    from autosar_cli.config import load_config
    from autosar_cli.ingest.pipeline import ingest

    said = ingest([], tmp_path / "d.h5", config=load_config(), nmea_logs=[cut], allow_partial=True).warnings
    assert f"{cut}: its last line is cut off by the file's end (a capture cut short); the sentence there skipped" \
           in said  # before, only the table's "cut off by the file's end 1"
    said = ingest([], tmp_path / "e.h5", config=load_config(), nmea_logs=[unended], allow_partial=True).warnings
    assert not any("cut off" in w for w in said)


def test_a_block_of_nul_bytes_in_a_capture_is_one_damage_warning_with_its_place(tmp_path: Path) -> None:
    """4 KiB of the real NEO-M8N capture zeroed (a card block never written): before, ingest said only "no checksum
    1" in its table. The reader now counts the damaged line, its bytes and where it starts; ingest warns with them.
    Every record of the lines outside the block is read as from the whole file."""
    from autosar_cli.config import load_config
    from autosar_cli.ingest.pipeline import ingest

    data = realdata("gpsd", "neo-m8n.log").read_bytes()
    at = 8518
    zeroed = tmp_path / "zeroed.log"
    zeroed.write_bytes(data[:at] + bytes(4096) + data[at + 4096:])
    line_start, line_end = data.rindex(b"\n", 0, at) + 1, data.index(b"\n", at + 4096) + 1
    reader = NmeaLogReader(zeroed)
    recs = list(reader)
    assert (reader.damaged_lines, reader.first_damage_byte, reader.damaged_bytes) == (
        1, line_start, line_end - line_start)
    kept = tmp_path / "kept.log"
    kept.write_bytes(data[:line_start] + data[line_end:])
    assert recs == list(NmeaLogReader(kept))
    whole = NmeaLogReader(realdata("gpsd", "neo-m8n.log"))
    list(whole)
    assert whole.damaged_lines == 0
    report = ingest([], tmp_path / "d.h5", config=load_config(), nmea_logs=[zeroed], allow_partial=True)
    assert f"{zeroed}: 1 damaged line(s), {line_end - line_start} bytes, skipped (a bad or no checksum, or bytes " \
           f"that are no sentence; the first at byte {line_start})" in report.warnings


def test_log_reader_comments_junk_and_joined_sentences(tmp_path: Path) -> None:
    gga, rmc = sentence(GGA.format(t="101010")), sentence(RMC.format(t="101010", d="150621"))
    path = tmp_path / "capture.nmea"
    path.write_bytes(b"# comment $GPGGA\n\n  \r\n" + gga.encode() + b"\r\n\xb5b\x01\x07\x00\xff" + rmc.encode()
                     + sentence("GPHDT,0.0,T").encode() + b"\n\x00\x01\x02\n")
    reader = NmeaLogReader(path)
    recs = list(reader)
    assert [type(r) for r in recs] == [NmeaFix, NmeaVelocity, NmeaHeading]
    assert {r.t_ns for r in recs} == {ns(datetime(2021, 6, 15, 10, 10, 10, tzinfo=UTC))}
    assert reader.skipped == Counter({"unparseable": 2})
    assert list(read_nmea_log(path)) == recs  # same records; a second iteration starts afresh
    assert list(reader) == recs and reader.skipped == Counter({"unparseable": 2})


def test_info_of_a_text_file_without_nmea_says_so() -> None:
    """OpenRadar's chirp.txt (complex samples, one per line) is taken for an NMEA capture by its name: `info` said
    "NMEA text" with no streams and exit 0, where ingest refuses it. It now refuses it as ingest does; a real NMEA
    capture (gpsd's, with unsupported sentences among the read ones) is summarised as before."""
    from typer.testing import CliRunner

    from autosar_cli.cli import app

    r = CliRunner().invoke(app, ["info", str(realdata("openradar", "chirp.txt"))])
    assert r.exit_code == 1 and "no NMEA 0183 sentence in this file" in r.stderr, r.output
    r = CliRunner().invoke(app, ["info", str(realdata("gpsd", "neo-m8n.log")), "--json"])
    assert r.exit_code == 0 and json.loads(r.stdout)["container"] == "NMEA text", r.output


def test_a_capture_whose_every_checksum_fails_is_called_damaged_not_empty(tmp_path: Path) -> None:
    """gpsd's capture with every sentence's checksum off by one bit: `info` and `ingest` said "no NMEA 0183
    sentence in this file", as of a file that holds none; they now say that none of its sentences could be read,
    how many failed how, and where the first is (a sentence whose checksum holds but whose fields do not parse:
    malformed)."""
    from typer.testing import CliRunner

    from autosar_cli.cli import app

    lines = realdata("gpsd", "neo-m8n.log").read_bytes().split(b"\n")
    flipped = [re.sub(rb"\*([0-9A-F]{2})", lambda m: b"*%02X" % (int(m.group(1), 16) ^ 1), line) for line in lines]
    capture = tmp_path / "flipped.nmea"
    capture.write_bytes(b"\n".join(flipped))
    n_sentences = sum(line.startswith(b"$") for line in lines)
    first = len(b"\n".join(lines[:next(i for i, line in enumerate(lines) if line.startswith(b"$"))])) + 1
    for args in (["info", str(capture)], ["ingest", "--nmea", str(capture), "-o", str(tmp_path / "d.h5")]):
        r = CliRunner().invoke(app, args)
        assert r.exit_code == 1 and r.stderr.count("\n") == 1, r.output
        assert (f"{capture}: none of its {n_sentences} NMEA 0183 sentences could be read "
                f"({n_sentences} bad checksum; the first damaged line at byte {first})") in r.stderr, r.stderr
    # sentences whose checksums hold but which are no sentence of NMEA 0183 count as sentences too
    malformed = tmp_path / "malformed.nmea"
    malformed.write_text("\n".join(sentence("GP!!!,123519") for _ in range(10)) + "\n")
    r = CliRunner().invoke(app, ["info", str(malformed)])
    assert r.exit_code == 1 and (f"{malformed}: none of its 10 NMEA 0183 sentences could be read (10 malformed; "
                                 "the first damaged line at byte 0)") in r.stderr, r.stderr
