#!/usr/bin/env python3
"""The stated error of the felt compliance against the true error, at named points.

    python3 bench/felt_error.py [--fine 3] [--only cantilever,block,ribplate] [--out DIR]

For each part, `ves precompute --json` at the scene's size gives, at each `[[probe]]` point, the
exact compliance of the hand's contact patch on that mesh (nᵀ W K⁻¹ Wᵀ n, along the inward
normal), the share the kept modes miss (`along_normal`), the mesh's own error of it estimated on
two coarser meshes (`mesh_error`) and the two together (`felt_error`): docs/accuracy.md, "The
error of what is felt". The same scene on a mesh `--fine` times finer everywhere gives the
reference compliance at the same points. Prints one row per point: the stated and the true mesh
error, the stated and the true error of what a hand feels ((1 − a)·c_h against c_fine), and
the ratios. The fine mesh keeps its own error (a third of the coarse one's at rate 1), so the
"true" column is a little low where the rate is slow.

With `--vertices N`, the per-vertex statement a hand reads during a pull is checked instead: the
part with the static correction, whose file states the mesh error at every vertex a hand can
touch (`felt/`); N of them where the part is compliant, spread over the surface (the most
compliant first, then each the farthest from those chosen), become `[[probe]]`s of the fine
run (centred at the vertex, along its inward normal); the true error is the fine compliance
against the file's exact block at the vertex.
"""
import argparse
import os
import re
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from precompute_run import ROOT, precompute  # noqa: E402

# The scenes' contact radius (the default), m.
RADIUS = 0.005


def probes(points):
    return "".join(f"[[probe]]\nat = [{x}, {y}, {z}]\nforce = [{-nx}, {-ny}, {-nz}]\n" for (x, y, z), (nx, ny, nz) in points)


PARTS = {
    "cantilever": {
        "step": "cases/cantilever/cantilever.step",
        "size": 0.025,
        "modes": 20,
        "body": """
[material]
young = 2.1e11
poisson = 0.3
density = 7850.0
[[fixed]]
plane = { axis = "x", value = 0.0 }
""" + probes([((0.975, 0.05, 0.05), (0, 0, 1)), ((0.5, 0.05, 0.05), (0, 0, 1)), ((0.75, 0.1, 0.025), (0, 1, 0))]),
    },
    "block": {
        "step": "cases/corpus/pmi_block_2holes.step",
        "size": 0.0015,
        "modes": 12,
        "body": """
[material]
young = 7.0e10
poisson = 0.33
density = 2700.0
[[fixed]]
faces = [11]
""" + probes([((0.0185, 0.0, 0.006), (0, 0, 1)), ((0.012, 0.0, 0.006), (0, 0, 1)), ((0.01, 0.005, 0.003), (0, 1, 0))]),
    },
    "ribplate": {
        "step": "cases/ribplate/ribplate.step",
        "size": 0.008,
        "modes": 30,
        "body": """
[material]
young = 3.0e9
poisson = 0.38
density = 1050.0
[[fixed]]
plane = { axis = "z", value = 0.0 }
""" + probes([((0.050, 0.024, 0.048), (0, 0, 1)), ((0.020, 0.120, 0.050), (-1, 0, 0)), ((0.150, 0.1125, 0.035), (1, 0, 0))]),
    },
}


def scene(name, part, size, modes):
    return f"""name = "{name}"
[geometry]
step = "{os.path.join(ROOT, part['step'])}"
unit = "mm"
[mesh]
size = {size}
order = 2
error_estimate = false
[modes]
count = {modes}
{part['body']}"""


def run(dirname, name, text):
    return precompute(dirname, name, text)[0]


