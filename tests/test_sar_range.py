"""Range compression against the float64 reference, on a synthetic point target and on real TI ADC data."""

from __future__ import annotations

import numpy as np
import pytest
import reference
import scipy.signal
from conftest import realdata

from autosar_cli.config import SPEED_OF_LIGHT, load_config
from autosar_cli.sar.range_compression import bistatic_range_axis, iq_to_complex, range_compress, taper

R = load_config().radar
FS, K, F0, N = R.sample_rate_hz, R.slope_hz_per_s, R.start_frequency_hz, R.num_samples


def _beat(tau: float) -> np.ndarray:
    t = np.arange(N) / FS
    return np.exp(2j * np.pi * (F0 * tau + K * tau * t - 0.5 * K * tau**2))


@pytest.mark.parametrize("name", ["hann", "hamming", "blackman", "bartlett", "nuttall", "rect"])
def test_taper_is_scipys_symmetric_window(name: str) -> None:
    import scipy.signal

    want = scipy.signal.get_window("boxcar" if name == "rect" else name, N, fftbins=False)
    np.testing.assert_allclose(taper(name, N), want, rtol=0, atol=1e-15)
    assert taper(name, N)[0] == pytest.approx(taper(name, N)[-1])  # symmetric, not periodic


def test_matches_the_float64_reference_on_random_data() -> None:
    rng = np.random.default_rng(5)
    x = (rng.normal(size=(6, N)) + 1j * rng.normal(size=(6, N))).astype(np.complex64)
    got = range_compress(x, sample_rate_hz=FS, slope_hz_per_s=K, upsample=8)
    ref = reference.range_compress(x.astype(np.complex128), reference.hann(N), 8)
    f = np.arange(N * 8) * FS / (N * 8)
    ref = ref * np.exp(1j * np.pi * f**2 / K)  # the RVP removal
    rel = np.sum(np.abs(got - ref) ** 2) / np.sum(np.abs(ref) ** 2)
    assert 10 * np.log10(rel) < -50


@pytest.mark.parametrize("path_m", [3.3 * 2, 12.345 * 2, 40.0])
def test_point_target_peak_range_width_and_phase(path_m: float) -> None:
    tau = path_m / SPEED_OF_LIGHT
    rc = range_compress(_beat(tau)[None], sample_rate_hz=FS, slope_hz_per_s=K, upsample=16)[0]
    axis = bistatic_range_axis(rc.size, sample_rate_hz=FS, slope_hz_per_s=K)
    k = int(np.argmax(np.abs(rc)))
    assert abs(axis[k] - path_m) <= axis[1] / 2 + 1e-12  # within half a (16x upsampled) bin
    # -3 dB width: the Hann main lobe, 1.44 bins of the unpadded FFT = 1.44 c / B in path length
    width = reference.minus3db_width(axis, np.abs(rc))
    assert width == pytest.approx(reference.window_width_bins(reference.hann(N)) * SPEED_OF_LIGHT * FS / (N * K),
                                  rel=0.02)
    # After RVP removal the peak carries exactly 2 pi (f0 + K t_c) tau (what back-projection undoes)
    t_c = 0.5 * (N - 1) / FS
    residual = np.angle(rc[k] * np.exp(-2j * np.pi * (F0 + K * t_c) * tau))
    # the sample sits up to half a bin from the true peak; the centre-referenced lobe is real, so the phase holds
    assert abs(residual) < 0.05


