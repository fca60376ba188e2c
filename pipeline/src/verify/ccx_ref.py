"""Reference modes and static response with CalculiX (ccx) on the exact mesh VES used.

Usage: python3 ccx_ref.py PROBLEM.h5 RESULT.h5 WORKDIR (called by `ves verify`).
Writes C3D4/C3D10 input decks, runs `ccx`, reads eigenvalues from the .dat file and
displacements from the ASCII .frd file. Supported parts only (no rigid modes).
"""
import os
import re
import subprocess
import sys

import h5py
import numpy as np

# CalculiX reads at most 20 characters per number: %.13g keeps every value within that.
# gmsh 10-node order: edges 01 12 20 30 32 31; CalculiX C3D10: 12 23 31 14 24 34.
CCX_FROM_GMSH = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]


def mesh_lines(nodes, tets):
    """*NODE and *ELEMENT (set EALL) of a gmsh-ordered 4- or 10-node tet mesh."""
    lines = ["*NODE"]
    lines += ["%d, %.13g, %.13g, %.13g" % (i + 1, *p) for i, p in enumerate(nodes)]
    typ = "C3D10" if tets.shape[1] == 10 else "C3D4"
    lines.append("*ELEMENT, TYPE=%s, ELSET=EALL" % typ)
    perm = CCX_FROM_GMSH if typ == "C3D10" else [0, 1, 2, 3]
    for e, t in enumerate(tets):
        ids = [str(t[j] + 1) for j in perm]
        # at most 16 entries per line in ccx decks
        lines.append("%d, %s" % (e + 1, ", ".join(ids[:8])) + ("," if len(ids) > 8 else ""))
        if len(ids) > 8:
            lines.append(", ".join(ids[8:]))
    return lines


def boundary_lines(fixed):
    """*BOUNDARY: each supported DOF 3i+c held at zero."""
    return ["*BOUNDARY"] + ["%d, %d, %d, 0." % (d // 3 + 1, d % 3 + 1, d % 3 + 1) for d in fixed]


def deck(nodes, tets, fixed, a, step):
    lines = mesh_lines(nodes, tets) + boundary_lines(fixed)
    lines += ["*MATERIAL, NAME=MAT", "*ELASTIC", "%.13g, %.13g" % (a["young"], a["poisson"]),
              "*DENSITY", "%.13g" % a["density"], "*SOLID SECTION, ELSET=EALL, MATERIAL=MAT"]
    lines += step
    return "\n".join(lines) + "\n"


def read_frd_disp(path, n):
    """All DISP blocks of an ASCII .frd file, each as an (n, 3) array."""
    return read_frd(path, n, "DISP", 3)


# CalculiX's STRESS block: SXX SYY SZZ SXY SYZ SZX; VES's Voigt order: xx yy zz yz xz xy.
VES_FROM_CCX_STRESS = [0, 1, 2, 4, 5, 3]


def read_frd(path, n, name, comps):
    """All `name` blocks of an ASCII .frd file, each as an (n, comps) array."""
    blocks, cur = [], None
    with open(path) as f:
        for line in f:
            if line.startswith(" -4  "):
                cur = np.zeros((n, comps)) if line[5:13].strip() == name else None
            elif cur is not None and line.startswith(" -1"):
                node = int(line[3:13])
                vals = [float(line[13 + 12 * j: 25 + 12 * j]) for j in range(comps)]
                cur[node - 1] = vals
            elif cur is not None and line.startswith(" -3"):
                blocks.append(cur)
                cur = None
    return blocks


def run(workdir, name, text):
    with open(os.path.join(workdir, name + ".inp"), "w") as f:
        f.write(text)
    r = subprocess.run(["ccx", "-i", name], cwd=workdir, capture_output=True, text=True)
    if r.returncode != 0 or "*ERROR" in r.stdout:
        sys.exit("ccx failed:\n" + r.stdout[-2000:])


def main(inp, out, workdir):
    with h5py.File(inp, "r") as f:
        nodes, tets = f["nodes"][:], f["tets"][:].astype(np.int64)
        fixed, load = f["fixed_dofs"][:].astype(np.int64), f["load"][:]
        a = dict(f.attrs)
    if int(a["rigid"]) != 0:
        sys.exit("ccx reference: only supported parts (this one has rigid modes)")
    n, k = len(nodes), int(a["modes"])
    run(workdir, "modes", deck(nodes, tets, fixed, a, ["*STEP", "*FREQUENCY", "%d" % k, "*NODE FILE", "U", "*EL FILE", "S", "*END STEP"]))
    with open(os.path.join(workdir, "modes.dat")) as f:
        dat = f.read()
    table = dat.split("E I G E N V A L U E   O U T P U T")[1]
    rows = re.findall(r"^\s+(\d+)\s+([-+0-9.Ee]+)\s+([-+0-9.Ee]+)\s+([-+0-9.Ee]+)\s+([-+0-9.Ee]+)", table, re.M)
    freqs = np.array([float(r[3]) for r in rows[:k]])
    disp = read_frd_disp(os.path.join(workdir, "modes.frd"), n)[:k]
    modes = np.stack([d.reshape(-1) for d in disp], axis=1)
    # Nodal stress of each mode shape (extrapolated from the integration points and averaged
    # over the elements at a node by CalculiX), rows 6i+k in VES's Voigt order.
    stress = read_frd(os.path.join(workdir, "modes.frd"), n, "STRESS", 6)[:k]
    mode_stress = np.stack([s[:, VES_FROM_CCX_STRESS].reshape(-1) for s in stress], axis=1)
    node = int(a["load_node"])
    cload = ["%d, %d, %.13g" % (node + 1, c + 1, load[3 * node + c]) for c in range(3) if load[3 * node + c] != 0.0]
    run(workdir, "static", deck(nodes, tets, fixed, a, ["*STEP", "*STATIC", "*CLOAD", *cload, "*NODE FILE", "U", "*END STEP"]))
    static = read_frd_disp(os.path.join(workdir, "static.frd"), n)[0].reshape(-1)
    with h5py.File(out, "w") as f:
        f["frequencies_hz"] = freqs
        f["modes"] = modes
        f["mode_stress"] = mode_stress
        f["static"] = static
        f.attrs["solver"] = "CalculiX ccx (%s)" % ("C3D10" if tets.shape[1] == 10 else "C3D4")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3])
