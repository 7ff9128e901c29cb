"""Stage 1 on the graded grid: one node per contour point, consecutive points on
neighbouring nodes, so no contour edge is split.

Appendix A takes, for each point, the nearest free corner of its cell.  Here
every ring is assigned at once: each point may take one of the
:data:`CANDIDATES` nodes nearest to it (cell corners and side midpoints, not
the box and not another ring's), consecutive points must take two nodes
joined by a grid edge (a cell side, or either diagonal of a leaf without a
finer neighbour), and no step may cut a corner (its two neighbours joined by
an edge too: three consecutive path nodes in one triangle) but an L-turn
along two sides of a leaf.  Among those assignments the one with the least
summed squared distance, in units of each point's local size, is found by
dynamic programming over pairs of consecutive candidates.  A node taken
twice is given to the nearer point and the ring assigned again.

Then the path fixes the leaves' diagonals: a diagonal step forces its leaf's
diagonal, and an L-turn along two sides of a leaf forces the diagonal through
the corner (a U-turn along three sides takes either and leaves one ear,
accepted when its contour points make a fair triangle).

``slide``: the path is fitted to the points evenly re-spaced between
corners and the deformation slides each node to its point, as on the
adapted grid.  ``extra``: a step may go through up to :data:`MAX_HOPS` grid
edges, its nodes extra boundary nodes on that contour edge; a route that
cuts a corner or crosses the path is taken out and the ring assigned again
(around the points concerned only).  Anything that cannot be met is a
:class:`~deformesh_cli.errors.SelectionError`, and the caller falls back to
the other grids.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import shapely

from .. import deadline
from ..contour import Contour
from ..errors import LimitError, SelectionError
from ..geometry import signed_area, sorted_lookup
from . import graded, graded_fit
from .respace import path_arclengths, respace

#: Nodes a contour point may take: the nearest this many.
CANDIDATES = 9

#: Times a ring is assigned again after a node was taken twice or a corner cut.
MAX_ROUNDS = 40

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
    #: (n_path, 2) arc lengths where each path node starts and ends its slide along the
    #: contour (:mod:`.respace`), or None for straight moves
    path_slide: np.ndarray | None = None
    _triangles: np.ndarray | None = field(default=None, init=False, repr=False)
    _kept: np.ndarray | None = field(default=None, init=False, repr=False)

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

    def band_nodes(self) -> np.ndarray | None:
        """Nodes within :data:`BAND_HOPS` edges of the path, or None if half the grid
        (or the nodes slide along the contour, farther than a band would follow)."""
        import scipy.sparse as sp

        if self.path_slide is not None:
            return None

        tri = self.triangles()
        n = self.grid.n_nodes
        a = np.concatenate([tri[:, 0], tri[:, 1], tri[:, 2]])
        b = np.concatenate([tri[:, 1], tri[:, 2], tri[:, 0]])
        adj = sp.csr_matrix((np.ones(len(a), np.int8), (a, b)), shape=(n, n))
        adj = adj + adj.T
        on = np.zeros(n, dtype=bool)
        on[self.path_nodes] = True
        for _ in range(BAND_HOPS):
            on |= (adj @ on.astype(np.int8)) > 0
        return on if on.sum() < 0.5 * n else None


def select_graded(
    contour: Contour,
    box: tuple[float, float, float, float] | None = None,
    margin: float | None = None,
    exterior: bool = False,
    growth: float = graded.DEFAULT_GROWTH,
    max_nodes: int | None = None,
    slide: bool = False,
    extra: bool = False,
    max_h: float | None = None,
    fit: bool = False,
    size=None,
    cache: dict | None = None,
) -> GradedSelection:
    """Lay the graded grid over ``contour`` and fit each ring's path to its points.

    ``slide``: fit the path to the contour's points evenly re-spaced between its
    corners (:func:`.respace.respace`), and let the deformation slide each node along
    the contour to its point, as the adapted grid does: for contours whose spacing
    changes faster than the cells can follow.

    ``fit``: lay a grid of one cell per point along each piece between corners and
    fit the path to the points slid to equal cell steps (:mod:`.graded_fit`); the
    deformation slides each node to its point.

    ``size`` (a :class:`~deformesh_cli.size.SizeFunction`): cells also no wider than
    ``lambda sqrt(f)``, ``lambda`` the median over the points of their cell size over
    ``sqrt(f)`` there, so the grid already grades as ``f`` asks and the deformation
    only smooths it (without it the cells start with areas 4 times apart across a
    level change, and the deformation multiplies them by ``f``).

    ``extra``: where two consecutive points have no neighbouring candidates, let
    the path step through up to :data:`MAX_HOPS` grid edges between them, their
    nodes extra boundary nodes on that contour edge (each costs far more than any
    distance, so as few as possible); without it, such a ring is a SelectionError.

    ``cache``: a dict kept between the calls for one contour with the same options
    but ``extra``, which then lay their grids once.
    """
    cache = {} if cache is None else cache
    key = (slide, fit)
    if key not in cache:
        try:
            cache[key] = _prepare(
                contour, box, margin, exterior, growth, max_nodes, slide, max_h, fit, size
            )
        except (SelectionError, LimitError) as exc:
            cache[key] = exc  # (the attempt with extra nodes fails the same way)
    prep = cache[key]
    if isinstance(prep, Exception):
        raise prep
    rs, contour, s, plain, edges = prep.rs, prep.contour, prep.local, prep.plain, prep.edges
    turns, free = plain.turn_keys, prep.free
    grid = GradedGrid(prep.grid.tree, prep.grid.points)
    points = grid.points
    graph = _Graph(edges, turns, points) if extra else None
    banned: set[int] = set()  # steps (node pair keys) found to cross or cut the path
    for _ in range(BAN_ROUNDS):
        try:
            sel = _lay_path(contour, grid, plain, free, edges, s, graph, banned, exterior)
            break
        except _Clash as exc:
            if graph is None or exc.pairs <= banned:
                raise
            banned |= exc.pairs
    else:
        raise SelectionError(
            f"{contour.source}: no graded-grid path without crossing itself after "
            f"{BAN_ROUNDS} rounds"
        )
    if rs is not None:
        s0, s1, sel.path_targets = path_arclengths(
            rs, sel.path_source, sel.path_ring, sel.path_targets
        )
        sel.path_slide = np.column_stack([s0, s1])
        sel.h_rule = "graded-fit" if fit else "graded-slid"
        sel.notes.insert(
            0,
            "graded grid of one cell per point, on the points slid to equal cell steps "
            "between corners; the deformation slides each node along the contour to its point"
            if fit
            else "graded grid on the points evenly re-spaced between corners; the "
            "deformation slides each node along the contour to its point",
        )
    return sel


@dataclass
class _Prepared:
    """The graded grid an attempt lays its path on, as :func:`_prepare` builds it (the
    same for an attempt with extra nodes and one without)."""

    rs: object  # the re-spaced copy the path is fitted to, or None
    contour: Contour  # the points the path is fitted to
    local: np.ndarray  # their local sizes (the assignment's unit of distance)
    grid: GradedGrid
    plain: _Plain
    edges: np.ndarray
    free: np.ndarray  # nodes a path may take


def _prepare(contour, box, margin, exterior, growth, max_nodes, slide, max_h, fit, size):
    """Lay the graded grid for :func:`select_graded` (its arguments)."""
    rs = None
    if slide:
        rs = respace(contour)
        if rs is None:
            raise SelectionError(f"{contour.source}: the evenly re-spaced copy is not valid")
        contour = rs.copy  # the path is fitted to the copy; targets go back to the points
    local = graded.local_sizes(contour)
    lo, hi = contour.points.min(axis=0), contour.points.max(axis=0)
    given = box is not None
    if box is None:
        if margin is None:
            margin = float((hi - lo).max()) if exterior else 3.0 * float(local.max())
        box = (lo[0] - margin, lo[1] - margin, hi[0] + margin, hi[1] + margin)
    build = {"growth": growth, "max_h": max_h, "box_given": given, "max_nodes": max_nodes}
    if size is not None:
        build["field"] = _size_field(contour, local, growth, size)
    if fit:
        tree = graded.build(
            contour, box, local=graded_fit.initial_sizes(contour), roots=graded_fit.ROOTS, **build
        )
        tree, _ = graded_fit.fit_tree(contour, tree, max_nodes)
        rs = graded_fit.copy(contour, tree)
        contour = rs.copy
        local = graded.local_sizes(contour)
    else:
        tree = graded.build(contour, box, local=local, **build)
    lay = tree.layout()
    points, tri0, _ = tree.triangulate(layout=lay)
    keys = tree.node_keys(layout=lay)
    grid = GradedGrid(tree, points)
    plain = _plain_leaves(lay, keys)
    edges = _allowed_edges(tri0, plain)
    free = np.ones(len(points), dtype=bool)
    free[grid.boundary_nodes()] = False
    centres = np.searchsorted(keys, lay.key(lay.centre[~lay.plain]))
    free[centres] = False
    return _Prepared(rs, contour, local, grid, plain, edges, free)


#: Times the path is laid again with the steps that crossed it or cut a corner taken
#: out (only with extra boundary nodes, whose routes the assignment does not see).
BAN_ROUNDS = 12


class _Clash(SelectionError):
    """The path crosses itself in a leaf or leaves a triangle of three consecutive
    nodes: ``pairs``, keys ``lo * n + hi`` of the steps involved."""

    def __init__(self, message: str, pairs: set[int]):
        super().__init__(message)
        self.pairs = pairs


def _lay_path(contour, grid, plain, free, edges, s, graph, banned, exterior) -> GradedSelection:
    """Every ring's path (:func:`_assign`, without the ``banned`` steps), the
    diagonals it forces, checked (:func:`_check`)."""
    free = free.copy()
    nodes, sources, targets, rings = [], [], [], []
    for r in range(contour.n_rings):
        order = contour.ring_order(r)
        path, src, tgt = _assign(
            contour, order, grid.points, free, edges, plain.turn_keys, s[order], graph, banned
        )
        free[path] = False
        nodes.append(path)
        sources.append(src)
        targets.append(tgt)
        rings.append(np.full(len(path), r))
    path_nodes = np.concatenate(nodes)
    path_ring = np.concatenate(rings)
    diagonals = _force_diagonals(contour, grid.tree.n_leaves, plain, path_nodes, path_ring)
    sel = GradedSelection(
        grid,
        path_nodes,
        np.concatenate(targets),
        np.concatenate(sources),
        path_ring,
        diagonals,
        h=float(grid.tree.hx),
        exterior=exterior,
    )
    _check(contour, sel)
    return sel


def _size_field(contour: Contour, local: np.ndarray, growth: float, size):
    """Cell sizes as a size function asks: ``lambda sqrt(f(x))``, anchored at the
    contour (``lambda`` the median over its points of their graded size over
    ``sqrt(f)``)."""
    s = graded.graded_sizes(contour.points, local, growth)
    scale = float(np.median(s / np.sqrt(size.values(contour.points))))
    return lambda xy: scale * np.sqrt(size.values(xy))


@dataclass
class _Plain:
    """The leaves without a finer neighbour, as the path sees them: their corner nodes,
    their diagonals (keys ``lo * n + hi``, sorted, with leaf and direction) and their
    L-turns (keys ``(a * n + b) * n + c`` of ``a -> b -> c`` along two sides, sorted,
    with leaf and the direction of the diagonal through ``b``)."""

    n: int
    corners: np.ndarray  # (p, 4): lower-left, lower-right, upper-right, upper-left
    diag_keys: np.ndarray
    diag_leaf: np.ndarray
    diag_dir: np.ndarray
    turn_keys: np.ndarray
    turn_leaf: np.ndarray
    turn_dir: np.ndarray


def _plain_leaves(lay: graded.Layout, keys: np.ndarray) -> _Plain:
    n = len(keys)
    leaves = np.flatnonzero(lay.plain)
    c = np.searchsorted(keys, lay.key(lay.corners[leaves])).astype(np.int64)

    def sort(k, leaf, d):
        o = np.argsort(k, kind="stable")
        return k[o], leaf[o], d[o]

    dk = [np.minimum(c[:, 0], c[:, 2]) * n + np.maximum(c[:, 0], c[:, 2]),
          np.minimum(c[:, 1], c[:, 3]) * n + np.maximum(c[:, 1], c[:, 3])]  # fmt: skip
    diag = sort(np.concatenate(dk), np.tile(leaves, 2), np.repeat([0, 1], len(leaves)))
    tk, tl, td = [], [], []
    for s in range(4):  # the diagonal through corner s: '/' at LL and UR, '\\' else
        a, b, d = c[:, (s - 1) % 4], c[:, s], c[:, (s + 1) % 4]
        tk += [(a * n + b) * n + d, (d * n + b) * n + a]
        tl += [leaves, leaves]
        td += [np.full(len(leaves), s % 2)] * 2
    turn = sort(np.concatenate(tk), np.concatenate(tl), np.concatenate(td))
    return _Plain(n, c, *diag, *turn)


def _allowed_edges(tri0, plain: _Plain) -> np.ndarray:
    """Sorted keys ``lo * n + hi`` of the node pairs a path step may join: the
    triangulation's edges, and both diagonals of every leaf without a finer
    neighbour."""
    n = plain.n
    e = np.concatenate([tri0[:, [0, 1]], tri0[:, [1, 2]], tri0[:, [2, 0]]])
    lo, hi = np.minimum(e[:, 0], e[:, 1]), np.maximum(e[:, 0], e[:, 1])
    return np.union1d(lo * n + hi, plain.diag_keys)


def _l_turn(a, b, c, turns, n) -> np.ndarray:
    """``a -> b -> c`` is an L-turn (one of the sorted ``turns`` keys)."""
    return sorted_lookup(turns, (a * n + b) * n + c)[0]


def _adjacent(edges: np.ndarray, n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    k = np.minimum(a, b) * n + np.maximum(a, b)
    return sorted_lookup(edges, k)[0] & (a != b)


#: The most grid edges one contour edge may take (so at most this less one extra
#: boundary nodes on it): a long edge beside short ones crosses several of the cells
#: its short neighbours need (4.5 cells on an icon of the corpus); a bound tuned on
#: the corpus, where 8 let six more contours through, their extra nodes then all
#: merged (``benchmarks/MEASURED.md``).
MAX_HOPS = 8


#: ... or, between two points with no pair of candidates within :data:`MAX_HOPS`,
#: this many (a corpus icon has a 10-cell edge at a level change).
FAR_HOPS = 16


def _hop_counts(edges: np.ndarray, n: int, free: np.ndarray, cand: np.ndarray) -> np.ndarray:
    """``hops[t, i, j]``: the grid edges from ``cand[t, i]`` to ``cand[t + 1, j]`` (the
    next point's, cyclically) through ``free`` nodes, 2 to :data:`MAX_HOPS` (to
    :data:`FAR_HOPS` where no pair is within that), else 0.  A breadth-first search
    from the candidates only (sparse rows), so its cost grows with the points, not the
    grid."""
    import scipy.sparse as sp

    m, k = cand.shape
    lo, hi = edges // n, edges % n
    a = sp.csr_matrix((np.ones(2 * len(lo), np.int32), (np.r_[lo, hi], np.r_[hi, lo])), (n, n))
    through = sp.diags(free.astype(np.int32), dtype=np.int32) @ a
    nxt = np.roll(cand, -1, axis=0)
    same = np.repeat(cand, k, axis=1).reshape(m, k, k) == np.tile(nxt, (1, k)).reshape(m, k, k)

    def counts(ts: np.ndarray, limit: int) -> np.ndarray:
        src, row = np.unique(cand[ts], return_inverse=True)
        row = row.reshape(len(ts), k)
        rows = np.repeat(row, k, axis=1).ravel()  # (search, node) pairs asked for
        cols = np.tile(nxt[ts], (1, k)).ravel()
        frontier = (a[src] > 0).astype(np.int32)
        dist = frontier.copy()  # grid edges to each node reached (1: a neighbour)
        for e in range(2, limit + 1):
            # a search that has reached every node asked of it goes no further
            missing = np.asarray(dist[rows, cols] == 0).ravel()
            going = np.bincount(rows[missing], minlength=len(src)) > 0
            if not going.any():
                break
            if not going.all():
                frontier = sp.diags(going.astype(np.int32), dtype=np.int32) @ frontier
            reach = ((frontier @ through) > 0).astype(np.int32)
            frontier = reach - reach.multiply(dist > 0)
            frontier.eliminate_zeros()
            if frontier.nnz == 0:
                break
            dist = dist + e * frontier
        dist = dist.tocsr()
        return np.asarray(dist[rows, cols]).ravel().reshape(len(ts), k, k)

    got = counts(np.arange(m), MAX_HOPS)
    stuck = np.flatnonzero(~((got >= 1) & ~same).any(axis=(1, 2)))
    if len(stuck):
        got[stuck] = counts(stuck, FAR_HOPS)
    return np.where((got >= 2) & ~same, got, 0)  # (neighbours are the plain steps)


class _Graph:
    """The grid's edges as Python sets, for the route search's many small questions."""

    def __init__(self, edges: np.ndarray, turns: np.ndarray, points: np.ndarray):
        n = self.n = len(points)
        #: the nodes' coordinates as Python pairs (for :func:`_route`)
        self.xy = points.tolist()
        self.edge_keys = set(edges.tolist())
        #: each ring's assignment as last laid, keyed by its first point and the free
        #: nodes (:func:`_assign`)
        self.memo: dict = {}
        self.turn_keys = set(turns.tolist())
        lo, hi = edges // n, edges % n
        self.neighbours: dict[int, list[int]] = {}
        for x, y in zip(lo.tolist(), hi.tolist()):
            self.neighbours.setdefault(x, []).append(y)
            self.neighbours.setdefault(y, []).append(x)

    def cuts(self, x: int, y: int, z: int) -> bool:
        """``x -> y -> z`` cuts a corner (see :func:`_viterbi`); -1: no node, no cut."""
        if x < 0 or z < 0:
            return False
        if x == z:
            return True
        n = self.n
        if (x * n + z if x < z else z * n + x) not in self.edge_keys:
            return False
        return (x * n + y) * n + z not in self.turn_keys


class _NoRoute(SelectionError):
    """:func:`_through` found no route for the steps ``failed`` (positions in the ring)."""

    def __init__(self, failed: list[int]):
        super().__init__(failed)
        self.failed = failed


def _through(
    contour,
    order,
    path,
    points,
    free,
    edges,
    graph: _Graph | None,
    banned,
    far,
    memo: dict,
):
    """The ring's path with the fewest free grid nodes put between each two consecutive
    nodes that are not neighbours (at most :data:`MAX_HOPS` edges, nearest the contour
    edge; more where the assignment counted more, ``far[t]``): ``(nodes, sources,
    targets)``, -1 the source of an extra node, the extra nodes' targets evenly spaced
    on their contour edge.  :class:`_NoRoute` names the steps with no route that cuts
    no corner through nodes the path leaves free.

    ``memo`` (a dict kept over the calls for one ring with the same ``free`` and
    ``banned``; a new one searches afresh): each search's route and the nodes it
    found taken and untaken; a search asked again with the same ends is answered
    from it while each of those nodes is still as it was (the search would go the
    same way)."""
    n = len(points)
    q = contour.points[order]
    nxt = np.roll(path, -1)
    gap = ~_adjacent(edges, n, path, nxt)
    if not gap.any():
        return path, order, q
    neighbours, cuts = graph.neighbours, graph.cuts
    open_ = free.tolist()  # (a list answers one node at a time faster)
    taken = set(path.tolist())

    nodes, sources, targets, failed = [], [], [], []
    for t in range(len(path)):
        nodes.append(path[t])
        sources.append(order[t])
        targets.append(q[t])
        if not gap[t]:
            continue
        a, b = int(path[t]), int(nxt[t])
        qa, qb = q[t], q[(t + 1) % len(q)]
        # the path's nodes either side (-1: a route of its own, not known yet)
        before = nodes[-2] if len(nodes) > 1 else (-1 if gap[-1] else int(path[-1]))
        after = -1 if gap[(t + 1) % len(path)] else int(path[(t + 2) % len(path)])
        limit = MAX_HOPS if far is None else max(MAX_HOPS, int(far[t]))
        key = (t, a, b, before, after, limit)
        got = memo.get(key)
        if got is not None and taken.isdisjoint(got[1]) and got[2] <= taken:
            route = got[0]
        else:
            seen: tuple[set, set] = (set(), set())
            route = _route(
                a, b, before, after, neighbours, open_, taken, graph.xy, qa, qb, cuts, banned,
                limit, seen,
            )  # fmt: skip
            memo[key] = (route, *seen)
        if route is None:
            failed.append(t)
            continue
        for j, w in enumerate(route, start=1):
            taken.add(w)
            nodes.append(w)
            sources.append(-1)
            targets.append(qa + (qb - qa) * j / (len(route) + 1))
    if failed:
        raise _NoRoute(failed)
    return np.array(nodes, np.int64), np.array(sources, np.int64), np.array(targets)


def _route(
    a,
    b,
    before,
    after,
    neighbours,
    free,
    taken,
    xy,
    qa,
    qb,
    cuts,
    banned=frozenset(),
    limit=MAX_HOPS,
    seen: tuple[set, set] | None = None,
) -> list[int] | None:
    """The intermediate nodes of the shortest route from ``a`` to ``b`` through free,
    untaken nodes (at most ``limit`` + 2 edges: the assignment counted routes of up to
    ``limit`` without the nodes taken since) that cuts no corner
    (``cuts(x, y, z)``), from the path node ``before`` ``a`` to the one ``after``
    ``b``, none of its steps ``banned``; of the shortest, the one nearest the segment
    ``qa - qb``.  A search over (previous node, node) states, so its work is bounded
    by the nodes within reach.  ``xy``: the nodes' coordinates, as Python pairs.
    ``seen``: two sets, filled with the free nodes the search found untaken and
    those it found ``taken`` (all it depends on that may change)."""
    import heapq

    # (in Python floats: numpy's arithmetic on single points costs ten times more)
    ax, ay = float(qa[0]), float(qa[1])
    dx, dy = float(qb[0]) - ax, float(qb[1]) - ay
    length2 = dx * dx + dy * dy or 1.0
    memo: dict[int, float] = {}

    def off(w):
        got = memo.get(w)
        if got is None:
            px, py = xy[w]
            u = min(max(((px - ax) * dx + (py - ay) * dy) / length2, 0.0), 1.0)
            got = memo[w] = math.hypot(px - (ax + u * dx), py - (ay + u * dy))
        return got

    clear, took = (set(), set()) if seen is None else seen
    start = (before, a)
    best = {start: (0, 0.0)}
    parent: dict = {start: None}
    heap = [(0, 0.0, before, a)]
    n = len(xy)
    while heap:
        hops, dist, x, y = heapq.heappop(heap)
        if best.get((x, y)) != (hops, dist):
            continue
        if (
            y != a
            and b in neighbours.get(y, ())
            and not cuts(x, y, b)
            and not cuts(y, b, after)
            and (y * n + b if y < b else b * n + y) not in banned
        ):
            route, state = [], (x, y)
            while state != start:
                route.append(state[1])
                state = parent[state]
            route.reverse()
            return route if len(set(route)) == len(route) else None
        if hops > limit:  # (with the step to b, the route would exceed limit + 2)
            continue
        for w in neighbours.get(y, ()):
            if w == x or not free[w]:
                continue
            if w in taken:
                took.add(w)
                continue
            clear.add(w)
            if cuts(x, y, w):
                continue
            if (y * n + w if y < w else w * n + y) in banned:
                continue
            key, value = (y, w), (hops + 1, dist + off(w))
            if key not in best or value < best[key]:
                best[key], parent[key] = value, (x, y)
                heapq.heappush(heap, (*value, y, w))
    return None


def _assign(
    contour, order, points, free, edges, turns, s, graph: _Graph | None = None, banned=frozenset()
):
    """One node per point of a ring (in ``order``), consecutive ones adjacent, the
    least summed squared distance over the local size; see the module's docstring.
    ``(nodes, sources, targets)`` as :func:`_through` gives them; a step whose route
    through extra nodes :func:`_through` cannot lay is taken out and the ring
    assigned again."""
    from scipy.spatial import cKDTree

    q = contour.points[order]
    m, n = len(q), len(points)
    key = (int(order[0]), free.tobytes())
    if graph is not None and key in graph.memo:
        # laid again with more steps banned: only where the path took them, again
        cand, cost, steps, pick = graph.memo[key]
        changed = steps.ban(np.array(sorted(banned), dtype=np.int64), pick)
    else:
        idx = np.flatnonzero(free)
        if len(idx) == 0:  # (a grid of boundary and centre nodes only: a coarse polygon)
            raise SelectionError(f"{contour.source}: the graded grid has no node a point may take")
        kd = cKDTree(points[idx])
        k = min(CANDIDATES, len(idx))
        dist, near = kd.query(q, k=k)
        cand = idx[near.reshape(m, k)]
        cost = (dist.reshape(m, k) / s[:, None]) ** 2
        hops = _hop_counts(edges, n, free, cand) if graph is not None else None
        steps = _Steps(cand, edges, turns, n, hops, np.array(sorted(banned), dtype=np.int64))
        changed, pick = [], None  # points whose choices changed since the last round
    routes: dict = {}  # the route searches of the rounds so far (:func:`_through`)
    for _ in range(MAX_ROUNDS):
        deadline.check()
        if pick is not None and changed:
            # with extra nodes, rounds change a few points: solve again around them
            # (without, the whole ring is solved again, as it always was)
            pick = _resolve(cost, steps, pick, changed) if graph is not None else None
        if pick is None:
            pick = _viterbi(cand, cost, steps) if steps.every_point_steps() else None
        path = None if pick is None else cand[np.arange(m), pick]
        changed = []
        if path is None:
            raise SelectionError(
                f"{contour.source}: no graded-grid path gives every point of "
                f"{contour.ring_labels[int(contour.ring[order[0]])]} a neighbour of the next"
            )
        uniq, counts = np.unique(path, return_counts=True)
        if (counts == 1).all():
            try:
                far = steps.hops[np.arange(m), pick, np.roll(pick, -1)]
                out = _through(
                    contour, order, path, points, free, edges, graph, banned, far, routes
                )
            except _NoRoute as exc:
                for t in exc.failed:  # that jump is not to be had
                    steps.forbid(t, pick[t], pick[(t + 1) % m])
                    changed += [t, t + 1]
                continue
            if graph is not None:
                graph.memo[key] = (cand, cost, steps, pick)
            return out
        for node in uniq[counts > 1]:  # a node taken twice: the nearer point keeps it
            at = np.flatnonzero(path == node)
            d = np.hypot(*(q[at] - points[node]).T)
            loser = np.delete(at, np.argmin(d))
            cost[loser] = np.where(cand[loser] == node, np.inf, cost[loser])
            changed += loser.tolist()
    raise SelectionError(
        f"{contour.source}: no graded-grid path for "
        f"{contour.ring_labels[int(contour.ring[order[0]])]} after {MAX_ROUNDS} rounds "
        "(nodes taken twice, or routes between points through nodes the path takes)"
    )


#: Candidates of the first point a ring's assignment may start from (the nearest ones).
STARTS = 3


#: What an extra boundary node costs in the assignment (its points' squared distances,
#: in units of their local sizes, are at most a few).
EXTRA_COST = 1e3


class _Steps:
    """What :func:`_viterbi` may do at each point, built once per ring's candidates:
    ``weight[t, i, j, l]``, the cost of the step ``cand[t, j] -> cand[t + 1, l]``
    after ``cand[t - 1, i] -> cand[t, j]`` (the extra nodes it goes through, at
    :data:`EXTRA_COST` each), infinite where that step or that triple is not
    allowed.  ``hops`` (:func:`_hop_counts`): steps through free nodes;
    ``ban``: sorted keys ``lo * n + hi`` of steps not to take."""

    def __init__(self, cand, edges, turns, n, hops=None, ban=None):
        m, k = cand.shape
        self.m, self.k = m, k
        nxt = np.roll(cand, -1, axis=0)
        x, y = np.repeat(cand, k, axis=1).ravel(), np.tile(nxt, (1, k)).ravel()
        self.pair_keys = (np.minimum(x, y) * n + np.maximum(x, y)).reshape(m, k, k)
        adj = _adjacent(edges, n, x, y).reshape(m, k, k)  # cand[t, i] -> cand[t + 1, j]
        if ban is not None and len(ban):
            adj &= ~sorted_lookup(ban, self.pair_keys.ravel())[0].reshape(m, k, k)
        prv = np.roll(cand, 1, axis=0)
        # a triple cuts a corner where its ends are adjacent (or one node) and it is no
        # L-turn: the ends are looked up per pair, the turns only where they are adjacent
        a = np.broadcast_to(prv[:, :, None], (m, k, k)).ravel()
        c = np.broadcast_to(nxt[:, None, :], (m, k, k)).ravel()
        ends = (_adjacent(edges, n, a, c) | (a == c)).reshape(m, k, 1, k)
        cut = np.array(np.broadcast_to(ends, (m, k, k, k)))
        at = np.nonzero(cut)
        cut[at] = ~_l_turn(prv[at[0], at[1]], cand[at[0], at[2]], nxt[at[0], at[3]], turns, n)
        self.adj = adj
        self.ok3 = ~cut.reshape(m, k, k, k)  # cand[t - 1, i], cand[t, j], cand[t + 1, l]
        self.hops = np.zeros((m, k, k), dtype=np.int64) if hops is None else hops
        self.weight = np.empty((m, k, k, k))
        self.update(np.arange(m))

    def step(self, t):
        """Steps ``cand[t, i] -> cand[t + 1, j]`` allowed (neighbours, or through nodes)."""
        return self.adj[t] | (self.hops[t] > 0)

    def every_point_steps(self) -> bool:
        """Each point has some step to the next (else no assignment exists, and
        :func:`_viterbi` need not look: the graded grid's usual failure, a contour edge
        longer than its neighbours' cells)."""
        return bool(self.step(slice(None)).any(axis=(1, 2)).all())

    def jump(self, t):
        return np.where(~self.adj[t] & (self.hops[t] > 0), EXTRA_COST * (self.hops[t] - 1), 0.0)

    def update(self, ts) -> None:
        """Recompute ``weight`` at points ``ts`` (after :attr:`hops` changed there, also
        at the next points: a step through nodes allows the triples either side of it,
        which the path's check sees whole afterwards)."""
        ts = np.unique(np.asarray(ts) % self.m)
        through = ~self.adj[ts] & (self.hops[ts] > 0)
        before = ~self.adj[ts - 1] & (self.hops[ts - 1] > 0)
        ok = self.ok3[ts] | through[:, None, :, :] | before[:, :, :, None]
        ok &= self.step(ts)[:, None, :, :]
        self.weight[ts] = np.where(ok, self.jump(ts)[:, None, :, :], np.inf)

    def ban(self, keys: np.ndarray, pick: np.ndarray) -> list[int]:
        """Take out the steps ``keys`` (sorted ``lo * n + hi``); the points where
        ``pick`` took one of them, and the next ones."""
        hit = sorted_lookup(keys, self.pair_keys.ravel())[0].reshape(self.m, self.k, self.k)
        hit &= self.adj
        ts = np.flatnonzero(hit.any(axis=(1, 2)))
        self.adj &= ~hit
        self.update(np.r_[ts, ts + 1])
        took = ts[hit[ts, pick[ts], pick[(ts + 1) % self.m]]]
        return np.r_[took, took + 1].tolist()

    def forbid(self, t: int, i: int, j: int) -> None:
        """No step through nodes from ``cand[t, i]`` to ``cand[t + 1, j]``."""
        self.hops[t, i, j] = 0
        self.update([t, t + 1])


def _viterbi(cand, cost, steps: _Steps) -> np.ndarray | None:
    """The cheapest closed sequence of candidates with consecutive ones adjacent and no
    step ``a -> b -> c`` whose ends ``a`` and ``c`` are adjacent too (it would cut a
    corner: a triangle of three path nodes, or a cell needing both diagonals), but an
    L-turn along two sides of a leaf (``steps``: :class:`_Steps`).  Dynamic
    programming over pairs of consecutive candidates, the first two points' pair
    fixed for each start."""
    m, k = cand.shape
    inf = np.inf
    w = steps.weight
    step0 = steps.step(0)
    starts = [(x0, x1) for x0 in np.argsort(cost[0])[:STARTS] for x1 in range(k)]
    starts = [(x0, x1) for x0, x1 in starts if np.isfinite(cost[0, x0]) and step0[x0, x1]]
    if not starts or m < 3:
        return None
    s0 = np.array([x for x, _ in starts])
    s1 = np.array([y for _, y in starts])
    ns = len(starts)
    d = np.full((ns, k, k), inf)  # d[s, i, j]: point t - 1 on i, point t on j
    d[np.arange(ns), s0, s1] = cost[0, s0] + cost[1, s1] + steps.jump(0)[s0, s1]
    back = np.empty((m, ns, k, k), dtype=np.int8)
    for t in range(1, m - 1):
        tot = d[:, :, :, None] + w[t][None]
        i = np.argmin(tot, axis=1)  # (s, j, l)
        back[t + 1] = i
        d = tot.min(axis=1) + cost[t + 1][None, None, :]  # (the argmin's values)
    # close the ring: last -> first, and the triples around the start
    close = d.copy()
    last = m - 1
    for si in range(ns):
        x0, x1 = s0[si], s1[si]
        first = np.where(np.isfinite(w[0][:, x0, x1]), 0.0, inf)
        close[si] = close[si] + w[last][:, :, x0] + first[None, :]
    si, i, j = np.unravel_index(int(np.argmin(close)), close.shape)
    if not np.isfinite(close[si, i, j]):
        return None
    sel = np.empty(m, dtype=np.int64)
    sel[m - 1], sel[m - 2] = j, i
    for t in range(m - 1, 1, -1):
        sel[t - 2] = back[t, si, sel[t - 1], sel[t]]
    return sel


#: Points either side of a change that :func:`_resolve` chooses again.
WINDOW = 16


def _resolve(cost, steps: _Steps, pick: np.ndarray, changed: list[int]) -> np.ndarray | None:
    """``pick`` (a candidate index per point) chosen again within :data:`WINDOW`
    points of each of ``changed``, the rest held; a window that finds nothing is
    widened, up to the whole ring (:func:`_viterbi`)."""
    m, k = cost.shape
    pick = pick.copy()
    for u in sorted({int(c) % m for c in changed}):
        half = WINDOW
        while True:
            if 2 * half + 5 >= m:
                return None  # (the caller solves the whole ring)
            got = _window(cost, steps, pick, u - half, u + half)
            if got is not None:
                pick = got
                break
            half *= 2
    return pick


def _window(cost, steps: _Steps, pick: np.ndarray, t0: int, t1: int) -> np.ndarray | None:
    """``pick`` with points ``t0..t1`` (cyclic) chosen again at least cost, the two
    points either side held, or None if no choice fits."""
    m, k = cost.shape
    w = steps.weight
    ts = np.arange(t0, t1 + 1) % m
    a, b = pick[(t0 - 2) % m], pick[(t0 - 1) % m]
    d = np.full((k, k), np.inf)  # d[i, j]: point t - 1 on i, point t on j
    d[a, b] = 0.0
    back = np.empty((len(ts), k, k), dtype=np.int8)
    for n_, t in enumerate(ts):
        tot = d[:, :, None] + w[(t - 1) % m]  # (i, j, l): l for point t
        i = np.argmin(tot, axis=0)
        back[n_] = i
        d = tot.min(axis=0) + cost[t][None, :]
    f1, f2 = pick[(t1 + 1) % m], pick[(t1 + 2) % m]
    end = d + w[t1 % m][:, :, f1] + w[(t1 + 1) % m][:, f1, f2][None, :]
    i, j = np.unravel_index(int(np.argmin(end)), end.shape)
    if not np.isfinite(end[i, j]):
        return None
    out = pick.copy()
    out[ts[-1]], prev = j, i
    for n_ in range(len(ts) - 1, 0, -1):
        out[ts[n_ - 1]] = prev
        prev = back[n_, prev, out[ts[n_]]]
    return out


def _force_diagonals(contour, n_leaves, plain: _Plain, path_nodes, path_ring) -> np.ndarray:
    """Each leaf's diagonal: forced by a diagonal path step, or else by an L-turn along
    two of its sides (the diagonal through the corner; of a U-turn's two, the first),
    '/' elsewhere.  Two diagonal steps in one leaf are a SelectionError; a diagonal
    step against an L-turn leaves an ear, which :func:`_check` judges."""
    n = plain.n
    nodes, ring = path_nodes, path_ring
    nxt = np.empty_like(nodes)
    prv = np.empty_like(nodes)
    for r in np.unique(ring):
        on = np.flatnonzero(ring == r)
        nxt[on], prv[on] = np.roll(nodes[on], -1), np.roll(nodes[on], 1)
    force = np.full(n_leaves, -1, dtype=np.int64)
    # diagonal steps
    k = np.minimum(nodes, nxt) * n + np.maximum(nodes, nxt)
    hit, at = sorted_lookup(plain.diag_keys, k)
    leaf, d = plain.diag_leaf[at[hit]], plain.diag_dir[at[hit]]
    both = np.unique(leaf[d == 1])
    clash = np.intersect1d(np.unique(leaf[d == 0]), both)
    if len(clash):
        steps = np.flatnonzero(hit)[np.isin(leaf, clash)]
        t = int(steps[0])
        raise _Clash(
            f"{contour.source}: the graded-grid path needs both diagonals of one cell "
            f"near path node {t} of ring {int(ring[t])}",
            set(k[steps].tolist()),
        )
    force[leaf] = d
    # L-turns, where no diagonal step decided (a U-turn: the first of its two)
    hit, at = sorted_lookup(plain.turn_keys, (prv * n + nodes) * n + nxt)
    leaf, d = plain.turn_leaf[at[hit]], plain.turn_dir[at[hit]]
    first = np.unique(leaf, return_index=True)[1]
    leaf, d = leaf[first], d[first]
    undecided = force[leaf] < 0
    force[leaf[undecided]] = d[undecided]
    out = np.zeros(n_leaves, dtype=np.uint8)
    out[force >= 0] = force[force >= 0]
    return out


def _fair_ears(sel: GradedSelection, ears: np.ndarray) -> np.ndarray:
    """Per ear triangle (three consecutive path nodes): its three targets make a
    triangle of the same orientation with no angle under :data:`EAR_ANGLE`."""
    where = np.full(sel.grid.n_nodes, -1, dtype=np.int64)
    where[sel.path_nodes] = np.arange(len(sel.path_nodes))
    q = sel.path_targets[where[ears]]  # (e, 3, 2)
    from ..geometry import signed_areas
    from ..quality import measures

    flat = q.reshape(-1, 2)
    t = np.arange(len(flat)).reshape(-1, 3)
    area = signed_areas(flat, t)
    smallest = measures(flat, t)[0]
    return (area > 0) & (smallest >= EAR_ANGLE)


#: An ear left by a U-turn is accepted when its contour points' triangle has no angle
#: under this (degrees; tuned on the corpus: 5 lets a coastline's spikes through,
#: which 10 refused, ``benchmarks/MEASURED.md``).
EAR_ANGLE = 5.0


def _check(contour: Contour, sel: GradedSelection) -> None:
    """Each ring's path a simple counter-clockwise polygon, no triangle with three
    consecutive path nodes."""
    p = sel.grid.points
    for r in np.unique(sel.path_ring):
        ring = p[sel.path_nodes[sel.path_ring == r]]
        if signed_area(ring) <= 0 or not shapely.is_simple(shapely.LinearRing(ring)):
            raise SelectionError(
                f"{contour.source}: the graded-grid path of {contour.ring_labels[r]} is not a "
                "simple counter-clockwise ring"
            )
    # a triangle of three consecutive path nodes collapses as the contour flattens
    # there; three path nodes from two sides of a thin part span it, which is fine
    n = sel.grid.n_nodes
    pos = np.full(n, -1, dtype=np.int64)
    ring_of = np.full(n, -1, dtype=np.int64)
    size = np.zeros(n, dtype=np.int64)
    for r in np.unique(sel.path_ring):
        nodes = sel.path_nodes[sel.path_ring == r]
        pos[nodes] = np.arange(len(nodes))
        ring_of[nodes] = r
        size[nodes] = len(nodes)
    tri = sel.triangles()
    pt, rt = pos[tri], ring_of[tri]
    on = (pt >= 0).all(axis=1) & (rt[:, 0] == rt[:, 1]) & (rt[:, 1] == rt[:, 2])
    p, m = np.sort(pt[on], axis=1), size[tri[on, 0]]
    span = np.minimum.reduce([p[:, 2] - p[:, 0], m - (p[:, 1] - p[:, 0]), m - (p[:, 2] - p[:, 1])])
    ear = span <= 2
    if ear.any():
        # an ear whose three contour points make a proper triangle turning the same way
        # (a U-turn at the end of a strip) keeps its area as the path lands on them
        idx = np.flatnonzero(on)[ear]
        ear[ear] = ~_fair_ears(sel, tri[idx])
    if ear.any():
        bad = tri[np.flatnonzero(on)[ear]]
        x, y = sel.grid.points[bad[0]].mean(axis=0)
        pairs = np.concatenate([bad[:, [0, 1]], bad[:, [1, 2]], bad[:, [2, 0]]])
        raise _Clash(
            f"{contour.source}: a graded-grid triangle has three consecutive path nodes "
            f"near ({x:.6g}, {y:.6g})",
            set((pairs.min(axis=1) * n + pairs.max(axis=1)).tolist()),
        )