def test_real_ti_adc_frame_shows_a_target() -> None:
    """OpenRadar's real TI mmWave frame (77.42 GHz, 60 MHz/us, 2.5 Msps, 128 samples): a clear range peak."""
    frame = np.load(realdata("openradar", "simple_frame_1.npy"))  # (chirps, samples), uint16 wrapped in complex
    iq = np.stack([frame.real.astype(np.int16), frame.imag.astype(np.int16)], axis=-1)
    beat = iq_to_complex(iq)
    rc = range_compress(beat - beat.mean(axis=-1, keepdims=True), sample_rate_hz=2.5e6, slope_hz_per_s=60e12,
                        upsample=4)
    profile = np.mean(np.abs(rc) ** 2, axis=0)
    axis = bistatic_range_axis(rc.shape[-1], sample_rate_hz=2.5e6, slope_hz_per_s=60e12) / 2
    # Tx->Rx coupling leaks into the first bins: look beyond 0.3 m; the upper half holds negative beat
    # frequencies (I/Q images), not targets.
    usable = (axis > 0.3) & (np.arange(axis.size) < axis.size // 2)
    k = int(np.argmax(np.where(usable, profile, 0.0)))
    assert 10 * np.log10(profile[k] / np.median(profile)) > 15  # a real reflector, well above the noise floor
    assert axis[k] == pytest.approx(1.9, abs=0.1)  # one-way range (m) of the strongest reflector in this capture
    # The same reflector straight from the samples: I + jQ in float64 less each chirp's mean, a plain FFT zero-padded
    # 16x (bins 1/16 of the native c fs / 2 K N = 48.8 mm), the strongest positive beat f past 0.3 m; range
    # c f / 2 K. The product's (Hann, 4x) peak lies within half a native bin of it (measured 6.1 mm, at 1.982 m).
    x = frame.real.astype(np.int16).astype(np.float64) + 1j * frame.imag.astype(np.int16)
    x -= x.mean(axis=1, keepdims=True)
    n = x.shape[1]
    power = np.mean(np.abs(np.fft.fft(x, 16 * n, axis=1)) ** 2, axis=0)
    f = np.arange(16 * n) * 2.5e6 / (16 * n)
    r = 299792458.0 * f / (2 * 60e12)
    j = int(np.argmax(np.where((r > 0.3) & (f < 1.25e6), power, 0.0)))
    assert r[j] == pytest.approx(1.98, abs=0.01)
    assert axis[k] == pytest.approx(r[j], abs=0.5 * 299792458.0 * 2.5e6 / (2 * 60e12 * n))


def test_real_ti_chirp_as_int16_iq_matches_the_float64_reference() -> None:
    """OpenRadar's one real chirp (``chirp.txt``, the same radar): int16 I/Q pairs straight into the kernel's own
    load-and-taper path give the float64 reference's profile, and its reflector stands 20 dB above the floor."""
    chirp = np.loadtxt(realdata("openradar", "chirp.txt"), dtype=np.complex128)  # uint16 wrapped in complex
    iq = np.stack([chirp.real.astype(np.uint16).astype(np.int16), chirp.imag.astype(np.uint16).astype(np.int16)],
                  axis=-1)
    fs, slope, n = 2.5e6, 60e12, chirp.size
    got = range_compress(iq[None], sample_rate_hz=fs, slope_hz_per_s=slope, upsample=4)[0]
    ref = reference.range_compress((iq[:, 0] + 1j * iq[:, 1]).astype(np.complex128), reference.hann(n), 4)
    f = np.arange(n * 4) * fs / (n * 4)
    ref = ref * np.exp(1j * np.pi * f**2 / slope)  # the RVP removal
    assert 10 * np.log10(np.sum(np.abs(got - ref) ** 2) / np.sum(np.abs(ref) ** 2)) < -50
    axis = bistatic_range_axis(got.size, sample_rate_hz=fs, slope_hz_per_s=slope) / 2
    power = np.abs(got) ** 2
    usable = (axis > 0.3) & (np.arange(axis.size) < axis.size // 2)  # past the Tx->Rx leak; positive beats
    k = int(np.argmax(np.where(usable, power, 0.0)))
    assert k == int(np.argmax(np.where(usable, np.abs(ref), 0.0)))
    assert 10 * np.log10(power[k] / np.median(power)) > 15
    assert 0.3 < axis[k] < 5.0  # a reflector in front of the bench radar, not the wrapped upper half


def test_range_compress_into_is_the_transposed_profile() -> None:
    from autosar_cli.sar.range_compression import range_compress, range_compress_into

    rng = np.random.default_rng(0)
    raw = rng.integers(-2000, 2000, (37, 540, 2)).astype(np.int16)
    re = np.zeros((540 * 4, 40), np.float32)
    im = np.zeros_like(re)
    range_compress_into(raw, re, im, sample_rate_hz=FS, slope_hz_per_s=K, upsample=4)
    ref = range_compress(raw, sample_rate_hz=FS, slope_hz_per_s=K, upsample=4)
    np.testing.assert_allclose(re[:, :37] + 1j * im[:, :37], ref.T, atol=1e-5 * np.abs(ref).max())
    assert not re[:, 37:].any()


@pytest.mark.parametrize("window", ["rect", "hann", "hamming", "blackman"])
def test_a_windows_first_range_null_is_the_one_its_response_has(window: str) -> None:
    """The first null of a tone's windowed spectrum (zero-padded 64x, float64), in bins of the unpadded FFT, is the
    window's stated half-width (rect 1, Hann and Hamming 2, Blackman 3), and ``range_null_m`` is that many bins of
    c / (2B)."""
    from autosar_cli.config import SPEED_OF_LIGHT
    from autosar_cli.sar.range_compression import NULL_BINS, range_null_m

    n, pad = 256, 64
    w = scipy.signal.get_window(window if window != "rect" else "boxcar", n, fftbins=False)
    spectrum = np.abs(np.fft.fft(w, n * pad))[: n * pad // 2]
    falling = np.flatnonzero(np.diff(spectrum) > 0)  # the first bin where the response rises again: its first null
    assert falling[0] / pad == pytest.approx(NULL_BINS[window], abs=0.05)
    fs, slope = 12.5e6, 60e12
    bandwidth = slope * n / fs
    assert range_null_m(sample_rate_hz=fs, slope_hz_per_s=slope, num_samples=n, window=window) == pytest.approx(
        NULL_BINS[window] * SPEED_OF_LIGHT / (2 * bandwidth))
