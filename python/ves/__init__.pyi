from __future__ import annotations

from typing import Tuple

import numpy as np
import numpy.typing as npt
import scipy.sparse

from ._native import (
    AssemblyError as AssemblyError,
    Basis as Basis,
    BasisError as BasisError,
    Error as Error,
    Haptics as Haptics,
    MeshError as MeshError,
    OutputError as OutputError,
    SceneError as SceneError,
    SceneLike,
    SolverError as SolverError,
    Space as Space,
    SupportError as SupportError,
    VerifyError as VerifyError,
    VesWarning as VesWarning,
    faces as faces,
    precompute as precompute,
    session as session,
    verify as verify,
)

__version__: str

def matrices(
    scene: SceneLike, *, progress: bool = True, allow_geo_scripts: bool = False
) -> Tuple[scipy.sparse.csc_matrix, scipy.sparse.csc_matrix, npt.NDArray[np.uint32]]:
    """K and M (symmetric, free DOFs) and the free-DOF map of a scene's global space."""
