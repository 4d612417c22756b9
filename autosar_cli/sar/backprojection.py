"""Time-domain back-projection kernel (paper eq. (18)-(23)): exact bistatic range per channel, linear
interpolation of the range-compressed samples, carrier phase rotation, coherent sum over pulses and
channels. Array in, array out; geometry (grids, windows) and I/O live elsewhere.

Why the kernel looks the way it does (measured on the 2-core AVX-512 development machine):

* Lanes run over **pulses**, not pixels. Between neighbouring pulses a pixel's range changes by far less
  than a range bin, so 16 lanes read 3, 4 or 6 neighbouring rows of a (bin, pulse) array with contiguous
  loads and select per lane. With lanes over pixels every sample is a gather, and gathers cost ~17
  cycles per 8 lanes here.
* Each antenna's range to pulse p is written as ``R_p = R_q + delta`` about a reference pulse q of the same
  pixel, with ``R_q`` exact in float64 once per pixel chunk and ``delta = d / (R_q + sqrt(R_q^2 + d))``,
  ``d = |a|^2 - 2 x.a`` (``a`` = antenna displacement since pulse q, ``x`` = pixel - antenna at q), in
  float32: exact (no series, so no bound on the chunk's length), ~1e-7 relative, and it keeps the carrier
  phase accurate in float32: phase is ``frac(R_q k) + delta k`` with ``delta`` small, instead of
  ``R k`` ~ 1e4 cycles. With ``error_model="numpy"`` the division vectorises (a reciprocal estimate and a
  Newton step): ~5 cycles per 16 lanes, as much as the sixth-order series in ``e = d / R_q^2`` it replaced,
  whose ``|e| <= 0.1`` cut the benchmark's full-aperture chunks short (fixed case 0.86 -> 1.00 G/s per
  thread; test1's image equal to -137 dB).
* sin/cos of the residual phase by minimax polynomials of the half angle (error < 2e-6).
* A chunk reads 3, 4 or 6 rows, so its range migration must stay below four bins. Wide, squinted windows
  (every pulse for every pixel) migrate further; rather than cutting them into many short chunks (each
  with its sizing check and loop set-up, ~600 cycles), each vector of 16 pulses then picks its own four rows
  (``_accumulate_vectors``; where no lane needs masking, four vectors per horizontal sum,
  ``_accumulate_vectors_inside``: ~1.2x the cost per vector of the six-row loop), and chunks are as long as
  the window. That pays with one channel (0.84x the time on the benchmark's fixed case), not with the
  product's eight or twelve, which share each chunk's fixed costs (see ``VSPAN_MAX``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray

from autosar_cli.kernel_cache import compile_in_child

LANES = 16  #: pulses per vector (one AVX-512 register of float32)
DEFAULT_MAX_CHUNK = 512  #: pulses per reference (longer windows are split)
MAX_ROWS = 6  #: the fast path reads 3, 4 or 6 neighbouring rows per chunk and channel
MAX_SPAN_BINS = MAX_ROWS - 2.05  #: range migration allowed within a chunk on the fast path
#: In a block of at most VECTOR_ROWS_MAX_CHANNELS channels, a chunk whose migration exceeds the six rows takes
#: the per-vector path (:func:`_accumulate_vectors`) instead of being cut, if 16 pulses change channel 0's
#: path by less than VSPAN_MAX bins at both of its ends: every lane then lies within 8/15 x 1.6 = 0.85 bins of
#: its vector's centre lane, inside the four rows around it (+-1 bin), with 0.15 bins to spare for
#: vibration. A chunk's fixed costs (sizing, references, loop set-up) are shared by all channels, so cutting
#: costs less with many: with one channel (the benchmark's fixed case) the per-vector rows took 0.84x the
#: time, with test1's eight channels at 1 cm resolution 1.05-1.10x (interleaved focus runs), so the
#: product's 8- and 12-channel blocks keep cutting.
VSPAN_MAX = 1.6
VECTOR_ROWS_MAX_CHANNELS = 1


def _fit_odd(fn, n_terms: int, half_width: float) -> tuple[float, ...]:
    """Least-squares (Chebyshev-node) polynomial in f^2 so that fn(f) ~ f * P(f^2) on [-w, w]."""
    f = half_width * np.cos(np.pi * (np.arange(400) + 0.5) / 400)
    A = np.stack([f ** (2 * k + 1) for k in range(n_terms)], axis=1)
    return tuple(np.linalg.lstsq(A, fn(f), rcond=None)[0])


def _fit_even(fn, n_terms: int, half_width: float) -> tuple[float, ...]:
    f = half_width * np.cos(np.pi * (np.arange(400) + 0.5) / 400)
    A = np.stack([f ** (2 * k) for k in range(n_terms)], axis=1)
    return tuple(np.linalg.lstsq(A, fn(f), rcond=None)[0])


# sin(pi f), cos(pi f) on f in [-1/2, 1/2]; the kernel forms the full angle 2 pi f by doubling
# (max errors 7e-5 and 7e-6: the phasor errs < 2e-4, -75 dB)
_S1, _S3, _S5 = _fit_odd(lambda f: np.sin(np.pi * f), 3, 0.5)
_C0, _C2, _C4, _C6 = _fit_even(lambda f: np.cos(np.pi * f), 4, 0.5)


_U = nb.uint64  # unsigned indices: numba's negative-index wraparound turns contiguous loads into gathers
_F = nb.float32


@nb.njit(fastmath=True, cache=True, inline="always", error_model="numpy")
def _antenna_deltas(ax, ay, az, a, p, q, n_pad, mx, my, mz, r_q, r_q2, out):  # pragma: no cover - compiled
    """out[l] = R(p + l) - R(q) for antenna a, l < n_pad: exact, as d / (R_q + sqrt(R_q^2 + d)) with
    d = R^2 - R_q^2 = |u|^2 - 2 x.u (u = antenna displacement since pulse q, x = pixel - antenna at q; mx, my,
    mz = -2 x). The difference of squares is small where R - R_q is, so float32 keeps it to ~1e-7 relative,
    and the square root only enters the denominator; contiguous float32 loads. ``error_model="numpy"`` in the
    caller lets LLVM vectorise the division (a reciprocal estimate and a Newton step)."""
    qx = ax[a, q]
    qy = ay[a, q]
    qz = az[a, q]
    rx = ax[a]
    ry = ay[a]
    rz = az[a]
    base = _U(p)
    for l in range(_U(n_pad)):
        dx = rx[base + l] - qx
        dy = ry[base + l] - qy
        dz = rz[base + l] - qz
        d = dx * (dx + mx) + dy * (dy + my) + dz * (dz + mz)
        out[l] = d / (r_q + np.sqrt(max(r_q2 + d, _F(0.0))))


@nb.njit(fastmath=True, cache=True, inline="always")
def _rotate(s_re, s_im, f, w):  # pragma: no cover - compiled
    """w (s_re + j s_im) exp(-2j pi f) for f in cycles (any value); w is 1, or 0 for a padding lane."""
    f = f - np.floor(f + _F(0.5))
    f2 = f * f
    sh = f * (_F(_S1) + f2 * (_F(_S3) + f2 * _F(_S5))) * w  # w sin(pi f)
    ch = _F(_C0) + f2 * (_F(_C2) + f2 * (_F(_C4) + f2 * _F(_C6)))  # cos(pi f)
    cs = w - _F(2.0) * sh * sh  # w cos(2 pi f)
    sn = _F(2.0) * sh * ch  # w sin(2 pi f)
    return s_re * cs + s_im * sn, s_im * cs - s_re * sn


@nb.njit(fastmath=True, cache=True, inline="always")
def _interp_rows(prof_re, prof_im, r0, l, stride, fi, n_rows):  # pragma: no cover - compiled
    """Sample at fractional row fi in [0, n_rows - 1) of rows r0, r0 + stride, ... (n_rows: 3, 4 or 6, a
    constant at every call site, so the branches fold away), pulse column l: contiguous loads, a per-lane
    select of the two rows around fi, linear interpolation."""
    r1 = r0 + stride
    r2 = r1 + stride
    m1 = fi >= _F(1.0)
    fr = fi - np.floor(fi)
    x0 = prof_re[r0 + l]
    x1 = prof_re[r1 + l]
    x2 = prof_re[r2 + l]
    y0 = prof_im[r0 + l]
    y1 = prof_im[r1 + l]
    y2 = prof_im[r2 + l]
    if n_rows == 3:
        a_re = x1 if m1 else x0
        b_re = x2 if m1 else x1
        a_im = y1 if m1 else y0
        b_im = y2 if m1 else y1
    else:
        r3 = r2 + stride
        m2 = fi >= _F(2.0)
        x3 = prof_re[r3 + l]
        y3 = prof_im[r3 + l]
        if n_rows == 4:
            a_re = x2 if m2 else (x1 if m1 else x0)
            b_re = x3 if m2 else (x2 if m1 else x1)
            a_im = y2 if m2 else (y1 if m1 else y0)
            b_im = y3 if m2 else (y2 if m1 else y1)
        else:
            r4 = r3 + stride
            r5 = r4 + stride
            m3 = fi >= _F(3.0)
            m4 = fi >= _F(4.0)
            x4 = prof_re[r4 + l]
            y4 = prof_im[r4 + l]
            x5 = prof_re[r5 + l]
            y5 = prof_im[r5 + l]
            a_re = x4 if m4 else (x3 if m3 else (x2 if m2 else (x1 if m1 else x0)))
            b_re = x5 if m4 else (x4 if m3 else (x3 if m2 else (x2 if m1 else x1)))
            a_im = y4 if m4 else (y3 if m3 else (y2 if m2 else (y1 if m1 else y0)))
            b_im = y5 if m4 else (y4 if m3 else (y3 if m2 else (y2 if m1 else y1)))
    return a_re + fr * (b_re - a_re), a_im + fr * (b_im - a_im)


def _make_accumulate(masked: bool, n_rows: int):  # noqa: ANN202 - returns a numba dispatcher
    """Build the row-window accumulator (compile-time variants): ``masked`` zeroes lanes >= n_valid; it reads
    rows b0 .. b0 + n_rows - 1 (3, 4 or 6), so every sample must lie within [b0, b0 + n_rows - 1)."""
    if n_rows not in (3, 4, 6):
        raise ValueError(f"n_rows {n_rows}: 3, 4 or 6")

    @nb.njit(fastmath=True, cache=True, inline="always")
    def accumulate(prof_re, prof_im, row0, stride, b0, dt, dr, start, n_lanes, n_valid, i0, c0, bin_inv,
                   cyc_per_m):  # pragma: no cover - compiled
        """Sum over lanes start .. start + n_lanes of the interpolated, phase-rotated samples.

        Lane l reads pulse column row0 + l of rows b0 .. b0 + n_rows - 1 (contiguous loads, then a per-lane
        select); the caller guarantees that every lane's fractional bin lies in [b0, b0 + n_rows - 1).
        """
        r0 = _U(row0 + b0 * stride)
        fb0 = _F(b0)
        ib = _F(bin_inv)
        kc = _F(cyc_per_m)
        sr = _F(0.0)
        si = _F(0.0)
        nu = _U(n_valid)
        for l in range(_U(start), _U(start + n_lanes)):
            db = dt[l] + dr[l]
            w = (_F(1.0) if l < nu else _F(0.0)) if masked else _F(1.0)
            s_re, s_im = _interp_rows(prof_re, prof_im, r0, l, _U(stride), i0 - fb0 + db * ib, n_rows)
            t_re, t_im = _rotate(s_re, s_im, c0 + db * kc, w)
            sr += t_re
            si += t_im
        return sr, si

    return accumulate


_accumulate_3rows = _make_accumulate(False, 3)
_accumulate_3rows_masked = _make_accumulate(True, 3)
_accumulate_4rows = _make_accumulate(False, 4)
_accumulate_4rows_masked = _make_accumulate(True, 4)
_accumulate_6rows = _make_accumulate(False, 6)
_accumulate_6rows_masked = _make_accumulate(True, 6)


def _make_accumulate_pair(masked: bool):  # noqa: ANN202 - returns a numba dispatcher
    """Two channels of the same Tx in one loop, three rows each (the usual case under stripmap windows):
    one loop's fixed cost (entry, exit, sums; ~140 cycles) serves both, and the Tx deltas are loaded once."""

    @nb.njit(fastmath=True, cache=True, inline="always")
    def accumulate_pair(prof_re, prof_im, row0a, row0b, stride, b0a, b0b, dt, dra, drb, n_lanes, n_valid, i0a, i0b,
                        c0a, c0b, bin_inv, cyc_per_m):  # pragma: no cover - compiled
        """(re, im) sums of channel a and of channel b over lanes 0 .. n_lanes; see ``accumulate``."""
        ra0 = _U(row0a + b0a * stride)
        rb0 = _U(row0b + b0b * stride)
        ga = i0a - _F(b0a)
        gb = i0b - _F(b0b)
        ib = _F(bin_inv)
        kc = _F(cyc_per_m)
        sra = _F(0.0)
        sia = _F(0.0)
        srb = _F(0.0)
        sib = _F(0.0)
        nu = _U(n_valid)
        for l in range(_U(n_lanes)):
            t = dt[l]
            dba = t + dra[l]
            dbb = t + drb[l]
            w = (_F(1.0) if l < nu else _F(0.0)) if masked else _F(1.0)
            s_re, s_im = _interp_rows(prof_re, prof_im, ra0, l, _U(stride), ga + dba * ib, 3)
            t_re, t_im = _rotate(s_re, s_im, c0a + dba * kc, w)
            sra += t_re
            sia += t_im
            s_re, s_im = _interp_rows(prof_re, prof_im, rb0, l, _U(stride), gb + dbb * ib, 3)
            t_re, t_im = _rotate(s_re, s_im, c0b + dbb * kc, w)
            srb += t_re
            sib += t_im
        return sra, sia, srb, sib

    return accumulate_pair


