"""Stage 1: background grid, node selection (paper, Appendix A) and grid path.

Data flow::

    Contour --choose_grid--> Grid --select_nodes--> one node per contour point
            --build_path--> closed grid path (gaps filled with extra boundary
                            nodes on the contour edge) --validate--> forced
                            cell diagonals --> background triangles

The background triangulation is built *after* selection (docs/method.md): a
diagonal step of the path forces that cell's diagonal, and at an L-turn
the corner cell is split through the corner node, so that no triangle has
three consecutive path nodes (it would collapse as the contour flattens).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .. import deadline
from ..contour import Contour, grown_box
from ..errors import LimitError, OptionError, SelectionError
from ..geometry import next_on_ring, signed_area, signed_areas

#: Default cap on background grid nodes.  A full solve costs about 1.2 kB per
#: node at peak (sparse LU of a 2D Laplacian), so 8e6 nodes stay well inside
#: this machine's 24 GiB while leaving room for the rest of the pipeline.
DEFAULT_MAX_NODES = 8_000_000

#: The largest ``--max-nodes`` taken: beyond it no machine holds the grid anyway, and
#: counts stay well inside the integers the arrays index with.
MAX_NODES_CEILING = 1_000_000_000

#: ``--grid`` choices: ``graded`` is the constructed graded quadtree grid
#: (:mod:`.construct`); ``uniform`` is Appendix A's grid; ``auto`` is ``graded``, or
#: ``uniform`` when ``--h`` is given.
GRIDS = ("auto", "uniform", "graded")

#: Default margin between the contour's bounding box and the background box, in cells.
DEFAULT_MARGIN_CELLS = 3

#: How many times the default h is halved when the grid path touches itself.
MAX_REFINEMENTS = 3

DIAG_SLASH = 0  # cell split along (i, j)-(i+1, j+1)
DIAG_BACKSLASH = 1  # cell split along (i+1, j)-(i, j+1)


@dataclass(frozen=True)
class Grid:
    """A Cartesian background grid of ``nx`` by ``ny`` cells.

    Node ``(i, j)`` sits at ``(x0 + i*hx, y0 + j*hy)`` and has id ``j*(nx+1) + i``.
    """

    x0: float
    y0: float
    hx: float
    hy: float
    nx: int
    ny: int

    @property
    def n_nodes(self) -> int:
        return (self.nx + 1) * (self.ny + 1)

    @property
    def box(self) -> tuple[float, float, float, float]:
        return (self.x0, self.y0, self.x0 + self.nx * self.hx, self.y0 + self.ny * self.hy)

    def node_id(self, i: np.ndarray | int, j: np.ndarray | int) -> np.ndarray:
        return np.asarray(j) * (self.nx + 1) + np.asarray(i)

    def node_ij(self, nid: np.ndarray | int) -> tuple[np.ndarray, np.ndarray]:
        nid = np.asarray(nid)
        return nid % (self.nx + 1), nid // (self.nx + 1)

    def coords(self, nid: np.ndarray | int | None = None) -> np.ndarray:
        """Undeformed coordinates of the given nodes (all nodes by default)."""
        if nid is None:
            nid = np.arange(self.n_nodes)
        i, j = self.node_ij(nid)
        return np.column_stack([self.x0 + i * self.hx, self.y0 + j * self.hy])

    def boundary_nodes(self) -> np.ndarray:
        i, j = self.node_ij(np.arange(self.n_nodes))
        return np.flatnonzero((i == 0) | (j == 0) | (i == self.nx) | (j == self.ny))

    def box_ring(self) -> np.ndarray:
        """The box's nodes counter-clockwise from the lower left corner."""
        nx, ny, w = self.nx, self.ny, self.nx + 1
        bottom = np.arange(nx)
        right = nx + np.arange(ny) * w
        top = ny * w + np.arange(nx, 0, -1)
        left = np.arange(ny, 0, -1) * w
        return np.concatenate([bottom, right, top, left])

    def side_edges(self) -> tuple[int, int, int, int]:
        """How many edges of :meth:`box_ring` lie on the bottom, right, top, left sides."""
        return (self.nx, self.ny, self.nx, self.ny)


def estimate_nodes(width: float, height: float, h: float) -> float:
    """Grid nodes for a box, computed in floating point (never overflows; inf for a box
    no grid of step ``h`` spans)."""
    cells = (width / h - 1e-9, height / h - 1e-9)
    if not all(math.isfinite(c) for c in cells):
        return math.inf
    return (math.ceil(cells[0]) + 1.0) * (math.ceil(cells[1]) + 1.0)


