"""TI DCA1000 captures: every layout against an independent encoder written from TI's app note (SWRA581),
malformed sizes and recording/config contradictions through the CLI, the simulated drive as capture +
navigation MCAP against its RawFrame form, and OpenRadar's real TI frames through the product's range
compression."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import realdata
from typer.testing import CliRunner

from autosar_cli.cli import app
from autosar_cli.config import load_config
from autosar_cli.ingest.dca1000 import (
    ADC_FORMATS,
    CaptureError,
    CaptureParams,
    Dca1000Capture,
    params_from_radar,
    write_capture,
)
from autosar_cli.ingest.dca1000_packets import packets_of
from autosar_cli.ingest.decoders import frame_statistics, implausible_frames
from autosar_cli.store.drive import Drive

CFG = load_config()
runner = CliRunner()
START = "2024-05-01T10:00:00Z"


def app_note_bytes(pris: np.ndarray, p: CaptureParams) -> bytes:
    """The file TI's app note describes, value by value: frames, loops, chirps in chirp-table order; 4-lane:
    per sample I of lanes 1-4 then Q of lanes 1-4 (real: the 4 lanes), unused lanes 0; 2-lane: per Rx its
    samples, complex as I(n) I(n+1) Q(n) Q(n+1)."""
    vals: list[int] = []
    tx_axis = sorted(p.chirp_tx)
    for pri in pris:  # one loop of the chirp table each
        for tx in p.chirp_tx:
            c = pri[tx_axis.index(tx)]  # (rx, sample, I/Q)
            if p.lanes == 4:
                for s in range(p.num_samples):
                    for part in ((0, 1) if p.complex else (0,)):
                        for lane in range(4):
                            vals.append(int(c[p.rx_channels.index(lane), s, part]) if lane in p.rx_channels
                                        else 0)
            else:
                for r in range(p.num_rx):
                    if p.complex:
                        for s in range(0, p.num_samples, 2):
                            vals += [int(c[r, s, 0]), int(c[r, s + 1, 0]), int(c[r, s, 1]), int(c[r, s + 1, 1])]
                    else:
                        vals += [int(c[r, s, 0]) for s in range(p.num_samples)]
    return np.asarray(vals, dtype="<i2").tobytes()


def small_params(lanes: int, fmt: str, chirp_tx: tuple[int, ...], rx: tuple[int, ...], loops: int) -> CaptureParams:
    return CaptureParams(profile_start_frequency_hz=77e9, slope_hz_per_s=30e12, sample_rate_hz=5e6, num_samples=8,
                         adc_start_s=0.0, chirp_period_s=20e-6, rx_channels=rx, chirp_tx=chirp_tx, num_loops=loops,
                         num_frames=0, frame_period_s=1e-3, adc_format=fmt, lanes=lanes)


@pytest.mark.parametrize("fmt", ADC_FORMATS)
@pytest.mark.parametrize("lanes", [2, 4])
@pytest.mark.parametrize("chirp_tx", [(0,), (1, 0), (2, 0, 1)])
def test_layout_round_trips(tmp_path: Path, fmt: str, lanes: int, chirp_tx: tuple[int, ...]) -> None:
    rx = (0, 1, 3) if lanes == 4 else (0, 1, 2, 3)  # a disabled lane stays in the 4-lane layout
    p = small_params(lanes, fmt, chirp_tx, rx, loops=2)
    rng = np.random.default_rng(len(chirp_tx) * 10 + lanes)
    pris = rng.integers(-32768, 32768, (3 * 2, len(chirp_tx), len(rx), 8, 2), dtype=np.int16)
    if fmt == "real":
        pris[..., 1] = 0
    # the writer writes the app note's bytes, split across files mid-frame (JSON) or as adc_data.bin (.cfg)
    param_format = "json" if lanes == 4 or len(chirp_tx) == 2 else "cfg"
    files = write_capture(tmp_path, p, [pris[:2], pris[2:]], param_format=param_format,
                          split_bytes=p.frame_bytes + 2 if param_format == "json" else 0)
    assert b"".join(f.read_bytes() for f in files) == app_note_bytes(pris, p)
    assert len(files) > 1 or param_format == "cfg"
    cap = Dca1000Capture(tmp_path)
    assert (cap.params.lanes, cap.params.adc_format, cap.params.chirp_tx) == (lanes, fmt, chirp_tx)
    got = np.concatenate([b for _, b, _ in cap.blocks(frames_per_block=2)])
    np.testing.assert_array_equal(got, pris)
    # frame times: frame periodicity, then one loop (num_tx chirp slots) per PRI within the frame
    t = cap.pri_times_ns(cap.frame_starts_ns(1_000))
    np.testing.assert_array_equal(t[:4], [1_000, 1_000 + 20_000 * len(chirp_tx), 1_001_000,
                                          1_001_000 + 20_000 * len(chirp_tx)])


@pytest.mark.parametrize("bits", [12, 14])
def test_narrow_adc_samples_are_sign_extended(tmp_path: Path, bits: int) -> None:
    """12/14-bit samples sit unextended in the low bits of each int16 (SWRA581's readers sign-extend them)."""
    p = dataclasses.replace(small_params(2, "complex1x", (0, 1), (0, 1, 2, 3), loops=1), adc_bits=bits)
    rng = np.random.default_rng(bits)
    pris = rng.integers(-(1 << (bits - 1)), 1 << (bits - 1), (4, 2, 4, 8, 2), dtype=np.int16)
    files = write_capture(tmp_path, p, [pris])
    unsigned = np.frombuffer(app_note_bytes(pris, p), dtype="<i2").astype(np.int64) % (1 << bits)
    np.testing.assert_array_equal(np.fromfile(files[0], dtype="<i2"), unsigned)
    cap = Dca1000Capture(tmp_path)
    assert cap.params.adc_bits == bits
    np.testing.assert_array_equal(np.concatenate([b for _, b, _ in cap.blocks()]), pris)


@pytest.mark.parametrize("written, stated", [(12, 16), (14, 16), (16, 12), (16, 14)])
def test_adc_words_of_other_bits_than_the_parameters_give_are_refused(tmp_path: Path, written: int,
                                                                      stated: int) -> None:
    """Unextended 12/14-bit words read as the 16-bit samples the .cfg states would wrap every negative sample; 16-bit
    ones read as 12/14-bit would be sign-extended wrong: each is a one-line error naming the data, the parameter file
    and the words that contradict it."""
    p = dataclasses.replace(small_params(2, "complex1x", (0, 1), (0, 1, 2, 3), loops=1), adc_bits=written)
    pris = np.random.default_rng(written).integers(-(1 << (written - 1)), 1 << (written - 1), (4, 2, 4, 8, 2),
                                                   dtype=np.int16)
    write_capture(tmp_path, p, [pris])
    cfg = tmp_path / "capture.cfg"
    codes = {12: 0, 14: 1, 16: 2}
    cfg.write_text(cfg.read_text().replace(f"adcCfg {codes[written]} 1", f"adcCfg {codes[stated]} 1"))
    r = runner.invoke(app, ["info", str(tmp_path)])
    needle = "none negative and none above" if stated == 16 else "holds the word"
    assert_one_line_error(r.exit_code, r.stderr, f"{tmp_path / 'adc_data.bin'}: capture.cfg gives {stated}-bit ADC "
                          "samples", needle, "State the ADC's bits")


@pytest.mark.parametrize("bits, low, high", [(16, 150, 450), (16, 2100, 2900), (12, 1800, 2048)])
def test_a_quiet_capture_with_a_dc_offset_reads(tmp_path: Path, bits: int, low: int, high: int) -> None:
    """A quiet scene's samples about an ADC's DC offset (16-bit: 150..449 or 2100..2899, none negative; 12-bit:
    1800..2047) are its bits' samples: read as they are. Words none negative and below 2^14 are unextended narrower
    samples only where they lie near both 0 and the top of the narrower range (the negative ones wrapped)."""
    p = dataclasses.replace(small_params(2, "complex1x", (0, 1), (0, 1, 2, 3), loops=1), adc_bits=bits)
    pris = np.random.default_rng(bits).integers(low, high, (4, 2, 4, 8, 2), dtype=np.int16)
    write_capture(tmp_path, p, [pris])
    cap = Dca1000Capture(tmp_path)
    np.testing.assert_array_equal(np.concatenate([b for _, b, _ in cap.blocks()]), pris)


def sdk_cfg(tmp_path: Path, **change: str) -> Path:
    """A capture matching the default config, as an mmWave SDK .cfg (2-lane), with edited command lines."""
    p = params_from_radar(CFG.radar, lanes=2)
    rng = np.random.default_rng(1)
    pris = rng.integers(-500, 500, (3, 3, 4, 540, 2), dtype=np.int16)
    write_capture(tmp_path, p, [pris])
    cfg = tmp_path / "capture.cfg"
    lines = cfg.read_text().splitlines()
    for cmd, value in change.items():
        lines = [f"{cmd} {value}" if ln.split(" ", 1)[0] == cmd else ln for ln in lines]
    cfg.write_text("\n".join(lines) + "\n")
    return tmp_path


def cli_ingest(capture: Path, out: Path, *extra: str) -> tuple[int, str]:
    r = runner.invoke(app, ["ingest", "--radar", str(capture), "--radar-start", START, "--allow-partial",
                            "-o", str(out), *extra])
    return r.exit_code, r.stderr


def assert_one_line_error(code: int, stderr: str, *needles: str) -> None:
    assert code == 1, stderr
    assert stderr.strip().count("\n") == 0 and "Traceback" not in stderr, stderr
    for needle in needles:
        assert needle in stderr, (needle, stderr)


def test_sdk_cfg_capture_ingests_with_recorded_parameters(tmp_path: Path) -> None:
    cap = sdk_cfg(tmp_path / "cap")
    code, stderr = cli_ingest(cap, tmp_path / "d.h5")
    assert code == 0, stderr
    with Drive(tmp_path / "d.h5") as d:
        r = d.radar()
        assert r.raw.shape == (3, 3, 4, 540, 2)
        assert r.t_ns[1] - r.t_ns[0] == round(1e9 / 990.0)
        assert r.t_ns[0] == 1714557600 * 10**9  # START
        src = json.loads(r.attrs["parameter_sources"])
        assert src["slope_hz_per_s"] == "recording" and src["tx_positions_m"] == "config"
        assert r.attrs["lvds_lanes"] == 2 and r.attrs["prf_hz"] == pytest.approx(990.0)
    r = runner.invoke(app, ["info", str(tmp_path / "d.h5")])
    assert r.exit_code == 0 and "radar parameter" in r.stdout and "recording" in r.stdout
    r = runner.invoke(app, ["info", str(cap), "--json"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert d["container"].startswith("TI DCA1000 capture (2-lane complex1x") and d["streams"][0]["count"] == 3
    assert d["radar_parameters"]["num_samples"] == {"value": 540, "source": "recording"}
    # batch pairs one capture with each log
    r = runner.invoke(app, ["batch", str(cap), "--radar", str(cap), "--radar", str(cap), "-o", str(tmp_path / "b")])
    assert_one_line_error(r.exit_code, r.stderr, "--radar given 2 times for 1 logs")


@pytest.mark.parametrize(("change", "needles"), [
    ({"channelCfg": "15 3 0", "chirpCfg": "0 0 0 0 0 0 0 1\nchirpCfg 1 1 0 0 0 0 0 2",
      "frameCfg": "0 1 1 0 1.01010101010101 1 0"}, ["num_tx is 2", "radar.num_tx is 3"]),
    ({"channelCfg": "7 7 0"}, ["num_rx is 3", "radar.num_rx is 4"]),
    ({"profileCfg": "0 77 20 0 40 0 0 75 0 512 13500 0 0 30"}, ["num_samples is 512", "radar.num_samples is 540"]),
    ({"profileCfg": "0 77 20 0 40 0 0 16.75 0 540 13500 0 0 30"},
     ["670000000 (slope x ADC window)", "radar.bandwidth_hz is 3e+09"]),
    ({"frameCfg": "0 2 1 0 1 1 0"}, ["prf_hz is 1000", "radar.prf_hz is 990"]),
    ({"profileCfg": "0 77 30 0 40 0 0 75 0 540 13500 0 0 30"}, ["tx_start_offsets_s"]),
])
def test_contradictions_are_one_line_errors(tmp_path: Path, change: dict[str, str], needles: list[str]) -> None:
    cap = sdk_cfg(tmp_path / "cap", **change)
    code, stderr = cli_ingest(cap, tmp_path / "d.h5")
    assert_one_line_error(code, stderr, str(cap), "--radar-override", *needles)
    assert not (tmp_path / "d.h5").exists()


@pytest.mark.parametrize(("field", "value", "needle"), [
    ("iqSwapSel", 1, "iqSwapSel is 1 (Q before I)"),
    ("chInterleave", 1, "chInterleave is 1 on a 4-lane device; its DCA1000 layout is interleaved (0)"),
    ("transferFmtPkt0", "0x6", "transferFmtPkt0 is 0x6: the capture holds more than ADC data"),
])
def test_studio_json_layouts_that_are_not_read_are_refused(tmp_path: Path, field: str, value: object,
                                                          needle: str) -> None:
    """mmWave Studio states how the DCA1000 stream is laid out; a layout other than those read here (TI's
    rawDataReader's rules: I first, 4 lanes interleaved, 2 lanes not, ADC data alone) is a one-line error, not
    samples read in the wrong order."""
    p = params_from_radar(CFG.radar, lanes=4)
    write_capture(tmp_path, p, [np.ones((2, 3, 4, 540, 2), dtype=np.int16)], param_format="json")
    js = tmp_path / "capture.mmwave.json"
    doc = json.loads(js.read_text())
    capture = doc["mmWaveDevices"][0]["rawDataCaptureConfig"]
    (capture.setdefault("rlDevDataPathCfg_t", {}) if field == "transferFmtPkt0"
     else capture["rlDevDataFmtCfg_t"])[field] = value
    js.write_text(json.dumps(doc))
    assert_one_line_error(*cli_ingest(tmp_path, tmp_path / "d.h5"), needle, "capture.mmwave.json")


@pytest.mark.parametrize(("change", "needle"), [
    ({"dataLoggingMode": "multi"}, "DCA1000Config.dataLoggingMode is 'multi'; only raw captures"),
    ({"lvdsMode": 2}, "DCA1000Config.lvdsMode is 2 (2 lanes) but the device of capture.mmwave.json sends 4"),
])
def test_the_setup_json_twin_must_agree(tmp_path: Path, change: dict[str, object], needle: str) -> None:
    """mmWave Studio's ``*.setup.json`` says how the DCA1000 logged: a multi-mode capture, or one logged over
    other LVDS lanes than the device sends, is a one-line error naming the twin."""
    write_capture(tmp_path, params_from_radar(CFG.radar, lanes=4), [np.ones((2, 3, 4, 540, 2), dtype=np.int16)],
                  param_format="json")
    setup = tmp_path / "capture.setup.json"
    doc = json.loads(setup.read_text())
    doc["DCA1000Config"].update(change)
    setup.write_text(json.dumps(doc))
    assert_one_line_error(*cli_ingest(tmp_path, tmp_path / "d.h5"), needle, "capture.setup.json")


#: the DCA1000 CLI's cf.json as TI's user guide gives it, for a 2-lane device sending 16-bit samples
CLI_CF_JSON = {"DCA1000Config": {
    "dataLoggingMode": "raw", "dataTransferMode": "LVDSCapture", "dataCaptureMode": "ethernetStream", "lvdsMode": 2,
    "dataFormatMode": 3, "packetDelay_us": 25,
    "ethernetConfig": {"DCA1000IPAddress": "192.168.33.180", "DCA1000ConfigPort": 4096, "DCA1000DataPort": 4098},
    "captureConfig": {"fileBasePath": "C:\\capture", "filePrefix": "adc_data", "maxRecFileSize_MB": 1024,
                      "sequenceNumberEnable": 1, "captureStopMode": "infinite"}}}


@pytest.mark.parametrize(("change", "needle"), [
    ({}, ""),
    ({"dataFormatMode": 1}, "cf.json: DCA1000Config.dataFormatMode is 1 (12-bit words) but capture.cfg gives 16-bit"),
    ({"lvdsMode": 1}, "cf.json: DCA1000Config.lvdsMode is 1 (4 lanes) but the device of capture.cfg sends 2"),
    ({"dataLoggingMode": "multi"}, "cf.json: DCA1000Config.dataLoggingMode is 'multi'; only raw captures"),
    ({"dataFormatMode": "3"}, ""),
])
def test_the_dca1000_clis_config_beside_an_sdk_capture_must_agree(tmp_path: Path, change: dict[str, object],
                                                                  needle: str) -> None:
    """A capture recorded with TI's DCA1000 CLI keeps its configuration (cf.json) beside the SDK .cfg: words of
    other bits than the ADC's, other LVDS lanes or multi mode would read as wrong samples: a one-line error naming
    it. One that agrees reads as without it."""
    cap = sdk_cfg(tmp_path / "cap")
    (cap / "cf.json").write_text(json.dumps({"DCA1000Config": {**CLI_CF_JSON["DCA1000Config"], **change}}))
    if needle:
        assert_one_line_error(*cli_ingest(cap, tmp_path / "d.h5"), needle)
        assert not (tmp_path / "d.h5").exists()
    else:
        code, stderr = cli_ingest(cap, tmp_path / "d.h5")
        assert code == 0, stderr
        with h5py.File(tmp_path / "d.h5") as f:
            assert f["radar"][next(iter(f["radar"]))]["raw"].shape[0] == 3
        r = runner.invoke(app, ["info", str(cap), "--json"])
        assert "(2-lane complex1x, 1 file, capture.cfg + cf.json;" in json.loads(r.stdout)["container"]


@pytest.mark.parametrize(("stream", "needle"), [
    ("-1 1 1 0", "lvdsStreamCfg -1 1 1 0 streams HSI headers; only ADC data without headers"),
    ("-1 0 4 1", "streams chirp parameters or quality data, the processing chain's output"),
])
def test_sdk_streams_other_than_adc_data_are_refused(tmp_path: Path, stream: str, needle: str) -> None:
    """An mmWave SDK .cfg whose LVDS stream carries more than ADC data (HSI headers, chirp parameters, the
    processing chain's output) is a one-line error, not those bytes read as samples."""
    assert_one_line_error(*cli_ingest(sdk_cfg(tmp_path / "cap", lvdsStreamCfg=stream), tmp_path / "d.h5"), needle)


@pytest.mark.parametrize(("chirp", "needle"), [
    ("0 0 1 0 0 0 0 1", "chirp 0 uses profile 1, not profile 0 whose parameters are read"),
    ("0 0 0 0 0.5 0 0 1", "chirp 0 varies its profile (start frequency, slope, idle time, ADC start time by 0, "
                          "0.5, 0, 0)"),
])
def test_chirps_unlike_the_profile_are_refused(tmp_path: Path, chirp: str, needle: str) -> None:
    """Focusing takes one start frequency, slope, idle and ADC start time for every pulse: a chirp of another
    profile, or one that varies the profile, is a one-line error rather than pulses focused with the wrong slope."""
    assert_one_line_error(*cli_ingest(sdk_cfg(tmp_path / "cap", chirpCfg=chirp), tmp_path / "d.h5"), needle)


def test_waveforms_other_than_frames_of_chirps_are_refused(tmp_path: Path) -> None:
    """Advanced frames (sub-frames of other chirps) and continuous wave leave frameCfg / rlFrameCfg_t stale,
    and a cascade's JSON states several devices: a one-line error each, not the capture cut into frames it was
    not recorded in or read as the first device's."""
    assert_one_line_error(*cli_ingest(sdk_cfg(tmp_path / "a", dfeDataOutputMode="3"), tmp_path / "a.h5"),
                          "dfeDataOutputMode 3 (advanced frames of sub-frames); only frames of chirps")
    write_capture(tmp_path / "b", params_from_radar(CFG.radar, lanes=4), [np.ones((2, 3, 4, 540, 2), np.int16)],
                  param_format="json")
    js = tmp_path / "b" / "capture.mmwave.json"
    doc = json.loads(js.read_text())
    doc["mmWaveDevices"][0]["rfConfig"]["waveformType"] = "advancedFrameChirp"
    js.write_text(json.dumps(doc))
    assert_one_line_error(*cli_ingest(tmp_path / "b", tmp_path / "b.h5"),
                          "rfConfig.waveformType is 'advancedFrameChirp'; only frames of chirps")
    doc["mmWaveDevices"][0]["rfConfig"].pop("waveformType")
    doc["mmWaveDevices"] *= 4  # a cascade (MMWCAS: four devices, one file series each)
    js.write_text(json.dumps(doc))
    assert_one_line_error(*cli_ingest(tmp_path / "b", tmp_path / "c.h5"),
                          "a cascade of 4 mmWave devices; one device's capture is read")


def test_override_keeps_the_recording_and_selects_antenna_rows(tmp_path: Path) -> None:
    p = dataclasses.replace(params_from_radar(CFG.radar), chirp_tx=(2, 0))  # Tx2 first, then Tx0
    rng = np.random.default_rng(2)
    pris = rng.integers(-500, 500, (4, 2, 4, 540, 2), dtype=np.int16)
    write_capture(tmp_path / "cap", p, [pris], param_format="json")
    code, stderr = cli_ingest(tmp_path / "cap", tmp_path / "d.h5")
    assert_one_line_error(code, stderr, "num_tx is 2", "radar.num_tx is 3")
    code, stderr = cli_ingest(tmp_path / "cap", tmp_path / "d.h5", "--radar-override")
    assert code == 0 and "kept the recording's" in stderr
    with Drive(tmp_path / "d.h5") as d:
        r = d.radar()
        np.testing.assert_array_equal(r.raw[()], pris)  # Tx axis ascending: Tx0, Tx2
        np.testing.assert_allclose(r.attrs["tx_positions_m"], np.asarray(CFG.radar.tx_positions_m)[[0, 2]])
        np.testing.assert_allclose(r.attrs["tx_start_offsets_s"], [60e-6, 0.0])  # Tx0 chirps second
    # a Tx the config has no antenna row for: refused even with the override
    p3 = dataclasses.replace(params_from_radar(CFG.radar), chirp_tx=(0, 1, 3))
    write_capture(tmp_path / "cap3", p3, [pris[:, [0, 1, 1]]], param_format="json")
    code, stderr = cli_ingest(tmp_path / "cap3", tmp_path / "d3.h5", "--radar-override")
    assert_one_line_error(code, stderr, "uses Tx 3 of its board", "radar.tx_positions_wavelengths has 3 rows")


def test_a_capture_on_two_of_the_boards_three_tx_focuses_its_reflectors(tmp_path: Path) -> None:
    """A TI board's Tx 0 and 2 (AWR1243's azimuth-only MIMO): the config keeps the board's three rows and says
    which the radar uses (``tx_channels``); the drive takes those rows, and its reflectors focus within 1 cm of the
    truth (0.49 cm measured). The board's config as it is names what to set; with ``--radar-override`` it runs to
    the same image (focus takes the antennas the drive's radar recorded; it reshaped 3 rows into 2 and crashed)."""
    from autosar_cli.evaluate.report import evaluate_run
    from autosar_cli.ingest.pipeline import IngestOptions, RadarCaptureOptions
    from autosar_cli.run import run

    cfg_path = tmp_path / "tx02.toml"
    cfg_path.write_text('base = "default"\n\n[radar]\nnum_tx = 2\ntx_channels = [0, 2]\n')
    cfg = load_config(cfg_path)
    r = runner.invoke(app, ["simulate", "-s", "ci", "--seed", "7", "-f", "dca1000", "--dynamics", "kinematic",
                            "-c", str(cfg_path), "-o", str(tmp_path / "ci.mcap"), "--json"])
    assert r.exit_code == 0, r.output
    mcap, capture = tmp_path / "ci.mcap", Path(json.loads(r.stdout)["radar_capture"])
    code, stderr = cli_ingest(capture, tmp_path / "d.h5")  # the board's config as it is
    assert_one_line_error(code, stderr, "radar.num_tx = 2, radar.tx_channels = [0, 2]")
    run([mcap, capture], tmp_path / "run", cfg)
    with Drive(tmp_path / "run" / "drive.h5") as d:
        a = d.radar().attrs
    assert list(a["tx_channels"]) == [0, 2] and json.loads(a["parameter_sources"])["tx_channels"] == "recording"
    np.testing.assert_allclose(a["tx_positions_m"], np.asarray(CFG.radar.tx_positions_m)[[0, 2]])
    got = evaluate_run(tmp_path / "run", tmp_path / "ev", mcap.with_name("ci.mcap.truth.h5"))["reflectors"]
    assert len(got) == 3 and max(g["aligned_error_m"] for g in got) < 0.01
    overridden = run([mcap, capture], tmp_path / "ovr", CFG, ingest_options=IngestOptions(
        radar=RadarCaptureOptions(override=True)))
    assert overridden["status"] == "degraded"
    with h5py.File(tmp_path / "run" / "image.h5") as x, h5py.File(tmp_path / "ovr" / "image.h5") as y:
        np.testing.assert_array_equal(x["image"][()], y["image"][()])
    # a config of the two rows in use alone cannot place the board's Tx 2
    two = tmp_path / "two.toml"
    two.write_text('base = "default"\n\n[radar]\nnum_tx = 2\n'
                   'tx_positions_wavelengths = [[0.0, 0.0, 0.0], [0.0, 2.0, 0.0]]\n')
    code, stderr = cli_ingest(capture, tmp_path / "d2.h5", "--config", str(two))
    assert_one_line_error(code, stderr, "uses Tx 2 of its board", "radar.tx_channels = [0, 2]")


def test_malformed_sizes(tmp_path: Path) -> None:
    cap = sdk_cfg(tmp_path / "cap")
    data = (cap / "adc_data.bin").read_bytes()
    frame = len(data) // 3
    # trailing partial frame: left out, counted
    (cap / "adc_data.bin").write_bytes(data + data[:1000])
    code, stderr = cli_ingest(cap, tmp_path / "d.h5")
    assert code == 0 and "trailing partial frame left out (1000 of 25920 bytes, 1 frame)" in stderr
    with Drive(tmp_path / "d.h5") as d:
        assert d.radar().raw.shape[0] == 3
    # less than one frame
    (cap / "adc_data.bin").write_bytes(data[: frame - 8])
    assert_one_line_error(*cli_ingest(cap, tmp_path / "e.h5"), "fit no frame layout", "25920 bytes a frame",
                          "3 chirps x 4 Rx x 540 samples, complex1x, 2-lane")
    # cut inside a sample (a full disk, an interrupted copy): the whole frames are kept
    (cap / "adc_data.bin").write_bytes(data[:2 * frame + 6])
    code, stderr = cli_ingest(cap, tmp_path / "g.h5")
    assert code == 0 and "trailing partial frame left out (6 of 25920 bytes, 1 frame)" in stderr
    with Drive(tmp_path / "g.h5") as d:
        assert d.radar().raw.shape[0] == 2
    # no start time: neither --radar-start nor a sync topic
    (cap / "adc_data.bin").write_bytes(data)
    r = runner.invoke(app, ["ingest", "--radar", str(cap), "--allow-partial", "-o", str(tmp_path / "f.h5")])
    assert_one_line_error(r.exit_code, r.stderr, "no start time", "--radar-start")
    # more frames than the frame configuration says the capture holds (a second recording appended, or numFrames
    # not the recording's: refused, it lost the frames configured): those configured kept, the rest left out, said
    cfg = cap / "capture.cfg"
    cfg.write_text(cfg.read_text().replace("frameCfg 0 2 1 0 ", "frameCfg 0 2 1 2 "))
    first = np.random.default_rng(1).integers(-500, 500, (3, 3, 4, 540, 2), dtype=np.int16)[:2]
    for extra, said in ((b"", "holds 3 frames but capture.cfg configures 2 (1 loops x 3 chirps x 4 Rx x 540 samples, "
                         "complex1x, 2-lane = 25920 bytes a frame): its first 2 kept, the 25920 bytes after them left "
                         "out (1 frame: a second recording appended, or numFrames not the recording's?)"),
                        (data[:1000], "holds 3 frames and 1000 bytes but capture.cfg configures 2 (1 loops x 3 chirps"
                         " x 4 Rx x 540 samples, complex1x, 2-lane = 25920 bytes a frame): its first 2 kept, the "
                         "26920 bytes after them left out (1 frame and 1000 bytes: a second recording appended")):
        (cap / "adc_data.bin").write_bytes(data + extra)
        code, stderr = cli_ingest(cap, tmp_path / "e.h5", "--overwrite")
        assert code == 0 and said in stderr and "partial frame" not in stderr, stderr
        with Drive(tmp_path / "e.h5") as d:
            np.testing.assert_array_equal(d.radar().raw[:], first)
    (cap / "adc_data.bin").write_bytes(data)
    # a .bin without parameters beside it
    lone = tmp_path / "lone"
    lone.mkdir()
    (lone / "adc_data.bin").write_bytes(data)
    r = runner.invoke(app, ["ingest", str(lone / "adc_data.bin"), "-o", str(tmp_path / "f.h5")])
    assert_one_line_error(r.exit_code, r.stderr, "without a DCA1000 parameter file")


def test_a_folder_holding_adc_data_and_another_captures_files_is_refused(tmp_path: Path) -> None:
    """adc_data.bin beside mmWave Studio's raw twin (adc_data_Raw_0.bin …) is the capture; beside another series
    (run2_0.bin, run2_1.bin) or another .bin it is a one-line error naming them, and each reads given as CAPTURE."""
    cap = sdk_cfg(tmp_path / "cap")
    data = (cap / "adc_data.bin").read_bytes()
    (cap / "adc_data_Raw_0.bin").write_bytes(b"".join(packets_of(data, PACKET)))
    assert Dca1000Capture(cap).files == [cap / "adc_data.bin"]
    (cap / "run2_0.bin").write_bytes(data[:30000])
    (cap / "run2_1.bin").write_bytes(data[30000:])
    assert_one_line_error(*cli_ingest(cap, tmp_path / "d.h5"), f"{cap}: adc_data.bin and run2_0.bin, run2_1.bin: "
                          "the data of two captures? Give the capture's .bin file as CAPTURE")
    assert Dca1000Capture(cap / "adc_data.bin").files == [cap / "adc_data.bin"]
    assert Dca1000Capture(cap / "run2_0.bin").files == [cap / "run2_0.bin", cap / "run2_1.bin"]



def test_adc_data_beside_the_raw_files_of_another_recording_is_refused(tmp_path: Path) -> None:
    """mmWave Studio run again into a folder rewrites adc_data_Raw_0.bin; the earlier run's post-processed adc_data.bin
    stayed and was read as the capture, without a word (the campaign's "stale-flat" trials: 981 PRIs of the other
    recording, exit 0). adc_data.bin is read beside its raw twin only where it holds the twin's data (the first
    packet's at its byte count, or the first 4 KiB of data recorded without headers); else one line naming the byte,
    and each reads given as CAPTURE."""
    cap = sdk_cfg(tmp_path / "cap")
    data = (cap / "adc_data.bin").read_bytes()
    frame = len(data) // 3
    packets = packets_of(data, PACKET)
    for twin in (b"".join(packets), b"".join(packets[1:]), data[:5000]):  # the first packet lost; no headers
        (cap / "adc_data_Raw_0.bin").write_bytes(twin)
        assert Dca1000Capture(cap).files == [cap / "adc_data.bin"]
    other = data[frame:] + data[:frame]  # another recording of the same setup
    (cap / "adc_data_Raw_0.bin").write_bytes(b"".join(packets_of(other, PACKET)))
    first = next(i for i in range(len(data)) if data[i] != other[i])
    assert_one_line_error(*cli_ingest(cap, tmp_path / "d.h5"),
                          f"{cap}: adc_data.bin is not adc_data_Raw_0.bin's data (stream byte {first} differs): the "
                          "data of two recordings (mmWave Studio run again into this folder)? Give the capture's .bin "
                          "file as CAPTURE")
    (cap / "adc_data_Raw_0.bin").write_bytes(other[:5000])
    assert_one_line_error(*cli_ingest(cap, tmp_path / "d.h5"), f"(stream byte {first} differs)")
    (cap / "adc_data_Raw_0.bin").write_bytes(b"".join(packets_of(other, PACKET)))
    assert Dca1000Capture(cap / "adc_data.bin").files == [cap / "adc_data.bin"]
    assert Dca1000Capture(cap / "adc_data_Raw_0.bin").files == [cap / "adc_data_Raw_0.bin"]


def test_a_capture_folder_not_read_as_one_says_why(tmp_path: Path) -> None:
    """`autosar info` of a folder whose ADC data is not read as a capture (adc_data.bin beside another capture's
    series) listed it as a plain folder ('0 stale partial file(s)'), exit 0, where ingest refuses it in one line:
    info says ingest's reason. A stray .bin beside one split series was left out of the capture without a word: it
    is refused as adc_data.bin's companions are."""
    cap = sdk_cfg(tmp_path / "cap")
    (cap / "run2_0.bin").write_bytes(b"\x01\x00" * 100)
    r = runner.invoke(app, ["info", str(cap)])
    assert_one_line_error(r.exit_code, r.stderr, f"{cap}: adc_data.bin and run2_0.bin: the data of two captures?")
    (cap / "adc_data.bin").rename(cap / "old.bin")
    (cap / "run2_1.bin").write_bytes(b"\x01\x00" * 100)
    assert_one_line_error(*cli_ingest(cap, tmp_path / "d.h5"),
                          f"{cap}: old.bin beside the split series run2_<k>.bin: the data of two captures?")
    plain = tmp_path / "plain"
    plain.mkdir()
    (plain / "notes.txt").write_text("a folder of no capture")
    (plain / "tool.cfg").write_text("any tool's config")
    assert runner.invoke(app, ["info", str(plain)]).exit_code == 0

@pytest.fixture(scope="module")
def simulated_capture(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    """`simulate --format dca1000` of ci seed 7 (kinematic): (navigation MCAP, capture, `run` of the two)."""
    from autosar_cli.run import run

    tmp = tmp_path_factory.mktemp("dca1000_sim")
    r = runner.invoke(app, ["simulate", "-s", "ci", "--seed", "7", "-f", "dca1000", "--dynamics", "kinematic",
                            "-o", str(tmp / "ci.mcap"), "--json"])
    assert r.exit_code == 0, r.output
    capture = Path(json.loads(r.stdout)["radar_capture"])
    run([tmp / "ci.mcap", capture], tmp / "a", CFG)  # the whole chain: ingest, navigate, focus
    return tmp / "ci.mcap", capture, tmp / "a"


def test_a_capture_whose_sync_runs_on_the_radars_crystal_reports_its_drift(tmp_path: Path) -> None:
    """`simulate -f dca1000` with the radar's crystal 800 ppm fast: the sync topic stamps each frame on the radar's
    clock, a frame period apart, so the triggers show no drift of their own (nothing applied), but the logger took
    them in on the navigation's clock: ingest reads +800 ppm off their log times and names the value to state."""
    import shutil

    cfg_path = tmp_path / "fast.toml"
    text = Path(CFG.source).read_text()
    shutil.copy(Path(CFG.source).parent / "autosar_giulia.dbc", tmp_path)  # the config names its DBC beside it
    cfg_path.write_text(text.replace("\nradar_clock_drift_ppm = 0.0 ", "\nradar_clock_drift_ppm = 800.0 "))
    assert load_config(cfg_path).simulation.radar_clock_drift_ppm == 800.0
    r = runner.invoke(app, ["simulate", "-s", "ci", "--seed", "7", "-f", "dca1000", "--dynamics", "kinematic",
                            "--config", str(cfg_path), "-o", str(tmp_path / "ci.mcap"), "--json"])
    assert r.exit_code == 0, r.output
    capture = Path(json.loads(r.stdout)["radar_capture"])
    r = runner.invoke(app, ["ingest", str(tmp_path / "ci.mcap"), "--radar", str(capture), "-o",
                            str(tmp_path / "drive.h5")])
    assert r.exit_code == 0, r.output
    with Drive(tmp_path / "drive.h5") as d:
        attrs = d.radar().attrs
    assert not attrs["frame_clock_applied"]
    assert attrs["log_clock_drift_ppm"] == pytest.approx(800.0, abs=0.5)
    assert "frame stamps run +800.0 ± " in r.stderr and "state radar.clock_drift_ppm = 800.0" in r.stderr, r.stderr
    r = runner.invoke(app, ["info", str(tmp_path / "drive.h5"), "--json"])
    shown = json.loads(r.stdout)["radar_parameters"]
    assert shown["log_clock_drift_ppm"]["value"].startswith("+800.0")
    assert shown["log_clock_drift_ppm"]["source"] == "the log times"
    assert "(applied)" not in shown["frame_clock_drift_ppm"]["value"]


def test_simulated_capture_ingests_to_the_rawframe_cube(ci_run: Path, simulated_capture: tuple[Path, Path, Path]
                                                        ) -> None:
    """`simulate --format dca1000` (capture + navigation MCAP with a frame-sync topic) ingests to the same
    radar cube, frame times and radar parameters as the RawFrame MCAP of the same seed (conftest's ci_run), and
    `run` focuses both to the same image."""
    _, capture, whole = simulated_capture
    assert (capture / "capture.mmwave.json").exists() and (capture / "adc_data.bin").exists()
    with h5py.File(whole / "image.h5") as a, h5py.File(ci_run / "image.h5") as b:
        images = [name for name, obj in a.items() if isinstance(obj, h5py.Dataset)]
        assert images
        for name in images:
            np.testing.assert_array_equal(a[name][()], b[name][()], err_msg=name)
    with h5py.File(whole / "drive.h5") as a, h5py.File(ci_run / "drive.h5") as b:
        ra, rb = a["radar/scanbrick_w43"], b["radar/scanbrick_w43"]
        for name in ("raw", "t_ns", "frame_index"):
            np.testing.assert_array_equal(ra[name][()], rb[name][()])
        for key in ("start_frequency_hz", "slope_hz_per_s", "sample_rate_hz", "tx_start_offsets_s", "num_tx",
                    "num_rx", "num_samples", "bandwidth_hz", "prf_hz", "tx_positions_m", "rx_positions_m",
                    "lever_arm_m", "yaw_deg", "pitch_deg", "roll_deg"):
            np.testing.assert_array_equal(ra.attrs[key], rb.attrs[key], err_msg=key)
        assert ra.attrs["start_time_source"] == "topic /dca1000/sync"
        # the navigation is the same too
        np.testing.assert_array_equal(a["imu/ins_radar/t_ns"][()], b["imu/ins_radar/t_ns"][()])
    # the capture's frames are the drive's radar: not an input nothing of which reached it (it was said to be)
    assert json.loads((whole / "run.json").read_text())["warnings"] == []


def test_batch_gives_each_drives_capture_its_own_start(simulated_capture: tuple[Path, Path, Path],
                                                       tmp_path: Path) -> None:
    """`batch --radar-start` once per log: each drive's capture starts at its own time (the second 5 ms after its
    sync, as a capture timed by hand would); given once for two logs it is refused (one time for every capture
    would be wrong for all but one)."""
    mcap, capture, whole = simulated_capture
    with Drive(whole / "drive.h5") as d:
        synced = int(d.radar().t_ns[0])
    logs = [tmp_path / "a.mcap", tmp_path / "b.mcap"]
    for log in logs:
        log.write_bytes(mcap.read_bytes())
    # the second capture named by its parameter file, as ingest takes it
    args = ["batch", *map(str, logs), "--radar", str(capture), "--radar", str(capture / "capture.mmwave.json"),
            "--workers", "1"]
    r = runner.invoke(app, [*args, "--radar-start", str(synced), "-o", str(tmp_path / "x")])
    assert_one_line_error(r.exit_code, r.stderr, "--radar-start given 1 times for 2 logs")
    r = runner.invoke(app, [*args, "--radar-start", str(synced), "--radar-start", str(synced + 5_000_000),
                            "-o", str(tmp_path / "out"), "--json"])
    assert r.exit_code == 0, r.output
    for name, start in (("a", synced), ("b", synced + 5_000_000)):
        with Drive(tmp_path / "out" / name / "drive.h5") as d:
            assert int(d.radar().t_ns[0]) == start


def test_run_reads_its_capture_as_ingest_does(simulated_capture: tuple[Path, Path, Path], tmp_path: Path) -> None:
    """`run --radar` takes a capture named by its parameter file, as `ingest --radar` does (it was refused as "an
    unknown log container"), and a folder without one is refused for that (it was called "not a rosbag2 bag")."""
    mcap, capture, whole = simulated_capture
    r = runner.invoke(app, ["run", str(mcap), "--radar", str(capture / "capture.mmwave.json"),
                            "-o", str(tmp_path / "run")])
    assert r.exit_code == 0, r.output
    with h5py.File(tmp_path / "run" / "image.h5") as a, h5py.File(whole / "image.h5") as b:
        np.testing.assert_array_equal(a["image"][()], b["image"][()])
    # what it read is the capture: its size and digest (run.json, the drive's provenance) cover the data, not only
    # the 2 kB parameter file (which they did)
    read = (capture / "capture.mmwave.json").stat().st_size + (capture / "adc_data.bin").stat().st_size
    assert json.loads((tmp_path / "run" / "run.json").read_text())["inputs"][1]["size_bytes"] == read
    with Drive(tmp_path / "run" / "drive.h5") as d:
        radar_input = next(i for i in d.report()["inputs"] if i["kind"] == "radar")
    assert radar_input["size_bytes"] == read
    assert radar_input["sha256"] != hashlib.sha256((capture / "capture.mmwave.json").read_bytes()).hexdigest()
    bare = tmp_path / "bare"
    bare.mkdir()
    shutil.copy(capture / "adc_data.bin", bare / "adc_data.bin")
    r = runner.invoke(app, ["run", str(mcap), "--radar", str(bare), "-o", str(tmp_path / "bare_run")])
    assert_one_line_error(r.exit_code, r.stderr, f"{bare}: no DCA1000 parameter file")


def test_a_capture_that_lost_packets_focuses_its_reflectors_where_the_whole_one_does(
        simulated_capture: tuple[Path, Path, Path], tmp_path: Path) -> None:
    """The simulated capture recorded as the DCA1000's packets, 60 of its 17464 lost at random: `run` leaves out
    the 62 of 981 PRIs they touched and says the run is degraded; its corner reflectors focus within 1 mm of
    where the whole capture's do (0.4-0.6 mm measured), as wide (1 %), their peaks lower by what the PRIs left out
    take (6.3 % of the pulses: 0.57 dB coherent; 0.40-0.57 dB measured)."""
    from autosar_cli.evaluate.report import evaluate_run
    from autosar_cli.run import run

    mcap, capture, whole = simulated_capture
    data = (capture / "adc_data.bin").read_bytes()
    packets = packets_of(data, PACKET)
    lost = set(np.random.default_rng(3).choice(len(packets), 60, replace=False).tolist())
    lossy = tmp_path / "lossy"
    lossy.mkdir()
    for name in ("capture.mmwave.json", "capture.setup.json"):
        (lossy / name).write_bytes((capture / name).read_bytes())
    (lossy / "adc_data_Raw_0.bin").write_bytes(b"".join(pk for k, pk in enumerate(packets) if k not in lost))
    manifest = run([mcap, lossy], tmp_path / "run", CFG)
    assert manifest["status"] == "degraded", manifest["warnings"]
    assert any("PRIs left out, they hold data the DCA1000 lost (60 lost packets)" in w for w in manifest["warnings"])
    truth = mcap.parent / "ci.mcap.truth.h5"
    ref = {r["name"]: r for r in evaluate_run(whole, tmp_path / "ref", truth)["reflectors"]}
    got = evaluate_run(tmp_path / "run", tmp_path / "rep", truth)["reflectors"]
    assert len(got) == len(ref) == 3
    for r in got:
        w = ref[r["name"]]
        assert np.hypot(*np.subtract(r["peak_xy"], w["peak_xy"])) < 1e-3
        assert r["irw_cross_m"] == pytest.approx(w["irw_cross_m"], rel=0.05)
        assert -1.5 < r["peak_db"] - w["peak_db"] < 0.0


def trigger_log(path: Path, stamps_ns: np.ndarray) -> Path:
    """An MCAP holding one std_msgs/Header per frame trigger on /dca1000/sync (as ``simulate -f dca1000`` writes)."""
    from autosar_cli import msgs
    from autosar_cli.sim.logwriter import open_log_writer

    typestore = msgs.typestore_for(2)
    with open_log_writer(path, "mcap") as writer:
        writer.add_topic("/dca1000/sync", msgs.HEADER)
        for t in stamps_ns:
            writer.write("/dca1000/sync", int(t), msgs.header(typestore, int(t), "dca1000"))
    return path


def test_hardware_triggered_frames_take_their_triggers_times(tmp_path: Path) -> None:
    """A capture whose frames start on an external trigger (triggerSelect 2; e.g. one per distance travelled) is
    timed frame by frame by its triggers, not by the frame period; too few triggers is a one-line error; a
    software-triggered capture whose per-frame triggers run 10 % slower than its period says so."""
    p = dataclasses.replace(params_from_radar(CFG.radar, lanes=4), hardware_trigger=True)
    pris = np.random.default_rng(4).integers(-500, 500, (40, 3, 4, 540, 2), dtype=np.int16)
    write_capture(tmp_path / "hw", p, [pris], param_format="json")
    assert Dca1000Capture(tmp_path / "hw").params.hardware_trigger
    r = runner.invoke(app, ["info", str(tmp_path / "hw"), "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["container"].endswith("hardware trigger, timed by the sync topic at ingest)")
    r = runner.invoke(app, ["ingest", str(tmp_path / "hw"), "-o", str(tmp_path / "alone.h5")])  # not --radar-start
    assert_one_line_error(r.exit_code, r.stderr, "a DCA1000 capture and no log", "(triggerSelect 2), so only their "
                          "triggers time them; --radar-start cannot")
    assert "--radar-start TIME" not in r.stderr
    start = 1_714_557_600_000_000_000
    stamps = start + np.cumsum(np.random.default_rng(5).integers(800_000, 3_000_000, 40))
    log = trigger_log(tmp_path / "hw.mcap", stamps)
    r = runner.invoke(app, ["ingest", str(log), "--radar", str(tmp_path / "hw"), "--allow-partial",
                            "-o", str(tmp_path / "hw.h5")])
    assert r.exit_code == 0, r.output
    with Drive(tmp_path / "hw.h5") as d:
        np.testing.assert_array_equal(d.radar().t_ns, stamps)
    with h5py.File(tmp_path / "hw.h5") as f:
        assert f["radar/scanbrick_w43"].attrs["start_time_source"] == "topic /dca1000/sync, a trigger per frame"
    few = trigger_log(tmp_path / "few.mcap", stamps[:30])
    r = runner.invoke(app, ["ingest", str(few), "--radar", str(tmp_path / "hw"), "--allow-partial",
                            "-o", str(tmp_path / "few.h5")])
    assert_one_line_error(r.exit_code, r.stderr, "hardware trigger (triggerSelect 2)", "30 triggers for 40 frames")

    write_capture(tmp_path / "sw", params_from_radar(CFG.radar, lanes=4), [pris], param_format="json")
    slow = trigger_log(tmp_path / "slow.mcap", start + np.arange(40) * round(1.1e9 / CFG.radar.prf_hz))
    r = runner.invoke(app, ["ingest", str(slow), "--radar", str(tmp_path / "sw"), "--allow-partial",
                            "-o", str(tmp_path / "sw.h5")])
    assert r.exit_code == 0, r.output
    assert "frames every 1.0101 ms drift up to 3.94 ms from their 40 triggers on topic /dca1000/sync (frame 39)" \
        in r.stderr, r.stderr.splitlines()


def test_a_frame_clock_that_drifts_is_timed_by_its_triggers(tmp_path: Path) -> None:
    """A software-triggered capture whose radar crystal runs 500 ppm fast: its 40 per-frame triggers on the
    logger's clock come every 1.0101 ms / 1.0005. Ingest measures the frame clock against them and times the frames
    by the triggers' period (to 1 ns of each trigger, where the stated period leaves the last 20 us off), says so
    in one line and in the radar's attributes; triggers a period apart leave the frames as the period times them."""
    pris = np.random.default_rng(4).integers(-500, 500, (40, 3, 4, 540, 2), dtype=np.int16)
    write_capture(tmp_path / "sw", params_from_radar(CFG.radar, lanes=4), [pris], param_format="json")
    start, period_ns = 1_714_557_600_000_000_000, 1e9 / CFG.radar.prf_hz
    for name, ppm in (("fast", 500.0), ("nominal", 0.0)):
        stamps = start + np.round(np.arange(40) * period_ns / (1 + ppm * 1e-6)).astype(np.int64)
        log = trigger_log(tmp_path / f"{name}.mcap", stamps)
        r = runner.invoke(app, ["ingest", str(log), "--radar", str(tmp_path / "sw"), "--allow-partial",
                                "-o", str(tmp_path / f"{name}.h5")])
        assert r.exit_code == 0, r.output
        with Drive(tmp_path / f"{name}.h5") as d:
            t_ns, attrs = d.radar().t_ns[()], d.radar().attrs
        assert np.abs(t_ns - stamps).max() <= 1
        assert attrs["frame_clock_applied"] == bool(ppm)
        # the crystal times the ramp and the ADC too: the chirp as the triggers' clock sees it
        rate = 1 + attrs["frame_clock_drift_ppm"] * 1e-6 if ppm else 1.0
        assert attrs["slope_hz_per_s"] == pytest.approx(CFG.radar.slope_hz_per_s * rate**2, rel=1e-12)
        assert attrs["sample_rate_hz"] == pytest.approx(CFG.radar.sample_rate_hz * rate, rel=1e-12)
        assert ("configured_start_frequency_hz" in attrs) == bool(ppm)
        assert attrs["frame_clock_drift_ppm"] == pytest.approx(ppm, abs=4 * attrs["frame_clock_drift_std_ppm"] + 0.5)
        assert ("its 40 triggers on topic /dca1000/sync come every 1.009596 ms" in r.stderr) == bool(ppm), r.stderr
        if ppm:
            assert "the radar's frame clock runs +500.0 ± " in r.stderr
            assert np.abs(start + np.round(np.arange(40) * period_ns) - stamps).max() > 19_000  # the period alone
            shown = json.loads(runner.invoke(app, ["info", str(tmp_path / f"{name}.h5"), "--json"]).stdout)
            assert shown["radar_parameters"]["frame_clock_drift_ppm"]["value"].endswith("ppm (applied)")
            assert shown["radar_parameters"]["slope_hz_per_s"]["source"].endswith("on the triggers' clock")
            # a drift stated as well would be taken out twice: focus refuses it in one line
            from autosar_cli.sar.focus import FocusError, FocusOptions, open_radar

            with Drive(tmp_path / f"{name}.h5") as d, pytest.raises(FocusError, match="would take a drift out twice"):
                open_radar(d, FocusOptions(radar_clock_drift_ppm=500.0))


def test_triggers_that_are_not_one_per_frame_are_said(tmp_path: Path) -> None:
    """A software-triggered capture of 40 frames whose sync topic holds 41 triggers (the DCA1000 armed a frame late:
    the first trigger's frame is not in the capture) or 39 (the logger stopped first): its frames are timed from the
    first trigger as before, and one warning says the counts differ and what a late start does to every frame."""
    pris = np.random.default_rng(4).integers(-500, 500, (40, 3, 4, 540, 2), dtype=np.int16)
    write_capture(tmp_path / "sw", params_from_radar(CFG.radar, lanes=4), [pris], param_format="json")
    start, period_ns = 1_714_557_600_000_000_000, 1e9 / CFG.radar.prf_hz
    for n in (41, 39, 1):
        log = trigger_log(tmp_path / f"t{n}.mcap", start + np.round(np.arange(n) * period_ns).astype(np.int64))
        r = runner.invoke(app, ["ingest", str(log), "--radar", str(tmp_path / "sw"), "--allow-partial",
                                "-o", str(tmp_path / f"t{n}.h5")])
        assert r.exit_code == 0, r.output
        with Drive(tmp_path / f"t{n}.h5") as d:
            assert d.radar().t_ns[0] == start
        said = [line for line in r.stderr.splitlines() if "triggers on topic /dca1000/sync for its 40 frames" in line]
        assert said == ([f"warning: {tmp_path / 'sw' / 'adc_data.bin'}: {n} triggers on topic /dca1000/sync for its "
                         "40 frames: timed from the first trigger, so every frame the capture missed at its start "
                         "puts all its frames a frame period (1.0101 ms) early; where it did, give --radar-start"]
                        if n > 1 else []), r.stderr.splitlines()


def test_a_loop_count_off_by_two_is_said_against_the_triggers(tmp_path: Path) -> None:
    """A capture of 42 frames of one loop whose mmWave Studio JSON states 3 loops a frame and numFrames 0, read with
    a config of its 2970 Hz PRF: the ADC stream marks no frame, so it reads as 14 frames of 3 loops whole, every PRI
    timed wrong. With --radar-start its log's 42 triggers were not looked at: exit 0, not a word. Now the count is
    said whoever times the frames, with the loop count that makes one frame a trigger; 41 triggers name none."""
    pris = np.random.default_rng(4).integers(-500, 500, (42, 3, 4, 540, 2), dtype=np.int16)
    write_capture(tmp_path / "cap", params_from_radar(CFG.radar, lanes=4), [pris], param_format="json")
    js = tmp_path / "cap" / "capture.mmwave.json"
    frame = json.loads(js.read_text())["mmWaveDevices"][0]["rfConfig"]["rlFrameCfg_t"]
    assert (frame["numLoops"], frame["numFrames"]) == (1, 0) and js.read_text().count('"numLoops": 1,') == 1
    js.write_text(js.read_text().replace('"numLoops": 1,', '"numLoops": 3,'))
    cfg = tmp_path / "prf.toml"
    cfg.write_text(f'base = "default"\n\n[radar]\nprf_hz = {3 * CFG.radar.prf_hz}\n')
    start, period_ns = 1_714_557_600_000_000_000, 1e9 / CFG.radar.prf_hz
    for n in (42, 41):
        log = trigger_log(tmp_path / f"t{n}.mcap", start + np.round(np.arange(n) * period_ns).astype(np.int64))
        for timing in ([], ["--radar-start", str(start)]):
            r = runner.invoke(app, ["ingest", str(log), "--radar", str(tmp_path / "cap"), "--allow-partial",
                                    "--config", str(cfg), "-o", str(tmp_path / f"t{n}{len(timing)}.h5"), *timing])
            assert r.exit_code == 0, r.output
            with Drive(tmp_path / f"t{n}{len(timing)}.h5") as d:
                assert len(d.radar().t_ns) == 42
            said = [line for line in r.stderr.splitlines() if "triggers on topic /dca1000/sync" in line]
            assert len(said) == 1 and f"{n} triggers on topic /dca1000/sync for its 14 frames" in said[0], said
            assert ("(timed from --radar-start)" in said[0]) == bool(timing)
            assert ("its 42 loops would be 1 a frame, one frame a trigger: does capture.mmwave.json state the "
                    "recording's loop count (numLoops 3)?" in said[0]) == (n == 42), said


def test_the_frame_clock_is_measured_through_jitter_and_late_triggers() -> None:
    """3000 triggers 1 ms apart on the radar's clock, 60 ppm fast, stamped with 20 us of jitter and five messages
    50 ms late: the line through them reads the drift within 3 std (std under 1 ppm) and applies it; the same
    triggers on a clock without drift apply nothing."""
    from autosar_cli.ingest.radar_block import frame_clock_against_triggers

    rng = np.random.default_rng(11)
    k = np.arange(3000)
    for ppm in (60.0, 0.0):
        stamps = 10**18 + np.round(k * 1e6 / (1 + ppm * 1e-6) + rng.normal(0, 20e3, k.size)).astype(np.int64)
        stamps[rng.choice(k.size, 5, replace=False)] += 50_000_000
        clock = frame_clock_against_triggers(stamps, 1e-3)
        print(clock)
        assert abs(clock.drift_ppm - ppm) < 3 * clock.drift_std_ppm
        assert clock.drift_std_ppm < 1.0
        assert clock.applied == bool(ppm)


PACKET = 1456  # the DCA1000's default data bytes per packet


def config_capture(folder: Path, n_pris: int = 150, **write: int) -> tuple[CaptureParams, np.ndarray, list[Path]]:
    """``n_pris`` random PRIs of the default config's radar as a 2-lane capture (one PRI a frame, 25920 bytes)."""
    p = params_from_radar(CFG.radar, lanes=2)
    pris = np.random.default_rng(2).integers(-500, 500, (n_pris, 3, 4, 540, 2), dtype=np.int16)
    return p, pris, write_capture(folder, p, [pris], **write)


def pris_of(byte_range: tuple[int, int], p: CaptureParams) -> set[int]:
    """PRIs (one a frame here) that stream bytes [a, b) touch."""
    return set(range(byte_range[0] // p.frame_bytes, (byte_range[1] - 1) // p.frame_bytes + 1))


def test_recorded_dca1000_packets_read_as_the_data_alone(tmp_path: Path) -> None:
    """The DCA1000's packets as a recorder stores them (10-byte header: sequence number, bytes sent before; then
    1456 data bytes, the last packet fewer; split files of whole packets) read as the same PRIs as the data
    alone, and `info` says which it holds."""
    p, pris, flat = config_capture(tmp_path / "flat")
    _, _, raw = config_capture(tmp_path / "raw", packet_bytes=PACKET, split_bytes=1_000_000)
    assert len(raw) == 4 and [f.name for f in raw][:2] == ["adc_data_Raw_0.bin", "adc_data_Raw_1.bin"]
    head = raw[0].read_bytes()[:2 * (PACKET + 10)]
    # the second packet's header as a real DCA1000 raw capture shows it (quoted on TI's E2E forum): sequence 2,
    # 1456 data bytes sent before it
    assert head[PACKET + 10:PACKET + 20] == bytes.fromhex("02000000b00500000000")
    cap = Dca1000Capture(tmp_path / "raw")
    assert cap.packets is not None and cap.packets.data_bytes == PACKET
    assert cap.packets.packets == -(-len(pris) * p.frame_bytes // PACKET) and cap.packets.lost_packets == 0
    got = list(cap.blocks())
    np.testing.assert_array_equal(np.concatenate([b for _, b, _ in got]), pris)
    assert not any(d.any() for _, _, d in got) and cap.warnings == []
    assert Dca1000Capture(tmp_path / "flat").packets is None
    r = runner.invoke(app, ["info", str(tmp_path / "raw"), "--json"])
    assert r.exit_code == 0, r.output
    assert "DCA1000 packets of 1456 data bytes: 2671 recorded, 0 lost" in r.stdout


def test_lost_reordered_and_repeated_packets(tmp_path: Path) -> None:
    """A recording that lost two packets, got two out of order and one twice: the packets go where their byte
    counts say, the PRIs a lost packet touches are left out (the frame index jumps there, as in a log that
    lost frames) with one warning that counts them, and every other PRI is the one written."""
    p, pris, files = config_capture(tmp_path / "cap", packet_bytes=PACKET)
    stream = files[0].read_bytes()
    step = PACKET + 10
    packets = [stream[i:i + step] for i in range(0, len(stream), step)]
    lost = [712, 2000]  # 712 straddles PRIs 39 and 40; 2000 lies inside PRI 112
    edited = [pk for k, pk in enumerate(packets) if k not in lost]
    edited[300], edited[301] = edited[301], edited[300]
    edited.insert(500, edited[499])
    files[0].write_bytes(b"".join(edited))
    left_out = set().union(*(pris_of((k * PACKET, (k + 1) * PACKET), p) for k in lost))
    assert left_out == {39, 40, 112}

    cap = Dca1000Capture(tmp_path / "cap")
    assert (cap.packets.lost_packets, cap.packets.late, cap.packets.duplicates) == (2, 1, 1)
    blocks = list(cap.blocks())
    damaged = np.concatenate([d for _, _, d in blocks])
    assert set(np.flatnonzero(damaged)) == left_out
    keep = ~damaged
    np.testing.assert_array_equal(np.concatenate([b for _, b, _ in blocks])[keep], pris[keep])

    code, stderr = cli_ingest(tmp_path / "cap", tmp_path / "d.h5")
    assert code == 0, stderr
    assert "3 of 150 PRIs left out, they hold data the DCA1000 lost (2 lost packets)" in stderr, stderr.splitlines()
    with Drive(tmp_path / "d.h5") as d:
        radar = d.radar()
        np.testing.assert_array_equal(radar.frame_index, np.flatnonzero(keep))
        np.testing.assert_array_equal(radar.raw[()], pris[keep])
    with h5py.File(tmp_path / "d.h5") as f:
        np.testing.assert_array_equal(f["radar/scanbrick_w43/gap_frame_index"][()], [[38, 41], [111, 113]])
    # the first 1300 packets lost: the reader's first block of 64 PRIs whole, and where the stream starts
    files[0].write_bytes(b"".join(packets[1300:]))
    code, stderr = cli_ingest(tmp_path / "cap", tmp_path / "e.h5")
    assert code == 0 and "74 of 150 PRIs left out, they hold data the DCA1000 lost (1300 lost packets)" in stderr
    with Drive(tmp_path / "e.h5") as d:
        np.testing.assert_array_equal(d.radar().frame_index, np.arange(74, 150))  # 1300 x 1456 B: into PRI 73
        np.testing.assert_array_equal(d.radar().raw[()], pris[74:])


def test_a_second_recording_appended_to_the_first_is_left_out_by_name(tmp_path: Path) -> None:
    """Two recordings in one raw file (the second's packets start again at sequence 1, byte count 0): the first is
    read whole, the second left out with one warning naming the file and byte where it starts, whether the first
    ends inside a packet (40 PRIs: 712 packets and 128 bytes) or at a packet's edge (91 PRIs); a packet cut short
    inside a recording is said, its bytes kept and the PRIs it lacks left out."""
    for n_first in (40, 91):
        p, first, files = config_capture(tmp_path / f"a{n_first}", n_pris=n_first, packet_bytes=PACKET)
        _, _, second = config_capture(tmp_path / f"b{n_first}", n_pris=60, packet_bytes=PACKET)
        size = files[0].stat().st_size
        files[0].write_bytes(files[0].read_bytes() + second[0].read_bytes())
        cap = Dca1000Capture(tmp_path / f"a{n_first}")
        blocks = list(cap.blocks())
        assert cap.num_frames == n_first and not any(d.any() for _, _, d in blocks)
        np.testing.assert_array_equal(np.concatenate([b for _, b, _ in blocks]), first)
        assert cap.warnings == [f"{files[0]}: byte {size}: the DCA1000's packets start again (byte count 0 after "
                                f"{(n_first * p.frame_bytes - 1) // PACKET * PACKET}): a second recording appended "
                                "to the first, left out (split it off at that byte to read it)"]
    p, pris, files = config_capture(tmp_path / "cut", packet_bytes=PACKET)
    stream = files[0].read_bytes()
    at = 300 * (PACKET + 10)  # packet 301 loses its last 500 bytes
    files[0].write_bytes(stream[:at + 10 + 956] + stream[at + 10 + PACKET:])
    cap = Dca1000Capture(tmp_path / "cut")
    blocks = list(cap.blocks())
    assert cap.warnings[0] == f"{files[0]}: the packet at byte {at} (sequence 301) holds 956 of 1456 data bytes: " \
                              "the rest lost"
    damaged = np.concatenate([d for _, _, d in blocks])
    assert set(np.flatnonzero(damaged)) == pris_of((300 * PACKET + 956, 301 * PACKET), p) == {16}
    np.testing.assert_array_equal(np.concatenate([b for _, b, _ in blocks])[~damaged], pris[~damaged])


def test_a_second_recording_after_a_first_of_fewer_than_64_packets_is_left_out_by_name(tmp_path: Path) -> None:
    """A first recording of fewer than 64 packets (3 PRIs: 54 packets, the last of 592 bytes) with a second of 60
    PRIs appended: the second's packets came no more than 64 behind the first's furthest, so they were taken for
    repeats: 60 frames read, the first's 3 PRIs then 56 of the second's, 2 left out as "lost", and no word of a
    second recording. A packet UDP repeats is the same bytes; the second's repeat the first's byte counts with other
    data: the first is read, the second left out naming its byte, as after a longer first. A first of 10 packets (no
    whole frame) is refused naming where the second starts (it read as 60 frames, no warning); a packet repeated
    verbatim in a short recording is still a repeat."""
    p, first, files = config_capture(tmp_path / "short", n_pris=3, packet_bytes=PACKET)
    second = np.random.default_rng(9).integers(-500, 500, (60, 3, 4, 540, 2), dtype=np.int16)
    appended = write_capture(tmp_path / "second", p, [second], packet_bytes=PACKET)[0].read_bytes()
    step = PACKET + 10
    one = files[0].read_bytes()
    assert len(one) == 53 * step + 10 + 592
    files[0].write_bytes(one + appended)
    cap = Dca1000Capture(tmp_path / "short")
    blocks = list(cap.blocks())
    assert cap.num_frames == 3 and not any(d.any() for _, _, d in blocks)
    np.testing.assert_array_equal(np.concatenate([b for _, b, _ in blocks]), first)
    assert (cap.packets.packets, cap.packets.duplicates) == (54, 0)
    assert cap.warnings == [f"{files[0]}: byte {len(one)}: the DCA1000's packets start again (byte count 0 after "
                            f"{53 * PACKET}): a second recording appended to the first, left out (split it off at "
                            "that byte to read it)"]
    # the second's first two packets swapped: it starts at the first of them in the file all the same
    swapped = appended[step:2 * step] + appended[:step] + appended[2 * step:]
    files[0].write_bytes(one + swapped)
    cap = Dca1000Capture(tmp_path / "short")
    assert cap.num_frames == 3 and f"byte {len(one)}: the DCA1000's packets start again (byte count 1456 after " \
        f"{53 * PACKET})" in cap.warnings[0]
    # a first of 10 packets, under one frame
    files[0].write_bytes(one[:10 * step] + appended)
    with pytest.raises(CaptureError, match=rf"14560 bytes fit no frame layout .* 25920 bytes a frame; .*adc_data.bin: "
                                           rf"byte {10 * step}: the DCA1000's packets start again"):
        Dca1000Capture(tmp_path / "short")
    # a short recording whose packet 6 UDP repeated after packet 41: read whole, one repeat
    packets = [one[i:i + step] for i in range(0, len(one), step)]
    files[0].write_bytes(b"".join(packets[:41] + [packets[5]] + packets[41:]))
    cap = Dca1000Capture(tmp_path / "short")
    blocks = list(cap.blocks())
    assert (cap.num_frames, cap.packets.duplicates, cap.warnings) == (3, 1, [])
    np.testing.assert_array_equal(np.concatenate([b for _, b, _ in blocks]), first)


def test_an_earlier_longer_recordings_split_files_left_beside_are_said(tmp_path: Path) -> None:
    """mmWave Studio run again into a folder overwrites the split files its recording fills: a longer earlier one's
    last files stay. Their packets start on the same grid, so they were read on as this recording's, past a gap
    counted as lost packets (the campaign's "stale-split" trials, numFrames 0: the earlier recording's PRIs kept as
    this one's, its warnings of lost packets only). Where a file starts with a packet past the furthest before it,
    the file before ending at a packet's edge, by over 64 packets or after a packet of fewer bytes (a recording's
    last), a warning names the files; the recording's own files, split anywhere or losing packets, draw none."""
    p = params_from_radar(CFG.radar, lanes=2)
    older = np.random.default_rng(9).integers(-500, 500, (200, 3, 4, 540, 2), dtype=np.int16)
    for n_pris, per_file, short in ((100, 40, " (one of fewer bytes)"), (90, 200, "")):
        size = per_file * (PACKET + 10)  # files of whole packets, as the DCA1000 splits its recording
        _, _, new = config_capture(tmp_path / f"cap{n_pris}", n_pris=n_pris, packet_bytes=PACKET, split_bytes=size)
        if not short:  # its last packet whole: the recording ends at a packet's edge
            new[-1].write_bytes(new[-1].read_bytes()[:-(n_pris * p.frame_bytes % PACKET) - 10])
        old = write_capture(tmp_path / f"old{n_pris}", p, [older], packet_bytes=PACKET, split_bytes=size)
        assert not any("packets) past" in w for w in Dca1000Capture(tmp_path / f"cap{n_pris}").warnings)
        for f in old[len(new):]:
            shutil.copyfile(f, tmp_path / f"cap{n_pris}" / f.name)
        cap = Dca1000Capture(tmp_path / f"cap{n_pris}")
        k = len(new)
        gap = k * per_file * PACKET - (n_pris * p.frame_bytes if short else n_pris * p.frame_bytes // PACKET * PACKET)
        assert [w for w in cap.warnings if "packets) past" in w] == [
            f"{tmp_path / f'cap{n_pris}' / f'adc_data_Raw_{k}.bin'}: its first packet (byte count "
            f"{k * per_file * PACKET}) lies {gap} bytes ({gap / PACKET:.1f} packets) past the last of "
            f"adc_data_Raw_{k - 1}.bin, which ends at a packet's edge{short}: an earlier, longer recording's files "
            f"left beside this one's (mmWave Studio run again into the folder), or the end of adc_data_Raw_{k - 1}.bin "
            "lost? Move " + ", ".join(f.name for f in old[k:]) + " away if they are another recording's"], cap.warnings


def test_a_loss_that_starts_or_ends_at_a_pris_edge_costs_only_the_pris_it_touches(tmp_path: Path) -> None:
    """Every 91 frames (25920 bytes) a packet (1456 bytes) starts at a PRI's first byte. Such a packet lost, or
    zero-filled by post-processing, read as zeros found on aligned groups of four, and the PRIs within three values
    of them were left out: the whole PRI before (after) it too (the campaign's "stale-split" trials lost this
    recording's last PRI, 980, to the gap after it). Only the PRIs the zeros touch are left out now."""
    p, pris, files = config_capture(tmp_path / "raw", n_pris=200, packet_bytes=PACKET)
    assert 1620 * PACKET == 91 * p.frame_bytes
    stream = files[0].read_bytes()
    step = PACKET + 10
    for gone, touched in ((1620, {91}), (1619, {90}), (3240, {182})):
        files[0].write_bytes(stream[:gone * step] + stream[(gone + 1) * step:])
        blocks = list(Dca1000Capture(tmp_path / "raw").blocks())
        damaged = np.concatenate([d for _, _, d in blocks])
        assert set(np.flatnonzero(damaged)) == touched == pris_of((gone * PACKET, (gone + 1) * PACKET), p)
        np.testing.assert_array_equal(np.concatenate([b for _, b, _ in blocks])[~damaged], pris[~damaged])
    _, _, flat = config_capture(tmp_path / "flat", n_pris=200)
    data = bytearray(flat[0].read_bytes())
    data[1620 * PACKET:1621 * PACKET] = bytes(PACKET)  # Packet_Reorder_Zerofill's fill
    flat[0].write_bytes(bytes(data))
    damaged = np.concatenate([d for _, _, d in Dca1000Capture(tmp_path / "flat").blocks()])
    assert set(np.flatnonzero(damaged)) == {91}


def test_a_packet_repeated_with_other_data_costs_only_its_pris(tmp_path: Path) -> None:
    """A packet repeated with a byte changed in its copy, inside a recording of 2671 packets: right after itself it
    stopped ingest with an IndexError; three packets later it was named a second recording, the rest of the capture
    left out (56 of 150 PRIs read; 1 of 150 where packet 21 repeated). Which copy holds the ADC's data cannot be
    told, so the PRIs the packet touches are left out, said with the byte; every other PRI is the one written. A
    second recording after a short first is still told by the packets after the repeat staying behind."""
    p, pris, files = config_capture(tmp_path / "cap", packet_bytes=PACKET)
    stream = files[0].read_bytes()
    step = PACKET + 10
    packets = [stream[i:i + step] for i in range(0, len(stream), step)]
    for where, later in ((1000, 0), (1000, 3), (20, 3), (1000, "reordered")):
        copy = bytearray(packets[where])
        copy[500] ^= 0x40
        if later == "reordered":  # the copy after the packet two on, the one between sent late: [..., w, w+2, w', w+1]
            later = 1
            files[0].write_bytes(b"".join(packets[:where + 1] + [packets[where + 2], bytes(copy), packets[where + 1]]
                                          + packets[where + 3:]))
        else:
            files[0].write_bytes(b"".join(packets[:where + 1 + later] + [bytes(copy)] + packets[where + 1 + later:]))
        cap = Dca1000Capture(tmp_path / "cap")
        blocks = list(cap.blocks())
        damaged = np.concatenate([d for _, _, d in blocks])
        assert cap.num_frames == len(pris)
        assert set(np.flatnonzero(damaged)) == pris_of((where * PACKET, (where + 1) * PACKET), p)
        np.testing.assert_array_equal(np.concatenate([b for _, b, _ in blocks])[~damaged], pris[~damaged])
        assert cap.warnings == [
            f"{files[0]}: byte {(where + 1 + later) * step}: a packet repeats byte count {where * PACKET} with other "
            "data: which copy holds the ADC's data cannot be told, the PRIs it touches left out",
            f"{files[0]}: 1 of 150 PRIs left out, they hold data the DCA1000 lost (1 packets repeated with other "
            "data)"]
    code, stderr = cli_ingest(tmp_path / "cap", tmp_path / "d.h5")
    assert code == 0 and "a packet repeats byte count 1456000 with other data" in stderr, stderr
    r = runner.invoke(app, ["info", str(tmp_path / "cap"), "--json"])
    assert r.exit_code == 0 and "2671 recorded, 0 lost, 2 out of order, 1 repeated (1 with other data: their PRIs " \
        "left out)" in r.stdout, r.output


def test_packets_split_across_files_and_a_damaged_file(tmp_path: Path) -> None:
    """A recording split anywhere (a packet, even its header, across two files) reads as one stream. Bytes that
    break the packet layout (a header overwritten in the second file) are left out up to the next header that
    fits, with a warning naming the file and offset; the PRIs they held are left out and every other PRI is the
    one written. A split file missing from the middle: its packets are lost, the later files' are read."""
    p, pris, files = config_capture(tmp_path / "one", packet_bytes=PACKET)
    stream = files[0].read_bytes()
    split = tmp_path / "split"
    split.mkdir()
    (split / "capture.cfg").write_bytes((tmp_path / "one" / "capture.cfg").read_bytes())
    cuts = [0, 1_000_003, 1500 * (PACKET + 10) + 5, len(stream)]  # cut in a packet's data, then in a header
    for k in range(3):
        (split / f"adc_data_Raw_{k}.bin").write_bytes(stream[cuts[k]:cuts[k + 1]])
    cap = Dca1000Capture(split)
    assert len(cap.files) == 3 and cap.packets.lost_packets == 0
    blocks = list(cap.blocks())
    np.testing.assert_array_equal(np.concatenate([b for _, b, _ in blocks]), pris)
    assert cap.warnings == [] and not any(d.any() for _, _, d in blocks)
    # its middle file missing: the next starts inside a packet, where reading resumes at the next header
    (split / "adc_data_Raw_1.bin").unlink()
    cap = Dca1000Capture(split)
    assert cap.warnings == [f"{split}: split file adc_data_Raw_1.bin missing: its packets are lost"]
    blocks = list(cap.blocks())
    damaged = np.concatenate([d for _, _, d in blocks])
    first_lost = cuts[1] // (PACKET + 10) * PACKET  # the loss starts in the packet the cut went through
    assert np.flatnonzero(damaged)[0] == first_lost // p.frame_bytes and damaged.sum() < 50
    np.testing.assert_array_equal(np.concatenate([b for _, b, _ in blocks])[~damaged], pris[~damaged])

    _, _, files = config_capture(tmp_path / "three", packet_bytes=PACKET, split_bytes=1_000_000)
    assert len(files) == 4
    damaged_at = 300 * (PACKET + 10)  # a header in the second file
    with open(files[1], "r+b") as f:
        f.seek(damaged_at)
        f.write(b"\xff" * 20)
    cap = Dca1000Capture(tmp_path / "three")
    assert cap.warnings == [f"{files[1]}: byte {damaged_at} is no DCA1000 packet of 1456 data bytes (sequence "
                            f"{0xffffffff}, byte count {2**48 - 1}): left out up to byte {damaged_at + PACKET + 10}"]
    per_file = 1_000_000 // (PACKET + 10)
    lost = ((per_file + 300) * PACKET, (per_file + 301) * PACKET)
    np.testing.assert_array_equal(cap.packets.lost, [lost])
    blocks = list(cap.blocks())
    damaged = np.concatenate([d for _, _, d in blocks])
    assert set(np.flatnonzero(damaged)) == pris_of(lost, p)
    np.testing.assert_array_equal(np.concatenate([b for _, b, _ in blocks])[~damaged], pris[~damaged])

    files[1].unlink()
    cap = Dca1000Capture(tmp_path / "three")
    assert cap.warnings[0] == f"{files[0].parent}: split file adc_data_Raw_1.bin missing: its packets are lost"
    lost = (per_file * PACKET, 2 * per_file * PACKET)
    np.testing.assert_array_equal(cap.packets.lost, [lost])
    blocks = list(cap.blocks())
    damaged = np.concatenate([d for _, _, d in blocks])
    assert set(np.flatnonzero(damaged)) == pris_of(lost, p) and len(damaged) == len(pris)
    np.testing.assert_array_equal(np.concatenate([b for _, b, _ in blocks])[~damaged], pris[~damaged])
    # the data alone: where the files after a missing one belong is unknown, so they are left out
    _, _, files = config_capture(tmp_path / "flat", split_bytes=1_000_000)
    files[1].unlink()
    cap = Dca1000Capture(tmp_path / "flat")
    assert cap.files == files[:1] and cap.num_frames == 1_000_000 // p.frame_bytes
    assert cap.warnings[0] == (f"{files[0].parent}: split file adc_data_Raw_1.bin missing: the 2 after it left "
                               "out, for where their data belongs is unknown without it")


def test_zero_filled_packets_of_post_processed_data_are_left_out(tmp_path: Path) -> None:
    """mmWave Studio's post-processing fills a lost packet with zeros: a run of zeros as long as a packet is no
    echo. The PRIs it touches are left out: one inside a PRI; one across the edge of the reader's 64-frame blocks
    that is too short to be seen on either side alone (an 800-byte packet: 200 zeros each side); and isolated
    zero samples, which real ADC data holds, are kept."""
    p, pris, files = config_capture(tmp_path / "cap")
    data = bytearray(files[0].read_bytes())
    inside = (100 * p.frame_bytes + 5000, 100 * p.frame_bytes + 5000 + PACKET)
    edge = (64 * p.frame_bytes - 400, 64 * p.frame_bytes + 400)
    for a, b in (inside, edge):
        data[a:b] = bytes(b - a)
    files[0].write_bytes(bytes(data))
    assert np.count_nonzero(pris == 0) > 100  # single zero samples elsewhere
    cap = Dca1000Capture(tmp_path / "cap")
    blocks = list(cap.blocks())
    damaged = np.concatenate([d for _, _, d in blocks])
    assert set(np.flatnonzero(damaged)) == pris_of(inside, p) | pris_of(edge, p) == {63, 64, 100}
    np.testing.assert_array_equal(np.concatenate([b for _, b, _ in blocks])[~damaged], pris[~damaged])
    assert cap.damage == {"lost packets": 0, "zero-filled runs": 2, "PRIs": 3}
    assert cap.warnings == [f"{files[0]}: 3 of 150 PRIs left out, they hold data the DCA1000 lost "
                            "(2 zero-filled runs)"]


def test_a_flipped_high_byte_in_the_adc_data_is_reported(tmp_path: Path) -> None:
    """The ADC data carries no checksum; a flipped high byte makes a sample no ADC gives beside its frame's
    (crest factor), which ingest reports by PRI, as for RawFrame logs. The PRI is kept: the warning says where."""
    p, pris, files = config_capture(tmp_path / "cap")
    data = bytearray(files[0].read_bytes())
    at = 77 * p.frame_bytes + 2 * 1001 + 1  # the high byte of a sample of PRI 77
    data[at] ^= 0x70
    files[0].write_bytes(bytes(data))
    code, stderr = cli_ingest(tmp_path / "cap", tmp_path / "d.h5")
    assert code == 0, stderr
    assert "1 radar frames have a crest factor (peak/RMS) far above the stream's, or are all zero (damaged " \
           "data?): frame indices 77" in stderr, stderr.splitlines()
    with Drive(tmp_path / "d.h5") as d:
        assert d.radar().raw.shape[0] == len(pris)


def test_real_ti_frames_through_a_capture(tmp_path: Path) -> None:
    """OpenRadar's real TI frame (2 Tx x 4 Rx TDM-MIMO, 128 loops, 60 MHz/us, 2.5 Msps, 128 samples) written
    back as a 2-lane DCA1000 capture, read by the ingest reader and range-compressed by the product: the real
    target stands >= 20 dB above the median floor, at the range a plain float64 numpy FFT gives."""
    from autosar_cli.sar.range_compression import bistatic_range_axis, range_compress

    frames = np.load(realdata("openradar", "doppler_example_1.npy"))  # (chirps, 2 Tx x 4 Rx, samples)
    iq = np.stack([frames.real.astype(np.int16), frames.imag.astype(np.int16)], axis=-1)
    pris = iq.reshape(128, 2, 4, 128, 2)
    p = CaptureParams(profile_start_frequency_hz=77e9, slope_hz_per_s=60e12, sample_rate_hz=2.5e6,
                      num_samples=128, adc_start_s=0.0, chirp_period_s=100e-6, rx_channels=(0, 1, 2, 3),
                      chirp_tx=(0, 1), num_loops=128, num_frames=1, frame_period_s=40e-3, adc_format="complex1x",
                      lanes=2)
    write_capture(tmp_path, p, [pris])
    cap = Dca1000Capture(tmp_path)
    blocks = list(cap.blocks())
    raw = np.concatenate([b for _, b, _ in blocks])
    assert raw.shape == (128, 2, 4, 128, 2)
    assert not any(d.any() for _, _, d in blocks)  # real ADC noise holds no run of zeros a lost packet leaves
    assert len(implausible_frames(frame_statistics(np.arange(128), raw))) == 0  # nor a crest factor ingest flags

    up = 4
    rc = range_compress(raw, sample_rate_hz=cap.params.sample_rate_hz, slope_hz_per_s=cap.params.slope_hz_per_s,
                        upsample=up)
    profile = np.mean(np.abs(rc) ** 2, axis=(0, 1, 2))
    axis = bistatic_range_axis(profile.size, sample_rate_hz=2.5e6, slope_hz_per_s=60e12) / 2
    usable = (axis > 0.3) & (np.arange(axis.size) < axis.size // 2)  # beyond Tx->Rx leakage; positive beats
    k = int(np.argmax(np.where(usable, profile, 0.0)))
    assert 10 * np.log10(profile[k] / np.median(profile)) >= 20.0

    # reference: straight from the .npy, float64, Hann-tapered zero-padded numpy FFT
    beat = frames.real.astype(np.int16).astype(np.float64) + 1j * frames.imag.astype(np.int16).astype(np.float64)
    ref = np.mean(np.abs(np.fft.fft(beat * np.hanning(128), n=128 * up, axis=-1)) ** 2, axis=(0, 1))
    k_ref = int(np.argmax(np.where(usable, ref, 0.0)))
    ref_range = k_ref * 3e8 * 2.5e6 / (2 * 60e12 * 128 * up)
    assert axis[k] == pytest.approx(ref_range, abs=3e8 / (2 * 60e12 * 128 / 2.5e6) / up * 1.01)
    assert 1.0 < axis[k] < 3.0


def test_the_sdk_cfgs_channel_calibration_is_the_drives_stated_gains(tmp_path: Path) -> None:
    """``compRangeBiasAndRxChanPhase`` (TI's per-channel compensation, Tx-major over the device's 3 Tx x 4 Rx) is
    kept as the radar's channel gains, their inverse, on the drive's (Tx, Rx) axes; focus undoes them."""
    from autosar_cli.sar.channel_calibration import with_stated_gains
    from autosar_cli.sar.channel_gains import stated_channel_gains
    from autosar_cli.sar.focus import FocusOptions, channel_pairs

    rng = np.random.default_rng(5)
    coeff = np.exp(1j * rng.uniform(-np.pi, np.pi, 12)) * rng.uniform(0.7, 1.3, 12)
    cap = sdk_cfg(tmp_path / "cap")
    cfg = cap / "capture.cfg"
    line = "compRangeBiasAndRxChanPhase 0.05 " + " ".join(f"{c.real:.6f} {c.imag:.6f}" for c in coeff)
    cfg.write_text(cfg.read_text().replace("sensorStart", line + "\nsensorStart"))
    code, stderr = cli_ingest(cap, tmp_path / "d.h5")
    assert code == 0, stderr
    assert "range bias 0.05 m is not applied" in stderr
    with Drive(tmp_path / "d.h5") as d:
        attrs = dict(d.radar().attrs)
    gains = 1.0 / coeff.reshape(3, 4)
    assert np.allclose(attrs["channel_gain_db"], 20 * np.log10(np.abs(gains)), atol=1e-6)
    assert np.allclose(np.exp(1j * np.radians(attrs["channel_phase_deg"])), np.exp(1j * np.angle(gains)), atol=1e-6)
    stated = stated_channel_gains(attrs)
    assert stated is not None
    pairs = channel_pairs(3, 4, 8)
    undone = stated.correction(pairs) * np.array([gains[t, r] for t, r in pairs])
    assert np.allclose(undone, undone[0], rtol=1e-3)  # every channel alike once undone
    assert with_stated_gains(tmp_path / "d.h5", FocusOptions()).channel_gains == stated
    # the identity (TI's default) states nothing; a line of the wrong length is one line's error
    cfg.write_text(cfg.read_text().replace(line, "compRangeBiasAndRxChanPhase 0.0" + " 1 0" * 12))
    assert cli_ingest(cap, tmp_path / "e.h5")[0] == 0
    with Drive(tmp_path / "e.h5") as d:
        assert "channel_phase_deg" not in d.radar().attrs
    cfg.write_text(cfg.read_text().replace("compRangeBiasAndRxChanPhase 0.0" + " 1 0" * 12,
                                           "compRangeBiasAndRxChanPhase 0.0" + " 1 0" * 5))
    code, stderr = cli_ingest(cap, tmp_path / "f.h5")
    assert_one_line_error(code, stderr, "compRangeBiasAndRxChanPhase has 11 values")


@pytest.mark.parametrize(("args", "said"), [
    (["--radar-start", "1612951200"], "not a time from 2000 on in ns since the Unix epoch (seconds"),
    (["--radar-start", "99999999999999999999999999"], "not a time from 2000 on"),
    (["--radar-start", "2021-02-10T10:00:00Z", "--time-offset", "x.asc=1e300"], "more than a century"),
])
def test_a_start_or_offset_no_clock_can_be_is_refused_naming_the_option(tmp_path: Path, args: list[str],
                                                                          said: str) -> None:
    """A capture's start given in seconds was taken for ns (the radar 1.6 s after 1970, exit 0); one too large for
    an int64, or a time offset of 1e300 s, ended in "Python int too large to convert to C long" or "cannot convert
    float infinity to integer". Each is one line naming the option."""
    r = runner.invoke(app, ["ingest", str(tmp_path / "x.mcap"), "-o", str(tmp_path / "d.h5"), *args])
    assert_one_line_error(r.exit_code, r.stderr, said)


def test_a_capture_cut_at_a_frames_end_says_how_many_frames_it_lacks(tmp_path: Path) -> None:
    """A capture cut exactly at a frame's end (a copy stopped there) read as whole: no warning, the run ok, though
    its parameter file configures twice its frames. It now names how many it holds of those configured."""
    p = params_from_radar(CFG.radar, num_frames=4)
    pris = np.random.default_rng(6).integers(-500, 500, (4, 3, 4, 540, 2), dtype=np.int16)
    write_capture(tmp_path / "cap", p, [pris], param_format="json")
    data = tmp_path / "cap" / "adc_data.bin"
    data.write_bytes(data.read_bytes()[:2 * p.frame_bytes])
    code, stderr = cli_ingest(tmp_path / "cap", tmp_path / "d.h5")
    assert code == 0 and "adc_data.bin: holds 2 of the 4 frames capture.mmwave.json configures" in stderr, stderr
    with Drive(tmp_path / "d.h5") as d:
        assert len(d.radar().t_ns) == 2


def test_a_drive_whose_capture_was_not_given_says_to_give_it(simulated_capture: tuple[Path, Path, Path],
                                                            tmp_path: Path) -> None:
    """`ingest LOG` of a DCA1000 drive without --radar said only "no radar stream (use --allow-partial ...)": it
    names the capture beside the log, or, alone, the frame triggers the log holds, and the option to give."""
    log, capture, _ = simulated_capture
    r = runner.invoke(app, ["ingest", str(log), "-o", str(tmp_path / "d.h5")])
    assert r.exit_code == 1 and f"no radar stream; a DCA1000 capture lies beside it ({capture}): give it with " \
        f"--radar {capture}" in " ".join(r.stderr.split()), r.stderr
    alone = tmp_path / "alone" / log.name
    alone.parent.mkdir()
    shutil.copy(log, alone)
    r = runner.invoke(app, ["ingest", str(alone), "-o", str(tmp_path / "d.h5")])
    assert r.exit_code == 1 and "no radar stream; the log holds 981 DCA1000 frame triggers on /dca1000/sync: give " \
        "their capture with --radar CAPTURE" in " ".join(r.stderr.split()), r.stderr
    assert not (tmp_path / "d.h5").exists()
    # another drive's capture beside it too: the one named as the log is named (the first in order was)
    pair = tmp_path / "pair"
    pair.mkdir()
    shutil.copy(log, pair / "x.mcap")
    for name in ("a_other.dca1000", "x.dca1000"):
        (pair / name).symlink_to(capture, target_is_directory=True)
    r = runner.invoke(app, ["ingest", str(pair / "x.mcap"), "-o", str(tmp_path / "d.h5")])
    assert f"--radar {pair / 'x.dca1000'}" in " ".join(r.stderr.split()), r.stderr
