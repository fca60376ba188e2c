#!/usr/bin/env python3
"""Markdown table of VES's estimated discretization error against the true error.

    ves precompute SCENE -o B.h5 --json > run.json
    python3 bench/estimate_vs_truth.py run.json cases/<case>/converged.json [--basis B.h5 --kind beam|plate|ribplate]

The true error of each mode is (f − f_converged)/f_converged with f_converged from
bench/converged.py. Prints one row per mode (the number the basis carries, and the two
estimates it was chosen from: coarse-mesh Richardson and recovery on the mesh itself), then
a summary per estimate over the modes whose true error is above 0.5 % and above 0.1 %
(docs/accuracy.md). With --basis, each mode gets a class read from its shape (--kind says how
to read it; bench/mode_class.py).
"""
import argparse
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))


def summary(name, pairs, above):
    rows = [(e, t) for e, t in pairs if abs(t) > above and e == e]
    if not rows:
        return f"{name}: no mode above {100 * above:g} %"
    r = [e / abs(t) for e, t in rows]
    inside = sum(1 for x in r if 0.5 <= x <= 2)
    under = sum(1 for x in r if x < 0.5)
    return (f"{name}, true error > {100 * above:g} %: estimate/true {min(r):.2f}–{max(r):.2f}, "
            f"{inside} of {len(r)} within 2×, {under} under by more than 2×")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("run")
    ap.add_argument("reference")
    ap.add_argument("--basis")
    ap.add_argument("--kind", choices=["beam", "plate", "ribplate", "solid"], default="solid")
    a = ap.parse_args()
    run = json.loads(open(a.run).read().strip().splitlines()[-1])["spaces"][0]
    ref = json.load(open(a.reference))["frequencies_hz"]
    est = run["estimated_relative_error"]
    modes = run["error_estimate"]["modes"]
    classes = [""] * len(est)
    if a.basis:
        import mode_class
        classes = mode_class.classify(a.basis, a.kind)
    print(f"{run['dofs']} unknowns\n")
    print("| mode | class | f (Hz) | converged (Hz) | true error | estimate | est / true | Richardson / true "
          "| recovery / true | rule | reliable |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    nan = float("nan")
    kept, rich, rec = [], [], []
    for i, f in enumerate(run["frequencies_hz"][:len(ref)]):
        t = (f - ref[i]) / ref[i]
        m = modes[i]
        ri = m.get("richardson")
        rc = m.get("recovery")
        ri = nan if ri is None else ri
        rc = nan if rc is None else rc
        q = lambda x: f"{x / abs(t):.2f}" if t and x == x else "—"
        print(f"| {i + 1} | {classes[i]} | {f:.4f} | {ref[i]:.4f} | {t:.2e} | {est[i]:.2e} | {q(est[i])} | "
              f"{q(ri)} | {q(rc)} | {m.get('rule', 'richardson')} | {'yes' if m['reliable'] else 'no'} |")
        kept.append((est[i], t))
        rich.append((ri, t))
        rec.append((rc, t))
    flagged = sum(1 for m in modes if not m["reliable"])
    print(f"\nflagged unreliable: {flagged} of {len(modes)}")
    for above in (5e-3, 1e-3):
        for name, pairs in (("estimate", kept), ("Richardson", rich), ("recovery", rec)):
            print(summary(name, pairs, above))
    if a.basis:
        print("\nPer class, true error > 0.1 % (estimate / Richardson / recovery over true):")
        for c in sorted(set(classes)):
            idx = [i for i in range(len(kept)) if classes[i] == c and abs(kept[i][1]) > 1e-3]
            if not idx:
                continue
            span = lambda pairs: "–".join(f"{x:.2f}" for x in (
                min(pairs[i][0] / abs(pairs[i][1]) for i in idx),
                max(pairs[i][0] / abs(pairs[i][1]) for i in idx))) if all(pairs[i][0] == pairs[i][0] for i in idx) else "—"
            print(f"- {c} ({len(idx)} modes): {span(kept)} / {span(rich)} / {span(rec)}")


if __name__ == "__main__":
    main()