def choose_grid(
    contour: Contour,
    h: float | None = None,
    box: tuple[float, float, float, float] | None = None,
    margin: float | None = None,
    max_nodes: int = DEFAULT_MAX_NODES,
    exterior: bool = False,
) -> tuple[Grid, dict]:
    """Lay the background grid.

    ``h`` defaults to Appendix A's ``0.9 * d_c / sqrt(2)`` with ``d_c`` the
    smallest distance between two contour points.  The box defaults to the
    contour's bounding box grown by ``margin`` (default 3 cells; for an
    ``exterior`` mesh, the contour's larger extent).  An exterior mesh needs
    at least one cell between the contour and the box.  Cells are
    never larger than ``h``: when the box is not a whole number of cells, the
    step along that axis is shrunk slightly so the box is kept exactly.

    Raises :class:`LimitError` (with the estimate and a hint) before allocating
    anything when the grid would exceed ``max_nodes``.
    """
    p = contour.points
    d_c, ka, kb = contour.min_spacing()
    info: dict = {"d_c": d_c, "h_rule": "given"}
    if h is None:
        h = 0.9 * d_c / math.sqrt(2.0)
        info["h_rule"] = "appendix-a"
    if not (h > 0 and math.isfinite(h)):
        raise OptionError(f"--h must be a positive number, got {h}")
    lo, hi = p.min(axis=0), p.max(axis=0)
    default_margin = box is None and margin is None
    if box is None:
        m = DEFAULT_MARGIN_CELLS * h if margin is None else float(margin)
        if exterior and margin is None:
            m = float(np.ptp(p, axis=0).max())
        if not (m >= 0 and math.isfinite(m)):
            raise OptionError(f"--margin must be a non-negative number, got {margin}")
        box = grown_box(contour, lo, hi, m)
    else:
        box = checked_box(contour, box)
    width, height = box[2] - box[0], box[3] - box[1]
    est = estimate_nodes(width, height, h)
    info["estimated_nodes"] = est
    if est > max_nodes:
        margin_cells = DEFAULT_MARGIN_CELLS if default_margin and not exterior else 0
        size = (hi - lo) if default_margin and not exterior else (width, height)
        raise LimitError(
            _too_many_nodes(
                contour,
                est,
                h,
                info["h_rule"],
                d_c,
                ka,
                kb,
                tuple(float(v) for v in size),
                margin_cells,
                max_nodes,
            )
        )
    nx = max(1, math.ceil(width / h - 1e-9))
    ny = max(1, math.ceil(height / h - 1e-9))
    grid = Grid(box[0], box[1], width / nx, height / ny, nx, ny)
    if exterior:
        gap = np.minimum(
            np.minimum(p[:, 0] - box[0], box[2] - p[:, 0]) / grid.hx,
            np.minimum(p[:, 1] - box[1], box[3] - p[:, 1]) / grid.hy,
        )
        if gap.min() < 1.0:
            k = int(np.argmin(gap))
            raise OptionError(
                f"{contour.source}: {contour.where(k)} is less than one cell from the box "
                f"{_fmt_box(box)}; an exterior mesh needs room around the contour: give a "
                "larger --box or --margin"
            )
    info["h"] = h
    return grid, info


def _fmt_box(box) -> str:
    return ",".join(f"{v:g}" for v in box)


def checked_box(contour: Contour, box) -> tuple[float, float, float, float]:
    """A given ``--box`` as floats, checked: ordered, and holding every contour point
    (an :class:`OptionError` naming the first one outside)."""
    from ..contour import MAX_COORDINATE

    box = tuple(float(v) for v in box)
    if not (box[0] < box[2] and box[1] < box[3]):
        raise OptionError(f"--box {_fmt_box(box)}: need XMIN < XMAX and YMIN < YMAX")
    if not max(abs(v) for v in box) <= MAX_COORDINATE:  # (NaN fails too)
        raise OptionError(
            f"--box {_fmt_box(box)}: its sides must lie within {MAX_COORDINATE:g} of 0, "
            "as the contour's points do (its areas would overflow)"
        )
    p = contour.points
    out = (p[:, 0] < box[0]) | (p[:, 0] > box[2]) | (p[:, 1] < box[1]) | (p[:, 1] > box[3])
    if out.any():
        k = int(np.argmax(out))
        raise OptionError(
            f"{contour.source}: {contour.where(k)} lies outside --box {_fmt_box(box)}"
        )
    return box


#: Consecutive spacings varying less than this count as even in the refusal's hint.
EVEN_SPACING_RATIO = 4.0


def _too_many_nodes(contour, est, h, rule, d_c, ka, kb, box_size, margin_cells, max_nodes) -> str:
    """The refusal message, with a hint that only names an ``--h`` known to be workable.

    Every contour point needs a grid node of its own, so ``h`` cannot be much
    larger than the spacing where points crowd: the largest safe guess is the
    smallest spacing between consecutive points (for evenly spaced contours
    that is the spacing itself, which gives no extra nodes at all).  ``box_size``
    is the box without the margin when ``margin_cells`` is set (the default
    margin of that many cells), else the fixed box.
    """
    seg = contour.edge_lengths()
    ratio = float(seg.max() / seg.min())
    why = (
        f"h = {h:.3g} from the smallest spacing {d_c:.3g} (points {ka} and {kb})"
        if rule == "appendix-a"
        else f"--h {h:.3g}"
    )
    head = (
        f"{contour.source}: the background grid would need {est:.2g} nodes ({why}), "
        f"over --max-nodes {max_nodes}"
    )
    h_try = float(seg.min())
    grow = 2 * margin_cells * h_try
    est_try = estimate_nodes(box_size[0] + grow, box_size[1] + grow, h_try)
    if h_try > h and est_try <= max_nodes:
        return (
            f"{head}: try --h {h_try:.3g} (the smallest spacing between consecutive "
            "points; with a larger h crowded points get no node of their own)"
        )
    median, fit = float(np.median(seg)), _fitting_spacing(box_size, margin_cells, max_nodes)
    example = (
        f"{median:.3g}, its median spacing"
        if median >= fit
        else f"{fit:.2g}, about the finest spacing this box allows within --max-nodes"
    )
    fix = (
        "use fewer contour points"
        if ratio <= EVEN_SPACING_RATIO and median >= fit
        else "re-space it with --resample SPACING (corners kept; e.g. --resample "
        f"{example}; the given points are then not all boundary nodes)"
    )
    return (
        f"{head}; even h = {h_try:.3g}, the smallest spacing between consecutive points, "
        f"would need {est_try:.2g} nodes (the spacing varies {ratio:.3g}x along the contour): "
        f"{fix} or raise --max-nodes"
    )


def _fitting_spacing(box_size, margin_cells: int, max_nodes: int) -> float:
    """A contour spacing whose Appendix A grid (h = 0.9 d / sqrt 2) fits ``max_nodes``
    on this box (with a tenth to spare): the smallest ``--resample`` worth suggesting."""
    w, hgt = box_size
    h = math.sqrt(w * hgt / max_nodes)
    for _ in range(20):  # the margin grows with h: a few fixed-point steps
        h = math.sqrt((w + 2 * margin_cells * h) * (hgt + 2 * margin_cells * h) / max_nodes)
    return 1.1 * h * math.sqrt(2) / 0.9


