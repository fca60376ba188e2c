"""Reads the files of `ves export BASIS --vtu DIR` with meshio and checks them against the basis
(h5py): node coordinates, cells in VTK order, every mode shape, every stress tensor (VTK order
xx yy zz xy yz xz). Prints "ok" or raises.

    python3 vtu_check.py DIR BASIS.h5
"""
import sys

import h5py
import meshio
import numpy as np

out, h5 = sys.argv[1], sys.argv[2]
with h5py.File(h5, "r") as f:
    for name, g in f["spaces"].items():
        m = meshio.read(f"{out}/{name}.vtu")
        nodes, tets, basis = g["mesh/nodes"][:], g["mesh/tets"][:], g["modes/basis"][:]
        assert np.array_equal(m.points, nodes), name
        order = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8] if tets.shape[1] == 10 else [0, 1, 2, 3]
        assert len(m.cells) == 1 and np.array_equal(m.cells[0].data, tets[:, order]), name
        shapes = sorted(k for k in m.point_data if k.startswith("mode_"))
        assert len(shapes) == basis.shape[1], (name, shapes)
        for j, k in enumerate(shapes):
            assert k == "mode_%0*d_displacement" % (max(2, len(str(basis.shape[1]))), j + 1), k
            assert np.array_equal(m.point_data[k], basis[:, j].reshape(-1, 3)), (name, k)
        assert np.array_equal(m.field_data["frequencies_hz"].ravel(), g["modes/frequencies_hz"][:]), name
        held = np.zeros(len(nodes))
        held[g["mesh/fixed_dofs"][:] // 3] = 1
        assert np.array_equal(m.point_data["fixed"].ravel(), held), name
        for load, c in g.get("loads", {}).items():
            assert np.array_equal(m.point_data["load_%s_displacement" % load], c["displacement"][:]), load
            assert np.array_equal(m.point_data["load_%s_von_mises" % load].ravel(), c["von_mises"][:]), load
            # The stress tensor on the vertices file, VTK order xx yy zz xy yz xz.
            v = meshio.read(f"{out}/{name}_vertices.vtu")
            assert np.array_equal(v.point_data["load_%s_stress" % load], c["stress"][:][:, [0, 1, 2, 5, 3, 4]]), load
        if "stress" in g["modes"]:
            nv = g["mesh"].attrs["vertex_count"]
            v = meshio.read(f"{out}/{name}_vertices.vtu")
            assert np.array_equal(v.points, nodes[:nv]) and np.array_equal(v.cells[0].data, tets[:, :4])
            stress = g["modes/stress"][:]
            plain = sorted(k for k in v.point_data if k.startswith("mode_") and k.endswith("_stress"))
            assert len(plain) == basis.shape[1], (name, plain)
            for j, k in enumerate(plain):
                want = stress[:, j].reshape(nv, 6)[:, [0, 1, 2, 5, 3, 4]]
                assert np.array_equal(v.point_data[k], want), (name, k)
                # Scaled to 1 mm of the mode's peak displacement magnitude (over every node):
                # the mode times the factor peaks at exactly 1 mm, and the stress arrays are the
                # plain ones times that factor.
                peak = np.linalg.norm(basis[:, j].reshape(-1, 3), axis=1).max()
                scale = 1e-3 / peak
                assert np.isclose(np.linalg.norm(scale * basis[:, j].reshape(-1, 3), axis=1).max(), 1e-3, rtol=1e-14)
                assert np.isclose(v.field_data["peak_displacement_m"].ravel()[j], peak, rtol=1e-15), (name, j)
                assert np.isclose(v.field_data["per_mm_scale"].ravel()[j], scale, rtol=1e-15), (name, j)
                per_mm = v.point_data[k + "_per_mm"]
                assert np.allclose(per_mm, want * scale, rtol=1e-14, atol=0), (name, k)
                s = want * scale  # VTK order xx yy zz xy yz xz
                vm = np.sqrt(0.5 * ((s[:, 0] - s[:, 1]) ** 2 + (s[:, 1] - s[:, 2]) ** 2 + (s[:, 2] - s[:, 0]) ** 2)
                             + 3 * (s[:, 3] ** 2 + s[:, 4] ** 2 + s[:, 5] ** 2))
                got = v.point_data[k.replace("_stress", "_von_mises_per_mm")].ravel()
                assert np.allclose(got, vm, rtol=1e-12, atol=0), (name, k)
print("ok")
