"""Stage 1 on the graded grid, constructed: one selection for every valid contour.

1. **Sizes from geometry** (:func:`feature_samples`): at each contour point the
   smaller of its two edges and its distance to the nearest contour edge not
   incident to it; along each edge, samples where another part of the contour
   (a non-adjacent edge, or an adjacent one at an acute angle) comes closer than
   the edge's own pieces are long.  Spatial index queries bounded by each
   sample's own length: the cost grows with the samples, never all pairs.
2. **A quadtree that resolves them** (:func:`.graded.build_from`): cells about
   each sample's size, growing by at most ``growth`` away, balanced 2:1, split
   into right isosceles triangles.
3. **The region and its loops** (:func:`region`): the triangles whose centroid
   lies in the domain.  Its boundary, the triangles' edges used once, is a set
   of closed loops of grid edges within one cell of the contour.  A node where
   the region touches itself at a corner only (a pinch) takes the triangles
   around it, so every loop is simple.
4. **Selection** (:func:`_assign`): each contour point takes one of the nearest
   nodes of its ring's loop, in the ring's order (:func:`_monotone`); the loop
   nodes between two consecutive points' nodes are extra boundary nodes, each
   carried to its projection on that contour edge (kept in the loop's order).
   A region triangle whose three nodes all have targets on one contour edge, or
   whose targets would not make a counter-clockwise triangle, would flatten or
   fold: it leaves the region and the loop is laid again.  Where two points take
   one node, or take nodes out of the ring's order, or no loop follows a ring,
   the cells at those points are halved and the grid laid again, at
   most :data:`REFINE_ROUNDS` times (the loop then passes nearer each point
   than half the distance to its neighbours).

The deformation carries every loop node onto its target; stage 3 then takes
the extra boundary nodes out again (:mod:`..recover`), so the boundary nodes of
the mesh are exactly the contour's points.  Sharp empty ears are cut off before
the grid is laid (:func:`cut_ears`) and added back after (:func:`restore_ears`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import shapely

from .._predicates import boxes_meet_segments, segments_meet_triangles
from ..contour import Contour, far_field_box, grown_box
from ..errors import LimitError, OptionError, SelectionError
from ..geometry import boundary_edges, next_on_ring, prev_on_ring, signed_areas, touching
from . import graded
from ._monotone import between_costs, programme
from .boxtree import box_tree
from .nearest import Nearest
from .segments import Segments
from .uniform import DEFAULT_MAX_NODES

#: Band of the deformation on the graded grid: nodes within this many edges of the
#: path (the uniform grid's 4 cells).
BAND_HOPS = 4


@dataclass
class GradedGrid:
    """The graded background as the stages see it: its nodes and its box."""

    tree: graded.Quadtree
    points: np.ndarray  # (n, 2) undeformed node coordinates

    @property
    def n_nodes(self) -> int:
        return len(self.points)

    @property
    def box(self) -> tuple[float, float, float, float]:
        return self.tree.box

    @property
    def nx(self) -> int:
        return self.tree.nx

    @property
    def ny(self) -> int:
        return self.tree.ny

    @property
    def hx(self) -> float:
        return self.tree.hx

    @property
    def hy(self) -> float:
        return self.tree.hy

    def coords(self, nid: np.ndarray | int | None = None) -> np.ndarray:
        return self.points if nid is None else self.points[nid]

    def _sides(self):
        x0, y0, x1, y1 = self.box
        x, y = self.points[:, 0], self.points[:, 1]
        xmax, ymax = x.max(), y.max()  # the box's far sides, as the nodes have them
        return x == x0, x == xmax, y == y0, y == ymax

    def boundary_nodes(self) -> np.ndarray:
        left, right, bottom, top = self._sides()
        return np.flatnonzero(left | right | bottom | top)

    def box_ring(self) -> np.ndarray:
        """The box's nodes counter-clockwise from the lower left corner."""
        left, right, bottom, top = self._sides()
        x, y = self.points[:, 0], self.points[:, 1]
        parts = [
            np.flatnonzero(bottom & ~right)[np.argsort(x[bottom & ~right])],
            np.flatnonzero(right & ~top)[np.argsort(y[right & ~top])],
            np.flatnonzero(top & ~left)[np.argsort(-x[top & ~left])],
            np.flatnonzero(left & ~bottom)[np.argsort(-y[left & ~bottom])],
        ]
        return np.concatenate(parts)

    def side_edges(self) -> tuple[int, int, int, int]:
        left, right, bottom, top = self._sides()
        return (
            int((bottom & ~right).sum()),
            int((right & ~top).sum()),
            int((top & ~left).sum()),
            int((left & ~bottom).sum()),
        )


@dataclass
class GradedSelection:
    """Stage 1's result on the graded grid (the attributes the later stages read, as
    :class:`~deformesh_cli.select.uniform.Selection` has them)."""

    grid: GradedGrid
    path_nodes: np.ndarray
    path_targets: np.ndarray
    path_source: np.ndarray
    path_ring: np.ndarray
    diagonals: np.ndarray  # per leaf
    h: float  # the finest cell
    exterior: bool = False
    notes: list[str] = field(default_factory=list)
    h_rule: str = "graded"
    path_rule: str = "graded"
    searched_further: int = 0
    refinements: int = 0
    #: the deformation may fold triangles near the path; stage 3 meshes them again
    mends_folds: ClassVar[bool] = True
    _triangles: np.ndarray | None = field(default=None, init=False, repr=False)
    _kept: np.ndarray | None = field(default=None, init=False, repr=False)
    _sizes: graded.SizeField | None = field(default=None, init=False, repr=False)

    def size_field(self, contour: Contour, growth: float, max_h, max_nodes, box=None):
        """The size field the grid was laid for without a size function
        (:func:`size_field` of the contour it was laid for and these options, ``box``
        an exterior mesh's: :func:`exterior_box`): stage 3 coarsens the interior to
        it."""
        if self._sizes is None and self.path_rule == OWN_TRIANGLES:
            # (no node but the contour's: nothing to coarsen, no samples to take)
            self._sizes = graded.SizeField(contour.points, contour.edge_lengths(), growth, max_h)
        if self._sizes is None:
            self._sizes = size_field(contour, self.exterior, growth, max_h, max_nodes, box)
        return self._sizes

    @property
    def extra_nodes(self) -> int:
        return int(np.count_nonzero(self.path_source < 0))

    def triangles(self) -> np.ndarray:
        if self._triangles is None:
            self._triangles = self.grid.tree.triangulate(self.diagonals)[1]
        return self._triangles

    def inside_triangles(self) -> np.ndarray:
        """Per triangle: its centroid inside the rings' paths (even-odd); a centroid is
        never on a path, whose steps are triangle edges."""
        tri = self.triangles()
        p = self.grid.points
        cen = (p[tri[:, 0]] + p[tri[:, 1]] + p[tri[:, 2]]) / 3.0
        inside = np.zeros(len(tri), dtype=bool)
        for r in np.unique(self.path_ring):
            ring = shapely.Polygon(p[self.path_nodes[self.path_ring == r]])
            inside ^= shapely.contains_xy(ring, cen[:, 0], cen[:, 1])
        return inside

    def kept_triangles(self) -> np.ndarray:
        """Per triangle: on the domain's side of the paths (:meth:`inside_triangles`,
        or outside them for an exterior mesh)."""
        if self._kept is None:
            inside = self.inside_triangles()
            self._kept = ~inside if self.exterior else inside
        return self._kept

    def held_nodes(self) -> np.ndarray:
        """The nodes the deformation holds where they are: the box's, but for an interior
        mesh those of its loops (its region is bounded by its loops alone, whose nodes
        all go to contour points, also where the coarse cells along a long edge reach the
        box's side)."""
        held = self.grid.boundary_nodes()
        return held if self.exterior else np.setdiff1d(held, self.path_nodes)

    def band_nodes(self) -> np.ndarray | None:
        """Nodes within :data:`BAND_HOPS` edges of the path, or None if half the grid."""
        n = self.grid.n_nodes
        tri = self.triangles()
        on = np.zeros(n, dtype=bool)
        on[self.path_nodes] = True
        for _ in range(BAND_HOPS):  # (one edge further each time: a triangle's corners
            on[tri[touching(on, tri)]] = True  # are its edges' ends)
        return on if on.sum() < 0.5 * n else None


#: The ``path_rule`` of a constructed selection (stage 3 takes every extra node out).
CONSTRUCTED = "graded-loop"

