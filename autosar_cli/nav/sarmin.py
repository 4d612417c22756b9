"""SAR-MIN: UKF fusion of GNSS, N gyros, four wheel speeds and the steering angle (paper Sec. II-B),
every measurement applied at its own instant, with Mahalanobis gating and an RTS smoother.

Array-in, array-out: :func:`run_sarmin` takes :class:`~.inputs.NavInputs` and returns a
:class:`NavSolution`; reading drive.h5 and writing trajectory.h5 happen elsewhere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.special import chdtri

from autosar_cli.config import Config
from autosar_cli.interrupts import interrupts_held

from . import models as m
from .frames import wrap_angle
from .inputs import Measurements, NavInputError, NavInputs

Array = NDArray[np.float64]

# Merwe's scaled sigma points (kappa = 3 - n): the same for both engines
SIGMA_ALPHA = 1e-3
SIGMA_BETA = 2.0


@dataclass
class NavSolution:
    """Estimated rear-axle states over time (see :mod:`.models` for the state layout)."""

    t: Array  #: s since t0_ns
    x: Array  #: (K, n)
    P: Array  #: (K, n, n)
    state_names: list[str]
    rejected: dict[str, int]
    updates: dict[str, int]
    #: where only the states were smoothed (``run_sarmin(..., smoothed_covariance=False)``): the filter's history,
    #: ``P`` is the filtered covariance (the smoothed one at the last state only), and :func:`with_smoothed_covariance`
    #: completes the smoothing
    filtered: _FilterHistory | None = None


@dataclass
class _FilterHistory:
    """The compiled filter's output that the smoother reads (:func:`.sarmin_kernel.run_filter`)."""

    x: Array
    P: Array
    x_pred: Array
    transition: Array
    P_pred_kinematic: Array
    dt: Array
    q: Array
    beta: Array


def with_smoothed_covariance(sol: NavSolution) -> NavSolution:
    """``sol`` smoothed in full: itself where it already is, else its filter history through the RTS smoother
    (in place: ``sol``'s covariances become the smoothed ones, and it no longer holds the history)."""
    h = sol.filtered
    if h is None:
        return sol
    sol.filtered = None
    from . import sarmin_kernel as kern

    with interrupts_held():
        xs, Ps = kern.smooth(h.x, h.P, h.x_pred, h.transition, h.P_pred_kinematic, h.dt, h.q, h.beta)
    return NavSolution(sol.t, xs, Ps, sol.state_names, sol.rejected, sol.updates)


def chi2_gate(probability: float, dof: int) -> float:
    """Squared Mahalanobis distance that a consistent innovation of ``dof`` dimensions stays below with
    ``probability`` (the chi-square quantile; scipy.special's inverse survival function, as scipy.stats'
    ``chi2.ppf`` computes it, without scipy.stats' ~0.3 s import)."""
    return float(chdtri(dof, 1.0 - probability))


def steering_held_states(scale_i: int) -> list[int]:
    """States a steering update leaves alone: the speed and the four wheel scales.

    The road-wheel angle measures ``atan(L omega / v)``. Updating ``v`` through it multiplies the
    innovation by a Jacobian ``-L omega / v**2`` taken at the current yaw rate, whose error (the gyros'
    white noise, ~4 mrad/s per sample) is correlated with that same innovation: the product drifts ``v``
    upwards. On test1-3 (seeds 1, 2) it made the wheel scales 0.02-0.035 % too small (the track that much
    too long), and it vanished with noise-free gyros. The steering still corrects the yaw rate, the gyro
    biases and its own offset; the speed is left to the wheels and GNSS (a Schmidt "consider" update).
    """
    return [m.V] + list(range(scale_i, scale_i + 4))


def models_gnss_error(inputs: NavInputs) -> bool:
    """Whether the filter carries the GNSS position's slow error as two Gauss-Markov states."""
    return inputs.gnss_error_std_m > 0.0 and inputs.gnss_error_time_s > 0.0


def models_gnss_velocity_error(inputs: NavInputs) -> bool:
    """Whether the filter carries the GNSS velocity's correlated error as two Gauss-Markov states."""
    return inputs.gnss_velocity_error_std_mps > 0.0 and inputs.gnss_velocity_error_time_s > 0.0


