#!/usr/bin/env python3
"""Cost of reaching a target error with `[mesh] target_error`, from the steps of a run.

    ves precompute SCENE --json > run.json     # SCENE with target_error (local or uniform)
    python3 bench/refinement_cost.py run.json cases/<case>/converged.json [target]

Per refinement step: unknowns, seconds (mesh + assemble + solve of that mesh), the largest
estimated error, and the largest true error against the reference (the k-th frequency against
the k-th converged one: by Rayleigh–Ritz the k-th discrete eigenvalue bounds the k-th exact one
from above, so the comparison by rank needs no mode pairing). Then the first step whose true
error is below the target (default 0.01), with the unknowns and the cumulated seconds spent to
get there — the figure compared between local and uniform refinement (docs/accuracy.md).
"""
import json
import sys

run = json.loads(open(sys.argv[1]).read().strip().splitlines()[-1])
ref = json.load(open(sys.argv[2]))["frequencies_hz"]
target = float(sys.argv[3]) if len(sys.argv) > 3 else 0.01
space = run["spaces"][0]
steps = space["refinements"] or []
print("| step | size (mm, largest / smallest) | unknowns | s | estimated (worst) | true (worst) |")
print("|---|---|---|---|---|---|")
spent = 0.0
reached = None
for k, s in enumerate(steps):
    spent += s["seconds"]
    true = max(abs(f - ref[i]) / ref[i] for i, f in enumerate(s["frequencies_hz"]))
    est = s["max_estimated_error"]
    print(f"| {k + 1} | {1e3 * s['size']:.2f} / {1e3 * s['smallest_size']:.2f} | {s['dofs']} | {s['seconds']:.1f} | "
          f"{'—' if est is None else f'{100 * est:.2f} %'} | {100 * true:.2f} % |")
    if reached is None and true <= target:
        reached = (k + 1, s["dofs"], spent)
total = run["timings_s"]["total"]
print(f"\nrun total {total:.1f} s (estimates included); ", end="")
if reached:
    print(f"true error ≤ {100 * target:g} % first at step {reached[0]}: {reached[1]} unknowns, "
          f"{reached[2]:.1f} s of meshes up to it (estimates excluded)")
else:
    print(f"true error never ≤ {100 * target:g} %")
