"""Typed configuration loaded from TOML, validated with messages that name the offending key.

The default file is ``configs/giulia_scanbrick.toml``. Every section maps onto a frozen dataclass;
unknown keys and impossible values raise :class:`ConfigError` naming the key path
(e.g. ``radar.slope_hz_per_s``).
"""

from __future__ import annotations

import difflib
import itertools
import math
import tomllib
import types
import typing
from dataclasses import MISSING, dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Any, Literal

SPEED_OF_LIGHT = 299_792_458.0

CONFIG_DIR = Path(__file__).resolve().parent.parent / "configs"
DEFAULT_CONFIG = CONFIG_DIR / "giulia_scanbrick.toml"
MSG_DIR = CONFIG_DIR / "msg"
MAX_CLOCK_DRIFT_PPM = 1000.0  #: the largest radar clock drift a config may state or simulate (ppm)
MAX_LATENCY_S = 2.0  #: the largest latency a sensor's table may state (s)
#: the standalone CAN logs' suffixes (any case) read by :mod:`autosar_cli.ingest.canlog`; here, where the command
#: line's help can name them without importing python-can
CAN_LOG_SUFFIXES: tuple[str, ...] = (".blf", ".asc", ".trc", ".log", ".mf4")
#: a log container's files (a rosbag2 bag's storage files among them), and an NMEA capture's: read by
#: :mod:`autosar_cli.ingest.inputs`, here for the same reason
LOG_SUFFIXES: tuple[str, ...] = (".mcap", ".bag", ".db3")
NMEA_SUFFIXES: tuple[str, ...] = (".nmea", ".txt", ".gps")


class ConfigError(ValueError):
    """A configuration file is malformed or holds an impossible value."""


# ----------------------------------------------------------------------------- sections


@dataclass(frozen=True)
class VehicleConfig:
    name: str
    wheelbase_m: float
    track_front_m: float
    track_rear_m: float
    steering_ratio: float
    wheel_radius_m: float
    cog_to_rear_axle_m: float
    cog_height_m: float
    #: K of the steady-state steering, road-wheel angle = L kappa + K a_y (rad per m/s^2); what SAR-MIN's steering
    #: model assumes (0: the kinematic bicycle)
    understeer_gradient_rad_per_mps2: float = 0.0
    #: the rear tyres' slip angle per m/s^2 of lateral acceleration, m a / (L C_r): how far the rear axle's direction of
    #: motion turns from the body's heading in SAR-MIN's motion model (0: no slip; navigation.estimate_rear_slip fits
    #: the drive's)
    rear_slip_gain_rad_per_mps2: float = 0.0
    #: the body rolls and pitches about an axis this high above the road under the CoG (the suspension's roll centre):
    #: where SAR-MIN's radar moves with the IMU's roll and pitch (nav.attitude)
    roll_axis_height_m: float = 0.10


@dataclass(frozen=True)
class MountingConfig:
    """Radar pose in the body frame: lever arm (m) and yaw/pitch/roll (deg, applied z-y-x)."""

    lever_arm_m: tuple[float, float, float]
    yaw_deg: float
    pitch_deg: float = 0.0
    roll_deg: float = 0.0


@dataclass(frozen=True)
class RadarConfig:
    name: str
    topic: str
    start_frequency_hz: float
    bandwidth_hz: float
    slope_hz_per_s: float
    sample_rate_hz: float
    num_samples: int
    num_tx: int
    num_rx: int
    prf_hz: float
    chirp_period_s: float
    max_range_m: float
    beamwidth_az_deg: float
    beamwidth_el_deg: float
    #: phase centres of the board's antennas in the radar frame (wavelengths at ``start_frequency_hz``), row k
    #: the board's Tx (Rx) k; without ``tx_channels`` (``rx_channels``) one row per antenna in use
    tx_positions_wavelengths: tuple[tuple[float, float, float], ...]
    rx_positions_wavelengths: tuple[tuple[float, float, float], ...]
    mounting: MountingConfig
    #: how late the radar's frame stamps run against the navigation's clock (s): a capture timed by its host's
    #: clock, or by a sync message sent before the first frame's trigger; focus takes each frame as started this
    #: much before its stamp (the autofocus measures it on a drive that stops: docs/SENSOR_ERRORS.md)
    clock_offset_s: float = 0.0
    #: how fast the radar's frame clock runs against the navigation's (ppm; parts per million of elapsed time): a
    #: capture timed by its own crystal's frame counter (a DCA1000 capture's frame period) gains this much from its
    #: first frame on; focus takes each frame as started ``clock_offset_s`` plus this share of the time since the
    #: stream's first stamp before its stamp
    clock_drift_ppm: float = 0.0
    #: the board's Tx (Rx) that the radar uses, in the order of the cube's Tx (Rx) axis: rows of
    #: ``tx_positions_wavelengths`` (a capture on Tx 0 and 2 of a 3-Tx board: ``[0, 2]``); None: every row, in order
    tx_channels: tuple[int, ...] | None = None
    rx_channels: tuple[int, ...] | None = None

    @property
    def wavelength_m(self) -> float:
        return SPEED_OF_LIGHT / self.start_frequency_hz

    @property
    def centre_frequency_hz(self) -> float:
        return self.start_frequency_hz + 0.5 * self.bandwidth_hz

    @property
    def tx_in_use(self) -> tuple[int, ...]:
        """The board's Tx the radar uses (rows of ``tx_positions_wavelengths``), in the cube's Tx order."""
        return self.tx_channels if self.tx_channels is not None else tuple(range(self.num_tx))

    @property
    def rx_in_use(self) -> tuple[int, ...]:
        """The board's Rx the radar uses (rows of ``rx_positions_wavelengths``), in the cube's Rx order."""
        return self.rx_channels if self.rx_channels is not None else tuple(range(self.num_rx))

    def board_positions_m(self, rows: tuple[tuple[float, float, float], ...]) -> tuple[tuple[float, float, float], ...]:
        """``rows`` (the board's antennas, wavelengths) in metres, radar frame."""
        lam = self.wavelength_m
        return tuple(tuple(c * lam for c in p) for p in rows)  # type: ignore[misc]

    @property
    def tx_positions_m(self) -> tuple[tuple[float, float, float], ...]:
        """Phase centres (m, radar frame) of the Tx in use, in the cube's Tx order."""
        board = self.board_positions_m(self.tx_positions_wavelengths)
        return tuple(board[k] for k in self.tx_in_use)

    @property
    def rx_positions_m(self) -> tuple[tuple[float, float, float], ...]:
        """Phase centres (m, radar frame) of the Rx in use, in the cube's Rx order."""
        board = self.board_positions_m(self.rx_positions_wavelengths)
        return tuple(board[k] for k in self.rx_in_use)

    def using_channels(self, tx: tuple[int, ...], rx: tuple[int, ...]) -> RadarConfig:
        """This radar on the board's Tx ``tx`` and Rx ``rx`` (a drive's recorded channels)."""
        return replace(self, num_tx=len(tx), num_rx=len(rx), tx_channels=tuple(tx), rx_channels=tuple(rx))

    @property
    def tx_start_offsets_s(self) -> tuple[float, ...]:
        """Start of each Tx chirp relative to the start of the PRI (s)."""
        return tuple(k * self.chirp_period_s for k in range(self.num_tx))

    @property
    def chirp_duration_s(self) -> float:
        """ADC window length (s)."""
        return self.num_samples / self.sample_rate_hz

    @property
    def range_resolution_m(self) -> float:
        return SPEED_OF_LIGHT / (2.0 * self.bandwidth_hz)


@dataclass(frozen=True)
class CanConfig:
    dbc: str
    roles: dict[str, str]
    topic: str = ""
    checksum: str = "fca_giorgio"  #: CHECKSUM rule of frames that have one: "fca_giorgio" or "none"

    def role_signal(self, role: str) -> tuple[str, str]:
        """(message name, signal name) that plays ``role``."""
        message, _, signal = self.roles[role].partition(".")
        return message, signal


@dataclass(frozen=True)
class GyroErrors:
    turn_on_bias_dps: float
    bias_instability_dps: float
    bias_tau_s: float
    noise_density_dps_rthz: float


@dataclass(frozen=True)
class AccelErrors:
    turn_on_bias_mps2: float
    bias_instability_mps2: float
    bias_tau_s: float
    noise_density_mps2_rthz: float


@dataclass(frozen=True)
class WheelErrors:
    radius_scale_error_std: float
    noise_std_mps: float
    # the ABS ECU's speed window: each value is the mean over its last N tooth pitches, so it describes the instant
    # lag_distance_m / v before its stamp, (N + 1) / 2 x 2 pi r / Z for a Z-tooth ring on a wheel of radius r;
    # with lag_distance_std_m > 0 navigation combines it with the lag fitted to the drive (0: the fit alone)
    lag_distance_m: float = 0.0
    lag_distance_std_m: float = 0.0


