#!/usr/bin/env python3
"""Instant support changes against the exact solve, on real parts: a Markdown table.

    python3 bench/instant_supports.py [--parts mould,bracket,block,crankshaft] [--work DIR]

For each part: a free-body basis at a fixed mesh size (the page's starting scene is a free body),
then three support sets chosen from the part's own CAD faces as a user would pick them — the
largest planar face clamped, that face and the planar face farthest from it, and the largest
bores as bearings (an elastic mount on the largest planar face where the part has no bore) —
and, where it has two bores, a fourth: the first located, the second floating. The
sets are taken one after the other as in a session: each instant basis starts from the previous
set's exact basis (`ves precompute SCENE --instant-from PREVIOUS`), and is compared with
`ves precompute SCENE` on the same mesh (the mesh size is fixed, so both mesh alike):

- time to the instant basis (the whole `ves precompute --instant-from` process, wall clock) and
  to the exact one;
- the first 10 frequencies' largest relative error, and the bound the instant basis states;
- the felt point compliance (nᵀ Σ φφᵀ/λ n at a surface vertex along its normal, the same modes
  kept) at three surface vertices far from the held faces.

Faces are classified from the basis's own `mesh/surface_faces`: planar (every triangle normal
within 1° of the mean), cylindrical (normals perpendicular to one axis) and bores among those
(normals towards the axis).
"""
import argparse
import json
import os
import subprocess
import sys
import time

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CORPUS = os.path.join(ROOT, "cases", "corpus")
STEEL = "young = 2.1e11\npoisson = 0.3\ndensity = 7850.0"
# name: (step file, unit, material, mesh table)
PARTS = {
    "mould": (os.path.join(ROOT, "cases/mould/mould.step"), "mm",
              "young = 3.0e9\npoisson = 0.38\ndensity = 1050.0", "size = 0.013\norder = 1"),
    "bracket": (os.path.join(ROOT, "cases/bracket/bracket.step"), "mm",
                "young = 7.0e10\npoisson = 0.33\ndensity = 2700.0", "size = 0.008\norder = 2"),
    "block": (os.path.join(CORPUS, "pmi_block_2holes.step"), "mm", STEEL, None),
    "crankshaft": (os.path.join(CORPUS, "crankshaft.step"), "mm", STEEL, None),
}
MODES = 12


def scene(name, part, mesh, fixed):
    step, unit, material, _ = PARTS[part]
    text = f'name = "{name}"\n[geometry]\nstep = "{step}"\nunit = "{unit}"\n'
    text += f"[material]\n{material}\n[mesh]\n{mesh}\n"
    for f in fixed:
        text += "[[fixed]]\n" + "".join(f"{k} = {v}\n" for k, v in f.items())
    return text + f"[modes]\ncount = {MODES}\n"