#: Cells next to a contour point measure at most this times its size (its shorter
#: edge, or its distance to another part of the contour): a loop step, a cell's side
#: or diagonal, is then no longer than the points' spacing, so each point has a loop
#: node of its own without halving.  With a size function ``f``, cells elsewhere are
#: at most ``lambda sqrt(f)``, ``lambda`` the median over the points of this times
#: their size over ``sqrt(f)``.
CELL_FACTOR = 2.0**-0.5

#: Cells along an edge measure about this times the clearance there (the distance to
#: the nearest other part of the contour): the loops of two parts stay apart.
CLEARANCE_FACTOR = 0.5

#: The cells of a ring the domain surrounds (a hole; for an exterior mesh, every
#: ring) are at most its length over this: the loop closes round it with at least
#: about this many nodes, however few its points (a small hole of three).
RING_CELLS = 16

#: Rounds of mending pinches (each takes in or gives up every pinch's triangles at once).
PINCH_ROUNDS = 64

#: Times the cells at points that took one node, or nodes out of order, are halved.
REFINE_ROUNDS = 8

#: Edges shorter than this fraction of the contour's extent are not bisected further.
FLOOR = 1e-9


#: Another part of the contour: a point ``y`` that the contour reaches from ``x`` only
#: after more than this times ``|x - y|`` along it (it turned back), or on another ring.
TURN = 2.0


def feature_samples(
    contour: Contour,
    max_nodes: int | None = None,
    exterior: bool = False,
    box: tuple[float, float, float, float] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(points, sizes, point_sizes, edge)``: where the cells must be how small, and
    the contour point (for an edge's sample, the edge's first point) each belongs to.

    ``point_sizes[k]`` is contour point ``k``'s size: the smaller of its two edges
    and its clearance (on a ring the domain surrounds, also its ring's length over
    :data:`RING_CELLS`), its distance to another part of the contour (:data:`TURN`)
    across the domain (on the domain's side of the point: the two sides of a thin
    part, a hole near the outline).  ``points`` and ``sizes`` are those points and
    sizes followed by samples along the edges: each edge is bisected while a piece
    is longer than the clearance at its middle, except a piece at an end no longer
    than that end's point size.  A sample's size is :data:`CLEARANCE_FACTOR` times
    its clearance, at most its piece's length.  A thin gap of the outside (a slot,
    two parts a hair apart) asks for no small cells: the region keeps its two sides
    apart (:func:`across_gaps`, :func:`bridges`).  ``box``: the sides of an exterior
    mesh's box, another part of the boundary, whose distance counts as a clearance
    like the contour's own (so the loops stay off the box).  More samples than ``max_nodes``
    (each asks for a cell of its own) is a :class:`LimitError`.
    """
    p = contour.points
    m = contour.n
    ring = contour.ring
    nxt = next_on_ring(ring)
    prv = prev_on_ring(contour.ring)
    a, b = p, p[nxt]
    length = contour.edge_lengths()
    segments, arc, perimeter = contour_segments(contour)
    # the directions forward and back along the contour with the domain on the left:
    # at each point, and along each edge
    dom_next, dom_prev = _domain_walk(contour, exterior)
    at_point = (p[dom_next] - p, p[dom_prev] - p)
    along_edge = np.where((dom_next == nxt)[:, None], b - a, a - b)
    along_edge = (along_edge, -along_edge)
    # point sizes: the shorter edge, and another part of the contour within it
    surrounded = np.array([contour.is_hole(r) != exterior for r in range(contour.n_rings)])
    s = np.minimum(length, length[prv])
    s = np.where(surrounded[ring], np.minimum(s, perimeter[ring] / RING_CELLS), s)
    own = np.column_stack([np.arange(m), prv])
    s = np.minimum(s, segments.clearance(p, arc, ring, own, at_point, s, TURN))
    if box is not None:
        s = np.minimum(s, _to_box(p, box))
    floor = FLOOR * float(np.ptp(p, axis=0).max())
    seg = np.arange(m)
    t0 = np.zeros(m)
    t1 = np.ones(m)
    out_xy, out_size, out_edge = [p], [s], [np.arange(m)]
    count = m
    while len(seg):
        if max_nodes is not None and count + len(seg) > max_nodes:
            k = int(seg[0])
            raise LimitError(
                f"{contour.source}: its thin parts ask for more than {max_nodes:,} cells "
                f"(near {contour.where(k)}); raise --max-nodes"
            )
        ell = (t1 - t0) * length[seg]
        tm = (t0 + t1) / 2
        mid = a[seg] + tm[:, None] * (b[seg] - a[seg])
        # (within twice the piece's length: a piece short enough not to split still
        # learns the clearance its parent was split for)
        x_arc = arc[seg] + tm * length[seg]
        own = np.column_stack([seg, seg])  # (an adjacent edge counts where it turned back)
        wedge = (along_edge[0][seg], along_edge[1][seg])
        c = segments.clearance(mid, x_arc, ring[seg], own, wedge, 2 * ell, TURN)
        if box is not None:
            c = np.minimum(c, _to_box(mid, box))
        end_size = np.minimum(
            np.where(t0 == 0, s[seg], np.inf), np.where(t1 == 1, s[nxt[seg]], np.inf)
        )
        end_size[np.isinf(end_size)] = 0.0  # (a piece inside an edge stops at c alone)
        split = (ell > c) & (ell > end_size) & (ell > floor)
        done = ~split & np.isfinite(c)
        count += int(done.sum())
        out_xy.append(mid[done])
        out_size.append(np.minimum(ell[done], CLEARANCE_FACTOR * c[done]))
        out_edge.append(seg[done])
        seg, t0, t1, tm = seg[split], t0[split], t1[split], tm[split]
        seg = np.repeat(seg, 2)
        t0, t1 = np.column_stack([t0, tm]).ravel(), np.column_stack([tm, t1]).ravel()
    return np.concatenate(out_xy), np.concatenate(out_size), s, np.concatenate(out_edge)


def contour_segments(contour: Contour) -> tuple[Segments, np.ndarray, np.ndarray]:
    """``(segments, arc, perimeter)``: the contour's edges (edge ``k`` from point ``k`` to
    the next on its ring) ready for clearance queries, how far along its ring each
    starts, and each ring's length."""
    ring, length = contour.ring, contour.edge_lengths()
    p = contour.points
    starts = np.asarray(contour.starts)
    run = np.cumsum(length)
    arc = run - length - np.concatenate([[0.0], run])[starts[:-1]][ring]  # along its ring
    perimeter = np.add.reduceat(length, starts[:-1])
    return Segments(p, p[next_on_ring(ring)], arc, length, ring, perimeter), arc, perimeter


def _to_box(q: np.ndarray, box: tuple[float, float, float, float]) -> np.ndarray:
    """Each point's distance to the nearest side of ``box`` (it lies inside)."""
    return np.minimum(
        np.minimum(q[:, 0] - box[0], box[2] - q[:, 0]),
        np.minimum(q[:, 1] - box[1], box[3] - q[:, 1]),
    )


def region(
    tri: np.ndarray,
    inside: np.ndarray,
    n: int,
    fixed: np.ndarray,
    banned: np.ndarray,
    in_domain: np.ndarray,
):
    """``inside`` without pinches (a node with two or more region edges leaving it):
    a pinch node inside the domain (``in_domain``) takes the triangles around it
    (a neck of the domain thinner than the cells), one outside it gives up its
    region triangles (two parts of the domain across a gap thinner than the
    cells).  Triangles taken in are not given up, nor ``banned`` ones or ones of
    ``fixed`` nodes only taken in, so this ends.  Returns the region and its
    boundary's next node per node (-1 off the boundary)."""
    inside = inside.copy()
    banned = banned.copy()
    taken = np.zeros(len(tri), dtype=bool)
    for _ in range(PINCH_ROUNDS):
        e = boundary_edges(tri[inside], n)
        e = e[~(fixed[e[:, 0]] & fixed[e[:, 1]])]  # (the box's sides are not a loop)
        out = np.bincount(e[:, 0], minlength=n)
        pinch = out > 1
        if not pinch.any():
            nxt = np.full(n, -1, dtype=np.int64)
            nxt[e[:, 0]] = e[:, 1]
            return inside, nxt
        fill = np.zeros(n, dtype=bool)
        fill[pinch & in_domain] = True
        cut = pinch & ~in_domain
        add = fill[tri].any(axis=1) & ~inside & ~banned & ~fixed[tri].all(axis=1)
        drop = cut[tri].any(axis=1) & inside & ~taken
        if not (add.any() or drop.any()):
            raise _Pinch(np.flatnonzero(pinch))
        inside |= add
        taken |= add
        inside &= ~drop
        banned |= drop
    raise _Pinch(np.flatnonzero(pinch))


