"""Periodic meshes (``--periodic DX,DY``): boundary nodes paired across a translation.

deformesh keeps the given points as the boundary, so where a contour's points repeat
under a translation (a channel whose inlet and outlet carry the same points, a
cascade passage whose two sides are one curve shifted by the pitch) the mesh's
boundary nodes do too: :func:`pair` finds the pairs.  The far-field box's sides are
made to match by the graded grid (:func:`.select.graded.match_sides`).
"""

from __future__ import annotations

import numpy as np

from .errors import SelectionError
from .mesh import Mesh

#: Two nodes pair when one lies within this fraction of the mesh's extent of the
#: other's translate: the rounding of a shift written in decimal, far below any
#: spacing the graded grid can hold (:data:`.select.graded.MAX_CELLS_ACROSS`).
TOLERANCE = 1e-9


def pair(mesh: Mesh, shift: tuple[float, float], source: str) -> np.ndarray:
    """The periodic pairs of ``mesh`` under ``shift``: ``(k, 2)`` node numbers
    ``(node, partner)``, ``partner`` the boundary node at ``node + shift`` (within
    :data:`TOLERANCE`), sorted by ``node``.

    Only the nodes of *paired edges* count: a boundary edge both of whose ends have a
    partner, and whose partners are joined by a boundary edge too (the sides that
    repeat; a lone node that happens to have one is no side).  Raises
    :class:`SelectionError` when no edge pairs, naming the first boundary point
    without a partner, and when a box side faces the other across the shift but is
    not wholly paired."""
    from scipy.spatial import cKDTree

    pts, lines = mesh.points, mesh.lines
    nodes = np.unique(lines)
    extent = float(np.ptp(pts, axis=0).max()) or 1.0
    tol = TOLERANCE * extent
    d = np.asarray(shift, dtype=np.float64)
    if not float(np.hypot(*d)) > tol:  # (each node would be its own partner)
        raise SelectionError(
            f"{source}: --periodic {shift[0]:g},{shift[1]:g} is shorter than the pairing "
            f"tolerance {tol:.3g} (1e-9 of the mesh's extent {extent:.6g})"
        )
    dist, at = cKDTree(pts[nodes]).query(pts[nodes] + d, distance_upper_bound=tol)
    partner = np.full(mesh.n_nodes, -1, dtype=np.int64)
    has = np.isfinite(dist)
    partner[nodes[has]] = nodes[at[has]]
    back = paired_edges(lines, partner)
    paired = np.zeros(mesh.n_nodes, dtype=bool)
    paired[lines[back].ravel()] = True
    _check_sides(mesh, shift, source, partner, tol)
    if not back.any():
        k = int(nodes[~has][0]) if (~has).any() else int(nodes[0])
        x, y = pts[k]
        raise SelectionError(
            f"{source}: --periodic {shift[0]:g},{shift[1]:g} pairs no boundary edge with "
            f"another: {_name(mesh, k)} ({x:.6g}, {y:.6g}) has no boundary node at "
            f"({x + shift[0]:.6g}, {y + shift[1]:.6g})"
        )
    src = np.flatnonzero(paired)
    return np.column_stack([src, partner[src]])


def paired_edges(lines: np.ndarray, partner: np.ndarray) -> np.ndarray:
    """Per boundary line: both its nodes have a ``partner`` (-1: none), and the partners
    are joined by a boundary line running the other way (the domain lies on the other
    side of it)."""
    n = len(partner)
    a, b = lines[:, 0], lines[:, 1]
    pa, pb = partner[a], partner[b]
    return (pa >= 0) & (pb >= 0) & np.isin(pb * n + pa, a * n + b)


def side_roles(mesh: Mesh) -> np.ndarray | None:
    """Per boundary line of a periodic mesh: 1 on a side whose nodes' partners are
    another side's, 2 on that other side, 0 elsewhere (None: the mesh is not
    periodic)."""
    if not len(mesh.periodic):
        return None
    partner = partner_data(mesh.n_nodes, mesh.periodic).astype(np.int64)
    origin = partner_data(mesh.n_nodes, mesh.periodic[:, ::-1]).astype(np.int64)
    master, slave = paired_edges(mesh.lines, partner), paired_edges(mesh.lines, origin)
    return np.where(master, 1, np.where(slave, 2, 0))


def _check_sides(mesh: Mesh, shift, source: str, partner, tol: float) -> None:
    """A box side facing the opposite side across ``shift`` must be wholly paired."""
    names = list(mesh.groups)
    if "bottom" not in names:
        return
    pts = mesh.points
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    dx, dy = shift
    faces = []
    if abs(dx) <= tol and abs(abs(dy) - (hi[1] - lo[1])) <= tol:
        faces.append("bottom" if dy > 0 else "top")
    if abs(dy) <= tol and abs(abs(dx) - (hi[0] - lo[0])) <= tol:
        faces.append("left" if dx > 0 else "right")
    for side in faces:
        on = np.unique(mesh.lines[mesh.line_group == names.index(side)])
        missing = on[partner[on] < 0]
        if len(missing):
            k = int(missing[0])
            raise SelectionError(
                f"{source}: --periodic {dx:g},{dy:g}: the box side {side}'s node at "
                f"({pts[k, 0]:.6g}, {pts[k, 1]:.6g}) has no node on the opposite side"
            )


def _name(mesh: Mesh, k: int) -> str:
    return f"contour point {k}" if k < mesh.n_contour else f"boundary node {k}"


def partner_data(n: int, pairs: np.ndarray) -> np.ndarray:
    """Per node: its partner (``pairs``), or -1: the ``periodic`` point data."""
    out = np.full(n, -1, dtype=np.int32)
    out[pairs[:, 0]] = pairs[:, 1]
    return out