#: The narrow band reaches this many cells (grid steps, in i or j) past the
#: nearest path node, and at least :data:`BAND_REACH` times the largest distance a
#: path node travels.  With the quality stage a band of 4 cells gives the same
#: smallest angles as the whole grid (tests/test_band.py allows 0.05 degrees) at
#: about half the cost of 8 (``benchmarks/MEASURED.md``).
BAND_CELLS = 4
BAND_REACH = 3.0


def _dilate(on: np.ndarray, reach: int, axis: int) -> np.ndarray:
    """True where ``on`` has a True within ``reach`` places along ``axis``.

    (``scipy.ndimage.maximum_filter`` does this too, but its import is slow.)
    """
    c = np.cumsum(on, axis=axis, dtype=np.int64)
    c = np.concatenate([np.zeros_like(c.take([0], axis=axis)), c], axis=axis)
    n = on.shape[axis]
    hi = np.minimum(np.arange(n) + reach + 1, n)
    lo = np.maximum(np.arange(n) - reach, 0)
    return c.take(hi, axis=axis) > c.take(lo, axis=axis)


@dataclass
class Selection:
    """The result of stage 1: everything ``deform`` needs.

    ``path_nodes[t]`` is the grid node moved onto ``path_targets[t]``;
    ``path_source[t]`` is the input index of the contour point it carries, or
    -1 for an extra boundary node placed on a contour edge; ``path_ring[t]``
    is its ring.  Each ring's path runs counter-clockwise, ring after ring.
    ``diagonals[c]`` is the split of cell ``c``.  ``exterior``: the mesh is
    the box minus the contour.
    """

    grid: Grid
    path_nodes: np.ndarray
    path_targets: np.ndarray
    path_source: np.ndarray
    diagonals: np.ndarray
    h: float
    h_rule: str
    searched_further: int = 0
    refinements: int = 0
    notes: list[str] = field(default_factory=list)
    path_rule: str = "appendix-a"
    path_ring: np.ndarray | None = None
    exterior: bool = False
    #: the deformation folds no triangle (Appendix A's grid), or fails
    mends_folds: ClassVar[bool] = False
    #: :meth:`triangles`, built on first use (every stage after selection needs them)
    _triangles: np.ndarray | None = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self):
        if self.path_ring is None:
            self.path_ring = np.zeros(len(self.path_nodes), dtype=np.int64)

    @property
    def extra_nodes(self) -> int:
        return int(np.count_nonzero(self.path_source < 0))

    def triangles(self) -> np.ndarray:
        """The background grid's triangles (built once, then shared: do not modify)."""
        if self._triangles is None:
            self._triangles = grid_triangles(self.grid, self.diagonals)
        return self._triangles

    def inside_triangles(self) -> np.ndarray:
        """Per triangle of :meth:`triangles`: inside the rings' paths (even-odd)."""
        n_rings = int(self.path_ring.max()) + 1 if len(self.path_ring) else 0
        return topology_inside(self.grid, self.diagonals, self.path_nodes, self.path_ring, n_rings)

    def held_nodes(self) -> np.ndarray:
        """The nodes the deformation holds where they are: the box's."""
        return self.grid.boundary_nodes()

    def kept_triangles(self) -> np.ndarray:
        """Per triangle: on the domain's side of the paths (outside them for an
        exterior mesh)."""
        inside = self.inside_triangles()
        return ~inside if self.exterior else inside

    def size_field(self, contour, growth, max_h, max_nodes, box=None) -> None:
        """None: Appendix A's grid is uniform, and its mesh stays as the paper builds it
        (stage 3 coarsens nothing)."""
        return None

    def band_nodes(self) -> np.ndarray | None:
        """Boolean node mask of the narrow band (:data:`BAND_CELLS`), or None when it
        would cover half the grid."""
        g = self.grid
        h = min(g.hx, g.hy)
        travel = np.hypot(*(self.path_targets - g.coords(self.path_nodes)).T).max(initial=0.0)
        reach = max(BAND_CELLS, int(np.ceil(BAND_REACH * travel / h)))
        on = np.zeros((g.ny + 1, g.nx + 1), dtype=bool)
        i, j = g.node_ij(self.path_nodes)
        on[j, i] = True
        band = _dilate(_dilate(on, reach, 0), reach, 1).ravel()
        return band if band.sum() < 0.5 * g.n_nodes else None


def grid_triangles(
    grid: Grid, diagonals: np.ndarray, cells: np.ndarray | None = None
) -> np.ndarray:
    """Counter-clockwise triangles of the grid, two per cell, split as ``diagonals`` says.

    ``cells`` (cell ids ``j * nx + i``) restricts them to those cells, in that order.
    """
    nx = grid.nx
    if cells is None:  # every cell: corner ids without a division per cell
        n00 = (np.arange(grid.ny)[:, None] * (nx + 1) + np.arange(nx)).ravel()
        slash = diagonals == DIAG_SLASH
    else:
        n00 = cells // nx * (nx + 1) + cells % nx
        slash = diagonals[cells] == DIAG_SLASH
    # '/': (n00, n10, n11), (n00, n11, n01); '\\': (n00, n10, n01), (n10, n11, n01)
    tri = np.empty((len(n00), 2, 3), dtype=np.int64)
    tri[:, 0, 0] = n00
    tri[:, 0, 1] = n00 + 1
    tri[:, 0, 2] = n00 + nx + 1 + slash
    tri[:, 1, 0] = n00 + ~slash
    tri[:, 1, 1] = n00 + nx + 2
    tri[:, 1, 2] = n00 + nx + 1
    return tri.reshape(-1, 3)


