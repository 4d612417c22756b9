"""Straightforward float64 reference radar processing for tests, independent of the package's code.

Range compression: taper, zero-padded FFT over fast time, phase referenced to the window centre.
Back-projection: exact bistatic delay per Tx/Rx pair, linear interpolation of the compressed samples,
removal of the full beat phase 2 pi (f0 tau + K tau t_c - K tau^2 / 2) at the window centre t_c.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

C = 299_792_458.0


def crc8_j1850(data: bytes) -> int:
    """Bitwise CRC-8, polynomial 0x1D, init 0x00, not reflected, no final XOR (independent of candb's table)."""
    crc = 0
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


def hann(n: int) -> np.ndarray:
    return np.hanning(n)


def range_compress(raw: np.ndarray, window: np.ndarray, upsample: int) -> np.ndarray:
    """raw (..., N) complex beat samples -> (..., N * upsample) spectra referenced to the window centre."""
    n = raw.shape[-1]
    nfft = n * upsample
    spec = np.fft.fft(raw * window, nfft, axis=-1)
    k = np.arange(nfft)
    return spec * np.exp(1j * np.pi * k * (n - 1) / nfft)


def backproject(rc: np.ndarray, tx: np.ndarray, rx: np.ndarray, pixels: np.ndarray, *, f0: float, slope: float,
                fs: float, n_samples: int) -> np.ndarray:
    """rc (P, Ch, Nfft) compressed pulses; tx, rx (P, Ch, 3) antenna positions (m); pixels (M, 3).
    Returns the complex image at the pixels (M,)."""
    nfft = rc.shape[-1]
    t_c = 0.5 * (n_samples - 1) / fs
    image = np.zeros(len(pixels), dtype=np.complex128)
    for p in range(rc.shape[0]):
        for ch in range(rc.shape[1]):
            tau = (np.linalg.norm(pixels - tx[p, ch], axis=1) + np.linalg.norm(pixels - rx[p, ch], axis=1)) / C
            x = slope * tau * nfft / fs
            i0 = np.floor(x).astype(int)
            a = x - i0
            valid = (i0 >= 0) & (i0 + 1 < nfft)
            i0 = np.clip(i0, 0, nfft - 2)
            s = (1 - a) * rc[p, ch, i0] + a * rc[p, ch, i0 + 1]
            phase = 2 * np.pi * (f0 * tau + slope * tau * t_c - 0.5 * slope * tau**2)
            image += np.where(valid, s * np.exp(-1j * phase), 0.0)
    return image


def minus3db_width(x: np.ndarray, mag: np.ndarray) -> float:
    """-3 dB width of the main lobe of |mag| sampled at x (linear interpolation of the crossings)."""
    p = mag**2 / np.max(mag**2)
    i = int(np.argmax(p))
    lo = i
    while lo > 0 and p[lo] > 0.5:
        lo -= 1
    hi = i
    while hi < len(p) - 1 and p[hi] > 0.5:
        hi += 1
    xl = np.interp(0.5, [p[lo], p[lo + 1]], [x[lo], x[lo + 1]])
    xh = np.interp(0.5, [p[hi], p[hi - 1]], [x[hi], x[hi - 1]])
    return float(xh - xl)


def window_width_bins(window: np.ndarray, oversample: int = 64) -> float:
    """-3 dB width of the taper's spectral main lobe, in FFT bins of the unpadded length."""
    n = len(window)
    spec = np.abs(np.fft.fftshift(np.fft.fft(window, n * oversample)))
    x = (np.arange(n * oversample) - n * oversample // 2) / oversample
    return minus3db_width(x, spec)


def tdbp(profiles: np.ndarray, antennas: np.ndarray, channels: np.ndarray, pixels: np.ndarray,
         windows: np.ndarray, *, range0_m: np.ndarray, bin_m: float, cycles_per_m: float) -> np.ndarray:
    """Windowed back-projection, float64, one pixel at a time.

    profiles (C, B, P) complex; antennas (A, P, 3); channels (C, 2) Tx/Rx antenna indices; pixels (N, 3);
    windows (N, 2) pulse ranges [lo, hi); bin b of channel c lies at bistatic path range0_m[c] + b * bin_m.
    """
    profiles = np.asarray(profiles, dtype=np.complex128)
    n_ch, n_bins, _ = profiles.shape
    r0 = np.broadcast_to(np.asarray(range0_m, dtype=np.float64), (n_ch,))
    image = np.zeros(len(pixels), dtype=np.complex128)
    for n, (pix, (lo, hi)) in enumerate(zip(pixels, windows, strict=True)):
        pulses = np.arange(lo, hi)
        for c, (ta, ra) in enumerate(channels):
            path = (np.sqrt(np.sum((pix - antennas[ta, pulses]) ** 2, axis=1))
                    + np.sqrt(np.sum((pix - antennas[ra, pulses]) ** 2, axis=1)))
            x = (path - r0[c]) / bin_m
            i0 = np.floor(x).astype(int)
            frac = x - i0
            ok = (i0 >= 0) & (i0 + 1 < n_bins)
            i0 = np.clip(i0, 0, n_bins - 2)
            s = (1 - frac) * profiles[c, i0, pulses] + frac * profiles[c, i0 + 1, pulses]
            image[n] += np.sum(np.where(ok, s * np.exp(-2j * np.pi * cycles_per_m * path), 0.0))
    return image


def pattern_exponent(beamwidth_deg: float) -> float:
    """n of a cos^n one-way power pattern that is -3 dB at half the beamwidth."""
    return float(np.log(0.5) / np.log(np.cos(np.radians(beamwidth_deg / 2.0))))


IF_BAND_FRACTION = 0.98  # the simulator receives beat frequencies below 0.98 fs (its anti-alias filter)


def beat_reference(
    tx_start: NDArray[np.float64],
    tx_end: NDArray[np.float64],
    rx_start: NDArray[np.float64],
    rx_end: NDArray[np.float64],
    radar_origin: NDArray[np.float64],
    enu_to_radar: NDArray[np.float64],
    targets: NDArray[np.float64],
    rcs_m2: NDArray[np.float64],
    *,
    start_frequency_hz: float,
    slope_hz_per_s: float,
    sample_rate_hz: float,
    num_samples: int,
    amplitude_lsb: float,
    beamwidth_az_deg: float,
    beamwidth_el_deg: float,
    target_velocity: NDArray[np.float64] | None = None,
    chirp_start_s: NDArray[np.float64] | None = None,
    road_reflection: float = 0.0,
    road_height: NDArray[np.float64] | None = None,
    retroreflector: NDArray[np.bool_] | None = None,
) -> NDArray[np.complex128]:
    """Straightforward float64 version of the simulator's beat synthesis (``synthesize_beat``): exact phase at
    every sample, with the antenna positions interpolated linearly over the chirp and each target where its
    velocity (m/s, (M, 3)) has taken it at that sample (``chirp_start_s`` (F, T): each chirp's first sample, s).
    With ``road_reflection`` Gamma, a target more than 1 cm above ``road_height`` (M,) is also reached by way of
    its image mirrored in that plane: out and back each direct or by the image, each leg with its own one-way
    pattern (the square root of the two-way one) and 1/r spreading, Gamma per bounce; a ``retroreflector`` only
    straight back (direct-direct and image-image). For tests on small cases."""
    c = C
    n = np.arange(num_samples)
    t = n / sample_rate_hz
    frac = t * sample_rate_hz / num_samples  # 0 .. (N-1)/N of the way from start to end positions
    n_az, n_el = pattern_exponent(beamwidth_az_deg), pattern_exponent(beamwidth_el_deg)
    max_path = IF_BAND_FRACTION * sample_rate_hz * c / slope_hz_per_s
    n_frames, n_tx = tx_start.shape[:2]
    n_rx = rx_start.shape[2]
    out = np.zeros((n_frames, n_tx, n_rx, num_samples), dtype=np.complex128)
    velocity = np.zeros_like(targets) if target_velocity is None else np.asarray(target_velocity, np.float64)
    starts = np.zeros((n_frames, n_tx)) if chirp_start_s is None else np.asarray(chirp_start_s, np.float64)
    ground = np.zeros(len(targets)) if road_height is None else np.asarray(road_height, np.float64)
    retro = np.zeros(len(targets), bool) if retroreflector is None else np.asarray(retroreflector, bool)
    bounces = road_reflection != 0.0

    def in_the_road(where: NDArray[np.float64]) -> NDArray[np.float64]:
        """``where`` (M, ..., 3) mirrored in the horizontal plane of each target's road."""
        image = where.copy()
        image[..., 2] = 2 * ground.reshape((-1,) + (1,) * (where.ndim - 2)) - where[..., 2]
        return image

    def leg(where: NDArray[np.float64], f: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Range (M,) and one-way amplitude pattern (M,) from the radar's origin to ``where`` (M, 3)."""
        d = where - radar_origin[f]
        r = np.linalg.norm(d, axis=1)
        u = (enu_to_radar[f] @ d.T).T / r[:, None]
        horiz = np.hypot(u[:, 0], u[:, 1])
        power = np.where(u[:, 0] > 0, np.abs(u[:, 0] / np.maximum(horiz, 1e-300)) ** n_az
                         * np.minimum(horiz, 1.0) ** n_el, 0.0)
        return r, np.sqrt(power)

    for f in range(n_frames):
        at_start = targets + velocity * starts[f, 0]
        r, g = leg(at_start, f)
        ri, gi = leg(in_the_road(at_start), f)
        above = at_start[:, 2] - ground > 0.01
        # (tx leg by the image, rx leg by the image, amplitude (M,)) of each path
        paths = [(False, False, np.where((2 * r < max_path) & (r >= 0.05), g * g / r**2, 0.0))]
        if bounces:
            cross = np.where(above & ~retro & (r + ri < max_path) & (r >= 0.05), road_reflection * g * gi / (r * ri),
                             0.0)
            paths += [(True, False, cross), (False, True, cross),
                      (True, True, np.where(above & (2 * ri < max_path) & (r >= 0.05),
                                            road_reflection**2 * gi * gi / ri**2, 0.0))]
        for k in range(n_tx):
            tx = tx_start[f, k][None, :] + frac[:, None] * (tx_end[f, k] - tx_start[f, k])[None, :]
            for q in range(n_rx):
                rx = rx_start[f, k, q][None, :] + frac[:, None] * (rx_end[f, k, q] - rx_start[f, k, q])[None, :]
                where = targets[:, None, :] + velocity[:, None, :] * (starts[f, k] + t)[None, :, None]  # (M, N, 3)
                image = in_the_road(where)
                for tx_image, rx_image, amplitude in paths:
                    path = (np.linalg.norm((image if tx_image else where) - tx[None], axis=2)
                            + np.linalg.norm((image if rx_image else where) - rx[None], axis=2))
                    tau = path / c
                    phase = 2 * np.pi * (start_frequency_hz * tau + slope_hz_per_s * tau * t[None, :]
                                         - 0.5 * slope_hz_per_s * tau**2)
                    gain = amplitude_lsb * np.sqrt(rcs_m2) * amplitude
                    out[f, k, q] += (gain[:, None] * np.exp(1j * phase)).sum(axis=0)
    return out


# ---------------------------------------------------------------- radiometry (radar equation), for the focus tests


def centred_window_response(window: np.ndarray, offset_bins: np.ndarray) -> np.ndarray:
    """Real amplitude spectrum of the taper about its centre, at offsets (unpadded FFT bins) from a tone."""
    n = len(window)
    k = np.arange(n) - 0.5 * (n - 1)
    return np.cos(2 * np.pi * np.asarray(offset_bins)[..., None] * k / n) @ window


def stripmap_pulses(pixel: np.ndarray, tx0: np.ndarray, half_width_rad: float) -> np.ndarray:
    """Pulses whose line of sight from Tx0 (P, 3) to the pixel is within half_width of the zero-Doppler plane of
    the direction of travel (central differences of Tx0's track): a boolean mask (P,)."""
    v = np.gradient(tx0, axis=0)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    los = pixel[None, :] - tx0
    sin_psi = np.sum(los * v, axis=1) / np.linalg.norm(los, axis=1)
    return np.abs(sin_psi) <= np.sin(half_width_rad)


def focused_peak_prediction(target: np.ndarray, rcs_m2: float, tx: np.ndarray, rx: np.ndarray,
                            pairs: list[tuple[int, int]], *, amplitude_1m2_1m_lsb: float, beamwidth_az_deg: float,
                            beamwidth_el_deg: float, f0: float, slope: float, fs: float, n_samples: int,
                            upsample: int, resolution_m: float) -> tuple[float, int]:
    """|focused image| at a point target by the radar equation, and the pulses in its window.

    Per pulse and channel the beat tone has amplitude A1 sqrt(rcs) g(az, el) / R^2 (A1: the ADC amplitude of 1 m^2
    at 1 m on boresight; g = cos^n_az(az) cos^n_el(el), each antenna's one-way power pattern, so the two-way
    amplitude; R from the radar's centre). The Hann-tapered FFT gives it the coherent gain sum(w) at the tone;
    linear interpolation between bins of the x``upsample`` zero-padded spectrum loses what the taper's response
    loses at the sample's fractional position; the back-projection sums pulses x channels coherently.
    tx (P, T, 3), rx (P, T, R, 3): true phase centres (ENU m) at each chirp; the radar's axes come from the Rx
    row (y, Rx0 -> Rx3) and the vertical (z): boresight x = y x z.
    """
    lam_c = C / (f0 + 0.5 * slope * n_samples / fs)
    half_width = lam_c / (4 * resolution_m)
    window = np.hanning(n_samples)
    sel = stripmap_pulses(target, tx[:, 0], half_width)
    tx, rx = tx[sel], rx[sel]
    y = rx[:, 0, -1] - rx[:, 0, 0]
    y /= np.linalg.norm(y, axis=1, keepdims=True)
    x = np.cross(y, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    centre = 0.5 * (tx.mean(axis=1) + rx.mean(axis=(1, 2)))
    los = target[None, :] - centre
    r = np.linalg.norm(los, axis=1)
    ux = np.sum(los * x, axis=1) / r
    uy = np.sum(los * y, axis=1) / r
    horiz = np.hypot(ux, uy)
    gain = (ux / horiz) ** pattern_exponent(beamwidth_az_deg) * horiz ** pattern_exponent(beamwidth_el_deg)
    amp = amplitude_1m2_1m_lsb * np.sqrt(rcs_m2) * gain / r**2
    bin_path = C * fs / (n_samples * upsample * slope)
    total = 0.0
    for t, q in pairs:
        path = np.linalg.norm(target - tx[:, t], axis=1) + np.linalg.norm(target - rx[:, t, q], axis=1)
        frac = path / bin_path % 1.0
        interp = ((1 - frac) * centred_window_response(window, frac / upsample)
                  + frac * centred_window_response(window, (1 - frac) / upsample))
        total += float(np.sum(amp * interp))
    return total, int(sel.sum())


def noise_floor_prediction(noise_std_lsb: float, n_samples: int, upsample: int) -> float:
    """Mean |compressed sample|^2 (LSB^2) of white complex noise, std noise_std_lsb per rail plus the int16
    ADC's rounding (1/12 LSB^2 per rail), after the Hann taper, the FFT and linear interpolation between bins of
    the x``upsample`` spectrum at a uniformly distributed fractional position: sum(w^2) (2/3 + rho/3), rho the
    correlation of neighbouring bins. A pixel's floor is this times the pulses x channels it sums."""
    w = np.hanning(n_samples)
    k = np.arange(n_samples) - 0.5 * (n_samples - 1)
    rho = np.sum(w**2 * np.cos(2 * np.pi * k / (n_samples * upsample))) / np.sum(w**2)
    return 2 * (noise_std_lsb**2 + 1 / 12) * np.sum(w**2) * (2 / 3 + rho / 3)


class FlatRoad:
    """A level, perfectly smooth road (the closed-form single-track and roll values assume one)."""

    def height(self, s: np.ndarray, w: np.ndarray, side: int) -> np.ndarray:
        return np.zeros(np.broadcast(np.asarray(s), np.asarray(w)).shape)

    def grade_height(self, s: np.ndarray) -> np.ndarray:
        return np.zeros_like(np.asarray(s, dtype=np.float64))
