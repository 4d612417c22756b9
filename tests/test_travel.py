"""The one helper for distance travelled along a track."""

from __future__ import annotations

import math

import numpy as np

from autosar_cli.nav.trajectory import cumulative_travel


def test_cumulative_travel_sums_the_steps() -> None:
    rng = np.random.default_rng(3)
    for dims in (2, 3):
        points = rng.normal(size=(50, dims)) * 4.0
        expected = [0.0]
        for a, b in zip(points[:-1], points[1:], strict=True):
            step = math.sqrt(sum((float(x) - float(y)) ** 2 for x, y in zip(a, b, strict=True)))
            expected.append(expected[-1] + step)
        np.testing.assert_allclose(cumulative_travel(points), expected, rtol=1e-14, atol=1e-12)
    # a 3-4-5 step, a standstill, then back: travel counts every metre
    assert cumulative_travel([[0, 0], [3, 4], [3, 4], [0, 0]]).tolist() == [0.0, 5.0, 5.0, 10.0]
    assert cumulative_travel(np.zeros((1, 2))).tolist() == [0.0]


def _right_turn(yaw_rate_error: float = 0.0, t_ref_s: float = 0.0):
    """A car at 5 m/s: 8 s east, a quarter turn right of 10 m radius, 8 s south, sampled at 100 Hz, its heading
    integrated from its yaw rate plus ``yaw_rate_error`` (rad/s) from ``t_ref_s`` on, and its rear axle from that
    heading (the trapezoid rule): the track a navigation built on that yaw rate draws."""
    from autosar_cli.nav.geodesy import GeodeticOrigin
    from autosar_cli.types import Trajectory

    v, radius = 5.0, 10.0
    turn_s = 0.5 * math.pi * radius / v
    t = np.arange(0.0, 16.0 + turn_s, 0.01)
    yaw_rate = np.where((t >= 8.0) & (t < 8.0 + turn_s), -v / radius, 0.0)
    rate = yaw_rate + yaw_rate_error
    heading = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))])
    heading -= yaw_rate_error * t_ref_s  # the error's heading is 0 at t_ref
    vel = v * np.column_stack([np.cos(heading), np.sin(heading)])
    xy = np.vstack([[0.0, 0.0], np.cumsum(0.5 * (vel[1:] + vel[:-1]) * np.diff(t)[:, None], axis=0)])
    return Trajectory("sar-min", np.round(t * 1e9).astype(np.int64) + 10**18, xy, heading, np.full_like(t, v), rate,
                      GeodeticOrigin(45.0, 9.0, 100.0), 1.4, 0.5)


def test_a_yaw_rate_error_bends_the_radars_track_as_the_heading_ramp_says() -> None:
    """The track of a yaw rate 1e-4 rad/s too high from the turn's middle on, less the right one, is 1e-4 times
    :func:`heading_ramp_displacement` (its radar point, 2.4 m ahead and 0.8 m to the side, included): the track
    rebuilt from the turned heading, not the function's own sum: bent by up to 2.6 cm at the ends, the prediction
    off by 0.01 mm."""
    from autosar_cli.config import load_config
    from autosar_cli.nav.trajectory import heading_ramp_displacement, phase_centre_lever_arm

    config = load_config()
    right = _right_turn()
    t_ref_ns = int(right.t_ns[len(right.t_ns) // 2])
    b = 1e-4
    bent = _right_turn(b, (t_ref_ns - right.t_ns[0]) / 1e9)
    # the two tracks agree at t_ref (rebuilt from the same start: move the bent one there)
    lever = phase_centre_lever_arm(config)[None]
    t = right.t_ns[::10]
    moved = bent.body_points(t, lever)[:, 0, :2] - right.body_points(t, lever)[:, 0, :2]
    k = np.argmin(np.abs(t - t_ref_ns))
    moved -= moved[k]
    predicted = b * heading_ramp_displacement(right, t, t_ref_ns, config)
    print(f"bent by up to {100 * np.abs(moved).max():.2f} cm; prediction off by "
          f"{1e3 * np.abs(moved - predicted).max():.3f} mm at most")
    assert np.abs(moved).max() > 0.02
    # second order in b (the turned lever, the rotation's cosine): 1e-4 rad over tens of metres
    np.testing.assert_allclose(predicted, moved, atol=2e-5)


def test_the_scale_a_yaw_rate_uncertainty_leaves_is_umeyamas() -> None:
    """A right turn's track whose navigation states its gyros' mean bias to 0.002 deg/s: the scale std the
    slow motion adds (:func:`heading_ramp_scale_std`) is that std times the similarity scale (Umeyama's, the
    evaluation's :func:`fit_similarity_scale`, by finite difference) of the track bent by it, to 1 %. On a
    straight drive only the radar's sideways lever arm ``l`` turns into the drive's direction, by ``b t`` at time
    ``t``: a scale of ``|l| b / v``, to 2 %. A track with no covariance states none."""
    from dataclasses import replace

    from autosar_cli.config import load_config
    from autosar_cli.evaluate.alignment import fit_similarity_scale
    from autosar_cli.nav.trajectory import (
        centre_instant,
        heading_ramp_displacement,
        phase_centre_lever_arm,
        radar_track,
    )
    from autosar_cli.sar.pass_ranges import heading_ramp_scale_std

    config = load_config()
    right = _right_turn()
    names = ["px", "py", "v", "psi", "omega", "bias.a", "bias.b", "bias.steering"]
    std = math.radians(0.002)
    cov = np.zeros((len(right.t_ns), len(names), len(names)))
    cov[:, 5:7, 5:7] = std**2  # the two gyros' biases wholly correlated: their mean's std is std
    cov[:, 7, 7] = 1.0  # the steering's offset is no gyro's
    stated = replace(right, state_names=names, covariance=cov)
    t = right.t_ns[::10]
    track = radar_track(right, t, config)
    bend = heading_ramp_displacement(right, t, centre_instant(right), config)
    eps = 1e-7
    expected = std * abs(fit_similarity_scale(track, track + eps * bend) - 1.0) / eps
    got = heading_ramp_scale_std(stated, config)
    print(f"scale std {100 * got:.4f} %, Umeyama's {100 * expected:.4f} %")
    assert got > 1e-5 and abs(got - expected) < 0.01 * expected
    assert heading_ramp_scale_std(right, config) == 0.0
    straight = _right_turn()
    straight = replace(straight, rear_axle_enu=np.column_stack([5.0 * straight.t, np.zeros(len(straight.t))]),
                       heading=np.zeros(len(straight.t)), yaw_rate=np.zeros(len(straight.t)), state_names=names,
                       covariance=cov)
    sideways = abs(phase_centre_lever_arm(config)[1])
    assert abs(heading_ramp_scale_std(straight, config) - sideways * std / 5.0) < 0.02 * sideways * std / 5.0
