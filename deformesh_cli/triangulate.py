"""Stage 3: keep the deformed triangles inside the contour and renumber.

Inside/outside is decided twice and the two must agree: by shapely on the
centroids of the deformed triangles (``contains_xy``) and by topology on the
undeformed grid (a triangle is inside when its centroid is inside the grid
path).  If no triangle folded, the deformation is a homeomorphism and the
two coincide (DESIGN.md section 3); a disagreement is a contract violation.
"""

from __future__ import annotations

import numpy as np
import shapely

from .contour import Contour
from .errors import ContractError
from .mesh import Mesh


def extract(
    contour: Contour,
    grid_points: np.ndarray,
    points: np.ndarray,
    tri: np.ndarray,
    path_nodes: np.ndarray,
    path_source: np.ndarray,
) -> Mesh:
    """Cut the interior mesh out of the deformed background mesh.

    Parameters
    ----------
    contour : the input contour (node ``k`` of the result is its point ``k``).
    grid_points : (N, 2) undeformed coordinates of the background nodes.
    points : (N, 2) deformed coordinates.
    tri : (T, 3) background triangles, counter-clockwise.
    path_nodes, path_source : the counter-clockwise boundary path and, per path
        node, the input index of its contour point (-1 for an extra node).
    """
    poly = shapely.Polygon(contour.ccw_points)
    cen = points[tri].mean(axis=1)
    inside = shapely.contains_xy(poly, cen[:, 0], cen[:, 1])
    grid_poly = shapely.Polygon(grid_points[path_nodes])
    cen0 = grid_points[tri].mean(axis=1)
    inside0 = shapely.contains_xy(grid_poly, cen0[:, 0], cen0[:, 1])
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
    contour_nodes = path_nodes[path_source >= 0]
    new_id[contour_nodes] = path_source[path_source >= 0]
    extra = path_nodes[path_source < 0]
    new_id[extra] = m + np.arange(len(extra))
    used = np.zeros(len(points), dtype=bool)
    used[kept.ravel()] = True
    used[path_nodes] = False
    interior = np.flatnonzero(used)
    new_id[interior] = m + len(extra) + np.arange(len(interior))
    n_total = m + len(extra) + len(interior)
    out = np.empty((n_total, 2))
    order = np.empty(n_total, dtype=np.int64)
    order[new_id[new_id >= 0]] = np.flatnonzero(new_id >= 0)
    out[:] = points[order]
    tris = new_id[kept]
    ring = new_id[path_nodes]
    lines = np.column_stack([ring, np.roll(ring, -1)])
    return Mesh(out, tris, lines, n_contour=m, n_extra=len(extra))
