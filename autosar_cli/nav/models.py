"""SAR-MIN motion and measurement models (paper Sec. II-B, eq. 8-9), vectorised over sigma points.

State (ENU navigation frame, SI): ``[px, py, v, psi, omega, b_1 .. b_N, b_steer, s_fl .. s_rr, e_x, e_y]``.

- ``px, py``: the centre of the rear axle. It moves at the rear tyres' slip angle ``alpha = g v omega`` from the
  body x-axis (``g`` the rear-slip gain, rad per m/s^2 of lateral acceleration; 0: no side slip), along
  ``psi - alpha``: CTRV with that course is exact for a steady turn.
- ``v``: speed of that point (m/s); ``psi``: heading of the body x-axis (rad, from East, CCW), what the gyros
  integrate; ``omega``: yaw rate (rad/s).
- ``b_i``: bias of gyro i (rad/s); ``b_steer``: road-wheel angle offset of the steering sensor (rad).
- ``s_w``: scale error of wheel w's speed (tyre radius); ``e_x, e_y``: the GNSS position's slow error (m,
  ENU), first-order Gauss-Markov (only with ``navigation.gnss_error_model = "gauss_markov"``).

The kinematic states follow CTRV; the others are parameters that either stay constant (random walk) or
decay as Gauss-Markov processes with rate ``beta`` (1/s): ``x' = exp(-beta dt) x`` plus noise.

All functions take ``X`` of shape (m, n): one row per sigma point.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: a bounded prediction step through a gap is taken only where it leaves more than this to the next instant (s): a
#: step landing within a ns of a measurement's instant wrote two trajectory samples the same ns once rounded
STEP_SLACK_S = 1e-9

PX, PY, V, PSI, OMEGA = 0, 1, 2, 3, 4
N_KINEMATIC = 5

Array = NDArray[np.float64]


def ctrv_step(X: Array, dt: float, slip_gain: float = 0.0) -> Array:
    """Constant turn rate and velocity over ``dt`` seconds (exact, smooth at omega -> 0).

    The chord is ``v dt sinc(omega dt / 2)`` long and points along ``psi - g v omega + omega dt / 2`` (``g`` =
    ``slip_gain``: the rear axle's course is the body's heading less the rear tyres' slip angle).
    """
    out = X.copy()
    v, psi, w = X[:, V], X[:, PSI], X[:, OMEGA]
    half = 0.5 * w * dt
    chord = v * dt * np.sinc(half / np.pi)  # numpy's sinc is sin(pi x)/(pi x)
    course = psi - slip_gain * v * w
    out[:, PX] += chord * np.cos(course + half)
    out[:, PY] += chord * np.sin(course + half)
    out[:, PSI] = psi + w * dt
    return out


def decay_parameters(X: Array, beta: Array, dt: float) -> Array:
    """Gauss-Markov parameters of every sigma point decayed over ``dt``: ``x_r exp(-beta_r dt)``;
    ``beta`` (n,) 1/s, 0 for kinematic and constant states. Returns a new array."""
    return X * np.exp(-beta * dt)


def process_noise(q: Array, beta: Array, dt: float) -> Array:
    """Diagonal process noise accumulated over ``dt`` (n,): ``q dt`` for a random walk of intensity ``q``,
    ``q (1 - exp(-2 beta dt)) / (2 beta)`` for a Gauss-Markov state of intensity ``q = 2 sigma^2 beta``
    (its steady variance ``sigma^2``); the second tends to the first as beta -> 0."""
    out = q * dt
    gm = beta > 0
    out[gm] = q[gm] * -np.expm1(-2.0 * beta[gm] * dt) / (2.0 * beta[gm])
    return out


def point_position(X: Array, lever_xy: tuple[float, float]) -> Array:
    """ENU (x, y) of a body point ``lever_xy`` (m, body frame relative to the rear-axle centre); (m, 2)."""
    c, s = np.cos(X[:, PSI]), np.sin(X[:, PSI])
    lx, ly = lever_xy
    return np.stack([X[:, PX] + c * lx - s * ly, X[:, PY] + s * lx + c * ly], axis=1)


def gnss_position(X: Array, lever_xy: tuple[float, float], error_index: int) -> Array:
    """GNSS fix (ENU x, y) of an antenna at ``lever_xy``: its position plus the slow error states
    ``X[:, error_index:error_index + 2]`` (``error_index < 0``: none modelled); (m, 2)."""
    p = point_position(X, lever_xy)
    return p + X[:, error_index:error_index + 2] if error_index >= 0 else p


def point_velocity(X: Array, lever_xy: tuple[float, float], slip_gain: float = 0.0, error_i: int = -1) -> Array:
    """ENU ground velocity (m/s) of a body point ``lever_xy`` relative to the rear-axle centre, the rear axle moving
    at the slip angle ``slip_gain v omega`` (see :func:`ctrv_step`); (m, 2). ``error_i``: first of two states
    (east, north) added to it, a GNSS velocity's correlated error (-1: none)."""
    c, s = np.cos(X[:, PSI]), np.sin(X[:, PSI])
    lx, ly = lever_xy
    alpha = slip_gain * X[:, V] * X[:, OMEGA]
    bx = X[:, V] * np.cos(alpha) - X[:, OMEGA] * ly  # body-frame velocity of the point
    by = -X[:, V] * np.sin(alpha) + X[:, OMEGA] * lx
    v = np.stack([c * bx - s * by, s * bx + c * by], axis=1)
    return v + X[:, error_i:error_i + 2] if error_i >= 0 else v


def wheel_speeds(X: Array, wheelbase_m: float, track_front_m: float, track_rear_m: float,
                 slip_gain: float = 0.0) -> Array:
    """Ground speed (m/s) of the four wheel centres (fl, fr, rl, rr) under the bicycle model; (m, 4).

    Rear wheels roll along the body: v cos(alpha) -+ omega * track/2, alpha = ``slip_gain`` v omega the rear axle's
    slip angle. Front wheels also move sideways at omega * wheelbase - v sin(alpha). Signed, negative
    where the state's speed is: the car drives forwards (an ABS ECU's speeds carry no sign). With unsigned
    predictions ``v`` and ``-v`` look alike to the wheels: at a stop the filter's speed could cross zero and go on
    backwards once the car pulled away, its GNSS updates then gated out (urban seed 0, kinematic: 172 m off).
    """
    v, w = X[:, V], X[:, OMEGA]
    alpha = slip_gain * v * w
    lat = w * wheelbase_m - v * np.sin(alpha)
    v = v * np.cos(alpha)
    left, right = v - w * track_front_m / 2, v + w * track_front_m / 2
    fl = np.copysign(np.hypot(left, lat), left)
    fr = np.copysign(np.hypot(right, lat), right)
    return np.stack([fl, fr, v - w * track_rear_m / 2, v + w * track_rear_m / 2], axis=1)


def measured_wheel_speeds(X: Array, scale_index: int, wheelbase_m: float, track_front_m: float, track_rear_m: float,
                          slip_gain: float = 0.0, rigid: bool = True) -> Array:
    """What the four wheels (fl, fr, rl, rr) read, for every sigma point; (m, 4) m/s. Signed: negative where the
    state's speed is (see :func:`wheel_speeds`).

    ``rigid``: ``(1 + s_w)`` times the wheel centre's ground speed along its plane (:func:`wheel_speeds`). Exact for
    tyres of fixed radius on a rigid bicycle, and then the right-left difference ``omega T (1 + s)`` calibrates the
    common scale ``s`` against the gyros' yaw rate, known to 0.1 %: a strong measure in every turn.

    Else load-compliant: a wheel reads ``(1 + s_w) v cos(alpha) -+ omega T / 2``, the front ones plus the excess of
    their ground speed over that (their sideways ``omega L - v sin(alpha)``) taken at the mean point ``X[0]``. Where
    the outer tyres roll on a smaller radius, track and radii are known only to the load gains' fit; the difference
    then carries their error into the scale (full vehicle, test3: the track 0.1 % long), and the front-rear ratio,
    1 + (omega L / v)^2 / 2, into the speed amplified (v / omega L)^2-fold (the front tyres' slip angles and
    parallel steering: 0.03 % long). Here neither informs the scale or the speed.
    """
    v, w = X[:, V], X[:, OMEGA]
    alpha = slip_gain * v * w
    scale = 1.0 + X[:, scale_index:scale_index + 4]
    if rigid:
        return scale * wheel_speeds(X, wheelbase_m, track_front_m, track_rear_m, slip_gain)
    forward = v * np.cos(alpha)
    out = np.stack([forward * scale[:, 0] - w * track_front_m / 2, forward * scale[:, 1] + w * track_front_m / 2,
                    forward * scale[:, 2] - w * track_rear_m / 2, forward * scale[:, 3] + w * track_rear_m / 2], axis=1)
    lat0 = w[0] * wheelbase_m - v[0] * np.sin(alpha[0])
    for k in (0, 1):
        f0 = out[0, k]
        out[:, k] += np.copysign(np.hypot(f0, lat0), f0) - f0
    return out


def road_wheel_angle(X: Array, wheelbase_m: float, steer_bias_index: int, understeer_gradient: float = 0.0) -> Array:
    """Measured road-wheel angle (rad) = atan(L omega / v) + K v omega + offset; (m, 1): the linear single-track
    model's steady state, K the understeer gradient (rad per m/s^2 of lateral acceleration v omega; 0: the
    kinematic bicycle). Only meaningful for v > 0."""
    v = np.maximum(X[:, V], 1e-3)
    return (np.arctan(wheelbase_m * X[:, OMEGA] / v) + understeer_gradient * X[:, V] * X[:, OMEGA]
            + X[:, steer_bias_index])[:, None]


def gnss_heading(X: Array, offset_index: int) -> Array:
    """The body's heading as a GNSS receiver gives it (rad, ENU): the heading plus the constant offset state
    ``X[:, offset_index]`` (the antennas' baseline against the body's axis); (m, 1)."""
    return (X[:, PSI] + X[:, offset_index])[:, None]


def gyro(X: Array, bias_index: int) -> Array:
    """Yaw rate measured by a gyro with its own bias (rad/s); (m, 1)."""
    return (X[:, OMEGA] + X[:, bias_index])[:, None]
