"""Benchmark the paper's comparison over several seeds: how often each accuracy criterion holds per method.

Usage: python benches/bench_paper.py [--scenarios test1,test2,test3] [--seeds 0-9] [--dynamics full] [--keep]

For every scenario and seed: ``autosar simulate --scenario S --seed N`` (MCAP), then ``autosar compare LOG -o DIR
--methods none,ins,sar-min,truth --json`` (``--methods`` adds e.g. sar-min+af). Per drive it records, for every
navigated method, the worst corner reflector (whole-track and local alignment), the worst peak loss and the RPE across
track over 1 m and 10 m; the entropies (whole image, range-normalised, far swath) of every method and whether they
fall in the paper's order; SAR-MIN's track scale against the truth's (the similarity fitted to the phase-centre
tracks) beside what the GNSS velocity alone allows (its mean along-track error over the drive), and the wall times.
Prints one line per drive and a summary (medians, counts of drives meeting each criterion); writes
benches/results/paper.json after every drive (the committed file: the kinematic car, ``--dynamics kinematic``,
as ``make bench-paper`` runs it), and ``--resume`` skips the drives already in it.
A drive's outputs are deleted after it is measured unless --keep (test2 is ~0.5 GB of log and ~1 GB of products).
The full vehicle model's runs: the ablation, one run per ``--components`` set, to
benches/results/paper_ablation.json with ``--resume`` (``make bench-ablation``); ``--understeer-gradient K`` and
``--rear-slip-gain G`` give SAR-MIN's steering model an understeer term and its motion model the rear tyres' slip;
``--no-fits`` navigates in one pass without the fitted
wheel-speed lag, slip and load gains, rear slip and the steering test (the A/B: benches/results/paper_fits.json,
before the slip and load gains). With them: ``--scenarios test3,urban --seeds 0,1 --methods sar-min,sar-min+af
--dynamics full --output benches/results/paper_wheel_radii.json``; ``--planar`` leaves SAR-MIN's radar on a planar
body, not moved by the IMU's roll and pitch (for an A/B).
The 40 drives, the product as it is (``make bench-paper-full``): ``--scenarios test1,test2,test3,urban --seeds 0-9
--methods sar-min,sar-min+af --dynamics full --output benches/results/paper_full_slow.json``. Older states of the
autofocus on them (the file's ``note`` says which): the phases alone, benches/results/paper_full_level.json; before
the level GNSS antenna, the load-compliant wheels, the lag's stated window and the rear slip:
benches/results/paper_full_fits.json; with ``--radar-height`` (its rows lack the flag; 29 drives):
benches/results/paper_full_height.json.
Another car (``--car``: entries of the simulated car's [vehicle_dynamics]; the processor keeps the config's):
``--scenarios test1,test2,test3 --seeds 10,11 --dynamics full --methods sar-min,sar-min+af --car
mass_kg=1900,cornering_stiffness_front_n_per_rad=70000.0,cornering_stiffness_rear_n_per_rad=95000.0,
roll_gradient_deg_per_g=5.5,pitch_gradient_deg_per_g=3.0,road_class='"B"' --output
benches/results/paper_full_car.json``, with the config's car on seeds 10-16 beside it (no ``--car``, ``--seeds 10-16
--resume``): 21 drives outside the 40, to show their figures are not tuned to their seeds; seeds 17-18 add the
config's car, a softer one (``--car``) and a radar case that shakes more (``--simulation``: entries of [simulation],
for the simulator only), with ``--resume`` into the same file (commands in docs/AUTOFOCUS.md).
SAR-MIN's own settings otherwise than the config (``--navigation``: entries of [navigation], e.g.
``wheel_lag_window_always=true``; rows and groups name them), side by side with the config's in
benches/results/paper_fits.json. The processor's own [processing] settings otherwise than the config
(``--processing``, e.g. ``autofocus_fast_motion=true``): benches/results/paper_full_fast.json, and with the stage's
``FastMotionOptions.apply_reliability`` on (at b036e0c, where it was the stage's form):
benches/results/paper_full_fast_reliability.json. What the processor is told of the radar otherwise than the config
(``--radar``: entries of [radar], e.g. ``clock_drift_ppm=500.0`` beside ``--simulation radar_clock_drift_ppm=500.0``):
benches/results/paper_full_car.json, groups "[radar ...]". A radar mounted otherwise than the config's, the
processor told so (``--mounted-radar``: entries of [radar] for both, e.g. ``mounting.yaw_deg=-90.0``): the same file,
groups "[mounted ...]".
"""

