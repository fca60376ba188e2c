"""K and M from ``ves.matrices``: the same eigenvalues through scipy as in the basis."""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as sla

import ves
from conftest import CANTILEVER


def test_eigsh_of_k_and_m_gives_the_basis_eigenvalues(cantilever):
    K, M, free = ves.matrices(CANTILEVER, progress=False)
    n = cantilever.nodes.shape[0]
    assert K.shape == M.shape == (len(free), len(free))
    assert len(free) == 3 * n - len(cantilever.fixed_dofs)
    # The free DOFs are the complement of the basis's supported ones, in order.
    np.testing.assert_array_equal(np.setdiff1d(np.arange(3 * n), cantilever.fixed_dofs), free)
    assert abs(K - K.T).max() == 0.0 and abs(M - M.T).max() == 0.0
    k = 8
    lam, _ = sla.eigsh(K, k=k, M=M, sigma=0.0, which="LM", tol=1e-12)
    np.testing.assert_allclose(np.sort(lam), cantilever.eigenvalues[:k], rtol=1e-9)


def test_basis_modes_are_m_orthonormal_and_k_diagonal(cantilever):
    K, M, free = ves.matrices(CANTILEVER, progress=False)
    phi = cantilever.modes[free, :]
    np.testing.assert_allclose(phi.T @ (M @ phi), np.eye(phi.shape[1]), atol=1e-9)
    lam = cantilever.eigenvalues
    np.testing.assert_allclose(phi.T @ (K @ phi), np.diag(lam), atol=1e-7 * lam.max())