def _loops(nxt: np.ndarray) -> list[np.ndarray]:
    """The closed loops of the successor map ``nxt`` (each from its smallest node)."""
    seen = nxt < 0
    loops = []
    for start in np.flatnonzero(~seen):
        if seen[start]:
            continue
        loop = [start]
        seen[start] = True
        v = nxt[start]
        while v != start:
            if seen[v]:
                raise SelectionError("the region's boundary is not a set of closed loops")
            loop.append(v)
            seen[v] = True
            v = nxt[v]
        loops.append(np.array(loop, dtype=np.int64))
    return loops


def select_constructed(
    contour: Contour,
    box: tuple[float, float, float, float] | None = None,
    margin: float | None = None,
    exterior: bool = False,
    growth: float = graded.DEFAULT_GROWTH,
    max_nodes: int | None = None,
    max_h: float | None = None,
    size_function=None,
    periodic: tuple[float, float] | None = None,
) -> GradedSelection:
    """The graded grid laid for ``contour`` and each ring's loop fitted to its points
    (the module's steps).  ``periodic``: on an exterior mesh, a translation by the
    box's height ``(0, H)`` or width ``(W, 0)`` cuts the opposite sides alike
    (:func:`.graded.match_sides`).  ``size_function`` (a :class:`~..size.SizeFunction`): the
    cells also follow it, at most ``lambda sqrt(f)`` wide, ``lambda`` the median over
    the contour's points of :data:`CELL_FACTOR` times their size over ``sqrt(f)``."""
    if not exterior and thin_triangles(contour):
        return own_triangles(contour)
    prv = prev_on_ring(contour.ring)
    lo, hi = contour.points.min(axis=0), contour.points.max(axis=0)
    given = box is not None
    if exterior:  # (the box is part of the domain's boundary: the sizes see its sides)
        box = exterior_box(contour, box, margin)
        xy, size, s, edge, field = _wanted(contour, True, max_nodes, size_function, box)
    else:  # (the background only: at least the room for the loop around the contour)
        xy, size, s, edge, field = _wanted(contour, False, max_nodes, size_function)
        room = 3.0 * float(s.max())
        if box is None:
            margin = room if margin is None else max(margin, room)
            box = grown_box(contour, lo, hi, margin)
        else:
            box = _checked_box(contour, box, False)
            box = (min(box[0], lo[0] - room), min(box[1], lo[1] - room),
                   max(box[2], hi[0] + room), max(box[3], hi[1] + room))  # fmt: skip
    wrap = _wrap(box, periodic) if exterior else None
    factor = np.full(len(xy), CELL_FACTOR)
    crowded = None
    sizes = None  # (the coarsening's, with no size function)
    for _ in range(REFINE_ROUNDS + 1):
        tree, laid_for = graded.build_from(
            xy, size * factor, box, growth, max_h, given, max_nodes, field=field, wrap=wrap
        )
        if sizes is None:  # (the first: every point at CELL_FACTOR)
            sizes = laid_for
        try:
            sel = _select_on(contour, tree, exterior, s)
            sel._sizes = sizes if size_function is None else None
            return sel
        except _Crowded as exc:
            crowded = exc.points
            # the points' cells, and the cells along their edges
            factor[np.isin(edge, np.concatenate([crowded, prv[crowded]]))] /= 2.0
    raise SelectionError(
        f"{contour.source}: contour points still share grid nodes after halving their "
        f"cells {REFINE_ROUNDS} times, near {contour.where(int(crowded[0]))}"
    )


#: A periodic translation matches a box side when within this fraction of the box's
#: extent of it (as :data:`..periodic.TOLERANCE`).
WRAP_TOLERANCE = 1e-9


def _wrap(box, periodic) -> tuple[bool, bool] | None:
    """Which opposite sides of an exterior ``box`` the translation ``periodic`` maps
    onto each other: ``(left and right, bottom and top)``."""
    if periodic is None:
        return None
    w, h = box[2] - box[0], box[3] - box[1]
    tol = WRAP_TOLERANCE * max(w, h)
    dx, dy = periodic
    return (abs(dy) <= tol and abs(abs(dx) - w) <= tol, abs(dx) <= tol and abs(abs(dy) - h) <= tol)


def thin_triangles(contour: Contour) -> bool:
    """Every ring is a triangle (three points, none inside another) with a side forced
    under :data:`THIN_ANGLE` and its angles at least :data:`EAR_SHARE` of that bound: what
    a thin part's ears leave (:func:`cut_ears`), or a thin triangle given as it is.  Its
    triangle is then the mesh: the grid would resolve its width along its length."""
    from ..forced import edge_angles
    from ..geometry import domain
    from ..quality import measures

    if contour.n != 3 * contour.n_rings or any(contour.depth):
        return False
    nxt, _ = _domain_walk(contour, False)
    lines = np.column_stack([np.arange(contour.n), nxt])
    p = contour.points
    geom = domain([p[contour.ring_order(r)] for r in range(contour.n_rings)])
    bound = edge_angles(p, lines, geom).reshape(contour.n_rings, 3).min(axis=1)
    smallest = measures(p, lines[:, 0].reshape(contour.n_rings, 3))[0]
    return bool(((bound < THIN_ANGLE) & (smallest >= EAR_SHARE * bound)).all())


def own_triangles(contour: Contour) -> GradedSelection:
    """The selection whose mesh is each ring's own triangle (:func:`thin_triangles`): a
    row of root cells, ring ``r``'s points the corners of the lower triangle of cell
    ``2 r`` (no two rings share a node), nothing else kept.  The deformation moves those
    corners onto the points (every node of a kept triangle a path node), and the stages
    after it run as on any graded grid."""
    rings = contour.n_rings
    lo, hi = contour.points.min(axis=0), contour.points.max(axis=0)
    nx = 2 * rings - 1
    h = float(max((hi - lo).max(), np.finfo(float).tiny)) / nx
    tree = graded.Quadtree(
        float(lo[0]), float(lo[1]), h, h, 0, nx, 1,
        np.zeros(nx, np.int64), np.arange(nx, dtype=np.int64), np.zeros(nx, np.int64),
    )  # fmt: skip
    diagonals = np.zeros(nx, dtype=np.uint8)
    points, tri, cell = tree.triangulate(diagonals)
    nxt, _ = _domain_walk(contour, False)
    nodes, targets, source, ring = [], [], [], []
    for r in range(rings):
        corners = tri[np.flatnonzero(cell == 2 * r)[0]]  # (counter-clockwise)
        k = int(contour.starts[r])
        order = [k, int(nxt[k]), int(nxt[nxt[k]])]  # (the domain on the left)
        nodes.append(corners)
        targets.append(contour.points[order])
        source.append(order)
        ring.append([r, r, r])
    sel = GradedSelection(
        GradedGrid(tree, points),
        np.concatenate(nodes).astype(np.int64),
        np.concatenate(targets),
        np.concatenate(source).astype(np.int64),
        np.concatenate(ring).astype(np.int64),
        diagonals,
        h,
        path_rule=OWN_TRIANGLES,
    )
    sel.notes.append(
        f"{rings} thin triangle(s), each meshed as itself: a grid could add only slivers along them"
    )
    return sel


#: The ``path_rule`` of :func:`own_triangles`' selection.
OWN_TRIANGLES = "own-triangles"


def _wanted(contour: Contour, exterior: bool, max_nodes: int | None, size_function, box=None):
    """:func:`feature_samples` of ``contour`` (``box``: an exterior mesh's), and the
    cells' size field of the size function (None without one)."""
    xy, size, s, edge = feature_samples(contour, max_nodes or DEFAULT_MAX_NODES, exterior, box)
    field = None
    if size_function is not None:
        at = np.sqrt(size_function.values(contour.points))
        scale = float(np.median(CELL_FACTOR * s / at))
        field = lambda q: scale * np.sqrt(size_function.values(q))  # noqa: E731
    return xy, size, s, edge, field


def exterior_box(contour: Contour, box, margin) -> tuple[float, float, float, float]:
    """The box an exterior mesh of ``contour`` is laid in: ``box`` as given (checked),
    or the far field at ``margin``."""
    return _checked_box(contour, far_field_box(contour, margin) if box is None else box, True)