@dataclass(frozen=True)
class SteeringErrors:
    offset_std_deg: float
    noise_std_deg: float


@dataclass(frozen=True)
class GnssErrors:
    horizontal_std_m: float
    vertical_std_m: float
    correlation_time_s: float
    white_std_m: float
    velocity_std_mps: float
    heading_std_deg: float
    #: the velocity noise's correlation time (s; first-order Gauss-Markov, std ``velocity_std_mps`` per sample).
    #: 0: white. A receiver's own filter smooths its Doppler velocity, so its errors persist over samples.
    velocity_correlation_time_s: float = 0.0
    #: spans with no fix, velocity or heading: (start s from the drive's start, duration s) each (a tunnel, trees)
    outages: tuple[tuple[float, float], ...] = ()
    #: spans whose fixes a reflection moves: (start s, duration s, east m, north m) each; the receiver reports them
    #: with its usual sigma, as one that cannot tell does
    multipath: tuple[tuple[float, float, float, float], ...] = ()


SensorKind = Literal["wheel_speeds", "steering", "can_imu", "imu", "gnss", "can_gnss"]

REQUIRED_ERROR_TABLES: dict[str, tuple[str, ...]] = {
    "wheel_speeds": ("wheel",),
    "steering": ("steering",),
    "can_imu": ("gyro", "accel"),
    "imu": ("gyro", "accel"),
    "gnss": ("gnss",),
    "can_gnss": ("gnss",),
}


_COMMON_SENSOR_KEYS = frozenset({"kind", "rate_hz", "latency_s", "lever_arm_m"})
#: the keys of a sensor table each kind reads (beside the common ones and its error tables)
_KIND_KEYS: dict[str, frozenset[str]] = {
    "imu": frozenset({"mounting_ypr_deg", "topic", "frame_id", "dof"}),
    "gnss": frozenset({"topic", "frame_id", "velocity_topic", "velocity_type", "nmea_topic"}),
}


@dataclass(frozen=True)
class SensorConfig:
    kind: SensorKind
    rate_hz: float
    latency_s: float = 0.0
    lever_arm_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: an IMU's axes turned into the body's: yaw, pitch, roll (deg), z-y-x as the radar's mounting
    #: (``nav.frames.mounting_rotation``); a 3-DoF IMU (yaw rate only) may only be turned in yaw
    mounting_ypr_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    topic: str = ""
    frame_id: str = ""
    dof: int = 6
    velocity_topic: str = ""
    velocity_type: Literal["twist", "twist_with_covariance"] = "twist"
    nmea_topic: str = ""
    gyro: GyroErrors | None = None
    accel: AccelErrors | None = None
    wheel: WheelErrors | None = None
    steering: SteeringErrors | None = None
    gnss: GnssErrors | None = None


@dataclass(frozen=True)
class ProcessingConfig:
    focus_height_m: float = 0.5
    pixel_m: float = 0.04
    cross_range_resolution_m: float = 0.04
    range_window: Literal["hann", "hamming", "rect", "taylor"] = "hann"
    range_upsample: int = 4
    channels: Literal[8, 12] = 8
    autofocus_slow_motion: bool = True  #: the autofocus takes the slow motion from the points' passes first
    autofocus_fast_motion: bool = False  #: and, last, the fast across-track motion from many scatterers
    autofocus_channel_gains: bool = True  #: the autofocus measures the radar's channel gains first, undone where off
    autofocus_pass_block_s: float = 0.1  #: the slow motion sums each point's pulses over blocks this long (s)


@dataclass(frozen=True)
class SimulationConfig:
    origin_lat_deg: float
    origin_lon_deg: float
    origin_height_m: float
    start_time_utc: str
    truth_rate_hz: float = 1000.0
    radar_noise_std_lsb: float = 3.0
    radar_amplitude_lsb: float = 1500.0
    vibration_vertical_rms_m: float = 1.0e-3
    vibration_horizontal_rms_m: float = 0.08e-3
    vibration_band_hz: tuple[float, float] = (4.0, 25.0)
    # the radar's channels as an uncalibrated front end leaves them: each Tx's and each Rx's path adds its own
    # phase (deg) and gain (dB), drawn once per drive (normal, these stds), so virtual channel (tx, rx) carries
    # their sum; 0 (the config's): channels matched, as the processor assumes unless it calibrates them
    channel_phase_std_deg: float = 0.0
    channel_gain_std_db: float = 0.0
    # the radar's frame stamps minus the instants its frames start (s): a capture timed by its host's clock or a sync
    # message that is not the first frame's trigger; 0 (the config's): stamped exactly, as the processor assumes
    radar_clock_offset_s: float = 0.0
    # how fast the radar's frame clock runs against the true time (ppm): its frames start every frame period on its
    # own clock, so the frames are that much closer together than their stamps say, from the first frame on; 0 (the
    # config's): a crystal on its nominal frequency, as the processor assumes
    radar_clock_drift_ppm: float = 0.0
    # "kinematic": planar kinematic bicycle on a level road (the motion SAR-MIN assumes); "full": single-track
    # dynamics with tyre slip, body roll/pitch/heave on the suspension, a rough road ([vehicle_dynamics]).
    dynamics: Literal["kinematic", "full"] = "full"
    # the kinematic model's wheel speeds as an ABS ECU reports them: each the mean over its last edges of a perfect
    # tone ring ([vehicle_dynamics]), the window the wheel sensor's table states (lag_distance_m); false: each
    # wheel's instantaneous speed. The full model's wheels always pass through their ring (component wheel_ticks).
    kinematic_ecu_window: bool = False
    # riders passing the car, each [along the path from the radar's start (m), to its left (m; the radar side is
    # negative), speed along the path (m/s; negative: the other way)]: moving scatterers the processor does not
    # model (sim.scene.SceneBuilder.cyclist)
    cyclists: tuple[tuple[float, float, float], ...] = ()
    # the road's specular amplitude reflection coefficient at grazing incidence (real, -1 < Gamma < 1): every
    # scatterer above the road is also seen by way of it (multipath: four paths, the image in the road;
    # sim.echo), which the processor does not model; 0 (the config's): no path by way of the road
    road_reflection: float = 0.0


@dataclass(frozen=True)
class VehicleDynamicsConfig:
    """Parameters of the simulator's full vehicle model (sources in configs/giulia_scanbrick.toml)."""

    mass_kg: float = 1600.0
    yaw_inertia_kgm2: float = 2600.0
    cornering_stiffness_front_n_per_rad: float = 90000.0  # per axle
    cornering_stiffness_rear_n_per_rad: float = 120000.0
    friction_coefficient: float = 0.9
    slip_stiffness_per_load: float = 15.0  # longitudinal: F_x / (F_z * slip)
    brake_front_fraction: float = 0.7
    drive_front_fraction: float = 0.0  # share of the drive torque on the front axle: 0 rear-driven, 1 front-driven
    rolling_resistance: float = 0.012
    drag_area_m2: float = 0.65  # C_d * A
    heave_frequency_hz: float = 1.3
    pitch_frequency_hz: float = 1.5
    roll_frequency_hz: float = 1.7
    heave_damping_ratio: float = 0.3
    pitch_damping_ratio: float = 0.3
    roll_damping_ratio: float = 0.35
    roll_gradient_deg_per_g: float = 4.0
    pitch_gradient_deg_per_g: float = 2.0
    roll_centre_height_m: float = 0.10
    tyre_vertical_stiffness_n_per_m: float = 250000.0
    rolling_radius_deflection_fraction: float = 0.33
    rolling_radius_speed_growth_per_mps2: float = 1.5e-6
    driver_preview_s: float = 0.3
    driver_lateral_gain: float = 1.5
    driver_heading_gain: float = 0.5
    tone_ring_teeth: int = 48
    tooth_pitch_error_std: float = 0.002  # fraction of one tooth's pitch
    edges_per_speed_estimate: int = 6
    wheel_speed_timeout_s: float = 0.3
    imu_misalignment_deg: tuple[float, float] = (0.3, 1.0)  # magnitude per axis drawn uniformly in this range
    road_class: Literal["A", "B", "C"] = "A"
    road_coherence_decay: float = 0.8  # left/right coherence exp(-decay * n * track)
    road_grade_percent: float = 1.0
    road_grade_wavelength_m: float = 120.0
    road_cross_fall_percent: float = 2.0
    road_max_frequency_cpm: float = 8.0
    # which effects the full model has (ablation): lateral tyre slip and the driver; roll/pitch from the
    # accelerations; the road (grade, cross-fall, roughness, features) through the suspension; load- and
    # speed-dependent rolling radius and longitudinal slip; tone-ring wheel speeds; IMU mounting misalignment
    components: tuple[Literal["slip", "body", "road", "tyre_radius", "wheel_ticks", "imu_misalignment"], ...] = (
        "slip", "body", "road", "tyre_radius", "wheel_ticks", "imu_misalignment")


