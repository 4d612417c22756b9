"""The autofocus's fast-motion stage (sar/fast_motion.py): its pieces against straightforward code, a fast
across-track error injected into the truth track recovered from many scatterers, and its refusal."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.signal import butter, sosfiltfilt
from typer.testing import CliRunner

from autosar_cli.cli import app
from autosar_cli.config import load_config
from autosar_cli.evaluate.evaluation import load_truth
from autosar_cli.sar.fast_motion import (
    FastMotionOptions,
    fast_motion,
    history_steps,
    moving_average_removal,
    node_prior,
    step_columns,
    step_design,
)
from autosar_cli.sar.focus import FocusOptions
from autosar_cli.sar.normal_equations import BandedCholesky
from autosar_cli.sar.phase_history import focus_history, frame_geometry, gather_phase_histories, pair_antennas
from autosar_cli.sar.point_selection import candidate_points, points_and_scatterers
from autosar_cli.sar.residual_motion import AutofocusOptions
from autosar_cli.sar.step_normals import add_normals, apply_model, history_normals, remove_moving_average
from autosar_cli.store.trajectory import read_trajectory
from autosar_cli.types import MotionCorrection, Trajectory

CFG = load_config()
runner = CliRunner()


def test_moving_average_removal_is_each_sample_less_its_segments_neighbours() -> None:
    rng = np.random.default_rng(3)
    segment = np.repeat([0, 1, 2], [7, 2, 11])
    x = rng.normal(size=len(segment))
    half = 3
    expected = np.empty_like(x)
    for i in range(len(x)):
        near = [j for j in range(len(x)) if segment[j] == segment[i] and abs(j - i) <= half]
        expected[i] = x[i] - np.mean(x[near])
    np.testing.assert_allclose(moving_average_removal(segment, half) @ x, expected, rtol=0, atol=1e-14)
    starts = np.array([0, 7, 9, 20])
    np.testing.assert_allclose(remove_moving_average(x, starts, half), expected, rtol=0, atol=1e-14)


def test_the_histories_banded_normal_equations_are_the_sparse_products() -> None:
    """Each history's normal equations formed in band form, weighted and summed, are the sparse model's
    ``M^T W M`` and ``M^T W d`` (M = (I - A) S), and the banded Cholesky solves them as SuperLU does."""
    rng = np.random.default_rng(11)
    node_s, n_nodes, kappa, half = 0.01, 300, 4 * math.pi / 0.0039, 6
    counts = [40, 5, 120, 77]  # steps of four histories, each its own span of time
    t0 = [0.1, 0.9, 1.0, 2.2]
    t = np.concatenate([t0[s] + 0.0101 * np.arange(c)[:, None] + [0.0, 0.0101] for s, c in enumerate(counts)])
    gain = rng.uniform(0.3, 1.0, size=(len(t), 2))
    segment = np.repeat(np.arange(len(counts)), counts)
    starts = np.concatenate([[0], np.cumsum(counts)])
    steps = rng.normal(scale=0.3, size=len(t))
    weight = np.array([2.0, 0.0, 0.5, 11.0])
    model = (moving_average_removal(segment, half) @ step_design(t, gain, n_nodes, node_s, kappa)).toarray()
    data = moving_average_removal(segment, half) @ steps
    w = weight[segment]
    expected_normal = model.T @ (w[:, None] * model)
    expected_rhs = model.T @ (w * data)
    cols, vals = step_columns(t, gain, n_nodes, node_s, kappa)
    normals = history_normals(cols, vals, remove_moving_average(steps, starts, half), starts, half)
    band, rhs = add_normals(normals, weight, n_nodes)
    dense = np.zeros((n_nodes, n_nodes))
    for k in range(band.shape[0]):
        dense[np.arange(k, n_nodes), np.arange(n_nodes - k)] = band[k, :n_nodes - k]
    dense = np.tril(dense) + np.tril(dense, -1).T
    scale = np.abs(expected_normal).max()
    assert normals.bandwidth >= 2 * half  # a row reaches the nodes of its whole window
    np.testing.assert_allclose(dense, expected_normal, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(rhs, expected_rhs, rtol=0, atol=1e-12 * np.abs(expected_rhs).max())
    e = rng.normal(scale=1e-4, size=n_nodes)
    np.testing.assert_allclose(apply_model(cols, vals, starts, half, e), model @ e, rtol=0, atol=1e-10)
    prior = node_prior(n_nodes, 3e-4, 1e-3).toarray()
    full = expected_normal + prior
    prior_band = np.zeros_like(band)
    for k in range(2):
        prior_band[k, :n_nodes - k] = np.diag(prior, -k)
    solution = BandedCholesky(band + prior_band).solve(expected_rhs)
    np.testing.assert_allclose(solution, np.linalg.solve(full, expected_rhs), rtol=1e-9, atol=0)


def test_step_design_is_the_phase_step_of_a_motion_interpolated_between_nodes() -> None:
    """A phase step between samples a and b is kappa (g_b e(t_b) - g_a e(t_a)), e linear between the nodes."""
    rng = np.random.default_rng(5)
    node_s, n_nodes, kappa = 0.01, 40, 4 * math.pi / 0.0039
    e = rng.normal(scale=1e-4, size=n_nodes)
    t = np.sort(rng.uniform(0.0, 0.38, size=(25, 2)), axis=1)
    gain = rng.uniform(0.5, 1.0, size=(25, 2))
    nodes_t = np.arange(n_nodes) * node_s
    expected = kappa * (gain[:, 1] * np.interp(t[:, 1], nodes_t, e) - gain[:, 0] * np.interp(t[:, 0], nodes_t, e))
    np.testing.assert_allclose(step_design(t, gain, n_nodes, node_s, kappa) @ e, expected, rtol=1e-12, atol=0)


@pytest.fixture(scope="module")
def ci_drive(ci_mcap, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Trajectory, Trajectory, Path]:
    """The ci drive ingested (drive.h5), its navigated track, its truth trajectory in the drive's frame and the
    truth file."""
    out = tmp_path_factory.mktemp("fast") / "run"
    r = runner.invoke(app, ["run", str(ci_mcap.log_path), "-o", str(out)])
    assert r.exit_code == 0, r.output
    nav = read_trajectory(out / "trajectory.h5", covariance=False)
    return out / "drive.h5", nav, load_truth(ci_mcap.truth_path, nav.origin, CFG).trajectory, ci_mcap.truth_path


def test_the_first_images_points_are_the_same_out_to_the_radars_range(ci_drive: tuple[Any, ...]) -> None:
    """One first image out to the radar's range gives the autofocus the same points as its own out to 17 m."""
    drive, nav, _, _ = ci_drive
    focus, opts = FocusOptions.from_config(CFG), AutofocusOptions.from_config(CFG)
    points, scatterers, _ = points_and_scatterers(drive, nav, CFG, focus, opts, FastMotionOptions())
    np.testing.assert_array_equal(points, candidate_points(drive, nav, CFG, focus, opts))
    assert len(scatterers) > 2 * len(points)
    reach = np.hypot(*(scatterers[:, :2] - nav.rear_axle_enu.mean(axis=0)[:2]).T)
    assert reach.max() > 18.0  # the far swath's scatterers too


