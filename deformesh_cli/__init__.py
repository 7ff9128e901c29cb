"""deformesh: conforming triangle meshes by deforming a Cartesian grid.

The method is Liao, Chen, Cai, Hildebrand and Fleitas, "A New Method for
Triangular Mesh Generation": select background grid nodes near the contour
points (Appendix A), move them onto the contour by a div-curl deformation
solved with least-squares finite elements over pseudo-time, and keep the
triangles inside the contour.

Public API::

    from deformesh_cli import load_contour, mesh_contour
    contour = load_contour("contour.csv")
    result = mesh_contour(contour)
    result.mesh.points, result.mesh.triangles
"""

__version__ = "0.1.0"

from .contour import Contour
from .errors import (
    ContractError,
    DeformeshError,
    FoldError,
    InputError,
    LimitError,
    OptionError,
    SelectionError,
)
from .pipeline import MeshResult, mesh_contour
from .readers import load_contour, parse_csv

__all__ = [
    "__version__",
    "Contour",
    "load_contour",
    "parse_csv",
    "mesh_contour",
    "MeshResult",
    "DeformeshError",
    "InputError",
    "OptionError",
    "LimitError",
    "SelectionError",
    "FoldError",
    "ContractError",
]
