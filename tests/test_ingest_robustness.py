"""Ingest robustness: tampered, damaged and incomplete logs, each fault injected a known number of times.

Every tampered MCAP is a copy of the simulated ci drive (seed 7) written by :func:`tamper`, which passes
each message through a callback that may drop, keep, edit, duplicate or hold it back. The tests check that
ingest counts exactly what was injected, writes exactly the rows that remain, never fails on a bad
message and, where a file cannot be read at all, fails with one clear error naming the file.
"""

from __future__ import annotations

import dataclasses
import io
import json
import math
import re
import shutil
import sqlite3
import zlib
from collections import Counter
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Chunk, Message
from mcap.stream_reader import breakup_chunk
from mcap.writer import CompressionType, Writer
from typer.testing import CliRunner

from autosar_cli import msgs
from autosar_cli.candb import giorgio_checksum
from autosar_cli.cli import app
from autosar_cli.config import Config, load_config
from autosar_cli.ingest.pipeline import IngestError, IngestReport, ingest
from autosar_cli.sim.simulate import SimulationResult
from autosar_cli.store.drive import Drive

TS = msgs.typestore_for(2)
Out = list[tuple[int, int, bytes]]  # (log_time, channel_id, CDR bytes) to write for one source message

CAN_TOPIC = "/from_can_bus"
RADAR_TOPIC = "/scanbrick/raw_frames"
RADAR = "radar/scanbrick_w43"
ABS_1, ABS_2, EPS_1, ORC_1 = 0xEE, 0xFE, 0xDE, 0xD2
SECOND = 1_000_000_000

runner = CliRunner()


# ------------------------------------------------------------------------------------------ helpers
@dataclasses.dataclass(frozen=True)
class Rec:
    """One message of the source log, as the tamper callback sees it."""

    topic: str
    msgtype: str
    channel_id: int
    log_time: int
    data: bytes
    n: int  #: index of the message within its topic (0-based)

    def keep(self) -> Out:
        return [(self.log_time, self.channel_id, self.data)]

    def decode(self) -> Any:
        return TS.deserialize_cdr(self.data, self.msgtype)

    def encode(self, msg: Any) -> bytes:
        return bytes(TS.serialize_cdr(msg, self.msgtype))

    def edited(self, **changes: Any) -> Out:
        """This message with top-level fields replaced (``dataclasses.replace``), same log time."""
        return [(self.log_time, self.channel_id, self.encode(dataclasses.replace(self.decode(), **changes)))]


def tamper(src: Path, dst: Path, fn: Callable[[Rec], Out], extra: Sequence[tuple[str, str, str]] = ()) -> Path:
    """Copy the MCAP ``src`` to ``dst`` through ``fn``; ``extra`` adds channels (topic, schema name, schema text).

    Schemas and channels keep their ids; extra channels get the next ids (see :func:`channel_ids`).
    """
    seen: Counter[str] = Counter()
    with open(src, "rb") as f, open(dst, "wb") as out:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        w = Writer(out, compression=CompressionType.ZSTD, chunk_size=4 * 1024 * 1024)
        w.start(profile="ros2", library="test_ingest_robustness")
        for sid, s in sorted(summary.schemas.items()):
            assert w.register_schema(s.name, s.encoding, s.data) == sid
        for cid, c in sorted(summary.channels.items()):
            assert w.register_channel(c.topic, c.message_encoding, c.schema_id, c.metadata) == cid
        for topic, name, text in extra:
            sid = w.register_schema(name, "ros2msg", text.encode())
            w.register_channel(topic, "cdr", sid, {})
        for schema, channel, m in reader.iter_messages(log_time_order=False):
            rec = Rec(channel.topic, schema.name, channel.id, m.log_time, bytes(m.data), seen[channel.topic])
            seen[channel.topic] += 1
            for t, cid, data in fn(rec):
                w.add_message(cid, t, data, t)
        w.finish()
    return dst


def channel_ids(path: Path) -> dict[str, int]:
    """topic -> channel id of an MCAP file."""
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return {c.topic: c.id for c in summary.channels.values()}


def stamp(msg: Any) -> int:
    return int(msg.header.stamp.sec) * SECOND + int(msg.header.stamp.nanosec)


def shifted(msg: Any, dt_ns: int) -> Any:
    """``msg`` with its header stamp moved by ``dt_ns``."""
    sec, nanosec = divmod(stamp(msg) + dt_ns, SECOND)
    st = dataclasses.replace(msg.header.stamp, sec=sec, nanosec=nanosec)
    return dataclasses.replace(msg, header=dataclasses.replace(msg.header, stamp=st))


@dataclasses.dataclass
class Ingested:
    report: IngestReport
    drive: Path
    log: Path
    injected: dict[str, Any] = dataclasses.field(default_factory=dict)  #: what the tamper callback did

    @property
    def streams(self) -> dict[str, dict[str, Any]]:
        return {s["path"]: s for s in self.report.streams}

    def t_ns(self, path: str) -> np.ndarray:
        with Drive(self.drive) as d:
            return d.h5[path]["t_ns"][()]


def run(log: Path, out_dir: Path, config: Config, **kw: Any) -> Ingested:
    out_dir.mkdir(parents=True, exist_ok=True)
    drive = out_dir / "drive.h5"
    return Ingested(ingest([log], drive, config=config, **kw), drive, log)


def no_output(out_dir: Path) -> bool:
    """Neither drive.h5 nor drive.h5.partial was left behind."""
    return not (out_dir / "drive.h5").exists() and not (out_dir / "drive.h5.partial").exists()


def one_error_line(stderr: str) -> str:
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, stderr
    assert lines[0].startswith("error:"), stderr
    return lines[0]


# ----------------------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def cfg() -> Config:
    return load_config()


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("robust")


