"""The radar's channel gains (sar/channel_gains.py, sar/channel_calibration.py): an uncalibrated front end's
per-channel phase and gain, put on by the simulator, measured on the drive's own points and undone by focus."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest

from autosar_cli.config import load_config
from autosar_cli.evaluate.evaluation import load_truth
from autosar_cli.ingest.pipeline import ingest
from autosar_cli.nav.inputs import load_inputs
from autosar_cli.sar.channel_calibration import ChannelCalibrationOptions, gains_from_spectra, measure_channel_gains
from autosar_cli.sar.channel_gains import ChannelGains
from autosar_cli.sar.focus import FocusOptions, channel_pairs, focus_images
from autosar_cli.sar.point_selection import candidate_points
from autosar_cli.sar.range_compression import range_compress_into
from autosar_cli.sar.residual_motion import AutofocusOptions
from autosar_cli.sim.simulate import channel_errors, simulate, stream_rng
from autosar_cli.store.drive import Drive

CFG = load_config()
PAIRS = channel_pairs(3, 4, 8)


def test_the_simulators_channel_errors_are_a_tx_and_an_rx_path_each_and_seeded() -> None:
    g = channel_errors(stream_rng(3, "radar/channels"), 3, 4, 30.0, 1.0)
    assert g.shape == (3, 4)
    # channel (t, r) is Tx t's path times Rx r's: every 2 x 2 minor vanishes
    assert np.allclose(g[1:, 1:] * g[0, 0], g[1:, :1] * g[:1, 1:], atol=1e-5)
    assert np.array_equal(g, channel_errors(stream_rng(3, "radar/channels"), 3, 4, 30.0, 1.0))
    assert 10.0 < np.degrees(np.std(np.angle(g))) < 90.0
    assert np.array_equal(channel_errors(stream_rng(3, "radar/channels"), 3, 4, 0.0, 0.0), np.ones((3, 4)))


def test_gains_normalise_and_their_correction_undoes_them() -> None:
    g = 2.0 * np.exp(0.3j) * channel_errors(stream_rng(1, "radar/channels"), 3, 4, 40.0, 2.0)
    gains = ChannelGains.from_complex(g)
    c = gains.complex()
    assert abs(np.angle(c.sum())) < 1e-4 and abs(np.mean(np.log(np.abs(c)))) < 1e-4
    ratio = c / g  # one complex constant: the common phase and gain, which change no image
    assert np.allclose(ratio, ratio[0, 0], rtol=1e-3)
    # undone over the pairs used, whose own phase sum and geometric mean are kept
    undone = gains.correction(PAIRS) * np.array([c[t, r] for t, r in PAIRS])
    assert np.allclose(undone, undone[0], atol=1e-4)
    assert np.allclose(gains.correction(PAIRS), ChannelGains.from_complex(g[[0, 2]]).correction(
        [(0, r) for r in range(4)] + [(1, r) for r in range(4)]), atol=1e-4)
    assert ChannelGains.from_dict(gains.to_dict()) == gains
    # a mask: the channels not measured stay matched, the others normalise among themselves
    measured = np.zeros((3, 4), bool)
    measured[[0, 2]] = True
    part = ChannelGains.from_complex(g, measured).complex()
    assert np.allclose(part[1], 1.0) and abs(np.angle(part[measured].sum())) < 1e-4


def test_range_compression_puts_the_gain_on_every_profile() -> None:
    rng = np.random.default_rng(0)
    for n in (540, 541):  # the batched FFT's sizes, and scipy's
        raw = rng.integers(-2000, 2000, (16, n, 2)).astype(np.int16)
        out = [np.zeros((4 * n, 16), np.float32) for _ in range(4)]
        kw = dict(sample_rate_hz=10e6, slope_hz_per_s=60e12, upsample=4)
        range_compress_into(raw, out[0], out[1], **kw)
        range_compress_into(raw, out[2], out[3], gain=0.5 - 0.8j, **kw)
        z0, z1 = out[0] + 1j * out[1], out[2] + 1j * out[3]
        assert np.allclose(z1, (0.5 - 0.8j) * z0, atol=1e-3 * np.abs(z0).max())


def test_the_gains_are_those_the_point_scatterers_agree_on() -> None:
    """Five still points see the channels' gains; two see a ramp along the array (a point seen over part of its
    aperture), one is clutter: the gains are the five's."""
    rng = np.random.default_rng(4)
    c = len(PAIRS)
    true = np.exp(1j * rng.normal(0, 0.6, c)) * 10 ** (rng.normal(0, 1.0, c) / 20)
    spectra = []
    for p in range(8):
        v = true * np.exp(1j * (np.arange(c) * 0.5 if p in (5, 6) else 0.0))
        z = rng.normal(size=(200, 1)) * np.exp(2j * np.pi * rng.random((200, 1))) * v[None, :]
        z = z + (0.05 if p < 7 else 3.0) * (rng.normal(size=(200, c)) + 1j * rng.normal(size=(200, c)))
        spectra.append(z.T @ z.conj())
    g, used, _ = gains_from_spectra(np.array(spectra), ChannelCalibrationOptions())
    assert g is not None and used.tolist() == [True] * 5 + [False] * 3
    err = g / true
    err /= np.exp(1j * np.angle(err.sum())) * np.exp(np.mean(np.log(np.abs(err))))
    assert np.degrees(np.abs(np.angle(err))).max() < 1.0 and np.abs(20 * np.log10(np.abs(err))).max() < 0.1


