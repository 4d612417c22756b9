"""Navigation inputs read from a drive.h5: every measurement SAR-MIN fuses, at its measurement instant.

I/O only (no filtering). Times are float64 seconds since ``t0_ns``, already corrected for each
sensor's configured latency (header stamp − latency = the instant the value refers to). Positions are
ENU metres at ``origin``, whose height is the road surface under the first GNSS fix.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import h5py
import numpy as np
from numpy.typing import NDArray

from autosar_cli.config import Config, GnssErrors
from autosar_cli.nav.frames import gravity_tilt_deg, levelling_pitch_roll_deg, sensor_to_body, wrap_angle
from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.store.drive import Drive

Array = NDArray[np.float64]


class NavInputError(ValueError):
    """A drive lacks what navigation needs; the message says what."""


class GravityRemovedError(NavInputError):
    """:func:`read_imu`'s refusal of a stream whose accelerometers hold no gravity, with what it said of it (``said``,
    no drive named) and its columns (``columns``) for a caller that takes its gyros alone."""

    def __init__(self, message: str, said: str, columns: dict[str, Array]) -> None:
        super().__init__(message)
        self.said, self.columns = said, columns


@dataclass
class Measurements:
    """One sensor's samples: times (s), values (n, k) and the standard deviation of one sample (k,)."""

    name: str
    t: Array
    z: Array
    sigma: Array


@dataclass(frozen=True)
class ImuSamples:
    """A 6-DoF IMU's samples (body axes: x forward, y left, z up)."""

    name: str
    t: Array  #: (N,) s since the navigation's t0, latency removed
    angular_velocity: Array  #: (N, 3) rad/s
    specific_force: Array  #: (N, 3) m/s^2 (the accelerometers' reading: acceleration minus gravity)
    lever_arm_m: tuple[float, float, float]  #: the IMU in the body frame, from the CoG
    #: its accelerations with gravity taken out by its driver (:class:`GravityRemovedError`): no roll and pitch from it
    gravity_removed: bool = False


@dataclass
class NavInputs:
    t0_ns: int
    origin: GeodeticOrigin
    gyros: list[Measurements] = field(default_factory=list)
    wheels: Measurements | None = None
    steering: Measurements | None = None  # road-wheel angle (rad) = steering-wheel angle / ratio
    gnss_position: Measurements | None = None  # antenna ENU (x, y)
    gnss_velocity: Measurements | None = None  # antenna ENU (vx, vy)
    gnss_climb: Measurements | None = None  # antenna's up velocity (m/s), where the receiver gives one
    gnss_heading: Measurements | None = None  # the receiver's heading of the body (rad, ENU), where it gives one
    gnss_heading_offset_std: float = 0.0  # prior std of that heading's constant offset (rad)
    gnss_heading_missing: str = ""  # why there is no such heading, where navigation.gnss_heading asked for one
    standstill: Measurements | None = None  # zero yaw rate (rad/s) where the wheels stand still
    gnss_lever_m: tuple[float, float, float] = (0.0, 0.0, 0.0)  # antenna in the body frame (from the CoG)
    attitude_imu: ImuSamples | None = None  # the 6-DoF IMU of navigation.attitude_imu, where the drive has it
    gyro_bias_std: list[float] = field(default_factory=list)  # prior std of each gyro's bias (rad/s)
    gyro_bias_walk: list[float] = field(default_factory=list)  # bias random walk (rad/s per sqrt(s))
    steering_offset_std: float = 0.0  # prior std of the road-wheel angle offset (rad)
    wheel_scale_std: float = 0.0
    wheel_lag_prior_m: tuple[float, float] = (0.0, 0.0)  # the wheel sensor's lag distance and its std (0: none)
    # the wheels as tyres of fixed radius on a rigid bicycle (models.measured_wheel_speeds); False where their
    # radii are seen to change with load
    rigid_wheels: bool = True
    # GNSS position error, per horizontal axis: first-order Gauss-Markov (std m, correlation time s) on top
    # of gnss_position.sigma (white, per fix); std 0 means the fixes are taken as independent.
    gnss_error_std_m: float = 0.0
    gnss_error_time_s: float = 0.0
    #: the horizontal std per axis (m) the receiver states for its fixes (NavSatFix position_covariance of a known
    #: type, the median over the fixes); NaN where it states none (NMEA, type 0)
    gnss_reported_std_m: float = math.nan
    #: the GNSS velocity's correlated error (m/s per axis, s), carried as two Gauss-Markov states where it is > 0
    #: (:func:`~autosar_cli.nav.gnss_noise.velocity_decorrelated`); the samples' sigma is then its white part
    gnss_velocity_error_std_mps: float = 0.0
    gnss_velocity_error_time_s: float = 0.0
    #: what the inputs lack that navigate says in one line each (a receiver that gives no altitude)
    warnings: list[str] = field(default_factory=list)


def lsb_of(values: Array) -> float:
    """Quantisation step of a recorded signal: the smallest gap between its distinct values (0 if none)."""
    u = np.unique(values[np.isfinite(values)])
    if len(u) < 2:
        return 0.0
    gaps = np.diff(u)
    return float(gaps[gaps > 1e-12].min()) if (gaps > 1e-12).any() else 0.0


def _reported_horizontal_std(drive: Drive, fix: h5py.Group) -> float:
    """The median over the fixes of the horizontal std per axis (m) the receiver states (the mean of the east and
    north variances of ``position_covariance``, where its type is known and the variances finite and positive); NaN
    where no fix states one."""
    if "position_covariance" not in fix or "position_covariance_type" not in fix:
        return math.nan
    stated = drive.columns(fix, ("position_covariance", "position_covariance_type"))
    cov = np.asarray(stated["position_covariance"], dtype=np.float64)
    known = np.asarray(stated["position_covariance_type"]) > 0
    if cov.ndim != 2 or cov.shape[1] != 9 or known.shape != (len(cov),):
        return math.nan  # not NavSatFix's row-major 3 x 3 per fix: nothing the receiver states that can be read
    var = 0.5 * (cov[:, 0] + cov[:, 4])
    ok = known & np.isfinite(var) & (var > 0)
    return float(np.sqrt(np.median(var[ok]))) if ok.any() else math.nan


