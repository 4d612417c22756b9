"""Benchmark `autosar ingest`: throughput (MB/s of log) and peak memory, 1x and 4x drive length.

Usage: python benches/bench_ingest.py [--scenario test1] [--repeat 3] [--workdir DIR]

Simulates the scenario (MCAP, seed 1) once, builds a 4x longer log by repeating its messages with
shifted times and frame indices, then ingests each log ``--repeat`` times, every run in a fresh
process that ingests the log twice and reports both wall times (cold: the first ingest of the
process, including one-time lazy imports and type-store builds, ~0.3 s; warm: the second) and its
peak RSS. Throughput is log bytes / warm median. Prints a table and writes benches/results/ingest.json.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"

_CHILD = r"""
import json, resource, sys, time
from pathlib import Path
from autosar_cli.config import load_config
from autosar_cli.ingest.pipeline import ingest
cfg = load_config()
out = Path(sys.argv[2])
walls = []
for _ in range(2):  # cold: first ingest of the process (lazy imports, type stores); warm: the second one
    out.unlink(missing_ok=True)
    t = time.perf_counter()
    report = ingest([Path(sys.argv[1])], out, config=cfg)
    walls.append(time.perf_counter() - t)
print(json.dumps({"cold_s": walls[0], "wall_s": walls[1], "bytes": report.bytes_read, "messages": report.messages,
                  "duration_s": (report.end_ns - report.start_ns) / 1e9,
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "drive_bytes": out.stat().st_size}))
out.unlink()
"""


def repeat_log(src: Path, dst: Path, times: int) -> None:
    """Write ``src`` ``times`` times in a row: log times, header stamps and radar frame indices shifted.

    Every message type of the simulator starts with a std_msgs/Header, so the stamp sits at bytes 4..12
    of the CDR payload; RawFrame's frame_index follows the frame_id string.
    """
    from mcap.reader import make_reader
    from mcap.writer import CompressionType, Writer

    with open(src, "rb") as f:
        summary = make_reader(f).get_summary()
        assert summary is not None
        span = summary.statistics.message_end_time - summary.statistics.message_start_time + 1_000_000
        frames = max(summary.statistics.channel_message_counts.values())
    with open(dst, "wb") as out:
        w = Writer(out, compression=CompressionType.ZSTD, chunk_size=4 * 1024 * 1024)
        w.start(profile="ros2", library="bench_ingest")
        ids: dict[int, int] = {}
        schema_ids: dict[int, int] = {}
        for k in range(times):
            with open(src, "rb") as f:
                for schema, channel, msg in make_reader(f).iter_messages(log_time_order=False):
                    if schema.id not in schema_ids:
                        schema_ids[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
                    if channel.id not in ids:
                        ids[channel.id] = w.register_channel(channel.topic, channel.message_encoding,
                                                             schema_ids[schema.id])
                    data = bytearray(msg.data)
                    sec, nsec = struct.unpack_from("<iI", data, 4)
                    stamp = sec * 1_000_000_000 + nsec + k * span
                    struct.pack_into("<iI", data, 4, stamp // 1_000_000_000, stamp % 1_000_000_000)
                    if schema.name.endswith("RawFrame"):
                        (n,) = struct.unpack_from("<I", data, 12)
                        pos = 4 + ((16 + n - 4 + 3) & ~3)
                        (idx,) = struct.unpack_from("<I", data, pos)
                        struct.pack_into("<I", data, pos, idx + k * (frames + 10))
                    w.add_message(ids[channel.id], msg.log_time + k * span, bytes(data), msg.publish_time + k * span)
        w.finish()


def ingest_once(log: Path, workdir: Path) -> dict:
    proc = subprocess.run([sys.executable, "-c", _CHILD, str(log), str(workdir / "drive.h5")], check=True,
                          capture_output=True, text=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="test1")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--workdir", type=Path, default=None, help="keep the simulated logs here (reused if present)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = args.workdir or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        log1 = work / f"{args.scenario}_seed1.mcap"
        if not log1.exists():
            subprocess.run([sys.executable, "-m", "autosar_cli.cli", "simulate", "--scenario", args.scenario,
                            "--seed", "1", "--output", str(log1), "--overwrite"], check=True, capture_output=True)
        log4 = work / f"{args.scenario}_seed1_x4.mcap"
        if not log4.exists():
            repeat_log(log1, log4, 4)
        rows = []
        for label, log in (("1x", log1), ("4x", log4)):
            runs = [ingest_once(log, work) for _ in range(args.repeat)]
            wall = statistics.median(r["wall_s"] for r in runs)
            cold = statistics.median(r["cold_s"] for r in runs)
            r0 = runs[0]
            rows.append({"log": label, "scenario": args.scenario, "repeat": args.repeat,
                         "log_MB": round(r0["bytes"] / 1e6, 1), "drive_s": round(r0["duration_s"], 2),
                         "messages": r0["messages"], "median_wall_s": round(wall, 3),
                         "walls_s": [round(r["wall_s"], 3) for r in runs],
                         "throughput_MB_s": round(r0["bytes"] / 1e6 / wall, 1),
                         "median_cold_wall_s": round(cold, 3),
                         "cold_throughput_MB_s": round(r0["bytes"] / 1e6 / cold, 1),
                         "peak_rss_MB": round(max(r["peak_rss_mb"] for r in runs), 1),
                         "drive_h5_MB": round(r0["drive_bytes"] / 1e6, 1)})
    head = ("log", "MB", "drive s", "warm s", "MB/s", "cold s", "MB/s", "peak RSS MB", "drive.h5 MB")
    print("{:4s} {:>7s} {:>8s} {:>8s} {:>7s} {:>8s} {:>7s} {:>12s} {:>12s}".format(*head))
    for r in rows:
        print(f"{r['log']:4s} {r['log_MB']:7.1f} {r['drive_s']:8.2f} {r['median_wall_s']:8.3f} "
              f"{r['throughput_MB_s']:7.1f} {r['median_cold_wall_s']:8.3f} {r['cold_throughput_MB_s']:7.1f} "
              f"{r['peak_rss_MB']:12.1f} {r['drive_h5_MB']:12.1f}")
    RESULTS.mkdir(exist_ok=True)
    result = {"benchmark": "ingest", "machine": {"cpus": _cpus(), "python": platform.python_version()},
              "target": {"throughput_MB_s": 200, "peak_rss_MB": 400}, "rows": rows}
    (RESULTS / "ingest.json").write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {RESULTS / 'ingest.json'}")


def _cpus() -> int:
    import os

    return len(os.sched_getaffinity(0))


if __name__ == "__main__":
    main()
