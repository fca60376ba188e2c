#!/usr/bin/env python3
"""Markdown table of VES's estimated discretization error against the true error.

    ves precompute SCENE --json > run.json
    python3 bench/estimate_vs_truth.py run.json cases/<case>/converged.json

The true error of each mode is (f − f_converged)/f_converged with f_converged from
bench/converged.py. Prints one row per mode and a summary line (docs/accuracy.md).
"""
import json
import sys

run = json.loads(open(sys.argv[1]).read().strip().splitlines()[-1])["spaces"][0]
ref = json.load(open(sys.argv[2]))["frequencies_hz"]
est = run["estimated_relative_error"]
modes = run["error_estimate"]["modes"]
print(f"{run['dofs']} unknowns\n")
print("| mode | f (Hz) | converged (Hz) | true error | estimate | estimate / true | measured rate | reliable |")
print("|---|---|---|---|---|---|---|---|")
ratios = []
for i, f in enumerate(run["frequencies_hz"]):
    t = (f - ref[i]) / ref[i]
    r = est[i] / abs(t) if t else float("nan")
    if abs(t) > 1e-3:
        ratios.append(r)
    q = modes[i]["measured_rate"]
    print(f"| {i + 1} | {f:.4f} | {ref[i]:.4f} | {t:.2e} | {est[i]:.2e} | {r:.2f} | "
          f"{'—' if q is None else f'{q:.2f}'} | {'yes' if modes[i]['reliable'] else 'no'} |")
if ratios:
    inside = sum(1 for r in ratios if 0.5 <= r <= 2)
    print(f"\nWhere the true error is above 0.1 %: estimate/true {min(ratios):.2f}–{max(ratios):.2f}, "
          f"{inside} of {len(ratios)} modes within a factor 2.")
