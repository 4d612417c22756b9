"""Ingest round trip: every simulated format into drive.h5, compared with the truth sidecar and with an
independent decode of the log (rosbags' AnyReader, cantools)."""

from __future__ import annotations

import math
from pathlib import Path

import cantools
import h5py
import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from autosar_cli.config import load_config
from autosar_cli.ingest.pipeline import ingest
from autosar_cli.msgs import typestore_for
from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.store.drive import FORMAT_VERSION, Drive

CFG = load_config()


@pytest.fixture(scope="module", params=["mcap", "ros1", "ros2"])
def drive(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory):
    sim = request.getfixturevalue(f"ci_{request.param}")
    out = tmp_path_factory.mktemp("drive") / "drive.h5"
    report = ingest([sim.log_path], out, config=CFG)
    with Drive(out) as d, h5py.File(sim.truth_path, "r") as truth:
        yield request.param, sim, report, d, truth


def test_layout_and_report(drive) -> None:
    fmt, sim, report, d, _ = drive
    assert d.attrs["format"] == "autosar-drive" and d.attrs["format_version"] == FORMAT_VERSION
    assert d.radar_names() == ["scanbrick_w43"]
    assert d.imu_sources() == ["imu_cog_a", "imu_cog_b", "ins_cog", "ins_radar"]
    assert d.gnss_sources() == ["gnss_cog", "gnss_radar"]
    assert d.can_messages() == ["ABS_1", "ABS_2", "EPS_1", "ORC_1"]
    assert report.warnings == [] and report.skipped_channels == []
    assert report.can["checksum_errors"] == {} and report.can["counter_errors"] == {}
    for s in report.streams:  # a clean simulated log: nothing dropped, nothing repaired
        assert (s["duplicates"], s["late_dropped"], s["time_jumps"], s["gaps"]) == (0, 0, 0, 0), s
        assert s["written"] == s["received"], s
    inputs = d.h5["provenance/inputs"][()]
    assert inputs.shape == (1,) and len(inputs[0]["sha256"]) == 64 and inputs[0]["size_bytes"] > 10e6
    assert report.messages == sum(sim.message_counts.values())
    assert d.can_roles()["wheel_speed_fl"] == "ABS_1/WHEEL_SPEED_FL"


def test_radar_cube_is_bit_exact(drive) -> None:
    _, sim, _, d, truth = drive
    radar = d.radar()
    np.testing.assert_array_equal(radar.frame_index, truth["radar/frame_index"][()])
    np.testing.assert_array_equal(radar.t_ns, truth["radar/t_ns"][()])
    assert radar.raw.shape == (sim.radar_frames, 3, 4, 540, 2)
    assert radar.attrs["num_samples"] == 540 and radar.attrs["slope_hz_per_s"] == CFG.radar.slope_hz_per_s
    np.testing.assert_allclose(radar.attrs["tx_start_offsets_s"], [0.0, 60e-6, 120e-6])
    # Independent decode of frames 0, 500 and the last one straight from the log.
    want = {0, 500, sim.radar_frames - 1}
    with AnyReader([sim.log_path], default_typestore=typestore_for(2)) as reader:
        conns = [c for c in reader.connections if c.msgtype.endswith("RawFrame")]
        for i, (conn, _, data) in enumerate(reader.messages(connections=conns)):
            if i in want:
                msg = reader.deserialize(data, conn.msgtype)
                np.testing.assert_array_equal(radar.raw[i].ravel(), msg.data)


def test_imu_times_and_values(drive) -> None:
    _, _, _, d, truth = drive
    for name in ("imu_cog_a", "ins_radar"):
        s = d.series(f"imu/{name}")
        tr = truth[f"sensors/{name}"]
        np.testing.assert_array_equal(s["t_ns"], tr["stamp_ns"][()])
        # measured = true + bias + white noise (noise density x sqrt(rate)); 6 sigma
        sigma = math.radians(CFG.sensors[name].gyro.noise_density_dps_rthz) * math.sqrt(CFG.sensors[name].rate_hz)
        err = s["angular_velocity"][:, 2] - tr["angular_velocity"][:, 2] - tr["gyro_bias"][:, 2]
        assert np.abs(err).max() < 6 * sigma
    assert np.isnan(d.series("imu/imu_cog_a")["angular_velocity"][:, :2]).all()  # 3-DoF: unmeasured axes NaN


