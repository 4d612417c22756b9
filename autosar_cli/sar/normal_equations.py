"""Sparse symmetric positive-definite normal equations, as the autofocus's least-squares fits form them: general
sparse (:func:`factor_normal`) or banded (:class:`BandedCholesky`).

SuperLU's symmetric mode (minimum degree on A + A^T, the diagonal as pivots) factorises them about 4 times faster
than its general default (COLAMD with partial pivoting) on the phase fit's 5400-unknown systems (test2 seed 1:
5.9 against 22.9 ms per solve, the same solution to 2e-12), and needs no pivoting: the priors make every such
matrix positive definite.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.linalg import cho_solve_banded, cholesky_banded
from threadpoolctl import ThreadpoolController

# the BLAS libraries loaded with scipy.linalg (numpy's and scipy's own)
_BLAS = ThreadpoolController()


def factor_normal(normal: sp.spmatrix | sp.sparray) -> spla.SuperLU:
    """The LU factors of a sparse symmetric positive-definite ``normal`` matrix (n, n)."""
    return spla.splu(sp.csc_matrix(normal), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                     options={"SymmetricMode": True})


class BandedCholesky:
    """The Cholesky factor of a symmetric positive-definite banded matrix given by its lower band ``band``
    (bandwidth + 1, n) (``band[k, j]`` its entry at (j + k, j)), LAPACK's: the fast-motion fit's systems (test2
    seed 1: 2662 nodes, bandwidth 111), where a band beats a general sparse factorisation.

    On one BLAS thread: OpenBLAS's two threads took 9-445 ms for one such factorisation on a loaded 2-core host,
    one 2-9 ms."""

    def __init__(self, band: np.ndarray) -> None:
        with _BLAS.limit(limits=1, user_api="blas"):
            self.factor = cholesky_banded(band, lower=True, check_finite=False)
        n = band.shape[1]
        self.shape = (n, n)

    def solve(self, b: np.ndarray) -> np.ndarray:
        """The matrix's inverse times ``b`` (n,) or (n, k)."""
        with _BLAS.limit(limits=1, user_api="blas"):
            return cho_solve_banded((self.factor, True), b, check_finite=False)


def node_posterior_std(lu: spla.SuperLU | BandedCholesky, n_nodes: int, components: int, every: int = 10) -> np.ndarray:
    """Std (n_nodes, components) of a correction whose unknowns start with ``components`` blocks of ``n_nodes``
    node values, from the factorised normal matrix ``lu``: computed every ``every`` nodes and interpolated between."""
    picks = np.unique(np.concatenate([np.arange(0, n_nodes, every), [n_nodes - 1]]))
    out = np.empty((n_nodes, components))
    for comp in range(components):
        cols = comp * n_nodes + picks
        e = np.zeros((lu.shape[0], len(cols)))
        e[cols, np.arange(len(cols))] = 1.0
        with _BLAS.limit(limits=1, user_api="blas"):  # see BandedCholesky
            var = lu.solve(e)[cols, np.arange(len(cols))]
        out[:, comp] = np.interp(np.arange(n_nodes), picks, np.sqrt(np.maximum(var, 0.0)))
    return out


def node_difference(n_nodes: int) -> sp.dia_matrix:
    """(n_nodes - 1, n_nodes): each node's value less the one before it (a correction's change between nodes)."""
    return sp.diags([np.ones(n_nodes - 1), -np.ones(n_nodes - 1)], [1, 0], shape=(n_nodes - 1, n_nodes))