from __future__ import annotations

import argparse
import hashlib
import json
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

RESULTS = Path(__file__).resolve().parent / "results"
METHODS = ("none", "ins", "sar-min", "truth")  # the default; --methods adds sar-min+af
PAPER_ORDER = ("none", "ins", "sar-min", "truth")
ENTROPIES = {"entropy": "whole image", "entropy_rn": "range-normalised", "entropy_far": "far swath"}
# sar-min >= truth allows the entropy's sampling on a 2 cm grid, as the tests do (SAR-MIN minus the truth moved by
# up to 0.16 % over half-pixel shifts of the grid on test1-3 seed 1, lowest -0.03 %; EVALUATION.md)
SARMIN_BELOW_TRUTH_TOLERANCE = 0.001


def parse_seeds(text: str) -> list[int]:
    """'1-5' or '1,3,7' -> seeds."""
    seeds: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        seeds.extend(range(int(lo), int(hi or lo) + 1))
    return seeds


def cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "autosar_cli.cli", *args], check=True, capture_output=True,
                          text=True)


#: what a probe may simulate otherwise than the config the processor keeps: options, and keys of its rows
OTHER_VEHICLE = ("car", "simulation", "sensors")


def variant_tag(options: str) -> str:
    """``--car``/``--navigation``-style options (``key=value,...``) as a file-name part."""
    return re.sub(r"[^A-Za-z0-9.]+", "_", options)


def top_level_items(given: str) -> list[str]:
    """``given`` ("key=value,...") split at the commas outside brackets: a list value, nested too, keeps its own."""
    items, depth, start = [], 0, 0
    for i, ch in enumerate(given):
        depth += (ch == "[") - (ch == "]")
        if ch == "," and depth == 0:
            items.append(given[start:i])
            start = i + 1
    return [*items, given[start:]]


