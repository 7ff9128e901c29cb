"""XDMF 3 with an HDF5 sidecar (meshio; needs h5py): triangles and boundary lines with
``group`` tags, point data.

The tags are those of the .msh physical groups (boundaries 1.., domain
last).  The sidecar is named after the file (``mesh.xdmf`` -> ``mesh.h5``).
"""

from __future__ import annotations

from ..errors import DependencyError
from ..mesh import Mesh
from ._common import GROUP_DATA, cell_groups, meshio_mesh
from .format import Format


def write(mesh: Mesh, path: str, version: str | None = None) -> None:
    try:
        import h5py  # noqa: F401
    except ImportError:
        raise DependencyError(
            f"{path}: writing .xdmf needs h5py: pip install 'deformesh[all]'"
        ) from None
    import meshio

    m = meshio_mesh(mesh, dim3=True, cell_data={GROUP_DATA: cell_groups(mesh)})
    meshio.write(path, m, file_format="xdmf")


FORMAT = Format(
    name="xdmf",
    description="XDMF 3 with an HDF5 sidecar (.h5; needs h5py)",
    write=write,
    boundary_groups=True,
    point_data=True,
    sidecar=".h5",
    meshio_format="xdmf",
)
