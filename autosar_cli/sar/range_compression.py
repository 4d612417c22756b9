"""FMCW range compression (paper Sec. III-A): taper, zero-padded FFT over fast time, phase referenced
to the centre of the ADC window, residual-video-phase (RVP) removal.

Beat signal of a point at two-way delay tau, fast time t from the first ADC sample:
``s(t) = exp(j 2 pi (f0 tau + K tau t - K tau^2 / 2))``. After compression the sample at beat
frequency ``f = K tau`` carries ``exp(j 2 pi (f0 tau + K tau t_c))`` with t_c the window centre: the
RVP term ``-pi K tau^2 = -pi f^2 / K`` is removed here, so back-projection only has to undo
``2 pi (f0 + K t_c) tau``. Bin k of an ``N * upsample`` FFT is the beat frequency ``k fs / (N up)``,
i.e. the bistatic path length ``c k fs / (K N up)`` (Tx -> target -> Rx, metres).

Array in, array out; no I/O.
"""

from __future__ import annotations

import functools

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray

from autosar_cli.config import SPEED_OF_LIGHT
from autosar_cli.sar.range_fft import compress_iq, radices


def iq_to_complex(raw: NDArray[np.int16]) -> NDArray[np.complex64]:
    """int16 I/Q pairs (..., N, 2) -> complex64 (..., N)."""
    raw = np.asarray(raw)
    out = np.empty(raw.shape[:-1], dtype=np.complex64)
    out.real = raw[..., 0]
    out.imag = raw[..., 1]
    return out


_NUMPY_WINDOWS = {"hann": np.hanning, "hanning": np.hanning, "hamming": np.hamming, "blackman": np.blackman,
                  "bartlett": np.bartlett}


def taper(name: str, n: int) -> NDArray[np.float64]:
    """Fast-time window of length n ("hann", "hamming", "blackman", "rect", or any scipy window name)."""
    if name in ("rect", "none", "boxcar"):
        return np.ones(n)
    if name in _NUMPY_WINDOWS:  # symmetric, as scipy's fftbins=False; scipy.signal costs ~0.6 s to import
        return _NUMPY_WINDOWS[name](n)
    import scipy.signal

    return scipy.signal.get_window(name, n, fftbins=False)


@functools.lru_cache(maxsize=8)
def reference_ramp(n: int, nfft: int, sample_rate_hz: float, slope_hz_per_s: float) -> NDArray[np.complex64]:
    """Window-centre reference and RVP removal (nfft,) for each compressed bin of ``n`` samples, in one float64
    phase ramp (read-only: cached)."""
    k = np.arange(nfft)
    f = k * sample_rate_hz / nfft
    ramp = np.exp(1j * (np.pi * k * (n - 1) / nfft + np.pi * f**2 / slope_hz_per_s)).astype(np.complex64)
    ramp.flags.writeable = False
    return ramp


@functools.lru_cache(maxsize=8)
def _taper32(name: str, n: int) -> NDArray[np.float32]:
    return taper(name, n).astype(np.float32)


@nb.njit(cache=True, nogil=True)
def _load_iq_tapered(raw, w, out):  # pragma: no cover - compiled
    """out[..., n] = (I + jQ)[..., n] * w[n] for int16 pairs raw (P, N, 2) (any strides), zero beyond N; out
    (P, >= N)."""
    for p in range(raw.shape[0]):
        for n in range(raw.shape[1]):
            out[p, n] = complex(np.float32(raw[p, n, 0]) * w[n], np.float32(raw[p, n, 1]) * w[n])
        for n in range(raw.shape[1], out.shape[1]):
            out[p, n] = 0.0


