"""SU2 native mesh: triangles (VTK type 5) and quads (9), nodes, one ``MARKER_TAG`` per
boundary group.

Our own writer: meshio's su2 writer fails on boundary line cells.
"""

from __future__ import annotations

import numpy as np

from ..mesh import Mesh
from .format import Format


def write(mesh: Mesh, path: str, version: str | None = None) -> None:
    with open(path, "w", encoding="ascii", newline="\n") as f:
        f.write(f"% deformesh mesh: points 0..{mesh.n_contour - 1} are the contour points\n")
        nt, nq = len(mesh.triangles), len(mesh.quads)
        f.write(f"NDIME= 2\nNELEM= {nt + nq}\n")
        tri = np.column_stack([np.full(nt, 5), mesh.triangles, np.arange(nt)])
        np.savetxt(f, tri, fmt="%d")
        if nq:  # (VTK type 9)
            quad = np.column_stack([np.full(nq, 9), mesh.quads, nt + np.arange(nq)])
            np.savetxt(f, quad, fmt="%d")
        f.write(f"NPOIN= {mesh.n_nodes}\n")
        for k, (x, y) in enumerate(mesh.points.tolist()):
            f.write(f"{x!r} {y!r} {k}\n")
        f.write(f"NMARK= {len(np.unique(mesh.line_group))}\n")
        for g, name in enumerate(mesh.groups):
            lines = mesh.lines[mesh.line_group == g]
            if len(lines) == 0:
                continue
            f.write(f"MARKER_TAG= {name}\nMARKER_ELEMS= {len(lines)}\n")
            np.savetxt(f, np.column_stack([np.full(len(lines), 3), lines]), fmt="%d")


FORMAT = Format(
    name="su2",
    description="SU2 native, one MARKER_TAG per boundary",
    write=write,
    boundary_groups=True,
    meshio_format="su2",
)