def config_copy(components: str | None, understeer: float | None, work: Path, rear_slip: float | None = None,
                fits: bool = True, attitude: bool = True, radar_height: bool = False, car: str | None = None,
                simulation: str | None = None, sensors: str | None = None, navigation: str | None = None,
                processing: str | None = None, radar: str | None = None) -> Path:
    """A copy of the default config whose full vehicle model has only ``components`` (comma-separated; None: all),
    whose steering model has the understeer gradient ``understeer`` and whose trajectory the rear-slip gain
    ``rear_slip`` (rad per m/s^2; None: the config's); ``fits`` False: SAR-MIN in one pass, without the fitted
    understeer, yaw lag and wheel-speed lag; ``radar_height``: SAR-MIN's radar lifted along the road; ``car``:
    "key=value,..." entries of [vehicle_dynamics], the simulated car (only the simulator reads that section);
    ``simulation``: the same for [simulation]; ``sensors``: "sensor.table.key=value,..." entries of the sensors'
    error tables, e.g. gnss_cog.gnss.velocity_std_mps=0.06 (a copy so changed is for the simulator alone: the
    processor reads its noises from the same tables); ``navigation``: "key=value,..." entries of [navigation], SAR-MIN's
    own settings; ``processing``: the same for [processing]; ``radar``: the same for [radar], what the processor is
    told of the radar (e.g. clock_drift_ppm=500.0; the simulator takes its radar's own from [simulation])."""
    from autosar_cli.config import DEFAULT_CONFIG

    text = DEFAULT_CONFIG.read_text()
    entries: list[tuple[str, str, str, str]] = []  # (option, section, key, value)
    for option, section, given in (("--car", "vehicle_dynamics", car), ("--simulation", "simulation", simulation),
                                   ("--sensors", "sensors", sensors), ("--navigation", "navigation", navigation),
                                   ("--processing", "processing", processing), ("--radar", "radar", radar)):
        for item in top_level_items(given or ""):  # a list value keeps its commas
            if item:
                key, _, value = item.partition("=")
                table, _, key = f"{section}.{key.strip()}".rpartition(".")
                entries.append((option, table, key, value.strip()))
    for option, section, key, value in entries:
        head, header, tail = text.partition(f"\n[{section}]\n")
        body, nxt, rest = tail.partition("\n[")
        line = f"{key} = {value}"
        body, n = re.subn(rf"^{re.escape(key)} = [^#\n]*?(\s*#.*)?$", lambda m, line=line: line + (m.group(1) or ""),
                          body, count=1, flags=re.MULTILINE)
        if not header or n != 1:
            raise SystemExit(f"{option}: {key!r} is not an entry of [{section}]")
        text = head + header + body + nxt + rest
    if components is not None:
        wanted = ", ".join(f'"{c}"' for c in components.split(",") if c)
        text = re.sub(r"^components = \[.*\]$", f"components = [{wanted}]", text, count=1, flags=re.MULTILINE)
    if understeer is not None:
        text = re.sub(r"^understeer_gradient_rad_per_mps2 = \S+", f"understeer_gradient_rad_per_mps2 = {understeer!r}",
                      text, count=1, flags=re.MULTILINE)
    text = re.sub(r'^dbc = "(.*)"$', lambda m: f'dbc = "{(DEFAULT_CONFIG.parent / m.group(1)).as_posix()}"', text,
                  count=1, flags=re.MULTILINE)
    if rear_slip is not None:
        text = re.sub(r"^rear_slip_gain_rad_per_mps2 = \S+", f"rear_slip_gain_rad_per_mps2 = {rear_slip!r}", text,
                      count=1, flags=re.MULTILINE)
    if not attitude:
        text = re.sub(r'^attitude_imu = "\S*"', 'attitude_imu = ""', text, count=1, flags=re.MULTILINE)
    if radar_height:
        text = re.sub(r"^radar_height = false", "radar_height = true", text, count=1, flags=re.MULTILINE)
    if not fits:
        for key in ("estimate_understeer", "estimate_wheel_lag", "estimate_wheel_radii", "estimate_rear_slip"):
            text = re.sub(rf"^{key} = true", f"{key} = false", text, count=1, flags=re.MULTILINE)
    tag = (components.replace(",", "+") or "none") if components is not None else "all"
    variant = (("" if fits else "_nofits") + ("" if attitude else "_planar") + ("_height" if radar_height else "")
               + ("_car" + variant_tag(car) if car else "") + ("_sim" + variant_tag(simulation) if simulation else "")
               + ("_sensors" + variant_tag(sensors) if sensors else "")
               + ("_nav" + variant_tag(navigation) if navigation else "")
               + ("_proc" + variant_tag(processing) if processing else "")
               + ("_radar" + variant_tag(radar) if radar else ""))
    name = f"config_{tag}_us{understeer}_slip{rear_slip}{variant}"
    if len(name) > 200:  # a file name has at most 255 bytes
        name = f"config_{hashlib.sha256(name.encode()).hexdigest()[:16]}"
    path = work / f"{name}.toml"
    path.write_text(text)
    return path


def in_paper_order(e: dict[str, float]) -> bool | None:
    """none > ins > sar-min >= truth (the last within the sampling tolerance); None when a method was not run."""
    if any(m not in e for m in PAPER_ORDER):
        return None
    return (e["none"] > e["ins"] > e["sar-min"]
            and e["sar-min"] >= e["truth"] * (1.0 - SARMIN_BELOW_TRUTH_TOLERANCE))


