"""``autosar navigate``: drive.h5 in, trajectory out, by one of the methods."""

from __future__ import annotations

import math
import os
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.integrate import cumulative_trapezoid

from autosar_cli.config import CAN_LOG_SUFFIXES, Config
from autosar_cli.nav import models as m
from autosar_cli.nav.attitude import (
    CROSSOVER_HZ,
    PITCH_BIAS_MIN_SPEED_MPS,
    BodyAttitude,
    climb,
    estimate_attitude,
    pitch_bias,
    road_slope,
    tilt_heights,
    tilt_offsets,
    without_pitch_bias,
)
from autosar_cli.nav.baselines import from_truth, gnss_only, straight_line
from autosar_cli.nav.can_latency import MIN_SAMPLES as MIN_CAN_SAMPLES
from autosar_cli.nav.can_latency import (
    delayed_can,
    fit_can_clock,
    fit_can_latency,
    imus_moved,
    wheels_late_against_gnss,
)
from autosar_cli.nav.dead_reckoning import dead_reckoned_start
from autosar_cli.nav.gnss_latency import EDGE, SEARCH_S, delayed_gnss, fit_gnss_latency
from autosar_cli.nav.gnss_latency import MIN_SPAN_S as MIN_LATENCY_SPAN_S
from autosar_cli.nav.gnss_noise import (
    gnss_noise_checked,
    gnss_slow_error_checked,
    velocity_decorrelated,
    with_fit_bounds_widened,
)
from autosar_cli.nav.inputs import NavInputError, NavInputs, load_inputs
from autosar_cli.nav.rear_slip import fit_rear_slip
from autosar_cli.nav.sarmin import NavSolution, gnss_lever_rear, run_sarmin, with_smoothed_covariance
from autosar_cli.nav.trajectory import Trajectory, phase_centre_lever_arm, wheel_scale_mean_std
from autosar_cli.nav.understeer import UndersteerFit, fit_understeer
from autosar_cli.nav.wheel_speeds import (
    LOAD_GAINS,
    SLIP_GAINS,
    fit_wheel_speeds,
    gnss_speed_residual,
    lag_compensated_wheels,
    radius_corrected_wheels,
    raw_gyro_yaw_rate,
    restart_window_m,
    standstill_spans,
    standstill_yaw_rate,
    turning_standstills,
    wheel_gaps,
    wheel_scale_corrected,
    wheel_scale_error,
    without_restart_windows,
)
from autosar_cli.store.drive import Drive
from autosar_cli.types import MotionCorrection

METHODS = ("sar-min", "ins", "gnss", "none", "truth")
#: what a trajectory's info reports of its navigation (navigate --json, run.json): updates and what was fitted
REPORTED_INFO = ("updates", "rejected", "gnss_noise", "gnss_slow_error", "gnss_velocity_correlation", "gnss_latency",
                 "can_latency", "before_first_fix", "gnss_gaps", "understeer", "rear_slip", "wheel_lag", "wheel_radii",
                 "attitude", "wheel_gaps", "standstill_ns", "standstill_refused", "gnss_heading", "warnings")
SIGNIFICANT = 3.0  # a fitted lag or gradient is applied where it differs from the default by more stds than this
# ... and by more than these: a tenth of a sedan's understeer gradient (rad per m/s^2), 5 ms of yaw lag, 1 cm of
# wheel-speed lag distance, 0.1 % per m/s^2 of slip gain (at urban's 1 m/s^2 RMS, 1 mm per metre), 0.05 % per m/s^2
# of load gain. Smaller ones, significant or not, are below what changes a track: a kinematic drive's sensors
# show sub-millisecond timing offsets at several sigma, and load gains up to 0.033 % at 3.7 sigma on test3 (the
# full vehicle's are 0.06-0.12 %)
MIN_UNDERSTEER_CHANGE = 2e-4
MIN_YAW_LAG_S = 0.005
MIN_WHEEL_LAG_M = 0.01
MIN_SLIP_GAIN = 1e-3
MIN_LOAD_GAIN = 5e-4
#: ... and 1 mrad of rear slip per m/s^2 (a sixth of the full vehicle's 6.6)
MIN_REAR_SLIP_CHANGE = 1e-3
#: ... and 10 ms of CAN delay (a 40 ms bus put test1's reflectors 2.2 cm further off), where the drive turns
#: enough to show it: the yaw rate's change over 0.25 s means at least this RMS (test3 and urban 0.09-0.11 rad/s^2,
#: where the delay's std is 0.5-0.6 ms; test1-2, straight, 0.01, where the fit wanders by 50 ms)
MIN_CAN_DELAY_S = 0.01
MIN_YAW_ACCELERATION_RADPS2 = 0.03
#: ... and 20 ms of GNSS latency (a 15-20 ms error costs test1-3 0.5-2 cm: SENSOR_ERRORS.md)
MIN_GNSS_LATENCY_CHANGE_S = 0.02
#: the GNSS latency's fit moves the samples only beyond this many std: GNSS noise drawn 40 times onto test3 seed 42's
#: true velocity at the table's latency, the fit scattered by 20.6 ms where its std stated 16.9 (median), and at
#: 3 std one draw moved the samples by 56 ms (4-6 cm on the reflectors)
GNSS_LATENCY_SIGNIFICANT = 4.0
#: a GNSS latency fit whose best lies at its search's edge is a warning where the table's latency fits worse by this
#: chi-square (the profile's, which overstates: test1 seed 1 as recorded, a drive that hardly accelerates, 17 at the
#: edge; its GNSS 450 ms late on urban seed 1, 5671): elsewhere the drive does not show the latency
EDGE_MIN_TABLE_CHI2 = 100.0
#: a road car's understeer gradient lies within these (rad per m/s^2: -1 to 5.6 deg/g), and its steering within this
#: factor of the steady state they give (a steering ratio that varies along the rack, Ackermann): a steering whose
#: slope against the kinematic angle lies beyond them, by ``STEERING_GAIN_SIGNIFICANT`` std, is not this car's
#: road-wheel angle (its sign, its unit, the steering ratio): left out, and said
UNDERSTEER_RANGE = (-0.002, 0.01)
STEERING_GAIN_TOLERANCE = 1.25
STEERING_GAIN_SIGNIFICANT = 5.0
#: ... where the steering correlates with the kinematic angle by this (the gyros' errors then shrink the gain by at
#: most its square; test2's lane changes: 0.99, test1's straight drives ~0, the gain ~0) or the drive turns
MIN_STEERING_CORRELATION = 0.95
#: the CAN's and the GNSS's latencies against the IMUs, both after their stamps, are the IMUs' own where they agree
#: within this (s) or 3 std
IMUS_LATE_AGREE_S = 0.02
#: the attitude estimate's error (rad, 1 sigma): 0.76 / 0.47 mrad RMS roll / pitch on test3 seed 2 (nav.attitude)
ATTITUDE_STD_RAD = 1e-3
#: a stream whose updates SAR-MIN's gate refused more than this share of (of at least MIN_GATED) is warned of
MAX_GATED_SHARE = 0.5
MIN_GATED = 10