def run(ves, args):
    t = time.perf_counter()
    p = subprocess.run([ves] + args, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if p.returncode != 0:
        raise SystemExit(f"ves {' '.join(args)} failed: {p.stderr.strip()[-800:]}")
    return json.loads(p.stdout.strip().splitlines()[-1]), wall


def read(path):
    with h5py.File(path, "r", locking=False) as f:
        g = f["spaces/global"]
        out = {
            "nodes": g["mesh/nodes"][...],
            "tris": g["mesh/surface_triangles"][...].astype(np.int64),
            "faces": g["mesh/surface_faces"][...] if "surface_faces" in g["mesh"] else None,
            "lam": g["modes/eigenvalues"][...],
            "f": g["modes/frequencies_hz"][...],
            "phi": g["modes/basis"][...],
        }
    return out


def classify(b):
    """Per CAD face tag: area, kind (plane, cylinder, bore, other), centroid, axis."""
    x, t = b["nodes"], b["tris"]
    a, bb, c = x[t[:, 0]], x[t[:, 1]], x[t[:, 2]]
    cross = np.cross(bb - a, c - a)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    n = cross / np.maximum(2 * area, 1e-300)[:, None]
    mid = (a + bb + c) / 3
    faces = {}
    for tag in np.unique(b["faces"]):
        if tag == 0:
            continue
        s = b["faces"] == tag
        w, nn, m = area[s], n[s], mid[s]
        A = w.sum()
        mean = (w[:, None] * nn).sum(0)
        centroid = (w[:, None] * m).sum(0) / A
        kind, axis = "other", None
        if np.linalg.norm(mean) > 0 and np.min(nn @ (mean / np.linalg.norm(mean))) > np.cos(np.radians(1)):
            kind = "plane"
        else:
            S = (nn * w[:, None]).T @ nn
            e, v = np.linalg.eigh(S)
            axis = v[:, 0]
            # Facets of a coarse mesh tilt off a cylinder's surface: 0.2 leaves room for that.
            if e[0] < 0.02 * e[2] and e[1] > 0.3 * e[2] and np.max(np.abs(nn @ axis)) < 0.2:
                # m = a − R n on a cylinder of axis point a and radius R (R > 0 for a bore,
                # whose outward normals point to the axis).
                P = np.eye(3) - np.outer(axis, axis)
                rows = np.hstack([np.tile(P, (len(m), 1)), -(nn @ P).reshape(-1, 1)])
                sol = np.linalg.lstsq(rows, (m @ P).reshape(-1), rcond=None)[0]
                kind = "bore" if sol[3] > 0 else "cylinder"
                axis = (axis, sol[:3], abs(sol[3]))
        faces[int(tag)] = {"area": A, "kind": kind, "centroid": centroid, "axis": axis}
    return faces


def support_sets(faces):
    planes = sorted((t for t in faces if faces[t]["kind"] == "plane"), key=lambda t: -faces[t]["area"])
    first = planes[0]
    big = [t for t in planes[1:] if faces[t]["area"] >= 0.1 * faces[first]["area"]] or planes[1:]
    far = max(big, key=lambda t: np.linalg.norm(faces[t]["centroid"] - faces[first]["centroid"]))
    # Cylindrical faces grouped by the cylinder they lie on (a bore is often two half faces).
    groups = []
    for t in sorted((t for t in faces if faces[t]["kind"] in ("bore", "cylinder")), key=lambda t: -faces[t]["area"]):
        d, a, r = faces[t]["axis"]
        for g in groups:
            d0, a0, r0 = faces[g[0]]["axis"]
            off = (a - a0) - np.dot(a - a0, d0) * d0
            if abs(np.dot(d, d0)) > 0.999 and np.linalg.norm(off) < 0.05 * r0 and abs(r - r0) < 0.05 * r0:
                g.append(t)
                break
        else:
            groups.append([t])
    bores = sorted(groups, key=lambda g: -sum(faces[t]["area"] for t in g))
    sets = [
        ("one face clamped", [{"faces": f"[{first}]"}], [first]),
        ("two faces clamped", [{"faces": f"[{first}, {far}]"}], [first, far]),
    ]
    if bores:
        held = bores[:2]
        sets.append(("cylinders as bearings" if len(held) > 1 else "cylinder as bearing",
                     [{"faces": str(g), "kind": '"bearing"'} for g in held], [t for g in held for t in g]))
        if len(held) > 1:
            # A shaft's usual pair: the first located (held along its axis too), the other floating.
            sets.append(("located bearing and a floating one",
                         [{"faces": str(held[0]), "kind": '"bearing"', "located": "true"},
                          {"faces": str(held[1]), "kind": '"bearing"'}], [t for g in held for t in g]))
    else:
        sets.append(("elastic mount (no cylinder)",
                     [{"faces": f"[{first}]", "kind": '"elastic"', "stiffness": "1e11"}], [first]))
    return sets


def points(b, held_faces):
    """Three surface vertices far from the held faces, far from each other, with their normals."""
    x, t = b["nodes"], b["tris"]
    held = np.isin(b["faces"], held_faces)
    held_nodes = np.unique(t[held])
    surface = np.setdiff1d(np.unique(t), held_nodes)
    a, bb, c = x[t[:, 0]], x[t[:, 1]], x[t[:, 2]]
    cross = np.cross(bb - a, c - a)
    normal = np.zeros_like(x)
    for k in range(3):
        np.add.at(normal, t[:, k], cross)
    normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None]
    # Farthest-point picks: each the surface vertex farthest from the held nodes (a subsample of
    # at most 200) and from the vertices picked before it.
    held_sample = x[held_nodes][::max(1, len(held_nodes) // 200)]
    nearest = np.min(np.linalg.norm(x[surface][:, None, :] - held_sample[None, :, :], axis=2), axis=1)
    chosen = []
    for _ in range(3):
        k = int(np.argmax(nearest))
        chosen.append(surface[k])
        nearest = np.minimum(nearest, np.linalg.norm(x[surface] - x[surface[k]], axis=1))
    return [(k, normal[k]) for k in chosen]


def compliance(b, node, n):
    phi = b["phi"][3 * node:3 * node + 3, :]
    proj = n @ phi
    return float(np.sum(proj ** 2 / b["lam"]))


def part_mesh(ves, part, work):
    step, unit, material, mesh = PARTS[part]
    if mesh:
        return mesh
    # A fixed size of 1/25 of the part's largest extent (the page's first mesh is 1/15), order
    # 2: from the size VES itself advises (1/15) when given one larger than the part.
    probe = os.path.join(work, f"{part}-probe.toml")
    open(probe, "w").write(scene(f"{part}-probe", part, "size = 1e3\norder = 2", []))
    p = subprocess.run([ves, "precompute", probe, "-o", os.path.join(work, "never.h5")],
                       capture_output=True, text=True)
    advice = p.stderr.split("use about ")[1].split(" m")[0]
    return f"size = {float(advice) * 15 / 25:.6g}\norder = 2"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--parts", default="mould,bracket,block,crankshaft")
    ap.add_argument("--work", default="/tmp/ves-instant-bench")
    ap.add_argument("--ves", default=os.path.join(ROOT, "target/release/ves"))
    ap.add_argument("--page", action="store_true",
                    help="the page's defaults (10-node tets to a 5 %% error estimate) instead of a fixed mesh: "
                         "the exact compute may refine to another mesh, and the table gives how far the "
                         "frequencies move at the swap")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    rows = []
    for part in a.parts.split(","):
        mesh = "order = 2\ntarget_error = 0.05" if a.page else part_mesh(a.ves, part, a.work)
        free = os.path.join(a.work, f"{part}-free.h5")
        path = os.path.join(a.work, f"{part}-free.toml")
        open(path, "w").write(scene(f"{part}-free", part, mesh, []))
        info, wall = run(a.ves, ["precompute", path, "-o", free, "--json"])
        dofs = info["spaces"][0]["dofs"]
        print(f"{part}: free body, {dofs} unknowns, {wall:.1f} s", file=sys.stderr)
        faces = classify(read(free))
        previous = free
        for label, fixed, held in support_sets(faces):
            slug = label.split()[0]
            path = os.path.join(a.work, f"{part}-{slug}.toml")
            open(path, "w").write(scene(f"{part}-{slug}", part, mesh, fixed))
            inst_h5 = os.path.join(a.work, f"{part}-{slug}-instant.h5")
            exact_h5 = os.path.join(a.work, f"{part}-{slug}-exact.h5")
            for p in (inst_h5, exact_h5):
                if os.path.exists(p):
                    os.remove(p)
            iinfo, iwall = run(a.ves, ["precompute", path, "-o", inst_h5, "--json", "--instant-from", previous])
            einfo, ewall = run(a.ves, ["precompute", path, "-o", exact_h5, "--json"])
            ib, eb = read(inst_h5), read(exact_h5)
            same = ib["nodes"].shape == eb["nodes"].shape and np.allclose(ib["nodes"], eb["nodes"])
            assert same or a.page, "meshes differ"
            k = min(10, len(eb["f"]), len(ib["f"]))
            ferr = np.max(np.abs(ib["f"][:k] - eb["f"][:k]) / eb["f"][:k])
            bound = max(iinfo.get("instant", {}).get("frequency_bound", [float("nan")])[:k])
            cerr = [abs(compliance(ib, n, v) / compliance(eb, n, v) - 1) for n, v in points(eb, held)] \
                if same else [float("nan")]
            edofs = einfo["spaces"][0]["dofs"]
            rows.append((part, dofs if same else f"{dofs} → {edofs}", label, iwall,
                         iinfo.get("instant", {}).get("solves"), ferr, bound, max(cerr), ewall))
            print(f"  {label}: instant {iwall:.2f} s, freq err {ferr:.2e} (bound {bound:.2e}), "
                  f"compliance err {max(cerr):.2e}; exact {ewall:.1f} s", file=sys.stderr)
            previous = exact_h5
    print(f"load average at the end: {os.getloadavg()[0]:.1f}\n")
    print("| part | unknowns | supports (from the previous set) | instant: wall | solves | first 10 frequencies: "
          "largest error | stated bound | compliance at 3 points: largest error | exact: wall |")
    print("|---|---|---|---|---|---|---|---|---|")
    for part, dofs, label, iw, solves, fe, bd, ce, ew in rows:
        print(f"| {part} | {dofs} | {label} | {iw:.2f} s | {solves} | {100 * fe:.3g} % | {100 * bd:.3g} % "
              f"| {100 * ce:.3g} % | {ew:.1f} s |")


if __name__ == "__main__":
    main()
