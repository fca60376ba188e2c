"""``Basis.to_meshio``: one space of a basis as a ``meshio.Mesh``."""

from __future__ import annotations

import numpy as np

# gmsh's 10-node tet lists its last two mid-edge nodes the other way round from VTK's (and
# meshio's): the same permutation as format/src/element.rs TET10_TO_VTK.
_TET10_TO_VTK = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]


def to_meshio(space, modes=None):
    """The space's tets (``tetra10`` in VTK node order, or ``tetra``) with each mode shape as
    point data ``mode_1``, ``mode_2``, … ((n, 3), m per unit modal coordinate) and the
    frequencies as field data. ``modes``: how many (default all). Modal stress, defined at
    corner vertices only, is not included: `ves export --vtu` writes it on a vertices grid."""
    import meshio

    tets = np.asarray(space.tets, dtype=np.int64)
    if tets.shape[1] == 10:
        cells = [("tetra10", tets[:, _TET10_TO_VTK])]
    else:
        cells = [("tetra", tets)]
    phi = space.modes
    r = phi.shape[1] if modes is None else min(int(modes), phi.shape[1])
    point_data = {f"mode_{j + 1}": phi[:, j].reshape(-1, 3) for j in range(r)}
    return meshio.Mesh(
        np.asarray(space.nodes),
        cells,
        point_data=point_data,
        field_data={"frequencies_hz": np.asarray(space.frequencies_hz[:r])},
    )