def gated_streams(updates: dict[str, int], rejected: dict[str, int]) -> list[str]:
    """A warning for each stream whose updates SAR-MIN's gate refused more than ``MAX_GATED_SHARE`` of. The GNSS
    (``gnss_pos``, ``gnss_vel``): the car's own sensors and the GNSS disagree, and the track follows the former (the
    simulated drives: none refused, or 11 of 127 velocities with the GNSS's stamps 0.5 s late). Any other (a gyro,
    the wheels, the steering): it disagrees with the rest, which the track follows without it (a gyro in deg/s read
    as rad/s: all refused)."""
    out = []
    for stream in sorted(set(updates) | set(rejected), key=lambda s: (not s.startswith("gnss_"), s)):
        gated = int(rejected.get(stream, 0))
        total = gated + int(updates.get(stream, 0))
        if total < MIN_GATED or gated <= MAX_GATED_SHARE * total:
            continue
        if stream in ("gnss_pos", "gnss_vel"):
            what = "fixes" if stream == "gnss_pos" else "velocities"
            out.append(f"SAR-MIN's gate refused {gated} of {total} GNSS {what}: the car's own sensors and the GNSS "
                       "disagree (a unit, a lever arm, a latency, another drive's data?), and the track follows the "
                       "car's sensors")
        else:
            out.append(f"SAR-MIN's gate refused {gated} of {total} samples of {stream}: they disagree with the other "
                       "sensors (a unit, e.g. deg/s read as rad/s, a sign, a mounting, another drive's data?), and the "
                       "track follows the others")
    return out


#: a gyro whose yaw rate correlates with the median of the others' below this reads them with its sign turned; told
#: only where the drive turns (the others' median varies by over ``MIN_TURNING_RADPS`` RMS)
FLIPPED_GYRO_CORRELATION = -0.5
MIN_TURNING_RADPS = 0.02


def without_flipped_gyros(inputs: NavInputs) -> tuple[NavInputs, list[str]]:
    """``inputs`` without each gyro that reads the others' yaw rate with its sign turned (a mounting upside down, a
    DBC signal's sign), where there are three or more to outvote it, and a warning for each: the filter's gate
    refused most of its samples and named the GNSS, the heading followed it where the gate let it (52.8° off with one
    of urban seed 1's four turned)."""
    gyros = inputs.gyros
    if len(gyros) < 3:
        return inputs, []
    start, end = max(g.t[0] for g in gyros), min(g.t[-1] for g in gyros)
    grid = gyros[0].t[(gyros[0].t >= start) & (gyros[0].t <= end)]
    if len(grid) < 10:
        return inputs, []
    rates = np.array([np.interp(grid, g.t, g.z[:, 0]) for g in gyros])
    if np.std(np.median(rates, axis=0)) < MIN_TURNING_RADPS:
        return inputs, []
    flipped = {}
    for i in range(len(gyros)):
        others = np.median(np.delete(rates, i, axis=0), axis=0)
        if (c := float(np.corrcoef(rates[i], others)[0, 1])) < FLIPPED_GYRO_CORRELATION:
            flipped[i] = c
    if not flipped or len(flipped) > (len(gyros) - 1) // 2:  # no majority left to trust
        return inputs, []
    keep = [i for i in range(len(gyros)) if i not in flipped]
    return replace(inputs, gyros=[gyros[i] for i in keep], gyro_bias_std=[inputs.gyro_bias_std[i] for i in keep],
                   gyro_bias_walk=[inputs.gyro_bias_walk[i] for i in keep]), [
        f"gyro {gyros[i].name} reads the other gyros' yaw rate with its sign turned (correlation {c:.2f}): left out "
        "(its mounting, or its DBC signal's sign?)" for i, c in flipped.items()]


#: a span this long without a GNSS fix, and five of the receiver's intervals, is reported (``info["gnss_gaps"]``)
MIN_GNSS_GAP_S = 2.0


def gnss_gaps(inputs: NavInputs) -> list[dict[str, float | int]]:
    """The spans after the first GNSS fix without one (a tunnel, trees; the drive's start is
    ``info["before_first_fix"]``), to the drive's last wheel speed: start and end (ns), and their length (s). There
    the track rests on the wheels and gyros alone."""
    pos = inputs.gnss_position
    if pos is None or len(pos.t) < 2:
        return []
    ends = np.append(pos.t, inputs.wheels.t[-1] if inputs.wheels is not None else pos.t[-1])
    longest = max(MIN_GNSS_GAP_S, 5.0 * float(np.median(np.diff(pos.t))))
    return [{"start_ns": inputs.t0_ns + int(round(a * 1e9)), "end_ns": inputs.t0_ns + int(round(b * 1e9)),
             "duration_s": round(float(b - a), 3)} for a, b in zip(ends[:-1], ends[1:], strict=True) if b - a > longest]


def default_truth_path(drive: Drive) -> Path | None:
    """``<log>.truth.h5`` next to the first input log of the drive, if it exists."""
    from autosar_cli.sim.truth import truth_sidecar_of

    if "provenance/inputs" not in drive.h5:
        return None
    return truth_sidecar_of(row["path"].decode() if isinstance(row["path"], bytes) else str(row["path"])
                            for row in drive.h5["provenance/inputs"][()])


def _shows(change: float, std: float, minimum: float) -> bool:
    """Whether a fitted change from the default is both significant and large enough to matter."""
    return abs(change) > SIGNIFICANT * std and abs(change) > minimum


def gnss_latency_corrected(inputs: NavInputs, config: Config) -> tuple[NavInputs, dict]:
    """``inputs`` with the GNSS samples moved to the latency the drive shows against its 6-DoF IMU
    (:mod:`.gnss_latency`, ``navigation.estimate_gnss_latency``), where the fit is unambiguous, its std at most
    ``navigation.gnss_latency_max_std_s`` and it differs from the GNSS sensor's stated ``latency_s`` by more than
    ``GNSS_LATENCY_SIGNIFICANT`` std and ``MIN_GNSS_LATENCY_CHANGE_S``; and what the fit found, and why."""
    nav = config.navigation
    sensor = config.sensors.get(nav.gnss)
    table = sensor.latency_s if sensor else 0.0
    if not nav.estimate_gnss_latency:
        return inputs, {"applied": False, "table_latency_s": table,
                        "reason": "navigation.estimate_gnss_latency is off: the table's latency"}
    attitude, _ = body_attitude(inputs, config)
    fit = fit_gnss_latency(inputs, table, attitude)
    if fit is None:
        return inputs, {"applied": False, "table_latency_s": table,
                        "reason": f"no 6-DoF IMU (navigation.attitude_imu) or GNSS velocity, or under "
                                  f"{MIN_LATENCY_SPAN_S:g} s of both: the table's latency"}
    if fit.ambiguous.startswith(EDGE) and fit.table_chi2 > EDGE_MIN_TABLE_CHI2:
        return inputs, replace(fit, reason=f"{fit.ambiguous}: the table's latency").to_dict() | {"warning": (
            f"GNSS latency: its velocity fits the IMU {fit.imu}'s best {SEARCH_S * 1000:.0f} ms or more from the "
            f"table's {table * 1000:g} ms, at the search's edge (its stamps or the IMU's on another clock?): the "
            "table's latency kept")}
    if fit.ambiguous:
        why = f"{fit.ambiguous}: the table's latency"
    elif not fit.std_s <= nav.gnss_latency_max_std_s:
        why = (f"std {fit.std_s * 1000:.0f} ms above navigation.gnss_latency_max_std_s (the drive's acceleration "
               f"changes by {fit.accel_change_rms_mps2:.2f} m/s^2 RMS): the table's latency")
    elif not (abs(fit.change_s) > GNSS_LATENCY_SIGNIFICANT * fit.std_s
              and abs(fit.change_s) > MIN_GNSS_LATENCY_CHANGE_S):
        why = (f"within {GNSS_LATENCY_SIGNIFICANT:g} std or {MIN_GNSS_LATENCY_CHANGE_S * 1000:g} ms of the table's "
               f"{table * 1000:g} ms: the table's latency")
    elif table + fit.change_s < -GNSS_LATENCY_SIGNIFICANT * fit.std_s:
        said = (f"the samples would refer to {-(table + fit.change_s) * 1000:.0f} ms after their stamps against the "
                f"IMU {fit.imu}'s (+- {fit.std_s * 1000:.0f} ms), which no receiver does: the IMU's stamps late, or "
                "the GNSS's on another clock?")
        return inputs, replace(fit, reason=f"{said}: the table's latency").to_dict() | {
            "after_stamps": True, "warning": f"GNSS latency: {said} The table's latency kept"}
    else:
        return delayed_gnss(inputs, fit.change_s), replace(
            fit, applied=True, reason=f"the samples refer to {(table + fit.change_s) * 1000:.0f} ms before their "
                                      f"stamps, not the table's {table * 1000:g} ms: moved by the fitted latency"
                                      f" (set [sensors.{nav.gnss}] latency_s)").to_dict()
    return inputs, replace(fit, reason=why).to_dict()