def with_altitudes(fix: dict[str, Array], stream: str) -> tuple[dict[str, Array], str]:
    """``fix`` (columns ``t_ns``, ``altitude_m``) with each altitude the receiver does not give (NaN: NavSatFix's
    "no altitude available", a 2-D fix) interpolated in time from the others', or 0 where no fix gives one, and then a
    warning naming ``stream``. A NaN altitude had made every fix's ENU position NaN, and SAR-MIN's whole trajectory
    with it, without a word."""
    alt = np.asarray(fix["altitude_m"], dtype=np.float64)
    given = np.isfinite(alt)
    if given.all():
        return fix, ""
    if not given.any():
        return {**fix, "altitude_m": np.zeros(len(alt))}, (
            f"{stream}: none of its {len(alt)} fixes gives an altitude (NaN): taken as 0 m above the ellipsoid, so the "
            "drive's heights are relative and its horizontal scale off by the height over the Earth's radius "
            "(16 ppm per 100 m)")
    t = np.asarray(fix["t_ns"], dtype=np.float64)
    return {**fix, "altitude_m": np.where(given, alt, np.interp(t, t[given], alt[given]))}, ""


#: a GNSS velocity farther than this from every fix (or ``NO_FIX_REACH_INTERVALS`` of the fixes' median interval,
#: where that is longer) comes where the receiver had no solution
NO_FIX_REACH_S = 1.0
NO_FIX_REACH_INTERVALS = 2.5


def velocities_with_fixes(t_fix_ns: Array, vel: dict[str, Array], stream: str) -> tuple[dict[str, Array], str]:
    """``vel`` (columns ``t_ns`` and the rest, row by row) without the velocities that come where the receiver gives no
    fix, and a warning naming ``stream`` that counts them. A receiver without a solution still reports a velocity
    (0, or its last; a u-blox's NAV-PVT while its fix says none): urban seed 1 with 10 s unfixed and its velocities 0
    there, SAR-MIN's track was 17.3 cm RMS across once aligned (1.46 with the velocities left out), exit 0, no word."""
    t_fix, t_vel = np.asarray(t_fix_ns, dtype=np.int64), np.asarray(vel["t_ns"], dtype=np.int64)
    if len(t_fix) == 0 or len(t_vel) == 0:
        return vel, ""
    interval = float(np.median(np.diff(t_fix))) / 1e9 if len(t_fix) > 1 else 0.0
    reach = max(NO_FIX_REACH_S, NO_FIX_REACH_INTERVALS * interval)
    i = np.clip(np.searchsorted(t_fix, t_vel), 1, len(t_fix) - 1) if len(t_fix) > 1 else np.zeros(len(t_vel), int)
    nearest = np.minimum(np.abs(t_vel - t_fix[i]), np.abs(t_vel - t_fix[np.maximum(i - 1, 0)])) / 1e9
    unfixed = nearest > reach
    if not unfixed.any():
        return vel, ""
    return {k: np.asarray(v)[~unfixed] for k, v in vel.items()}, (
        f"{stream}: {int(unfixed.sum())} of its {len(t_vel)} velocities come where the receiver gives no fix (over "
        f"{reach:.1f} s from one): left out (a receiver without a solution reports 0 or its last velocity)")


#: the GNSS velocity is checked against the fixes' own motion (their differences over ``FIX_DIFFERENCE_S``) where the
#: fixes move faster than ``FRAME_MIN_SPEED_MPS``, at ``FRAME_MIN_SAMPLES`` instants or more. Its direction a median
#: ``FRAME_MAX_ANGLE_DEG`` or more from theirs is no receiver's noise (urban seed 1 as recorded: 0.67 deg; test1-3 and
#: urban seed 0 of the full vehicle 0.57-0.74); where its east and north swapped fit within ``FRAME_FIT_ANGLE_DEG``, it
#: is north, east, down (NED)
FIX_DIFFERENCE_S = 1.0
FRAME_MIN_SPEED_MPS = 2.0
FRAME_MIN_SAMPLES = 20
FRAME_MAX_ANGLE_DEG = 30.0
FRAME_FIT_ANGLE_DEG = 10.0