def _scatterer_histories(drive: Path, track: Trajectory, fast: FastMotionOptions) -> tuple[np.ndarray, Any]:
    """The stage's scatterers in the first image along ``track`` (P, 3) (ENU m) and their histories read along it."""
    focus, opts = FocusOptions.from_config(CFG), AutofocusOptions.from_config(CFG)
    scatterers = points_and_scatterers(drive, track, CFG, focus, opts, fast)[1]
    return scatterers, gather_phase_histories(drive, track, CFG, scatterers, focus, half_beam_deg=fast.half_beam_deg,
                                              window_bins=fast.window_bins, channels=fast.channels)


def test_steps_where_a_walls_mirror_image_aliases_onto_the_point_are_left_out(ci_drive: tuple[Any, ...]) -> None:
    """A pulse's range sample holds a point on a wall and the wall's mirror image about broadside, whose Doppler is
    twice the point's own, 4 v (u . along) / lambda: where that aliases (PRF 990 Hz) to within ``alias_hz`` of the
    point's, the low-passed sample holds both, and its steps are left out (but near broadside, where the two
    coincide). The ci drive's scatterers along its exact track: every step kept has both samples clear by that
    rule, computed here from the track's speed and the scatterer's direction from the radar; without the rule a
    fifth of the steps would hold one that is not."""
    drive, _, truth, _ = ci_drive
    fast = FastMotionOptions()
    scatterers, hist = _scatterer_histories(drive, truth, fast)
    z, los = focus_history(hist, *pair_antennas(hist, truth, CFG), scatterers)
    kept, every = (history_steps(hist, z, los, truth, CFG, replace(fast, alias_hz=a)) for a in (fast.alias_hz, 0.0))
    prf = kept.prf_hz

    def clear(steps: Any, margin_hz: float) -> np.ndarray:
        """(M, 2) whether each step's samples are clear of their mirror image's alias (or near broadside)."""
        point = np.array([hist.point[run[0]] for run in steps.runs])[steps.segment]
        t_ns = truth.t_ns[0] + np.round(steps.t * 1e9).astype(np.int64)
        ok = np.zeros(steps.t.shape, dtype=bool)
        for end in (0, 1):
            centre, _, along = frame_geometry(truth, t_ns[:, end], CFG)
            u = scatterers[point] - centre
            u /= np.linalg.norm(u, axis=1, keepdims=True)
            speed = np.interp(t_ns[:, end], truth.t_ns, np.abs(truth.speed))
            mirror = 4.0 * speed * np.einsum("nk,nk->n", u, along) * hist.cycles_per_m
            alias = np.abs((mirror + prf / 2) % prf - prf / 2)
            ok[:, end] = (alias > fast.alias_hz - margin_hz) | (np.abs(mirror) < fast.alias_hz / 4 + margin_hz)
        return ok

    # 3 Hz either side of the limits: here the radar's origin stands for the channels' mean phase centre
    assert clear(kept, 3.0).all()
    assert (~clear(every, -3.0).all(axis=1)).sum() > 0.15 * len(every.step)  # measured: 132 of 631