def test_gnss_fix_equals_truth_plus_error(drive) -> None:
    _, _, _, d, truth = drive
    origin = GeodeticOrigin(truth.attrs["origin_lat_deg"], truth.attrs["origin_lon_deg"],
                            truth.attrs["origin_height_m"])
    for name in ("gnss_cog", "gnss_radar"):
        fix = d.series(f"gnss/{name}/fix")
        tr = truth[f"sensors/{name}"]
        np.testing.assert_array_equal(fix["t_ns"], tr["stamp_ns"][()])
        enu = origin.to_enu(fix["latitude_deg"], fix["longitude_deg"], fix["altitude_m"])
        np.testing.assert_allclose(enu, tr["position_enu"][()] + tr["position_error"][()], atol=1e-6)
    nmea = d.series("gnss/gnss_cog/nmea_fix")
    np.testing.assert_array_equal(nmea["fix_time_ns"], truth["sensors/gnss_cog/t_ns"][()])
    enu = origin.to_enu(nmea["latitude_deg"], nmea["longitude_deg"], nmea["altitude_m"])
    ref = truth["sensors/gnss_cog/position_enu"][()] + truth["sensors/gnss_cog/position_error"][()]
    np.testing.assert_allclose(enu[:, :2], ref[:, :2], atol=2e-4)  # 1e-7 arc-minute NMEA resolution
    np.testing.assert_allclose(enu[:, 2], ref[:, 2], atol=6e-4)  # altitude to 1 mm in GGA


def test_can_values_in_si_within_quantisation(drive) -> None:
    _, _, _, d, truth = drive
    db = cantools.database.load_file(str(CFG.dbc_path))
    q = db.get_message_by_name("ABS_1").get_signal_by_name("WHEEL_SPEED_FL").scale  # m/s per LSB
    t, v = d.can_role("wheel_speed_fl")
    tr = truth["sensors/wheel_speeds"]
    np.testing.assert_array_equal(t, tr["stamp_ns"][()])
    expected = tr["wheel_speed_fl"][()] * tr["scale_factor"][0]
    assert np.abs(v - expected).max() < 6 * CFG.sensors["wheel_speeds"].wheel.noise_std_mps + q / 2
    # Steering: DBC degrees -> radians; truth is the true angle, measured adds offset + noise.
    t, angle = d.can_role("steering_wheel_angle")
    st = truth["sensors/steering"]
    lsb = math.radians(db.get_message_by_name("EPS_1").get_signal_by_name("STEERING_ANGLE").scale)
    err = angle - st["steering_wheel_angle"][()] - st["offset"][0]
    assert np.abs(err).max() < 6 * math.radians(CFG.sensors["steering"].steering.noise_std_deg) + lsb / 2
    # ORC yaw rate: 1e-4 rad/s LSB.
    t, yaw = d.can_role("yaw_rate.orc")
    orc = truth["sensors/orc"]
    sigma = math.radians(CFG.sensors["orc"].gyro.noise_density_dps_rthz) * math.sqrt(100.0)
    assert np.abs(yaw - orc["yaw_rate.orc"][()] - orc["gyro_bias"][()]).max() < 6 * sigma + 0.5e-4


def test_drive_info_lists_series(drive, tmp_path: Path) -> None:
    from autosar_cli.ingest.inspect import summarize

    _, sim, _, d, _ = drive
    s = {x.topic: x for x in summarize(d.path).streams}
    assert s["radar/scanbrick_w43"].count == sim.radar_frames
    assert s["imu/imu_cog_a"].rate_hz == pytest.approx(500.0, rel=0.01)
    assert all(x.gaps == 0 for x in s.values())
