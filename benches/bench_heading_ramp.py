"""Benchmark what a heading ramp leaves on the track: the worst reflector with the yaw-rate error known (truth).

Usage: python benches/bench_heading_ramp.py --keep DIR [--drives urban:0,urban:1,...]
                                            [--output benches/results/heading_ramp.json]

The gyros' biases drift (Gauss-Markov, 0.002-0.005 deg/s over 100-150 s), and SAR-MIN tells their common part from
the car's yaw rate only through the GNSS velocity's course. What it leaves is, to first order, one number per drive:
a yaw-rate error ``b`` (rad/s), which turns the track by ``b (t - t_c)`` about the instant ``t_c`` nearest its
centroid and so bends it by ``b`` times the integral of ``(t - t_c) J dp`` (``J``: a quarter turn left; the radar's
lever arm turned with it), 5 cm over urban's 200 m at 3.4e-5 rad/s. No pass of a point sees it (it bends a 26 m pass
by well under a millimetre).

Per drive (``simulate --dynamics full``, ``ingest``, ``navigate``, kept under DIR/<scenario><seed> as
bench_af_pass_ranges.py keeps them): SAR-MIN's track and the slow motion's (``sar.pass_ranges``, the product's first
autofocus stage; the phases after it move the track by millimetres), each one's ramp fitted to the truth with the
rigid motion (a least-squares fit of the radar's track error at 10 Hz), and each one's worst error with and
without its ramp where a corner reflector is imaged: the track's, after the evaluation's rigid alignment, at each
reflector's zero-Doppler instant (bench_nav_seeds.py's ``reflector_track_max_cm``; no image is focused: the
product's misses on urban are within 0.2 cm of their slow track's figure). The summary: per track, the drives within
2 cm and the median; the RMS of the slow motion's scale error (against SAR-MIN's, as bench_af_pass_ranges.py reads
it) over its stated std, and over the nodes' share of it alone (without ``heading_ramp_scale_std``). Beside each
ramp, the track's course drift: how fast its course at the GNSS antenna turns away from the truth's, a weighted
slope at the GNSS velocity's instants (:func:`course_drift`), against the course floor, that slope's std from the
course alone (each sample ``sigma_v / v`` rad, :func:`course_floor`): the drift is the yaw-rate error proper, the
ramp also takes what the track's other errors (along it, through the turns) project on its bend. The rows hold each
drive's ramps, drifts (deg/s) and figures. The committed file: ``--drives
urban:0,...,urban:15`` (~10 min; the drives of af_pass_ranges.json and paper_full_car.json's urban rows).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_af_pass_ranges import kept_drive  # noqa: E402
from bench_nav_seeds import reflector_track_errors  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
WITHIN_CM = 2.0
TRACKS = ("sar-min", "sar-min less ramp", "slow", "slow less ramp")


def fitted_ramp(est: Any, truth: Any, config: Any) -> float:
    """The yaw-rate error (rad/s) that, with a rigid motion, best fits ``est``'s radar track error against the
    truth's at 10 Hz over the moving instants."""
    from autosar_cli.evaluate.trajectory_metrics import common_instants
    from autosar_cli.nav.trajectory import centre_instant, heading_ramp_displacement, radar_track

    t = common_instants(est, truth.trajectory, rate_hz=10.0)
    a, b = radar_track(est, t, config), radar_track(truth.trajectory, t, config)
    c, n = a.mean(axis=0), len(t)
    design = np.column_stack([np.tile([1.0, 0.0], n), np.tile([0.0, 1.0], n),
                              np.column_stack([-(a[:, 1] - c[1]), a[:, 0] - c[0]]).ravel(),
                              heading_ramp_displacement(est, t, centre_instant(est), config).ravel()])
    x, *_ = np.linalg.lstsq(design, (a - b).ravel(), rcond=None)
    return float(x[-1])


