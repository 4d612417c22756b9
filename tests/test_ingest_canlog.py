"""Tests of standalone CAN log ingest: real CANedge MDF4 recordings of a GNSS/IMU module, and round trips
through the formats python-can writes (ASC, BLF, TRC, candump -L)."""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import mmap
import random
import re
import struct
import subprocess
import sys
from collections import Counter
from collections.abc import Callable, Iterator
from datetime import UTC, datetime, timedelta
from functools import cache
from pathlib import Path
from typing import Any

import can
import numpy as np
import pytest
from asammdf import MDF
from cantools.database.can import Database

from autosar_cli.candb import check_frame, encode_frame, load_dbc
from autosar_cli.ingest.canlog import CAN_LOG_SUFFIXES, CanLogError, is_can_log, read_can_log
from autosar_cli.ingest.decoders import CanDecoder
from autosar_cli.ingest.mdf4_blocks import mdf4_cut
from autosar_cli.ingest.mdf4_layout import blocks
from autosar_cli.ingest.mdf4_shift import block_starts, shifted_links
from autosar_cli.ingest.mdf4_sorted import _sorted_groups, out_of_order
from autosar_cli.ingest.records import CanRecord
from autosar_cli.store.drive import DriveWriter
from tests.conftest import realdata

REPO = Path(__file__).resolve().parents[1]
PROJECT_DBC = REPO / "configs" / "autosar_giulia.dbc"
CSS = "css-electronics"
MF4_2022 = "2F6913DB_00000004_00000001.MF4"
MF4_2023_1 = "2F6913DB_00001089_00000001-63BEF5CD.MF4"
MF4_2023_2 = "2F6913DB_00001089_00000002-63BEFDF9.MF4"

# Facts of the real files, checked against asammdf and python-can (see test_real_mf4_*).
# name: (frames, frames on channel 1 (0x7xx diagnostics), on channel 2 (GNSS module), first t [s], last t [s])
MF4_FACTS = {
    MF4_2022: (5588, 221, 5367, 1641469561.9497, 1641469625.4197),
    MF4_2023_1: (4024, 1011, 3013, 1673458929.10395, 1673459099.6699),
    MF4_2023_2: (3587, 304, 3283, 1673459099.772, 1673459288.66955),
}
# Where the module was: the 2022 recording is 9 km north of the 2023 drives (not near 56.07 N).
MF4_PLACE = {MF4_2022: (56.1517, 10.1738), MF4_2023_1: (56.0707, 10.1604), MF4_2023_2: (56.0704, 10.1602)}
# gnss_pos / gnss_time frames: 1 Hz, each of them valid.
MF4_GNSS_FRAMES = {MF4_2022: 44, MF4_2023_1: 168, MF4_2023_2: 178}
# Median of (logger time - GNSS epoch in gnss_time) [s]: the 2023 logger clock lags GNSS time by ~29 s.
MF4_CLOCK_OFFSET = {MF4_2022: -0.1055, MF4_2023_1: -28.9028, MF4_2023_2: -28.8160}

T_2022 = datetime(2022, 1, 1, tzinfo=UTC).timestamp() * 1e9
T_2024 = datetime(2024, 1, 1, tzinfo=UTC).timestamp() * 1e9


@cache
def _real_records(name: str) -> tuple[CanRecord, ...]:
    """All records of a real MF4 file (read once per test session)."""
    return tuple(read_can_log(realdata(CSS, name)))


@cache
def _gnss_dbc() -> Database:
    db, warnings = load_dbc(realdata(CSS, "gnss.dbc"))
    assert warnings == ["gnss.dbc: 9 message names are given to several frame ids (gnss_pos 0x3 / 0x13; gnss_time "
                        "0x2 / 0x12; gnss_attitude 0x5 / 0x15 and 6 more): each id is its own stream, NAME_0xID, "
                        "which a CAN role names to pick one"]
    return db


def _decoded(name: str, message: str) -> list[tuple[int, dict[str, float]]]:
    """(t_ns, decoded physical values, choices as numbers) of a GNSS-module message, looked up by frame ID."""
    db = _gnss_dbc()
    out = []
    for rec in _real_records(name):
        if rec.channel != "2":
            continue
        try:
            msg = db.get_message_by_frame_id(rec.frame_id)
        except KeyError:
            continue  # 0x10 in the 2022 file is not in gnss.dbc
        if msg.name == message:
            values = msg.decode(rec.data, decode_choices=False)
            out.append((rec.t_ns, {k: float(v) for k, v in values.items()}))
    return out


# ---------------------------------------------------------------------------------------------------------
# Real CANedge MDF4 files


@pytest.mark.parametrize("name", sorted(MF4_FACTS))
def test_real_mf4_counts_and_absolute_times(name: str) -> None:
    path = realdata(CSS, name)
    frames, on_ch1, on_ch2, first_s, last_s = MF4_FACTS[name]
    records = _real_records(name)
    assert len(records) == frames
    with MDF(path) as mdf:  # asammdf's own count: cycles of the CAN data-frame channel groups
        cycles = sum(
            g.channel_group.cycles_nr for g in mdf.groups if any(c.name == "CAN_DataFrame" for c in g.channels)
        )
    assert cycles == frames
    assert Counter(r.channel for r in records) == {"1": on_ch1, "2": on_ch2}
    t = np.array([r.t_ns for r in records], dtype=np.int64)
    assert T_2022 <= t.min() and t.max() < T_2024  # absolute Unix times, not offsets from the start
    assert t[0] == pytest.approx(first_s * 1e9, abs=1e3)
    assert t[-1] == pytest.approx(last_s * 1e9, abs=1e3)
    assert np.all(np.diff(t) >= 0)  # all three files: 0 decreasing steps (python-can merges groups by time)
    assert all(not r.is_extended and not r.is_error and not r.is_remote and r.dlc == len(r.data) for r in records)
    ids = {r.frame_id for r in records if r.channel == "2"}
    assert ids == (set(range(17, 26)) if "1089" in name else set(range(1, 10)) | {0x10})
    assert all(0x700 <= r.frame_id <= 0x7FF for r in records if r.channel == "1")


def test_real_mf4_files_are_whole_record_by_record() -> None:
    """The three CANedge files are unfinalised (their last data block runs to the file's end): walked record by
    record (each record id's fixed length, or a VLSD record's own), each ends exactly at its last byte."""
    for name in MF4_FACTS:
        path = realdata(CSS, name)
        assert path.read_bytes()[:8] == b"UnFinMF " and mdf4_cut(path) is None


@pytest.mark.parametrize("fraction", [0.1, 0.5, 0.9])
def test_truncated_real_mf4_keeps_every_whole_frame_then_errs(tmp_path: Path, fraction: float) -> None:
    """A CANedge file cut short (its card pulled mid-write): asammdf alone ends early without a word, or stops
    at the frame the cut breaks and loses the ones before it (the 0.9 cut: 4000 frames, then an error). The
    frames before the cut are read, equal to the whole file's first ones and about as many as the bytes before
    the cut hold (its records are 13 and 23 bytes long, in pairs), then a one-line error names the cut."""
    whole = realdata(CSS, MF4_2022)
    data = whole.read_bytes()
    cut = tmp_path / "cut.MF4"
    cut.write_bytes(data[:int(len(data) * fraction)])
    reference = _real_records(MF4_2022)
    got: list[CanRecord] = []
    with pytest.raises(CanLogError) as info:
        for rec in read_can_log(cut):
            got.append(rec)
    records_start = data.index(b"##DT") + 24
    expected = len(reference) * (len(cut.read_bytes()) - records_start) / (len(data) - records_start)
    assert got == list(reference[:len(got)]) and abs(len(got) - expected) < 20
    message = str(info.value)
    assert "cut.MF4" in message and "truncated MDF4" in message and f"{len(got)} frames" in message
    assert "\n" not in message


