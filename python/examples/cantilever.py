#!/usr/bin/env python3
"""The example of docs/python.md: precompute the cantilever, draw |u| of its first mode, pull
its tip for one second and plot the force the hand feels against time.

    python3 python/examples/cantilever.py [OUT.png]   (default docs/python/cantilever.png)

Needs the ves package (pip install ./python) and matplotlib.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

import ves

repo = Path(__file__).resolve().parents[2]
out_png = Path(sys.argv[1]) if len(sys.argv) > 1 else repo / "docs" / "python" / "cantilever.png"

# 1. Precompute: mesh, K and M, the 20 lowest modes, written to an HDF5 basis and opened.
work = Path(tempfile.mkdtemp())
basis = ves.precompute(repo / "cases" / "cantilever" / "scene.toml", work / "cantilever.h5")
print("first frequencies, Hz:", np.round(basis.frequencies_hz[:4], 2))

# 2. Mode 1 on the surface: nodes (n, 3), modes (3n, r) with row 3i + c = component c of node i.
nodes, tri = basis.nodes, basis.surface_triangles
u = basis.modes[:, 0].reshape(-1, 3)
size = np.abs(u).max()
drawn = nodes + 0.15 * u / size  # shape scaled so the tip moves 0.15 m
magnitude = np.linalg.norm(u, axis=1)[tri].mean(axis=1)

fig = plt.figure(figsize=(11, 4.2))
ax = fig.add_subplot(1, 2, 1, projection="3d")
colours = plt.cm.viridis(magnitude / magnitude.max())
ax.add_collection3d(Poly3DCollection(drawn[tri], facecolors=colours, edgecolor="none"))
ax.set(xlim=(0, 1), ylim=(-0.2, 0.3), zlim=(-0.2, 0.2), xlabel="x, m", ylabel="y, m", zlabel="z, m")
ax.set_box_aspect((1.0, 0.5, 0.4))
ax.set_title(f"mode 1, {basis.frequencies_hz[0]:.2f} Hz: |u| (normalised)")
ax.view_init(elev=20, azim=-60)

# 3. Pull the tip: grab the top corner of the free end, raise the hand 1 mm in 20 ms, hold it
#    there for the rest of the second (1 kHz steps, the device's rate).
sim = ves.Haptics(basis, stiffness=2e4, max_force=50.0)
rest = sim.rest_positions
corner = int(np.argmax(rest[:, 0] + rest[:, 2]))
tip = rest[corner]
sim.step(tip[None, :], buttons=True)
t = np.arange(1, 1001) * 1e-3
hand = np.repeat(tip[None, :], len(t), axis=0)
hand[:, 2] += 1e-3 * np.minimum(t / 0.02, 1.0)
force = np.empty((len(t), 3))
lifted = np.empty(len(t))
for k in range(len(t)):
    force[k] = sim.step(hand[k : k + 1], buttons=True)[0]
    lifted[k] = sim.hand_outputs()[0]["vertex_position"][2] - tip[2]
print(f"after 1 s: force {force[-1, 2]:.3f} N on the hand, tip raised {1e6 * lifted[-1]:.2f} µm")

ax2 = fig.add_subplot(1, 2, 2)
ax2.plot(t, force[:, 2], lw=1, color="C0")
ax2.set(xlabel="time, s", ylabel="force on the hand (z), N", title="tip corner pulled up 1 mm in 20 ms, held")
ax2.grid(alpha=0.3)
ax3 = ax2.twinx()
ax3.plot(t, 1e6 * lifted, lw=1, color="C1")
ax3.set_ylabel("tip corner raised, µm", color="C1")
fig.tight_layout()
out_png.parent.mkdir(parents=True, exist_ok=True)
fig.savefig(out_png, dpi=110)
print("wrote", out_png)
