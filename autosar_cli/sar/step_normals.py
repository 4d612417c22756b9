"""Normal equations of phase-step histories, each less its own moving average, formed per history in band form: the
fit of the fast-motion stage (:mod:`autosar_cli.sar.fast_motion`). Array in, array out.

History s's steps ``y`` (m,) see the motion ``e`` on the nodes through ``S`` (m, n): four entries a row (a step's
two samples, each linear between two nodes; :func:`~autosar_cli.sar.fast_motion.step_columns`). The fit compares
``y - A y`` with ``(S - A S) e``, ``A`` the mean over each step's neighbours within ``half`` steps in its history.
Each history's normal matrix ``(S - A S)^T (S - A S)`` and right-hand side ``(S - A S)^T (y - A y)`` reach only the
nodes its steps span, and each step's row of ``S - A S`` only the ~2 ``half`` nodes its window spans: formed once
per history (:func:`history_normals`), the reweighting passes and the fits of the two halves and of the whole only
add them up with their weights (:func:`add_normals`) and solve a banded system. On test2 seed 1 (57 632 steps of
250 histories, 2662 nodes) the sparse products and SuperLU factorisations this replaces took 2.4 s of the stage's
3.5 (a loaded host); the same solution to rounding (``tests/test_fast_motion.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def remove_moving_average(x: Array, starts: NDArray[np.int64], half: int) -> Array:
    """``x`` (M,) less, at each step, the mean of its history's steps within ``half`` of it; history s holds steps
    ``starts[s]`` to ``starts[s + 1] - 1`` (``starts`` (S + 1,), ascending, ending at M)."""
    lo, hi = window_bounds(starts, half)
    c = np.concatenate([[0.0], np.cumsum(x)])
    return x - (c[hi] - c[lo]) / (hi - lo)


def window_bounds(starts: NDArray[np.int64], half: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Each step's window ``[lo, hi)`` (M,) of its history's steps within ``half`` of it."""
    counts = np.diff(starts)
    first = np.repeat(starts[:-1], counts)
    last = np.repeat(starts[1:], counts)
    idx = np.arange(int(starts[-1]))
    return np.maximum(idx - half, first), np.minimum(idx + half + 1, last)


def apply_model(cols: NDArray[np.int64], vals: Array, starts: NDArray[np.int64], half: int, e: Array) -> Array:
    """``(S - A S) e`` (M,) for the motion ``e`` (n,) on the nodes; ``S`` given by its entries ``cols``, ``vals``
    (M, 4)."""
    return remove_moving_average(np.einsum("mk,mk->m", vals, e[cols]), starts, half)


@dataclass(frozen=True)
class HistoryNormals:
    """Each history's normal matrix and right-hand side over the nodes its steps reach (:func:`history_normals`).

    History s's nodes are ``node_lo[s]`` ... ``node_lo[s] + ptr[s + 1] - ptr[s] - 1``; its rows of ``blocks`` and
    ``rhs`` start at ``ptr[s]``; ``blocks[ptr[s] + p, k]`` is its matrix's entry at nodes (``node_lo[s] + p + k``,
    ``node_lo[s] + p``), the lower band as LAPACK's banded Cholesky takes it."""

    node_lo: NDArray[np.int64]  #: (S,)
    ptr: NDArray[np.int64]  #: (S + 1,)
    blocks: Array  #: (ptr[-1], bandwidth + 1)
    rhs: Array  #: (ptr[-1],)

    @property
    def bandwidth(self) -> int:
        return self.blocks.shape[1] - 1


