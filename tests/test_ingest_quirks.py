"""Quirks of real cars' logs that must not be taken without a word (a helper's hunt for silently wrong results).

Each test rewrites the simulated ci drive the way a real recording goes wrong and checks the product, or the warning
that must name the problem."""

from __future__ import annotations

import struct
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from autosar_cli.config import load_config
from autosar_cli.ingest.pipeline import ingest

GNSS_AND_RADAR = {"/ins_cog/fix", "/ins_cog/fix_velocity", "/ins_cog/nmea", "/ins_radar/fix", "/ins_radar/vel",
                  "/scanbrick/raw_frames"}


def rewrite_mcap(src: Path, dst: Path, fn: Callable[[str, int, bytes], tuple[int, bytes] | None]) -> Path:
    """``src`` copied to ``dst`` message by message: ``fn(topic, log_ns, cdr)`` gives (log_ns, cdr), or None to leave
    the message out."""
    with open(src, "rb") as f, open(dst, "wb") as g:
        r = make_reader(f)
        w = Writer(g, compression=CompressionType.ZSTD)
        w.start("ros2", "quirks")
        summary = r.get_summary()
        assert summary is not None
        schemas = {sid: w.register_schema(s.name, s.encoding, s.data) for sid, s in summary.schemas.items()}
        channels = {cid: w.register_channel(c.topic, c.message_encoding, schemas[c.schema_id], c.metadata)
                    for cid, c in summary.channels.items()}
        for _, ch, m in r.iter_messages(log_time_order=True):
            out = fn(ch.topic, m.log_time, bytes(m.data))
            if out is not None:
                w.add_message(channels[ch.id], out[0], out[1], out[0])
        w.finish()
    return dst


def header_stamp(cdr: bytes) -> int:
    """A CDR message's std_msgs/Header stamp (ns): the first field after the 4-byte encapsulation."""
    sec, nsec = struct.unpack_from("<iI", cdr, 4)
    return sec * 1_000_000_000 + nsec


def with_header_stamp(cdr: bytes, t_ns: int) -> bytes:
    sec, nsec = divmod(t_ns, 1_000_000_000)
    return cdr[:4] + struct.pack("<iI", sec, nsec) + cdr[12:]


def test_gnss_outliving_the_imus_and_can_gives_a_trajectory_its_readers_take(sim_dir: Path, tmp_path: Path) -> None:
    """The car's IMUs and CAN stop 0.3 s before its GNSS and radar (a logger's streams stop at different times):
    SAR-MIN dead-reckons to the last fixes in max_step_s steps summed in floats, lands a hair before a fix's instant
    and writes both, one ns apart in float seconds and the same after rounding to ns. navigate exited 0 with the
    trajectory.h5 holding repeated t_ns (urban: 7 of them with 1 s cut, 1 with 0.3 s), which focus and every other
    reader then refuse ('t_ns does not increase at sample N')."""
    from dataclasses import replace

    from conftest import NAV_ONLY_PRF_HZ, simulated

    from autosar_cli.nav.navigate import navigate
    from autosar_cli.store.trajectory import read_trajectory, write_trajectory

    sim = simulated(sim_dir, "urban", "mcap", 1, prf_hz=NAV_ONLY_PRF_HZ)
    with open(sim.log_path, "rb") as f:
        stats = make_reader(f).get_summary().statistics
    cut = stats.message_end_time - 300_000_000
    log = rewrite_mcap(sim.log_path, tmp_path / "cut.mcap",
                       lambda topic, t, cdr: None if topic not in GNSS_AND_RADAR and t > cut else (t, cdr))
    base = load_config()
    cfg = replace(base, radar=replace(base.radar, prf_hz=NAV_ONLY_PRF_HZ))
    ingest([log], tmp_path / "d.h5", config=cfg)
    traj = navigate(tmp_path / "d.h5", "sar-min", cfg)
    assert np.all(np.diff(traj.t_ns) > 0), f"t_ns repeats at samples {np.flatnonzero(np.diff(traj.t_ns) <= 0)}"
    write_trajectory(tmp_path / "t.h5", traj)
    read_trajectory(tmp_path / "t.h5")
