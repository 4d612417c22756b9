"""The simulated CAN bus carries what the truth sidecar says it should.

Reads the `ci` MCAP with the mcap reader + mcap_ros2 decoder and decodes every frame with cantools
(none of our reading code), then checks each decoded signal against the truth sidecar: the value is the
true value plus the sensor's error state (wheel radius scale factor, steering-wheel offset, gyro and
accelerometer biases), plus white noise of the configured standard deviation, plus the DBC quantisation.
Frames are matched to truth samples by header stamp (== /sensors/<name>/stamp_ns). Also checks the
Giorgio J1850 checksums (recomputed here), the rolling counters and the 100 Hz rates.
"""

from __future__ import annotations

import tomllib
from collections import defaultdict
from pathlib import Path

import cantools
import h5py
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from reference import crc8_j1850

from autosar_cli.candb import check_frame

REPO = Path(__file__).resolve().parents[1]
DBC = REPO / "configs" / "autosar_giulia.dbc"
TOML = REPO / "configs" / "giulia_scanbrick.toml"
CAN_TOPIC = "/from_can_bus"

# message -> simulated sensor (/sensors/<name> in the truth file)
MESSAGE_SENSOR = {"ABS_1": "wheel_speeds", "EPS_1": "steering", "ABS_2": "esc", "ORC_1": "orc"}
# role -> (message, signal) the config must declare (checked against [can.roles])
EXPECTED_ROLES = {
    "wheel_speed_fl": ("ABS_1", "WHEEL_SPEED_FL"),
    "wheel_speed_fr": ("ABS_1", "WHEEL_SPEED_FR"),
    "wheel_speed_rl": ("ABS_1", "WHEEL_SPEED_RL"),
    "wheel_speed_rr": ("ABS_1", "WHEEL_SPEED_RR"),
    "steering_wheel_angle": ("EPS_1", "STEERING_ANGLE"),
    "steering_wheel_rate": ("EPS_1", "STEERING_RATE"),
    "yaw_rate.esc": ("ABS_2", "YAW_RATE"),
    "accel_long.esc": ("ABS_2", "LONG_ACCEL"),
    "accel_lat.esc": ("ABS_2", "LATERAL_ACCEL"),
    "yaw_rate.orc": ("ORC_1", "YAW_RATE"),
    "accel_long.orc": ("ORC_1", "LONG_ACCEL"),
    "accel_lat.orc": ("ORC_1", "LATERAL_ACCEL"),
}
# Giorgio checksum final XOR per frame ID (DBC comment; opendbc fca_giorgio), default 0x0A
FINAL_XOR = {0xDE: 0x10, 0x106: 0xF6, 0x122: 0xF1}




def test_crc8_reference_value():
    # CRC-8/SAE-J1850 without its init/xorout (0xFF/0xFF): check value of "123456789" is 0x37
    assert crc8_j1850(b"123456789") == 0x37


@pytest.fixture(scope="module")
def config() -> dict:
    with open(TOML, "rb") as f:
        return tomllib.load(f)


@pytest.fixture(scope="module")
def db():
    return cantools.database.load_file(str(DBC))