@dataclass(frozen=True)
class NavigationConfig:
    """SAR-MIN tuning (measurement noises come from each sensor's own error table)."""

    gyros: tuple[str, ...] = ("imu_cog_a", "imu_cog_b", "orc", "esc")  # yaw-rate sensors fused, by sensor name
    gnss: str = "gnss_cog"  # GNSS source fused (fix + velocity)
    # process: white acceleration, m/s^2 per sqrt(Hz). Over the 10 ms between wheel samples it lets the speed
    # move 3 cm/s (3 m/s^2 of real acceleration); 0.8 let it move 8 cm/s, so a GNSS velocity a few ms from
    # a wheel sample said little about the wheels' scale (its 1-sigma stayed 0.05-0.09 % on test1 and test2).
    speed_noise_mps2: float = 0.3
    yaw_rate_noise_radps2: float = 0.08  # process: white yaw acceleration, rad/s^2 per sqrt(Hz)
    position_noise_m: float = 0.002  # process: unmodelled position jitter, m per sqrt(Hz)
    # GNSS position error as the filter models it. "gauss_markov": two states (east, north) with the GNSS
    # sensor's own error table (horizontal_std_m, correlation_time_s) plus white_std_m per fix; "white":
    # independent fixes of gnss_position_std_m (the slow error then leaks into the speed, see EVALUATION.md).
    gnss_error_model: Literal["gauss_markov", "white"] = "gauss_markov"
    gnss_position_std_m: float = 0.5  # per-fix noise of the "white" model only
    # the GNSS receiver's own heading (NMEA HDT: a dual-antenna or INS heading of the body), where the drive has
    # one, as a measurement of the heading plus a constant offset (the antennas' baseline against the body's axis,
    # prior std gnss_heading_offset_std_deg); its noise is the sensor table's heading_std_deg. Off by default: at the
    # simulated receiver's 0.3 deg urban's autofocused images went within 2 cm on 10 of 16 drives against 9 (test1-3
    # 30 of 30 either way), and the kinematic drives are not measured with it (docs/NAVIGATION.md)
    gnss_heading: bool = False
    gnss_heading_offset_std_deg: float = 1.0
    steering_min_speed_mps: float = 1.0  # below it the steering model atan(L omega / v) is not used
    # where all four wheels read exactly 0 for 1 s or more, the yaw rate is 0 to this std at each gyro sample (0: off)
    standstill_yaw_rate_std_dps: float = 0.001
    # fit the understeer gradient K and the yaw lag to the drive's turns on a pass without the steering, and keep that
    # pass where they show the car not steering as the kinematic bicycle (K's std at most
    # understeer_max_std_rad_per_mps2); else, and with estimate_understeer off, the steering is used
    estimate_understeer: bool = True
    understeer_max_std_rad_per_mps2: float = 0.0005
    # the wheel speeds' lag c / v behind their stamps (an ABS ECU's edge window) fitted against the GNSS velocity,
    # and the samples moved back by it, where c's std is at most wheel_lag_max_std_m
    estimate_wheel_lag: bool = True
    wheel_lag_max_std_m: float = 0.02
    # the wheel sensor's stated window ([sensors.*.wheel] lag_distance_m) joins that fit on every drive that does
    # not contradict it, not only where the drive shows a lag: right for a real ABS ECU; off by default because the
    # kinematic simulator's wheel speeds have no window (docs/NAVIGATION.md)
    wheel_lag_window_always: bool = False
    # each axle's slip (per m/s^2 of acceleration, drive and brake) and lateral load gain (per m/s^2 of lateral
    # acceleration) fitted to the drive, and the wheel speeds divided by those whose std is at most this
    estimate_wheel_radii: bool = True
    # the GNSS receiver's latency measured against the 6-DoF IMU of attitude_imu (nav.gnss_latency), and the GNSS
    # samples moved by it where the fit is unambiguous, its std at most gnss_latency_max_std_s, and it differs from
    # the sensor's stated latency_s by more than 4 std and 20 ms
    estimate_gnss_latency: bool = True
    gnss_latency_max_std_s: float = 0.025
    # the CAN bus's delay beyond its sensors' tables measured by the CAN gyros against the IMUs' (nav.can_latency),
    # and every CAN signal moved by it where its std is at most can_latency_max_std_s and it differs from 0 by more
    # than 3 std and 10 ms
    estimate_can_latency: bool = True
    can_latency_max_std_s: float = 0.005
    # the rear tyres' slip gain (the rear axle's course = heading - g v omega) fitted against the GNSS velocity on a
    # first pass, and SAR-MIN's final pass run with it where its std is at most rear_slip_max_std_rad_per_mps2
    estimate_rear_slip: bool = True
    rear_slip_max_std_rad_per_mps2: float = 0.002
    # each GNSS stream's white noise measured from its own samples (nav.gnss_noise), and the table's sigma raised to
    # it where it is at least 1.4 times the table's (a receiver noisier than its datasheet)
    estimate_gnss_noise: bool = True
    # a GNSS velocity whose errors correlate from sample to sample (measured against the wheel speeds whenever
    # estimate_gnss_noise is on, and reported) carried as two Gauss-Markov states; off, the samples stay independent
    # and navigate warns that the scale and heading it states are too confident (docs/SENSOR_ERRORS.md)
    gnss_velocity_error_states: bool = True
    # the 6-DoF IMU whose roll and pitch move SAR-MIN's radar (nav.attitude; "" = none): the radar's motion as the
    # body rolls and pitches, grade included, as the trajectory's correction
    attitude_imu: str = ""
    # the radar's height along the drive from that IMU's pitch (the road's grade, the body's tilt), the IMU's pitch
    # bias taken out against the GNSS's vertical velocity; off (the default: it biases the autofocus's track scale on
    # straight drives, docs/NAVIGATION.md), or without a vertical velocity: a fixed height
    radar_height: bool = False
    # that IMU's pitch bias, measured on the GNSS's vertical velocity, taken out even with radar_height off: the roof
    # antenna, moved to a level body by the biased pitch, then sits fore-aft of where it is, which the GNSS velocity
    # in turns reads as rear slip (docs/NAVIGATION.md); off: no better on the 40 drives, navigation only
    attitude_pitch_bias: bool = False
    wheel_radius_gain_max_std_per_mps2: float = 0.01
    gate_probability: float = 0.9999  # chi-square gate of each update
    max_step_s: float = 0.05  # longest single prediction step (dead reckoning through gaps)
    ins_imu: str = "ins_radar"  # INS baseline: the radar-mounted 6-DoF IMU ...
    ins_gnss: str = "gnss_radar"  # ... and its own GNSS


@dataclass(frozen=True)
class Config:
    vehicle: VehicleConfig
    radar: RadarConfig
    can: CanConfig
    sensors: dict[str, SensorConfig]
    processing: ProcessingConfig = field(default_factory=ProcessingConfig)
    simulation: SimulationConfig | None = None
    vehicle_dynamics: VehicleDynamicsConfig = field(default_factory=VehicleDynamicsConfig)
    navigation: NavigationConfig = field(default_factory=NavigationConfig)
    source: str = ""
    bases: tuple[str, ...] = ()  #: the configs ``source`` is laid over (``base = ...``), nearest first

    @property
    def files(self) -> tuple[str, ...]:
        """Every file this config was read from: ``source``, then its bases."""
        return ((self.source,) if self.source else ()) + self.bases

    def text(self) -> str:
        """The TOML this config was read from, for provenance: its file's, or, laid over bases, each file's
        after a comment line naming it."""
        if not self.bases:
            return Path(self.source).read_text(encoding="utf-8") if self.source else ""
        return "".join(f"# autosar config layer: {f}\n{Path(f).read_text(encoding='utf-8')}\n" for f in self.files)

    @property
    def dbc_path(self) -> Path:
        p = Path(self.can.dbc)
        if not p.is_absolute() and self.source:
            p = Path(self.source).parent / p
        return p

    def sensors_of_kind(self, kind: str) -> dict[str, SensorConfig]:
        return {name: s for name, s in self.sensors.items() if s.kind == kind}

    def pinned_topics(self) -> dict[str, tuple[str, str, str]]:
        """topic -> (stream kind, sensor name, config key) for every topic the config pins: the radar's, the CAN
        bus's, each IMU's, each receiver's fixes, velocity and NMEA."""
        out = {self.radar.topic: ("radar", self.radar.name, "radar.topic")}
        if self.can.topic:
            out[self.can.topic] = ("can", "can", "can.topic")
        for name, s in self.sensors.items():
            if s.kind == "imu" and s.topic:
                out[s.topic] = ("imu", name, f"sensors.{name}.topic")
            elif s.kind == "gnss":
                for topic, kind, key in ((s.topic, "fix", "topic"), (s.velocity_topic, "velocity", "velocity_topic"),
                                         (s.nmea_topic, "nmea", "nmea_topic")):
                    if topic:
                        out[topic] = (kind, name, f"sensors.{name}.{key}")
        return out


