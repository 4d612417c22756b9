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
def _sigmas(x, P, lam):  # noqa: ANN001, ANN202
    n = x.shape[0]
    S = 0.5 * (P + P.T) * (n + lam)
    L = np.linalg.cholesky(S)  # lower; filterpy uses the rows of the upper factor = columns of L
    sig = np.empty((2 * n + 1, n))
    sig[0] = x
    for k in range(n):
        for j in range(n):
            sig[k + 1, j] = x[j] + L[j, k]
            sig[n + k + 1, j] = x[j] - L[j, k]
        sig[k + 1, PSI] = _wrap(sig[k + 1, PSI])
        sig[n + k + 1, PSI] = _wrap(sig[n + k + 1, PSI])
    return sig


@njit(cache=True)
def _mean(sig, Wm):  # noqa: ANN001, ANN202
    x = Wm @ sig
    s = 0.0
    c = 0.0
    for i in range(sig.shape[0]):
        s += Wm[i] * np.sin(sig[i, PSI])
        c += Wm[i] * np.cos(sig[i, PSI])
    x[PSI] = np.arctan2(s, c)
    return x


@njit(cache=True)
def _resid(sig, x):  # noqa: ANN001, ANN202
    d = sig - x
    for i in range(d.shape[0]):
        d[i, PSI] = _wrap(d[i, PSI])
    return d


@njit(cache=True)
def _ctrv(sig, dt):  # noqa: ANN001, ANN202
    out = sig.copy()
    for i in range(sig.shape[0]):
        v, psi, w = sig[i, V], sig[i, PSI], sig[i, OMEGA]
        half = 0.5 * w * dt
        sinc = 1.0 if abs(half) < 1e-12 else np.sin(half) / half
        chord = v * dt * sinc
        out[i, PX] += chord * np.cos(psi + half)
        out[i, PY] += chord * np.sin(psi + half)
        out[i, PSI] = psi + w * dt
    return out


@njit(cache=True)
def _predict(x, P, dt, q, Wm, Wc, lam):  # noqa: ANN001, ANN202
    sig = _sigmas(x, P, lam)
    prop = _ctrv(sig, dt)
    xp = _mean(prop, Wm)
    dy = _resid(prop, xp)
    dx = _resid(sig, x)
    Pp = (dy.T * Wc) @ dy
    for j in range(x.shape[0]):
        Pp[j, j] += q[j] * dt
    cross = (dx.T * Wc) @ dy
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
    sig = _sigmas(x, P, lam)
    zs = _measure(sig, kind, ng, geo, scale_i, steer_i)
    k = zs.shape[1]
    zp = Wm @ zs
    dz = zs - zp
    S = (dz.T * Wc) @ dz
    for j in range(k):
        S[j, j] += sigma[j] ** 2
    y = z[:k] - zp
    S_inv = np.linalg.inv(S)
    if y @ S_inv @ y > gate:
        return x, P, False
    dx = _resid(sig, x)
    Pxz = (dx.T * Wc) @ dz
    K = Pxz @ S_inv
    xn = x + K @ y
    xn[PSI] = _wrap(xn[PSI])
    Pn = P - K @ S @ K.T
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
            x, P, ok = _update(x, P, zs[e], sigmas[e], kind, ng, geo, scale_i, steer_i, gates[k_dim], Wm, Wc, lam)
            if ok:
                used[kind] += 1
            else:
                rejected[kind] += 1
        K += 1
        T[K], X[K], PP[K] = t_now, x, P
    K += 1
    return T[:K], X[:K], PP[:K], XP[:K - 1], PPp[:K - 1], C[:K - 1], used, rejected


@njit(cache=True)
def smooth(X, PP, XP, PPp, C):  # noqa: ANN001, ANN201
    """Unscented RTS smoother over the kernel's history (asynchronous steps)."""
    xs = X.copy()
    Ps = PP.copy()
    for k in range(X.shape[0] - 2, -1, -1):
        G = np.linalg.solve(PPp[k].T, C[k].T).T
        d = xs[k + 1] - XP[k]
        d[PSI] = _wrap(d[PSI])
        xs[k] = X[k] + G @ d
        xs[k, PSI] = _wrap(xs[k, PSI])
        Ps[k] = PP[k] + G @ (Ps[k + 1] - PPp[k]) @ G.T
    return xs, Ps
