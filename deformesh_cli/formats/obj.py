"""Wavefront OBJ with z = 0: faces, and the boundary as ``l`` lines (1-based)."""

from __future__ import annotations

import numpy as np

from ..mesh import Mesh
from .format import Format


def write(mesh: Mesh, path: str, version: str | None = None) -> None:
    with open(path, "w", encoding="ascii", newline="\n") as f:
        f.write(f"# deformesh mesh: nodes 1..{mesh.n_contour} are the contour points\n")
        np.savetxt(f, mesh.points, fmt="v %.17g %.17g 0")
        np.savetxt(f, mesh.triangles + 1, fmt="f %d %d %d")
        if len(mesh.quads):
            np.savetxt(f, mesh.quads + 1, fmt="f %d %d %d %d")
        np.savetxt(f, mesh.lines + 1, fmt="l %d %d")


FORMAT = Format(name="obj", description="Wavefront OBJ (z = 0)", write=write, meshio_format="obj")
