"""VTK XML unstructured grid (meshio): triangles and boundary lines, point data, and
each cell's physical group tag as in .msh (cell data ``group``)."""

from __future__ import annotations

from ..mesh import Mesh
from ._common import GROUP_DATA, cell_groups, meshio_mesh
from .format import Format


def write(mesh: Mesh, path: str, version: str | None = None) -> None:
    import meshio

    m = meshio_mesh(mesh, dim3=True, cell_data={GROUP_DATA: cell_groups(mesh)})
    meshio.write(path, m, file_format="vtu")


FORMAT = Format(
    name="vtu",
    description="VTK XML unstructured grid",
    write=write,
    boundary_groups=True,
    point_data=True,
    meshio_format="vtu",
)
