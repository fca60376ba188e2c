"""Moves a `ves verify` problem between HDF5 and the .npy files the FEniCSx driver reads.

Usage: python3 fx_bridge.py in PROBLEM.h5 WORKDIR | out WORKDIR RESULT.h5
"""
import json
import os
import sys

import h5py
import numpy as np

if sys.argv[1] == "in":
    src, work = sys.argv[2], sys.argv[3]
    with h5py.File(src, "r") as f:
        for name, key in [("nodes", "nodes"), ("tets", "tets"), ("fixed", "fixed_dofs"), ("load", "load")]:
            np.save(os.path.join(work, "fx_%s.npy" % name), f[key][:])
        attrs = {k: (v.item() if hasattr(v, "item") else v) for k, v in f.attrs.items()}
    with open(os.path.join(work, "fx_attrs.json"), "w") as f:
        json.dump(attrs, f)
else:
    work, out = sys.argv[2], sys.argv[3]
    with h5py.File(out, "w") as f:
        f["frequencies_hz"] = np.load(os.path.join(work, "fx_out_freqs.npy"))
        f["modes"] = np.load(os.path.join(work, "fx_out_modes.npy"))
        f["static"] = np.load(os.path.join(work, "fx_out_static.npy"))
        with open(os.path.join(work, "fx_out_solver.txt")) as s:
            f.attrs["solver"] = s.read()
