"""Reference static load cases with CalculiX (ccx *STATIC) on the exact mesh and nodal loads VES used.

Usage: python3 ccx_static.py PROBLEM.h5 RESULT.h5 WORKDIR (called by `ves verify`).
With the attribute nlgeom = 1 (a nonlinear scene) each deck is *STEP, NLGEOM.
PROBLEM.h5 holds nodes, tets (gmsh order), fixed_dofs, loads [cases, 3n] (N per DOF) and the
material; one deck per case (*CLOAD at every loaded DOF), displacements of every node and the
supports' total reaction read from the .dat file (*NODE PRINT: 7 significant digits, where the
.frd file has 6). RESULT.h5: displacement [cases, 3n], reaction [cases, 3].
"""
import os
import re
import subprocess
import sys

import h5py
import numpy as np

# The mesh and supports as the modal reference writes them (ves verify puts it beside this file).
from ccx_ref import boundary_lines, mesh_lines


def deck(nodes, tets, fixed, young, poisson, load, nlgeom=False):
    n = len(nodes)
    lines = mesh_lines(nodes, tets)
    lines += ["*NSET, NSET=NALL, GENERATE", "1, %d, 1" % n, "*NSET, NSET=NFIX"]
    held = sorted({int(d) // 3 + 1 for d in fixed})
    lines += [", ".join(str(i) for i in held[k:k + 8]) for k in range(0, len(held), 8)]
    lines += boundary_lines(fixed)
    lines += ["*MATERIAL, NAME=MAT", "*ELASTIC", "%.13g, %.13g" % (young, poisson),
              "*SOLID SECTION, ELSET=EALL, MATERIAL=MAT"]
    if nlgeom:
        # Geometrically nonlinear (St. Venant–Kirchhoff with *ELASTIC), dead loads, the load
        # applied in increments of at most 5 %.
        lines += ["*STEP, NLGEOM, INC=1000", "*STATIC", "0.05, 1.0, 1e-6, 0.05", "*CLOAD"]
    else:
        lines += ["*STEP", "*STATIC", "*CLOAD"]
    lines += ["%d, %d, %.13g" % (d // 3 + 1, d % 3 + 1, load[d]) for d in np.flatnonzero(load)]
    lines += ["*NODE PRINT, NSET=NALL", "U", "*NODE PRINT, NSET=NFIX, TOTALS=ONLY", "RF", "*END STEP"]
    return "\n".join(lines) + "\n"


NUMBER = r"[-+]?\d\.\d+E[-+]\d+"


def read_dat(path, n):
    """Displacements (n, 3) and the total reaction (3) of a .dat file."""
    with open(path) as f:
        text = f.read()
    # With NLGEOM every increment prints: the last block is the converged end of the step.
    text = text[text.rfind(" displacements"):] if " displacements" in text else text
    disp_part, total_part = text.split(" total force")
    u = np.zeros((n, 3))
    for m in re.finditer(r"^\s+(\d+)\s+(%s)\s+(%s)\s+(%s)\s*$" % (NUMBER, NUMBER, NUMBER), disp_part, re.M):
        u[int(m.group(1)) - 1] = [float(m.group(k)) for k in (2, 3, 4)]
    totals = re.findall(NUMBER, total_part.split("\n", 1)[1])
    return u.reshape(-1), np.array([float(v) for v in totals[:3]])


def main(inp, out, workdir):
    with h5py.File(inp, "r") as f:
        nodes, tets = f["nodes"][:], f["tets"][:].astype(np.int64)
        fixed, loads = f["fixed_dofs"][:].astype(np.int64), f["loads"][:]
        young, poisson = float(f.attrs["young"]), float(f.attrs["poisson"])
        nlgeom = bool(int(f.attrs.get("nlgeom", 0)))
    disp, reaction = [], []
    for k, load in enumerate(loads):
        name = "static%d" % k
        with open(os.path.join(workdir, name + ".inp"), "w") as f:
            f.write(deck(nodes, tets, fixed, young, poisson, load, nlgeom))
        r = subprocess.run(["ccx", "-i", name], cwd=workdir, capture_output=True, text=True)
        if r.returncode != 0 or "*ERROR" in r.stdout:
            sys.exit("ccx failed:\n" + r.stdout[-2000:])
        u, rf = read_dat(os.path.join(workdir, name + ".dat"), len(nodes))
        disp.append(u)
        reaction.append(rf)
    with h5py.File(out, "w") as f:
        f["displacement"] = np.array(disp)
        f["reaction"] = np.array(reaction)
        f.attrs["solver"] = "CalculiX ccx *STATIC%s (%s)" % (", NLGEOM" if nlgeom else "", "C3D10" if tets.shape[1] == 10 else "C3D4")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3])
