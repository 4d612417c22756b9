"""Phase histories of point scatterers: what back-projection makes of each pulse at one point, kept so that a
trajectory correction can be tried on them many times without reading the radar again.

:func:`gather_phase_histories` reads the frames that see the points once, range-compresses them and keeps a window
of bins around each point's predicted range per pulse and channel (:func:`narrow_histories` takes a narrower beam
and window from them along a nearby track); :func:`focus_history` back-projects a pulse onto its point from given
antenna positions (exact bistatic path, linear interpolation between bins and the carrier phase, as the product's
kernel does); :func:`range_offsets` measures each point's range from its envelope; :func:`channel_phase` the phase
between its first and last channel (which a moving scatterer's shows). Used by the residual-motion autofocus
(:mod:`autosar_cli.sar.residual_motion`).
"""

from __future__ import annotations

import dataclasses
import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from autosar_cli.config import Config
from autosar_cli.nav.trajectory import phase_centre_lever_arm, radar_phase_centres, radar_side
from autosar_cli.sar.focus import FocusOptions, RadarParameters, channel_pairs, open_radar
from autosar_cli.sar.history_kernel import focus_windows, take_windows
from autosar_cli.sar.range_compression import range_compress, reference_ramp
from autosar_cli.store.drive import Drive
from autosar_cli.types import Trajectory

Array = NDArray[np.float64]


@dataclass
class PhaseHistories:
    """Range-compressed samples around each point's expected range, for every (point, pulse) pair it is seen in.

    Pair n: point ``point[n]``, radar frame ``frame_t_ns[frame[n]]``; channel c's bins ``bin0[n, c]`` ...
    ``bin0[n, c] + W - 1`` (bistatic path ``bin * bin_m``) are ``samples[n, c]``.
    """

    point: NDArray[np.int64]  #: (N,)
    frame: NDArray[np.int64]  #: (N,) index into frame_t_ns
    frame_t_ns: NDArray[np.int64]  #: (F,) the frames used
    bin0: NDArray[np.int64]  #: (N, C)
    samples: NDArray[np.complex64]  #: (N, C, W)
    pairs: list[tuple[int, int]]  #: (Tx, Rx) of each channel
    tx_offsets_s: Array  #: (T,) chirp start of each Tx in the PRI
    bin_m: float  #: bistatic path per bin (m)
    cycles_per_m: float  #: phase turns per metre of bistatic path
    slope_hz_per_s: float = math.nan  #: the chirp's slope (the stream's own, as focus takes it)


def histories_of(hist: PhaseHistories, used: NDArray[np.bool_]) -> tuple[PhaseHistories, NDArray[np.bool_]]:
    """The histories of the ``used`` (P,) points' pulses only, and the mask of those pulses."""
    keep = used[hist.point]
    return dataclasses.replace(hist, point=hist.point[keep], frame=hist.frame[keep], bin0=hist.bin0[keep],
                               samples=hist.samples[keep]), keep


def frame_geometry(traj: Trajectory, t_ns: NDArray[np.int64], config: Config) -> tuple[Array, Array, Array]:
    """Mean phase centre (F, 3), unit across-track vector towards the radar side (F, 3), unit along (F, 3)."""
    centre = traj.body_points(t_ns, phase_centre_lever_arm(config)[None])[:, 0]
    _, heading = traj.pose(t_ns)
    side = radar_side(config)
    zero = np.zeros_like(heading)
    along = np.stack([np.cos(heading), np.sin(heading), zero], axis=-1)
    across = side * np.stack([-np.sin(heading), np.cos(heading), zero], axis=-1)
    return centre, across, along


