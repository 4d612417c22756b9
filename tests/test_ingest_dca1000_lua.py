"""DCA1000 captures configured by an mmWave Studio Lua script (``ar1.ProfileConfig(...)`` ...) instead of its JSON."""

from __future__ import annotations

import dataclasses
from decimal import Decimal
from pathlib import Path

import numpy as np
import pytest
from test_ingest_dca1000 import CFG, assert_one_line_error, cli_ingest

from autosar_cli.ingest.dca1000 import ADC_FORMATS, CaptureParams, Dca1000Capture, params_from_radar, write_capture
from autosar_cli.ingest.dca1000_lua import parse_studio_lua
from autosar_cli.ingest.dca1000_params import ADC_BITS, _in_unit, _ramp_end_us

#: TI's DataCaptureDemo_xWR.lua configures an AWR1243 so (its own comment reads the profile's arguments: profile id,
#: start frequency, idle time, ADC start time, ramp end time, six Tx back-offs and phases, the slope 29.982, Tx start
#: time, 256 ADC samples, 10000 ksps, the high-pass corners and the gain 30)
TI_DEMO = """\
-- mmWave Studio: AWR1243, one Tx, four Rx
if (ar1.ChanNAdcConfig(1, 0, 0, 1, 1, 1, 1, 2, 1, 0) == 0) then
    WriteToLog("ChanNAdcConfig Success\\n", "green")
end
ar1.DataPathConfig(1, 1, 0)
ar1.LvdsClkConfig(1, 1)
ar1.LVDSLaneConfig(0, 1, 1, 1, 1, 1, 0, 0)
--[[ a profile left from another device:
ar1.ProfileConfig(0, 60, 100, 6, 60, 0, 0, 0, 0, 0, 0, 29.982, 0, 256, 10000, 0, 0, 30)
]]
if(ar1.ProfileConfig(0, 77, 100, 6, 60, 0, 0, 0, 0, 0, 0, 29.982, 0, 256, 10000, 0, 0, 30) == 0) then
    WriteToLog("ProfileConfig Success\\n", "green")
end
ar1.ChirpConfig(0, 0, 0, 0, 0, 0, 0, 1, 0, 0)  -- chirp 0 on Tx0
ar1.FrameConfig(0, 0, 8, 128, 40, 0, 0, 1)
ar1.CaptureCardConfig_Mode(1, 1, 1, 2, 3, 30)
"""


def test_ti_demo_script_reads_as_its_arguments_say(tmp_path: Path) -> None:
    """The arguments by position as TI documents them: 77 GHz, 100 us idle, 6 us ADC start, 60 us ramp end,
    29.982 MHz/us, 256 samples at 10 Msps, 128 loops of Tx0 in 8 frames of 40 ms, 4 lanes of complex 16-bit."""
    script = tmp_path / "DataCaptureDemo_xWR.lua"
    script.write_text(TI_DEMO)
    p = parse_studio_lua(script)
    assert (p.profile_start_frequency_hz, p.adc_start_s, p.chirp_period_s) == (77e9, 6e-6, 160e-6)
    assert (p.slope_hz_per_s, p.num_samples, p.sample_rate_hz) == (29.982e12, 256, 10e6)
    assert (p.chirp_tx, p.rx_channels, p.num_loops, p.num_frames, p.frame_period_s) == ((0,), (0, 1, 2, 3), 128, 8,
                                                                                         0.04)
    assert (p.lanes, p.adc_format, p.adc_bits, p.hardware_trigger) == (4, "complex1x", 16, False)
    assert p.start_frequency_hz == pytest.approx(77e9 + 29.982e12 * 6e-6, abs=1.0)  # at the first ADC sample
    assert p.bandwidth_hz == pytest.approx(29.982e12 * 25.6e-6)