def latencies_corrected(inputs: NavInputs, config: Config) -> tuple[NavInputs, dict, dict, list[str]]:
    """``inputs`` with the CAN's and the GNSS's latencies measured against the IMUs (:func:`can_latency_corrected`,
    :func:`gnss_latency_corrected`) and, where both put their samples after their stamps by one delay
    (:data:`IMUS_LATE_AGREE_S` and 3 std), the IMUs moved by it instead: it is theirs, stamped late (urban seed 1
    with its four IMUs 0.3 s late: the CAN moved by -296 ms to them, the GNSS refused by the gate, the track 6.6 m
    across). The two latencies' findings, and a warning where the IMUs moved."""
    moved, can = can_latency_corrected(inputs, config)
    moved, gnss = gnss_latency_corrected(moved, config)
    if not (gnss.get("after_stamps") and can.get("applied") and can["delay_s"] < 0
            and abs(can["delay_s"] - gnss["change_s"]) <= max(IMUS_LATE_AGREE_S,
                                                              3.0 * math.hypot(can["std_s"], gnss["std_s"]))):
        return moved, can, gnss, []
    weights = np.array([can["std_s"], gnss["std_s"]]) ** -2.0
    late = -float(np.dot(weights, [can["delay_s"], gnss["change_s"]]) / weights.sum())
    imus = sorted({*can["imu_gyros"], gnss["imu"]})
    said = (f"IMUs {', '.join(imus)}: stamped {late * 1000:.0f} ms late against both the CAN's gyros "
            f"({-can['delay_s'] * 1000:.0f} +- {can['std_s'] * 1000:.0f} ms) and the GNSS's velocity "
            f"({-gnss['change_s'] * 1000:.0f} +- {gnss['std_s'] * 1000:.0f} ms): moved by it (their clock; set their "
            "latency_s)")
    inputs, can = can_latency_corrected(imus_moved(inputs, late, imus), config)
    inputs, gnss = gnss_latency_corrected(inputs, config)
    return inputs, can, gnss, [said]


def can_log_files(drive: Drive) -> list[str]:
    """The names of the CAN log files (``.blf``, ``.asc`` ...: a logger of their own, on its own clock) ``drive``'s
    CAN messages were read from."""
    sources = {str(drive.h5["can"][m].attrs.get("source_file", "")) for m in drive.can_messages()}
    return sorted(Path(s).name for s in sources if Path(s).suffix.lower() in CAN_LOG_SUFFIXES)


def can_clock_corrected(inputs: NavInputs, config: Config, can_logs: list[str]) -> tuple[NavInputs, list[str]]:
    """``inputs`` with every CAN signal moved by the CAN gyros' lag against the IMUs' where it lies beyond the CAN
    delay's search (:func:`fit_can_clock`: a CAN logger's clock set wrong) and the wheel speeds show it against the
    GNSS speed too (:func:`wheels_late_against_gnss`; else the IMUs are off both), and a warning saying so (the
    ``--time-offset`` that mends it where the CAN came from the CAN log files ``can_logs``); where the wheels cannot
    tell whose clock is off, nothing moved and a warning saying that; as they are otherwise, or where
    ``navigation.estimate_can_latency`` is off. Urban seed 1's CAN log 2 s late: the gate refused 447 of 580 fixes,
    naming the GNSS, and the track went 2.2 m across."""
    if not config.navigation.estimate_can_latency:
        return inputs, []
    can = [name for name, s in config.sensors.items() if s.kind == "can_imu"]
    imu = [name for name, s in config.sensors.items() if s.kind == "imu"]
    late = fit_can_clock(inputs, can, imu)
    if late is None:
        return inputs, []
    used = ", ".join(g.name for g in inputs.gyros if g.name in imu)
    runs = (f"CAN: its gyros' yaw rate runs {abs(late):.2f} s {'late' if late > 0 else 'early'} against the IMUs' "
            f"({used}), beyond any bus's delay")
    mend = (f"--time-offset {can_logs[0]}={-late:.2f} at ingest" if len(can_logs) == 1 else
            f"--time-offset CAN_LOG={-late:.2f} at ingest for the CAN log of {', '.join(can_logs)} that is off"
            if can_logs else "the CAN topic's stamps")
    if not wheels_late_against_gnss(inputs, late):  # the IMUs' clock may be the one off: latencies_corrected's
        return inputs, [f"{runs}, and the wheel speeds against the GNSS speed cannot tell whose clock is off, the "
                        f"CAN's or the IMUs': nothing moved; check both ({mend} where the CAN's)"]
    return delayed_can(inputs, late, can), [f"{runs}: a CAN logger's clock set wrong? Every CAN signal moved by it "
                                            f"(or {mend})"]


def can_latency_corrected(inputs: NavInputs, config: Config) -> tuple[NavInputs, dict]:
    """``inputs`` with every CAN signal moved by the delay beyond the tables that the CAN gyros show against the IMUs'
    (:mod:`.can_latency`, ``navigation.estimate_can_latency``), where the drive turns enough to measure it
    (``MIN_YAW_ACCELERATION_RADPS2``), its std is at most ``navigation.can_latency_max_std_s`` and it differs from 0
    by more than ``SIGNIFICANT`` std and ``MIN_CAN_DELAY_S``; and what the fit found, and why."""
    nav = config.navigation
    if not nav.estimate_can_latency:
        return inputs, {"applied": False, "reason": "navigation.estimate_can_latency is off: the tables' latencies"}
    can = [name for name, s in config.sensors.items() if s.kind == "can_imu"]
    imu = [name for name, s in config.sensors.items() if s.kind == "imu"]
    fit = fit_can_latency(inputs, can, imu)
    if fit is None:
        return inputs, {"applied": False, "reason": "no CAN gyro and IMU gyro over a common span of "
                                                    f"{MIN_CAN_SAMPLES} samples: the tables' latencies"}
    if fit.yaw_acceleration_rms_radps2 < MIN_YAW_ACCELERATION_RADPS2:
        why = (f"the drive hardly turns (yaw rate's change {fit.yaw_acceleration_rms_radps2:.3f} rad/s^2 RMS, under "
               f"{MIN_YAW_ACCELERATION_RADPS2:g}): unmeasured, the tables' latencies")
    elif not fit.std_s <= nav.can_latency_max_std_s:
        why = f"std {fit.std_s * 1000:.1f} ms above navigation.can_latency_max_std_s: the tables' latencies"
    elif not _shows(fit.delay_s, fit.std_s, MIN_CAN_DELAY_S):
        why = f"within {SIGNIFICANT:g} std or {MIN_CAN_DELAY_S * 1000:g} ms of the tables: their latencies"
    else:
        return delayed_can(inputs, fit.delay_s, can), replace(
            fit, applied=True, reason=f"the CAN signals refer to {fit.delay_s * 1000:.0f} ms before their tables "
                                      "say: moved by it (the logger's clock or the bus; set the CAN sensors' "
                                      "latency_s)").to_dict()
    return inputs, replace(fit, reason=why).to_dict()