def vertex_statements(path, count):
    """The file's per-vertex felt errors: N compliant vertices spread over the surface, each with
    its position, outward normal, exact compliance along it and stated mesh error."""
    import h5py
    with h5py.File(path, "r") as f:
        g = f["spaces/global"]
        nodes, tris = g["mesh/nodes"][:], g["mesh/surface_triangles"][:]
        vn, stated = g["felt/nodes"][:], g["felt/mesh_error"][:]
        cn, cb = g["compliance/nodes"][:], g["compliance/blocks"][:]
    a, b, c = (nodes[tris[:, k]] for k in range(3))
    area = np.cross(b - a, c - a)
    normals = np.zeros_like(nodes)
    for k in range(3):
        np.add.at(normals, tris[:, k], area)
    n = normals[vn] / np.linalg.norm(normals[vn], axis=1)[:, None]
    blocks = cb[np.searchsorted(cn, vn)]
    blocks = 0.5 * (blocks + blocks.transpose(0, 2, 1))
    exact = np.einsum("ki,kij,kj->k", n, blocks, n)
    ok = np.flatnonzero(exact >= 0.01 * exact.max())
    x = nodes[vn]
    # Each vertex's size: the mean length of the surface edges at it.
    edges = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    length = np.linalg.norm(nodes[edges[:, 0]] - nodes[edges[:, 1]], axis=1)
    total, count_at = np.zeros(len(nodes)), np.zeros(len(nodes))
    for k in range(2):
        np.add.at(total, edges[:, k], length)
        np.add.at(count_at, edges[:, k], 1)
    size = total[vn] / np.maximum(count_at[vn], 1)
    chosen = [ok[np.argmax(exact[ok])]]
    near = np.linalg.norm(x[ok] - x[chosen[0]], axis=1)
    while len(chosen) < min(count, len(ok)):
        k = ok[np.argmax(near)]
        chosen.append(k)
        near = np.minimum(near, np.linalg.norm(x[ok] - x[k], axis=1))
    return [(x[k], n[k], exact[k], stated[k], size[k]) for k in chosen]


def per_vertex(dirname, a):
    """The per-vertex table (`--vertices`)."""
    print("| part | vertex (m) | compliance (m/N) | mesh error: stated / true | stated / true | true with the fine "
          "mesh's unresolved indentation | stated / that |")
    print("|---|---|---|---|---|---|---|")
    ratios, corrected = [], []
    for name in a.only.split(","):
        part = PARTS[name]
        body = part["body"].split("[[probe]]")[0] + '[static_correction]\nregion = "surface"\n'
        coarse, path = precompute(dirname, name + "_vertices", scene(name, {**part, "body": body}, part["size"],
                                                                          part["modes"]))
        spread = coarse["spaces"][0]["felt_compliance"]["mesh_at_vertices"]
        points = vertex_statements(path, a.vertices)
        fine_body = body.replace('[static_correction]\nregion = "surface"\n', "") + probes(
            [(tuple(float(v) for v in p), tuple(float(v) for v in nrm)) for p, nrm, _, _, _ in points])
        fine = run(dirname, name + "_vertices_fine", scene(name + "_fine", {**part, "body": fine_body},
                                                           part["size"] / a.fine, 1))
        print(f"<!-- {name}: {coarse['spaces'][0]['dofs']} unknowns, {spread['vertices']} compliant vertices "
              f"(median {100 * spread['median']:.2f} %, 90 % <= {100 * spread['p90']:.2f} %), felt check "
              f"{coarse['timings_s']['felt_compliance']:.1f} s of {coarse['timings_s']['total']:.1f} s; fine mesh "
              f"{fine['spaces'][0]['dofs']} unknowns -->", file=sys.stderr)
        young = float(re.search(r"young = ([0-9.e+-]+)", body).group(1))
        nu = float(re.search(r"poisson = ([0-9.e+-]+)", body).group(1))
        sampled = fine["spaces"][0]["felt_compliance"]["points"]
        for p, _, ch, mesh, h in points:
            # The fine run's point for this vertex (a patch that reaches a support there is not sampled).
            q = next((q for q in sampled if np.linalg.norm(np.array(q["position_m"]) - p) < 1e-3 * RADIUS), None)
            where = ", ".join(f"{v:.4f}" for v in p)
            if q is None:
                print(f"| {name} | ({where}) | {ch:.4e} | {100 * mesh:.2f} % / not sampled on the fine mesh | | | |")
                continue
            cf = q["exact_m_per_n"]
            true = (cf - ch) / cf
            r = mesh / abs(true) if true != 0 else float("nan")
            ratios.append(r)
            # The fine mesh does not resolve a patch smaller than its elements either: Boussinesq's
            # indentation of the disk, 2(1 − ν²)/(π E a), times the share 1 − a/h it misses.
            h_fine = h / a.fine
            missed = 2 * (1 - nu * nu) / (np.pi * young * RADIUS) * max(0.0, 1 - RADIUS / h_fine)
            true_c = (cf + missed - ch) / (cf + missed)
            rc = mesh / abs(true_c) if true_c != 0 else float("nan")
            corrected.append(rc)
            print(f"| {name} | ({where}) | {ch:.4e} | {100 * mesh:.2f} % / {100 * true:+.2f} % | {r:.2f} | "
                  f"{100 * true_c:+.2f} % | {rc:.2f} |")
    summarise("mesh error at vertices, against the fine mesh", ratios)
    summarise("mesh error at vertices, against the fine mesh with its unresolved indentation", corrected)


