"""The options of a meshing run and of a moving mesh, each default written once.

:class:`MeshOptions` is what ``deformesh all`` takes, and each of ``select``,
``deform`` and ``triangulate`` takes its stage's share of it; batches send it
to their workers and the state file records it.  :class:`MoveOptions` is what
``deformesh move`` takes.  Both are frozen and keyword-only.

Each field carries, in its metadata, what the command line needs to offer
it: the flag, the help text, the choices (taken from the core's own
registries) and the kind of value.  :mod:`deformesh_cli.cli.options` builds the
click options from them, so the defaults and ``--help`` cannot drift from the
library's.  Nothing here imports click.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from .deform import DEFAULT_STEPS, MAX_STEPS, SOLVERS, SOLVES
from .formats import FORMATS, MSH_VERSIONS
from .layers import DEFAULT_GROWTH as DEFAULT_LAYER_GROWTH
from .layers import LAYER_CELLS, MAX_LAYERS
from .quads import CELLS
from .select import DEFAULT_MAX_NODES, GRIDS, MAX_NODES_CEILING
from .select.graded import DEFAULT_GROWTH

#: The kinds of value a field's ``kind`` metadata names (the command line checks them):
#: ``text``, ``flag`` (``--x``), ``switch`` (``--x/--no-x``), ``choice`` (one of
#: ``choices``), ``positive`` (a finite float > 0), ``float``, ``count`` (an int >= ``min``
#: and <= ``max`` where given),
#: ``box`` (XMIN,YMIN,XMAX,YMAX), ``vector`` (DX,DY, not both 0), ``path`` (an existing file).
KINDS = ("text", "flag", "switch", "choice", "positive", "float", "count", "box", "vector", "path")


#: ``deformesh move``'s default floor on a frame's smallest angle, in degrees: the
#: condition number of a P1 stiffness matrix grows as 1 / sin of its smallest angle
#: (Shewchuk, "What is a good linear finite element?"), 29 times a right triangle's
#: at 2 degrees.
DEFAULT_MIN_ANGLE = 2.0


def _opt(default: Any, help: str, kind: str = "text", **meta: Any) -> Any:
    """A dataclass field whose metadata says how the command line offers it."""
    assert kind in KINDS
    return field(default=default, metadata={"help": help, "kind": kind, **meta})


_STEPS_HELP = "Pseudo-time steps of the deformation."
_SOLVER_HELP = (
    "Linear solver per step: sparse LDL^T ('direct'), multigrid-preconditioned CG ('amg'), "
    "or 'auto' (direct on the band and the graded grid, and up to 60,000 free nodes on a "
    "whole uniform grid)."
)
#: ``merge_extra`` choices (:mod:`.merge`).
MERGE_EXTRA = ("auto", "merge", "keep")

_DECIMAL_HELP = "Decimal mark of the CSV numbers; with ',' the delimiter is ';', tab or spaces."


@dataclass(frozen=True, kw_only=True)
class MeshOptions:
    """Every option of a meshing run, grouped by the stage that reads it.

    Reading the contour: ``decimal``, ``tolerance``, ``element_id``,
    ``stroke``, ``resample``.  Stage 1 (select): ``h``, ``box``, ``margin``, ``strict``,
    ``max_nodes``, ``exterior``, ``grid``, ``growth``, ``max_h``, ``periodic``.  Stage 2
    (deform): ``steps``, ``solver``, ``solve``, ``size``, ``size_field``.  Stage 3 (triangulate):
    ``improve``, ``merge_extra``, ``cells``.  Boundary layers (``deformesh all``): ``layers``,
    ``first_height``, ``layer_growth``, ``layers_on``, ``layer_cells``.  Writing:
    ``fmt``, ``msh_version``.
    """

    # reading the contour
    decimal: str = _opt(".", _DECIMAL_HELP, "choice", choices=(".", ","))
    tolerance: str | None = _opt(
        None,
        "SVG: largest gap between a curve and its chords, in drawing units, or "
        "a percentage of the drawing's diagonal ('0.5%').  Default: 0.1%.",
        metavar="TOL",
    )
    element_id: str | None = _opt(
        None,
        "SVG: mesh only the element with this id (a shape or a group). "
        "Default: every filled shape.",
        flag="--id",
        metavar="ID",
    )
    stroke: bool = _opt(
        False,
        "SVG: mesh the outline of the stroked shapes (line icons drawn with fill='none'), "
        "with their stroke widths, caps and joins, instead of the filled shapes.",
        "flag",
    )
    resample: str | None = _opt(
        None,
        "Re-space the contour evenly (corners kept) at SPACING, in contour units "
        "or as a percentage of its diagonal ('1%'). The given points are then "
        "no longer all boundary nodes.",
        metavar="SPACING",
    )
    # stage 1: select
    h: float | None = _opt(
        None,
        "Grid step. Default: Appendix A's 0.9*d_c/sqrt(2), d_c the smallest "
        "distance between two contour points.",
        "positive",
    )
    box: tuple[float, float, float, float] | None = _opt(
        None,
        "Background box XMIN,YMIN,XMAX,YMAX (must contain the contour). "
        "Default: the contour's bounding box grown by --margin.",
        "box",
    )
    margin: float | None = _opt(
        None,
        "Gap between the contour's bounding box and the background box, in "
        "contour units. Default: 3 grid steps.",
        "positive",
    )
    strict: bool = _opt(
        False,
        "Fail instead of adding boundary nodes where consecutive contour points "
        "select grid nodes that are not neighbours.",
        "flag",
    )
    max_nodes: int = _opt(
        DEFAULT_MAX_NODES,
        "Refuse grids with more nodes than this (memory guard).",
        "count",
        min=4,
        max=MAX_NODES_CEILING,
    )
    exterior: bool = _opt(
        False,
        "Mesh the box minus the contour (e.g. an airfoil in a far-field box). "
        "Default margin: the contour's larger extent.",
        "flag",
    )
    grid: str = _opt(
        "auto",
        "'graded': a quadtree grid whose cells follow the contour's spacing and its "
        "thin parts and grow away from it; the boundary nodes are exactly the given "
        "points; 'uniform': Appendix A's grid of one step (extra boundary nodes where "
        "consecutive points take grid nodes that are not neighbours); 'auto': graded, "
        "or uniform with --h.",
        "choice",
        choices=GRIDS,
    )
    growth: float = _opt(
        DEFAULT_GROWTH,
        "Graded grid: how fast cells grow away from the contour (a cell at distance d "
        "from a point of local size s is at most s + (GROWTH - 1) d wide).",
        "positive",
    )
    max_h: float | None = _opt(
        None,
        "Largest mesh size: contour edges longer than H are split into equal pieces "
        "(new boundary nodes after the given points) and no grid cell is larger. "
        "Default: the given points are the boundary; cells as large as the box allows.",
        "positive",
        metavar="H",
    )
    periodic: tuple[float, float] | None = _opt(
        None,
        "Pair every boundary node p with the boundary node at p + (DX, DY), if any (the "
        "mesh is periodic there); with --exterior and the box's height (0,H) or width "
        "(W,0), the opposite box sides get matching nodes. Refused when it pairs no "
        "boundary edge with another.",
        "vector",
    )
    # stage 2: deform
    steps: int = _opt(DEFAULT_STEPS, _STEPS_HELP, "count", min=1, max=MAX_STEPS)
    solver: str = _opt("auto", _SOLVER_HELP, "choice", choices=SOLVERS)
    solve: str = _opt(
        "band",
        "Deform only a narrow band of cells around the path ('band': at least 4 cells, "
        "3 times the farthest path node's travel) or the whole background grid ('full').",
        "choice",
        choices=SOLVES,
    )
    size: str | None = _opt(
        None,
        "Size function f: cells end with areas proportional to f. An expression "
        "in x, y and d (distance to the contour), e.g. '0.2 + d': numbers, arithmetic, "
        "comparisons and the functions listed in docs/method.md.",
        metavar="EXPR",
    )
    size_field: str | None = _opt(
        None,
        "Size function as values on a regular grid: rows x, y, f (CSV or .npy).",
        "path",
    )
    # stage 3: triangulate
    improve: bool = _opt(
        True,
        "Better triangles: around every triangle under 35 degrees, flip edges, move "
        "free nodes and, where that cannot help (a thin part, a sharp corner), re-mesh a "
        "few triangles around one node, while the smallest angle grows (boundary nodes "
        "never move).",
        "switch",
    )
    merge_extra: str = _opt(
        "auto",
        "Extra boundary nodes (where the grid path needed nodes between two consecutive "
        "contour points): 'merge' takes them out (the triangles around each run are "
        "meshed again with the contour edge), 'keep' keeps them; 'auto' keeps them on the "
        "uniform grid (--grid uniform or --h, the paper's form) and takes them out on "
        "the graded one.",
        "choice",
        choices=MERGE_EXTRA,
    )
    cells: str = _opt(
        "tri",
        "Cells: triangles ('tri'); 'quad': pairs of triangles made quads where every "
        "corner of the quad is within 45 degrees of a right angle, chosen over the whole "
        "mesh, triangles elsewhere; 'quad-only': every cell split into quads (a node at "
        "the middle of every edge, the boundary's included; boundary layers are cut "
        "along the wall only, each keeping its height).",
        "choice",
        choices=CELLS,
    )
    # boundary layers
    layers: int = _opt(
        0,
        "Boundary layers: stack this many layers of cells along the walls (--layers-on), "
        "each layer node on the wall normal of a contour point. Needs --first-height. "
        "Default: none.",
        "count",
        min=0,
        max=MAX_LAYERS,
        metavar="N",
    )
    first_height: float | None = _opt(
        None,
        "Boundary layers: the first layer's height, in contour units.",
        "positive",
        metavar="H",
    )
    layer_growth: float = _opt(
        DEFAULT_LAYER_GROWTH,
        "Boundary layers: each layer this many times the one below (at least 1).",
        "positive",
        metavar="R",
    )
    layers_on: str | None = _opt(
        None,
        "Boundary layers: the boundary groups that are walls, comma-separated "
        "(contour, contour_2, hole_1, ...). Default: every ring; never the box's sides.",
        metavar="GROUPS",
    )
    layer_cells: str = _opt(
        "quad",
        "Boundary layers: cells between layers as quads, or each quad as two triangles.",
        "choice",
        choices=LAYER_CELLS,
    )
    # writing
    fmt: str | None = _opt(
        None,
        "Mesh format. Default: from the output file's extension.",
        "choice",
        choices=tuple(sorted(FORMATS)),
        flag="--format",
    )
    msh_version: str = _opt(
        MSH_VERSIONS[0],
        "Gmsh file version for .msh output (ASCII either way).",
        "choice",
        choices=tuple(sorted(MSH_VERSIONS)),
    )

    def replace(self, **changes: Any) -> MeshOptions:
        """A copy with ``changes`` (field names); an unknown name is a ``TypeError``."""
        return dataclasses.replace(self, **changes)

    def stage(self, name: str) -> dict[str, Any]:
        """The fields one stage reads (``read``, ``select``, ``deform``, ``triangulate``,
        ``write``), as a dict: what a state file records."""
        return {k: getattr(self, k) for k in STAGES[name]}


#: Which fields each stage reads.
STAGES: dict[str, tuple[str, ...]] = {
    "read": ("decimal", "tolerance", "element_id", "stroke", "resample"),
    "select": (
        "h",
        "box",
        "margin",
        "strict",
        "max_nodes",
        "exterior",
        "grid",
        "growth",
        "max_h",
        "periodic",
    ),  # fmt: skip
    "deform": ("steps", "solver", "solve", "size", "size_field"),
    "triangulate": ("improve", "merge_extra", "cells"),
    "layers": ("layers", "first_height", "layer_growth", "layers_on", "layer_cells"),
    "write": ("fmt", "msh_version"),
}


@dataclass(frozen=True, kw_only=True)
class MoveOptions:
    """The options of ``deformesh move``: carrying a mesh along its contour's frames."""

    dt: float = _opt(
        1.0,
        "Time between frames: the .pvd's time step; velocity = displacement / dt.",
        "positive",
    )
    steps: int = _opt(DEFAULT_STEPS, _STEPS_HELP, "count", min=1, max=MAX_STEPS)
    solver: str = _opt("auto", _SOLVER_HELP, "choice", choices=SOLVERS)
    solve: str = _opt(
        "full",
        "Solve on the whole mesh ('full', the paper's scheme) or, on an exterior "
        "mesh, on a band around the contour ('band': faster, but changes of shape "
        "pile up at the band's edge).",
        "choice",
        choices=SOLVES,
    )
    fmt: str = _opt(
        "vtu",
        "Frame format.  Velocity is written where the format has point data (vtu, vtk, xdmf).",
        "choice",
        choices=tuple(sorted(FORMATS)),
        flag="--format",
    )
    decimal: str = _opt(
        ".", "Decimal mark of the frames' CSV numbers.", "choice", choices=(".", ",")
    )
    min_angle: float = _opt(
        DEFAULT_MIN_ANGLE,
        "Floor on each frame's smallest angle, in degrees (a mesh that starts below it, "
        "as its contour forces, is held to its own start): the first frame under it "
        "stops the run, frames before it kept, or is meshed afresh with --remesh. "
        "0: no floor.",
        "float",
    )
    remesh: bool = _opt(
        False,
        "Mesh a frame whose smallest angle falls under --min-angle afresh from its "
        "contour (new triangles from that frame on; the velocity carried over by "
        "linear interpolation) and go on.",
        "flag",
    )


def from_record(cls: type, record: dict) -> Any:
    """An options object from a record (a state file's ``options``): the fields it
    names, lists back to tuples; other keys are ignored."""
    known = fields(cls)
    return cls(
        **{k: tuple(v) if isinstance(v, list) else v for k, v in record.items() if k in known}
    )


def fields(cls: type) -> dict[str, dataclasses.Field]:
    """An options class's fields by name."""
    return {f.name: f for f in dataclasses.fields(cls)}


def flag(f: dataclasses.Field) -> str:
    """The command-line flag of a field (``--max-nodes`` for ``max_nodes``)."""
    return f.metadata.get("flag", "--" + f.name.replace("_", "-"))
