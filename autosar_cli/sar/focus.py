"""``autosar focus``: drive.h5 + trajectory.h5 in, focused image out (paper Sec. III).

Streaming over blocks of pulses, so memory depends on the block and the image, not on the drive: for
each block the raw frames are read, range-compressed straight into the kernel's (channel, bin, pulse)
layout, the antenna phase centres of every chirp are derived from the trajectory, each pixel near the
block gets the pulses inside its stripmap window, and the block is back-projected into the image. A
pixel whose window straddles two blocks gets one partial sum from each. The next block's windows and frames
are prepared in a thread meanwhile.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections import Counter
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from autosar_cli import __version__
from autosar_cli.config import MAX_CROSS_RANGE_RESOLUTION_M, SPEED_OF_LIGHT, Config
from autosar_cli.nav.trajectory import (
    Trajectory,
    antenna_lever_arms,
    cumulative_travel,
    measured_mounting,
    radar_phase_centres,
    radar_side,
)
from autosar_cli.sar.backprojection import PulseBlock, backproject_block
from autosar_cli.sar.channel_gains import ChannelGains, stated_channel_gains, trajectory_channel_gains
from autosar_cli.sar.grid import FocusGrid, GridError, box_grid, check_image_size, track_grid
from autosar_cli.sar.range_compression import range_compress_into, range_null_m
from autosar_cli.sar.stripmap import (
    block_context,
    look_angle_margin_m,
    processed_half_width,
    stripmap_windows,
    zero_doppler_pulses,
)
from autosar_cli.store.atomic import already_exists
from autosar_cli.store.drive import Drive, RadarStream
from autosar_cli.store.image import FocusedImage, preload_quicklook, product_paths, write_image
from autosar_cli.store.outputs import check_output
from autosar_cli.store.trajectory import read_trajectory


class FocusError(ValueError):
    """A problem with focus's inputs; the message names the file and the problem."""


@dataclass(frozen=True)
class FocusOptions:
    pixel_m: float = 0.04  #: pixel spacing (m)
    resolution_m: float = 0.04  #: target cross-range resolution rho (m): processed beam half-width lambda/(4 rho)
    channels: int = 8  #: 8: Tx0 + Tx2 with the 4 Rx (phase centres lambda/4 apart); 12: all Tx
    height_m: float = 0.5  #: focusing plane height (ENU z, m)
    grid: str = "auto"  #: "auto" (along the track, radar side) or "x0,y0,x1,y1" (ENU m)
    window: str = "hann"  #: range taper
    upsample: int = 4  #: range zero-padding factor
    block_pulses: int = 512  #: pulses per processing block
    min_speed_mps: float = 0.2  #: frames slower than this are skipped (no synthetic aperture)
    radar: str | None = None  #: the drive's radar stream to focus (``/radar/<name>``; None: its first)
    #: the front end's channel gains, undone before the channels are summed, where the trajectory carries none
    #: (its ``info["channel_gains"]``: those its autofocus measured and applied, or the truth's); None: those the
    #: drive's radar states (a TI capture's calibration), else matched channels
    channel_gains: ChannelGains | None = None
    #: how late the radar's frame stamps run against the navigation's clock (s; ``radar.clock_offset_s``): each
    #: frame is taken as started this much before its stamp (:func:`open_radar`)
    radar_clock_offset_s: float = 0.0
    #: how fast the radar's frame clock runs against the navigation's (ppm; ``radar.clock_drift_ppm``), from the
    #: stream's first stamp on (:func:`open_radar`)
    radar_clock_drift_ppm: float = 0.0

    def __post_init__(self) -> None:
        # a CLI override is checked here, as the config's values are in config.py (the pixel: sar.grid, first)
        if not (math.isfinite(self.resolution_m) and self.resolution_m > 0):
            raise FocusError(f"focus: cross-range resolution {self.resolution_m} m: must be a positive finite number")
        if self.resolution_m > MAX_CROSS_RANGE_RESOLUTION_M:  # an image of single pulses, 332 of 40443 pixels lit
            raise FocusError(f"focus: cross-range resolution {self.resolution_m:g} m: coarser than "
                             f"{MAX_CROSS_RANGE_RESOLUTION_M:g} m, its beam would hold a pulse or two, no SAR image")
        if not math.isfinite(self.height_m):
            raise FocusError(f"focus: focusing plane height {self.height_m} m: must be a finite number")
        if isinstance(self.channel_gains, dict):  # as an image's parameters store them
            object.__setattr__(self, "channel_gains", ChannelGains.from_dict(self.channel_gains))

    @classmethod
    def from_config(cls, config: Config, **overrides: Any) -> FocusOptions:
        p = config.processing
        base = dict(pixel_m=p.pixel_m, resolution_m=p.cross_range_resolution_m, channels=int(p.channels),
                    height_m=p.focus_height_m, window=p.range_window, upsample=p.range_upsample,
                    radar_clock_offset_s=config.radar.clock_offset_s,
                    radar_clock_drift_ppm=config.radar.clock_drift_ppm)
        base.update({k: v for k, v in overrides.items() if v is not None})
        return cls(**base)


@dataclass
class FocusReport:
    outputs: dict[str, str]
    grid_shape: tuple[int, int]
    frames_used: int
    frames_skipped: dict[str, int]
    backprojections: int  #: pixels x pulses x channels actually summed
    timings_s: dict[str, float] = field(default_factory=dict)
    drive_s: float = 0.0
    warnings: list[str] = field(default_factory=list)  #: what the image leaves out (another radar of the drive)
    grid_enu_m: tuple[float, float, float, float] | None = None  #: x0, y0, x1, y1 around the image (grid_enu_box)

    @property
    def backprojections_per_s(self) -> float:
        t = self.timings_s.get("backprojection", 0.0)
        return self.backprojections / t if t > 0 else 0.0

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["backprojections_per_s"] = self.backprojections_per_s
        d["wall_s"] = sum(self.timings_s.values())
        return d


