"""Stage 3: keep the deformed triangles inside the domain and renumber.

The domain is what the rings enclose by the even-odd rule (outer boundaries
minus holes, islands in holes again inside), or, for an exterior mesh, the
box minus that.  Inside/outside is decided by topology on the undeformed
grid: the even-odd rule applied to the rings' grid paths, by counting, along
each row of triangle centroids, the path edges crossed (exact: integer
arithmetic in thirds of a cell).  If no kept triangle folded, the kept cells,
whose boundary the path nodes carry onto the rings, map one to one onto the
domain.  Every kept triangle the deformation moved is also
tested by geometry, shapely on its deformed centroid against the rings; one
outside is a contract violation.  (Triangles it did not move are grid cells in
place; the contract check that follows, boundary = contour, no fold, area
conserved, covers them.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from .contour import Contour
from .errors import ContractError
from .geometry import domain, edge_uses, touching
from .mesh import Mesh
from .select import Selection
from .select.uniform import topology_inside  # noqa: F401 (stage 3's inside test)

BOX_SIDES = ("bottom", "right", "top", "left")


@dataclass
class Cut:
    """What stage 3 decides before knowing where the nodes went: which grid triangles
    are kept and how the nodes are renumbered (the mesh's triangles and lines)."""

    inside: np.ndarray  # (grid triangles,) bool
    order: np.ndarray  # mesh node k is grid node order[k]
    triangles: np.ndarray  # (t, 3) in mesh node ids
    lines: np.ndarray
    line_group: np.ndarray
    groups: tuple[str, ...]
    n_contour: int
    n_extra: int
    n_box: int
    edges: tuple | None = None  # geometry.edge_uses(triangles, nodes), when computed


def extract(contour: Contour, sel: Selection, points: np.ndarray) -> Mesh:
    """Cut the mesh of the domain out of the deformed background mesh.

    ``sel`` is the :class:`~deformesh_cli.select.Selection` (grid, triangles,
    ring paths), ``points`` the deformed coordinates of every grid node.
    Node ``k`` of the result is contour point ``k``.
    """
    return place(contour, sel, cut(contour, sel), points)


def cut(contour: Contour, sel: Selection, edges: bool = False) -> Cut:
    """The topological half of :func:`extract`: it needs only the selection, so it can
    run while the deformation does.  ``edges``: also count the edge uses of the kept
    triangles (:func:`~.geometry.edge_uses`, what the contract check needs most)."""
    grid = sel.grid
    tri = sel.triangles()
    path_nodes, path_source, path_ring = sel.path_nodes, sel.path_source, sel.path_ring
    inside = sel.kept_triangles()
    kept = tri[inside]
    m = contour.n
    new_id = np.full(grid.n_nodes, -1, dtype=np.int64)
    on = path_source >= 0
    new_id[path_nodes[on]] = path_source[on]
    extra = path_nodes[~on]
    new_id[extra] = m + np.arange(len(extra))
    nxt = m + len(extra)
    box_ring = np.zeros(0, dtype=np.int64)
    if sel.exterior:
        box_ring = grid.box_ring()
        new_id[box_ring] = nxt + np.arange(len(box_ring))
        nxt += len(box_ring)
    used = np.zeros(grid.n_nodes, dtype=bool)
    used[kept.ravel()] = True
    used[new_id >= 0] = False
    interior = np.flatnonzero(used)
    new_id[interior] = nxt + np.arange(len(interior))
    n_total = nxt + len(interior)
    order = np.empty(n_total, dtype=np.int64)
    order[new_id[new_id >= 0]] = np.flatnonzero(new_id >= 0)
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
        side = np.repeat(np.arange(4), grid.side_edges())
        lines.append(np.column_stack([ring, np.roll(ring, -1)]))
        group.append(contour.n_rings + side)
        names += list(BOX_SIDES)
    triangles = new_id[kept]
    out = Cut(
        inside,
        order,
        triangles,
        np.concatenate(lines),
        np.concatenate(group),
        tuple(names),
        m,
        len(extra),
        len(box_ring),
    )
    if edges:
        out.edges = edge_uses(triangles, n_total)
    return out


def place(
    contour: Contour, sel: Selection, c: Cut, points: np.ndarray, folded: bool = False
) -> Mesh:
    """The mesh of cut ``c`` at the deformed ``points`` (every grid node).

    Every kept triangle the deformation moved is tested by geometry (shapely, its
    deformed centroid against the rings); one whose centroid falls outside the
    domain is a :class:`ContractError`.  The dropped triangles are not tested: on
    the graded grid the deformation leaves them be, and those along the path may
    fold.  ``folded``: the mesh may hold folded or flat triangles, which stage 3
    meshes again (a graded deformation); the kept triangles touching one
    (:func:`.untangle.tangled`) are not tested (:mod:`.untangle`
    mends them, and the contract check holds the mended mesh).
    """
    grid, tri = sel.grid, sel.triangles()
    g = grid.coords()
    moved = (points[:, 0] != g[:, 0]) | (points[:, 1] != g[:, 1])
    tested = touching(moved, tri) & c.inside
    if folded:
        from .untangle import tangled

        kept = tri[c.inside]
        near_fold = np.zeros(len(points), dtype=bool)
        near_fold[kept[tangled(points, kept)].ravel()] = True
        tested &= ~touching(near_fold, tri)
    near = np.flatnonzero(tested)
    rings = [contour.points[contour.ring_order(r)] for r in range(contour.n_rings)]
    cen = _centroids(points, tri[near])
    box = grid.box if sel.exterior else None
    geometric = shapely.contains_xy(domain(rings, box), cen[:, 0], cen[:, 1])
    if not geometric.all():
        t = int(np.argmin(geometric))
        x, y = cen[t]
        raise ContractError(
            f"{contour.source}: inside/outside disagree near ({x:.6g}, {y:.6g}): the "
            "deformed mesh is not a faithful image of the grid there"
        )
    return Mesh(
        points[c.order],
        c.triangles,
        c.lines,
        n_contour=c.n_contour,
        n_extra=c.n_extra,
        line_group=c.line_group,
        groups=c.groups,
        n_box=c.n_box,
    )


def _centroids(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Triangle centroids (a third of the corner sum; ``points[tri].mean`` is 3x slower)."""
    return (points[tri[:, 0]] + points[tri[:, 1]] + points[tri[:, 2]]) / 3.0
