"""Fault campaign: seeded faults against the CLI, each trial classified by what the user would see.

Usage: python benches/fault_campaign.py [--seed 0] [--jobs 1] [--workdir DIR] [--scale 1.0]

Simulates the ci drive (seed 7) as MCAP, ROS1 bag and rosbag2 (sqlite3), ingests, navigates and focuses
it once for reference products, then runs trials of these classes through ``python -m autosar_cli.cli``
in subprocesses (minimum counts at ``--scale 1``):

    mcap 100, ros1 40, rosbag2 40   byte flips, truncations, damaged record headers / index / metadata
    ros1-records 40                 the ROS1 bag rewritten with its chunks uncompressed (`rosbag record`'s
                                    default: nothing but the records' lengths frames its messages), 1-3 bytes
                                    of message records' framing (their two lengths and header) overwritten
    hdf5 60                         byte flips in drive.h5 and trajectory.h5, then focus
    config 30                       non-finite, negative, huge, mistyped, missing and non-UTF-8 values
    kill 30                         SIGKILL / SIGINT at a random moment of ingest or focus, then a rerun
    disk-full 5                     ingest and focus onto a 5 MiB tmpfs (skipped with a message if no mount)
    path 12                         outputs that are inputs, directories, under files, 255-byte names; a named
                                    pipe and a symbolic link loop as inputs
    dca1000 40                      a TI DCA1000 capture (beside its navigation MCAP): packets lost, reordered,
                                    repeated or overwritten in a recording split across files, a split file
                                    missing, a packet zero-filled or the data cut in the post-processed file,
                                    an edited number in its mmWave Studio JSON (flipped ADC sample bits are
                                    left out: the format carries no checksum to find them by); from trial 40 on,
                                    what a re-run or a setup of other frames leaves (``DCA_SETUP_KINDS``): a second
                                    recording appended (in one file, split, after a first cut short, of under 64
                                    packets), an earlier, longer recording's split files or adc_data.bin left
                                    beside this one's, a second series beside it, frames of another recording after
                                    adc_data.bin's; numFrames above or below the frames held, the data cut at a
                                    frame's end or followed by a partial frame, numLoops with or without the frame
                                    period scaled, a frame period the per-frame triggers contradict
    canlog 40                       standalone CAN logs cut short at a random byte (``autosar info --json``):
                                    ASC, TRC, candump -L and BLF written by python-can (2000 frames), and a
                                    real CANedge MDF4 file (``../shared/realdata``; its trials skipped without)
    realfiles 56                    other people's recordings (``../shared/realdata``: the Husky's ROS1 bag, two
                                    CANedge MDF4 files, a u-blox NMEA capture) cut, with 1, 8 or 64 bytes
                                    overwritten, 4 KiB zeroed, added or lost at a random place, then ingested
    finalised 28                    the two CANedge MDF4 files as asammdf finalises them (sorted groups, the
                                    data bytes in SD blocks), damaged as realfiles' are

Outcomes: clean-error (exit != 0, one error line, no traceback), kept-with-warning, ok, crash-or-traceback,
silent-wrong (exit 0, product differs from the undamaged one, no warning), input-harmed (an input's bytes
changed), partial-left (a *.partial remains after the next run). For damaged MCAP and ROS1 logs the
messages ingested are checked against the messages of the chunks the damage did not touch; for a cut text CAN
log, the frames read against python-can's count on the log's whole lines before the cut. Each MCAP trial's log is
also read by the MCAP reader in this process without and with ``--allow-unverified`` (chunks whose CRC alone fails
read too): the messages read, and of them those the undamaged file does not hold (``mcap_allow_unverified``).

Prints the counts per class and writes benches/results/fault_campaign.json (``--classes`` runs a subset
and merges it into that file's earlier run of the same seed and scale).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import random
import re
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

RESULTS = Path(__file__).resolve().parent / "results"
REPO = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "autosar_cli.cli"]
OUTCOMES = ("clean-error", "kept-with-warning", "ok", "crash-or-traceback", "silent-wrong", "input-harmed",
            "partial-left")
BAD = ("crash-or-traceback", "silent-wrong", "input-harmed", "partial-left")
COUNTS = {"mcap": 100, "ros1": 40, "ros1-records": 40, "rosbag2": 40, "hdf5": 60, "config": 30, "kill": 30,
          "disk-full": 5, "path": 12,
          "dca1000": 70, "canlog": 40, "realfiles": 56, "finalised": 28}
PACKET = 1456  #: the DCA1000's default data bytes per packet


@dataclass
class Trial:
    cls: str
    n: int
    fault: str
    outcome: str = ""
    rc: int | None = None
    detail: str = ""
    chunks_expected: int | None = None  #: messages of the chunks the damage left intact (MCAP, ROS1)
    messages_read: int | None = None
    messages_whole: int | None = None  #: realfiles: the messages of the file undamaged
    #: MCAP: (messages read, of them not in the undamaged file) by the reader as ingest runs it, and with
    #: ``--allow-unverified`` (chunks whose CRC alone fails read too)
    unverified: dict[str, int] | None = None
    wall_s: float = 0.0


@dataclass
class Base:
    """The undamaged inputs and their products."""

    dir: Path
    mcap: Path
    ros1: Path
    ros2: Path
    drive: Path
    traj: Path
    image: Path
    dca_mcap: Path | None = None  #: the navigation log of the DCA1000 drive, with its frame-sync topic
    dca_flat: Path | None = None  #: its capture as post-processed data (adc_data.bin)
    dca_packets: Path | None = None  #: the same as recorded packets, one stream of bytes (cut into files per trial)
    can_logs: dict[str, Path] = field(default_factory=dict)  #: suffix -> an undamaged CAN log
    can_frames: dict[str, int] = field(default_factory=dict)  #: suffix -> its frames
    mcap_chunks: list[tuple[int, int, int]] = field(default_factory=list)  #: (start, end, messages)
    mcap_messages: Counter[tuple[str, int, bytes]] = field(default_factory=Counter)  #: (topic, time, digest)
    ros1_chunks: list[tuple[int, int, int]] = field(default_factory=list)
    ros1u: Path | None = None  #: the ROS1 bag with its chunks uncompressed
    ros1u_records: list[tuple[int, int]] = field(default_factory=list)  #: (start, data start) of its messages
    digests: dict[str, str] = field(default_factory=dict)
    real_warnings: dict[str, set[str]] = field(default_factory=dict)  #: a real input's warnings, undamaged
    real_messages: dict[str, int] = field(default_factory=dict)  #: the messages a real input gives, undamaged


# ------------------------------------------------------------------------------------------ helpers
def cli(args: list[str], cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run(CLI + args, cwd=cwd, capture_output=True, text=True, timeout=timeout, env=_env())


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = f"{REPO}{os.pathsep}{env.get('PYTHONPATH', '')}"
    env["COLUMNS"] = "200"
    return env


def tree_hash(path: Path) -> str:
    if not path.exists():
        return "missing"
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    h = hashlib.sha256()
    for p in files:
        h.update(str(p.relative_to(path) if path.is_dir() else p.name).encode())
        h.update(hashlib.file_digest(open(p, "rb"), "sha256").digest())  # noqa: SIM115
    if path.is_dir():
        h.update(repr(sorted(q.name for q in path.iterdir())).encode())  # stray -wal/-shm files count as harm
    return h.hexdigest()


def product_datasets(f: Any) -> list[tuple[str, Any]]:
    """An open HDF5 product's datasets (name, dataset), in visiting order, provenance and inputs left out: what
    two products of the same input must share."""
    import h5py

    import autosar_cli.store.drive  # noqa: F401  (registers the compression filters)

    found: list[tuple[str, Any]] = []

    def visit(name: str, obj: object) -> None:
        if isinstance(obj, h5py.Dataset) and not name.startswith(("provenance", "inputs")):
            found.append((name, obj))

    f.visititems(visit)
    return found


def product_digest(path: Path) -> str:
    """sha256 over every dataset of an HDF5 product (names and values; attributes and provenance left out)."""
    import h5py

    h = hashlib.sha256()
    with h5py.File(path, "r") as f:
        for name, obj in product_datasets(f):
            h.update(name.encode())
            h.update(obj[()].tobytes() if obj.shape != () else repr(obj[()]).encode())
    return h.hexdigest()


def classify(r: subprocess.CompletedProcess[str], product: Path | None, reference: str | None,
             warned: bool = False) -> tuple[str, str]:
    """Outcome of one finished command (input harm and partials are checked by the caller). ``warned``: the
    command's JSON report carries warnings (``--json`` prints them there, not on stderr)."""
    text = r.stdout + r.stderr
    if r.returncode < 0 or "Traceback" in text or r.returncode not in (0, 1, 2, 130):
        return "crash-or-traceback", text.strip().splitlines()[-1][:200] if text.strip() else f"rc {r.returncode}"
    if r.returncode != 0:
        lines = [ln for ln in r.stderr.splitlines() if ln.strip() and not ln.startswith("warning:")]
        errors = [ln for ln in lines if ln.startswith("error:")]
        if len(errors) == 1:
            return "clean-error", errors[0][:200]
        return "crash-or-traceback", f"{len(errors)} error lines: {(lines or [''])[-1][:160]}"
    warned = warned or "warning:" in r.stderr
    if product is None or reference is None:
        return ("kept-with-warning" if warned else "ok"), ""
    try:
        same = product_digest(product) == reference
    except Exception as exc:  # an exit-0 product that cannot be read back is wrong output
        return "silent-wrong", f"product unreadable: {exc}"[:200]
    if same:
        return "ok", ""
    return ("kept-with-warning", "") if warned else ("silent-wrong", "product differs, no warning")