def wheel_speeds_corrected(inputs: NavInputs, config: Config) -> tuple[NavInputs, dict, dict]:
    """The inputs with the wheel speeds corrected by what :mod:`.wheel_speeds` fits to the drive and the drive
    shows: divided by their slip and load factors (``navigation.estimate_wheel_radii``: a gain is shown where its
    std is at most ``wheel_radius_gain_max_std_per_mps2`` and it differs from 0 by more than ``SIGNIFICANT`` of
    them and ``MIN_SLIP_GAIN`` / ``MIN_LOAD_GAIN``; the measured slip gains go together, and only where the lag beside
    which they were fitted is estimated and pinned down), then moved back by their lag
    (``navigation.estimate_wheel_lag``, the same test with ``wheel_lag_max_std_m`` and ``MIN_WHEEL_LAG_M``; the fit
    conditioned on the wheel sensor's stated window where it has one and they agree); and what the fits found, lag
    and radii."""
    nav, veh = config.navigation, config.vehicle
    if not (nav.estimate_wheel_lag or nav.estimate_wheel_radii):
        off = {"applied": False, "reason": "navigation.estimate_wheel_lag is off"}
        return inputs, off, {"applied": {}, "reason": "navigation.estimate_wheel_radii is off"}
    lag, radii = fit_wheel_speeds(inputs, gnss_lever_rear(inputs, config), veh.wheelbase_m,
                                  (veh.track_front_m, veh.track_rear_m), window_always=nav.wheel_lag_window_always)
    radii_info: dict = {"applied": {}, "reason": "no wheel speeds, or no GNSS velocity and gyros, or no motion above "
                                                 "1 m/s"}
    if not nav.estimate_wheel_radii:
        radii_info = {"applied": {}, "reason": "navigation.estimate_wheel_radii is off"}
    elif radii is not None:
        limit = nav.wheel_radius_gain_max_std_per_mps2
        # the slip gains are one term (the tyres' slip stiffness times the axle's share of drive and brake): the
        # measured ones are applied together where one shows; a drive that never brakes leaves the brake gains
        # unmeasured, and they never act on it. At a steady speed the slip regressor a v is alike the lag's -a / v:
        # where the lag is not pinned down, or not estimated (and so not corrected), neither are they
        lag_known = nav.estimate_wheel_lag and lag is not None and lag.std_m <= nav.wheel_lag_max_std_m
        measured = [name for name in SLIP_GAINS if radii.slip_gain_std[name] <= limit] if lag_known else []
        shows = any(_shows(radii.slip_gain[name], radii.slip_gain_std[name], MIN_SLIP_GAIN) for name in measured)
        shows = shows or (nav.wheel_lag_window_always and lag is not None and lag.fitted_m is not None)
        # with the GNSS velocity's slow error carried as states, the scale rests on the speed's changes, i.e. on
        # the accelerations where slip acts, so a gain left out costs more than its noise: a receiver smoothing over
        # 0.5 s hid urban's slip at 1.5-2.5 std, and the scale of its seeds 0-9 went 0.16 % short without them
        shows = shows or (inputs.gnss_velocity_error_time_s > 0 and bool(measured))
        gains = {name: radii.slip_gain[name] for name in measured} if shows else {}
        gains.update({f"load_{name}": radii.load_gain[name] for name in LOAD_GAINS
                      if radii.load_gain_std[name] <= limit
                      and _shows(radii.load_gain[name], radii.load_gain_std[name], MIN_LOAD_GAIN)})
        if gains:
            inputs = replace(inputs, wheels=radius_corrected_wheels(inputs, gains),
                             rigid_wheels=not any(name.startswith("load_") for name in gains))
            why = "fitted to the drive" + ("" if len(gains) == len(SLIP_GAINS) + len(LOAD_GAINS) else
                                           "; the gains not listed are not shown")
        else:
            why = (f"no gain with std at most navigation.wheel_radius_gain_max_std_per_mps2 and more than "
                   f"{SIGNIFICANT:g} std from 0: wheel speeds as recorded")
        radii_info = replace(radii, applied=gains, reason=why).to_dict()
        radii_info["wheel_model"] = "rigid" if inputs.rigid_wheels else "load-compliant"
    if not nav.estimate_wheel_lag:
        return inputs, {"applied": False, "reason": "navigation.estimate_wheel_lag is off"}, radii_info
    if lag is None:
        return inputs, {"applied": False, "reason": "no wheel speeds, GNSS velocity, or motion above 1 m/s"}, radii_info
    if not lag.std_m <= nav.wheel_lag_max_std_m:
        return inputs, replace(lag, reason=f"std {lag.std_m:.2g} m above navigation.wheel_lag_max_std_m (a / v "
                                           f"{lag.accel_over_speed_rms:.2f} 1/s RMS): samples as stamped").to_dict(), \
            radii_info
    if not _shows(lag.lag_distance_m, lag.std_m, MIN_WHEEL_LAG_M):
        return inputs, replace(lag, reason=f"lag within {SIGNIFICANT:g} std or {MIN_WHEEL_LAG_M} m of 0: samples as "
                                           "stamped").to_dict(), radii_info
    assert inputs.wheels is not None
    # a drive that shows the ECU's window also shows where that window reaches back across a standstill
    clear, dropped = without_restart_windows(inputs.wheels, restart_window_m(lag))
    moved = replace(inputs, wheels=lag_compensated_wheels(clear, lag))
    assert moved.wheels is not None
    unread = len(clear.t) - len(moved.wheels.t)
    if lag.prior_m is None:
        source = "fitted to the drive"
    elif lag.fitted_m is not None:
        source = "fitted to the drive and the wheel sensor's stated window"
    else:
        source = (f"fitted to the drive, more than {SIGNIFICANT:g} std from the wheel sensor's stated window "
                  f"{lag.prior_m:g} m, which is left out")
    return moved, replace(lag, applied=True, reason=source, restart_rows_dropped=dropped,
                          unread_rows_dropped=unread).to_dict(), radii_info


def gnss_heading_info(sol: NavSolution, inputs: NavInputs) -> dict[str, object]:
    """What became of the receiver's heading that ``navigation.gnss_heading`` asked for: the samples fused and the
    offset SAR-MIN found (deg, and its std), or why none was fused."""
    if "offset.gnss_heading" not in sol.state_names:
        return {"applied": False, "reason": inputs.gnss_heading_missing}
    i = sol.state_names.index("offset.gnss_heading")
    return {"applied": True, "samples": int(sol.updates.get("gnss_heading", 0)),
            "rejected": int(sol.rejected.get("gnss_heading", 0)),
            "offset_deg": float(np.rad2deg(sol.x[-1, i])),
            "offset_std_deg": float(np.rad2deg(np.sqrt(sol.P[-1, i, i])))}