def size_field(
    contour: Contour,
    exterior: bool = False,
    growth: float = graded.DEFAULT_GROWTH,
    max_h: float | None = None,
    max_nodes: int | None = None,
    box: tuple[float, float, float, float] | None = None,
) -> graded.SizeField:
    """The size field :func:`select_constructed` lays the grid for with no size
    function, every point's cells at :data:`CELL_FACTOR` times its size (before any is
    halved for a crowded point); ``box``: an exterior mesh's (:func:`exterior_box`),
    whose sides count as the contour's do."""
    xy, size, _, _, _ = _wanted(contour, exterior, max_nodes, None, box if exterior else None)
    s = graded.graded_sizes(xy, size * CELL_FACTOR, growth)
    return graded.SizeField(xy, s, growth, max_h)


def _checked_box(contour: Contour, box, exterior: bool) -> tuple[float, float, float, float]:
    """A given ``--box``, checked (:func:`.uniform.checked_box`) and, for an exterior
    mesh, with every point strictly inside (the mesh is the box minus the contour: a
    point on the box's side would split it)."""
    from .uniform import _fmt_box, checked_box

    box = checked_box(contour, box)
    p = contour.points
    gap = np.minimum(
        np.minimum(p[:, 0] - box[0], box[2] - p[:, 0]),
        np.minimum(p[:, 1] - box[1], box[3] - p[:, 1]),
    )
    k = int(np.argmin(gap))
    if exterior and gap[k] <= 0:
        raise OptionError(
            f"{contour.source}: {contour.where(k)} is on the side of the box {_fmt_box(box)}; "
            "an exterior mesh needs room around the contour: give a larger --box or --margin"
        )
    return box


def _target_edges(n: int, nodes, ring, source) -> np.ndarray:
    """Per grid node, the two contour edges its target lies on, each named by the
    contour point it starts from along the loop (an extra node's twice; -1, -2 for a
    node without a target, on no edge)."""
    out = np.column_stack([np.full(n, -1), np.full(n, -2)])
    for r in np.unique(ring):
        at = np.flatnonzero(ring == r)
        src = source[at]
        is_point = src >= 0
        # the last point at or before each node along the loop (wrapping round)
        idx = np.where(is_point, np.arange(len(at)), -1)
        last = np.maximum.accumulate(idx)
        last[last < 0] = np.flatnonzero(is_point)[-1]
        own = src[last]
        prev_point = np.roll(src[is_point], 1)  # each point's previous point
        before = own.copy()
        before[is_point] = prev_point
        out[nodes[at], 0] = own
        out[nodes[at], 1] = before
    return out


def _on_one_edge(edges: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Per triangle: its three nodes' targets share a contour edge (:func:`_target_edges`)."""
    a, b, c = edges[tri[:, 0]], edges[tri[:, 1]], edges[tri[:, 2]]
    out = np.zeros(len(tri), dtype=bool)
    for k in (0, 1):
        e = a[:, k]
        out |= (e >= 0) & ((b == e[:, None]).any(axis=1)) & ((c == e[:, None]).any(axis=1))
    return out


def _arcs(contour: Contour) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(arc, length, perimeter)``: where each edge starts along its ring, its length,
    and each ring's length."""
    length = contour.edge_lengths()
    starts = np.asarray(contour.starts)
    run = np.cumsum(length)
    arc = run - length - np.concatenate([[0.0], run])[starts[:-1]][contour.ring]
    return arc, length, np.add.reduceat(length, starts[:-1])


def _to_segment(x: np.ndarray, a: np.ndarray, b: np.ndarray):
    """``(distance, parameter)`` of the nearest point of the segment ``a b`` to each
    ``x`` (the point ``a + parameter (b - a)``)."""
    ab = b - a
    ll = np.einsum("ij,ij->i", ab, ab)
    t = np.clip(np.einsum("ij,ij->i", x - a, ab) / np.where(ll > 0, ll, 1.0), 0.0, 1.0)
    y = a + t[:, None] * ab
    return np.hypot(*(x - y).T), t


def across_gaps(
    contour: Contour,
    points: np.ndarray,
    tri: np.ndarray,
    cell: np.ndarray,
    pairs: tuple[np.ndarray, np.ndarray],
    dom,
    exterior: bool,
) -> np.ndarray:
    """Per triangle (counter-clockwise, sorted by their leaf ``cell``):
    it meets two other parts of the contour with the outside between them, so it
    spans a gap of the outside narrower than itself (a slot, two parts a hair
    apart).  Of the pieces of two contour edges inside it, a pair of points (their
    ends, or their nearest points) are other parts where the contour joins them
    only over more than :data:`TURN` times their distance, with the outside between
    them where their middle is not in the domain.  ``pairs``: :func:`leaf_edges`."""
    out = np.zeros(len(tri), dtype=bool)
    leaf, seg = pairs
    if not len(leaf) or not len(tri):
        return out
    first = np.searchsorted(cell, np.arange(int(max(cell.max(), leaf.max())) + 2))
    count = first[leaf + 1] - first[leaf]
    t = (
        np.repeat(first[leaf], count)
        + np.arange(count.sum())
        - np.repeat(np.cumsum(count) - count, count)
    )
    e = np.repeat(seg, count)
    p = contour.points
    nxt = next_on_ring(contour.ring)
    a, ab = p[e], p[nxt[e]] - p[e]
    lo, hi = np.zeros(len(t)), np.ones(len(t))
    v = points[tri[t]]
    with np.errstate(divide="ignore", invalid="ignore"):
        for i in range(3):  # (the edge's parameters on the inner side of each side)
            vi, side = v[:, i], v[:, (i + 1) % 3] - v[:, i]
            num = side[:, 0] * (a[:, 1] - vi[:, 1]) - side[:, 1] * (a[:, 0] - vi[:, 0])
            den = side[:, 0] * ab[:, 1] - side[:, 1] * ab[:, 0]
            r = -num / den
            lo = np.where(den > 0, np.maximum(lo, r), lo)
            hi = np.where(den < 0, np.minimum(hi, r), hi)
            hi = np.where((den == 0) & (num < 0), -1.0, hi)
    # (whether they meet, exactly, a touch included (compiled exact predicates); the
    # pieces as round-off has them)
    meet = np.empty(len(t), dtype=np.uint8)
    segments_meet_triangles(points, tri, t, a, a + ab, meet)
    meet = meet.view(bool)
    lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)
    t, e, lo, hi, a, ab = t[meet], e[meet], lo[meet], hi[meet], a[meet], ab[meet]
    order = np.lexsort((e, t))
    t, e, lo, hi, a, ab = t[order], e[order], lo[order], hi[order], a[order], ab[order]
    p0, p1 = a + lo[:, None] * ab, a + hi[:, None] * ab
    arc, length, perimeter = _arcs(contour)
    ring = contour.ring
    hits = []
    for o in range(1, len(t)):
        i = np.flatnonzero(t[o:] == t[:-o])
        if not len(i):
            break
        j, r = i + o, np.arange(len(i))
        ei, ej = e[i], e[j]
        # pairs of points, one on each piece (edge parameters): the four pairs of their
        # ends, and their nearest points
        ends = [_to_segment(p0[i], p0[j], p1[j]), _to_segment(p1[i], p0[j], p1[j]),
                _to_segment(p0[j], p0[i], p1[i]), _to_segment(p1[j], p0[i], p1[i])]  # fmt: skip
        k = np.argmin(np.stack([d for d, _ in ends]), axis=0)
        on = np.stack([u for _, u in ends])[k, r]
        near_i = np.choose(k, [np.zeros(len(i)), np.ones(len(i)), on, on])
        near_j = np.choose(k, [on, on, np.zeros(len(i)), np.ones(len(i))])
        si = np.stack([lo[i], lo[i], hi[i], hi[i], lo[i] + near_i * (hi[i] - lo[i])])
        sj = np.stack([lo[j], hi[j], lo[j], hi[j], lo[j] + near_j * (hi[j] - lo[j])])
        x = a[i] + si[..., None] * ab[i]
        y = a[j] + sj[..., None] * ab[j]
        dist = np.hypot(x[..., 0] - y[..., 0], x[..., 1] - y[..., 1])
        # how far the contour runs from one to the other, the shorter way round
        per = perimeter[ring[ei]]
        run = (arc[ej] + sj * length[ej] - arc[ei] - si * length[ei]) % per
        # two edges with a shared point: both from their distances to it and the angle
        # there (nought apart at that point, whatever round-off does to coordinates)
        after, before = nxt[ei] == ej, nxt[ej] == ei
        ri = np.where(after, 1 - si, si) * length[ei]
        rj = np.where(after, sj, 1 - sj) * length[ej]
        cos = np.einsum("ij,ij->i", ab[i], ab[j]) / (length[ei] * length[ej])
        shared = after | before
        run = np.where(shared, ri + rj, run)
        dist = np.where(shared, np.sqrt(np.maximum(ri**2 + rj**2 + 2 * ri * rj * cos, 0)), dist)
        along = np.where(ring[ei] == ring[ej], np.minimum(run, per - run), np.inf)
        other = along > TURN * dist
        if other.any():
            c, q = np.nonzero(other)
            mid = 0.5 * (x[c, q] + y[c, q])
            gap = shapely.contains_xy(dom, mid[:, 0], mid[:, 1]) == exterior
            hits.append(t[i[q[gap]]])
    if hits:
        out[np.concatenate(hits)] = True
    return out


