"""Damaged containers keep every intact part: ROS1 bags, rosbag2 sqlite3 storage and MCAP files.

Each test damages a copy of the simulated ci drive (seed 7) in a known place and checks the messages
kept against a reference computed independently from the undamaged file (rosbags' index, sqlite3's own
reading of the intact database, the MCAP summary's chunk index): everything outside the damage is kept,
nothing inside it is invented, and a warning names the file and the byte offsets.
"""

from __future__ import annotations

import io
import json
import re
import shutil
import sqlite3
import struct
import subprocess
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from conftest import realdata
from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Chunk, Message
from mcap.stream_reader import breakup_chunk

from autosar_cli.config import load_config
from autosar_cli.ingest.pipeline import ingest
from autosar_cli.ingest.sources import open_source
from autosar_cli.sim.simulate import SimulationResult

Msg = tuple[str, int, bytes]  # (topic, log time ns, payload)


def read_all(path: Path) -> tuple[list[Msg], list[str]]:
    src = open_source(path)
    msgs = [(m.channel.topic, m.log_ns, bytes(m.data)) for m in src.messages()]
    return msgs, src.stats.warnings


def cut_two_thirds_in(data: bytes, start: int, end: int, out: Path) -> int:
    """``data`` cut two thirds into its record at bytes ``start``-``end`` (a copy or a disk that ran out
    mid-write), written to ``out``; returns the byte of the cut."""
    cut = start + 2 * (end - start) // 3
    out.write_bytes(data[:cut])
    return cut


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("damage")


# ------------------------------------------------------------------------------------------- ROS1
def ros1_chunks(bag: Path) -> list[tuple[int, int, list[Msg]]]:
    """(record start, record end, messages) of every chunk, from rosbags' index of the intact bag."""
    from rosbags.rosbag1 import Reader

    with Reader(bag) as reader:
        topics = {c.id: c.topic for c in reader.connections}
        payloads: dict[tuple[str, int], list[bytes]] = {}
        for c, t, d in reader.messages():  # in index order: (time, chunk, offset within the chunk)
            payloads.setdefault((c.topic, t), []).append(d)
        by_chunk: dict[int, list[tuple[int, Msg]]] = {}
        for cid, entries in reader.indexes.items():
            for e in sorted(entries, key=lambda e: (e.time, e.chunk_pos, e.offset)):
                msg = (topics[cid], e.time, payloads[(topics[cid], e.time)].pop(0))
                by_chunk.setdefault(e.chunk_pos, []).append((e.offset, msg))
        out = []
        for pos, entries in sorted(by_chunk.items()):
            ch = reader.chunks[pos]
            out.append((pos, ch.datapos + ch.datasize, [m for _, m in sorted(entries, key=lambda e: e[0])]))
    return out


def ros1_record_ends(data: bytes) -> list[tuple[int, int]]:
    """(op, end offset) of every record of a decompressed ROS1 chunk, walked by its two length fields."""
    out, at = [], 0
    while at < len(data):
        (hlen,) = struct.unpack_from("<I", data, at)
        header = data[at + 4:at + 4 + hlen]
        (dlen,) = struct.unpack_from("<I", data, at + 4 + hlen)
        at += 8 + hlen + dlen
        op = header[header.index(b"op=") + 3]
        out.append((op, at))
    return out


