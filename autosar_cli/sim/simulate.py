"""``autosar simulate``: a complete synthetic drive log (+ ground-truth sidecar) for a scenario.

Navigation sensors are generated for the whole drive up front (small); radar frames are synthesised in
blocks and merged into the log in log-time order, so memory stays bounded by one block of the radar
cube whatever the drive length. Everything random comes from generators seeded by (seed, stream name):
the same seed gives byte-identical files.
"""

from __future__ import annotations

import contextlib
import heapq
import time
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from datetime import datetime
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from autosar_cli import __version__, msgs
from autosar_cli.candb import load_dbc
from autosar_cli.config import Config, load_config
from autosar_cli.ingest.dca1000 import CaptureWriter, params_from_radar
from autosar_cli.interrupts import interrupts_held
from autosar_cli.nav.frames import mounting_rotation, rot_z
from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.sim import sensors as sensor_models
from autosar_cli.sim.dynamics import FullMotion, full_motion
from autosar_cli.sim.echo import synthesize_beat
from autosar_cli.sim.logwriter import open_log_writer
from autosar_cli.sim.messages import MessageFactory, can_topic, sensor_topics
from autosar_cli.sim.scenario import Scenario, build_scenario
from autosar_cli.sim.scene import Scene
from autosar_cli.sim.trajectory import TruthMotion
from autosar_cli.sim.truth import TruthWriter, truth_path_for
from autosar_cli.store.drive import frame_crc32

LogFormat = Literal["mcap", "ros1", "ros2", "dca1000"]
RADAR_SYNC_TOPIC = "/dca1000/sync"  #: dca1000 format: std_msgs/Header stamped at each frame's start
Dynamics = Literal["kinematic", "full"]
Motion = TruthMotion | FullMotion
RADAR_BLOCK_FRAMES = 128
RADAR_TRANSFER_DELAY_NS = 1_500_000  # frame leaves the radar after its last chirp, over Ethernet

ProgressCallback = Callable[[int, int], None]


@dataclass
class SimulationResult:
    log_path: Path
    truth_path: Path
    scenario: str
    seed: int
    format: str
    duration_s: float
    radar_frames: int
    message_counts: dict[str, int] = field(default_factory=dict)
    elapsed_s: float = 0.0
    radar_capture: Path | None = None  #: dca1000 format: the capture directory beside the navigation log


def capture_dir_for(log_path: Path) -> Path:
    """Where ``--format dca1000`` writes the radar capture of ``log_path`` (the navigation MCAP)."""
    return log_path.with_name(log_path.stem + ".dca1000")


def stream_rng(seed: int, stream: str) -> np.random.Generator:
    """Independent generator per named stream, so adding a sensor does not change the others."""
    return np.random.default_rng([seed, zlib.crc32(stream.encode())])


def channel_errors(rng: np.random.Generator, num_tx: int, num_rx: int, phase_std_deg: float, gain_std_db: float
                   ) -> NDArray[np.complex64]:
    """The complex gain (num_tx, num_rx) an uncalibrated front end puts on each virtual channel: each Tx's and each
    Rx's path its own phase (normal, ``phase_std_deg``) and gain (normal, ``gain_std_db``), the channel their sum.
    Drawn in one order whatever the stds, so a drive's other samples do not move with them."""
    phase = np.radians(phase_std_deg) * rng.standard_normal(num_tx + num_rx)
    gain_db = gain_std_db * rng.standard_normal(num_tx + num_rx)
    path = 10 ** (gain_db / 20) * np.exp(1j * phase)
    return (path[:num_tx, None] * path[None, num_tx:]).astype(np.complex64)


def start_time_ns(config: Config) -> int:
    assert config.simulation is not None
    dt = datetime.fromisoformat(config.simulation.start_time_utc.replace("Z", "+00:00"))
    return int(round(dt.timestamp())) * 1_000_000_000 + dt.microsecond * 1000