def velocity_frame_checked(t_fix: Array, fix_xy: Array, t_vel: Array, velocity: Array, stream: str
                           ) -> tuple[Array, str]:
    """``velocity`` (n, 3: ENU, m/s, at ``t_vel``) as ENU, and a warning naming ``stream`` where it is not: its
    direction against the fixes' motion (``fix_xy`` ENU m at ``t_fix``, the same antenna). Where it agrees only with
    its first two axes swapped, it is NED (x north, y east, z down, as some INS drivers publish), and is read as such
    (urban seed 1: the track 125 m off the truth, the gate refusing 579 of 580 fixes, and the warning 'the car's own
    sensors and the GNSS disagree'). Where it disagrees otherwise, it is kept (the gate weighs it: the fixes alone did
    no better) and said, as the body's axes where it points along its own x whatever the fixes' course."""
    finite = np.isfinite(velocity[:, :2]).all(axis=1)
    t_v, v_xy = t_vel[finite], velocity[finite, :2]
    if len(t_fix) < 3 or len(t_v) < 2:
        return velocity, ""
    dt = float(np.median(np.diff(t_fix)))
    k = max(1, int(round(FIX_DIFFERENCE_S / 2 / dt))) if dt > 0 else 1
    span = t_fix[2 * k:] - t_fix[:-2 * k]
    if len(span) == 0:
        return velocity, ""
    motion = (fix_xy[2 * k:] - fix_xy[:-2 * k]) / np.maximum(span, 1e-9)[:, None]
    tc = t_fix[k:-k]
    use = ((span < 1.5 * 2 * k * dt) & (np.linalg.norm(motion, axis=1) > FRAME_MIN_SPEED_MPS)
           & (tc >= t_v[0]) & (tc <= t_v[-1]))
    if use.sum() < FRAME_MIN_SAMPLES:
        return velocity, ""
    v = np.stack([np.interp(tc[use], t_v, v_xy[:, i]) for i in range(2)], axis=1)
    course = np.arctan2(motion[use, 1], motion[use, 0])

    def off_deg(east: Array, north: Array) -> float:
        return float(np.rad2deg(np.median(np.abs(wrap_angle(np.arctan2(north, east) - course)))))

    given = off_deg(v[:, 0], v[:, 1])
    if given < FRAME_MAX_ANGLE_DEG:
        return velocity, ""
    swapped = off_deg(v[:, 1], v[:, 0])
    if swapped < FRAME_FIT_ANGLE_DEG:
        ned = np.stack([velocity[:, 1], velocity[:, 0], -velocity[:, 2]], axis=1) if velocity.shape[1] > 2 else (
            velocity[:, [1, 0]])
        return ned, (f"{stream}: its direction agrees with the fixes' motion only with its x and y swapped (a median "
                     f"{given:.0f} deg off as given, {swapped:.1f} deg swapped): north, east, down (NED), not ENU (x "
                     "east, y north, z up); read as NED")
    along_x = float(np.rad2deg(np.median(np.abs(np.arctan2(v[:, 1], v[:, 0])))))
    if along_x < FRAME_FIT_ANGLE_DEG:  # forward whatever the course: the car would only ever drive east
        return velocity, (f"{stream}: its direction is a median {given:.0f} deg off the fixes' motion but "
                          f"{along_x:.1f} deg off its own x axis whatever their course: the body's axes (x forward), "
                          "not ENU (x east, y north, z up); the gate weighs it against the car's sensors")
    return velocity, (f"{stream}: its direction is a median {given:.0f} deg off the fixes' motion (at {int(use.sum())} "
                      "instants while moving): not ENU (x east, y north, z up) as read, or not the fixes' antenna?")


def _load_gnss_heading(out: NavInputs, drive: Drive, gnss: h5py.Group, source: str, errors: GnssErrors | None,
                       offset_std_deg: float, rel: Callable[[Array, str], Array]) -> None:
    """``out``'s receiver heading from ``gnss``' NMEA heading stream, or why there is none."""
    if "nmea_heading" not in gnss:
        out.gnss_heading_missing = f"the drive has no NMEA heading (gnss/{source}/nmea_heading)"
        return
    hdt = drive.columns(gnss["nmea_heading"], ("t_ns", "heading_rad"))
    ok = np.isfinite(hdt["heading_rad"])
    if not ok.any():
        out.gnss_heading_missing = f"gnss/{source}/nmea_heading has no valid heading (all {len(ok)} samples are NaN)"
        return
    std = np.deg2rad(errors.heading_std_deg if errors and errors.heading_std_deg > 0 else 0.5)
    out.gnss_heading = Measurements(source, rel(hdt["t_ns"][ok], source), hdt["heading_rad"][ok, None],
                                    np.array([std]))
    out.gnss_heading_offset_std = float(np.deg2rad(offset_std_deg))


#: an IMU whose accelerometers read gravity farther than this from the body's up, its mounting applied, is mounted
#: turned: its z gyro is then not the yaw rate (a road's grade and a car's roll or pitch are a few degrees)
MAX_GRAVITY_TILT_DEG = 30.0
#: the median magnitude of a 6-DoF IMU's specific force over a drive (m/s^2): gravity and the car's accelerations
GRAVITY_RANGE_MPS2 = (7.0, 12.5)
#: ... below it, with the median vector under this share of the median magnitude (no fixed direction: gravity's, in
#: any unit, is ~1), the driver took gravity out (urban seed 1's ins_cog: 0.33 m/s^2, its median 0.07)
GRAVITY_REMOVED_SHARE = 0.5


#: an IMU whose gravity reads this far (deg) from its z axis, unturned by the config, has its z down
UPSIDE_DOWN_TILT_DEG = 170.0


#: an IMU stream over this share of whose samples repeat the one before exactly, every axis, is published faster
#: than its sensor samples (none of the simulator's or the real Husky's repeat one)
MAX_REPEATED_SHARE = 0.2


def without_repeated_samples(imu: dict[str, Array], stream: str) -> tuple[dict[str, Array], str]:
    """``imu`` (columns ``t_ns``, ``angular_velocity``, ``linear_acceleration``, row by row) without the samples that
    repeat the one before on every axis, where over :data:`MAX_REPEATED_SHARE` of them do (a driver publishing its
    sensor's last sample at twice its rate), and a warning naming ``stream`` that counts them; else as given. Urban seed
    1 with every sample of its four IMUs sent twice: the gyros weighed twice, 1.07 cm RMS across once aligned (0.95 as
    recorded), no word."""
    x = np.hstack([imu["angular_velocity"], imu["linear_acceleration"]])
    same = np.r_[False, np.all((x[1:] == x[:-1]) | (np.isnan(x[1:]) & np.isnan(x[:-1])), axis=1)]
    if len(x) < 2 or same.mean() <= MAX_REPEATED_SHARE:
        return imu, ""
    return ({k: np.asarray(v)[~same] for k, v in imu.items()},
            f"{stream}: {int(same.sum())} of {len(same)} samples repeat the one before on every axis (its driver "
            "publishing the sensor's last sample faster than the sensor samples): left out, each counted once")