def track_scale(result_dir: Path) -> float:
    """SAR-MIN's phase-centre track scale against the truth's, less 1, over the radar frames while moving
    (``evaluate.trajectory_metrics.radar_track_scale``)."""
    from autosar_cli.config import load_config
    from autosar_cli.evaluate.trajectory_metrics import radar_track_scale
    from autosar_cli.store.drive import radar_times
    from autosar_cli.store.trajectory import read_trajectory

    est = read_trajectory(result_dir / "sar-min" / "trajectory.h5", covariance=False)
    true = read_trajectory(result_dir / "truth" / "trajectory.h5", covariance=False)
    return radar_track_scale(est, true, radar_times(result_dir / "drive.h5"), load_config())


def gnss_velocity_scale(scenario: str, seed: int, config: Any = None) -> tuple[float, float]:
    """What the fused GNSS velocity alone says of the track's scale, and its standard error (both - 1, not %).

    -(mean along-track error of the GNSS velocity) / (mean speed) over the fixes while moving: the scale of a
    track whose speed were the GNSS's averaged over the drive. The draws are the simulator's own (same seed, same
    sensor stream), so this is exactly the noise in the log; ``config``: the simulator's (None: the default).
    """
    import numpy as np

    from autosar_cli.config import load_config
    from autosar_cli.sim import sensors
    from autosar_cli.sim.scenario import build_scenario
    from autosar_cli.sim.simulate import stream_rng

    config = config or load_config()
    name = config.navigation.gnss
    samples = sensors.gnss(build_scenario(scenario, config).motion, name, config.sensors[name],
                           stream_rng(seed, f"sensor/{name}"))
    v, v_true = samples.values["velocity_enu"][:, :2], samples.truth["velocity_enu"][:, :2]
    speed = np.hypot(*v_true.T)
    moving = speed >= 0.2
    along = np.sum((v - v_true)[moving] * (v_true[moving] / speed[moving, None]), axis=1)
    mean_speed = float(speed[moving].mean())
    return -float(along.mean()) / mean_speed, float(along.std() / np.sqrt(along.size)) / mean_speed


def pct(fraction: float | None) -> float | None:
    """fraction -> % to 1e-4; None (an autofocus that refused has no scale std) stays None."""
    return None if fraction is None else round(100 * fraction, 4)


def mm(metres: float | None) -> float | None:
    """metres -> mm to the micrometre; None (a drive too short for the measure) stays None."""
    return None if metres is None else round(1000 * metres, 3)


