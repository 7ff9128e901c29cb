"""Stage 3: the interior taken to the size field the grid was laid for.

A balanced quadtree lets a cell be at most twice its neighbour, so away from the
contour its cells are smaller than the size field asks (the field may grow
faster than one level per cell): a graded grid's mesh has about twice the nodes
it needs there.  This stage removes interior nodes by edge collapse: an interior
node ``a`` goes into a neighbour ``b`` (``a``'s triangles take ``b`` in its place;
the two on the edge ``ab`` go) only if

- every edge the collapse makes is at most :data:`LONGEST` times the size field
  (the mean of its ends' values): no longer than the diagonal of the largest cell
  the quadtree admits there;
- ``a`` and ``b`` have no common neighbour but the two across the edge ``ab`` (the
  link condition): the mesh stays a triangulation of the same domain;
- every triangle it makes is counter-clockwise with its smallest angle at least
  :data:`ANGLE` degrees, or :data:`EDGE_ANGLE` (the quality stage's target) where
  it has a boundary node.

Each node tries its shortest such edge (relative to the size field); collapses are
made in rounds of ones that share no triangle and do not meet at their ``b``
(:func:`_independent`), the shorter first, until none is allowed.  Every round
makes at least one (the first in that order), so it ends; no round reads the
clock.  Boundary nodes never move or go: every contour
point stays a node, every boundary edge an edge, and the area is unchanged.  Nothing
here prints or exits.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .cavity import renumber
from .improve import TARGET
from .mesh import Mesh

#: A collapse makes no edge longer than this times the size field: the diagonal of a
#: quadtree cell at the largest it may be (:data:`.graded.SPLIT_ABOVE` times the field).
LONGEST = 2.0

#: A collapse makes no triangle whose smallest angle is under this (degrees): the
#: bound Triangle is run with (``q30``); the quality stage works above it afterwards.
ANGLE = 30.0

#: ... and none with a boundary node under the quality stage's target (degrees): it
#: cannot move that node, and works on every triangle under its target.
EDGE_ANGLE = TARGET

#: Edges within this many halvings (log2 of length over the size field) go in the same
#: class when collapses are ordered (:func:`_independent`).
STEP = 0.25


def coarsen(mesh: Mesh, size: Callable[[np.ndarray], np.ndarray]) -> tuple[Mesh, int]:
    """``mesh`` with interior nodes collapsed where its edges are shorter than the size
    field ``size`` (points (k, 2) -> sizes (k,)) allows (the module's rules), and how
    many nodes went."""
    pts = np.ascontiguousarray(mesh.points, dtype=np.float64)
    n = len(pts)
    tri = np.array(mesh.triangles, dtype=np.int64, copy=True)
    free = np.ones(n, dtype=bool)
    free[mesh.lines.ravel()] = False
    free[: mesh.n_contour + mesh.n_extra + mesh.n_box] = False
    if not free.any() or len(tri) == 0:
        return mesh, 0
    need = np.ascontiguousarray(size(pts), dtype=np.float64)
    stars, deg = _stars(tri, n)
    alive = np.ones(len(tri), dtype=bool)
    gone = np.zeros(n, dtype=bool)
    tan_floor = np.tan(np.radians([ANGLE, EDGE_ANGLE]))  # (inside; at the boundary)
    boundary = ~free
    active = np.flatnonzero(free)
    kept = _Candidates.none()  # (weighed before, and nothing they read has changed)
    while True:
        c = _Candidates.join(
            [kept, _weigh(pts, tri, stars, deg, need, active, tan_floor, boundary)]
        )
        if len(c.a) == 0:
            break
        won = _independent(c)
        wa, wb = c.a[won], c.b[won]
        stars = _collapse(tri, stars, deg, alive, wa, wb)
        gone[wa] = True
        # next: every node whose triangles changed, weighed again; the ones not taken
        # are kept as they are unless their triangles or their b's neighbours changed
        touched = np.zeros(n, dtype=bool)
        touched[c.nbr[won[c.rows]]] = True
        same = ~won & ~touched[c.a] & ~touched[c.b]
        kept = c.subset(same)
        touched[c.a[~won & ~same]] = True  # (with them, in order: a union by mask)
        active = np.flatnonzero(touched & free & ~gone)
    removed = int(gone.sum())
    return (renumber(mesh, tri[alive], gone), removed) if removed else (mesh, 0)


def _independent(cands: _Candidates) -> np.ndarray:
    """Per candidate (``a`` into ``b``; ``rows``: its entries in ``nbr``, ``a``'s
    neighbours, and ``star``, ``a``'s triangles): taken in this round.  Two collapses
    taken share no triangle, no ``b``, and neither's ``b`` is a neighbour of the
    other's ``a`` (so each one's new edges are new after the other too); every
    candidate not taken conflicts with one taken (a maximal set).  Shorter edges (by
    :data:`STEP` classes of their length over the size field) go first, and within a
    class an order fixed by the node's number but scattered over the mesh, so that
    most of a crowd of equal edges goes at once."""
    a, b, key, rows, nbr, star = (
        cands.a, cands.b, cands.key, cands.rows, cands.nbr, cands.star
    )  # fmt: skip
    c = len(a)
    scatter = (a.astype(np.uint64) * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(11)
    rank = np.empty(c, dtype=np.int64)
    rank[np.lexsort((a, scatter, np.floor(np.log2(key) / STEP)))] = np.arange(c)
    # (nodes and triangles numbered among these candidates' only)
    _, tri_at = np.unique(star, return_inverse=True)
    nodes, at = np.unique(np.concatenate([b, nbr]), return_inverse=True)
    b_at, nbr_at = at[:c], at[c:]
    m, n = int(tri_at.max()) + 1, len(nodes)
    open_ = np.ones(c, dtype=bool)
    won = np.zeros(c, dtype=bool)
    tri_taken = np.zeros(m, dtype=bool)
    nbr_taken = np.zeros(n, dtype=bool)  # a neighbour of a taken collapse's a
    into_taken = np.zeros(n, dtype=bool)  # a taken collapse's b
    while open_.any():
        o_rows = open_[rows]
        least_tri = np.full(m, c, dtype=np.int64)
        np.minimum.at(least_tri, tri_at[o_rows], rank[rows[o_rows]])
        least_into = np.full(n, c, dtype=np.int64)
        np.minimum.at(least_into, b_at[open_], rank[open_])
        least_nbr = np.full(n, c, dtype=np.int64)
        np.minimum.at(least_nbr, nbr_at[o_rows], rank[rows[o_rows]])
        win = open_ & (least_into[b_at] == rank) & (least_nbr[b_at] == rank)
        bad = (least_tri[tri_at] != rank[rows]) | (least_into[nbr_at] < rank[rows])
        win[rows[bad]] = False
        won |= win
        tri_taken[tri_at[win[rows]]] = True
        nbr_taken[nbr_at[win[rows]]] = True
        into_taken[b_at[win]] = True
        blocked = into_taken[b_at] | nbr_taken[b_at]
        blocked[rows[tri_taken[tri_at] | into_taken[nbr_at]]] = True
        open_ &= ~blocked & ~won
    return won


@dataclass
class _Candidates:
    """Collapses allowed: ``a`` into ``b`` (``key``: the edge's length over the size
    field); ``a``'s neighbours ``nbr`` and triangles ``star``, candidate ``rows[i]``'s."""

    a: np.ndarray
    b: np.ndarray
    key: np.ndarray
    rows: np.ndarray
    nbr: np.ndarray
    star: np.ndarray

    @classmethod
    def none(cls) -> _Candidates:
        i, f = np.zeros(0, dtype=np.int64), np.zeros(0)
        return cls(i, i, f, i, i, i)

    @classmethod
    def join(cls, parts: list[_Candidates]) -> _Candidates:
        off = np.cumsum([0] + [len(p.a) for p in parts[:-1]])
        return cls(
            *(np.concatenate([getattr(p, f) for p in parts]) for f in ("a", "b", "key")),
            np.concatenate([p.rows + o for p, o in zip(parts, off)]),
            np.concatenate([p.nbr for p in parts]),
            np.concatenate([p.star for p in parts]),
        )

    def subset(self, mask: np.ndarray) -> _Candidates:
        at = np.cumsum(mask) - 1
        keep = mask[self.rows]
        return _Candidates(
            self.a[mask], self.b[mask], self.key[mask],
            at[self.rows[keep]], self.nbr[keep], self.star[keep],
        )  # fmt: skip


def _stars(tri: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per node: its triangles' ids (padded with -1) and how many."""
    flat = tri.ravel()
    order = np.argsort(flat, kind="stable")
    deg = np.bincount(flat, minlength=n)
    width = int(deg.max())
    start = np.concatenate([[0], np.cumsum(deg)[:-1]])
    col = np.arange(len(flat)) - np.repeat(start, deg)
    stars = np.full((n, width), -1, dtype=np.int64)
    stars[flat[order], col] = order // 3
    return stars, deg


def _weigh(pts, tri, stars, deg, need, nodes, tan_floor, boundary):
    """:class:`_Candidates` of the ``nodes`` with an allowed collapse: each into its
    shortest allowed edge's other end (the module's rules, weighed per node by a
    compiled loop, :mod:`._coarsen`)."""
    from ._coarsen import weigh

    c = len(nodes)
    w = int(deg[nodes].max()) if c else 0
    u = np.empty((c, w), dtype=np.int64)
    v = np.empty((c, w), dtype=np.int64)
    scratch = (np.empty(w, dtype=np.int64), np.empty((w, w)), np.empty((w, w)))
    b = np.empty(c, dtype=np.int64)
    key = np.empty(c)
    weigh(
        pts, tri, stars, deg, need, nodes, boundary.view(np.uint8),
        float(tan_floor[0]), float(tan_floor[1]), 0.5 * LONGEST,
        u, v, *scratch, np.empty(w), np.empty(w), b, key,
    )  # fmt: skip
    rows = np.flatnonzero(b >= 0)
    valid = np.arange(w) < deg[nodes[rows], None]
    r_idx = np.repeat(np.arange(len(rows)), valid.sum(axis=1))
    star = stars[nodes[rows], :w][valid]
    return _Candidates(nodes[rows], b[rows], key[rows], r_idx, u[rows][valid], star)


def _collapse(tri, stars, deg, alive, wa, wb):
    """Collapse each ``wa`` into its ``wb`` (their stars apart): the triangles renamed,
    the two on each edge dead, the stars of ``wb`` and of the two across mended (the
    star array, widened if a star outgrew it).  A compiled loop (:mod:`._coarsen`)."""
    from ._coarsen import collapse, collapse_width

    wa = np.ascontiguousarray(wa, dtype=np.int64)
    wb = np.ascontiguousarray(wb, dtype=np.int64)
    width = collapse_width(tri, stars, deg, wa, wb)
    if width > stars.shape[1]:
        stars = np.concatenate([stars, np.full((len(stars), width - stars.shape[1]), -1)], axis=1)
    collapse(tri, stars, deg, alive.view(np.uint8), wa, wb)
    return stars
