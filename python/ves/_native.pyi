"""Type stubs of the native module (re-exported by ``ves``)."""

from __future__ import annotations

import os
from typing import Any, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

SceneLike = Union[str, os.PathLike, Mapping[str, Any]]

class Error(Exception):
    """Base of every VES error; the message is the CLI's one line."""

class SceneError(Error):
    """The scene is malformed or asks for something invalid."""

class MeshError(Error):
    """The geometry could not be read or meshed."""

class SupportError(Error):
    """A ``[[fixed]]`` or ``[[load]]`` region cannot be applied to the mesh, or the supports leave a body free."""

class AssemblyError(Error):
    """An element of the mesh is degenerate or inverted."""

class SolverError(Error):
    """The factorisation or the eigen-solve failed."""

class BasisError(Error):
    """A basis file is missing, foreign, damaged or inconsistent."""

class OutputError(Error):
    """The output file cannot or must not be written; whatever was at its path is kept."""

class VerifyError(Error):
    """A reference solver is missing, not applicable, or failed."""

class VesWarning(UserWarning):
    """A warning of the pipeline (the line the CLI prints); also listed in ``Basis.summary["warnings"]``."""

class Space:
    """One space of a basis: the global mesh, or the finer mesh of one volume of interest."""

    name: str
    element_order: int
    rigid_modes_dropped: int
    voi: Optional[Tuple[Tuple[float, float, float], Tuple[float, float, float]]]
    vertex_count: int
    meshing_strategy: Optional[str]
    mode_count: int
    @property
    def nodes(self) -> npt.NDArray[np.float64]:
        """Node coordinates, m, shape (n, 3): corner vertices first."""
    @property
    def tets(self) -> npt.NDArray[np.uint32]:
        """Tetrahedra, shape (m, 4) or (m, 10), gmsh node order."""
    @property
    def surface_triangles(self) -> npt.NDArray[np.uint32]:
        """Boundary triangles on corner vertices, outward, shape (k, 3)."""
    @property
    def surface_faces(self) -> Optional[npt.NDArray[np.uint32]]:
        """CAD face tag of each surface triangle, shape (k,), or None."""
    @property
    def fixed_dofs(self) -> npt.NDArray[np.uint32]:
        """Supported DOFs, index 3i + c."""
    @property
    def eigenvalues(self) -> npt.NDArray[np.float64]:
        """Elastic eigenvalues λ = ω², rad²/s², ascending, shape (r,)."""
    @property
    def frequencies_hz(self) -> npt.NDArray[np.float64]:
        """Frequencies, Hz, shape (r,)."""
    @property
    def relative_residuals(self) -> npt.NDArray[np.float64]:
        """‖Kφ − λMφ‖ / ‖Kφ‖ of each mode, shape (r,)."""
    @property
    def modes(self) -> npt.NDArray[np.float64]:
        """M-normalised mode shapes, shape (3n, r): row 3i + c is component c of node i."""
    @property
    def stress(self) -> Optional[npt.NDArray[np.float64]]:
        """Modal stress at corner vertices, Pa per unit q, shape (6·nv, r) (Voigt xx yy zz yz xz xy), or None."""
    @property
    def load_cases(self) -> List[str]:
        """The static load cases' names ([[load]], [gravity]), in the file's order."""
    def load(self, name: str) -> dict:
        """One load case: kind, displacement (n, 3) m, von_mises (n,) Pa, stress (nv, 6) Pa, total_force, reaction (3,) N, balance_residual, max_displacement, max_von_mises, peak and regular_peak (verdict, value, error Pa or None, refined, position; or None)."""
    @property
    def estimated_relative_error(self) -> Optional[npt.NDArray[np.float64]]:
        """Each mode's estimated relative discretization error, shape (r,), or None."""
    @property
    def compliance(self) -> Optional[Tuple[npt.NDArray[np.uint32], npt.NDArray[np.float64]]]:
        """Exact static compliance: node indices (p,) and 3×3 blocks (p, 3, 3), m/N; or None."""
    @property
    def rigid(self) -> Optional[dict]:
        """A movable part's mass, center_of_mass, inertia and free_motions (k, 6): the rigid
        motions its supports leave, twists (v, ω) about the centre of mass (six for a free
        body); None for a part held in every direction."""
    def to_meshio(self, modes: Optional[int] = None) -> Any:
        """The space as a meshio.Mesh: tets in VTK order, mode shapes as point data mode_1, …"""

