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


@pytest.mark.parametrize(("topic", "named", "stamp"), [
    # a CAN bridge stamping its frames with the time since boot (1000 s in)
    ("/from_can_bus", "can/", lambda t, first: t - first + 1000 * 1_000_000_000),
    # the 6-DoF IMU's own clock, not synchronised, 0.3 s late against the logger's
    ("/ins_cog/imu", "imu/ins_cog", lambda t, first: t + 300_000_000),
])
def test_a_stream_stamped_on_another_clock_is_warned_of(ci_mcap, tmp_path: Path, topic: str, named: str,
                                                        stamp: Callable[[int, int], int]) -> None:
    """Every stream of one recording is stamped within milliseconds of its log time (latency), but ingest takes each
    stream's header stamps as they are, whatever their offset from the log times (a stream's own clock offset is only
    used to repair jumps within it). The CAN on a boot clock: exit 0, no warning, 'drive of 1612950257.98 s' (51 years,
    urban seed 1), navigate 'travelled 8075235286.6 m' with the wheels, steering and CAN gyros nowhere in the drive's
    real span. The 6-DoF IMU 0.3 s late: navigate's GNSS latency fit moves the GNSS by -294 ms (the samples 'refer to
    -244 ms before their stamps', which no receiver does), and the track is 1.25 m off the truth (median; 0.225 as
    recorded), 0.387 m RMS across once aligned (0.009), exit 0 with no warning. Ingest knows each stream's clock
    offset (header - log): one far from the others' must be a warning naming the stream."""
    first: dict[str, int] = {}

    def fn(t_topic: str, t: int, cdr: bytes) -> tuple[int, bytes]:
        if t_topic != topic:
            return t, cdr
        h = header_stamp(cdr)
        first.setdefault("t", h)
        return t, with_header_stamp(cdr, stamp(h, first["t"]))

    log = rewrite_mcap(ci_mcap.log_path, tmp_path / "clock.mcap", fn)
    report = ingest([log], tmp_path / "d.h5", config=load_config())
    assert [w for w in report.warnings if named in w or topic in w], report.warnings


_DBC = '''VERSION ""

NS_ :

BS_:

BU_: ECU

BO_ 256 SPD: 8 ECU
 SG_ SPEED_A : 8|16@1+ (0.01,0) [0|655.35] "m/s" ECU

'''


def _speed_frame(raw: int) -> str:
    return bytes([0, raw & 0xFF, raw >> 8, 0, 0, 0, 0, 0]).hex().upper()


@pytest.mark.parametrize("other", ["can0 00000100", "can1 100"], ids=["extended_id", "second_bus"])
def test_another_message_with_the_same_number_is_not_decoded_as_the_dbcs(tmp_path: Path, other: str) -> None:
    """A candump log of 0x100 (standard, 10 m/s) beside frames of another message numbered 0x100: an extended id
    0x00000100 (a J1939-style ECU), or 0x100 on a second bus (can1). The decoder looks an unknown (id, extended) up
    under the other flag and ignores the channel, so both land in /can/SPD: 400 rows alternating 10 and 30 m/s, exit
    0, no warning of it (the warnings said are of the config's roles and the radar, which this log lacks). A DBC
    without a CHECKSUM signal (any car but the Giulia, [can] checksum = "none") has nothing else to stop them."""
    import h5py

    dbc = tmp_path / "spd.dbc"
    dbc.write_text(_DBC)
    t = 1_700_000_000.0
    lines = []
    for i in range(200):
        lines.append(f"({t + i * 0.01:.6f}) can0 100#{_speed_frame(1000)}")
        lines.append(f"({t + i * 0.01 + 0.0003:.6f}) {other}#{_speed_frame(3000)}")
    log = tmp_path / "two.log"
    log.write_text("\n".join(lines) + "\n")
    report = ingest([], tmp_path / "d.h5", config=load_config(), can_logs=[log], dbc=dbc, allow_partial=True)
    with h5py.File(tmp_path / "d.h5", "r") as f:
        speeds = f["can/SPD/SPEED_A"][()]
    assert len(speeds) == 200 and set(np.round(speeds, 2)) == {10.0}, np.unique(speeds, return_counts=True)
    said = [w for w in report.warnings if "SPD (0x100) on can1, read from can0 ×200" in w]
    assert bool(said) == (other == "can1 100"), report.warnings  # an extended 0x00000100 is simply not in the DBC


def test_a_multiplexed_dbc_message_is_decoded_or_refused_clearly(tmp_path: Path) -> None:
    """A DBC with a multiplexed message (one signal per multiplexer value, common in real DBCs): ingest failed with
    "error: 'TEMP_B'" (a KeyError: the decoder asks every signal of each frame, and cantools gives only the ones its
    multiplexer selects), the whole CAN log lost."""
    dbc = tmp_path / "mux.dbc"
    dbc.write_text(_DBC.replace(' SG_ SPEED_A : 8|16@1+ (0.01,0) [0|655.35] "m/s" ECU\n',
                                ' SG_ MUX M : 0|8@1+ (1,0) [0|255] "" ECU\n'
                                ' SG_ SPEED_A m0 : 8|16@1+ (0.01,0) [0|655.35] "m/s" ECU\n'
                                ' SG_ TEMP_B m1 : 8|16@1+ (0.1,-40) [-40|6513.5] "degC" ECU\n'))
    t = 1_700_000_000.0
    log = tmp_path / "mux.log"
    log.write_text("".join(f"({t + i * 0.01:.6f}) can0 100#{'00E8030000000000' if i % 2 == 0 else '01BC020000000000'}\n"
                           for i in range(200)))
    mine = tmp_path / "mux.toml"  # the multiplexed signal as a role: the navigation reads the rows that carry it
    mine.write_text('base = "default"\n[can.roles]\nsteering_wheel_angle = "SPD.SPEED_A"\n')
    report = ingest([], tmp_path / "d.h5", config=load_config(mine), can_logs=[log], dbc=dbc, allow_partial=True)
    assert report.can["decoded"] == 200
    import h5py

    from autosar_cli.store.drive import Drive

    with Drive(tmp_path / "d.h5") as d:
        t, angle = d.can_role("steering_wheel_angle")
    assert len(t) == 100 and np.all(angle == 10.0) and np.all(np.diff(t) > 0)

    with h5py.File(tmp_path / "d.h5", "r") as f:  # each frame's row holds the signal its multiplexer selects
        speed, temp = f["can/SPD/SPEED_A"][()], f["can/SPD/TEMP_B"][()]
    assert np.array_equal(np.isnan(speed), np.arange(200) % 2 == 1) and np.all(speed[::2] == 10.0)
    assert np.array_equal(np.isnan(temp), np.arange(200) % 2 == 0)
    assert np.allclose(temp[1::2], 700 * 0.1 - 40), temp[1]  # 0x2BC at 0.1 degC, -40
