"""Batched zero-padded FFT for range compression, written straight into the kernel's (bin, pulse) layout.

A Stockham FFT (decimation in frequency, radices 4, 3, 5 and 2) whose SIMD lanes run over pulses: every
butterfly is a contiguous loop over ``s * BATCH`` floats of (sample, pulse) planes, with no shuffles. It
works on batches of ``BATCH`` pulses, so the working set (four 2160 x 32 float32 planes, ~1.1 MB) stays in
the L2 cache. Each batch's int16 I/Q samples are transposed into a (sample, pulse) tile of 32-bit words on the
way in; the zero padding is pruned (the first pass, of radix ``upsample``, has a single non-zero input per
butterfly and is a twiddle multiply); the last pass writes into a staging area of up to ``GROUP`` batches,
which is then copied, times the reference ramp, into the planar, pulse-contiguous rows back-projection reads.
All scratch memory is one buffer per thread, reused.

Measured on 512-pulse blocks of test1 (8 channels, 540 samples, x4 padding, docs/FOCUS.md): 2 threads, 22-28 ms
per block against 45-65 ms for the first version of this module (written straight into the rows from each
32-pulse batch, with numpy's transposing loads) and ~61 ms for scipy's FFT + ramp + transposes; one thread,
0.47-0.49 of the first version's time per channel (paired rounds in one process). Its output equals scipy's
to -137 dB.

Array in, array out; :mod:`autosar_cli.sar.range_compression` decides when to use it.
"""

from __future__ import annotations

import functools
import math
import threading

import numba as nb
import numpy as np
from numpy.typing import NDArray

BATCH = 32  #: pulses per batch: 0.76 of scipy's time on the block above, against 0.81 with 16 and 0.90 with 64
#: batches staged before their rows are written (at most): 32-pulse pieces of 2160 rows took ~3x as long to write
#: as 256-pulse ones; whole 512-pulse rows (4.4 MB per plane, with the work buffer reused) beat 256-pulse pieces by
#: 6-9 % and 128-pulse ones by 15-26 % (paired rounds on test1 blocks, 1 and 2 threads)
GROUP = 16
RADICES = (4, 3, 5, 2)

_F = nb.float32
_U = nb.uint64  # unsigned indices: numba's negative-index wraparound would keep the loops from vectorising


@functools.lru_cache(maxsize=8)
def radices(n: int) -> tuple[int, ...] | None:
    """The radix of each pass for an n-point FFT, or None if n has a prime factor above 5."""
    out = []
    for r in RADICES:
        while n % r == 0:
            out.append(r)
            n //= r
    return tuple(out) if n == 1 else None


@functools.lru_cache(maxsize=8)
def fft_plan(n: int, upsample: int) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float32],
                                           NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
    """Radices, twiddle offsets and twiddles (real, imaginary) of the passes of an n-point FFT after the pruned
    first pass of an (n * upsample)-point one, whose twiddles come last. Twiddles in float64, then rounded."""
    rad = radices(n)
    if rad is None:
        raise ValueError(f"{n}-point FFT: a prime factor above 5")
    p = np.arange(n)[:, None]
    first = np.exp(-2j * np.pi * p * np.arange(upsample)[None, :] / (n * upsample)).ravel()
    tw, offsets, off, length = [], [], 0, n
    for r in rad:
        m = length // r
        w = np.exp(-2j * np.pi * np.arange(m)[:, None] * np.arange(1, r)[None, :] / length).ravel()
        tw.append(w)
        offsets.append(off)
        off += w.size
        length = m
    tw_all = np.concatenate(tw) if tw else np.zeros(0, complex)
    return (np.array(rad, np.int64), np.array(offsets, np.int64), tw_all.real.astype(np.float32),
            tw_all.imag.astype(np.float32), first.real.astype(np.float32), first.imag.astype(np.float32))


# The passes read x[q + s (p + r m)] and write y[q + s (R p + k)] (Stockham), with q and the pulse together
# forming the contiguous inner loop. ``ids`` is the identity: reading p from it hides p's affine form from
# LLVM, which otherwise hoists the vector loop's overlap checks out of the p loop, over ranges in which the
# output streams do overlap, and always runs the scalar loop (measured 3x slower).

