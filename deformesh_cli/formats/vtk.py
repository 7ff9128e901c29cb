"""VTK legacy 4.2, binary (big-endian): triangles (and quads) and boundary lines, point data, and
each cell's physical group tag as in .msh (cell data ``group``), the groups' names
in the dataset's field data (per name, its ``(tag, dimension)``).

Byte for byte what meshio's legacy 4.2 writer writes for the same mesh, but for
the title line and the dataset's field data (tested), without importing meshio.
Version 4.2, not 5.1: VTK's own reader refuses 5.1's ``vtktypeint32`` in field
data, and meshio's 5.1 reader reads ``int`` as 64 bits; in 4.2 both read ``int``
as 32 bits (tested with both).
"""

from __future__ import annotations

import numpy as np

from ..errors import WriteError
from ..mesh import Mesh
from ._common import GROUP_DATA, cell_groups, contour_point, group_table
from .format import Format

#: The second line of our .vtk files (a free-text title in the legacy format).
TITLE = "deformesh mesh: point k < number of contour points is contour point k"


def write(mesh: Mesh, path: str, version: str | None = None) -> None:
    n, tri, quads, lines = mesh.n_nodes, mesh.triangles, mesh.quads, mesh.lines
    nt, nq, nl = len(tri), len(quads), len(lines)
    pts = np.zeros((n, 3), dtype=">f8")
    pts[:, :2] = mesh.points
    cells = np.empty(4 * nt + 5 * nq + 3 * nl, dtype=">i4")  # (count, corners) per cell
    by_tri = cells[: 4 * nt].reshape(nt, 4)
    by_tri[:, 0], by_tri[:, 1:] = 3, tri
    by_quad = cells[4 * nt : 4 * nt + 5 * nq].reshape(nq, 5)
    by_quad[:, 0], by_quad[:, 1:] = 4, quads
    by_line = cells[4 * nt + 5 * nq :].reshape(nl, 3)
    by_line[:, 0], by_line[:, 1:] = 2, lines
    # VTK_TRIANGLE, VTK_QUAD, VTK_LINE
    types = np.repeat(np.array([5, 9, 3], dtype=">i4"), [nt, nq, nl])
    nt += nq  # (the cells of the domain)
    cp = contour_point(mesh).astype(">i4")
    fields = [(f"contour_point 1 {n} int\n".encode(), cp)]
    for name, data in mesh.point_data.items():  # as meshio writes them: floats as double
        whole = np.asarray(data).dtype.kind in "iu"
        data = np.asarray(data, dtype=">i4" if whole else ">f8")
        k = 1 if data.ndim == 1 else data.shape[1]
        fields.append((f"{name} {k} {n} {'int' if whole else 'double'}\n".encode(), data))
    with open(path, "wb") as f:
        f.write(
            f"# vtk DataFile Version 4.2\n{TITLE}\nBINARY\nDATASET UNSTRUCTURED_GRID\n".encode()
            + field_block(group_table(mesh))  # (the group names: the dataset's)
            + f"POINTS {n} double\n".encode()
        )
        for head, data in (
            (b"", pts),
            (f"CELLS {nt + nl} {len(cells)}\n".encode(), cells),
            (f"CELL_TYPES {nt + nl}\n".encode(), types),
            (f"POINT_DATA {n}\nFIELD FieldData {len(fields)}\n".encode() + fields[0][0], cp),
            *fields[1:],
            (
                f"CELL_DATA {nt + nl}\nFIELD FieldData 1\n{GROUP_DATA} 1 {nt + nl} int\n".encode(),
                np.concatenate(cell_groups(mesh)).astype(">i4"),
            ),
        ):
            f.write(head)
            f.write(np.ascontiguousarray(data).data)  # (the array's bytes, not a copy)
            f.write(b"\n")


def field_block(table: dict) -> bytes:
    """The dataset's field data of a binary legacy file: per name, its integer array
    as one tuple (``b""`` for none)."""
    if not table:
        return b""
    out = f"FIELD FieldData {len(table)}\n".encode()
    for name, tag in table.items():
        tag = np.asarray(tag, dtype=">i4").ravel()
        out += f"{name} {tag.size} 1 int\n".encode() + tag.tobytes() + b"\n"
    return out


def add_field_data(path: str, table: dict) -> None:
    """Put ``table`` into the dataset's field data of the binary legacy file meshio
    wrote at ``path`` (meshio writes none)."""
    if not table:
        return
    with open(path, "rb") as f:
        data = f.read()
    head = b"DATASET UNSTRUCTURED_GRID\n"
    if data.count(head) != 1 or b"\nBINARY\n" not in data[:200]:
        raise WriteError(f"{path}: unexpected VTK layout from meshio")
    with open(path, "wb") as f:
        f.write(data.replace(head, head + field_block(table), 1))


FORMAT = Format(
    name="vtk",
    description="VTK legacy 4.2, binary",
    binary=True,
    write=write,
    boundary_groups=True,
    point_data=True,
    meshio_format="vtk",
)