def bridges(
    tri: np.ndarray, kept: np.ndarray, outside: np.ndarray, segments: shapely.STRtree, points
) -> np.ndarray:
    """Per triangle: a region triangle (``kept``) sharing with another one a side that
    lies wholly outside the domain (its ends ``outside``, meeting no contour edge of
    ``segments``): the two span a gap of the outside between them."""
    t = np.flatnonzero(kept & (outside[tri].sum(axis=1) >= 2))
    out = np.zeros(len(tri), dtype=bool)
    if len(t) < 2:
        return out
    sides = np.sort(np.stack([tri[t][:, [0, 1]], tri[t][:, [1, 2]], tri[t][:, [2, 0]]], 1), -1)
    sides = sides.reshape(-1, 2)
    owner = np.repeat(t, 3)
    out_ends = outside[sides].all(axis=1)
    sides, owner = sides[out_ends], owner[out_ends]
    order = np.lexsort((sides[:, 1], sides[:, 0]))
    sides, owner = sides[order], owner[order]
    twice = np.flatnonzero((sides[1:] == sides[:-1]).all(axis=1))
    if not len(twice):
        return out
    lines = shapely.linestrings(points[sides[twice]])
    met = np.zeros(len(twice), dtype=bool)
    met[segments.query(lines, predicate="intersects")[0]] = True
    clear = twice[~met]
    out[owner[clear]] = True
    out[owner[clear + 1]] = True
    return out


class _Pinch(SelectionError):
    """Nodes where the region touches itself and no triangle may mend it."""

    def __init__(self, nodes: np.ndarray):
        super().__init__("the region's boundary has a pinch that no triangle mends")
        self.nodes = nodes


class _Crowded(SelectionError):
    """Points that took one node, or nodes out of their ring's order, or the first
    points of the edges nearest to a pinch the region could not mend."""

    def __init__(self, points: np.ndarray):
        super().__init__("crowded")
        self.points = points


def leaf_edges(contour: Contour, tree: graded.Quadtree) -> tuple[np.ndarray, np.ndarray]:
    """``(leaf, edge)``: each pair of a leaf and a contour edge (named by its first
    point) that meet, and a few that pass within round-off of the leaf (its box
    grown by a billionth of its side: an edge along a side of the leaf counts); by
    leaf, then edge.  Exact predicates, by a compiled walk over a tree of the
    edges' bounding boxes."""
    side = tree.sizes()
    height = tree.hy * 2.0**tree.level
    x0 = tree.x0 + tree.i * side
    y0 = tree.y0 + tree.j * height
    pad = 1e-9 * side
    p = contour.points
    q = p[next_on_ring(contour.ring)]
    edges = box_tree(np.minimum(p, q), np.maximum(p, q), 4)
    f8 = lambda v: np.ascontiguousarray(v, dtype=np.float64)  # noqa: E731
    boxes = (f8(x0 - pad), f8(x0 + side + pad), f8(y0 - pad), f8(y0 + height + pad))
    ends = (f8(p[:, 0]), f8(p[:, 1]), f8(q[:, 0]), f8(q[:, 1]))
    room = 4 * (len(p) + len(x0))
    while True:
        leaf = np.empty(room, dtype=np.int64)
        seg = np.empty(room, dtype=np.int64)
        m = boxes_meet_segments(
            *boxes, *ends, edges.order, edges.start, edges.box, edges.leaf0, leaf, seg
        )
        if m <= room:
            return leaf[:m], seg[:m]
        room = m


def diagonals_along(contour: Contour, tree: graded.Quadtree, pairs=None) -> np.ndarray:
    """Per leaf, the diagonal closer to the direction of the contour edges that cross
    it (0: ``/``, 1: ``\\``; their lengths weigh each edge's ``sin 2 theta``), so the
    loop follows the contour along diagonals rather than in steps; 0 where none does.
    ``pairs``: :func:`leaf_edges`, if already found."""
    leaf, seg = leaf_edges(contour, tree) if pairs is None else pairs
    p = contour.points
    q = p[next_on_ring(contour.ring)]
    d = q[seg] - p[seg]
    weight = d[:, 0] * d[:, 1] / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-300)
    lean = np.bincount(leaf, weights=weight, minlength=tree.n_leaves)
    return (lean < 0).astype(np.uint8)


def _select_on(contour: Contour, tree: graded.Quadtree, exterior: bool, size) -> GradedSelection:
    pairs = leaf_edges(contour, tree)
    diagonals = diagonals_along(contour, tree, pairs)
    points, tri, cell = tree.triangulate(diagonals)
    grid = GradedGrid(tree, points)
    n = len(points)
    # the box's nodes: an exterior mesh's box sides are a boundary of its own, never a
    # loop; an interior mesh's region is bounded by its loops alone, which may run along
    # the box's side where the cells of a long edge are wider than the margin
    fixed = np.zeros(n, dtype=bool)
    if exterior:
        fixed[grid.boundary_nodes()] = True
    rings = [contour.points[contour.ring_order(r)] for r in range(contour.n_rings)]
    from ..geometry import domain

    dom = domain(rings)
    cen = points[tri].mean(axis=1)
    inside = shapely.contains_xy(dom, cen[:, 0], cen[:, 1])
    in_domain = shapely.contains_xy(dom, points[:, 0], points[:, 1])
    if exterior:
        inside, in_domain = ~inside, ~in_domain
    # triangles across a thin gap of the outside never join the region
    banned = across_gaps(contour, points, tri, cell, pairs, dom, exterior)
    p = contour.points
    segments = shapely.STRtree(
        shapely.linestrings(np.stack([p, p[next_on_ring(contour.ring)]], axis=1))
    )
    for _ in range(PINCH_ROUNDS):
        try:
            kept, nxt = region(tri, inside & ~banned, n, fixed, banned, in_domain)
        except _Pinch as exc:  # (cells too coarse there: finer ones along the nearest edges)
            _, near = segments.query_nearest(shapely.points(points[exc.nodes]), all_matches=False)
            raise _Crowded(np.unique(near)) from None
        bridge = bridges(tri, kept, ~in_domain, segments, points)
        if bridge.any():
            banned |= bridge
            continue
        try:
            path = _assign(contour, grid, nxt, exterior, size)
        except _Stray as exc:
            # an island of the region leaves it, a hole in it joins it; a hole of triangles
            # across a gap (which never join) is a gap the cells are too coarse to follow:
            # finer ones along the nearest edges
            stuck = []
            for loop in exc.loops:
                poly = shapely.Polygon(points[loop])
                enclosed = shapely.contains_xy(poly, cen[:, 0], cen[:, 1])
                island = shapely.is_ccw(shapely.LinearRing(points[loop]))
                if island:  # (for good: a pinch beside it may not take it back)
                    inside &= ~enclosed
                    banned |= enclosed
                elif (enclosed & ~banned & ~inside).any():
                    inside |= enclosed & ~banned
                else:
                    stuck.append(loop)
            if stuck:
                nodes = np.unique(np.concatenate(stuck))
                _, near = segments.query_nearest(shapely.points(points[nodes]), all_matches=False)
                raise _Crowded(np.unique(near)) from None
            continue
        nodes, targets, ring, source = path
        has = np.full(n, False)
        has[nodes] = True
        target_of = np.zeros((n, 2))
        target_of[nodes] = targets
        full = kept & has[tri].all(axis=1)
        if full.any():
            t = np.flatnonzero(full)
            area = signed_areas(target_of, tri[t])
            scale = np.hypot(*(target_of[tri[t, 0]] - target_of[tri[t, 1]]).T) ** 2
            # flat by construction (three targets on one contour edge), or by round-off
            flat = _on_one_edge(_target_edges(n, nodes, ring, source), tri[t])
            bad = t[flat | (area <= 1e-9 * np.maximum(scale, 1e-300))]
            if len(bad):
                banned[bad] = True
                continue
        sel = GradedSelection(
            grid,
            nodes,
            targets,
            source,
            ring,
            diagonals,
            h=float(tree.hx),
            exterior=exterior,
        )
        sel.h_rule = "graded"
        sel.path_rule = CONSTRUCTED
        sel._kept = kept
        sel._triangles = tri  # (the same diagonals: not triangulated again)
        return sel
    raise SelectionError(f"{contour.source}: triangles that would flatten still in the region")


