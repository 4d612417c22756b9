"""Benchmark SAR-MIN's accuracy over many seeds, navigation only: the statistics one seed cannot give.

Usage: python benches/bench_nav_seeds.py [--scenarios test1,test2,test3] [--seeds 10-69]
                                         [--gnss-models gauss_markov,white:0.5,white:2]
                                         [--navigation 'estimate_gnss_noise=false;estimate_gnss_noise=true']
                                         [--sensors 'gnss_cog.gnss.velocity_std_mps=0.06,...']
                                         [--components 'tyre_radius;wheel_ticks']
                                         [--simulation kinematic_ecu_window=true]
                                         [--output benches/results/nav_seeds.json] [--append]

For every filter setting, scenario and seed: ``simulate`` with the radar at 20 Hz instead of 990 Hz (the navigation
sensors draw from their own random streams, so their samples are those of the full simulation; ~2.5 s per drive
instead of ~35 s), ``ingest``, ``navigate --method sar-min``, and against the truth at 100 Hz while moving, at the
radar's mean phase centre: the track's scale (similarity fitted to the truth's, - 1; below 0 the track is too long),
its aligned RMSE and maximum after the rigid SE(2) alignment, the maximum with the scale removed too (the shape),
the absolute RMSE and the absolute error over the std SAR-MIN's covariance states for the position (along and across,
RMS: 1 where that std is right), and what the GNSS velocity alone
says of the scale (its mean along-track error over the drive: benches/bench_paper.py). A reflector's whole-track
aligned error is about the scale times its along-track distance from the track's centre: 0.055 % is 3 cm at 55 m.
Prints one line per setting and scenario; writes the rows and the summary as JSON, with which of SAR-MIN's fitted
terms each drive applied (``--dynamics kinematic --seeds 0-9 --output benches/results/nav_seeds_kinematic.json``:
none shows on the kinematic drives; ``--scenarios test1,test2,test3,urban --seeds 0-9 --dynamics full --output
benches/results/nav_seeds_full.json``: the full vehicle model). ``--navigation`` compares settings of SAR-MIN
side by side on the same drives; ``--sensors`` simulates sensors other than the error tables SAR-MIN weighs them by.
Where the track is at each corner reflector's zero-Doppler instant (``reflector_across_max_cm``: across, which the
autofocus leaves; ``reflector_track_max_cm``) gives urban's floor: ``--scenarios urban --seeds 0-9 --dynamics full
--append --sensors ";$G;gnss_cog.gnss.velocity_std_mps=0.015;gnss_cog.gnss.horizontal_std_m=0.0,gnss_cog.gnss.
white_std_m=0.0;$G,gnss_cog.gnss.velocity_std_mps=0.0,gnss_cog.gnss.horizontal_std_m=0.0,gnss_cog.gnss.white_std_m=0.0"``
(one line), where ``$G`` is ``<g>.gyro.turn_on_bias_dps=0.0,<g>.gyro.bias_instability_dps=0.0,<g>.gyro.
noise_density_dps_rthz=0.0`` for each of esc, orc, imu_cog_a and imu_cog_b (~14 min).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_paper import config_copy, gnss_velocity_scale, parse_seeds  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
NAV_ONLY_PRF_HZ = 20.0
SCALE_LIMIT = 5.5e-4  #: |scale| above it puts a reflector 55 m from the track's centre more than 3 cm off


def reflector_track_errors(est: Any, scene: Any, config: Any, t_ns: Any, errors: Any = None) -> tuple[Any, Any]:
    """The track's aligned error (m) along and across where each corner reflector is imaged (its zero-Doppler
    instant), (C,) each: the rigid alignment over the instants ``t_ns`` (ns), as the evaluation makes it; ``scene``:
    the drive's ``load_truth``; ``errors``: ``est``'s ``trajectory_errors`` at the radar's phase centre over
    ``t_ns``, where already made."""
    from autosar_cli.evaluate.trajectory_metrics import trajectory_errors
    from autosar_cli.nav.trajectory import phase_centre_lever_arm, zero_doppler_times

    t = np.asarray(t_ns, dtype=np.int64)
    if errors is None:
        errors = trajectory_errors(est, scene.trajectory, phase_centre_lever_arm(config), t)
    crs = scene.targets.corner_reflectors
    at = np.searchsorted(t, np.asarray(zero_doppler_times(scene.trajectory, scene.targets_above_road(crs), config,
                                                          t))).clip(0, len(t) - 1)
    return errors.aligned_along[at], errors.aligned_across[at]


def measure(scenario: str, seed: int, config: Any, work: Path, dynamics: str | None = None,
            sim_config: Any = None) -> dict[str, float]:
    """One drive: simulated from ``sim_config`` (None: ``config``), navigated with ``config``."""
    from autosar_cli.evaluate.alignment import fit_se2, fit_similarity_scale
    from autosar_cli.evaluate.evaluation import load_truth
    from autosar_cli.evaluate.trajectory_metrics import common_instants, stated_position_z, trajectory_errors
    from autosar_cli.ingest.pipeline import ingest
    from autosar_cli.nav.navigate import navigate
    from autosar_cli.nav.trajectory import phase_centre_lever_arm, track_scale_std
    from autosar_cli.sim.simulate import simulate

    log = work / f"{scenario}_s{seed}.mcap"
    sim = simulate(scenario, log, seed=seed, config=sim_config or config, dynamics=dynamics)  # type: ignore[arg-type]
    drive = work / f"{scenario}_s{seed}.h5"
    ingest([log], drive, config=config)
    est = navigate(drive, "sar-min", config)
    scene = load_truth(sim.truth_path, est.origin, config)
    truth = scene.trajectory
    t = common_instants(est, truth)
    errors = trajectory_errors(est, truth, phase_centre_lever_arm(config), t)
    e_xy, r_xy = errors.est_xy, errors.ref_xy
    residual = np.hypot(*(fit_se2(e_xy, r_xy).apply(e_xy) - r_xy).T)
    # the shape: what is left with the scale removed too (a similarity fit), which no scale estimate corrects
    scale = fit_similarity_scale(e_xy, r_xy)
    scaled = e_xy.mean(axis=0) + scale * (e_xy - e_xy.mean(axis=0))
    shape = np.hypot(*(fit_se2(scaled, r_xy).apply(scaled) - r_xy).T)
    along, across = reflector_track_errors(est, scene, config, t, errors)
    z = stated_position_z(est, errors)
    assert z is not None  # SAR-MIN states its position's covariance
    z_along, z_across = z
    gnss, _ = gnss_velocity_scale(scenario, seed, sim_config)
    for p in (log, drive, sim.truth_path):
        Path(p).unlink(missing_ok=True)
    scale_std = track_scale_std(est)
    return {"scale_pct": 100 * (scale - 1.0), "gnss_velocity_scale_pct": 100 * gnss,
            # the navigation's own std of it (its covariance), against which the scale's error is a z-score
            "scale_std_pct": 100 * scale_std if scale_std is not None else float("nan"),
            "aligned_rmse_cm": 100 * float(np.sqrt(np.mean(residual**2))),
            "aligned_max_cm": 100 * float(residual.max()),
            "shape_max_cm": 100 * float(shape.max()),
            "reflector_track_max_cm": 100 * float(np.hypot(across, along).max()),
            "reflector_across_max_cm": 100 * float(np.abs(across).max()),
            "abs_rmse_m": float(np.sqrt(np.mean(np.sum((e_xy - r_xy) ** 2, axis=1)))),
            # the absolute error over the std SAR-MIN states for its position (its covariance), RMS over the instants
            "position_z_along_rms": float(np.sqrt(np.mean(z_along**2))),
            "position_z_across_rms": float(np.sqrt(np.mean(z_across**2))),
            "position_z_mean_along": float(np.mean(z_along)), "position_z_mean_across": float(np.mean(z_across)),
            # which of the fitted lags SAR-MIN applied (docs/NAVIGATION.md)
            "steering_left_out": bool(est.info["understeer"]["steering_left_out"]),
            # the steering's slope against the kinematic angle, and whether it was refused as not this car's
            "steering_gain": est.info["understeer"].get("gain"), "steering_gain_std": est.info["understeer"].get(
                "gain_std"), "steering_refused": bool(est.info["understeer"].get("refused")),
            "steering_yaw_rate_rms_radps": est.info["understeer"].get("yaw_rate_rms_radps"),
            "steering_gain_correlation": est.info["understeer"].get("gain_correlation"),
            "warnings": est.info.get("warnings", []),
            "wheel_lag_applied": bool(est.info["wheel_lag"]["applied"]),
            "wheel_radii_applied": bool(est.info["wheel_radii"]["applied"]),
            "rear_slip_applied": bool(est.info["rear_slip"]["applied"]),
            "rear_slip_gain": est.info["rear_slip"].get("gain"), "rear_slip_std": est.info["rear_slip"].get("std"),
            # the white noise each GNSS stream shows over its table's, and whether SAR-MIN weighed it so
            **{f"gnss_{k}_noise_ratio": v["ratio"] for k, v in est.info.get("gnss_noise", {}).items()},
            "gnss_noise_applied": any(v["applied"] for v in est.info.get("gnss_noise", {}).values()),
            # the GNSS latency's change from its table against the 6-DoF IMU, and whether the samples moved by it
            **{f"gnss_latency_{k}_ms": float("nan") if (v := est.info["gnss_latency"].get(f"{k}_s")) is None
               else 1000 * v for k in ("change", "std")},
            "gnss_latency_ambiguous": bool(est.info["gnss_latency"].get("ambiguous")),
            "gnss_latency_applied": bool(est.info["gnss_latency"]["applied"]),
            "can_delay_ms": 1000 * (est.info["can_latency"].get("delay_s") or float("nan")),
            "can_latency_applied": bool(est.info["can_latency"]["applied"]),
            # how the GNSS velocity's errors correlate from sample to sample, and whether SAR-MIN weighed them so
            "gnss_velocity_correlation": float("nan") if (rho := est.info.get("gnss_velocity_correlation", {})
                                                          .get("correlation")) is None else rho,
            "gnss_velocity_decorrelated": bool(est.info.get("gnss_velocity_correlation", {}).get("applied")),
            # the updates the chi-square gate refused, all kinds together
            "rejected": int(sum(est.info.get("rejected", {}).values()))}


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    scale = np.array([r["scale_pct"] for r in rows])
    gnss = np.array([r["gnss_velocity_scale_pct"] for r in rows])
    z = scale / np.array([r.get("scale_std_pct", np.nan) for r in rows])
    aligned_max = [r["aligned_max_cm"] for r in rows]
    return {"drives": len(rows), "scale_rms_pct": round(float(np.sqrt(np.mean(scale**2))), 4),
            "scale_mean_pct": round(float(scale.mean()), 4),
            "gnss_velocity_scale_rms_pct": round(float(np.sqrt(np.mean(gnss**2))), 4),
            "scale_correlation_with_gnss_velocity": round(float(np.corrcoef(scale, gnss)[0, 1]), 3),
            # what SAR-MIN adds to its GNSS velocity's scale, mean and its standard error: 0 where it adds no bias
            "scale_minus_gnss_velocity_mean_pct": round(float(np.mean(scale - gnss)), 4),
            "scale_minus_gnss_velocity_se_pct": round(float(np.std(scale - gnss, ddof=1) / np.sqrt(len(rows))), 4)
            if len(rows) > 1 else float("nan"),
            # the scale's error over the navigation's own std, RMS: 1 where that std is right
            "scale_z_rms": round(float(np.sqrt(np.mean(z**2))), 2),
            "scale_beyond_limit": int(np.sum(np.abs(scale) > 100 * SCALE_LIMIT)),
            "aligned_rmse_mean_cm": round(statistics.fmean(r["aligned_rmse_cm"] for r in rows), 3),
            "aligned_max_median_cm": round(statistics.median(aligned_max), 3),
            "aligned_max_p90_cm": round(float(np.percentile(aligned_max, 90)), 3),
            "shape_max_median_cm": round(statistics.median(r.get("shape_max_cm", np.nan) for r in rows), 3),
            # the track at the corner reflectors: where a navigation-only image would put them (the autofocus
            # corrects along the track, not across it: docs/AUTOFOCUS.md)
            "reflector_track_max_median_cm": round(statistics.median(r.get("reflector_track_max_cm", np.nan)
                                                                     for r in rows), 2),
            "reflector_across_max_median_cm": round(statistics.median(r.get("reflector_across_max_cm", np.nan)
                                                                      for r in rows), 2),
            "reflector_across_within_2cm": sum(r.get("reflector_across_max_cm", np.inf) <= 2.0 for r in rows),
            "abs_rmse_mean_m": round(statistics.fmean(r["abs_rmse_m"] for r in rows), 4),
            # the position's error over its stated std, RMS over the drives' instants: 1 where that std is right
            **{f"position_z_{a}_rms": round(float(np.sqrt(np.mean([r[f"position_z_{a}_rms"] ** 2 for r in rows]))), 2)
               for a in ("along", "across") if all(f"position_z_{a}_rms" in r for r in rows)},
            "steering_left_out": sum(r["steering_left_out"] for r in rows),
            "wheel_lag_applied": sum(r["wheel_lag_applied"] for r in rows),
            "wheel_radii_applied": sum(r.get("wheel_radii_applied", False) for r in rows),
            "rear_slip_applied": sum(r.get("rear_slip_applied", False) for r in rows),
            "gnss_noise_applied": sum(r.get("gnss_noise_applied", False) for r in rows),
            "gnss_latency_applied": sum(r.get("gnss_latency_applied", False) for r in rows),
            "can_latency_applied": sum(r.get("can_latency_applied", False) for r in rows),
            "gnss_velocity_decorrelated": sum(r.get("gnss_velocity_decorrelated", False) for r in rows),
            "rejected_median": statistics.median(r.get("rejected", 0) for r in rows)}


def main() -> None:
    from autosar_cli.config import load_config

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", default="test1,test2,test3")
    ap.add_argument("--seeds", default="10-69", help="e.g. 10-69 (held out from the tests' seed 1 and "
                                                      "bench_paper's 0-9)")
    ap.add_argument("--gnss-models", default=None,
                    help="comma-separated GNSS error models to compare: gauss_markov, or white:<std m> "
                         "(navigation.gnss_error_model, gnss_position_std_m; default: the config's)")
    ap.add_argument("--navigation", default=None,
                    help="';'-separated settings of [navigation] to compare, each 'key=value,...' (bench_paper.py), "
                         "e.g. 'estimate_gnss_noise=false;estimate_gnss_noise=true' (default: the config's)")
    ap.add_argument("--components", default=None,
                    help="';'-separated sets of the full vehicle's components to simulate, each comma-separated, e.g. "
                         "'tyre_radius;wheel_ticks' (default: the config's; with --dynamics full)")
    ap.add_argument("--sensors", default=None,
                    help="';'-separated sets of simulated sensors that differ from the error tables SAR-MIN weighs "
                         "them by, each 'sensor.table.key=value,...' (bench_paper.py; empty: the tables), e.g. "
                         "';gnss_cog.gnss.velocity_std_mps=0.06'")
    ap.add_argument("--simulation", default=None,
                    help="entries of [simulation] for the simulator, 'key=value,...' (bench_paper.py), e.g. "
                         "kinematic_ecu_window=true")
    ap.add_argument("--dynamics", choices=("kinematic", "full"), default=None,
                    help="simulator vehicle model (default: the config's simulation.dynamics)")
    ap.add_argument("--output", type=Path, default=RESULTS / "nav_seeds.json")
    ap.add_argument("--append", action="store_true",
                    help="add this run's groups and rows to those of --output (a group of the same name is replaced, "
                         "its rows with it)")
    args = ap.parse_args()
    base = load_config()
    config = dataclasses.replace(base, radar=dataclasses.replace(base.radar, prf_hz=NAV_ONLY_PRF_HZ))
    nav = base.navigation
    default = "gauss_markov" if nav.gnss_error_model == "gauss_markov" else f"white:{nav.gnss_position_std_m:g}"
    models = args.gnss_models.split(",") if args.gnss_models else [default]
    settings = args.navigation.split(";") if args.navigation else [""]
    rows: list[dict[str, Any]] = []
    summary: dict[str, Any] = {}
    components = args.components.split(";") if args.components is not None else [None]
    sensor_sets = args.sensors.split(";") if args.sensors is not None else [""]
    with tempfile.TemporaryDirectory() as tmp:
        for model, edits, comps, sensors in ((m, e, c, x) for m in models for e in settings for c in components
                                             for x in sensor_sets):
            # the simulated car's components, sensors and simulation: the config's unless --components / --sensors /
            # --simulation
            sim_config = (dataclasses.replace(load_config(config_copy(comps, None, Path(tmp), sensors=sensors,
                                                                      simulation=args.simulation)),
                                              radar=config.radar)
                          if comps is not None or sensors or args.simulation else None)
            # SAR-MIN's own settings: the config's [navigation] as bench_paper.py --navigation edits it
            edited = load_config(config_copy(None, None, Path(tmp), navigation=edits)).navigation if edits else nav
            kind, _, std = model.partition(":")
            setting = {"gnss_error_model": kind, **({"gnss_position_std_m": float(std)} if std else {})}
            cfg = dataclasses.replace(config,
                                      navigation=dataclasses.replace(edited, **setting))  # type: ignore[arg-type]
            label = (model + (f" {args.dynamics}" if args.dynamics else "") + (f" {edits}" if edits else "")
                     + (f" [{comps}]" if comps is not None else "")
                     + (f" sensors {sensors}" if sensors else "")
                     + (f" simulation {args.simulation}" if args.simulation else ""))
            for scenario in args.scenarios.split(","):
                t = time.perf_counter()
                group = f"{scenario} {label}"
                these = [{"group": group, "gnss_model": model, "dynamics": args.dynamics,
                          **({"navigation": edits} if edits else {}),
                          **({"components": comps} if comps is not None else {}),
                          **({"sensors": sensors} if sensors else {}),
                          **({"simulation": args.simulation} if args.simulation else {}),
                          "scenario": scenario, "seed": seed,
                          **{k: (round(v, 4) if isinstance(v, float) else v)
                             for k, v in measure(scenario, seed, cfg, Path(tmp), args.dynamics, sim_config).items()}}
                         for seed in parse_seeds(args.seeds)]
                rows += these
                s = summarise(these)
                summary[group] = s
                print(f"{scenario}, GNSS error {label}: {s['drives']} drives, "
                      f"scale RMS {s['scale_rms_pct']:.4f} % "
                      f"(GNSS velocity alone {s['gnss_velocity_scale_rms_pct']:.4f} %, correlation "
                      f"{s['scale_correlation_with_gnss_velocity']:.2f}), |scale| > {100 * SCALE_LIMIT:.3f} % on "
                      f"{s['scale_beyond_limit']}, aligned RMSE {s['aligned_rmse_mean_cm']:.2f} cm, aligned max median "
                      f"{s['aligned_max_median_cm']:.2f} / p90 {s['aligned_max_p90_cm']:.2f} cm, abs RMSE "
                      f"{s['abs_rmse_mean_m']:.3f} m, steering left out / wheel lag / wheel gains applied on "
                      f"{s['steering_left_out']} / {s['wheel_lag_applied']} / {s['wheel_radii_applied']}; at the "
                      f"reflectors the track's worst median {s['reflector_track_max_median_cm']:.2f} cm, across "
                      f"{s['reflector_across_max_median_cm']:.2f} cm, across within 2 cm on "
                      f"{s['reflector_across_within_2cm']}, GNSS latency moved on {s['gnss_latency_applied']}, "
                      f"CAN on {s['can_latency_applied']}, "
                      f"velocity weighed by its correlation on {s['gnss_velocity_decorrelated']}, scale z RMS "
                      f"{s['scale_z_rms']:.2f}, position z RMS along / across {s['position_z_along_rms']:.2f} / "
                      f"{s['position_z_across_rms']:.2f} ({time.perf_counter() - t:.0f} s)",
                      flush=True)
    if args.append and args.output.exists():
        old = json.loads(args.output.read_text())
        ran = set(summary)  # this run's groups replace only themselves, rows and all
        summary = {**{k: v for k, v in old["summary"].items() if k not in ran}, **summary}
        rows = [r for r in old["rows"] if r.get("group") not in ran] + rows
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps({"benchmark": "nav_seeds", "radar_prf_hz": NAV_ONLY_PRF_HZ, "summary": summary,
                                       "rows": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