@nb.njit(fastmath=True, cache=True, nogil=True)
def _pass2(xr, xi, yr, yi, s, m, nb_, twr, twi, off, ids):  # pragma: no cover - compiled
    sb = _U(s * nb_)
    for p_ in range(m):
        p = ids[p_]
        w1r = twr[off + p]
        w1i = twi[off + p]
        i0 = _U(p * sb)
        i1 = _U((p + m) * sb)
        o0 = _U(2 * p * sb)
        o1 = o0 + sb
        for j in range(sb):
            ar = xr[i0 + j]
            ai = xi[i0 + j]
            br = xr[i1 + j]
            bi = xi[i1 + j]
            yr[o0 + j] = ar + br
            yi[o0 + j] = ai + bi
            dr = ar - br
            di = ai - bi
            yr[o1 + j] = dr * w1r - di * w1i
            yi[o1 + j] = dr * w1i + di * w1r


@nb.njit(fastmath=True, cache=True, nogil=True)
def _pass3(xr, xi, yr, yi, s, m, nb_, twr, twi, off, ids):  # pragma: no cover - compiled
    sb = _U(s * nb_)
    h = _F(-0.5)
    s3 = _F(math.sqrt(3.0) / 2)
    for p_ in range(m):
        p = ids[p_]
        w1r = twr[off + 2 * p]
        w1i = twi[off + 2 * p]
        w2r = twr[off + 2 * p + 1]
        w2i = twi[off + 2 * p + 1]
        i0 = _U(p * sb)
        i1 = _U((p + m) * sb)
        i2 = _U((p + 2 * m) * sb)
        o0 = _U(3 * p * sb)
        o1 = o0 + sb
        o2 = o1 + sb
        for j in range(sb):
            a0r = xr[i0 + j]
            a0i = xi[i0 + j]
            a1r = xr[i1 + j]
            a1i = xi[i1 + j]
            a2r = xr[i2 + j]
            a2i = xi[i2 + j]
            t1r = a1r + a2r
            t1i = a1i + a2i
            t2r = a0r + h * t1r
            t2i = a0i + h * t1i
            t3r = s3 * (a1i - a2i)  # -i sin(2 pi / 3) (a1 - a2)
            t3i = -s3 * (a1r - a2r)
            yr[o0 + j] = a0r + t1r
            yi[o0 + j] = a0i + t1i
            y1r = t2r + t3r
            y1i = t2i + t3i
            y2r = t2r - t3r
            y2i = t2i - t3i
            yr[o1 + j] = y1r * w1r - y1i * w1i
            yi[o1 + j] = y1r * w1i + y1i * w1r
            yr[o2 + j] = y2r * w2r - y2i * w2i
            yi[o2 + j] = y2r * w2i + y2i * w2r


@nb.njit(fastmath=True, cache=True, nogil=True)
def _pass4(xr, xi, yr, yi, s, m, nb_, twr, twi, off, ids):  # pragma: no cover - compiled
    sb = _U(s * nb_)
    for p_ in range(m):
        p = ids[p_]
        w1r = twr[off + 3 * p]
        w1i = twi[off + 3 * p]
        w2r = twr[off + 3 * p + 1]
        w2i = twi[off + 3 * p + 1]
        w3r = twr[off + 3 * p + 2]
        w3i = twi[off + 3 * p + 2]
        i0 = _U(p * sb)
        i1 = _U((p + m) * sb)
        i2 = _U((p + 2 * m) * sb)
        i3 = _U((p + 3 * m) * sb)
        o0 = _U(4 * p * sb)
        o1 = o0 + sb
        o2 = o1 + sb
        o3 = o2 + sb
        for j in range(sb):
            a0r = xr[i0 + j]
            a0i = xi[i0 + j]
            a1r = xr[i1 + j]
            a1i = xi[i1 + j]
            a2r = xr[i2 + j]
            a2i = xi[i2 + j]
            a3r = xr[i3 + j]
            a3i = xi[i3 + j]
            t0r = a0r + a2r
            t0i = a0i + a2i
            t1r = a0r - a2r
            t1i = a0i - a2i
            t2r = a1r + a3r
            t2i = a1i + a3i
            t3r = a1i - a3i  # -i (a1 - a3)
            t3i = a3r - a1r
            yr[o0 + j] = t0r + t2r
            yi[o0 + j] = t0i + t2i
            y1r = t1r + t3r
            y1i = t1i + t3i
            y2r = t0r - t2r
            y2i = t0i - t2i
            y3r = t1r - t3r
            y3i = t1i - t3i
            yr[o1 + j] = y1r * w1r - y1i * w1i
            yi[o1 + j] = y1r * w1i + y1i * w1r
            yr[o2 + j] = y2r * w2r - y2i * w2i
            yi[o2 + j] = y2r * w2i + y2i * w2r
            yr[o3 + j] = y3r * w3r - y3i * w3i
            yi[o3 + j] = y3r * w3i + y3i * w3r