#: An extra node's place on its contour edge: its projection onto the edge (made
#: monotone along the loop) blended with this share of its share of the loop's length
#: between the edge's points, which increases strictly, so the targets keep the loop's
#: order and a node moves about its distance from the edge.
SHARE = 0.1

#: Loop nodes a point may take: the nearest this many.
CANDIDATES = 8


def _monotone(q: np.ndarray, loop: np.ndarray, s: np.ndarray) -> np.ndarray | None:
    """Loop positions for the ring's points ``q`` (in ring order) on the closed
    ``loop`` (coordinates, in the same direction): each point one of its
    :data:`CANDIDATES` nearest loop nodes, the positions strictly increasing once
    around the loop, the least sum of the squared distances, in units of each
    point's size ``s``, from each point to its node and from every loop node between
    two points' nodes that lies past an end of the edge joining them to that end (so
    a corner takes the loop's corner, not a node past it whose neighbour would then
    be carried round the corner).
    Dynamic programming along the ring from the point whose nearest node is
    nearest (in those units), which keeps it.  Returns the positions, or the
    indices of the points where no such choice exists (an array shorter than
    ``q``; None: every point)."""
    m, nl = len(q), len(loop)
    if nl < m:
        return None
    k = min(CANDIDATES, nl)
    dist, cand = Nearest(loop).query(q, k)
    cost = (dist / s[:, None]) ** 2
    t0 = int(np.argmin(cost[:, 0]))
    order = np.roll(np.arange(m), -t0)
    cand, cost = cand[order], cost[order]
    widest = nl - (m - 1)  # (every other step one loop edge)
    total = np.full(k, np.inf)
    total[0] = cost[0, 0]
    back = np.zeros((m, k), dtype=np.int64)
    failed = []  # (where no choice exists: the programme starts again after it)
    # (infinite where a step is not allowed: the loop holds only the minimum-plus
    # products, one step after the other)
    between = _between_costs(loop, cand, q[order], s[order], widest)
    reset = np.zeros(m, dtype=np.uint8)
    programme(between, np.ascontiguousarray(cost), back, total, reset)  # (compiled)
    for t in np.flatnonzero(reset):
        failed += [t - 2, t - 1, t]
    if failed:
        return order[np.clip(failed, 0, m - 1)]
    total = total + between[0][:, 0]
    if not np.isfinite(total).any():
        return order[[m - 2, m - 1, 0]] if m > 2 else None
    pick = np.empty(m, dtype=np.int64)
    pick[m - 1] = int(np.argmin(total))
    for t in range(m - 1, 0, -1):
        pick[t - 1] = back[t, pick[t]]
    pos = cand[np.arange(m), pick]
    if (np.diff(np.append(pos, pos[0] + nl)) % nl == 0).any() or int(
        ((np.roll(pos, -1) - pos) % nl).sum()
    ) != nl:
        return order  # (more than once around)
    out = np.empty(m, dtype=np.int64)
    out[order] = pos
    return out


def _between_costs(
    loop: np.ndarray, cand: np.ndarray, q: np.ndarray, s: np.ndarray, widest: int
) -> np.ndarray:
    """``(m, k, k)``: for each step ``t`` (from point ``t - 1`` to ``t``, ``t = 0`` the
    closing one from ``m - 1``) and each pair of their candidate loop positions, the
    summed squared distances, in units of the first point's size ``s``, from the loop
    nodes strictly between them (going forward) that lie past an end of the edge
    joining the two points to that end.  Inf where the step is not allowed: the
    second not ahead of the first, more than ``widest`` loop nodes ahead, or further
    ahead, in the loop's length, than halfway between the edge's share of its ring and
    the whole loop (the loop follows the ring, and a contour edge is never longer than
    the rest of its ring: a step that far would be one back; the loop's nodes may
    crowd at one end of an edge, so their count would not tell).
    Each step's edge is measured once from each of its first point's candidates,
    forward as far as its furthest allowed pair reaches; each pair reads its sum off
    that row's running sum (a compiled loop, :mod:`._monotone`)."""
    nl, (m, k) = len(loop), cand.shape
    prev = np.roll(np.arange(m), 1)
    seg = np.hypot(*(np.roll(loop, -1, axis=0) - loop).T)
    at = np.concatenate([[0.0], np.cumsum(seg)[:-1]])  # (the loop's length to each node)
    edge = np.hypot(*(q - q[prev]).T)
    share = edge / edge.sum()  # (each edge's share of its ring, at most a half)
    out = np.empty((m, k, k))
    f8 = lambda v: np.ascontiguousarray(v, dtype=np.float64)  # noqa: E731
    between_costs(
        f8(loop), at, float(seg.sum()), np.ascontiguousarray(cand, dtype=np.int64), f8(q),
        f8(s), share, int(widest), out, np.empty(nl + 1),
    )  # fmt: skip
    return out


def _owners(contour: Contour, p: np.ndarray, loops: list[np.ndarray]) -> np.ndarray:
    """Per loop, the ring it follows, or -1: each ring's loop is the one that most of
    its points have the nearest node on; two rings choosing one loop (the cells are
    too coarse for one of them to have its own) is :class:`_Crowded` at both."""
    loop_of = np.concatenate([np.full(len(lp), i) for i, lp in enumerate(loops)])
    k = Nearest(p[np.concatenate(loops)]).query(contour.points)[1][:, 0]
    # per ring, the loop most of its points are nearest to (the lowest on a tie): the
    # (ring, loop) pairs counted at once, not a pass over the points per ring
    nloops = len(loops)
    pair, count = np.unique(contour.ring * nloops + loop_of[k], return_counts=True)
    ring, loop = pair // nloops, pair % nloops
    order = np.lexsort((loop, -count, ring))
    _, first = np.unique(ring[order], return_index=True)  # (every ring has points)
    choice = loop[order][first]
    shared = np.bincount(choice, minlength=len(loops)) > 1
    if shared.any():  # (one ring has no loop of its own there: finer cells at both)
        raise _Crowded(np.flatnonzero(shared[choice][contour.ring]))
    owner = np.full(len(loops), -1, dtype=np.int64)
    owner[choice] = np.arange(contour.n_rings)
    return owner


class _Stray(SelectionError):
    """Loops that follow no ring: the boundaries of islands of the region, or of
    holes in it, too small for a ring's points to be nearest to them."""

    def __init__(self, loops: list[np.ndarray]):
        super().__init__("stray loops")
        self.loops = loops


def _assign(contour: Contour, grid: GradedGrid, nxt: np.ndarray, exterior: bool, size):
    """``(path nodes, targets, ring, source)``: each ring's loop from :func:`_monotone`'s fit
    (see the module's step 4); raises :class:`_Stray` or :class:`_Crowded`."""

    loops = _loops(nxt)
    if not loops:  # (no triangle's centroid in the domain: finer cells everywhere)
        raise _Crowded(np.arange(contour.n))
    p = grid.points
    owner = _owners(contour, p, loops)
    stray = np.flatnonzero(owner < 0)
    if len(stray):
        raise _Stray([loops[i] for i in stray])
    nodes, targets, sources, rings = [], [], [], []
    crowded = []
    for r in range(contour.n_rings):
        mine = np.flatnonzero(owner == r)
        if len(mine) != 1:
            q = contour.ring_order(r)
            raise _Crowded(q)  # (no loop, or several: finer cells along the ring)
        loop = loops[mine[0]]
        # path direction: counter-clockwise as the ring is walked
        domain_left = contour.is_hole(r) == exterior
        if not domain_left:
            loop = loop[::-1]
        order = contour.ring_order(r)
        q = contour.points[order]
        nl, m = len(loop), len(order)
        pos = _monotone(q, p[loop], size[order])
        if pos is None or len(pos) != m:
            crowded.append(order if pos is None else order[pos])
            continue
        rel = (pos - pos[0]) % nl
        loop = np.roll(loop, -pos[0])
        xy = p[loop]
        seg = np.hypot(*(np.roll(xy, -1, axis=0) - xy).T)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        start = rel  # loop position of each point's node
        end = np.append(rel[1:], nl)
        k_of = np.repeat(np.arange(m), end - start)  # the edge each loop node lies on
        pos_in = np.arange(nl)
        share = (cum[pos_in] - cum[start[k_of]]) / (cum[end[k_of]] - cum[start[k_of]])
        qa, qb = q[k_of], q[(k_of + 1) % m]
        # where the node projects onto its edge, kept in the loop's order along it
        ab = qb - qa
        proj = np.einsum("ij,ij->i", xy - qa, ab) / np.einsum("ij,ij->i", ab, ab)
        proj = np.clip(proj, 0.0, 1.0)
        proj[start] = 0.0
        run = np.maximum.accumulate(np.where(pos_in == start[k_of], 0.0, proj) + k_of)
        proj = run - k_of
        frac = (1.0 - SHARE) * proj + SHARE * share
        tgt = qa + frac[:, None] * ab
        src = np.full(nl, -1, dtype=np.int64)
        src[start] = order
        tgt[start] = q
        nodes.append(loop)
        targets.append(tgt)
        sources.append(src)
        rings.append(np.full(nl, r))
    if crowded:
        raise _Crowded(np.unique(np.concatenate(crowded)))
    return tuple(np.concatenate(a) for a in (nodes, targets, rings, sources))


