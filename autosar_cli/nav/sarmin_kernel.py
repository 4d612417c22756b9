"""Compiled SAR-MIN filter loop (numba): the same UKF as :class:`~.ukf.VectorUKF` driven by
:func:`~.sarmin.run_sarmin`, without Python in the per-measurement path.

The sigma-point weights are Merwe's scaled points, computed by :func:`merwe_weights` with filterpy's
expressions (a test checks them equal to :class:`filterpy.kalman.MerweScaledSigmaPoints`'s, bit for bit;
importing filterpy costs ~0.4 s, which the compiled path does not need). The kernel reproduces filterpy's
sigma-point placement (columns ``L[:, j]`` of the lower Cholesky factor of
``(n + lambda) P``, i.e. the rows of filterpy's upper factor) and unscented transform.
``tests/test_nav_sarmin.py`` checks it against the numpy/filterpy path state by state.

Partitioned prediction. CTRV moves only the ``NK = 5`` kinematic states ``k``; the parameters ``p``
(biases, scales) are constant. With ``L = [[Lkk, 0], [Lpk, Lpp]]`` the sigma points built from the
parameter columns have the centre's kinematic part, so the full unscented transform reduces exactly to

- ``x_k'``, ``Pkk'``: the transform of the 11 points ``x_k``, ``x_k +- Lkk[:, j]`` (the ``2 (n - 5)``
  parameter points add their weight to the centre), plus ``Q_k dt``;
- ``Pkp' = F Pkp A`` with ``F = Wc_1 (n + lambda) M Lkk^-1`` and ``M[:, j] = dy_{+j} - dy_{-j}`` (the
  statistical linearisation of CTRV: ``Lpk^T = (n + lambda) Lkk^-1 Pkp``), ``Ppp' = A Ppp A + Q_p``, where
  ``A = diag(exp(-beta dt))`` decays the Gauss-Markov parameters (1 for the constant ones; the transform
  of a linear map is exact);
- the cross-covariance the smoother needs, ``cov(x, x') = P Phi^T`` with ``Phi = diag(F, A)``.

So the filter stores per step only ``x'``, ``F`` and ``Pkk'`` besides the filtered states; the smoother
rebuilds ``P_pred`` and the cross-covariance from them. Measurements at the instant of the previous one
(``dt = 0``) predict nothing (the transform is the identity there) and refine the same stored state:
the smoother sees one state per distinct instant, exactly what it would compute through identity steps.

Weighted means are summed as ``sum_i Wm_i y_i = wsum y_0 + sum_{i>0} Wm_i (y_i - y_0)`` with ``wsum`` the
exact sum of filterpy's weights (:func:`math.fsum`). Those weights are ~1e6 with both signs and sum to 1
only within ~1e-9; the reference's ``Wm @ sigmas`` carries that factor (on an ENU coordinate of 50 m,
~3e-8 m per step) and so does this form, without the cancellation error of summing the raw products.

Event kinds: ``0 .. ng-1`` gyro i; ``ng`` wheels; ``ng+1`` steering; ``ng+2`` GNSS position;
``ng+3`` GNSS velocity; ``ng+4`` GNSS heading (the heading plus the offset state ``heading_i``);
``ng+5`` a standstill's zero yaw rate.
Measurement values are padded to 4 columns. ``geo``: wheelbase, front and rear track,
GNSS lever (x, y), understeer gradient, rear-slip gain, 1 for the rigid wheel model or 0 for the
load-compliant one (:func:`~.models.measured_wheel_speeds`), and the first of the two GNSS velocity error
states (east, north; -1: none). ``gnss_i``: first of the two GNSS position error states (east, north), or -1
when the filter has none.
"""

from __future__ import annotations

import numpy as np
from numba import njit

PX, PY, V, PSI, OMEGA = 0, 1, 2, 3, 4
NK = 5  # kinematic states (the only ones CTRV moves); the rest are constant parameters


