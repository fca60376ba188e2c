#!/usr/bin/env python3
"""Mesh-converged reference frequencies of a scene, for checking VES's error estimate.

Runs `ves precompute SCENE` (its error estimate off) at three fine element sizes, pairs modes by
order (check that the three meshes agree on the mode order: the printed differences are small
and smooth), measures each mode's convergence rate from the three and extrapolates (Richardson,
h = unknowns^(-1/3), rate capped at 4: 10-node tets). Prints one JSON object with the
extrapolated frequencies, each mode's measured rate, the meshes and the command line; save it
as the case's converged.json.

    python3 bench/converged.py cases/cantilever/scene.toml 0.0125 0.00833 0.00625 > cases/cantilever/converged.json
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile


def rate(h, d1, d2):
    """q with (h1^q - h0^q)/(h2^q - h1^q) = d1/d2 (h0 < h1 < h2), or None."""
    rho = d1 / d2 if d2 else float("inf")
    if not rho > 0:
        return None
    g = lambda q: (h[1] ** q - h[0] ** q) / (h[2] ** q - h[1] ** q) - rho
    lo, hi = 1e-3, 30.0
    if g(lo) <= 0:
        return None
    if g(hi) >= 0:
        return hi
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if g(mid) > 0 else (lo, mid)
    return 0.5 * (lo + hi)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("sizes", nargs=3, type=float, help="three element sizes (m), any order")
    ap.add_argument("--ves", default=os.path.join(os.path.dirname(__file__), "..", "target", "release", "ves"))
    a = ap.parse_args()
    text = open(a.scene).read()
    base = os.path.dirname(os.path.abspath(a.scene))
    text = re.sub(r'step\s*=\s*"([^"]+)"', lambda m: f'step = "{os.path.join(base, m.group(1))}"', text)
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for size in sorted(a.sizes):
            scene = re.sub(r"\[mesh\][^\[]*", f"[mesh]\nsize = {size}\norder = 2\nerror_estimate = false\n\n", text)
            path = os.path.join(tmp, f"s{size}.toml")
            open(path, "w").write(scene)
            out = subprocess.run(
                [a.ves, "precompute", path, "-o", os.path.join(tmp, "b.h5"), "--json"],
                check=True, capture_output=True, text=True,
            )
            s = json.loads(out.stdout.strip().splitlines()[-1])["spaces"][0]
            runs.append({"size": size, "dofs": s["dofs"], "frequencies_hz": s["frequencies_hz"],
                         "seconds": s["seconds"]})
            print(f"size {size}: {s['dofs']} unknowns, {s['seconds']:.1f} s", file=sys.stderr)
    h = [r["dofs"] ** (-1 / 3) for r in runs]
    converged, rates = [], []
    for i in range(len(runs[0]["frequencies_hz"])):
        f = [r["frequencies_hz"][i] for r in runs]
        q = rate(h, f[1] - f[0], f[2] - f[1])
        used = min(q, 4.0) if q else 4.0
        converged.append(f[0] - (f[1] - f[0]) * h[0] ** used / (h[1] ** used - h[0] ** used))
        rates.append(q)
    print(json.dumps({
        "scene": a.scene,
        "frequencies_hz": converged,
        "measured_rates": rates,
        "finest_minus_converged": [(r - c) / c for r, c in zip(runs[0]["frequencies_hz"], converged)],
        "meshes": runs,
        "method": "Richardson over three 10-node meshes, rate measured per mode (capped at 4), h = unknowns^(-1/3)",
        "command": "python3 bench/converged.py " + " ".join([a.scene] + [str(s) for s in a.sizes]),
    }, indent=1))


if __name__ == "__main__":
    main()