def course_samples(drive_path: Path, config: Any, track: Any, truth: Any) -> tuple[Any, Any, Any]:
    """The GNSS velocity's instants (ns) where the car moves (above 0.5 m/s) and both ``track`` and ``truth`` hold
    (0.1 s inside their ends), the weight of each one's course as SAR-MIN weighs it, ``(v / sigma_v)^2``
    (1/rad^2), and the antenna's (1, 3) lever arm (m, body)."""
    from autosar_cli.nav.gnss_noise import gnss_noise_checked
    from autosar_cli.nav.inputs import load_inputs
    from autosar_cli.store.drive import Drive

    with Drive(drive_path) as drive:
        inputs = load_inputs(drive, config)
    inputs, _ = gnss_noise_checked(inputs, config.navigation.estimate_gnss_noise)
    vel = inputs.gnss_velocity
    speed = np.hypot(vel.z[:, 0], vel.z[:, 1])
    t_ns = inputs.t0_ns + np.round(vel.t * 1e9).astype(np.int64)
    keep = ((speed > 0.5) & (t_ns > max(track.t_ns[0], truth.t_ns[0]) + 100_000_000)
            & (t_ns < min(track.t_ns[-1], truth.t_ns[-1]) - 100_000_000))
    return t_ns[keep], (speed[keep] / vel.sigma[0]) ** 2, np.array([inputs.gnss_lever_m])


def _slope(t_ns: Any, weight: Any, y: Any | None = None) -> tuple[float, float]:
    """Weighted least-squares slope (per s) of ``y`` over ``t_ns`` with an offset (0 without ``y``), and its std
    from the weights alone."""
    t_s = (t_ns - t_ns[0]) / 1e9
    dt = t_s - np.sum(weight * t_s) / np.sum(weight)
    sxx = np.sum(weight * dt**2)
    return (0.0 if y is None else float(np.sum(weight * dt * y) / sxx)), float(1.0 / np.sqrt(sxx))


def course_floor(samples: Any) -> float:
    """The std (rad/s) of a yaw-rate error that the GNSS velocity's course alone leaves (each sample's course
    noise ``sigma_v / v``)."""
    t_ns, weight, _ = samples
    return _slope(t_ns, weight)[1]


def course_drift(track: Any, truth: Any, samples: Any) -> float:
    """How fast ``track``'s course at the GNSS antenna turns away from the truth's (rad/s): a weighted slope at the
    GNSS velocity's ``samples`` (:func:`course_samples`)."""
    from autosar_cli.nav.frames import wrap_angle

    t_ns, weight, lever = samples
    half = 50_000_000

    def course(trajectory: Any) -> Any:
        ahead, behind = (trajectory.body_points(t_ns + d, lever)[:, 0, :2] for d in (half, -half))
        step = ahead - behind
        return np.arctan2(step[:, 1], step[:, 0])

    return _slope(t_ns, weight, wrap_angle(course(track) - course(truth)))[0]


def less_ramp(trajectory: Any, ramp: float, config: Any) -> Any:
    """``trajectory`` with the motion of the yaw-rate error ``ramp`` (rad/s) taken out."""
    from autosar_cli.nav.trajectory import centre_instant, heading_ramp_displacement
    from autosar_cli.sar.pass_ranges import with_correction
    from autosar_cli.types import MotionCorrection

    t = trajectory.t_ns
    offset = -ramp * heading_ramp_displacement(trajectory, t, centre_instant(trajectory), config)
    return with_correction(trajectory, MotionCorrection(t, np.column_stack([offset, np.zeros(len(t))]),
                                                        np.zeros((len(t), 3))))