def _state_names(inputs: NavInputs) -> list[str]:
    return (["px", "py", "v", "psi", "omega"] + [f"bias.{g.name}" for g in inputs.gyros] + ["bias.steering"]
            + [f"scale.wheel_{w}" for w in ("fl", "fr", "rl", "rr")]
            + (["gnss_error.east", "gnss_error.north"] if models_gnss_error(inputs) else [])
            + (["gnss_velocity_error.east", "gnss_velocity_error.north"] if models_gnss_velocity_error(inputs)
               else [])
            + (["offset.gnss_heading"] if inputs.gnss_heading is not None else []))


def _initial_state(inputs: NavInputs, config: Config, n: int, gnss_i: int) -> tuple[float, Array, Array]:
    """Start state from the first data: position and heading from GNSS, speed from wheels, yaw rate from gyros;
    ``gnss_i``: first of the two GNSS error states (-1: none). The GNSS heading's offset, where the filter has
    one, is the last state."""
    pos = inputs.gnss_position
    assert pos is not None
    vel = inputs.gnss_velocity
    x0 = np.zeros(n)
    P0 = np.zeros((n, n))
    t_start = float(pos.t[0])
    psi, psi_std = 0.0, np.pi
    v_fixes: tuple[float, float] | None = None
    if vel is not None:
        speed = np.hypot(vel.z[:, 0], vel.z[:, 1])
        moving = np.flatnonzero(speed > 0.5)
        if len(moving):
            k = moving[0]
            psi = float(np.arctan2(vel.z[k, 1], vel.z[k, 0]))
            psi_std = float(3 * vel.sigma[0] / speed[k]) + 0.02
            t_start = max(t_start, float(vel.t[k]))
    else:  # a receiver logging fixes alone: the course of its first move clear of their noise
        start = _first_move(pos, inputs.gnss_error_std_m)
        if start is not None:
            t_start, psi, psi_std, v_fixes = start
    k = int(np.searchsorted(pos.t, t_start - 1e-9))
    k = min(k, len(pos.t) - 1)
    t_start = max(t_start, float(pos.t[k]))
    lx, ly = gnss_lever_rear(inputs, config)
    c, s = np.cos(psi), np.sin(psi)
    x0[m.PX] = pos.z[k, 0] - (c * lx - s * ly)
    x0[m.PY] = pos.z[k, 1] - (s * lx + c * ly)
    x0[m.PSI] = psi
    v0, v_std = 0.0, 2.0
    if inputs.wheels is not None:
        near = np.abs(inputs.wheels.t - t_start) < 0.1
        if near.any():
            v0, v_std = float(np.median(inputs.wheels.z[near][:, 2:])), 0.1
    elif vel is not None:
        v0 = float(np.hypot(*vel.z[np.argmin(np.abs(vel.t - t_start))]))
    elif v_fixes is not None:
        v0, v_std = v_fixes
    x0[m.V] = v0
    rates = [float(np.median(g.z[np.abs(g.t - t_start) < 0.1, 0])) for g in inputs.gyros
             if (np.abs(g.t - t_start) < 0.1).any()]
    x0[m.OMEGA] = float(np.median(rates)) if rates else 0.0
    pos_var = pos.sigma[0] ** 2 + inputs.gnss_error_std_m**2  # the first fix's whole error
    diag = [pos_var, pos_var, v_std**2, psi_std**2, 0.02**2]
    diag += [b**2 for b in inputs.gyro_bias_std] + [max(inputs.steering_offset_std, 1e-4) ** 2]
    diag += [max(inputs.wheel_scale_std, 1e-4) ** 2] * 4
    if gnss_i >= 0:
        diag += [inputs.gnss_error_std_m**2] * 2
    if models_gnss_velocity_error(inputs):
        diag += [inputs.gnss_velocity_error_std_mps**2] * 2
    if inputs.gnss_heading is not None:
        diag += [inputs.gnss_heading_offset_std**2]
    P0[np.diag_indices(n)] = diag
    if gnss_i >= 0:  # the start is the fix minus its error: they are anti-correlated
        e, var = gnss_i, inputs.gnss_error_std_m**2
        P0[m.PX, e] = P0[e, m.PX] = P0[m.PY, e + 1] = P0[e + 1, m.PY] = -var
    return t_start, x0, P0


#: a start course from fixes alone: the first move this many times their per-fix noise (white and slow)
FIRST_MOVE_SIGMAS = 8.0


