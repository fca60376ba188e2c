#!/usr/bin/env python3
"""The soft cantilever's tip pulled 0.3 m down over 1.5 s, held 0.5 s, brought back over 1.5 s,
then let go, in a real-time `ves session` (docs/nonlinear.md).

Usage: python3 bench/nonlinear_pull.py [VES] (default target/release/ves). Precomputes
cases/soft_cantilever into a temporary folder, writes the script, runs the session and prints
its timing and energy figures as JSON.
"""
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import h5py
import numpy as np

REPO = Path(__file__).resolve().parents[1]
VES = sys.argv[1] if len(sys.argv) > 1 else str(REPO / "target" / "release" / "ves")

with tempfile.TemporaryDirectory() as tmp:
    basis = Path(tmp) / "soft.h5"
    subprocess.run([VES, "precompute", str(REPO / "cases/soft_cantilever/scene.toml"), "-o", str(basis)],
                   check=True, capture_output=True)
    with h5py.File(basis, "r") as f:
        g = f["spaces/global"]
        nv = int(g["mesh"].attrs["vertex_count"])
        x = g["mesh/nodes"][:nv]
    tip = x[np.argmin(((x - [1.0, 0.05, 0.025]) ** 2).sum(1))]
    rows = ["t,x,y,z,button"]
    for k in range(6001):
        t = k * 1e-3
        s = t / 1.5 if t < 1.5 else 1.0 if t < 2.0 else 1.0 - (t - 2.0) / 1.5 if t < 3.5 else 0.0
        held = t < 3.5
        rows.append("%.4f,%.6f,%.6f,%.6f,%d" % (t, tip[0] if held else tip[0] + 1.0, tip[1], tip[2] - 0.3 * s, held))
    script = Path(tmp) / "pull.csv"
    script.write_text("\n".join(rows) + "\n")
    run = subprocess.run([VES, "session", str(basis), "--device", "script:%s" % script, "--json"],
                         check=True, capture_output=True, text=True)
    d = json.loads(run.stdout.strip().splitlines()[-1])
    keys = ["missed_deadlines", "periods_over_1_1_ms", "step_ns_median", "step_ns_p99", "step_ns_max",
            "quarantined", "final_energy_j", "max_energy_j", "strain_max"]
    print(json.dumps({k: d[k] for k in keys}))
