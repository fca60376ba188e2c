#!/usr/bin/env python3
"""The refinement's forecasts of its next mesh against what that mesh took: a Markdown table.

    python3 bench/forecast_vs_actual.py [--target 0.02] [--max-dofs 300000] [PART.step ...]

Each part (default: the five STEP files of cases/corpus) is refined from scratch (an empty mesh
cache, so no remembered mesh) as a free body of steel, 10-node tets, 10 modes, to `--target`.
Each step after the first carries the forecast the step before made when it chose it (`forecast`
in `ves precompute --json`'s `refinements`: unknowns, seconds, peak memory), set here beside the
step's own unknowns, seconds and the process's peak resident memory once it was solved. These
forecasts are what stops a refinement ("the next mesh would need about … GB") and what the page
says a compute will take.
"""
import argparse
import glob
import json
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("parts", nargs="*")
    ap.add_argument("--target", type=float, default=0.02)
    ap.add_argument("--max-dofs", type=int, default=300000)
    ap.add_argument("--ves", default=os.path.join(ROOT, "target/release/ves"))
    a = ap.parse_args()
    parts = a.parts or sorted(glob.glob(os.path.join(ROOT, "cases/corpus/*.step")))
    rows = []
    for step in parts:
        name = os.path.splitext(os.path.basename(step))[0]
        with tempfile.TemporaryDirectory() as work:
            scene = os.path.join(work, "scene.toml")
            open(scene, "w").write(
                f'name = "{name}"\n[geometry]\nstep = "{os.path.abspath(step)}"\nunit = "mm"\n'
                "[material]\nyoung = 2.1e11\npoisson = 0.3\ndensity = 7850.0\n"
                f"[mesh]\norder = 2\ntarget_error = {a.target}\nmax_dofs = {a.max_dofs}\n[modes]\ncount = 10\n"
            )
            env = dict(os.environ, XDG_CACHE_HOME=os.path.join(work, "cache"))
            t = time.perf_counter()
            p = subprocess.run([a.ves, "precompute", scene, "-o", os.path.join(work, "b.h5"), "--json"],
                               capture_output=True, text=True, env=env)
            wall = time.perf_counter() - t
        if p.returncode != 0:
            print(f"{name}: failed: {p.stderr.strip()[-300:]}", file=sys.stderr)
            continue
        steps = json.loads(p.stdout.strip().splitlines()[-1])["spaces"][0].get("refinements") or []
        print(f"{name}: {len(steps)} meshes, {wall:.0f} s", file=sys.stderr)
        for k, s in enumerate(steps):
            f = s.get("forecast")
            if f:
                rows.append((name, k + 1, f["dofs"], s["dofs"], f["seconds"], s["seconds"],
                             f["peak_bytes"] / 1e9, s["peak_rss_bytes"] / 1e9))
    print(f"target_error {a.target}, max_dofs {a.max_dofs}; load average at the end {os.getloadavg()[0]:.1f}\n")
    print("| part | mesh | unknowns: forecast / actual | seconds: forecast / actual (ratio) | peak GB: forecast / actual (ratio) |")
    print("|---|---|---|---|---|")
    for name, k, fd, d, fs, s, fb, b in rows:
        print(f"| {name} | {k} | {fd:.3g} / {d} | {fs:.1f} / {s:.1f} ({fs / s:.2f}) | {fb:.2f} / {b:.2f} ({fb / b:.2f}) |")
    if rows:
        ts = [r[4] / r[5] for r in rows]
        ms = [r[6] / r[7] for r in rows]
        print(f"\nseconds forecast/actual {min(ts):.2f}–{max(ts):.2f}; peak memory {min(ms):.2f}–{max(ms):.2f} "
              f"({sum(1 for x in ts if 1 / 1.5 <= x <= 1.5)} and {sum(1 for x in ms if 1 / 1.5 <= x <= 1.5)} "
              f"of {len(rows)} within 1.5×)")


if __name__ == "__main__":
    main()
