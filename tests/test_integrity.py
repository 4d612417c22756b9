"""Stored products are checked when read: Fletcher-32 checksums turn a flipped byte into an error naming the
file and dataset, and a trajectory no car could drive is refused."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from autosar_cli.cli import app
from autosar_cli.config import load_config
from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.nav.navigate import navigate
from autosar_cli.nav.trajectory import Trajectory
from autosar_cli.sar.focus import DAMAGED_FRAMES
from autosar_cli.store.drive import Column, Drive, DriveWriter
from autosar_cli.store.hdf5_read import DamagedFileError
from autosar_cli.store.image import read_image
from autosar_cli.store.trajectory import TrajectoryFormatError, read_trajectory, write_trajectory

runner = CliRunner()


def _straight_track(n: int = 200) -> Trajectory:
    """A car at 2 m/s heading north-east, 100 Hz, turning at 0.1 rad/s (float64 reference values)."""
    t_ns = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 10_000_000
    t = (t_ns - t_ns[0]) / 1e9
    heading = 0.7 + 0.1 * t
    xy = np.stack([np.cumsum(2.0 * 0.01 * np.cos(heading)), np.cumsum(2.0 * 0.01 * np.sin(heading))], axis=1)
    return Trajectory("test", t_ns, xy, heading, np.full(n, 2.0), np.full(n, 0.1),
                      GeodeticOrigin(45.0, 9.0, 120.0), 1.4, 0.5)


def _flip_byte_in(path: Path, dataset: str, at: float = 0.5) -> None:
    """Flip one byte of ``dataset``'s first stored chunk (or contiguous data) in the file."""
    with h5py.File(path, "r") as f:
        ds = f[dataset]
        if ds.chunks:
            info = ds.id.get_chunk_info(0)
            offset, size = info.byte_offset, info.size
        else:
            offset, size = ds.id.get_offset(), ds.id.get_storage_size()
    with open(path, "r+b") as fh:
        fh.seek(offset + int(size * at))
        b = fh.read(1)[0]
        fh.seek(offset + int(size * at))
        fh.write(bytes([b ^ 0x10]))


def test_a_flipped_byte_in_a_trajectory_is_an_error_naming_file_and_dataset(tmp_path: Path) -> None:
    path = write_trajectory(tmp_path / "trajectory.h5", _straight_track())
    np.testing.assert_array_equal(read_trajectory(path).heading, _straight_track().heading)
    _flip_byte_in(path, "heading")
    with pytest.raises(DamagedFileError, match=r"trajectory\.h5: dataset /heading is damaged .*; make the trajectory "
                                               r"again from its drive \(autosar navigate\)$"):
        read_trajectory(path)


