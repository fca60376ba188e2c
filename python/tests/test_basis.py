"""Basis files: the package's precompute equals the CLI's, and the arrays mean what the file
format says."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import ves


def test_frequencies_equal_the_cli_basis_of_the_same_scene(cantilever, cantilever_cli):
    path, summary = cantilever_cli
    cli = ves.Basis.open(path)
    np.testing.assert_allclose(cantilever.frequencies_hz, cli.frequencies_hz, rtol=1e-12, atol=0)
    np.testing.assert_allclose(cantilever.eigenvalues, cli.eigenvalues, rtol=1e-12, atol=0)
    # And what the CLI printed, and what precompute reported, are what the files hold.
    printed = summary["spaces"][0]["frequencies_hz"]
    np.testing.assert_allclose(cli.frequencies_hz, printed, rtol=1e-15, atol=0)
    reported = cantilever.summary["spaces"][0]
    np.testing.assert_allclose(cantilever.frequencies_hz, reported["frequencies_hz"], rtol=1e-15, atol=0)
    assert reported["nodes"] == summary["spaces"][0]["nodes"] == cantilever.nodes.shape[0]


def test_open_agrees_with_ves_info(cli, cantilever):
    run = subprocess.run([str(cli), "info", str(cantilever.path), "--json"], capture_output=True, text=True, check=True)
    info = json.loads(run.stdout.strip().splitlines()[-1])
    space = info["spaces"][0]
    assert cantilever.spaces == [s["name"] for s in info["spaces"]] == ["global"]
    assert cantilever.nodes.shape == (space["nodes"], 3)
    assert cantilever.vertex_count == space["vertices"]
    assert cantilever.tets.shape == (space["tets"], 10)
    np.testing.assert_array_equal(cantilever.frequencies_hz, space["frequencies_hz"])


def test_arrays_follow_the_file_contract(cantilever):
    b = cantilever
    n, r = b.nodes.shape[0], b.frequencies_hz.shape[0]
    assert b.modes.shape == (3 * n, r) and r == 20
    np.testing.assert_allclose(b.frequencies_hz, np.sqrt(b.eigenvalues) / (2 * np.pi), rtol=1e-14)
    assert np.all(np.diff(b.eigenvalues) > 0)
    # Surface triangles on corner vertices; one CAD face tag each (a box has six faces).
    assert b.surface_triangles.max() < b.vertex_count
    assert b.surface_faces is not None and b.surface_faces.shape == (b.surface_triangles.shape[0],)
    assert set(np.unique(b.surface_faces)) == set(range(1, 7))
    # The clamped plane x = 0: exactly its nodes' three components are fixed, and every mode
    # is zero there.
    x0 = np.flatnonzero(np.abs(b.nodes[:, 0]) < 1e-9)
    expected = np.sort(np.concatenate([3 * x0, 3 * x0 + 1, 3 * x0 + 2]))
    np.testing.assert_array_equal(b.fixed_dofs, expected)
    assert np.all(b.modes[b.fixed_dofs.astype(np.int64), :] == 0.0)
    # Metres: the beam is 1 m x 0.1 m x 0.05 m (the STEP file is in millimetres).
    np.testing.assert_allclose(b.nodes.max(axis=0) - b.nodes.min(axis=0), [1.0, 0.1, 0.05], rtol=1e-9)
    assert b.material["young"] == 2.1e11 and b.material["rayleigh_beta"] == 1e-5
    assert b.space("global").mode_count == r


def test_arrays_are_shared_and_read_only(cantilever):
    a = cantilever.modes
    assert a is cantilever.modes or np.shares_memory(a, cantilever.modes)
    with pytest.raises(ValueError):
        a[0, 0] = 1.0


def test_missing_foreign_and_truncated_files_are_basis_errors(tmp_path, cantilever):
    with pytest.raises(ves.BasisError, match="no such file"):
        ves.Basis.open(tmp_path / "missing.h5")
    with pytest.raises(ves.BasisError, match="is a directory"):
        ves.Basis.open(tmp_path)
    text = tmp_path / "scene.h5"
    text.write_text("not hdf5")
    with pytest.raises(ves.BasisError, match="scene.h5"):
        ves.Basis.open(text)
    data = cantilever.path.read_bytes()
    for fraction in (0.1, 0.5, 0.9, 0.999):
        cut = tmp_path / f"cut{fraction}.h5"
        cut.write_bytes(data[: int(len(data) * fraction)])
        with pytest.raises(ves.BasisError):
            ves.Basis.open(cut)
    with pytest.raises(KeyError, match="no space"):
        cantilever.space("rib1")
    assert isinstance(ves.BasisError("x"), ves.Error)


def test_damaged_copies_are_errors_not_crashes(cantilever, tmp_path):
    """Bytes flipped at random in copies of a basis: each open raises BasisError or reads a
    basis whose checks passed. Run in a child interpreter, so that a crash fails the test
    instead of ending the run."""
    script = (
        "import random, sys\n"
        "import ves\n"
        "data = open(sys.argv[1], 'rb').read()\n"
        "rng = random.Random(32)\n"
        "refused = opened = 0\n"
        "for k in range(100):\n"
        "    b = bytearray(data)\n"
        "    for _ in range(rng.randint(1, 8)):\n"
        "        i = rng.randrange(len(b))\n"
        "        b[i] ^= 1 << rng.randrange(8)\n"
        "    path = f'{sys.argv[2]}/flip{k}.h5'\n"
        "    open(path, 'wb').write(b)\n"
        "    try:\n"
        "        basis = ves.Basis.open(path)\n"
        "        assert basis.modes.shape[1] == len(basis.frequencies_hz)\n"
        "        opened += 1\n"
        "    except ves.BasisError:\n"
        "        refused += 1\n"
        "print(refused, opened)\n"
    )
    run = subprocess.run(
        [sys.executable, "-c", script, str(cantilever.path), str(tmp_path)], capture_output=True, text=True
    )
    assert run.returncode == 0, run.stderr[-2000:]
    refused, opened = map(int, run.stdout.split())
    assert refused + opened == 100 and refused > 0


def test_to_meshio_round_trips_through_a_vtu_file(cantilever, tmp_path):
    meshio = pytest.importorskip("meshio")
    mesh = cantilever.to_meshio(modes=3)
    path = tmp_path / "cantilever.vtu"
    mesh.write(path)
    back = meshio.read(path)
    np.testing.assert_array_equal(back.points, cantilever.nodes)
    tets = back.cells_dict["tetra10"]
    assert tets.shape == cantilever.tets.shape
    # VTK's node order differs from gmsh's in the last two mid-edge nodes only.
    np.testing.assert_array_equal(tets[:, :8], cantilever.tets[:, :8])
    np.testing.assert_array_equal(tets[:, 8], cantilever.tets[:, 9])
    np.testing.assert_array_equal(back.point_data["mode_1"], cantilever.modes[:, 0].reshape(-1, 3))
    assert sorted(back.point_data) == ["mode_1", "mode_2", "mode_3"]