def body_attitude(inputs: NavInputs, config: Config) -> tuple[BodyAttitude | None, str]:
    """The body's roll and pitch over the drive from the 6-DoF IMU ``navigation.attitude_imu`` (:mod:`.attitude`),
    before any pass: the rear axle's speed from the rear wheels (the GNSS speed without them), its yaw rate the
    gyros' (:func:`_gyro_yaw_rate`). None, and why, where there is no such IMU or it covers too little of the drive."""
    nav = config.navigation
    if not nav.attitude_imu:
        return None, "navigation.attitude_imu is empty: the radar and the GNSS antenna as on a planar body"
    if inputs.attitude_imu is None:
        return None, (f"no 6-DoF IMU stream imu/{nav.attitude_imu} in the drive: the radar and the GNSS antenna as "
                      "on a planar body")
    if inputs.attitude_imu.gravity_removed:
        return None, (f"imu/{nav.attitude_imu} reads gravity-removed acceleration: no roll and pitch from it, the "
                      "radar and the GNSS antenna as on a planar body")
    if inputs.wheels is not None:
        t, speed = inputs.wheels.t, inputs.wheels.z[:, 2:].mean(axis=1)
    elif inputs.gnss_velocity is not None:
        t, speed = inputs.gnss_velocity.t, np.hypot(*inputs.gnss_velocity.z.T)
    else:
        t = speed = np.zeros(0)
    att = None
    if len(t) >= 2:
        att = estimate_attitude(inputs.attitude_imu, t, speed, _gyro_yaw_rate(inputs, t),
                                cog_to_rear_axle_m=config.vehicle.cog_to_rear_axle_m,
                                cog_height_m=config.vehicle.cog_height_m,
                                roll_axis_height_m=config.vehicle.roll_axis_height_m)
    if att is None:
        return None, (f"imu/{nav.attitude_imu} covers less than {1 / CROSSOVER_HZ:g} s of the drive: the radar and "
                      "the GNSS antenna as on a planar body")
    if (nav.radar_height or nav.attitude_pitch_bias) and inputs.gnss_climb is not None:
        antenna = _lever_from_roll_axis(np.asarray(inputs.gnss_lever_m), config)
        att = without_pitch_bias(att, *pitch_bias(att, np.interp(att.t, t, speed), inputs.gnss_climb, antenna))
    return att, "the body's roll and pitch from the IMU"


def _gyro_yaw_rate(inputs: NavInputs, t: np.ndarray) -> np.ndarray:
    """The gyros' yaw rate (rad/s, biases and all) at the increasing times ``t`` (s): the wheel fits' own
    (:func:`raw_gyro_yaw_rate`), held at its first and last values outside the gyros' span."""
    w = raw_gyro_yaw_rate(inputs, t)
    inside = np.isfinite(w)
    return np.interp(t, t[inside], w[inside]) if inside.any() else np.zeros_like(t)


def _lever_from_roll_axis(lever_from_cog: np.ndarray, config: Config) -> np.ndarray:
    return np.asarray(lever_from_cog, dtype=np.float64) + np.array(
        [0.0, 0.0, config.vehicle.cog_height_m - config.vehicle.roll_axis_height_m])


def radar_slope(inputs: NavInputs, config: Config, t: np.ndarray) -> np.ndarray | None:
    """The slope (N,) of the radar's path (its rise over its horizontal run) at times ``t`` (N,) (s, the inputs'
    clock), over +-1 s (:func:`road_slope`): the GNSS antenna's climb moved to the radar by the body's tilt
    (:func:`body_attitude`; a radar 2 m ahead of the CoG rises and falls as the body pitches, which the roof
    antenna does not: on test3's full vehicle on a 4 % grade the antenna's slope is 3.5e-3 RMS off the radar's,
    0.9e-3 with the tilt). None without the GNSS's vertical and horizontal velocities."""
    if inputs.gnss_climb is None or inputs.gnss_velocity is None:
        return None
    climb_rate = inputs.gnss_climb
    att, _ = body_attitude(inputs, config)
    if att is not None:
        radar = _lever_from_roll_axis(phase_centre_lever_arm(config), config)
        antenna = _lever_from_roll_axis(np.asarray(inputs.gnss_lever_m), config)
        above = tilt_heights(att.roll, att.pitch, radar) - tilt_heights(att.roll, att.pitch, antenna)
        # its change over each climb sample's own interval, not a derivative sampled there: summed over the
        # average's span it is the chord the radar rose by, free of the IMU's noise between the samples
        dt = float(np.median(np.diff(climb_rate.t))) if len(climb_rate.t) > 1 else 0.1
        rate = (np.interp(climb_rate.t + dt / 2, att.t, above) - np.interp(climb_rate.t - dt / 2, att.t, above)) / dt
        climb_rate = replace(climb_rate, z=climb_rate.z + rate[:, None])
    return road_slope(climb_rate, inputs.gnss_velocity, t)


def gnss_on_level_body(inputs: NavInputs, att: BodyAttitude, config: Config) -> NavInputs:
    """``inputs`` with the GNSS fixes and velocities moved to where the antenna would be on a level body.

    An antenna h above the roll axis moves fore-aft by h theta and sideways by -h phi as the body pitches and
    rolls; SAR-MIN's antenna model is planar. On a grade that changes by 1 % over 60 m (the simulator's road) the
    roof antenna, 1.35 m up, moves 0.07 % of the distance driven fore-aft: the track's scale, were it left in.
    The offsets rotate to ENU by the GNSS velocity's course, which is within a few mrad of the body's heading.
    """
    pos, vel = inputs.gnss_position, inputs.gnss_velocity
    if pos is None:
        return inputs
    lever = _lever_from_roll_axis(np.asarray(inputs.gnss_lever_m), config)
    body = tilt_offsets(att.roll, att.pitch, np.zeros_like(att.t), lever)  # (N, 2) body frame
    body_rate = np.gradient(body, att.t, axis=0)
    heading = _course(inputs, att.t)
    yaw_rate = _gyro_yaw_rate(inputs, att.t)
    c, s = np.cos(heading), np.sin(heading)
    offset = np.stack([c * body[:, 0] - s * body[:, 1], s * body[:, 0] + c * body[:, 1]], axis=1)
    # d/dt R(psi) d = R(psi) (d' + omega J d), J d = (-d_y, d_x)
    bx, by = body_rate[:, 0] - yaw_rate * body[:, 1], body_rate[:, 1] + yaw_rate * body[:, 0]
    offset_rate = np.stack([c * bx - s * by, s * bx + c * by], axis=1)

    def at(t: np.ndarray, x: np.ndarray) -> np.ndarray:
        return np.stack([np.interp(t, att.t, x[:, k]) for k in range(2)], axis=1)

    out = replace(inputs, gnss_position=replace(pos, z=pos.z - at(pos.t, offset)))
    if vel is not None:
        out = replace(out, gnss_velocity=replace(vel, z=vel.z - at(vel.t, offset_rate)))
    return out


def _course(inputs: NavInputs, t: np.ndarray) -> np.ndarray:
    """The GNSS velocity's course (rad, ENU) at times ``t`` (s), interpolated across slow samples (below 1 m/s);
    0 where the drive never moves faster."""
    vel = inputs.gnss_velocity
    if vel is None:
        return np.zeros_like(t)
    moving = np.hypot(*vel.z.T) > 1.0
    if not moving.any():
        return np.zeros_like(t)
    return np.interp(t, vel.t[moving], np.unwrap(np.arctan2(vel.z[moving, 1], vel.z[moving, 0])))


