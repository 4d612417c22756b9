"""The paper's comparison (none vs INS vs SAR-MIN vs truth) on a simulated drive, and its checks, shared by
test_paper_comparison.py (test2, the straight drive, with the radar autofocus beside) and
test_paper_comparison_curves.py (test1 and test3): one file per xdist worker's share of the work."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from conftest import simulated

from autosar_cli.config import load_config
from autosar_cli.evaluate.compare import compare

CFG = load_config()


# one comparison per scenario and set of methods in this worker, shared by its tests
COMPARISONS: dict[str, dict[str, Any]] = {}


PAPER_METHODS = ["none", "ins", "sar-min", "truth"]
# test2 also carries the radar autofocus's claims: one comparison of the five methods serves both
AUTOFOCUS_METHODS = ["none", "ins", "sar-min", "sar-min+af", "truth"]
# the scale sweep on the truth's reflectors (sar-min+scale): outside CI (make test-long), its own comparison
SWEEP_METHODS = ["sar-min", "sar-min+scale", "truth"]


def default_methods(scenario: str) -> list[str]:
    return AUTOFOCUS_METHODS if scenario == "test2" else PAPER_METHODS


def comparison(sim_dir: Path, tmp_path_factory: pytest.TempPathFactory, scenario: str,
               methods: list[str] | None = None) -> dict[str, Any]:
    """compare() of a simulated scenario (seed 1, default config: with the radar's unobservable vibration), once
    per session and set of methods: by default the paper's four methods, and on test2 the autofocus too."""
    methods = methods or default_methods(scenario)
    key = f"{scenario}:{','.join(methods)}"
    if key not in COMPARISONS:
        sim = simulated(sim_dir, scenario, "mcap", 1)
        out = tmp_path_factory.mktemp(f"compare_{scenario}")
        COMPARISONS[key] = {**compare([sim.log_path], out, CFG, methods=methods), "directory": str(out)}
    return COMPARISONS[key]


def print_comparison(scenario: str, result: dict[str, Any]) -> None:
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


def check_paper_comparison(scenario: str, sim_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    """SAR-MIN images every reflector where it belongs and as bright as the truth trajectory does; the INS and the
    straight line do not; the facade is as straight with SAR-MIN as with the truth and bent with the others."""
    result = comparison(sim_dir, tmp_path_factory, scenario)
    print_comparison(scenario, result)
    res = result["results"]
    assert result["methods"] == default_methods(scenario)
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


# sar-min >= truth within the entropy's sampling on the 2 cm grid: on test1-3 seed 1 a half-pixel shift of the grid
# moves an image's range-normalised or far-swath entropy by up to 0.2 %, SAR-MIN minus the truth on the same grid
# by up to 0.16 % (lowest -0.03 %); before the processed aperture's look angle was bounded in curves, test3's moved
# by up to 2 % (docs/EVALUATION.md)
TRUTH_TOLERANCE = 0.001


ENTROPY_XFAIL = ("measured (seed 1): beside focus, the whole image's entropy follows how bright its few strongest "
                  "scatterers are (car bodies, kerb, lamp posts at 1-5 m, which the range law makes brightest) and "
                  "how a 2 cm grid samples them (a half-pixel shift moved test2's straight-line image by 2.4 %); "
                  "test1 none 7.880 > sar-min 7.687 > truth 7.580 > ins 7.472, test2 ins 7.753 > truth 7.553 > "
                  "sar-min 7.521 > none 7.408, test3 ins 7.938 > none 7.914 > sar-min 7.802 > truth 7.779 "
                  "(see docs/EVALUATION.md)")


RN_ORDER_XFAIL = ("measured (seed 1): test1's INS image is 0.5 % lower in range-normalised entropy than SAR-MIN's "
                   "(8.306 against 8.349) while its far swath is 3.8 % higher (9.150 against 8.812) and its reflectors "
                   "are 5-12 cm off: over the near swath's apertures of a few cm its errors shift the image rather "
                   "than blur it, and its position steps at each GNSS correction cut those apertures differently "
                   "(it was 8.472 until the look-angle cut was computed with the neighbouring blocks' pulses)")



def check_entropy_order(scenario: str, sim_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    """The whole image's plain entropy: none > ins > sar-min >= truth (it does not hold: ENTROPY_XFAIL)."""
    res = comparison(sim_dir, tmp_path_factory, scenario)["results"]
    h = {m: res[m]["summary"]["entropy"] for m in res}
    assert h["none"] > h["ins"] > h["sar-min"], h
    assert h["sar-min"] >= h["truth"] * (1 - TRUTH_TOLERANCE), h


def check_range_normalised_entropy_order(scenario: str, sim_dir: Path,
                                         tmp_path_factory: pytest.TempPathFactory) -> None:
    """The whole image's entropy once the range law is undone (|z|^2 R^2: every scatterer counts by its reflectivity,
    not by its nearness): none > ins > sar-min. Seed 1: test2 9.681 > 9.651 > 9.594, test3 9.417 > 8.738 > 8.384
    (test1: RN_ORDER_XFAIL)."""
    res = comparison(sim_dir, tmp_path_factory, scenario)["results"]
    h = {m: res[m]["summary"]["entropy_rn"] for m in res}
    assert h["none"] > h["ins"] > h["sar-min"], h


def check_far_swath_entropy_order(scenario: str, sim_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    """Where the processed apertures are long enough for navigation errors to defocus (at least half the maximum
    range from the track), the entropy ranks the methods as the paper's images do (seed 1, 2 cm grid: test1
    9.712 > 9.150 > 8.812, test2 9.400 > 9.237 > 9.141, test3 10.137 > 8.971 > 8.808 nats), and the contrast the other
    way."""
    res = comparison(sim_dir, tmp_path_factory, scenario)["results"]
    h = {m: res[m]["summary"]["entropy_far"] for m in res}
    c = {m: res[m]["summary"]["contrast_far"] for m in res}
    assert h["none"] > h["ins"] > h["sar-min"], h
    assert c["none"] < c["ins"] < c["sar-min"], c


def check_entropy_not_below_the_truths(measure: str, scenario: str, sim_dir: Path,
                                       tmp_path_factory: pytest.TempPathFactory) -> None:
    """The range-normalised and far-swath entropies: sar-min >= truth (seed 1, sar-min / truth: range-normalised
    test1 8.349 / 8.229, test2 9.594 / 9.466, test3 8.384 / 8.320; far swath test1 8.812 / 8.709, test2 9.141 /
    8.988, test3 8.808 / 8.702)."""
    res = comparison(sim_dir, tmp_path_factory, scenario)["results"]
    h = {m: res[m]["summary"][measure] for m in res}
    assert h["sar-min"] >= h["truth"] * (1 - TRUTH_TOLERANCE), h