def _first_move(pos: Measurements, slow_std_m: float) -> tuple[float, float, float, tuple[float, float]] | None:
    """Where a drive has fixes but no GNSS velocity: (start time, course, its std, (speed, its std)) of the first
    move between two fixes that clears ``FIRST_MOVE_SIGMAS`` times the fixes' noise (the shortest such move ending
    at the first fix that far from the drive's first), taken at its middle; None where the fixes never move so far.
    The slow error moves both ends alike over a few seconds, so the white noise sets the course's std; the slow
    error only sets how far is clear."""
    white = float(pos.sigma[0])
    need = FIRST_MOVE_SIGMAS * float(np.hypot(white, slow_std_m))
    far = np.flatnonzero(np.hypot(*(pos.z[:, :2] - pos.z[0, :2]).T) > need)
    if not len(far):
        return None
    k = int(far[0])
    j = int(np.flatnonzero(np.hypot(*(pos.z[k, :2] - pos.z[:k, :2]).T) > need)[-1])  # fix 0 is one
    step = pos.z[k, :2] - pos.z[j, :2]
    dist = float(np.hypot(*step))
    speed = dist / max(float(pos.t[k] - pos.t[j]), 1e-3)
    course_std = float(np.sqrt(2.0) * white / dist) + 0.05  # + a turn within the move
    return 0.5 * float(pos.t[j] + pos.t[k]), float(np.arctan2(step[1], step[0])), course_std, (speed, 0.5 * speed + 0.2)


def gnss_lever_rear(inputs: NavInputs, config: Config) -> tuple[float, float]:
    """The GNSS antenna's horizontal lever arm from the rear axle (m, body frame)."""
    lx, ly, _ = inputs.gnss_lever_m
    return lx + config.vehicle.cog_to_rear_axle_m, ly