@pytest.fixture(scope="module")
def can(ci_mcap, db):
    """Per message name: stamps (n,) int64, decoded signals {name: (n,)}, raw payloads, counters, ids."""
    out: dict[str, dict] = defaultdict(lambda: {"stamp": [], "signals": defaultdict(list), "data": [],
                                                "log_time": []})
    with open(ci_mcap.log_path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, _, message, frame in reader.iter_decoded_messages(topics=[CAN_TOPIC]):
            assert schema.name == "can_msgs/msg/Frame"
            assert not frame.is_extended and not frame.is_rtr and not frame.is_error
            msg = db.get_message_by_frame_id(frame.id)
            data = bytes(frame.data)
            assert len(data) == 8
            assert frame.dlc == msg.length
            assert data[frame.dlc:] == bytes(8 - frame.dlc), "bytes beyond the DLC must be zero"
            payload = data[: frame.dlc]
            e = out[msg.name]
            e["stamp"].append(frame.header.stamp.sec * 1_000_000_000 + frame.header.stamp.nanosec)
            e["log_time"].append(message.log_time)
            e["data"].append(payload)
            for k, v in msg.decode(payload, decode_choices=False).items():
                e["signals"][k].append(v)
    for e in out.values():
        e["stamp"] = np.array(e["stamp"], dtype=np.int64)
        e["log_time"] = np.array(e["log_time"], dtype=np.int64)
        e["signals"] = {k: np.array(v, dtype=np.float64) for k, v in e["signals"].items()}
    return dict(out)


@pytest.fixture(scope="module")
def truth(ci_mcap):
    with h5py.File(ci_mcap.truth_path) as t:
        return {name: {k: t[f"sensors/{name}/{k}"][()] for k in t[f"sensors/{name}"]}
                for name in MESSAGE_SENSOR.values()}


def matched(can, truth, message):
    """Indices into the truth arrays of the message's frames (by header stamp), asserting a 1:1 match."""
    sensor = MESSAGE_SENSOR[message]
    stamps = can[message]["stamp"]
    t_stamp = truth[sensor]["stamp_ns"]
    assert len(stamps) == len(t_stamp), f"{message}: {len(stamps)} frames for {len(t_stamp)} truth samples"
    idx = np.searchsorted(t_stamp, stamps)
    assert np.all(idx < len(t_stamp))
    assert np.array_equal(t_stamp[idx], stamps), f"{message}: header stamps not in the truth stamp_ns"
    assert np.array_equal(np.sort(idx), np.arange(len(t_stamp)))
    return idx


def qstep(db, message, signal) -> float:
    return abs(db.get_message_by_name(message).get_signal_by_name(signal).scale)


def check_residual(res, sigma, q, label, n_sigma=5.0):
    """Residual = decoded - (true + error state): white noise of std sigma then rounding to a step q."""
    res = np.asarray(res, dtype=np.float64)
    n = res.size
    assert n >= 50, label
    assert np.all(np.isfinite(res)), label
    # rounding to nearest adds at most q/2 to the noise
    worst = np.max(np.abs(res))
    assert worst <= n_sigma * sigma + 0.5 * q * (1 + 1e-9) + 1e-12, f"{label}: |residual| {worst:.3g} > bound"
    # noise + uniform quantisation error; sample std has relative SE ~ 1/sqrt(2n) (~7 % for n = 98)
    expected = np.sqrt(sigma**2 + q**2 / 12.0)
    ratio = np.std(res) / expected
    assert 0.75 < ratio < 1.25, f"{label}: residual std {np.std(res):.3g} vs expected {expected:.3g}"
    # no leftover bias: mean within 4 standard errors
    assert abs(np.mean(res)) < 4.0 * expected / np.sqrt(n), f"{label}: residual mean {np.mean(res):.3g}"


def test_config_roles_match_the_dbc(config, db):
    roles = config["can"]["roles"]
    assert {k: tuple(v.split(".")) for k, v in roles.items()} == EXPECTED_ROLES
    for message, signal in EXPECTED_ROLES.values():
        db.get_message_by_name(message).get_signal_by_name(signal)
    for sensor in MESSAGE_SENSOR.values():
        assert config["sensors"][sensor]["rate_hz"] == 100.0


def test_every_frame_is_a_known_message_at_100hz(can, truth, config, ci_mcap):
    assert set(can) == set(MESSAGE_SENSOR)
    total = sum(len(e["stamp"]) for e in can.values())
    assert total == ci_mcap.message_counts[CAN_TOPIC]
    for message, e in can.items():
        stamps = e["stamp"]
        assert np.all(np.diff(stamps) > 0), f"{message}: stamps not increasing in log order"
        rate = (len(stamps) - 1) / ((stamps[-1] - stamps[0]) * 1e-9)
        assert abs(rate - 100.0) < 1.0, f"{message}: {rate:.3f} Hz"
        # one frame per sample over the whole drive (at 100 Hz, less the latency)
        assert abs(len(stamps) - ci_mcap.duration_s * 100.0) <= 3, message
        # header stamp = measurement instant + the configured latency, logged a little later
        sensor = MESSAGE_SENSOR[message]
        idx = matched(can, truth, message)
        latency_ns = round(config["sensors"][sensor]["latency_s"] * 1e9)
        assert np.all(np.abs(stamps - truth[sensor]["t_ns"][idx] - latency_ns) <= 1), message
        delay = e["log_time"] - stamps
        assert np.all((delay >= 0) & (delay < 5_000_000)), f"{message}: log time - stamp {delay.min()}..{delay.max()}"


def test_checksums_valid(can, db, ci_mcap):
    n = 0
    for message, e in can.items():
        m = db.get_message_by_name(message)
        for payload, chk in zip(e["data"], e["signals"]["CHECKSUM"], strict=True):
            expected = crc8_j1850(payload[:-1]) ^ FINAL_XOR.get(m.frame_id, 0x0A)
            assert payload[-1] == expected == int(chk), f"{message}: checksum {payload[-1]:#04x} != {expected:#04x}"
            assert check_frame(db, m.frame_id, payload).checksum_ok
            n += 1
    assert n == ci_mcap.message_counts[CAN_TOPIC]


def test_checksum_detects_corruption(can, db):
    # the check above is not vacuous: flipping any one payload bit breaks it
    payload = bytearray(can["ABS_1"]["data"][10])
    fid = db.get_message_by_name("ABS_1").frame_id
    for bit in range(8 * (len(payload) - 1)):
        bad = bytearray(payload)
        bad[bit // 8] ^= 1 << (bit % 8)
        assert crc8_j1850(bytes(bad[:-1])) ^ 0x0A != bad[-1]
        assert not check_frame(db, fid, bytes(bad)).checksum_ok


def test_counters_increment_mod_16(can):
    for message, e in can.items():
        counter = e["signals"]["COUNTER"].astype(int)
        assert np.all((counter >= 0) & (counter <= 15))
        assert np.all(np.diff(counter) % 16 == 1), f"{message}: counter jumps {set(np.diff(counter) % 16)}"
        # all 16 values used (more than 16 frames)
        assert set(counter) == set(range(16))


def test_wheel_speeds(can, truth, db, config):
    t = truth["wheel_speeds"]
    idx = matched(can, truth, "ABS_1")
    sigma = config["sensors"]["wheel_speeds"]["wheel"]["noise_std_mps"]
    scale_std = config["sensors"]["wheel_speeds"]["wheel"]["radius_scale_error_std"]
    scale = t["scale_factor"]
    assert scale.shape == (4,)
    assert np.all(np.abs(scale - 1.0) < 5 * scale_std)
    chi2_unit_scale = 0.0
    for i, wheel in enumerate(("fl", "fr", "rl", "rr")):
        signal = f"WHEEL_SPEED_{wheel.upper()}"
        q = qstep(db, "ABS_1", signal)
        assert q == pytest.approx(0.017)
        decoded = can["ABS_1"]["signals"][signal]
        true = t[f"wheel_speed_{wheel}"][idx]
        assert np.all(true > 1.0), "ci drives at ~2.3 m/s"
        # bound without knowing the error state: q/2 + 5 sigma + |scale error| * speed
        assert np.all(np.abs(decoded - true) <= 0.5 * q + 5 * sigma + np.abs(scale[i] - 1) * true + 1e-9)
        check_residual(decoded - true * scale[i], sigma, q, f"wheel {wheel}")
        # the scale factor estimated from the log (least squares through 0) is the truth one
        fitted = np.sum(decoded * true) / np.sum(true * true)
        se = np.sqrt(sigma**2 + q**2 / 12) / np.sqrt(np.sum(true * true))
        assert abs(fitted - scale[i]) < 4 * se, f"wheel {wheel}: fitted scale {fitted:.5f} vs {scale[i]:.5f}"
        chi2_unit_scale += ((scale[i] - 1.0) / se) ** 2
    # the scale test has power: the log is grossly inconsistent with four unit scale factors (chi2, 4 dof;
    # expected ~ 4 x (0.004 / 0.0004)^2 = 400 for the configured radius error)
    assert chi2_unit_scale > 25.0


def test_steering_wheel_angle(can, truth, db, config):
    t = truth["steering"]
    idx = matched(can, truth, "EPS_1")
    cfg = config["sensors"]["steering"]["steering"]
    sigma = cfg["noise_std_deg"]
    q = qstep(db, "EPS_1", "STEERING_ANGLE")
    assert q == pytest.approx(0.1)
    decoded = can["EPS_1"]["signals"]["STEERING_ANGLE"]  # deg in the DBC
    true_deg = np.rad2deg(t["steering_wheel_angle"][idx])
    offset_deg = float(np.rad2deg(t["offset"][0]))
    assert abs(offset_deg) < 5 * cfg["offset_std_deg"]
    assert np.all(np.abs(decoded - true_deg) <= 0.5 * q + 5 * sigma + abs(offset_deg) + 1e-9)
    check_residual(decoded - (true_deg + offset_deg), sigma, q, "steering angle")
    # the offset seen in the log is the truth one (SE ~ 0.06 / sqrt(155) = 0.005 deg)
    se = np.sqrt(sigma**2 + q**2 / 12) / np.sqrt(len(decoded))
    assert np.mean(decoded - true_deg) == pytest.approx(offset_deg, abs=4 * se)
    # the ci drive steers: true angle spans more than the offset, so a missing ratio would show
    assert np.ptp(true_deg) > 1.0 or np.max(np.abs(true_deg)) > 1.0


def test_steering_wheel_rate(can, truth, db):
    # no rate in the truth file: compare with the derivative of the true angle (smooth, 100 Hz)
    t = truth["steering"]
    idx = matched(can, truth, "EPS_1")
    q = qstep(db, "EPS_1", "STEERING_RATE")
    assert q == pytest.approx(0.5)
    order = np.argsort(idx)
    tt = t["t_ns"][idx][order] * 1e-9
    angle = np.rad2deg(t["steering_wheel_angle"][idx][order])
    rate = np.gradient(angle, tt)
    decoded = can["EPS_1"]["signals"]["STEERING_RATE"][order]
    err = np.abs(decoded - rate)[1:-1]
    assert np.max(err) <= 0.5 * q + 0.2, f"steering rate error {np.max(err):.3f} deg/s"


@pytest.mark.parametrize("sensor,message", [("esc", "ABS_2"), ("orc", "ORC_1")])
def test_can_imu_yaw_rate(can, truth, db, config, sensor, message):
    t = truth[sensor]
    idx = matched(can, truth, message)
    g = config["sensors"][sensor]["gyro"]
    rate_hz = config["sensors"][sensor]["rate_hz"]
    sigma = np.deg2rad(g["noise_density_dps_rthz"]) * np.sqrt(rate_hz)
    q = qstep(db, message, "YAW_RATE")
    decoded = can[message]["signals"]["YAW_RATE"]
    true = t[f"yaw_rate.{sensor}"][idx]
    bias = t["gyro_bias"][idx]
    assert bias.shape == true.shape
    # turn-on bias in [0.5, 1.5] x nominal plus a small Gauss-Markov drift
    nominal = np.deg2rad(g["turn_on_bias_dps"])
    drift = np.deg2rad(g["bias_instability_dps"])
    assert np.all((np.abs(bias) > 0.5 * nominal - 5 * drift) & (np.abs(bias) < 1.5 * nominal + 5 * drift))
    # ci curves: the true yaw rate (~0.03 rad/s) is well above the noise, so a wrong sign or scale shows
    assert np.min(np.abs(true)) > 5 * sigma + q
    assert np.all(np.abs(decoded - true) <= 0.5 * q + 5 * sigma + np.abs(bias) + 1e-12)
    check_residual(decoded - (true + bias), sigma, q, f"{sensor} yaw rate")
    se = np.sqrt(sigma**2 + q**2 / 12) / np.sqrt(len(decoded))
    assert np.mean(decoded - true) == pytest.approx(np.mean(bias), abs=4 * se)
    assert abs(np.mean(bias)) > 4 * se  # the bias is visible, so the check above has power


@pytest.mark.parametrize("sensor,message", [("esc", "ABS_2"), ("orc", "ORC_1")])
@pytest.mark.parametrize("axis,signal", [(0, "LONG_ACCEL"), (1, "LATERAL_ACCEL")])
def test_can_imu_accelerations(can, truth, db, config, sensor, message, axis, signal):
    t = truth[sensor]
    idx = matched(can, truth, message)
    a = config["sensors"][sensor]["accel"]
    rate_hz = config["sensors"][sensor]["rate_hz"]
    sigma = a["noise_density_mps2_rthz"] * np.sqrt(rate_hz)
    q = qstep(db, message, signal)
    decoded = can[message]["signals"][signal]
    key = "accel_long" if axis == 0 else "accel_lat"
    true = t[f"{key}.{sensor}"][idx]
    bias = t["accel_bias"][idx, axis]
    assert np.all(np.abs(decoded - true) <= 0.5 * q + 5 * sigma + np.abs(bias) + 1e-12)
    check_residual(decoded - (true + bias), sigma, q, f"{sensor} {signal}")
    se = np.sqrt(sigma**2 + q**2 / 12) / np.sqrt(len(decoded))
    assert np.mean(decoded - true) == pytest.approx(np.mean(bias), abs=4 * se)
    assert abs(np.mean(bias)) > 4 * se
