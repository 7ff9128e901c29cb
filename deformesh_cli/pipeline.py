"""The three stages chained: contour -> selection -> deformation -> mesh.

Each stage function here is what one subcommand runs; :func:`mesh_contour`
is what ``deformesh all`` runs.  Nothing here prints or exits.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import deform as _deform
from . import quality, triangulate
from . import size as _size
from .contour import Contour
from .deform import DEFAULT_STEPS, DeformStats
from .mesh import Mesh
from .select import DEFAULT_MAX_NODES, Selection, select
from .size import SizeFunction


@dataclass
class Deformed:
    """Stage 2 output: the selection plus the deformed node coordinates."""

    selection: Selection
    points: np.ndarray
    stats: DeformStats | None = None


@dataclass
class MeshResult:
    mesh: Mesh
    selection: Selection
    deform_stats: DeformStats | None
    report: dict = field(default_factory=dict)


def run_select(contour: Contour, h=None, box=None, margin=None, strict=False,
               max_nodes=DEFAULT_MAX_NODES, exterior=False) -> Selection:
    return select(contour, h=h, box=box, margin=margin, strict=strict, max_nodes=max_nodes,
                  exterior=exterior)


def run_deform(contour: Contour, sel: Selection, steps: int = DEFAULT_STEPS,
               callback=None, solver: str = "auto", size: SizeFunction | None = None) -> Deformed:
    """Stage 2.  ``size`` (as given; normalised here over the grid's box) shapes the cells."""
    grid = sel.grid
    pts0 = grid.coords()
    tri = sel.triangles()
    if size is not None:
        size.normalise(grid.box)
    pos, st = _deform.deform(
        pts0, tri, sel.path_nodes, sel.path_targets, grid.boundary_nodes(),
        steps=steps, callback=callback, describe=_describer(contour, sel), solver=solver,
        size=None if size is None else _size.SizePath(size.g1, grid.box),
    )
    return Deformed(sel, pos, st)


def _describer(contour: Contour, sel: Selection):
    src = sel.path_source
    nodes = sel.path_nodes

    def describe(tri_nodes) -> str:
        hit = np.flatnonzero(np.isin(nodes, tri_nodes) & (src >= 0))
        if len(hit) == 0:
            return ""
        return f" (by contour {contour.where(int(src[hit[0]]))})"

    return describe


def run_triangulate(contour: Contour, d: Deformed,
                    size: SizeFunction | None = None) -> tuple[Mesh, dict]:
    sel = d.selection
    mesh = triangulate.extract(contour, sel, d.points)
    quality.check_contract(mesh, contour, sel.grid.box if sel.exterior else None)
    report = quality.stats(mesh)
    report["contract"] = "ok"
    if size is not None:
        report["size"] = size.label
        rho = _size.spearman(mesh.points, mesh.triangles, size, exclude=mesh.lines.ravel())
        report["size_correlation"] = None if np.isnan(rho) else rho
    return mesh, report


def mesh_contour(contour: Contour, h=None, box=None, margin=None, strict=False,
                 max_nodes=DEFAULT_MAX_NODES, steps=DEFAULT_STEPS, callback=None,
                 solver: str = "auto", exterior: bool = False,
                 size: SizeFunction | None = None) -> MeshResult:
    """Mesh the inside of ``contour`` (or the box minus it, ``exterior``).

    The result meets the contract or this raises.
    """
    sel = run_select(contour, h, box, margin, strict, max_nodes, exterior)
    d = run_deform(contour, sel, steps, callback, solver, size)
    mesh, report = run_triangulate(contour, d, size)
    report.update(selection_report(sel))
    return MeshResult(mesh, sel, d.stats, report)


def selection_report(sel: Selection) -> dict:
    g = sel.grid
    return {
        "h": float(sel.h),
        "h_rule": sel.h_rule,
        "grid": [int(g.nx), int(g.ny)],
        "grid_nodes": int(g.n_nodes),
        "box": [float(v) for v in g.box],
        "searched_further": int(sel.searched_further),
        "refinements": int(sel.refinements),
        "path_rule": sel.path_rule,
        "exterior": bool(sel.exterior),
        "notes": list(sel.notes),
    }