_accumulate_pair = _make_accumulate_pair(False)
_accumulate_pair_masked = _make_accumulate_pair(True)


@nb.njit(fastmath=True, cache=True, inline="always")
def _vector_rows(g, dt, dr, at, ib, bmax, row0, stride):  # pragma: no cover - compiled
    """The four rows of the vector of 16 pulses from lane ``at``: flat index of its first lane in the lowest row
    (around its centre lane's sample, clamped to the profile) and its lanes' fractional-row offset."""
    b = min(max(int(g + (dt[at + 8] + dr[at + 8]) * ib) - 1, 0), bmax)
    return _U(row0 + b * stride + at), g - _F(b)


# The per-vector accumulators are called, not inlined into _tdbp's IR as the others are: the kernel's first compile
# takes 44 s instead of 78 s (benches/bench_compile.py), and it runs as fast (test1's focus, the 1-channel bench).
@nb.njit(fastmath=True, cache=True)
def _accumulate_vectors(prof_re, prof_im, row0, stride, n_bins, dt, dr, n_vec, n_valid, i0, c0, bin_inv,
                        cyc_per_m):  # pragma: no cover - compiled
    """Sum over lanes 0 .. n_vec * 16 (lanes >= n_valid count 0), each vector of 16 pulses reading its own four
    rows, around its centre lane's sample: chunks with any range migration (wide, squinted windows), at the
    price of a horizontal sum per vector. Lanes outside rows 0 .. n_bins - 1 of the profile add nothing."""
    ib = _F(bin_inv)
    kc = _F(cyc_per_m)
    g = _F(i0)
    sr = _F(0.0)
    si = _F(0.0)
    nu = _U(n_valid)
    bmax = n_bins - 4
    for v in range(n_vec):
        base = v * LANES
        r0, gb = _vector_rows(g, dt, dr, base, ib, bmax, row0, stride)
        ub = _U(base)
        vr = _F(0.0)
        vi = _F(0.0)
        for j in range(_U(LANES)):
            l = ub + j
            db = dt[l] + dr[l]
            fi = gb + db * ib
            w = _F(1.0) if (fi >= _F(0.0)) & (fi < _F(3.0)) & (l < nu) else _F(0.0)
            s_re, s_im = _interp_rows(prof_re, prof_im, r0, j, _U(stride), fi, 4)
            t_re, t_im = _rotate(s_re, s_im, c0 + db * kc, w)
            vr += t_re
            vi += t_im
        sr += vr
        si += vi
    return sr, si


