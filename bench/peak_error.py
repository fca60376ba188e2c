#!/usr/bin/env python3
"""The stated error of each load case's peak stresses against the true error.

    python3 bench/peak_error.py [--fine 3] [--only cantilever,block,ribplate] [--out DIR]

For each part (the cantilever's service loads, the corpus block held at one end and bent, the
ribplate held at one end and bent), `ves precompute --json` at the scene's mesh size studies every
case's peaks (docs/accuracy.md, "The error of the peak stress"); the same scene on a mesh
`--fine` times finer everywhere gives the reference: the largest von Mises within the studied
radius (1.5 local element sizes) of each peak. Prints one row per peak: the verdict, the value,
the stated error, the value on the fine mesh, the true error (|value − fine|) and their ratio.
A singular peak has no stated error: its fine-mesh value shows whether it kept rising.
"""
import argparse
import math
import os
import sys
import tempfile

import h5py
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from precompute_run import ROOT, precompute  # noqa: E402

PARTS = {
    "cantilever": {
        "step": "cases/cantilever/cantilever.step",
        "size": 0.025,
        "body": """
[material]
young = 2.1e11
poisson = 0.3
density = 7850.0
yield_strength = 2.5e8
[[fixed]]
plane = { axis = "x", value = 0.0 }
[[load]]
name = "tip"
plane = { axis = "x", value = 1.0 }
force = [0.0, 0.0, -1000.0]
[[load]]
name = "top_pressure"
faces = [6]
pressure = 1.0e5
[gravity]
acceleration = [0.0, 0.0, -9.81]
""",
    },
    "block": {
        "step": "cases/corpus/pmi_block_2holes.step",
        "size": 0.0015,
        "body": """
[material]
young = 7.0e10
poisson = 0.33
density = 2700.0
[[fixed]]
faces = [11]
[[load]]
name = "end_down"
faces = [14]
force = [0.0, 0.0, -100.0]
""",
    },
    "ribplate": {
        "step": "cases/ribplate/ribplate.step",
        "size": 0.008,
        "body": """
[material]
young = 3.0e9
poisson = 0.38
density = 1050.0
[[fixed]]
faces = [1]
[[load]]
name = "end_up"
faces = [6]
force = [0.0, 0.0, 100.0]
[[load]]
name = "rib_push"
faces = [25]
force = [50.0, 0.0, 0.0]
""",
    },
}


def scene(name, part, size, study):
    return f"""name = "{name}"
[geometry]
step = "{os.path.join(ROOT, part['step'])}"
unit = "mm"
[mesh]
size = {size}
order = 2
error_estimate = false
[modes]
count = 1
[stress]
peak_error = {'true' if study else 'false'}
{part['body']}"""


def run(dirname, name, text):
    return precompute(dirname, name, text)


def fine_values(basis, case):
    with h5py.File(basis) as f:
        g = f["spaces/global"]
        nv = int(g["mesh"].attrs["vertex_count"])
        x = g["mesh/nodes"][:nv]
        vm = g[f"loads/{case}/von_mises"][:nv]
    return x, vm


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--fine", type=float, default=3.0)
    ap.add_argument("--only", default=",".join(PARTS))
    ap.add_argument("--out")
    a = ap.parse_args()
    dirname = a.out or tempfile.mkdtemp(prefix="ves-peak-")
    os.makedirs(dirname, exist_ok=True)
    print("| part | case | peak at (m) | verdict | value (MPa) | refined (MPa) | stated error | fine mesh (MPa) "
          "| true error | stated / true |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    ratios = []
    for name in a.only.split(","):
        part = PARTS[name]
        studied, _ = run(dirname, name, scene(name, part, part["size"], True))
        space = studied["spaces"][0]
        fine, basis = run(dirname, name + "_fine", scene(name + "_fine", part, part["size"] / a.fine, False))
        print(f"<!-- {name}: {space['dofs']} unknowns, study {studied['timings_s']['peak_stress']:.1f} s of "
              f"{studied['timings_s']['total']:.1f} s; fine mesh {fine['spaces'][0]['dofs']} unknowns -->",
              file=sys.stderr)
        for case in space["loads"]:
            x, vm = fine_values(basis, case["name"])
            for p in case["peaks"]:
                at = np.array(p["at_m"])
                near = np.linalg.norm(x - at, axis=1) <= 1.5 * p["local_size_m"]
                ref = float(vm[near].max()) if near.any() else math.nan
                v = p["value_pa"]
                true = abs(v - ref)
                err = p["error_pa"]
                stated = "—" if err is None else f"{100 * err / v:.2f} %"
                ratio = "—"
                if err is not None and true > 0:
                    ratio = f"{err / true:.2f}"
                    ratios.append(err / true)
                where = ", ".join(f"{c:.4f}" for c in p["at_m"])
                refined = " → ".join(f"{r / 1e6:.3f}" for r in p["refined_pa"])
                print(f"| {name} | {case['name']} | ({where}) | {p['verdict']} | {v / 1e6:.3f} | {refined} | "
                      f"{stated} | {ref / 1e6:.3f} | {100 * true / v:.2f} % | {ratio} |")
    if ratios:
        inside = sum(1 for r in ratios if 0.5 <= r <= 2)
        under = sum(1 for r in ratios if r < 0.5)
        print(f"\nstated/true over {len(ratios)} peaks with an error: {min(ratios):.2f}–{max(ratios):.2f}, "
              f"{inside} within 2×, {under} under by more than 2×")


if __name__ == "__main__":
    main()