def read_imu(drive: Drive, name: str, config: Config) -> dict[str, Array]:
    """The IMU stream ``imu/<name>`` (``t_ns``, ``angular_velocity``, ``linear_acceleration``) on the body's axes,
    turned by the sensor's ``mounting_ypr_deg``. Refused, naming the stream, where its accelerometers (all three
    axes) read gravity outside ``GRAVITY_RANGE_MPS2`` or more than ``MAX_GRAVITY_TILT_DEG`` from the body's up."""
    cols = drive.columns(drive.h5["imu"][name], ("t_ns", "angular_velocity", "linear_acceleration"))
    s = config.sensors.get(name)
    mounting = tuple(s.mounting_ypr_deg) if s else (0.0, 0.0, 0.0)
    w = sensor_to_body(cols["angular_velocity"], mounting)  # type: ignore[arg-type]
    f = sensor_to_body(cols["linear_acceleration"], mounting)  # type: ignore[arg-type]
    whole = np.isfinite(f).all(axis=1)
    if whole.any():
        g = np.median(f[whole], axis=0)
        magnitude = float(np.median(np.linalg.norm(f[whole], axis=1)))
        if magnitude < GRAVITY_RANGE_MPS2[0] and np.linalg.norm(g) < GRAVITY_REMOVED_SHARE * magnitude:
            said = (f"imu/{name}: its accelerometers read no gravity (median magnitude {magnitude:.2f} m/s^2, in no "
                    f"fixed direction: their median [{g[0]:.2f}, {g[1]:.2f}, {g[2]:.2f}]): gravity-removed ('free' or "
                    "linear) acceleration, not the specific force an accelerometer measures")
            raise GravityRemovedError(
                f"{drive.path}: {said}; neither roll and pitch nor a strapdown come from it (log the driver's raw "
                "acceleration, gravity in it)", said, {"t_ns": cols["t_ns"], "angular_velocity": w,
                                                        "linear_acceleration": f})
        if not GRAVITY_RANGE_MPS2[0] <= magnitude <= GRAVITY_RANGE_MPS2[1]:
            raise NavInputError(
                f"{drive.path}: imu/{name}: its accelerometers read gravity as {magnitude:.2f} m/s^2 (median "
                f"magnitude), not about 9.81: a unit (g read as m/s^2 is 1.0) or a scale in the log")
        tilt = gravity_tilt_deg(g)
        if tilt > MAX_GRAVITY_TILT_DEG:
            turned = f"with its mounting_ypr_deg {list(mounting)}" if any(mounting) else "as mounted in the config"
            raw_g = np.median(np.asarray(cols["linear_acceleration"])[whole], axis=0)
            pitch, roll = levelling_pitch_roll_deg(raw_g)
            # a sensor whose z points down is a NED / FRD one (PX4's, some INS drivers'), not mounted upside down
            down = (": its z points down, NED / FRD axes (x forward, y right, z down), which a 180 deg roll makes "
                    "ROS's") if tilt > UPSIDE_DOWN_TILT_DEG and not any(mounting) else ""
            raise NavInputError(
                f"{drive.path}: imu/{name}: its accelerometers read gravity {tilt:.0f} deg from the body's up "
                f"{turned} (median [{g[0]:.2f}, {g[1]:.2f}, {g[2]:.2f}] m/s^2 on the body's x, y, z), so its z gyro "
                f"is not the yaw rate: give the sensor's mounting_ypr_deg (yaw, pitch, roll of its axes; gravity "
                f"levels it at about [yaw, {pitch:.1f}, {roll:.1f}], the yaw yours to give){down}")
    return {"t_ns": cols["t_ns"], "angular_velocity": w, "linear_acceleration": f}


def can_gnss_streams(drive: Drive, name: str) -> tuple[dict[str, Array], dict[str, Array] | None]:
    """A GNSS receiver on CAN (config kind ``can_gnss``) as its fixes and velocities, in the columns of a
    NavSatFix stream's (``t_ns``, ``latitude_deg``, ``longitude_deg``, ``altitude_m``) and a twist's
    (``t_ns``, ``velocity_enu`` with NaN up). Its CAN roles: ``latitude.<name>`` and ``longitude.<name>`` (deg),
    optional ``altitude.<name>`` (m; else 0) and ``position_valid.<name>`` (fixes where it reads 0 left out), and
    ``speed.<name>`` (m/s) with ``course.<name>`` (rad from north, clockwise: the direction of travel) for the
    velocity; without them, the fixes alone."""
    roles = drive.can_roles()
    need = [f"latitude.{name}", f"longitude.{name}"]
    if missing := [r for r in need if r not in roles]:
        raise NavInputError(f"{drive.path}: the GNSS receiver {name} is on CAN (config kind can_gnss) but the drive "
                            f"has no CAN signal for {', '.join(missing)} (its roles: {', '.join(sorted(roles))})")
    t_ns, lat = drive.can_role(f"latitude.{name}")

    def at_fixes(role: str) -> Array:  # a signal of another message than the latitude's, at the latitude's times
        t, v = drive.can_role(role)
        same = len(t) == len(t_ns) and np.array_equal(t, t_ns)
        return v if same else np.interp(t_ns, t, v) if len(t) else np.full(len(t_ns), np.nan)

    lon = at_fixes(f"longitude.{name}")
    alt = at_fixes(f"altitude.{name}") if f"altitude.{name}" in roles else np.zeros(len(t_ns))
    keep = np.isfinite(lat) & np.isfinite(lon)
    if f"position_valid.{name}" in roles:
        keep &= at_fixes(f"position_valid.{name}") > 0.5
    fix = {"t_ns": t_ns[keep], "latitude_deg": lat[keep], "longitude_deg": lon[keep], "altitude_m": alt[keep]}
    if f"speed.{name}" not in roles or f"course.{name}" not in roles:
        return fix, None
    t_speed, speed = drive.can_role(f"speed.{name}")
    t_course, course = drive.can_role(f"course.{name}")
    c = np.interp(t_speed, t_course, np.unwrap(course)) if len(t_course) else np.full(len(t_speed), np.nan)
    enu = np.stack([speed * np.sin(c), speed * np.cos(c), np.full(len(c), np.nan)], axis=1)
    ok = np.isfinite(enu[:, :2]).all(axis=1)
    return fix, {"t_ns": t_speed[ok], "velocity_enu": enu[ok]}


