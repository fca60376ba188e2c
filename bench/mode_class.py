#!/usr/bin/env python3
"""A mode's class read from its shape in a basis file, for the per-class tables of
docs/accuracy.md (used by bench/estimate_vs_truth.py --basis).

    python3 bench/mode_class.py B.h5 beam|plate|ribplate|solid

beam: long axis x (the cantilever): axial (u_x carries most of the motion), torsion (the
dominant transverse component is odd across the other transverse axis), bending.
plate: thin in z (the 200:1 plate): in-plane (u_z carries less than half), torsion (u_z odd in y
about the plate's centre line), bending.
ribplate: which rib moves most (its share of Σ|u|² over the vertices above the plate); "coupled"
when none carries 60 %; a rib's mode is bending (across the rib's thickness, even along its
length), torsion (across the thickness, odd along its length) or in-plane (along the rib).
solid: "global" (no class).
"""
import sys

import h5py
import numpy as np

# The ribplate's ribs (m): x0, x1, y0, y1, and which axis is across the rib's thickness.
RIBS = [((0.020, 0.080, 0.020, 0.028), 1), ((0.120, 0.180, 0.020, 0.028), 1),
        ((0.020, 0.028, 0.100, 0.140), 0), ((0.140, 0.150, 0.090, 0.135), 0)]


def oddness(u, across, along, bins=20):
    """−1 when u is odd in `across` (about its mid-range), +1 when even; binned along `along`."""
    mid = 0.5 * (across.min() + across.max())
    edges = np.linspace(along.min(), along.max() + 1e-12, bins + 1)
    idx = np.digitize(along, edges) - 1
    num = den = 0.0
    for b in range(bins):
        plus = u[(idx == b) & (across > mid)]
        minus = u[(idx == b) & (across < mid)]
        if len(plus) and len(minus):
            mp, mm = plus.mean(), minus.mean()
            num += mp * mm
            den += 0.5 * (mp * mp + mm * mm)
    return num / den if den else 0.0


def one(x, u, kind):
    share = (u ** 2).sum(axis=0) / max((u ** 2).sum(), 1e-300)
    if kind == "beam":
        if share[0] > 0.5:
            return "axial"
        c = 1 if share[1] > share[2] else 2
        return "torsion" if oddness(u[:, c], x[:, 3 - c], x[:, 0]) < 0 else "bending"
    if kind == "plate":
        if share[2] < 0.5:
            return "in-plane"
        return "torsion" if oddness(u[:, 2], x[:, 1], x[:, 0]) < 0 else "bending"
    if kind == "ribplate":
        e = (u ** 2).sum(axis=1)
        total = e.sum()
        best, k = 0.0, None
        for i, ((x0, x1, y0, y1), _) in enumerate(RIBS):
            on = (x[:, 2] > 0.008 + 1e-6) & (x[:, 0] >= x0 - 1e-6) & (x[:, 0] <= x1 + 1e-6) \
                & (x[:, 1] >= y0 - 1e-6) & (x[:, 1] <= y1 + 1e-6)
            s = e[on].sum() / total
            if s > best:
                best, k, mask = s, i, on
        if best < 0.6:
            return "coupled"
        across = RIBS[k][1]
        along = 1 - across
        xs, us = x[mask], u[mask]
        sh = (us ** 2).sum(axis=0) / (us ** 2).sum()
        if sh[across] < 0.5:
            return f"rib{k + 1} in-plane"
        odd = oddness(us[:, across], xs[:, along], xs[:, 2]) < 0
        return f"rib{k + 1} {'torsion' if odd else 'bending'}"
    return "global"


def classify(path, kind):
    with h5py.File(path, "r") as f:
        g = f["spaces/global"]
        nv = int(g["mesh"].attrs["vertex_count"])
        x = g["mesh/nodes"][:nv]
        phi = g["modes/basis"][:]
    r = phi.shape[1]
    return [one(x, phi[:3 * nv, j].reshape(nv, 3), kind) for j in range(r)]


if __name__ == "__main__":
    for i, c in enumerate(classify(sys.argv[1], sys.argv[2])):
        print(i + 1, c)