def with_attitude(traj: Trajectory, att: BodyAttitude | None, reason: str, t0_ns: int, config: Config) -> Trajectory:
    """``traj`` with the radar's horizontal motion as the body rolls and pitches by ``att`` (times in s since
    ``t0_ns``; see :func:`body_attitude`, which gives ``reason``) as its correction; what was done in its
    ``info["attitude"]``."""
    if att is None:
        return replace(traj, info={**traj.info, "attitude": {"applied": False, "reason": reason}})
    lever = _lever_from_roll_axis(phase_centre_lever_arm(config), config)
    offset = np.zeros((len(att.t), 3))
    t_ns = t0_ns + np.round(att.t * 1e9).astype(np.int64)
    offset[:, :2] = tilt_offsets(att.roll, att.pitch, traj.body_heading(t_ns), lever)
    std = np.zeros_like(offset)
    std[:, :2] = abs(lever[2]) * ATTITUDE_STD_RAD
    height = _height_decision(att, config)
    if height["applied"]:
        speed = np.interp(t_ns, traj.t_ns, traj.speed)
        offset[:, 2] = climb(att.t, speed, att.pitch) + tilt_heights(att.roll, att.pitch, lever)
        travelled = cumulative_trapezoid(speed, att.t, initial=0.0)
        std[:, 2] = np.hypot(abs(lever[0]) * ATTITUDE_STD_RAD, att.pitch_bias_std * travelled)
        height["range_m"] = float(np.ptp(offset[:, 2]))
    correction = MotionCorrection(t_ns, offset, std)
    moved = np.hypot(offset[:, 0] - offset[:, 0].mean(), offset[:, 1] - offset[:, 1].mean())
    info = {**att.to_dict(), "applied": True, "reason": reason,
            "radar_above_axis_m": float(lever[2]), "offset_rms_mm": float(1e3 * np.sqrt(np.mean(moved**2))),
            "offset_max_mm": float(1e3 * moved.max()), "height": height}
    return replace(traj, correction=correction, info={**traj.info, "attitude": info})


def _height_decision(att: BodyAttitude, config: Config) -> dict[str, Any]:
    """Whether the radar's height is taken from ``att``, and why (the trajectory's info["attitude"]["height"])."""
    if not config.navigation.radar_height:
        return {"applied": False, "reason": "navigation.radar_height is off: the radar at a fixed height"}
    if not math.isfinite(att.pitch_bias):
        why = (f"{att.pitch_bias_samples} GNSS climb rates above {PITCH_BIAS_MIN_SPEED_MPS:g} m/s"
               if att.pitch_bias_samples else "no GNSS vertical velocity")
        return {"applied": False, "reason": f"{why} to take the IMU's pitch bias out: the radar at a fixed height"}
    return {"applied": True, "reason": "the radar's height from the IMU's pitch along the drive, its bias "
                                       "measured on the GNSS's vertical velocity"}


def with_standstill(inputs: NavInputs, config: Config, spans: list[tuple[float, float]] | None = None
                    ) -> tuple[NavInputs, list[tuple[float, float]]]:
    """``inputs`` with a zero yaw rate at every gyro sample where the wheels stand still
    (:func:`.wheel_speeds.standstill_yaw_rate`, std ``navigation.standstill_yaw_rate_std_dps``; none where it is 0),
    and those standstills (s since ``inputs.t0_ns``; ``spans``: these, not the wheels' own)."""
    spans = standstill_spans(inputs.wheels) if spans is None else spans
    gyro_t = np.concatenate([g.t for g in inputs.gyros]) if inputs.gyros else np.zeros(0)
    zero = standstill_yaw_rate(spans, gyro_t, np.deg2rad(config.navigation.standstill_yaw_rate_std_dps))
    return replace(inputs, standstill=zero), spans


def sarmin_with_fits(inputs: NavInputs, config: Config, smooth: bool = True
                              ) -> tuple[NavSolution, dict, dict, float]:
    """SAR-MIN with the terms fitted to the drive on a first pass without the steering: the steering's understeer
    gradient and yaw lag against the gyros (:mod:`.understeer`, with ``navigation.estimate_understeer``), and the
    rear tyres' slip gain against the GNSS velocity (:mod:`.rear_slip`, with ``navigation.estimate_rear_slip``).

    Where the drive shows the car steering otherwise than the kinematic bicycle (K off the vehicle's, or a yaw lag,
    by more than ``SIGNIFICANT`` std and the ``MIN_*`` sizes) the steering is left out, and its tyres are known to
    slip (:func:`rear_slip_gain`). The first pass is the solution where the steering is left out and no rear slip
    shows; else SAR-MIN runs once more, with the steering or without it and with the slip gain that showed. Returns
    the solution, what the steering fit found and why the steering was or was not used, the same for the rear
    slip, and the slip gain navigated with."""
    nav, veh = config.navigation, config.vehicle
    test_steering = nav.estimate_understeer and inputs.steering is not None
    first_inputs = replace(inputs, steering=None) if test_steering else inputs
    # the first pass's states feed the fits; its covariance is smoothed only where it is the solution
    first = run_sarmin(first_inputs, config, smooth=smooth, smoothed_covariance=False)
    if test_steering:
        info = steering_fit(inputs, config, first)
    else:  # no steering: nothing to say (navigate leaves "understeer" out of its info)
        info = {"steering_left_out": False, "gradient": veh.understeer_gradient_rad_per_mps2,
                "reason": f"{steering_used(veh.understeer_gradient_rad_per_mps2)} "
                          "(navigation.estimate_understeer is off)" if inputs.steering else "no steering"}
    left_out = bool(info["steering_left_out"])
    # a steering refused as not this car's says nothing of its tyres
    gain, slip_info = rear_slip_gain(inputs, config, first, tyres_slip=left_out and not info.get("refused"))
    slip_config = replace(config, vehicle=replace(veh, rear_slip_gain_rad_per_mps2=gain))
    if test_steering and not left_out:
        return run_sarmin(inputs, slip_config, smooth=smooth), info, slip_info, gain
    rerun = gain != veh.rear_slip_gain_rad_per_mps2
    sol = run_sarmin(first_inputs, slip_config, smooth=smooth) if rerun else with_smoothed_covariance(first)
    return sol, info, slip_info, gain


def steering_used(vehicle_k: float) -> str:
    """What navigated with the steering: the vehicle's understeer gradient (the start of a fit's ``reason``)."""
    return f"steering used with the vehicle's understeer gradient {vehicle_k:.3g} rad per m/s^2"