@nb.njit(fastmath=True, cache=True, nogil=True)
def _pass5_pair(xr, xi, yr, yi, sb, i0, i1, i2, i3, i4, oa, ob, ca, cb, sa, sb_, war, wai, wbr,
                wbi):  # pragma: no cover - compiled
    """Two outputs of the radix-5 butterflies, a = t - i u and b = t + i u, twiddled by wa and wb, where
    t = a0 + ca (a1 + a4) + cb (a2 + a3) and u = sa (a1 - a4) + sb_ (a2 - a3)."""
    for j in range(sb):
        b1r = xr[i1 + j] + xr[i4 + j]
        b1i = xi[i1 + j] + xi[i4 + j]
        b2r = xr[i2 + j] + xr[i3 + j]
        b2i = xi[i2 + j] + xi[i3 + j]
        d1r = xr[i1 + j] - xr[i4 + j]
        d1i = xi[i1 + j] - xi[i4 + j]
        d2r = xr[i2 + j] - xr[i3 + j]
        d2i = xi[i2 + j] - xi[i3 + j]
        tr = xr[i0 + j] + ca * b1r + cb * b2r
        ti = xi[i0 + j] + ca * b1i + cb * b2i
        ur = sa * d1r + sb_ * d2r
        ui = sa * d1i + sb_ * d2i
        yar = tr + ui
        yai = ti - ur
        ybr = tr - ui
        ybi = ti + ur
        yr[oa + j] = yar * war - yai * wai
        yi[oa + j] = yar * wai + yai * war
        yr[ob + j] = ybr * wbr - ybi * wbi
        yi[ob + j] = ybr * wbi + ybi * wbr


@nb.njit(fastmath=True, cache=True, nogil=True)
def _pass5(xr, xi, yr, yi, s, m, nb_, twr, twi, off, ids):  # pragma: no cover - compiled
    sb = _U(s * nb_)
    c1 = _F(math.cos(2 * math.pi / 5))
    c2 = _F(math.cos(4 * math.pi / 5))
    s1 = _F(math.sin(2 * math.pi / 5))
    s2 = _F(math.sin(4 * math.pi / 5))
    for p_ in range(m):
        p = ids[p_]
        w = off + 4 * p
        i0 = _U(p * sb)
        i1 = _U((p + m) * sb)
        i2 = _U((p + 2 * m) * sb)
        i3 = _U((p + 3 * m) * sb)
        i4 = _U((p + 4 * m) * sb)
        o0 = _U(5 * p * sb)
        o1 = o0 + sb
        o2 = o1 + sb
        o3 = o2 + sb
        o4 = o3 + sb
        # three loops with fewer output streams each: one loop writing all ten needs more runtime overlap checks
        # than LLVM's vectoriser allows, and ran scalar (measured 3x slower)
        for j in range(sb):
            yr[o0 + j] = xr[i0 + j] + xr[i1 + j] + xr[i2 + j] + xr[i3 + j] + xr[i4 + j]
            yi[o0 + j] = xi[i0 + j] + xi[i1 + j] + xi[i2 + j] + xi[i3 + j] + xi[i4 + j]
        _pass5_pair(xr, xi, yr, yi, sb, i0, i1, i2, i3, i4, o1, o4, c1, c2, s1, s2, twr[w], twi[w], twr[w + 3],
                    twi[w + 3])
        _pass5_pair(xr, xi, yr, yi, sb, i0, i1, i2, i3, i4, o2, o3, c2, c1, s2, -s1, twr[w + 1], twi[w + 1],
                    twr[w + 2], twi[w + 2])


