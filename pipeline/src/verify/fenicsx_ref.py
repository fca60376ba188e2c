"""Reference modes and static response with FEniCSx (dolfinx 0.5, SLEPc) on the exact mesh VES
used. Runs under Debian's /usr/bin/python3 (python3-dolfinx); exchanges .npy files, not HDF5,
so it needs no h5py next to dolfinx's MPI build of HDF5.

Usage: /usr/bin/python3 fenicsx_ref.py WORKDIR (reads WORKDIR/fx_*.npy, writes WORKDIR/fx_out_*.npy)
"""
import json
import os
import sys

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fpetsc
from dolfinx.cpp.io import perm_gmsh
from dolfinx.cpp.mesh import CellType
from dolfinx.mesh import create_mesh
from mpi4py import MPI
from petsc4py import PETSc
from slepc4py import SLEPc


def main(work):
    ld = lambda n: np.load(os.path.join(work, "fx_%s.npy" % n))
    nodes, tets, fixed, load = ld("nodes"), ld("tets").astype(np.int64), ld("fixed").astype(np.int64), ld("load")
    with open(os.path.join(work, "fx_attrs.json")) as f:
        a = json.load(f)
    order = int(a["order"])
    nper = 10 if order == 2 else 4
    # dolfinx 0.5's gmshio.ufl_mesh needs the gmsh Python module; build the same UFL mesh here.
    cell = ufl.Cell("tetrahedron", geometric_dimension=3)
    domain = ufl.Mesh(ufl.VectorElement("Lagrange", cell, order))
    cells = tets[:, perm_gmsh(CellType.tetrahedron, nper)]
    msh = create_mesh(MPI.COMM_SELF, cells, nodes, domain)
    V = fem.VectorFunctionSpace(msh, ("Lagrange", order))
    E, nu, rho = a["young"], a["poisson"], a["density"]
    mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    eps = lambda w: ufl.sym(ufl.grad(w))
    sig = lambda w: 2 * mu * eps(w) + lmbda * ufl.tr(eps(w)) * ufl.Identity(3)
    # Exact quadrature on straight elements, as VES uses.
    dk = ufl.dx(metadata={"quadrature_degree": 2 * (order - 1)})
    dm = ufl.dx(metadata={"quadrature_degree": 2 * order})
    K = fpetsc.assemble_matrix(fem.form(ufl.inner(sig(u), eps(v)) * dk))
    K.assemble()
    M = fpetsc.assemble_matrix(fem.form(rho * ufl.inner(u, v) * dm))
    M.assemble()

    # Our node i -> dof block b, matched by coordinates (P1/P2 dofs sit on the mesh nodes).
    coords = V.tabulate_dof_coordinates()
    scale = np.abs(nodes).max()
    key = lambda p: tuple(np.round(np.asarray(p) / scale, 9))
    where = {key(p): b for b, p in enumerate(coords)}
    block = np.array([where[key(p)] for p in nodes], dtype=np.int64)
    rows = (3 * block[fixed // 3] + fixed % 3).astype(np.int32)
    # Supported DOFs: K gets 1 on the diagonal, M 0, so they never appear near the shift.
    K.zeroRowsColumns(rows, 1.0)
    M.zeroRowsColumns(rows, 0.0)

    k = int(a["modes"]) + int(a["rigid"])
    e = SLEPc.EPS().create(MPI.COMM_SELF)
    e.setOperators(K, M)
    e.setProblemType(SLEPc.EPS.ProblemType.GHEP)
    e.setDimensions(k)
    e.setTolerances(1e-12, 1000)
    st = e.getST()
    st.setType("sinvert")
    e.setTarget(float(a["sigma"]))
    e.setWhichEigenpairs(SLEPc.EPS.Which.TARGET_MAGNITUDE)
    ksp = st.getKSP()
    ksp.setType("preonly")
    ksp.getPC().setType("cholesky")
    e.solve()
    vr = K.createVecRight()
    pairs = []
    for i in range(e.getConverged()):
        lam = e.getEigenpair(i, vr).real
        pairs.append((lam, vr.getArray().copy()))
    pairs.sort(key=lambda p: p[0])
    pairs = pairs[int(a["rigid"]):int(a["rigid"]) + int(a["modes"])]
    idx = (3 * block[:, None] + np.arange(3)[None, :]).reshape(-1)
    freqs = np.array([np.sqrt(max(l, 0.0)) / (2 * np.pi) for l, _ in pairs])
    modes = np.stack([vec[idx] for _, vec in pairs], axis=1)
    static = np.zeros(3 * len(nodes))
    if int(a["rigid"]) == 0:
        b = K.createVecRight()
        arr = np.zeros(b.getSize())
        arr[idx] = load
        arr[rows] = 0.0
        b.setArray(arr)
        x = K.createVecRight()
        solver = PETSc.KSP().create(MPI.COMM_SELF)
        solver.setOperators(K)
        solver.setType("preonly")
        solver.getPC().setType("cholesky")
        solver.solve(b, x)
        static = x.getArray()[idx]
    np.save(os.path.join(work, "fx_out_freqs.npy"), freqs)
    np.save(os.path.join(work, "fx_out_modes.npy"), modes)
    np.save(os.path.join(work, "fx_out_static.npy"), static)
    import dolfinx
    with open(os.path.join(work, "fx_out_solver.txt"), "w") as f:
        f.write("FEniCSx dolfinx %s (SLEPc shift-invert, PETSc Cholesky)" % dolfinx.__version__)


if __name__ == "__main__":
    main(sys.argv[1])
