"""The track where the GNSS is missing: dead-reckoned back before the first fix (nav/dead_reckoning.py), and the gaps
after it reported (nav.navigate.gnss_gaps)."""

from __future__ import annotations

import numpy as np
import pytest

from autosar_cli.nav import models as m

SPEED, YAW_RATE, BIAS, SCALE = 5.0, 0.1, 0.004, 0.01
TRACK = 1.6


def _circle(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rear axle on a circle of 50 m (5 m/s, 0.1 rad/s) through the origin, heading East at t = 5 s: position
    (N, 2) m and heading (N,) rad."""
    psi = YAW_RATE * (t - 5.0)
    radius = SPEED / YAW_RATE
    return np.stack([radius * np.sin(psi), radius * (1.0 - np.cos(psi))], axis=1), psi


def _drive(first_fix_s: float = 5.0):  # noqa: ANN202
    """NavInputs of exact rear wheel speeds (scaled by 1 + SCALE) and one gyro (biased by BIAS) over 0-10 s, and a
    NavSolution whose states start at ``first_fix_s`` with the true state, the bias and the scale known."""
    from autosar_cli.nav.geodesy import GeodeticOrigin
    from autosar_cli.nav.inputs import Measurements, NavInputs
    from autosar_cli.nav.sarmin import NavSolution, _state_names

    t = np.arange(0.0, 10.0, 0.01)
    rear = np.array([SPEED - YAW_RATE * TRACK / 2, SPEED + YAW_RATE * TRACK / 2]) * (1.0 + SCALE)
    wheels = Measurements("wheels", t, np.tile(np.concatenate([rear, rear]), (t.size, 1)), np.full(4, 0.02))
    gyro = Measurements("gyro", t, np.full((t.size, 1), YAW_RATE + BIAS), np.array([0.003]))
    inputs = NavInputs(0, GeodeticOrigin(45.0, 7.0, 0.0), gyros=[gyro], wheels=wheels)
    names = _state_names(inputs)
    ts = np.arange(first_fix_s, 10.0, 0.01)
    xy, psi = _circle(ts)
    x = np.zeros((ts.size, len(names)))
    x[:, m.PX], x[:, m.PY], x[:, m.PSI], x[:, m.V], x[:, m.OMEGA] = xy[:, 0], xy[:, 1], psi, SPEED, YAW_RATE
    x[:, names.index("bias.gyro")] = BIAS
    x[:, [names.index(f"scale.wheel_{w}") for w in ("fl", "fr", "rl", "rr")]] = SCALE
    P = np.repeat(np.diag(np.full(len(names), 1e-6))[None], ts.size, axis=0)
    return inputs, NavSolution(ts, x, P, names, {}, {})


def test_the_start_is_dead_reckoned_back_along_the_path_and_its_covariance_is_the_steps_jacobian() -> None:
    """On a 50 m circle with exact wheel speeds and yaw rate, the 5 s before the first fix come back on the circle
    within 0.1 mm (the steps turn at their middle). Moved by a small change of the first state's heading, gyro bias
    or wheel scale, the start moves as the Jacobian the covariance is carried with says, within 1 %."""
    from autosar_cli.nav.dead_reckoning import dead_reckoned_start

    inputs, sol = _drive()
    out, info = dead_reckoned_start(sol, inputs)
    assert info["applied"] and info["span_s"] == pytest.approx(5.0, abs=1e-9)
    assert out.t[0] == 0.0 and np.array_equal(out.t[-len(sol.t):], sol.t)
    early = out.t < 5.0
    xy, psi = _circle(out.t[early])
    assert np.abs(out.x[early][:, [m.PX, m.PY]] - xy).max() < 1e-4
    assert np.abs(out.x[early][:, m.PSI] - psi).max() < 1e-9
    assert np.allclose(out.x[early][:, m.V], SPEED) and np.allclose(out.x[early][:, m.OMEGA], YAW_RATE)
    names = sol.state_names
    for name, delta in (("psi", 1e-4), ("bias.gyro", 1e-5), ("scale.wheel_rl", 1e-4), ("scale.wheel_rr", 1e-4)):
        i = names.index(name)
        moved = sol.x.copy()
        moved[0, i] += delta
        P0 = np.zeros_like(sol.P[0])
        P0[i, i] = 1.0
        start, _ = dead_reckoned_start(type(sol)(sol.t, moved, np.repeat(P0[None], len(sol.t), 0), names, {}, {}),
                                       inputs)
        shift = (start.x[0, [m.PX, m.PY]] - out.x[0, [m.PX, m.PY]]) / delta
        # the covariance's column of this state, less the white noise on its diagonal
        jacobian_column = start.P[0][[m.PX, m.PY], i]
        assert np.linalg.norm(shift) > 1.0, name
        assert np.linalg.norm(shift - jacobian_column) < 0.01 * np.linalg.norm(shift), (name, shift, jacobian_column)


def test_a_first_fix_at_the_first_wheel_speed_leaves_the_solution_as_it_is() -> None:
    from autosar_cli.nav.dead_reckoning import dead_reckoned_start

    inputs, sol = _drive(first_fix_s=0.3)
    out, info = dead_reckoned_start(sol, inputs)
    assert out is sol and not info["applied"] and "within 0.5 s" in str(info["reason"])


def test_navigate_covers_a_drive_whose_first_seconds_have_no_gnss(tmp_path) -> None:  # noqa: ANN001
    """test1 by the simulator's full car (seed 0) with no GNSS over its first 5 s: the trajectory starts with the
    wheel speeds, not 5 s later, and over those 5 s (25 m) its rear axle stays within 6 cm of the truth's after the
    whole track's rigid alignment (measured 4.9 cm: the filter's speed at the first fix is 13 mm/s low), its heading
    at the start within twice the std it states (1.0 against 2.9 mrad)."""
    from conftest import full_car_drive, with_gnss_errors

    from autosar_cli.evaluate.alignment import fit_se2
    from autosar_cli.evaluate.evaluation import load_truth
    from autosar_cli.evaluate.trajectory_metrics import common_instants
    from autosar_cli.nav.navigate import navigate

    drive, sim, cfg = full_car_drive(tmp_path, "test1", with_gnss_errors(outages=((0.0, 5.0),)))
    traj = navigate(drive, "sar-min", cfg)
    info = traj.info["before_first_fix"]
    assert info["applied"] and 4.8 < info["span_s"] < 5.2, info
    truth = load_truth(sim.truth_path, traj.origin, cfg).trajectory
    assert abs(traj.t_ns[0] - truth.t_ns[0]) < 0.1e9
    t = common_instants(traj, truth)
    est, ref = ([np.interp(t, tr.t_ns, tr.rear_axle_enu[:, i]) for i in (0, 1)] for tr in (traj, truth))
    est, ref = np.stack(est, axis=1), np.stack(ref, axis=1)
    error = np.hypot(*(fit_se2(est, ref).apply(est) - ref).T)
    early = t < t[0] + 4.5e9
    assert error[early].max() < 0.06, error[early].max()
    # what it inherits from the first fix's state: the heading, within the std it states
    heading_error = np.angle(np.exp(1j * (traj.state[0, m.PSI] - np.interp(traj.t_ns[0], truth.t_ns, truth.heading))))
    assert abs(heading_error) < 2.0 * info["heading_std_rad"], (heading_error, info)


def test_gnss_gaps_are_the_spans_after_the_first_fix_without_one() -> None:
    """10 Hz fixes with none over 3-6.5 s and none after 8 s while the wheels run to 12 s: two gaps (3.5 and 4 s);
    a 1 s gap is the receiver's ordinary hiccup, not reported."""
    from autosar_cli.nav.geodesy import GeodeticOrigin
    from autosar_cli.nav.inputs import Measurements, NavInputs
    from autosar_cli.nav.navigate import gnss_gaps

    t = np.round(np.arange(0.0, 8.05, 0.1), 6)
    t = t[((t <= 3.0) | (t >= 6.5)) & ((t <= 1.0) | (t >= 2.0))]
    fixes = Measurements("gnss", t, np.zeros((t.size, 2)), np.full(2, 0.25))
    wheels = Measurements("wheels", np.arange(0.0, 12.0, 0.01), np.zeros((1200, 4)), np.full(4, 0.02))
    gaps = gnss_gaps(NavInputs(10**18, GeodeticOrigin(45.0, 7.0, 0.0), gnss_position=fixes, wheels=wheels))
    assert [g["duration_s"] for g in gaps] == [3.5, 3.99]
    assert gaps[0]["start_ns"] == 10**18 + 3 * 10**9 and gaps[1]["end_ns"] == 10**18 + 11_990_000_000