# ----------------------------------------------------------------------------- loading


def load_config(path: str | Path | None = None) -> Config:
    """Load and validate a TOML config (default: ``configs/giulia_scanbrick.toml``). A config whose top level
    says ``base = "PATH"`` (relative to itself; ``"default"`` for the default config) holds only what differs
    from that one: its tables are merged over the base's, key by key, its values (arrays too) replace the base's; a
    CAN role set to ``""`` is unset (the car has no such signal)."""
    p = Path(path) if path is not None else DEFAULT_CONFIG
    bases: list[str] = []
    raw = _layered(p, (), bases)
    try:
        cfg = config_from_dict(raw, source=str(p.resolve()), bases=tuple(bases))
    except ConfigError as exc:
        raise ConfigError(f"{p}: {exc}") from None
    return cfg


def _read_toml(p: Path) -> dict[str, Any]:
    if p.exists() and not (p.is_file() or p.is_dir()):  # a pipe would block on a writer that never comes
        raise ConfigError(f"{p}: not a regular file (a pipe, socket or device); give the config file")
    try:
        with open(p, "rb") as f:
            return tomllib.load(f)
    except FileNotFoundError:
        raise ConfigError(f"{p}: config file not found") from None
    except IsADirectoryError:
        raise ConfigError(f"{p}: a directory, not a config file") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML: not UTF-8 text (byte {exc.start})") from None
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read the config: {exc.strerror}") from None


def _layered(p: Path, below: tuple[Path, ...], bases: list[str]) -> dict[str, Any]:
    """The TOML at ``p`` merged over its ``base`` chain, whose files are appended to ``bases``; a relative
    ``can.dbc`` made absolute beside the file that names it (a config elsewhere that takes the default's DBC still
    finds it)."""
    raw = _read_toml(p)
    can = raw.get("can")
    if isinstance(can, dict) and isinstance(can.get("dbc"), str) and not Path(can["dbc"]).is_absolute():
        can["dbc"] = str(p.resolve().parent / can["dbc"])
    if "base" not in raw:
        return raw
    base = raw.pop("base")
    if not isinstance(base, str) or not base:
        raise ConfigError(f"{p}: base: expected the path of the config this one changes, or \"default\"")
    base_path = DEFAULT_CONFIG if base == "default" else p.parent / base
    if base_path.resolve() in below + (p.resolve(),):
        raise ConfigError(f"{p}: base: {base_path} is this config or one it is the base of (a circle)")
    bases.append(str(base_path.resolve()))
    try:
        under = _layered(base_path, below + (p.resolve(),), bases)
    except ConfigError as exc:
        said = str(exc)
        if said.startswith(f"{base_path}: ") and not said.startswith(f"{base_path}: base: "):  # the base file itself
            raise ConfigError(f"{p}: base: {said}") from None
        raise
    return _merged(under, raw)


def _merged(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in over.items():
        out[key] = _merged(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out


def config_from_dict(raw: dict[str, Any], source: str = "", bases: tuple[str, ...] = ()) -> Config:
    """Build a validated :class:`Config` from a parsed TOML mapping (``source`` and ``bases``: the files it was
    read from)."""
    data = dict(raw)
    can = data.get("can")
    if isinstance(can, dict) and isinstance(can.get("roles"), dict):
        # TOML has no null: a role set to "" says this car has no such signal (a layer unsets its base's role)
        data["can"] = {**can, "roles": {role: ref for role, ref in can["roles"].items() if ref != ""}}
    data["source"], data["bases"] = source, bases
    cfg = _build(Config, data, "")
    _validate(cfg)
    return cfg


#: the coarsest cross-range resolution taken (m): coarser, its processed beam (lambda / 4 rho, 1 mrad at 77 GHz)
#: holds a pulse or two of a car's aperture, an image of single pulses that looks like a SAR image
MAX_CROSS_RANGE_RESOLUTION_M = 1.0

#: the finest range interpolation taken (default 4): each range profile holds this many times its samples, in memory
MAX_RANGE_UPSAMPLE = 64

#: the CAN roles the stages read: the car's own, and per CAN sensor (``QUANTITY.<sensor>``) by its kind
VEHICLE_ROLES = ("wheel_speed_fl", "wheel_speed_fr", "wheel_speed_rl", "wheel_speed_rr", "steering_wheel_angle",
                 "steering_wheel_rate")
SENSOR_ROLES: dict[str, tuple[str, ...]] = {
    "can_imu": ("yaw_rate", "accel_long", "accel_lat"),
    "can_gnss": ("latitude", "longitude", "altitude", "position_valid", "speed", "course"),
}

#: the SI unit each role's signal is read in (:func:`autosar_cli.candb.si_factor` converts a DBC's); the quantity of a
#: sensor's role (``yaw_rate.esc``) by its part before the dot; ``position_valid`` is a flag, of no unit
ROLE_UNITS = {"wheel_speed": "m/s", "steering_wheel_angle": "rad", "steering_wheel_rate": "rad/s",
              "yaw_rate": "rad/s", "accel_long": "m/s^2", "accel_lat": "m/s^2", "latitude": "deg",
              "longitude": "deg", "altitude": "m", "speed": "m/s", "course": "rad"}


def role_unit(role: str) -> str | None:
    """The SI unit the stages read a CAN role's signal in (``wheel_speed_fl``: m/s); None for a flag."""
    quantity = role.partition(".")[0]
    return ROLE_UNITS.get("wheel_speed" if quantity.startswith("wheel_speed_") else quantity)


def _known_role(role: str, sensors: dict[str, SensorConfig]) -> None:
    """A role name is one the stages read: a misspelt one was a role nothing played (the wheel speeds gone from
    navigation without a word)."""
    quantity, dot, sensor = role.partition(".")
    if not dot:
        if role not in VEHICLE_ROLES:
            dotted = [f"{q}.<sensor>" for qs in SENSOR_ROLES.values() for q in qs]
            raise ConfigError(f"can.roles.{role}: not a role{_suggestion(role, list(VEHICLE_ROLES))}; the roles: "
                              f"{', '.join(VEHICLE_ROLES)}, and per CAN sensor {', '.join(dotted)}")
        return
    kinds = [k for k, qs in SENSOR_ROLES.items() if quantity in qs]
    if not kinds:
        names = [q for qs in SENSOR_ROLES.values() for q in qs]
        raise ConfigError(f"can.roles.{role}: {quantity!r} is not a quantity of a CAN sensor"
                          f"{_suggestion(quantity, names)}; a can_imu's: {', '.join(SENSOR_ROLES['can_imu'])}; a "
                          f"can_gnss's: {', '.join(SENSOR_ROLES['can_gnss'])}")
    s = sensors.get(sensor)
    if s is None or s.kind not in kinds:
        theirs = sorted(n for n, t in sensors.items() if t.kind in kinds)
        what = "no sensor of [sensors]" if s is None else f"a {s.kind} sensor, not a {' or '.join(kinds)}"
        raise ConfigError(f"can.roles.{role}: {sensor!r} is {what}{_suggestion(sensor, theirs)}; the config's "
                          f"{' or '.join(kinds)} sensors: {', '.join(theirs) or 'none'}")


def _suggestion(key: str, names: list[str], value: Any = None) -> str:
    """What an unknown ``key`` was likely meant to be: a near spelling of a key of its table (``names``), where a
    key of that name belongs, or, of a table (``value`` a dict: ``[focus]`` holding ``pixel_m``), the table whose
    keys it holds; "" if none."""
    near = difflib.get_close_matches(key, names, n=1, cutoff=0.75)
    if near:
        return f" (did you mean {near[0]}?)"
    paths = _key_paths(Config, "")
    homes = [p for p in paths if p.rsplit(".", 1)[-1] == key]
    tables = [f"[{p.rsplit('.', 1)[0]}]" if "." in p else "the top level" for p in homes]
    if homes:
        return f" (a key of {' and '.join(tables)})"
    if isinstance(value, dict) and value:
        # the tables that hold every key of this one
        holders = [t for t in dict.fromkeys(p.rsplit(".", 1)[0] for p in paths if "." in p)
                   if all(f"{t}.{k}" in paths for k in value)]
        if holders:
            return f" (its keys belong in {' and '.join(f'[{t}]' for t in holders)})"
    return ""


def _key_paths(cls: Any, path: str) -> list[str]:
    """Every key path of the config's tables (``cls`` a dataclass), ``path`` its own."""
    hints = typing.get_type_hints(cls)
    out = []
    for f in fields(cls):
        sub = _join(path, f.name)
        out.append(sub)
        if is_dataclass(hints[f.name]):
            out += _key_paths(hints[f.name], sub)
    return out


def _keys_of_its_kind(table: dict[str, Any], path: str) -> None:
    """Refuse a sensor table's key that another kind of sensor reads (a wheel sensor's ``dof`` or
    ``mounting_ypr_deg``, an IMU's ``gnss`` table): nothing would read it, so what it says would be silently ignored.
    The one place this rule lives: every config is built from such tables (:func:`config_from_dict`)."""
    kind = table["kind"]
    own = _COMMON_SENSOR_KEYS | _KIND_KEYS.get(kind, frozenset()) | set(REQUIRED_ERROR_TABLES[kind])
    for key in sorted(set(table) - own):
        theirs = sorted(k for k in REQUIRED_ERROR_TABLES
                        if key in _KIND_KEYS.get(k, ()) or key in REQUIRED_ERROR_TABLES[k])
        what = "table" if isinstance(table[key], dict) else "key"
        raise ConfigError(f"{_join(path, key)}: {_a(kind)} sensor reads no {key} {what} ({_a(' or '.join(theirs))} "
                          f"sensor's); {_a(kind)} sensor's: {', '.join(sorted(own - {'kind'}))}")


def _a(noun: str) -> str:
    return f"{'an' if noun[:1] in 'aeiou' else 'a'} {noun}"


def _build(cls: Any, value: Any, path: str) -> Any:
    """Convert parsed TOML into the annotated type ``cls``; reject unknown keys."""
    origin = typing.get_origin(cls)
    where = path or "<top level>"
    if is_dataclass(cls):
        if not isinstance(value, dict):
            raise ConfigError(f"{where}: expected a table, got {type(value).__name__}")
        hints = typing.get_type_hints(cls)
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(value) - names)
        if unknown:
            raise ConfigError(f"{_join(path, unknown[0])}: unknown key"
                              f"{_suggestion(unknown[0], sorted(names), value[unknown[0]])}")
        if cls is SensorConfig and value.get("kind") in REQUIRED_ERROR_TABLES:
            _keys_of_its_kind(value, path)
        kwargs = {}
        for f in fields(cls):
            if f.name in value:
                kwargs[f.name] = _build(hints[f.name], value[f.name], _join(path, f.name))
            elif f.default is MISSING and f.default_factory is MISSING:
                what = "table" if is_dataclass(hints[f.name]) else "key"
                raise ConfigError(f"{_join(path, f.name)}: missing required {what} (a config is complete, or "
                                  "says base = \"default\" and holds only what differs from it)")
        return cls(**kwargs)
    if origin in (types.UnionType, typing.Union):
        args = [a for a in typing.get_args(cls) if a is not type(None)]
        if value is None:
            return None
        return _build(args[0], value, path)
    if origin is Literal:
        allowed = typing.get_args(cls)
        if value not in allowed:
            raise ConfigError(f"{where}: {value!r} is not one of {', '.join(map(repr, allowed))}")
        return value
    if origin is dict:
        key_t, val_t = typing.get_args(cls)
        if not isinstance(value, dict):
            raise ConfigError(f"{where}: expected a table")
        built = {}
        for k, v in value.items():
            try:
                built[str(k)] = _build(val_t, v, _join(path, str(k)))
            except ConfigError as exc:
                kinds = [str(n) for n, t in value.items() if isinstance(t, dict) and "kind" in t]
                if is_dataclass(val_t) and str(exc).startswith(f"{_join(path, str(k))}.kind: missing required key"):
                    # a table without the kind every named one has: a name misspelt, or a new one half-given
                    raise ConfigError(f"{_join(path, str(k))}: not one of [{path}]{_suggestion(str(k), kinds)}; a "
                                      f"new one needs kind (the others: {', '.join(kinds)})") from None
                raise
        return built
    if origin is tuple:
        args = typing.get_args(cls)
        if not isinstance(value, list | tuple):
            raise ConfigError(f"{where}: expected an array")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_build(args[0], v, f"{where}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            raise ConfigError(f"{where}: expected {len(args)} values, got {len(value)}")
        return tuple(_build(a, v, f"{where}[{i}]") for i, (a, v) in enumerate(zip(args, value, strict=True)))
    if cls is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"{where}: expected a number, got {value!r}")
        return float(value)
    if cls is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where}: expected an integer, got {value!r}")
        return value
    if cls is str:
        if not isinstance(value, str):
            raise ConfigError(f"{where}: expected a string, got {value!r}")
        return value
    if cls is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{where}: expected true or false, got {value!r}")
        return value
    raise TypeError(f"unsupported config type {cls!r} at {where}")  # a bug in this module, not in the file