def merwe_weights(n: int, alpha: float, beta: float, kappa: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Mean and covariance weights (2n + 1 each) and ``lambda`` of Merwe's scaled sigma points, as
    :class:`filterpy.kalman.MerweScaledSigmaPoints` computes them (same expressions, same rounding)."""
    lam = alpha**2 * (n + kappa) - n
    c = 0.5 / (n + lam)
    wc = np.full(2 * n + 1, c)
    wm = np.full(2 * n + 1, c)
    wc[0] = lam / (n + lam) + (1 - alpha**2 + beta)
    wm[0] = lam / (n + lam)
    return wm, wc, float(lam)


@njit(cache=True)
def _wrap(a: float) -> float:
    """Angle to [-pi, pi); one already there is returned as it is (no round trip through +-pi)."""
    if -np.pi <= a < np.pi:
        return a
    return (a + np.pi) % (2.0 * np.pi) - np.pi


@njit(cache=True)
def _cholesky_into(A, scale, m, L, inv_diag):  # noqa: ANN001, ANN202
    """Lower Cholesky factor of ``scale * A[:m, :m]`` (SPD) into ``L``, 1 / diagonal into ``inv_diag``."""
    for j in range(m):
        d = scale * A[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if d <= 0.0:
            raise np.linalg.LinAlgError("covariance is not positive definite")
        s = np.sqrt(d)
        L[j, j] = s
        inv = 1.0 / s
        inv_diag[j] = inv
        for i in range(j + 1, m):
            v = scale * A[i, j]
            for k in range(j):
                v -= L[i, k] * L[j, k]
            L[i, j] = v * inv
        for i in range(j):
            L[i, j] = 0.0


@njit(cache=True)
def _ctrv_points(pts, prop, dt, slip):  # noqa: ANN001, ANN202
    """CTRV over ``dt`` of every kinematic sigma point: the chord ``v dt sinc(omega dt / 2)`` along
    ``psi - slip v omega + omega dt / 2`` (exact, smooth at omega -> 0; :func:`~.models.ctrv_step`)."""
    for i in range(pts.shape[0]):
        v, psi, w = pts[i, V], pts[i, PSI], pts[i, OMEGA]
        half = 0.5 * w * dt
        sinc = 1.0 if abs(half) < 1e-12 else np.sin(half) / half
        chord = v * dt * sinc
        course = psi - slip * v * w
        prop[i, PX] = pts[i, PX] + chord * np.cos(course + half)
        prop[i, PY] = pts[i, PY] + chord * np.sin(course + half)
        prop[i, V] = v
        prop[i, PSI] = psi + w * dt
        prop[i, OMEGA] = w


@njit(cache=True, inline="always")
def _sigma_points_into(x, L, m, pts):  # noqa: ANN001, ANN202
    """Symmetric sigma points of the first ``m`` states: ``pts[0] = x``, ``pts[1 + j] = x + L[:, j]``,
    ``pts[1 + m + j] = x - L[:, j]`` (``L`` the scaled Cholesky factor), headings wrapped to [-pi, pi)."""
    for r in range(m):
        pts[0, r] = x[r]
    for j in range(m):
        for r in range(m):
            pts[1 + j, r] = x[r] + L[r, j]
            pts[1 + m + j, r] = x[r] - L[r, j]
        pts[1 + j, PSI] = _wrap(pts[1 + j, PSI])
        pts[1 + m + j, PSI] = _wrap(pts[1 + m + j, PSI])


@njit(cache=True)
def _parameter_step(q, beta, dt, a, qd):  # noqa: ANN001, ANN202
    """Decay ``a = exp(-beta dt)`` and accumulated noise ``qd`` of every state over ``dt`` (as
    :func:`~.models.process_noise`: ``q dt``, or ``q (1 - a^2) / (2 beta)`` for a Gauss-Markov state)."""
    for r in range(q.shape[0]):
        if beta[r] > 0.0:
            a[r] = np.exp(-beta[r] * dt)
            qd[r] = q[r] * -np.expm1(-2.0 * beta[r] * dt) / (2.0 * beta[r])
        else:
            a[r] = 1.0
            qd[r] = q[r] * dt


@njit(cache=True)
def _predict(x, P, xn, Pn, dt, q, beta, Wm, Wc, c, wsum, L5, inv5, pts, prop, dy, F, Pkk, a, qd, slip):  # noqa: ANN001, ANN202
    """Unscented CTRV prediction of node ``(x, P)`` by ``dt`` into ``(xn, Pn)`` (partitioned, see the
    module docstring); also fills ``F`` and ``Pkk`` (the predicted kinematic block) for the smoother.
    ``a``, ``qd`` (n,): work vectors (each state's decay and process noise over ``dt``)."""
    n = x.shape[0]
    _parameter_step(q, beta, dt, a, qd)
    _cholesky_into(P, c, NK, L5, inv5)
    _sigma_points_into(x, L5, NK, pts)
    _ctrv_points(pts, prop, dt, slip)
    # Mean: the centre plus weighted deviations (the parameter points equal the centre); the heading as
    # wrapped deviations from the centre point (see ukf._mean_x).
    for r in range(NK):
        ref = prop[0, r]
        acc = 0.0
        if r == PSI:
            for i in range(1, 2 * NK + 1):
                acc += Wm[i] * _wrap(prop[i, r] - ref)
            xn[r] = _wrap(ref + acc)
        else:
            for i in range(1, 2 * NK + 1):
                acc += Wm[i] * (prop[i, r] - ref)
            xn[r] = wsum * ref + acc
    for i in range(2 * NK + 1):
        for r in range(NK):
            dy[i, r] = prop[i, r] - xn[r]
        dy[i, PSI] = _wrap(dy[i, PSI])
    w0 = Wc[0] + 2 * (n - NK) * Wc[1]  # the centre and the parameter points
    w1 = Wc[1]
    for r in range(NK):
        for col in range(r, NK):
            acc = 0.0
            for i in range(1, 2 * NK + 1):
                acc += dy[i, r] * dy[i, col]
            v = w0 * dy[0, r] * dy[0, col] + w1 * acc
            if col == r:
                v += qd[r]
            Pkk[r, col] = v
            Pkk[col, r] = v
    # F = Wc_1 (n + lambda) M Lkk^-1: each row solves Lkk^T f = s m (back substitution).
    s = w1 * c
    for r in range(NK):
        for i in range(NK - 1, -1, -1):
            v = s * (dy[1 + i, r] - dy[1 + NK + i, r])
            for j in range(i + 1, NK):
                v -= L5[j, i] * F[r, j]
            F[r, i] = v * inv5[i]
    for r in range(NK):
        for col in range(NK):
            Pn[r, col] = Pkk[r, col]
    _fill_parameter_blocks(P, F, Pn, n, a, qd)
    for r in range(NK, n):
        xn[r] = wsum * a[r] * x[r]  # sum_i Wm_i a x_p: the +-Lpk deviations cancel in pairs


@njit(cache=True)
def _fill_parameter_blocks(P, F, Pn, n, a, qd):  # noqa: ANN001, ANN202
    """``Pn[k, p] = F P[k, p] A`` (and its transpose), ``Pn[p, p] = A P[p, p] A + Qd``: the predicted
    covariance outside the kinematic block (shared by the filter and the smoother's rebuild)."""
    for r in range(NK):
        for col in range(NK, n):
            acc = 0.0
            for j in range(NK):
                acc += F[r, j] * P[j, col]
            acc *= a[col]
            Pn[r, col] = acc
            Pn[col, r] = acc
    for r in range(NK, n):
        for col in range(NK, n):
            Pn[r, col] = a[r] * a[col] * P[r, col]
        Pn[r, r] += qd[r]


@njit(cache=True)
def _measure(sig, kind, ng, geo, scale_i, steer_i, gnss_i, zsig):  # noqa: ANN001, ANN202
    """Predicted measurement of every sigma point for event ``kind`` into ``zsig``; returns its size."""
    m = sig.shape[0]
    wheelbase, tf, tr, lx, ly, k_us, slip = geo[0], geo[1], geo[2], geo[3], geo[4], geo[5], geo[6]
    if kind == ng:  # wheels fl, fr, rl, rr (models.measured_wheel_speeds)
        rigid = geo[7] > 0
        for i in range(m):
            v, w = sig[i, V], sig[i, OMEGA]
            forward = v * np.cos(slip * v * w)
            if rigid:
                lat = w * wheelbase - v * np.sin(slip * v * w)
                zsig[i, 0] = np.copysign(np.hypot(forward - w * tf / 2, lat), forward - w * tf / 2) * (
                    1.0 + sig[i, scale_i])
                zsig[i, 1] = np.copysign(np.hypot(forward + w * tf / 2, lat), forward + w * tf / 2) * (
                    1.0 + sig[i, scale_i + 1])
                zsig[i, 2] = (forward - w * tr / 2) * (1.0 + sig[i, scale_i + 2])
                zsig[i, 3] = (forward + w * tr / 2) * (1.0 + sig[i, scale_i + 3])
            else:
                zsig[i, 0] = forward * (1.0 + sig[i, scale_i]) - w * tf / 2
                zsig[i, 1] = forward * (1.0 + sig[i, scale_i + 1]) + w * tf / 2
                zsig[i, 2] = forward * (1.0 + sig[i, scale_i + 2]) - w * tr / 2
                zsig[i, 3] = forward * (1.0 + sig[i, scale_i + 3]) + w * tr / 2
        if not rigid:
            lat0 = sig[0, OMEGA] * wheelbase - sig[0, V] * np.sin(slip * sig[0, V] * sig[0, OMEGA])
            for k in range(2):
                f0 = zsig[0, k]
                excess = np.copysign(np.hypot(f0, lat0), f0) - f0
                for i in range(m):
                    zsig[i, k] += excess
        return 4
    if kind == ng + 1:  # road-wheel angle
        for i in range(m):
            v = max(sig[i, V], 1e-3)
            zsig[i, 0] = (np.arctan(wheelbase * sig[i, OMEGA] / v) + k_us * sig[i, V] * sig[i, OMEGA]
                          + sig[i, steer_i])
        return 1
    for i in range(m):
        c, s = np.cos(sig[i, PSI]), np.sin(sig[i, PSI])
        if kind == ng + 2:  # antenna position, plus the fix's slow error
            zsig[i, 0] = sig[i, PX] + c * lx - s * ly
            zsig[i, 1] = sig[i, PY] + s * lx + c * ly
            if gnss_i >= 0:
                zsig[i, 0] += sig[i, gnss_i]
                zsig[i, 1] += sig[i, gnss_i + 1]
        else:  # antenna velocity, the rear axle at its slip angle
            alpha = slip * sig[i, V] * sig[i, OMEGA]
            bx = sig[i, V] * np.cos(alpha) - sig[i, OMEGA] * ly
            by = -sig[i, V] * np.sin(alpha) + sig[i, OMEGA] * lx
            zsig[i, 0] = c * bx - s * by
            zsig[i, 1] = s * bx + c * by
            if geo[8] >= 0:  # plus its correlated error
                zsig[i, 0] += sig[i, int(geo[8])]
                zsig[i, 1] += sig[i, int(geo[8]) + 1]
    return 2


@njit(cache=True)
def _update_nl(x, P, z, sigma, kind, ng, geo, scale_i, steer_i, gnss_i, gate, Wm, Wc, c, wsum,  # noqa: ANN001, ANN202
               L, inv_d, sig, zsig, Pxz, Kg, S, Ls, v4, hold):
    """Unscented update of ``(x, P)`` in place; False (state untouched) when the gate rejects it.

    ``hold`` (n,) bool: states the update leaves alone (a Schmidt "consider" update: their estimate and
    their own covariance block stay, their cross-covariance with the updated states is the exact one for
    that gain).

    Work arrays: ``L`` (n, n), ``inv_d`` (n,), ``sig`` (2n+1, n), ``zsig`` (2n+1, 4), ``Pxz``, ``Kg``
    (n, 4), ``S``, ``Ls``, ``v4`` (4, 4).
    """
    n = x.shape[0]
    m = 2 * n + 1
    _cholesky_into(P, c, n, L, inv_d)
    _sigma_points_into(x, L, n, sig)
    k = _measure(sig, kind, ng, geo, scale_i, steer_i, gnss_i, zsig)
    zp, inv_s, y, u = v4[0], v4[1], v4[2], v4[3]
    for a in range(k):
        ref = zsig[0, a]
        acc = 0.0
        for i in range(1, m):
            acc += Wm[i] * (zsig[i, a] - ref)
        zp[a] = wsum * ref + acc
    for i in range(m):
        for a in range(k):
            zsig[i, a] -= zp[a]  # now dz
    for a in range(k):
        for b in range(a, k):
            acc = Wc[0] * zsig[0, a] * zsig[0, b]
            for i in range(1, m):
                acc += Wc[i] * zsig[i, a] * zsig[i, b]
            S[a, b] = acc
            S[b, a] = acc
        S[a, a] += sigma[a] * sigma[a]
    for j in range(k):  # Cholesky of S (k <= 4)
        d = S[j, j]
        for i in range(j):
            d -= Ls[j, i] * Ls[j, i]
        if d <= 0.0:
            return False
        Ls[j, j] = np.sqrt(d)
        inv_s[j] = 1.0 / Ls[j, j]
        for i in range(j + 1, k):
            v = S[i, j]
            for t in range(j):
                v -= Ls[i, t] * Ls[j, t]
            Ls[i, j] = v * inv_s[j]
    d2 = 0.0
    for a in range(k):
        y[a] = z[a] - zp[a]
        v = y[a]
        for b in range(a):
            v -= Ls[a, b] * u[b]
        u[a] = v * inv_s[a]
        d2 += u[a] * u[a]
    if d2 > gate:
        return False
    # Pxz = sum_i Wc_i dx_i dz_i^T with dx = +-L[:, j] (0 for the centre).
    w1 = Wc[1]
    for r in range(n):
        for a in range(k):
            acc = 0.0
            for j in range(r + 1):  # L is lower triangular
                acc += L[r, j] * (zsig[1 + j, a] - zsig[1 + n + j, a])
            Pxz[r, a] = w1 * acc
    # K = Pxz S^-1 (row by row through the Cholesky factor of S), x += K y, P -= K Pxz^T.
    for r in range(n):
        for a in range(k):
            v = Pxz[r, a]
            for b in range(a):
                v -= Ls[a, b] * Kg[r, b]
            Kg[r, a] = v * inv_s[a]
        for a in range(k - 1, -1, -1):
            v = Kg[r, a]
            for b in range(a + 1, k):
                v -= Ls[b, a] * Kg[r, b]
            Kg[r, a] = v * inv_s[a]
    for r in range(n):
        if hold[r]:
            continue
        acc = 0.0
        for a in range(k):
            acc += Kg[r, a] * y[a]
        x[r] += acc
    x[PSI] = _wrap(x[PSI])
    # P - K Pxz^T - Pxz K^T + K S K^T with K's held rows zeroed: the usual P - Pxz S^-1 Pxz^T except on the
    # held block, which stays.
    for r in range(n):
        for col in range(r, n):
            if hold[r] and hold[col]:
                continue
            acc = 0.0
            for a in range(k):
                acc += Kg[r, a] * Pxz[col, a]
            P[r, col] -= acc
        for col in range(r + 1, n):
            P[col, r] = P[r, col]
    return True


@njit(cache=True)
def _update_sum(x, P, z, sigma, i, j, circular, gate, ph):  # noqa: ANN001, ANN202
    """Update with z = x_i + x_j (a gyro: omega + its bias; the GNSS heading: psi + its offset, ``circular``: the
    innovation taken on the circle), or z = x_i where ``j < 0`` (a standstill: omega).
    Linear in the state, so the Kalman update is what the unscented one computes
    (the unscented transform is exact for linear functions), at O(n^2) without sigma points."""
    n = x.shape[0]
    y = z - x[i] - (x[j] if j >= 0 else 0.0)
    if circular:
        y = _wrap(y)
    for r in range(n):
        ph[r] = P[r, i] + (P[r, j] if j >= 0 else 0.0)  # P H^T
    S = ph[i] + (ph[j] if j >= 0 else 0.0) + sigma * sigma
    if y * y / S > gate:
        return False
    g = y / S
    for r in range(n):
        x[r] += ph[r] * g
    x[PSI] = _wrap(x[PSI])
    for r in range(n):
        a = ph[r] / S
        for col in range(r, n):
            P[r, col] -= a * ph[col]
        for col in range(r + 1, n):
            P[col, r] = P[r, col]
    return True


@njit(cache=True)
def run_filter(times, kinds, zs, sigmas, t_start, x0, P0, q, beta, Wm, Wc, lam, ng, geo, scale_i, steer_i,  # noqa: ANN001, ANN201
               gnss_i, heading_i, steer_min_speed, gates, max_step, step_slack, wsum, steer_hold):
    """Filter all events in time order; one stored state per distinct instant.

    ``steer_hold`` (n,) bool: the states a steering update leaves alone (see :func:`_update_nl`).
    ``step_slack`` (s): a bounded step of ``max_step`` is taken only where it leaves more than this to the next
    instant (:data:`.models.STEP_SLACK_S`; an argument, not a global, so that a cached kernel cannot keep an old one).

    Returns ``T, X, PP`` (node times, filtered states and covariances), ``XP, FF, PK, DT`` (per step
    k -> k+1: predicted state, linearised kinematic transition, predicted kinematic covariance, dt) and
    per-kind counts of used and rejected measurements.
    """
    n = x0.shape[0]
    E = times.shape[0]
    span = times[-1] - t_start if E else 0.0
    cap = E + int(span / max_step) + 2
    c = n + lam
    T = np.empty(cap)
    X = np.empty((cap, n))
    PP = np.empty((cap, n, n))
    XP = np.empty((cap, n))
    FF = np.empty((cap, NK, NK))
    PK = np.empty((cap, NK, NK))
    DT = np.empty(cap)
    used = np.zeros(ng + 6, dtype=np.int64)
    rejected = np.zeros(ng + 6, dtype=np.int64)
    # work buffers
    L5 = np.zeros((NK, NK))
    inv5 = np.empty(NK)
    pts = np.empty((2 * NK + 1, NK))
    prop = np.empty((2 * NK + 1, NK))
    dy = np.empty((2 * NK + 1, NK))
    L = np.zeros((n, n))
    inv_d = np.empty(n)
    sig = np.empty((2 * n + 1, n))
    zsig = np.empty((2 * n + 1, 4))
    Pxz = np.empty((n, 4))
    Kg = np.empty((n, 4))
    S = np.zeros((4, 4))
    Ls = np.zeros((4, 4))
    v4 = np.empty((4, 4))
    ph = np.empty(n)
    a = np.empty(n)
    qd = np.empty(n)
    no_hold = np.zeros(n, dtype=np.bool_)
    X[0] = x0
    for r in range(n):
        for col in range(n):
            PP[0, r, col] = 0.5 * (P0[r, col] + P0[col, r])
    t_now = t_start
    T[0] = t_now
    K = 0
    for e in range(E):
        t = times[e]
        while t - t_now > max_step + step_slack:  # dead reckoning through gaps, in bounded steps
            _predict(X[K], PP[K], X[K + 1], PP[K + 1], max_step, q, beta, Wm, Wc, c, wsum, L5, inv5, pts, prop,
                     dy, FF[K], PK[K], a, qd, geo[6])
            XP[K] = X[K + 1]
            DT[K] = max_step
            t_now += max_step
            K += 1
            T[K] = t_now
        if t > t_now:
            _predict(X[K], PP[K], X[K + 1], PP[K + 1], t - t_now, q, beta, Wm, Wc, c, wsum, L5, inv5, pts, prop,
                     dy, FF[K], PK[K], a, qd, geo[6])
            XP[K] = X[K + 1]
            DT[K] = t - t_now
            t_now = t
            K += 1
            T[K] = t_now
        x = X[K]
        P = PP[K]
        kind = kinds[e]
        if kind == ng + 1 and x[V] < steer_min_speed:
            continue
        if kind < ng:
            ok = _update_sum(x, P, zs[e, 0], sigmas[e, 0], OMEGA, NK + kind, False, gates[1], ph)
        elif kind == ng + 4:
            ok = _update_sum(x, P, zs[e, 0], sigmas[e, 0], PSI, heading_i, True, gates[1], ph)
        elif kind == ng + 5:
            ok = _update_sum(x, P, zs[e, 0], sigmas[e, 0], OMEGA, -1, False, gates[1], ph)
        else:
            k_dim = 4 if kind == ng else (1 if kind == ng + 1 else 2)
            ok = _update_nl(x, P, zs[e], sigmas[e], kind, ng, geo, scale_i, steer_i, gnss_i, gates[k_dim], Wm, Wc, c,
                            wsum, L, inv_d, sig, zsig, Pxz, Kg, S, Ls, v4,
                            steer_hold if kind == ng + 1 else no_hold)
        if ok:
            used[kind] += 1
        else:
            rejected[kind] += 1
    K += 1
    return T[:K], X[:K], PP[:K], XP[:K - 1], FF[:K - 1], PK[:K - 1], DT[:K - 1], used, rejected


@njit(cache=True, inline="always")
def _rebuild_prediction(P, F, Pkk, dt, q, beta, Pp, n, a, qd):  # noqa: ANN001, ANN202
    """The smoother's ``P_pred`` of a step into ``Pp[:n, :n]`` from the filtered ``P``, the step's linearised
    transition ``F``, its predicted kinematic block ``Pkk`` and ``dt``; ``a``, ``qd`` receive the parameters'
    decay and noise."""
    _parameter_step(q, beta, dt, a, qd)
    _fill_parameter_blocks(P, F, Pp, n, a, qd)
    for r in range(NK):
        for col in range(NK):
            Pp[r, col] = Pkk[r, col]


@njit(cache=True, fastmath=True)
def _smooth_pass(X, PP, XP, FF, PK, DT, q, beta):  # noqa: ANN001, ANN202
    """Unscented RTS smoother, in place over ``X`` and ``PP`` (filtered -> smoothed).

    Per step: ``P_pred`` rebuilt from the filtered ``P_k`` (as :func:`_predict` built it), ``G^T`` from
    ``P_pred G^T = Phi P_k`` (the cross-covariance ``P_k Phi^T``, transposed) through the Cholesky factor
    of ``P_pred``, then ``x_k += G (xs_{k+1} - x_pred)``, ``P_k += G (Ps_{k+1} - P_pred) G^T``.
    The work matrices have ``m >= n`` columns (a multiple of 4, zero beyond ``n``): whole-vector rows.
    """
    K, n = X.shape[0], X.shape[1]
    m = (n + 3) // 4 * 4
    Pk = np.zeros((m, m))  # P_k, then G D G^T
    Pp = np.zeros((m, m))  # P_pred, then D = Ps_{k+1} - P_pred
    B = np.zeros((m, m))  # Phi P_k, then G^T
    W = np.zeros((m, m))  # D G^T
    L = np.zeros((n, n))
    inv_d = np.empty(n)
    d = np.zeros(m)
    dx = np.zeros(m)
    a = np.empty(n)
    qd = np.empty(n)
    for k in range(K - 2, -1, -1):
        P = PP[k]
        F = FF[k]
        for r in range(n):
            for col in range(n):
                Pk[r, col] = P[r, col]
        _rebuild_prediction(P, F, PK[k], DT[k], q, beta, Pp, n, a, qd)
        for r in range(NK):
            for col in range(m):
                B[r, col] = 0.0
            for j in range(NK):
                f = F[r, j]
                for col in range(m):
                    B[r, col] += f * Pk[j, col]
        for r in range(NK, n):
            for col in range(m):
                B[r, col] = a[r] * Pk[r, col]
        _cholesky_into(Pp, 1.0, n, L, inv_d)
        for i in range(n):  # L Y = B
            for j in range(i):
                lij = L[i, j]
                for col in range(m):
                    B[i, col] -= lij * B[j, col]
            inv = inv_d[i]
            for col in range(m):
                B[i, col] *= inv
        for i in range(n - 1, -1, -1):  # L^T G^T = Y
            for j in range(i + 1, n):
                lji = L[j, i]
                for col in range(m):
                    B[i, col] -= lji * B[j, col]
            inv = inv_d[i]
            for col in range(m):
                B[i, col] *= inv
        for j in range(n):
            d[j] = X[k + 1, j] - XP[k, j]
        d[PSI] = _wrap(d[PSI])
        for r in range(m):
            dx[r] = 0.0
        for j in range(n):
            dj = d[j]
            for r in range(m):
                dx[r] += B[j, r] * dj
        for r in range(n):
            X[k, r] += dx[r]
        X[k, PSI] = _wrap(X[k, PSI])
        for r in range(n):
            for col in range(n):
                Pp[r, col] = PP[k + 1, r, col] - Pp[r, col]
        for r in range(n):  # W = D G^T
            for col in range(m):
                W[r, col] = 0.0
            for j in range(n):
                drj = Pp[r, j]
                for col in range(m):
                    W[r, col] += drj * B[j, col]
        for r in range(n):  # G W
            for col in range(m):
                Pk[r, col] = 0.0
        for j in range(n):
            for r in range(n):
                g = B[j, r]
                for col in range(m):
                    Pk[r, col] += g * W[j, col]
        for r in range(n):
            for col in range(n):
                P[r, col] += 0.5 * (Pk[r, col] + Pk[col, r])


@njit(cache=True, fastmath=True)
def _smooth_means_pass(X, PP, XP, FF, PK, DT, q, beta):  # noqa: ANN001, ANN202
    """The RTS smoother's means alone, in place over ``X``; ``PP`` (the filtered covariances) is only read.

    The smoothed mean needs no smoothed covariance: ``G d = P_k Phi^T P_pred^-1 d`` with
    ``d = xs_{k+1} - x_pred``, one Cholesky factor and two triangular solves of a vector per step, where
    :func:`_smooth_pass` forms ``G`` and two matrix products (on test1, 25 ms against 68 ms).
    """
    K, n = X.shape[0], X.shape[1]
    Pp = np.zeros((n, n))
    L = np.zeros((n, n))
    inv_d = np.empty(n)
    y = np.empty(n)
    u = np.empty(n)
    a = np.empty(n)
    qd = np.empty(n)
    for k in range(K - 2, -1, -1):
        P = PP[k]
        F = FF[k]
        _rebuild_prediction(P, F, PK[k], DT[k], q, beta, Pp, n, a, qd)
        _cholesky_into(Pp, 1.0, n, L, inv_d)
        for j in range(n):
            y[j] = X[k + 1, j] - XP[k, j]
        y[PSI] = _wrap(y[PSI])
        for i in range(n):  # L w = d
            acc = y[i]
            for j in range(i):
                acc -= L[i, j] * y[j]
            y[i] = acc * inv_d[i]
        for i in range(n - 1, -1, -1):  # L^T y = w
            acc = y[i]
            for j in range(i + 1, n):
                acc -= L[j, i] * y[j]
            y[i] = acc * inv_d[i]
        for j in range(NK):  # u = Phi^T y
            acc = 0.0
            for r in range(NK):
                acc += F[r, j] * y[r]
            u[j] = acc
        for j in range(NK, n):
            u[j] = a[j] * y[j]
        for r in range(n):
            acc = 0.0
            for j in range(n):
                acc += P[r, j] * u[j]
            X[k, r] += acc
        X[k, PSI] = _wrap(X[k, PSI])


def smooth(X, PP, XP, FF, PK, DT, q, beta):  # noqa: ANN001, ANN201
    """Unscented RTS smoother over the kernel's history; overwrites and returns ``X``, ``PP``."""
    _smooth_pass(X, PP, XP, FF, PK, DT, q, beta)
    return X, PP


def smooth_means(X, PP, XP, FF, PK, DT, q, beta):  # noqa: ANN001, ANN201
    """The smoothed states alone over the kernel's history (``PP`` stays filtered); overwrites and returns ``X``."""
    _smooth_means_pass(X, PP, XP, FF, PK, DT, q, beta)
    return X