@pytest.fixture(scope="module")
def base(ci_mcap: SimulationResult, work: Path, cfg: Config) -> Ingested:
    """The untampered ci drive: the reference every tampered ingest is compared with."""
    got = run(ci_mcap.log_path, work / "base", cfg)
    s = got.streams
    assert s[RADAR]["written"] == 981 and s["imu/imu_cog_a"]["written"] == 494 and got.report.can["decoded"] == 392
    assert got.report.warnings == [] and got.report.skipped_channels == []
    return got


@pytest.fixture(scope="module")
def can_tampered(ci_mcap: SimulationResult, work: Path, cfg: Config) -> Ingested:
    """5 ABS_1 frames with a flipped CHECKSUM byte, 3 ABS_2 frames dropped (counter skips), 2 EPS_1 frames with a
    wrong DLC, 4 extra frames with the unknown ID 0x555."""
    per_id: Counter[int] = Counter()
    injected: dict[str, list[int]] = {"checksum": [], "dropped": [], "dlc": [], "unknown": []}

    def fn(r: Rec) -> Out:
        if r.topic != CAN_TOPIC:
            return r.keep()
        m = r.decode()
        k = per_id[m.id]
        per_id[m.id] += 1
        if m.id == ABS_1 and k in (10, 20, 30, 40, 50):
            injected["checksum"].append(stamp(m))
            data = m.data.copy()
            data[7] ^= 0xFF  # CHECKSUM is the last byte
            return r.edited(data=data)
        if m.id == ABS_2 and k in (15, 45, 75):
            injected["dropped"].append(stamp(m))
            return []
        if m.id == EPS_1 and k in (25, 65):
            injected["dlc"].append(stamp(m))
            return r.edited(dlc=5)
        if m.id == ORC_1 and k in (5, 35, 55, 85):
            injected["unknown"].append(stamp(m))
            return r.keep() + r.edited(id=0x555)
        return r.keep()

    log = tamper(ci_mcap.log_path, work / "can.mcap", fn)
    got = run(log, work / "can", cfg)
    got.injected = injected
    return got


@pytest.fixture(scope="module")
def timing_tampered(ci_mcap: SimulationResult, work: Path, cfg: Config) -> Ingested:
    """/imu/cog_a: 3 adjacent swaps + 1 message delayed by 3 (file order); /imu/cog_b: 6 duplicates (5 adjacent,
    1 three messages later); /ins_cog/imu: 4 header stamps +1000 s (one among the first 8)."""
    held: dict[str, Out] = {}
    jumps = (3, 30, 60, 90)

    def fn(r: Rec) -> Out:
        if r.topic == "/imu/cog_a":
            if r.n in (100, 200, 300, 400):
                held["a"] = r.keep()
                return []
            if r.n in (101, 201, 301, 403):
                return r.keep() + held.pop("a")
        elif r.topic == "/imu/cog_b":
            if r.n in (50, 150, 250, 350, 450):
                return r.keep() + r.keep()
            if r.n == 60:
                held["b"] = r.keep()
            if r.n == 63:
                return r.keep() + held.pop("b")
        elif r.topic == "/ins_cog/imu" and r.n in jumps:
            return [(r.log_time, r.channel_id, r.encode(shifted(r.decode(), 1000 * SECOND)))]
        return r.keep()

    log = tamper(ci_mcap.log_path, work / "timing.mcap", fn)
    assert not held
    got = run(log, work / "timing", cfg)
    got.injected = {"jumps": jumps}
    return got