def drive_row(work: Path) -> dict[str, Any]:
    from autosar_cli.config import load_config
    from autosar_cli.evaluate.evaluation import load_truth
    from autosar_cli.evaluate.trajectory_metrics import common_instants, radar_track_scale
    from autosar_cli.sar.focus import FocusOptions
    from autosar_cli.sar.pass_ranges import estimate_slow_motion, heading_ramp_scale_std
    from autosar_cli.sar.point_selection import candidate_points
    from autosar_cli.sar.residual_motion import AutofocusOptions
    from autosar_cli.store.drive import radar_times
    from autosar_cli.store.trajectory import read_trajectory

    config = load_config()
    drive = work / "drive.h5"
    est = read_trajectory(work / "sarmin.h5")
    truth = load_truth(work / "log.mcap.truth.h5", est.origin, config)
    focus = FocusOptions.from_config(config)
    points = candidate_points(drive, est, config, focus, AutofocusOptions())
    motion = estimate_slow_motion(drive, est, config, points, focus)
    slow = motion.trajectory
    frames = radar_times(drive)
    t = common_instants(est, truth.trajectory, frames)
    # the slow motion's scale against SAR-MIN's scale error, over its std with and without the ramp's share
    error = motion.scale - radar_track_scale(est, truth.trajectory, frames, config)
    ramp_std = heading_ramp_scale_std(est, config)
    row: dict[str, Any] = {"slow_scale_error_pct": round(100 * error, 4), "slow_scale_std_pct":
                           round(100 * motion.scale_std, 4), "ramp_scale_std_pct": round(100 * ramp_std, 4),
                           "slow_scale_z": round(error / motion.scale_std, 2),
                           "slow_scale_z_nodes": round(error / np.sqrt(motion.scale_std**2 - ramp_std**2), 2)}

    def worst_cm(track: Any) -> float:
        return round(100 * float(np.max(np.hypot(*reflector_track_errors(track, truth, config, t)))), 2)

    samples = course_samples(drive, config, est, truth.trajectory)  # the slow track keeps SAR-MIN's instants
    row["course_floor_deg_per_s"] = round(float(np.rad2deg(course_floor(samples))), 6)
    for name, track in (("sar-min", est), ("slow", slow)):
        ramp = fitted_ramp(track, truth, config)
        row[f"{name}_ramp_deg_per_s"] = round(float(np.rad2deg(ramp)), 6)
        row[f"{name}_course_drift_deg_per_s"] = round(float(np.rad2deg(course_drift(track, truth.trajectory,
                                                                                      samples))), 6)
        row[name], row[f"{name} less ramp"] = worst_cm(track), worst_cm(less_ramp(track, ramp, config))
    return row


def rms(values: list[float], digits: int) -> float:
    return round(float(np.sqrt(np.mean(np.square(values)))), digits)


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per track: the drives within ``WITHIN_CM`` and the median worst error; the ramps and course drifts, RMS,
    and their correlation; the scale's z, RMS."""
    out: dict[str, Any] = {}
    for name in TRACKS:
        worst = [r[name] for r in rows]
        out[f"{name} within {WITHIN_CM:g} cm"] = sum(w <= WITHIN_CM for w in worst)
        out[f"{name} median cm"] = round(float(np.median(worst)), 2)
    out["course floor RMS deg/s"] = rms([r["course_floor_deg_per_s"] for r in rows], 6)
    for name in ("sar-min", "slow"):
        ramps, drifts = ([r[f"{name}_{key}_deg_per_s"] for r in rows] for key in ("ramp", "course_drift"))
        out[f"{name} course drift RMS deg/s"] = rms(drifts, 6)
        out[f"{name} ramp RMS deg/s"] = rms(ramps, 6)
        if len(rows) > 1:
            out[f"{name} ramp vs course drift, correlation"] = round(float(np.corrcoef(ramps, drifts)[0, 1]), 2)
    for key, label in (("slow_scale_z", "slow scale z RMS"), ("slow_scale_z_nodes", "the nodes' alone")):
        out[label] = rms([r[key] for r in rows], 2)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drives", default="urban:0,urban:1", help="scenario:seed,...")
    ap.add_argument("--keep", type=Path, required=True, help="each drive's files under DIR/<scenario><seed>")
    ap.add_argument("--output", type=Path, default=RESULTS / "heading_ramp.json")
    args = ap.parse_args()
    rows: list[dict[str, Any]] = []
    args.output.parent.mkdir(parents=True, exist_ok=True)
    for item in args.drives.split(","):
        scenario, seed = item.split(":")
        start = time.perf_counter()
        row = {"scenario": scenario, "seed": int(seed),
               **drive_row(kept_drive(scenario, int(seed), args.keep / f"{scenario}{seed}"))}
        rows.append(row)
        print(json.dumps(row), f"({time.perf_counter() - start:.0f} s)", flush=True)
        # after every drive, so that a stopped run keeps what it measured
        args.output.write_text(json.dumps({"benchmark": "heading_ramp", "drives": len(rows), "summary": summary(rows),
                                           "rows": rows}, indent=1) + "\n")
    print(json.dumps(summary(rows), indent=1))


if __name__ == "__main__":
    main()
