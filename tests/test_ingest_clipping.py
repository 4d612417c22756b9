"""A radar front end driven to the ADC's full scale (a strong reflector close by): ingest counts, per radar stream,
the samples at full scale and the frames that hold any, and says so in one warning line."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from conftest import realdata
from typer.testing import CliRunner

from autosar_cli.cli import app
from autosar_cli.config import load_config
from autosar_cli.ingest.dca1000 import params_from_radar, write_capture
from autosar_cli.ingest.decoders import frame_statistics
from autosar_cli.ingest.pipeline import ingest
from autosar_cli.sim.simulate import SimulationResult, simulate
from autosar_cli.store.drive import Drive

CFG = load_config()
START = "2024-05-01T10:00:00Z"


def radar_stream(streams: list[dict]) -> dict:
    (radar,) = [s for s in streams if s["kind"] == "radar"]
    return radar


@pytest.fixture(scope="module")
def loud_ci(tmp_path_factory: pytest.TempPathFactory) -> SimulationResult:
    """The ci drive (seed 7) with the echoes 30x the config's (radar_amplitude_lsb 45000): its strongest echoes
    drive the int16 ADC to full scale in 551 of its 981 frames (the simulator clips at -32768/32767)."""
    cfg = dataclasses.replace(CFG, simulation=dataclasses.replace(CFG.simulation, radar_amplitude_lsb=45000.0))
    return simulate("ci", tmp_path_factory.mktemp("loud") / "ci_loud.mcap", seed=7, config=cfg,
                    dynamics="kinematic")


def test_a_clipping_radar_is_counted_and_said(loud_ci: SimulationResult, tmp_path: Path) -> None:
    report = ingest([loud_ci.log_path], tmp_path / "loud.h5", config=CFG)
    with Drive(tmp_path / "loud.h5") as d:
        raw = d.radar().raw[()]
    at_full = np.count_nonzero((raw == -32768) | (raw == 32767), axis=(1, 2, 3, 4))
    radar = radar_stream(report.streams)
    assert (radar["full_scale_frames"], radar["full_scale_samples"]) == (551, 74926)
    assert (np.count_nonzero(at_full), int(at_full.sum())) == (551, 74926)  # the stored cube's, counted here
    assert radar["adc_full_scale"] == [-32768, 32767] and radar["written"] == 981
    hits = [w for w in report.warnings if "full scale" in w]
    assert hits == ["radar/scanbrick_w43: 551 of 981 frames hold samples at the ADC's full scale (74926 samples at "
                    "-32768 or 32767; clipped: a reflector too strong or too close; the image may hold ghosts)"]


def test_a_clean_drive_holds_no_sample_at_full_scale(ci_mcap: SimulationResult, tmp_path: Path) -> None:
    """The config's ci drive peaks at ~1700 of 32767: none counted, nothing said."""
    report = ingest([ci_mcap.log_path], tmp_path / "clean.h5", config=CFG)
    radar = radar_stream(report.streams)
    assert (radar["full_scale_frames"], radar["full_scale_samples"]) == (0, 0)
    assert not any("full scale" in w for w in report.warnings), report.warnings


def test_a_12_bit_capture_clips_at_its_own_full_scale(tmp_path: Path) -> None:
    """A 12-bit DCA1000 capture's full scale is -2048/2047 (sign-extended from its words): a tone whose amplitude
    swells past it over the middle PRIs is counted there, PRI by PRI (a capture's frames are its PRIs)."""
    p = dataclasses.replace(params_from_radar(CFG.radar, lanes=2), adc_bits=12)
    rng = np.random.default_rng(12)
    n = 150
    amplitude = 1200 + 1200 * np.sin(np.pi * np.arange(n) / (n - 1))  # 1200 at the ends, 2400 in the middle
    phase = 2 * np.pi * (0.1 * np.arange(540) + rng.uniform(0, 1, (3, 4, 1)))
    tone = amplitude[:, None, None, None, None] * np.stack([np.cos(phase), np.sin(phase)], axis=-1)
    pris = np.clip(np.rint(tone + rng.normal(0, 5, tone.shape)), -2048, 2047).astype(np.int16)
    at_full = np.count_nonzero((pris == -2048) | (pris == 2047), axis=(1, 2, 3, 4))
    assert (np.count_nonzero(at_full), int(at_full.sum())) == (76, 265117)
    write_capture(tmp_path / "cap", p, [pris])
    r = CliRunner().invoke(app, ["ingest", "--radar", str(tmp_path / "cap"), "--radar-start", START,
                                 "--allow-partial", "-o", str(tmp_path / "d.h5")])
    assert r.exit_code == 0, r.stderr
    assert "76 of 150 frames hold samples at the ADC's full scale (265117 samples at -2048 or 2047; clipped" \
        in r.stderr, r.stderr
    assert "crest factor" not in r.stderr, r.stderr  # a clipped frame is not a damaged one


def test_real_ti_frames_hold_no_sample_at_full_scale() -> None:
    """OpenRadar's real TI frame (16-bit ADC, 128 loops of 2 Tx x 4 Rx, 128 samples): its samples peak at 265 of
    32767 (42 dB under full scale), none counted."""
    frames = np.load(realdata("openradar", "doppler_example_1.npy"))
    iq = np.stack([frames.real.astype(np.int16), frames.imag.astype(np.int16)], axis=-1).reshape(128, 2, 4, 128, 2)
    stats = frame_statistics(np.arange(128), iq, 16)
    assert int(stats[:, 1].max()) == 265 and stats[:, 3].sum() == 0
    iq[5, 1, 2, 7] = (-32768, 32767)  # two samples of one PRI at full scale
    assert frame_statistics(np.arange(128), iq, 16)[:, 3].tolist() == [0] * 5 + [2] + [0] * 122