class Basis:
    """A modal-basis file (HDF5, format v1), read whole and checked when opened."""

    path: str
    generator: str
    scene_toml: str
    default_space: str
    file_bytes: int
    summary: Optional[dict]
    @staticmethod
    def open(path: Union[str, os.PathLike]) -> Basis:
        """Opens and checks a basis file; raises BasisError naming the file when it is not a sound basis."""
    @property
    def spaces(self) -> list[str]:
        """Names of the spaces, "global" first."""
    def space(self, name: str) -> Space:
        """The space named ``name``; KeyError when there is none."""
    @property
    def material(self) -> dict:
        """young, poisson, density, rayleigh_alpha, rayleigh_beta, yield_strength."""
    # The default space's arrays (see Space).
    @property
    def frequencies_hz(self) -> npt.NDArray[np.float64]: ...
    @property
    def eigenvalues(self) -> npt.NDArray[np.float64]: ...
    @property
    def modes(self) -> npt.NDArray[np.float64]: ...
    @property
    def nodes(self) -> npt.NDArray[np.float64]: ...
    @property
    def vertex_count(self) -> int: ...
    @property
    def tets(self) -> npt.NDArray[np.uint32]: ...
    @property
    def surface_triangles(self) -> npt.NDArray[np.uint32]: ...
    @property
    def surface_faces(self) -> Optional[npt.NDArray[np.uint32]]: ...
    @property
    def fixed_dofs(self) -> npt.NDArray[np.uint32]: ...
    @property
    def stress(self) -> Optional[npt.NDArray[np.float64]]: ...
    @property
    def load_cases(self) -> List[str]: ...
    def load(self, name: str) -> dict: ...
    @property
    def estimated_relative_error(self) -> Optional[npt.NDArray[np.float64]]: ...
    @property
    def relative_residuals(self) -> npt.NDArray[np.float64]: ...
    @property
    def compliance(self) -> Optional[Tuple[npt.NDArray[np.uint32], npt.NDArray[np.float64]]]: ...
    @property
    def rigid(self) -> Optional[dict]: ...
    def to_meshio(self, modes: Optional[int] = None, space: Optional[str] = None) -> Any:
        """The default space (or ``space``) as a meshio.Mesh."""