def _channels(kind: str, count: int, channels: tuple[int, ...] | None, rows: int) -> None:
    """Check ``radar.<kind>_channels`` against ``num_<kind>`` and the board's ``rows``."""
    name = f"radar.{kind}_positions_wavelengths"
    if channels is None:
        if rows != count:
            raise ConfigError(f"{name}: {rows} rows for num_{kind} = {count} (one row per antenna in use; a board's "
                              f"rows for some of its antennas: give radar.{kind}_channels, the rows in use)")
        return
    if len(channels) != count:
        raise ConfigError(f"radar.{kind}_channels: {len(channels)} antennas for num_{kind} = {count}")
    if len(set(channels)) != len(channels) or not all(0 <= c < rows for c in channels):
        raise ConfigError(f"radar.{kind}_channels: {list(channels)} must be distinct rows of {name} (0-{rows - 1})")


#: the units a chirp's keys are likely given in where slope x ADC window misses bandwidth_hz: key -> (the least and
#: the most value any FMCW radar's has in the key's SI unit, that unit, (factor to it, other unit) each)
_CHIRP_UNITS: dict[str, tuple[float, float, str, tuple[tuple[float, str], ...]]] = {
    "slope_hz_per_s": (1e9, 1e15, "Hz/s", ((1e12, "MHz/us"),)),
    "sample_rate_hz": (1e5, 1e8, "Hz", ((1e3, "ksps"), (1e6, "Msps"))),
    "bandwidth_hz": (1e6, 1e11, "Hz", ((1e6, "MHz"), (1e9, "GHz"))),
}


def _chirp_units_slipped(r: RadarConfig) -> str:
    """The chirp's keys whose values lie below any radar's in their SI unit and, read in another (MHz/us, ksps, Msps,
    MHz, GHz), make slope x ADC window (``slope_hz_per_s * num_samples / sample_rate_hz``) equal ``bandwidth_hz``,
    each named with its value in the SI unit ("" if none): a datasheet's 75 MHz/us slope was refused as a bandwidth
    that differs, naming bandwidth_hz alone (all three in a datasheet's units agree with one another: refused as a
    chirp period shorter than the ADC window, naming that alone). A key below its least value is read in another
    unit, one that takes it within its range (TI's 75 MHz/us, 13.5 Msps, 3000 MHz: not 3000 GHz)."""
    options = [[(k, f, u) for f, u in units if lo <= getattr(r, k) * f <= hi] if getattr(r, k) < lo else [(k, 1.0, "")]
               for k, (lo, hi, _, units) in _CHIRP_UNITS.items()]
    for combo in itertools.product(*options):
        scale = {k: f for k, f, _ in combo}
        slope, rate = r.slope_hz_per_s * scale["slope_hz_per_s"], r.sample_rate_hz * scale["sample_rate_hz"]
        bandwidth = r.bandwidth_hz * scale["bandwidth_hz"]
        if any(f != 1.0 for f in scale.values()) and abs(slope * r.num_samples / rate - bandwidth) <= 1e-6 * bandwidth:
            return "".join(f"radar.{k}: {getattr(r, k):g} is likely in {u}, {getattr(r, k) * f:g} "
                           f"{_CHIRP_UNITS[k][2]}; " for k, f, u in combo if f != 1.0)
    return ""


#: the carriers (Hz) of FMCW radars (automotive 24 / 77 / 79 GHz among them): 77 is GHz, not Hz
MIN_CARRIER_HZ, MAX_CARRIER_HZ = 1e9, 3e11
#: the furthest (m) the focusing plane may lie from the road: 500 is the default's 0.5 m in mm (it failed at focus,
#: "no ground ... at height 500.0 m", naming no key)
MAX_FOCUS_HEIGHT_M = 20.0

