"""Unscented Kalman filter with models vectorised over sigma points, and an RTS smoother for
asynchronous steps.

filterpy supplies the sigma-point machinery (:class:`filterpy.kalman.MerweScaledSigmaPoints` and
:func:`filterpy.kalman.unscented_transform`). Its ``UnscentedKalmanFilter`` calls the models once per
sigma point from Python and its ``rts_smoother`` assumes one uniform step between stored states; here
the models take all sigma points at once and every step keeps its own ``dt``, so the smoother works on
a filter that predicted to each measurement's own timestamp.

Angles: state components listed in ``angle_indices`` are averaged on the circle and their residuals
wrapped to [-pi, pi).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints, unscented_transform
from numpy.typing import NDArray

from .frames import wrap_angle

Array = NDArray[np.float64]


@dataclass
class StepRecord:
    """What the smoother needs from one predict step k -> k+1."""

    x_pred: Array
    P_pred: Array
    cross: Array  # cov(x_k, x_{k+1|k})


@dataclass
class FilterHistory:
    t: list[float] = field(default_factory=list)
    x: list[Array] = field(default_factory=list)
    P: list[Array] = field(default_factory=list)
    steps: list[StepRecord] = field(default_factory=list)  # steps[k]: transition from state k to k+1


class VectorUKF:
    """UKF whose process and measurement functions map (m, n) sigma points to (m, ...) at once."""

    def __init__(self, x0: Array, P0: Array, fx: Callable[[Array, float], Array], angle_indices: Sequence[int] = (),
                 alpha: float = 1e-3, beta: float = 2.0, kappa: float | None = None) -> None:
        n = len(x0)
        self.x = np.asarray(x0, dtype=np.float64).copy()
        self.P = np.asarray(P0, dtype=np.float64).copy()
        self.fx = fx
        self.angles = list(angle_indices)
        self.points = MerweScaledSigmaPoints(n, alpha=alpha, beta=beta, kappa=3.0 - n if kappa is None else kappa,
                                             subtract=self._residual_x)
        self.Wm, self.Wc = self.points.Wm, self.points.Wc

    # -- angle-aware mean and residual ---------------------------------------------------------------
    def _residual_x(self, a: Array, b: Array) -> Array:
        d = np.subtract(a, b)
        if self.angles:
            d[..., self.angles] = wrap_angle(d[..., self.angles])
        return d

    def _mean_x(self, sigmas: Array, Wm: Array) -> Array:
        """Weighted mean; angles as the centre point plus the weighted mean of wrapped deviations.

        Merwe weights with a small alpha are large and of both signs (the centre weight is about
        -n / alpha^2 (n + kappa)), so averaging sin/cos would cancel catastrophically; deviations are small.
        """
        x = Wm @ sigmas
        for i in self.angles:
            ref = sigmas[0, i]
            x[i] = float(wrap_angle(ref + Wm @ wrap_angle(sigmas[:, i] - ref)))
        return x

    def _sigmas(self) -> Array:
        P = 0.5 * (self.P + self.P.T)
        return self.points.sigma_points(self.x, P)

    # -- filter ----------------------------------------------------------------------------------------
    def predict(self, dt: float, Q: Array) -> StepRecord:
        """Propagate by ``dt`` seconds with additive process noise ``Q``; returns the smoother's record."""
        sigmas = self._sigmas()
        prop = self.fx(sigmas, dt)
        x_pred, P_pred = unscented_transform(prop, self.Wm, self.Wc, Q, self._mean_x, self._residual_x)
        dx = self._residual_x(sigmas, self.x)
        dy = self._residual_x(prop, x_pred)
        cross = (self.Wc[:, None] * dx).T @ dy
        self.x, self.P = x_pred, P_pred
        return StepRecord(x_pred.copy(), P_pred.copy(), cross)

    def update(self, z: Array, hx: Callable[[Array], Array], R: Array, gate_chi2: float | None = None,
               hold: Sequence[int] = ()) -> bool:
        """Correct with measurement ``z`` (k,), model ``hx`` ((m, n) -> (m, k)), noise ``R`` (k, k).

        Returns False (and leaves the state alone) when the squared Mahalanobis distance of the
        innovation exceeds ``gate_chi2``. ``hold``: states the update leaves alone (Schmidt's consider
        update: their gain rows are zero and the covariance is the one for that gain,
        P - K Pxz^T - Pxz K^T + K S K^T).
        """
        sigmas = self._sigmas()
        zs = hx(sigmas)
        zp = self.Wm @ zs
        dz = zs - zp
        S = (self.Wc[:, None] * dz).T @ dz + R
        y = np.asarray(z, dtype=np.float64) - zp
        try:
            S_inv = np.linalg.inv(S)
        except np.linalg.LinAlgError:
            return False
        if gate_chi2 is not None and float(y @ S_inv @ y) > gate_chi2:
            return False
        dx = self._residual_x(sigmas, self.x)
        Pxz = (self.Wc[:, None] * dx).T @ dz
        K = Pxz @ S_inv
        if len(hold):
            K[list(hold)] = 0.0
        self.x = self.x + K @ y
        for i in self.angles:
            self.x[i] = wrap_angle(self.x[i])
        if len(hold):
            self.P = self.P - K @ Pxz.T - Pxz @ K.T + K @ S @ K.T
        else:
            self.P = self.P - K @ S @ K.T
        return True


def rts_smooth(history: FilterHistory, angle_indices: Sequence[int] = ()) -> tuple[Array, Array]:
    """Unscented RTS smoother over a filter history with arbitrary steps; returns (xs (K, n), Ps (K, n, n))."""
    x = np.array(history.x)
    P = np.array(history.P)
    xs, Ps = x.copy(), P.copy()
    angles = list(angle_indices)
    for k in range(len(x) - 2, -1, -1):
        st = history.steps[k]
        G = np.linalg.solve(st.P_pred.T, st.cross.T).T  # cross @ inv(P_pred)
        d = xs[k + 1] - st.x_pred
        if angles:
            d[angles] = wrap_angle(d[angles])
        xs[k] = x[k] + G @ d
        if angles:
            xs[k, angles] = wrap_angle(xs[k, angles])
        Ps[k] = P[k] + G @ (Ps[k + 1] - st.P_pred) @ G.T
    return xs, Ps
