"""Binary little-endian PLY: vertices (z = 0) and faces (triangles, then any quads).

Our own writer: meshio's stamps the time into the header and writes the
boundary lines as two-vertex faces.  PLY has no boundary markers; the
boundary is the edges used by one face (``edge`` elements would be standard
but meshio's reader refuses them).
"""

from __future__ import annotations

import numpy as np

from ..mesh import Mesh
from .format import Format


def write(mesh: Mesh, path: str, version: str | None = None) -> None:
    n, t, nq = mesh.n_nodes, len(mesh.triangles), len(mesh.quads)
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"comment deformesh mesh: vertices 0..{mesh.n_contour - 1} are the contour points\n"
        f"element vertex {n}\nproperty double x\nproperty double y\nproperty double z\n"
        f"element face {t + nq}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    v = np.zeros((n, 3), "<f8")
    v[:, :2] = mesh.points
    f = np.zeros(t, dtype=[("k", "u1"), ("v", "<i4", 3)])
    f["k"], f["v"] = 3, mesh.triangles
    q = np.zeros(nq, dtype=[("k", "u1"), ("v", "<i4", 4)])
    q["k"], q["v"] = 4, mesh.quads
    with open(path, "wb") as out:
        out.write(header.encode("ascii"))
        out.write(v.tobytes())
        out.write(f.tobytes())
        out.write(q.tobytes())


FORMAT = Format(
    name="ply",
    description="PLY binary (z = 0), triangles (and quads)",
    binary=True,
    write=write,
    meshio_format="ply",
)
