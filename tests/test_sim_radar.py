"""The simulator's radar data is physically right: a float64 back-projection of the raw `ci` frames
along the TRUE phase centres focuses every corner reflector at its true position with the theoretical
range resolution. Reads the log with mcap + rosbags (not our code)."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
import reference as ref
from mcap.reader import make_reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

C = ref.C


def read_raw_frames(path, keep: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """The RawFrames of an MCAP, all or those whose frame index is in ``keep``: (frame_index (F,),
    cube (F, T, R, N) complex64, radar parameters)."""
    wanted = None if keep is None else {int(k) for k in keep}
    store = get_typestore(Stores.ROS2_HUMBLE)
    frames, index, params = [], [], {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, _channel, message in reader.iter_messages():
            if schema.name != "scanbrick_msgs/msg/RawFrame":
                continue
            if "scanbrick_msgs/msg/RawFrame" not in store.types:
                text = schema.data.decode()
                store.register(get_types_from_msg(text.split("=" * 80)[0], schema.name))
            m = store.deserialize_cdr(message.data, schema.name)
            if wanted is not None and m.frame_index not in wanted:
                continue
            params = {"f0": m.start_frequency_hz, "slope": m.slope_hz_per_s, "fs": m.sample_rate_hz,
                      "n": m.num_samples, "offsets": np.array(m.tx_start_offsets_s)}
            iq = np.asarray(m.data, dtype=np.float32).reshape(m.num_tx, m.num_rx, m.num_samples, 2)
            frames.append(iq[..., 0] + 1j * iq[..., 1])
            index.append(m.frame_index)
    return np.array(index), np.array(frames, dtype=np.complex64), params


@pytest.fixture(scope="module")
def ci_data(ci_mcap):
    index, cube, params = read_raw_frames(ci_mcap.log_path)
    with h5py.File(ci_mcap.truth_path) as t:
        truth = {
            "frame_index": t["radar/frame_index"][:],
            "tx": t["radar/tx_position_enu"][:],
            "rx": t["radar/rx_position_enu"][:],
            "targets": t["targets/position_enu"][:],
            "corners": t["targets/corner_reflectors"][:],
            "origin": t["trajectory/radar_origin_enu"][:],
        }
    return index, cube, params, truth


def test_frames_match_truth_and_are_contiguous(ci_data, ci_mcap):
    index, cube, params, truth = ci_data
    assert np.array_equal(index, truth["frame_index"])
    assert np.array_equal(index, np.arange(len(index)))
    assert cube.shape[1:] == (3, 4, 540)
    assert params["f0"] == 77e9 and params["slope"] == 75e12 and params["fs"] == 13.5e6
    assert np.allclose(params["offsets"], [0.0, 60e-6, 120e-6])
    # 1.57 s at 990 Hz
    assert abs(len(index) - ci_mcap.duration_s * 990) < 3


def array_centres(truth) -> np.ndarray:
    """(F, 3) midpoint of each frame's mean Tx and mean Rx phase centre (truth["tx"] (F, T, 3), ["rx"] (F, T, R, 3))."""
    return 0.5 * (truth["tx"].mean(axis=1) + truth["rx"].mean(axis=(1, 2)))


def stripmap_frames(truth, target, f0: float) -> np.ndarray:
    """Rows of the truth's per-frame arrays whose array centre sees ``target`` within the stripmap window
    (+- lambda / (4 rho) of broadside, rho = 4 cm); frames standing still have no broadside and are left out."""
    half_width = C / f0 / (4 * 0.04)
    centre = array_centres(truth)
    velocity = np.gradient(centre, axis=0)
    los = target[None, :] - centre
    with np.errstate(invalid="ignore", divide="ignore"):
        cosang = np.einsum("ij,ij->i", los[:, :2], velocity[:, :2]) / (
            np.linalg.norm(los[:, :2], axis=1) * np.linalg.norm(velocity[:, :2], axis=1))
    return np.flatnonzero(np.abs(np.arcsin(np.clip(cosang, -1, 1))) < half_width)