def steering_fit(inputs: NavInputs, config: Config, first: NavSolution) -> dict:
    """What the steering fit (:mod:`.understeer`) finds on ``first`` (a pass without the steering), and whether
    the steering is left out (``steering_left_out``): where K differs from the vehicle's, or a yaw lag shows, by more
    than ``SIGNIFICANT`` std and the ``MIN_*`` sizes, with K's std at most ``understeer_max_std_rad_per_mps2``.
    Its ``reason`` says what SAR-MIN navigated with (the steering, with the vehicle's K, or without it) and why."""
    nav, veh = config.navigation, config.vehicle
    vehicle_k = {"steering_left_out": False, "gradient": veh.understeer_gradient_rad_per_mps2}
    used = steering_used(veh.understeer_gradient_rad_per_mps2)
    common_scale_std = wheel_scale_mean_std(first.P[-1], first.state_names) or 0.0
    fit = fit_understeer(inputs, first.t, first.x, veh.wheelbase_m, nav.steering_min_speed_mps, common_scale_std)
    if fit is None:
        return {**vehicle_k, "reason": f"{used}: no steering samples above navigation.steering_min_speed_mps to "
                                       "test it on"}
    if said := steering_gain_error(fit, veh.wheelbase_m, veh.steering_ratio):
        return replace(fit, steering_left_out=True, reason=f"{said}; navigated without the steering").to_dict() | {
            "refused": True, "warning": f"steering: [sensors.{inputs.steering.name}] {said}; navigated without it"}
    drive_k = f"the drive's ({fit.gradient:.3g} +- {fit.std:.2g})"
    if not fit.std <= nav.understeer_max_std_rad_per_mps2:
        return replace(fit, reason=f"{used}: {drive_k} too uncertain to test it (std above "
                                   f"navigation.understeer_max_std_rad_per_mps2; lateral acceleration "
                                   f"{fit.lateral_accel_rms_mps2:.2f} m/s^2 RMS)").to_dict()
    if not (_shows(fit.gradient - veh.understeer_gradient_rad_per_mps2, fit.std, MIN_UNDERSTEER_CHANGE)
            or (_shows(fit.yaw_lag_coefficient_s2, fit.yaw_lag_coefficient_std_s2, 0.0)
                and abs(fit.yaw_lag_s) > MIN_YAW_LAG_S)):
        return replace(fit, reason=f"{used}: {drive_k} within {SIGNIFICANT:g} std or {MIN_UNDERSTEER_CHANGE:g} of "
                                   f"it, its yaw lag ({fit.yaw_lag_s * 1000:.1f} ms) within {SIGNIFICANT:g} std or "
                                   f"{MIN_YAW_LAG_S * 1000:g} ms of 0").to_dict()
    return replace(fit, steering_left_out=True, reason=(
        f"steering left out: the car does not steer as the kinematic bicycle (its understeer gradient "
        f"{fit.gradient:.3g} +- {fit.std:.2g} rad per m/s^2, the vehicle's {veh.understeer_gradient_rad_per_mps2:.3g}; "
        f"its yaw lag {fit.yaw_lag_s * 1000:.1f} ms)")).to_dict()


def steering_gain_error(fit: UndersteerFit, wheelbase_m: float, steering_ratio: float) -> str | None:
    """Why the steering is not this car's road-wheel angle, where its slope against the kinematic angle (``fit.gain``)
    lies beyond what a car steers at the drive's speeds (:data:`UNDERSTEER_RANGE`, :data:`STEERING_GAIN_TOLERANCE`)
    by :data:`STEERING_GAIN_SIGNIFICANT` std, where the turns make the kinematic angle (the steering follows it by
    :data:`MIN_STEERING_CORRELATION`, or the yaw rate varies by ``MIN_TURNING_RADPS`` RMS): elsewhere the gyros' errors
    are much of it, and shrink the gain towards 0; else None."""
    if abs(fit.gain_correlation) < MIN_STEERING_CORRELATION and fit.yaw_rate_rms_radps < MIN_TURNING_RADPS:
        return None
    v2_over_l = fit.gain_speed_mps**2 / wheelbase_m
    # no car steers against its turn: an oversteering one's gain reaches 0 only at its critical speed
    low = max((1.0 + UNDERSTEER_RANGE[0] * v2_over_l) / STEERING_GAIN_TOLERANCE, 0.0)
    high = (1.0 + UNDERSTEER_RANGE[1] * v2_over_l) * STEERING_GAIN_TOLERANCE
    margin = STEERING_GAIN_SIGNIFICANT * fit.gain_std
    if low - margin <= fit.gain <= high + margin:
        return None
    size, within = abs(fit.gain), np.log(STEERING_GAIN_TOLERANCE)
    causes = ["its sign turned"] if fit.gain < 0 else []
    if size > 0 and abs(np.log(size * np.pi / 180.0)) < within:
        causes.append("degrees read as radians (its DBC unit?)")
    elif size > 0 and abs(np.log(size * 180.0 / np.pi)) < within:
        causes.append("radians read as degrees")
    elif size > 0 and abs(np.log(size * steering_ratio)) < within:
        causes.append("the road wheels' angle where the steering wheel's is expected")
    elif size < 0.1:
        causes.append("it hardly follows the turns (a stuck sensor, another signal, another drive's?)")
    elif abs(np.log(size)) > 2 * within:
        causes.append(f"a DBC factor, or vehicle.steering_ratio {steering_ratio:g}?")
    return (f"it reads {fit.gain:.3g} times the road-wheel angle the gyros and wheels give (+- {fit.gain_std:.2g}; a "
            f"car steers {low:.2f}-{high:.2f} times it at the drive's {fit.gain_speed_mps:.1f} m/s)"
            + (f": {', '.join(causes)}" if causes else ""))


def rear_slip_gain(inputs: NavInputs, config: Config, first: NavSolution, tyres_slip: bool = False
                   ) -> tuple[float, dict]:
    """The rear-slip gain to navigate with: the one fitted on ``first`` (:mod:`.rear_slip`) where its std is at most
    ``navigation.rear_slip_max_std_rad_per_mps2`` and it differs from the vehicle's by ``MIN_REAR_SLIP_CHANGE`` and,
    unless ``tyres_slip``, by ``SIGNIFICANT`` std; else the vehicle's. Also what the fit found, and why.

    ``tyres_slip``: the steering fit showed the car steering otherwise than the kinematic bicycle (its tyres carry
    their lateral forces at slip angles), so a rear slip gain of 0 is known wrong and the fitted one is the better
    estimate even where its noise could make it: on test3's full vehicle the fit scatters by 1.2e-3 about the
    tyres' 6.6e-3, and at 3 std one drive in ten kept 0."""
    nav, veh = config.navigation, config.vehicle
    own = veh.rear_slip_gain_rad_per_mps2
    if not nav.estimate_rear_slip:
        return own, {"applied": False, "gain": own, "reason": "navigation.estimate_rear_slip is off"}
    fit = fit_rear_slip(inputs, first.t, first.x, gnss_lever_rear(inputs, config), own)
    if fit is None:
        return own, {"applied": False, "gain": own, "reason": "fewer than 20 GNSS velocities while moving"}
    if not fit.std <= nav.rear_slip_max_std_rad_per_mps2:
        why = (f"g's std {fit.std:.2g} above navigation.rear_slip_max_std_rad_per_mps2 (lateral acceleration "
               f"{fit.lateral_accel_rms_mps2:.2f} m/s^2 RMS): the vehicle's {own:g}")
        return own, replace(fit, reason=why).to_dict()
    if not _shows(fit.gain - own, fit.std if not tyres_slip else 0.0, MIN_REAR_SLIP_CHANGE):
        why = (f"g within {MIN_REAR_SLIP_CHANGE:g} of the vehicle's {own:g}" if tyres_slip else
               f"g within {SIGNIFICANT:g} std or {MIN_REAR_SLIP_CHANGE:g} of the vehicle's {own:g}")
        return own, replace(fit, reason=why).to_dict()
    why = "fitted to the drive" + (" (the steering shows the tyres slip)" if tyres_slip else "")
    return fit.gain, replace(fit, applied=True, reason=f"{why}: the rear axle's course turned by it").to_dict()