def drive_difference(product: Path, reference: Path) -> str:
    """What differs between two drive files: the radar samples changed (how many, in how many frames, the largest
    change in ADC counts against the frames' RMS), else the other datasets that differ. ROS containers carry no
    checksum, so a flipped byte inside a radar sample reaches the drive unseen; this says whether that is all."""
    import h5py
    import numpy as np

    other: list[str] = []
    radar: list[str] = []
    with h5py.File(product, "r") as new, h5py.File(reference, "r") as ref:
        for name, obj in product_datasets(ref):
            a, b = obj[()], new[name][()] if name in new else None
            if b is None or a.shape != b.shape:
                other.append(name)
            elif name.endswith("/raw"):
                changed = a != b
                if changed.any():
                    frames = changed.reshape(len(a), -1).any(axis=1)
                    delta = np.abs(b.astype(np.int32) - a.astype(np.int32))[changed]
                    rms = float(np.sqrt(np.mean(a[frames].astype(np.float64) ** 2)))
                    radar.append(f"{name}: {int(changed.sum())} samples in {int(frames.sum())} frames changed by up "
                                 f"to {int(delta.max())} counts (the frames' RMS {rms:.0f})")
            elif not np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"):
                other.append(name)
    return "; ".join(radar + ([f"also {', '.join(other[:4])}"] if other else [])) or "no dataset differs"


def partials(where: Path) -> list[str]:
    return sorted(str(p.relative_to(where)) for p in where.rglob("*") if ".partial" in p.name)


# ------------------------------------------------------------------------------------ chunk layout
def mcap_chunks(path: Path) -> list[tuple[int, int, int]]:
    """(record start, record end, messages) of every chunk, from the intact file's summary."""
    import io

    from mcap.data_stream import ReadDataStream
    from mcap.reader import make_reader
    from mcap.records import Chunk, Message
    from mcap.stream_reader import breakup_chunk

    out = []
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
        assert summary is not None
        for c in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
            f.seek(c.chunk_start_offset + 9)
            chunk = Chunk.read(ReadDataStream(io.BytesIO(f.read(c.chunk_length - 9))))
            n = sum(1 for r in breakup_chunk(chunk) if isinstance(r, Message))
            out.append((c.chunk_start_offset, c.chunk_start_offset + c.chunk_length, n))
    return out


def ros1_chunks(path: Path) -> list[tuple[int, int, int]]:
    from rosbags.rosbag1 import Reader

    with Reader(path) as reader:
        per: Counter[int] = Counter(e.chunk_pos for entries in reader.indexes.values() for e in entries)
        return [(pos, reader.chunks[pos].datapos + reader.chunks[pos].datasize, n) for pos, n in sorted(per.items())]


def uncompressed_ros1(bag: Path, out: Path) -> tuple[Path, list[tuple[int, int]]]:
    """``bag`` rewritten by rosbags' writer with its chunks uncompressed, and its message records' (start, data
    start) in the file, walked by their two lengths."""
    from rosbags.rosbag1 import Reader, Writer

    with Reader(bag) as reader, Writer(out) as writer:
        conns = {c.id: writer.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest)
                 for c in reader.connections}
        for c, t, d in reader.messages():
            writer.write(conns[c.id], t, d)
    data = out.read_bytes()
    records = []
    with Reader(out) as reader:
        for ch in reader.chunks.values():
            at = ch.datapos
            while at < ch.datapos + ch.datasize:
                (hlen,) = struct.unpack_from("<I", data, at)
                (dlen,) = struct.unpack_from("<I", data, at + 4 + hlen)
                if b"op=\x02" in data[at + 4:at + 4 + hlen]:
                    records.append((at, at + 8 + hlen))
                at += 8 + hlen + dlen
    return out, sorted(records)


def mcap_messages(path: Path, keep_unverified: bool) -> Counter[tuple[str, int, bytes]]:
    """(topic, log time, payload digest) of every message the MCAP reader gives of ``path``."""
    from autosar_cli.ingest.mcap_source import McapSource

    got: Counter[tuple[str, int, bytes]] = Counter()
    for m in McapSource(path, keep_unverified=keep_unverified).messages():
        got[(m.channel.topic, m.log_ns, hashlib.blake2b(m.data, digest_size=8).digest())] += 1
    return got


def unverified_read(base: Base, log: Path) -> dict[str, int]:
    """What the MCAP reader gives of the damaged ``log`` without and with ``--allow-unverified``: messages read,
    and of them, those the undamaged file does not hold (wrong)."""
    out = {"messages_whole": base.mcap_messages.total()}
    for name, keep in (("read", False), ("read_unverified", True)):
        try:
            got = mcap_messages(log, keep)
        except Exception:  # a file the reader refuses: the CLI trial says how
            got = Counter()
        out[name] = got.total()
        out[name.replace("read", "wrong")] = (got - base.mcap_messages).total()
    return out


def intact(chunks: list[tuple[int, int, int]], damaged: list[tuple[int, int]]) -> int:
    """Messages of the chunks no damaged byte range [a, b) touches."""
    return sum(n for s, e, n in chunks if not any(a < e and b > s for a, b in damaged))


# ------------------------------------------------------------------------------------------- setup
def setup(work: Path) -> Base:
    for fmt, name in (("mcap", "ci.mcap"), ("ros1", "ci.bag"), ("ros2", "ci_ros2")):
        r = cli(["simulate", "-s", "ci", "-f", fmt, "--seed", "7", "-o", name], work)
        assert r.returncode == 0, r.stderr
    base = Base(work, work / "ci.mcap", work / "ci.bag", work / "ci_ros2", work / "drive.h5", work / "traj.h5",
                work / "image.h5")
    for args in (["ingest", "ci.mcap", "-o", "drive.h5"], ["navigate", "drive.h5", "-o", "traj.h5"],
                 ["focus", "drive.h5", "-t", "traj.h5", "-o", "image"]):
        r = cli(args, work)
        assert r.returncode == 0, r.stderr
    for name, log in (("mcap", "ci.mcap"), ("ros1", "ci.bag"), ("rosbag2", "ci_ros2")):
        r = cli(["ingest", log, "-o", f"ref_{name}.h5"], work)
        assert r.returncode == 0, r.stderr
        base.digests[name] = product_digest(work / f"ref_{name}.h5")
    base.digests["image"] = product_digest(base.image)
    base.digests["traj"] = product_digest(base.traj)
    base.mcap_chunks = mcap_chunks(base.mcap)
    base.mcap_messages = mcap_messages(base.mcap, keep_unverified=False)
    base.ros1_chunks = ros1_chunks(base.ros1)
    base.ros1u, base.ros1u_records = uncompressed_ros1(base.ros1, work / "ci_uncompressed.bag")
    r = cli(["ingest", base.ros1u.name, "-o", "ref_ros1-records.h5"], work)
    assert r.returncode == 0, r.stderr
    base.digests["ros1-records"] = product_digest(work / "ref_ros1-records.h5")
    r = cli(["simulate", "-s", "ci", "-f", "dca1000", "--seed", "7", "-o", "dca.mcap"], work)
    assert r.returncode == 0, r.stderr
    base.dca_mcap, base.dca_flat = work / "dca.mcap", work / "dca.dca1000"
    r = cli(["ingest", "dca.mcap", "--radar", "dca.dca1000", "-o", "ref_dca1000.h5"], work)
    assert r.returncode == 0, r.stderr
    base.digests["dca1000"] = product_digest(work / "ref_dca1000.h5")
    base.dca_packets = work / "dca_packets.bin"
    from autosar_cli.ingest.dca1000_packets import packets_of

    base.dca_packets.write_bytes(b"".join(packets_of((base.dca_flat / "adc_data.bin").read_bytes(), PACKET)))
    _can_logs(base, work)
    _real_files(base, work)
    return base


