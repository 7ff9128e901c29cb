"""VTK XML unstructured grid (meshio): triangles and boundary lines, point data."""

from __future__ import annotations

from ..mesh import Mesh
from ._common import meshio_mesh
from .format import Format


def write(mesh: Mesh, path: str, version: str | None = None) -> None:
    import meshio

    meshio.write(path, meshio_mesh(mesh, dim3=True), file_format="vtu")


FORMAT = Format(
    name="vtu",
    description="VTK XML unstructured grid",
    write=write,
    point_data=True,
    meshio_format="vtu",
)
