"""sar.normal_equations: the symmetric-mode factorisation solves the autofocus's kind of normal equations as a dense
float64 solver does."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from autosar_cli.sar.normal_equations import factor_normal


def test_factor_normal_solves_a_banded_arrow_system_as_dense_code_does() -> None:
    """Node blocks with smoothness priors (banded) coupled to a few dense columns (points, scale), as the phase
    fit's normal matrix is: the solution equals numpy's dense solve to 1e-10."""
    rng = np.random.default_rng(3)
    n_nodes, n_dense, rows = 400, 7, 3000
    cols = rng.integers(0, n_nodes - 1, rows)
    frac = rng.uniform(size=rows)
    design = sp.csr_matrix((np.concatenate([1 - frac, frac, *rng.normal(size=(n_dense, rows))]),
                            (np.tile(np.arange(rows), 2 + n_dense),
                             np.concatenate([cols, cols + 1, *[np.full(rows, n_nodes + k) for k in range(n_dense)]]))),
                           shape=(rows, n_nodes + n_dense))
    diff = sp.diags([-np.ones(n_nodes - 1), np.ones(n_nodes - 1)], [0, 1], shape=(n_nodes - 1, n_nodes))
    smooth = sp.hstack([diff, sp.csr_matrix((n_nodes - 1, n_dense))])
    normal = design.T @ design + 10.0 * (smooth.T @ smooth) + 1e-3 * sp.eye(n_nodes + n_dense)
    rhs = rng.normal(size=n_nodes + n_dense)
    x = factor_normal(normal).solve(rhs)
    expected = np.linalg.solve(normal.toarray(), rhs)
    np.testing.assert_allclose(x, expected, rtol=0, atol=1e-10 * np.abs(expected).max())