def test_a_product_cut_short_says_by_how_much(tmp_path: Path) -> None:
    """An HDF5 product cut short (an interrupted copy, a full disk) is named as such, with the bytes it has and
    those its superblock declares, not as "not an HDF5 file"; a file that is not HDF5 at all still is."""
    path = write_trajectory(tmp_path / "trajectory.h5", _straight_track())
    data = path.read_bytes()
    cut = tmp_path / "cut.h5"
    cut.write_bytes(data[:len(data) // 2])
    with pytest.raises(TrajectoryFormatError) as info:
        read_trajectory(cut)
    assert str(info.value) == (f"{cut}: cut short: {len(data) // 2} of the {len(data)} bytes its HDF5 superblock "
                               "declares (an interrupted copy or a full disk); make it again")
    r = runner.invoke(app, ["navigate", str(cut), "-o", str(tmp_path / "t.h5")])
    assert r.exit_code == 1 and "cut short" in r.stderr and "Traceback" not in r.output
    (tmp_path / "junk.h5").write_bytes(b"not hdf5" * 100)
    with pytest.raises(TrajectoryFormatError, match="junk.h5: not an HDF5 file"):
        read_trajectory(tmp_path / "junk.h5")
    with pytest.raises(TrajectoryFormatError, match=r"gone.h5: no such file or directory$"):
        read_trajectory(tmp_path / "gone.h5")  # the library's reader (the CLI checks its inputs before)
    # absent, or a directory: said so, not "not an HDF5 file ([Errno 2] Unable to synchronously open file ...)"
    (tmp_path / "a_dir").mkdir()
    for cmd, missing in ((["navigate", str(tmp_path / "gone.h5"), "-o", str(tmp_path / "t2.h5")], "gone.h5"),
                         (["focus", str(tmp_path / "a_dir"), "-t", str(path), "-o", str(tmp_path / "img")], "a_dir")):
        r = runner.invoke(app, cmd)
        assert r.exit_code == 1 and "Traceback" not in r.output
        why = "no such file or directory" if missing == "gone.h5" else "a directory, not a drive.h5"
        assert r.stderr.strip().endswith(f"{missing}: {why}"), r.stderr


def test_a_flipped_byte_in_the_radar_cube_is_an_error_naming_file_and_dataset(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    raw = rng.normal(0, 300, size=(64, 3, 4, 540, 2)).astype(np.int16)
    w = DriveWriter(tmp_path / "drive.h5", {"autosar_version": "test"})
    cube = w.radar("radar/scanbrick", (3, 4, 540), {})
    cube.append_frames(np.arange(64, dtype=np.int64) * 1_000_000, np.arange(64, dtype=np.int64), raw)
    w.table("can/ABS_1", {"t_ns": Column(np.int64), "speed": Column(np.float64)}, {}).append(
        {"t_ns": np.arange(10, dtype=np.int64), "speed": np.arange(10.0)})
    path = w.commit()
    with Drive(path) as d:
        np.testing.assert_array_equal(d.radar().frames(0, 64), raw)
        assert d.radar().raw.chunks == (64, 1, 1, 540, 2)  # one chunk per channel
    _flip_byte_in(path, "radar/scanbrick/raw", at=0.7)  # the first chunk: Tx 0, Rx 0's first 64 frames
    for pairs in (None, [(0, 0), (2, 3)]):
        with Drive(path) as d, pytest.raises(DamagedFileError, match=r"drive\.h5: dataset /radar/scanbrick/raw "
                                                                     r"is damaged"):
            d.radar().frames(0, 64, pairs)
    with Drive(path) as d:  # the other channels' chunks are intact, and read
        np.testing.assert_array_equal(d.radar().frames(0, 64, [(2, 3), (1, 0)]), raw[:, [2, 1], [3, 0]])
    # a missing dataset names the file and the dataset too, not h5py's "Unable to synchronously open object"
    with h5py.File(path, "r+") as f:
        del f["can/ABS_1/speed"]
        f["can"].attrs["roles"] = '{"wheel_speed_fl": "ABS_1/speed"}'
    with Drive(path) as d, pytest.raises(DamagedFileError, match=r"drive\.h5: dataset /can/ABS_1/speed is missing"):
        d.can_role("wheel_speed_fl")


def _flip_byte_in_chunk(path: Path, dataset: str, row: int, tx: int | None, rx: int | None) -> None:
    """Flip one byte in the middle of the stored chunk of ``dataset`` that holds ``row`` (of channel (tx, rx) of a
    radar cube; a table's column: None, None)."""
    with h5py.File(path, "r") as f:
        ds = f[dataset]
        coord = (row - row % ds.chunks[0],) + ((tx, rx, 0, 0) if tx is not None else (0,) * (ds.ndim - 1))
        info = ds.id.get_chunk_info_by_coord(coord)
    with open(path, "r+b") as fh:
        fh.seek(info.byte_offset + info.size // 2)
        b = fh.read(1)[0]
        fh.seek(info.byte_offset + info.size // 2)
        fh.write(bytes([b ^ 0x10]))


def test_a_damaged_radar_chunk_costs_only_its_frames(tmp_path: Path) -> None:
    """A flipped byte in Tx 0 / Rx 0's chunk of frames 64-127: reading frames 10-179 with that channel gives the
    others as stored and frames 64-127 zeroed in every channel, not intact; without that channel, all intact."""
    rng = np.random.default_rng(4)
    raw = rng.normal(0, 300, size=(192, 3, 4, 64, 2)).astype(np.int16)
    w = DriveWriter(tmp_path / "drive.h5", {"autosar_version": "test"})
    w.radar("radar/scanbrick", (3, 4, 64), {}).append_frames(np.arange(192, dtype=np.int64) * 1_000_000,
                                                             np.arange(192, dtype=np.int64), raw)
    path = w.commit()
    _flip_byte_in_chunk(path, "radar/scanbrick/raw", 100, 0, 0)
    pairs = [(0, 0), (2, 3)]
    with Drive(path) as d:
        radar = d.radar()
        with pytest.raises(DamagedFileError):
            radar.frames(10, 180, pairs)
        got, intact = radar.intact_frames(10, 180, pairs)
        whole, all_intact = radar.intact_frames(10, 180, [(2, 3), (1, 1)])
        everything, intact_all = radar.intact_frames(0, 192)
    bad = (np.arange(10, 180) >= 64) & (np.arange(10, 180) < 128)
    np.testing.assert_array_equal(intact, ~bad)
    np.testing.assert_array_equal(got[~bad], raw[10:180][~bad][:, [0, 2], [0, 3]])
    assert not got[bad].any()
    assert all_intact.all() and np.array_equal(whole, raw[10:180][:, [2, 1], [3, 1]])
    assert intact_all.sum() == 128 and np.array_equal(everything[intact_all], raw[intact_all])


@pytest.mark.parametrize("tiles", [1, 2])
def test_focus_of_a_drive_damaged_in_a_radar_chunk_leaves_out_its_frames_and_says_so(
        ci_run: Path, tmp_path: Path, tiles: int) -> None:
    """The ci drive with a flipped byte in a radar chunk of a channel the image uses: focus failed whole ("dataset
    ... is damaged and cannot be read"). It makes the image without that chunk's 64 frames: the warning names them
    by frame index, the image's parameters and the report count them, and the image is the undamaged one's but
    for those frames' part: its peak where the undamaged one's is, and the pixels those frames' beam never reaches
    the same to the bit."""
    for name in ("drive.h5", "trajectory.h5"):
        (tmp_path / name).write_bytes((ci_run / name).read_bytes())
    drive, traj = tmp_path / "drive.h5", tmp_path / "trajectory.h5"
    args = ["-t", str(traj), "--json", "--tiles", str(tiles)]
    r = runner.invoke(app, ["focus", str(drive), "-o", str(tmp_path / "whole"), *args])
    assert r.exit_code == 0, r.output
    whole = json.loads(r.stdout)
    with Drive(drive) as d:
        radar = d.radar()
        middle = len(radar.t_ns) // 2
        first = middle - middle % radar.raw.chunks[0]
        index = radar.frame_index[first:first + radar.raw.chunks[0]]
        dataset = radar.raw.name
    _flip_byte_in_chunk(drive, dataset, middle, 0, 1)
    r = runner.invoke(app, ["focus", str(drive), "-o", str(tmp_path / "damaged"), *args])
    assert r.exit_code == 0, r.output
    damaged = json.loads(r.stdout)
    assert damaged["frames_skipped"][DAMAGED_FRAMES] == 64
    assert damaged["frames_used"] == whole["frames_used"] - 64
    assert damaged["warnings"][0] == (f"{drive}: 64 frames of radar {radar.name} (frame index {index[0]}-{index[-1]}) "
                                      "failed their checksum (the drive is damaged there): left out of the image, "
                                      "which lacks their part")
    a, b = read_image(tmp_path / "whole.h5"), read_image(tmp_path / "damaged.h5")
    assert b.params["frames_damaged"] == 64 and a.params["frames_damaged"] == 0
    assert b.provenance["warnings"] == damaged["warnings"] and damaged["status"] == "degraded"
    if tiles == 1:  # its evaluation is marked degraded by the image's own warning (it read only the drive's: ok)
        r = runner.invoke(app, ["evaluate", str(tmp_path / "damaged.h5"), "-o", str(tmp_path / "ev"), "--json"])
        assert r.exit_code == 0, r.output
        assert json.loads(r.stdout)["status"] == "degraded"
    peak = np.unravel_index(np.argmax(np.abs(a.image)), a.image.shape)
    assert np.unravel_index(np.argmax(np.abs(b.image)), b.image.shape) == peak
    assert abs(b.image[peak]) <= abs(a.image[peak]) * (1 + 1e-6)
    assert 0.3 < np.mean(a.image == b.image) < 0.95  # ci seed 7: 66 % to the bit
    assert 0.99 < np.linalg.norm(b.image) / np.linalg.norm(a.image) < 1.0  # 64 of ~2000 frames: 0.9985


def test_a_damaged_table_chunk_costs_only_its_rows(tmp_path: Path) -> None:
    """A flipped byte in the second stored chunk (rows 4096-8191) of one column of a 10000-row table: reading the
    table gives every column without those rows, the others as stored, and one line in the drive's ``damage``
    naming them; a signal read by its CAN role the same."""
    t_ns = np.arange(10000, dtype=np.int64) * 1_000_000
    speed = np.sin(np.arange(10000) / 300.0)
    w = DriveWriter(tmp_path / "drive.h5", {"autosar_version": "test"})
    w.table("can/ABS_1", {"t_ns": Column(np.int64), "speed": Column(np.float64)}, {}).append(
        {"t_ns": t_ns, "speed": speed})
    w.set_attrs("can", {"roles": '{"wheel_speed_fl": "ABS_1/speed"}'})
    path = w.commit()
    _flip_byte_in_chunk(path, "can/ABS_1/speed", 5000, None, None)
    keep = (np.arange(10000) < 4096) | (np.arange(10000) >= 8192)
    with Drive(path) as d:
        table = d.series("can/ABS_1")
        t, v = d.can_role("wheel_speed_fl")
        damage = list(d.damage)
    np.testing.assert_array_equal(table["t_ns"], t_ns[keep])
    np.testing.assert_array_equal(table["speed"], speed[keep])
    assert np.array_equal(t, t_ns[keep]) and np.array_equal(v, speed[keep])
    assert damage == [f"{path}: rows 4096-8191 of /can/ABS_1 (4096 of 10000) failed their checksum (the drive is "
                      "damaged there): left out, a gap in that stream"]


def test_navigate_on_a_drive_damaged_in_an_imu_table_bridges_the_rows_it_lost(test1_drive: tuple[Path, Any],
                                                                             tmp_path: Path) -> None:
    """test1 with a flipped byte in the second stored chunk of one IMU's gyro column (rows 4096-6347 of 6348):
    navigate failed ("dataset ... is damaged and cannot be read"). It navigates without those rows of that IMU, in
    every column, and warns naming them; the track stays within 5 mm of the undamaged drive's (1.2 mm measured: the
    other gyros carry the yaw rate)."""
    drive = tmp_path / "drive.h5"
    drive.write_bytes(test1_drive[0].read_bytes())
    _flip_byte_in_chunk(drive, "imu/imu_cog_b/angular_velocity", 5000, None, None)
    cfg = load_config()
    whole, damaged = navigate(test1_drive[0], "sar-min", cfg), navigate(drive, "sar-min", cfg)
    assert damaged.info["warnings"][0] == (f"{drive}: rows 4096-6347 of /imu/imu_cog_b (2252 of 6348) failed their "
                                           "checksum (the drive is damaged there): left out, a gap in that stream")
    assert not any("checksum" in w for w in whole.info.get("warnings", []))
    t = damaged.t_ns
    off = np.hypot(*(np.interp(t, whole.t_ns, whole.rear_axle_enu[:, k]) - damaged.rear_axle_enu[:, k]
                     for k in (0, 1)))
    assert off.max() < 0.005


def test_info_verify_names_each_damaged_chunk_and_exits_1(tmp_path: Path) -> None:
    """``autosar info FILE --verify`` reads every stored chunk of a file autosar wrote: an intact drive and
    trajectory pass (exit 0); with a byte flipped in a radar chunk (frames 64-127 of Tx 0 / Rx 1) and one in a
    table's column (rows 4096-8191), each is named by dataset, rows and channel, and the exit code is 1."""
    rng = np.random.default_rng(5)
    w = DriveWriter(tmp_path / "drive.h5", {"autosar_version": "test"})
    w.radar("radar/scanbrick", (3, 4, 64), {}).append_frames(
        np.arange(192, dtype=np.int64) * 1_000_000, np.arange(192, dtype=np.int64),
        rng.normal(0, 300, size=(192, 3, 4, 64, 2)).astype(np.int16))
    w.table("can/ABS_1", {"t_ns": Column(np.int64), "speed": Column(np.float64)}, {}).append(
        {"t_ns": np.arange(10000, dtype=np.int64), "speed": rng.normal(size=10000)})
    drive = w.commit()
    traj = tmp_path / "trajectory.h5"
    write_trajectory(traj, _straight_track())
    for path in (drive, traj):
        r = runner.invoke(app, ["info", str(path), "--verify"])
        assert r.exit_code == 0 and "every checksum holds" in r.stdout, r.output
    _flip_byte_in_chunk(drive, "radar/scanbrick/raw", 100, 0, 1)
    _flip_byte_in_chunk(drive, "can/ABS_1/speed", 5000, None, None)
    r = runner.invoke(app, ["info", str(drive), "--verify", "--json"])
    assert r.exit_code == 1
    found = json.loads(r.stdout)
    assert not found["intact"] and found["chunks"] == 192 // 64 * 12 + 2 + 2 * 3  # cube, its times and indices, table
    assert [(d["dataset"], d["rows"], d["at"]) for d in found["damaged"]] == [
        ("/can/ABS_1/speed", [4096, 8192], []), ("/radar/scanbrick/raw", [64, 128], [0, 1])]
    r = runner.invoke(app, ["info", str(drive), "--verify"])
    assert r.exit_code == 1 and "2 of" in r.stdout and "/radar/scanbrick/raw rows 64-127 at [0, 1]" in r.stderr


def test_info_verify_of_a_run_directory_checks_each_product(tmp_path: Path) -> None:
    """``autosar info DIR --verify`` checks every file autosar writes with checksums in a run's directory (its
    HDF5 files chunk by chunk, its GeoTIFF tile by tile, column by column): all hold, exit 0; one pixel of the
    GeoTIFF changed, that file is named with its columns, the others still hold, exit 1; a foreign .h5 among them is
    named as not readable, not a crash."""
    import rasterio

    from autosar_cli.sar.grid import FocusGrid
    from autosar_cli.store.image import FocusedImage, write_image

    write_trajectory(tmp_path / "trajectory.h5", _straight_track())
    grid = FocusGrid((0.0, 2.0), (1.0, 0.0), (0.0, -1.0), 0.04, 300, 40, 0.0)
    rng = np.random.default_rng(2)
    z = (rng.normal(size=grid.shape) + 1j * rng.normal(size=grid.shape)).astype(np.complex64)
    write_image(tmp_path / "image", FocusedImage(z, grid, GeodeticOrigin(45.06, 7.66, 240.0), {"pixel_m": 0.04}))
    r = runner.invoke(app, ["info", str(tmp_path), "--verify", "--json"])
    assert r.exit_code == 0, r.output
    found = json.loads(r.stdout)
    assert found["intact"] and [Path(f["path"]).name for f in found["files"]] == [
        "image.h5", "image.png", "image.tif", "trajectory.h5"]
    with rasterio.open(tmp_path / "image.tif", "r+") as dst:
        dst.write(np.array([[3.0]], np.float32), 1, window=rasterio.windows.Window(207, 11, 1, 1))
    (tmp_path / "notes.h5").write_bytes(b"not an HDF5 file at all")
    r = runner.invoke(app, ["info", str(tmp_path), "--verify"])
    assert r.exit_code == 1
    assert "damaged: columns 207-207 differ from those written" in r.stderr and "notes.h5" in r.stderr
    shown = r.stdout.replace("\n", "")  # rich wraps at its console's width
    assert f"{tmp_path / 'trajectory.h5'}: 6 datasets, 6 stored chunks, every checksum holds" in shown


def test_the_quicklooks_own_checksums_are_checked(tmp_path: Path) -> None:
    """A PNG carries a CRC-32 after every chunk and the Adler-32 of its pixels' zlib stream: ``verify_png`` names
    the chunk whose CRC differs (a bit flipped in the pixels, or in the header), a stream that does not inflate, and
    a file cut inside a chunk; the quicklook as written holds."""
    from autosar_cli.sar.grid import FocusGrid
    from autosar_cli.store.image import FocusedImage, write_image
    from autosar_cli.store.png_check import verify_png

    grid = FocusGrid((0.0, 2.0), (1.0, 0.0), (0.0, -1.0), 0.04, 300, 40, 0.0)
    rng = np.random.default_rng(4)
    z = (rng.normal(size=grid.shape) + 1j * rng.normal(size=grid.shape)).astype(np.complex64)
    png = write_image(tmp_path / "image", FocusedImage(z, grid, GeodeticOrigin(45.06, 7.66, 240.0), {}))["png"]
    assert verify_png(png).intact and verify_png(png).chunks >= 4
    data = png.read_bytes()
    idat = data.index(b"IDAT") - 4
    flipped = bytearray(data)
    flipped[idat + 8 + 100] ^= 0x10
    damaged = tmp_path / "flipped.png"
    damaged.write_bytes(bytes(flipped))
    assert verify_png(damaged).damaged[0] == f"IDAT chunk at byte {idat}: its CRC-32 differs"
    assert verify_png(damaged).damaged[1].startswith("the pixels' zlib stream: ")
    flipped = bytearray(data)
    flipped[8 + 8 + 3] ^= 0x01  # the width's lowest byte
    damaged.write_bytes(bytes(flipped))
    assert verify_png(damaged).damaged[0] == "IHDR chunk at byte 8: its CRC-32 differs"
    damaged.write_bytes(data[:idat + 50])
    assert verify_png(damaged).damaged == [f"IDAT chunk at byte {idat}: says "
                                          f"{int.from_bytes(data[idat:idat + 4], 'big')} bytes, the file ends 38 "
                                          "after its header"]


def test_a_heading_no_car_can_have_is_refused(tmp_path: Path) -> None:
    traj = _straight_track()
    traj.heading[57] = -1.9e171  # what a flipped exponent byte made of a heading (finite, absurd)
    path = write_trajectory(tmp_path / "trajectory.h5", traj)
    with pytest.raises(TrajectoryFormatError, match=r"trajectory\.h5: step between headings exceeds 1\.571 rad "
                                                    r"at sample 56"):
        read_trajectory(path)
    traj = _straight_track()
    traj.speed[10] = np.nan
    with pytest.raises(TrajectoryFormatError, match="speed exceeds 100 m/s at sample 10"):
        read_trajectory(write_trajectory(tmp_path / "t2.h5", traj))


def test_missing_format_version_is_named(tmp_path: Path) -> None:
    path = write_trajectory(tmp_path / "trajectory.h5", _straight_track())
    with h5py.File(path, "r+") as f:
        del f.attrs["format_version"]
    with pytest.raises(TrajectoryFormatError, match="has no format_version attribute"):
        read_trajectory(path)
    drive = DriveWriter(tmp_path / "drive.h5", {}).commit()
    with h5py.File(drive, "r+") as f:
        del f.attrs["format_version"]
    r = runner.invoke(app, ["navigate", str(drive), "-o", str(tmp_path / "t.h5")])
    assert r.exit_code == 1 and "drive.h5: has no format_version attribute" in r.output.replace("\n", "")


@pytest.mark.parametrize("chunk_channels", [(1, 1), (3, 4)], ids=["per-channel", "whole-frame"])
def test_channel_reads_equal_the_frames_channels_in_either_chunk_layout(tmp_path: Path,
                                                                         chunk_channels: tuple[int, int]) -> None:
    """Drives written with one chunk per channel, and those written before with whole frames per chunk."""
    raw = np.random.default_rng(4).normal(0, 300, size=(70, 3, 4, 16, 2)).astype(np.int16)
    w = DriveWriter(tmp_path / "drive.h5", {"autosar_version": "test"})
    w.radar("radar/scanbrick", (3, 4, 16), {}).append_frames(np.arange(70, dtype=np.int64), np.arange(70), raw)
    path = w.commit()
    with h5py.File(path, "r+") as f:
        del f["radar/scanbrick/raw"]
        f["radar/scanbrick"].create_dataset("raw", data=raw, chunks=(32, *chunk_channels, 16, 2), fletcher32=True)
    every = [(t, r) for t in range(3) for r in range(4)]
    with Drive(path) as d:
        radar = d.radar()
        assert radar.raw.chunks[1:3] == chunk_channels
        np.testing.assert_array_equal(radar.frames(5, 69, [(0, 0), (2, 3), (1, 2)]), raw[5:69, [0, 2, 1], [0, 3, 2]])
        np.testing.assert_array_equal(radar.frames(40, 80, every), raw[40:].reshape(30, 12, 16, 2))


def test_appends_that_end_inside_a_chunk_read_back_whole(tmp_path: Path) -> None:
    """Appends of 37, 100 and 5 frames (chunks hold 64): every frame reads back as written, whole or by channel."""
    raw = np.random.default_rng(6).normal(0, 300, size=(142, 3, 4, 16, 2)).astype(np.int16)
    w = DriveWriter(tmp_path / "drive.h5", {"autosar_version": "test"})
    cube = w.radar("radar/scanbrick", (3, 4, 16), {})
    for lo, hi in ((0, 37), (37, 137), (137, 142)):
        cube.append_frames(np.arange(lo, hi, dtype=np.int64), np.arange(lo, hi), raw[lo:hi].copy())
    path = w.commit()
    with Drive(path) as d:
        np.testing.assert_array_equal(d.radar().frames(0, 142), raw)
        np.testing.assert_array_equal(d.radar().frames(30, 140, [(1, 3), (0, 0)]), raw[30:140, [1, 0], [3, 0]])


@pytest.mark.parametrize(("name", "group", "key"), [
    ("trajectory.h5", "/", "origin_lat_deg"), ("image.h5", "/", "origin_lat_deg"), ("drive.h5", "/", "created_utc"),
    ("drive.h5", "radar/scanbrick_w43", "start_frequency_hz")])
def test_a_flipped_byte_in_an_attribute_is_damage_not_another_value(ci_run: Path, tmp_path: Path, name: str,
                                                                      group: str, key: str) -> None:
    """Attributes lie outside every dataset checksum: one bit of a trajectory's origin latitude moved the image
    870 m, `info --verify` said every checksum held and focus went on. The attributes' CRC (store.attr_checksum)
    makes it damage: --verify names it (exit 1); a trajectory or image is refused in one line, a drive read on with
    a warning that marks its products degraded (as a damaged table's rows are)."""
    from autosar_cli.store.attr_checksum import ATTRS_CRC

    src = ci_run / name
    with h5py.File(src) as f:
        assert ATTRS_CRC in f.attrs
        stored = f[group].attrs[key]
        value = stored.encode() if isinstance(stored, str) else np.asarray(stored).tobytes()
    data = bytearray(src.read_bytes())
    assert data.count(value) == 1
    data[data.index(value) + 5] ^= 0x01  # one bit: a float's mantissa 0.0003 % off, a date's digit: not absurd
    damaged = tmp_path / name
    damaged.write_bytes(bytes(data))
    r = runner.invoke(app, ["info", str(damaged), "--verify"])
    assert r.exit_code == 1 and "its attributes" in r.stderr, r.output
    r = runner.invoke(app, ["focus", str(damaged if name == "drive.h5" else ci_run / "drive.h5"), "-t",
                            str(damaged if name == "trajectory.h5" else ci_run / "trajectory.h5"), "-o",
                            str(tmp_path / "img"), "--json"] if name != "image.h5" else
                      ["evaluate", str(damaged), "-o", str(tmp_path / "ev")])
    if name == "drive.h5" and group != "/":  # HDF5's own checksum of the radar's object header finds this one
        assert r.exit_code == 1 and r.stderr.count("\n") == 1 and str(damaged) in r.stderr, r.output
        assert "radar/scanbrick_w43 is damaged and cannot be read" in r.stderr
        return
    if name == "drive.h5":  # the rest of a drive is read, as a damaged table's is: the image marked degraded
        assert r.exit_code == 0 and json.loads(r.stdout)["status"] == "degraded", r.output
        assert "its attributes fail their checksum" in json.loads(r.stdout)["warnings"][0]
        # in tiles too: each tile's focus read the drive's warning, and `focus --tiles 2` dropped it (status ok)
        t = runner.invoke(app, ["focus", str(damaged), "-t", str(ci_run / "trajectory.h5"), "-o",
                                str(tmp_path / "tiled"), "--json", "--tiles", "2"])
        assert t.exit_code == 0, t.output
        assert json.loads(t.stdout)["warnings"] == json.loads(r.stdout)["warnings"]
        assert read_image(tmp_path / "tiled.h5").provenance["warnings"] == json.loads(r.stdout)["warnings"]
        return
    assert r.exit_code == 1 and r.stderr.count("\n") == 1 and "its attributes" in r.stderr, r.output
    assert str(damaged) in r.stderr


@pytest.mark.parametrize("damage", ["image.tif removed", "run.json cut"])
def test_info_verify_of_a_run_missing_a_product_is_not_intact(ci_run: Path, tmp_path: Path, damage: str) -> None:
    """`info RUN --verify` checked the files present: a run whose image.tif was gone, or whose run.json was cut,
    was called intact (exit 0). The products run.json lists must be there, and run.json must read."""
    import shutil

    run_dir = tmp_path / "run"
    shutil.copytree(ci_run, run_dir)
    if damage == "image.tif removed":
        (run_dir / "image.tif").unlink()
    else:
        (run_dir / "run.json").write_bytes((run_dir / "run.json").read_bytes()[:100])
    r = runner.invoke(app, ["info", str(run_dir), "--verify", "--json"])
    assert r.exit_code == 1 and json.loads(r.stdout)["intact"] is False, r.output
    said = "image.tif: listed in run.json but missing" if damage == "image.tif removed" else "run manifest"
    assert any(said in f.get("error", "") for f in json.loads(r.stdout)["files"]), r.stdout
    r = runner.invoke(app, ["info", str(ci_run), "--verify"])
    assert r.exit_code == 0, r.output


def test_evaluate_names_what_it_cannot_read(ci_run: Path, ci_mcap, tmp_path: Path) -> None:  # noqa: ANN001
    """evaluate of a run whose image has a damaged chunk said only "Can't synchronously read data (filter returned
    failure during read)"; given a drive, a log or a cut file as --truth, HDF5's own words ("can't locate attribute
    in name index", "file signature not found"). Each now names the file (and the dataset), and what it is not."""
    import shutil

    run_dir = tmp_path / "run"
    shutil.copytree(ci_run, run_dir)
    _flip_byte_in(run_dir / "image.h5", "image")
    r = runner.invoke(app, ["evaluate", str(run_dir), "-o", str(tmp_path / "e0")])
    assert r.exit_code == 1 and r.stderr.count("\n") == 1, r.output
    assert f"{run_dir / 'image.h5'}: dataset /image is damaged and cannot be read" in r.stderr, r.stderr
    cut = tmp_path / "cut.truth.h5"
    cut.write_bytes(Path(ci_mcap.truth_path).read_bytes()[:70_000])
    for truth, said in ((ci_run / "drive.h5", "not an autosar truth sidecar but an autosar-drive file"),
                        (ci_run / "image.png", "not an autosar truth sidecar (not a readable HDF5 file: file "
                                               "signature not found)"),
                        (cut, "not an autosar truth sidecar (not a readable HDF5 file: truncated file")):
        r = runner.invoke(app, ["evaluate", str(ci_run), "-o", str(tmp_path / "e1"), "--truth", str(truth)])
        assert r.exit_code == 1 and r.stderr.count("\n") == 1, r.output
        assert f"{truth}: {said}" in r.stderr, r.stderr
