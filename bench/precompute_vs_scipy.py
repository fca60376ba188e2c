#!/usr/bin/env python3
"""Precompute benchmark: `ves precompute` against scipy's eigsh shift-invert on the same K, M.

Runs `ves precompute SCENE --json` (its own stage timings), exports the very same assembled
matrices with `ves matrices`, and times scipy.sparse.linalg.eigsh(K, k, M, sigma) — ARPACK
driven by SuperLU, the usual Python route — with the same shift, number of modes and tolerance.
Prints one JSON object; `--markdown` also prints a table row for docs/benchmarks.md.

Needs: pip install scipy h5py numpy
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import h5py
import numpy as np
import scipy
import scipy.sparse as sp
from scipy.sparse.linalg import eigsh


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("--ves", default=os.path.join(os.path.dirname(__file__), "..", "target", "release", "ves"))
    ap.add_argument("--markdown", action="store_true")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        basis = os.path.join(tmp, "basis.h5")
        t = time.perf_counter()
        out = subprocess.run([args.ves, "precompute", args.scene, "-o", basis, "--json"],
                             check=True, capture_output=True, text=True)
        ves_wall = time.perf_counter() - t
        summary = json.loads(out.stdout.strip().splitlines()[-1])
        space = summary["spaces"][0]
        nev = len(space["frequencies_hz"])

        km = os.path.join(tmp, "km.h5")
        subprocess.run([args.ves, "matrices", args.scene, "-o", km], check=True, capture_output=True)
        with h5py.File(km, "r") as f:
            cp, ri = f["col_ptr"][:], f["row_idx"][:]
            k, m = f["k"][:], f["m"][:]
            rigid = int(f.attrs["rigid_modes"])
            n = len(cp) - 1
        lower_k = sp.csc_matrix((k, ri, cp), shape=(n, n))
        lower_m = sp.csc_matrix((m, ri, cp), shape=(n, n))
        K = (lower_k + lower_k.T - sp.diags(lower_k.diagonal())).tocsc()
        M = (lower_m + lower_m.T - sp.diags(lower_m.diagonal())).tocsc()
        assert n == space["dofs"], f"scipy sees {n} unknowns, ves {space['dofs']}: meshes differ"
        scale = K.diagonal().sum() / M.diagonal().sum()
        # The shift ves uses first: 0 for a supported part, -1e-6 tr K / tr M with rigid modes.
        sigma = 0.0 if rigid == 0 else -1e-6 * scale
        t = time.perf_counter()
        vals = eigsh(K, k=nev + rigid, M=M, sigma=sigma, which="LM", tol=1e-12, return_eigenvectors=True)[0]
        scipy_s = time.perf_counter() - t
    vals = np.sort(vals)[rigid:]
    f_scipy = np.sqrt(vals) / (2 * np.pi)
    f_ves = np.array(space["frequencies_hz"])
    result = {
        "scene": args.scene,
        "nodes": space["nodes"],
        "tets": space["tets"],
        "dofs": n,
        "modes": nev,
        "ves_timings_s": summary["timings_s"],
        "ves_wall_s": ves_wall,
        "ves_solve_s": summary["timings_s"]["factorize"] + summary["timings_s"]["eigensolve"],
        "scipy_eigsh_s": scipy_s,
        "scipy_version": scipy.__version__,
        "max_rel_freq_diff": float(np.max(np.abs(f_ves - f_scipy) / f_scipy)),
    }
    print(json.dumps(result))
    if args.markdown:
        t = summary["timings_s"]
        print(f"| {os.path.basename(os.path.dirname(os.path.abspath(args.scene)))} | {space['nodes']} | {space['tets']} | {n} | {nev} "
              f"| {t['mesh']:.2f} | {t['assemble']:.2f} | {t['factorize']:.2f} | {t['eigensolve']:.2f} | {t['write']:.2f} "
              f"| **{t['total']:.2f}** | {scipy_s:.2f} | {result['max_rel_freq_diff']:.1e} |")


if __name__ == "__main__":
    sys.exit(main())
