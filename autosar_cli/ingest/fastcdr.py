"""Hand-written little-endian CDR readers for the hottest message types: RawFrame, Imu and CAN Frame.

A radar-heavy log is ~95 % RawFrame, Imu and CAN messages. rosbags' generic deserializer builds a full
message object (~20 µs per RawFrame, ~12 µs per Imu here); these read just the fields ingest stores
with :mod:`struct` (~3 µs). They are used only for CDR channels whose definition is the built-in one
(checked in :mod:`.typesys`), and tests compare them field by field with rosbags.

CDR alignment is relative to the byte after the 4-byte encapsulation header.
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np

_LE = b"\x00\x01"
_SEC_NSEC_LEN = struct.Struct("<iII")  # stamp.sec, stamp.nanosec, frame_id length
_U32 = struct.Struct("<I")
_F3 = struct.Struct("<3d")
_IMU = struct.Struct("<37d")
_CAN = struct.Struct("<I???B8s")  # id, is_rtr, is_extended, is_error, dlc, data[8]


class NotLittleEndian(ValueError):
    """The payload is big-endian CDR; use the generic deserializer."""


def _header(buf: Any) -> tuple[int, int]:
    """(stamp in ns, offset after the header) of a CDR message starting with std_msgs/Header."""
    if bytes(buf[:2]) != _LE:
        raise NotLittleEndian
    sec, nsec, n = _SEC_NSEC_LEN.unpack_from(buf, 4)
    return sec * 1_000_000_000 + nsec, 16 + n


def _align(pos: int, size: int) -> int:
    return 4 + ((pos - 4 + size - 1) & ~(size - 1))


def raw_frame(buf: Any) -> tuple[int, int, tuple[Any, ...], np.ndarray]:
    """scanbrick_msgs/msg/RawFrame → (stamp ns, frame_index, params, int16 data view).

    ``params`` = (start_frequency_hz, slope_hz_per_s, sample_rate_hz, tx_start_offsets_s tuple,
    (num_tx, num_rx, num_samples)), the same tuple :class:`~.decoders.RadarDecoder` compares.
    """
    stamp, pos = _header(buf)
    pos = _align(pos, 4)
    (frame_index,) = _U32.unpack_from(buf, pos)
    pos = _align(pos + 4, 8)
    f0, slope, fs = _F3.unpack_from(buf, pos)
    pos += 24
    (n,) = _U32.unpack_from(buf, pos)
    pos += 4
    if n:
        pos = _align(pos, 8)
        offsets = struct.unpack_from(f"<{n}d", buf, pos)
        pos += 8 * n
    else:
        offsets = ()
    num_tx, num_rx = buf[pos], buf[pos + 1]
    pos = _align(pos + 2, 2)
    (num_samples,) = struct.unpack_from("<H", buf, pos)
    pos = _align(pos + 2, 4)
    (count,) = _U32.unpack_from(buf, pos)
    pos += 4
    if count:
        pos = _align(pos, 2)
    if pos + 2 * count > len(buf):
        raise ValueError("RawFrame data runs past the end of the message")
    data = np.frombuffer(buf, dtype="<i2", count=count, offset=pos)
    return stamp, frame_index, (f0, slope, fs, offsets, (num_tx, num_rx, num_samples)), data


def imu(buf: Any) -> tuple[int, tuple[float, ...]]:
    """sensor_msgs/msg/Imu → (stamp ns, row) with the row layout of :func:`~.decoders.imu_row`."""
    stamp, pos = _header(buf)
    v = _IMU.unpack_from(buf, _align(pos, 8))
    # wire order: orientation(4) cov(9) angular_velocity(3) cov(9) linear_acceleration(3) cov(9)
    return stamp, (*v[13:16], *v[25:28], *v[0:4], *v[16:25], *v[28:37], *v[4:13])


def can_frame(buf: Any) -> tuple[int, int, bool, bool, bool, int, bytes]:
    """can_msgs/msg/Frame → (stamp ns, id, is_rtr, is_extended, is_error, dlc, data[8])."""
    stamp, pos = _header(buf)
    return (stamp, *_CAN.unpack_from(buf, _align(pos, 4)))