class Haptics:
    """A haptic simulation: hands pull or press the part through a virtual spring-damper; with
    volumes of interest, every space is simulated and the one holding the hands is active."""

    time: float
    steps: int
    spaces: list[str]
    @property
    def active_space(self) -> str:
        """The space simulated now ("global", or the VOI that holds the hands)."""
    @property
    def switches(self) -> int:
        """Switches between spaces so far."""
    def __init__(
        self,
        basis: Basis,
        stiffness: float = 500.0,
        damping: Optional[float] = None,
        *,
        max_force: float = 10.0,
        dt: float = 1e-3,
        hands: int = 1,
        space: Optional[str] = None,
        modes: Optional[int] = None,
        free_body: bool = False,
        static_correction: bool = True,
    ) -> None: ...
    def step(
        self,
        hand_positions: npt.ArrayLike,
        velocities: Optional[npt.ArrayLike] = None,
        buttons: Union[bool, Sequence[bool], None] = None,
        out: Optional[npt.NDArray[np.float64]] = None,
    ) -> npt.NDArray[np.float64]:
        """One step: hand positions (n, 3) m → device forces (n, 3) N (into ``out`` when given)."""
    def hand_outputs(self) -> list[dict]:
        """Each hand's output of the last step (force, vertex, vertex_position, contact, clamped, strain, …, felt_error: what the hand feels wrong at its vertex, or None)."""
    @property
    def q(self) -> npt.NDArray[np.float64]:
        """Modal coordinates, shape (r,)."""
    @property
    def qdot(self) -> npt.NDArray[np.float64]:
        """Modal velocities, shape (r,)."""
    @property
    def vertex_nodes(self) -> npt.NDArray[np.uint32]:
        """File node index of each kept (surface) vertex."""
    @property
    def rest_positions(self) -> npt.NDArray[np.float64]:
        """Rest positions of the kept vertices, m, shape (nv, 3)."""
    def displacements(self) -> npt.NDArray[np.float32]:
        """u = Φ q at the kept vertices, m, shape (nv, 3)."""
    def von_mises(self) -> Optional[npt.NDArray[np.float32]]:
        """Von Mises stress at the kept vertices, Pa, or None without modal stress."""
    def support_reactions(self) -> Optional[npt.NDArray[np.float64]]:
        """Per [[fixed]] support, force x y z (N) then moment x y z (N·m) about its centre,
        shape (s, 6); None for a free body or a basis without stored reactions."""
    @property
    def support_centres(self) -> Optional[npt.NDArray[np.float64]]:
        """The point each support's moment is about, m, shape (s, 3)."""
    @property
    def pose(self) -> Optional[npt.NDArray[np.float64]]:
        """Free body: centre of mass then quaternion (w, x, y, z); None when supported."""
    @property
    def quarantined(self) -> int:
        """Steps rolled back for a non-finite result."""
    @property
    def mode_count(self) -> int: ...
    def set_strain_watch(self, limit: float, policy: str = "flag") -> None:
        """Strain watch: "flag", "stiffen" or "release" past ``limit``."""
    def reset(self) -> None:
        """Back to rest, hands let go, time zero."""

def precompute(
    scene: SceneLike,
    out: Union[str, os.PathLike, None] = None,
    *,
    solver: str = "auto",
    progress: bool = True,
    modes: Optional[int] = None,
    force: bool = False,
    allow_geo_scripts: bool = False,
) -> Basis:
    """Meshes the scene, computes its lowest modes, writes the basis (default beside the scene, <name>.h5) and opens it."""

def faces(
    path: Union[str, os.PathLike],
    *,
    progress: bool = True,
    allow_geo_scripts: bool = False,
) -> list:
    """``ves faces --json`` as a call: the part's CAD faces as dicts (tag, kind "plane" / "cylinder" / "other", area_m2, centroid_m; normal; axis, axis_point_m, radius_m, concave; name: the STEP file's name of the face, or None)."""

def verify(
    input: Union[str, os.PathLike, Basis],
    against: str = "all",
    *,
    modes: Optional[int] = None,
    tol_freq: Optional[float] = None,
    min_mac: Optional[float] = None,
    max_angle: Optional[float] = None,
    tol_static: Optional[float] = None,
    stress: bool = False,
    tol_stress: Optional[float] = None,
    progress: bool = True,
) -> dict:
    """``ves verify --json`` as a call: the report as a dict; ``report["pass"]`` says whether every tolerance held."""

def session(
    basis: Union[str, os.PathLike, Basis],
    devices: Sequence[Union[str, os.PathLike]],
    *,
    rate: float = 1000.0,
    duration: Optional[float] = None,
    stiffness: float = 500.0,
    damping: Optional[float] = None,
    max_force: float = 10.0,
    strain_limit: float = 0.02,
    strain_policy: str = "flag",
    min_safety_factor: float = 1.0,
    spin: bool = False,
    realtime: bool = False,
    modes: Optional[int] = None,
    space: Optional[str] = None,
) -> dict:
    """``ves session --json`` as a call: replays device scripts (CSV t, x, y, z[, button]) in real time; the stats as a dict."""

def _matrices(scene: SceneLike, *, progress: bool = True, allow_geo_scripts: bool = False) -> dict: ...
def _isolate_meshing(worker: Union[str, os.PathLike]) -> None: ...
def _serve_mesh_rung(dir: Union[str, os.PathLike]) -> None: ...
def _rust_step_ns(basis: Basis, modes: Optional[int] = None, batches: int = 200, per_batch: int = 1000) -> float: ...
