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
"""
import argparse
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from precompute_run import ROOT, precompute  # noqa: E402

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


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--fine", type=float, default=3.0)
    ap.add_argument("--only", default=",".join(PARTS))
    ap.add_argument("--out")
    a = ap.parse_args()
    dirname = a.out or tempfile.mkdtemp(prefix="ves-felt-")
    os.makedirs(dirname, exist_ok=True)
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
    good = [r for r in ratios if r == r]
    if good:
        inside = sum(1 for r in good if 0.5 <= r <= 2)
        under = sum(1 for r in good if r < 0.5)
        print(f"\nfelt error stated/true over {len(good)} points: {min(good):.2f}–{max(good):.2f}, {inside} within 2×, "
              f"{under} under by more than 2×")


if __name__ == "__main__":
    main()
