#!/usr/bin/env python3
"""gmsh's 3D algorithms side by side on the corpus parts (docs/benchmarks.md, issue 42).

Each part gets the corpus' default scene (cli/tests/corpus.rs: 10-node tets of 1/15 of its
largest extent, clamped over its lowest 3 % along x, steel, 10 modes; the error estimate off, so
that nothing else meshes beside it) and is precomputed `--runs` times by every variant, each run
with an empty mesh cache. A variant is `NAME=COMMAND`: the `ves` binary to run, optionally
preceded by VAR=VALUE settings of its environment, e.g.

    bench/mesh_algorithms.py --variant delaunay=/tmp/ves-old --variant hxt=target/release/ves

Reported per part and variant: the meshing stage (`timings_s.mesh`, median), the CPU seconds of
the whole run with its meshing processes (median; steadier than wall time on a busy VM), nodes and tets, the
ladder's rung, whether every run gave the same mesh (the same tets, nodes equal to 1e-9 of the part's size), the worst
shape quality (6√2·V/l_rms³, 1 = regular) and how many tets are under 0.02 (slivers, as the
precompute warns) and under 0.1, the order-2 step (curved tets invalid after it, repaired by
gmsh, straightened), the largest residual, and each variant's largest frequency difference to the
first variant's, beside the first variant's own estimated discretization error (one more run
with the error estimate on, `--estimate`).

Needs: h5py numpy, gmsh's command line (for the part's extent).
"""
import argparse
import json
import os
import resource
import shlex
import statistics
import subprocess
import sys
import tempfile

import h5py
import numpy as np


def extent_mm(step, tmp):
    """The part's largest extent (mm) from gmsh's surface mesh at a coarse size."""
    out = os.path.join(tmp, "probe.msh")
    subprocess.run(["gmsh", step, "-2", "-format", "msh2", "-o", out, "-setstring", "Geometry.OCCTargetUnit", "MM",
                    "-setnumber", "Mesh.MeshSizeFactor", "4"], check=True, capture_output=True)
    with open(out) as f:
        lines = f.read().split("\n")
    start = lines.index("$Nodes") + 2
    end = lines.index("$EndNodes")
    xyz = np.array([[float(v) for v in l.split()[1:4]] for l in lines[start:end]])
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    return lo, hi


def scene(step, tmp, estimate):
    lo, hi = extent_mm(step, tmp)
    lo, hi = lo * 1e-3, hi * 1e-3
    l = float((hi - lo).max())
    clamp_lo = [lo[0] - 0.01 * l, lo[1] - 0.01 * l, lo[2] - 0.01 * l]
    clamp_hi = [lo[0] + 0.03 * l, hi[1] + 0.01 * l, hi[2] + 0.01 * l]
    name = os.path.splitext(os.path.basename(step))[0]
    text = (f'name = "{name}"\n[geometry]\nstep = "{os.path.abspath(step)}"\nunit = "mm"\n'
            f"[material]\nyoung = 2.1e11\npoisson = 0.3\ndensity = 7850.0\n"
            f"[mesh]\nsize = {l / 15:e}\norder = 2\nerror_estimate = {'true' if estimate else 'false'}\n"
            f"[[fixed]]\nbox = {{ min = [{clamp_lo[0]:e}, {clamp_lo[1]:e}, {clamp_lo[2]:e}], "
            f"max = [{clamp_hi[0]:e}, {clamp_hi[1]:e}, {clamp_hi[2]:e}] }}\n[modes]\ncount = 10\n")
    path = os.path.join(tmp, f"{name}{'-est' if estimate else ''}.toml")
    with open(path, "w") as f:
        f.write(text)
    return path


def run(variant, scene_path, tmp):
    words = shlex.split(variant)
    env = dict(os.environ)
    while words and "=" in words[0] and not words[0].startswith("/"):
        k, v = words.pop(0).split("=", 1)
        env[k] = v
    cache = tempfile.mkdtemp(dir=tmp)
    env["VES_CACHE_DIR"] = cache
    out = os.path.join(tmp, "basis.h5")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run(words + ["precompute", scene_path, "-o", out, "--json", "--force"], env=env,
                       capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    # CPU seconds of the whole run and its meshing processes: steadier than wall time on a busy VM.
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    subprocess.run(["rm", "-rf", cache])
    if p.returncode != 0:
        return {"error": p.stderr.strip().splitlines()[-1] if p.stderr.strip() else f"exit {p.returncode}"}
    d = json.loads(p.stdout.strip().splitlines()[-1])
    s = d["spaces"][0]
    with h5py.File(out) as f:
        g = f["spaces/global/mesh"]
        nodes = g["nodes"][()]
        tets = g["tets"][()]
    x = nodes[tets[:, :4].astype(np.int64)]
    vol = np.einsum("ij,ij->i", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0]) / 6.0
    l2 = sum(((x[:, a] - x[:, b]) ** 2).sum(axis=1) for a, b in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)])
    q = 6.0 * np.sqrt(2.0) * vol / np.sqrt(l2 / 6.0) ** 3
    m = s.get("meshing", {})
    return {
        "mesh_s": d["timings_s"]["mesh"], "cpu_s": cpu, "total_s": d["timings_s"]["total"], "nodes": s["nodes"], "tets": s["tets"],
        "mesh": (nodes, tets), "min_q": float(q.min()), "below_002": int((q < 0.02).sum()), "below_01": int((q < 0.1).sum()),
        "rung": m.get("strategy"), "distorted": m.get("distorted"), "repaired": m.get("repaired_by_gmsh"),
        "straightened": m.get("straightened"), "residual": s["max_relative_residual"], "f": s["frequencies_hz"],
        "est": s.get("estimated_relative_error"),
    }


