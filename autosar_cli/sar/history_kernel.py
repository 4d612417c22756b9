"""Kept range windows: taken from the range profiles and back-projected onto their points (numba kernels).

Their taking (:func:`take_windows`, for :func:`autosar_cli.sar.phase_history.gather_phase_histories`), and their
back-projection, the inner loop of the residual-motion autofocus's model (:func:`focus_windows`, for
:func:`autosar_cli.sar.phase_history.focus_history` and ``range_offsets``). Array in, array out.

Each (point, pulse) pair's channels hold a window of range bins around the point's predicted path
(:class:`~autosar_cli.sar.phase_history.PhaseHistories`); the pair's value is the channels' samples at the exact
bistatic path (linear interpolation between bins), rotated by the path's carrier phase and summed, as the
product's back-projection kernel does. One fused loop in float64: the numpy form made a dozen (pairs, channels)
temporaries per call, and the autofocus calls it ~100 times a drive. The pairs are shared among numba's threads
(0.49 of one thread's time on 2 cores, test2's 35 625 pairs), the same bits as on one.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray


@nb.njit(parallel=True, cache=True, nogil=True, error_model="numpy")
def _focus_windows(samples, bin0, tx, rx, points, point_of, bin_m, cycles_per_m, offsets_bins,
                   z_re, z_im, inside, los):  # pragma: no cover - compiled
    n_pairs, n_ch, width = samples.shape
    for n in nb.prange(n_pairs):  # each pair writes its own rows only: the same sums in any thread order
        j = point_of[n]
        for k in range(3):
            los[n, k] = points[j, k]
        for c in range(n_ch):
            d_tx = 0.0
            d_rx = 0.0
            for k in range(3):
                d_tx += (tx[n, c, k] - points[j, k]) ** 2
                d_rx += (rx[n, c, k] - points[j, k]) ** 2
                los[n, k] -= 0.5 * (tx[n, c, k] + rx[n, c, k]) / n_ch
            path = math.sqrt(d_tx) + math.sqrt(d_rx)
            turns = path * cycles_per_m
            phase = -2.0 * math.pi * (turns - math.floor(turns))
            rot_re, rot_im = math.cos(phase), math.sin(phase)
            fi0 = path / bin_m - bin0[n, c]
            for m in range(offsets_bins.shape[0]):
                fi = fi0 + offsets_bins[m]
                i = int(math.floor(fi))
                if i < 0 or i >= width - 1:
                    inside[n, m] = False
                    continue
                f = fi - i
                s0 = samples[n, c, i]
                s1 = samples[n, c, i + 1]
                s_re = float(s0.real) + f * (float(s1.real) - float(s0.real))
                s_im = float(s0.imag) + f * (float(s1.imag) - float(s0.imag))
                z_re[n, m] += s_re * rot_re - s_im * rot_im
                z_im[n, m] += s_re * rot_im + s_im * rot_re
        norm = math.sqrt(los[n, 0] ** 2 + los[n, 1] ** 2 + los[n, 2] ** 2)
        for k in range(3):
            los[n, k] /= norm


def focus_windows(samples: NDArray[np.complex64], bin0: NDArray[np.int64], tx: NDArray[np.float64],
                  rx: NDArray[np.float64], points_enu: NDArray[np.float64], point_of: NDArray[np.int64],
                  bin_m: float, cycles_per_m: float, offsets_bins: NDArray[np.float64]
                  ) -> tuple[NDArray[np.complex128], NDArray[np.bool_], NDArray[np.float64]]:
    """Each pair's channels summed (N, K) at its exact path plus each of ``offsets_bins`` (K,) bins, rotated by
    the carrier phase of the exact path; whether every channel's sample lay inside its window (N, K) (one
    outside contributes 0); and each pair's unit line of sight (N, 3) from its channels' mean phase centre to its
    point.

    ``samples`` (N, C, W) complex range samples, bins ``bin0`` (N, C) ... ``bin0 + W - 1`` (bistatic path ``bin *
    bin_m``, m); ``tx``, ``rx`` (N, C, 3) ENU m, each pair's antennas; ``points_enu`` (P, 3) ENU m, pair n's
    point ``point_of[n]``; ``cycles_per_m`` carrier turns per metre of bistatic path."""
    n, k = len(samples), len(offsets_bins)
    z_re, z_im = np.zeros((n, k)), np.zeros((n, k))
    inside = np.ones((n, k), dtype=np.bool_)
    los = np.empty((n, 3))
    _focus_windows(np.ascontiguousarray(samples), np.ascontiguousarray(bin0, dtype=np.int64),
                   np.ascontiguousarray(tx, dtype=np.float64), np.ascontiguousarray(rx, dtype=np.float64),
                   np.ascontiguousarray(points_enu, dtype=np.float64), np.ascontiguousarray(point_of, dtype=np.int64),
                   float(bin_m), float(cycles_per_m), np.ascontiguousarray(offsets_bins, dtype=np.float64),
                   z_re, z_im, inside, los)
    return z_re + 1j * z_im, inside, los


@nb.njit(cache=True, nogil=True)
def _take_windows(profiles, ramp, row, start, samples, ramp_windows):  # pragma: no cover - compiled
    for n in range(row.shape[0]):
        for c in range(start.shape[1]):
            b = start[n, c]
            for i in range(samples.shape[2]):
                samples[n, c, i] = profiles[row[n], c, b + i]
                ramp_windows[n, c, i] = ramp[b + i]


def take_windows(profiles: NDArray[np.complex64], ramp: NDArray[np.complex64], row: NDArray[np.int64],
                 start: NDArray[np.int64], samples: NDArray[np.complex64]) -> None:
    """``samples[n, c] = profiles[row[n], c, start[n, c]:start[n, c] + W] * ramp[start[n, c]:start[n, c] + W]``.

    ``profiles`` (B, C, K) complex range profiles before their reference ramp (``range_compress(...,
    referenced=False)``); ``ramp`` (K,) the ramp; ``row`` (N,) each window's profile; ``start`` (N, C) first bins,
    each in 0 ... K - W; ``samples`` (N, C, W) written in place. The product is numpy's, so the windows equal
    those of the referenced profiles bit for bit (a window copy, not fancy indexing: 4 times faster on test2)."""
    if len(row) and (start.min() < 0 or start.max() > profiles.shape[-1] - samples.shape[-1]):
        raise ValueError("a range window reaches beyond its profile")
    ramp_windows = np.empty_like(samples)
    _take_windows(profiles, ramp, np.ascontiguousarray(row, dtype=np.int64),
                  np.ascontiguousarray(start, dtype=np.int64), samples, ramp_windows)
    samples *= ramp_windows