@nb.njit(fastmath=True, cache=True, inline="always")
def _vector_lane(prof_re, prof_im, dt, dr, l, rb, j, stride, gv, ib, c0, kc):  # pragma: no cover - compiled
    """Lane j (pulse column l of the chunk) of a vector reading its own four rows from ``rb``: the interpolated,
    phase-rotated sample, unmasked."""
    db = dt[l] + dr[l]
    s_re, s_im = _interp_rows(prof_re, prof_im, rb, j, stride, gv + db * ib, 4)
    return _rotate(s_re, s_im, c0 + db * kc, _F(1.0))


@nb.njit(fastmath=True, cache=True)
def _accumulate_vectors_inside(prof_re, prof_im, row0, stride, n_bins, dt, dr, n_vec, i0, c0, bin_inv,
                               cyc_per_m):  # pragma: no cover - compiled
    """:func:`_accumulate_vectors` for a chunk of whole vectors whose samples all lie inside the profiles (no
    lane is masked) and four vectors per horizontal sum: 26 cycles per vector instead of 42 in a loop alone
    (docs/FOCUS.md, "Back-projection kernel")."""
    ib = _F(bin_inv)
    kc = _F(cyc_per_m)
    g = _F(i0)
    bmax = n_bins - 4
    us = _U(stride)
    sr = _F(0.0)
    si = _F(0.0)
    n_quad = n_vec // 4
    for v in range(n_quad):
        at = v * 4 * LANES
        rb0, g0 = _vector_rows(g, dt, dr, at, ib, bmax, row0, stride)
        rb1, g1 = _vector_rows(g, dt, dr, at + LANES, ib, bmax, row0, stride)
        rb2, g2 = _vector_rows(g, dt, dr, at + 2 * LANES, ib, bmax, row0, stride)
        rb3, g3 = _vector_rows(g, dt, dr, at + 3 * LANES, ib, bmax, row0, stride)
        ua = _U(at)
        vr = _F(0.0)
        vi = _F(0.0)
        for j in range(_U(LANES)):
            l = ua + j
            a_re, a_im = _vector_lane(prof_re, prof_im, dt, dr, l, rb0, j, us, g0, ib, c0, kc)
            b_re, b_im = _vector_lane(prof_re, prof_im, dt, dr, l + _U(LANES), rb1, j, us, g1, ib, c0, kc)
            c_re, c_im = _vector_lane(prof_re, prof_im, dt, dr, l + _U(2 * LANES), rb2, j, us, g2, ib, c0, kc)
            d_re, d_im = _vector_lane(prof_re, prof_im, dt, dr, l + _U(3 * LANES), rb3, j, us, g3, ib, c0, kc)
            vr += (a_re + b_re) + (c_re + d_re)
            vi += (a_im + b_im) + (c_im + d_im)
        sr += vr
        si += vi
    for v in range(n_quad * 4, n_vec):
        at = v * LANES
        rb, gv = _vector_rows(g, dt, dr, at, ib, bmax, row0, stride)
        ua = _U(at)
        vr = _F(0.0)
        vi = _F(0.0)
        for j in range(_U(LANES)):
            t_re, t_im = _vector_lane(prof_re, prof_im, dt, dr, ua + j, rb, j, us, gv, ib, c0, kc)
            vr += t_re
            vi += t_im
        sr += vr
        si += vi
    return sr, si


