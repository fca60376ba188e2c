"""The haptic runtime from Python: a grabbed tip settles on beam theory's static deflection."""

from __future__ import annotations

import numpy as np
import pytest

import ves

E, NU = 2.1e11, 0.3
L, B, T = 1.0, 0.1, 0.05  # length (x), width (y), thickness (z), m


def timoshenko_tip_compliance_z(offset_y: float) -> float:
    """Deflection per newton at the free end of a cantilever loaded there along z, `offset_y`
    off the centre line: bending L³/(3EI), shear L/(κGA) with Cowper's κ for a rectangle, and
    the twist of the offset load, e²L/(GJ) (Saint-Venant J of a rectangle, Roark's series)."""
    i = B * T**3 / 12
    g = E / (2 * (1 + NU))
    kappa = 10 * (1 + NU) / (12 + 11 * NU)
    j = B * T**3 * (1 / 3 - 0.21 * (T / B) * (1 - T**4 / (12 * B**4)))
    return L**3 / (3 * E * i) + L / (kappa * g * B * T) + offset_y**2 * L / (g * j)


def settle(sim, hip, steps):
    """Holds the hand at ``hip`` (button held) for ``steps`` steps; the device forces of each."""
    return np.array([sim.step(hip, buttons=True)[0] for _ in range(steps)])


def test_grabbed_tip_deflection_matches_beam_theory(cantilever):
    # The vertex of the free end face nearest its centre: near the neutral axis, so the pull
    # hardly twists the beam (the twist is in the reference).
    centre = np.array([L, B / 2, T / 2])
    sim = ves.Haptics(cantilever, stiffness=2e4, damping=500.0, max_force=1e3)
    rest = sim.rest_positions
    distance = np.linalg.norm(rest - centre, axis=1)
    distance[np.abs(rest[:, 0] - L) > 1e-9] = np.inf
    tip = int(np.argmin(distance))
    assert distance[tip] < 0.25 * B
    pull = rest[tip] + [0.0, 0.0, 0.5e-3]
    sim.step(rest[tip][None, :], buttons=True)  # grab
    forces = settle(sim, pull[None, :], 3000)
    out = sim.hand_outputs()[0]
    assert out["vertex"] == tip and out["contact"] and not out["clamped"]
    # Settled: the last 100 steps change the force by less than 1e-9 of it.
    f = -forces[-1]  # force on the part
    assert np.abs(forces[-100:] - forces[-1]).max() < 1e-9 * np.linalg.norm(f)
    u = np.array(out["vertex_position"]) - rest[tip]
    np.testing.assert_allclose(u, sim.displacements()[tip], rtol=1e-5, atol=1e-12)
    # Coupling equilibrium: F = k (hip − vertex).
    np.testing.assert_allclose(f, 2e4 * (pull - np.array(out["vertex_position"])), rtol=1e-9, atol=1e-9)
    # The runtime's static response is the basis's modal one, Σ φᵢφᵢᵀ F / λᵢ (the runtime
    # holds Φ in single precision).
    node = int(sim.vertex_nodes[tip])
    rows = cantilever.modes[3 * node : 3 * node + 3, :]
    modal = rows @ ((rows.T @ f) / cantilever.eigenvalues)
    np.testing.assert_allclose(u, modal, rtol=1e-5, atol=1e-6 * abs(modal[2]))
    compliance = u[2] / f[2]
    beam = timoshenko_tip_compliance_z(rest[tip][1] - B / 2)
    # Allowed: the basis's own estimate of its error (a stiffness error is twice a frequency
    # error, λ = ω²) plus the 1 % that tests/cantilever.rs allows between the 3D model and
    # Timoshenko's beam (the 3D clamp also holds the root's cross-section flat and keeps it from
    # contracting, which beam theory does not). Both make the 3D part the stiffer one.
    err = cantilever.estimated_relative_error
    assert err is not None
    allowed = 2 * float(err[0]) + 0.01
    assert compliance < beam
    assert abs(compliance - beam) <= allowed * beam, (compliance, beam, allowed)
    # The clamped root carries the pull back whole, settled: the modes' reactions with the share
    # the 20 modes leave out of the static response (~10 %) added back by equilibrium — its
    # force −f and the moment −(x − c) × f of the pull about the root's centre.
    (root,) = sim.support_reactions()
    assert sim.support_centres.shape == (1, 3)
    np.testing.assert_allclose(root[:3], -f, rtol=0, atol=1e-6 * np.linalg.norm(f))
    lever = rest[tip] - sim.support_centres[0]
    np.testing.assert_allclose(root[3:], -np.cross(lever, f), rtol=0, atol=1e-6 * L * np.linalg.norm(f))
    assert abs(root[4] / (L * f[2]) - 1) < 0.01, (root, f)


