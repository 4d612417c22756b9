"""CAN log damage sweep: frames read from real CANedge MDF4 files, finalised copies, a BLF, an ASC, damaged everywhere.

Each of the three CANedge files under ``../shared/realdata/css-electronics``, a finalised copy of two of them
(written by asammdf, uncompressed), a BLF of the three files' frames (written by python-can, its default 128 KiB
log containers) and an ASC of the 2023 file's (python-can) gets 4 KiB zeroed at every 4 KiB, and 64 random bytes
(seeded) at every 2 KiB, one damage per trial, and is read with ``read_can_log`` as ingest reads it. The ASC and
a TRC of the same frames (python-can) also get one printable byte (seeded, not the one there) overwritten at a
seeded place of every 8th frame line: the damage a text log's reader may take for an event it does not read; and
each CANedge file 40 trials of random bytes added, or bytes lost, at a seeded place before its data (8 B to 8 KiB:
every block after the place moves), and each finalised copy 40 trials of its own bytes (seeded, block headers among
them) added, or bytes lost, at a seeded place anywhere (its data come before its blocks). Per trial:
the frames read, whether none were, how many of them the undamaged file does not have (foreign: wrong and not
reported; an MDF4 conversion block damaged so that it still parses gives these), and whether anything but a
``CanLogError`` came out (a traceback); summed, the trials that lost frames or read foreign ones without a word
(``unsaid_loss``, ``unsaid_foreign``: a data byte's hex digit made another reads as a frame, which no text log's
checksum shows). ``--against
DIR`` runs the same trials with the package of another checkout beside this one's (``git worktree add DIR REV``), in
the same run. Results: ``benches/results/can_log_damage.json``, summed per format (``summary``: the MDF4 files,
``blf``, ``asc``, ``trc``; the shift trials ``mdf4_shifted``, ``finalised_shifted``; the line trials ``asc_lines``,
``trc_lines``;
``..._against``: the other checkout's).

Usage: python benches/bench_can_log_damage.py [--against DIR] [--zero-step 4096] [--random-step 2048]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import random
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from checkouts import in_checkout, revision

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
REAL = REPO.parent / "shared" / "realdata" / "css-electronics"
FILES = ("2F6913DB_00000004_00000001.MF4", "2F6913DB_00001089_00000001-63BEF5CD.MF4",
         "2F6913DB_00001089_00000002-63BEFDF9.MF4")
FINALISED = FILES[:2]
ZEROED = 4096
OVERWRITTEN = 64
LINE_STEP = 8  # every 8th frame line of a text log gets a printable byte
SHIFT_TRIALS = 40  # bytes added or lost before a CANedge file's data, per file
SHIFT_LENGTHS = (8, 16, 24, 100, 512, 1000, 4096, 8192)


def _damages(size: int, zero_step: int, random_step: int, seed: int) -> list[tuple[str, int, bytes]]:
    """(kind, byte, the bytes put there) of each trial on a file of ``size`` bytes."""
    rng = random.Random(seed)
    out = [("zeroed", at, bytes(min(ZEROED, size - at))) for at in range(0, size, zero_step)]
    out += [("overwritten", at, rng.randbytes(min(OVERWRITTEN, size - at))) for at in range(0, size, random_step)]
    return out


def _line_damages(data: bytes, seed: int) -> list[tuple[str, int, bytes]]:
    """("printable byte", byte, the byte put there) of each line trial on a text log's bytes ``data``: a seeded
    place of every :data:`LINE_STEP`-th frame line (a line whose first non-blank is a digit, not "Start of
    measurement")."""
    rng = random.Random(seed)
    out, start = [], 0
    frame_lines = 0
    for line in data.split(b"\n"):
        body = line.rstrip(b"\r")
        if body.strip()[:1].isdigit() and b"Start of" not in body:
            if frame_lines % LINE_STEP == 0:
                at = rng.randrange(len(body))
                put = bytes([rng.choice([c for c in range(0x20, 0x7F) if c != body[at]])])
                out.append(("printable byte", start + at, put))
            frame_lines += 1
        start += len(line) + 1
    return out


def _shift_damages(data: bytes, seed: int) -> list[tuple[str, int, bytes, int]]:
    """("added"/"lost", byte, the bytes put there, the bytes taken out) of each shift trial on an MDF4 file's bytes
    ``data``: :data:`SHIFT_TRIALS` seeded places before its first data block, random bytes added or bytes lost,
    of seeded lengths (every block after the place moves)."""
    rng = random.Random(seed)
    first_data = data.find(b"##DT\x00\x00\x00\x00")
    out = []
    for k in range(SHIFT_TRIALS):
        at, n = rng.randrange(200, first_data), rng.choice(SHIFT_LENGTHS)
        out.append(("added", at, rng.randbytes(n), 0) if k % 2 == 0 else ("lost", at, b"", n))
    return out


def _finalised_shift_damages(data: bytes, seed: int) -> list[tuple[str, int, bytes, int]]:
    """("added"/"lost", byte, the bytes put there, the bytes taken out) of each shift trial on a finalised MDF4
    file's bytes ``data``: :data:`SHIFT_TRIALS` seeded places anywhere past its header, a seeded stretch of its own
    bytes added (copies of block headers among them) or bytes lost, of seeded lengths."""
    rng = random.Random(seed)
    out = []
    for k in range(SHIFT_TRIALS):
        at, n = rng.randrange(200, len(data) - max(SHIFT_LENGTHS)), rng.choice(SHIFT_LENGTHS)
        source = rng.randrange(0, len(data) - n)
        out.append(("added", at, data[source:source + n], 0) if k % 2 == 0 else ("lost", at, b"", n))
    return out


def _sweep(files: list[Path], zero_step: int, random_step: int) -> list[dict[str, object]]:
    """The trials on ``files`` with the package importable now (a worker's: its checkout first on sys.path)."""
    import logging

    from autosar_cli.ingest.canlog import CanLogError, read_can_log

    logging.getLogger("asammdf").setLevel(logging.CRITICAL)  # asammdf logs the damage it meets; the trial counts it

    def frames(path: Path) -> tuple[list[tuple[object, ...]], str]:
        got: list[tuple[object, ...]] = []
        try:
            for r in read_can_log(path):
                got.append((r.t_ns, r.frame_id, r.is_extended, r.dlc, r.data, r.channel))
        except CanLogError:
            return got, "error"
        except Exception as exc:  # what the user would see as a traceback
            return got, f"traceback: {type(exc).__name__}"
        return got, ""

    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-can-log-") as scratch:
        for src in files:
            data = src.read_bytes()
            whole, _ = frames(src)
            known = set(whole)
            trials = [(kind, at, put, len(put)) for kind, at, put in
                      _damages(len(data), zero_step, random_step, seed=len(data))]
            if src.suffix.lower() in (".asc", ".trc"):
                trials += [(kind, at, put, len(put)) for kind, at, put in _line_damages(data, seed=len(data))]
            if src.suffix.lower() == ".mf4":
                trials += (_shift_damages if src.parent == REAL else _finalised_shift_damages)(data, seed=len(data))
            for n, (kind, at, put, taken) in enumerate(trials):
                trial = Path(scratch) / f"{n}_{src.name}"
                trial.write_bytes(data[:at] + put + data[at + taken:])
                got, ended = frames(trial)
                trial.unlink()
                rows.append({"file": src.name, "kind": kind, "at": at, "frames_read": len(got),
                             "frames_whole": len(whole), "foreign": sum(1 for g in got if g not in known),
                             "ended": ended})
    return rows


def _summary(rows: list[dict[str, object]]) -> dict[str, object]:
    read = sum(int(r["frames_read"]) for r in rows)  # type: ignore[call-overload]
    whole = sum(int(r["frames_whole"]) for r in rows)  # type: ignore[call-overload]
    return {"trials": len(rows), "frames_read": read, "frames_whole": whole, "share_read": round(read / whole, 4),
            "none_read": sum(1 for r in rows if r["frames_read"] == 0),
            "foreign_frames": sum(int(r["foreign"]) for r in rows),  # type: ignore[call-overload]
            "tracebacks": sum(1 for r in rows if str(r["ended"]).startswith("traceback")),
            "unsaid_loss": sum(1 for r in rows if not r["ended"] and r["frames_read"] < r["frames_whole"]),
            "unsaid_foreign": sum(1 for r in rows if not r["ended"] and r["foreign"])}


def _log_of(logs: list[Path], dest: Path) -> Path:
    """A log of the frames of ``logs``, in turn, written by python-can in ``dest``'s format (BLF, ASC, TRC). An ASC's
    header dates are its writing's ("date ...", "Begin Triggerblock ..."): held to one moment, so that every run
    damages the same bytes of the same lines."""
    from datetime import datetime
    from unittest import mock

    import can

    from autosar_cli.ingest.canlog import read_can_log

    class _Written(datetime):
        @classmethod
        def now(cls, tz: object = None) -> _Written:  # type: ignore[override]
            return cls(2023, 1, 11, 18, 42, 9, 103000)

    with mock.patch("can.io.asc.datetime", _Written), \
            {".blf": can.BLFWriter, ".asc": can.ASCWriter, ".trc": can.TRCWriter}[dest.suffix](dest) as writer:
        for log in logs:
            for r in read_can_log(log):
                writer.on_message_received(can.Message(
                    timestamp=r.t_ns / 1e9, arbitration_id=r.frame_id, is_extended_id=r.is_extended, dlc=r.dlc,
                    data=r.data, is_error_frame=r.is_error, is_remote_frame=r.is_remote, channel=int(r.channel) - 1))
    return dest


def _worker(root: Path, files: list[Path], zero_step: int, random_step: int, out: Path) -> list[dict[str, object]]:
    """The sweep in a process of its own, ``root``'s package first on its path."""
    return in_checkout(__file__, root, ["--zero-step", str(zero_step), "--random-step", str(random_step),
                                        *map(str, files)], out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--against", type=Path, help="another checkout whose package runs the same trials beside")
    ap.add_argument("--zero-step", type=int, default=4096)
    ap.add_argument("--random-step", type=int, default=2048)
    ap.add_argument("--output", type=Path, default=HERE / "results" / "can_log_damage.json")
    ap.add_argument("--worker", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("files", nargs="*", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        args.worker.write_text(json.dumps(_sweep(args.files, args.zero_step, args.random_step)))
        return
    if not REAL.is_dir():
        sys.exit(f"{REAL} is absent: the sweep needs the real CANedge files")
    from asammdf import MDF

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="bench-can-log-") as scratch:
        files = [REAL / name for name in FILES]
        for name in FINALISED:
            copy = Path(scratch) / name.replace(".MF4", ".mf4")
            with MDF(REAL / name) as mdf:
                mdf.save(copy, overwrite=True, compression=0)
            files.append(copy)
        files.append(_log_of(files[:len(FILES)], Path(scratch) / "css_frames.blf"))
        files.append(_log_of(files[1:2], Path(scratch) / "css_2023.asc"))
        files.append(_log_of(files[1:2], Path(scratch) / "css_2023.trc"))
        roots = {"this": REPO, **({"against": args.against.resolve()} if args.against else {})}
        with ThreadPoolExecutor(len(roots)) as pool:  # the two checkouts side by side, a process each
            runs = {name: pool.submit(_worker, root, files, args.zero_step, args.random_step,
                                      Path(scratch) / f"{name}.json") for name, root in roots.items()}
            rows = {name: run.result() for name, run in runs.items()}
    result: dict[str, object] = {
        "benchmark": "can_log_damage", "damage": f"{ZEROED} B zeroed every {args.zero_step} B, {OVERWRITTEN} random "
        f"B every {args.random_step} B", "files": len(files)}
    # the loggers' own files end in .MF4, the finalised copies in .mf4
    kinds = (("mdf4", (".mf4", ".MF4"), ("zeroed", "overwritten")), ("mdf4_shifted", (".MF4",), ("added", "lost")),
             ("finalised_shifted", (".mf4",), ("added", "lost")),
             ("blf", (".blf",), ("zeroed", "overwritten")), ("asc", (".asc",), ("zeroed", "overwritten")),
             ("trc", (".trc",), ("zeroed", "overwritten")), ("asc_lines", (".asc",), ("printable byte",)),
             ("trc_lines", (".trc",), ("printable byte",)))
    for kind, suffixes, damages in kinds:
        for name in roots:
            mine = [r for r in rows[name] if Path(str(r["file"])).suffix in suffixes
                    and r["kind"] in damages]
            key = ("summary" if kind == "mdf4" else kind) if name == "this" else f"{kind}_against"
            result[key] = {"revision": revision(roots[name]), **_summary(mine)}
    result |= {"wall_s": round(time.perf_counter() - t0, 1), "rows": rows["this"],
               "python": platform.python_version(), "cores": os.cpu_count()}
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(result, indent=1) + "\n")
    for key, summary in result.items():
        if isinstance(summary, dict):
            print(key, json.dumps(summary))
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