def studio_lua(p: CaptureParams) -> str:
    """``p`` as mmWave Studio's Lua calls, its profile values given through variables as scripts often do."""
    ramp = _ramp_end_us(p)
    idle = Decimal(_in_unit(p.chirp_period_s, -6)) - ramp
    tx = [int(t in p.chirp_tx) for t in range(3)]
    rx = [int(r in p.rx_channels) for r in range(4)]
    lanes = "1, 1, 1, 1" if p.lanes == 4 else "1, 1, 0, 0"
    chirps = "\n".join(f"ar1.ChirpConfig({k}, {k}, 0, 0, 0, 0, 0, {int(t == 0)}, {int(t == 1)}, {int(t == 2)})"
                       for k, t in enumerate(p.chirp_tx))
    return f"""\
start_freq = {_in_unit(p.profile_start_frequency_hz, 9)}
slope = {_in_unit(p.slope_hz_per_s, 12)}
adc_samples = {p.num_samples}
ar1.ChanNAdcConfig({', '.join(map(str, tx + rx))}, {ADC_BITS.index(p.adc_bits)}, {ADC_FORMATS.index(p.adc_format)}, 0)
ar1.LVDSLaneConfig(0, {lanes}, 1, 0, 0)
ar1.DataPathConfig(1, 1, 0)
ar1.ProfileConfig(0, start_freq, {idle}, {_in_unit(p.adc_start_s, -6)}, {ramp}, 0, 0, 0, 0, 0, 0, slope, 0, \
adc_samples, {_in_unit(p.sample_rate_hz, 3)}, 0, 0, 30)
{chirps}
ar1.FrameConfig(0, {p.num_tx - 1}, {p.num_frames}, {p.num_loops}, {_in_unit(p.frame_period_s, -3)}, 0, 0, 1)
ar1.CaptureCardConfig_Mode(1, {1 if p.lanes == 4 else 2}, 1, 2, {ADC_BITS.index(p.adc_bits) + 1}, 30)
"""


@pytest.mark.parametrize("lanes", [4, 2])
def test_a_capture_configured_by_its_lua_script_reads_as_by_its_json(tmp_path: Path, lanes: int) -> None:
    """The config's radar (3 Tx in the order 0, 2, 1, 4 Rx) captured, its parameters given by the mmWave Studio JSON
    and by the Lua script that set the same: the same parameters, the same PRIs."""
    p = dataclasses.replace(params_from_radar(CFG.radar, lanes=lanes), chirp_tx=(0, 2, 1))
    pris = np.random.default_rng(3).integers(-800, 800, (2 * p.num_loops, 3, 4, p.num_samples, 2), dtype=np.int16)
    write_capture(tmp_path, p, [pris], param_format="json")
    by_json = Dca1000Capture(tmp_path)
    for twin in tmp_path.glob("*.json"):
        twin.unlink()
    (tmp_path / "capture.lua").write_text(studio_lua(p))
    by_lua = Dca1000Capture(tmp_path)
    assert dataclasses.replace(by_lua.params, source="") == dataclasses.replace(by_json.params, source="")
    np.testing.assert_array_equal(np.concatenate([b for _, b, _ in by_lua.blocks()]), pris)
    code, stderr = cli_ingest(tmp_path, tmp_path / "d.h5", "--radar-override")  # the config's chirps: Tx 0, 1, 2
    assert code == 0, stderr


@pytest.mark.parametrize(("edit", "needle"), [
    (("start_freq = 77", "start_freq = 77\nstart_freq = 78"), "line 8: ar1.ProfileConfig argument 'start_freq': "
                                                              "assigned several values"),
    (("slope, 0, adc_samples", "slope * 2, 0, adc_samples"), "argument 'slope * 2': no number the script assigns"),
    (("ar1.FrameConfig(", "ar1.ProfileConfig(1, 60, 7, 6, 60, 0, 0, 0, 0, 0, 0, 29.982, 0, 256, 10000, 0, 0, 30)\n"
                          "ar1.FrameConfig("), "ar1.ProfileConfig with other arguments on lines 7, 11; keep the call"),
    (("ar1.FrameConfig(", "ar1.ChirpConfig(1, 1, 0, 0, 0, 0, 0, 0, 1, 0)\nar1.FrameConfig("),
     "chirp 1 configured otherwise on lines 9 and 11 (ar1.ChirpConfig)"),
    (("1, 2, 1, 0)\n", "1, 2, 1, 1)\n"), "ar1.ChanNAdcConfig swaps I and Q (iqSwap 1)"),
    (("ar1.CaptureCardConfig_Mode(1, 1,", "ar1.CaptureCardConfig_Mode(1, 2,"),
     "ar1.CaptureCardConfig_Mode's lvdsMode is 2 (2 lanes) but the device of capture.lua sends 4"),
    (("ar1.CaptureCardConfig_Mode(1,", "ar1.CaptureCardConfig_Mode(2,"), "dataLoggingMode is '2 (not raw)'"),
    (("ar1.DataPathConfig(1, 1, 0)", "ar1.DataPathConfig(1, 6, 0)"), "sends transferFmtPkt0 0x6"),
    (("ar1.FrameConfig(", "ar1.AdvanceFrameConfig(1, 0, 0)\nar1.FrameConfig("), "configures advanced frames"),
    (("ar1.FrameConfig(0, 2,", "ar1.FrameConfig(0, 3,"), "frame uses chirp 3, which no chirp configuration defines"),
])
def test_lua_scripts_that_cannot_be_read_as_one_capture_are_refused(tmp_path: Path, edit: tuple[str, str],
                                                                    needle: str) -> None:
    """A value the reader cannot evaluate, a script that configures two devices by branch, a layout or waveform not
    read here: each a one-line error naming the script (and the line), not a guess."""
    p = dataclasses.replace(params_from_radar(CFG.radar, lanes=4), chirp_tx=(0, 2, 1))
    write_capture(tmp_path, p, [np.ones((2, 3, 4, p.num_samples, 2), dtype=np.int16)], param_format="json")
    for twin in tmp_path.glob("*.json"):
        twin.unlink()
    text = studio_lua(p)
    assert text.count(edit[0]) == 1, edit[0]
    (tmp_path / "capture.lua").write_text(text.replace(edit[0], edit[1]))
    assert_one_line_error(*cli_ingest(tmp_path, tmp_path / "d.h5"), "capture.lua: ", needle)
    assert not (tmp_path / "d.h5").exists()