def test_halves_that_measure_opposite_motions_correct_nothing(ci_drive: tuple[Any, ...]) -> None:
    """The stage's gate: its scatterers are fitted in two halves (even and odd), and where those disagree nothing is
    corrected. The ci drive's scatterers along its exact track, each history's samples turned by 0.5 rad at 7 Hz
    (what 0.16 mm of across-track motion would do): the same way in both halves, they agree and the motion is
    corrected (measured: the halves' correlation +0.51, 0.10 mm RMS); the even ones one way and the odd ones the
    other, they disagree (-0.54) and the track is left alone, the reason said. (ci's few scatterers: two that fit
    per half are let through.)"""
    drive, _, truth, _ = ci_drive
    fast = FastMotionOptions(min_histories=2)
    scatterers, hist = _scatterer_histories(drive, truth, fast)
    turn = 0.5 * np.sin(2 * np.pi * 7.0 * (hist.frame_t_ns[hist.frame] - truth.t_ns[0]) / 1e9)
    results = {}
    for name, sign in (("alike", np.ones(len(hist.point))), ("opposite", np.where(hist.point % 2 == 0, 1.0, -1.0))):
        turned = replace(hist, samples=(hist.samples * np.exp(1j * sign * turn)[:, None, None]).astype(np.complex64))
        results[name] = fast_motion(turned, truth, CFG, scatterers, fast)
    alike, opposite = results["alike"], results["opposite"]
    assert alike.applied and alike.halves_correlation > 0.3, alike.reason
    assert 0.07 < alike.correction_rms_mm() < 0.15  # the turn's 0.11 mm RMS
    assert not opposite.applied and opposite.correction is None
    assert opposite.halves_correlation < -0.3
    assert opposite.reason.startswith("the two halves of its scatterers disagree")