def test_truncated_finalised_mf4_names_the_cut(tmp_path: Path) -> None:
    whole = tmp_path / "whole.mf4"
    _write_mf4(whole, _frames())
    assert whole.read_bytes()[:8] == b"MDF     " and mdf4_cut(whole) is None
    cut = tmp_path / "cut.mf4"
    cut.write_bytes(whole.read_bytes()[:whole.stat().st_size * 3 // 4])
    found = mdf4_cut(cut)
    assert found is not None and "byte" in found.reason
    with pytest.raises(CanLogError, match="cut.mf4.*cut short|cut.mf4: truncated MDF4"):
        list(read_can_log(cut))


def test_an_mf4_asammdf_cannot_open_is_one_line_and_no_traceback(tmp_path: Path) -> None:
    """asammdf prints the traceback of an error to stdout before it raises it: on a CANedge file cut inside its
    blocks, or one with 4 KiB pasted into it, that went to the terminal (and into --json's output) above our error.
    The CLI now says one line on stderr, led by what our block walk found (a cut) with the reader's own error after
    it, and nothing on stdout; the pasted file is now read whole, its damage a warning in the JSON summary."""
    from typer.testing import CliRunner

    from autosar_cli.cli import app

    data = realdata(CSS, MF4_2022).read_bytes()
    cut = tmp_path / "cut.MF4"
    cut.write_bytes(data[:11957])
    pasted = tmp_path / "pasted.MF4"  # inside a text block: its links moved, the block itself asammdf cannot read
    pasted.write_bytes(data[:1346] + data[10000:10000 + 4096] + data[1346:])

    def ingest(log: Path) -> Any:
        return CliRunner().invoke(app, ["ingest", "--can-log", str(log), "-o", str(tmp_path / f"{log.stem}.h5"),
                                        "--json", "--allow-partial", "--dbc", str(realdata(CSS, "gnss.dbc"))])
    r = ingest(cut)
    assert r.exit_code == 1 and r.stdout == "" and "Traceback" not in r.output
    lines = r.stderr.strip().splitlines()
    assert lines[-1].startswith(f"error: {cut}: truncated MDF4 log, no frame read: block header at byte 14608 cut "
                                "off (the reader: "), lines
    r = ingest(pasted)
    assert r.exit_code == 0 and "Traceback" not in r.output
    summary = json.loads(r.stdout)
    assert any(w.startswith(f"{pasted}: damaged MDF4 log: no block at byte 2496, where a link points (it reads "
                            "b'\\x00\\x00\\x00\\x00'): damaged there: 4096 bytes added before byte 5480: ")
               and w.endswith("; 5588 frames read") for w in summary["warnings"]), summary["warnings"]


def _read_until_error(log: Path) -> tuple[list[CanRecord], str]:
    """The frames read from ``log`` and the error its reader ends with."""
    got: list[CanRecord] = []
    with pytest.raises(CanLogError) as info:
        for rec in read_can_log(log):
            got.append(rec)
    return got, str(info.value)


def _read_damaged(path: Path, data: bytes | bytearray) -> tuple[list[CanRecord], str]:
    """``data`` written to ``path``, then :func:`_read_until_error` of it."""
    path.write_bytes(bytes(data))
    return _read_until_error(path)


def _in_order_within(got: list[CanRecord], reference: tuple[CanRecord, ...]) -> bool:
    """Whether ``got`` is ``reference`` with some frames left out, the rest in their order."""
    rest = iter(reference)
    return all(any(rec == ref for ref in rest) for rec in got)


@pytest.mark.parametrize("name, at, added, lost", [
    (MF4_2023_1, 27374, 4096, 0), (MF4_2023_1, 54154, 0, 4096), (MF4_2023_2, 41503, 0, 1000),
    (MF4_2023_2, 92625, 4096, 0), (MF4_2022, 3154, 0, 100), (MF4_2023_1, 27374, 13, 0)],
    ids=["4 KiB added", "4 KiB lost", "1000 bytes lost", "4 KiB added late", "100 bytes lost", "13 bytes added"])
def test_a_real_mf4_with_bytes_added_or_lost_before_its_data_reads_its_frames(tmp_path: Path, name: str, at: int,
                                                                               added: int, lost: int) -> None:
    """Bytes added to or lost from a CANedge file's blocks (before its data): every block after that place lies
    that many bytes off where the links say, and no frame was read ("no block at byte 106776, where a link
    points"). The blocks are found by their ids, the links moved by the one shift most of them agree on (not onto a
    block an intact link names): every frame read, none the undamaged file lacks, and the error says how many bytes
    and where. A count not a multiple of 8 moves the blocks off the 8-byte boundaries asammdf finds an unfinalised
    file's blocks on (100 bytes lost read no frame: "KeyError: b'##DG'"); the copy puts them back on theirs."""
    path = realdata(CSS, name)
    data = path.read_bytes()
    whole = list(read_can_log(path))
    damaged = tmp_path / name
    damaged.write_bytes(data[:at] + random.Random(at).randbytes(added) + data[at + lost:])
    got, message = _read_until_error(damaged)
    assert got == whole
    what = f"{added} bytes added" if added else f"{lost} bytes lost"
    assert f": {what} before byte " in message
    assert f"links moved by {added - lost:+d} to the blocks they name (" in message


def test_links_overwritten_past_any_file_are_damage_not_a_shift(tmp_path: Path) -> None:
    """64 bytes of 0xFF over two channel groups' blocks of a CANedge file: their links point past any file (2^64 -
    1). They are damage the mending steps over (both groups left out, every frame read), not links a shift moved
    (taken as one, a number past any int64 raised before the mending)."""
    data = realdata(CSS, MF4_2023_1).read_bytes()
    damaged = tmp_path / MF4_2023_1
    damaged.write_bytes(data[:8192] + b"\xff" * 64 + data[8192 + 64:])
    with open(damaged, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        assert shifted_links(buf) is None
    got, message = _read_until_error(damaged)
    assert got == list(_real_records(MF4_2023_1))
    assert "past any file: damaged there: 2 channel groups left out" in message


def test_a_shift_moves_no_link_onto_a_block_an_intact_link_names(tmp_path: Path) -> None:
    """512 bytes added inside a text block near the start of a CANedge file: the shift (+512) lands some of the
    links that find no block of their kind on blocks that intact links name (blocks before the place, which did not
    move: a run of channel blocks at one spacing). Those are not moved (moved, a copy's chains looped: 3 GB and
    minutes in asammdf). 42 links point where another block now lies: 29 of a kind they may not name (a source
    where their conversion lay), 13 of their own (the next in a run of channel groups); being past the place, they
    are moved too (left, asammdf read the frames' groups without their conversions and dropped them: 98 frames
    read). The block the bytes went into is marked torn; the groups it breaks are left out, the links to
    descriptions it broke unlinked: every frame read, each as the undamaged file has it."""
    data = realdata(CSS, MF4_2023_2).read_bytes()
    damaged = tmp_path / MF4_2023_2
    damaged.write_bytes(data[:1625] + bytes(512) + data[1625:])
    with open(damaged, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        shift = shifted_links(buf)
        starts = set(block_starts(buf))
        pointing_at_blocks = sum(1 for at, _ in shift.patches[:-1] if struct.unpack_from("<Q", buf, at)[0] in starts)
    assert shift is not None and (shift.by, shift.dangling, len(shift.patches), shift.torn) == (512, 1141, 1144, 1592)
    assert pointing_at_blocks == 42
    assert shift.patches[-1] == (1592, 0)  # the text block the bytes went into: its id cleared in the copy
    assert min(value for _, value in shift.patches[:-1]) >= 1625 + 512  # only onto blocks that moved
    got, message = _read_until_error(damaged)
    assert got == list(_real_records(MF4_2023_2))
    assert ": 512 bytes added before byte 2160: 1143 links moved by +512 to the blocks they name (1141 found no " \
           "block of their kind); the block at byte 1592 before them torn" in message


@pytest.mark.parametrize("name, at, damage, lost_at_most", [
    (MF4_2022, 100000, bytes(range(7, 71)), 5), (MF4_2022, 120000, bytes(4096), 125),
    (MF4_2023_1, 122570, bytes(4096), 260), (MF4_2023_2, 140000, bytes(range(100, 164)), 25)],
    ids=["64 bytes overwritten", "4 KiB zeroed", "2023: 4 KiB zeroed", "2023: 64 bytes overwritten"])
def test_a_real_mf4_damaged_inside_its_records_keeps_the_frames_around_it(tmp_path: Path, name: str, at: int,
                                                                           damage: bytes, lost_at_most: int) -> None:
    """Bytes overwritten or zeroed inside a CANedge file's records (not at its end): asammdf read on into them (an
    array-shape mismatch, a SystemError) or lost every frame; then only the frames before the damage were kept
    (2382 and 2939 of the 2022 file's 5588). The record walk finds the first record no group owns, keeps the
    frames before it less the last two (the 64 bytes parse as records for 16 bytes), and reads on from the second
    record of the first run of records that agree again: the 2022 layout's data offsets (each frame's fixed record
    points into its data bytes' records), the 2023 layout's times (most frames hold their data bytes inline). What
    is read is the whole file's frames less those of the damaged bytes, in order (the 2022 file: 5584 of 5588 with
    64 bytes overwritten); the error says damaged (not cut), where, and which bytes were left out."""
    data = realdata(CSS, name).read_bytes()
    log = tmp_path / "damaged.MF4"
    log.write_bytes(data[:at] + damage + data[at + len(damage):])
    got, message = _read_until_error(log)
    reference = _real_records(name)
    assert _in_order_within(got, reference) and len(reference) - lost_at_most <= len(got) < len(reference)
    assert message.startswith(f"{log}: damaged MDF4 log: record at byte ") and "cut" not in message
    left_out = message.split("damaged there, bytes ")[1].split(" left out")[0].split(" to ")
    assert int(left_out[0]) < at and int(left_out[1]) >= at + len(damage)
    assert message.endswith(f"the records after them read; {len(got)} frames read")


@pytest.mark.parametrize("name, at, source, lost_at_most", [(MF4_2022, 60000, 150000, 5),
                                                             (MF4_2023_1, 150000, 120000, 20)],
                         ids=["2022: from further on", "2023: from before"])
def test_records_pasted_from_elsewhere_in_an_mf4_are_not_read_twice(tmp_path: Path, name: str, at: int,
                                                                     source: int, lost_at_most: int) -> None:
    """4 KiB of a file's own records pasted into it elsewhere (a copy that went wrong): they parse and agree among
    themselves, but the 2022 layout's data offsets there lie beyond what the bytes left out can hold, and the 2023
    layout's times lie before the frames already read; so the walk reads on from the file's own records after
    them: every frame once, in order, less the few the pasted bytes broke."""
    data = realdata(CSS, name).read_bytes()
    log = tmp_path / "pasted.MF4"
    log.write_bytes(data[:at] + data[source:source + 4096] + data[at:])
    got, message = _read_until_error(log)
    reference = _real_records(name)
    assert _in_order_within(got, reference) and len(got) >= len(reference) - lost_at_most
    assert message.count("left out and the records after them read") == 1


# The 2022 file's frame at byte 50478: its 23-byte fixed record (its data offset at byte 50493), then its 13-byte
# data-bytes record at 50501 (a record id, a 4-byte length, 8 data bytes); the next frame's fixed record at 50514.
_FRAME, _DATA, _NEXT = 50478, 50501, 50514


@pytest.mark.parametrize("damage, kept, says", [
    (lambda d: d[:_FRAME] + d[_NEXT:], 5587, "the frame at byte 50478 and those after it point 12 bytes past their "
     "data-bytes records (12 bytes of data-bytes records lost before it): read at their own"),
    (lambda d: d[:_NEXT] + d[_FRAME:], 5588, "1 frame whose data offset points to data bytes another frame reads "
     "left out (byte 50514; the first's point to those of the frame at byte 50478)"),
    (lambda d: d[:_DATA] + d[_NEXT:], 5587, "1 frame with no data-bytes record before the next frame left out (byte "
     "50478); the frame at byte 50501 and those after it point 12 bytes past"),
    (lambda d: d[:_NEXT] + d[_DATA:_NEXT] + d[_NEXT:], 5588, "1 data-bytes record no frame points to left out (byte "
     "50514)"),
    (lambda d: d[:14668] + d[14632:], 5588, "1 frame whose data offset points to data bytes another frame reads left "
     "out (byte 14668; the first's point to those of the frame at byte 14632)")],
    ids=["a frame lost", "a frame written twice", "a data-bytes record lost", "a data-bytes record written twice",
         "the first frame written twice"])
def test_an_mf4_frame_lost_or_written_twice_keeps_every_other_frame(tmp_path: Path, damage: Callable[[bytes], bytes],
                                                                    kept: int, says: str) -> None:
    """One frame's records (or its data-bytes record alone) lost from the 2022 file's records, or written twice:
    every record still parses, but each frame after it points 12 bytes off its own data bytes, and asammdf read a
    length from inside a record there ("Unable to allocate 3.81 TiB"): no frame at all. Each frame is paired with
    the data-bytes record after it: a lost record's place is named and the frames after it read at their own
    records, a second copy (which points to data bytes a frame before it reads) left out; every intact frame read
    once, in order."""
    data = realdata(CSS, MF4_2022).read_bytes()
    got, message = _read_damaged(tmp_path / "damaged.MF4", damage(data))
    reference = _real_records(MF4_2022)
    assert len(got) == kept and len(set(got)) == kept and _in_order_within(got, reference)
    assert message.startswith(f"{tmp_path / 'damaged.MF4'}: damaged MDF4 log: {says}")
    assert message.endswith(f"; {kept} frames read") and "\n" not in message


@pytest.mark.parametrize("offset, says", [
    ("462e", "1 frame whose data offset points to data bytes another frame reads left out (byte 50514; the first's "
     "point to those of the frame at byte 50478)"),
    ("5e2e", "1 frame whose data offset points past or before its data-bytes record, the frames either side to "
     "their own (a damaged offset), left out (byte 50514; the first's by +12 bytes)")],
    ids=["to the frame before's", "to the frame after's"])
def test_an_mf4_frame_whose_data_offset_points_to_another_frames_bytes_is_left_out(tmp_path: Path, offset: str,
                                                                                   says: str) -> None:
    """The data offset of the 2022 file's frame at byte 50514 overwritten to point to the data-bytes record of the
    frame before it, or after it: asammdf read that frame's bytes as its own, without a word (the ingest's
    AngularRateZ row 770 held the frame before's value). A data-bytes record is read by one frame, and each
    frame's follows it: the frame whose offset disagrees is left out, named, and every other frame read."""
    data = bytearray(realdata(CSS, MF4_2022).read_bytes())
    data[_NEXT + 15:_NEXT + 17] = bytes.fromhex(offset)
    got, message = _read_damaged(tmp_path / "damaged.MF4", data)
    reference = _real_records(MF4_2022)
    assert len(got) == len(reference) - 1 and _in_order_within(got, reference)
    lost = Counter(reference) - Counter(got)
    assert [r.data for r in lost] == [bytes(data[_NEXT + 28:_NEXT + 36])]  # the frame's own data bytes
    assert message == f"{tmp_path / 'damaged.MF4'}: damaged MDF4 log: {says}; 5587 frames read"


def test_an_mf4_whose_records_never_agree_again_keeps_the_frames_before_the_damage(tmp_path: Path) -> None:
    """Random bytes from inside the 2022 file's records to its end: no run of records agrees again, so the frames
    before the damage less the last two are read and the error says from which byte on nothing was."""
    data = realdata(CSS, MF4_2022).read_bytes()
    log = tmp_path / "damaged.MF4"
    log.write_bytes(data[:130000] + random.Random(1).randbytes(len(data) - 130000))
    got, message = _read_until_error(log)
    assert got == list(_real_records(MF4_2022)[:len(got)]) and len(got) > 3000
    kept_to = int(message.split(" bytes on from byte ")[1].split()[0])
    assert kept_to < 130000 and message.endswith(f"not read; {len(got)} frames read before it")


@pytest.fixture(scope="module")
def finalised(tmp_path_factory: pytest.TempPathFactory) -> Callable[[str], Path]:
    """A real CANedge file finalised by asammdf (a function of its name, each written once): its frames sorted
    into groups of fixed-size records, each group's in one ``##DT`` block; the 2022 file's data bytes in an
    ``##SD`` block (22-byte records from byte 752, the SD block from byte 126680), the 2023 file's in the records."""
    root = tmp_path_factory.mktemp("finalised")

    @cache
    def write(name: str) -> Path:
        out = root / f"{Path(name).stem}.mf4"
        with MDF(realdata(CSS, name)) as mdf:
            mdf.save(out, overwrite=True, compression=0)
        return out
    return write


@pytest.mark.parametrize("name, at, damage, lost_at_most, block", [
    (MF4_2022, 20956, bytes(range(100, 164)), 7, 728), (MF4_2022, 88180, bytes(4096), 190, 728),
    (MF4_2022, 155290, b"\xff", 3, 728), (MF4_2023_1, 21610, bytes(4096), 260, 17008)],
    ids=["64 bytes in its records", "4 KiB zeroed in its records", "a data length's byte",
         "2023: 4 KiB zeroed near its start"])
def test_a_finalised_mf4_damaged_in_its_records_keeps_every_other_frame(tmp_path: Path,
                                                                         finalised: Callable[[str], Path],
                                                                         name: str, at: int, damage: bytes,
                                                                         lost_at_most: int, block: int) -> None:
    """A finalised MDF4 (one sorted group per kind of frame) damaged inside its records: asammdf read it in blocks
    of 1000 records until the damage broke one (an array-shape mismatch, a SystemError, a MemoryError for
    terabytes from a damaged length) and lost the records of that block and every one after; where a frame's data
    bytes stand in its record, it read zeroed records as frames at time 0. The records whose data offsets point to
    no whole data bytes in the SD block (or, the SD block holding the data in the records' order, do not follow on
    from their neighbours), and those whose times fall outside the group's longest run in time order, are left out
    with the records either side of them, through a copy whose data block holds the others: every other frame is
    read, in order, and the error says how many were left out and where the first was."""
    path = finalised(name)
    data = path.read_bytes()
    reference = _real_records(name)
    assert list(read_can_log(path)) == list(reference)  # undamaged: no check fires
    log = tmp_path / "damaged.mf4"
    log.write_bytes(data[:at] + damage + data[at + len(damage):])
    got, message = _read_until_error(log)
    assert _in_order_within(got, reference) and len(reference) - lost_at_most <= len(got) < len(reference)
    assert message.startswith(f"{log}: damaged MDF4 log: ") and f"records of the data block at byte {block} are " \
        f"damaged" in message
    assert message.endswith(f"({len(reference) - len(got)}); {len(got)} frames read")


@pytest.mark.parametrize("name, at, added, lost, kept, said", [
    (MF4_2023_1, 120004, 4096, 0, (4024, 4024), "4096 bytes added before byte "),
    (MF4_2023_1, 150000, 0, 4096, (4024, 4024), "4096 bytes lost before byte "),
    (MF4_2022, 89075, 0, 4096, (5588 - 200, 5588), "4096 bytes lost inside the data block at byte 728, found near"),
    (MF4_2022, 156372, 4096, 0, (5588 - 8, 5588), "4096 bytes added inside the data block at byte 126656, found"),
    (MF4_2022, 60000, 0, 4400, (5588 - 213, 5588), "4400 bytes lost inside the data block at byte 728, found"),
    (MF4_2022, 150004, 0, 4092, (5588 - 349, 5588), "4092 bytes lost inside the data block at byte 126656, found"),
    (MF4_2022, 169512, 0, 24, (5588 - 120, 5588 - 100), "24 bytes lost inside the data block at byte 126656, found"),
    (MF4_2023_1, 30004, 4096, 0, (1011, 1011), "(its data block at byte 17008 damaged)"),
    (MF4_2023_1, 20477, 1, 0, (4024 - 4, 4024), "1 bytes added inside the data block at byte 17008, found near"),
    (MF4_2023_1, 42315, 0, 4090, (4024 - 260, 4024), "4090 bytes lost inside the data block at byte 17008, found")],
    ids=["4 KiB added to its blocks", "4 KiB lost from its blocks", "4 KiB lost from its records",
         "4 KiB added to its records' data bytes", "200 records lost", "341 records' data bytes lost",
         "two records' data bytes lost",
         "2023: 4 KiB added to its records, checked by their times alone",
         "2023: a byte added to its time-checked records", "2023: 4090 bytes lost from its time-checked records"])
def test_a_finalised_mf4_with_bytes_added_or_lost_keeps_the_frames_they_spare(
        tmp_path: Path, finalised: Callable[[str], Path], name: str, at: int, added: int, lost: int,
        kept: tuple[int, int], said: str) -> None:
    """A finalised file (a CANedge file as asammdf writes it: its records, and the 2022 file's data bytes in an SD
    block, first; the blocks that describe them after) with some of its own bytes added, or bytes lost: every block
    after that place lies that many bytes off where the links say, and no frame was read ("no block at byte 65448,
    where a link points"). No data group's data link moves, so the shift is taken from the descriptions' links
    alone. Where the place lies among the blocks, every frame is read. Where it lies inside a data block (the
    last block a link names before those that moved: the bytes added hold copies of block headers, which no link
    names), the copy takes the bytes added out, or puts zeros in for those lost, where its records show the place
    (the fewest damaged records away from it), so that every block after it lies where its links say, and leaves
    out the records there: the frames before and after read (the group was left out, or its records read off their
    boundaries as frames the file lacks), also where the bytes lost are whole records or whole data bytes (the gap
    in the data offsets shows the place); where places apart are as good (24 bytes lost, two frames' data bytes of
    12: those between a place tried and the true one read their neighbours', which no check sees), the records
    between them are left out. Records checked by their times alone (the 2023 file's: records read off their
    boundaries may rise as true ones do; a byte added read 2796 frames the file lacks) are put back where the fewest
    records also break the bits the block's first and last records hold alike (a record read off its boundaries
    nearly always does); where the bytes are a whole number of records, the one at the place joins two records'
    bytes, which no check tells from a true one, so they are not put back: their group is left out, the other groups'
    1011 frames read, none the undamaged file lacks."""
    path = finalised(name)
    data = path.read_bytes()
    reference = _real_records(name)
    damaged = tmp_path / "damaged.mf4"
    # added: a copy of some of the 2023 file's blocks (headers in it), or the 2022 file's records
    damaged.write_bytes(data[:at] + data[70004:70004 + added] + data[at + lost:])
    got, message = _read_until_error(damaged)
    assert _in_order_within(got, reference) and kept[0] <= len(got) <= kept[1]
    assert said in message and message.endswith(f"; {len(got)} frames read")
    with open(damaged, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        shift = shifted_links(buf)
    if shift is not None and shift.data_block is not None:  # put back: the records at the place left out whatever
        at, _ = shift.inserted                                # the checks say (in the records, the one it lies in)
        assert shift.holes and (shift.data_block != 728 or any(a <= at < b for a, b in shift.holes))


def test_zeroed_stamps_outnumbering_the_whole_ones_are_the_damage() -> None:
    """A group's last 167 records zeroed after 80 whole ones (4 KiB over the finalised 2023 file's second data
    block): the longest run that did not fall was the zeros', so the 80 were left out and the 167 read as frames
    at the recording's start. A run of equal times counts once; equal stamps beside a whole one stay."""
    times = np.r_[np.arange(1, 81) * 1000.0, np.zeros(167)]
    flagged = out_of_order(times)
    assert not flagged[:80].any() and flagged[80:].all()
    pairs = np.repeat(np.arange(1, 101) * 1000.0, 2)  # frames logged in pairs, one stamp each
    pairs[101] = 0.0
    assert np.flatnonzero(out_of_order(pairs)).tolist() == [101]


def test_a_finalised_mf4_frame_stamped_a_step_early_is_not_damage(tmp_path: Path,
                                                                    finalised: Callable[[str], Path]) -> None:
    """Two neighbouring records of the finalised 2022 file with their times swapped (a writer that stamps a frame
    a step early: its time falls by one step): not damage, every frame read, no error."""
    data = bytearray(finalised(MF4_2022).read_bytes())
    first = 752 + 22 * 3000  # record 3000's time, an 8-byte float at its start
    a, b = data[first:first + 8], data[first + 22:first + 30]
    data[first:first + 8], data[first + 22:first + 30] = b, a
    log = tmp_path / "early.mf4"
    log.write_bytes(bytes(data))
    got = list(read_can_log(log))
    assert len(got) == 5588 and sorted(r.t_ns for r in got) == sorted(r.t_ns for r in _real_records(MF4_2022))


def test_a_finalised_mf4_whose_group_claims_more_records_than_it_holds(tmp_path: Path,
                                                                        finalised: Callable[[str], Path]) -> None:
    """A group's record count damaged upwards: asammdf read every record its block holds and then failed with an
    error of its own ("IndexError: index 0 is out of bounds for axis 0 with size 0"). Now the copy's count is the
    block's, and the error says what the group claimed."""
    data = bytearray(finalised(MF4_2022).read_bytes())
    with open(finalised(MF4_2022), "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        cycles_at = next(cg_data + 8 for cg_data, *_ in _sorted_groups(buf, list(blocks(buf))))
    struct.pack_into("<Q", data, cycles_at, 5588 + 700)
    log = tmp_path / "claims.mf4"
    log.write_bytes(bytes(data))
    got, message = _read_until_error(log)
    assert got == list(_real_records(MF4_2022))
    assert message == (f"{log}: damaged MDF4 log: the group of the data block at byte 728 says it has 6288 records, "
                       f"the block holds 5588; 5588 frames read")


@pytest.mark.parametrize("at, says, then", [
    (88, "a link points to byte 9223372036854775807, past any file: damaged there",
     "the data groups' chain broken at byte 9223372036854775807, 1 found again after it; 5588 frames read"),
    (5352 + 8, "its ##CG block at byte 5352 runs past the end (9223372036854775807 bytes)", None)],
    ids=["a link", "a block's length"])
def test_an_mf4_link_or_length_past_any_file_is_damage_not_a_cut(tmp_path: Path, at: int, says: str,
                                                                 then: str | None) -> None:
    """A link or block length damaged to a value no file reaches (over 2^40 bytes) was reported as the file cut
    short ("truncated ... block header at byte 9520860662089567504 cut off", the fault campaign's): it is damage.
    The header's link to its one data group damaged, that group is found again by its block and read whole; the
    block of the group that holds the frames damaged, none is read."""
    data = bytearray(realdata(CSS, MF4_2022).read_bytes())
    struct.pack_into("<Q", data, at, (1 << 63) - 1)
    log = tmp_path / "damaged.MF4"
    log.write_bytes(bytes(data))
    got, message = _read_until_error(log)
    if then is None:
        assert got == [] and message.startswith(f"{log}: damaged MDF4 log, no frame read: {says} (the reader: ")
    else:
        assert got == list(_real_records(MF4_2022)) and message == f"{log}: damaged MDF4 log: {says}: {then}"


@pytest.mark.parametrize("name, at, damage, says", [
    (MF4_2023_1, 77824, bytes(4096), "no block at byte 78456, where a link points (it reads b'\\x00\\x00\\x00\\x00'): "
     "damaged there: 3 channel groups left out, their blocks damaged (at bytes 13320, 13472, 13632)"),
    (MF4_2023_1, 16281, bytes(range(7, 71)), "no block at byte 16312, where a link points (it reads b\"&'()\"): "
     "damaged there: the channel groups' chain broken at byte 16312, 5 found again after it"),
    (MF4_2022, 9000, bytes(range(7, 71)), "no block at byte 9008, where a link points (it reads "
     "b'\\x0f\\x10\\x11\\x12'): damaged there: 1 channel group left out, its blocks damaged (at byte 5664)")],
    ids=["2023: 4 KiB zeroed in its channels", "2023: a group's block overwritten", "2022: a channel overwritten"])
def test_an_mf4_whose_damaged_blocks_describe_empty_groups_reads_every_frame(tmp_path: Path, name: str, at: int,
                                                                            damage: bytes, says: str) -> None:
    """A CANedge file describes more groups than it records into (the 2023 files 73, three holding frames; the
    2022 file 9, two): damage to the blocks of the others (their channels, or a group's own block, which breaks the
    chain of those after it) lost the whole file ("damaged MDF4 log, no frame read"). The damaged groups are left
    out of a copy's chain, those after a break found again by their blocks' ids: every frame is read."""
    data = realdata(CSS, name).read_bytes()
    log = tmp_path / "damaged.MF4"
    log.write_bytes(data[:at] + damage + data[at + len(damage):])
    got, message = _read_until_error(log)
    assert got == list(_real_records(name))
    assert message == f"{log}: damaged MDF4 log: {says}; {len(got)} frames read"


_ISO_FD_TABLE = struct.pack("<32d", *(v for k, n in enumerate((0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64))
                                    for v in (k, n)))


@pytest.mark.parametrize("name, final", [(MF4_2023_1, False), (MF4_2023_2, True)], ids=["2023", "2023 finalised"])
def test_an_mf4_whose_dlc_table_is_damaged_reads_each_frame_with_its_own_bytes(
        tmp_path: Path, finalised: Callable[[str], Path], name: str, final: bool) -> None:
    """A CANedge's DataLength channel is the frame's DLC through a value-to-value table (ISO 11898-1's: 0-8, 12, 16
    ... 64). Two of its values overwritten (DLC 1 read as 5 bytes, DLC 4 as 6) read every frame of those DLCs with
    bytes of its data field that are no part of it, without a word; the reader's copy gets the standard's table
    back and every frame is read as it was, with the damage named."""
    data = (finalised(name) if final else realdata(CSS, name)).read_bytes()
    table = data.index(_ISO_FD_TABLE)
    assert data.count(_ISO_FD_TABLE) == 1
    damaged = bytearray(data)
    struct.pack_into("<d", damaged, table + 8 * 3, 5.0)  # DLC 1's length
    struct.pack_into("<d", damaged, table + 8 * 9, 6.0)  # DLC 4's
    log = tmp_path / "damaged.MF4"
    log.write_bytes(damaged)
    got, message = _read_until_error(log)
    whole = list(read_can_log(finalised(name))) if final else list(_real_records(name))
    assert got == whole
    assert sum(1 for r in whole if r.dlc in (1, 4)) > 100  # frames the damage reached
    block = table - 80  # the ##CC block: 24 header bytes, 4 links, 24 bytes before its values (type ... range)
    assert data[block:block + 4] == b"##CC"
    assert message == (f"{log}: damaged MDF4 log: the DLC-to-length table of its DataLength channel (conversion "
                       f"block at byte {block}) damaged (DLC 1 read as 5 bytes, DLC 4 read as 6 bytes): read with "
                       f"ISO 11898-1's; {len(got)} frames read")


def _cc_table(pairs: list[tuple[float, float]], count: int | None = None) -> bytes:
    """A ##CC block of type 5 (value to value) at byte 0 holding ``pairs``; ``count``: the value count it says."""
    fixed = struct.pack("<BBHHHdd", 5, 0, 0, 0, 2 * len(pairs) if count is None else count, 0.0, 0.0)
    values = struct.pack(f"<{2 * len(pairs)}d", *(v for pair in pairs for v in pair))
    body = struct.pack("<4Q", 0, 0, 0, 0) + fixed + values
    return struct.pack("<4s4xQQ", b"##CC", 24 + len(body), 4) + body


@pytest.mark.parametrize("pairs, count, wrong", [
    ([(k, min(k, 8)) for k in range(16)], None, None),  # a classic logger's table: DLC 9-15 carry 8 bytes
    ([(k, k) for k in range(9)], None, None),  # DLC 0-8 only
    ([(k, (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)[k]) for k in range(16)], None, None),
    ([(k, min(k, 8)) for k in range(15)] + [(15, float("nan"))], None, [(15, 8.0)]),
    ([(k, k) for k in range(9)], 12, []),
    ([(k, k) for k in range(4)] + [(4.5, 4)] + [(k, k) for k in range(5, 9)], None, [(4, 4.0)])],
    ids=["classic", "0-8", "CAN FD", "a NaN in a classic table", "its count", "a key"])
def test_a_dlc_table_is_judged_by_iso_11898_1(pairs: list[tuple[float, float]], count: int | None,
                                              wrong: list[tuple[int, float]] | None) -> None:
    from autosar_cli.ingest.mdf4_dlc import _judged_table

    cc = _cc_table(pairs, count)
    judged = _judged_table(cc, 0)  # type: ignore[arg-type]
    if wrong is None:
        assert judged is None
        return
    assert judged is not None
    mended = bytearray(cc)
    for at, value in judged[0]:
        mended[at:at + 8] = value.to_bytes(8, "little")
    assert _judged_table(bytes(mended), 0) is None  # type: ignore[arg-type]
    got = struct.unpack_from(f"<{2 * len(pairs)}d", mended, 80)
    assert [(int(k), n) for k, n in zip(got[0::2], got[1::2], strict=True)] == [(k, _n(k, pairs)) for k in
                                                                               range(len(pairs))]
    assert struct.unpack_from("<H", mended, 62)[0] == 2 * len(pairs)
    for k, n in wrong:
        assert (got[2 * k], got[2 * k + 1]) == (k, n)


def _n(k: int, pairs: list[tuple[float, float]]) -> float:
    """The standard's length of DLC ``k`` in the convention of the test table ``pairs`` (classic where 15 is 8)."""
    fd = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)
    classic = len(pairs) == 16 and pairs[9][1] == 8
    return float(min(k, 8) if classic else fd[k])


def test_an_mf4_group_left_out_with_its_frames_keeps_the_other_groups(tmp_path: Path) -> None:
    """4 KiB zeroed across the channels of four of the 2023 file's groups, one of them holding 764 frames: its
    records, whose size no intact block gives, are damage the record walk reads past; the other groups' frames are
    read, in order, and the error names the first places and counts the others."""
    data = realdata(CSS, MF4_2023_1).read_bytes()
    log = tmp_path / "damaged.MF4"
    log.write_bytes(data[:40960] + bytes(4096) + data[40960 + 4096:])
    got, message = _read_until_error(log)
    reference = _real_records(MF4_2023_1)
    assert _in_order_within(got, reference) and len(got) == 3005  # of 4024: the group's 764 and those beside them
    assert message.startswith(f"{log}: damaged MDF4 log: no block at byte 41976, where a link points (it reads "
                              "b'\\x00\\x00\\x00\\x00'): damaged there: 4 channel groups left out, their blocks "
                              "damaged (at bytes 9376, 9520, 9664 ...); record at byte 118377 has an unknown record id")
    assert "; 72 more places damaged as these; " in message and message.endswith("; 3005 frames read")


def test_a_link_count_no_file_holds_is_damage_not_a_cut(tmp_path: Path) -> None:
    """64 bytes over a channel block of the 2022 file's frame group, its link count among them: it was read as the
    file cut inside that block's links ("truncated MDF4 log"). It is damage; the group holding every frame is left
    out, so none is read, and the error says so."""
    data = realdata(CSS, MF4_2022).read_bytes()
    log = tmp_path / "damaged.MF4"
    log.write_bytes(data[:6300] + bytes(range(7, 71)) + data[6300 + 64:])
    got, message = _read_until_error(log)
    assert got == [] and "truncated" not in message
    assert message.startswith(f"{log}: damaged MDF4 log: ##CN block at byte 6288 says it has 1301839424133073931 "
                              "links, more than any file holds: damaged there: 1 channel group left out")


@pytest.mark.parametrize("name, at, says", [
    (MF4_2023_1, 120832, "no block at byte 122680, where a link points (it reads b'\\x00\\x00\\x00\\x00'): damaged "
     "there: 2 channel groups (and the 2 data groups that held them) left out, their blocks damaged (at bytes 122680, "
     "124856)"),
    (MF4_2022, 196000, "no block at byte 197096, where a link points (it reads b'\\x00\\x00\\x00\\x00'): damaged "
     "there: 3 channel groups (and the 3 data groups that held them) left out, their blocks damaged (at bytes "
     "197096, 199752, 201520); 8 links to damaged blocks no record needs (comments, sources, names) unlinked")],
    ids=["2023", "2022"])
def test_a_finalised_mf4_whose_damaged_blocks_describe_empty_groups_reads_every_frame(
        tmp_path: Path, finalised: Callable[[str], Path], name: str, at: int, says: str) -> None:
    """A finalised file keeps its blocks after its data, each group in a data group of its own: 4 KiB zeroed over
    the blocks of groups without frames lost the whole file. Their data groups are left out of a copy's chain:
    every frame is read."""
    data = finalised(name).read_bytes()
    log = tmp_path / "damaged.mf4"
    log.write_bytes(data[:at] + bytes(4096) + data[at + 4096:])
    got, message = _read_until_error(log)
    assert got == list(_real_records(name))
    assert message == f"{log}: damaged MDF4 log: {says}; {len(got)} frames read"


def test_a_group_whose_data_bytes_lie_in_a_damaged_group_is_left_out_with_it(tmp_path: Path) -> None:
    """The 2022 file's frames hold their data bytes in a group of their own (variable-length records): that group's
    link to its channels damaged, it is left out, and the frames' group with it (asammdf read no frame from a copy
    that kept it: "Wrong signal data block refence"); nothing is read, and the error says which groups."""
    data = bytearray(realdata(CSS, MF4_2022).read_bytes())
    struct.pack_into("<Q", data, 5456 + 24 + 1 * 8, 0x0123456789AB)
    log = tmp_path / "damaged.MF4"
    log.write_bytes(bytes(data))
    got, message = _read_until_error(log)
    assert got == [] and message.startswith(
        f"{log}: damaged MDF4 log: a link points to byte 1250999896491, past any file: damaged there: 2 channel "
        "groups left out, their blocks damaged (at bytes 5352, 5456); record at byte 14632 has an unknown record id")


def test_a_block_whose_descriptive_link_is_garbage_is_damaged_with_its_group(tmp_path: Path) -> None:
    """64 bytes overwritten over a channel block of a group without frames: its comment link and its data fields
    (bit count, data type). The link points past any file, so the block is damaged, not only the comment it
    named: its group is left out and every frame read (unlinking the comment alone kept the group, and asammdf
    failed on its fields: "data type '<u167164795' not understood", no frame read)."""
    data = bytearray(realdata(CSS, MF4_2023_1).read_bytes())
    data[53248:53312] = bytes(range(7, 71))  # the channel block at byte 53176: link 7 and the fields after it
    log = tmp_path / "damaged.MF4"
    got, message = _read_damaged(log, data)
    assert got == list(_real_records(MF4_2023_1))
    assert message.endswith("damaged there: 1 channel group left out, its blocks damaged (at byte 10528); "
                            "4024 frames read")


def test_a_data_groups_garbage_comment_link_is_unlinked(tmp_path: Path, finalised: Callable[[str], Path]) -> None:
    """A data group's comment link, and the header's links (history, hierarchy, attachments, events, comment), lead
    to nothing a record needs: whatever is damaged behind one, the link itself is unlinked (kept, the copy still
    reached the garbage and asammdf read no frame: "Incomplete block ... exceeds the file size")."""
    data = bytearray(finalised(MF4_2023_1).read_bytes())
    first_dg = struct.unpack_from("<Q", data, 64 + 24)[0]
    struct.pack_into("<Q", data, first_dg + 24 + 3 * 8, 0x7B626A5D7D6F9934)
    log = tmp_path / "damaged.mf4"
    got, message = _read_damaged(log, data)
    assert got == list(_real_records(MF4_2023_1))
    assert message.endswith("past any file: damaged there: 1 link to damaged blocks no record needs (comments, "
                            "sources, names) unlinked; 4024 frames read")


@pytest.mark.parametrize("name, at, damage, links", [
    (MF4_2022, 5456 + 24 + 5 * 8, struct.pack("<Q", 5464), 1), (MF4_2022, 5080, bytes(56), 5),
    (MF4_2022, 2496, bytes(822), 1), (MF4_2023_1, 3728, bytes(649), 3)],
    ids=["the data bytes' group's comment link into its own block", "a source block five groups name",
         "the file's comment",
         "2023: the sources' comment"])
def test_a_damaged_block_no_record_needs_is_unlinked_and_its_groups_kept(tmp_path: Path, name: str, at: int,
                                                                          damage: bytes, links: int) -> None:
    """A comment, a source, a name of the acquisition: asammdf reads them, none is needed for a record. Damaged,
    the group that names it was left out with its frames (the 2023 source's comment: 51 groups and every frame,
    the records of the groups left out then unknown to the record walk); now the links to it are unlinked in the
    reader's copy and every frame is read. (A link that points past the file or off a block's alignment is damaged
    itself, and its block with it: that group is left out, as the test above shows.)"""
    data = bytearray(realdata(CSS, name).read_bytes())
    data[at:at + len(damage)] = damage
    log = tmp_path / "damaged.MF4"
    got, message = _read_damaged(log, data)
    assert got == list(_real_records(name))
    said = "link" if links == 1 else "links"
    assert message.endswith(f"damaged there: {links} {said} to damaged blocks no record needs (comments, sources, "
                            f"names) unlinked; {len(got)} frames read")


def test_a_failed_mf4_open_leaves_no_half_built_reader_to_the_garbage_collector(tmp_path: Path) -> None:
    """asammdf leaves the MDF4 object of a failed open half built, its __del__ raising; the error's frames held it
    until the garbage collector ran that __del__ at some later moment, which inside compile() (numpy parsing the
    next file's dtypes) made CPython 3.11 fail a whole file ("SystemError: AST constructor recursion depth
    mismatch"), and pytest warn. It is freed when the open fails."""
    import gc

    from asammdf.blocks.mdf_v4 import MDF4

    log = tmp_path / "cut.MF4"
    log.write_bytes(realdata(CSS, MF4_2022).read_bytes()[:11957])
    with pytest.raises(CanLogError, match="truncated MDF4 log, no frame read") as info:
        list(read_can_log(log))
    half_built = [o for o in gc.get_referrers(MDF4) if isinstance(o, MDF4) and not hasattr(o, "_file")]
    assert info.value.__cause__ is not None and half_built == []


def test_a_frame_whose_damaged_id_no_frame_can_have_is_warned_of(tmp_path: Path) -> None:
    """3 bytes of a frame's id in the real 2022 CANedge file overwritten (a fault campaign trial's, less its bytes
    in the stamp): its id reads 1614028 on a standard frame, which no standard frame can have (0x7FF at most).
    Before, it was one more unknown id in the CAN counts; now it is skipped with a warning, and the drive is the
    whole file's less that frame."""
    from autosar_cli.config import load_config
    from autosar_cli.ingest.pipeline import ingest

    data = realdata(CSS, MF4_2022).read_bytes()
    log = tmp_path / "damaged.MF4"
    log.write_bytes(data[:38925] + bytes.fromhex("6406c5") + data[38928:])
    damaged = list(read_can_log(log))
    changed = [(a, b) for a, b in zip(_real_records(MF4_2022), damaged, strict=True) if a != b]
    assert len(changed) == 1 and changed[0][1].frame_id == 1614028 and not changed[0][1].is_extended
    config = load_config(REPO / "configs" / "examples" / "css_canedge_gnss.toml")
    report = ingest([], tmp_path / "d.h5", config=config, dbc=realdata(CSS, "gnss.dbc"), can_logs=[log],
                    allow_partial=True)
    assert report.can["impossible_ids"] == 1 and "0x18A0CC" not in report.can["unknown_ids"]
    assert "1 CAN frames with an id no frame of theirs can have (a standard id over 0x7FF) skipped (damaged " \
           "data?)" in report.warnings


@pytest.mark.parametrize("name, at, damage", [(MF4_2022, 38920, bytes.fromhex("45d55f1abe6406c5")),
                                              (MF4_2023_1, 161711, bytes(8))],
                         ids=["2022: a stamp's high bytes", "2023: 8 bytes zeroed"])
def test_an_mf4_frame_whose_stamp_falls_out_of_its_groups_order_is_left_out(tmp_path: Path, name: str, at: int,
                                                                            damage: bytes) -> None:
    """Bytes of a frame's stamp overwritten inside a CANedge file's records (fault campaign trials': they parse, so
    the walk saw nothing and the frame went into the drive at the recording's start, or at time 0). Each group's
    frames are in time order (checked on the three real files); a stamp far out of it is damage: that frame and
    those either side are left out, every other frame read, and the error says so."""
    data = realdata(CSS, name).read_bytes()
    log = tmp_path / "damaged.MF4"
    log.write_bytes(data[:at] + damage + data[at + len(damage):])
    got, message = _read_until_error(log)
    reference = _real_records(name)
    assert _in_order_within(got, reference) and len(reference) - 4 <= len(got) < len(reference)
    assert "1 of the records read have a time out of their group's order (a damaged stamp; the first at byte " \
        in message and message.endswith(f"their frames and those either side left out; {len(got)} frames read")


def test_a_can_log_error_names_the_users_file_not_a_cut_copy(tmp_path: Path) -> None:
    """A text log whose last line is cut is read from a copy up to its last whole line; what is wrong with it
    names the file the user gave."""
    log = tmp_path / "random.log"
    log.write_bytes(b"\x8c\x10garbage that is no candump line\nand a cut las")
    with pytest.raises(CanLogError, match=f"^{log}: not a candump -L log"):
        list(read_can_log(log))


def test_real_mf4_suffix_and_streaming() -> None:
    path = realdata(CSS, MF4_2023_2)
    assert path.suffix == ".MF4" and is_can_log(path)
    it = read_can_log(path)
    assert isinstance(it, Iterator) and not isinstance(it, list | tuple)
    first = next(it)
    it.close()  # closes the reader early
    assert first == _real_records(MF4_2023_2)[0]
    assert first.frame_id == 25 and first.channel == "2" and first.data.hex() == "fb13d0c9ff01d07f"


def test_gnss_dbc_duplicate_names_resolve_by_frame_id() -> None:
    db = _gnss_dbc()
    assert len(db.messages) == 18  # 2 x 9; cantools drops VECTOR__INDEPENDENT_SIG_MSG
    for low in range(1, 10):
        a, b = db.get_message_by_frame_id(low), db.get_message_by_frame_id(low + 16)
        assert a.name == b.name and [s.name for s in a.signals] == [s.name for s in b.signals]
    assert db.get_message_by_frame_id(3).name == db.get_message_by_frame_id(19).name == "gnss_pos"


@pytest.mark.parametrize("name", sorted(MF4_FACTS))
def test_real_gnss_positions(name: str) -> None:
    positions = _decoded(name, "gnss_pos")
    valid = [v for _, v in positions if v["PositionValid"] == 1]
    assert len(valid) == len(positions) == MF4_GNSS_FRAMES[name]
    lat0, lon0 = MF4_PLACE[name]
    for v in valid:
        assert abs(v["Latitude"] - lat0) < 0.05 and abs(v["Longitude"] - lon0) < 0.05
    assert abs(np.mean([v["Latitude"] for v in valid]) - lat0) < 2e-4
    assert abs(np.mean([v["Longitude"] for v in valid]) - lon0) < 2e-4


def test_real_gnss_pos_by_hand() -> None:
    """First gnss_pos frame of the first 2023 file, decoded from its bytes per gnss.dbc's Intel layout."""
    rec = next(r for r in _real_records(MF4_2023_1) if r.channel == "2" and r.frame_id == 19)
    assert rec.data.hex() == "39b769f1adb36a0d"
    raw = int.from_bytes(rec.data, "little")  # @1 = little endian: start bit counts from bit 0 of byte 0

    def field(start: int, length: int) -> int:
        return (raw >> start) & ((1 << length) - 1)

    valid, lat_raw, lon_raw, accuracy = field(0, 1), field(1, 28), field(29, 29), field(58, 6)
    assert (valid, lat_raw, lon_raw, accuracy) == (1, 146_070_428, 190_160_239, 3)
    lat, lon = lat_raw * 1e-6 - 90, lon_raw * 1e-6 - 180  # (1E-006,-90) and (1E-006,-180)
    assert lat == pytest.approx(56.070428, abs=1e-9) and lon == pytest.approx(10.160239, abs=1e-9)
    decoded = _gnss_dbc().get_message_by_frame_id(rec.frame_id).decode(rec.data, decode_choices=False)
    assert decoded["PositionValid"] == valid and decoded["PositionAccuracy"] == accuracy
    assert decoded["Latitude"] == pytest.approx(lat, abs=1e-12)
    assert decoded["Longitude"] == pytest.approx(lon, abs=1e-12)


@pytest.mark.parametrize("name", sorted(MF4_FACTS))
def test_real_logger_clock_against_gnss_time(name: str) -> None:
    """gnss_time carries the GNSS epoch: logger times are absolute, off by the logger's clock error."""
    epochs = _decoded(name, "gnss_time")
    assert len(epochs) == MF4_GNSS_FRAMES[name]
    offsets = np.array([t / 1e9 - v["Epoch"] for t, v in epochs if v["TimeValid"] == 1])
    assert np.median(offsets) == pytest.approx(MF4_CLOCK_OFFSET[name], abs=0.01)
    assert np.ptp(offsets) < 0.7  # jitter of the 1 Hz message, no jumps


def _speed_and_track(name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Valid gnss_speed (t [s], Speed), and speed from consecutive valid positions at mid times."""
    sp = np.array([(t / 1e9, v["Speed"]) for t, v in _decoded(name, "gnss_speed") if v["SpeedValid"] == 1])
    pos = np.array(
        [(t / 1e9, v["Latitude"], v["Longitude"]) for t, v in _decoded(name, "gnss_pos") if v["PositionValid"] == 1]
    )
    r_earth = 6_371_000.0
    north = np.diff(np.radians(pos[:, 1])) * r_earth
    east = np.diff(np.radians(pos[:, 2])) * r_earth * math.cos(math.radians(pos[0, 1]))
    steps = np.hypot(north, east)
    track = np.column_stack([0.5 * (pos[1:, 0] + pos[:-1, 0]), steps / np.diff(pos[:, 0]), steps])
    return sp, track, pos


def test_real_gnss_speed_matches_positions() -> None:
    """2023 drive: Speed (max 7.449 m/s) agrees with the speed between consecutive decoded positions."""
    sp, track, _ = _speed_and_track(MF4_2023_1)
    assert sp[:, 1].max() == pytest.approx(7.449, abs=1e-9)
    speed_at = np.interp(track[:, 0], sp[:, 0], sp[:, 1])
    moving = speed_at > 1.0
    assert moving.sum() >= 50
    assert np.median(np.abs(track[moving, 1] - speed_at[moving])) < 0.1
    assert np.abs(track[moving, 1] - speed_at[moving]).max() < 0.5
    path = track[:, 2].sum()  # 249.4 m from positions vs 246.5 m integrated speed
    assert np.trapezoid(sp[:, 1], sp[:, 0]) == pytest.approx(path, rel=0.03)
    assert path == pytest.approx(249.4, abs=0.5)


def test_real_gnss_speed_other_files() -> None:
    """The second 2023 file peaks at 6.367 m/s ("about 6.4"); the 2022 file is a module standing still."""
    sp2, _, _ = _speed_and_track(MF4_2023_2)
    assert sp2[:, 1].max() == pytest.approx(6.367, abs=1e-9)
    sp0, _, pos0 = _speed_and_track(MF4_2022)
    assert sp0[:, 1].max() < 0.5
    spread = (np.ptp(pos0[:, 1]) * 111_000, np.ptp(pos0[:, 2]) * 62_000)
    assert max(spread) < 20  # metres of GNSS scatter, no motion


# ---------------------------------------------------------------------------------------------------------
# Round trips through python-can writers

T0_NS = 1_600_000_000_123_456_789  # not on a whole ms: shows what each format keeps of the start time
PERIOD_NS = 10_000_000
N_CYCLES = 100  # one ABS_1 and one EPS_1 per cycle -> 200 frames


@cache
def _giulia() -> Database:
    db, warnings = load_dbc(PROJECT_DBC)
    assert warnings == []
    return db


def _frames() -> list[tuple[int, str, dict[str, float], can.Message]]:
    """(true t_ns, message name, physical values, python-can message) of 100 ABS_1 + 100 EPS_1 frames."""
    db = _giulia()
    out = []
    for i in range(N_CYCLES):
        t_abs = T0_NS + i * PERIOD_NS
        abs_values = {
            "WHEEL_SPEED_FL": 10.0 + 0.05 * i,
            "WHEEL_SPEED_FR": 10.1 + 0.05 * i,
            "WHEEL_SPEED_RL": 9.9 + 0.05 * i,
            "WHEEL_SPEED_RR": 10.0 + 0.049 * i,
        }
        eps_values = {"STEERING_ANGLE": -30.0 + 0.37 * i, "STEERING_RATE": -20.0 + 0.5 * i}
        for t_ns, name, values, channel in (
            (t_abs, "ABS_1", abs_values, 0),
            (t_abs + 3_141_593, "EPS_1", eps_values, 1),
        ):
            data = encode_frame(db, name, values, i)
            frame_id = db.get_message_by_name(name).frame_id
            msg = can.Message(
                timestamp=t_ns / 1e9, arbitration_id=frame_id, is_extended_id=False, data=data, channel=channel
            )
            out.append((t_ns, name, values, msg))
    return out


WRITERS: dict[str, type[can.io.generic.MessageWriter]] = {
    ".asc": can.ASCWriter,
    ".blf": can.BLFWriter,
    ".trc": can.TRCWriter,
    ".log": can.CanutilsLogWriter,
}
# Time kept per format, in ns: (constant offset of the whole file, per-frame tolerance). ASC and BLF keep the
# start date to 1 ms (python-can truncates; ASC: as local time); ASC, TRC and candump store offsets/times to
# 1 us; BLF objects to 1 ns. Plus 0.12 us of float64 seconds in python-can itself.
TIME_FACTS = {
    ".asc": (-(T0_NS % 1_000_000), 1_200),
    ".blf": (0, 300),
    ".trc": (0, 1_200),
    ".log": (0, 700),
}
CHANNELS = {".asc": ("1", "2"), ".blf": ("1", "2"), ".trc": ("1", "2"), ".log": ("can0", "can1")}


def _write_mf4(path: Path, frames: list[tuple[int, str, dict[str, float], can.Message]]) -> None:
    """A finalised MDF4 file of ``frames`` (:func:`_frames`), written by python-can (asammdf)."""
    with can.MF4Writer(path) as writer:
        for *_, msg in frames:
            writer.on_message_received(msg)


def _write(path: Path, messages: list[can.Message]) -> None:
    with WRITERS[path.suffix](path) as writer:
        for msg in messages:
            writer.on_message_received(msg)


@pytest.mark.parametrize("suffix", sorted(WRITERS))
def test_round_trip(tmp_path: Path, suffix: str) -> None:
    frames = _frames()
    path = tmp_path / f"giulia{suffix}"
    _write(path, [f[3] for f in frames])
    assert is_can_log(path)
    records = list(read_can_log(path))
    assert len(records) == len(frames) == 2 * N_CYCLES
    db = _giulia()
    offset, tolerance = TIME_FACTS[suffix]
    for rec, (t_ns, name, values, msg) in zip(records, frames, strict=True):
        assert (rec.frame_id, rec.is_extended, rec.dlc, rec.data) == (
            msg.arbitration_id,
            False,
            msg.dlc,
            bytes(msg.data),
        )
        assert not rec.is_error and not rec.is_remote
        assert rec.channel == CHANNELS[suffix][msg.channel]
        assert abs(rec.t_ns - (t_ns + offset)) <= tolerance, (rec.t_ns, t_ns)
        check = check_frame(db, rec.frame_id, rec.data)
        assert check.name == name and check.checksum_ok is True
        message = db.get_message_by_frame_id(rec.frame_id)
        decoded = message.decode(rec.data)
        for signal, value in values.items():
            assert abs(decoded[signal] - value) <= message.get_signal_by_name(signal).scale / 2 + 1e-9, signal
    counters = [check_frame(db, r.frame_id, r.data).counter for r in records if r.frame_id == 0xEE]
    assert counters == [i % 16 for i in range(N_CYCLES)]


def _relative(asc: str) -> str:
    """An ASC log's text with each event's time the time since the event before (the header's ``timestamps
    relative``, a CANoe / CANalyzer logging option), from each trigger block's start."""
    out, before = [], 0
    for line in asc.splitlines(keepends=True):
        if line.lower().startswith("base "):
            line = line.replace("absolute", "relative")
        elif line.lower().startswith("begin triggerblock"):
            before = 0
        elif found := re.match(r"(\s*)(\d+)\.(\d{6})(?=\s)", line):
            at = int(found[2]) * 1_000_000 + int(found[3])
            line = f"{found[1]}{(at - before) // 1_000_000}.{(at - before) % 1_000_000:06d}{line[found.end():]}"
            before = at
        out.append(line)
    return "".join(out)


def test_an_asc_whose_times_are_relative_reads_each_frame_at_its_own_time(tmp_path: Path) -> None:
    """An ASC written with ``base hex timestamps relative`` holds each event's time since the one before, which
    python-can ignores (it reads them as times since the start): urban seed 1's 23188 CAN frames so came within 0.2 ms
    of one another, and ingest kept 9 rows of them, as duplicates and late frames, without a word (navigate then went
    without wheel speeds or steering). Summed as the lines are fed, every frame reads at its time in the absolute
    log, to the ns; an ingest keeps every frame."""
    frames = _frames()
    absolute = tmp_path / "absolute.asc"
    _write(absolute, [f[3] for f in frames])
    relative = tmp_path / "relative.asc"
    relative.write_text(_relative(absolute.read_text()))
    assert "timestamps relative" in relative.read_text()
    want = [r.t_ns for r in read_can_log(absolute)]
    got = list(read_can_log(relative))
    assert [r.t_ns for r in got] == want and (want[-1] - want[0]) / 1e9 == pytest.approx(0.99, abs=0.01)
    # a frame line damaged after its time (a NUL in its data) is left out; its time still counts for those after it
    # (they read 6.9 ms early before: its time since the frame before)
    lines = relative.read_text().splitlines(keepends=True)
    k = [i for i, line in enumerate(lines) if " Rx " in line][10]
    lines[k] = lines[k][:-6] + "\0" + lines[k][-5:]
    damaged = tmp_path / "damaged.asc"
    damaged.write_text("".join(lines))
    read = []
    with pytest.raises(CanLogError, match=r"1 line no frame could be read from left out \(line 16\)"):
        read.extend(r.t_ns for r in read_can_log(damaged))
    assert read == want[:10] + want[11:]
    from autosar_cli.config import load_config
    from autosar_cli.ingest.pipeline import ingest

    report = ingest([], tmp_path / "d.h5", config=load_config(), can_logs=[relative], allow_partial=True)
    assert {s["path"]: s["written"] for s in report.streams if s["path"].startswith("can/")} == {
        "can/ABS_1": N_CYCLES, "can/EPS_1": N_CYCLES}, report.streams


def test_a_can_log_whose_clock_steps_back_while_recording_is_warned_of(tmp_path: Path) -> None:
    """A logger whose clock is set back while it records (NTP, PTP stepping a PC's clock) writes the frames after the
    step stamped before those it wrote before: a stream's reorder buffer (512 messages) interleaves the two, without
    a word. Urban seed 1's CAN as a candump log stepping 0.3 s back halfway went 16.3 cm across (0.96 as recorded).
    The step is one warning naming the file, the frame and the size; a log in time order says nothing."""
    from autosar_cli.config import load_config
    from autosar_cli.ingest.pipeline import ingest

    messages = [f[3] for f in _frames()]
    for m in messages[N_CYCLES:]:
        m.timestamp -= 0.3
    stepped = tmp_path / "stepped.log"
    _write(stepped, messages)
    report = ingest([], tmp_path / "d.h5", config=load_config(), can_logs=[stepped], allow_partial=True)
    said = [w for w in report.warnings if w.startswith(f"{stepped}: its frame times step back")]
    assert len(said) == 1, report.warnings
    assert f"by up to 0.293 s from frame {N_CYCLES + 1} on" in said[0] and "49 frames stamped over 50 ms" in said[0]
    whole = tmp_path / "whole.log"
    _write(whole, [f[3] for f in _frames()])
    report = ingest([], tmp_path / "w.h5", config=load_config(), can_logs=[whole], allow_partial=True)
    assert not [w for w in report.warnings if "step back" in w], report.warnings


def test_a_can_log_whose_clock_steps_forward_is_told_from_frames_lost(tmp_path: Path) -> None:
    """A logger whose clock is set forward while it records leaves a gap in its times with no frame lost: urban seed
    1's CAN as a candump log stepping 0.3 s forward halfway went 13.2 cm across, without a word. The jump is one
    warning naming the file, the frame, the time and the size; the rolling counters across it tell a clock step (on
    by one) from 30 frames of each ID lost (they skip); 32 frames lost (the counters go round twice) say neither; a
    log in time order, and one that steps back, say nothing of a jump."""
    from autosar_cli.config import load_config
    from autosar_cli.ingest.pipeline import ingest

    def jumps(name: str, messages: list[can.Message]) -> list[str]:
        path = tmp_path / name
        _write(path, messages)
        report = ingest([], tmp_path / f"{name}.h5", config=load_config(), can_logs=[path], allow_partial=True)
        return [w for w in report.warnings if w.startswith(f"{path}: its frame times jump forward")]

    stepped = [f[3] for f in _frames()]
    for m in stepped[N_CYCLES:]:
        m.timestamp += 0.3
    said = jumps("stepped.log", stepped)
    assert len(said) == 1 and (f"by up to 0.307 s after frame {N_CYCLES} (2020-09-13T12:26:40.616+00:00; 1 such "
                               "jump): no frame where ID 0xEE on can0 came every 10 ms (31 periods)") in said[0], said
    assert "counters of the 2 IDs that have one go on by one across it: no frame lost, the logger's clock set forward" \
        in said[0]
    frames = [f[3] for f in _frames()]
    said = jumps("lost.log", frames[:N_CYCLES] + frames[N_CYCLES + 60:])
    assert len(said) == 1 and "0.307 s after frame 100" in said[0], said
    assert "counters of 2 of the 2 IDs that have one skip across it: frames lost" in said[0]
    said = jumps("lost32.log", frames[:N_CYCLES] + frames[N_CYCLES + 64:])
    assert len(said) == 1 and "0.327 s" in said[0] and "no rolling counter tells which" in said[0], said
    assert jumps("whole.log", frames) == []
    back = [f[3] for f in _frames()]
    for m in back[N_CYCLES:]:
        m.timestamp -= 0.3
    assert jumps("back.log", back) == []


def test_a_real_can_logs_id_that_pauses_while_another_comes_on_time_is_no_jump(tmp_path: Path) -> None:
    """The 2022 CANedge file's 0x9 (every 10 ms) pauses 0.5 s while 0x10 comes on, every 200 ms, as before: no jump
    of the file's times, none warned of (it was, 0.2 s twice, before 0x10's own times were asked)."""
    from autosar_cli.config import load_config
    from autosar_cli.ingest.pipeline import ingest

    path = realdata(CSS, MF4_2022)
    report = ingest([], tmp_path / "d.h5", config=load_config(), can_logs=[path],
                    allow_partial=True, dbc=path.parent / "gnss.dbc")
    assert not [w for w in report.warnings if "jump forward" in w], report.warnings


def test_round_trip_extended_ids(tmp_path: Path) -> None:
    msgs = [
        can.Message(timestamp=1.6e9 + 0.25, arbitration_id=0x18FF1234, is_extended_id=True, data=b"\x01\x02\x03"),
        can.Message(timestamp=1.6e9 + 0.27, arbitration_id=0x001, is_extended_id=True, data=b""),
    ]
    for suffix in WRITERS:
        path = tmp_path / f"ext{suffix}"
        _write(path, msgs)
        got = [(r.frame_id, r.is_extended, r.data, r.t_ns) for r in read_can_log(path)]
        assert got == [
            (0x18FF1234, True, b"\x01\x02\x03", pytest.approx(1_600_000_000_250_000_000, abs=1_200)),
            (0x001, True, b"", pytest.approx(1_600_000_000_270_000_000, abs=1_200)),
        ], suffix


def test_times_to_ns_exact(tmp_path: Path) -> None:
    """t_ns is the float time rounded to the ns: not timestamp * 1e9, which is only 256 ns fine near 1.6e18."""
    path = tmp_path / "exact.log"
    path.write_text("(1600000000.250000) can0 0EE#01\n(1600000000.000001) vcan1 1FFFFFFF#\n")
    records = list(read_can_log(path))
    assert [r.t_ns for r in records] == [1_600_000_000_250_000_000, pytest.approx(1_600_000_000_000_001_000, abs=120)]
    assert [(r.channel, r.frame_id, r.is_extended) for r in records] == [
        ("can0", 0xEE, False),
        ("vcan1", 0x1FFFFFFF, True),
    ]


# ---------------------------------------------------------------------------------------------------------
# Errors


def test_truncated_blf_yields_frames_then_error(tmp_path: Path) -> None:
    frames = _frames()
    whole = tmp_path / "whole.blf"
    _write(whole, [f[3] for f in frames])
    reference = list(read_can_log(whole))
    cut = tmp_path / "cut.blf"
    cut.write_bytes(whole.read_bytes()[: whole.stat().st_size // 2])
    with can.BLFReader(cut) as reader:  # python-can itself ends such a file silently, with fewer frames
        assert 0 < sum(1 for _ in reader) < len(frames)
    got: list[CanRecord] = []
    with pytest.raises(CanLogError) as info:  # only CanLogError, never a raw reader exception
        for rec in read_can_log(cut):
            got.append(rec)
    assert 0 < len(got) < len(frames) and got == reference[: len(got)]
    message = str(info.value)
    assert "cut.blf" in message and "truncated" in message and "\n" not in message


def _blf_in_containers(path: Path) -> tuple[list[CanRecord], list[int]]:
    """A BLF of :func:`_frames` in many small log containers (frames run on from one into the next), as read, and
    the byte of each container."""
    with can.BLFWriter(path, max_container_size=1024) as writer:
        for *_, msg in _frames():
            writer.on_message_received(msg)
    return list(read_can_log(path)), _container_starts(path.read_bytes())


def _container_starts(data: bytes) -> list[int]:
    """The byte of each of a BLF's objects (its log containers), by their sizes."""
    starts, pos = [], struct.unpack_from("<L", data, 4)[0]
    while pos < len(data):
        size = struct.unpack_from("<L", data, pos + 8)[0]
        starts.append(pos)
        pos += size + size % 4
    return starts


def _python_can_reads(log: Path) -> int:
    """The frames python-can's BLFReader gives before it ends or raises."""
    n = 0
    with contextlib.suppress(Exception), can.BLFReader(log) as reader:
        for _ in reader:
            n += 1
    return n


@pytest.mark.parametrize("damage, says, moved", [
    (lambda data, at: data[:at + 40] + bytes(64) + data[at + 104:], "does not inflate", 0),
    (lambda data, at: data[:at] + bytes(16) + data[at + 16:], "has no object header (it reads b'\\x00\\x00\\x00\\x00')",
     0),
    (lambda data, at: data[:at + 100] + data[at + 300:], "does not inflate", -200)],
    ids=["64 bytes zeroed in its stream", "its header zeroed", "200 bytes lost"])
def test_a_blf_damaged_inside_keeps_the_frames_of_every_other_container(tmp_path: Path, damage, says: str,
                                                                       moved: int) -> None:
    """A BLF whose fifth log container is damaged: python-can stopped there (a zlib error, a BLFParseError, or
    silently where a damaged size took it past the end) and every frame after it was lost. The damaged container
    is left out (the frames its neighbours share with it too), every other one read from a copy: the file's frames
    less those, in order, and the error says where."""
    whole = tmp_path / "whole.blf"
    reference, starts = _blf_in_containers(whole)
    assert len(reference) == 2 * N_CYCLES and len(starts) >= 8
    at = starts[4]
    log = tmp_path / "damaged.blf"
    log.write_bytes(damage(whole.read_bytes(), at))
    per_container = len(reference) / len(starts)
    assert _python_can_reads(log) < 5 * per_container + 2
    got, message = _read_until_error(log)
    assert _in_order_within(got, reference) and len(reference) - per_container - 2 <= len(got) < len(reference)
    assert message == (f"{log}: damaged BLF log: the container at byte {at} {says}: damaged there, bytes {at} to "
                       f"{starts[5] + moved} left out and the containers after them read; {len(got)} frames read")


def test_a_blf_whose_last_container_is_damaged_keeps_what_its_stream_gave_before(tmp_path: Path) -> None:
    """The end of the last container's stream zeroed: what zlib gives before it
    fails is kept, in time order, less its last two frames (their bytes may already be the damage's). python-can
    read those and a frame zlib made of the zeros (id 0 on channel 511, 1100 s after the start), then stopped with
    an error of its own; the last container dropped whole would have lost 2400 good frames."""
    whole = tmp_path / "whole.blf"
    with can.BLFWriter(whole) as writer:  # 40 s of frames: python-can's 128 KiB containers, 3 of them
        for second in range(40):
            for *_, msg in _frames():
                writer.on_message_received(can.Message(timestamp=msg.timestamp + second, channel=msg.channel,
                                                       arbitration_id=msg.arbitration_id, data=msg.data,
                                                       is_extended_id=False))
    reference = list(read_can_log(whole))
    data = whole.read_bytes()
    log = tmp_path / "damaged.blf"
    log.write_bytes(data[:-44] + bytes(44))
    by_python_can = 0
    with contextlib.suppress(can.io.blf.BLFParseError), can.BLFReader(log) as reader:
        for _ in reader:
            by_python_can += 1
    got, message = _read_until_error(log)
    assert by_python_can - 2 <= len(got) < len(reference) and got == reference[:len(got)]
    last = _container_starts(data)[-1]
    assert message == (f"{log}: damaged BLF log: the container at byte {last} does not inflate: damaged there, no "
                       f"container after it, bytes {last} to {len(data)} left out; {len(got)} frames read")


@pytest.mark.parametrize("more", [500, 3000], ids=["inside the file", "past its end"])
def test_a_blf_container_whose_size_is_damaged_is_read_to_its_streams_end(tmp_path: Path, more: int) -> None:
    """The fifth container's size damaged upwards: python-can took the bytes after it for its own and read on from
    inside the next container (a BLFParseError), or past the end (silently short). Its zlib stream says where it
    ends: every frame is read, and the error names the container."""
    whole = tmp_path / "whole.blf"
    reference, starts = _blf_in_containers(whole)
    data = whole.read_bytes()
    at = starts[4]
    size = struct.unpack_from("<L", data, at + 8)[0]
    log = tmp_path / "damaged.blf"
    log.write_bytes(data[:at + 8] + struct.pack("<L", size + more) + data[at + 12:])
    assert (at + size + more > len(data)) == (more == 3000)
    assert _python_can_reads(log) < len(reference) - 80
    got, message = _read_until_error(log)
    assert got == reference
    assert message == (f"{log}: damaged BLF log: the container at byte {at} says it holds {size + more} bytes, its "
                       f"stream {size}: read to there; {len(reference)} frames read")


@pytest.mark.parametrize("at, damage, says", [
    (0, b"LOGX", "has no signature (it reads b'LOGX')"),
    (4, struct.pack("<L", 0x7FFF0000), "says it holds 2147418112 bytes"),
    (4, struct.pack("<L", 16), "says it holds 16 bytes")],
    ids=["its signature", "its size, past the end", "its size, inside itself"])
def test_a_blf_whose_file_header_is_damaged_is_read_with_it_rebuilt(tmp_path: Path, at: int, damage: bytes,
                                                                    says: str) -> None:
    """python-can refused a BLF whose header's signature was damaged, read none of its frames without a word where
    its size said more than the file holds (it skipped them all as the header's), and raised where it said less.
    The first object lies after a header of the standard 144 bytes: every frame is read, at its own time, from a
    copy whose header is rebuilt (the start time and the other fields kept), and the error says so."""
    whole = tmp_path / "whole.blf"
    reference, _ = _blf_in_containers(whole)
    data = whole.read_bytes()
    log = tmp_path / "damaged.blf"
    log.write_bytes(data[:at] + damage + data[at + len(damage):])
    assert _python_can_reads(log) == 0
    got, message = _read_until_error(log)
    assert got == reference
    assert message == (f"{log}: damaged BLF log: its file header {says}: rebuilt, its fields after the first 8 bytes "
                       f"kept; {len(reference)} frames read")


def test_a_blf_whose_file_size_is_damaged_is_told_from_one_cut_short(tmp_path: Path) -> None:
    """The header's file size damaged upwards, every container there: read whole, the error says the size is
    damaged, not that the file was cut. A file cut where a container ends, its size undamaged: the containers its
    header's uncompressed size counts are not all there, so it is said to be cut, its frames before the cut read."""
    whole = tmp_path / "whole.blf"
    reference, starts = _blf_in_containers(whole)
    data = whole.read_bytes()
    sized = tmp_path / "sized.blf"
    got, message = _read_damaged(sized, data[:16] + struct.pack("<Q", 10**9) + data[24:])
    assert got == reference
    assert message == (f"{sized}: damaged BLF log: its header says 1000000000 bytes, the file has {len(data)} and "
                       f"every log container its uncompressed size counts; {len(reference)} frames read")
    cut = tmp_path / "cut.blf"
    got, message = _read_damaged(cut, data[:starts[5]])
    assert 0 < len(got) < len(reference) and got == reference[:len(got)]
    assert message.startswith(f"{cut}: truncated BLF log: header says {len(data)} bytes, file has {starts[5]} ")


@pytest.mark.parametrize("damage", ["start and stop times zeroed", "start time zeroed, the last container lost"])
def test_a_blf_whose_start_time_is_no_date_is_read_at_offsets_with_a_warning(tmp_path: Path, damage: str) -> None:
    """The header's start time (a SYSTEMTIME at byte 40) zeroed: python-can reads it as 0 and every frame at its
    offset from the measurement's start, near 1970, without a word. Where the stop time (byte 56) is lost too, or the
    file's last objects are (the stop time is the last object's), nothing gives the start back: the frames are read
    at their offsets, and the reader says their times are no dates."""
    whole = tmp_path / "whole.blf"
    reference, starts = _blf_in_containers(whole)
    data = whole.read_bytes()
    damaged = data[:40] + bytes(32) + data[72:] if "stop" in damage else data[:40] + bytes(16) + data[56:starts[-1]]
    log = tmp_path / "damaged.blf"
    log.write_bytes(damaged)
    warned: list[str] = []
    got: list[CanRecord] = []
    with contextlib.suppress(CanLogError):  # the lost container is named at the end
        for rec in read_can_log(log, warned.append):
            got.append(rec)
    assert 0 < len(got) <= len(reference) and reference[0].t_ns > 10**18 and 0 <= got[0].t_ns < 10**9
    start_ns = reference[0].t_ns - got[0].t_ns  # python-can's float seconds: each time within 1 us of the file's
    assert all(abs(r.t_ns + start_ns - ref.t_ns) < 1000 for r, ref in zip(got, reference, strict=False))
    assert [dataclasses.replace(r, t_ns=0) for r in got] == [dataclasses.replace(r, t_ns=0) for r in reference][
        :len(got)]
    assert warned == [f"{log}: no start date in the header; times are offsets from the measurement start"]


def test_a_blf_whose_start_time_alone_is_lost_takes_it_from_its_stop_time(tmp_path: Path) -> None:
    """The header's start time zeroed, its stop time (the last object's, to the millisecond) and every container
    whole: the start is the stop time less the last object's time, every frame within 1 ms of its own time and all
    by one offset, and the error says so."""
    whole = tmp_path / "whole.blf"
    with can.BLFWriter(whole, max_container_size=1024) as writer:
        for k, (*_, msg) in enumerate(_frames()):  # times off the millisecond grid
            writer.on_message_received(can.Message(timestamp=msg.timestamp + 0.000_437 * k, channel=msg.channel,
                                                   arbitration_id=msg.arbitration_id, data=msg.data,
                                                   is_extended_id=msg.is_extended_id))
    reference = list(read_can_log(whole))
    data = whole.read_bytes()
    log = tmp_path / "damaged.blf"
    got, message = _read_damaged(log, data[:40] + bytes(16) + data[56:])
    offsets = {r.t_ns - ref.t_ns for r, ref in zip(got, reference, strict=True)}
    assert max(offsets) - min(offsets) < 1000 and all(abs(o) <= 1_000_000 for o in offsets)
    assert [dataclasses.replace(r, t_ns=0) for r in got] == [dataclasses.replace(r, t_ns=0) for r in reference]
    assert message == (f"{log}: damaged BLF log: its file header's start time is no date: taken from its stop time "
                       f"less its last object's time (to 1 ms); {len(reference)} frames read")


_KIND = {".asc": "ASC", ".trc": "TRC", ".log": "candump -L"}


@pytest.mark.parametrize("suffix", [".asc", ".trc", ".log"])
@pytest.mark.parametrize("damage", ["zeroed", "a data byte lost", "a data byte overwritten"])
def test_a_text_log_damaged_in_a_line_keeps_every_other_line(tmp_path: Path, suffix: str, damage: str) -> None:
    """16 bytes zeroed in a frame line in the middle of a text log, its last data byte lost, or a data byte made
    "ZZ": python-can skipped a line no pattern of its matched without a word, read a frame short of its data bytes
    (DLC 8, 7 bytes) as a whole one, or raised at the line it could not parse (every frame after it lost). Such a
    line is left out and counted, the reader started again with the header's lines (its start date, base, columns)
    and the lines after: every other frame read, at its own time. candump states no length: a frame a byte short
    reads whole."""
    log = tmp_path / f"whole{suffix}"
    _write(log, [f[3] for f in _frames()])
    reference = list(read_can_log(log))
    text = log.read_bytes()
    start = text.index(b"\n", len(text) // 2) + 1  # the frame line after the middle
    end = text.index(b"\n", start)
    line = text[:start].count(b"\n") + 1
    damaged = tmp_path / f"damaged{suffix}"
    if damage == "zeroed":
        damaged.write_bytes(text[:start + 20] + bytes(16) + text[start + 36:])
    elif damage == "a data byte overwritten":
        at = text.index(b"#", start) + 1 if suffix == ".log" else end - 2
        damaged.write_bytes(text[:at] + b"ZZ" + text[at + 2:])
    elif suffix == ".log":  # the first data byte: "0EE#16F8..." -> "0EE#F8..."
        hash_at = text.index(b"#", start)
        damaged.write_bytes(text[:hash_at + 1] + text[hash_at + 3:])
        got = list(read_can_log(damaged))
        assert len(got) == len(reference) and got[line - 1].data == reference[line - 1].data[1:]
        return
    else:
        damaged.write_bytes(text[:end - 3] + text[end:])
    got, message = _read_until_error(damaged)
    assert _in_order_within(got, reference) and len(got) == len(reference) - 1
    assert message == (f"{damaged}: damaged {_KIND[suffix]} log: 1 line no frame could be read from left out (line "
                       f"{line}), the lines after read; {len(got)} frames read")


def test_an_asc_damaged_in_its_second_trigger_block_reads_on_at_that_blocks_times(tmp_path: Path) -> None:
    """An ASC whose second half is a trigger block of its own (dated at its first frame, its times counted from
    that date), damaged in a line there: the reader started again reads the header and then the second block's
    "Begin Triggerblock" line again, so the frames after the damage keep their times (from the first block's date
    they would be half a second early, without a word)."""
    log = tmp_path / "whole.asc"
    _write(log, [f[3] for f in _frames()])
    lines = log.read_text().split("\n")
    begin = next(i for i, ln in enumerate(lines) if ln.startswith("Begin Triggerblock "))
    date = datetime.strptime(lines[begin].removeprefix("Begin Triggerblock "), "%a %b %d %H:%M:%S.%f %Y")
    middle = len(lines) // 2
    shift = math.floor(float(lines[middle].split(None, 1)[0]) * 1000) / 1000  # at its first frame, to the ms
    later = (date + timedelta(seconds=shift)).strftime("%a %b %d %H:%M:%S.%f")[:-3] + date.strftime(" %Y")
    second = [f"{float(ln.split(None, 1)[0]) - shift:9.6f} {ln.split(None, 1)[1]}" if ln.strip() and
              ln.split(None, 1)[0][0].isdigit() else ln for ln in lines[middle:]]
    two_blocks = tmp_path / "two_blocks.asc"
    two_blocks.write_text("\n".join([*lines[:middle], "End TriggerBlock", f"Begin Triggerblock {later}", *second]))
    reference = list(read_can_log(two_blocks))
    one_block = list(read_can_log(log))
    assert len(reference) == len(one_block)
    assert max(abs(a.t_ns - b.t_ns) for a, b in zip(reference, one_block, strict=True)) < 1000  # the same times
    text = two_blocks.read_bytes()
    start = text.index(b"\n", 3 * len(text) // 4) + 1  # a frame line in the second block
    end = text.index(b"\n", start)
    damaged = tmp_path / "damaged.asc"
    damaged.write_bytes(text[:end - 2] + b"ZZ" + text[end:])
    got, _ = _read_until_error(damaged)
    assert len(got) == len(reference) - 1 and _in_order_within(got, reference)


@pytest.mark.parametrize("suffix", [".asc", ".trc", ".log"])
def test_a_text_log_whose_first_frame_line_is_damaged_reads_the_others_at_their_times(tmp_path: Path,
                                                                                     suffix: str) -> None:
    """The first frame line's last data byte made "ZZ": python-can raised before any frame and the log gave none.
    The header is then the lines before that one: every other frame read, at its own time (the header's date)."""
    log = tmp_path / f"whole{suffix}"
    _write(log, [f[3] for f in _frames()])
    reference = list(read_can_log(log))
    text = log.read_bytes()
    lines = text.split(b"\n")
    data = reference[0].data.hex().upper().encode()
    spaced = b" ".join(data[i:i + 2] for i in range(0, len(data), 2))
    first = next(i for i, ln in enumerate(lines) if data in ln or spaced in ln)  # the first frame's line
    damaged_line = lines[first]
    at = damaged_line.index(b"#") + 1 if suffix == ".log" else len(damaged_line.rstrip()) - 2
    lines[first] = damaged_line[:at] + b"ZZ" + damaged_line[at + 2:]
    damaged = tmp_path / f"damaged{suffix}"
    damaged.write_bytes(b"\n".join(lines))
    got, message = _read_until_error(damaged)
    assert got == reference[1:]
    assert message == (f"{damaged}: damaged {_KIND[suffix]} log: 1 line no frame could be read from left out (line "
                       f"{first + 1}), the lines after read; {len(got)} frames read")


def _frame_line_damaged(text: bytes, first: bool, damage: str) -> tuple[bytes, int]:
    """``text`` with one byte of a frame line overwritten where python-can's pattern looks (the middle line, or the
    first frame's), and that line's number: the time's last digit made "F", or the blank after the time "i"."""
    lines = text.split(b"\n")
    frame_lines = [i for i, ln in enumerate(lines) if ln.strip()[:1].isdigit() and b"Start of" not in ln]
    at_line = frame_lines[0] if first else frame_lines[len(frame_lines) // 2]
    line = lines[at_line]
    time_ends = line.index(b".") + line[line.index(b"."):].index(b" ")  # the time: the token with the point
    at = time_ends - 1 if damage == "a letter in the time" else time_ends
    lines[at_line] = line[:at] + (b"F" if damage == "a letter in the time" else b"i") + line[at + 1:]
    return b"\n".join(lines), at_line + 1


@pytest.mark.parametrize("suffix", [".asc", ".trc"])
@pytest.mark.parametrize("damage", ["a letter in the time", "the blank after the time a letter"])
@pytest.mark.parametrize("first", [False, True], ids=["a frame line", "the first frame line"])
def test_a_text_log_frame_line_damaged_where_the_reader_looks_is_counted(tmp_path: Path, suffix: str, damage: str,
                                                                        first: bool) -> None:
    """One byte overwritten where python-can's ASC or TRC pattern looks: its reader skipped that line as an event it
    does not read, without a word (a printable byte overwritten at a seeded place of an ASC's frame line lost that
    frame silently in 229 of 503 trials, a TRC's in 66: bench_can_log_damage.py). The line no frame came from is
    shaped as the frame lines around it: counted, and named, as a damaged one; the other frames read."""
    log = tmp_path / f"whole{suffix}"
    _write(log, [f[3] for f in _frames()])
    reference = list(read_can_log(log))
    text, line = _frame_line_damaged(log.read_bytes(), first, damage)
    damaged = tmp_path / f"damaged{suffix}"
    damaged.write_bytes(text)
    got, message = _read_until_error(damaged)
    assert _in_order_within(got, reference) and len(got) == len(reference) - 1
    assert message == (f"{damaged}: damaged {_KIND[suffix]} log: 1 line no frame could be read from left out (line "
                       f"{line}), the lines after read; {len(got)} frames read")


def test_an_ascs_other_events_are_not_taken_for_damaged_frames(tmp_path: Path) -> None:
    """Lines of events python-can does not read (a comment, a chip status, bus statistics, a system variable, a
    J1939 transport message) between the frames of an ASC are shaped otherwise than its frame lines: every frame
    read, no line counted as damage."""
    log = tmp_path / "whole.asc"
    _write(log, [f[3] for f in _frames()])
    reference = list(read_can_log(log))
    lines = log.read_text().split("\n")
    frame_lines = [i for i, ln in enumerate(lines) if ln.strip()[:1].isdigit() and "Start of" not in ln]
    events = ["// logging resumed by the user", "   {t} CAN 1 Status:chip status error active",
              "   {t} 1  Statistic: D 3 R 0 XD 0 XR 0 E 0 O 0 B 0.14%", "   {t} SV: 1 0 1 ::Sys::Engine::Mode = 1",
              "   {t} J1939TP FEECp 3j R 1 0 18 00 ff 7 d 8 aa bb cc dd ee ff 01 02"]
    with_events = list(lines)
    for n, i in enumerate(reversed(frame_lines[10::37])):
        t = lines[i].split(None, 1)[0]
        with_events.insert(i, events[n % len(events)].format(t=t))
    assert len(with_events) - len(lines) >= len(events)
    other = tmp_path / "with_events.asc"
    other.write_text("\n".join(with_events))
    assert list(read_can_log(other)) == reference


def test_an_ascs_classic_frame_with_a_dlc_over_8_is_read_as_8_bytes(tmp_path: Path) -> None:
    """A classic frame's DLC 9-15 states 8 data bytes (ISO 11898-1; a CANalyzer log's "d D 55 AA 01 02 03 04 05
    06  Length = ..."). python-can reads the code as the CAN FD length (32), so the frame was left out as short of
    its bytes and the log called damaged: it is read, its DLC the code (13), and decoded as its 8-byte message.
    A classic line holding 64 bytes ("d 40 ..."), or a damaged one python-can reads as DLC 13 ('Rx " d 8 12 60 ...':
    "d" the DLC, "8" the first byte), is not such a frame: still left out."""
    log = tmp_path / "whole.asc"
    _write(log, [f[3] for f in _frames()])
    reference = list(read_can_log(log))
    text = log.read_text()
    first = reference[0]
    line = next(ln for ln in text.split("\n") if first.data.hex(" ").upper() in ln)
    long_dlc = line.replace(" d 8 ", " d D ") + "  Length = 232016 BitCount = 119 ID = 1023"
    sixty_four = line.replace(" d 8 ", " d 40 ") + " 00" * 56
    (tmp_path / "long_dlc.asc").write_text(text.replace(line, long_dlc, 1))
    got = list(read_can_log(tmp_path / "long_dlc.asc"))
    assert got == [dataclasses.replace(first, dlc=13), *reference[1:]]
    writer = DriveWriter(tmp_path / "drive.h5", {})
    try:
        decoder = CanDecoder(writer, _giulia(), "fca_giorgio", dict)
        decoder.feed(got[0], None, got[0].t_ns)
        assert (decoder.stats.decoded, dict(decoder.stats.dlc_mismatch)) == (1, {})
        decoder.feed(dataclasses.replace(got[0], data=got[0].data[:7]), None, got[0].t_ns)  # 7 bytes: short
        assert (decoder.stats.decoded, dict(decoder.stats.dlc_mismatch)) == (1, {"ABS_1": 1})
    finally:
        writer.abort()
    junk_before_d = line.replace("Rx   d 8 ", 'Rx " d 8 ')  # python-can: DLC "d" (32), data "8 12 60 ..."
    assert junk_before_d != line
    for name, damaged_line in (("sixty_four", sixty_four), ("junk_before_d", junk_before_d)):
        (tmp_path / f"{name}.asc").write_text(text.replace(line, damaged_line, 1))
        got, message = _read_until_error(tmp_path / f"{name}.asc")
        assert got == reference[1:] and "1 line no frame could be read from left out" in message


@pytest.mark.parametrize("suffix", [".asc", ".trc", ".log"])
def test_text_log_cut_inside_its_last_line_keeps_the_lines_before(tmp_path: Path, suffix: str) -> None:
    """Every writer ends its lines; a text log whose end cuts its last frame's line (python-can skips a broken
    TRC line without a word, and reads a broken candump line as a frame with fewer data bytes, a silently wrong
    frame) keeps exactly the frames of its whole lines and ends in a one-line error naming the cut."""
    frames = _frames()
    whole = tmp_path / f"whole{suffix}"
    _write(whole, [f[3] for f in frames])
    reference = list(read_can_log(whole))
    text = whole.read_bytes()
    last_frame_line = text.rindex(b"\n", 0, text.rindex(b"\n", 0, len(text) - 1) if suffix == ".asc" else len(text) - 1)
    cut_at = last_frame_line + 1 + 30  # 30 bytes into the last frame's line
    cut = tmp_path / f"cut{suffix}"
    cut.write_bytes(text[:cut_at])
    got: list[CanRecord] = []
    with pytest.raises(CanLogError) as info:
        for rec in read_can_log(cut):
            got.append(rec)
    assert got == reference[:-1]
    kind = {".asc": "ASC", ".trc": "TRC", ".log": "candump -L"}[suffix]
    assert str(info.value) == (f"{cut}: truncated {kind} log: its last line is cut off (30 bytes "
                               f"after the last line end); {len(got)} frames read before it")
    at_line_end = tmp_path / f"at_line_end{suffix}"  # a cut between lines: a shorter log, but for ASC's block
    at_line_end.write_bytes(text[:last_frame_line + 1])
    if suffix == ".asc":
        with pytest.raises(CanLogError, match="End TriggerBlock"):
            list(read_can_log(at_line_end))
    else:
        assert list(read_can_log(at_line_end)) == reference[:-1]


def test_corrupt_files(tmp_path: Path) -> None:
    bad = tmp_path / "garbage.blf"
    bad.write_bytes(b"not a binary logging file" * 10)
    with pytest.raises(CanLogError, match="garbage.blf"):
        list(read_can_log(bad))
    empty = tmp_path / "empty.mf4"
    empty.write_bytes(b"")
    with pytest.raises(CanLogError, match="empty.mf4"):
        list(read_can_log(empty))
    candump = tmp_path / "bad.log"
    candump.write_text("(1600000000.000000) can0 0EE#1260\nthis line is not candump output at all\n")
    got = []
    with pytest.raises(CanLogError, match=r"bad\.log: damaged candump -L log: 1 line no frame could be read from left "
                                          r"out \(line 2\), the lines after read; 1 frames read"):
        for rec in read_can_log(candump):
            got.append(rec)
    assert [r.data for r in got] == [b"\x12\x60"]


def test_missing_file_and_unknown_suffix(tmp_path: Path) -> None:
    with pytest.raises(CanLogError, match="nothere.blf"):
        read_can_log(tmp_path / "nothere.blf")
    odd = tmp_path / "frames.xyz"
    odd.write_text("")
    with pytest.raises(CanLogError, match="frames.xyz") as info:
        read_can_log(odd)
    assert all(suffix in str(info.value) for suffix in CAN_LOG_SUFFIXES)
    assert not is_can_log(odd)


def test_nmea_log_is_not_a_can_log() -> None:
    """.log is shared with NMEA captures: is_can_log sniffs the first line, read_can_log refuses clearly."""
    nmea = realdata("gpsd", "neo-m8n.log")
    assert not is_can_log(nmea)
    with pytest.raises(CanLogError, match="neo-m8n.log: not a candump -L log"):
        list(read_can_log(nmea))


_LEAN_MF4 = """
import json, sys
from autosar_cli.ingest import mf4_support
mf4_support.defer()  # as the autosar command does
import autosar_cli.ingest.pipeline  # noqa: F401  (cantools, python-can)
from autosar_cli.ingest.canlog import read_can_log
before = sorted(m for m in ("asammdf", "pandas") if m in sys.modules)
records = [[r.t_ns, r.frame_id, r.data.hex(), r.channel] for r in read_can_log(sys.argv[1])]
print(json.dumps({"before": before, "after": "asammdf" in sys.modules, "records": records}))
"""


def test_mf4_support_is_loaded_when_the_first_mf4_log_is_opened(tmp_path: Path) -> None:
    # The autosar command imports python-can without asammdf (and pandas); an .mf4 log then still reads exactly
    # as with python-can imported the usual way (this process).
    frames = _frames()
    path = tmp_path / "giulia.mf4"
    _write_mf4(path, frames)
    expected = [[r.t_ns, r.frame_id, r.data.hex(), r.channel] for r in read_can_log(path)]
    assert len(expected) == len(frames) and [e[1] for e in expected] == [f[3].arbitration_id for f in frames]
    out = subprocess.run([sys.executable, "-c", _LEAN_MF4, str(path)], check=True, capture_output=True, text=True,
                         cwd=REPO)
    lean = json.loads(out.stdout)
    assert lean["before"] == [] and lean["after"] is True
    assert lean["records"] == expected


def test_a_failed_read_of_an_unfinalised_mf4_leaves_no_copy_of_it(tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """asammdf reads an unfinalised MF4 (a logger's, CSS Electronics') from a copy of it in the system's temporary
    folder; where the read failed (here a block's length damaged), that copy, the whole log, was left there. It is
    now made in a folder of the reader's own, removed with it, read or not."""
    import tempfile

    scratch = tmp_path / "system_tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    log = bytearray(realdata("css-electronics", "2F6913DB_00000004_00000001.MF4").read_bytes())
    log[1810] ^= 0xFF
    log[1811] ^= 0xFF
    damaged = tmp_path / "damaged.mf4"
    damaged.write_bytes(log)
    with pytest.raises(CanLogError, match="its ##TX block at byte 1800 runs past the end"):
        list(read_can_log(damaged))
    assert list(scratch.iterdir()) == []
    frames = list(read_can_log(realdata("css-electronics", "2F6913DB_00000004_00000001.MF4")))  # read whole
    assert len(frames) > 0 and list(scratch.iterdir()) == []