def focus_reflector(cube, params, truth, target):
    """Float64 TDBP around one reflector with the true phase centres, all 12 channels, pulses within the
    stripmap window (:func:`stripmap_frames`)."""
    tx = truth["tx"]  # (F, T, 3)
    rx = truth["rx"]  # (F, T, R, 3)
    centre = array_centres(truth)
    sel = stripmap_frames(truth, target, params["f0"])
    assert len(sel) > 20, "reflector not illuminated inside the stripmap window"
    window = ref.hann(params["n"])
    rc = ref.range_compress(cube[sel].astype(np.complex128), window, 8).reshape(len(sel), 12, -1)
    txc = np.repeat(tx[sel], 4, axis=1)  # channel order (tx, rx)
    rxc = rx[sel].reshape(len(sel), 12, 3)
    kw = dict(f0=params["f0"], slope=params["slope"], fs=params["fs"], n_samples=params["n"])
    mid = centre[sel].mean(axis=0)
    u_range = np.append((target - mid)[:2] / np.linalg.norm((target - mid)[:2]), 0.0)
    u_along = np.array([-u_range[1], u_range[0], 0.0])
    return rc, txc, rxc, kw, u_range, u_along


@pytest.mark.parametrize("which", [0, 1, 2])
def test_corner_reflector_focuses_at_true_position_with_theoretical_range_width(ci_data, which):
    index, cube, params, truth = ci_data
    target = truth["targets"][truth["corners"][which]]
    rc, txc, rxc, kw, u_range, u_along = focus_reflector(cube, params, truth, target)
    # coarse-to-fine peak search on the focusing plane z = target height
    best = target.copy()
    for span, step in ((0.08, 0.01), (0.012, 0.001)):
        g = np.arange(-span, span + 1e-9, step)
        gx, gy = np.meshgrid(g, g, indexing="ij")
        pix = best + gx.reshape(-1, 1) * u_range + gy.reshape(-1, 1) * u_along
        img = np.abs(ref.backproject(rc, txc, rxc, pix, **kw))
        best = pix[int(np.argmax(img))]
    error = np.linalg.norm((best - target)[:2])
    assert error < 0.01, f"peak {error * 100:.2f} cm from the true position"

    # range cut through the peak
    d = np.arange(-0.15, 0.15 + 1e-9, 0.002)
    cut = np.abs(ref.backproject(rc, txc, rxc, best + d[:, None] * u_range, **kw))
    width = ref.minus3db_width(d, cut)
    theory = ref.window_width_bins(ref.hann(params["n"])) * C / (2 * params["slope"] * params["n"] / params["fs"])
    assert abs(width / theory - 1) < 0.15, f"range -3 dB width {width * 100:.2f} cm vs theory {theory * 100:.2f} cm"
    assert 0.06 < theory < 0.08  # Hann taper: 1.44 x c/2B


def test_rcs_and_noise_levels_are_realistic(ci_data):
    index, cube, params, truth = ci_data
    raw_i = cube.real
    # int16 ADC: never clipped on this scene, noise floor ~3 LSB per rail
    assert np.abs(raw_i).max() < 32767
    window = ref.hann(540)
    rc = np.fft.fft(cube[:50, 0, 0] * window, axis=-1)
    floor = np.median(np.abs(rc[:, 400:530]))  # beyond all targets (> 22 m)
    # 3 LSB per rail plus the ADC's rounding (1/12 LSB^2 per rail) through the taper: Rayleigh median sqrt(P ln 2)
    floor_theory = np.sqrt(2 * (3.0**2 + 1 / 12) * np.sum(window**2) * np.log(2))
    peak = np.abs(rc).max()
    snr = 20 * np.log10(peak / floor)
    print(f"compressed noise floor {20 * np.log10(floor):.2f} dB (theory {20 * np.log10(floor_theory):.2f} dB), "
          f"peak {20 * np.log10(peak):.2f} dB, SNR {snr:.1f} dB")
    assert abs(20 * np.log10(floor / floor_theory)) < 0.3
    assert 20 * np.log10(peak) < 20 * np.log10(32767 * np.sum(window))  # below a full-scale tone
