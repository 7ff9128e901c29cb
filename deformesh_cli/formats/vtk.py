"""VTK legacy 5.1, binary (big-endian): triangles and boundary lines, point data.

Byte for byte what meshio writes for the same mesh, but for the title line
(tested), without importing meshio.
"""

from __future__ import annotations

import numpy as np

from ..mesh import Mesh
from ._common import contour_point
from .format import Format

#: The second line of our .vtk files (a free-text title in the legacy format).
TITLE = "deformesh mesh: point k < number of contour points is contour point k"


def write(mesh: Mesh, path: str, version: str | None = None) -> None:
    n, tri, lines = mesh.n_nodes, mesh.triangles, mesh.lines
    nt, nl = len(tri), len(lines)
    pts = np.zeros((n, 3), dtype=">f8")
    pts[:, :2] = mesh.points
    offsets = np.concatenate(
        [np.arange(0, 3 * nt + 1, 3), 3 * nt + np.arange(2, 2 * nl + 1, 2)]
    ).astype(">i8")
    conn = np.concatenate([tri.ravel(), lines.ravel()]).astype(">i8")
    types = np.repeat(np.array([5, 3], dtype=">i4"), [nt, nl])  # VTK_TRIANGLE, VTK_LINE
    cp = contour_point(mesh).astype(">i4")
    fields = [(f"contour_point 1 {n} vtktypeint32\n".encode(), cp)]
    for name, data in mesh.point_data.items():  # as meshio writes them: floats as double
        data = np.asarray(data, dtype=">f8")
        k = 1 if data.ndim == 1 else data.shape[1]
        fields.append((f"{name} {k} {n} double\n".encode(), data))
    with open(path, "wb") as f:
        f.write(
            f"# vtk DataFile Version 5.1\n{TITLE}\nBINARY\n"
            f"DATASET UNSTRUCTURED_GRID\nPOINTS {n} double\n".encode()
        )
        for head, data in (
            (b"", pts),
            (
                f"CELLS {nt + nl + 1} {3 * nt + 2 * nl}\nOFFSETS vtktypeint64\n".encode(),
                offsets,
            ),
            (b"CONNECTIVITY vtktypeint64\n", conn),
            (f"CELL_TYPES {nt + nl}\n".encode(), types),
            (f"POINT_DATA {n}\nFIELD FieldData {len(fields)}\n".encode() + fields[0][0], cp),
            *fields[1:],
        ):
            f.write(head)
            f.write(data.tobytes())
            f.write(b"\n")


FORMAT = Format(
    name="vtk",
    description="VTK legacy 5.1, binary",
    write=write,
    point_data=True,
    meshio_format="vtk",
)
