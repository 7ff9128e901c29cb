"""A graded Cartesian background: a balanced quadtree of square cells, conforming
right isosceles triangles.

The cells have sides ``h0 * 2**k`` (level ``k``; level 0 is the finest) and
tile the box.  Near each contour point the cells are about the contour's
local size there (:func:`local_sizes`: its spacing to its neighbours, and
its distance to other parts of the contour, so that the two sides of a thin
part get cells of their own); away from the contour they grow by at most
``growth`` per cell width (:func:`refine`), and neighbouring cells differ
by at most one level (:func:`balance`).

Every leaf is split into right isosceles triangles (:meth:`Quadtree.triangulate`):

- a leaf whose four neighbours are no finer than it is cut along one
  diagonal (``/`` or ``\\``, per leaf: a path can force it);
- a leaf with a finer neighbour has the midpoints of those sides as
  nodes; it is cut as a fan from a new centre node to its corners and
  midpoints (4 to 8 triangles).

So the triangulation is conforming across level changes and, before any
deformation, every triangle is 45-45-90.

Coordinates are kept on an integer lattice of step ``h0 / 2`` (centres of
level-0 cells are lattice points), ``x = x0 + I * hx / 2``, ``y = y0 + J *
hy / 2``, with ``hx = hy = h0`` when the box is a whole number of root cells
(a box given exactly may stretch one axis by less than one root cell over
the box's extent).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..contour import Contour
from ..errors import LimitError, OptionError
from ..geometry import morton, prev_on_ring
from .cones import Cones

#: Default growth: how much larger a cell may be than the contour's local size
#: per cell width of distance (a size field ``s_q + (growth - 1) |x - q|``).
DEFAULT_GROWTH = 2.0

#: A cell next to a contour point has at most this times the point's local size,
#: so that each point has a cell of its own (Appendix A's 0.9 / sqrt(2)).
CELL_FACTOR = 1.0

#: A cell is split when it is larger than this times the size field: cells end between
#: ``1 / SPLIT_ABOVE`` and ``SPLIT_ABOVE`` times it (a power of two apart).
SPLIT_ABOVE = 1.4142135623730951

#: Points this many places apart along a ring or more count as "other parts" of the
#: contour for the local feature size.
APART = 3


def local_sizes(contour: Contour) -> np.ndarray:
    """Per contour point: the smaller of its two edges, and of its distance to the
    contour's points at least :data:`APART` places away along its ring (or on
    another ring): what a cell near it may measure for the two sides of a thin
    part to keep distinct nodes."""
    from scipy.spatial import cKDTree

    p = contour.points
    m = len(p)
    edge = contour.edge_lengths()
    prev = edge[prev_on_ring(contour.ring)]
    s = np.minimum(edge, prev)
    tree = cKDTree(p)
    k = min(m, 2 * APART + 2)
    dist, idx = tree.query(p, k=k)
    ring = contour.ring
    pos = np.arange(m) - np.asarray(contour.starts)[ring]
    size = np.diff(contour.starts)[ring]
    for c in range(1, k):
        j = idx[:, c]
        same = ring[j] == ring
        apart = np.abs(pos[j] - pos)
        apart = np.minimum(apart, size - apart)
        far = ~same | (apart >= APART)
        s = np.where(far, np.minimum(s, dist[:, c]), s)
    return s


def graded_sizes(points: np.ndarray, s: np.ndarray, growth: float) -> np.ndarray:
    """``s`` made consistent with the growth: at every point ``q``, the least over the
    points ``q'`` of ``s_q' + (growth - 1) |q - q'|`` (to within
    :data:`~.cones.SLACK`).

    So no point asks for cells much larger than a neighbour's: between any two points
    the result changes by at most ``(growth - 1)`` times their distance (and the
    slack).  :class:`~.cones.Cones`: ``O(log n)`` per point on contours.
    """
    return Cones(points, s, growth - 1.0).least(points)


@dataclass
class Quadtree:
    """The leaves of a balanced quadtree over a box.

    Attributes
    ----------
    x0, y0 : lower-left corner of the box.
    hx, hy : the finest cell's width and height (``h0``; equal unless the box
        was given and stretched).
    top : the root level: root cells have sides ``2**top`` finest cells.
    nx, ny : root cells along x and y.
    level, i, j : (c,) int64 each: leaf ``c`` is cell ``(i, j)`` of level ``level``,
        covering finest cells ``i * 2**level .. (i + 1) * 2**level - 1`` in x (and
        likewise in y).
    """

    x0: float
    y0: float
    hx: float
    hy: float
    top: int
    nx: int
    ny: int
    level: np.ndarray
    i: np.ndarray
    j: np.ndarray
    _sorted: tuple | None = field(default=None, init=False, repr=False, compare=False)

    @property
    def box(self) -> tuple[float, float, float, float]:
        w = self.nx * 2**self.top
        h = self.ny * 2**self.top
        return (self.x0, self.y0, self.x0 + w * self.hx, self.y0 + h * self.hy)

    @property
    def n_leaves(self) -> int:
        return len(self.level)

    def sizes(self) -> np.ndarray:
        """Each leaf's side (its width)."""
        return self.hx * 2.0**self.level

    def _morton_order(self) -> tuple[np.ndarray, np.ndarray]:
        """``(order, starts)``: the leaves sorted by the Morton code of their first
        finest cell, and those codes (sorted once: the leaves do not change)."""
        if self._sorted is None:
            start = morton(self.i << self.level, self.j << self.level)
            order = np.argsort(start, kind="stable")
            self._sorted = (order, start[order])
        return self._sorted

    def _split_order(self, marks: np.ndarray, renum: np.ndarray, kept: int):
        """:meth:`_morton_order` of the tree with the ``marks``ed leaves split in four,
        numbered as :func:`balance` numbers them (the kept leaves by ``renum``, then four
        children per split leaf, in Morton order, after them): each split leaf's place
        in the order taken by its children, whose codes follow its own in steps of a
        child's cells."""
        order, starts = self._morton_order()
        split = marks[order]
        child_of = np.cumsum(marks) - 1  # (the split leaf's rank among the split)
        width = np.where(split, 4, 1)
        at = np.repeat(np.arange(len(order)), width)
        q = np.arange(len(at)) - np.repeat(np.cumsum(width) - width, width)
        leaf = order[at]
        new_order = np.where(split[at], kept + 4 * child_of[leaf] + q, renum[leaf]).astype(np.int64)
        # (a child's cells: 4^(level - 1); a leaf of level 0 is never split)
        step = np.where(split[at], 4 ** np.maximum(self.level[leaf] - 1, 0), 0)
        return new_order, starts[at] + q * step

    def overlapping(self) -> bool:
        """Some two leaves share a cell.  An aligned block is a run of Morton codes and
        two blocks are disjoint or nested, so in the order of their first cells one
        starting before the one before it ends is the only way."""
        order, starts = self._morton_order()
        return bool((starts[1:] < starts[:-1] + 4 ** self.level[order][:-1]).any())

    def leaf_index(self, level: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """The leaf that holds cell ``(level, i, j)`` (the cell itself or an ancestor),
        or -1 where the cell is split into finer leaves or lies outside the box.

        The leaves tile the lattice and each is an aligned block, so in Morton order
        each covers one run of finest cells: the leaf holding the cell's first finest
        cell is the last leaf starting at or before it (one binary search), and it
        holds the whole cell when it is at least as coarse."""
        from ._quadtree import leaf_index

        order, starts = self._morton_order()
        out = np.empty(len(level), dtype=np.int64)
        width, height = self.nx * 2**self.top, self.ny * 2**self.top
        i64 = lambda v: np.ascontiguousarray(v, dtype=np.int64)  # noqa: E731
        leaf_index(
            starts, i64(order), i64(self.level), i64(level), i64(i), i64(j),
            width, height, self.top, out,
        )  # fmt: skip
        return out

    def layout(self) -> Layout:
        """Which sides of each leaf have a finer neighbour (so a midpoint node), and the
        lattice's key stride."""
        n = self.n_leaves
        lv, i, j = self.level, self.i, self.j
        finer = np.zeros((n, 4), dtype=bool)  # bottom, right, top, left
        width, height = self.nx * 2**self.top, self.ny * 2**self.top
        for s, (di, dj) in enumerate(((0, -1), (1, 0), (0, 1), (-1, 0))):
            ni, nj = i + di, j + dj
            inside = (ni >= 0) & (nj >= 0) & (ni * 2**lv < width) & (nj * 2**lv < height)
            holder = np.zeros(n, dtype=np.int64)
            holder[inside] = self.leaf_index(lv[inside], ni[inside], nj[inside])
            # the cell across that side at the same level is split: no leaf holds it
            finer[:, s] = inside & (holder < 0)
        return Layout(finer, 2 * height + 1)

    def triangulate(self, diagonals: np.ndarray | None = None, layout: Layout | None = None):
        """The conforming triangulation: ``(points, triangles, cell)``.

        ``diagonals`` (per leaf, 0 for ``/`` or 1 for ``\\``; default all ``/``) is
        used by leaves without a finer neighbour.  ``cell[t]`` is the leaf of
        triangle ``t``.  Triangles are counter-clockwise.  The node numbering does
        not depend on ``diagonals``.  ``layout``: :meth:`layout`, if already made.
        """
        from ._quadtree import emit

        lay = self.layout() if layout is None else layout
        n = self.n_leaves
        if diagonals is None:
            diagonals = np.zeros(n, dtype=np.uint8)
        finer = np.ascontiguousarray(lay.finer, dtype=np.uint8)
        count = np.where(lay.plain, 2, 4 + finer.sum(axis=1, dtype=np.int64))
        keys = np.empty((int(count.sum()), 3), dtype=np.int64)
        cell = np.empty(len(keys), dtype=np.int64)
        i64 = lambda v: np.ascontiguousarray(v, dtype=np.int64)  # noqa: E731
        emit(
            i64(self.level), i64(self.i), i64(self.j), finer,
            np.ascontiguousarray(diagonals, dtype=np.uint8), lay.stride, keys, cell,
        )  # fmt: skip
        # the nodes: the distinct keys, sorted (a leaf's corners are far apart in key
        # order, so a sort and a binary search per corner beat an argsort)
        flat = keys.ravel()
        ukey = np.sort(flat)
        new = np.empty(len(ukey), dtype=bool)
        new[:1] = True
        np.not_equal(ukey[1:], ukey[:-1], out=new[1:])
        ukey = ukey[new]
        inv = np.searchsorted(ukey, flat)
        li, lj = ukey // lay.stride, ukey % lay.stride
        points = np.column_stack([self.x0 + li * (self.hx / 2), self.y0 + lj * (self.hy / 2)])
        return points, inv.reshape(-1, 3).astype(np.int64), cell


@dataclass
class Layout:
    """Per leaf, which sides have a finer neighbour (see :meth:`Quadtree.layout`); the
    lattice keys' stride (key = lattice x * stride + lattice y, in half finest cells)."""

    finer: np.ndarray  # (n, 4) bool: bottom, right, top, left
    stride: int

    @property
    def plain(self) -> np.ndarray:
        """Leaves with no finer neighbour: two triangles along a diagonal."""
        return ~self.finer.any(axis=1)


def build(
    contour: Contour,
    box: tuple[float, float, float, float],
    growth: float = DEFAULT_GROWTH,
    max_h: float | None = None,
    factor: float | None = None,
    box_given: bool = False,
    max_nodes: int | None = None,
    local: np.ndarray | None = None,
    roots: int | None = None,
    field=None,
) -> Quadtree:
    """The balanced quadtree over ``box`` for ``contour``.

    The finest cell ``h0`` is the largest ``root / 2**k`` (``root`` the root cells'
    side, at most ``max_h``; default: the box's shorter side) not above
    :data:`SPLIT_ABOVE` times ``factor`` times the smallest graded local size.
    Without ``box_given`` the box is grown to a whole number of root cells, keeping
    its centre, so cells are square; a given box is kept and the finest cell
    stretched along one axis to fit.  ``roots``: :func:`root_cells`'.  ``field``: a
    further size field (points (k, 2) -> sizes (k,)) the cells must not exceed, as a
    size function asks (:func:`refine`).
    """
    if not growth > 1.0:
        raise OptionError(f"--growth must be > 1 (cells grow away from the contour), got {growth}")
    factor = CELL_FACTOR if factor is None else factor
    if local is None:  # (a caller that needs them too passes them)
        local = local_sizes(contour)
    s = graded_sizes(contour.points, local, growth) * factor
    return _lay(contour.points, s, box, growth, max_h, box_given, max_nodes, roots, field)


def build_from(
    points: np.ndarray,
    sizes: np.ndarray,
    box: tuple[float, float, float, float],
    growth: float = DEFAULT_GROWTH,
    max_h: float | None = None,
    box_given: bool = False,
    max_nodes: int | None = None,
    roots: int | None = None,
    field=None,
    wrap: tuple[bool, bool] | None = None,
) -> tuple[Quadtree, SizeField]:
    """The balanced quadtree over ``box`` whose cells near each of ``points`` are
    about its size (``sizes``, made consistent with the growth by
    :func:`graded_sizes`): :func:`build` for sizes given point by point; and the size
    field it was refined to, but ``field``.  ``wrap``: opposite box sides cut alike
    (:func:`match_sides`)."""
    if not growth > 1.0:
        raise OptionError(f"--growth must be > 1 (cells grow away from the contour), got {growth}")
    laid_for = SizeField(points, graded_sizes(points, sizes, growth), growth, max_h)
    tree = _lay(points, laid_for.s, box, growth, max_h, box_given, max_nodes, roots, field,
                laid_for.cones, wrap)  # fmt: skip
    return tree, laid_for


@dataclass
class SizeField:
    """The size a quadtree was refined to with no further field, at any point ``q``:
    the least over the ``points`` of ``s_p + (growth - 1) |q - p|`` (to within
    :data:`~.cones.SLACK`), and half ``max_h`` where given (:func:`refine` measures from the cell
    instead of its centre).  Stage 3 coarsens the interior to it
    (:mod:`~deformesh_cli.coarsen`: no edge longer than twice it)."""

    points: np.ndarray
    s: np.ndarray
    growth: float
    max_h: float | None = None

    @cached_property
    def cones(self) -> Cones:
        """The cones of ``points`` and ``s`` (built once: :func:`refine` walks them too)."""
        return Cones(self.points, self.s, self.growth - 1.0)

    def __call__(self, q: np.ndarray) -> np.ndarray:
        out = self.cones.least(q)
        if self.max_h is not None:  # (no edge a collapse makes longer than max_h)
            out = np.minimum(out, self.max_h / 2.0)
        return out


def _lay(
    points, s, box, growth, max_h, box_given, max_nodes, roots, field, cones=None, wrap=None
) -> Quadtree:
    """Root cells over ``box`` for the sizes ``s`` at ``points``, refined and balanced
    (``cones``: theirs, if already built; ``wrap``: :func:`match_sides`')."""
    xmin, ymin, xmax, ymax = box
    w, h = xmax - xmin, ymax - ymin
    nx, ny, top, h0 = root_cells(w, h, float(s.min()), max_h, exact=box_given, roots=roots)
    if max(nx, ny) * 2**top > MAX_CELLS_ACROSS:
        x, y = points[int(np.argmin(s))]
        raise LimitError(
            f"its finest cells ({float(s.min()):.3g}, near ({x:.6g}, {y:.6g}), where the "
            f"contour's points or edges come that close) are over {MAX_CELLS_ACROSS:.3g} "
            f"times smaller than the box ({max(w, h):.3g}): a grid cannot hold both scales "
            "in double precision; mesh its small part and its large one apart"
        )
    if max_nodes is not None and nx * ny > max_nodes:  # (before any array of them)
        raise LimitError(
            f"the graded grid would need more than {max_nodes} cells ({nx:,} x {ny:,} root "
            "cells); raise --max-nodes or give a larger --max-h"
        )
    if box_given:
        hx, hy = w / (nx * 2**top), h / (ny * 2**top)
        x0, y0 = xmin, ymin
    else:
        hx = hy = h0
        x0 = xmin - (nx * 2**top * h0 - w) / 2
        y0 = ymin - (ny * 2**top * h0 - h) / 2
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    tree = Quadtree(
        x0, y0, hx, hy, top, nx, ny,
        np.full(nx * ny, top, np.int64), i.ravel().astype(np.int64), j.ravel().astype(np.int64),
    )  # fmt: skip
    tree = refine(tree, points, s, growth, max_nodes, field, cones)
    tree = balance(tree)
    if wrap is not None and any(wrap):
        tree = match_sides(tree, *wrap)
    return tree


def children(lv: np.ndarray, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, ...]:
    """The four children of each leaf ``(lv, i, j)``, in Morton order, leaf by leaf."""
    n = len(lv)
    return (
        np.repeat(lv - 1, 4),
        np.repeat(i, 4) * 2 + np.tile([0, 1, 0, 1], n),
        np.repeat(j, 4) * 2 + np.tile([0, 0, 1, 1], n),
    )


def split_leaves(lv, i, j, marks: np.ndarray) -> tuple[np.ndarray, ...]:
    """The leaves ``(lv, i, j)`` with the ``marks``ed ones split in four: the kept ones
    first, in their order, then :func:`children` of the split."""
    keep = ~marks
    return tuple(
        np.concatenate([a[keep], c])
        for a, c in zip((lv, i, j), children(lv[marks], i[marks], j[marks]))
    )


def match_sides(tree: Quadtree, across_x: bool, across_y: bool) -> Quadtree:
    """``tree`` with its opposite box sides cut alike: with ``across_y`` the leaves along
    the bottom and along the top span the same x intervals (with ``across_x``, the left
    and right sides the same y intervals), each refined to the finer of the two facing
    it, then balanced again, until nothing changes.  The box sides' nodes are the
    corners of those leaves, so a translation across the box maps them onto one
    another (``--periodic`` on an exterior mesh).  Only splits: it ends, at worst with
    both sides at the finest level."""
    width, height = tree.nx * 2**tree.top, tree.ny * 2**tree.top
    t = tree
    while True:
        lv, i, j = t.level, t.i, t.j
        marks = np.zeros(len(lv), dtype=bool)
        checks = []
        if across_y:  # (a bottom leaf's first x on the top row, a top leaf's on the bottom)
            checks += [
                (j == 0, i << lv, height - 1, True),
                ((j + 1) << lv == height, i << lv, 0, True),
            ]
        if across_x:
            checks += [
                (i == 0, j << lv, width - 1, False),
                ((i + 1) << lv == width, j << lv, 0, False),
            ]
        for on, along, far, rows in checks:
            k = np.flatnonzero(on)
            zero = np.zeros(len(k), dtype=np.int64)
            other = np.full(len(k), far, dtype=np.int64)
            ii, jj = (along[k], other) if rows else (other, along[k])
            holder = t.leaf_index(zero, ii, jj)
            marks[holder[lv[holder] > lv[k]]] = True
        if not marks.any():
            return t
        t = balance(
            Quadtree(t.x0, t.y0, t.hx, t.hy, t.top, t.nx, t.ny, *split_leaves(lv, i, j, marks))
        )


#: The most finest cells across the box: Morton codes (:func:`..geometry.morton`) and lattice keys
#: (``Layout.stride``) are whole numbers below 2**63 for at most 28 levels of 2**28 cells.
MAX_CELLS_ACROSS = 2**28

#: Root cells along the box's shorter side: at least this many, so that the finest
#: cell can be sized to within ``1 / (2 * ROOTS)`` of the smallest local size.
ROOTS = 8

#: A given box may stretch the cells along one axis by at most this fraction.
MAX_STRETCH = 1.0 / (2 * ROOTS) + 1e-9


def root_cells(
    w: float,
    h: float,
    target: float,
    max_h: float | None = None,
    exact: bool = False,
    roots: int | None = None,
) -> tuple[int, int, int, float]:
    """``(nx, ny, top, h0)``: root cells of ``2**top`` finest cells of side ``h0`` about
    ``target``, tiling a ``w`` by ``h`` box.

    At least ``roots`` (default :data:`ROOTS`) root cells along the shorter side (and
    none larger than ``max_h``).  For an ``exact`` box the root cells divide it, so ``h0`` is within
    ``1 / (2 * ROOTS)`` of ``target`` and the two axes within :data:`MAX_STRETCH`;
    otherwise ``h0`` is ``target`` and the box is to grow to a whole number of root
    cells (less than one root cell more along each axis).
    """
    short, long_ = min(w, h), max(w, h)
    top = max(0, math.floor(math.log2(short / ((roots or ROOTS) * target))))
    if max_h is not None:
        while top > 0 and target * 2**top > max_h:
            top -= 1
    if exact:
        n = max(1, round(short / (target * 2**top)))
        side = short / n
        m = max(1, round(long_ / side))
        nx, ny = (m, n) if w >= h else (n, m)
        return nx, ny, top, side / 2**top
    side = target * 2**top
    return max(1, math.ceil(w / side - 1e-9)), max(1, math.ceil(h / side - 1e-9)), top, target


def refine(
    tree: Quadtree,
    points: np.ndarray,
    s: np.ndarray,
    growth: float,
    max_nodes: int | None = None,
    field=None,
    cones: Cones | None = None,
) -> Quadtree:
    """Split every leaf larger than the size field ``min over q of s_q + (growth - 1)
    d(q, cell)`` (``d`` the distance from point ``q`` to the cell), and than ``field``
    at its centre if given, level by level from the root (``cones``: those of
    ``points`` and ``s``, if already built)."""
    if cones is None:
        cones = Cones(points, s, growth - 1.0)
    lv, i, j = tree.level, tree.i, tree.j
    keep_l, keep_i, keep_j = [], [], []
    while len(lv):
        w = tree.hx * 2.0**lv
        hgt = tree.hy * 2.0**lv
        x0 = tree.x0 + i * w
        y0 = tree.y0 + j * hgt
        cx, cy = x0 + w / 2, y0 + hgt / 2
        need = cones.least(np.column_stack([cx, cy]), w / 2, hgt / 2)
        if field is not None:
            need = np.minimum(need, field(np.column_stack([cx, cy])))
        split = (np.maximum(w, hgt) > SPLIT_ABOVE * need) & (lv > 0)
        keep_l.append(lv[~split])
        keep_i.append(i[~split])
        keep_j.append(j[~split])
        if max_nodes is not None and sum(len(a) for a in keep_l) + 4 * split.sum() > max_nodes:
            raise LimitError(
                f"the graded grid would need more than {max_nodes} cells; "
                "raise --max-nodes or give a larger --growth"
            )
        lv, i, j = children(lv[split], i[split], j[split])
    return Quadtree(
        tree.x0, tree.y0, tree.hx, tree.hy, tree.top, tree.nx, tree.ny,
        np.concatenate(keep_l), np.concatenate(keep_i), np.concatenate(keep_j),
    )  # fmt: skip


def balance(tree: Quadtree) -> Quadtree:
    """Split leaves until every two leaves sharing a side differ by at most one level.

    Each round, a leaf looks up the leaves across its four sides at its own level and
    marks those more than one level coarser; the marked split in four.  A leaf asks
    again only when it is new or one it found was split (the others' answers cannot
    change), so the rounds, and the tree, are those of every leaf asking every time."""
    lv, i, j = tree.level, tree.i, tree.j
    ask = np.arange(len(lv))
    t = Quadtree(tree.x0, tree.y0, tree.hx, tree.hy, tree.top, tree.nx, tree.ny, lv, i, j)
    while True:
        marks = np.zeros(len(lv), dtype=bool)
        holders = []
        for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            holder = t.leaf_index(lv[ask], i[ask] + di, j[ask] + dj)
            ok = holder >= 0
            too_big = ok.copy()
            too_big[ok] = lv[holder[ok]] > lv[ask][ok] + 1
            marks[holder[too_big]] = True
            holders.append(holder)
        if not marks.any():
            return t
        found = np.column_stack(holders)
        again = ask[(marks[np.maximum(found, 0)] & (found >= 0)).any(axis=1)]
        keep = ~marks
        renum = np.cumsum(keep) - 1
        again = renum[again[keep[again]]]  # (a marked one is asked for by its children)
        kept = int(keep.sum())
        lv, i, j = split_leaves(lv, i, j, marks)
        ask = np.concatenate([again, np.arange(kept, len(lv))])
        split = t._split_order(marks, renum, kept)
        t = Quadtree(tree.x0, tree.y0, tree.hx, tree.hy, tree.top, tree.nx, tree.ny, lv, i, j)
        t._sorted = split  # (the Morton order of the leaves, kept up to date, not re-sorted)