def test_truncated_ros1_bag_keeps_every_whole_message_before_the_cut(ci_ros1: SimulationResult, work: Path) -> None:
    """Cut two thirds into a chunk, the bag keeps every chunk before it and the cut chunk's messages whose
    records its lz4 prefix holds whole: those of the intact chunk, decompressed whole, that end within the bytes
    the warning says were decoded."""
    import lz4.frame
    from rosbags.rosbag1 import Reader

    chunks = ros1_chunks(ci_ros1.log_path)
    data = ci_ros1.log_path.read_bytes()
    start, end, cut_msgs = chunks[len(chunks) // 2]
    bag = work / "cut.bag"
    cut = cut_two_thirds_in(data, start, end, bag)
    got, warnings = read_all(bag)
    intact = [m for s_, e, msgs in chunks if e <= cut for m in msgs]
    assert 0 < len(intact) < sum(len(c[2]) for c in chunks)
    hit = [w for w in warnings if str(bag) in w and f"bytes {start}-{cut}: a chunk the file's end cuts" in w]
    assert len(hit) == 1, warnings
    kept, decoded = (int(x) for x in re.search(r"its first (\d+) messages kept, from (\d+) of", hit[0]).groups())
    with Reader(ci_ros1.log_path) as reader:
        ch = reader.chunks[start]
        whole = lz4.frame.decompress(data[ch.datapos:ch.datapos + ch.datasize])
    ends = [e for op, e in ros1_record_ends(whole) if op == 0x02]
    assert len(ends) == len(cut_msgs)
    assert 0 < decoded < len(whole) and kept == sum(e <= decoded for e in ends) > 0
    assert Counter(got) == Counter(intact + cut_msgs[:kept])


def ros1_record(fields: dict[str, bytes], data: bytes) -> bytes:
    header = b"".join(struct.pack("<I", len(k) + 1 + len(v)) + k.encode() + b"=" + v for k, v in fields.items())
    return struct.pack("<I", len(header)) + header + struct.pack("<I", len(data)) + data


@pytest.mark.parametrize("compression", ["none", "lz4"])
def test_ros1_chunk_a_killed_recording_left_open_keeps_its_whole_messages(compression: str,
                                                                           ci_ros1: SimulationResult,
                                                                           work: Path) -> None:
    """``rosbag record`` writes a chunk's header with both sizes 0 and fills them in when it closes the chunk; killed
    before, it leaves that chunk's messages after the header (uncompressed: records of their own; lz4: a stream
    to the file's end). The bag built so from ci's, cut two thirds into a chunk, keeps every chunk before it and
    the open chunk's messages whose records the bytes hold whole (walked by their two lengths here)."""
    import lz4.frame
    from rosbags.rosbag1 import Reader

    chunks = ros1_chunks(ci_ros1.log_path)
    data = ci_ros1.log_path.read_bytes()
    start, end, open_msgs = chunks[len(chunks) // 2]
    with Reader(ci_ros1.log_path) as reader:
        ch = reader.chunks[start]
        packed = data[ch.datapos:ch.datapos + ch.datasize]
    records = lz4.frame.decompress(packed)
    header = ros1_record({"compression": compression.encode(), "op": b"\x05", "size": bytes(4)}, b"")
    if compression == "none":
        body = records[:2 * len(records) // 3]
        whole = sum(op == 0x02 and e <= len(body) for op, e in ros1_record_ends(records))
    else:
        body = packed[:2 * len(packed) // 3]
        decoded = lz4.frame.LZ4FrameDecompressor().decompress(body)
        whole = sum(op == 0x02 and e <= len(decoded) for op, e in ros1_record_ends(records))
    bag = work / f"killed_{compression}.bag"
    bag.write_bytes(data[:start] + header + body)
    got, warnings = read_all(bag)
    before = [m for s_, e, msgs in chunks if e <= start for m in msgs]
    assert 0 < whole < len(open_msgs)
    assert Counter(got) == Counter(before + open_msgs[:whole])
    assert any(str(bag) in w and f"{start}" in w and "never closed" in w and f" {whole} " in w
               for w in warnings), warnings


def test_ros1_damaged_chunk_costs_only_that_chunk(ci_ros1: SimulationResult, work: Path) -> None:
    chunks = ros1_chunks(ci_ros1.log_path)
    start, end, lost = chunks[len(chunks) // 3]
    data = bytearray(ci_ros1.log_path.read_bytes())
    mid = (start + end) // 2
    data[mid:mid + 64] = bytes(b ^ 0x5A for b in data[mid:mid + 64])  # inside the compressed chunk data
    bag = work / "bad_chunk.bag"
    bag.write_bytes(bytes(data))
    got, warnings = read_all(bag)
    kept = [m for s, _, msgs in chunks if s != start for m in msgs]
    # the damaged chunk does not decompress or breaks mid-way: at most its messages before the damage stay
    assert Counter(got) - Counter(lost) == Counter(kept)
    assert len(got) < len(kept) + len(lost)
    assert any(str(bag) in w and f"chunk at bytes {start}-{end}" in w for w in warnings), warnings


def test_ros1_chunk_with_a_damaged_data_length_costs_nothing(ci_ros1: SimulationResult, work: Path) -> None:
    """A chunk record whose data length runs past the file's end but whose lz4 stream, decoded from its start,
    gives exactly the size its header states: the length field is what was damaged; the chunk is read by its
    stream's own end and reading goes on after it (before, the chunk was lost to the resynchronisation)."""
    chunks = ros1_chunks(ci_ros1.log_path)
    start, _, _ = chunks[2]
    data = bytearray(ci_ros1.log_path.read_bytes())
    (hlen,) = struct.unpack_from("<I", data, start)
    data[start + 4 + hlen + 3] = 0x7F  # the data length's top byte: ~2 GiB
    bag = work / "bad_data_length.bag"
    bag.write_bytes(bytes(data))
    got, warnings = read_all(bag)
    assert Counter(got) == Counter(m for _, _, msgs in chunks for m in msgs)
    assert any(str(bag) in w and f"chunk at byte {start}: its data length does not fit" in w for w in warnings), \
        warnings


def test_ros1_damaged_chunk_header_resynchronises(ci_ros1: SimulationResult, work: Path) -> None:
    chunks = ros1_chunks(ci_ros1.log_path)
    start, _, lost = chunks[2]
    data = bytearray(ci_ros1.log_path.read_bytes())
    data[start:start + 4] = b"\xff\xff\xff\x7f"  # the chunk record's header length
    bag = work / "bad_header.bag"
    bag.write_bytes(bytes(data))
    got, warnings = read_all(bag)
    assert Counter(got) == Counter(m for s, _, msgs in chunks if s != start for m in msgs)
    assert any(str(bag) in w and f"bytes {start}-" in w for w in warnings), warnings


@pytest.fixture(scope="module")
def ci_ros1_uncompressed(ci_ros1: SimulationResult, work: Path) -> Path:
    """ci's bag rewritten by rosbags' writer with its chunks uncompressed (`rosbag record`'s default): nothing but
    the record lengths frames its messages."""
    from rosbags.rosbag1 import Reader, Writer

    out = work / "uncompressed.bag"
    with Reader(ci_ros1.log_path) as reader, Writer(out) as writer:
        conns = {c.id: writer.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest)
                 for c in reader.connections}
        for c, t, d in reader.messages():
            writer.write(conns[c.id], t, d)
    return out


def ros1_message_records(bag: Path, chunk_pos: int) -> tuple[int, list[tuple[int, int, int, Msg]]]:
    """(data start, records) of the uncompressed chunk at ``chunk_pos``: each message record's (start, data length
    field offset, data length, message), walked by its two length fields."""
    from rosbags.rosbag1 import Reader

    data = bag.read_bytes()
    with Reader(bag) as reader:
        topics = {c.id: c.topic for c in reader.connections}
        ch = reader.chunks[chunk_pos]
    out, at, end = [], ch.datapos, ch.datapos + ch.datasize
    while at < end:
        (hlen,) = struct.unpack_from("<I", data, at)
        fields = {}
        f = at + 4
        while f < at + 4 + hlen:
            (size,) = struct.unpack_from("<I", data, f)
            name, _, value = data[f + 4:f + 4 + size].partition(b"=")
            fields[name] = value
            f += 4 + size
        (dlen,) = struct.unpack_from("<I", data, at + 4 + hlen)
        if fields[b"op"] == b"\x02":
            sec, nsec = struct.unpack("<II", fields[b"time"])
            msg = (topics[struct.unpack("<I", fields[b"conn"])[0]], sec * 10**9 + nsec,
                   data[at + 8 + hlen:at + 8 + hlen + dlen])
            out.append((at, at + 4 + hlen, dlen, msg))
        at += 8 + hlen + dlen
    return ch.datapos, out


@pytest.mark.parametrize("damage", ["shorter", "huge", "header"])
@pytest.mark.parametrize("size", ["small", "radar"])
def test_ros1_uncompressed_message_with_a_damaged_length_costs_only_that_message(
        damage: str, size: str, ci_ros1_uncompressed: Path, work: Path) -> None:
    """In an uncompressed chunk, a message record's data length set 40 bytes short (read through the index, the
    message came out cut, with no word) or to ~2 GiB, or its header length flipped (the rest of the chunk was lost,
    ~100 messages): only that message is left out, the damage named at its offset, and every other message kept
    byte for byte."""
    bag = ci_ros1_uncompressed
    chunks = ros1_chunks(bag)
    start = chunks[5][0]
    dstart, records = ros1_message_records(bag, start)
    pick = [r for r in records if (len(r[3][2]) > 10_000) == (size == "radar")][3]
    rec_start, dlen_at, dlen, lost = pick
    data = bytearray(bag.read_bytes())
    if damage == "header":
        data[rec_start + 1] ^= 0x10
    else:
        struct.pack_into("<I", data, dlen_at, {"shorter": dlen - 40, "huge": 0x7F00_0000}[damage])
    out = work / f"uncompressed_{damage}_{size}.bag"
    out.write_bytes(bytes(data))
    got, warnings = read_all(out)
    intact = [m for _, _, msgs in chunks for m in msgs]
    assert Counter(got) == Counter(intact) - Counter([lost]) and len(got) == len(intact) - 1
    offset = rec_start - dstart
    assert any(str(out) in w and f"chunk at bytes {start}-" in w and f"offset {offset}" in w
               and "read on from the next record" in w for w in warnings), warnings


@pytest.mark.parametrize("run_on", ["40 bytes", "to the next record's end"])
@pytest.mark.parametrize("size", ["small", "radar"])
def test_ros1_uncompressed_message_whose_length_runs_over_an_indexed_record_costs_nothing(
        run_on: str, size: str, ci_ros1_uncompressed: Path, work: Path) -> None:
    """In an uncompressed chunk, a message record's data length run on 40 bytes into the next record, or to exactly
    where the record after it starts: read through the index, the message came out with the next record's bytes,
    with no word; the scan the chain check sends the bag to left the message out (40 bytes), or read it with the next
    record's bytes and lost that record, with no warning naming either (to the next record's end). The index places
    the record it ran over: the message is read up to it, both kept byte for byte, the damage named at its offset."""
    bag = ci_ros1_uncompressed
    chunks = ros1_chunks(bag)
    start = chunks[5][0]
    dstart, records = ros1_message_records(bag, start)
    i = [k for k, r in enumerate(records[:-1]) if (len(r[3][2]) > 10_000) == (size == "radar")][3]
    rec_start, dlen_at, dlen, _ = records[i]
    over = 40 if run_on == "40 bytes" else records[i + 2][0] - records[i + 1][0]
    data = bytearray(bag.read_bytes())
    struct.pack_into("<I", data, dlen_at, dlen + over)
    out = work / f"uncompressed_run_on_{over}_{size}.bag"
    out.write_bytes(bytes(data))
    got, warnings = read_all(out)
    assert Counter(got) == Counter(m for _, _, msgs in chunks for m in msgs), warnings
    assert any(str(out) in w and f"chunk at bytes {start}-" in w and f"offset {rec_start - dstart} has a data length "
               f"({dlen + over} bytes) running over the record its index places at offset {records[i + 1][0] - dstart}"
               in w for w in warnings), warnings


@pytest.fixture(scope="module")
def ci_ros1_connections_between(ci_ros1: SimulationResult, work: Path) -> Path:
    """ci's bag rewritten uncompressed with each connection record written just before its connection's first
    message, as `rosbag record` writes them: between message records, which the index does not place."""
    from rosbags.rosbag1 import Reader, Writer

    out = work / "connections_between.bag"
    with Reader(ci_ros1.log_path) as reader, Writer(out) as writer:
        conns: dict[int, Any] = {}
        for c, t, d in reader.messages():
            if c.id not in conns:
                conns[c.id] = writer.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest)
            writer.write(conns[c.id], t, d)
    return out


def ros1_chunk_records(bag: Path, chunk_pos: int) -> tuple[int, list[tuple[int, int, int, int, str]]]:
    """(data start, records) of the uncompressed chunk at ``chunk_pos``: each record's (start, op, data length field
    offset, data length, topic), walked by its two length fields."""
    from rosbags.rosbag1 import Reader

    data = bag.read_bytes()
    with Reader(bag) as reader:
        topics = {c.id: c.topic for c in reader.connections}
        ch = reader.chunks[chunk_pos]
    out, at = [], ch.datapos
    while at < ch.datapos + ch.datasize:
        (hlen,) = struct.unpack_from("<I", data, at)
        header = data[at + 4:at + 4 + hlen]
        (dlen,) = struct.unpack_from("<I", data, at + 4 + hlen)
        conn = header.index(b"conn=") + len(b"conn=")
        out.append((at, header[header.index(b"op=") + 3], at + 4 + hlen, dlen,
                    topics[struct.unpack_from("<I", header, conn)[0]]))
        at += 8 + hlen + dlen
    return ch.datapos, out


@pytest.mark.parametrize("indexed", [True, False])
@pytest.mark.parametrize("run_on", ["to its end", "40 bytes past it", "40 bytes into it"])
@pytest.mark.parametrize("before", ["radar", "imu"])
def test_ros1_uncompressed_message_whose_length_runs_over_a_connection_record_costs_nothing(
        before: str, run_on: str, indexed: bool, ci_ros1_connections_between: Path, work: Path) -> None:
    """In an uncompressed chunk, the data length of the message record before a connection record (a radar frame,
    or an IMU message before the CAN topic's) run on to exactly that record's end, 40 bytes past it or 40 bytes into
    it, in the bag read through its index or without (its header's index_pos 0). Read through the index, the message
    came out with the connection record's bytes without a word (to its end: the records chain, the index places only
    messages; an IMU message decodes so), or with a warning naming the message record the index places (40 bytes
    past it); without the index, the connection record was lost too, and the messages on its connection with it.
    The connection record reads where the message's length says its data lies: the message is read up to it, both
    kept, the damage named with the message's offset and both topics."""
    bag = ci_ros1_connections_between
    chunks = ros1_chunks(bag)
    start = chunks[0][0]
    dstart, records = ros1_chunk_records(bag, start)
    i = next(k for k, r in enumerate(records[1:], 1) if r[1] == 0x07 and records[k - 1][1] == 0x02
             and (records[k - 1][3] > 10_000) == (before == "radar"))
    rec_start, _, dlen_at, dlen, topic = records[i - 1]
    conn_start, _, _, _, conn_topic = records[i]
    conn_length = records[i + 1][0] - conn_start
    over = {"to its end": conn_length, "40 bytes past it": conn_length + 40, "40 bytes into it": 40}[run_on]
    data = bytearray(bag.read_bytes())
    struct.pack_into("<I", data, dlen_at, dlen + over)
    if not indexed:
        at = data.index(b"index_pos=", 13) + len(b"index_pos=")
        data[at:at + 8] = bytes(8)
    out = work / f"run_on_a_connection_{before}_{over}_{indexed}.bag"
    out.write_bytes(bytes(data))
    got, warnings = read_all(out)
    assert Counter(got) == Counter(m for _, _, msgs in chunks for m in msgs), warnings
    said = (f"offset {rec_start - dstart} ({topic}) has a data length ({dlen + over} bytes) running over the "
            f"connection record of {conn_topic} at offset {conn_start - dstart}: read up to it ({dlen} bytes)")
    assert any(str(out) in w and f"chunk at bytes {start}-" in w and said in w for w in warnings), warnings


@pytest.mark.parametrize("damage", ["header", "data"])
def test_ros1_damaged_connection_record_in_a_chunk_costs_no_message(damage: str, ci_ros1_uncompressed: Path,
                                                                   work: Path) -> None:
    """The last connection record before a chunk's first message with its header length flipped, or its data length
    run on into that message: rosbags reads the connections from the index, not from the chunks, and the chain check
    sends the bag to the scan; the scan takes them from the index too (it knew only the chunks' copies: every message
    on that connection, in every chunk, was left out as on an undeclared connection, where b5f8fca read them all),
    and reads on from the connection record's data, not from where its length led (past the message it ran on
    into)."""
    from rosbags.rosbag1 import Reader

    bag = ci_ros1_uncompressed
    chunks = ros1_chunks(bag)
    start = chunks[0][0]
    data = bytearray(bag.read_bytes())
    with Reader(bag) as reader:
        ch = reader.chunks[start]
    at, conn = ch.datapos, None
    while True:  # the last connection record before the chunk's first message
        (hlen,) = struct.unpack_from("<I", data, at)
        (dlen,) = struct.unpack_from("<I", data, at + 4 + hlen)
        if b"op=\x02" in data[at + 4:at + 4 + hlen]:
            break
        conn = (at, hlen, dlen)
        at += 8 + hlen + dlen
    assert conn is not None
    message_length = 8 + hlen + dlen
    at, hlen, dlen = conn
    if damage == "header":
        data[at + 1] ^= 0x10
    else:
        struct.pack_into("<I", data, at + 4 + hlen, dlen + message_length + 10)
    out = work / f"connection_{damage}.bag"
    out.write_bytes(bytes(data))
    got, warnings = read_all(out)
    assert Counter(got) == Counter(m for _, _, msgs in chunks for m in msgs), warnings


@pytest.mark.parametrize(("compressed", "by"), [(False, -1000), (False, 1000), (True, 1000)])
def test_ros1_chunk_whose_data_length_is_off_but_fits_costs_nothing(compressed: bool, by: int,
                                                                    ci_ros1: SimulationResult,
                                                                    ci_ros1_uncompressed: Path, work: Path) -> None:
    """A chunk's data length 1000 bytes short or long, inside the file: an uncompressed chunk's data is read to the
    size its header states (it was lost whole, with the 111 messages of the chunk after it, the reading resumed
    1000 bytes off); an lz4 chunk is read to its stream's end (its chunk-info records after it were skipped)."""
    bag = ci_ros1.log_path if compressed else ci_ros1_uncompressed
    chunks = ros1_chunks(bag)
    start = chunks[5][0]
    data = bytearray(bag.read_bytes())
    (hlen,) = struct.unpack_from("<I", data, start)
    (dlen,) = struct.unpack_from("<I", data, start + 4 + hlen)
    struct.pack_into("<I", data, start + 4 + hlen, dlen + by)
    out = work / f"chunk_length_{compressed}_{by}.bag"
    out.write_bytes(bytes(data))
    got, warnings = read_all(out)
    assert Counter(got) == Counter(m for _, _, msgs in chunks for m in msgs)
    assert any(str(out) in w and f"chunk at byte {start}: its data length" in w
               and f"byte {start + 8 + hlen + dlen}: read by that" in w for w in warnings), warnings


@pytest.mark.parametrize("copy", ["record", "index"])
def test_ros1_message_time_damaged_in_one_copy_is_read_at_the_other(copy: str, ci_ros1_uncompressed: Path,
                                                                    work: Path) -> None:
    """A message's time is written twice, in its record and in the index (rosbags asserts they agree, and the bag
    is scanned): its seconds' low byte changed in one copy puts that copy outside its chunk's time span (the chunk
    info's, a third copy), and the message is read at the other's time, with a warning naming it (before, the
    record's time was taken, whichever was damaged, without a word on which message)."""
    bag = ci_ros1_uncompressed
    chunks = ros1_chunks(bag)
    start = chunks[5][0]
    dstart, records = ros1_message_records(bag, start)
    rec_start, dlen_at, _, msg = records[7]
    data = bytearray(bag.read_bytes())
    offset = rec_start - dstart
    if copy == "record":
        sec_at = data.index(b"time=", rec_start, dlen_at) + 5
    else:  # the index data record of its connection, after the chunk: (sec, nsec, offset) entries
        (hlen,) = struct.unpack_from("<I", data, start)
        (dlen,) = struct.unpack_from("<I", data, start + 4 + hlen)
        entry = struct.pack("<IiI", msg[1] // 10**9, msg[1] % 10**9, offset)
        sec_at = data.index(entry, start + 8 + hlen + dlen)
    data[sec_at] ^= 0x40  # 64 s off
    out = work / f"time_in_{copy}.bag"
    out.write_bytes(bytes(data))
    got, warnings = read_all(out)
    assert Counter(got) == Counter(m for _, _, msgs in chunks for m in msgs)
    other = {"record": "index", "index": "record"}[copy]
    assert any(str(out) in w and f"the chunk at byte {start}, offset {offset}" in w and f"read at the {other}'s time"
               in w for w in warnings), warnings


def test_ros1_uncompressed_chunk_whose_size_field_is_off_is_read_by_its_data_length(ci_ros1_uncompressed: Path,
                                                                                  work: Path) -> None:
    """An uncompressed chunk's size field 3000 bytes too large, in a bag read without its index (its header's
    index_pos set to 0, as a recording not yet closed has it): the data length, which the next record follows, is
    right. The scan read the chunk to the size, over the next chunk's records, and lost them; now it reads it by
    its data length, with a warning, and keeps every message."""
    bag = ci_ros1_uncompressed
    chunks = ros1_chunks(bag)
    start = chunks[5][0]
    data = bytearray(bag.read_bytes())
    at = data.index(b"index_pos=", 13) + len(b"index_pos=")
    data[at:at + 8] = bytes(8)
    (hlen,) = struct.unpack_from("<I", data, start)
    size_at = data.index(b"size=", start, start + 4 + hlen) + len(b"size=")
    (size,) = struct.unpack_from("<I", data, size_at)
    struct.pack_into("<I", data, size_at, size + 3000)
    out = work / "chunk_size_off.bag"
    out.write_bytes(bytes(data))
    got, warnings = read_all(out)
    assert Counter(got) == Counter(m for _, _, msgs in chunks for m in msgs)
    assert any(str(out) in w and f"chunk at byte {start}: its size field does not fit its data" in w
               for w in warnings), warnings


# ---------------------------------------------------------------------------------------- rosbag2
def db_rows(bag: Path) -> list[tuple[int, Msg]]:
    """(row id, message) of the intact rosbag2, straight from sqlite3 (payloads decompressed as rosbag2 does)."""
    import zstandard

    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    zstd = zstandard.ZstdDecompressor() if meta.get("compression_mode", "").lower() == "message" else None
    db = sqlite3.connect(f"file:{next(bag.glob('*.db3'))}?immutable=1", uri=True)
    rows = db.execute("SELECT messages.id, topics.name, timestamp, data FROM messages JOIN topics "
                      "ON topics.id = topic_id ORDER BY messages.id").fetchall()
    db.close()
    return [(i, (t, ts, zstd.decompress(d) if zstd else d)) for i, t, ts, d in rows]


def copy_bag(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return next(dst.glob("*.db3"))


def test_truncated_rosbag2_keeps_the_rows_before_the_cut(ci_ros2: SimulationResult, work: Path) -> None:
    rows = db_rows(ci_ros2.log_path)
    bag = work / "half_ros2"
    db3 = copy_bag(ci_ros2.log_path, bag)
    data = db3.read_bytes()
    db3.write_bytes(data[: len(data) // 2])
    got, warnings = read_all(bag)
    # exactly a prefix of the rows by id, and most of what the first half of the file holds
    n = len(got)
    assert Counter(got) == Counter(m for _, m in rows[:n])
    assert 0.4 * len(rows) < n < len(rows)
    assert any(str(db3) in w and f"ids {rows[n][0]}-{rows[-1][0]}" in w for w in warnings), warnings
    assert sorted(p.name for p in bag.iterdir()) == [db3.name, "metadata.yaml"]


def killed_wal_recording(intact: Path, bag: Path, batch: int = 50) -> tuple[int, int]:
    """``intact``'s bag as a WAL-mode recording (rosbag2's ``resilient`` preset) killed before its last
    checkpoint: its first two thirds of rows in the .db3, the rest committed ``batch`` rows per transaction into
    the -wal beside it (no automatic checkpoint), the files copied while the writer still holds them. Returns
    the first row id only the log holds and the last transaction's first id."""
    writer = bag.with_name(bag.name + "_writer")
    db3 = copy_bag(intact, writer)
    con = sqlite3.connect(db3)
    (n,) = con.execute("SELECT count(*) FROM messages").fetchone()
    cut = 2 * n // 3
    tail = con.execute("SELECT id, topic_id, timestamp, data FROM messages WHERE id > ? ORDER BY id",
                       (cut,)).fetchall()
    con.execute("DELETE FROM messages WHERE id > ?", (cut,))
    con.commit()
    con.execute("VACUUM")
    assert con.execute("PRAGMA journal_mode=WAL").fetchone() == ("wal",)
    con.execute("PRAGMA wal_autocheckpoint=0")
    for i in range(0, len(tail), batch):
        con.executemany("INSERT INTO messages (id, topic_id, timestamp, data) VALUES (?, ?, ?, ?)", tail[i:i + batch])
        con.commit()
    bag.mkdir()
    for f in writer.iterdir():
        if not f.name.endswith("-shm"):
            shutil.copyfile(f, bag / f.name)
    con.close()
    return tail[0][0], tail[(len(tail) - 1) // batch * batch][0]


@pytest.mark.parametrize("metadata", [True, False])
def test_rosbag2_killed_wal_recording_keeps_what_its_log_committed(metadata: bool, ci_ros2: SimulationResult,
                                                                   work: Path) -> None:
    """A WAL-mode recording killed before its last checkpoint holds its last rows only in the -wal file, which
    an immutable open (rosbags', and ours) never reads: every row is read, with the log's committed pages, and
    nothing is written beside the input (no -shm, no checkpoint). Without metadata.yaml (``ros2 bag record``
    writes it last) the directory is read from its storage files."""
    rows = db_rows(ci_ros2.log_path)
    bag = work / f"killed_wal_{metadata}"
    first_in_log, _ = killed_wal_recording(ci_ros2.log_path, bag)
    if not metadata:
        (bag / "metadata.yaml").unlink()
    db3 = next(bag.glob("*.db3"))
    with sqlite3.connect(f"file:{db3}?immutable=1", uri=True) as db:  # the file alone: two thirds
        assert db.execute("SELECT max(id) FROM messages").fetchone() == (first_in_log - 1,)
    before = {f.name: f.read_bytes() for f in bag.iterdir()}
    got, warnings = read_all(bag)
    assert Counter(got) == Counter(m for _, m in rows)
    assert any(str(db3) in w and "write-ahead log" in w and "committed pages" in w for w in warnings), warnings
    assert {f.name: f.read_bytes() for f in bag.iterdir()} == before
    from typer.testing import CliRunner

    from autosar_cli.cli import app

    r = CliRunner().invoke(app, ["info", str(bag), "--json"])  # a bag, not a plain directory, without its yaml
    assert r.exit_code == 0 and sum(s["count"] for s in json.loads(r.stdout)["streams"]) == len(rows), r.output


def test_rosbag2_wal_torn_last_transaction_is_left_out(ci_ros2: SimulationResult, work: Path) -> None:
    """A log whose last frame is torn (the writer killed while appending it) loses only the transaction that
    frame would have committed: the rows before it are read, none of it."""
    rows = db_rows(ci_ros2.log_path)
    bag = work / "torn_wal"
    _, last_txn = killed_wal_recording(ci_ros2.log_path, bag)
    wal = next(bag.glob("*.db3-wal"))
    wal.write_bytes(wal.read_bytes()[:-100])
    got, warnings = read_all(bag)
    assert Counter(got) == Counter(m for i, m in rows if i < last_txn)
    assert any("write-ahead log" in w for w in warnings), warnings


def test_rosbag2_storage_file_given_on_its_own(ci_ros2: SimulationResult, work: Path) -> None:
    """A bag's .db3 given on its own (a copied file, a killed recording's) reads its rows, by SQL, those of that
    file only: where its directory's metadata.yaml lists more files, a warning says the bag has more."""
    rows = db_rows(ci_ros2.log_path)
    db3 = next(ci_ros2.log_path.glob("*.db3"))
    got, warnings = read_all(db3)
    assert Counter(got) == Counter(m for _, m in rows) and warnings == []
    bag = work / "two_files"
    bag.mkdir()
    for name in ("b_0.db3", "b_1.db3"):
        shutil.copyfile(db3, bag / name)
    meta = yaml.safe_load((ci_ros2.log_path / "metadata.yaml").read_text())
    meta["rosbag2_bagfile_information"]["relative_file_paths"] = ["b_0.db3", "b_1.db3"]
    (bag / "metadata.yaml").write_text(yaml.safe_dump(meta))
    got, warnings = read_all(bag / "b_1.db3")
    assert Counter(got) == Counter(m for _, m in rows)
    assert warnings == [f"{bag / 'b_1.db3'}: one of the 2 storage files of the bag {bag}; give the directory to read "
                        "them all"]


def test_wal_with_a_bad_header_checksum_is_not_applied() -> None:
    from autosar_cli.ingest.sqlite_wal import apply_wal

    header = struct.pack(">8I", 0x377F0682, 3007000, 4096, 0, 1, 2, 0, 0)
    assert apply_wal(b"SQLite format 3\x00" + bytes(4080), header + bytes(24 + 4096)) is None


def test_rosbag2_zstd_error_names_file_row_and_topic(ci_ros2: SimulationResult, work: Path) -> None:
    rows = db_rows(ci_ros2.log_path)
    bag = work / "zstd_ros2"
    db3 = copy_bag(ci_ros2.log_path, bag)
    db = sqlite3.connect(db3)
    with db:
        (row_id, topic), = db.execute("SELECT messages.id, topics.name FROM messages JOIN topics ON "
                                      "topics.id = topic_id WHERE topics.name = '/scanbrick/raw_frames' "
                                      "ORDER BY messages.id LIMIT 1 OFFSET 400").fetchall()
        blob = bytearray(db.execute("SELECT data FROM messages WHERE id = ?", (row_id,)).fetchone()[0])
        blob[:4] = bytes(4)  # the zstd frame magic
        db.execute("UPDATE messages SET data = ? WHERE id = ?", (bytes(blob), row_id))
    db.close()
    msgs = ingest([bag], work / "zstd_ros2.h5", config=load_config())
    assert any(str(db3) in w and f"row {row_id}" in w and topic in w for w in msgs.warnings), msgs.warnings
    radar = {s["path"]: s for s in msgs.streams}["radar/scanbrick_w43"]
    assert radar["written"] == sum(1 for _, m in rows if m[0] == topic) - 1


def _mount_tmpfs(where: Path) -> bool:
    where.mkdir()
    return subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64m", "tmpfs", str(where)],
                          capture_output=True).returncode == 0


def test_rosbag2_sqlite_read_direct_writes_nothing_and_works_read_only(ci_ros2: SimulationResult,
                                                                        work: Path) -> None:
    """A WAL-mode database whose QoS mismatch sends every topic to the direct SQL reader."""
    bag = work / "wal_ros2"
    db3 = copy_bag(ci_ros2.log_path, bag)
    db = sqlite3.connect(db3)
    db.execute("PRAGMA journal_mode=WAL")
    db.close()
    meta_path = bag / "metadata.yaml"
    meta = yaml.safe_load(meta_path.read_text())
    for entry in meta["rosbag2_bagfile_information"]["topics_with_message_count"]:
        for q in entry["topic_metadata"]["offered_qos_profiles"]:
            q["reliability"] = "best_effort"
    meta_path.write_text(yaml.safe_dump(meta, sort_keys=False))
    before = sorted(p.name for p in bag.iterdir())
    want = Counter(m for _, m in db_rows(ci_ros2.log_path))
    got, _ = read_all(bag)
    assert Counter(got) == want
    assert sorted(p.name for p in bag.iterdir()) == before  # no -wal / -shm left in the input directory

    media = work / "ro_media"
    if not _mount_tmpfs(media):
        pytest.skip("cannot mount a tmpfs here (not root)")
    try:
        shutil.copytree(bag, media / "bag")
        subprocess.run(["mount", "-o", "remount,ro", str(media)], check=True)
        got, _ = read_all(media / "bag")
        assert Counter(got) == want
    finally:
        subprocess.run(["umount", str(media)], check=False)


# ------------------------------------------------------------------------------------------- MCAP
def mcap_chunks(path: Path) -> list[tuple[int, int, list[Msg]]]:
    """(record start, record end, messages) of every chunk, from the intact file's summary."""
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
        assert summary is not None
        topics = {c.id: c.topic for c in summary.channels.values()}
        out = []
        for ci in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
            f.seek(ci.chunk_start_offset + 9)
            chunk = Chunk.read(ReadDataStream(io.BytesIO(f.read(ci.chunk_length - 9))))
            msgs = [(topics[r.channel_id], r.log_time, bytes(r.data)) for r in breakup_chunk(chunk)
                    if isinstance(r, Message)]
            out.append((ci.chunk_start_offset, ci.chunk_start_offset + ci.chunk_length, msgs))
    return out


def test_mcap_bad_first_chunk_opcode_costs_only_that_chunk(ci_mcap: SimulationResult, work: Path) -> None:
    chunks = mcap_chunks(ci_mcap.log_path)
    start, end, _ = chunks[0]
    data = bytearray(ci_mcap.log_path.read_bytes())
    assert start == 69
    data[69] = 0x04  # the first chunk now reads as a channel record that does not parse
    log = work / "b69.mcap"
    log.write_bytes(bytes(data))
    got, warnings = read_all(log)
    # the channels it declared are taken from the summary: every other chunk is kept
    assert Counter(got) == Counter(m for s, _, msgs in chunks if s != start for m in msgs)
    assert any(str(log) in w and f"bytes 69-{end}" in w and "channel record" in w for w in warnings), warnings


def mcap_record_ends(data: bytes) -> list[tuple[int, int]]:
    """(opcode, end offset) of every record of a decompressed MCAP chunk."""
    out, at = [], 0
    while at < len(data):
        op, length = struct.unpack_from("<BQ", data, at)
        at += 9 + length
        out.append((op, at))
    return out


def test_mcap_cut_inside_a_chunk_keeps_its_whole_messages(ci_mcap: SimulationResult, work: Path) -> None:
    """Cut two thirds into a zstd chunk (a copy or a disk that ran out mid-write), the file keeps every chunk
    before it and the cut chunk's messages whose records the decoded prefix holds whole: those of the intact
    chunk, decompressed whole by the mcap library, that end within the bytes the warning says were decoded."""
    chunks = mcap_chunks(ci_mcap.log_path)
    data = ci_mcap.log_path.read_bytes()
    start, end, cut_msgs = chunks[len(chunks) // 2]
    log = work / "cut_inside.mcap"
    cut = cut_two_thirds_in(data, start, end, log)
    got, warnings = read_all(log)
    assert len(warnings) == 1 and warnings[0].startswith(f"{log}: damaged MCAP at byte {start} of {cut}: "), warnings
    kept, decoded, size = (int(x) for x in re.search(r"(\d+) whole messages kept from (\d+) of its (\d+) bytes "
                                                       r"\(its CRC could not be checked\)", warnings[0]).groups())
    chunk = Chunk.read(ReadDataStream(io.BytesIO(data[start + 9:end])))
    import zstandard

    whole = zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
    ends = [e for op, e in mcap_record_ends(whole) if op == 0x05]
    assert size == len(whole) and len(ends) == len(cut_msgs)
    assert 0 < decoded < size and kept == sum(e <= decoded for e in ends) > 0
    assert Counter(got) == Counter([m for _, e, msgs in chunks if e <= start for m in msgs] + cut_msgs[:kept])


@pytest.mark.parametrize("name, kept_whole", [("rosbag2_tests_mcap_cdr_test/cdr_test_0.mcap", True),
                                              ("rosbag2_py_mcap_talker/talker.mcap", False)])
def test_real_mcap_cut_inside_its_chunk(name: str, kept_whole: bool, tmp_path: Path) -> None:
    """ROS 2's own MCAP files (rosbag2's test resources), each one chunk, cut two thirds into it: the uncompressed
    chunk keeps the messages whose records end before the cut, by the mcap library's reading of the intact file;
    the zstd one (2965 bytes, inside zstd's first block) gives none back, and says so, rather than anything else."""
    src = realdata("ros2-rosbag2", *name.split("/"))
    chunks = mcap_chunks(src)
    assert len(chunks) == 1
    start, end, msgs = chunks[0]
    data = src.read_bytes()
    log = tmp_path / "cut.mcap"
    cut = cut_two_thirds_in(data, start, end, log)
    got, warnings = read_all(log)
    import zstandard

    chunk = Chunk.read(ReadDataStream(io.BytesIO(data[start + 9:end])))
    records_start = end - len(chunk.data)  # the records are the chunk record's last bytes
    whole = bytes(chunk.data) if not chunk.compression else zstandard.ZstdDecompressor().decompress(
        chunk.data, max_output_size=chunk.uncompressed_size)
    ends = [e for op, e in mcap_record_ends(whole) if op == 0x05]
    expected = sum(records_start + e <= cut for e in ends) if kept_whole else 0
    assert len(ends) == len(msgs) and (expected > 0) == kept_whole
    assert Counter(got) == Counter(msgs[:expected])
    assert len(warnings) == 1 and f"{expected} whole messages kept" in warnings[0], warnings


@pytest.mark.parametrize("compression", ["zstd", "lz4", ""])
def test_mcap_cut_chunk_prefix_decodes_for_every_codec(compression: str) -> None:
    """A chunk's compressed data cut anywhere decodes to a prefix of its payload, for each MCAP codec."""
    import lz4.frame
    import zstandard

    from autosar_cli.ingest.mcap_source import _decode

    rng = np.random.default_rng(3)
    payload = rng.integers(0, 16, 600_000, dtype=np.uint8).tobytes()  # compressible, not trivially
    packed = {"zstd": zstandard.ZstdCompressor().compress, "lz4": lz4.frame.compress,
              "": bytes}[compression](payload)
    for frac in (0.3, 0.7, 1.0):
        part = packed[:int(len(packed) * frac)]
        out = _decode(Chunk(compression=compression, data=part, message_start_time=0, message_end_time=0,
                            uncompressed_crc=0, uncompressed_size=len(payload)), prefix=True)
        assert out == payload[:len(out)]
        assert len(out) == len(payload) if frac == 1.0 else 0 < len(out) < len(payload)


@pytest.mark.parametrize("where", ["message index length", "chunk length"])
def test_mcap_bad_record_length_resynchronises(where: str, ci_mcap: SimulationResult, work: Path) -> None:
    """A record length that runs past the file's end: a message index's costs only that record (reading
    resynchronises on the next one); a chunk's costs nothing, its own records length placing its end (it passes
    its CRC there), and reading goes on after it."""
    chunks = mcap_chunks(ci_mcap.log_path)
    data = bytearray(ci_mcap.log_path.read_bytes())
    start, end, _ = chunks[1]
    if where == "chunk length":
        data[start + 5] = 0x01  # length byte 4: +4 GiB
    else:  # the message index record right after the first chunk: nothing of value is in it
        assert data[chunks[0][1]] == 0x07
        data[chunks[0][1] + 3] = 0x77
    log = work / f"len_{where.replace(' ', '_')}.mcap"
    log.write_bytes(bytes(data))
    got, warnings = read_all(log)
    assert Counter(got) == Counter(m for _, _, msgs in chunks for m in msgs)
    if where == "chunk length":
        assert warnings == [f"{log}: damaged MCAP: the chunk at byte {start} says it is {end - start - 9 + (1 << 32)} "
                            f"bytes long, its records end at byte {end}: read by them"]
    else:
        hits = [w for w in warnings if str(log) in w and re.search(r"bytes \d+-\d+ skipped", w)]
        assert len(hits) == 1, warnings


def test_rosbag2_unreadable_metadata_reads_the_storage_anyway(ci_ros2: SimulationResult, work: Path) -> None:
    bag = work / "bad_meta"
    db3 = copy_bag(ci_ros2.log_path, bag)
    meta = bag / "metadata.yaml"
    text = bytearray(meta.read_bytes())
    text[len(text) // 2] = 0xFF  # not UTF-8 any more
    meta.write_bytes(bytes(text))
    got, warnings = read_all(bag)
    assert Counter(got) == Counter(m for _, m in db_rows(ci_ros2.log_path))
    assert any(str(meta) in w and db3.name in w for w in warnings), warnings


def test_mcap_cut_between_records_is_told_from_an_unindexed_one(ci_mcap: SimulationResult, work: Path) -> None:
    """An MCAP without a summary whose writer finished (its footer and closing magic present) reads with no
    warning; one cut exactly after a chunk, where no record is broken, keeps every chunk before the cut and says
    it ends without its footer (before, both said only "no MCAP summary (unindexed or truncated file)", which
    made every run on a complete unindexed log degraded and left the cut one unnamed)."""
    from mcap.writer import IndexType, Writer

    chunks = mcap_chunks(ci_mcap.log_path)
    unindexed = work / "unindexed.mcap"
    with open(ci_mcap.log_path, "rb") as f, open(unindexed, "wb") as out:
        w = Writer(out, index_types=IndexType.NONE, use_summary_offsets=False, use_statistics=False,
                   repeat_channels=False, repeat_schemas=False)
        w.start(profile="ros2", library="test")
        ids: dict[str, int] = {}
        for schema, channel, msg in make_reader(f).iter_messages(log_time_order=False):
            if channel.topic not in ids:
                ids[channel.topic] = w.register_channel(channel.topic, channel.message_encoding,
                                                        w.register_schema(schema.name, schema.encoding, schema.data))
            w.add_message(ids[channel.topic], msg.log_time, msg.data, msg.publish_time)
        w.finish()
    got, warnings = read_all(unindexed)
    assert warnings == [] and Counter(got) == Counter(m for _, _, msgs in chunks for m in msgs)
    cut = chunks[len(chunks) // 2][1]  # the end of a chunk record: the next byte starts a record
    log = work / "cut_between.mcap"
    log.write_bytes(ci_mcap.log_path.read_bytes()[:cut])
    got, warnings = read_all(log)
    assert Counter(got) == Counter(m for _, e, msgs in chunks if e <= cut for m in msgs)
    assert warnings == [f"{log}: damaged MCAP at byte {cut} of {cut}: file ends without its footer (truncated, "
                        "or its writer never finished); everything before it was read"]


@pytest.mark.parametrize("shift", [4096, -4096], ids=["bytes added", "bytes lost"])
def test_mcap_shifted_summary_is_found_by_its_data_end(shift: int, ci_mcap: SimulationResult, work: Path) -> None:
    """4 KiB added to (or lost from) the first chunk: the footer's summary offset then misses the summary, and the
    first chunk held the only schema and channel records of the data section. The summary is found by its DataEnd
    record: every other chunk is kept (before, the whole log was "no known sensor streams")."""
    chunks = mcap_chunks(ci_mcap.log_path)
    start, end, _ = chunks[0]
    data = ci_mcap.log_path.read_bytes()
    at = (start + end) // 2
    damaged = data[:at] + data[100:100 + shift] + data[at:] if shift > 0 else data[:at] + data[at - shift:]
    log = work / f"shifted_{shift}.mcap"
    log.write_bytes(damaged)
    got, warnings = read_all(log)
    assert Counter(got) == Counter(m for s, _, msgs in chunks if s != start for m in msgs)
    assert f"{log}: the footer's summary offset misses the summary (bytes added or lost before it); its schemas " \
           "and channels found by its DataEnd record, the chunk indexes not used" in warnings
    assert any(f"chunk ending at byte {end} skipped" in w for w in warnings), warnings


def test_rosbag2_topics_metadata_yaml_does_not_list_are_read_from_the_storage(ci_ros2: SimulationResult,
                                                                           work: Path) -> None:
    """rosbags reads the topics metadata.yaml lists: one it leaves out (hand-edited, or cut off at a line end so
    that it still parses) was lost without a word. The storage's own topics table is read too; a metadata.yaml cut
    so short that rosbags refuses it reads every topic the storage holds."""
    rows = db_rows(ci_ros2.log_path)
    bag = work / "unlisted_ros2"
    copy_bag(ci_ros2.log_path, bag)
    meta_path = bag / "metadata.yaml"
    meta = yaml.safe_load(meta_path.read_text())
    listed = meta["rosbag2_bagfile_information"]["topics_with_message_count"]
    gone = next(e["topic_metadata"]["name"] for e in listed if e["topic_metadata"]["name"].endswith("/fix"))
    meta["rosbag2_bagfile_information"]["topics_with_message_count"] = [
        e for e in listed if e["topic_metadata"]["name"] != gone]
    meta_path.write_text(yaml.safe_dump(meta))
    got, warnings = read_all(bag)
    assert Counter(got) == Counter(m for _, m in rows)
    n = sum(1 for _, m in rows if m[0] == gone)
    assert f"{bag}: metadata.yaml does not list {gone} ({n} messages); read from the sqlite3 storage" in warnings
    text = (ci_ros2.log_path / "metadata.yaml").read_text()
    meta_path.write_text(text[:text.index("topics_with_message_count")])  # still YAML; rosbags refuses it
    got, warnings = read_all(bag)
    assert Counter(got) == Counter(m for _, m in rows)
    assert any("rosbags failed when opened" in w for w in warnings), warnings
    meta_path.write_text(text[:text.index("topics_with_message_count")] + "  bad: [unclosed\n")  # no YAML at all
    got, warnings = read_all(bag)
    assert Counter(got) == Counter(m for _, m in rows)
    said = [w for w in warnings if "metadata" in w or "YAML" in w]
    assert said and all("\n" not in w for w in said), said  # YAML's message drew the place over five lines


def test_rosbag2_sqlite_header_that_declares_gigabytes_pads_nothing_in_memory(ci_ros2: SimulationResult,
                                                                           work: Path) -> None:
    """A storage file whose header's page count is damaged to 500000 pages (2 GB at 4 KiB): sqlite refuses it as
    it is, and the padding to the declared size that lets it read a cut file goes to a sparse temporary file (it
    took 4.2 GB of memory and 12 s in memory). Every row is read; random bytes behind sqlite's magic are refused,
    naming the file."""
    rows = db_rows(ci_ros2.log_path)
    bag = work / "pages_ros2"
    db3 = copy_bag(ci_ros2.log_path, bag)
    data = bytearray(db3.read_bytes())
    data[28:32] = (500_000).to_bytes(4, "big")
    db3.write_bytes(bytes(data))
    got, warnings = read_all(bag)
    assert Counter(got) == Counter(m for _, m in rows)
    assert any(f"{db3}: damaged sqlite3 storage: {len(data)} bytes, its header declares " in w for w in warnings)
    assert sorted(p.name for p in bag.iterdir()) == [db3.name, "metadata.yaml"]
    rng = np.random.default_rng(1200)
    db3.write_bytes(b"SQLite format 3\x00" + rng.integers(0, 256, 65536, dtype=np.uint8).tobytes())
    with pytest.raises(Exception, match=f"{re.escape(str(db3))}: not a readable sqlite3 file"):
        read_all(bag)


def test_what_went_wrong_before_an_ingest_error_is_said_with_it(ci_ros2: SimulationResult, work: Path) -> None:
    """A rosbag2 bag whose storage file is gone ends in "no known sensor streams"; the warnings gathered before it
    (the file metadata.yaml lists is missing, each topic's shortfall) were dropped with the drive. They come first,
    then the error, and no drive is written."""
    from typer.testing import CliRunner

    from autosar_cli.cli import app

    bag = work / "no_storage_ros2"
    db3 = copy_bag(ci_ros2.log_path, bag)
    db3.unlink()
    r = CliRunner().invoke(app, ["ingest", str(bag), "-o", str(work / "no_storage.h5")])
    lines = r.stderr.strip().splitlines()
    assert r.exit_code == 1 and "Traceback" not in r.output and not (work / "no_storage.h5").exists()
    assert lines[0] == f"warning: {bag}: storage file {db3.name} listed in metadata.yaml is missing", lines
    assert lines[-1].startswith(f"error: {bag}: no known sensor streams") and all(
        ln.startswith("warning: ") for ln in lines[:-1]), lines


def test_rosbag2_storage_mislabelled_in_metadata_is_read_as_what_its_files_are(ci_ros2: SimulationResult,
                                                                              work: Path) -> None:
    """metadata.yaml saying "mcap" over a sqlite3 storage file: before, "not an MCAP file" and nothing read; the
    files' own first bytes decide, every row is read, and a warning names the disagreement."""
    rows = db_rows(ci_ros2.log_path)
    bag = work / "mislabelled_ros2"
    copy_bag(ci_ros2.log_path, bag)
    meta_path = bag / "metadata.yaml"
    meta_path.write_text(meta_path.read_text().replace("storage_identifier: sqlite3", "storage_identifier: mcap"))
    got, warnings = read_all(bag)
    assert Counter(got) == Counter(m for _, m in rows)
    assert f"{bag}: metadata.yaml says 'mcap' storage, its files are sqlite3: read as what they are" in warnings


@pytest.mark.parametrize("where", ["payload", "log time"])
def test_an_uncompressed_chunk_failing_its_crc_is_read_when_asked_its_damage_in_one_message(work: Path,
                                                                                         where: str) -> None:
    """An uncompressed MCAP of 300 messages in small chunks, one byte changed in a message of the third chunk: its
    CRC fails. Left out by default, counted; read when asked: every message, the changed one alone differing where
    the byte lay in its payload, left out where it lay in its log time (its chunk's message index does not list it)."""
    from mcap.writer import CompressionType, Writer

    log = work / f"uncompressed_{where.replace(' ', '_')}.mcap"
    sent = [("/blob", 1_600_000_000_000_000_000 + k * 1_000_000, bytes([k % 256]) * 100) for k in range(300)]
    with open(log, "wb") as f:
        writer = Writer(f, compression=CompressionType.NONE, chunk_size=4096)
        writer.start()
        schema = writer.register_schema("test_msgs/msg/Blob", "ros2msg", b"uint8[] data")
        channel = writer.register_channel("/blob", "cdr", schema)
        for k, (_, t, payload) in enumerate(sent):
            writer.add_message(channel, t, payload, t, sequence=k)
        writer.finish()
    chunks = mcap_chunks(log)
    assert len(chunks) > 4 and [m for *_, msgs in chunks for m in msgs] == sent
    start, end, inside = chunks[2]
    data = bytearray(log.read_bytes())
    at = data.index(inside[3][2], start)  # its payload; its log time 16 bytes before (then the publish time)
    data[at + 50 if where == "payload" else at - 14] ^= 0xFF
    log.write_bytes(bytes(data))

    got, warnings = read_all(log)
    assert got == [m for m in sent if m not in inside]
    assert f"{log}: damaged MCAP: chunk ending at byte {end} skipped: its CRC does not match (its {len(inside)} " \
           "messages; autosar ingest --allow-unverified keeps them)" in warnings

    src = open_source(log, keep_unverified=True)
    got = [(m.channel.topic, m.log_ns, bytes(m.data)) for m in src.messages()]
    k = sent.index(inside[3])
    if where == "payload":
        assert len(got) == len(sent) and [n for n, (a, b) in enumerate(zip(got, sent, strict=True)) if a != b] == [k]
    else:
        assert got == sent[:k] + sent[k + 1:]
    first, last = (f"2020-09-13T12:26:40.{t // 10**6 % 1000:03d}Z" for _, t, _ in (inside[0], inside[-1]))
    unlisted = int(where != "payload")
    assert f"{log}: damaged MCAP: chunk ending at byte {end} read although its CRC does not match " \
           f"(--allow-unverified): its {len(inside) - unlisted} messages logged {first} to {last} kept, checked " \
           f"against its message index ({unlisted} it does not list left out); one or more of their bytes not as " \
           "written" in src.stats.warnings, src.stats.warnings
