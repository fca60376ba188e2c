"""The child process that meshes one rung of the meshing ladder (``ves-mesh-worker mesh-worker
DIR``), so that nothing gmsh does can end the interpreter that called ``ves.precompute``."""

from __future__ import annotations

import sys


def main() -> int:
    if len(sys.argv) != 3 or sys.argv[1] != "mesh-worker":
        print("usage: ves-mesh-worker mesh-worker DIR (started by ves.precompute)", file=sys.stderr)
        return 2
    from . import _native

    try:
        _native._serve_mesh_rung(sys.argv[2])
    except _native.Error as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