REAL = REPO.parent / "shared" / "realdata"
_CSS = ["--dbc", str(REAL / "css-electronics" / "gnss.dbc"), "--config",
        str(REPO / "configs" / "examples" / "css_canedge_gnss.toml")]
#: (name, file under ../shared/realdata, the ingest arguments that read it, given its damaged copy)
REAL_INPUTS: list[tuple[str, str, Callable[[Path], list[str]]]] = [
    ("Husky ROS1 bag", "robot_localization/test1.bag",
     lambda p: [str(p), "--config", str(REPO / "configs" / "examples" / "husky_test1.toml")]),
    ("CANedge MF4 2022", "css-electronics/2F6913DB_00000004_00000001.MF4", lambda p: ["--can-log", str(p), *_CSS]),
    ("CANedge MF4 2023", "css-electronics/2F6913DB_00001089_00000001-63BEF5CD.MF4",
     lambda p: ["--can-log", str(p), *_CSS]),
    ("NEO-M8N NMEA", "gpsd/neo-m8n.log", lambda p: ["--nmea", str(p)]),
]
#: the CANedge files as asammdf finalises them (sorted groups, data bytes in SD blocks), written at setup
FINALISED_INPUTS = [(f"finalised {name}", f"finalised/{Path(rel).stem}.mf4", args)
                    for name, rel, args in REAL_INPUTS if rel.endswith(".MF4")]
REAL_DAMAGE = ("cut", "1 byte overwritten", "8 bytes overwritten", "64 bytes overwritten", "4 KiB zeroed",
               "4 KiB added", "4 KiB lost")


def _real_files(base: Base, work: Path) -> None:
    """Each real input's drive.h5 as it ingests undamaged (the reference its damaged copies are held to), and the
    warnings it gives undamaged (no radar, a DBC's reused names), which say nothing of damage."""
    from asammdf import MDF

    for (_, rel, _), (_, finalised, _) in zip([i for i in REAL_INPUTS if i[1].endswith(".MF4")], FINALISED_INPUTS,
                                              strict=True):
        if (REAL / rel).is_file():
            (work / finalised).parent.mkdir(exist_ok=True)
            with MDF(REAL / rel) as mdf:
                mdf.save(work / finalised, overwrite=True, compression=0)
    for name, rel, args in [*REAL_INPUTS, *FINALISED_INPUTS]:
        root = work if rel.startswith("finalised/") else REAL
        if (root / rel).is_file():
            out = work / f"ref_real_{len(base.digests)}.h5"
            r = cli(["ingest", *args(root / rel), "-o", str(out), "--allow-partial", "--json"], work)
            assert r.returncode == 0, r.stderr
            base.digests[f"real:{name}"] = product_digest(out)
            report = json.loads(r.stdout)
            base.real_warnings[name] = {w.replace(str(root / rel), "LOG") for w in report["warnings"]}
            base.real_messages[name] = int(report["messages"])


def _can_logs(base: Base, work: Path) -> None:
    """2000 frames (two channels, standard IDs, 0-8 data bytes) written by python-can per text format and BLF,
    and the real 2022 CANedge MDF4 file where ../shared/realdata has it."""
    import can

    rng = random.Random(7)
    frames = [can.Message(timestamp=1.6e9 + 0.001 * i, arbitration_id=rng.randrange(0x7FF), channel=i % 2,
                          data=bytes(rng.randrange(256) for _ in range(rng.randrange(9)))) for i in range(2000)]
    for suffix, writer in ((".asc", can.ASCWriter), (".trc", can.TRCWriter), (".log", can.CanutilsLogWriter),
                           (".blf", can.BLFWriter)):
        path = work / f"can{suffix}"
        with writer(path) as w:
            for msg in frames:
                w.on_message_received(msg)
        base.can_logs[suffix] = path
    real = REPO.parent / "shared" / "realdata" / "css-electronics" / "2F6913DB_00000004_00000001.MF4"
    if real.is_file():
        base.can_logs[".mf4"] = real
    for suffix, path in base.can_logs.items():
        base.can_frames[suffix] = _info_frames(cli(["info", str(path), "--json"], work))


def _info_frames(r: subprocess.CompletedProcess[str]) -> int:
    """Frames ``autosar info --json`` of a CAN log counts (over its streams)."""
    return sum(int(s["count"]) for s in json.loads(r.stdout)["streams"])


# ------------------------------------------------------------------------------------------ faults
def flip(data: bytearray, rng: random.Random, n: int, lo: int = 0, hi: int | None = None) -> list[tuple[int, int]]:
    hi = len(data) if hi is None else hi
    spots = []
    for _ in range(n):
        i = rng.randrange(lo, hi)
        data[i] ^= rng.randrange(1, 256)
        spots.append((i, i + 1))
    return spots