class _Visibility:
    """Whether the straight segment from a contour point to a node crosses a contour.

    A node seen from ``Q_k`` only across another part of the contour would put
    ``P_k`` on the wrong side of it (a thin trailing edge: an upper-surface
    point taking a node below the lower surface) and the path would cross
    itself.  Every ring's edges block; the two edges at ``Q_k`` touch it
    there and are ignored.  ``q`` holds all rings' points, ring after ring;
    ``nxt[k]`` is the point after ``k`` on its ring.
    """

    def __init__(self, q: np.ndarray, nxt: np.ndarray | None = None):
        import shapely

        self.q = q
        self.nxt = np.roll(np.arange(len(q)), -1) if nxt is None else nxt
        self.prv = np.empty_like(self.nxt)
        self.prv[self.nxt] = np.arange(len(q))
        self.shapely = shapely
        self.edges = shapely.linestrings(np.stack([q, q[self.nxt]], axis=1))
        self.tree = shapely.STRtree(self.edges)

    def visible(self, k: np.ndarray, xy: np.ndarray) -> np.ndarray:
        """For pairs (contour point k[r], node at xy[r]) -> True when nothing is crossed."""
        shp = self.shapely
        # stop just short of the node: a node lying on the contour (at another
        # point, say) touches it there without being across it
        end = self.q[k] + (xy - self.q[k]) * (1.0 - 1e-9)
        segs = shp.linestrings(np.stack([self.q[k], end], axis=1))
        si, ei = self.tree.query(segs, predicate="intersects")
        kk = k[si]
        adjacent = (ei == kk) | (ei == self.prv[kk])
        blocked = np.zeros(len(k), dtype=bool)
        blocked[si[~adjacent]] = True
        return ~blocked


class NoFreeNode(SelectionError):
    """No free node that point ``k`` (counter-clockwise index) can see is left on the grid."""

    def __init__(self, k: int):
        super().__init__(f"no free grid node left for point {k}")
        self.k = k