def same_mesh(a, b):
    """The same tets on nodes that agree to round-off (1e-9 of the part's size: gmsh's curving
    moves nodes by ~1e-12 m from one run to the next)."""
    (na, ta), (nb, tb) = a, b
    if na.shape != nb.shape or ta.shape != tb.shape or not (ta == tb).all():
        return False
    return float(np.abs(na - nb).max()) <= 1e-9 * float((na.max(axis=0) - na.min(axis=0)).max())


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--corpus", default=os.path.join(os.path.dirname(__file__), "..", "..", "shared", "geometry",
                                                      "corpus"))
    ap.add_argument("--variant", action="append", required=True, help="NAME=[VAR=VALUE ...] /path/to/ves")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--estimate", action="store_true", help="one more run of the first variant with the estimate")
    ap.add_argument("--parts", help="comma-separated part names (default: every *.step of the corpus)")
    args = ap.parse_args()
    variants = [v.split("=", 1) for v in args.variant]
    steps = sorted(os.path.join(args.corpus, f) for f in os.listdir(args.corpus) if f.endswith(".step"))
    if args.parts:
        wanted = args.parts.split(",")
        steps = [s for s in steps if os.path.splitext(os.path.basename(s))[0] in wanted]
    print("| part | variant | mesh (s), median | run's CPU (s), median | nodes | tets | rung | same mesh every run | min quality | "
          "q < 0.02 / < 0.1 | order 2: distorted / repaired / straightened | max residual | f1 (Hz) | "
          "max freq. diff. to the first | first's estimated error (max) |")
    print("|" + "---|" * 15)
    with tempfile.TemporaryDirectory() as tmp:
        for step in steps:
            name = os.path.splitext(os.path.basename(step))[0]
            sc = scene(step, tmp, False)
            est = None
            if args.estimate:
                r = run(variants[0][1], scene(step, tmp, True), tmp)
                est = max(r["est"]) if "est" in r and r["est"] else None
            ref = None
            # Interleaved (a run of each variant, then the next round): the VM's load moves
            # every figure, and so moves them alike.
            rounds = [[run(cmd, sc, tmp) for _, cmd in variants] for _ in range(args.runs)]
            for k, (vname, cmd) in enumerate(variants):
                runs = [r[k] for r in rounds]
                ok = [r for r in runs if "error" not in r]
                meshes = [r.pop("mesh") for r in ok]
                print(json.dumps({"part": name, "variant": vname, "runs": runs}), file=sys.stderr)
                if not ok:
                    print(f"| {name} | {vname} | failed: {runs[0]['error']} |" + " |" * 12)
                    continue
                r = ok[0]
                same = sum(not same_mesh(meshes[0], m) for m in meshes[1:])
                same = "yes" if same == 0 and len(ok) == len(runs) else f"**no** ({same} of {len(runs) - 1} differ)"
                nodes = "/".join(sorted({str(o["nodes"]) for o in ok}))
                tets = "/".join(sorted({str(o["tets"]) for o in ok}))
                if ref is None:
                    ref = r["f"]
                diff = max(abs(a - b) / b for a, b in zip(r["f"], ref))
                print(f"| {name} | {vname} | {statistics.median(o['mesh_s'] for o in ok):.2f} | "
                      f"{statistics.median(o['cpu_s'] for o in ok):.2f} | {nodes} | {tets} | "
                      f"{r['rung']} | {same} | {r['min_q']:.1e} | {r['below_002']} / {r['below_01']} | "
                      f"{r['distorted']} / {r['repaired']} / {r['straightened']} | {r['residual']:.1e} | "
                      f"{r['f'][0]:.1f} | {diff:.2e} | {'' if est is None else f'{est:.2e}'} |", flush=True)


if __name__ == "__main__":
    main()