#: the slowest rate (Hz) an IMU's or CAN gyro's table may state: its noise per sample is its noise density x
#: sqrt(rate_hz), so test1's ESC gyro (100 Hz) stated as its period (0.01) was trusted 100 times too much, the track
#: moved 5.1 cm and the reflectors 3.0-5.1 cm, status ok
MIN_GYRO_RATE_HZ = 1.0

#: the latency (s) from which a sensor's table is refused as one stated in ms: stamps a second after the instant their
#: values refer to are no sensor's (a logger's clock set wrong is an offset of every stream, not a latency), where an
#: NMEA receiver at 4800 baud sends its last sentences of a fix up to ~1 s after it (~500 bytes at 480 bytes/s);
#: gnss_cog.latency_s = 1 (1 ms meant) moved the ci drive's track 2.31 m (0.44 -> 2.17 m RMS from the truth, heading
#: 0.73 -> 28.8 mrad RMS), status ok
LATENCY_IN_MS_S = 1.0

#: the least angle (deg) between the radar's boresight and the car's x axis: a radar looking along its own track
#: makes no SAR image (the ci drive's reflectors lost 13.6 dB with yaw_deg -0.785, the default's -45 in radians)
MIN_BORESIGHT_OFF_AXIS_DEG = 10.0


#: a radar this high above the CoG (m; a car's roof is ~0.9 m above it) may sit on one side looking across the roof
#: at the other: a roof rack's or a mast's mount, which the lateral check leaves alone
MIN_ABOVE_COG_ACROSS_THE_ROOF_M = 0.5


def _looks_sideways(m: MountingConfig, track_m: float) -> None:
    """The radar looks to a side of the car, and not across it: a yaw in radians turns its boresight along the track;
    a lever arm's y with its sign turned (or x and y swapped), or a yaw's sign turned, puts a radar on one side looking
    through the car at the other, whose image focus placed as far to the wrong side without a word (the ci drive's
    reflectors 1.50 m off with y's sign turned, 4.3 m with x and y swapped); one on the roof may look across it."""
    off_axis = math.degrees(math.asin(min(1.0, abs(math.sin(math.radians(m.yaw_deg))))))
    if off_axis < MIN_BORESIGHT_OFF_AXIS_DEG:
        radians = (f"; in radians? {m.yaw_deg:g} rad is {math.degrees(m.yaw_deg):.1f} deg"
                   if abs(m.yaw_deg) <= 2 * math.pi else "")
        raise ConfigError(f"radar.mounting.yaw_deg: {m.yaw_deg:g} turns the boresight {off_axis:.1f} deg off the car's "
                          f"x axis, along its track, which makes no SAR image: a side-looking radar's is at least "
                          f"{MIN_BORESIGHT_OFF_AXIS_DEG:g} deg off it (-90: broadside to the right, +90: to the left)"
                          f"{radians}")
    y, z = m.lever_arm_m[1], m.lever_arm_m[2]
    looks = 1.0 if math.sin(math.radians(m.yaw_deg)) > 0 else -1.0  # nav.trajectory.radar_side's rule
    if abs(y) > track_m / 4 and y * looks < 0 and z < MIN_ABOVE_COG_ACROSS_THE_ROOF_M:
        sits, side = ("left", "right") if y > 0 else ("right", "left")
        raise ConfigError(f"radar.mounting: the radar sits {abs(y):.2f} m {sits} of the car's centre line "
                          f"(lever_arm_m[1] = {y:g}; body y is to the left) yet looks to the {side} (yaw_deg "
                          f"{m.yaw_deg:g}; > 0 left), through the car: the sign of lever_arm_m's y or of yaw_deg "
                          f"turned, or lever_arm_m's x and y swapped?")


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


# ----------------------------------------------------------------------------- validation


#: the largest magnitude a number may have, by the unit its name ends in (longest suffix first): beyond what any car,
#: road or sensor has; a value past it is a typo or another unit, and would overflow or empty the filter's arithmetic
_LARGEST_BY_UNIT: tuple[tuple[str, float], ...] = (
    ("_hz_per_s", 1e16), ("_error_std", 1.0), ("_dps_rthz", 1e3), ("_mps2_rthz", 1e3), ("_rad_per_mps2", 1.0),
    ("_per_mps2", 1.0), ("_n_per_rad", 1e7), ("_n_per_m", 1e8), ("_deg_per_g", 90.0), ("_radps2", 100.0),
    ("_mps2", 1e3), ("_mps", 1e3), ("_dps", 1e4), ("_kgm2", 1e6), ("_kg", 1e5), ("_m2", 100.0), ("_hz", 1e12),
    ("_ppm", 1e6), ("_s", 1e7), ("_m", 1e5), ("_deg", 360.0), ("_db", 100.0), ("_lsb", 1e5), ("_percent", 100.0),
    ("_cpm", 1e3), ("_wavelengths", 1e3),
)
#: any other number's (counts, ratios, gains, fractions)
_LARGEST_OTHERWISE = 1e6
#: tighter bounds where a looser one still leaves nonsense the stages run on without a word (a car 1 km long)
_LARGEST_BY_NAME: dict[str, tuple[float, str]] = {
    "wheelbase_m": (20.0, "no road vehicle's"), "track_front_m": (10.0, "no road vehicle's"),
    "track_rear_m": (10.0, "no road vehicle's"), "wheel_radius_m": (3.0, "no road vehicle's"),
    "cog_height_m": (10.0, "no road vehicle's"), "steering_ratio": (100.0, "no road vehicle's"),
    "latency_s": (MAX_LATENCY_S, "a sensor whose stamps lag its values by more is on another clock"),
    "lever_arm_m": (50.0, "no sensor on a road vehicle is so far from its reference point"),
}


def _largest(name: str) -> tuple[float, str]:
    """The largest magnitude a number named ``name`` may have, and why."""
    if name in _LARGEST_BY_NAME:
        return _LARGEST_BY_NAME[name]
    unit = next(((suffix, cap) for suffix, cap in _LARGEST_BY_UNIT if name.endswith(suffix)), None)
    if unit is None:
        return _LARGEST_OTHERWISE, "beyond any setting's"
    return unit[1], f"beyond any car's, road's or sensor's in {unit[0].lstrip('_')}"


def _all_plausible(node: Any, path: str, name: str = "") -> None:
    """Every number anywhere in the config is finite (nan or inf has no meaning in any setting) and within the
    largest magnitude its unit allows (:data:`_LARGEST_BY_UNIT`)."""
    if is_dataclass(node):
        for f in fields(node):
            _all_plausible(getattr(node, f.name), _join(path, f.name), f.name)
    elif isinstance(node, dict):
        for k, v in node.items():
            _all_plausible(v, _join(path, str(k)), str(k))
    elif isinstance(node, tuple):
        for i, v in enumerate(node):
            _all_plausible(v, f"{path}[{i}]", name)
    elif isinstance(node, float) and not math.isfinite(node):
        raise ConfigError(f"{path}: must be finite, got {node!r}")
    elif isinstance(node, int | float) and not isinstance(node, bool):
        largest, why = _largest(name)
        if abs(node) > largest:
            raise ConfigError(f"{path}: {node!r} is more than {largest:g} in magnitude ({why}): a typo, or another "
                              "unit?")


def _positive(path: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0):
        raise ConfigError(f"{path}: must be a positive finite number, got {value!r}")


def _non_negative(path: str, value: float) -> None:
    if not (math.isfinite(value) and value >= 0):
        raise ConfigError(f"{path}: must be a non-negative finite number, got {value!r}")


def _clock_drift(path: str, value: float) -> None:
    # a crystal off by more than 0.1 % is a wrong frame period, not a drift
    if not (math.isfinite(value) and abs(value) <= MAX_CLOCK_DRIFT_PPM):
        raise ConfigError(f"{path}: {value!r} is not a clock drift of at most {MAX_CLOCK_DRIFT_PPM:g} ppm either way")


def _finite_vector(path: str, values: tuple[float, ...]) -> None:
    if not all(math.isfinite(v) for v in values):
        raise ConfigError(f"{path}: every component must be finite, got {list(values)!r}")


def _latencies_in_ms(sensors: dict[str, SensorConfig]) -> None:
    """Refuse a sensor's latency of :data:`LATENCY_IN_MS_S` or more (checked before the bounds of every number, whose
    latency bound, 2 s, lets 1 or 2 through and says nothing of ms above it)."""
    for name, s in sensors.items():
        if math.isfinite(s.latency_s) and s.latency_s >= LATENCY_IN_MS_S:
            raise ConfigError(f"sensors.{name}.latency_s: {s.latency_s:g} s is no sensor's latency (its stamps that "
                              f"long after the instant its values refer to; under {LATENCY_IN_MS_S:g} s): in ms? If "
                              f"you meant {s.latency_s:g} ms write {s.latency_s / 1000:g}")