def history_normals(cols: NDArray[np.int64], vals: Array, data: Array, starts: NDArray[np.int64],
                    half: int) -> HistoryNormals:
    """Each history's ``(S - A S)^T (S - A S)`` and ``(S - A S)^T data`` (the module's docstring), ``S``'s entries
    ``cols``, ``vals`` (M, 4) (nodes, and rad per m of motion), ``data`` (M,) (rad: the steps less their moving
    average, :func:`remove_moving_average`), history s's steps ``starts[s]`` to ``starts[s + 1] - 1``."""
    cols = np.ascontiguousarray(cols, dtype=np.int64)
    starts = np.ascontiguousarray(starts, dtype=np.int64)
    if len(cols) == 0:
        return HistoryNormals(np.zeros(0, np.int64), np.zeros(1, np.int64), np.zeros((0, 1)), np.zeros(0))
    lo, hi = window_bounds(starts, half)
    # each row of S - A S spans the nodes of its window's steps (its own among them)
    row_lo, row_hi = _row_spans(cols, lo, hi)
    bandwidth = int((row_hi - row_lo).max())
    node_lo = np.minimum.reduceat(row_lo, starts[:-1])
    node_hi = np.maximum.reduceat(row_hi, starts[:-1])
    ptr = np.concatenate([[0], np.cumsum(node_hi - node_lo + 1)]).astype(np.int64)
    blocks = np.zeros((int(ptr[-1]), bandwidth + 1))
    rhs = np.zeros(int(ptr[-1]))
    _history_normals(cols, np.ascontiguousarray(vals, dtype=np.float64), np.ascontiguousarray(data, np.float64),
                     starts, lo, hi, row_lo, row_hi, node_lo, ptr, blocks, rhs)
    return HistoryNormals(node_lo, ptr, blocks, rhs)


def add_normals(normals: HistoryNormals, weight: Array, n_nodes: int) -> tuple[Array, Array]:
    """The sum over histories of ``weight`` (S,) times each one's normal matrix, in lower band form
    (bandwidth + 1, n_nodes), and times its right-hand side (n_nodes,)."""
    band = np.zeros((normals.bandwidth + 1, n_nodes))
    rhs = np.zeros(n_nodes)
    _add_normals(normals.blocks, normals.rhs, normals.node_lo, normals.ptr, np.asarray(weight, np.float64), band, rhs)
    return band, rhs


@nb.njit(cache=True, nogil=True)
def _row_spans(cols, lo, hi):  # pragma: no cover - compiled
    row_lo = np.empty(cols.shape[0], np.int64)
    row_hi = np.empty(cols.shape[0], np.int64)
    for i in range(cols.shape[0]):
        a = cols[lo[i], 0]
        b = a
        for j in range(lo[i], hi[i]):
            for k in range(4):
                a = min(a, cols[j, k])
                b = max(b, cols[j, k])
        row_lo[i] = a
        row_hi[i] = b
    return row_lo, row_hi


@nb.njit(parallel=True, cache=True, nogil=True)
def _history_normals(cols, vals, data, starts, lo, hi, row_lo, row_hi, node_lo, ptr, blocks,
                     rhs):  # pragma: no cover - compiled
    n_hist = starts.shape[0] - 1
    for s in nb.prange(n_hist):  # each history writes its own rows of blocks and rhs only
        base = ptr[s]
        row = np.zeros(ptr[s + 1] - base)
        for i in range(starts[s], starts[s + 1]):
            r0 = row_lo[i] - node_lo[s]
            r1 = row_hi[i] - node_lo[s]
            for p in range(r0, r1 + 1):
                row[p] = 0.0
            inv = 1.0 / (hi[i] - lo[i])
            for j in range(lo[i], hi[i]):
                for k in range(4):
                    row[cols[j, k] - node_lo[s]] -= inv * vals[j, k]
            for k in range(4):
                row[cols[i, k] - node_lo[s]] += vals[i, k]
            d = data[i]
            for p in range(r0, r1 + 1):
                rp = row[p]
                if rp == 0.0:
                    continue
                rhs[base + p] += rp * d
                for q in range(p, r1 + 1):
                    blocks[base + p, q - p] += rp * row[q]


@nb.njit(cache=True, nogil=True)
def _add_normals(blocks, rhs_in, node_lo, ptr, weight, band, rhs):  # pragma: no cover - compiled
    width = blocks.shape[1]
    for s in range(weight.shape[0]):
        w = weight[s]
        if w == 0.0:
            continue
        for p in range(ptr[s + 1] - ptr[s]):
            j = node_lo[s] + p
            rhs[j] += w * rhs_in[ptr[s] + p]
            for k in range(width):
                band[k, j] += w * blocks[ptr[s] + p, k]
