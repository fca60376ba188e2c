"""Reference modes and static response with scikit-fem on the exact mesh VES used.

Usage: python3 skfem_ref.py PROBLEM.h5 RESULT.h5 (files written and read by `ves verify`).
10-node tets with curved edges (gmsh puts mid-edge nodes on curved faces) are given to
scikit-fem as a quadratic (isoparametric) MeshTet2 whose edge nodes are ours; straight-sided ones
as a linear mesh, where scikit-fem's P2 places them at the midpoints.
"""
from dataclasses import replace
import sys

import h5py
import numpy as np
from scipy.sparse.linalg import eigsh, spsolve
from skfem import Basis, BilinearForm, ElementTetP1, ElementTetP2, ElementVector, MeshTet, MeshTet2, asm
from skfem.helpers import dot
from skfem.models.elasticity import lame_parameters, linear_elasticity

GMSH_EDGES = [(0, 1), (1, 2), (2, 0), (3, 0), (3, 2), (3, 1)]


def main(inp, out):
    with h5py.File(inp, "r") as f:
        nodes = f["nodes"][:]
        tets = f["tets"][:].astype(np.int64)
        fixed = f["fixed_dofs"][:].astype(np.int64)
        load = f["load"][:]
        a = dict(f.attrs)
    order, nv = int(a["order"]), int(a["vertex_count"])
    E, nu, rho = float(a["young"]), float(a["poisson"]), float(a["density"])
    k = int(a["modes"]) + int(a["rigid"])
    mesh = MeshTet(np.ascontiguousarray(nodes[:nv].T), np.ascontiguousarray(tets[:, :4].T))
    curved = False
    if order == 2:
        mid = np.stack([(nodes[tets[:, p]] + nodes[tets[:, q]]) / 2 for p, q in GMSH_EDGES], axis=1)
        curved = np.abs(nodes[tets[:, 4:]] - mid).max() > 1e-12 * np.ptp(nodes, axis=0).max()
        if curved:
            quad = MeshTet2.from_mesh(mesh)
            doflocs = quad.doflocs.copy()
            edges = np.sort(mesh.edges, axis=0)
            key = {(int(p), int(q)): e for e, (p, q) in enumerate(zip(*edges))}
            for t in tets:
                for j, (p, q) in enumerate(GMSH_EDGES):
                    doflocs[:, nv + key[tuple(sorted((int(t[p]), int(t[q]))))]] = nodes[t[4 + j]]
            mesh = replace(quad, doflocs=doflocs)
    elem = ElementVector(ElementTetP2() if order == 2 else ElementTetP1())
    # Exact for straight elements; on curved ones (rational integrands) close to converged.
    basis = Basis(mesh, elem, intorder=(6 if curved else 4) if order == 2 else 2)
    K = asm(linear_elasticity(*lame_parameters(E, nu)), basis).tocsc()
    M = asm(BilinearForm(lambda u, v, w: rho * dot(u, v)), basis).tocsc()

    n = len(nodes)
    ours_to_sk = np.full(3 * n, -1, dtype=np.int64)
    for c in range(3):
        ours_to_sk[3 * np.arange(nv) + c] = basis.nodal_dofs[c]
    if order == 2:
        edges = np.sort(mesh.edges, axis=0)
        key = {(int(p), int(q)): e for e, (p, q) in enumerate(zip(*edges))}
        for t in tets:
            for j, (p, q) in enumerate(GMSH_EDGES):
                e = key[tuple(sorted((int(t[p]), int(t[q]))))]
                for c in range(3):
                    ours_to_sk[3 * t[4 + j] + c] = basis.edge_dofs[c, e]
    assert (ours_to_sk >= 0).all(), "unmapped nodes"
    N = K.shape[0]
    D = ours_to_sk[fixed]
    I = np.setdiff1d(np.arange(N), D)
    KI, MI = K[I][:, I], M[I][:, I]
    vals, vecs = eigsh(KI, k=k, M=MI, sigma=float(a["sigma"]), which="LM", tol=1e-12)
    order_ = np.argsort(vals)
    vals, vecs = vals[order_][int(a["rigid"]):], vecs[:, order_][:, int(a["rigid"]):]
    full = np.zeros((N, vecs.shape[1]))
    full[I] = vecs
    modes = full[ours_to_sk]
    F = np.zeros(N)
    F[ours_to_sk] = load
    u = np.zeros(N)
    if int(a["rigid"]) == 0:
        u[I] = spsolve(KI, F[I])
    with h5py.File(out, "w") as f:
        f["frequencies_hz"] = np.sqrt(np.maximum(vals, 0)) / (2 * np.pi)
        f["modes"] = modes
        f["static"] = u[ours_to_sk]
        f.attrs["solver"] = "scikit-fem %s (scipy eigsh shift-invert, SuperLU)" % __import__("skfem").__version__


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