#: GGA qualities that are not a measured position: 6 dead reckoning (the receiver's own estimate), 7 entered by
#: hand, 8 a simulator's
NMEA_UNMEASURED_QUALITIES = (6, 7, 8)


@dataclass(frozen=True)
class ReceiverStreams:
    """A GNSS receiver's fixes and velocities in the columns of a NavSatFix stream's (``t_ns``, ``latitude_deg``,
    ``longitude_deg``, ``altitude_m``) and a twist's (``t_ns``, ``velocity_enu`` (n, 3) m/s ENU, NaN where the
    receiver gives no up), the drive's streams they came from, and what was left out of them."""

    fix: dict[str, Array]
    velocity: dict[str, Array] | None
    fix_stream: str
    velocity_stream: str
    warnings: tuple[str, ...] = ()


def _first_of_each_fix_time(cols: dict[str, Array]) -> dict[str, Array]:
    """``cols`` without the rows whose NMEA fix time repeats an earlier row's: a receiver talking GPS and GNSS
    (GPGGA beside GNGGA) sends one epoch twice, which would count it twice. Rows without a fix time (VTG) stay."""
    t_fix = np.asarray(cols["fix_time_ns"], dtype=np.float64)
    timed = np.isfinite(t_fix)
    keep = ~timed
    keep[np.flatnonzero(timed)[np.unique(t_fix[timed], return_index=True)[1]]] = True
    return {k: np.asarray(v)[keep] for k, v in cols.items()}


def nmea_receiver_streams(drive: Drive, name: str) -> ReceiverStreams:
    """A receiver the drive holds only as NMEA sentences (``gnss/<name>/nmea_fix``): its GGA fixes, without those
    whose quality says they are not measured (:data:`NMEA_UNMEASURED_QUALITIES`, counted in a warning), or, where it
    sent no GGA, its RMC positions (no altitude); and its RMC velocities (else VTG's) from speed and course, with NaN
    up (NMEA gives no vertical velocity)."""
    g = drive.h5["gnss"][name]
    # a receiver sending RMC alone (ingest writes its GGA table all the same): its positions, no altitude, which
    # with_altitudes says
    if ("nmea_fix" not in g or not g["nmea_fix"]["t_ns"].shape[0]) and "latitude_deg" in g.get("nmea_velocity", {}):
        rmc = _first_of_each_fix_time(drive.columns(g["nmea_velocity"], ("t_ns", "fix_time_ns", "latitude_deg",
                                                                         "longitude_deg")))
        placed = np.isfinite(rmc["latitude_deg"]) & np.isfinite(rmc["longitude_deg"])
        fix = {k: np.asarray(rmc[k])[placed] for k in ("t_ns", "latitude_deg", "longitude_deg")}
        fix["altitude_m"] = np.full(int(placed.sum()), np.nan)
        fix_stream, warnings = f"gnss/{name}/nmea_velocity", ()
    else:
        gga = _first_of_each_fix_time(drive.columns(g["nmea_fix"], ("t_ns", "fix_time_ns", "latitude_deg",
                                                                    "longitude_deg", "altitude_m", "quality")))
        unmeasured = np.isin(gga["quality"], NMEA_UNMEASURED_QUALITIES)
        warnings = (f"gnss/{name}/nmea_fix: {int(unmeasured.sum())} of {len(unmeasured)} GGA fixes left out, their "
                    f"quality ({', '.join(str(q) for q in sorted(set(gga['quality'][unmeasured].astype(int))))}: "
                    "dead reckoning, manual or simulated) not a measured position",) if unmeasured.any() else ()
        fix = {k: np.asarray(gga[k])[~unmeasured] for k in ("t_ns", "latitude_deg", "longitude_deg", "altitude_m")}
        fix_stream = f"gnss/{name}/nmea_fix"
    kind = next((k for k in ("nmea_velocity", "nmea_vtg") if k in g and g[k]["t_ns"].shape[0]), None)
    if kind is None:
        return ReceiverStreams(fix, None, fix_stream, "", warnings)
    cols = _first_of_each_fix_time(drive.columns(g[kind], ("t_ns", "fix_time_ns", "speed_mps", "course_rad")))
    speed, course = np.asarray(cols["speed_mps"]), np.asarray(cols["course_rad"])
    # standing still, a receiver leaves the course empty: its velocity is 0 all the same
    course = np.where(speed == 0.0, 0.0, course)
    enu = np.stack([speed * np.cos(course), speed * np.sin(course), np.full(len(speed), np.nan)], axis=1)
    ok = np.isfinite(enu[:, :2]).all(axis=1)
    return ReceiverStreams(fix, {"t_ns": np.asarray(cols["t_ns"])[ok], "velocity_enu": enu[ok]}, fix_stream,
                           f"gnss/{name}/{kind}", warnings)


def capture_latency_said(streams: ReceiverStreams, name: str, latency_s: float) -> ReceiverStreams:
    """``streams`` of the NMEA text capture ``gnss/<name>``, with a warning where its sensor states a latency: a
    capture's times are its fixes' own (UTC), so the stated ``latency_s`` (a ROS receiver's, kept in a config) moves
    them that much earlier, by latency times speed along the track (the ci drive's 0.05 s: 12 cm at 2.4 m/s)."""
    if latency_s == 0.0:
        return streams
    vel = streams.velocity
    speed = (float(np.median(np.hypot(vel["velocity_enu"][:, 0], vel["velocity_enu"][:, 1])))
             if vel is not None and len(vel["t_ns"]) else math.nan)
    shift = f", {100 * speed * latency_s:.0f} cm along the track at its median {speed:.1f} m/s" \
        if math.isfinite(speed) else ""
    return replace(streams, warnings=(*streams.warnings, (
        f"gnss/{name}: an NMEA capture, stamped with its fixes' own times, yet [sensors.{name}] latency_s is "
        f"{latency_s:g} s, which moves every fix that much earlier{shift}: set latency_s = 0 unless the capture's "
        "clock runs late")))