def _validate(cfg: Config) -> None:
    _latencies_in_ms(cfg.sensors)
    _all_plausible(cfg, "")
    v = cfg.vehicle
    for name in ("wheelbase_m", "track_front_m", "track_rear_m", "steering_ratio", "wheel_radius_m"):
        _positive(f"vehicle.{name}", getattr(v, name))
    if v.steering_ratio < 1.0:  # the road wheels turning further than the steering wheel: the ratio inverted
        raise ConfigError(f"vehicle.steering_ratio: {v.steering_ratio:g} turns the road wheels "
                          f"{1 / v.steering_ratio:.3g} times as far as the steering wheel, which no car's do (it is "
                          f"the steering wheel's angle over the road wheels', 10-25 on cars): inverted"
                          + (f", {1 / v.steering_ratio:.3g}?" if 5.0 <= 1 / v.steering_ratio <= 30.0 else "?"))
    _non_negative("vehicle.cog_height_m", v.cog_height_m)
    if not 0.0 <= v.roll_axis_height_m <= max(v.cog_height_m, 0.0):
        raise ConfigError(f"vehicle.roll_axis_height_m: must lie between the road (0) and the CoG "
                          f"({v.cog_height_m} m), got {v.roll_axis_height_m}")
    if not 0.0 <= v.cog_to_rear_axle_m <= v.wheelbase_m:
        raise ConfigError(
            f"vehicle.cog_to_rear_axle_m: must lie between 0 and the wheelbase ({v.wheelbase_m} m), "
            f"got {v.cog_to_rear_axle_m}"
        )

    r = cfg.radar
    for name in ("start_frequency_hz", "bandwidth_hz", "slope_hz_per_s", "sample_rate_hz", "prf_hz",
                 "chirp_period_s", "max_range_m", "beamwidth_az_deg", "beamwidth_el_deg"):
        _positive(f"radar.{name}", getattr(r, name))
    if not MIN_CARRIER_HZ <= r.start_frequency_hz <= MAX_CARRIER_HZ:
        f0 = r.start_frequency_hz
        raise ConfigError(f"radar.start_frequency_hz: {f0:g} Hz is no FMCW radar's carrier ({MIN_CARRIER_HZ / 1e9:g}-"
                          f"{MAX_CARRIER_HZ / 1e9:g} GHz)" + (f": in GHz? {f0:g} GHz is {f0 * 1e9:g} Hz"
                                                              if MIN_CARRIER_HZ <= f0 * 1e9 <= MAX_CARRIER_HZ else ""))
    for name in ("num_samples", "num_tx", "num_rx"):
        if getattr(r, name) < 1:
            raise ConfigError(f"radar.{name}: must be at least 1, got {getattr(r, name)}")
    swept = r.slope_hz_per_s * r.num_samples / r.sample_rate_hz
    if abs(swept - r.bandwidth_hz) > 1e-6 * r.bandwidth_hz:
        raise ConfigError(
            f"{_chirp_units_slipped(r)}radar.bandwidth_hz: slope x ADC window = {swept:.6g} Hz differs from "
            f"bandwidth_hz = "
            f"{r.bandwidth_hz:.6g} Hz (slope_hz_per_s * num_samples / sample_rate_hz must equal it)"
        )
    r_max = r.sample_rate_hz * SPEED_OF_LIGHT / (2.0 * r.slope_hz_per_s)
    if r.max_range_m > r_max * 1.001:
        raise ConfigError(
            f"radar.max_range_m: {r.max_range_m} m exceeds the unambiguous range fs*c/(2K) = {r_max:.3f} m"
        )
    if r.chirp_period_s < r.chirp_duration_s:
        raise ConfigError(
            f"{_chirp_units_slipped(r)}radar.chirp_period_s: {r.chirp_period_s} s is shorter than the ADC window "
            f"{r.chirp_duration_s} s"
        )
    if r.num_tx * r.chirp_period_s > 1.0 / r.prf_hz:
        raise ConfigError(f"radar.prf_hz: {r.num_tx} chirps of {r.chirp_period_s} s do not fit in one PRI")
    if not (math.isfinite(r.clock_offset_s) and abs(r.clock_offset_s) <= 1.0):
        raise ConfigError(f"radar.clock_offset_s: {r.clock_offset_s} is not a time offset of at most 1 s either way")
    _clock_drift("radar.clock_drift_ppm", r.clock_drift_ppm)
    for kind, count in (("tx", r.num_tx), ("rx", r.num_rx)):
        _channels(kind, count, getattr(r, f"{kind}_channels"), len(getattr(r, f"{kind}_positions_wavelengths")))
    for i, p in enumerate(r.tx_positions_wavelengths):
        _finite_vector(f"radar.tx_positions_wavelengths[{i}]", p)
    for i, p in enumerate(r.rx_positions_wavelengths):
        _finite_vector(f"radar.rx_positions_wavelengths[{i}]", p)
    m = r.mounting
    _finite_vector("radar.mounting.lever_arm_m", m.lever_arm_m)
    for name in ("yaw_deg", "pitch_deg", "roll_deg"):
        _finite_vector(f"radar.mounting.{name}", (getattr(m, name),))
    _looks_sideways(m, min(v.track_front_m, v.track_rear_m))

    if cfg.can.checksum not in ("fca_giorgio", "none"):
        raise ConfigError(f"can.checksum: expected 'fca_giorgio' or 'none', got {cfg.can.checksum!r}")
    for role, ref in cfg.can.roles.items():
        message, dot, signal = ref.partition(".")
        if not dot or not message or not signal:
            raise ConfigError(f"can.roles.{role}: expected 'MESSAGE.SIGNAL', got {ref!r}")
        _known_role(role, cfg.sensors)

    for name, s in cfg.sensors.items():
        base = f"sensors.{name}"
        _positive(f"{base}.rate_hz", s.rate_hz)
        if s.kind in ("imu", "can_imu") and s.rate_hz < MIN_GYRO_RATE_HZ:
            raise ConfigError(f"{base}.rate_hz: {s.rate_hz:g} Hz is no gyro's (its yaw rate's noise per sample is "
                              f"noise_density_dps_rthz x sqrt(rate_hz)): a period in s ({s.rate_hz:g} s is "
                              f"{1 / s.rate_hz:.4g} Hz), or kHz?")
        _non_negative(f"{base}.latency_s", s.latency_s)
        _finite_vector(f"{base}.lever_arm_m", s.lever_arm_m)
        for sub in REQUIRED_ERROR_TABLES[s.kind]:
            if getattr(s, sub) is None:
                raise ConfigError(f"{base}.{sub}: a {s.kind} sensor needs this error-model table")
        # a gnss sensor without topics is an NMEA text capture, which ingest names by its file
        if s.kind == "imu" and not s.topic:
            raise ConfigError(f"{base}.topic: an imu sensor needs a topic")
        if s.kind == "imu" and s.dof not in (3, 6):
            raise ConfigError(f"{base}.dof: must be 3 or 6, got {s.dof}")
        _finite_vector(f"{base}.mounting_ypr_deg", s.mounting_ypr_deg)
        if s.kind == "imu" and s.dof == 3 and any(s.mounting_ypr_deg[1:]):
            raise ConfigError(f"{base}.mounting_ypr_deg: a 3-DoF IMU measures the yaw rate alone, which a pitch or "
                              f"roll of its mounting would mix with axes it does not have")
        for sub in ("gyro", "accel", "wheel", "steering", "gnss"):
            errors = getattr(s, sub)
            if errors is not None:
                for f in fields(errors):
                    if f.name not in ("outages", "multipath"):
                        _non_negative(f"{base}.{sub}.{f.name}", getattr(errors, f.name))
                if hasattr(errors, "bias_tau_s"):  # a bias's correlation time divides its random walk
                    _positive(f"{base}.{sub}.bias_tau_s", errors.bias_tau_s)
        if s.gnss is not None:
            for what, spans in (("outages", s.gnss.outages), ("multipath", s.gnss.multipath)):
                for i, span in enumerate(spans):
                    where = f"{base}.gnss.{what}[{i}]"
                    _finite_vector(where, span)
                    if not (span[0] >= 0 and span[1] > 0):
                        raise ConfigError(f"{where}: needs a start >= 0 s and a duration > 0 s, got {list(span)!r}")

    nav = cfg.navigation
    for name in ("speed_noise_mps2", "yaw_rate_noise_radps2", "gnss_position_std_m", "max_step_s"):
        _positive(f"navigation.{name}", getattr(nav, name))
    if not 1e-3 <= nav.max_step_s <= 1.0:  # shorter: millions of steps between two measurements
        raise ConfigError(f"navigation.max_step_s: must lie in [0.001, 1] s, got {nav.max_step_s!r}")
    _non_negative("navigation.position_noise_m", nav.position_noise_m)
    _non_negative("navigation.steering_min_speed_mps", nav.steering_min_speed_mps)
    _non_negative("navigation.standstill_yaw_rate_std_dps", nav.standstill_yaw_rate_std_dps)
    _non_negative("navigation.understeer_max_std_rad_per_mps2", nav.understeer_max_std_rad_per_mps2)
    _non_negative("navigation.wheel_lag_max_std_m", nav.wheel_lag_max_std_m)
    _non_negative("navigation.wheel_radius_gain_max_std_per_mps2", nav.wheel_radius_gain_max_std_per_mps2)
    _non_negative("navigation.rear_slip_max_std_rad_per_mps2", nav.rear_slip_max_std_rad_per_mps2)
    _non_negative("navigation.gnss_latency_max_std_s", nav.gnss_latency_max_std_s)
    _non_negative("navigation.can_latency_max_std_s", nav.can_latency_max_std_s)
    _positive("navigation.gnss_heading_offset_std_deg", nav.gnss_heading_offset_std_deg)
    for i, gyro in enumerate(nav.gyros):
        if gyro in nav.gyros[:i]:  # each one its own bias state: the same samples fused as independent gyros
            raise ConfigError(f"navigation.gyros: {gyro!r} listed {nav.gyros.count(gyro)} times")
        s = cfg.sensors.get(gyro)
        if s is None or s.kind not in ("imu", "can_imu"):
            theirs = sorted(n for n, t in cfg.sensors.items() if t.kind in ("imu", "can_imu"))
            what = "no sensor of [sensors]" if s is None else f"a {s.kind} sensor, which has no gyro"
            raise ConfigError(f"navigation.gyros: {gyro!r} is {what}{_suggestion(gyro, theirs)}; the config's imu "
                              f"and can_imu sensors: {', '.join(theirs) or 'none'}")
    if nav.attitude_imu:
        imu = cfg.sensors.get(nav.attitude_imu)
        if imu is None or imu.kind != "imu" or imu.dof != 6:
            raise ConfigError(f"navigation.attitude_imu: {nav.attitude_imu!r} is not a 6-DoF IMU of [sensors]")
    if not 0.0 < nav.gate_probability < 1.0:
        raise ConfigError(f"navigation.gate_probability: must lie strictly between 0 and 1, got "
                          f"{nav.gate_probability!r}")

    p = cfg.processing
    _positive("processing.pixel_m", p.pixel_m)
    _positive("processing.cross_range_resolution_m", p.cross_range_resolution_m)
    if p.cross_range_resolution_m > MAX_CROSS_RANGE_RESOLUTION_M:
        raise ConfigError(f"processing.cross_range_resolution_m: {p.cross_range_resolution_m!r} m is coarser than "
                          f"{MAX_CROSS_RANGE_RESOLUTION_M:g} m: its beam would hold a pulse or two, no SAR image")
    finest = cfg.radar.wavelength_m / (4 * math.radians(cfg.radar.beamwidth_az_deg / 2))
    if p.cross_range_resolution_m < finest:
        raise ConfigError(f"processing.cross_range_resolution_m: {p.cross_range_resolution_m!r} m asks for a wider "
                          f"beam than the antenna's (radar.beamwidth_az_deg): the finest it holds is {finest:.3g} m")
    _finite_vector("processing.focus_height_m", (p.focus_height_m,))
    if abs(p.focus_height_m) > MAX_FOCUS_HEIGHT_M:
        raise ConfigError(f"processing.focus_height_m: {p.focus_height_m:g} m from the road is no plane a car's radar "
                          f"images (at most {MAX_FOCUS_HEIGHT_M:g} m): in mm? {p.focus_height_m:g} mm is "
                          f"{p.focus_height_m / 1000:g} m")
    if not 1 <= p.range_upsample <= MAX_RANGE_UPSAMPLE:  # beyond, the range profiles alone fill the memory
        raise ConfigError(f"processing.range_upsample: must lie in [1, {MAX_RANGE_UPSAMPLE}], got {p.range_upsample}")
    if not 0.0 < p.autofocus_pass_block_s <= 1.0:  # a block no longer than the slow motion's 1 s nodes
        raise ConfigError(f"processing.autofocus_pass_block_s: must lie in (0, 1] s, got {p.autofocus_pass_block_s!r}")

    dyn = cfg.vehicle_dynamics
    for name in ("mass_kg", "yaw_inertia_kgm2", "cornering_stiffness_front_n_per_rad",
                 "cornering_stiffness_rear_n_per_rad", "friction_coefficient", "slip_stiffness_per_load",
                 "heave_frequency_hz", "pitch_frequency_hz", "roll_frequency_hz", "heave_damping_ratio",
                 "pitch_damping_ratio", "roll_damping_ratio", "tyre_vertical_stiffness_n_per_m", "tone_ring_teeth",
                 "edges_per_speed_estimate", "wheel_speed_timeout_s", "road_grade_wavelength_m",
                 "road_max_frequency_cpm"):
        _positive(f"vehicle_dynamics.{name}", getattr(dyn, name))
    for name in ("rolling_resistance", "drag_area_m2", "roll_gradient_deg_per_g", "pitch_gradient_deg_per_g",
                 "roll_centre_height_m", "rolling_radius_deflection_fraction", "rolling_radius_speed_growth_per_mps2",
                 "driver_preview_s", "driver_lateral_gain", "driver_heading_gain", "tooth_pitch_error_std",
                 "road_coherence_decay"):
        _non_negative(f"vehicle_dynamics.{name}", getattr(dyn, name))
    _finite_vector("vehicle_dynamics.imu_misalignment_deg", dyn.imu_misalignment_deg)
    if min(dyn.imu_misalignment_deg) < 0:
        raise ConfigError(f"vehicle_dynamics.imu_misalignment_deg: magnitudes are not negative, got "
                          f"{list(dyn.imu_misalignment_deg)}")
    for name in ("brake_front_fraction", "drive_front_fraction"):
        if not 0.0 <= getattr(dyn, name) <= 1.0:
            raise ConfigError(f"vehicle_dynamics.{name}: must lie between 0 and 1 (the front axle's share), got "
                              f"{getattr(dyn, name)!r}")

    sim = cfg.simulation
    if sim is not None:
        if not -90.0 <= sim.origin_lat_deg <= 90.0:
            raise ConfigError(f"simulation.origin_lat_deg: {sim.origin_lat_deg} is not a latitude")
        if not -180.0 <= sim.origin_lon_deg <= 180.0:
            raise ConfigError(f"simulation.origin_lon_deg: {sim.origin_lon_deg} is not a longitude")
        _positive("simulation.truth_rate_hz", sim.truth_rate_hz)
        _non_negative("simulation.radar_noise_std_lsb", sim.radar_noise_std_lsb)
        _positive("simulation.radar_amplitude_lsb", sim.radar_amplitude_lsb)
        _non_negative("simulation.vibration_vertical_rms_m", sim.vibration_vertical_rms_m)
        _non_negative("simulation.vibration_horizontal_rms_m", sim.vibration_horizontal_rms_m)
        _non_negative("simulation.channel_phase_std_deg", sim.channel_phase_std_deg)
        _non_negative("simulation.channel_gain_std_db", sim.channel_gain_std_db)
        if not (math.isfinite(sim.radar_clock_offset_s) and abs(sim.radar_clock_offset_s) <= 1.0):
            raise ConfigError(f"simulation.radar_clock_offset_s: {sim.radar_clock_offset_s} is not a time offset of at "
                              "most 1 s either way")
        _clock_drift("simulation.radar_clock_drift_ppm", sim.radar_clock_drift_ppm)
        if not (math.isfinite(sim.road_reflection) and abs(sim.road_reflection) < 1.0):
            raise ConfigError(f"simulation.road_reflection: {sim.road_reflection} is not a reflection coefficient "
                              "(-1 < Gamma < 1)")
        for i, rider in enumerate(sim.cyclists):
            _finite_vector(f"simulation.cyclists[{i}]", rider)
        lo, hi = sim.vibration_band_hz
        if not 0 < lo < hi:
            raise ConfigError(f"simulation.vibration_band_hz: need 0 < low < high, got {[lo, hi]}")
        try:
            from datetime import datetime

            datetime.fromisoformat(sim.start_time_utc.replace("Z", "+00:00"))
        except ValueError:
            raise ConfigError(f"simulation.start_time_utc: not an ISO 8601 time: {sim.start_time_utc!r}") from None