@nb.njit(fastmath=True, cache=True, nogil=True)
def _compress(iq, first_re, first_im, rad, offs, twr, twi, ramp_re, ramp_im, out_re, out_im, nb_, group,
              work, tile):  # pragma: no cover - compiled
    """iq (P, N) int32, any strides: each pulse's I/Q samples, I in the low 16 bits (:func:`_packed_iq`);
    tile (N * nb_,) int32: room for one batch of them. first_* (N * up,): the pruned
    pass's twiddles times the taper; rad, offs, twr, twi: :func:`fft_plan`; ramp_* (N * up,): per bin.
    out_* (N * up, >= n_pulses): (bin, pulse) rows, first n_pulses columns written. ``group`` batches are
    staged before they are copied into the rows (see ``GROUP``). ``work``: :func:`workspace_size` floats."""
    n_pulses, n = iq.shape
    up = first_re.size // n
    n_fft = n * up
    n_batch = (n_pulses + nb_ - 1) // nb_
    plane = n_fft * nb_
    ids = np.arange(n_fft)
    ar = work[:plane]
    ai = work[plane: 2 * plane]
    br = work[2 * plane: 3 * plane]
    bi = work[3 * plane: 4 * plane]
    stage_r = work[4 * plane: (4 + group) * plane]
    stage_i = work[(4 + group) * plane: (4 + 2 * group) * plane]
    # one sample of the batch's pulses, decoded
    xr_row = work[(4 + 2 * group) * plane: (4 + 2 * group) * plane + nb_]
    xi_row = work[(4 + 2 * group) * plane + nb_: (4 + 2 * group) * plane + 2 * nb_]
    bu = _U(nb_)
    n_st = rad.size
    for ib in range(n_batch):
        p0 = ib * nb_
        g = ib % group
        dst_r = stage_r[g * plane: (g + 1) * plane]
        dst_i = stage_i[g * plane: (g + 1) * plane]
        # the batch as a (sample, pulse) tile of I/Q words, zero beyond the last pulse: a transpose within the L1/L2
        # cache, one 32-bit store per sample (0.49 against 0.72 ms per channel block for I and Q apart, measured)
        n_in = min(nb_, n_pulses - p0)
        if n_in < nb_:
            tile[:] = 0
        for b in range(n_in):
            pulse = iq[p0 + b]
            for k in range(n):
                tile[k * nb_ + b] = pulse[k]
        # pruned first pass: y[up k + r] = x[k] w^(k r) (first_* carry the taper too); the other up - 1 inputs of
        # each butterfly are zeros
        yr = ar if n_st > 0 else dst_r
        yi = ai if n_st > 0 else dst_i
        for k in range(n):
            i = _U(k * nb_)
            for b in range(bu):
                word = tile[i + b]
                lo = word & 0xFFFF
                xr_row[b] = _F(lo - ((lo & 0x8000) << 1))  # the low half, sign-extended
                xi_row[b] = _F(word >> 16)
            for r in range(up):
                wr = first_re[k * up + r]
                wi = first_im[k * up + r]
                o = _U((up * k + r) * nb_)
                for b in range(bu):
                    xr_ = xr_row[b]
                    xi_ = xi_row[b]
                    yr[o + b] = xr_ * wr - xi_ * wi
                    yi[o + b] = xr_ * wi + xi_ * wr
        s = up
        length = n
        src = 0
        for st in range(n_st):
            r = rad[st]
            m = length // r
            if src == 0:
                xr, xi, yr, yi = ar, ai, br, bi
            else:
                xr, xi, yr, yi = br, bi, ar, ai
            if st == n_st - 1:  # the last pass writes into the staging slot
                yr = dst_r
                yi = dst_i
            if r == 4:
                _pass4(xr, xi, yr, yi, s, m, nb_, twr, twi, offs[st], ids)
            elif r == 3:
                _pass3(xr, xi, yr, yi, s, m, nb_, twr, twi, offs[st], ids)
            elif r == 5:
                _pass5(xr, xi, yr, yi, s, m, nb_, twr, twi, offs[st], ids)
            else:
                _pass2(xr, xi, yr, yi, s, m, nb_, twr, twi, offs[st], ids)
            src = 1 - src
            s *= r
            length = m
        if g < group - 1 and ib < n_batch - 1:
            continue
        # the staged batches, times the reference ramp, into the (bin, pulse) rows (the padding pulses of the last
        # batch are dropped): group * nb_ pulses of each row at a time
        g0 = ib - g
        for k in range(n_fft):
            rr = ramp_re[k]
            ri = ramp_im[k]
            row_r = out_re[k]
            row_i = out_im[k]
            for h in range(g + 1):
                q0 = (g0 + h) * nb_
                n_out = _U(min(nb_, n_pulses - q0))
                base = _U(h * plane + k * nb_)
                for b in range(n_out):
                    vr = stage_r[base + b]
                    vi = stage_i[base + b]
                    row_r[_U(q0) + b] = vr * rr - vi * ri
                    row_i[_U(q0) + b] = vr * ri + vi * rr