@nb.njit(cache=True)
def _accumulate_exact(prof_re, prof_im, row0, stride, n_bins, ax, ay, az, ta, ra, p, n, px, py, pz, range0,
                      bin_inv, cyc_per_m):  # pragma: no cover - compiled
    """Scalar float64 path, exact distances: for chunks the row windows cannot serve (samples past either end
    of the profiles, range migration beyond six rows where per-vector rows are not allowed)."""
    sr = 0.0
    si = 0.0
    for l in range(n):
        pp = p + l
        path = (math.sqrt((px - ax[ta, pp]) ** 2 + (py - ay[ta, pp]) ** 2 + (pz - az[ta, pp]) ** 2)
                + math.sqrt((px - ax[ra, pp]) ** 2 + (py - ay[ra, pp]) ** 2 + (pz - az[ra, pp]) ** 2))
        fi = (path - range0) * bin_inv
        if fi < 0.0:
            continue
        ib = int(fi)
        if ib + 1 >= n_bins:
            continue
        fr = fi - ib
        o = row0 + ib * stride + l
        s_re = prof_re[o] + fr * (prof_re[o + stride] - prof_re[o])
        s_im = prof_im[o] + fr * (prof_im[o + stride] - prof_im[o])
        turns = path * cyc_per_m
        ang = 2.0 * math.pi * (turns - math.floor(turns))
        cs = math.cos(ang)
        sn = math.sin(ang)
        sr += s_re * cs + s_im * sn
        si += s_im * cs - s_re * sn
    return sr, si