def summarise(what, ratios):
    good = [r for r in ratios if r == r]
    if good:
        inside = sum(1 for r in good if 0.5 <= r <= 2)
        under = sum(1 for r in good if r < 0.5)
        print(f"\n{what} stated/true over {len(good)} points: {min(good):.2f}–{max(good):.2f}, {inside} within 2×, "
              f"{under} under by more than 2×")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--fine", type=float, default=3.0)
    ap.add_argument("--only", default=",".join(PARTS))
    ap.add_argument("--out")
    ap.add_argument("--vertices", type=int, default=0, help="check N per-vertex statements a part instead")
    a = ap.parse_args()
    dirname = a.out or tempfile.mkdtemp(prefix="ves-felt-")
    os.makedirs(dirname, exist_ok=True)
    if a.vertices:
        return per_vertex(dirname, a)
    print("| part | point (m) | compliance (m/N) | modes miss | mesh error: stated / true | felt error: stated / true "
          "| ratio (mesh, felt) |")
    print("|---|---|---|---|---|---|---|")
    ratios = []
    for name in a.only.split(","):
        part = PARTS[name]
        coarse = run(dirname, name, scene(name, part, part["size"], part["modes"]))
        fine = run(dirname, name + "_fine", scene(name + "_fine", part, part["size"] / a.fine, 1))
        c, f = coarse["spaces"][0], fine["spaces"][0]
        print(f"<!-- {name}: {c['dofs']} unknowns, felt check {coarse['timings_s']['felt_compliance']:.1f} s of "
              f"{coarse['timings_s']['total']:.1f} s; fine mesh {f['dofs']} unknowns -->", file=sys.stderr)
        count = part["body"].count("[[probe]]")
        for p, q in zip(c["felt_compliance"]["points"][:count], f["felt_compliance"]["points"][:count]):
            ch, cf, share = p["exact_m_per_n"], q["exact_m_per_n"], p["along_normal"]
            true_mesh = (cf - ch) / cf
            true_felt = (cf - (1 - share) * ch) / cf
            mesh, felt = p["mesh_error"], p["felt_error"]
            r_mesh = mesh / abs(true_mesh) if mesh is not None and true_mesh != 0 else float("nan")
            r_felt = felt / abs(true_felt) if felt is not None and true_felt != 0 else float("nan")
            ratios.append(r_felt)
            where = ", ".join(f"{x:.4f}" for x in p["position_m"])
            st = lambda v: "—" if v is None else f"{100 * v:.2f} %"
            print(f"| {name} | ({where}) | {ch:.4e} | {100 * share:.2f} % | {st(mesh)} / {100 * true_mesh:+.2f} % | "
                  f"{st(felt)} / {100 * true_felt:+.2f} % | {r_mesh:.2f}, {r_felt:.2f} |")
    summarise("felt error", ratios)


if __name__ == "__main__":
    main()