def test_state_read_out(cantilever):
    sim = ves.Haptics(cantilever, stiffness=2e4, damping=50.0)
    assert sim.mode_count == 20 and sim.q.shape == (20,) and np.all(sim.q == 0)
    nv = sim.rest_positions.shape[0]
    assert sim.displacements().shape == (nv, 3) and sim.vertex_nodes.shape == (nv,)
    np.testing.assert_array_equal(cantilever.nodes[sim.vertex_nodes], sim.rest_positions)
    corner = sim.rest_positions[np.argmax(sim.rest_positions[:, 0] + sim.rest_positions[:, 2])]
    sim.step(corner[None, :], buttons=True)
    for _ in range(50):
        f = sim.step((corner + [0, 0, 1e-3])[None, :], buttons=True)
    assert f.shape == (1, 3) and f[0, 2] < 0  # the device is pulled back down
    assert np.any(sim.q != 0) and sim.time == pytest.approx(51e-3)
    assert sim.von_mises() is None  # the cantilever's basis has no modal stress
    assert sim.pose is None  # a supported part
    sim.reset()
    assert np.all(sim.q == 0) and sim.time == 0.0
    # Fewer modes.
    assert ves.Haptics(cantilever, modes=5).mode_count == 5


@pytest.mark.parametrize(
    "call",
    [
        lambda s: s.step([[np.nan, 0, 0]]),
        lambda s: s.step([[1e300, 0, 0]]),
        lambda s: s.step(np.zeros((2, 3))),
        lambda s: s.step(np.zeros((1, 2))),
        lambda s: s.step(np.zeros((0, 3))),
        lambda s: s.step([[0, 0, 0]], velocities=[[0, 0, np.inf]]),
        lambda s: s.step([[0, 0, 0]], buttons=[True, False]),
        lambda s: s.set_strain_watch(0.02, "explode"),
        lambda s: s.set_strain_watch(-1.0),
    ],
)
def test_bad_step_input_is_a_value_error(cantilever, call):
    sim = ves.Haptics(cantilever)
    with pytest.raises(ValueError):
        call(sim)
    # The simulation is still usable.
    assert sim.step([[1.0, 0.05, 0.05]]).shape == (1, 3)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"stiffness": -1.0},
        {"stiffness": float("nan")},
        {"damping": -1.0},
        {"max_force": 0.0},
        {"dt": 0.0},
        {"dt": float("inf")},
        {"hands": 0},
        {"hands": 17},
        {"modes": 0},
        {"modes": 21},
        {"free_body": True},
    ],
)
def test_bad_settings_are_value_errors(cantilever, kwargs):
    with pytest.raises(ValueError):
        ves.Haptics(cantilever, **kwargs)


def test_out_is_filled_in_place(cantilever):
    sim = ves.Haptics(cantilever, stiffness=2e4)
    corner = sim.rest_positions[np.argmax(sim.rest_positions[:, 0] + sim.rest_positions[:, 2])]
    sim.step(corner[None, :], buttons=True)
    out = np.full((1, 3), np.nan)
    got = sim.step((corner + [0, 0, 1e-3])[None, :], buttons=True, out=out)
    assert got is out and np.all(np.isfinite(out)) and out[0, 2] < 0
    with pytest.raises(ValueError):
        sim.step(corner[None, :], out=np.zeros((2, 3)))
    frozen = np.zeros((1, 3))
    frozen.flags.writeable = False
    with pytest.raises(ValueError, match="read-only"):
        sim.step(corner[None, :], out=frozen)
    with pytest.raises(TypeError):
        sim.step(corner[None, :], out=np.zeros((1, 3), dtype=np.float32))


def test_step_rejects_wrong_types(cantilever):
    sim = ves.Haptics(cantilever)
    with pytest.raises((TypeError, ValueError)):
        sim.step("not an array")
    with pytest.raises(KeyError):
        ves.Haptics(cantilever, space="rib1")