def receiver_streams(drive: Drive, name: str, key: str, latency_s: float = 0.0) -> ReceiverStreams:
    """The receiver ``gnss/<name>`` (the config's ``key`` names it) as its NavSatFix fixes and twist velocities, or,
    where it logged neither, its NMEA sentences' (:func:`nmea_receiver_streams`; an NMEA text capture's with
    :func:`capture_latency_said` of its sensor's ``latency_s``). Refused, saying what the drive holds, where it has
    neither."""
    if name not in drive.gnss_sources():
        # a text capture has no topic to pin it by: the config names its receiver after the file
        if captures := drive.nmea_captures():
            raise NavInputError(
                f"{drive.path}: no GNSS stream gnss/{name} (config {key}); the drive has "
                f"{', '.join(f'gnss/{s}' for s in drive.gnss_sources())}, of which "
                f"{', '.join(f'gnss/{c}' for c in captures)} an NMEA capture named by its file: name its receiver so "
                f"in a --config ({key} = \"{captures[0]}\", and a [sensors.{captures[0]}] of kind gnss for its "
                f"lever arm and errors: autosar info DRIVE --config-sketch)")
        raise NavInputError(f"{drive.path}: no GNSS stream gnss/{name} (config {key}); {streams_held(drive, 'gnss')}")
    g = drive.h5["gnss"][name]
    if "fix" in g:
        vel = drive.columns(g["velocity"], ("t_ns", "velocity_enu")) if "velocity" in g else None
        return ReceiverStreams(drive.columns(g["fix"], ("t_ns", "latitude_deg", "longitude_deg", "altitude_m")), vel,
                               f"gnss/{name}/fix", f"gnss/{name}/velocity")
    if "nmea_fix" in g or ("nmea_velocity" in g and "latitude_deg" in g["nmea_velocity"]):
        streams = nmea_receiver_streams(drive, name)
        return capture_latency_said(streams, name, latency_s) if name in drive.nmea_captures() else streams
    raise NavInputError(f"{drive.path}: gnss/{name} (config {key}) has no position: neither a NavSatFix stream nor "
                        f"NMEA GGA sentences, only {', '.join(sorted(g))}")


#: a gyro whose yaw rate is 180/pi times the others' (within ``DEGREES_TOLERANCE`` of it) reads deg/s, not ROS's
#: rad/s (a driver's unit); told only where the others' yaw rate varies by ``DEGREES_MIN_TURNING_RADPS`` RMS
DEGREES_TOLERANCE = 0.1
DEGREES_MIN_TURNING_RADPS = 0.02


def yaw_rate_scale(t: Array, z: Array, t_ref: Array, z_ref: Array) -> float:
    """The slope of the yaw rate ``z`` (at ``t``) against ``z_ref`` (at ``t_ref``) over their common span, each one's
    mean (a bias) taken out; NaN where they share under 10 of the reference's instants or it varies by under
    ``DEGREES_MIN_TURNING_RADPS`` RMS there."""
    ok, ok_ref = np.isfinite(z), np.isfinite(z_ref)
    t, z, t_ref, z_ref = t[ok], z[ok], t_ref[ok_ref], z_ref[ok_ref]
    if len(t) < 2 or len(t_ref) < 2:
        return math.nan
    inside = (t_ref >= t[0]) & (t_ref <= t[-1])
    if inside.sum() < 10:
        return math.nan
    ref = z_ref[inside] - z_ref[inside].mean()
    if np.sqrt(np.mean(ref ** 2)) < DEGREES_MIN_TURNING_RADPS:
        return math.nan
    at = np.interp(t_ref[inside], t, z)
    return float(np.dot(at - at.mean(), ref) / np.dot(ref, ref))


def reads_degrees(scale: float) -> bool:
    """Whether a yaw rate ``scale`` times another's (:func:`yaw_rate_scale`) is that one's in deg/s."""
    return abs(scale / math.degrees(1.0) - 1.0) < DEGREES_TOLERANCE


def gyros_in_degrees(rates: dict[str, tuple[Array, Array]]) -> dict[str, float]:
    """Each of ``rates`` (name: times s, yaw rate) that reads deg/s against the median of the others' (three or more
    gyros, so that they outvote it), with its scale against them. Urban seed 1 with one of its four gyros in deg/s: the
    gate refused 27236 of its 28987 samples and let the rest (near 0) through, the steering was refused as '0.162
    times the road-wheel angle', the track 35.8 cm RMS across once aligned (0.95 as recorded)."""
    if len(rates) < 3:
        return {}
    names = list(rates)
    grid = rates[names[0]][0]
    grid = grid[(grid >= max(t[0] for t, _ in rates.values())) & (grid <= min(t[-1] for t, _ in rates.values()))]
    if len(grid) < 10:
        return {}
    on_grid = np.array([np.interp(grid, t, z) for t, z in rates.values()])
    out = {}
    for i, name in enumerate(names):
        scale = yaw_rate_scale(*rates[name], grid, np.median(np.delete(on_grid, i, axis=0), axis=0))
        if reads_degrees(scale):
            out[name] = scale
    return out if len(out) <= (len(names) - 1) // 2 else {}  # no majority left to trust


def streams_held(drive: Drive, kind: str) -> str:
    """What the drive holds of ``kind`` ("gnss" or "imu"), for an error that names a missing stream: the config
    names a sensor's stream by its topic, so a drive logged on other topics holds them under names of its own."""
    names = drive.gnss_sources() if kind == "gnss" else drive.imu_sources()
    if not names:
        return f"the drive has no {kind} stream"
    return (f"the drive has {', '.join(f'{kind}/{n}' for n in names)}: name the sensors in a --config "
            f"(each [sensors.*] topic, as in configs/giulia_scanbrick.toml) and ingest again")


