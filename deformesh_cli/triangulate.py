"""Stage 3: keep the deformed triangles inside the domain and renumber.

The domain is what the rings enclose by the even-odd rule (outer boundaries
minus holes, islands in holes again inside), or, for an exterior mesh, the
box minus that.  Inside/outside is decided twice and the two must agree: by
shapely on the centroids of the deformed triangles (``contains_xy``) and by
topology on the undeformed grid (the same rule applied to the rings' grid
paths).  If no triangle folded, the deformation is a homeomorphism and the
two coincide (DESIGN.md section 3); a disagreement is a contract violation.
"""

from __future__ import annotations

from functools import reduce

import numpy as np
import shapely

from .contour import Contour
from .errors import ContractError
from .mesh import Mesh

BOX_SIDES = ("bottom", "right", "top", "left")


def domain(rings: list[np.ndarray], box=None):
    """Shapely geometry of the region the rings enclose (even-odd), or ``box`` minus it."""
    polys = [shapely.Polygon(r) for r in rings]
    inside = reduce(shapely.symmetric_difference, polys)
    if box is None:
        return inside
    return shapely.box(*box).difference(inside)


def extract(contour: Contour, sel, points: np.ndarray) -> Mesh:
    """Cut the mesh of the domain out of the deformed background mesh.

    ``sel`` is the :class:`~deformesh_cli.select.Selection` (grid, triangles,
    ring paths), ``points`` the deformed coordinates of every grid node.
    Node ``k`` of the result is contour point ``k``.
    """
    grid = sel.grid
    tri = sel.triangles()
    grid_points = grid.coords()
    path_nodes, path_source, path_ring = sel.path_nodes, sel.path_source, sel.path_ring
    box = grid.box if sel.exterior else None
    rings = [contour.points[contour.ring_order(r)] for r in range(contour.n_rings)]
    grid_rings = [grid_points[path_nodes[path_ring == r]] for r in range(contour.n_rings)]
    cen = _centroids(points, tri)
    inside = shapely.contains_xy(domain(rings, box), cen[:, 0], cen[:, 1])
    cen0 = _centroids(grid_points, tri)
    inside0 = shapely.contains_xy(domain(grid_rings, box), cen0[:, 0], cen0[:, 1])
    if not np.array_equal(inside, inside0):
        t = int(np.argmax(inside != inside0))
        x, y = cen[t]
        raise ContractError(
            f"{contour.source}: inside/outside disagree near ({x:.6g}, {y:.6g}): the "
            "deformed mesh is not a faithful image of the grid there"
        )
    kept = tri[inside]
    m = contour.n
    new_id = np.full(len(points), -1, dtype=np.int64)
    on = path_source >= 0
    new_id[path_nodes[on]] = path_source[on]
    extra = path_nodes[~on]
    new_id[extra] = m + np.arange(len(extra))
    nxt = m + len(extra)
    box_ring = np.zeros(0, dtype=np.int64)
    if sel.exterior:
        box_ring = _box_ring(grid)
        new_id[box_ring] = nxt + np.arange(len(box_ring))
        nxt += len(box_ring)
    used = np.zeros(len(points), dtype=bool)
    used[kept.ravel()] = True
    used[new_id >= 0] = False
    interior = np.flatnonzero(used)
    new_id[interior] = nxt + np.arange(len(interior))
    n_total = nxt + len(interior)
    order = np.empty(n_total, dtype=np.int64)
    order[new_id[new_id >= 0]] = np.flatnonzero(new_id >= 0)
    out = points[order]
    lines, group = [], []
    names = [contour.ring_name(r) for r in range(contour.n_rings)]
    for r in range(contour.n_rings):
        ring = new_id[path_nodes[path_ring == r]]
        e = np.column_stack([ring, np.roll(ring, -1)])
        if contour.is_hole(r) != sel.exterior:  # the domain lies outside this ring
            e = e[::-1, ::-1]
        lines.append(e)
        group.append(np.full(len(e), r))
    if sel.exterior:
        ring = new_id[box_ring]
        side = np.repeat(np.arange(4), [grid.nx, grid.ny, grid.nx, grid.ny])
        lines.append(np.column_stack([ring, np.roll(ring, -1)]))
        group.append(contour.n_rings + side)
        names += list(BOX_SIDES)
    return Mesh(out, new_id[kept], np.concatenate(lines), n_contour=m, n_extra=len(extra),
                line_group=np.concatenate(group), groups=tuple(names), n_box=len(box_ring))


def _centroids(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Triangle centroids (a third of the corner sum; ``points[tri].mean`` is 3x slower)."""
    return (points[tri[:, 0]] + points[tri[:, 1]] + points[tri[:, 2]]) / 3.0


def _box_ring(grid) -> np.ndarray:
    """Grid boundary nodes counter-clockwise from the lower left corner."""
    nx, ny, w = grid.nx, grid.ny, grid.nx + 1
    bottom = np.arange(nx)
    right = nx + np.arange(ny) * w
    top = ny * w + np.arange(nx, 0, -1)
    left = np.arange(ny, 0, -1) * w
    return np.concatenate([bottom, right, top, left])

