"""A nonlinear scene from Python: the summary says what the basis holds, the load case follows
the elastica, and a grabbed tip pulled down comes in along the beam (an arc, not a line)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import ves

SOFT = Path(__file__).resolve().parents[2] / "cases" / "soft_cantilever" / "scene.toml"


def test_soft_cantilever_from_python(tmp_path):
    basis = ves.precompute(SOFT, tmp_path / "soft.h5", progress=False)
    nl = basis.summary["spaces"][0]["nonlinear"]
    assert nl["eigenmodes"] == 6 and nl["derivatives"] == basis.eigenvalues.size - 6, nl
    # PL²/EI = 1: the elastica's tip deflection is 0.3017 L (Bisshopp & Drucker 1945).
    case = basis.load("alpha_1")
    u = case["displacement"].reshape(-1, 3)
    nodes = basis.nodes
    end = np.abs(nodes[:, 0] - 1.0) < 1e-9
    w = -u[end, 2].mean()
    assert abs(w / 0.3017 - 1) < 0.02, w
    # A hand grabs the tip and pulls it 0.2 m down slowly: the tip comes in along x.
    sim = ves.Haptics(basis, stiffness=500.0, max_force=10.0)
    rest = sim.rest_positions
    tip = int(np.argmin(np.linalg.norm(rest - [1.0, 0.05, 0.025], axis=1)))
    for k in range(1501):
        hip = rest[tip] + [0.0, 0.0, -0.2 * k / 1500]
        sim.step(hip[None, :], buttons=True)
    d = sim.displacements()[tip]
    assert d[2] < -0.15 and d[0] < -0.01, d
    assert sim.quarantined == 0