def test_a_free_bracket_held_by_one_corner_hangs_below_the_hand(work):
    """The free aluminium bracket (no supports: 6 rigid modes dropped, mass properties stored)
    grabbed at one vertex settles with its centre of mass under the hand and the hand carrying
    its weight."""
    from conftest import REPO

    bracket = ves.precompute(REPO / "cases" / "bracket" / "scene.toml", work / "bracket.h5", progress=False)
    assert bracket.space("global").rigid_modes_dropped == 6
    mass = bracket.rigid["mass"]
    np.testing.assert_array_equal(bracket.rigid["free_motions"], np.eye(6))  # all six free
    sim = ves.Haptics(bracket, stiffness=2000.0, free_body=True)
    hand = sim.rest_positions[0][None, :].copy()
    forces = np.zeros((1, 3))
    for _ in range(30_000):  # 30 s at 1 kHz: the swing dies out (momentum damping 1/s)
        sim.step(hand, None, True, forces)
    np.testing.assert_allclose(forces[0], [0.0, 0.0, -mass * 9.81], atol=1e-4 * mass * 9.81)
    pose = sim.pose
    np.testing.assert_allclose(pose[:2], hand[0, :2], atol=1e-5)
    assert pose[2] < hand[0, 2]
    assert abs(np.linalg.norm(pose[3:]) - 1.0) < 1e-12


def test_a_volume_of_interest_takes_over_where_the_hand_pulls(work):
    """The cantilever with a finer volume of interest at its free end (a scene given as a dict):
    a hand pulling the tip switches to the VOI space, whose static response agrees with the
    global space's within their estimated errors, without a jump in the force; released and
    moved away, the hand brings the global space back."""
    from conftest import CANTILEVER

    tomllib = pytest.importorskip("tomllib")
    scene = tomllib.loads(CANTILEVER.read_text())
    scene["geometry"]["step"] = str(CANTILEVER.parent / "cantilever.step")
    scene["name"] = "tip_voi"
    scene["voi"] = [{"name": "tip", "box": {"min": [0.8, -0.01, -0.01], "max": [1.01, 0.11, 0.06]}, "size": 0.0125}]
    basis = ves.precompute(scene, work / "tip_voi.h5", progress=False)
    assert basis.spaces == ["global", "tip"]
    assert basis.space("tip").nodes.shape[0] > basis.space("global").nodes.shape[0]

    def pull(space):
        sim = ves.Haptics(basis, stiffness=2e4, damping=50.0, max_force=100.0, space=space)
        rest = sim.rest_positions
        tip = rest[np.argmax(rest[:, 0] + rest[:, 2])]
        sim.step(tip[None, :], buttons=True)
        forces = np.array([sim.step((tip + [0, 0, 1e-3])[None, :], buttons=True)[0] for _ in range(3000)])
        return sim, np.array(sim.hand_outputs()[0]["vertex_position"]) - tip, forces

    both, u, f = pull(None)
    alone, u_global, f_global = pull("global")
    assert both.spaces == ["global", "tip"] and alone.spaces == ["global"]
    assert both.active_space == "tip" and both.switches == 1
    assert alone.active_space == "global" and alone.switches == 0
    errors = [float(basis.space(n).estimated_relative_error[0]) for n in basis.spaces]
    assert abs(u[2] - u_global[2]) <= 2 * sum(errors) * abs(u_global[2])
    # No burst at the switch: the largest change of force between two steps is the global
    # space's own, to 1 %.
    jump, jump_global = np.abs(np.diff(f[:, 2])).max(), np.abs(np.diff(f_global[:, 2])).max()
    assert jump <= 1.01 * jump_global
    for _ in range(500):  # let go, move far from the box
        both.step([[0.5, 0.05, 0.2]], buttons=False)
    assert both.active_space == "global" and both.switches == 2
    # Fewer modes in every space, transfers cut to match.
    assert ves.Haptics(basis, modes=5).mode_count == 5


def test_a_hand_is_told_the_felt_error_where_the_basis_states_it(cantilever):
    # Without the static correction the basis states what a hand feels wrong at the felt check's
    # sampled points (the modes' share and the mesh's error together), nowhere else; with fewer
    # modes than it was measured with, nowhere.
    points = {}
    for p in cantilever.summary["spaces"][0]["felt_compliance"]["points"]:
        points.setdefault(p["node"], p)
    for modes, stated in ((None, True), (3, False)):
        sim = ves.Haptics(cantilever, stiffness=2e4, damping=500.0, max_force=1e3, modes=modes)
        nodes = list(sim.vertex_nodes)
        told = 0
        for node, p in list(points.items())[:4]:
            k = nodes.index(node)
            sim.reset()
            sim.step(sim.rest_positions[k][None, :], buttons=True)
            out = sim.hand_outputs()[0]
            assert out["vertex"] == k and out["contact"]
            if stated and p["felt_error"] is not None:
                assert out["felt_error"] == pytest.approx(p["felt_error"], rel=1e-6)
                told += 1
            else:
                assert out["felt_error"] is None
        expected = sum(1 for p in list(points.values())[:4] if p["felt_error"] is not None)
        assert expected >= 1 and told == (expected if stated else 0)