def channel_pairs(n_tx: int, n_rx: int, channels: int) -> list[tuple[int, int]]:
    """(Tx, Rx) pairs processed: 8 = Tx0 and Tx2 with every Rx (8 phase centres lambda/4 apart in one row), 12 = all;
    2 = Tx0-Rx0 and Tx2-Rx(last), the virtual array's ends (autofocus's coarse first image and phase histories:
    a narrow processed beam, or one point's history, needs no more than one channel's along-track sampling); 1 =
    Tx0-Rx0."""
    if channels == 1:
        return [(0, 0)]
    if channels == 2 and n_tx >= 3:
        return [(0, 0), (2, n_rx - 1)]
    if channels == 12 or n_tx < 3:
        return [(t, r) for t in range(n_tx) for r in range(n_rx)]
    if channels == 8:
        return [(t, r) for t in (0, 2) for r in range(n_rx)]
    raise FocusError(f"--channels {channels}: choose 8 or 12")


@dataclass(frozen=True)
class RadarParameters:
    """What focusing needs of a drive's radar: its chirp (from the recording, the config where it says nothing),
    its array's size and the range axis of a compressed profile upsampled ``upsample`` times."""

    start_frequency_hz: float
    slope_hz_per_s: float
    sample_rate_hz: float
    n_tx: int
    n_rx: int
    n_samples: int
    tx_start_offsets_s: NDArray[np.float64]  #: (T,) chirp start of Tx k in the PRI
    n_bins: int  #: bins of a compressed profile
    bin_m: float  #: bistatic path per compressed bin (m)
    cycles_per_m: float  #: carrier turns per metre of bistatic path at the window's centre
    wavelength_m: float  #: at the chirp's centre frequency

    @classmethod
    def of(cls, radar: RadarStream, config: Config, upsample: int) -> RadarParameters:
        a = radar.attrs
        f0 = float(a.get("start_frequency_hz", config.radar.start_frequency_hz))
        slope = float(a.get("slope_hz_per_s", config.radar.slope_hz_per_s))
        fs = float(a.get("sample_rate_hz", config.radar.sample_rate_hz))
        n_tx, n_rx, n_samp = (int(v) for v in radar.raw.shape[1:4])
        if (len(config.radar.tx_in_use), len(config.radar.rx_in_use)) != (n_tx, n_rx):
            where = getattr(getattr(radar.raw, "file", None), "filename", "drive")
            raise FocusError(f"{where}: radar {radar.name} has {n_tx} Tx x {n_rx} Rx but the config's radar has "
                             f"{len(config.radar.tx_in_use)} x {len(config.radar.rx_in_use)} (radar.num_tx, num_rx, "
                             "tx_channels, rx_channels)")
        offsets = np.asarray(a.get("tx_start_offsets_s", config.radar.tx_start_offsets_s), dtype=np.float64)
        n_bins = n_samp * upsample
        return cls(f0, slope, fs, n_tx, n_rx, n_samp, offsets, n_bins, SPEED_OF_LIGHT * fs / (n_bins * slope),
                   (f0 + slope * 0.5 * (n_samp - 1) / fs) / SPEED_OF_LIGHT,
                   SPEED_OF_LIGHT / (f0 + 0.5 * slope * n_samp / fs))


def parse_grid(spec: str) -> tuple[float, float, float, float] | None:
    """``auto`` -> None; ``x0,y0,x1,y1`` -> the ENU box (m)."""
    if spec.strip().lower() == "auto":
        return None
    try:
        x0, y0, x1, y1 = (float(v) for v in spec.split(","))
    except ValueError:
        raise FocusError(f"--grid {spec!r}: expected 'auto' or x0,y0,x1,y1 (ENU metres)") from None
    return x0, y0, x1, y1


@dataclass
class _Geometry:
    frames: NDArray[np.int64]  #: indices of the frames used (into the radar stream)
    t_ns: NDArray[np.int64]
    reference: NDArray[np.float64]  #: (F, 3) Tx0 phase centre per frame (ENU m)
    velocity: NDArray[np.float64]  #: (F, 3) its direction of travel (m/s; :meth:`Trajectory.travel_velocity`)
    skipped: Counter[str]


def _usable_frames(radar: RadarStream, traj: Trajectory, config: Config, min_speed: float) -> _Geometry:
    """Frames inside the trajectory's time span and moving; their reference phase centre and velocity."""
    t = radar.t_ns
    skipped: Counter[str] = Counter()
    offsets = np.asarray(radar.attrs.get("tx_start_offsets_s", config.radar.tx_start_offsets_s), dtype=np.float64)
    last_chirp_ns = int(round(offsets.max() * 1e9)) if offsets.size else 0
    inside = (t >= traj.t_ns[0]) & (t + last_chirp_ns <= traj.t_ns[-1])
    skipped["outside the trajectory's time span"] = int((~inside).sum())
    frames = np.flatnonzero(inside)
    if frames.size == 0:
        return _Geometry(frames, t[frames], np.zeros((0, 3)), np.zeros((0, 3)), skipped)
    tx0 = antenna_lever_arms(config)[0][:1]
    ref = traj.body_points(t[frames], tx0)[:, 0]
    vel = traj.travel_velocity(t[frames], tx0)[:, 0]  # the beam points across the aperture's direction of travel
    moving = np.linalg.norm(vel[:, :2], axis=1) >= min_speed
    skipped[f"slower than {min_speed} m/s"] = int((~moving).sum())
    return _Geometry(frames[moving], t[frames][moving], ref[moving], vel[moving], skipped)


def _frames_to_focus(radar: RadarStream, traj: Trajectory, config: Config, min_speed: float, drive_path: str | Path,
                     traj_name: str) -> _Geometry:
    """:func:`_usable_frames`, refused where fewer than two are (nothing to form an aperture of)."""
    geometry = _usable_frames(radar, traj, config, min_speed)
    if geometry.frames.size < 2:
        raise FocusError(f"{drive_path}: no radar frame lies inside the trajectory {traj_name} while moving")
    return geometry


