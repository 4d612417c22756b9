"""The track before SAR-MIN's first GNSS fix, dead-reckoned back from it on the wheel speeds and gyros.

SAR-MIN starts where the first GNSS fix gives it a position and a heading (:func:`.sarmin._initial_state`). A drive
that begins where the sky is hidden (a car park, a tunnel, a street under trees) has wheel speeds and yaw rates from
its first second: without this, its radar frames before that fix lie outside the trajectory and focus leaves them
out (urban with its first 15 s unfixed: a quarter of the drive). Backwards from the smoothed state at the first fix
the heading takes the gyros' yaw rate less their estimated biases, the rear axle the rear wheels' speed less their
estimated scale, as the filter itself dead-reckons through a GNSS outage.

The covariance is the first state's carried back through the linearised steps (the heading's error turns the path
about the first fix, a bias error bends it, a scale error shortens it) plus the gyros' and wheels' white noise
integrated over the span.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np
from numpy.typing import NDArray

from . import models as m
from .inputs import NavInputs
from .sarmin import NavSolution

Array = NDArray[np.float64]

#: a first fix this close to the first wheel speed and yaw rate leaves nothing worth extending
MIN_SPAN_S = 0.5


@dataclass(frozen=True)
class DeadReckonedStart:
    """The span before the first fix (s) dead-reckoned, and the stated 1-sigma of the heading and of the rear axle's
    position (rad, m) at its start; ``applied`` False with ``reason`` where nothing was."""

    span_s: float
    heading_std_rad: float = float("nan")
    position_std_m: float = float("nan")
    applied: bool = False
    reason: str = ""

    def to_dict(self) -> dict[str, object]:
        return {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in asdict(self).items()}


def dead_reckoned_start(sol: NavSolution, inputs: NavInputs, slip_gain: float = 0.0,
                        min_span_s: float = MIN_SPAN_S) -> tuple[NavSolution, dict[str, object]]:
    """``sol`` with the wheel rows before its first state prepended, dead-reckoned back from that state (see the
    module's docstring), and what was done. ``slip_gain``: the rear tyres' slip gain SAR-MIN navigated with (rad per
    m/s^2; the rear axle's course is the heading less ``slip_gain v omega``)."""
    wheels, gyros = inputs.wheels, inputs.gyros
    if wheels is None or not gyros:
        return sol, DeadReckonedStart(0.0, reason="no wheel speeds or no gyros").to_dict()
    t_first = max(float(wheels.t[0]), min(float(g.t[0]) for g in gyros))
    span = float(sol.t[0]) - t_first
    if span < min_span_s:
        return sol, DeadReckonedStart(max(span, 0.0), reason=f"the first fix is within {min_span_s:g} s of the first "
                                                              "wheel speed and yaw rate").to_dict()
    names = sol.state_names
    x0, P0 = sol.x[0], sol.P[0]
    n = len(x0)
    bias_i = [names.index(f"bias.{g.name}") for g in gyros]
    scale_i = [names.index("scale.wheel_rl"), names.index("scale.wheel_rr")]
    t = wheels.t[(wheels.t >= t_first) & (wheels.t < sol.t[0])]
    rows = np.searchsorted(wheels.t, t)
    one_plus_scale = 1.0 + 0.5 * (x0[scale_i[0]] + x0[scale_i[1]])
    v = 0.5 * (wheels.z[rows, 2] + wheels.z[rows, 3]) / one_plus_scale
    covered = [np.interp(t, g.t, g.z[:, 0] - x0[b], left=np.nan) for g, b in zip(gyros, bias_i, strict=True)]
    omega = np.nanmean(covered, axis=0)
    count = np.sum(np.isfinite(covered), axis=0)
    # each step from t[k] to the next instant (the first fix after the last) turns at the rates of t[k], along the
    # course at its middle
    dt = np.diff(np.append(t, sol.t[0]))
    before = np.cumsum((omega * dt)[::-1])[::-1]  # heading turned from t[k] to the first fix
    psi = x0[m.PSI] - before
    course = psi + 0.5 * omega * dt - slip_gain * v * omega
    step = np.stack([v * dt * np.cos(course), v * dt * np.sin(course)], axis=1)
    xy = x0[[m.PX, m.PY]] - np.cumsum(step[::-1], axis=0)[::-1]
    # linearised: d xy / d psi0 turns the path about the first fix; d psi / d b_i is the time to it over the
    # gyros counted; d xy / d b_i sums the later steps' turns; the scale shortens the path
    to_fix = sol.t[0] - t
    turn = np.stack([-step[:, 1], step[:, 0]], axis=1)  # d step / d course
    d_xy_d_bias = -np.cumsum((turn * (to_fix / np.maximum(count, 1))[:, None])[::-1], axis=0)[::-1]
    x = np.repeat(x0[None], len(t), axis=0)
    x[:, m.PX], x[:, m.PY], x[:, m.PSI], x[:, m.V], x[:, m.OMEGA] = xy[:, 0], xy[:, 1], psi, v, omega
    wheel_var = float(np.mean(wheels.sigma[2:] ** 2)) / 2.0
    wheel_dt = float(np.median(np.diff(wheels.t))) if len(wheels.t) > 1 else 0.01
    gyro_var_dt = float(np.mean([g.sigma[0] ** 2 * np.median(np.diff(g.t)) for g in gyros])) / len(gyros)
    gyros_seen = np.maximum(count, 1)
    offset = x0[[m.PX, m.PY]] - xy  # (K, 2): the path from each instant to the first fix
    J = np.repeat(np.eye(n)[None], len(t), axis=0)
    J[:, m.PX, m.PSI], J[:, m.PY, m.PSI] = offset[:, 1], -offset[:, 0]
    for b in bias_i:
        J[:, m.PSI, b] = to_fix / gyros_seen
        J[:, m.OMEGA, b] = -1.0 / gyros_seen
        J[:, m.PX, b], J[:, m.PY, b] = d_xy_d_bias[:, 0], d_xy_d_bias[:, 1]
    for i in scale_i:
        J[:, m.PX, i], J[:, m.PY, i] = offset[:, 0] / (2.0 * one_plus_scale), offset[:, 1] / (2.0 * one_plus_scale)
        J[:, m.V, i] = -v / (2.0 * one_plus_scale)
    J[:, m.V, m.V] = J[:, m.OMEGA, m.OMEGA] = 0.0
    P = np.einsum("kij,jl,kml->kim", J, P0, J, optimize=True)
    # white noise over the span: the heading's random walk, the path's along-track and, through it, across
    distance = np.cumsum((np.abs(v) * dt)[::-1])[::-1]
    heading_var = gyro_var_dt * to_fix
    along_var = wheel_var * wheel_dt * to_fix
    across_var = distance**2 * heading_var / 3.0
    along = np.stack([np.cos(course), np.sin(course)], axis=1)
    across = np.stack([-along[:, 1], along[:, 0]], axis=1)
    P[:, m.PX:m.PY + 1, m.PX:m.PY + 1] += (along_var[:, None, None] * along[:, :, None] * along[:, None, :]
                                           + across_var[:, None, None] * across[:, :, None] * across[:, None, :])
    P[:, m.PSI, m.PSI] += heading_var
    P[:, m.V, m.V] += wheel_var
    P[:, m.OMEGA, m.OMEGA] += float(np.mean([g.sigma[0] ** 2 for g in gyros])) / gyros_seen
    info = DeadReckonedStart(span, float(np.sqrt(P[0][m.PSI, m.PSI])),
                             float(np.sqrt(P[0][m.PX, m.PX] + P[0][m.PY, m.PY])), applied=True,
                             reason=f"no GNSS fix over the drive's first {span:.1f} s: the track there is "
                                    "dead-reckoned back from the first fix on the wheel speeds and gyros")
    return replace(sol, t=np.concatenate([t, sol.t]), x=np.concatenate([x, sol.x]), P=np.concatenate([P, sol.P]),
                   filtered=None), info.to_dict()
