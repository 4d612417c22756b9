"""A config sketched from a drive.h5: the streams it holds pinned by their topics to the default config's sensors.

A log recorded on other topics than the config's is ingested under names of its own (``imu/imu_data``,
``gnss/gnss``); navigate then needs a config naming them. The sketch is that config's start, laid over the one the
drive was ingested with (``base = ...``): each GNSS receiver's fix, velocity and NMEA topics, each IMU's topic, its
degrees of freedom (NaN axes), rate and, where gravity shows it turned, the pitch and roll that level it; the radar's
topic; the gyros to fuse; the INS baseline's IMU and receiver. What a log cannot show stays the base's, and the
sketch says so: lever arms, the vehicle's geometry, the sensors' error tables, an IMU's yaw on the body. The base's
CAN roles the drive lacks are unset.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np

from autosar_cli.config import DEFAULT_CONFIG, REQUIRED_ERROR_TABLES, SPEED_OF_LIGHT, Config
from autosar_cli.nav.frames import gravity_tilt_deg, levelling_pitch_roll_deg
from autosar_cli.store.drive import Drive
from autosar_cli.store.hdf5_read import read_dataset

#: an IMU whose gravity reads this far from its z axis is sketched with the pitch and roll that level it (a car's
#: mounting errors and a road's grade are a few degrees, which navigation measures itself)
SKETCH_TILT_DEG = 10.0


def config_sketch(drive_path: str | Path, config: Config) -> str:
    """TOML: ``config`` (the one the drive was ingested with) with the drive's streams pinned to its sensors."""
    with Drive(drive_path) as drive:
        gnss = _gnss_tables(drive, config)
        imus = _imu_tables(drive, config)
        radar = [drive.h5["radar"][n].attrs.get("topic", "") for n in drive.radar_names()]
        roles = json.loads(drive.h5["can"].attrs.get("roles", "{}")) if "can" in drive.h5 else {}
    base = _base(config)
    lines = [f"# autosar config sketched from {drive_path} (autosar info DRIVE --config-sketch): the drive's streams",
             "# pinned to the base's sensors. Check what a log cannot show: each [sensors.*] lever_arm_m, the",
             "# [vehicle] geometry (cog_to_rear_axle_m: the reference point), the sensors' error tables, an IMU's yaw.",
             "# Then: autosar ingest LOG -o drive.h5 --config THIS; autosar navigate drive.h5 --config THIS",
             f'base = "{base}"', ""]
    for kind, tables in (("gnss", gnss), ("imu", imus)):
        for name, table in tables:
            lines.append(f"[sensors.{name}]")
            lines += _new_sensor(config, name, kind)[0]
            lines += [f"{key} = {_toml(value)}" + (f"  # {note}" if note else "") for key, value, note in table]
            lines += _new_sensor(config, name, kind)[1]
            lines.append("")
    if radar and radar[0]:
        lines += ["[radar]", f"topic = {_toml(radar[0])}", ""]
    absent = [role for role in config.can.roles if role not in roles]
    if absent:
        lines.append("[can.roles]  # the base's roles this drive's CAN lacks, unset: give your DBC's MESSAGE.SIGNAL")
        lines += [f'{_toml(role) if "." in role else role} = ""' for role in absent] + [""]
    # the base's gyros the drive has; where it has none of them, every IMU it has
    present = {name for name, _ in imus} | {n for n in config.sensors if f"yaw_rate.{n}" in roles}
    gyros = [g for g in config.navigation.gyros if g in present] or [name for name, _ in imus]
    lines += ["[navigation]", f"gyros = {_toml(gyros)}"]
    if gnss:
        lines.append(f"gnss = {_toml(gnss[0][0])}")
    six = [name for name, table in imus if ("dof", 6, "") in table]
    lines.append(f"attitude_imu = {_toml(six[0] if six else '')}")
    # the INS baseline's IMU and receiver: the base's where the drive has them, else its first 6-DoF IMU and receiver
    nav = config.navigation
    if six:
        lines.append(f"ins_imu = {_toml(nav.ins_imu if nav.ins_imu in six else six[0])}")
    if gnss:
        receivers = [name for name, _ in gnss]
        lines.append(f"ins_gnss = {_toml(nav.ins_gnss if nav.ins_gnss in receivers else receivers[0])}")
    return "\n".join(lines) + "\n"