def run_sarmin(inputs: NavInputs, config: Config, smooth: bool = True, engine: str = "numba",
               smoothed_covariance: bool = True) -> NavSolution:
    """Filter (and by default smooth) the drive; states at every measurement instant.

    ``engine``: "numba" (compiled loop, :mod:`.sarmin_kernel`) or "numpy" (the same filter through
    filterpy's sigma points and unscented transform, one Python call per measurement: the reference).
    ``smoothed_covariance=False`` (numba, with ``smooth``): smooth the states alone, for a pass whose states
    feed fits; the solution keeps what :func:`with_smoothed_covariance` needs to finish.
    """
    nav = config.navigation
    veh = config.vehicle
    ng = len(inputs.gyros)
    steer_i = m.N_KINEMATIC + ng
    scale_i = steer_i + 1  # four wheel scale errors (tyre radius): left/right differences fake a yaw rate
    gnss_i = scale_i + 4 if models_gnss_error(inputs) else -1  # the GNSS position's slow error (east, north)
    names = _state_names(inputs)
    n = len(names)
    # the GNSS heading's constant offset
    heading_i = names.index("offset.gnss_heading") if inputs.gnss_heading is not None else -1
    t_start, x0, P0 = _initial_state(inputs, config, n, gnss_i)

    q = np.zeros(n)
    q[m.PX] = q[m.PY] = nav.position_noise_m**2
    q[m.V] = nav.speed_noise_mps2**2
    q[m.PSI] = 1e-8
    q[m.OMEGA] = nav.yaw_rate_noise_radps2**2
    q[m.N_KINEMATIC:m.N_KINEMATIC + ng] = np.square(inputs.gyro_bias_walk)
    q[steer_i] = 1e-12
    q[scale_i:scale_i + 4] = 1e-12
    if heading_i >= 0:
        q[heading_i] = 1e-12
    beta = np.zeros(n)  # decay rates (1/s) of the Gauss-Markov states
    if gnss_i >= 0:
        beta[gnss_i:gnss_i + 2] = 1.0 / inputs.gnss_error_time_s
        q[gnss_i:gnss_i + 2] = 2.0 * inputs.gnss_error_std_m**2 * beta[gnss_i]
    # the GNSS velocity's correlated error (east, north)
    vel_i = names.index("gnss_velocity_error.east") if models_gnss_velocity_error(inputs) else -1
    if vel_i >= 0:
        beta[vel_i:vel_i + 2] = 1.0 / inputs.gnss_velocity_error_time_s
        q[vel_i:vel_i + 2] = 2.0 * inputs.gnss_velocity_error_std_mps**2 * beta[vel_i]

    # One event list: (time, sensor kind, sample index), in time order.
    sources: list[tuple[str, Measurements]] = [(f"gyro{i}", g) for i, g in enumerate(inputs.gyros)]
    for kind, meas in (("wheels", inputs.wheels), ("steering", inputs.steering), ("gnss_pos", inputs.gnss_position),
                       ("gnss_vel", inputs.gnss_velocity), ("gnss_heading", inputs.gnss_heading),
                       ("standstill", inputs.standstill)):
        if meas is not None:
            sources.append((kind, meas))
    times = np.concatenate([s.t for _, s in sources])
    kinds = np.concatenate([np.full(len(s.t), i, dtype=np.int32) for i, (_, s) in enumerate(sources)])
    index = np.concatenate([np.arange(len(s.t)) for _, s in sources])
    order = np.argsort(times, kind="stable")
    keep = times[order] >= t_start
    order = order[keep]

    gnss_lever = gnss_lever_rear(inputs, config)
    if engine == "numba":
        return _run_kernel(inputs, config, smooth, sources, times, kinds, index, order, t_start, x0, P0, q,
                           beta, names, steer_i, scale_i, gnss_i, heading_i, vel_i, gnss_lever, smoothed_covariance)
    from .ukf import FilterHistory, VectorUKF, rts_smooth  # filterpy (and its scipy.stats): ~0.4 s to import

    slip = veh.rear_slip_gain_rad_per_mps2
    ukf = VectorUKF(x0, P0, lambda X, dt: m.decay_parameters(m.ctrv_step(X, dt, slip), beta, dt),
                    angle_indices=[m.PSI], alpha=SIGMA_ALPHA, beta=SIGMA_BETA, kappa=3.0 - n)

    def wheel_fn(X: Array) -> Array:
        return m.measured_wheel_speeds(X, scale_i, veh.wheelbase_m, veh.track_front_m, veh.track_rear_m, slip,
                                       inputs.rigid_wheels)

    gates = {k: chi2_gate(nav.gate_probability, k) for k in (1, 2, 4)}
    rejected: dict[str, int] = {}
    updates: dict[str, int] = {}
    hist = FilterHistory()
    hist.t.append(t_start)
    hist.x.append(ukf.x.copy())
    hist.P.append(ukf.P.copy())
    t_now = t_start

    def advance(t: float) -> None:
        nonlocal t_now
        while t - t_now > nav.max_step_s + m.STEP_SLACK_S:  # dead reckoning through gaps, in bounded steps
            step = ukf.predict(nav.max_step_s, np.diag(m.process_noise(q, beta, nav.max_step_s)))
            t_now += nav.max_step_s
            hist.steps.append(step)
            hist.t.append(t_now)
            hist.x.append(ukf.x.copy())
            hist.P.append(ukf.P.copy())
        dt = max(t - t_now, 0.0)
        hist.steps.append(ukf.predict(dt, np.diag(m.process_noise(q, beta, dt))))
        t_now = max(t, t_now)

    for e in order:
        kind, meas = sources[kinds[e]]
        i = index[e]
        advance(float(times[e]))
        z = meas.z[i]
        ok = True
        if kind.startswith("gyro"):
            g = int(kind[4:])
            bias_i = m.N_KINEMATIC + g
            ok = ukf.update(z, lambda X, b=bias_i: m.gyro(X, b), np.diag(meas.sigma**2), gates[1])
        elif kind == "wheels":
            ok = ukf.update(z, wheel_fn, np.diag(meas.sigma**2), gates[4])
        elif kind == "steering":
            if ukf.x[m.V] < nav.steering_min_speed_mps:
                ok = None  # type: ignore[assignment]
            else:
                ok = ukf.update(z, lambda X: m.road_wheel_angle(X, veh.wheelbase_m, steer_i,
                                                                veh.understeer_gradient_rad_per_mps2),
                                np.diag(meas.sigma**2), gates[1], hold=steering_held_states(scale_i))
        elif kind == "gnss_pos":
            ok = ukf.update(z, lambda X: m.gnss_position(X, gnss_lever, gnss_i), np.diag(meas.sigma**2), gates[2])
        elif kind == "gnss_vel":
            ok = ukf.update(z, lambda X: m.point_velocity(X, gnss_lever, slip, vel_i), np.diag(meas.sigma**2),
                            gates[2])
        elif kind == "gnss_heading":
            # the heading nearest the prediction: the innovation on the circle
            zp = ukf.x[m.PSI] + ukf.x[heading_i]
            ok = ukf.update(zp + wrap_angle(z - zp), lambda X: m.gnss_heading(X, heading_i),
                            np.diag(meas.sigma**2), gates[1])
        elif kind == "standstill":
            ok = ukf.update(z, lambda X: X[:, m.OMEGA:m.OMEGA + 1], np.diag(meas.sigma**2), gates[1])
        key = kind if not kind.startswith("gyro") else inputs.gyros[int(kind[4:])].name
        if ok is False:
            rejected[key] = rejected.get(key, 0) + 1
        elif ok:
            updates[key] = updates.get(key, 0) + 1
        hist.t.append(t_now)
        hist.x.append(ukf.x.copy())
        hist.P.append(ukf.P.copy())
    if len(hist.t) < 2:
        raise NavInputError("no measurement after the initial GNSS fix: nothing to navigate")
    if smooth:
        xs, Ps = rts_smooth(hist, angle_indices=[m.PSI])
    else:
        xs, Ps = np.array(hist.x), np.array(hist.P)
    t = np.array(hist.t)
    # Several measurements at one instant give several states at that instant: keep the last (most informed).
    last = np.r_[np.diff(t) > 0, True]
    return NavSolution(t[last], xs[last], Ps[last], names, rejected, updates)