def navigate(drive_path: str | Path, method: str, config: Config, *, smooth: bool = True,
             truth_path: str | Path | None = None) -> Trajectory:
    """Estimate the trajectory of a drive.h5 with ``method`` (sar-min, ins, gnss, none, truth)."""
    if method not in METHODS:
        raise NavInputError(f"unknown method {method!r} (choose from {', '.join(METHODS)})")
    t0 = time.perf_counter()
    with Drive(drive_path) as drive:
        inputs = load_inputs(drive, config)
        # which recording this is: focus refuses a drive none of whose frames match (another drive's trajectory)
        recording = drive.radar().fingerprint() if drive.radar_names() else None
        if method == "ins":
            from autosar_cli.nav.ins import load_ins_inputs

            ins_inputs = load_ins_inputs(drive, config, inputs.origin, inputs.t0_ns)
        if method == "truth":
            from autosar_cli.sim.truth import truth_radar_mismatch

            truth_path = truth_path or default_truth_path(drive)
            if truth_path is None:
                raise NavInputError(f"{drive_path}: no truth sidecar found; give --truth LOG.truth.h5")
            if why := truth_radar_mismatch(truth_path, drive):
                raise NavInputError(why)
        damage = list(drive.damage)  # rows of a damaged drive left out of its tables: gaps the filter bridges
        can_logs = can_log_files(drive)
    if method == "sar-min":
        if not inputs.gyros:  # the baselines need none: a drive of GNSS alone has its gnss and none tracks
            raise NavInputError(f"{drive_path}: no gyro to fuse (config navigation.gyros is empty): SAR-MIN needs "
                                "one (--method gnss or none do not)")
        inputs, can_clock = can_clock_corrected(inputs, config, can_logs)
        if why := wheel_scale_error(inputs):
            raise NavInputError(f"{drive_path}: {why}")
        inputs, wheel_scale = wheel_scale_corrected(inputs)
        inputs, flipped = without_flipped_gyros(inputs)
        inputs, can_latency, gnss_latency, imus_late = latencies_corrected(inputs, config)
        inputs, gnss_slow_error = gnss_slow_error_checked(inputs, config.navigation.estimate_gnss_noise)
        inputs, gnss_noise = gnss_noise_checked(inputs, config.navigation.estimate_gnss_noise)
        inputs, velocity_correlation = velocity_decorrelated(
            inputs, gnss_speed_residual(inputs, gnss_lever_rear(inputs, config), config.vehicle.wheelbase_m),
            config.navigation.estimate_gnss_noise, config.navigation.gnss_velocity_error_states)
        # from the wheels as recorded: the lag's corrections below leave out rows at a standstill's ends
        inputs, standstill = with_standstill(inputs, config)
        fits_config = with_fit_bounds_widened(config, gnss_noise)
        inputs, wheel_lag, wheel_radii = wheel_speeds_corrected(inputs, fits_config)
        attitude, attitude_reason = body_attitude(inputs, config)
        if attitude is not None:
            inputs = gnss_on_level_body(inputs, attitude, config)
        sol, understeer, rear_slip, slip_gain = sarmin_with_fits(inputs, fits_config, smooth=smooth)
        turning = (turning_standstills(standstill, inputs.gyros, sol.t, sol.x[:, m.OMEGA],
                                       sol.x[:, [sol.state_names.index(f"bias.{g.name}") for g in inputs.gyros]])
                   if inputs.standstill is not None else [])
        if turning:  # the car crept below the wheels' lowest reading: navigated again without those spans
            refused = [span for span, _, _ in turning]
            standstill = [span for span in standstill if span not in refused]
            inputs, _ = with_standstill(inputs, config, standstill)
            sol, understeer, rear_slip, slip_gain = sarmin_with_fits(inputs, fits_config, smooth=smooth)
        sol, before_first_fix = dead_reckoned_start(sol, inputs, slip_gain)
        t_ns = inputs.t0_ns + np.round(sol.t * 1e9).astype(np.int64)
        # the filter's heading is the body's; the trajectory's is the rear axle's course, the body turned from it
        course = np.unwrap(sol.x[:, m.PSI]) - slip_gain * sol.x[:, m.V] * sol.x[:, m.OMEGA]
        traj = Trajectory("sar-min", t_ns, sol.x[:, [m.PX, m.PY]], course, sol.x[:, m.V],
                          sol.x[:, m.OMEGA], inputs.origin, config.vehicle.cog_to_rear_axle_m,
                          config.vehicle.cog_height_m, state=sol.x, state_names=sol.state_names,
                          covariance=sol.P, rear_slip_gain=slip_gain,
                          info={"updates": sol.updates, "rejected": sol.rejected, "smoothed": smooth,
                                **({"understeer": understeer} if inputs.steering is not None else {}),
                                "rear_slip": rear_slip, "wheel_lag": wheel_lag,
                                "wheel_radii": wheel_radii, "wheel_scale": wheel_scale, "gnss_noise": gnss_noise,
                                "gnss_slow_error": gnss_slow_error, "gnss_latency": gnss_latency,
                                "can_latency": can_latency,
                                "gnss_velocity_correlation": velocity_correlation,
                                "before_first_fix": before_first_fix, "gnss_gaps": gnss_gaps(inputs),
                                "standstill_ns": [[inputs.t0_ns + int(round(x * 1e9)) for x in span]
                                                  for span in standstill],
                                # wheels at 0 that the gyros contradict: the car crept and turned (no zero yaw rate)
                                "standstill_refused": [
                                    {"span_ns": [inputs.t0_ns + int(round(x * 1e9)) for x in span],
                                     "yaw_rate_dps": round(float(np.rad2deg(rate)), 4),
                                     "std_dps": round(float(np.rad2deg(std)), 4)} for span, rate, std in turning],
                                "wheel_gaps": [g.to_dict() for g in wheel_gaps(inputs.wheels, inputs.gnss_velocity,
                                                                               inputs.t0_ns)]})
        if config.navigation.gnss_heading:
            traj.info["gnss_heading"] = gnss_heading_info(sol, inputs)
        warnings = can_clock + flipped + imus_late + [w["warning"] for w in (gnss_latency, understeer)
                                                      if "warning" in w]
        if warnings := warnings + gated_streams(sol.updates, sol.rejected):
            traj.info["warnings"] = warnings
        traj = with_attitude(traj, attitude, attitude_reason, inputs.t0_ns, config)
    elif method == "ins":
        from autosar_cli.nav.ins import run_ins

        try:
            traj = run_ins(ins_inputs, config)
        except NavInputError as exc:  # its reasons name no drive
            raise NavInputError(f"{drive_path}: {exc}") from None
        if ins_warnings := [w for w in ins_inputs.warnings if w not in inputs.warnings]:  # its receiver's own
            traj.info["warnings"] = [*traj.info.get("warnings", []), *ins_warnings]
    elif method in ("gnss", "none"):
        try:
            traj = (gnss_only if method == "gnss" else straight_line)(inputs, config)
        except NavInputError as exc:  # the baselines' reasons name no drive
            raise NavInputError(f"{drive_path}: {exc}") from None
    else:
        traj = from_truth(str(truth_path), inputs.origin, config, radar_motion=True)
        traj.info["truth"] = os.path.abspath(truth_path)
    traj.info["drive"] = os.path.abspath(drive_path)
    if damage or inputs.warnings:
        traj.info["warnings"] = [*damage, *inputs.warnings, *traj.info.get("warnings", [])]
    if recording is not None:
        traj.info["drive_radar_frames"] = recording
    traj.info["elapsed_s"] = time.perf_counter() - t0
    return traj