def test_recovers_a_fast_across_track_error_from_many_scatterers(test1_drive: tuple[Path, Any]) -> None:
    """test1's truth track (kinematic, seed 1: no motion but the track's) plus a fast across-track motion (0.3 mm at
    7 Hz and 0.2 mm at 13 Hz, a body shaking on a rough road). The stage's correction along the truth track alone
    is its noise floor on this drive (measured 0.049 mm RMS above 2 Hz; its two halves of the histories agree
    little there, reliability 0.38); along the track with the motion, the halves agree (reliability 0.95) and the
    correction follows it (measured: correlation 0.94, gain 0.89) and leaves 0.088 of its 0.255 mm RMS."""
    drive, truth = test1_drive
    track = truth.trajectory
    t = track.t
    err = 3e-4 * np.sin(2 * np.pi * 7.0 * t) + 2e-4 * np.sin(2 * np.pi * 13.0 * t + 1.0)
    across = frame_geometry(track, track.t_ns, CFG)[1]
    wrong = replace(track, correction=MotionCorrection(track.t_ns, err[:, None] * across, np.zeros((len(t), 3))))
    focus, opts, fast = FocusOptions.from_config(CFG), AutofocusOptions.from_config(CFG), FastMotionOptions()
    scatterers = points_and_scatterers(drive, track, CFG, focus, opts, fast)[1]
    fits = []
    for along in (track, wrong):
        hist = gather_phase_histories(drive, along, CFG, scatterers, focus, half_beam_deg=fast.half_beam_deg,
                                      window_bins=fast.window_bins, channels=fast.channels)
        res = fast_motion(hist, along, CFG, scatterers, fast)
        assert res.applied and res.correction is not None, res.reason
        assert np.all(res.correction.std_enu >= 0)
        fits.append(res)
    nodes = fits[0].correction.t_ns
    across_nodes = frame_geometry(track, nodes, CFG)[1]
    floor, moved = (np.einsum("kd,kd->k", r.correction.at(nodes), across_nodes) for r in fits)
    injected = np.interp(nodes, track.t_ns, err)
    sos = butter(4, 2.0, "highpass", fs=1.0 / fast.node_s, output="sos")
    seen = fits[0].seen & fits[1].seen

    def rms(v: np.ndarray) -> float:
        return float(np.std(sosfiltfilt(sos, v)[seen]))

    injected_hp, moved_hp = (sosfiltfilt(sos, v)[seen] for v in (injected, moved))
    gain = float(np.dot(-moved_hp, injected_hp) / np.dot(injected_hp, injected_hp))
    correlation = float(np.corrcoef(injected_hp, -moved_hp)[0, 1])
    print(f"fast motion: floor {1e3 * rms(floor):.3f} mm; {1e3 * rms(injected):.3f} -> "
          f"{1e3 * rms(injected + moved):.3f} mm RMS above 2 Hz, gain {gain:.2f}, correlation {correlation:.3f}, "
          f"over {seen.mean():.2f} of the nodes ({fits[1].histories_used} of {fits[1].histories} histories; "
          f"reliability {fits[0].reliability:.2f} / {fits[1].reliability:.2f})")
    assert seen.mean() > 0.8
    assert rms(floor) < 6e-5
    assert rms(injected) > 2.4e-4
    assert correlation > 0.85 and 0.7 < gain < 1.05
    assert fits[0].reliability < 0.6 and fits[1].reliability > 0.8
    # the option's form: the same whole fit, scaled by its reliability
    scaled = fast_motion(hist, wrong, CFG, scatterers, replace(fast, apply_reliability=True))
    assert scaled.correction is not None and scaled.reliability == fits[1].reliability
    np.testing.assert_allclose(scaled.correction.offset_enu, fits[1].reliability * fits[1].correction.offset_enu,
                               rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(scaled.correction.std_enu, fits[1].reliability * fits[1].correction.std_enu,
                               rtol=1e-12, atol=1e-18)
    assert rms(injected + moved) < 0.45 * rms(injected)


def test_halves_of_pure_noise_hardly_agree() -> None:
    """Histories whose phase steps are pure noise (0.1 rad): the two halves' fits hardly agree, so the reliability
    that scales the correction, 2 r / (1 + r), stays small (and nothing is corrected where r <= 0)."""
    from autosar_cli.sar.fast_motion import HistorySteps, _fit_histories, _StepProblem

    rng = np.random.default_rng(11)
    n_hist, per, node_s = 12, 60, 0.01
    t0 = np.repeat(np.arange(n_hist) * 0.05, per) + np.tile(np.arange(per) * 0.01, n_hist)
    t = np.stack([t0, t0 + 0.01], -1)
    segment = np.repeat(np.arange(n_hist), per)
    steps = HistorySteps(t, rng.normal(scale=0.1, size=len(t0)), np.full((len(t0), 2), 0.9), segment,
                         [np.array([k]) for k in range(n_hist)], 1000.0)
    opts = FastMotionOptions()
    n_nodes = int(t.max() / node_s) + 2
    problem = _StepProblem.of(steps, n_nodes, 4 * math.pi / 0.0039, opts)
    fits = [_fit_histories(problem, (np.arange(n_hist) % 2) == half, opts) for half in (0, 1)]
    assert all(f.used.sum() == n_hist // 2 for f in fits)
    sos = butter(4, 2.0, "highpass", fs=1.0 / node_s, output="sos")
    a, b = (sosfiltfilt(sos, f.motion) for f in fits)
    assert abs(np.corrcoef(a, b)[0, 1]) < 0.3
