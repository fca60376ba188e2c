"""VES from Python: precompute a modal basis from a scene, read basis files as numpy arrays,
drive the haptic runtime, and get the assembled K and M as scipy.sparse matrices.

>>> import ves
>>> basis = ves.precompute("cases/cantilever/scene.toml", "cantilever.h5")
>>> basis.frequencies_hz[:3]
>>> sim = ves.Haptics(basis, stiffness=2000.0)
>>> forces = sim.step([[1.0, 0.05, 0.05]], buttons=True)

Every failure raises a subclass of :class:`ves.Error` whose message is the line the ``ves``
command prints.
"""

from __future__ import annotations

import os
import shutil
import sys
import sysconfig

from . import _native
from ._native import (
    AssemblyError,
    Basis,
    BasisError,
    Error,
    Haptics,
    MeshError,
    OutputError,
    SceneError,
    SolverError,
    Space,
    SupportError,
    VerifyError,
    VesWarning,
    faces,
    precompute,
    session,
    verify,
)

__version__ = _native.__version__

__all__ = [
    "AssemblyError",
    "Basis",
    "BasisError",
    "Error",
    "Haptics",
    "MeshError",
    "OutputError",
    "SceneError",
    "SolverError",
    "Space",
    "SupportError",
    "VerifyError",
    "VesWarning",
    "faces",
    "matrices",
    "precompute",
    "session",
    "verify",
]


def _mesh_worker() -> str | None:
    """The ``ves-mesh-worker`` script installed with this package, if it can be found."""
    name = "ves-mesh-worker"
    here = os.path.join(sysconfig.get_path("scripts"), name)
    if os.access(here, os.X_OK):
        return here
    beside = os.path.join(os.path.dirname(sys.executable), name)
    if os.access(beside, os.X_OK):
        return beside
    return shutil.which(name)


# gmsh runs in child processes so that nothing it does (an abort, a crash on a malformed file)
# can end the interpreter; without the worker script, meshing runs in this process.
_worker = _mesh_worker()
if _worker is not None:
    _native._isolate_meshing(_worker)


def matrices(scene, *, progress: bool = True, allow_geo_scripts: bool = False):
    """Stiffness K and consistent mass M of a scene's global space on its free DOFs.

    ``scene`` is the path of a scene file or a dict of its TOML tables. Returns
    ``(K, M, free_dofs)``: K and M symmetric ``scipy.sparse.csc_matrix`` of shape (f, f) (SI
    units: N/m and kg), ``free_dofs`` (f,) the full DOF index (3·node + component) of each
    unknown. Raises :class:`ves.SceneError`, :class:`ves.MeshError`, … like the ``ves matrices``
    command.
    """
    import scipy.sparse as sp

    d = _native._matrices(scene, progress=progress, allow_geo_scripts=allow_geo_scripts)
    n = len(d["free_dofs"])

    def full(values):
        lower = sp.csc_matrix((values, d["row_idx"], d["col_ptr"]), shape=(n, n))
        return (lower + lower.T - sp.diags(lower.diagonal())).tocsc()

    return full(d["k"]), full(d["m"]), d["free_dofs"]
