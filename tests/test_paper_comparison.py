"""(slow) The paper's comparison, none vs INS vs SAR-MIN vs truth, on simulated test1 / test2 / test3 drives: the
reflectors, the facade's straightness and the entropies; on test2 the radar autofocus (sar-min+af) beside them."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import simulated

from autosar_cli.config import load_config
from autosar_cli.evaluate.alignment import fit_similarity_scale
from autosar_cli.evaluate.compare import compare
from autosar_cli.evaluate.trajectory_metrics import common_instants
from autosar_cli.nav.trajectory import phase_centre_lever_arm
from autosar_cli.store.drive import radar_times
from autosar_cli.store.trajectory import read_trajectory

CFG = load_config()


# one comparison per scenario and set of methods, shared by the tests below
_COMPARISONS: dict[str, dict[str, Any]] = {}


_PAPER_METHODS = ["none", "ins", "sar-min", "truth"]
# test2 also carries the radar autofocus's claims: one comparison of the five methods serves both
_AUTOFOCUS_METHODS = ["none", "ins", "sar-min", "sar-min+af", "truth"]
# the scale sweep on the truth's reflectors (sar-min+scale): outside CI (make test-long), its own comparison
_SWEEP_METHODS = ["sar-min", "sar-min+scale", "truth"]


def _default_methods(scenario: str) -> list[str]:
    return _AUTOFOCUS_METHODS if scenario == "test2" else _PAPER_METHODS


def _comparison(sim_dir: Path, tmp_path_factory: pytest.TempPathFactory, scenario: str,
                methods: list[str] | None = None) -> dict[str, Any]:
    """compare() of a simulated scenario (seed 1, default config: with the radar's unobservable vibration), once
    per session and set of methods: by default the paper's four methods, and on test2 the autofocus too."""
    methods = methods or _default_methods(scenario)
    key = f"{scenario}:{','.join(methods)}"
    if key not in _COMPARISONS:
        sim = simulated(sim_dir, scenario, "mcap", 1)
        out = tmp_path_factory.mktemp(f"compare_{scenario}")
        _COMPARISONS[key] = {**compare([sim.log_path], out, CFG, methods=methods), "directory": str(out)}
    return _COMPARISONS[key]


def _print(scenario: str, result: dict[str, Any]) -> None:
    res = result["results"]
    for m in result["methods"]:
        s = res[m]["summary"]
        refl = ", ".join(f"{r['name']} {r['aligned_error_m'] * 100:.2f} ({r['local_aligned_error_m'] * 100:.2f}) cm "
                         f"{r['peak_loss_db']:+.2f} dB" for r in res[m]["reflectors"])
        print(f"{scenario} {m}: abs RMSE {s['abs_rmse_m'] * 100:.1f} cm, RPE 1 m across "
              f"{s['rpe_1m_across_m'] * 1e3:.2f} mm, entropy {s['entropy']:.4f} (range-normalised "
              f"{s['entropy_rn']:.4f}), contrast {s['contrast']:.1f}, "
              f"straightness facade {s['straightness_facade_m'] * 100:.2f} cm kerb "
              f"{s['straightness_kerb_m'] * 100:.2f} cm; {refl}")


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["test1", "test2", "test3"])
def test_paper_comparison(scenario: str, sim_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    """SAR-MIN images every reflector where it belongs and as bright as the truth trajectory does; the INS and the
    straight line do not; the facade is as straight with SAR-MIN as with the truth and bent with the others."""
    result = _comparison(sim_dir, tmp_path_factory, scenario)
    _print(scenario, result)
    res = result["results"]
    assert result["methods"] == _default_methods(scenario)
    sar = res["sar-min"]["reflectors"]
    assert len(sar) == 5
    # Whole-track SE(2) alignment: within 3 cm (seed 1: test1 <= 0.45, test3 <= 0.46 cm). On test2 (120 m) the
    # odometry's scale, which 25 s of 3 cm/s GNSS velocity pin down to ~0.04 % (1 sigma; seed 1 draws a GNSS
    # velocity 3.1 mm/s fast on average, and SAR-MIN's scale ends 0.065 % off), leaves an along-track stretch no
    # rotation removes (aligned track RMSE 2.3 cm, docs/EVALUATION.md): its reflectors measure 0.26-2.95 cm
    # (0.19-3.03 cm before SAR-MIN modelled the GNSS's slow error); aligned on the 10 m of track around each
    # reflector they are within 0.61 cm. Over seeds 0-9 (benches/bench_paper.py, docs/EVALUATION.md) test2 misses
    # 3 cm on the drives whose GNSS velocity runs >= 1.6 standard errors fast; with the local alignment none does.
    for r in sar:
        assert r["aligned_error_m"] < 0.03, r
        assert r["local_aligned_error_m"] < 0.03, r
        assert abs(r["peak_loss_db"]) <= 1.0, r  # within 1 dB of the truth-trajectory image
    for m in ("ins", "none"):  # the baselines are measurably worse on at least one reflector
        assert any(r["peak_loss_db"] >= 3.0 or r["aligned_error_m"] >= 0.05 for r in res[m]["reflectors"]), m
    straight = {m: res[m]["summary"]["straightness_facade_m"] for m in result["methods"]}
    assert straight["sar-min"] < straight["truth"] + 0.01, straight
    assert min(straight["ins"], straight["none"]) > 1.5 * straight["sar-min"], straight


def _scaled_comparison(sim_dir: Path, tmp_path_factory: pytest.TempPathFactory,
                       method: str) -> tuple[dict[str, Any], float, float]:
    """test2 seed 1's comparison (`_comparison`), checked for ``method``, a radar-scaled SAR-MIN: its reflectors
    are within 3 cm and 1 dB and at least 20 % better than SAR-MIN's worst. Returns the comparison, the truth's
    scale against SAR-MIN's track (length ratio - 1) and the scale ``method`` applied."""
    methods = _SWEEP_METHODS if method == "sar-min+scale" else _AUTOFOCUS_METHODS
    result = _comparison(sim_dir, tmp_path_factory, "test2", methods)
    out = Path(result["directory"])
    assert result["methods"] == methods
    tracks = {m: read_trajectory(out / m / "trajectory.h5", covariance=False) for m in ("sar-min", method, "truth")}

    def length(m: str) -> float:
        return float(np.sum(np.hypot(*np.diff(tracks[m].rear_axle_enu, axis=0).T)))

    # the scale error of SAR-MIN's odometry: the similarity fitting its phase-centre track to the truth's at the
    # radar frames (the length ratio would add what SAR-MIN's lateral jitter lengthens its path: ~0.01 %)
    t = common_instants(tracks["sar-min"], tracks["truth"], radar_times(out / "drive.h5"))
    lever = phase_centre_lever_arm(CFG)[None]
    true_scale = fit_similarity_scale(tracks["sar-min"].body_points(t, lever)[:, 0],
                                      tracks["truth"].body_points(t, lever)[:, 0]) - 1.0
    radar_scale = length(method) / length("sar-min") - 1.0
    assert radar_scale == pytest.approx(tracks[method].info["track_scale"], abs=2e-6)
    print(f"test2 track scale: truth against SAR-MIN {true_scale * 100:+.4f} %, {method} {radar_scale * 100:+.4f} %; "
          f"{result['notes']}")
    res = result["results"]
    worst = max(r["aligned_error_m"] for r in res["sar-min"]["reflectors"])
    assert max(r["aligned_error_m"] for r in res[method]["reflectors"]) < 0.8 * worst
    for r in res[method]["reflectors"]:
        assert r["aligned_error_m"] < 0.03, r
        assert abs(r["peak_loss_db"]) <= 1.0, r
    assert any(n.startswith(f"{method}:") for n in result["notes"])
    return result, true_scale, radar_scale


@pytest.mark.long
def test_radar_measured_scale_puts_test2s_reflectors_within_3_cm(sim_dir: Path,
                                                                 tmp_path_factory: pytest.TempPathFactory) -> None:
    """test2's reflectors are up to 3.0 cm off with the whole-track alignment because SAR-MIN's track is 0.06 % too
    long (25 s of GNSS velocity). Focused with a ±28 deg beam over a scale sweep, the five reflectors' sharpness
    puts the scale within 0.01 % of the truth's, and with it ("sar-min+scale") every reflector is within 3 cm and
    1 dB (measured: scale -0.075 % against -0.069 %, reflectors <= 0.94 cm, peak loss <= 0.26 dB; when the sweep
    took each patch's highest pixel: -0.099 %, <= 2.13 cm)."""
    _, true_scale, radar_scale = _scaled_comparison(sim_dir, tmp_path_factory, "sar-min+scale")
    assert 4e-4 < abs(true_scale) < 2e-3  # what GNSS left: the reason for the method
    assert abs(radar_scale - true_scale) < 1.5e-4
    assert abs(radar_scale - true_scale) < 0.5 * abs(true_scale)  # at least twice as close as SAR-MIN alone


@pytest.mark.slow
def test_radar_autofocus_without_truth_brings_test2s_reflectors_within_3_cm(
        sim_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    """sar-min+af: the residual-motion autofocus on the bright isolated points of SAR-MIN's own image, no truth; its
    scale comes from the points' phase histories with their ranges pinned by the range envelope. Measured on test2
    seed 1: scale -0.063 % against the truth's -0.065 % (SAR-MIN alone: 0)."""
    _, true_scale, radar_scale = _scaled_comparison(sim_dir, tmp_path_factory, "sar-min+af")
    assert abs(radar_scale - true_scale) < 4e-4


@pytest.mark.slow
def test_autofocus_fits_the_scale_with_the_motion(sim_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    """A track's scale shows in each point's quadratic phase, and so does across-track motion that curves over its
    aperture. The autofocus's scale, fitted with the rest of the track held, reads that motion as scale; refitted
    together with the motion from there, it does not. test1 seed 1, the truth track (the radar's true motion),
    exact and with a 2 mm across-track sine over 4 m of travel added: the scale the autofocus then applies (its
    error; the truth's is 0) measured +0.000 and +0.016 % (std 0.008 %); the scale alone gave +0.012 and
    +0.144 %."""
    from autosar_cli.nav.trajectory import cumulative_travel
    from autosar_cli.sar.focus import FocusOptions
    from autosar_cli.sar.phase_history import frame_geometry
    from autosar_cli.sar.residual_motion import AutofocusOptions, candidate_points, estimate_residual_motion
    from autosar_cli.types import MotionCorrection

    out = Path(_comparison(sim_dir, tmp_path_factory, "test1")["directory"])
    truth = read_trajectory(out / "truth" / "trajectory.h5", covariance=False)
    drive = out / "drive.h5"
    every = AutofocusOptions(prior_scale=0.002)
    # the exact track with the scale's points alone (the scale is theirs either way): the joint fit is then the last
    near = replace(every, max_range_m=every.scale_max_range_m)
    _, across, _ = frame_geometry(truth, truth.t_ns, CFG)  # unit, towards the radar's side
    base = truth.correction.at(truth.t_ns) if truth.correction is not None else np.zeros((len(truth.t_ns), 3))
    sine = np.sin(2 * np.pi * cumulative_travel(truth.rear_axle_enu) / 4.0)
    for amplitude_m, bound, opts in ((0.0, 1e-4, near), (0.002, 6e-4, every)):
        offset = base + amplitude_m * sine[:, None] * across
        moved = replace(truth, correction=MotionCorrection(truth.t_ns, offset, np.zeros_like(offset)))
        points = candidate_points(drive, truth, CFG, FocusOptions.from_config(CFG), opts)
        res = estimate_residual_motion(drive, moved, CFG, points, opts=opts)
        print(f"test1 truth track + {amplitude_m * 1e3:.0f} mm over 4 m: autofocus scale {res.scale * 100:+.4f} "
              f"± {res.scale_std * 100:.4f} % {res.scale_note}")
        assert res.applied and not res.scale_note, res.summary()
        assert abs(res.scale) < bound
        assert res.correction is not None and np.all(np.isfinite(res.correction.std_enu))


# sar-min >= truth within the entropy's sampling on the 2 cm grid: on test1-3 seed 1 a half-pixel shift of the grid
# moves an image's range-normalised or far-swath entropy by up to 0.2 %, SAR-MIN minus the truth on the same grid
# by up to 0.16 % (lowest -0.03 %); before the processed aperture's look angle was bounded in curves, test3's moved
# by up to 2 % (docs/EVALUATION.md)
_TRUTH_TOLERANCE = 0.001


_ENTROPY_XFAIL = ("measured (seed 1): beside focus, the whole image's entropy follows how bright its few strongest "
                  "scatterers are (car bodies, kerb, lamp posts at 1-5 m, which the range law makes brightest) and "
                  "how a 2 cm grid samples them (a half-pixel shift moved test2's straight-line image by 2.4 %); "
                  "test1 none 7.880 > sar-min 7.687 > truth 7.580 > ins 7.472, test2 ins 7.753 > truth 7.553 > "
                  "sar-min 7.521 > none 7.408, test3 ins 7.938 > none 7.914 > sar-min 7.802 > truth 7.779 "
                  "(see docs/EVALUATION.md)")


@pytest.mark.slow
@pytest.mark.parametrize("scenario", [pytest.param(s, marks=pytest.mark.xfail(strict=True, raises=AssertionError,
                                                                                reason=_ENTROPY_XFAIL))
                                      for s in ("test1", "test2", "test3")])
def test_entropy_orders_the_methods_as_in_the_paper(scenario: str, sim_dir: Path,
                                                    tmp_path_factory: pytest.TempPathFactory) -> None:
    """The whole image's plain entropy: none > ins > sar-min >= truth (it does not hold: the reason above)."""
    res = _comparison(sim_dir, tmp_path_factory, scenario)["results"]
    h = {m: res[m]["summary"]["entropy"] for m in res}
    assert h["none"] > h["ins"] > h["sar-min"], h
    assert h["sar-min"] >= h["truth"] * (1 - _TRUTH_TOLERANCE), h


_RN_ORDER_XFAIL = ("measured (seed 1): test1's INS image is 0.5 % lower in range-normalised entropy than SAR-MIN's "
                   "(8.306 against 8.349) while its far swath is 3.8 % higher (9.150 against 8.812) and its reflectors "
                   "are 5-12 cm off: over the near swath's apertures of a few cm its errors shift the image rather "
                   "than blur it, and its position steps at each GNSS correction cut those apertures differently "
                   "(it was 8.472 until the look-angle cut was computed with the neighbouring blocks' pulses)")


@pytest.mark.slow
@pytest.mark.parametrize("scenario", [pytest.param("test1",
                                                   marks=pytest.mark.xfail(strict=True, raises=AssertionError,
                                                                             reason=_RN_ORDER_XFAIL)),
                                      "test2", "test3"])
def test_range_normalised_entropy_orders_the_methods_as_in_the_paper(scenario: str, sim_dir: Path,
                                                                      tmp_path_factory: pytest.TempPathFactory) -> None:
    """The whole image's entropy once the range law is undone (|z|^2 R^2: every scatterer counts by its reflectivity,
    not by its nearness): none > ins > sar-min. Seed 1: test2 9.681 > 9.651 > 9.594, test3 9.417 > 8.738 > 8.384."""
    res = _comparison(sim_dir, tmp_path_factory, scenario)["results"]
    h = {m: res[m]["summary"]["entropy_rn"] for m in res}
    assert h["none"] > h["ins"] > h["sar-min"], h


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["test1", "test2", "test3"])
def test_far_swath_entropy_ranks_none_above_ins_above_sarmin(scenario: str, sim_dir: Path,
                                                             tmp_path_factory: pytest.TempPathFactory) -> None:
    """Where the processed apertures are long enough for navigation errors to defocus (at least half the maximum
    range from the track), the entropy ranks the methods as the paper's images do (seed 1, 2 cm grid: test1
    9.712 > 9.150 > 8.812, test2 9.400 > 9.237 > 9.141, test3 10.137 > 8.971 > 8.808 nats), and the contrast the other
    way."""
    res = _comparison(sim_dir, tmp_path_factory, scenario)["results"]
    h = {m: res[m]["summary"]["entropy_far"] for m in res}
    c = {m: res[m]["summary"]["contrast_far"] for m in res}
    assert h["none"] > h["ins"] > h["sar-min"], h
    assert c["none"] < c["ins"] < c["sar-min"], c


@pytest.mark.slow
@pytest.mark.parametrize("measure", ["entropy_rn", "entropy_far"])
@pytest.mark.parametrize("scenario", ["test1", "test2", "test3"])
def test_entropy_of_sarmin_is_not_below_the_truths(measure: str, scenario: str, sim_dir: Path,
                                                   tmp_path_factory: pytest.TempPathFactory) -> None:
    """The range-normalised and far-swath entropies: sar-min >= truth (seed 1, sar-min / truth: range-normalised
    test1 8.349 / 8.229, test2 9.594 / 9.466, test3 8.384 / 8.320; far swath test1 8.812 / 8.709, test2 9.141 /
    8.988, test3 8.808 / 8.702)."""
    res = _comparison(sim_dir, tmp_path_factory, scenario)["results"]
    h = {m: res[m]["summary"][measure] for m in res}
    assert h["sar-min"] >= h["truth"] * (1 - _TRUTH_TOLERANCE), h