@dataclass(frozen=True)
class RadarGeometry:
    """Antenna lever arms in the body frame (m) and the radar->body rotation."""

    mount_lever_arm: NDArray[np.float64]  # (3,)
    radar_to_body: NDArray[np.float64]  # (3, 3)
    tx_lever_arms: NDArray[np.float64]  # (T, 3)
    rx_lever_arms: NDArray[np.float64]  # (R, 3)

    @classmethod
    def from_config(cls, config: Config) -> RadarGeometry:
        r = config.radar
        rot = mounting_rotation(r.mounting.yaw_deg, r.mounting.pitch_deg, r.mounting.roll_deg)
        lever = np.asarray(r.mounting.lever_arm_m, dtype=np.float64)
        tx = lever + np.asarray(r.tx_positions_m) @ rot.T
        rx = lever + np.asarray(r.rx_positions_m) @ rot.T
        return cls(lever, rot, tx, rx)


class Vibration:
    """Radar-case vibration no sensor sees: a sum of random sinusoids per body axis (x, y, z), band-limited."""

    def __init__(self, rng: np.random.Generator, horizontal_rms: float, vertical_rms: float,
                 band_hz: tuple[float, float], components: int = 24) -> None:
        self.freq = rng.uniform(band_hz[0], band_hz[1], (3, components))
        self.phase = rng.uniform(0.0, 2 * np.pi, (3, components))
        rms = np.array([horizontal_rms, horizontal_rms, vertical_rms])
        self.amp = (rms * np.sqrt(2.0 / components))[:, None] * np.ones((3, components))

    def body(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Displacement in body axes (..., 3) m at times t (...)."""
        t = np.asarray(t, dtype=np.float64)
        arg = 2 * np.pi * t[..., None, None] * self.freq + self.phase
        return np.sum(self.amp * np.sin(arg), axis=-1)

    def enu(self, t: NDArray[np.float64], heading: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.einsum("...ij,...j->...i", rot_z(heading), self.body(t))


def body_to_enu(motion: Motion, t: NDArray[np.float64]) -> NDArray[np.float64]:
    """Body-to-ENU rotations (N, 3, 3): heading only on the kinematic model, full attitude on the full one."""
    if isinstance(motion, FullMotion):
        return motion.body_to_enu(t)
    return rot_z(motion.states(t)["heading"])


def vibration_enu(motion: Motion, vib: Vibration, t: NDArray[np.float64]) -> NDArray[np.float64]:
    """The radar vibration (N, 3) m in ENU, rotated with the body."""
    if isinstance(motion, FullMotion):
        return np.einsum("nij,nj->ni", motion.body_to_enu(t), vib.body(t))
    return vib.enu(t, motion.states(t)["heading"])


def antenna_positions(motion: Motion, geom: RadarGeometry, vib: Vibration, t: NDArray[np.float64],
                      lever_arms: NDArray[np.float64]) -> NDArray[np.float64]:
    """ENU positions (len(t), len(lever_arms), 3) of body points at times t, with the radar vibration."""
    nt, na = t.size, len(lever_arms)
    tt = np.repeat(t, na)
    pos = motion.point(tt, np.tile(lever_arms, (nt, 1))).position.reshape(nt, na, 3)
    return pos + vibration_enu(motion, vib, t)[:, None, :]


def radar_block(motion: Motion, config: Config, geom: RadarGeometry, vib: Vibration,
                t_frames: NDArray[np.float64], clock_rate: float = 1.0) -> dict[str, NDArray[np.float64]]:
    """Antenna positions at chirp start and ADC end for frames starting at t_frames (s), the chirps timed by a
    crystal ``clock_rate`` times its nominal frequency."""
    r = config.radar
    offsets = np.asarray(r.tx_start_offsets_s) / clock_rate
    t_win = r.chirp_duration_s / clock_rate
    F, T, R = t_frames.size, r.num_tx, r.num_rx
    out: dict[str, NDArray[np.float64]] = {}
    for tag, extra in (("start", 0.0), ("end", t_win)):
        tx = np.empty((F, T, 3))
        rx = np.empty((F, T, R, 3))
        for k in range(T):
            tc = t_frames + offsets[k] + extra
            tx[:, k] = antenna_positions(motion, geom, vib, tc, geom.tx_lever_arms[k : k + 1])[:, 0]
            rx[:, k] = antenna_positions(motion, geom, vib, tc, geom.rx_lever_arms)
        out[f"tx_{tag}"], out[f"rx_{tag}"] = tx, rx
    out["origin"] = antenna_positions(motion, geom, vib, t_frames, geom.mount_lever_arm[None, :])[:, 0]
    out["enu_to_radar"] = np.swapaxes(body_to_enu(motion, t_frames) @ geom.radar_to_body, -1, -2)
    out["vibration"] = vibration_enu(motion, vib, t_frames)
    return out


def on_road(scene: Scene, motion: FullMotion) -> Scene:
    """The scene lifted onto the road's grade: each scatterer by the centre-line height at its nearest path point."""
    from scipy.spatial import cKDTree

    s_path = np.arange(-5.0, motion.reference.path_length_m + 30.0, 0.1)
    xy = motion.reference.path(s_path)[0]
    _, nearest = cKDTree(xy).query(scene.position[:, :2])
    pos = scene.position.copy()
    lift = motion.road.grade_height(s_path[nearest])
    pos[:, 2] += lift
    return replace(scene, position=pos, road_height=lift)


def _sensor_samples(motion: Motion, config: Config, seed: int) -> list[sensor_models.SensorSamples]:
    out = []
    for name, s in config.sensors.items():
        rng = stream_rng(seed, f"sensor/{name}")
        if s.kind == "imu":
            out.append(sensor_models.imu(motion, name, s, rng))
        elif s.kind == "can_imu":
            out.append(sensor_models.can_imu(motion, name, s, rng))
        elif s.kind == "wheel_speeds":
            out.append(sensor_models.wheel_speeds(motion, config, name, s, rng))
        elif s.kind == "steering":
            out.append(sensor_models.steering(motion, config, name, s, rng))
        elif s.kind == "gnss":
            out.append(sensor_models.gnss(motion, name, s, rng))
    return out


def simulate(
    scenario_name: str,
    output: Path,
    *,
    fmt: LogFormat = "mcap",
    seed: int = 0,
    config: Config | None = None,
    progress: ProgressCallback | None = None,
    scene: Scene | None = None,
    dynamics: Dynamics | None = None,
    overwrite: bool = False,
) -> SimulationResult:
    """Write a synthetic drive log for ``scenario_name`` to ``output`` and its truth sidecar next to it.

    ``fmt`` "dca1000": ``output`` is an MCAP of the navigation sensors plus a frame-trigger topic
    (:data:`RADAR_SYNC_TOPIC`), and the radar frames go to a TI DCA1000 capture (4-lane complex, mmWave
    Studio JSON) in :func:`capture_dir_for` ``(output)``; the same seed gives the same samples as the
    RawFrame log.

    ``scene``: scatterers to use instead of the scenario's (e.g. one point target, or none, for radiometry tests).

    ``dynamics``: "kinematic" or "full" vehicle model; None takes the config's simulation.dynamics.

    ``overwrite``: replace an existing log file at ``output`` once the new one is complete (the caller has
    checked that autosar wrote it; a rosbag2 directory the caller removes).
    """
    t_start = time.perf_counter()
    config = config or load_config()
    if config.simulation is None:
        raise ValueError(f"{config.source}: has no [simulation] table; autosar simulate needs one")
    sim = config.simulation
    scenario: Scenario = build_scenario(scenario_name, config)
    if scene is not None:
        scenario = replace(scenario, scene=scene)
    dynamics = dynamics or sim.dynamics
    motion: Motion = scenario.motion
    if dynamics == "full":
        motion = full_motion(scenario.name, scenario.motion, scenario.road, config.vehicle,
                             config.vehicle_dynamics, sim.truth_rate_hz)
        scenario = replace(scenario, scene=on_road(scenario.scene, motion))
    elif dynamics != "kinematic":
        raise ValueError(f"unknown vehicle dynamics {dynamics!r}; choose kinematic or full")
    ros_version = 1 if fmt == "ros1" else 2
    capture_dir = capture_dir_for(Path(output)) if fmt == "dca1000" else None
    typestore = msgs.typestore_for(ros_version)
    origin = GeodeticOrigin(sim.origin_lat_deg, sim.origin_lon_deg, sim.origin_height_m)
    t0_ns = start_time_ns(config)
    factory = MessageFactory(typestore, ros_version, t0_ns, origin)
    db, _ = load_dbc(config.dbc_path)
    output = Path(output)
    truth_path = truth_path_for(output)
    radar = config.radar

    # --- navigation sensors: whole drive, merged by log time
    samples = _sensor_samples(motion, config, seed)
    nav_streams = []
    for smp in samples:
        s = config.sensors[smp.name]
        if s.kind in ("wheel_speeds", "steering", "can_imu"):
            nav_streams.append(factory.can_frames(smp, config, db, can_topic(ros_version)))
        elif s.kind == "imu":
            nav_streams.append(factory.imu(smp, s))
        else:
            nav_streams.append(factory.gnss(smp, s))
    nav_messages = list(heapq.merge(*[list(st) for st in nav_streams], key=lambda m: m[0]))

    # --- radar frame schedule
    t_needed = (radar.num_tx - 1) * radar.chirp_period_s + radar.chirp_duration_s
    # the radar's frame timer runs on its own clock: a frame period on it is 1 / (1 + drift) of one in truth
    clock_rate = 1.0 + sim.radar_clock_drift_ppm * 1e-6
    n_frames = int(np.floor((motion.duration_s - t_needed) * radar.prf_hz * clock_rate)) + 1
    geom = RadarGeometry.from_config(config)
    vib = Vibration(stream_rng(seed, "radar/vibration"), sim.vibration_horizontal_rms_m,
                    sim.vibration_vertical_rms_m, sim.vibration_band_hz)
    noise_rng = stream_rng(seed, "radar/noise")
    channel_gain = channel_errors(stream_rng(seed, "radar/channels"), radar.num_tx, radar.num_rx,
                                  sim.channel_phase_std_deg, sim.channel_gain_std_db)

    attrs = {
        "scenario": scenario.name, "description": scenario.description, "seed": seed,
        "autosar_version": __version__, "origin_lat_deg": origin.lat_deg, "origin_lon_deg": origin.lon_deg,
        "origin_height_m": origin.height_m, "start_time_ns": t0_ns, "duration_s": motion.duration_s,
        "config_toml": config.text(),
        "log_format": fmt, "log_file": output.name,
        # the front end's channel mismatch the samples carry (tx, rx): 0 deg, 0 dB where matched
        "channel_phase_deg": np.degrees(np.angle(channel_gain)), "channel_gain_db": 20 * np.log10(np.abs(channel_gain)),
        # /radar's times are the frames' stamps: the instants they started plus this
        "radar_clock_offset_s": sim.radar_clock_offset_s,
        # and that clock counts 1 + this * 1e-6 s per true second from the first frame on (store.drive's
        # stamps_on_navigation_clock takes them back)
        "radar_clock_drift_ppm": sim.radar_clock_drift_ppm,
        "road_reflection": sim.road_reflection,
    }
    if dynamics == "full":
        attrs["dynamics"] = dynamics
    counts: dict[str, int] = {}
    truth = TruthWriter(truth_path, attrs, radar.num_tx, radar.num_rx)  # removes its partial if interrupted
    try:
        _write_truth_static(truth, scenario, motion, config, geom, samples, t0_ns)
        with open_log_writer(output, "mcap" if capture_dir else fmt, replace=overwrite) as writer, \
                contextlib.ExitStack() as stack:
            topics: dict[str, str] = {RADAR_SYNC_TOPIC: msgs.HEADER} if capture_dir else {radar.topic: msgs.RAW_FRAME}
            capture = stack.enter_context(CaptureWriter(
                capture_dir, params_from_radar(radar, num_frames=n_frames), param_format="json")) \
                if capture_dir else None
            for s in config.sensors.values():
                for tp in sensor_topics(s, ros_version):
                    topics.setdefault(tp.name, tp.msgtype)
            for topic in sorted(topics):
                writer.add_topic(topic, topics[topic])
            RawFrame = typestore.types[msgs.RAW_FRAME]
            offsets = np.asarray(radar.tx_start_offsets_s, dtype=np.float64)
            nav_i = 0
            for b0 in range(0, n_frames, RADAR_BLOCK_FRAMES):
                idx = np.arange(b0, min(b0 + RADAR_BLOCK_FRAMES, n_frames))
                t_frames = idx / (radar.prf_hz * clock_rate)
                geo = radar_block(motion, config, geom, vib, t_frames, clock_rate)
                beat = synthesize_beat(
                    geo["tx_start"], geo["tx_end"], geo["rx_start"], geo["rx_end"], geo["origin"],
                    geo["enu_to_radar"], scenario.scene.position, scenario.scene.rcs_m2,
                    # the ramp and the ADC run on the crystal too (store.drive.chirp_on_navigation_clock)
                    start_frequency_hz=radar.start_frequency_hz * clock_rate,
                    slope_hz_per_s=radar.slope_hz_per_s * clock_rate**2,
                    sample_rate_hz=radar.sample_rate_hz * clock_rate, num_samples=radar.num_samples,
                    amplitude_lsb=sim.radar_amplitude_lsb, beamwidth_az_deg=radar.beamwidth_az_deg,
                    beamwidth_el_deg=radar.beamwidth_el_deg, target_velocity=scenario.scene.velocity_enu,
                    chirp_start_s=t_frames[:, None] + offsets[None, :] / clock_rate,
                    road_reflection=sim.road_reflection, road_height=scenario.scene.road_height,
                    retroreflector=scenario.scene.retroreflector,
                )
                if sim.channel_phase_std_deg or sim.channel_gain_std_db:
                    beat *= channel_gain[None, :, :, None]
                iq = beat.view(np.float32).reshape(*beat.shape, 2)
                iq += noise_rng.standard_normal(iq.shape, dtype=np.float32) * np.float32(sim.radar_noise_std_lsb)
                raw = np.clip(np.rint(iq), -32768, 32767).astype(np.int16)
                # the frames as the drive stamps them: on the radar's clock, a frame period apart from
                # sim.radar_clock_offset_s late on
                t_counted = idx / radar.prf_hz
                stamps = t0_ns + np.round((t_counted + sim.radar_clock_offset_s) * 1e9).astype(np.int64)
                if capture is not None:
                    capture.write(raw)
                # the logger takes each frame in on its own clock, the navigation's: the true start plus the transfer
                received = t0_ns + np.round(t_frames * 1e9).astype(np.int64) + RADAR_TRANSFER_DELAY_NS
                for j, fi in enumerate(idx):
                    log_ns = int(received[j])
                    while nav_i < len(nav_messages) and nav_messages[nav_i][0] <= log_ns:
                        lt, topic, m = nav_messages[nav_i]
                        writer.write(topic, lt, m)
                        counts[topic] = counts.get(topic, 0) + 1
                        nav_i += 1
                    if capture is not None:
                        writer.write(RADAR_SYNC_TOPIC, log_ns, factory.header(int(stamps[j]), "dca1000"))
                        continue
                    msg = RawFrame(
                        header=factory.header(int(stamps[j]), "scanbrick"), frame_index=int(fi),
                        start_frequency_hz=radar.start_frequency_hz, slope_hz_per_s=radar.slope_hz_per_s,
                        sample_rate_hz=radar.sample_rate_hz, tx_start_offsets_s=offsets,
                        num_tx=radar.num_tx, num_rx=radar.num_rx, num_samples=radar.num_samples,
                        data=raw[j].reshape(-1),
                    )
                    writer.write(radar.topic, log_ns, msg)
                frame_topic = RADAR_SYNC_TOPIC if capture else radar.topic
                counts[frame_topic] = counts.get(frame_topic, 0) + len(idx)
                truth.append_radar({
                    "frame_index": idx, "t_ns": stamps,
                    "chirp_t_ns": t0_ns + np.round((t_counted[:, None] + offsets[None, :]
                                                      + sim.radar_clock_offset_s) * 1e9).astype(np.int64),
                    "tx_position_enu": geo["tx_start"], "rx_position_enu": geo["rx_start"],
                    "phase_centre_enu": 0.5 * (geo["tx_start"][:, :, None, :] + geo["rx_start"]),
                    "vibration_enu": geo["vibration"],
                    # each frame's samples as the drive will hold them: evaluation tells this drive's truth by them
                    "raw_crc32": np.array([frame_crc32(frame) for frame in raw], np.uint32),
                })
                if progress is not None:
                    progress(int(idx[-1]) + 1, n_frames)
            for lt, topic, m in nav_messages[nav_i:]:
                writer.write(topic, lt, m)
                counts[topic] = counts.get(topic, 0) + 1
            truth.finish()
            with interrupts_held():  # the log, its capture and its truth come into place together: a log stopped
                stack.close()        # between them was whole beside no truth, or a former drive's
                writer.close()
                truth.publish()
    except BaseException:
        truth.abort()
        raise
    return SimulationResult(output, truth_path, scenario.name, seed, fmt, motion.duration_s, n_frames, counts,
                            time.perf_counter() - t_start, capture_dir)


def _write_truth_static(truth: TruthWriter, scenario: Scenario, motion: Motion, config: Config,
                        geom: RadarGeometry, samples: list[sensor_models.SensorSamples], t0_ns: int) -> None:
    assert config.simulation is not None
    t = np.arange(0.0, motion.duration_s, 1.0 / config.simulation.truth_rate_hz)
    st = motion.states(t)
    truth.write_trajectory({
        "t_ns": t0_ns + np.round(t * 1e9).astype(np.int64),
        "position_enu": motion.point(t, np.zeros(3)).position,
        "rear_axle_enu": st["position"],
        "heading": st["heading"], "speed": st["speed"], "yaw_rate": st["yaw_rate"], "accel": st["accel"],
        "curvature": st["curvature"],
        "road_wheel_angle": motion.road_wheel_angle(t, config.vehicle.wheelbase_m),
        "radar_origin_enu": motion.point(t, geom.mount_lever_arm).position,
    })
    if isinstance(motion, FullMotion):
        truth.write_dynamics(_dynamics_truth(motion, t, t0_ns))
    truth.write_targets(scenario.scene)
    for smp in samples:
        truth.write_sensor(smp, t0_ns + np.round(smp.t_meas * 1e9).astype(np.int64),
                           t0_ns + np.round(smp.t_stamp * 1e9).astype(np.int64))


def _dynamics_truth(motion: FullMotion, t: NDArray[np.float64], t0_ns: int) -> dict[str, NDArray[np.float64]]:
    """The full model's 6-DOF pose and wheel states at the truth times t (s), and the road it drove on."""
    def wheels(a: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.stack([np.interp(t, motion.t, a[:, i]) for i in range(a.shape[1])], -1)

    return {
        "t_ns": t0_ns + np.round(t * 1e9).astype(np.int64),
        "attitude": motion.attitude(t), "body_rates": motion.body_rates(t), "side_slip": motion.side_slip(t),
        "lateral_offset": np.interp(t, motion.t, motion.lateral_offset),
        "wheel_load": wheels(motion.wheel_load), "rolling_radius": wheels(motion.rolling_radius),
        "longitudinal_slip": wheels(motion.longitudinal_slip), "wheel_rotation": motion.wheel_rotation(t),
        "road_height_at_wheels": wheels(motion.road_height),
        "road_s": motion.road.s, "road_track_heights": (motion.road.roughness + motion.road.features).T,
        "road_grade_height": motion.road.grade_height(motion.road.s),
    }