def test_a_script_named_as_the_capture_is_the_one_read_beside_others(tmp_path: Path) -> None:
    """mmWave Studio's scripts often lie together: the folder alone is refused naming them, the script named as
    CAPTURE is read with its folder's data."""
    p = params_from_radar(CFG.radar, lanes=4)
    pris = np.random.default_rng(4).integers(-800, 800, (p.num_loops, 3, 4, p.num_samples, 2), dtype=np.int16)
    write_capture(tmp_path, p, [pris], param_format="json")
    for twin in tmp_path.glob("*.json"):
        twin.unlink()
    (tmp_path / "capture.lua").write_text(studio_lua(p))
    (tmp_path / "other_device.lua").write_text(TI_DEMO)
    assert_one_line_error(*cli_ingest(tmp_path, tmp_path / "d.h5"), "several parameter files (capture.lua, "
                          "other_device.lua); give the capture's as CAPTURE")
    code, stderr = cli_ingest(tmp_path / "capture.lua", tmp_path / "d.h5")
    assert code == 0, stderr
    np.testing.assert_array_equal(np.concatenate([b for _, b, _ in Dca1000Capture(tmp_path / "capture.lua").blocks()]),
                                  pris)


def test_the_config_sketch_of_a_capture_is_a_config_it_ingests_with(tmp_path: Path) -> None:
    """`autosar info CAPTURE --config-sketch` of TI's demo capture (one Tx of the board, 256 samples at 10 Msps,
    29.982 MHz/us, 128 loops in 40 ms frames): a config that loads and that the capture ingests with, where the
    default config stops naming seven keys that differ."""
    from typer.testing import CliRunner

    from autosar_cli.cli import app

    script = tmp_path / "DataCaptureDemo_xWR.lua"
    script.write_text(TI_DEMO)
    p = dataclasses.replace(parse_studio_lua(script), num_frames=2)
    pris = np.random.default_rng(4).integers(-500, 500, (256, 1, 4, 256, 2), dtype=np.int16)
    write_capture(tmp_path / "cap", p, [pris], param_format="json")
    code, stderr = cli_ingest(tmp_path / "cap", tmp_path / "d.h5")
    assert code == 1 and stderr.count("but the config's") == 7, stderr
    r = CliRunner().invoke(app, ["info", str(tmp_path / "cap"), "--config-sketch"])
    assert r.exit_code == 0, r.output
    assert "num_tx = 1\n" in r.stdout and "tx_channels = [0]" in r.stdout and "prf_hz = 3200.0" in r.stdout
    (tmp_path / "sketch.toml").write_text(r.stdout)
    code, stderr = cli_ingest(tmp_path / "cap", tmp_path / "d.h5", "--config", str(tmp_path / "sketch.toml"))
    assert code == 0, stderr
    # over a base that names the board's antennas in use (Tx 0 and 2), the sketch of a 3-Tx capture names all three
    base = tmp_path / "base.toml"
    base.write_text('base = "default"\n\n[radar]\nnum_tx = 2\ntx_channels = [0, 2]\n')
    p3 = dataclasses.replace(params_from_radar(CFG.radar), num_frames=2)
    three = np.random.default_rng(5).integers(-500, 500, (2, 3, 4, 540, 2), dtype=np.int16)
    write_capture(tmp_path / "cap3", p3, [three], param_format="json")
    r = CliRunner().invoke(app, ["info", str(tmp_path / "cap3"), "--config-sketch", "--config", str(base)])
    assert r.exit_code == 0 and "tx_channels = [0, 1, 2]" in r.stdout, r.output
    (tmp_path / "sketch3.toml").write_text(r.stdout)
    code, stderr = cli_ingest(tmp_path / "cap3", tmp_path / "d3.h5", "--config", str(tmp_path / "sketch3.toml"))
    assert code == 0, stderr
