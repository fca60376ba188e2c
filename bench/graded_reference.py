#!/usr/bin/env python3
"""A mesh-converged reference from a locally refined run: Richardson over its three graded meshes.

    ves precompute SCENE --json > run.json    # SCENE with target_error and refinement = "local"
    python3 bench/graded_reference.py run.json > converged.json

The last mesh of a `refinement = "local"` run and the two coarser meshes of its error estimate
share one size field (scaled 1, 1.5, 2.25), graded towards the clamped edges and re-entrant
corners. Where uniform meshes converge slowly there (the 200:1 plate's clamped edge: rates
0.5–1.5 between 107k and 433k unknowns, which no edge singularity of a solid allows — the
slowest is a crack front's, 1), the graded sequence shows rates of 2.5–4.7, so its extrapolation
rests on an asymptotic sequence. Rate measured per mode (capped at 4: 10-node tets),
h = unknowns^(-1/3), modes paired by the run's MAC pairing.
"""
import json
import math
import sys

run = json.loads(open(sys.argv[1]).read().strip().splitlines()[-1])
space = run["spaces"][0]
levels = space["error_estimate"]["levels"]
dofs = [space["dofs"]] + [l["dofs"] for l in levels]
h = [n ** (-1 / 3) for n in dofs]
out, rates = [], []
for i, f0 in enumerate(space["frequencies_hz"]):
    f = [f0] + [l["frequencies_hz"][i] for l in levels]
    if any(x is None for x in f) or len(f) < 3:
        sys.exit(f"mode {i + 1} is not paired on every mesh: no reference")
    d1, d2 = f[1] - f[0], f[2] - f[1]
    rho = d1 / d2
    g = lambda q: (h[1] ** q - h[0] ** q) / (h[2] ** q - h[1] ** q) - rho
    lo, hi = 1e-3, 4.0
    if not rho > 0 or g(lo) <= 0:
        sys.exit(f"mode {i + 1}: differences do not shrink ({f}): no reference")
    if g(hi) >= 0:
        q = hi
    else:
        for _ in range(100):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if g(mid) > 0 else (lo, mid)
        q = 0.5 * (lo + hi)
    out.append(f[0] - d1 * h[0] ** q / (h[1] ** q - h[0] ** q))
    rates.append(q)
print(json.dumps({
    "scene": run.get("scene", ""),
    "frequencies_hz": out,
    "measured_rates": rates,
    "meshes": [{"dofs": n} for n in dofs],
    "method": "Richardson over the three graded meshes of a refinement = \"local\" run (size field x1, x1.5, x2.25), "
              "rate measured per mode, capped at 4, h = unknowns^(-1/3)",
    "command": "python3 bench/graded_reference.py run.json",
}, indent=1))
