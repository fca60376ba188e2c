"""The package as installed: no MPI, the meshing worker, the stubs."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import ves


def test_importing_ves_loads_no_mpi():
    """The package is built without the slepc feature and against serial HDF5: importing it
    and reading a basis maps no MPI library into the process."""
    script = (
        "import ves, sys\n"
        "ves.Basis.open(sys.argv[1])\n"
        "maps = open('/proc/self/maps').read()\n"
        "print('\\n'.join(sorted({l.split()[-1] for l in maps.splitlines() if 'mpi' in l.split()[-1].lower()})))\n"
    )
    from conftest import REPO

    run = subprocess.run(
        [sys.executable, "-c", script, str(REPO / "cases" / "cantilever" / "scene.toml")],
        capture_output=True,
        text=True,
    )
    # The scene is no basis: the open fails, after HDF5 has been loaded and used.
    assert "BasisError" in run.stderr, run.stderr[-2000:]
    assert run.stdout.strip() == "", f"MPI libraries mapped (build with HDF5_DIR=<serial HDF5>, as scripts/test_python does): {run.stdout}"


def test_the_meshing_worker_is_installed_and_used():
    assert ves._worker is not None and Path(ves._worker).name == "ves-mesh-worker"
    run = subprocess.run([ves._worker], capture_output=True, text=True)
    assert run.returncode == 2 and "usage" in run.stderr


def test_the_stubs_ship_with_the_package():
    here = Path(ves.__file__).parent
    for name in ("__init__.pyi", "_native.pyi", "py.typed"):
        assert (here / name).is_file(), name
    stub = (here / "_native.pyi").read_text()
    for name in ves.__all__:
        if name != "matrices":
            assert f"{name}" in stub, name