def workspace_size(n: int, upsample: int, group: int) -> int:
    """Float32 elements of :func:`_compress`'s work buffer for n samples, x upsample, ``group`` staged batches,
    followed by the batch's (sample, pulse) tile of I/Q words (n * BATCH)."""
    return (4 + 2 * group) * n * upsample * BATCH + 2 * BATCH + n * BATCH


_local = threading.local()


def _workspace(size: int) -> NDArray[np.float32]:
    """This thread's work buffer, reused across calls, its start aligned to 4 KB. A fresh one per call varied
    from call to call with where the allocator put its pieces, by up to 30 % (measured); reuse also saves
    the page faults of ~5 MB per channel block."""
    buf = getattr(_local, "buf", None)
    if buf is None or buf.size < size + 1024:
        buf = _local.buf = np.empty(size + 1024, np.float32)
    a0 = (-(buf.ctypes.data // 4)) % 1024
    return buf[a0: a0 + size]


def _packed_iq(raw: NDArray[np.int16]) -> NDArray[np.int32]:
    """(P, N, 2) int16 I/Q as (P, N) int32 words, I in the low 16 bits: a view where the pairs are adjacent and
    aligned on a little-endian host (focus's raw cubes), else a packed copy."""
    if (np.little_endian and raw.dtype == np.int16 and raw.strides[-1] == 2 and raw.strides[-2] % 4 == 0
            and raw.strides[0] % 4 == 0 and raw.ctypes.data % 4 == 0):
        return raw.view(np.int32)[..., 0]
    i = np.asarray(raw[..., 0], np.int32) & 0xFFFF
    return i | (np.asarray(raw[..., 1], np.int32) << 16)


def compress_iq(raw: NDArray[np.int16], taper: NDArray[np.float32], ramp: NDArray[np.complex64], upsample: int,
                out_re: NDArray[np.float32], out_im: NDArray[np.float32]) -> None:
    """Range-compress int16 I/Q pairs ``raw`` (P, N, 2) (any strides) into ``out_re``/``out_im`` (N * upsample,
    >= P) float32, bin-major with pulses contiguous: ``FFT_{N up}(taper * (I + jQ), zero-padded) * ramp``.

    ``taper`` (N,) float32; ``ramp`` (N * upsample,) complex, applied per compressed bin. N must factor into
    2, 3 and 5 (:func:`radices`).
    """
    n = raw.shape[1]
    group = max(1, min(GROUP, -(-raw.shape[0] // BATCH)))
    rad, offs, twr, twi, first_re, first_im = fft_plan(n, upsample)
    # the taper rides on the first pass's twiddles (sample k's row of them): no pass of its own
    w = np.repeat(np.asarray(taper, np.float32), upsample)
    ramp = np.asarray(ramp)
    work = _workspace(workspace_size(n, upsample, group))
    tile = work[work.size - n * BATCH:].view(np.int32)
    _compress(_packed_iq(raw), first_re * w, first_im * w, rad, offs, twr, twi,
              np.ascontiguousarray(ramp.real, np.float32), np.ascontiguousarray(ramp.imag, np.float32), out_re, out_im,
              BATCH, group, work, tile)