@pytest.fixture(scope="module")
def content_tampered(ci_mcap: SimulationResult, work: Path, cfg: Config) -> Ingested:
    """/ins_cog/fix: status -1 (twice) and NaN latitude (once); radar: 3 frames with truncated data."""
    injected: dict[str, list[int]] = {"no_fix": [], "radar_short": []}

    def fn(r: Rec) -> Out:
        if r.topic == "/ins_cog/fix" and r.n in (2, 5, 7):
            m = r.decode()
            injected["no_fix"].append(stamp(m))
            if r.n == 5:
                return r.edited(latitude=math.nan)
            return r.edited(status=dataclasses.replace(m.status, status=-1))
        if r.topic == RADAR_TOPIC and r.n in (100, 400, 700):
            m = r.decode()
            injected["radar_short"].append(int(m.frame_index))
            return r.edited(data=m.data[: len(m.data) // 2])
        return r.keep()

    log = tamper(ci_mcap.log_path, work / "content.mcap", fn)
    got = run(log, work / "content", cfg)
    got.injected = injected
    return got


@pytest.fixture(scope="module")
def radar_gap(ci_mcap: SimulationResult, work: Path, cfg: Config) -> Ingested:
    """5 consecutive radar frames (the 500th to the 504th) dropped."""
    log = tamper(ci_mcap.log_path, work / "radar_gap.mcap",
                 lambda r: [] if r.topic == RADAR_TOPIC and 500 <= r.n < 505 else r.keep())
    return run(log, work / "radar_gap", cfg)


# ------------------------------------------------------------------------------------- 1. CAN faults
def test_can_integrity_faults_counted_never_fatal(can_tampered: Ingested, base: Ingested) -> None:
    assert {k: len(v) for k, v in can_tampered.injected.items()} == {"checksum": 5, "dropped": 3, "dlc": 2,
                                                                      "unknown": 4}
    can = can_tampered.report.can
    assert can["frames"] == 392 - 3 + 4
    assert can["decoded"] == 392 - 3 - 5 - 2
    assert can["checksum_errors"] == {"ABS_1": 5}
    assert can["dlc_mismatch"] == {"EPS_1": 2}
    assert can["unknown_ids"] == {"0x555": 4}
    assert can["counter_errors"]["ABS_2"] == 3
    assert can["missing_roles"] == [] and can_tampered.drive.exists()

    s, b = can_tampered.streams, base.streams
    for group, dropped in (("ABS_1", "checksum"), ("ABS_2", "dropped"), ("EPS_1", "dlc"), ("ORC_1", "unknown")):
        lost = can_tampered.injected[dropped] if dropped != "unknown" else []
        assert s[f"can/{group}"]["written"] == b[f"can/{group}"]["written"] - len(lost), group
        # exactly the tampered frames are missing from drive.h5, everything else is there
        t, t0 = can_tampered.t_ns(f"can/{group}"), base.t_ns(f"can/{group}")
        assert np.array_equal(t, np.setdiff1d(t0, lost)), group
    # the CAN faults touch nothing else
    for path, st in b.items():
        if not path.startswith("can/"):
            assert s[path]["written"] == st["written"], path


def test_a_car_with_other_checksums_than_the_rule_is_told_which_key_to_set(tmp_path: Path) -> None:
    """A candump log of ABS_1 frames whose checksum byte is not the Giorgio CRC (another car's scheme under a DBC
    of one's own with a CHECKSUM signal): with the default rule every frame is dropped and the error says so and
    names [can] checksum = "none" (it said only "no known sensor streams"); with that rule all 300 decode."""
    rng = np.random.default_rng(5)
    lines = []
    for k in range(300):
        data = bytearray(rng.integers(0, 256, 8, dtype=np.uint8).tobytes())
        data[7] = (giorgio_checksum(0xEE, bytes(data)) + 1) % 256  # never the rule's
        lines.append(f"({1700000000 + k * 0.01:.6f}) can0 0EE#{data.hex().upper()}")
    log = tmp_path / "mycar.log"
    log.write_text("\n".join(lines) + "\n")
    r = CliRunner().invoke(app, ["ingest", "--can-log", str(log), "-o", str(tmp_path / "a.h5")])
    assert r.exit_code == 1 and r.stderr.count("\n") == 1, r.stderr
    assert "no known sensor streams" in r.stderr and "300 CAN frames dropped by the checksum rule" in r.stderr
    assert '[can] checksum = "none"' in r.stderr
    cfg = tmp_path / "none.toml"
    cfg.write_text('base = "default"\n\n[can]\nchecksum = "none"\n')
    r = CliRunner().invoke(app, ["ingest", "--can-log", str(log), "-o", str(tmp_path / "b.h5"), "--config", str(cfg),
                                 "--allow-partial", "--json"])
    assert r.exit_code == 0, r.stderr
    assert json.loads(r.stdout)["can"]["decoded"] == 300


def test_can_rejected_frames_are_not_also_counter_errors(can_tampered: Ingested) -> None:
    # The bus carried every ABS_1 and EPS_1 frame (only their content was bad): no counter ever skipped there.
    assert can_tampered.report.can["counter_errors"] == {"ABS_2": 3}


# -------------------------------------------------------------------- 2. out of order and duplicates
def test_out_of_order_messages_are_reordered(timing_tampered: Ingested, base: Ingested) -> None:
    st = timing_tampered.streams["imu/imu_cog_a"]
    assert (st["received"], st["written"]) == (494, 494)
    assert st["reordered"] == 4
    assert st["duplicates"] == st["late_dropped"] == st["time_jumps"] == 0
    t = timing_tampered.t_ns("imu/imu_cog_a")
    assert np.all(np.diff(t) > 0)
    assert np.array_equal(t, base.t_ns("imu/imu_cog_a"))


def test_duplicate_messages_are_dropped_and_counted(timing_tampered: Ingested, base: Ingested) -> None:
    st = timing_tampered.streams["imu/imu_cog_b"]
    assert (st["received"], st["written"]) == (494 + 6, 494)
    assert st["duplicates"] == 6
    assert st["reordered"] == st["late_dropped"] == 0
    t = timing_tampered.t_ns("imu/imu_cog_b")
    assert np.all(np.diff(t) > 0)
    assert np.array_equal(t, base.t_ns("imu/imu_cog_b"))
    with Drive(timing_tampered.drive) as d, Drive(base.drive) as d0:
        assert np.array_equal(d.series("imu/imu_cog_b")["angular_velocity"],
                              d0.series("imu/imu_cog_b")["angular_velocity"], equal_nan=True)


# ------------------------------------------------------------------------------------- 3. time jumps
def test_header_time_jumps_are_repaired(timing_tampered: Ingested, base: Ingested) -> None:
    st, st0 = timing_tampered.streams["imu/ins_cog"], base.streams["imu/ins_cog"]
    jumps = list(timing_tampered.injected["jumps"])
    assert st["time_jumps"] == len(jumps) == 4
    assert st["written"] == st0["written"] == 99
    assert st["clock_offset_ns"] == st0["clock_offset_ns"]  # the jump among the first 8 does not skew it
    t, t0 = timing_tampered.t_ns("imu/ins_cog"), base.t_ns("imu/ins_cog")
    assert np.all(np.diff(t) > 0)
    assert np.all(np.abs(t[jumps] - t0[jumps]) < 10_000_000)  # within 10 ms of the true stamp
    others = np.setdiff1d(np.arange(len(t0)), jumps)
    assert np.array_equal(t[others], t0[others])
    # the other streams are untouched by the jumps
    assert timing_tampered.streams["imu/ins_radar"]["time_jumps"] == 0


# ----------------------------------------------------------------------------------- 4. GNSS no fix
def test_gnss_without_fix_is_skipped(content_tampered: Ingested, base: Ingested) -> None:
    st = content_tampered.streams["gnss/gnss_cog/fix"]
    no_fix = content_tampered.injected["no_fix"]
    assert len(no_fix) == 3
    assert st["received"] == 10 and st["written"] == 7
    assert st["skipped"] == {"no fix": 3}
    t0 = base.t_ns("gnss/gnss_cog/fix")
    assert np.array_equal(content_tampered.t_ns("gnss/gnss_cog/fix"), np.setdiff1d(t0, no_fix))
    with Drive(content_tampered.drive) as d:
        fix = d.series("gnss/gnss_cog/fix")
    assert np.all(np.isfinite(fix["latitude_deg"])) and np.all(np.isfinite(fix["longitude_deg"]))
    assert np.all(fix["status"] >= 0)
    assert content_tampered.streams["gnss/gnss_radar/fix"]["skipped"] == {}


# ------------------------------------------------------------------------------------- 5. radar
def test_radar_frames_of_wrong_size_are_skipped(content_tampered: Ingested, base: Ingested) -> None:
    st = content_tampered.streams[RADAR]
    short = content_tampered.injected["radar_short"]
    assert st["received"] == 981 and st["written"] == 978
    assert st["skipped"] == {"wrong data size": 3}
    assert st["missing_frames"] == 3  # a skipped frame is a missing frame
    with Drive(content_tampered.drive) as d, Drive(base.drive) as d0:
        r, r0 = d.radar(), d0.radar()
        assert np.array_equal(r.frame_index, np.setdiff1d(r0.frame_index, short))
        assert r.raw.shape == (978, *r0.raw.shape[1:])
        assert np.array_equal(d.h5[RADAR]["gap_frame_index"][()], [[f - 1, f + 1] for f in short])


def test_radar_frame_index_gap_is_recorded(radar_gap: Ingested, base: Ingested) -> None:
    st = radar_gap.streams[RADAR]
    assert st["received"] == st["written"] == 981 - 5
    assert st["missing_frames"] == 5
    assert st["gaps"] == 1
    with Drive(base.drive) as d0:
        idx0, t0 = d0.radar().frame_index, d0.radar().t_ns
    with Drive(radar_gap.drive) as d:
        g = d.h5[RADAR]
        assert np.array_equal(g["gap_frame_index"][()], [[idx0[499], idx0[505]]])
        assert idx0[505] - idx0[499] == 6
        assert np.array_equal(g["gaps"][()], [[t0[499], t0[505]]])
        assert np.array_equal(g["frame_index"][()], np.delete(idx0, range(500, 505)))
        stored = {st["path"]: st for st in d.report()["streams"]}  # the report kept in drive.h5 says so too
    assert stored[RADAR]["missing_frames"] == 5 and stored[RADAR]["gaps"] == 1


# ---------------------------------------------------------------------------- 6. damaged containers
def _chunk_messages(path: Path, start: int, length: int) -> Counter[int]:
    """Messages per channel id inside the chunk record at ``start``."""
    with open(path, "rb") as f:
        f.seek(start)
        blob = f.read(length)
    assert blob[0] == 0x06  # chunk opcode; then a uint64 length, then the chunk body
    chunk = Chunk.read(ReadDataStream(io.BytesIO(blob[9:])))
    return Counter(r.channel_id for r in breakup_chunk(chunk) if isinstance(r, Message))


def test_truncated_mcap_keeps_what_came_before(ci_mcap: SimulationResult, work: Path, cfg: Config,
                                               base: Ingested) -> None:
    data = ci_mcap.log_path.read_bytes()
    log = work / "half.mcap"
    log.write_bytes(data[: len(data) // 2])
    got = run(log, work / "half", cfg)
    hits = [m for w in got.report.warnings if str(log) in w and (m := re.search(r"\bbyte (\d+)", w))]
    assert len(hits) == 1, got.report.warnings
    offset = int(hits[0].group(1))
    assert 0 < offset <= len(data) // 2
    radar = got.streams[RADAR]["written"]
    assert 0 < radar < 981
    # every stream holds exactly the beginning of the intact drive
    for path, st in got.streams.items():
        t = got.t_ns(path)
        assert np.array_equal(t, base.t_ns(path)[: len(t)]), path
        assert st["late_dropped"] == st["duplicates"] == 0


def test_the_drive_of_a_damaged_log_says_it_is_degraded(ci_mcap: SimulationResult, work: Path) -> None:
    """`autosar ingest` of a log cut in half: its warning, then a last line that marks the drive degraded and says
    where its warnings are kept; --json's "status" is "degraded" (a whole log's is "ok")."""
    log = work / "cut.mcap"
    log.write_bytes(ci_mcap.log_path.read_bytes()[: ci_mcap.log_path.stat().st_size // 2])
    r = runner.invoke(app, ["ingest", str(log), "-o", str(work / "cut.h5")], env={"COLUMNS": "300"},
                      terminal_width=300)
    assert r.exit_code == 0, r.output
    n = sum(ln.startswith("warning:") for ln in r.stderr.splitlines())
    said = f"{work / 'cut.h5'}: degraded ({n} warning{'s' if n > 1 else ''} above, in its /provenance report)"
    assert n >= 1 and "".join(r.stdout.split()).endswith("".join(said.split())), r.stdout  # as rich wraps it
    r = runner.invoke(app, ["ingest", str(log), "-o", str(work / "cut2.h5"), "--json"])
    assert json.loads(r.stdout)["status"] == "degraded"
    r = runner.invoke(app, ["ingest", str(ci_mcap.log_path), "-o", str(work / "whole.h5"), "--json"])
    assert json.loads(r.stdout)["status"] == "ok"


def test_corrupt_chunk_is_skipped_the_rest_is_read(ci_mcap: SimulationResult, work: Path, cfg: Config,
                                                   base: Ingested) -> None:
    with open(ci_mcap.log_path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    assert len(chunks) >= 3 and all(c.compression == "zstd" for c in chunks)
    bad = chunks[len(chunks) // 2]
    lost = _chunk_messages(ci_mcap.log_path, bad.chunk_start_offset, bad.chunk_length)
    data = bytearray(ci_mcap.log_path.read_bytes())
    mid = bad.chunk_start_offset + bad.chunk_length // 2
    data[mid: mid + 256] = bytes(b ^ 0xFF for b in data[mid: mid + 256])
    log = work / "bad_chunk.mcap"
    log.write_bytes(bytes(data))

    got = run(log, work / "bad_chunk", cfg)
    end = bad.chunk_start_offset + bad.chunk_length
    assert any(str(log) in w and f"chunk ending at byte {end} skipped" in w for w in got.report.warnings), \
        got.report.warnings
    ids = channel_ids(ci_mcap.log_path)
    lost_radar = lost[ids[RADAR_TOPIC]]
    assert 0 < lost_radar < 981
    st = got.streams
    assert st[RADAR]["written"] == 981 - lost_radar
    assert st[RADAR]["missing_frames"] == lost_radar
    for path, topic in (("imu/imu_cog_a", "/imu/cog_a"), ("imu/ins_radar", "/ins_radar/imu")):
        assert st[path]["written"] == base.streams[path]["written"] - lost[ids[topic]], path
    assert got.report.can["frames"] == 392 - lost[ids[CAN_TOPIC]]
    # the summary's counts show the shortfall per topic
    assert any(f"topic {RADAR_TOPIC}: {981 - lost_radar} of the 981" in w for w in got.report.warnings)


def _crc_failing_copy(log: Path, start: int, length: int, out: Path) -> int:
    """``log`` with one byte changed inside its chunk record at ``start`` so that the chunk still decompresses (zstd)
    to its size but fails its CRC, written to ``out``; returns the byte changed."""
    import zstandard

    data = bytearray(log.read_bytes())
    chunk = Chunk.read(ReadDataStream(io.BytesIO(bytes(data[start + 9:start + length]))))
    records_at = start + length - len(chunk.data)
    for at in range(records_at + len(chunk.data) // 2, records_at + len(chunk.data), 997):
        damaged = bytearray(chunk.data)
        damaged[at - records_at] ^= 0x01
        try:
            inflated = zstandard.ZstdDecompressor().decompress(bytes(damaged),
                                                                max_output_size=chunk.uncompressed_size)
        except zstandard.ZstdError:
            continue
        if len(inflated) == chunk.uncompressed_size and zlib.crc32(inflated) != chunk.uncompressed_crc:
            data[at] ^= 0x01
            out.write_bytes(bytes(data))
            return at
    raise AssertionError("no byte found whose change leaves the chunk decompressing")


def test_a_chunk_failing_its_crc_is_read_only_when_asked(ci_mcap: SimulationResult, work: Path, cfg: Config,
                                                         base: Ingested) -> None:
    """One bit changed in a zstd chunk so that it still decompresses: its CRC fails. By default the chunk is left out
    (its radar frames missing), and the warning counts its messages and names the option; with allow_unverified it
    is read, every radar frame written, and the warning names the chunk, its messages and their span."""
    with open(ci_mcap.log_path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    bad = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)[1]
    lost = _chunk_messages(ci_mcap.log_path, bad.chunk_start_offset, bad.chunk_length)
    log = work / "crc_fails.mcap"
    _crc_failing_copy(ci_mcap.log_path, bad.chunk_start_offset, bad.chunk_length, log)
    end = bad.chunk_start_offset + bad.chunk_length
    n = sum(lost.values())

    skipped = run(log, work / "crc_skipped", cfg)
    lost_radar = lost[channel_ids(ci_mcap.log_path)[RADAR_TOPIC]]
    assert 0 < lost_radar and skipped.streams[RADAR]["written"] == 981 - lost_radar
    assert f"{log}: damaged MCAP: chunk ending at byte {end} skipped: its CRC does not match (its {n} messages; " \
           "autosar ingest --allow-unverified keeps them)" in skipped.report.warnings

    kept = run(log, work / "crc_kept", cfg, allow_unverified=True)
    assert kept.streams[RADAR]["written"] == 981
    said = [w for w in kept.report.warnings if f"chunk ending at byte {end}" in w]
    assert len(said) == 1 and said[0].startswith(
        f"{log}: damaged MCAP: chunk ending at byte {end} read although its CRC does not match (--allow-unverified): "
        f"its {n} messages logged 20")
    assert said[0].endswith(" kept, checked against its message index (0 it does not list left out); one or more "
                            "of their bytes not as written")


def test_allow_unverified_reaches_the_reader_from_the_command_line(ci_mcap: SimulationResult, work: Path) -> None:
    """`autosar ingest --allow-unverified` reads the chunk whose CRC fails, and says so; without it the chunk is left
    out."""
    with open(ci_mcap.log_path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    bad = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)[2]
    log = work / "crc_fails_cli.mcap"
    _crc_failing_copy(ci_mcap.log_path, bad.chunk_start_offset, bad.chunk_length, log)
    end = bad.chunk_start_offset + bad.chunk_length
    for flag, written in (([], False), (["--allow-unverified"], True)):
        out = work / f"crc_cli{len(flag)}"
        r = runner.invoke(app, ["ingest", str(log), "-o", str(out / "drive.h5"), "--json", *flag])
        assert r.exit_code == 0, r.output
        report = json.loads(r.stdout)
        said = [w for w in report["warnings"] if f"chunk ending at byte {end}" in w]
        assert len(said) == 1 and ("read although" in said[0]) == written, said
        radar = next(s for s in report["streams"] if s["path"] == RADAR)
        assert (radar["written"] == 981) == written


@pytest.mark.parametrize("head", [b"", b"\x89MCAP0\r\n"], ids=["random", "magic-then-garbage"])
def test_not_an_mcap_is_a_clear_error(head: bytes, work: Path, cfg: Config) -> None:
    log = work / f"noise{len(head)}.mcap"
    log.write_bytes(head + np.random.default_rng(7).bytes(64 * 1024))
    out = work / f"noise{len(head)}"
    with pytest.raises(IngestError, match=re.escape(str(log))) as exc:
        run(log, out, cfg)
    assert "MCAP" in str(exc.value)  # says what is wrong with the file, not just "no sensor streams"
    assert no_output(out)


def test_mcap_cut_inside_first_chunk_error_says_damaged(ci_mcap: SimulationResult, work: Path, cfg: Config) -> None:
    log = work / "cut200.mcap"
    log.write_bytes(ci_mcap.log_path.read_bytes()[:200])  # magic, header record, part of the first chunk
    with pytest.raises(IngestError, match=re.escape(str(log))) as exc:
        run(log, work / "cut200", cfg)
    assert re.search(r"damaged|truncated", str(exc.value)), str(exc.value)


def test_cli_corrupt_mcap_one_error_line(work: Path) -> None:
    log = work / "cli noise.mcap"  # a space in the name: still one line, still named
    log.write_bytes(np.random.default_rng(3).bytes(16 * 1024))
    out = work / "cli_noise"
    r = runner.invoke(app, ["ingest", str(log), "-o", str(out / "drive.h5")])
    assert r.exit_code != 0
    assert str(log) in one_error_line(r.stderr)
    assert "Traceback" not in r.output and "Traceback" not in r.stderr
    assert no_output(out)


def test_truncated_ros1_bag_clear_error(ci_ros1: SimulationResult, work: Path, cfg: Config) -> None:
    data = ci_ros1.log_path.read_bytes()
    log = work / "half.bag"
    log.write_bytes(data[: len(data) // 2])
    out = work / "half_bag"
    r = runner.invoke(app, ["ingest", str(log), "-o", str(out / "drive.h5")])
    assert "Traceback" not in r.output and "Traceback" not in r.stderr
    if r.exit_code == 0:  # salvaged: then a warning must name the file
        assert any(ln.startswith("warning:") and str(log) in ln for ln in r.stderr.splitlines()), r.stderr
    else:
        line = one_error_line(r.stderr)
        assert str(log) in line and "ROS1 bag" in line
        assert no_output(out)
        with pytest.raises(IngestError, match=re.escape(str(log))):
            run(log, out, cfg)
        assert no_output(out)


# -------------------------------------------------------------------------- 7. missing radar or nav
def test_log_without_radar_needs_allow_partial(ci_mcap: SimulationResult, work: Path, cfg: Config,
                                               base: Ingested) -> None:
    log = tamper(ci_mcap.log_path, work / "no_radar.mcap", lambda r: [] if r.topic == RADAR_TOPIC else r.keep())
    with pytest.raises(IngestError, match="radar") as exc:
        run(log, work / "no_radar", cfg)
    assert "--allow-partial" in str(exc.value) and str(log) in str(exc.value)
    assert no_output(work / "no_radar")

    got = run(log, work / "no_radar_partial", cfg, allow_partial=True)
    assert got.report.partial is True
    assert any("radar" in w and "--allow-partial" in w for w in got.report.warnings)
    with Drive(got.drive) as d:
        assert d.radar_names() == []
        assert d.report()["partial"] is True
    assert RADAR not in got.streams
    for path, st in base.streams.items():
        if path != RADAR:
            assert got.streams[path]["written"] == st["written"], path


def test_log_without_navigation_is_refused(ci_mcap: SimulationResult, work: Path, cfg: Config) -> None:
    log = tamper(ci_mcap.log_path, work / "radar_only.mcap", lambda r: r.keep() if r.topic == RADAR_TOPIC else [])
    with pytest.raises(IngestError, match="navigation") as exc:
        run(log, work / "radar_only", cfg)
    assert "--allow-partial" in str(exc.value)
    assert no_output(work / "radar_only")


# ------------------------------------------------------------------------------------ 8. rosbag2 traps
def _edit_metadata(bag: Path, edit: Callable[[dict[str, Any]], None]) -> None:
    meta_path = bag / "metadata.yaml"
    meta = yaml.safe_load(meta_path.read_text(encoding="utf-8"))
    for entry in meta["rosbag2_bagfile_information"]["topics_with_message_count"]:
        edit(entry["topic_metadata"])
    meta_path.write_text(yaml.safe_dump(meta, sort_keys=False), encoding="utf-8")


def _rosbags_count(bag: Path) -> Counter[str]:
    from rosbags.rosbag2 import Reader

    with Reader(bag) as reader:
        return Counter(conn.topic for conn, _, _ in reader.messages())


def _change_qos(topic_meta: dict[str, Any]) -> None:
    for q in topic_meta["offered_qos_profiles"]:
        q["reliability"] = "best_effort"
        q["durability"] = "transient_local"


def test_rosbag2_qos_mismatch_is_read_anyway(ci_ros2: SimulationResult, work: Path, cfg: Config,
                                             base: Ingested) -> None:
    bag = work / "qos_all"
    shutil.copytree(ci_ros2.log_path, bag)
    _edit_metadata(bag, _change_qos)
    assert sum(_rosbags_count(bag).values()) == 0  # the trap is real: rosbags alone reads nothing

    got = run(bag, work / "qos_all_out", cfg)
    assert any("QoS mismatch" in w for w in got.report.warnings), got.report.warnings
    assert got.streams.keys() == base.streams.keys()
    for path, st in base.streams.items():
        assert got.streams[path]["written"] == st["written"], path
    assert got.report.can["decoded"] == 392


def test_rosbag2_qos_mismatch_on_one_topic(ci_ros2: SimulationResult, work: Path, cfg: Config,
                                           base: Ingested) -> None:
    bag = work / "qos_one"
    shutil.copytree(ci_ros2.log_path, bag)
    _edit_metadata(bag, lambda t: _change_qos(t) if t["name"] == "/imu/cog_a" else None)
    counts = _rosbags_count(bag)
    assert counts["/imu/cog_a"] == 0 and counts[RADAR_TOPIC] == 981  # rosbags silently drops just that topic

    got = run(bag, work / "qos_one_out", cfg)
    assert any("QoS mismatch" in w and "/imu/cog_a" in w for w in got.report.warnings), got.report.warnings
    for path, st in base.streams.items():
        assert got.streams[path]["written"] == st["written"], path
    assert np.array_equal(got.t_ns("imu/imu_cog_a"), base.t_ns("imu/imu_cog_a"))


def test_rosbag2_storage_shortfall_is_warned(ci_ros2: SimulationResult, work: Path, cfg: Config,
                                            base: Ingested) -> None:
    bag = work / "short"
    shutil.copytree(ci_ros2.log_path, bag)
    db = sqlite3.connect(next(bag.glob("*.db3")))
    with db:
        db.execute("DELETE FROM messages WHERE id IN (SELECT messages.id FROM messages JOIN topics "
                   "ON messages.topic_id = topics.id WHERE topics.name = '/ins_cog/fix' "
                   "ORDER BY messages.timestamp LIMIT 3 OFFSET 4)")
    db.close()

    got = run(bag, work / "short_out", cfg)
    hits = [w for w in got.report.warnings if "/ins_cog/fix" in w]
    assert len(hits) == 1 and "7 of the 10" in hits[0], got.report.warnings
    assert got.streams["gnss/gnss_cog/fix"]["written"] == 7
    for path, st in base.streams.items():
        if path != "gnss/gnss_cog/fix":
            assert got.streams[path]["written"] == st["written"], path


# -------------------------------------------------------------------- 9. unparseable embedded schema
SERVICE_SCHEMA = "int64 a\nint64 b\n---\nint64 sum\n"


@pytest.fixture(scope="module")
def bad_schema(ci_mcap: SimulationResult, work: Path, cfg: Config) -> Ingested:
    """Two extra channels with a service-like (``---``) schema: an unknown type (5 messages) and an Imu topic
    that copies every 10th /imu/cog_a message (50 messages)."""
    first_extra = max(channel_ids(ci_mcap.log_path).values()) + 1
    srv_id, imu_id = first_extra, first_extra + 1
    extra = [("/add_two_ints", "example_interfaces/srv/AddTwoInts", SERVICE_SCHEMA),
             ("/imu/extra", msgs.IMU, "std_msgs/Header header\n---\nfloat64 x\n")]

    def fn(r: Rec) -> Out:
        out = r.keep()
        if r.topic == RADAR_TOPIC and r.n % 100 == 0 and r.n < 500:
            out.append((r.log_time, srv_id, bytes(range(20))))
        if r.topic == "/imu/cog_a" and r.n % 10 == 0:
            out.append((r.log_time, imu_id, r.data))
        return out

    log = tamper(ci_mcap.log_path, work / "bad_schema.mcap", fn, extra)
    return run(log, work / "bad_schema", cfg)


def test_unparseable_schema_channel_is_skipped(bad_schema: Ingested, base: Ingested) -> None:
    skipped = {s["topic"]: s for s in bad_schema.report.skipped_channels}
    assert set(skipped) == {"/add_two_ints"}
    sk = skipped["/add_two_ints"]
    assert sk["msgtype"] == "example_interfaces/srv/AddTwoInts" and sk["reason"] and sk["messages"] == 5
    for path, st in base.streams.items():  # the rest is complete
        assert bad_schema.streams[path]["written"] == st["written"], path
    assert bad_schema.report.can["decoded"] == 392


def test_unparseable_schema_of_known_type_uses_builtin(bad_schema: Ingested, base: Ingested) -> None:
    assert any("/imu/extra" in w and "unparseable embedded definition" in w for w in bad_schema.report.warnings), \
        bad_schema.report.warnings
    st = bad_schema.streams["imu/imu_extra"]
    assert st["written"] == 50 and st["skipped"] == {}
    assert "undecodable_messages" not in bad_schema.report.can
    assert np.array_equal(bad_schema.t_ns("imu/imu_extra"), base.t_ns("imu/imu_cog_a")[::10])


def test_a_streams_clock_rate_is_read_off_its_log_times_through_jitter() -> None:
    """``ingest.series.ClockRate``: 3000 messages over 60 s whose header stamps run 50 ppm fast against their log
    times, received with 2 ms of uniform jitter, read 50 ppm within 3 std (std under 1 ppm); a stream stamped on
    the logger's clock reads 0; one whose stamps and log times are the same (no header) reads nothing over 0.5 s."""
    from autosar_cli.ingest.series import ClockRate

    rng = np.random.default_rng(3)
    t = 10**18 + np.sort(rng.integers(0, 60 * 10**9, 3000))
    for ppm in (50.0, 0.0):
        rate = ClockRate()
        header = t + np.round((t - t[0]) * ppm * 1e-6).astype(np.int64) + 7_000_000
        for h, lg in zip(header, t + rng.integers(0, 2_000_000, t.size), strict=True):
            rate.add(int(h), int(lg))
        fit = rate.fit()
        assert fit is not None
        assert abs(fit[0] - ppm) < 3 * fit[1] and fit[1] < 1.0, fit
    short = ClockRate()
    for k in range(100):
        short.add(10**18 + k * 4_000_000, 10**18 + k * 4_000_000)
    assert short.fit() is None


def test_a_stamp_far_after_both_its_neighbours_is_an_outlier_a_real_gap_is_not() -> None:
    """``ingest.series.Series`` on a 100 Hz stream stamped on one clock (a CAN log's frames): one byte of a stamp
    damaged to +502 s (a real CANedge file's, found by fuzzing) made the drive 510 s long and put the 3946 frames
    after it in the reorder window; it is dropped and counted. A real 5 s gap, the frames going on after it, is
    kept, as is a last frame far after the others (nothing after it tells)."""
    from autosar_cli.ingest.series import Series

    def run(stamps: list[int]) -> tuple[list[int], int, int]:
        out: list[int] = []
        series = Series(lambda t, rows: out.extend(t.tolist()))
        for k, t in enumerate(stamps):
            series.push(None, t, k)
        stats = series.finish()
        return out, stats.stamp_outliers, stats.reordered

    ms = 1_000_000
    clean = [10**18 + 10 * ms * k for k in range(2000)]
    damaged = clean.copy()
    damaged[1009] += 502 * 10**9
    out, outliers, reordered = run(damaged)
    assert out == clean[:1009] + clean[1010:] and (outliers, reordered) == (1, 0)
    gap = clean[:1000] + [t + 5 * 10**9 for t in clean[1000:]]
    assert run(gap) == (gap, 0, 0)
    last = clean[:-1] + [clean[-1] + 300 * 10**9]
    assert run(last) == (last, 0, 0)


def test_the_radars_clock_is_reported_against_the_navigation_streams() -> None:
    """``_radar_clock_rates``: a logger whose own clock runs 20 ppm slow against the sensors' stamps shows every
    navigation stream 20 ppm fast; a radar stream 120 ppm fast against the log times is 100 ppm fast against the
    navigation, which the warning names; one within 4 std of the navigation's is stored and not reported."""
    from autosar_cli.ingest.decoders import StreamInfo
    from autosar_cli.ingest.pipeline import _radar_clock_rates
    from autosar_cli.ingest.series import SeriesStats

    def info(path: str, kind: str, rate: float, std: float) -> StreamInfo:
        stats = SeriesStats(first_ns=10**18, last_ns=10**18 + 60 * 10**9, clock_rate_ppm=rate, clock_rate_std_ppm=std)
        return StreamInfo(path, kind, stats=stats)

    class Attrs:
        def __init__(self) -> None:
            self.set: dict[str, dict[str, float]] = {}

        def set_attrs(self, path: str, attrs: dict[str, float]) -> None:
            self.set[path] = attrs

    for radar_rate, reported in ((120.0, True), (21.0, False)):
        writer, warnings = Attrs(), []
        infos = [info("gnss/a/fix", "gnss", 19.8, 0.5), info("imu/a", "imu", 20.0, 0.2),
                 info("can/ABS_1", "can", 20.1, 0.3), info("radar/r", "radar", radar_rate, 0.1)]
        _radar_clock_rates(infos, writer, warnings)  # type: ignore[arg-type]
        assert writer.set["radar/r"]["log_clock_drift_ppm"] == pytest.approx(radar_rate - 20.0)
        assert bool(warnings) == reported, warnings
        if reported:
            assert "radar/r: its frame stamps run +100.0 ± 0.3 ppm fast" in warnings[0]
            assert "state radar.clock_drift_ppm = 100.0" in warnings[0]


def test_a_configs_topic_or_role_the_logs_lack_is_a_warning(ci_mcap, tmp_path: Path) -> None:
    """A typo in a pinned topic put the velocity under a name of its own topic's, and a role naming a message the DBC
    lacks played nothing: navigation went without them (half the drive's trajectory, no wheel speeds), status ok.
    Each is a warning naming the key and what the logs hold; the drive is degraded."""
    cfg = tmp_path / "typo.toml"
    cfg.write_text('base = "default"\n[sensors.gnss_cog]\nvelocity_topic = "/ins_cog/fix_velocityy"\n'
                   '[can.roles]\nwheel_speed_fl = "ABS_9.WHEEL_SPEED_FL"\n')
    report = ingest([ci_mcap.log_path], tmp_path / "d.h5", config=load_config(cfg))
    assert report.warnings == [
        "sensors.gnss_cog.velocity_topic: /ins_cog/fix_velocityy is in none of the logs, which hold velocity on "
        "/ins_cog/fix_velocity, a topic no sensor of the config names (a typo in the topic?): gnss_cog's velocity is "
        "not in the drive",
        "CAN roles of the config in no frame of the logs: wheel_speed_fl (a message or signal the DBC or the log does "
        "not have): the stages go without them"], report.warnings
    assert ingest([ci_mcap.log_path], tmp_path / "ok.h5", config=load_config()).warnings == []  # the right config: none
    cfg.write_text('base = "default"\n[sensors.gnss_cog]\nnmea_topic = "/ins_cog/nmae"\n')  # its kind's only one
    said = ingest([ci_mcap.log_path], tmp_path / "n.h5", config=load_config(cfg)).warnings
    assert [w for w in said if "typo" in w] == [
        "sensors.gnss_cog.nmea_topic: /ins_cog/nmae is in none of the logs, which hold nmea on /ins_cog/nmea, a topic "
        "no sensor of the config names (a typo in the topic?): gnss_cog's nmea is not in the drive"], said


def test_a_log_on_other_topics_altogether_is_no_typo(tmp_path: Path) -> None:
    """The default config on a robot's bag (its IMU on /imu/data, none of the default's topics): no "typo" warning
    for each of the default's IMUs (each claimed the one stream); the config sketch maps such a log."""
    from conftest import realdata

    bag = realdata("robot_localization", "test1.bag")
    report = ingest([bag], tmp_path / "d.h5", config=load_config(), allow_partial=True)
    assert not [w for w in report.warnings if "typo" in w], report.warnings


@pytest.mark.parametrize(("case", "expected"), [
    ("microseconds", True),  # 500 Hz, the nanoseconds field holding microseconds
    ("microseconds_across_a_second", True),
    ("nanoseconds", False),  # the same stream stamped right
    ("whole_seconds", False),  # a 1 Hz receiver stamped on its whole seconds: sub-second parts 0
    ("burst", False),  # right stamps, their log times one burst (a logger reading a USB buffer)
])
def test_stamps_in_microseconds_are_told_from_the_first_messages(case: str, expected: bool) -> None:
    from autosar_cli.ingest.series import stamps_hold_microseconds

    sec = 1_700_000_000 * 10**9
    start = {"microseconds_across_a_second": 0.9993e9, "whole_seconds": 0.0}.get(case, 0.2e9)
    period = 1e9 if case == "whole_seconds" else 2e6
    true = [int(sec + start + k * period) for k in range(8)]  # the instants, ns
    log = [t + 3_000_000 + (k * 7919 % 50_000) for k, t in enumerate(true)]  # 3 ms late, jittered
    if case == "burst":
        log = [true[-1] + 1_000_000] * 8
    stamps = true if case in ("nanoseconds", "whole_seconds", "burst") else [
        t // 10**9 * 10**9 + t % 10**9 // 1000 for t in true]
    assert stamps_hold_microseconds(list(zip(stamps, log, strict=True))) is expected
