"""XDMF 3 with an HDF5 sidecar (meshio's layout; needs h5py): triangles and boundary lines
with ``group`` tags (and the same as ``gmsh:physical``), the groups' names where meshio
reads them (an ``Information`` element), point data.

The tags are those of the .msh physical groups (boundaries 1.., domain
last).  The sidecar is named after the file (``mesh.xdmf`` -> ``mesh.h5``).
Both files are made in memory (:func:`render`), never in a temporary folder:
h5py, closing a file on a full disk, reports the error and then crashes the
process.  The sidecar's HDF5 user block (the 512 bytes HDF5 leaves to the
application) starts with :data:`MARK`, so a later run can tell a sidecar it
wrote from a user's file of the same name.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from ..errors import DependencyError
from ..mesh import Mesh
from ._common import group_cell_data, group_table, meshio_mesh
from .format import Format

#: The first bytes of every sidecar deformesh writes (in the HDF5 user block).
MARK = b"deformesh xdmf sidecar\n"
_USERBLOCK = 512


def _h5py(path: str):
    try:
        import h5py
    except ImportError:
        raise DependencyError(
            f"{path}: writing .xdmf needs h5py: pip install 'deformesh[all]'"
        ) from None
    return h5py


def render(mesh: Mesh, name: str) -> tuple[bytes, bytes]:
    """The bytes of ``name`` (an ``.xdmf`` file name) and of its sidecar."""
    m = meshio_mesh(mesh, dim3=True, cell_data=group_cell_data(mesh))
    m.field_data = group_table(mesh)
    return render_meshio(m, name)


def render_meshio(m, name: str) -> tuple[bytes, bytes]:
    """:func:`render` of a ``meshio.Mesh`` (its points, cells, point and cell data)."""
    h5py = _h5py(name)
    from xml.etree import ElementTree as ET

    from meshio.xdmf.main import XdmfWriter

    class _InMemory(XdmfWriter):
        """meshio's writer, its HDF5 file in a buffer and its XML returned, not written."""

        def __init__(self, name, m, buf):
            self.filename = Path(name)
            self.data_format, self.data_counter = "HDF", 0
            self.compression, self.compression_opts = "gzip", 4
            self.h5_filename = self.filename.with_suffix(".h5")
            with h5py.File(buf, "w", userblock_size=_USERBLOCK, track_order=True) as f:
                self.h5_file = f
                root = ET.Element("Xdmf", Version="3.0")
                grid = ET.SubElement(ET.SubElement(root, "Domain"), "Grid", Name="Grid")
                self.write_points(grid, m.points)
                self.write_cells(m.cells, grid)
                self.write_point_data(m.point_data, grid)
                self.write_cell_data(m.cell_data, grid)
                if m.field_data:  # the groups' names, where meshio's reader takes them
                    _information(grid, m.field_data)
            out = io.BytesIO()
            ET.ElementTree(root).write(out)
            self.xml = out.getvalue()

    buf = io.BytesIO()
    w = _InMemory(os.path.basename(name), m, buf)
    side = bytearray(buf.getvalue())
    side[: len(MARK)] = MARK
    return w.xml, bytes(side)


def _information(grid, field_data: dict) -> None:
    """The groups' names (name -> ``(tag, dimension)``) as the ``Information`` element
    meshio's XDMF reader takes them from: ``<main><map key=NAME dim=D>TAG</map>...``."""
    from xml.etree import ElementTree as ET

    info = ET.Element("main")
    for key, value in field_data.items():
        tag, dim = np.ravel(value)[:2]
        ET.SubElement(info, "map", key=key, dim=str(int(dim))).text = str(int(tag))
    element = ET.SubElement(grid, "Information", Name="Information", Value=str(len(field_data)))
    element.text = ET.tostring(info).decode()


FORMAT = Format(
    name="xdmf",
    description="XDMF 3 with an HDF5 sidecar (.h5; needs h5py)",
    boundary_groups=True,
    point_data=True,
    sidecar=".h5",
    render=render,
    sidecar_mark=MARK,
    meshio_format="xdmf",
)