def capture_config_sketch(capture: str | Path, config: Config) -> str:
    """TOML: ``config``'s radar with what a TI DCA1000 capture states (its chirp, counts, PRF and the board's antennas
    it uses), for the capture to ingest with (``radar.*`` must agree with the recording: docs/RADAR.md)."""
    from autosar_cli.ingest.dca1000 import Dca1000Capture
    from autosar_cli.ingest.radar_block import recorded_from_capture

    cap = Dca1000Capture(Path(capture))
    p, rec = cap.params, recorded_from_capture(cap)
    r = config.radar
    lines = [f"# autosar config sketched from {capture} (autosar info CAPTURE --config-sketch): the [radar] keys the",
             "# capture states, over the base's. Check what a capture cannot show: the board's antenna rows",
             "# (tx_positions_wavelengths, rx_positions_wavelengths: the base's), [radar.mounting], beamwidths.",
             "# Then: autosar ingest LOG --radar CAPTURE -o drive.h5 --config THIS",
             f'base = "{_base(config)}"', "", "[radar]"]
    keys: Table = [("start_frequency_hz", rec.start_frequency_hz, "at the first ADC sample"),
                   ("slope_hz_per_s", rec.slope_hz_per_s, ""), ("sample_rate_hz", rec.sample_rate_hz, ""),
                   ("num_samples", rec.num_samples, ""), ("bandwidth_hz", rec.bandwidth_hz, "slope x ADC window"),
                   ("num_tx", rec.num_tx, ""), ("num_rx", rec.num_rx, ""),
                   ("prf_hz", rec.prf_hz, "one PRI: a loop of the chirp table"),
                   ("chirp_period_s", p.chirp_period_s, "idle + ramp end time")]
    for kind, used in (("tx", p.tx_order), ("rx", p.rx_channels)):  # over a base that names its own, always
        if getattr(r, f"{kind}_channels") is not None or tuple(used) != tuple(range(len(getattr(
                r, f"{kind}_positions_wavelengths")))):
            keys.append((f"{kind}_channels", list(used), f"the board's {kind.title()} in use: rows of "
                         f"{kind}_positions_wavelengths"))
    unambiguous = rec.sample_rate_hz * SPEED_OF_LIGHT / (2.0 * rec.slope_hz_per_s)
    if r.max_range_m > unambiguous * 1.001:  # as the config's check allows
        keys.append(("max_range_m", math.floor(unambiguous * 10) / 10, "the chirp's unambiguous range"))
    lines += [f"{key} = {_toml(value)}" + (f"  # {note}" if note else "") for key, value, note in keys]
    if list(p.chirp_tx) != sorted(p.chirp_tx):
        lines.append(f"# its chirps go Tx {list(p.chirp_tx)}: the config's go in Tx order, so ingest needs "
                     "--radar-override")
    return "\n".join(lines) + "\n"


def _base(config: Config) -> str:
    """How a sketch names ``config`` as its base."""
    return "default" if Path(config.source or DEFAULT_CONFIG).resolve() == DEFAULT_CONFIG.resolve() \
        else str(Path(config.source).resolve())


Table = list[tuple[str, object, str]]


def _names(drive_names: list[str], wanted: list[str], config: Config, kind: str) -> list[str]:
    """A config sensor name for each stream: its own where the config has it, else the next of ``wanted``."""
    taken = {n for n in drive_names if n in config.sensors and config.sensors[n].kind == kind}
    free = [n for n in wanted if n not in taken]
    return [n if n in taken else (free.pop(0) if free else n) for n in drive_names]


def _new_sensor(config: Config, name: str, kind: str) -> tuple[list[str], list[str]]:
    """The lines a sensor the base lacks needs before and after its table: its kind, and the lever arm and error
    tables of the base's first sensor of that kind (the navigation's receiver, for a receiver), said to be that."""
    if name in config.sensors:
        return [], []
    nav = config.navigation
    like = [n for n, s in config.sensors.items() if s.kind == kind]
    template = nav.gnss if kind == "gnss" and nav.gnss in like else like[0] if like else None
    if template is None:
        return [f"kind = {_toml(kind)}"], []
    t = config.sensors[template]
    after = [f"lever_arm_m = {_toml(list(t.lever_arm_m))}  # the base's {template}'s: where this sensor is"]
    for sub in REQUIRED_ERROR_TABLES[kind]:
        after += ["", f"[sensors.{name}.{sub}]  # the base's {template}'s: this sensor's own"]
        after += [f"{key} = {_toml(value)}" for key, value in asdict(getattr(t, sub)).items()]
    return [f"kind = {_toml(kind)}"], after


def _fix_stream(drive: Drive, source: str) -> str:
    """The stream that gives ``gnss/<source>``'s positions: its NavSatFix's, else its GGA sentences'."""
    return "fix" if "fix" in drive.h5["gnss"][source] else "nmea_fix"