def drive_radar_config(config: Config, drive_path: str | Path, radar: str | None = None) -> Config:
    """``config`` with its radar on the board's antennas that the drive's radar ``radar`` (its first where None)
    recorded with (its ``tx_channels`` and ``rx_channels``, which ingest writes), so that every phase centre is one
    of the cube's antennas: what the recording states wins, the config's rows give their positions. ``config`` as
    it is where the drive states none."""
    with Drive(drive_path) as drive:
        attrs = drive.radar_attrs(radar)
    if "tx_channels" not in attrs or "rx_channels" not in attrs:
        return config
    r = config.radar
    tx, rx = (tuple(int(c) for c in attrs[f"{k}_channels"]) for k in ("tx", "rx"))
    if (r.tx_in_use, r.rx_in_use) != (tx, rx):
        for kind, used in (("tx", tx), ("rx", rx)):
            rows = len(getattr(r, f"{kind}_positions_wavelengths"))
            if max(used, default=0) >= rows:
                raise FocusError(f"{drive_path}: its radar used the board's {kind.title()} {list(used)} but the "
                                 f"config's radar.{kind}_positions_wavelengths has {rows} rows: give a row for each "
                                 f"of the board's antennas and radar.{kind}_channels = {list(used)}")
        config = replace(config, radar=r.using_channels(tx, rx))
    _check_same_antennas(config, attrs, drive_path)
    return config


def _check_same_antennas(config: Config, attrs: dict[str, Any], drive_path: str | Path) -> None:
    """Refuse a config whose antennas (in metres: its rows times its wavelength) are not those the drive was
    ingested with (its ``tx_positions_m``, ``rx_positions_m``): another start frequency, or other rows, would move
    every phase centre while the image's phase follows the drive's recorded chirp."""
    for kind in ("tx", "rx"):
        stored = attrs.get(f"{kind}_positions_m")
        if stored is None:
            continue
        configured = np.asarray(getattr(config.radar, f"{kind}_positions_m"), np.float64)
        stored = np.asarray(stored, np.float64)
        if configured.shape != stored.shape or not np.allclose(configured, stored, rtol=0.0, atol=1e-9):
            raise FocusError(f"{drive_path}: the config's radar puts its {kind.title()} antennas elsewhere than the "
                             f"drive was ingested with (radar.{kind}_positions_wavelengths x the wavelength of "
                             f"radar.start_frequency_hz {config.radar.start_frequency_hz:.9g}; the drive's "
                             f"{kind}_positions_m differ by up to {_largest_difference(configured, stored):.3g} m): "
                             "give the config it was ingested with, or ingest it again with this one")