def load_inputs(drive: Drive, config: Config) -> NavInputs:
    """Collect the SAR-MIN measurements of ``drive`` as the config names them."""
    nav = config.navigation
    gnss_cfg = config.sensors.get(nav.gnss)
    h5 = drive.h5
    gnss: h5py.Group | None = None
    if gnss_cfg is not None and gnss_cfg.kind == "can_gnss":
        fix, vel = can_gnss_streams(drive, nav.gnss)
        streams = ReceiverStreams(fix, vel, f"gnss/{nav.gnss}/fix", f"gnss/{nav.gnss}/velocity")
    else:
        streams = receiver_streams(drive, nav.gnss, "navigation.gnss", gnss_cfg.latency_s if gnss_cfg else 0.0)
        fix, vel = streams.fix, streams.velocity
        gnss = h5["gnss"][nav.gnss]
    if len(fix["t_ns"]) == 0:
        raise NavInputError(f"{drive.path}: {streams.fix_stream} is empty")
    fix, no_altitude = with_altitudes(fix, streams.fix_stream)
    lever = tuple(gnss_cfg.lever_arm_m) if gnss_cfg else (0.0, 0.0, 0.0)
    antenna_height = config.vehicle.cog_height_m + lever[2]
    origin = GeodeticOrigin(float(fix["latitude_deg"][0]), float(fix["longitude_deg"][0]),
                            float(fix["altitude_m"][0]) - antenna_height)
    t0 = int(fix["t_ns"][0])

    def rel(t_ns: Array, sensor: str) -> Array:
        s = config.sensors.get(sensor)
        latency = s.latency_s if s else 0.0
        return (np.asarray(t_ns, dtype=np.int64) - t0) / 1e9 - latency

    roles = drive.can_roles()
    can_times: dict[str, np.ndarray] = {}

    def can_role(role: str) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`Drive.can_role`, reading each message's time stamps once."""
        return drive.can_role(role, can_times)

    out = NavInputs(t0, origin, gnss_lever_m=lever,  # type: ignore[arg-type]
                    warnings=[*streams.warnings, *([no_altitude] if no_altitude else [])])
    enu = origin.to_enu(fix["latitude_deg"], fix["longitude_deg"], fix["altitude_m"])
    errors = gnss_cfg.gnss if gnss_cfg else None
    if nav.gnss_error_model == "gauss_markov":
        # no error table: a plain receiver's (metre-level, minutes) rather than none
        slow, tau, white = ((errors.horizontal_std_m, errors.correlation_time_s, errors.white_std_m) if errors
                            else (1.0, 60.0, 0.05))
        if tau > 0.0:
            out.gnss_error_std_m, out.gnss_error_time_s = slow, tau
        else:  # an uncorrelated table: all of it per fix
            white = float(np.hypot(slow, white))
        pos_std = np.full(2, max(white, 1e-3))
    else:
        pos_std = np.full(2, nav.gnss_position_std_m)
    out.gnss_position = Measurements(nav.gnss, rel(fix["t_ns"], nav.gnss), enu[:, :2], pos_std)
    out.gnss_reported_std_m = _reported_horizontal_std(drive, gnss["fix"]) if gnss is not None and "fix" in gnss \
        else math.nan
    if vel is not None:
        vel, unfixed = velocities_with_fixes(fix["t_ns"], vel, streams.velocity_stream)
        out.warnings += [unfixed] if unfixed else []
    if vel is not None and len(vel["t_ns"]):
        velocity, frame = velocity_frame_checked(out.gnss_position.t, enu[:, :2], rel(vel["t_ns"], nav.gnss),
                                                 np.asarray(vel["velocity_enu"], dtype=np.float64),
                                                 streams.velocity_stream)
        vel = {**vel, "velocity_enu": velocity}
        out.warnings += [frame] if frame else []
        std = max(errors.velocity_std_mps if errors else 0.05, 1e-3)  # a perfect (simulated) receiver's 0: 1 mm/s
        out.gnss_velocity = Measurements(nav.gnss, rel(vel["t_ns"], nav.gnss), vel["velocity_enu"][:, :2],
                                         np.full(2, std))
        up = vel["velocity_enu"][:, 2] if vel["velocity_enu"].shape[1] > 2 else np.zeros(0)
        # a receiver without a vertical velocity writes NaN there, or 0 throughout
        if np.isfinite(up).any() and np.any(up[np.isfinite(up)] != 0.0):
            # its stated variance where the stream has one; else receivers' usual 1.5 x the horizontal
            var = (drive.columns(gnss["velocity"], ("velocity_variance",))["velocity_variance"][:, 2]
                   if gnss is not None and "velocity" in gnss
                   and "velocity_variance" in gnss["velocity"] else np.zeros(0))
            var = np.median(var[np.isfinite(var)]) if np.isfinite(var).any() else 0.0
            up_std = float(np.sqrt(var)) if var > 0 else 1.5 * std
            ok = np.isfinite(up)
            out.gnss_climb = Measurements(nav.gnss, rel(vel["t_ns"][ok], nav.gnss), up[ok, None],
                                          np.array([up_std]))
    if nav.gnss_heading and gnss is not None:
        _load_gnss_heading(out, drive, gnss, nav.gnss, errors, nav.gnss_heading_offset_std_deg, rel)
    elif nav.gnss_heading:
        out.gnss_heading_missing = f"{nav.gnss} is a receiver on CAN: no NMEA heading"
    imu_sources = drive.imu_sources()
    imus: dict[str, dict[str, Array]] = {}  # read_imu's per stream: a gyro's may be the attitude IMU's too
    gravity_removed: dict[str, str] = {}  # what read_imu said of each stream whose driver took gravity out

    def imu_of(name: str) -> dict[str, Array]:
        """read_imu's, once per stream; a stream without gravity's columns, said in ``gravity_removed``: its gyros
        are usable (urban seed 1's attitude IMU without gravity had navigate refuse the drive, 'a unit (g read as m/s^2
        is 1.0) or a scale' at 0.33 m/s^2)"""
        if name not in imus:
            try:
                imus[name] = read_imu(drive, name, config)
            except GravityRemovedError as exc:
                imus[name], gravity_removed[name] = exc.columns, exc.said
            imus[name], repeated = without_repeated_samples(imus[name], f"imu/{name}")
            out.warnings += [repeated] if repeated else []
        return imus[name]

    yaw_rates: dict[str, tuple[Array, Array]] = {}  # each gyro's times (ns) and yaw rate as read
    for name in nav.gyros:
        s = config.sensors.get(name)
        if s is None or s.gyro is None:
            raise NavInputError(f"navigation.gyros: {name!r} is not a sensor with a gyro in the config")
        if s.kind == "imu":
            if name not in imu_sources:
                raise NavInputError(f"{drive.path}: no IMU stream imu/{name} (config navigation.gyros); "
                                    f"{streams_held(drive, 'imu')}")
            imu = imu_of(name)
            yaw_rates[name] = imu["t_ns"], imu["angular_velocity"][:, 2]
        else:
            try:
                yaw_rates[name] = can_role(f"yaw_rate.{name}")
            except KeyError as exc:
                raise NavInputError(str(exc).strip("'\"")) from exc
    in_degrees = gyros_in_degrees({n: (rel(t_ns, n), z) for n, (t_ns, z) in yaw_rates.items()})
    for name, scale in in_degrees.items():
        out.warnings.append(f"gyro {name}: its yaw rate reads {scale:.1f} times the other gyros' (180/pi = 57.3): "
                            "deg/s, not ROS's rad/s (its driver's unit, or its DBC's); read as deg/s")
    for name, (t_ns, z) in yaw_rates.items():
        s = config.sensors[name]
        z = np.deg2rad(z) if name in in_degrees else z
        q = lsb_of(z)
        sigma = np.deg2rad(s.gyro.noise_density_dps_rthz) * np.sqrt(s.rate_hz)
        out.gyros.append(Measurements(name, rel(t_ns, name), z[:, None], np.array([np.hypot(sigma, q / np.sqrt(12))])))
        out.gyro_bias_std.append(1.5 * np.deg2rad(s.gyro.turn_on_bias_dps))
        out.gyro_bias_walk.append(np.deg2rad(s.gyro.bias_instability_dps) * np.sqrt(2.0 / s.gyro.bias_tau_s))
    wheels_cfg = next((n for n, s in config.sensors.items() if s.kind == "wheel_speeds"), None)
    if wheels_cfg and all(f"wheel_speed_{w}" in roles for w in ("fl", "fr", "rl", "rr")):
        read = {w: can_role(f"wheel_speed_{w}") for w in ("fl", "fr", "rl", "rr")}
        t_ns = read["fl"][0]
        # a wheel in another message, or under another multiplexer value, is read at the front left's instants
        z = np.stack([v if np.array_equal(t, t_ns) else np.interp(t_ns, t, v) for t, v in read.values()], axis=1)
        s = config.sensors[wheels_cfg]
        q = lsb_of(z[:, 0])
        noise = s.wheel.noise_std_mps if s.wheel else 0.01
        out.wheels = Measurements(wheels_cfg, rel(t_ns, wheels_cfg), z, np.full(4, np.hypot(noise, q / np.sqrt(12))))
        out.wheel_scale_std = s.wheel.radius_scale_error_std if s.wheel else 0.005
        if s.wheel:
            out.wheel_lag_prior_m = (s.wheel.lag_distance_m, s.wheel.lag_distance_std_m)
    steer_cfg = next((n for n, s in config.sensors.items() if s.kind == "steering"), None)
    if steer_cfg and "steering_wheel_angle" in roles:
        t_ns, angle = can_role("steering_wheel_angle")
        s = config.sensors[steer_cfg]
        ratio = config.vehicle.steering_ratio
        q = lsb_of(angle)
        noise = np.deg2rad(s.steering.noise_std_deg) if s.steering else np.deg2rad(0.1)
        out.steering = Measurements(steer_cfg, rel(t_ns, steer_cfg), (angle / ratio)[:, None],
                                    np.array([np.hypot(noise, q / np.sqrt(12)) / ratio]))
        out.steering_offset_std = (np.deg2rad(s.steering.offset_std_deg) if s.steering else 0.02) / ratio * 2
    if nav.attitude_imu and nav.attitude_imu in imu_sources:
        imu = imu_of(nav.attitude_imu)
        w, f = imu["angular_velocity"], imu["linear_acceleration"]
        if nav.attitude_imu in in_degrees:
            w = np.deg2rad(w)
        elif out.gyros and reads_degrees(scale := yaw_rate_scale(
                rel(imu["t_ns"], nav.attitude_imu), w[:, 2], out.gyros[0].t,
                np.median([np.interp(out.gyros[0].t, g.t, g.z[:, 0]) for g in out.gyros], axis=0))):
            # its roll and pitch rates in deg/s: urban seed 1's radar and antenna tilted by them, the gate refused
            # 493 of 580 GNSS fixes and the track was 40.0 cm RMS across once aligned (0.95 as recorded)
            w = np.deg2rad(w)
            out.warnings.append(f"imu/{nav.attitude_imu}: its z gyro reads {scale:.1f} times the gyros' yaw rate "
                                "(180/pi = 57.3): deg/s, not ROS's rad/s (its driver's unit); read as deg/s")
        ok = np.isfinite(w).all(axis=1) & np.isfinite(f).all(axis=1)
        if ok.any():  # a 3-DoF stream (NaN axes) has no attitude to give: left out, and navigate says why
            out.attitude_imu = ImuSamples(nav.attitude_imu, rel(imu["t_ns"][ok], nav.attitude_imu), w[ok], f[ok],
                                          tuple(config.sensors[nav.attitude_imu].lever_arm_m),
                                          gravity_removed=nav.attitude_imu in gravity_removed)
    for name, said in gravity_removed.items():
        uses = [*(["its z gyro taken as the yaw rate as mounted (no gravity to check the mounting by)"]
                  if name in nav.gyros else []),
                *(["no roll and pitch from it (the radar and the GNSS antenna as on a planar body)"]
                  if name == nav.attitude_imu else [])]
        out.warnings.append(f"{said}: {'; '.join(uses)}")
    return out
