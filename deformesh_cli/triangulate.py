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
from functools import reduce

import numpy as np
import shapely

from .contour import Contour
from .errors import ContractError, SelectionError
from .geometry import edge_uses, touching
from .mesh import Mesh
from .select import DIAG_SLASH, Grid, Selection

BOX_SIDES = ("bottom", "right", "top", "left")


def domain(rings: list[np.ndarray], box: tuple | None = None) -> shapely.Geometry:
    """Shapely geometry of the region the rings enclose (even-odd), or ``box`` minus it."""
    polys = [shapely.Polygon(r) for r in rings]
    inside = reduce(shapely.symmetric_difference, polys)
    if box is None:
        return inside
    return shapely.box(*box).difference(inside)


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


def topology_inside(
    grid: Grid, diagonals: np.ndarray, path_nodes: np.ndarray, path_ring: np.ndarray, n_rings: int
) -> np.ndarray:
    """Whether each grid triangle (in :func:`~.select.grid_triangles` order) lies inside
    the rings' grid paths by the even-odd rule.

    In units of a third of a cell, triangle centroids sit at ``(3i + a, 3j + b)``
    with ``a, b`` in {1, 2}: two rows of centroids per row of cells, and no
    centroid on a grid line.  A path step (8-neighbour, between grid nodes)
    crosses each centroid row it spans at an integer abscissa; the parity of
    the crossings left of a centroid says inside.  A crossing can only land on
    a centroid if a diagonal step crosses a cell split the other way, which
    the selection never builds (checked: ``ValueError``).
    """
    nx, ny = grid.nx, grid.ny
    width = 3 * nx + 1
    toggles = np.zeros((2 * ny, width), dtype=np.uint8)
    for r in range(n_rings):
        i, j = grid.node_ij(path_nodes[path_ring == r])
        i1, j1 = np.roll(i, -1), np.roll(j, -1)
        di, dj = i1 - i, j1 - j
        if (np.maximum(np.abs(di), np.abs(dj)) != 1).any():
            raise SelectionError("a ring's grid path has a step that is not to an 8-neighbour")
        cross = dj != 0
        i, j, di, dj = i[cross], j[cross], di[cross], dj[cross]
        jmin = np.minimum(j, j + dj)
        for b in (1, 2):  # the lower and the upper centroid row of cell row jmin
            x = 3 * i + (3 * jmin + b - 3 * j) * di * dj
            row = 2 * jmin + b - 1
            slash = diagonals[jmin * nx + np.minimum(x // 3, nx - 1)] == DIAG_SLASH
            # the centroid of row b in cell x // 3 sits at a = 2 (b = 1) or 1 (b = 2) when
            # the cell is split '/', else at a = b
            a = np.where(slash, 3 - b, b)
            if ((x % 3 != 0) & (x % 3 == a)).any():
                raise SelectionError("a diagonal path step crosses its cell's split")
            np.bitwise_xor.at(toggles, (row, x), 1)
    parity = np.bitwise_xor.accumulate(toggles, axis=1)
    cells = np.arange(nx * ny)
    ci, cj = cells % nx, cells // nx
    slash = diagonals == DIAG_SLASH
    out = np.empty(2 * len(cells), dtype=bool)
    # first triangle of a cell: centroid row b = 1, at a = 2 ('/') or 1; second: b = 2
    out[0::2] = parity[2 * cj, 3 * ci + np.where(slash, 2, 1)]
    out[1::2] = parity[2 * cj + 1, 3 * ci + np.where(slash, 1, 2)]
    return out


def _centroids(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Triangle centroids (a third of the corner sum; ``points[tri].mean`` is 3x slower)."""
    return (points[tri[:, 0]] + points[tri[:, 1]] + points[tri[:, 2]]) / 3.0