@pytest.fixture(scope="module")
def mismatched_ci(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Any, Any]:
    """The ci drive (seed 7, kinematic) from a front end 45 deg and 1.5 dB off per Tx and Rx path (std), ingested; its
    truth; and its true gains (T, R) from the sidecar."""
    assert CFG.simulation is not None
    cfg = replace(CFG, simulation=replace(CFG.simulation, channel_phase_std_deg=45.0, channel_gain_std_db=1.5))
    tmp = tmp_path_factory.mktemp("channels")
    sim = simulate("ci", tmp / "ci.mcap", seed=7, config=cfg, dynamics="kinematic")
    drive = tmp / "drive.h5"
    ingest([sim.log_path], drive, config=CFG)
    with Drive(drive) as d:
        origin = load_inputs(d, CFG).origin
    with h5py.File(sim.truth_path) as f:
        true = 10 ** (f.attrs["channel_gain_db"] / 20) * np.exp(1j * np.radians(f.attrs["channel_phase_deg"]))
    return drive, load_truth(sim.truth_path, origin, CFG), true


def measured(drive: Path, trajectory: Any) -> Any:
    focus = FocusOptions.from_config(CFG)
    points = candidate_points(drive, trajectory, CFG, focus, AutofocusOptions())
    return measure_channel_gains(drive, trajectory, CFG, points, focus)


def test_an_uncalibrated_front_end_is_measured_on_the_drives_points(mismatched_ci: tuple[Path, Any, Any]) -> None:
    drive, truth, true = mismatched_ci
    cal = measured(drive, replace(truth.trajectory, info={}))
    assert cal.applied and cal.gains is not None and cal.points_used >= 2
    assert cal.phase_rms_deg > 15.0 and cal.peak_loss_db > 0.3
    g = np.array([cal.gains.complex()[t, r] for t, r in PAIRS])
    want = np.array([true[t, r] for t, r in PAIRS])
    err = g / want
    err /= np.exp(1j * np.angle(err.sum())) * np.exp(np.mean(np.log(np.abs(err))))
    assert np.degrees(np.abs(np.angle(err))).max() < 3.0
    assert np.abs(20 * np.log10(np.abs(err))).max() < 0.15


def test_matched_channels_are_left_as_they_are(ci_mcap: Any, tmp_path: Path) -> None:
    drive = tmp_path / "drive.h5"
    ingest([ci_mcap.log_path], drive, config=CFG)
    with Drive(drive) as d:
        origin = load_inputs(d, CFG).origin
    cal = measured(drive, load_truth(ci_mcap.truth_path, origin, CFG).trajectory)
    assert cal.gains is not None and not cal.applied and "as matched" in cal.reason
    assert cal.phase_rms_deg < 3.0 and cal.gain_rms_db < 0.3


def test_focus_undoes_the_measured_gains(mismatched_ci: tuple[Path, Any, Any]) -> None:
    """The image's brightest point: 1 dB or so down with the channels as recorded, within 0.05 dB of the image
    focused with the true gains once the measured ones are undone."""
    drive, truth, _ = mismatched_ci
    plain = replace(truth.trajectory, info={})
    cal = measured(drive, plain)
    opts = FocusOptions.from_config(CFG)

    def peak_db(traj: Any, options: FocusOptions) -> float:
        image = focus_images(drive, traj, CFG, options).images[0]
        assert image.params["channel_gains"] == (None if traj.info.get("channel_gains") is None
                                                 and options.channel_gains is None else image.params["channel_gains"])
        return float(20 * np.log10(np.abs(image.image).max()))

    ideal = peak_db(truth.trajectory, opts)  # the truth carries the true gains in its info
    assert peak_db(plain, opts) < ideal - 0.4
    assert abs(peak_db(plain, replace(opts, channel_gains=cal.gains)) - ideal) < 0.05


def test_gains_the_drive_states_are_kept_where_the_points_agree(mismatched_ci: tuple[Path, Any, Any],
                                                                 tmp_path: Path) -> None:
    """A drive whose radar states its true gains (as a TI capture's calibration does): the measurement agrees
    and keeps them; stating matched channels instead, it measures and applies its own."""
    import shutil

    from autosar_cli.sar.channel_calibration import with_stated_gains

    drive, truth, true = mismatched_ci
    stated = tmp_path / "stated.h5"
    shutil.copy(drive, stated)
    with h5py.File(stated, "r+") as f:
        radar = f["radar"][next(iter(f["radar"]))]
        radar.attrs["channel_phase_deg"] = np.degrees(np.angle(true))
        radar.attrs["channel_gain_db"] = 20 * np.log10(np.abs(true))
    plain = replace(truth.trajectory, info={})
    focus = with_stated_gains(stated, FocusOptions.from_config(CFG))
    assert focus.channel_gains is not None
    points = candidate_points(stated, plain, CFG, focus, AutofocusOptions())
    cal = measure_channel_gains(stated, plain, CFG, points, focus)
    assert not cal.applied and "the gains the drive states" in cal.reason and cal.phase_rms_deg < 3.0
    cal = measure_channel_gains(stated, plain, CFG, points, replace(focus, channel_gains=ChannelGains(
        ((0.0,) * 4,) * 3, ((0.0,) * 4,) * 3)))
    assert cal.applied