def _gnss_tables(drive: Drive, config: Config) -> list[tuple[str, Table]]:
    # a receiver logged as NMEA sentences alone is navigated from its GGA and RMC (nav.inputs.receiver_streams)
    sources = [s for s in drive.gnss_sources() if {"fix", "nmea_fix"} & set(drive.h5["gnss"][s])]
    nav = config.navigation
    wanted = [nav.gnss, nav.ins_gnss] + [n for n, s in config.sensors.items() if s.kind == "gnss"]
    # an NMEA text capture has no topic to pin: ingest names it by its file, and so must the config
    captures = set(drive.nmea_captures())
    names = iter(_names([s for s in sources if s not in captures], list(dict.fromkeys(wanted)), config, "gnss"))
    out = []
    for source in sources:
        name = source if source in captures else next(names)
        g = drive.h5["gnss"][source]
        fix = _fix_stream(drive, source)
        if source in captures:
            table: Table = [("topic", "", f"the NMEA capture {Path(g[fix].attrs.get('source_file', '')).name}: "
                                          "named by its file"),
                            ("latency_s", 0.0, "its times are its fixes' own (UTC), not a logger's stamps")]
        elif fix == "fix":
            table = [("topic", g["fix"].attrs.get("topic", ""), "")]
        else:
            table = [("topic", "", "no NavSatFix logged: navigated from the NMEA GGA and RMC")]
        if "velocity" in g:
            vtype = "twist_with_covariance" if "WithCovariance" in str(g["velocity"].attrs.get("msgtype", "")) \
                else "twist"
            table += [("velocity_topic", g["velocity"].attrs.get("topic", ""), ""), ("velocity_type", vtype, "")]
        elif fix == "fix":
            table.append(("velocity_topic", "", "none logged: SAR-MIN starts on the fixes' first move"))
        nmea = [k for k in g if k.startswith("nmea_")]
        table.append(("nmea_topic", g[nmea[0]].attrs.get("topic", "") if nmea else "", ""))
        table.append(_rate(drive, f"gnss/{source}/{fix}", config, name, "gnss"))
        out.append((name, table))
    return out


def _imu_tables(drive: Drive, config: Config) -> list[tuple[str, Table]]:
    sources = drive.imu_sources()
    rates = {s: np.asarray(read_dataset(drive.h5["imu"][s], "angular_velocity")) for s in sources}
    forces = {s: np.asarray(read_dataset(drive.h5["imu"][s], "linear_acceleration")) for s in sources}
    # 6 where the rates and accelerations are numbers on all three axes, else 3 (NaN axes)
    dof = {s: 6 if (np.isfinite(rates[s]).all(axis=1) & np.isfinite(forces[s]).all(axis=1)).any() else 3
           for s in sources}
    nav = config.navigation
    imu_names = [n for n, s in config.sensors.items() if s.kind == "imu"]
    six = [n for n in [nav.attitude_imu, nav.ins_imu, *imu_names] if n and config.sensors.get(n)
           and config.sensors[n].dof == 6]
    three = [n for n in imu_names if config.sensors[n].dof == 3]
    names = {}
    for want, of in ((list(dict.fromkeys(six)), 6), (three, 3)):
        group = [s for s in sources if dof[s] == of]
        names.update(zip(group, _names(group, want, config, "imu"), strict=True))
    out = []
    for source in sources:
        cols = drive.h5["imu"][source]
        table: Table = [("topic", cols.attrs.get("topic", ""), ""), ("dof", dof[source], ""),
                        _rate(drive, f"imu/{source}", config, names[source], "imu")]
        if dof[source] == 6:
            f = forces[source]
            g = np.median(f[np.isfinite(f).all(axis=1)], axis=0)
            tilt = gravity_tilt_deg(g)
            if tilt > SKETCH_TILT_DEG:
                pitch, roll = levelling_pitch_roll_deg(g)
                table.append(("mounting_ypr_deg", [0.0, round(pitch, 1), round(roll, 1)],
                              f"gravity reads {tilt:.0f} deg off its z: these level it; the yaw is yours"))
        out.append((names[source], table))
    return out


def _rate(drive: Drive, path: str, config: Config, name: str, kind: str) -> tuple[str, float, str]:
    """The ``rate_hz`` row of a sensor: the stream's measured rate; where its samples cannot measure one (a capture of
    one fix), the base's for that sensor (else for its first of ``kind``, else 1 Hz), said to be that."""
    t = np.asarray(read_dataset(drive.h5[path], "t_ns"), dtype=np.int64)
    rate = round(float((len(t) - 1) / ((t[-1] - t[0]) / 1e9)), 1) if len(t) > 1 and t[-1] > t[0] else 0.0
    if rate > 0:
        return "rate_hz", rate, "measured"
    like = [s for s in config.sensors.values() if s.kind == kind]
    base = config.sensors[name] if name in config.sensors else like[0] if like else None
    return "rate_hz", base.rate_hz if base else 1.0, f"{len(t)} sample(s): too few to measure, the base's"


def _toml(value: object) -> str:
    """A TOML value: a string, a list (or tuple), an integer or a float (numpy's too)."""
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, int | np.integer):
        return str(int(value))
    return repr(float(value))  # type: ignore[arg-type]