def range_compress(beat: ArrayLike, *, sample_rate_hz: float, slope_hz_per_s: float, window: str = "hann",
                   upsample: int = 8, workers: int = -1, referenced: bool = True) -> NDArray[np.complex64]:
    """Compress complex beat samples (..., N) to (..., N * upsample) range profiles (complex64).

    ``beat``: complex samples along fast time (last axis), or int16 I/Q pairs (..., N, 2). ``referenced=False``
    leaves out the multiplication by :func:`reference_ramp` (a caller that keeps only some bins applies it to
    those: numpy's product is the same there, bit for bit).
    """
    x = np.asarray(beat)
    iq = x.dtype == np.int16 and x.shape[-1] == 2
    n = x.shape[-2] if iq else x.shape[-1]
    nfft = n * upsample
    w = _taper32(window, n)
    # tapered and zero-padded by hand: scipy's own padding (n=nfft) made the FFT ~30 % slower (measured)
    if iq:
        padded = np.empty((*x.shape[:-2], nfft), np.complex64)
        _load_iq_tapered(x.reshape(-1, n, 2), w, padded.reshape(-1, nfft))
    else:
        padded = np.zeros((*x.shape[:-1], nfft), np.complex64)
        padded[..., :n] = x * w
    import scipy.fft  # here, not at the top: focus's own path (range_fft) never needs it, and it costs ~0.2 s to import

    spec = scipy.fft.fft(padded, axis=-1, workers=workers, overwrite_x=True)
    if referenced:
        spec *= reference_ramp(n, nfft, float(sample_rate_hz), float(slope_hz_per_s))
    return spec.astype(np.complex64, copy=False)


def range_compress_into(beat: ArrayLike, out_re: NDArray[np.float32], out_im: NDArray[np.float32], *,
                        sample_rate_hz: float, slope_hz_per_s: float, window: str = "hann", upsample: int = 8,
                        workers: int = -1, gain: complex | None = None) -> None:
    """Compress (P, N) beat samples (complex, or int16 I/Q (P, N, 2)) into planar (bin, pulse) arrays.

    ``out_re``/``out_im`` (N * upsample, >= P) float32 receive the profiles transposed: bin-major with pulses
    contiguous, the layout the back-projection kernel reads. int16 I/Q input whose N factors into 2, 3 and 5
    goes through the batched FFT of :mod:`.range_fft` (no transposes; equal to this path to -137 dB; one thread,
    whatever ``workers`` says). ``gain``: a complex factor on every profile (a channel's calibration,
    :meth:`autosar_cli.sar.channel_gains.ChannelGains.correction`), put on the reference ramp.
    """
    x = np.asarray(beat)
    if x.dtype == np.int16 and x.ndim == 3 and x.shape[-1] == 2 and radices(x.shape[1]) is not None:
        n = x.shape[1]
        ramp = reference_ramp(n, n * upsample, float(sample_rate_hz), float(slope_hz_per_s))
        if gain is not None:
            ramp = (ramp * np.complex64(gain)).astype(ramp.dtype)
        compress_iq(x, _taper32(window, n), ramp, upsample, out_re, out_im)
        return
    spec = range_compress(beat, sample_rate_hz=sample_rate_hz, slope_hz_per_s=slope_hz_per_s, window=window,
                          upsample=upsample, workers=workers)
    if gain is not None:
        spec *= np.complex64(gain)
    p = spec.shape[0]
    # numpy's strided copy transposes ~3x faster here than a tiled numba loop (measured)
    np.copyto(out_re[:, :p], spec.real.T)
    np.copyto(out_im[:, :p], spec.imag.T)


def bistatic_range_axis(n_fft: int, *, sample_rate_hz: float, slope_hz_per_s: float) -> NDArray[np.float64]:
    """Bistatic path length (m, Tx -> target -> Rx) of each compressed bin."""
    return SPEED_OF_LIGHT * np.arange(n_fft) * sample_rate_hz / (n_fft * slope_hz_per_s)


#: a range taper's first null from its peak, in bins of the unpadded FFT (c / (2 B) each): its main lobe's half-width
NULL_BINS = {"rect": 1.0, "boxcar": 1.0, "hann": 2.0, "hamming": 2.0, "blackman": 3.0}


def range_null_m(*, sample_rate_hz: float, slope_hz_per_s: float, num_samples: int, window: str = "hann") -> float:
    """Distance (m, one-way range) from a point's range peak to its response's first null: the window's
    :data:`NULL_BINS` times c / (2 B), B = slope x the ADC window (Hz); a window not listed is taken as Hann's."""
    bandwidth_hz = slope_hz_per_s * num_samples / sample_rate_hz
    return NULL_BINS.get(window, 2.0) * SPEED_OF_LIGHT / (2.0 * bandwidth_hz)