def drive_row(scenario: str, seed: int, comparison: dict[str, Any], sim_s: float, compare_s: float) -> dict[str, Any]:
    res = comparison["results"]
    row: dict[str, Any] = {"scenario": scenario, "seed": seed, "simulate_s": round(sim_s, 1),
                           "compare_s": round(compare_s, 1), "skipped": comparison.get("skipped", {})}
    for m in (m for m in res if m != "truth"):
        refl, traj = res[m]["reflectors"], res[m]["trajectory"]
        row[m] = {"reflector_error_max_cm": round(100 * max(r["aligned_error_m"] for r in refl), 2),
                  "reflector_error_local_max_cm": round(100 * max(r["local_aligned_error_m"] for r in refl), 2),
                  "peak_loss_max_db": round(max(r["peak_loss_db"] for r in refl), 2),
                  "peak_loss_min_db": round(min(r["peak_loss_db"] for r in refl), 2),
                  # against where the truth image has each (its own offset, e.g. a road's multipath, left out)
                  "reflector_error_vs_truth_image_max_cm": round(100 * max(r.get("reference_error_m") or 0.0
                                                                            for r in refl), 2),
                  "aligned_rmse_cm": round(100 * traj["aligned_rmse_m"], 2),
                  "rpe_1m_across_mm": mm(traj["rpe_1m_across_m"]), "rpe_10m_across_mm": mm(traj["rpe_10m_across_m"])}
        s = row[m]
        s["within_3cm_1db"] = s["reflector_error_max_cm"] < 3.0 and max(abs(s["peak_loss_max_db"]),
                                                                           abs(s["peak_loss_min_db"])) < 1.0
        # a peak brighter than the truth image's is no loss: the beam's pointing alone moves a peak by tenths of a dB
        s["within_2cm_1db"] = s["reflector_error_max_cm"] <= 2.0 and s["peak_loss_max_db"] <= 1.0
        s["worse"] = s["peak_loss_max_db"] >= 3.0 or s["reflector_error_max_cm"] >= 5.0
    af = comparison.get("autofocus")
    if af:  # the scale the autofocus measured (applied or not), its std and prior: against sarmin_track_scale_pct
        row["af_track_scale_pct"] = pct(af["track_scale"])
        row["af_track_scale_std_pct"] = pct(af["track_scale_std"])
        row["af_track_scale_prior_pct"] = pct(af.get("track_scale_prior_std", 0.0))
        if af.get("radar_mounting_yaw_deg") is not None:  # the boresight it measured, where it took one
            row["af_radar_mounting_yaw_deg"] = round(af["radar_mounting_yaw_deg"], 2)
        slow = af.get("slow_motion")
        if slow:  # the slow motion from the points' passes: applied, its points and what their joint fit leaves
            row["af_slow_motion"] = {k: slow.get(k) for k in ("applied", "points_used", "residual_mm")}
    for key in ENTROPIES:
        e = {m: res[m]["summary"][key] for m in res}
        row[key] = {**{m: round(v, 4) for m, v in e.items()}, "paper_order": in_paper_order(e)}
        if "truth" in e:  # each method's entropy relative to the truth image's
            row[key]["vs_truth_pct"] = {m: round(100 * (v / e["truth"] - 1.0), 3) for m, v in e.items() if m != "truth"}
    return row


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    n = len(rows)
    out: dict[str, Any] = {"drives": n}
    if not n:
        return out
    methods = list(dict.fromkeys(m for r in rows for m in r if isinstance(r[m], dict) and "reflector_error_max_cm"
                                 in r[m]))
    for m in methods:
        key = m.replace("-", "").replace("+", "_")
        if len(ran := [r for r in rows if m in r]) < n:
            out[f"{key}_skipped"] = n - len(ran)
        errs = [r[m]["reflector_error_max_cm"] for r in ran]
        out[f"{key}_reflector_error_max_cm"] = {"median": round(statistics.median(errs), 2), "max": max(errs)}
        out[f"{key}_within_3cm_1db"] = sum(r[m]["within_3cm_1db"] for r in ran)
        out[f"{key}_within_2cm_1db"] = sum(r[m]["within_2cm_1db"] for r in ran)
        out[f"{key}_local_within_3cm"] = sum(r[m]["reflector_error_local_max_cm"] < 3.0 for r in ran)
        out[f"{key}_rpe_1m_across_mm_max"] = max((r[m]["rpe_1m_across_mm"] or 0.0) for r in ran)
        if "vs_truth_pct" in ran[0]["entropy_far"]:
            far = [r["entropy_far"]["vs_truth_pct"][m] for r in ran]
            out[f"{key}_entropy_far_vs_truth_pct_max"] = max(far)
            # the bound on the far swath: within 0.2 % of the truth image's, either way / at most above it
            out[f"{key}_entropy_far_within_0_2pct"] = sum(abs(v) <= 0.2 for v in far)
            out[f"{key}_entropy_far_at_most_0_2pct_above"] = sum(v <= 0.2 for v in far)
        if m in ("none", "ins"):
            out[f"{key}_worse"] = sum(r[m]["worse"] for r in ran)
    for key in ENTROPIES:
        orders = [r[key]["paper_order"] for r in rows if r[key]["paper_order"] is not None]
        if orders:
            out[f"{key}_paper_order"] = sum(orders)

    def rms(values: list[float]) -> float:
        return round(statistics.fmean(v * v for v in values) ** 0.5, 4)

    out["sarmin_track_scale_rms_pct"] = rms([r["sarmin_track_scale_pct"] for r in rows])
    # the autofocus's stated scale std against its error, where it applied one (a scale not applied is exactly 0):
    # RMS 1 when the std says what the scale is worth
    applied = [r for r in rows if r.get("af_track_scale_pct") and r.get("af_track_scale_std_pct")]
    if applied:
        out["af_track_scale_applied"] = len(applied)
        out["af_track_scale_z_rms"] = rms([(r["af_track_scale_pct"] - r["sarmin_track_scale_pct"])
                                           / r["af_track_scale_std_pct"] for r in applied])
    with_gnss = [r for r in rows if "gnss_velocity_scale_pct" in r]  # (not on --car's drives)
    if with_gnss:
        out["gnss_velocity_scale_rms_pct"] = rms([r["gnss_velocity_scale_pct"] for r in with_gnss])
        out["sarmin_minus_gnss_velocity_scale_rms_pct"] = rms(
            [r["sarmin_track_scale_pct"] - r["gnss_velocity_scale_pct"] for r in with_gnss])
    return out


