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


def test_the_cli_file_says_how_to_read_its_triangles(cli, tmp_path):
    """`ves matrices` stores lower triangles: its `storage` attribute says so and how to rebuild
    K, and following it gives the package's whole K and M."""
    import subprocess

    import h5py
    from scipy.sparse import csc_matrix, diags

    out = tmp_path / "km.h5"
    subprocess.run([str(cli), "matrices", str(CANTILEVER), "-o", str(out)], check=True, capture_output=True)
    with h5py.File(out, "r") as f:
        note = f.attrs["storage"]
        note = note.decode() if isinstance(note, bytes) else str(note)
        parts = {name: f[name][...] for name in ("k", "m", "row_idx", "col_ptr")}
    assert "lower triangles" in note and "L + L^T - diag(L)" in note
    K, M, _ = ves.matrices(CANTILEVER, progress=False)
    for name, whole in (("k", K), ("m", M)):
        lower = csc_matrix((parts[name], parts["row_idx"], parts["col_ptr"]), shape=whole.shape)
        rebuilt = lower + lower.T - diags(lower.diagonal())
        assert abs(rebuilt - whole).max() <= 1e-12 * abs(whole).max(), name
