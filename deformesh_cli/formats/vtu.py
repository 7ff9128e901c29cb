"""VTK XML unstructured grid (meshio): triangles and boundary lines, point data, and
each cell's physical group tag as in .msh (cell data ``group``, and the same as
``gmsh:physical``, where meshio-based readers look), the groups' names in the grid's
field data (per name, its ``(tag, dimension)``; meshio writes no field data, so it is
put in after)."""

from __future__ import annotations

import numpy as np

from ..errors import WriteError
from ..mesh import Mesh
from ._common import group_cell_data, group_table, meshio_mesh
from .format import Format


def write(mesh: Mesh, path: str, version: str | None = None) -> None:
    import meshio

    m = meshio_mesh(mesh, dim3=True, cell_data=group_cell_data(mesh))
    meshio.write(path, m, file_format="vtu")
    add_field_data(path, group_table(mesh))


def add_field_data(path: str, table: dict) -> None:
    """Put ``table`` (name -> an integer array, one tuple) into the grid's field data of
    the VTU file meshio wrote at ``path`` (meshio writes none)."""
    from xml.sax.saxutils import quoteattr  # (it loads urllib and email: only here)

    if not table:
        return
    with open(path, "rb") as f:
        data = f.read()
    grid = b"<UnstructuredGrid>"
    if data.count(grid) != 1:  # (meshio's layout changed: the names would go astray)
        raise WriteError(f"{path}: unexpected VTU layout from meshio (no single {grid!r})")
    # (one component, a tuple per number: meshio reads it back as the flat array
    # ``[tag, dimension]`` it reads a .msh's groups into)
    arrays = "".join(
        f'<DataArray type="Int32" Name={quoteattr(name)} NumberOfComponents="1" '
        f'NumberOfTuples="{tag.size}" format="ascii">{" ".join(map(str, tag.ravel().tolist()))}'
        "</DataArray>\n"
        for name, tag in ((k, np.asarray(v, dtype=np.int32)) for k, v in table.items())
    )
    field = f"\n<FieldData>\n{arrays}</FieldData>".encode()
    with open(path, "wb") as f:
        f.write(data.replace(grid, grid + field, 1))


FORMAT = Format(
    name="vtu",
    description="VTK XML unstructured grid",
    write=write,
    boundary_groups=True,
    point_data=True,
    meshio_format="vtu",
)
