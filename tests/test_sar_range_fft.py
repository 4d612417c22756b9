"""The batched range FFT (autosar_cli.sar.range_fft) against a float64 numpy reference."""

from __future__ import annotations

import numpy as np
import pytest

from autosar_cli.sar import range_fft
from autosar_cli.sar.range_compression import range_compress, range_compress_into
from autosar_cli.sar.range_fft import compress_iq, radices

FS = 13.5e6
K = 75e12


def _reference(raw: np.ndarray, up: int) -> tuple[np.ndarray, np.ndarray]:
    """float64: Hann taper, zero-padded FFT, window-centre reference and RVP removal per bin; and the ramp."""
    n = raw.shape[1]
    nfft = n * up
    k = np.arange(nfft)
    f = k * FS / nfft
    ramp = np.exp(1j * (np.pi * k * (n - 1) / nfft + np.pi * f**2 / K))
    spec = np.fft.fft((raw[..., 0] + 1j * raw[..., 1].astype(np.float64)) * np.hanning(n), nfft, axis=-1)
    return spec * ramp, ramp


def _error_db(got: np.ndarray, ref: np.ndarray) -> float:
    return float(10 * np.log10(max(np.sum(np.abs(got - ref) ** 2) / np.sum(np.abs(ref) ** 2), 1e-30)))


# pulse counts within one batch, across batches, ending in a partial batch, and across the staged groups of
# GROUP * BATCH pulses (a full group, then a partial one ending in a partial batch)
@pytest.mark.parametrize(("n_pulses", "n", "up"), [(45, 540, 4), (64, 512, 2), (33, 60, 3), (7, 25, 8), (1, 540, 4),
                                                    (70, 48, 1), (300, 60, 3), (600, 30, 2)])
def test_equals_the_float64_reference(n_pulses: int, n: int, up: int) -> None:
    rng = np.random.default_rng(n + up)
    cube = rng.integers(-32768, 32767, (n_pulses, 3, 4, n, 2), endpoint=True).astype(np.int16)  # full range: sign bits
    raw = cube[:, 2, 1]  # strided, as focus hands over one Tx/Rx pair of the raw cube
    ref, ramp = _reference(raw, up)
    out_re = np.zeros((n * up, n_pulses + 3), np.float32)
    out_im = np.zeros_like(out_re)
    compress_iq(raw, np.hanning(n).astype(np.float32), ramp.astype(np.complex64), up, out_re, out_im)
    got = (out_re[:, :n_pulses] + 1j * out_im[:, :n_pulses]).T
    assert _error_db(got, ref) < -120.0
    assert not out_re[:, n_pulses:].any() and not out_im[:, n_pulses:].any()  # the batch padding is dropped


@pytest.mark.parametrize("layout", ["planar", "big-endian"])
def test_other_sample_layouts(layout: str) -> None:
    """I and Q in separate planes, or big-endian samples, take the packed copy instead of the int32 view."""
    rng = np.random.default_rng(5)
    raw = rng.integers(-32768, 32767, (40, 60, 2), endpoint=True).astype(np.int16)
    ref, ramp = _reference(raw, 3)
    given = np.ascontiguousarray(raw.transpose(2, 0, 1)).transpose(1, 2, 0) if layout == "planar" else raw.astype(">i2")
    out_re = np.zeros((180, 40), np.float32)
    out_im = np.zeros_like(out_re)
    compress_iq(given, np.hanning(60).astype(np.float32), ramp.astype(np.complex64), 3, out_re, out_im)
    assert _error_db((out_re + 1j * out_im).T, ref) < -120.0


@pytest.mark.parametrize("group", [1, 3])
def test_staged_groups_of_any_size(group: int, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(range_fft, "GROUP", group)  # 10 batches: groups of 3, 3, 3 and 1 (or ten of 1)
    rng = np.random.default_rng(group)
    raw = rng.integers(-2000, 2000, (300, 60, 2)).astype(np.int16)
    ref, ramp = _reference(raw, 2)
    out_re = np.zeros((120, 300), np.float32)
    out_im = np.zeros_like(out_re)
    compress_iq(raw, np.hanning(60).astype(np.float32), ramp.astype(np.complex64), 2, out_re, out_im)
    assert _error_db((out_re + 1j * out_im).T, ref) < -120.0


def test_a_point_target_lands_in_its_bin() -> None:
    n, up = 540, 4
    k0 = 1234.25  # between bins of the padded FFT
    t = np.arange(n)
    beat = 3000 * np.exp(2j * np.pi * k0 * t / (n * up))
    raw = np.stack([beat.real, beat.imag], axis=-1).round().astype(np.int16)[None]
    out_re = np.zeros((n * up, 1), np.float32)
    out_im = np.zeros_like(out_re)
    _, ramp = _reference(raw, up)
    compress_iq(raw, np.hanning(n).astype(np.float32), ramp.astype(np.complex64), up, out_re, out_im)
    mag = np.hypot(out_re[:, 0], out_im[:, 0])
    assert int(np.argmax(mag)) in (1234, 1235)
    assert abs(mag[1234] - mag[1235]) / mag.max() < 0.05  # a quarter bin off either: nearly equal


def test_radices_and_the_fallback_for_other_lengths() -> None:
    assert radices(540) == (4, 3, 3, 3, 5)
    assert radices(512) == (4, 4, 4, 4, 2)
    assert radices(28) is None  # 7 is not a radix
    rng = np.random.default_rng(1)
    for n in (540, 28):  # batched and scipy paths give the same planar profiles
        raw = rng.integers(-2000, 2000, (19, n, 2)).astype(np.int16)
        re = np.zeros((n * 4, 19), np.float32)
        im = np.zeros_like(re)
        range_compress_into(raw, re, im, sample_rate_hz=FS, slope_hz_per_s=K, upsample=4)
        ref = range_compress(raw, sample_rate_hz=FS, slope_hz_per_s=K, upsample=4)
        assert _error_db((re + 1j * im).T, ref) < -120.0