def _run_kernel(inputs: NavInputs, config: Config, smooth: bool, sources: list[tuple[str, Measurements]],
                times: Array, kinds: NDArray[np.int32], index: NDArray[np.int64], order: NDArray[np.int64],
                t_start: float, x0: Array, P0: Array, q: Array, beta: Array, names: list[str], steer_i: int,
                scale_i: int, gnss_i: int, heading_i: int, vel_i: int, gnss_lever: tuple[float, float],
                smoothed_covariance: bool) -> NavSolution:
    from . import sarmin_kernel as kern

    nav, veh = config.navigation, config.vehicle
    ng = len(inputs.gyros)
    # the kernel's event kinds (its module docstring): the gyros 0 .. ng-1, then these
    code = {k: ng + i for i, k in enumerate(("wheels", "steering", "gnss_pos", "gnss_vel", "gnss_heading",
                                                     "standstill"))}
    src_code = np.array([int(k[4:]) if k.startswith("gyro") else code[k] for k, _ in sources], dtype=np.int64)
    E = len(order)
    zs = np.zeros((E, 4))
    sig = np.ones((E, 4))
    ev_kind = src_code[kinds[order]]
    for s_idx, (_, meas) in enumerate(sources):
        sel = np.flatnonzero(kinds[order] == s_idx)
        k = meas.z.shape[1]
        zs[sel, :k] = meas.z[index[order][sel]]
        sig[sel, :k] = meas.sigma
    gates = np.zeros(5)
    for k in (1, 2, 4):
        gates[k] = chi2_gate(nav.gate_probability, k)
    geo = np.array([veh.wheelbase_m, veh.track_front_m, veh.track_rear_m, gnss_lever[0], gnss_lever[1],
                    veh.understeer_gradient_rad_per_mps2, veh.rear_slip_gain_rad_per_mps2, float(inputs.rigid_wheels),
                    float(vel_i)])
    steer_hold = np.zeros(len(x0), dtype=np.bool_)
    steer_hold[list(steering_held_states(scale_i))] = True
    wm, wc, lam = kern.merwe_weights(len(x0), SIGMA_ALPHA, SIGMA_BETA, 3.0 - len(x0))
    if E == 0:
        raise NavInputError("no measurement after the initial GNSS fix: nothing to navigate")
    # wsum: the exact sum of filterpy's weights (see the kernel's docstring).
    with interrupts_held():
        try:
            T, X, PP, XP, FF, PK, DT, used, rejected = kern.run_filter(
                times[order], ev_kind, zs, sig, t_start, x0, P0, q, beta, wm, wc, lam, ng, geo, scale_i, steer_i,
                gnss_i, heading_i, nav.steering_min_speed_mps, gates, nav.max_step_s, m.STEP_SLACK_S, math.fsum(wm),
                steer_hold)
        except np.linalg.LinAlgError as exc:  # the covariance lost its square root: numbers far off the drive's
            raise NavInputError(f"the filter failed ({exc}): a process noise (navigation.*_noise_*) or a sensor's "
                                "error table far off what the drive shows?") from exc
        filtered = None
        if not smooth:
            xs, Ps = X, PP
        elif smoothed_covariance:
            xs, Ps = kern.smooth(X, PP, XP, FF, PK, DT, q, beta)
        else:
            filtered = _FilterHistory(X.copy(), PP, XP, FF, PK, DT, q, beta)
            xs, Ps = kern.smooth_means(X, PP, XP, FF, PK, DT, q, beta), PP
    label = [g.name for g in inputs.gyros] + list(code)
    # One state per distinct instant already (the kernel refines a state for measurements at its instant).
    return NavSolution(T, xs, Ps, names,
                       {label[i]: int(v) for i, v in enumerate(rejected) if v},
                       {label[i]: int(v) for i, v in enumerate(used) if v}, filtered)