@nb.njit(fastmath=True, parallel=True, cache=True, nogil=True, error_model="numpy")
def _tdbp(prof_re, prof_im, n_bins, stride, ax, ay, az, ch_tx, ch_rx, range0, bin_inv, cycles_per_m,
          pix, win, order, per_task, max_chunk, out_re, out_im):  # pragma: no cover - compiled
    n_ch = ch_tx.shape[0]
    vectors_ok = n_ch <= VECTOR_ROWS_MAX_CHANNELS and n_bins >= 4  # may chunks take per-vector rows
    n_ant = ax.shape[0]
    for t in nb.prange(order.shape[0]):
        task = order[t]
        if task < 0:
            continue
        delta = np.zeros((n_ant, max_chunk + LANES), np.float32)
        r_ref = np.zeros(n_ant, np.float64)
        ch_i0 = np.zeros(n_ch, np.float64)
        ch_c0 = np.zeros(n_ch, np.float32)
        ch_b0 = np.zeros(n_ch, np.int64)
        ch_rows = np.zeros(n_ch, np.int64)
        ch_path = np.zeros(n_ch, np.int64)
        k_end = min((task + 1) * per_task, win.shape[0])
        for k in range(task * per_task, k_end):
            lo = win[k, 0]
            hi = win[k, 1]
            px = pix[k, 0]
            py = pix[k, 1]
            pz = pix[k, 2]
            acc_re = 0.0
            acc_im = 0.0
            p = lo
            chunk = max_chunk
            while p < hi:
                end = min(hi, p + chunk)
                # shorten the chunk until channel 0's samples span less than MAX_SPAN_BINS (the fast path reads up
                # to six rows) or, if they span more, 16 pulses span less than VSPAN_MAX (the per-vector rows serve
                # it). Checked on channel 0's two antennas: the others move with them and sit within centimetres.
                while True:
                    q = (p + end) // 2
                    sag = 0.0
                    span_lo = 0.0
                    span_hi = 0.0
                    h2 = (0.5 * (end - p)) ** 2
                    for a in (ch_tx[0], ch_rx[0]):
                        x = px - ax[a, q]
                        y = py - ay[a, q]
                        z = pz - az[a, q]
                        r2 = x * x + y * y + z * z
                        r = math.sqrt(r2)
                        for pe in (p, end - 1):
                            dx = np.float64(ax[a, pe]) - ax[a, q]
                            dy = np.float64(ay[a, pe]) - ay[a, q]
                            dz = np.float64(az[a, pe]) - az[a, q]
                            d = dx * (dx - 2.0 * x) + dy * (dy - 2.0 * y) + dz * (dz - 2.0 * z)
                            moved = math.sqrt(max(r2 + d, 0.0)) - r
                            if pe == p:
                                span_lo += moved
                            else:
                                span_hi += moved
                        # the closest the antenna comes within the chunk: the pixel's distance to the chord from
                        # its first to its last position (less 10 % for the path's bend)
                        sx = np.float64(ax[a, end - 1]) - ax[a, p]
                        sy = np.float64(ay[a, end - 1]) - ay[a, p]
                        sz = np.float64(az[a, end - 1]) - az[a, p]
                        s2 = sx * sx + sy * sy + sz * sz
                        wx = px - ax[a, p]
                        wy = py - ay[a, p]
                        wz = pz - az[a, p]
                        tc = min(max((wx * sx + wy * sy + wz * sz) / max(s2, 1e-30), 0.0), 1.0)
                        r_min = 0.9 * math.sqrt((wx - tc * sx) ** 2 + (wy - tc * sy) ** 2 + (wz - tc * sz) ** 2)
                        step2 = s2 / max(end - 1 - p, 1) ** 2
                        # |d2R/dp2| <= step^2 / R_min, doubled for path curvature and speed changes
                        sag += 2.0 * step2 / max(r_min, 1e-3) * h2 / 8.0
                    sag *= bin_inv
                    span = (max(0.0, span_lo, span_hi) - min(0.0, span_lo, span_hi)) * bin_inv + 2.0 * sag
                    # a span < MAX_ROWS - 2 bins keeps every sample within rows floor(lowest) + 0 .. MAX_ROWS - 1
                    vec = False
                    if span < MAX_SPAN_BINS or end - p <= LANES:
                        break
                    if vectors_ok:
                        # too much migration for six rows: per-vector rows serve it if 16 pulses span little
                        vspan = 0.0
                        for pe0 in (p, end - LANES):
                            rs = 0.0
                            for a in (ch_tx[0], ch_rx[0]):
                                rs += (math.sqrt((px - ax[a, pe0 + LANES - 1]) ** 2 + (py - ay[a, pe0 + LANES - 1]) ** 2
                                                 + (pz - az[a, pe0 + LANES - 1]) ** 2)
                                       - math.sqrt((px - ax[a, pe0]) ** 2 + (py - ay[a, pe0]) ** 2
                                                   + (pz - az[a, pe0]) ** 2))
                            vspan = max(vspan, abs(rs) * bin_inv)
                        if vspan < VSPAN_MAX:
                            vec = True
                            break
                    # the span grows about linearly with the chunk: jump to the length that fits
                    shrink = 0.85 * min(MAX_SPAN_BINS / max(span, 1e-12), 0.5)
                    end = p + max(LANES, int((end - p) * shrink) // LANES * LANES)
                # the next chunk's first guess: the length this one's margin allows (the span grows about linearly
                # with it), at most 1.4 x; a guess that fails costs a second check (~200 cycles)
                room = 0.9 * min(1.4 if vec else MAX_SPAN_BINS / max(span, 1e-12), 1.4)
                chunk = min(max_chunk, max(2 * LANES, int((end - p) * room)))
                n = end - p
                n_pad = (n + LANES - 1) // LANES * LANES
                for a in range(n_ant):
                    x = px - ax[a, q]
                    y = py - ay[a, q]
                    z = pz - az[a, q]
                    r2 = x * x + y * y + z * z
                    r_ref[a] = math.sqrt(r2)
                    _antenna_deltas(ax, ay, az, a, p, q, n_pad, np.float32(-2.0 * x), np.float32(-2.0 * y),
                                    np.float32(-2.0 * z), np.float32(r_ref[a]), np.float32(r2), delta[a])
                # per channel: reference phase, fractional bin, the rows its samples touch and the path it takes
                # (0: entirely past the profile, 1: row windows, 2: exact, 3: per-vector rows, 4: the same for whole
                # vectors none of whose rows meet the profile's ends, unmasked)
                full = n == n_pad
                for c in range(n_ch):
                    ta = ch_tx[c]
                    ra = ch_rx[c]
                    rb = r_ref[ta] + r_ref[ra]
                    i0 = (rb - range0[c]) * bin_inv
                    turns = rb * cycles_per_m
                    ch_c0[c] = np.float32(turns - math.floor(turns))
                    ch_i0[c] = i0
                    # rows touched: the fractional bin varies smoothly along the chunk; between its values at
                    # the ends and the centre it deviates by at most sag (|R''| <= step^2 / R per antenna)
                    i_first = i0 + (delta[ta, 0] + delta[ra, 0]) * bin_inv
                    i_last = i0 + (delta[ta, n - 1] + delta[ra, n - 1]) * bin_inv
                    b0 = int(math.floor(min(i0, i_first, i_last) - sag))
                    top = max(i0, i_first, i_last) + sag
                    rows = 3 if top < b0 + 2 else (4 if top < b0 + 3 else (6 if top < b0 + 5 else n_bins + 1))
                    ch_b0[c] = b0
                    ch_rows[c] = rows
                    if b0 >= n_bins - 1 or top < 0.0:
                        ch_path[c] = 0  # the far edge of the swath: nothing to add
                    elif vec:
                        ch_path[c] = 4 if full and b0 >= 1 and top < n_bins - 3 else 3
                    elif b0 >= 0 and b0 + rows <= n_bins:
                        ch_path[c] = 1
                    else:
                        ch_path[c] = 2
                c = 0
                while c < n_ch:
                    ta = ch_tx[c]
                    ra = ch_rx[c]
                    row0 = c * n_bins * stride + p
                    b0 = ch_b0[c]
                    rows = ch_rows[c]
                    i0 = ch_i0[c]
                    c0 = ch_c0[c]
                    d = c + 1
                    if (ch_path[c] == 1 and rows == 3 and d < n_ch and ch_path[d] == 1 and ch_rows[d] == 3
                            and ch_tx[d] == ta):
                        if full:
                            sr, si, sr2, si2 = _accumulate_pair(
                                prof_re, prof_im, row0, row0 + n_bins * stride, stride, b0, ch_b0[d], delta[ta],
                                delta[ra], delta[ch_rx[d]], n, n, np.float32(i0), np.float32(ch_i0[d]), c0, ch_c0[d],
                                bin_inv, cycles_per_m)
                        else:
                            sr, si, sr2, si2 = _accumulate_pair_masked(
                                prof_re, prof_im, row0, row0 + n_bins * stride, stride, b0, ch_b0[d], delta[ta],
                                delta[ra], delta[ch_rx[d]], n_pad, n, np.float32(i0), np.float32(ch_i0[d]), c0,
                                ch_c0[d], bin_inv, cycles_per_m)
                        acc_re += sr + sr2
                        acc_im += si + si2
                        c += 2
                        continue
                    if ch_path[c] == 4:
                        sr, si = _accumulate_vectors_inside(prof_re, prof_im, row0, stride, n_bins, delta[ta],
                                                            delta[ra], n // LANES, np.float32(i0), c0, bin_inv,
                                                            cycles_per_m)
                        acc_re += sr
                        acc_im += si
                    elif ch_path[c] == 3:
                        sr, si = _accumulate_vectors(prof_re, prof_im, row0, stride, n_bins, delta[ta], delta[ra],
                                                     n_pad // LANES, n, np.float32(i0), c0, bin_inv, cycles_per_m)
                        acc_re += sr
                        acc_im += si
                    elif ch_path[c] == 1:
                        # one loop per channel: a separate tail call costs more than masking every lane
                        if rows == 3:  # usual under stripmap windows
                            if full:
                                sr, si = _accumulate_3rows(prof_re, prof_im, row0, stride, b0, delta[ta], delta[ra], 0,
                                                           n, n, np.float32(i0), c0, bin_inv, cycles_per_m)
                            else:
                                sr, si = _accumulate_3rows_masked(prof_re, prof_im, row0, stride, b0, delta[ta],
                                                                  delta[ra], 0, n_pad, n, np.float32(i0), c0, bin_inv,
                                                                  cycles_per_m)
                        elif rows == 4:
                            if full:
                                sr, si = _accumulate_4rows(prof_re, prof_im, row0, stride, b0, delta[ta], delta[ra], 0,
                                                           n, n, np.float32(i0), c0, bin_inv, cycles_per_m)
                            else:
                                sr, si = _accumulate_4rows_masked(prof_re, prof_im, row0, stride, b0, delta[ta],
                                                                  delta[ra], 0, n_pad, n, np.float32(i0), c0, bin_inv,
                                                                  cycles_per_m)
                        elif full:  # wide windows at strong squint: longer chunks for two more rows
                            sr, si = _accumulate_6rows(prof_re, prof_im, row0, stride, b0, delta[ta], delta[ra], 0,
                                                       n, n, np.float32(i0), c0, bin_inv, cycles_per_m)
                        else:
                            sr, si = _accumulate_6rows_masked(prof_re, prof_im, row0, stride, b0, delta[ta], delta[ra],
                                                              0, n_pad, n, np.float32(i0), c0, bin_inv, cycles_per_m)
                        acc_re += sr
                        acc_im += si
                    elif ch_path[c] == 2:
                        sr, si = _accumulate_exact(prof_re, prof_im, row0, stride, n_bins, ax, ay, az, ta, ra, p, n,
                                                   px, py, pz, range0[c], bin_inv, cycles_per_m)
                        acc_re += sr
                        acc_im += si
                    c += 1
                p = end
            out_re[k] += acc_re
            out_im[k] += acc_im


@dataclass
class PulseBlock:
    """Range-compressed pulses laid out for the kernel (planar float32, pulses contiguous, zero padded).

    ``re``/``im`` (C, B, P + LANES): channel c, bistatic-range bin b (at path ``range0_m[c] + b * bin_m``,
    metres Tx -> pixel -> Rx), pulse p. ``antennas`` (A, P + LANES, 3) float32: phase centre of antenna a
    at pulse p, ENU metres relative to ``origin`` (keeps float32 positions exact to ~0.1 um over a block
    of a few metres). ``channels`` (C, 2): the (Tx, Rx) antenna indices of each channel. Each sample is
    multiplied by ``exp(-2j pi cycles_per_m R)``, R the exact bistatic path.
    """

    re: NDArray[np.float32]
    im: NDArray[np.float32]
    antennas: NDArray[np.float32]
    origin: NDArray[np.float64]
    channels: NDArray[np.int64]
    range0_m: NDArray[np.float64]
    bin_m: float
    cycles_per_m: float
    n_pulses: int

    @classmethod
    def empty(cls, n_channels: int, n_bins: int, n_pulses: int, n_antennas: int, *, channels: ArrayLike,
              range0_m: ArrayLike | float, bin_m: float, cycles_per_m: float) -> PulseBlock:
        """A zeroed block to be filled in place (``re``/``im`` per channel, then :meth:`set_antennas`)."""
        stride = n_pulses + LANES
        ch = np.ascontiguousarray(np.asarray(channels, dtype=np.int64).reshape(n_channels, 2))
        r0 = np.broadcast_to(np.asarray(range0_m, dtype=np.float64), (n_channels,)).copy()
        shape = (n_channels, n_bins, stride)
        ant = np.zeros((n_antennas, stride, 3), np.float32)
        return cls(np.zeros(shape, np.float32), np.zeros(shape, np.float32), ant, np.zeros(3), ch, r0, float(bin_m),
                   float(cycles_per_m), n_pulses)

    @classmethod
    def from_profiles(cls, profiles: ArrayLike, antennas: ArrayLike, channels: ArrayLike, *,
                      range0_m: ArrayLike | float, bin_m: float, cycles_per_m: float) -> PulseBlock:
        """From complex profiles (C, B, P) and antenna positions (A, P, 3) (ENU m, float64)."""
        prof = np.asarray(profiles)
        n_ch, n_bins, n_pulse = prof.shape
        ant = np.asarray(antennas, dtype=np.float64)
        block = cls.empty(n_ch, n_bins, n_pulse, ant.shape[0], channels=channels, range0_m=range0_m, bin_m=bin_m,
                          cycles_per_m=cycles_per_m)
        block.re[:, :, :n_pulse] = prof.real
        block.im[:, :, :n_pulse] = prof.imag
        block.set_antennas(ant)
        return block

    def set_antennas(self, antennas: ArrayLike) -> None:
        """Antenna phase centres (A, P, 3), ENU m (float64); the origin becomes their centre."""
        ant = np.asarray(antennas, dtype=np.float64)
        n = self.n_pulses
        self.origin = ant[:, n // 2].mean(axis=0)
        self.antennas[:, :n] = ant - self.origin
        self.antennas[:, n:] = self.antennas[:, n - 1: n]


def backproject_block(block: PulseBlock, pixels: ArrayLike, windows: ArrayLike, *,
                      out: NDArray[np.complex64] | None = None,
                      max_chunk: int = DEFAULT_MAX_CHUNK) -> NDArray[np.complex64]:
    """Back-project a block onto ``pixels`` (N, 3) ENU m, pulses ``windows`` (N, 2) [lo, hi) of the block.

    Returns (or adds into ``out``) the (N,) complex64 sums over the windows' pulses and all channels.
    """
    pix = np.ascontiguousarray(np.asarray(pixels, dtype=np.float64).reshape(-1, 3) - block.origin)
    win = np.ascontiguousarray(np.clip(np.asarray(windows, dtype=np.int64).reshape(-1, 2), 0, block.n_pulses))
    n = len(pix)
    if out is None:
        out = np.zeros(n, np.complex64)
    if n == 0:
        return out
    out_re = np.zeros(n, np.float32)
    out_im = np.zeros(n, np.float32)
    n_threads = nb.get_num_threads()
    per_task = max(1, min(256, n // (64 * n_threads) + 1))
    order = _balanced_order(win, n_threads, per_task)
    n_ch, n_bins, stride = block.re.shape
    ant = block.antennas
    args = (block.re.reshape(-1), block.im.reshape(-1), n_bins, stride, np.ascontiguousarray(ant[..., 0]),
            np.ascontiguousarray(ant[..., 1]), np.ascontiguousarray(ant[..., 2]), block.channels[:, 0].copy(),
            block.channels[:, 1].copy(), block.range0_m, 1.0 / block.bin_m, block.cycles_per_m, pix, win, order,
            per_task, int(max_chunk), out_re, out_im)
    compile_in_child(_tdbp, args)  # the same machine code in every process (autosar_cli.kernel_cache)
    _tdbp(*args)
    out += out_re + 1j * out_im
    return out


def backproject(profiles: ArrayLike, antennas: ArrayLike, channels: ArrayLike, pixels: ArrayLike,
                windows: ArrayLike, *, range0_m: ArrayLike | float, bin_m: float, cycles_per_m: float,
                out: NDArray[np.complex64] | None = None, max_chunk: int = DEFAULT_MAX_CHUNK) -> NDArray[np.complex64]:
    """Back-project complex profiles (C, B, P) seen by antennas (A, P, 3) onto pixels; see :class:`PulseBlock`."""
    block = PulseBlock.from_profiles(profiles, antennas, channels, range0_m=range0_m, bin_m=bin_m,
                                     cycles_per_m=cycles_per_m)
    return backproject_block(block, pixels, windows, out=out, max_chunk=max_chunk)


def _balanced_order(win: NDArray[np.int64], n_threads: int, per_task: int) -> NDArray[np.int64]:
    """Task order so that prange's equal contiguous shares get equal work (pixels' pulse counts differ a lot).

    Tasks (contiguous runs of ``per_task`` pixels) are sorted by work and dealt snake-wise to the thread
    shares; -1 pads the shares to equal length (the kernel skips it).
    """
    n = len(win)
    starts = np.arange(0, n, per_task)
    work = np.add.reduceat(np.maximum(win[:, 1] - win[:, 0], 0) + 8, starts)
    ranked = np.argsort(-work, kind="stable")
    n_task = len(starts)
    share = (n_task + n_threads - 1) // n_threads
    rnd, pos = np.divmod(np.arange(n_task), n_threads)
    thread = np.where(rnd % 2 == 0, pos, n_threads - 1 - pos)
    order = np.full(share * n_threads, -1, np.int64)
    order[thread * share + rnd] = ranked
    return order
