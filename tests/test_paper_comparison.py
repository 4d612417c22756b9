"""(slow) The paper's comparison, none vs INS vs SAR-MIN vs truth, on a simulated test2 drive (straight, 120 m):
the reflectors, the facade's straightness and the entropies, with the radar autofocus (sar-min+af) beside them.
test1 and test3: test_paper_comparison_curves.py; the checks: paper_comparison.py."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import paper_comparison as pc
import pytest

from autosar_cli.evaluate.alignment import fit_similarity_scale
from autosar_cli.evaluate.trajectory_metrics import common_instants
from autosar_cli.nav.trajectory import phase_centre_lever_arm
from autosar_cli.store.drive import radar_times
from autosar_cli.store.trajectory import read_trajectory


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["test2"])
def test_paper_comparison(scenario: str, sim_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    pc.check_paper_comparison(scenario, sim_dir, tmp_path_factory)


@pytest.mark.slow
@pytest.mark.parametrize("scenario", [pytest.param(s, marks=pytest.mark.xfail(strict=True, raises=AssertionError,
                                                                                reason=pc.ENTROPY_XFAIL))
                                      for s in ("test2",)])
def test_entropy_orders_the_methods_as_in_the_paper(scenario: str, sim_dir: Path,
                                                    tmp_path_factory: pytest.TempPathFactory) -> None:
    pc.check_entropy_order(scenario, sim_dir, tmp_path_factory)


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["test2"])
def test_range_normalised_entropy_orders_the_methods_as_in_the_paper(scenario: str, sim_dir: Path,
                                                                      tmp_path_factory: pytest.TempPathFactory) -> None:
    pc.check_range_normalised_entropy_order(scenario, sim_dir, tmp_path_factory)


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["test2"])
def test_far_swath_entropy_ranks_none_above_ins_above_sarmin(scenario: str, sim_dir: Path,
                                                             tmp_path_factory: pytest.TempPathFactory) -> None:
    pc.check_far_swath_entropy_order(scenario, sim_dir, tmp_path_factory)


@pytest.mark.slow
@pytest.mark.parametrize("measure", ["entropy_rn", "entropy_far"])
@pytest.mark.parametrize("scenario", ["test2"])
def test_entropy_of_sarmin_is_not_below_the_truths(measure: str, scenario: str, sim_dir: Path,
                                                   tmp_path_factory: pytest.TempPathFactory) -> None:
    pc.check_entropy_not_below_the_truths(measure, scenario, sim_dir, tmp_path_factory)


def _scaled_comparison(sim_dir: Path, tmp_path_factory: pytest.TempPathFactory,
                       method: str) -> tuple[dict[str, Any], float, float]:
    """test2 seed 1's comparison (`pc.comparison`), checked for ``method``, a radar-scaled SAR-MIN: its reflectors
    are within 3 cm and 1 dB and at least 20 % better than SAR-MIN's worst. Returns the comparison, the truth's
    scale against SAR-MIN's track (length ratio - 1) and the scale ``method`` applied."""
    methods = pc.SWEEP_METHODS if method == "sar-min+scale" else pc.AUTOFOCUS_METHODS
    result = pc.comparison(sim_dir, tmp_path_factory, "test2", methods)
    out = Path(result["directory"])
    assert result["methods"] == methods
    tracks = {m: read_trajectory(out / m / "trajectory.h5", covariance=False) for m in ("sar-min", method, "truth")}

    def length(m: str) -> float:
        return float(np.sum(np.hypot(*np.diff(tracks[m].rear_axle_enu, axis=0).T)))

    # the scale error of SAR-MIN's odometry: the similarity fitting its phase-centre track to the truth's at the
    # radar frames (the length ratio would add what SAR-MIN's lateral jitter lengthens its path: ~0.01 %)
    t = common_instants(tracks["sar-min"], tracks["truth"], radar_times(out / "drive.h5"))
    lever = phase_centre_lever_arm(pc.CFG)[None]
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
    result, true_scale, radar_scale = _scaled_comparison(sim_dir, tmp_path_factory, "sar-min+af")
    assert abs(radar_scale - true_scale) < 4e-4
    # the track written keeps the navigation's covariance, scaled with the track about its centre, the applied
    # scale's variance added along it (2e-5 m at most here, against the GNSS's 0.23 m)
    out = Path(result["directory"])
    nav, af = (read_trajectory(out / m / "trajectory.h5") for m in ("sar-min", "sar-min+af"))
    assert af.covariance is not None and af.state_names == nav.state_names
    i = nav.state_names.index("px")
    np.testing.assert_allclose(af.state[:, i], af.rear_axle_enu[:, 0], atol=1e-9)
    scale, scale_std = af.info["track_scale"], af.info["autofocus"]["track_scale_std"]
    reach = nav.rear_axle_enu[:, 0] - nav.rear_axle_enu[:, 0].mean()
    np.testing.assert_allclose(af.covariance[:, i, i], (1 + scale) ** 2 * nav.covariance[:, i, i]
                               + (scale_std * reach) ** 2, rtol=1e-9)
