"""The hand-written CDR readers agree with rosbags' generic deserializer field by field."""

from __future__ import annotations

import numpy as np
import pytest

from autosar_cli.ingest import fastcdr
from autosar_cli.ingest.decoders import _stamp_ns, imu_row
from autosar_cli.msgs import CAN_FRAME, IMU, RAW_FRAME, header, typestore_for

TS = typestore_for(2)
T = TS.types


@pytest.mark.parametrize("frame_id", ["", "r", "radar", "scanbrick_w43_front"])  # every string padding
@pytest.mark.parametrize("offsets", [[], [0.0], [0.0, 60e-6, 120e-6]])
def test_raw_frame_matches_rosbags(frame_id: str, offsets: list[float]) -> None:
    rng = np.random.default_rng(len(frame_id) + len(offsets))
    data = rng.integers(-32768, 32767, 2 * 3 * 4 * 5, dtype=np.int16)
    msg = T[RAW_FRAME](header=header(TS, 1_612_951_200_123_456_789, frame_id), frame_index=4_000_000_001,
                       start_frequency_hz=77e9, slope_hz_per_s=75e12, sample_rate_hz=13.5e6,
                       tx_start_offsets_s=np.array(offsets), num_tx=3, num_rx=4, num_samples=5, data=data)
    buf = TS.serialize_cdr(msg, RAW_FRAME)
    ref = TS.deserialize_cdr(buf, RAW_FRAME)
    stamp, index, params, samples = fastcdr.raw_frame(buf)
    assert stamp == _stamp_ns(ref.header) == 1_612_951_200_123_456_789
    assert index == ref.frame_index == 4_000_000_001
    assert params == (77e9, 75e12, 13.5e6, tuple(offsets), (3, 4, 5))
    np.testing.assert_array_equal(samples, data)


@pytest.mark.parametrize("frame_id", ["", "imu", "imu_cog_a"])
def test_imu_matches_rosbags(frame_id: str) -> None:
    rng = np.random.default_rng(1)
    v3 = T["geometry_msgs/msg/Vector3"]
    msg = T[IMU](header=header(TS, 1_000_000_007, frame_id),
                 orientation=T["geometry_msgs/msg/Quaternion"](x=0.1, y=0.2, z=0.3, w=0.9),
                 orientation_covariance=rng.normal(size=9), angular_velocity=v3(x=1.0, y=-2.0, z=np.nan),
                 angular_velocity_covariance=rng.normal(size=9),
                 linear_acceleration=v3(x=9.81, y=0.5, z=-0.25), linear_acceleration_covariance=rng.normal(size=9))
    buf = TS.serialize_cdr(msg, IMU)
    stamp, row = fastcdr.imu(buf)
    ref = TS.deserialize_cdr(buf, IMU)
    assert stamp == _stamp_ns(ref.header) == 1_000_000_007
    np.testing.assert_array_equal(np.array(row), np.array(imu_row(ref)))


def test_can_frame_matches_rosbags() -> None:
    data = np.array([0x17, 0x51, 0x97, 0xCC, 0x00, 0xDF, 0, 0], dtype=np.uint8)
    msg = T[CAN_FRAME](header=header(TS, 5, "can0"), id=0xDE, is_rtr=False, is_extended=True, is_error=False,
                       dlc=6, data=data)
    buf = TS.serialize_cdr(msg, CAN_FRAME)
    assert fastcdr.can_frame(buf) == (5, 0xDE, False, True, False, 6, data.tobytes())


def test_big_endian_is_left_to_rosbags() -> None:
    msg = T[CAN_FRAME](header=header(TS, 5, "can0"), id=1, is_rtr=False, is_extended=False, is_error=False,
                       dlc=0, data=np.zeros(8, np.uint8))
    buf = bytearray(TS.serialize_cdr(msg, CAN_FRAME))
    buf[1] = 0x00  # encapsulation kind CDR_BE
    with pytest.raises(fastcdr.NotLittleEndian):
        fastcdr.can_frame(bytes(buf))