def _largest_difference(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    return float(np.max(np.abs(a - b))) if a.shape == b.shape else float("inf")


def open_radar(drive: Drive, options: FocusOptions) -> RadarStream:
    """The radar stream ``options`` focuses (``options.radar``, else the drive's first), its frames' times on the
    navigation's clock (their stamps less ``options.radar_clock_offset_s`` and the clock's drift); any reader
    failure is a :class:`FocusError` naming the drive."""
    try:
        return drive.radar(options.radar).on_clock(options.radar_clock_offset_s, options.radar_clock_drift_ppm)
    except Exception as exc:  # noqa: BLE001 - any reader failure is an input problem here
        msg = str(exc)
        raise FocusError(msg if str(drive.path) in msg else f"{drive.path}: {msg}") from None


def check_same_recording(drive: Drive, radar: RadarStream, traj: Trajectory, traj_name: str) -> None:
    """Refuse a trajectory navigated from another recording than ``drive``'s: none of the radar frames it names
    (``info["drive_radar_frames"]``, :meth:`RadarStream.fingerprint`) matches the drive's frame of that index, in
    the stream they were taken from where the drive holds one of that name, else in ``radar`` (the stream focused).
    Two drives whose clocks overlap (simulated ones, or a logger that starts at 1970 on every boot) would otherwise
    focus one's radar along the other's track without a word."""
    frames = traj.info.get("drive_radar_frames")
    if not frames:
        return
    if frames.get("stream") in drive.radar_names() and frames["stream"] != radar.name:
        radar = drive.radar(frames["stream"])
    if n := radar.unmatched(frames["frame_index"], frames["crc32"]):
        raise FocusError(f"{traj_name}: navigated from another recording than {drive.path} (none of {n} radar "
                         f"frames it names matches the drive's); navigate {drive.path} itself")


def make_grid(options: FocusOptions, geometry: _Geometry, config: Config) -> FocusGrid:
    box = parse_grid(options.grid)
    check_grid_size(options, config)
    try:
        if box is not None:
            grid = box_grid(*box, pixel_m=options.pixel_m, height_m=options.height_m)
        else:
            grid = track_grid(geometry.reference[:, :2], side=radar_side(config), pixel_m=options.pixel_m,
                              height_m=options.height_m, antenna_height_m=float(np.mean(geometry.reference[:, 2])),
                              max_range_m=config.radar.max_range_m)
    except GridError as exc:
        raise FocusError(f"grid: {exc}") from None
    check_grid_size(options, config, grid)
    return grid


def auto_grid(drive_path: str | Path, trajectory: Trajectory, config: Config, options: FocusOptions) -> FocusGrid:
    """The grid ``autosar focus --grid auto`` would use along ``trajectory``."""
    with Drive(drive_path) as d:
        geometry = _frames_to_focus(open_radar(d, options), trajectory, config, options.min_speed_mps, drive_path,
                                    f"<{trajectory.method} trajectory>")
    return make_grid(replace(options, grid="auto"), geometry, config)


def _candidate_pixels(grid: FocusGrid, ref: NDArray[np.float64], vel: NDArray[np.float64], half_width: float,
                      max_range: float, side: float) -> tuple[slice, slice]:
    """Rows and columns of the grid that the pulses of a block can see through their processed beam.

    Bounds the wedges of the first and last pulse (zero-Doppler direction +- the half-width, out to the
    maximum range), with a margin for the turn in between.
    """
    pts = [ref[0, :2], ref[-1, :2]]
    for a, v in ((ref[0], vel[0]), (ref[-1], vel[-1])):
        heading = math.atan2(v[1], v[0])
        for d in (-1.5 * half_width, 0.0, 1.5 * half_width):
            ang = heading + side * math.pi / 2 + d
            pts.append(a[:2] + max_range * np.array([math.cos(ang), math.sin(ang)]))
    rows, cols = grid.enu_to_pixel(np.array(pts))
    r0 = max(0, int(math.floor(rows.min())) - 2)
    r1 = min(grid.n_across, int(math.ceil(rows.max())) + 3)
    c0 = max(0, int(math.floor(cols.min())) - 2)
    c1 = min(grid.n_along, int(math.ceil(cols.max())) + 3)
    return slice(r0, max(r0, r1)), slice(c0, max(c0, c1))


#: frames_skipped's reason for the frames of a damaged drive left out
DAMAGED_FRAMES = "damaged in the drive (their stored radar data failed its checksum)"


@dataclass
class FocusResult:
    """In-memory result of :func:`focus_images`: one image per grid plus what it took."""

    images: list[FocusedImage]
    frames_used: int
    frames_skipped: dict[str, int]
    backprojections: int
    timings_s: dict[str, float]
    drive_s: float
    warnings: list[str] = field(default_factory=list)  #: what the images lack (frames of a damaged drive)
    damaged_frame_index: list[int] = field(default_factory=list)  #: those frames, by index in the recording


def focus_images(drive_path: str | Path, trajectory: str | Path | Trajectory, config: Config, options: FocusOptions,
                 grids: list[FocusGrid] | None = None, *, progress: Callable[[int, int], None] | None = None,
                 command: str = "") -> FocusResult:
    """Focus a drive along a trajectory onto ``grids`` (default: the one ``options.grid`` describes).

    One pass over the radar data serves every grid, so e.g. fine patches around several reflectors cost
    one range compression. ``trajectory``: a trajectory.h5 path or a :class:`Trajectory`.
    """
    timings: Counter[str] = Counter()
    t_start = time.perf_counter()
    if isinstance(trajectory, Trajectory):
        traj, traj_name = trajectory, f"<{trajectory.method} trajectory>"
    else:
        traj_name = str(trajectory)
        try:
            traj = read_trajectory(trajectory, covariance=False)
        except (OSError, ValueError) as exc:
            msg = str(exc)
            raise FocusError(msg if traj_name in msg else f"{traj_name}: {msg}") from None
    config = measured_mounting(config, traj)  # a radar boresight its autofocus measured, where it took one
    with Drive(drive_path) as drive:
        radar = open_radar(drive, options)
        check_same_recording(drive, radar, traj, traj_name)
        rp = RadarParameters.of(radar, config, options.upsample)
        f0, slope, fs, n_samp, offsets = rp.start_frequency_hz, rp.slope_hz_per_s, rp.sample_rate_hz, rp.n_samples, \
            rp.tx_start_offsets_s
        n_bins, bin_m, cycles_per_m, wavelength = rp.n_bins, rp.bin_m, rp.cycles_per_m, rp.wavelength_m
        pairs = channel_pairs(rp.n_tx, rp.n_rx, options.channels)
        gains = trajectory_channel_gains(traj.info) or options.channel_gains or stated_channel_gains(radar.attrs)
        correction = [None] * len(pairs) if gains is None else list(gains.correction(pairs))
        geometry = _frames_to_focus(radar, traj, config, options.min_speed_mps, drive_path, traj_name)
        grid_list = grids if grids else [make_grid(options, geometry, config)]
        timings["geometry"] += time.perf_counter() - t_start

        half_width = processed_half_width(wavelength, options.resolution_m)
        if half_width > (beam := math.radians(config.radar.beamwidth_az_deg / 2)):
            raise FocusError(f"focus: cross-range resolution {options.resolution_m:g} m asks for a beam of +-"
                             f"{math.degrees(half_width):.3g} deg, wider than the antenna's +-{math.degrees(beam):g} "
                             f"deg (radar.beamwidth_az_deg): the finest it holds is {wavelength / (4 * beam):.3g} m")
        side = radar_side(config)
        used_tx = sorted({t for t, _ in pairs})
        antenna_of_tx = {t: i for i, t in enumerate(used_tx)}
        channels = np.array([[antenna_of_tx[t], len(used_tx) + c] for c, (t, _) in enumerate(pairs)])

        _check_memory(sum(g.size for g in grid_list) * np.dtype(np.complex64).itemsize, options)
        images = [np.zeros(g.size, np.complex64) for g in grid_list]
        n_bp = 0
        frames = geometry.frames
        n_blocks = (len(frames) + options.block_pulses - 1) // options.block_pulses
        # a block's windows need the pulses around it: a pixel's look-angle cut is centred on its zero-Doppler pulse
        travel = cumulative_travel(geometry.reference)
        rise = traj.height_offset(geometry.t_ns)
        lifted = bool(np.any(rise != 0.0))
        margin = look_angle_margin_m(config.radar.max_range_m, half_width)
        damaged: list[int] = []  # positions in the stream of frames whose stored chunks are damaged

        def prepare(b: int) -> tuple[slice, list[tuple[int, Any, Any, Any]], NDArray[np.int16] | None,
                                     NDArray[np.float64] | None]:
            """Block b's frames, per grid the pixels its beam reaches with their windows, its raw frames and the
            phase centres of its antennas (A, P, 3).

            Runs on the reader thread, beside this block's range compression and back-projection (h5py, blosc
            and the kernels release the GIL): one thread, so no numba-parallel launch nests in the kernel's.
            """
            sel = slice(b * options.block_pulses, min(len(frames), (b + 1) * options.block_pulses))
            context = block_context(travel, sel.start, sel.stop, margin)
            work = []
            for gi, grid in enumerate(grid_list):
                rows, cols = _candidate_pixels(grid, geometry.reference[sel], geometry.velocity[sel], half_width,
                                               config.radar.max_range_m, side)
                rr, cc = np.meshgrid(np.arange(grid.n_across)[rows], np.arange(grid.n_along)[cols], indexing="ij")
                if rr.size == 0:
                    continue
                pix = grid.pixel_enu(rr, cc).reshape(-1, 3)
                if lifted:  # the surface rises with the body at the pixel's closest approach (the windows' 3-D)
                    pix[:, 2] += rise[zero_doppler_pulses(pix, geometry.reference, geometry.velocity, context)]
                win = stripmap_windows(pix, geometry.reference, geometry.velocity, half_width, side, parallel=False,
                                       block=(sel.start, sel.stop), context=context)
                keep = win[:, 1] > win[:, 0]
                if keep.any():
                    work.append((gi, (rr * grid.n_along + cc).ravel()[keep], pix[keep], win[keep]))
            if not work:  # a block no grid needs is not even read
                return sel, work, None, None
            idx = frames[sel]
            raw, intact = radar.intact_frames(int(idx[0]), int(idx[-1]) + 1, pairs)  # (n, C, samples, 2)
            damaged.extend(idx[~intact[idx - idx[0]]].tolist())  # zeroed: they add nothing
            pc = radar_phase_centres(traj, geometry.t_ns[sel], offsets, config)
            ant = np.concatenate([pc.tx[:, used_tx].transpose(1, 0, 2),
                                  np.stack([pc.rx[:, t, r] for t, r in pairs])], axis=0)
            return sel, work, raw[idx - idx[0]], ant

        pool = ThreadPoolExecutor(max(1, min(len(pairs), numba.get_num_threads())))
        reader = ThreadPoolExecutor(1)
        try:
            block: PulseBlock | None = None
            pending = reader.submit(prepare, 0)
            for b in range(n_blocks):
                t0 = time.perf_counter()
                sel, work, raw, ant = pending.result()
                timings["read"] += time.perf_counter() - t0
                if b + 1 < n_blocks:
                    pending = reader.submit(prepare, b + 1)
                if raw is None:
                    if progress is not None:
                        progress(b + 1, n_blocks)
                    continue
                n_pulses = sel.stop - sel.start

                t0 = time.perf_counter()
                if block is None or block.n_pulses != n_pulses:
                    # reused while the length stays: range compression overwrites every pulse column and the zero
                    # padding stays; a fresh 70 MB block per 512 pulses cost ~15 ms of page faults (measured)
                    block = PulseBlock.empty(len(pairs), n_bins, n_pulses, len(used_tx) + len(pairs),
                                             channels=channels, range0_m=0.0, bin_m=bin_m, cycles_per_m=cycles_per_m)
                # one channel per thread (the batched FFT, or scipy's and its copies, release the GIL): both cores busy
                beats = [raw[:, c] for c in range(len(pairs))]
                compress = partial(range_compress_into, sample_rate_hz=fs, slope_hz_per_s=slope, window=options.window,
                                   upsample=options.upsample, workers=1)
                list(pool.map(lambda beat, re, im, gain, f=compress: f(beat, re, im, gain=gain), beats, block.re,
                              block.im, correction))
                timings["range_compression"] += time.perf_counter() - t0

                t0 = time.perf_counter()
                block.set_antennas(ant)
                for gi, flat, pix, win in work:
                    images[gi][flat] += backproject_block(block, pix, win)
                    n_bp += int(np.sum(win[:, 1] - win[:, 0])) * len(pairs)
                timings["backprojection"] += time.perf_counter() - t0
                if progress is not None:
                    progress(b + 1, n_blocks)
        finally:
            reader.shutdown(cancel_futures=True)
            pool.shutdown()
        drive_s = float((geometry.t_ns[-1] - geometry.t_ns[0]) / 1e9)
        damaged_index = sorted(int(i) for i in np.asarray(radar.frame_index)[np.asarray(damaged, np.int64)])
        warnings = [damaged_frames_warning(drive_path, radar.name, damaged_index)] if damaged else []
        warnings += drive.damage  # its attributes failing their checksum: the radar's chirp may be wrong
        uncovered = uncovered_frames_warning(drive_path, radar, offsets, traj, traj_name,
                                             geometry.skipped["outside the trajectory's time span"])
        bridged = bridged_gap_warning(geometry.t_ns, traj, traj_name)
        coarse = coarse_pixel_warning(max(g.pixel_m for g in grid_list), options.resolution_m,
                                      range_null_m(sample_rate_hz=fs, slope_hz_per_s=slope, num_samples=n_samp,
                                                   window=options.window))
        warnings += [w for w in (uncovered, bridged, coarse) if w]

    params = {**asdict(options), "channel_pairs": [list(p) for p in pairs], "start_frequency_hz": f0,
              "slope_hz_per_s": slope, "sample_rate_hz": fs, "num_samples": n_samp, "bin_m": bin_m,
              "cycles_per_m": cycles_per_m, "wavelength_m": wavelength, "half_width_rad": half_width,
              "trajectory_method": traj.method, "frames_used": int(len(frames)) - len(damaged),
              "frames_damaged": len(damaged), "backprojections": n_bp,
              "radar": radar.name, "channel_gains": gains.to_dict() if gains is not None else None,
              "radar_mounting_yaw_deg": config.radar.mounting.yaw_deg}
    # absolute: `autosar evaluate IMAGE` finds them from any directory
    provenance = {"drive": os.path.abspath(drive_path),
                  "trajectory": traj_name if isinstance(trajectory, Trajectory) else os.path.abspath(trajectory),
                  "autosar_version": __version__,
                  "command": command, "config": config.source}
    out = [FocusedImage(img.reshape(g.shape), g, traj.origin, dict(params), dict(provenance))
           for g, img in zip(grid_list, images, strict=True)]
    skipped = {k: v for k, v in geometry.skipped.items() if v}
    if damaged:
        skipped[DAMAGED_FRAMES] = len(damaged)
    return FocusResult(out, int(len(frames)) - len(damaged), skipped, n_bp, dict(timings), drive_s, warnings,
                       damaged_index)


def check_some_backprojection(n: int, drive_path: str | Path, options: FocusOptions, half_width_rad: float,
                              trajectory: str | Path | Trajectory, config: Config) -> None:
    """Refuse an image no pulse reached (all zero: a cross-range resolution so coarse its beam holds no pulse, or a
    --grid box the radar does not look at), saying, for a box, where the track lies (:func:`where_the_radar_looks`)."""
    if n == 0:
        where = "" if parse_grid(options.grid) is None else \
            f": {where_the_radar_looks(drive_path, trajectory, config, options)}"
        raise FocusError(f"{drive_path}: no radar pulse reaches a pixel within the processed beam (cross-range "
                         f"resolution {options.resolution_m:g} m: +-{math.degrees(half_width_rad):.3g} deg); the "
                         f"image would be empty{where}")


def where_the_radar_looks(drive_path: str | Path, trajectory: str | Path | Trajectory, config: Config,
                          options: FocusOptions) -> str:
    """Where the radar's track lies in the trajectory's ENU frame (the box of its phase centre over the frames
    focused), which side it looks to (:func:`radar_side`, by ``radar.mounting.yaw_deg``), and the box --grid auto
    covers: what a --grid no pulse reaches is told, to choose another by."""
    traj = trajectory if isinstance(trajectory, Trajectory) else read_trajectory(trajectory, covariance=False)
    config = measured_mounting(config, traj)
    with Drive(drive_path) as d:
        geometry = _frames_to_focus(open_radar(d, options), traj, config, options.min_speed_mps, drive_path,
                                    str(trajectory))
    (x0, y0), (x1, y1) = geometry.reference[:, :2].min(axis=0), geometry.reference[:, :2].max(axis=0)
    side = "left" if radar_side(config) > 0 else "right"
    said = (f"the radar's track spans x {x0:.1f} to {x1:.1f} m, y {y0:.1f} to {y1:.1f} m (ENU) and it looks to the "
            f"{side} (radar.mounting.yaw_deg {config.radar.mounting.yaw_deg:g})")
    try:
        auto = ",".join(f"{v:.1f}" for v in grid_enu_box(make_grid(replace(options, grid="auto"), geometry, config)))
    except FocusError:  # the auto grid too large at this pixel: the track alone
        return said
    return f"{said}; --grid auto covers {auto}"


def grid_enu_box(grid: FocusGrid) -> tuple[float, float, float, float]:
    """x0, y0, x1, y1 (ENU m) of the box around ``grid``'s outer pixel edges (a --grid value that holds it)."""
    corners = grid.corners_enu()
    (x0, y0), (x1, y1) = corners.min(axis=0), corners.max(axis=0)
    return round(float(x0), 3), round(float(y0), 3), round(float(x1), 3), round(float(y1), 3)


#: the brightest point's channels may add this far (dB) under their coherent gain, 20 log10(channels), before the image
#: is said to be blurred: the ci drive's reflectors lose 3 dB with Tx0 and Tx2's rows swapped, 12 dB with the Rx
#: spacing doubled, 19 dB with the mounting's yaw sign turned (imaged mirrored across the track)
MAX_CHANNEL_LOSS_DB = 6.0


def brightest_pixel(image: NDArray[np.complex64]) -> tuple[int, int]:
    """Row and column of ``image``'s largest magnitude (of equals, the first in row-major order)."""
    mag = np.abs(image)
    r, c = np.unravel_index(int(np.argmax(mag)), mag.shape)
    return int(r), int(c)


def channel_sum_loss_db(drive_path: str | Path, trajectory: str | Path | Trajectory, config: Config,
                        options: FocusOptions, image: FocusedImage, size_m: float = 0.4) -> float | None:
    """How far (dB) the image's brightest point sums its channels under their coherent gain (20 log10 of their
    count): that point focused again on a fine patch (``size_m`` square) with every channel and with Tx0-Rx0 alone.
    None where the image has under 4 channels or the one channel's patch is empty."""
    return point_channel_sum_loss_db(drive_path, trajectory, config, options, image.grid, brightest_pixel(image.image),
                                     len(image.params["channel_pairs"]), size_m)


def point_channel_sum_loss_db(drive_path: str | Path, trajectory: str | Path | Trajectory, config: Config,
                              options: FocusOptions, grid: FocusGrid, pixel: tuple[int, int], n: int,
                              size_m: float = 0.4) -> float | None:
    """:func:`channel_sum_loss_db` at ``pixel`` (row, column) of ``grid``, an image of ``n`` channels (focus in
    tiles: the brightest of the tiles' brightest pixels)."""
    if n < 4:
        return None
    x, y, _ = grid.pixel_enu(np.array([pixel[0]]), np.array([pixel[1]])).reshape(3)
    h = size_m / 2
    patch = box_grid(x - h, y - h, x + h, y + h, pixel_m=options.pixel_m / 4, height_m=grid.height_m)
    peaks = [float(np.abs(focus_images(drive_path, trajectory, config, replace(options, channels=k),
                                       grids=[patch]).images[0].image).max()) for k in (options.channels, 1)]
    if not peaks[1] > 0:
        return None
    return 20 * math.log10(n) - 20 * math.log10(peaks[0] / peaks[1])


def channels_incoherent_warning(drive_path: str | Path, trajectory: str | Path | Trajectory, config: Config,
                                options: FocusOptions, grid: FocusGrid, pixel: tuple[int, int], n: int) -> str | None:
    """A warning where the image's brightest point (``pixel`` of ``grid``, ``n`` channels) sums its channels far
    under their coherent gain (:func:`point_channel_sum_loss_db` over ``MAX_CHANNEL_LOSS_DB``): the array's phase
    centres (``radar.*_positions_wavelengths``, ``tx_channels``, ``[radar.mounting]``'s yaw) are not the radar's."""
    loss = point_channel_sum_loss_db(drive_path, trajectory, config, options, grid, pixel, n)
    if loss is None or loss <= MAX_CHANNEL_LOSS_DB:
        return None
    return (f"focus: the image's brightest point sums its {n} channels {loss:.1f} dB under their coherent gain: the "
            f"radar's antennas are not where the config places them (radar.tx_positions_wavelengths, "
            f"rx_positions_wavelengths, tx_channels, the sign of radar.mounting.yaw_deg); the image is blurred or "
            f"mirrored across the track")


#: a trajectory may start after the radar's first frame, or end before its last, by this much (s) before the frames it
#: leaves out are warned of: a track of GNSS fixes (gnss, none) ends at its last fix, up to a fix period and the
#: receiver's latency before the radar (the ci drive's: 0.09 s of its 0.99); a track sampled more sparsely (a 1 Hz
#: receiver's fixes) may end up to this many of its own sample spacings early
MAX_UNCOVERED_S = 0.25
MAX_UNCOVERED_SPACINGS = 1.5


def track_spacing_s(traj: Trajectory) -> float:
    """The median spacing (s) of ``traj``'s samples; 0 for a track of one sample."""
    return float(np.median(np.diff(np.asarray(traj.t_ns, np.int64)))) / 1e9 if len(traj.t_ns) > 1 else 0.0


def uncovered_frames_warning(drive_path: str | Path, radar: RadarStream, tx_start_offsets_s: NDArray[np.float64],
                             traj: Trajectory, traj_name: str, outside: int) -> str | None:
    """A warning where ``traj`` starts after the radar's first frame or ends before its last by more than
    :data:`MAX_UNCOVERED_S` and :data:`MAX_UNCOVERED_SPACINGS` of its sample spacings (a trajectory cut short,
    another span's, a GNSS that started late): the frames outside it are left out of the image
    (:func:`_usable_frames`, which counts them: ``outside``), which then covers part of the drive alone. None
    else."""
    t = np.asarray(radar.t_ns, np.int64)
    last_chirp_ns = int(round(float(np.max(tx_start_offsets_s)) * 1e9)) if np.size(tx_start_offsets_s) else 0
    early, late = (int(traj.t_ns[0]) - int(t[0])) / 1e9, (int(t[-1]) + last_chirp_ns - int(traj.t_ns[-1])) / 1e9
    if max(early, late) <= max(MAX_UNCOVERED_S, MAX_UNCOVERED_SPACINGS * track_spacing_s(traj)):
        return None
    ends = ([f"starts {early:.2f} s after the first"] if early > 0 else []) + \
        ([f"ends {late:.2f} s before the last"] if late > 0 else [])
    return (f"{traj_name}: {' and '.join(ends)} frame of radar {radar.name} in {drive_path}: {outside} of its "
            f"{len(t)} frames lie outside the trajectory and are left out of the image, which lacks their part")


#: a pixel may be this many times the distance from a point's peak to its response's first null (across, the
#: cross-range resolution rho; in range c / B, a Hann window's two bins) before the image is said to lose points: half
#: a pixel then reaches 0.7 of the way to the null, where a point lies 9 dB down its cross-range sinc
MAX_PIXEL_PER_NULL = 1.4


def coarse_pixel_warning(pixel_m: float, resolution_m: float, range_null_m: float) -> str | None:
    """A warning where ``pixel_m`` exceeds :data:`MAX_PIXEL_PER_NULL` times the nearer first null of a point's
    response (``resolution_m`` across, ``range_null_m`` along the range: :func:`.range_compression.range_null_m`,
    c / B with a Hann window): each pixel is the image at its
    centre, so a point between centres is sampled on its sidelobes and can vanish. None else."""
    null = min(resolution_m, range_null_m)
    if pixel_m <= MAX_PIXEL_PER_NULL * null:
        return None
    finest = MAX_PIXEL_PER_NULL * null
    how = (f"--pixel {finest:.3g} or finer, or a coarser --resolution" if resolution_m < range_null_m else
           f"--pixel {finest:.3g} or finer (the range response's, which --resolution does not widen)")
    return (f"focus: pixel {pixel_m:g} m samples a point's response whose first null lies {null:.3g} m from its peak "
            f"(cross-range resolution {resolution_m:g} m, range {range_null_m:.3g} m): a point between pixel "
            f"centres is sampled on its sidelobes and can vanish from the image (a pixel's value is the image at its "
            f"centre, not its area's); choose {how}")


#: a trajectory's samples may lie this far apart (s) around radar frames, and its pose carried through the gap (CTRV
#: from the sample before) land this far (m) from the sample after, before the gap is warned of: SAR-MIN's, the
#: truth's and the INS's samples lie milliseconds apart, a GNSS track's a fix period (0.1 s), and the line of `none`
#: (1001 samples over any drive) is carried through exactly; a track sampled more sparsely (a 1-4 Hz receiver's fixes,
#: each carried to the next only within its noise) has gaps of over this many of its own sample spacings
MAX_BRIDGED_S, MAX_BRIDGE_JUMP_M, MAX_BRIDGED_SPACINGS = 0.25, 0.01, 3.0


def bridged_gap_warning(frames_t_ns: NDArray[np.int64], traj: Trajectory, traj_name: str) -> str | None:
    """A warning where radar frames focused (``frames_t_ns``) lie in a gap of ``traj`` over :data:`MAX_BRIDGED_S`
    and :data:`MAX_BRIDGED_SPACINGS` of its sample spacings long whose far end its pose carried through the gap misses
    by over :data:`MAX_BRIDGE_JUMP_M` (a trajectory with samples cut out, a GNSS outage of a GNSS track): focus places
    those frames by that guess. None else."""
    t = np.asarray(traj.t_ns, np.int64)
    gaps = np.flatnonzero(np.diff(t) > max(MAX_BRIDGED_S, MAX_BRIDGED_SPACINGS * track_spacing_s(traj)) * 1e9)
    if gaps.size == 0:
        return None
    carried, _ = traj.pose(t[gaps + 1] - 1)  # from the sample before, to a nanosecond short of the one after
    jumps = np.linalg.norm(carried - traj.rear_axle_enu[gaps + 1], axis=1)
    frames = np.searchsorted(frames_t_ns, t[gaps + 1]) - np.searchsorted(frames_t_ns, t[gaps], side="right")
    bad = (jumps > MAX_BRIDGE_JUMP_M) & (frames > 0)
    if not bad.any():
        return None
    k = gaps[bad][np.argmax(jumps[bad])]
    i = int(np.flatnonzero(gaps == k)[0])
    more = f" (and {int(bad.sum()) - 1} more such gaps)" if bad.sum() > 1 else ""
    return (f"{traj_name}: has no sample for {(t[k + 1] - t[k]) / 1e9:.2f} s ({(t[k] - t[0]) / 1e9:.2f}-"
            f"{(t[k + 1] - t[0]) / 1e9:.2f} s after its first) where {int(frames[i])} radar frames lie{more}: focus "
            f"carries its pose through (CTRV), which lands {jumps[i] * 100:.1f} cm from the sample after; the image is "
            "blurred where those frames look")


def damaged_frames_warning(drive_path: str | Path, radar: str, frame_index: Sequence[int]) -> str:
    """One line naming the frames (``frame_index``: their sorted indices in the recording, named as runs) of the
    drive's radar stream ``radar`` left out of an image because their stored data failed its checksum."""
    index = np.asarray(frame_index, np.int64)
    runs = [f"{r[0]}-{r[-1]}" if len(r) > 1 else f"{r[0]}" for r in np.split(index, np.flatnonzero(np.diff(index) != 1)
                                                                                     + 1)]
    named = ", ".join(runs[:3]) + (f" and {len(runs) - 3} more runs" if len(runs) > 3 else "")
    return (f"{drive_path}: {len(index)} frames of radar {radar} (frame index {named}) failed their checksum (the "
            "drive is damaged there): left out of the image, which lacks their part")


def unfocused_radars(drive_path: str | Path, options: FocusOptions) -> list[str]:
    """A warning naming the drive's radar streams left unfocused where ``options`` chose none (a car with two
    radars: the first is focused), else none."""
    if options.radar is not None:
        return []
    with Drive(drive_path) as d:
        names = d.radar_names()
    focused, others = names[0] if names else None, names[1:]
    if not others:
        return []
    return [f"{drive_path}: holds {len(names)} radar streams; focused {focused}, not {', '.join(others)} "
            "(--radar-stream NAME focuses another)"]


def physical_memory_bytes() -> int | None:
    """This machine's memory (bytes); None where the system does not say (not POSIX)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return None


def _check_memory(image_bytes: int, options: FocusOptions) -> None:
    """Refuse an image held whole that this machine's memory cannot hold (numpy's "Unable to allocate ..." after
    the planning); the grid's own limit (sar.grid.MAX_IMAGE_BYTES) is the larger on most machines."""
    memory = physical_memory_bytes()
    if memory is not None and image_bytes > memory:
        raise FocusError(f"grid: pixel size {options.pixel_m:g} m: the image needs {image_bytes / 2**30:.3g} GiB, more "
                         f"than this machine's {memory / 2**30:.3g} GiB of memory; choose a larger pixel or a smaller "
                         "grid, or focus in tiles (--tiles)")


