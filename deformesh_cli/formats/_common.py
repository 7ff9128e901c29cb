"""What the format modules share: physical groups, the contour-point array, meshio meshes."""

from __future__ import annotations

import numpy as np

from ..mesh import Mesh


def groups(mesh: Mesh) -> dict[str, tuple[int, int]]:
    """Physical groups (name -> (tag, dimension)): the boundary groups 1, 2, ... then ``domain``."""
    out = {name: (k + 1, 1) for k, name in enumerate(mesh.groups)}
    out["domain"] = (len(mesh.groups) + 1, 2)
    return out


def group_table(mesh: Mesh) -> dict[str, np.ndarray]:
    """The physical groups as VTK field data: per group, an int32 array named after it
    holding ``(tag, dimension)`` (what meshio reads a ``.msh``'s groups into), so a
    reader can find which ``group`` tag is ``contour``, ``hole_1`` or a box side."""
    return {name: np.array(v, dtype=np.int32) for name, v in groups(mesh).items()}


def contour_point(mesh: Mesh) -> np.ndarray:
    """Per node: its contour point index (``k`` for node ``k < n_contour``), else -1."""
    k = np.arange(mesh.n_nodes)
    return np.where(k < mesh.n_contour, k, -1).astype(np.int32)


def cell_blocks(mesh: Mesh) -> list[tuple[str, np.ndarray]]:
    """The cells by kind, as meshio names them: the triangles (unless the mesh is of
    quads only), the quads (only where there are some), then the boundary lines."""
    out = []
    if len(mesh.triangles) or not len(mesh.quads):
        out.append(("triangle", mesh.triangles.astype(np.int64)))
    if len(mesh.quads):
        out.append(("quad", mesh.quads.astype(np.int64)))
    out.append(("line", mesh.lines.astype(np.int64)))
    return out


def cell_groups(mesh: Mesh) -> list[np.ndarray]:
    """Per cell block (:func:`cell_blocks`): each cell's physical group tag as in
    ``.msh`` (:func:`groups`: ``domain`` for the triangles and quads, each line its
    boundary group's)."""
    domain = groups(mesh)["domain"][0]
    return [
        (mesh.line_group + 1).astype(np.int32)
        if kind == "line"
        else np.full(len(cells), domain, dtype=np.int32)
        for kind, cells in cell_blocks(mesh)
    ]


#: The cell data array that carries :func:`cell_groups` in .vtk, .vtu and .xdmf files.
GROUP_DATA = "group"

#: The same tags under the name meshio gives a .msh file's physical groups: readers built
#: on meshio (scikit-fem's ``Mesh.load``) take the boundaries' names from it and the
#: field data (.vtu, .xdmf).
PHYSICAL_DATA = "gmsh:physical"


def group_cell_data(mesh: Mesh) -> dict[str, list[np.ndarray]]:
    """:func:`cell_groups` as the cell data of a .vtu or .xdmf file: ``group``, and the
    same tags as ``gmsh:physical``."""
    tags = cell_groups(mesh)
    return {GROUP_DATA: tags, PHYSICAL_DATA: tags}


def meshio_mesh(mesh: Mesh, dim3: bool = False, cell_data: dict | None = None):
    """The mesh as a ``meshio.Mesh``: its :func:`cell_blocks`; point data
    ``contour_point`` and the mesh's own; ``dim3`` pads z = 0."""
    import meshio

    pts = mesh.points
    if dim3:
        pts = np.column_stack([pts, np.zeros(len(pts))])
    return meshio.Mesh(
        pts,
        cell_blocks(mesh),
        point_data={"contour_point": contour_point(mesh), **mesh.point_data},
        cell_data=cell_data or {},
    )


def rows(fmt: str, table: np.ndarray) -> str:
    """``fmt`` (one row's %-format, ending in a newline) applied to every row of ``table``.

    One %-operation over the whole table, where meshio's ASCII writers format
    row by row in Python (``benchmarks/RESULTS.md`` has the cost of each).
    """
    if len(table) == 0:
        return ""
    return (fmt * len(table)) % tuple(table.ravel().tolist())
