"""Compiled SAR-MIN filter loop (numba): the same UKF as :class:`~.ukf.VectorUKF` driven by
:func:`~.sarmin.run_sarmin`, without Python in the per-measurement path.

filterpy still supplies the sigma-point weights (``Wm``, ``Wc``, ``lambda``: Merwe's scaled points);
the kernel reproduces its sigma-point placement (rows of the upper Cholesky factor of
``(n + lambda) P``) and unscented transform. ``tests/test_nav_sarmin.py`` checks it against the
numpy/filterpy path state by state.

Event kinds: ``0 .. ng-1`` gyro i; ``ng`` wheels; ``ng+1`` steering; ``ng+2`` GNSS position;
``ng+3`` GNSS velocity. Measurement values are padded to 4 columns.
"""

from __future__ import annotations

import numpy as np
from numba import njit

PX, PY, V, PSI, OMEGA = 0, 1, 2, 3, 4


@njit(cache=True)
def _wrap(a: float) -> float:
    return (a + np.pi) % (2.0 * np.pi) - np.pi


@njit(cache=True)
def _cholesky(A):  # noqa: ANN001, ANN202
    """Lower Cholesky factor of a small SPD matrix (plain loops: no LAPACK call overhead per event)."""
    n = A.shape[0]
    L = np.zeros((n, n))
    for j in range(n):
        d = A[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if d <= 0.0:
            raise np.linalg.LinAlgError("covariance is not positive definite")
        L[j, j] = np.sqrt(d)
        for i in range(j + 1, n):
            v = A[i, j]
            for k in range(j):
                v -= L[i, k] * L[j, k]
            L[i, j] = v / L[j, j]
    return L


@njit(cache=True, fastmath=True)
def _weighted_cov(a, b, W):  # noqa: ANN001, ANN202
    """sum_i W[i] a[i]^T b[i] for row-stacked deviations a (m, p), b (m, q)."""
    m, p = a.shape
    q = b.shape[1]
    out = np.zeros((p, q))
    for i in range(m):
        w = W[i]
        for r in range(p):
            ar = w * a[i, r]
            for c in range(q):
                out[r, c] += ar * b[i, c]
    return out


@njit(cache=True)
def _sigmas(x, P, lam):  # noqa: ANN001, ANN202
    n = x.shape[0]
    S = 0.5 * (P + P.T) * (n + lam)
    L = _cholesky(S)  # lower; filterpy uses the rows of the upper factor = columns of L
    sig = np.empty((2 * n + 1, n))
    sig[0] = x
    for k in range(n):
        for j in range(n):
            sig[k + 1, j] = x[j] + L[j, k]
            sig[n + k + 1, j] = x[j] - L[j, k]
        sig[k + 1, PSI] = _wrap(sig[k + 1, PSI])
        sig[n + k + 1, PSI] = _wrap(sig[n + k + 1, PSI])
    return sig, L


@njit(cache=True)
def _mean(sig, Wm):  # noqa: ANN001, ANN202
    x = Wm @ sig
    ref = sig[0, PSI]  # the heading mean as wrapped deviations from the centre point (see ukf._mean_x)
    acc = 0.0
    for i in range(sig.shape[0]):
        acc += Wm[i] * _wrap(sig[i, PSI] - ref)
    x[PSI] = _wrap(ref + acc)
    return x


@njit(cache=True)
def _resid(sig, x):  # noqa: ANN001, ANN202
    d = sig - x
    for i in range(d.shape[0]):
        d[i, PSI] = _wrap(d[i, PSI])
    return d


@njit(cache=True)
def _ctrv(sig, dt):  # noqa: ANN001, ANN202
    out = sig.copy()  # the caller keeps the undisturbed sigma points for the cross-covariance
    for i in range(sig.shape[0]):
        v, psi, w = sig[i, V], sig[i, PSI], sig[i, OMEGA]
        half = 0.5 * w * dt
        sinc = 1.0 if abs(half) < 1e-12 else np.sin(half) / half
        chord = v * dt * sinc
        out[i, PX] += chord * np.cos(psi + half)
        out[i, PY] += chord * np.sin(psi + half)
        out[i, PSI] = psi + w * dt
    return out


@njit(cache=True, fastmath=True)
def _predict(x, P, dt, q, Wm, Wc, lam):  # noqa: ANN001, ANN202
    n = x.shape[0]
    sig, L = _sigmas(x, P, lam)
    # CTRV moves only the 5 kinematic states. L is lower triangular, so sigma points built from
    # columns k >= 5 (parameters: biases, scales) have the centre's kinematic part: they propagate like
    # the centre point. Propagating the 11 distinct points is the same unscented transform, 3x cheaper.
    prop = sig.copy()
    head = np.empty((11, n))
    head[0] = sig[0]
    for k in range(5):
        head[1 + k] = sig[k + 1]
        head[6 + k] = sig[n + k + 1]
    moved = _ctrv(head, dt)
    for k in range(5):
        prop[k + 1, :5] = moved[1 + k, :5]
        prop[n + k + 1, :5] = moved[6 + k, :5]
    for i in range(2 * n + 1):
        if i == 0 or (5 < i <= n) or i > n + 5:
            prop[i, :5] = moved[0, :5]
    xp = _mean(prop, Wm)
    dy = _resid(prop, xp)
    # Covariance: symmetric, so only the upper triangle is summed.
    Pp = np.empty((n, n))
    for r in range(n):
        for c in range(r, n):
            acc = 0.0
            for i in range(2 * n + 1):
                acc += Wc[i] * dy[i, r] * dy[i, c]
            Pp[r, c] = acc
            Pp[c, r] = acc
        Pp[r, r] += q[r] * dt
    # Cross-covariance: the sigma deviations are +-L[:, k] (and 0 for the centre point), so
    # sum_i Wc_i dx_i dy_i^T = Wc_1 sum_k L[:, k] (dy_{k+1} - dy_{n+k+1})^T.
    diff = np.empty((n, n))
    for k in range(n):
        for c in range(n):
            diff[k, c] = dy[k + 1, c] - dy[n + k + 1, c]
    cross = np.zeros((n, n))
    w1 = Wc[1]
    for r in range(n):
        for k in range(r + 1):  # L is lower triangular
            lrk = w1 * L[r, k]
            for c in range(n):
                cross[r, c] += lrk * diff[k, c]
    xp[PSI] = _wrap(xp[PSI])
    return xp, Pp, cross


@njit(cache=True)
def _measure(sig, kind, ng, geo, scale_i, steer_i):  # noqa: ANN001, ANN202
    """Predicted measurement (m, k) of every sigma point for event ``kind``."""
    m = sig.shape[0]
    wheelbase, tf, tr, lx, ly = geo[0], geo[1], geo[2], geo[3], geo[4]
    if kind < ng:
        z = np.empty((m, 1))
        for i in range(m):
            z[i, 0] = sig[i, OMEGA] + sig[i, 5 + kind]
        return z
    if kind == ng:  # wheels fl, fr, rl, rr
        z = np.empty((m, 4))
        for i in range(m):
            v, w = sig[i, V], sig[i, OMEGA]
            lat = w * wheelbase
            z[i, 0] = np.hypot(v - w * tf / 2, lat) * (1.0 + sig[i, scale_i])
            z[i, 1] = np.hypot(v + w * tf / 2, lat) * (1.0 + sig[i, scale_i + 1])
            z[i, 2] = abs(v - w * tr / 2) * (1.0 + sig[i, scale_i + 2])
            z[i, 3] = abs(v + w * tr / 2) * (1.0 + sig[i, scale_i + 3])
        return z
    if kind == ng + 1:  # road-wheel angle
        z = np.empty((m, 1))
        for i in range(m):
            v = max(sig[i, V], 1e-3)
            z[i, 0] = np.arctan(wheelbase * sig[i, OMEGA] / v) + sig[i, steer_i]
        return z
    z = np.empty((m, 2))
    for i in range(m):
        c, s = np.cos(sig[i, PSI]), np.sin(sig[i, PSI])
        if kind == ng + 2:  # antenna position
            z[i, 0] = sig[i, PX] + c * lx - s * ly
            z[i, 1] = sig[i, PY] + s * lx + c * ly
        else:  # antenna velocity
            bx = sig[i, V] - sig[i, OMEGA] * ly
            by = sig[i, OMEGA] * lx
            z[i, 0] = c * bx - s * by
            z[i, 1] = s * bx + c * by
    return z


@njit(cache=True)
def _update(x, P, z, sigma, kind, ng, geo, scale_i, steer_i, gate, Wm, Wc, lam):  # noqa: ANN001, ANN202
    sig, _ = _sigmas(x, P, lam)
    zs = _measure(sig, kind, ng, geo, scale_i, steer_i)
    k = zs.shape[1]
    zp = Wm @ zs
    dz = zs - zp
    S = _weighted_cov(dz, dz, Wc)
    for j in range(k):
        S[j, j] += sigma[j] ** 2
    y = z[:k] - zp
    S_inv = np.ascontiguousarray(np.linalg.inv(S))
    if y @ S_inv @ y > gate:
        return x, P, False
    dx = _resid(sig, x)
    Pxz = _weighted_cov(dx, dz, Wc)
    K = Pxz @ S_inv
    xn = x + K @ y
    xn[PSI] = _wrap(xn[PSI])
    Pn = P - K @ S @ K.T
    return xn, Pn, True


@njit(cache=True)
def _update_gyro(x, P, z, sigma, bias_i, gate):  # noqa: ANN001, ANN202
    """Gyro update z = omega + b_i: linear in the state, so the Kalman update is what the unscented one
    computes (the unscented transform is exact for linear functions), at O(n^2) without sigma points."""
    n = x.shape[0]
    y = z - x[OMEGA] - x[bias_i]
    ph = P[:, OMEGA] + P[:, bias_i]  # P H^T
    S = ph[OMEGA] + ph[bias_i] + sigma * sigma
    if y * y / S > gate:
        return x, P, False
    xn = x + ph * (y / S)
    xn[PSI] = _wrap(xn[PSI])
    Pn = P.copy()
    for r in range(n):
        for c in range(n):
            Pn[r, c] -= ph[r] * ph[c] / S
    return xn, Pn, True


@njit(cache=True)
def run_filter(times, kinds, zs, sigmas, t_start, x0, P0, q, Wm, Wc, lam, ng, geo, scale_i, steer_i,  # noqa: ANN001, ANN201
               steer_min_speed, gates, max_step):
    """Filter all events in time order; returns the history the smoother needs and per-kind counts."""
    n = x0.shape[0]
    span = times[-1] - t_start if times.shape[0] else 0.0
    cap = times.shape[0] + int(span / max_step) + 2
    T = np.empty(cap)
    X = np.empty((cap, n))
    PP = np.empty((cap, n, n))
    XP = np.empty((cap, n))
    PPp = np.empty((cap, n, n))
    C = np.empty((cap, n, n))
    used = np.zeros(ng + 4, dtype=np.int64)
    rejected = np.zeros(ng + 4, dtype=np.int64)
    x, P = x0.copy(), P0.copy()
    t_now = t_start
    K = 0
    T[0], X[0], PP[0] = t_now, x, P
    for e in range(times.shape[0]):
        t = times[e]
        while t - t_now > max_step:
            x, P, cross = _predict(x, P, max_step, q, Wm, Wc, lam)
            XP[K], PPp[K], C[K] = x, P, cross
            t_now += max_step
            K += 1
            T[K], X[K], PP[K] = t_now, x, P
        dt = max(t - t_now, 0.0)
        x, P, cross = _predict(x, P, dt, q, Wm, Wc, lam)
        XP[K], PPp[K], C[K] = x, P, cross
        t_now = max(t, t_now)
        kind = kinds[e]
        if not (kind == ng + 1 and x[V] < steer_min_speed):
            k_dim = 1 if (kind < ng or kind == ng + 1) else (4 if kind == ng else 2)
            if kind < ng:
                x, P, ok = _update_gyro(x, P, zs[e, 0], sigmas[e, 0], 5 + kind, gates[1])
            else:
                x, P, ok = _update(x, P, np.ascontiguousarray(zs[e]), np.ascontiguousarray(sigmas[e]), kind, ng,
                                   geo, scale_i, steer_i, gates[k_dim], Wm, Wc, lam)
            if ok:
                used[kind] += 1
            else:
                rejected[kind] += 1
        K += 1
        T[K], X[K], PP[K] = t_now, x, P
    K += 1
    return T[:K], X[:K], PP[:K], XP[:K - 1], PPp[:K - 1], C[:K - 1], used, rejected


@njit(cache=True)
def _gains(PPp, C):  # noqa: ANN001, ANN202
    """G_k = C_k P_pred,k^-1 for every step (independent of each other)."""
    K, n = C.shape[0], C.shape[1]
    G = np.empty((K, n, n))
    for k in range(K):
        L = _cholesky(0.5 * (PPp[k] + PPp[k].T))
        y = np.empty(n)
        for r in range(n):
            for i in range(n):  # forward: L y = C[r]
                v = C[k, r, i]
                for j in range(i):
                    v -= L[i, j] * y[j]
                y[i] = v / L[i, i]
            for i in range(n - 1, -1, -1):  # backward: L^T g = y
                v = y[i]
                for j in range(i + 1, n):
                    v -= L[j, i] * G[k, r, j]
                G[k, r, i] = v / L[i, i]
    return G


@njit(cache=True)
def _smooth_pass(X, PP, XP, PPp, G):  # noqa: ANN001, ANN202
    xs = X.copy()
    Ps = PP.copy()
    n = X.shape[1]
    GD = np.empty((n, n))
    for k in range(X.shape[0] - 2, -1, -1):
        Gk = G[k]
        d = xs[k + 1] - XP[k]
        d[PSI] = _wrap(d[PSI])
        for r in range(n):
            acc = 0.0
            for c in range(n):
                acc += Gk[r, c] * d[c]
            xs[k, r] = X[k, r] + acc
        xs[k, PSI] = _wrap(xs[k, PSI])
        D = Ps[k + 1] - PPp[k]
        GD[:] = 0.0
        for r in range(n):
            for j in range(n):
                g = Gk[r, j]
                for c in range(n):
                    GD[r, c] += g * D[j, c]
        for r in range(n):
            for c in range(r, n):
                acc = 0.0
                for j in range(n):
                    acc += GD[r, j] * Gk[c, j]
                Ps[k, r, c] = PP[k, r, c] + acc
                Ps[k, c, r] = Ps[k, r, c]
    return xs, Ps


def smooth(X, PP, XP, PPp, C):  # noqa: ANN001, ANN201
    """Unscented RTS smoother over the kernel's history (asynchronous steps)."""
    return _smooth_pass(X, PP, XP, PPp, _gains(PPp, C))
