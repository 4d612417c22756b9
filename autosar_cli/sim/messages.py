"""Turn simulated sensor samples into the ROS messages the real devices' drivers publish.

CAN sensors become can_msgs/Frame (encoded with the DBC: quantisation, counters, J1850 checksums),
IMUs sensor_msgs/Imu, GNSS receivers sensor_msgs/NavSatFix + velocity and nmea_msgs/Sentence.
Everything is yielded as (log_time_ns, topic, msg) for a time-ordered merge.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import Any

import cantools
import numpy as np
from pynmeagps import NMEAMessage
from pynmeagps.nmeatypes_core import GET

from autosar_cli import msgs
from autosar_cli.candb import encode_frame, to_dbc_unit
from autosar_cli.config import Config, SensorConfig
from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.sim.sensors import SensorSamples

# Bus / driver transport delay between the header stamp and the logger receiving the message.
TRANSPORT_DELAY_NS = 200_000
GEOID_SEPARATION_M = 47.0  # reported in GGA; alt (MSL) = ellipsoidal height - separation
KNOTS_PER_MPS = 1.0 / 0.514444


@dataclass(frozen=True)
class Topic:
    name: str
    msgtype: str


def can_topic(ros_version: int) -> str:
    """Default CAN topic of the ROS drivers: socketcan_bridge (ROS1) / ros2_socketcan (ROS2)."""
    return "/received_messages" if ros_version == 1 else "/from_can_bus"


def sensor_topics(s: SensorConfig, ros_version: int) -> list[Topic]:
    if s.kind in ("wheel_speeds", "steering", "can_imu"):
        return [Topic(can_topic(ros_version), msgs.CAN_FRAME)]
    if s.kind == "imu":
        return [Topic(s.topic, msgs.IMU)]
    topics = [Topic(s.topic, msgs.NAV_SAT_FIX)]
    if s.velocity_topic:
        vt = msgs.TWIST_STAMPED if s.velocity_type == "twist" else msgs.TWIST_WITH_COVARIANCE_STAMPED
        topics.append(Topic(s.velocity_topic, vt))
    if s.nmea_topic:
        topics.append(Topic(s.nmea_topic, msgs.NMEA_SENTENCE))
    return topics


class MessageFactory:
    """Builds rosbags message objects for one typestore (ROS1 or ROS2)."""

    def __init__(self, typestore: Any, ros_version: int, start_ns: int, origin: GeodeticOrigin) -> None:
        self.ts = typestore
        self.ros_version = ros_version
        self.start_ns = start_ns
        self.origin = origin
        self.T = typestore.types

    def stamp_ns(self, t_s: float) -> int:
        return self.start_ns + int(round(t_s * 1e9))

    def header(self, t_ns: int, frame_id: str) -> Any:
        return msgs.header(self.ts, t_ns, frame_id)

    def vector3(self, v: np.ndarray) -> Any:
        return self.T["geometry_msgs/msg/Vector3"](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    # -- CAN -----------------------------------------------------------------------------------------
    def can_frames(self, samples: SensorSamples, config: Config, db: cantools.database.can.Database,
                   topic: str) -> Iterator[tuple[int, str, Any]]:
        """One frame per DBC message carrying any of this sensor's roles, at every sample time."""
        by_message: dict[str, dict[str, str]] = {}
        for role in samples.values:
            if role not in config.can.roles:
                continue
            message, signal = config.can.role_signal(role)
            by_message.setdefault(message, {})[role] = signal
        Frame = self.T[msgs.CAN_FRAME]
        for message, roles in by_message.items():
            frame_id = db.get_message_by_name(message).frame_id
            for i, t in enumerate(samples.t_stamp):
                values = {}
                for role, signal in roles.items():
                    value = samples.values[role][i]
                    value = to_dbc_unit(value, db.get_message_by_name(message).get_signal_by_name(signal).unit)
                    values[signal] = float(value)
                payload = encode_frame(db, message, values, counter=i)
                data = np.zeros(8, dtype=np.uint8)
                data[: len(payload)] = np.frombuffer(payload, dtype=np.uint8)
                t_ns = self.stamp_ns(t)
                msg = Frame(header=self.header(t_ns, "can0"), id=frame_id, is_rtr=False, is_extended=False,
                            is_error=False, dlc=len(payload), data=data)
                yield t_ns + TRANSPORT_DELAY_NS, topic, msg

    # -- IMU -----------------------------------------------------------------------------------------
    def imu(self, samples: SensorSamples, s: SensorConfig) -> Iterator[tuple[int, str, Any]]:
        Imu = self.T[msgs.IMU]
        Quaternion = self.T["geometry_msgs/msg/Quaternion"]
        gyro, accel = samples.values["angular_velocity"], samples.values["linear_acceleration"]
        no_orientation = np.zeros(9)
        no_orientation[0] = -1.0  # REP 145: orientation not provided
        g_cov = np.diag(np.full(3, (np.deg2rad(s.gyro.noise_density_dps_rthz) ** 2) * s.rate_hz)).ravel()
        a_cov = np.diag(np.full(3, (s.accel.noise_density_mps2_rthz**2) * s.rate_hz)).ravel()
        for i, t in enumerate(samples.t_stamp):
            t_ns = self.stamp_ns(t)
            msg = Imu(header=self.header(t_ns, s.frame_id or samples.name),
                      orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=no_orientation,
                      angular_velocity=self.vector3(gyro[i]), angular_velocity_covariance=g_cov,
                      linear_acceleration=self.vector3(accel[i]), linear_acceleration_covariance=a_cov)
            yield t_ns + TRANSPORT_DELAY_NS, s.topic, msg

    # -- GNSS ----------------------------------------------------------------------------------------
    def gnss(self, samples: SensorSamples, s: SensorConfig) -> Iterator[tuple[int, str, Any]]:
        e = s.gnss
        lat, lon, h = self.origin.to_geodetic(samples.values["position_enu"])
        vel = samples.values["velocity_enu"]
        NavSatFix, NavSatStatus = self.T[msgs.NAV_SAT_FIX], self.T["sensor_msgs/msg/NavSatStatus"]
        sh = (e.horizontal_std_m**2 + e.white_std_m**2)
        sv = (e.vertical_std_m**2 + 4 * e.white_std_m**2)
        pos_cov = np.diag([sh, sh, sv]).ravel()
        vel_cov = np.diag([e.velocity_std_mps**2] * 2 + [(1.5 * e.velocity_std_mps) ** 2] + [1e6] * 3).ravel()
        frame = s.frame_id or samples.name
        for i, t in enumerate(samples.t_stamp):
            t_ns = self.stamp_ns(t)
            hdr = self.header(t_ns, frame)
            fix = NavSatFix(header=hdr, status=NavSatStatus(status=0, service=1), latitude=float(lat[i]),
                            longitude=float(lon[i]), altitude=float(h[i]), position_covariance=pos_cov,
                            position_covariance_type=2)
            log_ns = t_ns + TRANSPORT_DELAY_NS
            yield log_ns, s.topic, fix
            if s.velocity_topic:
                twist = self.T["geometry_msgs/msg/Twist"](linear=self.vector3(vel[i]),
                                                          angular=self.vector3(np.zeros(3)))
                if s.velocity_type == "twist":
                    vmsg = self.T[msgs.TWIST_STAMPED](header=self.header(t_ns, frame), twist=twist)
                else:
                    cov = self.T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=vel_cov)
                    vmsg = self.T[msgs.TWIST_WITH_COVARIANCE_STAMPED](header=self.header(t_ns, frame), twist=cov)
                yield log_ns, s.velocity_topic, vmsg
            if s.nmea_topic:
                fix_time = datetime.fromtimestamp(0, UTC) + timedelta(
                    microseconds=round(self.stamp_ns(samples.t_meas[i]) / 1e3))
                speed = float(np.hypot(vel[i, 0], vel[i, 1]))
                for sentence in nmea_sentences(fix_time, float(lat[i]), float(lon[i]), float(h[i]), speed,
                                               float(samples.values["course_deg"][i]),
                                               float(samples.values["heading_deg"][i])):
                    yield log_ns, s.nmea_topic, self.T[msgs.NMEA_SENTENCE](header=self.header(t_ns, frame),
                                                                           sentence=sentence)