def gather_phase_histories(drive_path: str | Path, traj: Trajectory, config: Config, points_enu: Array,
                           focus: FocusOptions, *, half_beam_deg: float, window_bins: int, channels: int,
                           block_frames: int = 256, pairs: list[tuple[int, int]] | None = None,
                           frame_runs: tuple[int, int] | None = None) -> PhaseHistories:
    """Read and range-compress (``channels``, sar.focus.channel_pairs, or the (Tx, Rx) ``pairs`` given;
    ``focus``'s window and upsampling) the frames that see ``points_enu`` (P, 3) (ENU m) within ``half_beam_deg``
    of broadside, and keep ``window_bins`` bins around each point's range per pulse and channel (one pass over the
    radar data). ``focus.channel_gains``, where given, are undone on the windows kept; ``frame_runs`` (run,
    period): only the drive's frames ``i`` with ``i % period < run`` (runs of whole chunks of the raw cube, whose
    reads are what a sparse sample of frames costs)."""
    points = np.asarray(points_enu, dtype=np.float64).reshape(-1, 3)
    w = int(window_bins)
    with Drive(drive_path) as drive:
        radar = open_radar(drive, focus)
        rp = RadarParameters.of(radar, config, focus.upsample)
        fs, slope, offsets, n_bins, bin_m = rp.sample_rate_hz, rp.slope_hz_per_s, rp.tx_start_offsets_s, rp.n_bins, \
            rp.bin_m
        pairs = list(pairs) if pairs is not None else channel_pairs(rp.n_tx, rp.n_rx, channels)
        t_all = radar.t_ns
        last_chirp_ns = int(round(offsets.max() * 1e9)) if offsets.size else 0
        frames = np.flatnonzero((t_all >= traj.t_ns[0]) & (t_all + last_chirp_ns <= traj.t_ns[-1]))
        t = t_all[frames]
        seen = _seen(traj, t, config, points, _moving(traj, t, focus), half_beam_deg)
        if frame_runs is not None:
            seen[frames % frame_runs[1] >= frame_runs[0]] = False
        used = np.flatnonzero(seen.any(axis=1))
        # every (frame, point) pair in frame order, its samples written in place (joining per-block lists at the
        # end would cost as much again as taking the windows: test2's 130 MB)
        frame_of, point_of = np.nonzero(seen)
        n_pairs = len(frame_of)
        samples = np.empty((n_pairs, len(pairs), w), np.complex64)
        bin0 = np.empty((n_pairs, len(pairs)), np.int64)
        tx_idx = np.array([p[0] for p in pairs])
        rx_idx = np.array([p[1] for p in pairs])
        starts = list(range(0, len(used), block_frames))
        if frame_runs is not None:  # no block spans the frames between two runs: their chunks are not read
            starts = sorted(set(starts) | set((np.flatnonzero(np.diff(frames[used]) > 1) + 1).tolist()))
        blocks = [used[a:b] for a, b in zip(starts, [*starts[1:], len(used)], strict=False)]
        pc = radar_phase_centres(traj, t[used], offsets, config)  # elementwise in time: once for all blocks
        tx_all, rx_all = pc.tx[:, tx_idx], pc.rx[:, tx_idx, rx_idx]  # (U, C, 3)
        ramp = reference_ramp(rp.n_samples, n_bins, fs, slope)
        gain = None if focus.channel_gains is None else focus.channel_gains.correction(pairs)[:, None]

        def read(sel: NDArray[np.int64]) -> NDArray[np.int16]:
            raw = radar.frames(int(frames[sel[0]]), int(frames[sel[-1]]) + 1, pairs)
            return raw[frames[sel] - frames[sel[0]]]  # (B, C, samples, 2)

        # the next block is read while this one is compressed (h5py's reads and the FFTs release the GIL)
        with ThreadPoolExecutor(1) as reader:
            pending = reader.submit(read, blocks[0]) if blocks else None
            for b, (start, sel) in enumerate(zip(starts, blocks, strict=True)):
                raw = pending.result()
                if b + 1 < len(blocks):
                    pending = reader.submit(read, blocks[b + 1])
                # the ramp goes on the windows only (test2's are 7 % of the profiles' bins)
                profiles = range_compress(raw, sample_rate_hz=fs, slope_hz_per_s=slope, window=focus.window,
                                          upsample=focus.upsample, referenced=False)  # (B, C, bins)
                lo, hi = np.searchsorted(frame_of, sel[0]), np.searchsorted(frame_of, sel[-1], side="right")
                kk = np.searchsorted(sel, frame_of[lo:hi])
                tx, rx = tx_all[start + kk], rx_all[start + kk]  # (n, C, 3)
                p = points[point_of[lo:hi]][:, None, :]
                path = np.linalg.norm(tx - p, axis=-1) + np.linalg.norm(rx - p, axis=-1)
                b0 = np.floor(path / bin_m).astype(np.int64) - (w // 2 - 1)
                b0 = np.clip(b0, 0, n_bins - w)
                take_windows(profiles, ramp, kk, b0, samples[lo:hi])
                if gain is not None:
                    samples[lo:hi] *= gain
                bin0[lo:hi] = b0
    return PhaseHistories(point_of, frame_of, t, bin0, samples, pairs, offsets, bin_m, rp.cycles_per_m, slope)


def narrow_histories(hist: PhaseHistories, traj: Trajectory, config: Config, points_enu: Array, focus: FocusOptions,
                     *, half_beam_deg: float, window_bins: int) -> PhaseHistories:
    """What :func:`gather_phase_histories` would keep along ``traj`` of the points ``points_enu`` (P, 3) (ENU m),
    within ``half_beam_deg`` of broadside and ``window_bins`` bins around each range, taken from ``hist``: the same
    points' histories gathered with a wider beam and window along a track near ``traj`` (one read of the radar for
    both). Where a window reaches beyond ``hist``'s, it is moved back inside (a pulse whose path then leaves it is
    NaN in :func:`focus_history`)."""
    points = np.asarray(points_enu, dtype=np.float64).reshape(-1, 3)
    w, wide = int(window_bins), hist.samples.shape[-1]
    if w > wide:
        raise ValueError(f"a window of {w} bins cannot be taken from histories of {wide}")
    seen = _seen(traj, hist.frame_t_ns, config, points, _moving(traj, hist.frame_t_ns, focus), half_beam_deg)
    keep = np.flatnonzero(seen[hist.frame, hist.point])
    sub = dataclasses.replace(hist, point=hist.point[keep], frame=hist.frame[keep], bin0=hist.bin0[keep],
                              samples=hist.samples[keep])
    tx, rx = pair_antennas(sub, traj, config)
    p = points[sub.point][:, None, :]
    path = np.linalg.norm(tx - p, axis=-1) + np.linalg.norm(rx - p, axis=-1)
    start = np.clip(np.floor(path / hist.bin_m).astype(np.int64) - (w // 2 - 1) - sub.bin0, 0, wide - w)  # (n, C)
    samples = np.take_along_axis(sub.samples, start[..., None] + np.arange(w), axis=-1)
    return dataclasses.replace(sub, bin0=sub.bin0 + start, samples=samples)


def _moving(traj: Trajectory, t_ns: NDArray[np.int64], focus: FocusOptions) -> NDArray[np.bool_]:
    """(F,) whether the car moves fast enough at ``t_ns`` to focus (``focus.min_speed_mps``)."""
    speed = np.interp((t_ns - traj.t_ns[0]).astype(np.float64), (traj.t_ns - traj.t_ns[0]).astype(np.float64),
                      np.abs(traj.speed))
    return speed >= focus.min_speed_mps


def _seen(traj: Trajectory, t_ns: NDArray[np.int64], config: Config, points: Array, moving: NDArray[np.bool_],
          half_beam_deg: float, block_frames: int = 512) -> NDArray[np.bool_]:
    """(F, P) whether the radar at each frame ``t_ns`` sees each point (ENU m): on its side, within
    ``half_beam_deg`` of broadside, within its range, the car ``moving`` (F,); in blocks of frames, so the
    (frames, points, 3) geometry stays small."""
    seen = np.zeros((len(t_ns), len(points)), dtype=bool)
    sin_half_beam = math.sin(math.radians(half_beam_deg))
    reach = config.radar.max_range_m
    for b in range(0, len(t_ns), block_frames):
        centre, across, along = frame_geometry(traj, t_ns[b:b + block_frames], config)
        # only the points within the radar's range of the block's box can be seen from it
        lo, hi = centre.min(axis=0) - reach, centre.max(axis=0) + reach
        near = np.flatnonzero(np.all((points >= lo) & (points <= hi), axis=1))
        d = points[None, near, :] - centre[:, None, :]  # (B, P', 3)
        horiz = np.maximum(np.hypot(d[..., 0], d[..., 1]), 1e-9)
        seen[b:b + block_frames, near] = (moving[b:b + block_frames, None]
                                          & (np.einsum("fpk,fk->fp", d, across) > 0.0)
                                          & (np.abs(np.einsum("fpk,fk->fp", d, along)) <= sin_half_beam * horiz)
                                          & (np.einsum("fpk,fpk->fp", d, d) <= reach ** 2))
    return seen


def pair_antennas(hist: PhaseHistories, traj: Trajectory, config: Config) -> tuple[Array, Array]:
    """Tx and Rx phase centres (N, C, 3) (ENU m) of every pair's channels along ``traj``."""
    pc = radar_phase_centres(traj, hist.frame_t_ns, hist.tx_offsets_s, config)
    tx_idx = np.array([p[0] for p in hist.pairs])
    rx_idx = np.array([p[1] for p in hist.pairs])
    # the channels per frame first, then per pair: a pair's frame repeats for every point it sees
    return pc.tx[:, tx_idx][hist.frame], pc.rx[:, tx_idx, rx_idx][hist.frame]


def focus_history(hist: PhaseHistories, tx: Array, rx: Array, points_enu: Array,
                  channels: slice = slice(None)) -> tuple[NDArray[np.complex128], Array]:
    """Each pair's back-projected value (N,) (``channels`` summed, default all; exact path, linear interpolation
    between bins as the kernel does) from antennas ``tx``, ``rx`` (N, C, 3) (:func:`pair_antennas`, ENU m) onto
    ``points_enu`` (P, 3), and its unit line of sight (N, 3) from those channels' mean phase centre to the point.
    A pair whose path left its bin window in any of them gives NaN."""
    points = np.asarray(points_enu, dtype=np.float64)
    z, inside, los = focus_windows(*(np.ascontiguousarray(a[:, channels]) for a in (hist.samples, hist.bin0, tx, rx)),
                                   points, hist.point, hist.bin_m, hist.cycles_per_m, np.zeros(1))
    z = z[:, 0]
    z[~inside[:, 0]] = np.nan
    return z, los


def range_offsets(hist: PhaseHistories, tx: Array, rx: Array, points_enu: Array, n_points: int,
                  half_bins: float = 3.0, step_bins: float = 0.5) -> tuple[Array, Array, Array]:
    """Per point, how much longer (m of bistatic path) its echoes' range envelope says its path is than predicted
    from ``tx``, ``rx`` (N, C, 3): the peak, over offsets of +-``half_bins``, of the point's pulses summed
    coherently with the predicted phase (parabola through the three samples around it). Also each point's
    weight (its summed power) and mean line of sight (P, 3). Phases alone do not fix a point's range: a range error
    bends its phase history as a wrong speed does, so the envelope pins it."""
    points = np.asarray(points_enu, dtype=np.float64)
    ks = np.arange(-half_bins, half_bins + 1e-9, step_bins)
    z, _, los = focus_windows(hist.samples, hist.bin0, tx, rx, points, hist.point, hist.bin_m, hist.cycles_per_m, ks)
    # every (point, offset) sum in one bincount over point * K + offset (each sum still adds its pairs in order)
    cell = (hist.point[:, None] * len(ks) + np.arange(len(ks))).ravel()
    zs = (np.bincount(cell, z.real.ravel(), n_points * len(ks))
          + 1j * np.bincount(cell, z.imag.ravel(), n_points * len(ks))).reshape(n_points, len(ks))
    power = np.abs(zs) ** 2
    k = np.clip(np.argmax(power, axis=1), 1, len(ks) - 2)
    rows = np.arange(n_points)
    y0, y1, y2 = (np.log(np.maximum(power[rows, k + d], 1e-300)) for d in (-1, 0, 1))
    denom = y0 - 2 * y1 + y2
    frac = np.where(denom < 0, 0.5 * (y0 - y2) / np.where(denom < 0, denom, -1.0), 0.0)
    offset = (ks[k] + np.clip(frac, -1.0, 1.0) * step_bins) * hist.bin_m
    mean_los = np.stack([np.bincount(hist.point, los[:, c], n_points) for c in range(3)], axis=-1)
    mean_los /= np.maximum(np.linalg.norm(mean_los, axis=-1, keepdims=True), 1e-12)
    return offset, power.max(axis=1), mean_los


def channel_phase(hist: PhaseHistories, tx: Array, rx: Array, points_enu: Array, n_points: int) -> tuple[Array, Array]:
    """Per point (P,), the phase (rad) between the histories' first and last channel once each is back-projected
    onto it from ``tx``, ``rx`` (N, C, 3), summed over its pulses: arg sum(z_first conj(z_last)), and that sum's
    coherence |sum(z_first conj(z_last))| / sum(|z_first| |z_last|) (0 where it has no pulse). The channels are the
    virtual array's ends, apart along the road: a still point where the track puts it has one phase in both (its
    own); a scatterer crossing the beam at v_c, which back-projection places v_c R / v further along, is seen
    off that direction, by 2 pi/lambda times the channels' path difference (along-track interferometry)."""
    points = np.asarray(points_enu, dtype=np.float64).reshape(-1, 3)
    last = hist.samples.shape[1] - 1
    first, _ = focus_history(hist, tx, rx, points, channels=slice(0, 1))
    end, _ = focus_history(hist, tx, rx, points, channels=slice(last, last + 1))
    ok = np.isfinite(first) & np.isfinite(end)
    cross = np.where(ok, first * np.conj(end), 0.0)
    total = np.bincount(hist.point, cross.real, n_points) + 1j * np.bincount(hist.point, cross.imag, n_points)
    scale = np.bincount(hist.point, np.where(ok, np.abs(first) * np.abs(end), 0.0), n_points)
    return np.angle(total), np.where(scale > 0, np.abs(total) / np.where(scale > 0, scale, 1.0), 0.0)