def check_grid_size(options: FocusOptions, config: Config | None = None, grid: FocusGrid | None = None) -> None:
    """Refuse an image too large to hold (sar.grid.check_image_size), before or after planning its grid."""
    try:
        check_image_size(options.pixel_m, pixels=None if grid is None else float(grid.size),
                         box=parse_grid(options.grid), max_range_m=config.radar.max_range_m if config else None)
    except GridError as exc:
        raise FocusError(f"grid: {exc}") from None


def check_request(options: FocusOptions, output: str | Path, overwrite: bool,
                  inputs: Sequence[str | Path] = (), config: Config | None = None) -> None:
    """Fail before any work on a bad --grid, --channels or grid size, on products that are ``inputs`` (the
    drive, the trajectory), and on existing products without --overwrite or not written by autosar
    (store.outputs)."""
    if (box := parse_grid(options.grid)) is not None and 0 < min(box[2] - box[0], box[3] - box[1]) < options.pixel_m:
        raise FocusError(f"--grid {options.grid}: smaller than one pixel ({options.pixel_m:g} m), whose centre would "
                         "lie outside it")  # a 1 x 1 image beside the box asked for, exit 0
    check_grid_size(options, config)
    if options.channels not in (8, 12):
        raise FocusError(f"--channels {options.channels}: choose 8 or 12")
    for path in product_paths(Path(output)).values():  # what --overwrite would not replace (an input, another's
        check_output(path, inputs, overwrite=True)     # file) before the advice to pass it
    existing = [str(p) for p in product_paths(Path(output)).values() if p.exists()]
    if existing and not overwrite:
        raise FocusError(already_exists(existing[0]))