def container_trial(base: Base, cls: str, n: int, rng: random.Random, tdir: Path) -> Trial:
    src = {"mcap": base.mcap, "ros1": base.ros1, "rosbag2": base.ros2}[cls]
    kind = rng.choice(["flip"] * 5 + ["truncate"] * 3 + ["header"] * 2)
    dst = tdir / ("log" + ("" if cls == "rosbag2" else src.suffix))
    if cls == "rosbag2":
        shutil.copytree(src, dst)
        target = next(dst.glob("*.db3"))
        if kind == "header":  # damage metadata.yaml instead
            target = dst / "metadata.yaml"
    else:
        shutil.copyfile(src, dst)
        target = dst
    data = bytearray(target.read_bytes())
    damaged: list[tuple[int, int]]
    if kind == "flip":
        damaged = flip(data, rng, rng.randint(1, 10))
        fault = f"{len(damaged)} flipped bytes in {target.name}"
    elif kind == "truncate":
        cut = rng.randrange(len(data) // 50, len(data))
        damaged = [(cut, 1 << 62)]
        del data[cut:]
        fault = f"{target.name} truncated at byte {cut}"
    elif cls == "mcap":  # a record header: opcode or length bytes
        starts = _mcap_record_starts(bytes(data))
        s = rng.choice(starts)
        i = s + rng.randrange(0, 9)
        data[i] = rng.randrange(256)
        damaged = [(s, s + 9)]
        fault = f"record header byte {i} set to {data[i]:#04x}"
    elif cls == "ros1":  # the index and connection records at the end, or the bag header
        lo = max(e for _, e, _ in base.ros1_chunks)
        # the bag header record: after the 13-byte magic, padded to 4096 bytes by every writer
        lo, hi = rng.choice([(13, 13 + 4096), (lo, None)])
        damaged = flip(data, rng, rng.randint(1, 4), lo=lo, hi=hi)
        fault = f"{len(damaged)} flipped bytes in the bag header/index"
    else:
        damaged = flip(data, rng, rng.randint(1, 6))
        fault = f"{len(damaged)} flipped bytes in metadata.yaml"
    target.write_bytes(bytes(data))
    trial = ingest_trial(base, cls, n, fault, dst, tdir)
    chunks = {"mcap": base.mcap_chunks, "ros1": base.ros1_chunks}.get(cls)
    if chunks is not None:
        trial.chunks_expected = intact(chunks, damaged)
    if cls == "mcap":
        trial.unverified = unverified_read(base, dst)
    return trial


def ingest_trial(base: Base, cls: str, n: int, fault: str, log: Path, tdir: Path) -> Trial:
    """``autosar ingest --json`` of the damaged ``log``, classified against the undamaged log's drive
    (``ref_{cls}.h5``); the log must come out unchanged and no partial stay."""
    before = tree_hash(log)
    t0 = time.perf_counter()
    r = cli(["ingest", log.name, "-o", "out/drive.h5", "--json"], tdir)
    trial = Trial(cls, n, fault, rc=r.returncode, wall_s=time.perf_counter() - t0)
    report: dict[str, object] = {}
    if r.returncode == 0:
        try:
            report = json.loads(r.stdout)
            trial.messages_read = int(report["messages"])  # type: ignore[call-overload]
        except (ValueError, KeyError):
            pass
    trial.outcome, trial.detail = classify(r, tdir / "out" / "drive.h5", base.digests[cls],
                                           warned=bool(report.get("warnings")))
    if trial.outcome == "silent-wrong":
        trial.detail += ": " + drive_difference(tdir / "out" / "drive.h5", base.dir / f"ref_{cls}.h5")
    if tree_hash(log) != before:
        trial.outcome = "input-harmed"
    elif partials(tdir):
        trial.outcome, trial.detail = "partial-left", ", ".join(partials(tdir))
    return trial


def ros1_records_trial(base: Base, n: int, rng: random.Random, tdir: Path) -> Trial:
    """1-3 bytes of as many message records' framing in the uncompressed ROS1 bag overwritten; the messages of
    the other records are expected kept."""
    assert base.ros1u is not None
    dst = tdir / "log.bag"
    data = bytearray(base.ros1u.read_bytes())
    hit = rng.sample(base.ros1u_records, rng.randint(1, 3))
    spots = []
    for start, dstart in hit:
        i = rng.randrange(start, dstart)
        data[i] ^= rng.randrange(1, 256)
        spots.append(i)
    dst.write_bytes(bytes(data))
    trial = ingest_trial(base, "ros1-records", n, f"{len(hit)} message records' framing bytes overwritten (at "
                         f"{spots})", dst, tdir)
    trial.messages_whole = len(base.ros1u_records)
    trial.chunks_expected = len(base.ros1u_records) - len(hit)
    return trial


def _mcap_record_starts(data: bytes) -> list[int]:
    out, pos = [], 8
    while pos + 9 <= len(data):
        op, length = struct.unpack_from("<BQ", data, pos)
        out.append(pos)
        if op == 0x02:
            break
        pos += 9 + length
    return out


def hdf5_trial(base: Base, n: int, rng: random.Random, tdir: Path) -> Trial:
    which = "drive" if n % 2 == 0 else "traj"
    src = base.drive if which == "drive" else base.traj
    dst = tdir / src.name
    shutil.copyfile(src, dst)
    other = tdir / (base.traj.name if which == "drive" else base.drive.name)
    shutil.copyfile(base.traj if which == "drive" else base.drive, other)
    data = bytearray(dst.read_bytes())
    spots = flip(data, rng, rng.randint(1, 10), lo=len(data) // 20)  # past the superblock/root: the data
    dst.write_bytes(bytes(data))
    before = (tree_hash(dst), tree_hash(other))
    (tdir / "out").mkdir()
    t0 = time.perf_counter()
    r = cli(["focus", "drive.h5", "-t", "traj.h5", "-o", "out/image"], tdir)
    trial = Trial("hdf5", n, f"{len(spots)} flipped bytes in {src.name}", rc=r.returncode,
                  wall_s=time.perf_counter() - t0)
    trial.outcome, trial.detail = classify(r, tdir / "out" / "image.h5", base.digests["image"])
    if (tree_hash(dst), tree_hash(other)) != before:
        trial.outcome = "input-harmed"
    elif partials(tdir):
        trial.outcome, trial.detail = "partial-left", ", ".join(partials(tdir))
    return trial


CONFIG_VALUES = ["nan", "inf", "-inf", "-1.0", "0.0", "1e300", "-1e300", '"abc"', "[]", "true"]


def config_trial(base: Base, n: int, rng: random.Random, tdir: Path) -> Trial:
    from autosar_cli.config import DEFAULT_CONFIG

    text = Path(DEFAULT_CONFIG).read_text(encoding="utf-8")
    lines = text.splitlines()
    numeric = [i for i, ln in enumerate(lines) if "=" in ln and not ln.lstrip().startswith("#")
               and _is_number(ln.split("=", 1)[1].split("#")[0].strip())]
    mode = rng.choice(["value"] * 8 + ["delete", "utf8"])
    if mode == "value":
        i = rng.choice(numeric)
        key = lines[i].split("=", 1)[0].strip()
        value = rng.choice(CONFIG_VALUES)
        lines[i] = f"{key} = {value}"
        fault, blob = f"{key} = {value}", "\n".join(lines).encode()
    elif mode == "delete":
        i = rng.choice(numeric)
        fault = f"{lines[i].split('=', 1)[0].strip()} deleted"
        del lines[i]
        blob = "\n".join(lines).encode()
    else:
        fault, blob = "non-UTF-8 bytes", text.encode().replace(b"=", b"= \xff\xfe", 1)
    cfg = tdir / "cfg.toml"
    cfg.write_bytes(blob)
    shutil.copyfile(base.drive, tdir / "drive.h5")
    before = tree_hash(cfg), tree_hash(tdir / "drive.h5")
    t0 = time.perf_counter()
    r = cli(["navigate", "drive.h5", "-o", "out/traj.h5", "-c", "cfg.toml"], tdir)
    trial = Trial("config", n, fault, rc=r.returncode, wall_s=time.perf_counter() - t0)
    trial.outcome, trial.detail = classify(r, None, None)
    if r.returncode == 0 and not _finite_trajectory(tdir / "out" / "traj.h5"):
        trial.outcome, trial.detail = "silent-wrong", "non-finite trajectory, exit 0"
    if (tree_hash(cfg), tree_hash(tdir / "drive.h5")) != before:
        trial.outcome = "input-harmed"
    elif partials(tdir):
        trial.outcome, trial.detail = "partial-left", ", ".join(partials(tdir))
    return trial


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _finite_trajectory(path: Path) -> bool:
    import h5py
    import numpy as np

    import autosar_cli.store.drive  # noqa: F401

    with h5py.File(path, "r") as f:
        ok = True

        def visit(name: str, obj: object) -> None:
            nonlocal ok
            if isinstance(obj, h5py.Dataset) and obj.dtype.kind == "f" and obj.ndim >= 1:
                ok = ok and bool(np.all(np.isfinite(obj[()])))

        f.visititems(visit)
    return ok


def kill_trial(base: Base, n: int, rng: random.Random, tdir: Path) -> Trial:
    stage = "ingest" if n % 2 == 0 else "focus"
    sig = signal.SIGKILL if rng.random() < 0.5 else signal.SIGINT
    if stage == "ingest":
        shutil.copyfile(base.mcap, tdir / "ci.mcap")
        args, delay = ["ingest", "ci.mcap", "-o", "out/drive.h5"], rng.uniform(0.0, 1.6)
        inputs = [tdir / "ci.mcap"]
    else:
        shutil.copyfile(base.drive, tdir / "drive.h5")
        shutil.copyfile(base.traj, tdir / "traj.h5")
        (tdir / "out").mkdir()  # focus writes into an existing directory
        args, delay = ["focus", "drive.h5", "-t", "traj.h5", "-o", "out/image"], rng.uniform(0.0, 3.5)
        inputs = [tdir / "drive.h5", tdir / "traj.h5"]
    before = [tree_hash(p) for p in inputs]
    proc = subprocess.Popen(CLI + args, cwd=tdir, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=_env())
    time.sleep(delay)
    proc.send_signal(sig)
    out, errtext = proc.communicate(timeout=300)
    trial = Trial("kill", n, f"{sig.name} after {delay:.2f} s of {stage}", rc=proc.returncode)
    first = subprocess.CompletedProcess(args, proc.returncode, out, errtext)
    if sig == signal.SIGINT:
        if proc.returncode == 0:
            trial.outcome = "ok"
        elif "Traceback" in out + errtext or proc.returncode != 130:
            trial.outcome, trial.detail = "crash-or-traceback", f"SIGINT gave rc {proc.returncode}: " + \
                ((out + errtext).strip().splitlines() or [""])[-1][:150]
        else:
            trial.outcome = "clean-error"
    else:
        trial.outcome = "ok" if proc.returncode == 0 else "clean-error"  # SIGKILL cannot be handled
    del first
    rerun = cli(args + ["--overwrite"], tdir)
    if rerun.returncode != 0 and trial.outcome != "crash-or-traceback":
        trial.outcome, trial.detail = classify(rerun, None, None)
        trial.detail = "rerun: " + trial.detail
    if [tree_hash(p) for p in inputs] != before:
        trial.outcome = "input-harmed"
    elif partials(tdir):
        trial.outcome, trial.detail = "partial-left", ", ".join(partials(tdir))
    return trial


def disk_trial(base: Base, n: int, rng: random.Random, tdir: Path) -> Trial:
    mnt = tdir / "small"
    mnt.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=5m", "tmpfs", str(mnt)], capture_output=True).returncode:
        return Trial("disk-full", n, "skipped: cannot mount a tmpfs (needs root)", outcome="skipped")
    try:
        shutil.copyfile(base.mcap, tdir / "ci.mcap")
        shutil.copyfile(base.drive, tdir / "drive.h5")
        shutil.copyfile(base.traj, tdir / "traj.h5")
        if n % 2 == 0:
            args, fault = ["ingest", "ci.mcap", "-o", "small/drive.h5"], "ingest onto a 5 MiB tmpfs"
        else:  # fill most of it first so the image does not fit
            (mnt / "filler").write_bytes(bytes(5 * 1024 * 1024 - 64 * 1024))
            args, fault = ["focus", "drive.h5", "-t", "traj.h5", "-o", "small/image"], "focus onto a full tmpfs"
        before = [tree_hash(tdir / p) for p in ("ci.mcap", "drive.h5", "traj.h5")]
        r = cli(args, tdir)
        trial = Trial("disk-full", n, fault, rc=r.returncode)
        trial.outcome, trial.detail = classify(r, None, None)
        if [tree_hash(tdir / p) for p in ("ci.mcap", "drive.h5", "traj.h5")] != before:
            trial.outcome = "input-harmed"
        elif partials(mnt):
            trial.outcome, trial.detail = "partial-left", ", ".join(partials(mnt))
        return trial
    finally:
        subprocess.run(["umount", str(mnt)], capture_output=True)


PATH_CASES: list[tuple[str, Callable[[Path], list[str]], list[str]]] = [
    ("ingest -o its own input", lambda d: ["ingest", "ci.mcap", "-o", "ci.mcap", "--overwrite"], ["ci.mcap"]),
    ("navigate -o its own input", lambda d: ["navigate", "drive.h5", "-o", "drive.h5", "--overwrite"], ["drive.h5"]),
    ("focus -o onto the drive", lambda d: ["focus", "drive.h5", "-t", "traj.h5", "-o", "drive", "--overwrite"],
     ["drive.h5", "traj.h5"]),
    ("ingest -o a directory of files", lambda d: ["ingest", "ci.mcap", "-o", "keep", "--overwrite"], ["keep"]),
    ("output parent is a file", lambda d: ["ingest", "ci.mcap", "-o", "ci.mcap/drive.h5"], ["ci.mcap"]),
    ("255-byte output name", lambda d: ["ingest", "ci.mcap", "-o", "d" * 252 + ".h5"], ["ci.mcap"]),
    ("output in a missing directory", lambda d: ["navigate", "drive.h5", "-o", "no/such/dir/traj.h5"], ["drive.h5"]),
    ("input does not exist", lambda d: ["ingest", "missing.mcap", "-o", "out.h5"], ["ci.mcap"]),
    ("focus -t the drive itself", lambda d: ["focus", "drive.h5", "-t", "drive.h5", "-o", "img"], ["drive.h5"]),
    ("ingest -o inside a rosbag2 input", lambda d: ["ingest", "bag", "-o", "bag/drive.h5", "--overwrite"], ["bag"]),
    ("input is a named pipe", lambda d: _named_pipe(d / "pipe.mcap"), ["ci.mcap"]),
    ("input is a symbolic link loop", lambda d: _link_loop(d / "loop.mcap"), ["ci.mcap"]),
]


def _named_pipe(path: Path) -> list[str]:
    os.mkfifo(path)  # no writer ever comes
    return ["ingest", path.name, "-o", "out.h5"]


def _link_loop(path: Path) -> list[str]:
    path.symlink_to(path.with_name("other.mcap"))
    path.with_name("other.mcap").symlink_to(path)
    return ["ingest", path.name, "-o", "out.h5"]


def path_trial(base: Base, n: int, rng: random.Random, tdir: Path) -> Trial:
    name, make, watched = PATH_CASES[n % len(PATH_CASES)]
    shutil.copyfile(base.mcap, tdir / "ci.mcap")
    shutil.copyfile(base.drive, tdir / "drive.h5")
    shutil.copyfile(base.traj, tdir / "traj.h5")
    shutil.copytree(base.ros2, tdir / "bag")
    (tdir / "keep").mkdir()
    (tdir / "keep" / "notes.txt").write_text("precious\n")
    before = [tree_hash(tdir / p) for p in watched]
    r = cli(make(tdir), tdir)
    trial = Trial("path", n, name, rc=r.returncode)
    trial.outcome, trial.detail = classify(r, None, None)
    if [tree_hash(tdir / p) for p in watched] != before:
        trial.outcome, trial.detail = "input-harmed", f"{watched} changed"
    elif partials(tdir):
        trial.outcome, trial.detail = "partial-left", ", ".join(partials(tdir))
    return trial


#: dca1000 trials from this one on are of ``DCA_SETUP_KINDS``, each in turn (the first 40 keep their packet damage)
DCA_SETUP_FROM = 40
DCA_SETUP_KINDS = ("appended", "appended-split", "appended-cut", "appended-short", "stale-split", "stale-flat",
                   "second-series", "appended-flat", "numFrames-less", "numFrames-more", "cut-at-frame",
                   "partial-frame", "numLoops", "numLoops-prf", "period")


def _edit_frame_cfg(js: Path, **fields: float) -> None:
    """Set ``rlFrameCfg_t`` fields of an mmWave Studio JSON (numLoops, numFrames, framePeriodicity_msec)."""
    doc = json.loads(js.read_text())
    doc["mmWaveDevices"][0]["rfConfig"]["rlFrameCfg_t"].update(fields)
    js.write_text(json.dumps(doc, indent=2))


def _split_packets(packets: list[bytes], per_file: int) -> list[bytes]:
    """Packets in files of ``per_file`` packets each, as the DCA1000 records a long capture."""
    return [b"".join(packets[i:i + per_file]) for i in range(0, len(packets), per_file)]


def dca1000_pris_kept(product: Path, reference: Path) -> tuple[int, int]:
    """(PRIs of ``product`` that are the reference drive's at the same frame index, the other PRIs it holds)."""
    import h5py
    import numpy as np

    import autosar_cli.store.drive  # noqa: F401  (registers the compression filters)

    with h5py.File(product, "r") as new, h5py.File(reference, "r") as ref:
        group = next(k for k in ref["radar"])
        raw, idx = new[f"radar/{group}/raw"], new[f"radar/{group}/frame_index"][()]
        ref_raw = ref[f"radar/{group}/raw"]
        kept = 0
        for a in range(0, len(idx), 256):
            i = idx[a:a + 256]
            ok = i < len(ref_raw)
            same = np.zeros(len(i), dtype=bool)
            if ok.any():
                got, want = raw[a:a + 256][ok], ref_raw[i[ok].min():i[ok].max() + 1][i[ok] - i[ok].min()]
                same[ok] = (got == want).reshape(len(got), -1).all(axis=1)
            kept += int(same.sum())
        return kept, len(idx) - kept


def _ingest_capture(base: Base, tdir: Path, n: int, fault: str,
                    args: Sequence[str] = ()) -> tuple[Trial, subprocess.CompletedProcess[str], dict[str, Any]]:
    """Ingest the trial's damaged capture ``tdir``/cap beside the DCA1000 drive's log and classify the product;
    the trial, the command's result and its --json report."""
    t0 = time.perf_counter()
    r = cli(["ingest", str(base.dca_mcap), "--radar", "cap", "-o", "out/drive.h5", "--json", *args], tdir)
    trial = Trial("dca1000", n, fault, rc=r.returncode, wall_s=time.perf_counter() - t0)
    report: dict[str, Any] = {}
    if r.returncode == 0:
        try:
            report = json.loads(r.stdout)
        except ValueError:
            pass
    trial.outcome, trial.detail = classify(r, tdir / "out" / "drive.h5", base.digests["dca1000"],
                                           warned=bool(report.get("warnings")))
    return trial, r, report


def dca1000_setup_trial(base: Base, n: int, rng: random.Random, tdir: Path) -> Trial:
    """What a re-run of mmWave Studio or a setup of other frames than the recording's leaves: the capture (981 frames
    of 1 loop, 25920 bytes a frame, with a sync trigger per frame in its MCAP) with a second recording appended or
    an earlier one's files beside it, or its JSON's numFrames / numLoops / framePeriodicity_msec not the
    recording's. ``chunks_expected``: its PRIs that must be kept (the recording's intact whole frames), where the
    trial keeps them all; ``messages_read``: the product's PRIs that are the undamaged drive's at the same index."""
    assert base.dca_flat is not None and base.dca_packets is not None and base.dca_mcap is not None
    from autosar_cli.ingest.dca1000 import load_params

    kind = DCA_SETUP_KINDS[(n - DCA_SETUP_FROM) % len(DCA_SETUP_KINDS)]
    cap = tdir / "cap"
    shutil.copytree(base.dca_flat, cap)
    js = next(cap.glob("*.mmwave.json"))
    p, _ = load_params(js)
    fb, frames = p.frame_bytes, p.num_frames
    data = (cap / "adc_data.bin").read_bytes()
    from autosar_cli.ingest.dca1000_packets import packets_of

    def other(k: int) -> bytes:  # another recording of the same setup: this one's frames from frame k on
        return data[k * fb:] + data[:k * fb]

    packets = [bytes(pk) for pk in packets_of(data, PACKET)]
    expected: int | None = frames  # PRIs (1 loop a frame) the product must keep
    args: list[str] = []
    if kind.startswith("appended") and kind != "appended-flat":
        (cap / "adc_data.bin").unlink()
        shift = rng.randrange(1, frames)
        second = packets_of(other(shift), PACKET)
        first = packets
        if kind == "appended-cut":  # the first recording stopped inside a frame
            keep = rng.randrange(64, len(packets) - 1)
            first = packets[:keep]
            expected = keep * PACKET // fb
        if kind == "appended-short":
            second = second[:rng.randrange(2, 64)]
        else:
            second = second[:rng.randrange(64, len(second))]
        stream = b"".join(first) + b"".join(second)
        if kind == "appended-split":
            cuts = sorted(rng.sample(range(1, len(stream)), 3))
            for j, (a, b) in enumerate(zip([0, *cuts], [*cuts, len(stream)], strict=True)):
                (cap / f"adc_data_Raw_{j}.bin").write_bytes(stream[a:b])
        else:
            (cap / "adc_data_Raw_0.bin").write_bytes(stream)
        fault = (f"a second recording of {len(second)} packets (frames from {shift} on) appended after "
                 + (f"the first cut at packet {len(first)} of {len(packets)}" if kind == "appended-cut" else
                    f"the whole first ({len(packets)} packets)")
                 + (", cut into 4 files anywhere" if kind == "appended-split" else ", in adc_data_Raw_0.bin"))
    elif kind == "stale-split":  # re-run into the folder: an earlier, longer recording's last files stay beside
        (cap / "adc_data.bin").unlink()
        per_file = rng.randrange(len(packets) // 4, len(packets) // 2)
        longer = other(rng.randrange(1, frames)) + data[:rng.randrange(1, frames // 2) * fb]
        old = _split_packets([bytes(pk) for pk in packets_of(longer, PACKET)], per_file)
        new = _split_packets(packets, per_file)
        for j, blob in enumerate(new + old[len(new):]):
            (cap / f"adc_data_Raw_{j}.bin").write_bytes(blob)
        stated = rng.choice([frames, 0])
        _edit_frame_cfg(js, numFrames=stated)
        fault = (f"files of {per_file} packets: {len(new)} of this recording, then {len(old) - len(new)} left of an "
                 f"earlier one of {len(longer) // fb} frames (numFrames {stated})")
        expected = frames
    elif kind == "stale-flat":  # this recording's raw files beside the earlier one's post-processed adc_data.bin
        (cap / "adc_data.bin").write_bytes(other(rng.randrange(1, frames)))
        stream = b"".join(packets)
        cuts = sorted(rng.sample(range(1, len(stream)), 2))
        for j, (a, b) in enumerate(zip([0, *cuts], [*cuts, len(stream)], strict=True)):
            (cap / f"adc_data_Raw_{j}.bin").write_bytes(stream[a:b])
        fault = "adc_data.bin of an earlier recording beside this one's adc_data_Raw_0..2.bin"
        expected = None  # which of the two is meant cannot be told
    elif kind == "second-series":
        (cap / "adc_data.bin").unlink()
        (cap / "adc_data_Raw_0.bin").write_bytes(b"".join(packets))
        (cap / "run2_Raw_0.bin").write_bytes(b"".join(packets_of(other(rng.randrange(1, frames)), PACKET)))
        fault = "a second recording's run2_Raw_0.bin beside adc_data_Raw_0.bin"
        expected = None
    elif kind == "appended-flat":
        extra = rng.randrange(1, frames)
        (cap / "adc_data.bin").write_bytes(data + other(rng.randrange(1, frames))[:extra * fb])
        stated = rng.choice([frames, 0])
        _edit_frame_cfg(js, numFrames=stated)
        fault = f"adc_data.bin holds {extra} frames of another recording after its {frames} (numFrames {stated})"
    elif kind == "numFrames-less":
        stated = rng.randrange(1, frames)
        _edit_frame_cfg(js, numFrames=stated)
        fault = f"numFrames {stated}, the capture holds {frames}"
    elif kind == "numFrames-more":
        stated = rng.randrange(frames + 1, 3 * frames)
        _edit_frame_cfg(js, numFrames=stated)
        fault = f"numFrames {stated}, the capture holds {frames}"
    elif kind == "cut-at-frame":
        held = rng.randrange(1, frames)
        stated = rng.choice([frames, 0])
        (cap / "adc_data.bin").write_bytes(data[:held * fb])
        _edit_frame_cfg(js, numFrames=stated)
        fault = f"adc_data.bin cut at frame {held} of {frames} (numFrames {stated})"
        expected = held
    elif kind == "partial-frame":
        extra = rng.randrange(1, fb)
        if rng.random() < 0.5:
            (cap / "adc_data.bin").write_bytes(data + other(rng.randrange(1, frames))[:extra])
            fault = f"adc_data.bin followed by {extra} bytes of a frame"
        else:
            (cap / "adc_data.bin").unlink()
            longer = data + other(rng.randrange(1, frames))[:extra]
            (cap / "adc_data_Raw_0.bin").write_bytes(b"".join(packets_of(longer, PACKET)))
            fault = f"recorded packets of the capture and {extra} bytes of a frame more"
    elif kind in ("numLoops", "numLoops-prf"):
        k = rng.choice([3, 9, 109, 2, 4])  # 981 = 3 x 3 x 109; 2 and 4 leave a partial frame
        period = float(json.loads(js.read_text())["mmWaveDevices"][0]["rfConfig"]["rlFrameCfg_t"][
            "framePeriodicity_msec"])
        stated = rng.choice([frames, frames // k])
        fields: dict[str, float] = {"numLoops": k, "numFrames": stated}
        if kind == "numLoops":  # the PRF (loops / frame period) the config states stays
            fields["framePeriodicity_msec"] = period * k
        _edit_frame_cfg(js, **fields)
        fault = f"numLoops {k} (the recording's 1), numFrames {stated}" + (
            f", framePeriodicity_msec x {k}" if kind == "numLoops" else "")
        expected = None  # the PRIs are the same, but timed as loops of the stated frames
    else:  # a frame period the per-frame triggers contradict, the config's prf_hz agreeing with the JSON
        e = rng.choice([1.5e-5, 3e-5, 3e-4, 2e-3, 2e-2, -5e-4])
        period = float(json.loads(js.read_text())["mmWaveDevices"][0]["rfConfig"]["rlFrameCfg_t"][
            "framePeriodicity_msec"])
        _edit_frame_cfg(js, framePeriodicity_msec=period * (1 + e))
        (tdir / "radar.toml").write_text(f'base = "{REPO / "configs" / "giulia_scanbrick.toml"}"\n\n[radar]\n'
                                          f"prf_hz = {1e3 / (period * (1 + e))!r}\n")
        args = ["--config", "radar.toml"]
        fault = f"framePeriodicity_msec x (1 {e:+g}), the config's prf_hz with it"
        expected = None
    before = tree_hash(cap)
    trial, r, report = _ingest_capture(base, tdir, n, fault, args)
    if r.returncode == 0 and trial.outcome != "crash-or-traceback":
        kept, foreign = dca1000_pris_kept(tdir / "out" / "drive.h5", base.dir / "ref_dca1000.h5")
        trial.messages_read = kept
        if foreign:
            trial.detail = f"{foreign} PRIs not the recording's kept as its own" + (
                f"; {trial.detail}" if trial.detail else "")
        if expected is not None:
            trial.chunks_expected = expected
    elif expected is not None:
        trial.chunks_expected = expected
    if trial.outcome in ("kept-with-warning", "clean-error", "silent-wrong"):
        warns = [str(w) for w in report.get("warnings", [])] if isinstance(report.get("warnings"), list) else []
        said = "; ".join(w.replace(str(tdir), "") for w in warns) or trial.detail
        trial.detail = (trial.detail + " | " if trial.detail and trial.detail != said else "") + said[:400]
    if tree_hash(cap) != before:
        trial.outcome = "input-harmed"
    elif partials(tdir):
        trial.outcome, trial.detail = "partial-left", ", ".join(partials(tdir))
    return trial


def dca1000_trial(base: Base, n: int, rng: random.Random, tdir: Path) -> Trial:
    if n >= DCA_SETUP_FROM:
        return dca1000_setup_trial(base, n, rng, tdir)
    assert base.dca_flat is not None and base.dca_packets is not None and base.dca_mcap is not None
    kind = rng.choice(["lose", "reorder", "repeat", "header", "missing-file", "truncate", "zero-fill", "params"])
    cap = tdir / "cap"
    shutil.copytree(base.dca_flat, cap)
    data = (cap / "adc_data.bin").read_bytes()
    step = PACKET + 10
    if kind in ("lose", "reorder", "repeat", "header", "missing-file"):  # a recording of packets, cut anywhere
        (cap / "adc_data.bin").unlink()
        stream = base.dca_packets.read_bytes()
        packets = [stream[i:i + step] for i in range(0, len(stream), step)]
        k = rng.randint(1, 20)
        spots = sorted(rng.sample(range(len(packets) - 1), k))
        if kind == "lose":
            packets = [pk for i, pk in enumerate(packets) if i not in spots]
        elif kind == "reorder":
            for i in spots:
                packets[i], packets[i + 1] = packets[i + 1], packets[i]
        elif kind == "repeat":
            for i in reversed(spots):
                packets.insert(i + 1, packets[i])
        stream = bytearray(b"".join(packets))
        if kind == "header":
            for i in spots:
                stream[i * step + rng.randrange(10)] ^= rng.randrange(1, 256)
        cuts = sorted(rng.sample(range(1, len(stream)), 3))
        for j, (a, b) in enumerate(zip([0, *cuts], [*cuts, len(stream)], strict=True)):
            (cap / f"adc_data_Raw_{j}.bin").write_bytes(stream[a:b])
        fault = f"{k} packets {kind}" + (" (bytes flipped in their headers)" if kind == "header" else "")
        if kind == "missing-file":
            gone = rng.randint(1, 2)
            (cap / f"adc_data_Raw_{gone}.bin").unlink()
            fault = f"split file {gone} of 4 missing"
    elif kind == "truncate":
        cut = rng.randrange(len(data) // 50, len(data))
        (cap / "adc_data.bin").write_bytes(data[:cut])
        fault = f"adc_data.bin cut at byte {cut} of {len(data)}"
    elif kind == "zero-fill":
        k = rng.randint(1, 5)
        zeroed = bytearray(data)
        for _ in range(k):
            at = rng.randrange(0, len(data) - PACKET) // 2 * 2
            zeroed[at:at + PACKET] = bytes(PACKET)
        (cap / "adc_data.bin").write_bytes(bytes(zeroed))
        fault = f"{k} packets zero-filled in adc_data.bin"
    else:
        js = next(cap.glob("*.mmwave.json"))
        text = js.read_text()
        # a digit among its number's first six significant ones: a change further down is below any tolerance
        digits = []
        for m in re.finditer(r"\d[\d.]*", text):
            number = m.group()
            leading = sum(c.isdigit() for c in number[:len(number) - len(number.lstrip("0."))])
            digits += [m.start() + j for j, c in enumerate(number) if c.isdigit()][leading:][:6]
        i = rng.choice(digits)
        new = str((int(text[i]) + rng.randint(1, 9)) % 10)
        js.write_text(text[:i] + new + text[i + 1:])
        fault = f"{js.name}: digit at character {i} {text[i]} -> {new}"
    before = tree_hash(cap)
    trial, _, _ = _ingest_capture(base, tdir, n, fault)
    if tree_hash(cap) != before:
        trial.outcome = "input-harmed"
    elif partials(tdir):
        trial.outcome, trial.detail = "partial-left", ", ".join(partials(tdir))
    return trial


def canlog_trial(base: Base, n: int, rng: random.Random, tdir: Path) -> Trial:
    suffixes = sorted(base.can_logs)
    suffix = suffixes[n % len(suffixes)] if suffixes else ""
    if not suffix:
        return Trial("canlog", n, "no CAN log", outcome="skipped")
    src = base.can_logs[suffix]
    data = src.read_bytes()
    cut = rng.randrange(len(data) // 20, len(data))
    log = tdir / f"log{suffix}"
    log.write_bytes(data[:cut])
    trial = Trial("canlog", n, f"{src.name} cut at byte {cut} of {len(data)}")
    if suffix in (".asc", ".trc", ".log"):  # python-can's own count on the whole lines before the cut
        import can

        whole = tdir / f"whole{suffix}"
        whole.write_bytes(data[:data.rfind(b"\n", 0, cut) + 1])
        reader = {".asc": can.ASCReader, ".trc": can.TRCReader, ".log": can.CanutilsLogReader}[suffix]
        with reader(str(whole)) as frames:
            trial.chunks_expected = sum(1 for _ in frames)
    before = tree_hash(log)
    t0 = time.perf_counter()
    r = cli(["info", str(log), "--json"], tdir)
    trial.rc, trial.wall_s = r.returncode, time.perf_counter() - t0
    if r.returncode == 0:
        trial.messages_read = _info_frames(r)
        warned = bool(json.loads(r.stdout).get("warnings")) or "warning:" in r.stderr
        if trial.messages_read == base.can_frames[suffix] and not warned:
            trial.outcome = "ok"
        else:
            trial.outcome, trial.detail = ("kept-with-warning", "") if warned else \
                ("silent-wrong", f"{trial.messages_read} of {base.can_frames[suffix]} frames, no warning")
    else:
        trial.outcome, trial.detail = classify(r, None, None)
    if tree_hash(log) != before:
        trial.outcome = "input-harmed"
    return trial


def realfiles_trial(base: Base, n: int, rng: random.Random, tdir: Path, cls: str = "realfiles") -> Trial:
    inputs, root = (FINALISED_INPUTS, base.dir) if cls == "finalised" else (REAL_INPUTS, REAL)
    name, rel, args = inputs[n % len(inputs)]
    kind = REAL_DAMAGE[n // len(inputs) % len(REAL_DAMAGE)]
    if f"real:{name}" not in base.digests:
        return Trial(cls, n, f"{name}: not in ../shared/realdata", outcome="skipped")
    data = (root / rel).read_bytes()
    at = rng.randrange(1, len(data) - 4096)
    if kind == "cut":
        damaged = data[:at]
    elif kind.endswith("overwritten"):
        k = int(kind.split()[0])
        damaged = data[:at] + bytes(rng.randrange(256) for _ in range(k)) + data[at + k:]
    elif kind == "4 KiB zeroed":
        damaged = data[:at] + bytes(4096) + data[at + 4096:]
    elif kind == "4 KiB added":
        block = rng.randrange(0, len(data) - 4096)
        damaged = data[:at] + data[block:block + 4096] + data[at:]
    else:
        damaged = data[:at] + data[at + 4096:]
    log = tdir / Path(rel).name
    log.write_bytes(damaged)
    trial = Trial(cls, n, f"{name}: {kind} at byte {at} of {len(data)}")
    t0 = time.perf_counter()
    r = cli(["ingest", *args(log), "-o", "d.h5", "--allow-partial", "--json"], tdir, timeout=120)
    trial.rc, trial.wall_s = r.returncode, time.perf_counter() - t0
    warned = False
    if r.returncode == 0:
        try:
            report = json.loads(r.stdout)
        except json.JSONDecodeError:  # --json's output broken (a library printing on stdout) is a fault too
            trial.outcome, trial.detail = "crash-or-traceback", f"--json output not JSON: {r.stdout[:120]!r}"
            return trial
        said = {w.replace(str(log), "LOG") for w in report.get("warnings", [])}
        warned = bool(said - base.real_warnings[name])  # a word about the damage, not what it says undamaged
        trial.messages_read, trial.messages_whole = int(report["messages"]), base.real_messages[name]
    trial.outcome, trial.detail = classify(r, tdir / "d.h5" if r.returncode == 0 else None,
                                           base.digests[f"real:{name}"], warned)
    if r.returncode == 0 and r.stdout.lstrip()[:1] != "{":
        trial.outcome, trial.detail = "crash-or-traceback", f"--json output not JSON: {r.stdout[:120]!r}"
    return trial


# -------------------------------------------------------------------------------------------- main
def run_trial(base: Base, cls: str, n: int, seed: int, root: Path) -> Trial:
    rng = random.Random(f"{seed}:{cls}:{n}")
    tdir = root / f"{cls}_{n:03d}"
    tdir.mkdir()
    try:
        if cls in ("mcap", "ros1", "rosbag2"):
            return container_trial(base, cls, n, rng, tdir)
        return {"hdf5": hdf5_trial, "config": config_trial, "kill": kill_trial, "disk-full": disk_trial,
                "path": path_trial, "dca1000": dca1000_trial, "canlog": canlog_trial,
                "realfiles": realfiles_trial, "ros1-records": ros1_records_trial,
                "finalised": lambda *a: realfiles_trial(*a, cls="finalised")}[cls](base, n, rng, tdir)
    except subprocess.TimeoutExpired:
        return Trial(cls, n, "timeout", outcome="crash-or-traceback", detail="hung for 300 s")
    finally:
        shutil.rmtree(tdir, ignore_errors=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--scale", type=float, default=1.0, help="trials per class relative to the minimum counts")
    ap.add_argument("--classes", default=",".join(COUNTS), help="comma-separated subset of " + ",".join(COUNTS))
    ap.add_argument("--workdir", type=Path, default=None)
    args = ap.parse_args()
    root = args.workdir or Path(tempfile.mkdtemp(prefix="fault_campaign_"))
    root.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    base = setup(root)
    print(f"setup {time.perf_counter() - t0:.0f} s in {root}", file=sys.stderr)
    classes = [c for c in args.classes.split(",") if c]
    jobs = [(c, n) for c in classes for n in range(max(1, round(COUNTS[c] * args.scale)))]
    trials_dir = root / "trials"
    trials_dir.mkdir(exist_ok=True)
    with ThreadPoolExecutor(args.jobs) as pool:
        trials = list(pool.map(lambda cn: run_trial(base, cn[0], cn[1], args.seed, trials_dir), jobs))
    wall = time.perf_counter() - t0
    table: dict[str, Counter[str]] = {c: Counter(t.outcome for t in trials if t.cls == c) for c in classes}
    chunk_checks = [t for t in trials if t.chunks_expected is not None]
    chunk_fail = [t for t in chunk_checks if (t.messages_read or 0) < (t.chunks_expected or 0)]
    cols = [*OUTCOMES, "skipped"]
    print(f"{'class':10s} {'trials':>6s} " + " ".join(f"{o:>18s}" for o in cols))
    for c in classes:
        print(f"{c:10s} {sum(table[c].values()):6d} " + " ".join(f"{table[c].get(o, 0):18d}" for o in cols))
    print(f"intact chunks (MCAP, ROS1), message records (ROS1 uncompressed), whole lines (text CAN logs) or a DCA1000 "
          f"recording's whole frames kept: {len(chunk_checks) - len(chunk_fail)} of {len(chunk_checks)} trials")
    for t in trials:
        if t.cls == "dca1000" and "not the recording's kept as its own" in t.detail:
            print(f"  {t.cls} #{t.n} ({t.outcome}): {t.fault} -- {t.detail[:240]}")
    for c in classes:
        read = [t for t in trials if t.cls == c and t.messages_whole]
        if read:
            print(f"{c}: messages read of the undamaged files' where the ingest ended well ({len(read)} trials): "
                  f"{sum(t.messages_read or 0 for t in read)} of {sum(t.messages_whole or 0 for t in read)}; "
                  + ", ".join(f"{k} {sum(t.messages_read or 0 for t in read if k in t.fault)} of "
                              f"{sum(t.messages_whole or 0 for t in read if k in t.fault)}"
                              for k in sorted({t.fault.split(':')[0] for t in read})))
    for t in trials:
        if t.outcome in BAD:
            print(f"  {t.cls} #{t.n} {t.outcome}: {t.fault} -- {t.detail}")
    for t in chunk_fail:
        print(f"  {t.cls} #{t.n} lost intact chunks: {t.fault}: read {t.messages_read}, intact {t.chunks_expected}"
              f" ({t.outcome}: {t.detail})")
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / "fault_campaign.json"
    out = {"seed": args.seed, "scale": args.scale, "wall_s": {}, "table": {},
           "intact_chunks_kept": {}, "trials": []}
    if set(classes) != set(COUNTS) and path.exists():  # a subset of the classes: merge into the last run's
        old = json.loads(path.read_text())
        if old.get("seed") == args.seed and old.get("scale") == args.scale:
            out = old
    out["python"] = sys.version.split()[0]
    out["wall_s"] = {**out["wall_s"], ",".join(classes): round(wall, 1)}
    out["table"] = {**out["table"], **{c: dict(table[c]) for c in classes}}
    out["trials"] = [t for t in out["trials"] if t["cls"] not in classes] + [asdict(t) for t in trials]
    checked = [t for t in out["trials"] if t["chunks_expected"] is not None]
    out["intact_chunks_kept"] = {"trials": len(checked), "failed": sum(
        1 for t in checked if (t["messages_read"] or 0) < t["chunks_expected"])}
    mcap = [t["unverified"] for t in out["trials"] if t.get("unverified")]
    if mcap:
        out["mcap_allow_unverified"] = {"trials": len(mcap), **{k: sum(u[k] for u in mcap) for k in mcap[0]}}
        print("MCAP messages read of the undamaged file's, without / with --allow-unverified (not in it): "
              + ", ".join(f"{k} {v}" for k, v in out["mcap_allow_unverified"].items()))
    path.write_text(json.dumps(out, indent=1) + "\n")
    print(f"{len(trials)} trials in {wall:.0f} s; wrote {RESULTS / 'fault_campaign.json'}")
    if args.workdir is None:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