def group_key(row: dict[str, Any]) -> str:
    """Summary group of a row: the scenario, with the ablation's components and the understeer gradient where
    given."""
    comps, k, g = row.get("components"), row.get("understeer_gradient"), row.get("rear_slip_gain")
    return (row["scenario"] + ("" if comps is None else f" [{comps or 'none'}]")
            + ("" if k is None else f" [K={k:g}]") + ("" if g is None else f" [slip={g:g}]")
            + ("" if row.get("fits", True) else " [no fits]") + ("" if row.get("attitude", True) else " [planar]")
            + (" [car]" if row.get("car") else "") + (" [sim]" if row.get("simulation") else "")
            + (" [sensors]" if row.get("sensors") else "")
            + (f" [{row['navigation']}]" if row.get("navigation") else "")
            + (f" [{row['processing']}]" if row.get("processing") else "")
            + (f" [radar {row['radar']}]" if row.get("radar") else "")
            + (f" [mounted {row['mounted_radar']}]" if row.get("mounted_radar") else "")
            + (f" [{row['label']}]" if row.get("label") else ""))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", default="test1,test2,test3")
    ap.add_argument("--seeds", default="0-9", help="e.g. 0-9 or 1,3,7")
    ap.add_argument("--methods", default=",".join(METHODS),
                    help="compare's methods (sar-min and truth are always run)")
    ap.add_argument("--dynamics", choices=("kinematic", "full"), default=None,
                    help="simulator vehicle model (default: the config's simulation.dynamics)")
    ap.add_argument("--components", default=None,
                    help="ablation: the full model's effects to keep, e.g. slip or body,road (implies --dynamics full)")
    ap.add_argument("--understeer-gradient", type=float, default=None,
                    help="SAR-MIN's steering model's understeer gradient (rad per m/s^2; default: the config's)")
    ap.add_argument("--rear-slip-gain", type=float, default=None,
                    help="the rear-slip gain SAR-MIN's trajectory turns the body by (rad per m/s^2; default: config's)")
    ap.add_argument("--no-fits", action="store_true",
                    help="SAR-MIN in one pass: no fitted understeer, yaw lag or wheel-speed lag")
    ap.add_argument("--planar", action="store_true",
                    help="SAR-MIN's radar on a planar body: not moved by the IMU's roll and pitch")
    ap.add_argument("--radar-height", action="store_true",
                    help="SAR-MIN's radar lifted along the road's grade (navigation.radar_height)")
    ap.add_argument("--car", default=None,
                    help="the simulated car differs from the config's: [vehicle_dynamics] entries, e.g. "
                         "mass_kg=2000,road_class='\"B\"' (the processor keeps the config's)")
    ap.add_argument("--simulation", default=None,
                    help="the simulated radar differs from the config's: [simulation] entries, e.g. "
                         "vibration_horizontal_rms_m=0.25e-3 (the processor keeps the config's)")
    ap.add_argument("--sensors", default=None,
                    help="the simulated sensors differ from their error tables: sensor.table.key entries, e.g. "
                         "gnss_cog.gnss.velocity_std_mps=0.06 (the processor keeps the config's tables)")
    ap.add_argument("--navigation", default=None,
                    help="SAR-MIN's own settings differ from the config's: [navigation] entries, e.g. "
                         "wheel_lag_window_always=true")
    ap.add_argument("--processing", default=None,
                    help="the processor's [processing] entries differ from the config's, e.g. "
                         "autofocus_fast_motion=true")
    ap.add_argument("--radar", default=None,
                    help="what the processor is told of the radar differs from the config's: [radar] entries, e.g. "
                         "clock_drift_ppm=500.0 or mounting.yaw_deg=-42.0 (the simulator keeps the config's radar)")
    ap.add_argument("--mounted-radar", default=None,
                    help="the radar is mounted otherwise than the config's and the processor is told so: [radar] "
                         "entries for both, e.g. mounting.yaw_deg=-90.0 (broadside)")
    ap.add_argument("--workdir", type=Path, default=None)
    ap.add_argument("--keep", action="store_true", help="keep every drive's log and comparison")
    ap.add_argument("--resume", action="store_true", help="keep --output's rows and skip the drives already in it")
    ap.add_argument("--output", type=Path, default=RESULTS / "paper.json")
    ap.add_argument("--label", default="",
                    help="a summary group of their own for these rows, e.g. the product's state they measure")
    args = ap.parse_args()
    methods = [m for m in args.methods.split(",") if m]
    methods += [m for m in ("sar-min", "truth") if m not in methods]
    if args.components is not None:
        args.dynamics = "full"
    rows: list[dict[str, Any]] = []
    if args.resume and args.output.exists():
        rows = json.loads(args.output.read_text())["rows"]
    # what tells one run's drives from another's: a row's fields, or this run's options
    variant = {"dynamics": args.dynamics, "components": args.components,
               "understeer_gradient": args.understeer_gradient, "rear_slip_gain": args.rear_slip_gain,
               "fits": not args.no_fits, "attitude": not args.planar, "radar_height": args.radar_height,
               "car": args.car, "simulation": args.simulation, "sensors": args.sensors, "navigation": args.navigation,
               "processing": args.processing, "radar": args.radar, "mounted_radar": args.mounted_radar,
               "label": args.label or None}

    def drive_key(r: dict[str, Any]) -> tuple[Any, ...]:
        return (r["scenario"], r["seed"], r.get("dynamics"), r.get("components"), r.get("understeer_gradient"),
                r.get("rear_slip_gain"), r.get("fits", True), r.get("attitude", True), r.get("radar_height", False),
                r.get("car"), r.get("simulation"), r.get("sensors"), r.get("navigation"), r.get("processing"),
                r.get("radar"), r.get("mounted_radar"), r.get("label"))

    done = {drive_key(r) for r in rows}

    def write() -> dict[str, Any]:
        groups = list(dict.fromkeys(group_key(r) for r in rows))
        # the rows' other car, radar and sensors ("[car]", "[sim]", "[sensors]" in the groups)
        others = {k: " / ".join(sorted({r[k] for r in rows if r.get(k)})) for k in OTHER_VEHICLE}
        result = {"benchmark": "paper", "methods": methods, "dynamics": args.dynamics or "config",
                  "components": args.components, **{k: v for k, v in others.items() if v}, "rows": rows,
                  "summary": {g: summary([r for r in rows if group_key(r) == g]) for g in groups}
                  | {"all": summary(rows)}}
        args.output.parent.mkdir(parents=True, exist_ok=True)
        args.output.write_text(json.dumps(result, indent=2) + "\n")
        return result

    with tempfile.TemporaryDirectory() as tmp:
        work = args.workdir or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        custom = (args.components is not None or args.understeer_gradient is not None
                  or args.rear_slip_gain is not None or args.no_fits or args.planar or args.radar_height
                  or args.navigation is not None or args.processing is not None or args.radar is not None
                  or args.mounted_radar is not None)
        config = (["--config", str(config_copy(args.components, args.understeer_gradient, work, args.rear_slip_gain,
                                                not args.no_fits, not args.planar, args.radar_height,
                                                navigation=args.navigation, processing=args.processing,
                                                radar=",".join(r for r in (args.mounted_radar, args.radar) if r)))]
                  if custom else [])
        # the simulated car, radar and sensors: the config's unless --car / --simulation / --sensors (then only the
        # simulator is given the changed one); --radar is what the processor is told, so the simulator keeps the
        # config's radar (e.g. its mounting); --mounted-radar changes both
        other_vehicle = any(getattr(args, k) for k in OTHER_VEHICLE) or bool(args.radar) or bool(args.mounted_radar)
        sim_config = (["--config", str(config_copy(args.components, args.understeer_gradient, work, args.rear_slip_gain,
                                                    not args.no_fits, not args.planar, args.radar_height, args.car,
                                                    args.simulation, args.sensors, args.navigation,
                                                    radar=args.mounted_radar))]
                      if other_vehicle else config)
        for seed in parse_seeds(args.seeds):
            for scenario in args.scenarios.split(","):
                if drive_key({"scenario": scenario, "seed": seed, **variant}) in done:
                    continue
                tag = (f"_{args.dynamics}" if args.dynamics else "") + (
                    f"_{args.components.replace(',', '+')}" if args.components is not None else "") + (
                    "_car" if args.car else "") + ("_sim" if args.simulation else "") + (
                    "_sensors" if args.sensors else "") + (
                    "_mounted" + variant_tag(args.mounted_radar) if args.mounted_radar else "")
                log = work / f"{scenario}_s{seed}{tag}.mcap"
                t = time.perf_counter()
                if not log.exists():
                    dyn = ["--dynamics", args.dynamics] if args.dynamics else []
                    cli("simulate", "--scenario", scenario, "--seed", str(seed), "--output", str(log), "--overwrite",
                        *dyn, *sim_config)
                sim_s = time.perf_counter() - t
                out = work / f"{scenario}_s{seed}"
                t = time.perf_counter()
                comparison = json.loads(cli("compare", str(log), "-o", str(out), "--methods", ",".join(methods),
                                            "--overwrite", "--json", *config).stdout)  # the same config navigates
                row = drive_row(scenario, seed, comparison, sim_s, time.perf_counter() - t)
                row["dynamics"], row["components"] = args.dynamics, args.components
                if args.understeer_gradient is not None:
                    row["understeer_gradient"] = args.understeer_gradient
                if args.rear_slip_gain is not None:
                    row["rear_slip_gain"] = args.rear_slip_gain
                if args.no_fits:
                    row["fits"] = False
                if args.planar:
                    row["attitude"] = False
                if args.radar_height:
                    row["radar_height"] = True
                row |= {k: getattr(args, k) for k in OTHER_VEHICLE if getattr(args, k)}
                if args.navigation:
                    row["navigation"] = args.navigation
                if args.processing:
                    row["processing"] = args.processing
                if args.radar:
                    row["radar"] = args.radar
                if args.mounted_radar:
                    row["mounted_radar"] = args.mounted_radar
                if args.label:
                    row["label"] = args.label
                row["sarmin_track_scale_pct"] = pct(track_scale(out))
                if not other_vehicle:  # (it rebuilds the config's car's motion)
                    gnss_scale, gnss_se = gnss_velocity_scale(scenario, seed)
                    row["gnss_velocity_scale_pct"] = pct(gnss_scale)
                    row["gnss_velocity_scale_se_pct"] = pct(gnss_se)
                rows.append(row)
                print(f"{group_key(row)} seed {seed}: " + "; ".join(
                    f"{m} max {row[m]['reflector_error_max_cm']:.2f} cm (local "
                    f"{row[m]['reflector_error_local_max_cm']:.2f}), peak loss {row[m]['peak_loss_min_db']:+.2f}.."
                    f"{row[m]['peak_loss_max_db']:+.2f} dB" for m in methods if m in row)
                    + "; entropy order whole/rn/far "
                    + "/".join({True: "yes", False: "no", None: "-"}[row[k]["paper_order"]] for k in ENTROPIES),
                    flush=True)
                write()
                if not args.keep:
                    shutil.rmtree(out, ignore_errors=True)
                    for p in (log, log.with_name(log.name + ".truth.h5")):
                        p.unlink(missing_ok=True)
    print(json.dumps(write()["summary"], indent=2))


if __name__ == "__main__":
    main()