def focus(drive_path: str | Path, trajectory_path: str | Path, output: str | Path, config: Config,
          options: FocusOptions, *, overwrite: bool = False,
          progress: Callable[[int, int], None] | None = None, command: str = "") -> FocusReport:
    """Focus the radar of ``drive_path`` along ``trajectory_path`` and write OUT.tif/.h5/.png."""
    check_request(options, output, overwrite, [drive_path, trajectory_path], config)
    config = drive_radar_config(config, drive_path, options.radar)
    # the quicklook's imports run beside the focusing, from its first block on (its kernels and FFTs release the
    # GIL; before that, the imports would compete with numba's start-up for it)
    preload = threading.Thread(target=preload_quicklook, daemon=True)

    def on_block(done: int, total: int) -> None:
        if preload.ident is None:
            preload.start()
        if progress is not None:
            progress(done, total)

    res = focus_images(drive_path, trajectory_path, config, options, progress=on_block, command=command)
    check_some_backprojection(res.backprojections, drive_path, options, res.images[0].params["half_width_rad"],
                              trajectory_path, config)
    t0 = time.perf_counter()
    img = res.images[0]
    warnings = [*res.warnings, *unfocused_radars(drive_path, options)]
    incoherent = channels_incoherent_warning(drive_path, trajectory_path, config, options, img.grid,
                                             brightest_pixel(img.image), len(img.params["channel_pairs"]))
    warnings += [incoherent] if incoherent else []
    img.provenance["warnings"] = warnings  # what the image lacks, with it (evaluate reads them)
    outputs = write_image(Path(output), img, overwrite=overwrite)
    timings = dict(res.timings_s)
    timings["write"] = time.perf_counter() - t0
    return FocusReport({k: str(v) for k, v in outputs.items()}, img.grid.shape, res.frames_used, res.frames_skipped,
                       res.backprojections, timings, res.drive_s, warnings, grid_enu_box(img.grid))