def nmea_sentences(fix_time: datetime, lat: float, lon: float, height_m: float, speed_mps: float,
                   course_deg: float, heading_deg: float) -> list[str]:
    """GGA, RMC, VTG and HDT for one fix (pynmeagps does the formatting and checksums)."""
    hms = fix_time.strftime("%H:%M:%S.%f")[:-4]
    common = {"lat": lat, "NS": "N" if lat >= 0 else "S", "lon": lon, "EW": "E" if lon >= 0 else "W"}
    knots = speed_mps * KNOTS_PER_MPS
    out = [
        NMEAMessage("GN", "GGA", GET, time=hms, **common, quality=2, numSV=14, HDOP=0.7,
                    alt=round(height_m - GEOID_SEPARATION_M, 3), altUnit="M", sep=GEOID_SEPARATION_M, sepUnit="M",
                    hpnmeamode=True),
        NMEAMessage("GN", "RMC", GET, time=hms, status="A", **common, spd=round(knots, 3), cog=round(course_deg, 2),
                    date=fix_time.date(), mv="", mvEW="", posMode="D", hpnmeamode=True),
        NMEAMessage("GN", "VTG", GET, cogt=round(course_deg, 2), cogtUnit="T", cogm="", cogmUnit="M",
                    sogn=round(knots, 3), sognUnit="N", sogk=round(speed_mps * 3.6, 3), sogkUnit="K", posMode="D"),
        NMEAMessage("GN", "HDT", GET, headingT=round(heading_deg, 3), headingTu="T"),
    ]
    return [m.serialize().decode("ascii").strip() for m in out]