#: Corners sharper than this (degrees, on the domain's side) whose ear is empty and
#: has no angle under :data:`EAR_SHARE` of theirs are cut off before the grid is laid.
EAR_ANGLE = 30.0

#: ... where the corner's angle, and its sides' room, bound every mesh of these points
#: there: an ear whose other angles are at least a third of that keeps the smallest
#: angle within a third of what the points force.
EAR_SHARE = 1.0 / 3.0


#: A side whose forced bound (:func:`.forced.edge_angles`) is under this (degrees) lies
#: along a thin part: every mesh of these points has a triangle on it under this angle,
#: so the grid, whose cells there would be about the part's width, could add only
#: slivers along it, about ``4 / tan`` of its forced angle of them (230 at 1 degree,
#: 400,000 for a part 1e-5 wide and 1 long).  An empty ear on such a side whose angles
#: are at least :data:`EAR_SHARE` of that bound is cut off, as a sharp corner's is.
THIN_ANGLE = 1.0


def _angle_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The angles between the vectors ``u`` and ``v`` (degrees, 0 to 180), row by row
    (one pair: a 0-d array)."""
    cross = u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
    return np.degrees(np.arctan2(np.abs(cross), u[..., 0] * v[..., 0] + u[..., 1] * v[..., 1]))


def _maybe_ears(p: np.ndarray, prv: np.ndarray, nxt: np.ndarray) -> np.ndarray:
    """The points that may be ears (:func:`cut_ears`), at once for all: those whose angle
    on the domain's side is under 180 degrees and either under :data:`EAR_ANGLE` or with
    one of the ear's other angles under it and one not (a thin part's end).  Each test
    is widened by a billionth of a degree, so round-off never leaves out a point the
    exact test (``candidate``, which decides) would take."""
    u, v = p[prv] - p, p[nxt] - p
    ang = np.degrees(np.arctan2(u[:, 1] * v[:, 0] - u[:, 0] * v[:, 1], (u * v).sum(axis=1)))
    ang %= 360.0
    w = p[nxt] - p[prv]
    at_a, at_b = _angle_between(-u, w), _angle_between(-v, -w)
    lo, hi = np.minimum(at_a, at_b), np.maximum(at_a, at_b)
    eps = 1e-9
    sharp = (ang < EAR_ANGLE + eps) | (ang > 360.0 - eps)
    thin_end = (lo < EAR_ANGLE + eps) & (hi >= EAR_ANGLE - eps)
    return np.flatnonzero(((ang < 180.0 + eps) | (ang > 360.0 - eps)) & (sharp | thin_end))


def _domain_walk(contour: Contour, exterior: bool) -> tuple[np.ndarray, np.ndarray]:
    """Per point, its next and previous point with the domain on the left (a ring's
    :meth:`~.Contour.ring_order`, walked backwards where the domain is outside it)."""
    nxt = np.empty(contour.n, dtype=np.int64)
    for r in range(contour.n_rings):
        order = contour.ring_order(r)
        if contour.is_hole(r) != exterior:
            order = order[::-1]
        nxt[order] = np.roll(order, -1)
    prv = np.empty_like(nxt)
    prv[nxt] = np.arange(contour.n)
    return nxt, prv


def cut_ears(contour: Contour, exterior: bool = False):
    """``(grid contour, kept, ears)``: the contour without the tips of its sharp
    empty ears, the original indices of the points it keeps, and the ears cut
    (previous, tip, next; counter-clockwise).

    An ear at point P (previous A, next B, domain on the left) is cut when P's
    angle on the domain's side is under :data:`EAR_ANGLE` degrees, the ear's angles at
    A and B are at least :data:`EAR_SHARE` of the least of P's angle and the
    forced bounds of its sides A P and P B (every mesh keeping exactly the
    contour's points has a triangle at P, and one on each side, no better than
    those: the ear is within that share of the best there), and no other point lies in
    the closed triangle A P B (so no contour edge crosses the chord and the ear
    lies in the domain), and the corners the cut leaves at A and B are at least
    :data:`EAR_SHARE` of P's unless such a corner is an ear to cut in turn (a needle
    is cut tip by tip; a cut never leaves a far sharper needle it cannot cut).  Cuts
    repeat on the points left (sharpest first) while a ring keeps more than three
    points.  A needle the cells could follow only by thousands of cells across is one
    triangle, as in any mesh of those points."""
    import heapq

    p = contour.points
    m = contour.n
    nxt, prv = _domain_walk(contour, exterior)
    alive = np.ones(m, dtype=bool)
    left = np.bincount(contour.ring, minlength=contour.n_rings)
    tree = shapely.STRtree(shapely.points(p))

    geom = None
    rooms: dict[tuple[int, int], float] = {}

    def room(u: int, v: int) -> float:
        """The forced bound on the edge (or chord) u v: the largest base angle of an
        isosceles triangle on it inside the domain (:func:`.forced.edge_angles`); any
        mesh has a triangle on it no better (inf for a far field, not measured)."""
        nonlocal geom
        if exterior:
            return np.inf
        if (u, v) not in rooms:
            from ..forced import edge_angles
            from ..geometry import domain

            if geom is None:
                geom = domain([p[contour.ring_order(r)] for r in range(contour.n_rings)])
            rooms[u, v] = float(edge_angles(p, np.array([[u, v]]), geom)[0])
        return rooms[u, v]

    def _corner(k: int, a: int, b: int) -> float:
        """The angle at ``k`` on the domain's side between ``a`` before it and ``b``
        after it (degrees)."""
        u, v = p[a] - p[k], p[b] - p[k]
        return float(np.degrees(np.arctan2(u[1] * v[0] - u[0] * v[1], u @ v)) % 360.0)

    def _ear_after(k: int, j: int) -> bool:
        """Whether ``j`` (a neighbour of ``k``) is an ear once ``k`` is cut (one step
        ahead: ``j``'s own neighbours are not looked at)."""
        a, b = int(prv[k]), int(nxt[k])
        old_next, old_prev = nxt[a], prv[b]
        nxt[a], prv[b] = b, a
        alive[k] = False
        left[contour.ring[k]] -= 1
        try:
            return candidate(j, look=False) is not None
        finally:
            nxt[a], prv[b] = old_next, old_prev
            alive[k] = True
            left[contour.ring[k]] += 1

    def candidate(k: int, look: bool = True) -> float | None:
        a, b = prv[k], nxt[k]
        u, v = p[a] - p[k], p[b] - p[k]
        cross = u[1] * v[0] - u[0] * v[1]  # (b to a, counter-clockwise about k)
        ang = np.degrees(np.arctan2(cross, u @ v)) % 360.0
        if not 0.0 < ang < 180.0 or left[contour.ring[k]] <= 3:
            return None
        # the ear's angles at a and b
        rest = [
            float(_angle_between(p[k] - p[a], p[b] - p[a])),
            float(_angle_between(p[a] - p[b], p[k] - p[b])),
        ]
        if ang < EAR_ANGLE:  # a sharp corner
            if min(rest) < EAR_SHARE * min(ang, room(a, k), room(k, b)):
                return None
        else:  # a thin part's end: the side at its sharp end forced under THIN_ANGLE
            if not min(rest) < EAR_ANGLE <= max(rest):  # (a flat ear has two sharp ends)
                return None
            side = room(a, k) if rest[0] < rest[1] else room(k, b)  # (the sharp end's)
            if not (side < THIN_ANGLE and min(rest) >= EAR_SHARE * side):
                return None
            ang = min(rest)
        # the corners the cut leaves at a and b: none under EAR_SHARE of the one it takes
        # away, but for one that is an ear to cut in turn (a needle is cut tip by tip)
        for j, after in ((a, _corner(a, prv[a], b)), (b, _corner(b, a, nxt[b]))):
            if after < EAR_SHARE * ang and not (look and _ear_after(k, j)):
                return None
        ear = shapely.Polygon(p[[a, k, b]])
        near = tree.query(ear, predicate="intersects")
        near = near[alive[near]]
        if np.isin(near, [a, k, b], invert=True).any():
            return None
        return float(ang)

    # (angle, point, its neighbours' version): an entry is stale once a neighbour of
    # its point was cut (a cut only empties other ears, never fills one)
    version = np.zeros(m, dtype=np.int64)
    heap = [(a, k, 0) for k in _maybe_ears(p, prv, nxt) if (a := candidate(k)) is not None]
    heapq.heapify(heap)
    ears = []
    while heap:
        _, k, ver = heapq.heappop(heap)
        if not alive[k] or ver != version[k] or left[contour.ring[k]] <= 3:
            continue
        a, b = int(prv[k]), int(nxt[k])
        ears.append((a, k, b))
        alive[k] = False
        left[contour.ring[k]] -= 1
        nxt[a], prv[b] = b, a
        for j in (a, b):
            version[j] += 1
            c = candidate(j)
            if c is not None:
                heapq.heappush(heap, (c, j, int(version[j])))
    tips, d = _tips(p, np.flatnonzero(alive), nxt, prv, *_domain_walk(contour, exterior))
    if not len(tips) and alive.all():
        return contour, np.arange(m), np.zeros((0, 3), dtype=np.int64)
    if not exterior and len(tips):  # (thin triangles left are meshed as they are, tips and all)
        kept = np.flatnonzero(alive)
        left_over = _kept_contour(contour, p, contour.lines, contour.ring, kept)
        if thin_triangles(left_over):
            return left_over, kept, np.array(ears, dtype=np.int64).reshape(-1, 3)
    # a cut tip k gives way to two points at d from it: on its edge from prv[k]
    # (numbered m + 2 j) and on its edge to nxt[k] (m + 2 j + 1)
    on_prev = p[tips] + d[:, None] * _unit(p[prv[tips]] - p[tips])
    on_next = p[tips] + d[:, None] * _unit(p[nxt[tips]] - p[tips])
    first = m + 2 * np.arange(len(tips))
    ears += list(zip(first.tolist(), tips.tolist(), (first + 1).tolist()))
    xy = np.concatenate([p, np.stack([on_prev, on_next], axis=1).reshape(-1, 2)])
    lines = np.concatenate([contour.lines, np.repeat(contour.lines[tips], 2)])
    ring_of = np.concatenate([contour.ring, np.repeat(contour.ring[tips], 2)])
    # in the contour's stored order, the two points where the tip was (the one on
    # the edge from the stored predecessor first)
    alive[tips] = False
    kept = np.flatnonzero(alive)
    stored_prev = prev_on_ring(contour.ring)[tips] == prv[tips]
    pair = np.where(stored_prev[:, None], np.column_stack([first, first + 1]),
                    np.column_stack([first + 1, first]))  # fmt: skip
    kept = np.insert(kept, np.repeat(np.searchsorted(kept, tips), 2), pair.ravel())
    return (
        _kept_contour(contour, xy, lines, ring_of, kept, tips),
        kept,
        np.array(ears, dtype=np.int64),
    )


def _kept_contour(contour: Contour, xy, lines, ring_of, kept, tips=None) -> Contour:
    """The contour of the points ``kept`` (indices into ``xy``, ``lines`` and
    ``ring_of``, in the contour's stored order), its rings as ``contour``'s; its
    messages name each point by ``contour``'s (an added point ``m + 2 j`` or ``m + 2 j
    + 1`` by the cut tip ``tips[j]`` it stands beside)."""
    ring = ring_of[kept]
    m = contour.n
    own = contour.numbers if contour.numbers is not None else np.arange(m)
    beside = np.asarray(tips if tips is not None else [], dtype=np.int64)
    numbers = np.where(kept < m, own[np.minimum(kept, m - 1)],
                       own[beside[np.maximum(kept - m, 0) // 2]] if len(beside) else 0)  # fmt: skip
    starts = tuple(np.searchsorted(ring, np.arange(contour.n_rings + 1)).tolist())
    return Contour(
        xy[kept],
        lines[kept],
        contour.source,
        starts=starts,
        ring_clockwise=contour.ring_clockwise,
        depth=contour.depth,
        ring_labels=contour.ring_labels,
        numbers=numbers,
    )


#: A sharp corner whose ear is not cut is cut this fraction of its reach from its
#: point: the shorter of its sides and its distance to the rest of the contour.
TIP_SHARE = 1.0 / 3.0


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.hypot(*v.T)[:, None]


def _tips(p, alive: np.ndarray, nxt: np.ndarray, prv: np.ndarray, nxt0, prv0):
    """``(tips, d)``: the points of ``alive`` (the contour walked by ``nxt`` and
    ``prv``, domain on the left) whose angle on the domain's side is under
    :data:`EAR_ANGLE` and whose sides are edges of the contour (``nxt0``, ``prv0``: no
    cut ear's chord), and how far from each its tip is cut: :data:`TIP_SHARE` of the
    least of its sides and its distance to every other edge.  The triangle cut
    lies within that distance of its point, so it holds no other part of the
    contour, and two tips' triangles are apart."""
    a, b = p[prv[alive]] - p[alive], p[nxt[alive]] - p[alive]
    cross = a[:, 1] * b[:, 0] - a[:, 0] * b[:, 1]
    ang = np.degrees(np.arctan2(cross, np.einsum("ij,ij->i", a, b))) % 360.0
    sharp = (ang > 0.0) & (ang < EAR_ANGLE)
    sharp &= (nxt[alive] == nxt0[alive]) & (prv[alive] == prv0[alive])  # (no chord side)
    tips = alive[sharp]
    if not len(tips):
        return tips, np.zeros(0)
    reach = np.minimum(np.hypot(*a[sharp].T), np.hypot(*b[sharp].T))
    segs = shapely.linestrings(np.stack([p[alive], p[nxt[alive]]], axis=1))
    qi, si = shapely.STRtree(segs).query(
        shapely.points(p[tips]), predicate="dwithin", distance=reach
    )
    own = (alive[si] == tips[qi]) | (nxt[alive[si]] == tips[qi])
    qi, si = qi[~own], si[~own]
    dist = shapely.distance(shapely.points(p[tips[qi]]), segs[si])
    np.minimum.at(reach, qi, dist)
    return tips, TIP_SHARE * reach


def restore_ears(mesh, contour: Contour, kept: np.ndarray, ears: np.ndarray, exterior=False):
    """The mesh of the grid contour (:func:`cut_ears`) with the ears added back: node
    k is contour point k again, the boundary is the contour's.  The two points of a
    cut tip are extra boundary nodes, on its sides (numbered first among the extra
    ones), for :func:`..recover.recover` to take out."""
    from ..mesh import Mesh

    if not len(ears):
        return mesh
    mk, m = len(kept), contour.n
    n = len(mesh.points)
    added = int(np.count_nonzero(kept >= m))
    new = np.concatenate([kept, m + added + np.arange(n - mk)])
    at = np.zeros((added, 2))
    at[kept[kept >= m] - m] = mesh.points[:mk][kept >= m]
    points = np.concatenate([contour.points, at, mesh.points[mk:]])
    tri = np.concatenate([new[mesh.triangles], ears])
    nxt, _ = _domain_walk(contour, exterior)
    tip_of = {(int(a), int(b)): int(k) for a, k, b in ears if a >= m}
    tip_of.update({(b, a): k for (a, b), k in list(tip_of.items())})
    lines, groups = [], []
    for (u, v), g in zip(new[mesh.lines].tolist(), mesh.line_group.tolist()):
        if u < m and v < m:
            while nxt[u] != v:  # (a chord over cut tips: the contour's edges instead)
                lines.append((u, int(nxt[u])))
                groups.append(g)
                u = int(nxt[u])
        elif (u, v) in tip_of:  # (a cut tip's chord: its sides)
            lines.append((u, tip_of[u, v]))
            groups.append(g)
            u = tip_of[u, v]
        lines.append((u, v))
        groups.append(g)
    return Mesh(
        points=points,
        triangles=tri,
        lines=np.array(lines, dtype=np.int64),
        n_contour=m,
        n_extra=mesh.n_extra + added,
        line_group=np.array(groups, dtype=np.int64),
        groups=mesh.groups,
        n_box=mesh.n_box,
        point_data={},
    )