def select_nodes(
    grid: Grid,
    q: np.ndarray,
    taken: set[int] | None = None,
    vis: _Visibility | None = None,
    offset: int = 0,
) -> tuple[np.ndarray, int]:
    """Appendix A: for each point, the nearest free corner of the cell holding it.

    Points are taken in the order given.  A corner counts only if the point
    sees it without crossing the contour (see :class:`_Visibility`).  When no
    corner is free the search widens ring by ring around the cell and takes
    the nearest free visible node (the pseudo-code leaves such a point
    unassigned).  Returns grid node ids and how many points needed the wider
    search.  With several rings, ``taken`` holds the nodes earlier rings took
    (it is updated), ``vis`` sees all rings, and ``q`` is ring ``vis.q[offset:]``.
    """
    taken = set() if taken is None else taken
    out = np.empty(len(q), dtype=np.int64)
    further = 0
    t = (q[:, 0] - grid.x0) / grid.hx
    s = (q[:, 1] - grid.y0) / grid.hy
    ci = np.clip(np.floor(t).astype(np.int64), 0, grid.nx - 1)
    cj = np.clip(np.floor(s).astype(np.int64), 0, grid.ny - 1)
    di = np.array([0, 1, 0, 1])
    dj = np.array([0, 0, 1, 1])
    II, JJ = ci[:, None] + di, cj[:, None] + dj
    dist = np.hypot((II - t[:, None]) * grid.hx, (JJ - s[:, None]) * grid.hy)
    vis = _Visibility(q) if vis is None else vis
    corner_xy = np.column_stack([grid.x0 + II.ravel() * grid.hx, grid.y0 + JJ.ravel() * grid.hy])
    seen = vis.visible(np.repeat(np.arange(len(q)) + offset, 4), corner_xy).reshape(-1, 4)
    rank = np.argsort(dist, axis=1, kind="stable")
    ids = JJ * (grid.nx + 1) + II
    tangent = q - np.roll(q, 1, axis=0)
    prev_ij = None
    for k in range(len(q)):
        chosen = -1
        for c in rank[k]:
            nid = int(ids[k, c])
            if (
                seen[k, c]
                and nid not in taken
                and _forward(grid, prev_ij, II[k, c], JJ[k, c], tangent[k])
            ):
                chosen = nid
                break
        if chosen < 0:
            further += 1
            chosen = _search_further(
                grid,
                vis,
                k + offset,
                t[k],
                s[k],
                int(ci[k]),
                int(cj[k]),
                taken,
                prev_ij,
                tangent[k],
            )
            if chosen < 0:
                raise NoFreeNode(k)
        taken.add(chosen)
        out[k] = chosen
        prev_ij = (chosen % (grid.nx + 1), chosen // (grid.nx + 1))
    return out, further


def _forward(grid: Grid, prev_ij, i, j, tangent) -> bool:
    """A node does not lie behind the previous selected node along the contour's direction."""
    if prev_ij is None:
        return True
    return (i - prev_ij[0]) * grid.hx * tangent[0] + (j - prev_ij[1]) * grid.hy * tangent[1] >= 0


def _search_further(
    grid: Grid,
    vis: _Visibility,
    k: int,
    t: float,
    s: float,
    i: int,
    j: int,
    taken: set[int],
    prev_ij=None,
    tangent=None,
) -> int:
    """Nearest free, visible and forward node in widening rings; forward is dropped past r=3.

    Returns -1 when the whole grid has been searched.
    """
    for r in range(1, max(grid.nx, grid.ny) + 1):
        ii = np.arange(max(0, i - r), min(grid.nx, i + 1 + r) + 1)
        jj = np.arange(max(0, j - r), min(grid.ny, j + 1 + r) + 1)
        gi, gj = np.meshgrid(ii, jj)
        gi, gj = gi.ravel(), gj.ravel()
        ids = gj * (grid.nx + 1) + gi
        free = np.array([int(n) not in taken for n in ids])
        if r <= 3 and prev_ij is not None:
            free &= _forward(grid, prev_ij, gi, gj, tangent)
        if free.any():
            xy = np.column_stack([grid.x0 + gi[free] * grid.hx, grid.y0 + gj[free] * grid.hy])
            ok = vis.visible(np.full(len(xy), k), xy)
            if ok.any():
                d = np.hypot((gi[free] - t) * grid.hx, (gj[free] - s) * grid.hy)
                d[~ok] = np.inf
                return int(ids[free][np.lexsort((gi[free], gj[free], d))[0]])
    return -1


def build_path(
    grid: Grid, sel: np.ndarray, q: np.ndarray, src: np.ndarray, taken: set[int] | None = None
):
    """Close the selected nodes into a grid path of 8-neighbour steps.

    Where two consecutive selected nodes are ``D >= 2`` cells apart, the grid
    nodes of a shortest 8-connected route between them become extra boundary
    nodes, carried to evenly spaced points of the contour edge.  The route is
    the digital straight line when its nodes are free, otherwise the route
    closest to that line that avoids every node already on the path (see
    :func:`_route`); nodes in ``taken`` (other rings) are avoided too.
    Returns ``(nodes, targets, source)`` arrays over the path.
    """
    i, j = grid.node_ij(sel)
    m = len(sel)
    used = {int(n) for n in sel} | (taken or set())
    nodes, targets, source = [], [], []
    for k in range(m):
        k2 = (k + 1) % m
        nodes.append(int(sel[k]))
        targets.append(q[k])
        source.append(int(src[k]))
        a, b = (int(i[k]), int(j[k])), (int(i[k2]), int(j[k2]))
        D = max(abs(b[0] - a[0]), abs(b[1] - a[1]))
        if D < 2:
            continue
        deadline.check()  # (a route may search a window of many cells)
        f = np.arange(1, D) / D
        fi = a[0] + np.floor((b[0] - a[0]) * f + 0.5).astype(np.int64)
        fj = a[1] + np.floor((b[1] - a[1]) * f + 0.5).astype(np.int64)
        fill = grid.node_id(fi, fj).tolist()
        if any(n in used for n in fill):
            fill = _route(grid, a, b, used) or fill  # keep the collision for the error
        f = np.arange(1, len(fill) + 1) / (len(fill) + 1)
        nodes.extend(fill)
        used.update(fill)
        targets.extend(q[k] + f[:, None] * (q[k2] - q[k]))
        source.extend([-1] * len(fill))
    return (
        np.asarray(nodes, dtype=np.int64),
        np.asarray(targets, dtype=np.float64),
        np.asarray(source, dtype=np.int64),
    )


#: :func:`_route` checks the search's time bound after this many nodes.
CHECK_EVERY = 4096


def _route(grid: Grid, a, b, used: set[int], pad: int = 2) -> list[int] | None:
    """Interior nodes of the shortest 8-connected route a -> b avoiding ``used``.

    Dijkstra in the window around a and b grown by ``pad`` cells; each step
    costs 1 plus a small penalty for distance from the straight line, so among
    routes of equal length the one nearest the line wins.  None if no route.
    """
    import heapq

    i0, i1 = max(0, min(a[0], b[0]) - pad), min(grid.nx, max(a[0], b[0]) + pad)
    j0, j1 = max(0, min(a[1], b[1]) - pad), min(grid.ny, max(a[1], b[1]) + pad)
    dx, dy = b[0] - a[0], b[1] - a[1]
    norm = float(np.hypot(dx, dy))
    w = grid.nx + 1

    def off_line(i, j):
        return abs((i - a[0]) * dy - (j - a[1]) * dx) / norm

    best = {a: 0.0}
    came: dict = {}
    heap = [(0.0, a)]
    pops = 0
    while heap:
        cost, u = heapq.heappop(heap)
        pops += 1
        if pops % CHECK_EVERY == 0:
            deadline.check()  # (a window of a long edge on a fine grid: millions of cells)
        if u == b:
            out = []
            while came[u] != a:
                u = came[u]
                out.append(u[1] * w + u[0])
            return out[::-1]
        if cost > best[u]:
            continue
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                v = (u[0] + di, u[1] + dj)
                if v == u or not (i0 <= v[0] <= i1 and j0 <= v[1] <= j1):
                    continue
                if v != b and v[1] * w + v[0] in used:
                    continue
                c = cost + 1.0 + 0.01 * off_line(*v)
                if c < best.get(v, np.inf):
                    best[v] = c
                    came[v] = u
                    heapq.heappush(heap, (c, v))
    return None


def force_diagonals(
    grid: Grid, nodes: np.ndarray, targets: np.ndarray | None = None, ring: np.ndarray | None = None
):
    """Cell splits forced by the path(s), or the index of the first conflict.

    ``ring`` tells which closed path each entry is on (default: one path);
    a cell forced by two rings is a conflict too.

    Returns ``(diagonals, None)`` or ``(None, path_index)`` where the path
    touches itself: two crossing diagonal steps in one cell, or a cell asked
    for both splits by rules that do not come from one U-turn.

    A U-turn (two consecutive L-turns around one cell: the end of a strip one
    cell wide, as at a sharp trailing edge) leaves no split without a
    triangle of three consecutive path nodes; there the split whose worse
    triangle is fuller at ``targets`` is taken (``'/'`` without targets).
    """
    i, j = grid.node_ij(nodes)
    i, j = np.asarray(i), np.asarray(j)
    nxt = next_on_ring(np.zeros(len(nodes), np.int64) if ring is None else ring)
    prv = np.empty_like(nxt)
    prv[nxt] = np.arange(len(nxt))
    ni, nj = i[nxt], j[nxt]
    pi, pj = i[prv], j[prv]
    di, dj = ni - i, nj - j  # step out of each node
    qi, qj = i - pi, j - pj  # step into each node
    cells, dirs, where, kind = [], [], [], []
    # diagonal steps force their own diagonal
    diag = (di != 0) & (dj != 0)
    cells.append(np.minimum(j, nj)[diag] * grid.nx + np.minimum(i, ni)[diag])
    dirs.append(np.where(di[diag] * dj[diag] > 0, DIAG_SLASH, DIAG_BACKSLASH))
    where.append(np.flatnonzero(diag))
    kind.append(np.zeros(int(diag.sum()), dtype=np.int8))
    # L-turns split the corner cell through the corner node
    axis_in = (qi == 0) ^ (qj == 0)
    axis_out = (di == 0) ^ (dj == 0)
    lturn = axis_in & axis_out & (qi * di + qj * dj == 0)
    ci = np.minimum(np.minimum(pi, ni), i)[lturn]
    cj = np.minimum(np.minimum(pj, nj), j)[lturn]
    at_diag_slash = (i[lturn] - ci) == (j[lturn] - cj)
    cells.append(cj * grid.nx + ci)
    dirs.append(np.where(at_diag_slash, DIAG_SLASH, DIAG_BACKSLASH))
    where.append(np.flatnonzero(lturn))
    kind.append(np.ones(int(lturn.sum()), dtype=np.int8))
    cells_a = np.concatenate(cells)
    dirs_a = np.concatenate(dirs)
    where_a = np.concatenate(where)
    kind_a = np.concatenate(kind)
    order = np.lexsort((where_a, cells_a))
    cs, ds, ws, ks = cells_a[order], dirs_a[order], where_a[order], kind_a[order]
    uniq, start, count = np.unique(cs, return_index=True, return_counts=True)
    multi = np.flatnonzero(count > 1)
    uturn_cells = []
    for g in multi:
        s0 = start[g]
        w0, w1 = int(ws[s0]), int(ws[s0 + 1])
        # exactly two L-turns at consecutive path positions: a U-turn
        if count[g] == 2 and ks[s0] == 1 and ks[s0 + 1] == 1 and (nxt[w0] == w1 or nxt[w1] == w0):
            uturn_cells.append(int(uniq[g]))
            continue
        # two diagonal steps in one cell always cross or retrace; an L-turn
        # sharing a cell with another rule means the path wraps that cell
        return None, int(ws[s0 + 1])
    diagonals = np.full(grid.nx * grid.ny, DIAG_SLASH, dtype=np.uint8)
    single = np.isin(cs, uturn_cells, invert=True)
    diagonals[cs[single]] = ds[single]
    if uturn_cells and targets is not None:
        at = dict(zip(nodes.tolist(), targets))  # node id -> target, built once
        for cell in uturn_cells:
            diagonals[cell] = _uturn_split(grid, cell, at)
    return diagonals, None


def _uturn_split(grid: Grid, cell: int, at: dict) -> int:
    """The split of a U-turn cell whose worse triangle is fuller at the targets ``at[node]``."""
    ci, cj = cell % grid.nx, cell // grid.nx
    n00 = cj * (grid.nx + 1) + ci
    n10, n01, n11 = n00 + 1, n00 + grid.nx + 1, n00 + grid.nx + 2
    xy = {n: at[n] for n in (n00, n10, n01, n11)}

    def fullness(a, b, c):
        pa, pb, pc = xy[a], xy[b], xy[c]
        area = (pb[0] - pa[0]) * (pc[1] - pa[1]) - (pb[1] - pa[1]) * (pc[0] - pa[0])
        longest = max(np.sum((pb - pa) ** 2), np.sum((pc - pb) ** 2), np.sum((pa - pc) ** 2))
        return area / longest if longest > 0 else -np.inf

    slash = min(fullness(n00, n10, n11), fullness(n00, n11, n01))
    back = min(fullness(n00, n10, n01), fullness(n10, n11, n01))
    # a tie (a symmetric U-turn) goes to '/' whatever the round-off: translating
    # the contour by 0.25 once flipped it (hypothesis found the example)
    return DIAG_SLASH if slash >= back - UTURN_TIE else DIAG_BACKSLASH


#: Fullness (area / longest edge squared, dimensionless) differences below this are a tie.
UTURN_TIE = 1e-9


def _nearest_point(src: np.ndarray, t: int) -> int:
    """Input index of the contour point at or just before path position ``t``."""
    m = len(src)
    for back in range(m):
        s = src[(t - back) % m]
        if s >= 0:
            return int(s)
    return 0  # pragma: no cover


def fit_path(contour: Contour, grid: Grid, strict: bool = False, method: str = "greedy"):
    """Select nodes and build a valid path per ring on ``grid``; raise SelectionError if not.

    ``method`` is ``"greedy"`` (Appendix A, point by point) or ``"trace"``
    (the outline of the cells the contour crosses, see :mod:`.trace`).  Rings
    are taken in input order; nodes one ring took are not available to the
    next.  Returns ``(nodes, targets, source, ring, diagonals,
    searched_further)`` with the rings' paths one after the other.
    """
    vis = (
        _Visibility(contour.ccw_points, next_on_ring(contour.ring)) if method == "greedy" else None
    )
    taken: set[int] = set()
    parts, further = [], 0
    offset = 0
    for r in range(contour.n_rings):
        deadline.check()
        order = contour.ring_order(r)
        q = contour.points[order]
        if method == "trace":
            nodes, targets, source = _trace(contour, grid, q, order)
        else:
            try:
                sel, f = select_nodes(grid, q, taken, vis, offset)
            except NoFreeNode as exc:
                raise SelectionError(
                    f"{contour.source}: no free grid node left that "
                    f"{contour.where(int(order[exc.k]))} can see (h = "
                    f"{max(grid.hx, grid.hy):.4g}); the contour has more points here than the "
                    "grid has nodes: give a smaller --h"
                ) from None
            further += f
            if strict:
                _check_strict(contour, grid, sel, order)
            nodes, targets, source = build_path(grid, sel, q, order, taken)
        taken.update(nodes.tolist())
        parts.append((nodes, targets, source))
        offset += len(order)
    nodes = np.concatenate([p[0] for p in parts])
    targets = np.concatenate([p[1] for p in parts])
    source = np.concatenate([p[2] for p in parts])
    ring = np.repeat(np.arange(len(parts)), [len(p[0]) for p in parts])
    if strict and (source < 0).any():
        t = int(np.argmax(source < 0))
        after = source[t:][source[t:] >= 0]
        raise SelectionError(
            _strict_msg(
                contour,
                grid,
                _nearest_point(source, t),
                int(after[0]) if len(after) else int(source[0]),
            )
        )
    problem, diagonals = check_path(grid, nodes, targets, ring)
    if problem is not None:
        t, what = problem
        if what == "clockwise":
            raise SelectionError(
                f"{contour.source}: the grid path of ring {int(ring[t])} runs clockwise or "
                f"encloses nothing (h = {max(grid.hx, grid.hy):.4g} is too coarse for this "
                "contour); give a smaller --h"
            )
        raise SelectionError(_touch_msg(contour, grid, source, t, what))
    return nodes, targets, source, ring, diagonals, further


def check_path(grid: Grid, nodes: np.ndarray, targets: np.ndarray, ring: np.ndarray | None = None):
    """``(problem, diagonals)``: ``problem`` is ``None`` if the path can be deformed
    onto its targets, else ``(path index, what)``; ``diagonals`` the forced splits.

    ``ring`` (default: all one ring) tells which ring each path entry is on.
    The paths must visit each node once, force no cell twice (they would
    touch), each run counter-clockwise, and every triangle with all three
    corners on a path must keep its orientation at the targets.
    """
    ring = np.zeros(len(nodes), dtype=np.int64) if ring is None else ring
    uniq, counts = np.unique(nodes, return_counts=True)
    if (counts > 1).any():
        t = int(np.flatnonzero(nodes == uniq[np.argmax(counts > 1)])[-1])
        return (t, "visits one grid node twice"), None
    diagonals, bad = force_diagonals(grid, nodes, targets, ring)
    if diagonals is None:
        return (bad, "touches itself"), None
    for r in np.unique(ring):
        on = np.flatnonzero(ring == r)
        if signed_area(grid.coords(nodes[on])) <= 0:
            return (int(on[0]), "clockwise"), diagonals
    tri = _path_triangles(grid, diagonals, nodes)
    if len(tri):
        pos = np.full((grid.n_nodes, 2), np.nan)
        pos[nodes] = targets
        e = pos[tri] - np.roll(pos[tri], 1, axis=1)
        longest = np.max(np.sum(e**2, axis=2), axis=1)
        # a relative floor: three collinear targets give round-off areas
        bad_t = np.flatnonzero(~(signed_areas(pos, tri) > 1e-12 * longest))
        if len(bad_t):
            t = int(np.flatnonzero(nodes == tri[bad_t[0], 0])[0])
            return (
                t,
                (
                    "would need a triangle whose three corners are contour points in the "
                    "wrong order (it would fold)"
                ),
            ), diagonals
    return None, diagonals


def _check_strict(contour: Contour, grid: Grid, sel: np.ndarray, order: np.ndarray) -> None:
    i, j = grid.node_ij(sel)
    gap = np.maximum(np.abs(np.roll(i, -1) - i), np.abs(np.roll(j, -1) - j)) >= 2
    if gap.any():
        k = int(np.argmax(gap))
        raise SelectionError(
            _strict_msg(contour, grid, int(order[k]), int(order[(k + 1) % len(order)]))
        )


def _strict_msg(contour: Contour, grid: Grid, a: int, b: int) -> str:
    return (
        f"{contour.source}: {contour.where(a)} and point {b} select grid nodes more "
        f"than one cell apart (h = {max(grid.hx, grid.hy):.4g}); --strict forbids "
        "extra boundary nodes: give a larger --h or drop --strict"
    )


def _trace(contour: Contour, grid: Grid, q: np.ndarray, order: np.ndarray):
    """The traced path by the first region rule whose path passes :func:`check_path`."""
    from .trace import REGION_RULES, TraceError, trace_path

    last_error = None
    for rule in REGION_RULES:
        try:
            nodes, targets, source = trace_path(grid, q, order, rule)
        except TraceError as exc:
            where = f" near {contour.where(int(order[exc.k]))}" if exc.k is not None else ""
            last_error = SelectionError(
                f"{contour.source}: the grid path traced around the contour {exc.what}{where} "
                f"(h = {max(grid.hx, grid.hy):.4g}); give a smaller --h"
            )
            continue
        if check_path(grid, nodes, targets)[0] is None or rule == REGION_RULES[-1]:
            return nodes, targets, source  # the caller words a failure
    raise last_error


def _path_triangles(grid: Grid, diagonals: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Triangles of the cells around the path whose three corners are all path nodes."""
    i, j = grid.node_ij(nodes)
    ci = np.clip(np.concatenate([i, i - 1, i, i - 1]), 0, grid.nx - 1)
    cj = np.clip(np.concatenate([j, j, j - 1, j - 1]), 0, grid.ny - 1)
    cells = np.unique(cj * grid.nx + ci)
    tri = grid_triangles(grid, diagonals, cells)
    on_path = np.zeros(grid.n_nodes, dtype=bool)
    on_path[nodes] = True
    return tri[on_path[tri].all(axis=1)]


def _touch_msg(contour: Contour, grid: Grid, source: np.ndarray, t: int, what: str) -> str:
    k = _nearest_point(source, t)
    return (
        f"{contour.source}: the grid path {what} near {contour.where(k)} "
        f"(h = {max(grid.hx, grid.hy):.4g}); the contour comes closer to itself than the "
        "grid can follow: give a smaller --h"
    )


#: Grid offsets tried, in cells, when a path touches itself (before halving h).
SHIFTS = ((0.0, 0.0), (0.5, 0.5), (0.5, 0.0), (0.0, 0.5), (0.25, 0.75), (0.75, 0.25))


def _shifted(grid: Grid, shift: tuple[float, float], box_given: bool) -> Grid:
    """The same grid moved by a fraction of a cell (one more cell so it still covers).

    With a box the user gave, the box is kept and the cell count grows by one
    instead, which moves the nodes relative to the contour just as well.
    """
    if shift == (0.0, 0.0):
        return grid
    sx, sy = shift
    if box_given:
        x1, y1 = grid.x0 + grid.nx * grid.hx, grid.y0 + grid.ny * grid.hy
        nx, ny = grid.nx + (sx > 0), grid.ny + (sy > 0)
        return Grid(grid.x0, grid.y0, (x1 - grid.x0) / nx, (y1 - grid.y0) / ny, nx, ny)
    return Grid(
        grid.x0 - sx * grid.hx,
        grid.y0 - sy * grid.hy,
        grid.hx,
        grid.hy,
        grid.nx + (sx > 0),
        grid.ny + (sy > 0),
    )


def select(
    contour: Contour,
    h: float | None = None,
    box: tuple[float, float, float, float] | None = None,
    margin: float | None = None,
    strict: bool = False,
    max_nodes: int = DEFAULT_MAX_NODES,
    methods: tuple[str, ...] = ("greedy", "trace"),
    exterior: bool = False,
) -> Selection:
    """Stage 1 in full: grid, selection, path, forced diagonals.

    When the grid path touches itself, the grid is first shifted by a
    fraction of a cell (:data:`SHIFTS`: alignment decides which contour
    points compete for a node); if no shift works, the path is traced around
    the contour instead (:mod:`.trace`, again on each shift); then, for the
    default ``h`` only, the step is halved (at most :data:`MAX_REFINEMENTS`
    times, within ``max_nodes``).  If nothing works the error names the
    place.  ``methods`` restricts the path rules tried (tests use it to
    exercise tracing alone).

    For an exterior mesh with the default ``h`` (a far-field box is large
    compared with the contour's spacing), the coarsest step of
    :func:`_coarser_steps` that works is used; Appendix A's ``h`` only if
    none does.
    """
    if exterior and h is None:
        # a far-field box is large against the contour's smallest spacing:
        # start from the coarsest step that gives every point a node
        for h_try in _coarser_steps(contour, box, margin, max_nodes, exterior):
            deadline.check()
            try:
                sel = select(contour, h_try, box, margin, strict, max_nodes, methods, exterior)
            except (SelectionError, LimitError):
                continue
            sel.h_rule = "spacing"
            sel.notes.insert(
                0,
                f"exterior mesh: h = {h_try:.4g}, the coarsest step tried "
                "(median spacing / 1.25^k) that gives every contour point a node "
                "of its own",
            )
            return sel
    grid, info = choose_grid(contour, h, box, margin, max_nodes, exterior)
    h_used = info["h"]
    refinements = 0
    notes: list[str] = []
    first_error: SelectionError | None = None
    while True:
        for method, shift in [(m, sh) for m in methods for sh in SHIFTS]:
            deadline.check()
            g = _shifted(grid, shift, box is not None)
            if g.n_nodes > max_nodes:
                continue
            try:
                nodes, targets, source, ring, diagonals, further = fit_path(
                    contour, g, strict, method
                )
            except SelectionError as exc:
                first_error = first_error or exc
                if strict:
                    raise
                continue
            if method == "trace":
                notes.append(
                    "traced the grid path around the contour: Appendix A's selection "
                    "gave no simple path on any grid shift"
                )
            if shift != (0.0, 0.0):
                notes.append(f"shifted the grid by {shift} cells: the first try failed")
            return Selection(
                grid=g,
                path_nodes=nodes,
                path_targets=targets,
                path_source=source,
                diagonals=diagonals,
                h=h_used,
                h_rule=info["h_rule"],
                searched_further=further,
                refinements=refinements,
                notes=notes,
                path_rule="appendix-a" if method == "greedy" else "traced",
                path_ring=ring,
                exterior=exterior,
            )
        if h is not None or refinements >= MAX_REFINEMENTS:
            raise first_error
        try:
            grid, info = choose_grid(contour, h_used / 2, box, margin, max_nodes, exterior)
        except LimitError:
            raise first_error from None
        notes.append(f"halved h to {h_used / 2:.4g}: no simple grid path at h = {h_used:.4g}")
        h_used /= 2
        refinements += 1


#: Steps tried for exterior meshes: the median spacing
#: divided by 1.25**k, at most this many that pass the crowding test.
MAX_COARSER_TRIES = 3

#: A step is hopeless when one cell would hold more contour points than this.
MAX_POINTS_PER_CELL = 4


def _coarser_steps(contour: Contour, box, margin, max_nodes: int, exterior: bool):
    """Candidate steps, coarsest first, that fit ``max_nodes`` and do not crowd cells.

    Every contour point needs a node of its own; a cell holding more than
    :data:`MAX_POINTS_PER_CELL` points cannot give them one nearby, so such
    steps are skipped without trying (this keeps refusals fast).
    """
    p = contour.points
    h0 = float(np.median(contour.edge_lengths()))
    tried = 0
    for k in range(40):
        h = h0 / 1.25**k
        try:
            grid, _ = choose_grid(contour, h, box, margin, max_nodes, exterior)
        except (LimitError, OptionError):
            return
        ij = np.floor((p - (grid.x0, grid.y0)) / (grid.hx, grid.hy)).astype(np.int64)
        _, counts = np.unique(ij, axis=0, return_counts=True)
        if counts.max() > MAX_POINTS_PER_CELL:
            continue
        yield h
        tried += 1
        if tried >= MAX_COARSER_TRIES:
            return


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
