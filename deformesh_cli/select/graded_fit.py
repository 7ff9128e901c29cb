"""A graded grid fitted to the number of points: the copy the path follows is spaced
one cell per point.

A grid path moves one cell per step (a side or a diagonal of a leaf: both cover
one cell width along the axis the step mostly follows).  So a contour piece
whose points are, on average, further apart than the cells they cross, measured
that way, cannot give every point a node next to its neighbour's: the path
falls behind, a little at each step, until no candidate is left.  That is what
happens on airfoils and icons, whose spacing changes faster than cells can.

Here the grid and the points are made to agree, piece by piece (a piece runs
between two corners, or a corner and the ring's first point:
:func:`.respace.pieces`):

1. the quadtree is laid for cells one to two times each point's spacing,
   measured in the larger of its two axis components (:func:`initial_tree`);
2. each piece's *cell measure* ``mu`` is the number of cell steps the contour
   takes along it: the integral of ``max(|dx|, |dy|) / (leaf side)``
   (:func:`measure`).  Where ``mu`` is below :data:`RHO_LOW` times the piece's
   number of edges, the leaves it crosses are split, coarsest first, until it
   is about :data:`RHO_TARGET` times (:func:`fit_tree`);
3. the points are slid along each piece to equal steps of ``mu``
   (:func:`copy`): the path is fitted to that copy, and the deformation carries
   each node along the contour to its real point, as on the adapted grid.
"""

from __future__ import annotations

import numpy as np

from .. import deadline
from ..contour import Contour
from ..errors import SelectionError
from ..geometry import next_on_ring, prev_on_ring
from . import graded
from .respace import Respaced, arclengths, pieces, slid_copy

#: A piece whose cell measure is under this fraction of its edges gets finer cells.
RHO_LOW = 0.8
#: ... up to about this fraction.
RHO_TARGET = 0.95
#: Rounds of splitting before the grid is taken as it is.
ROUNDS = 10
#: Root cells along the box's shorter side: few, so that cells can grow as large as
#: the spacing of a thin body's contour (an airfoil's box is a few chords by a tenth).
ROOTS = 2


def leaf_at(tree: graded.Quadtree, xy: np.ndarray) -> np.ndarray:
    """The leaf holding each point (points outside the box: the nearest leaf on its
    edge)."""
    width, height = tree.nx * 2**tree.top, tree.ny * 2**tree.top
    ci = np.clip(np.floor((xy[:, 0] - tree.x0) / tree.hx).astype(np.int64), 0, width - 1)
    cj = np.clip(np.floor((xy[:, 1] - tree.y0) / tree.hy).astype(np.int64), 0, height - 1)
    return tree.leaf_index(np.zeros(len(xy), dtype=np.int64), ci, cj)


def measure(tree: graded.Quadtree, poly: np.ndarray, arc: np.ndarray):
    """A piece's polyline cut into sub-segments of at most a quarter of the leaf they
    start in: ``(cumulative cell measure, arc length, leaf, measure)`` per sub-segment
    (the first two with one more entry, at the piece's start)."""
    return measure_all(tree, [(poly, arc)])[0]


def measure_all(tree: graded.Quadtree, polys: list) -> list:
    """:func:`measure` of each ``(poly, arc)``, with the pieces' points, segments and
    sub-segments in flat arrays (a coastline has hundreds of pieces: a few numpy calls
    each, not a score); only the running sums go piece by piece, in order."""
    sizes = tree.sizes()
    counts = np.array([len(poly) for poly, _ in polys], dtype=np.int64)
    pts = np.concatenate([poly for poly, _ in polys])
    arc = np.concatenate([a for _, a in polys])
    at = sizes[leaf_at(tree, pts)]
    # segment s joins points s and s + 1 of one piece: every point but each piece's last
    last = np.cumsum(counts) - 1
    seg = np.ones(len(pts), dtype=bool)
    seg[last] = False
    seg = np.flatnonzero(seg)
    d = pts[seg + 1] - pts[seg]
    linf = np.abs(d).max(axis=1)
    nsub = np.maximum(1, np.ceil(4 * linf / np.minimum(at[seg], at[seg + 1]))).astype(np.int64)
    e = np.repeat(np.arange(len(seg)), nsub)
    k = np.repeat(nsub, nsub)
    u0 = (np.arange(int(nsub.sum())) - np.repeat(np.cumsum(nsub) - nsub, nsub)) / k
    mid = pts[seg[e]] + (u0 + 0.5 / k)[:, None] * d[e]
    deadline.check()
    leaf = leaf_at(tree, mid)
    dmu = linf[e] / k / sizes[leaf]
    a0 = arc[seg[e]]
    sarc = a0 + u0 * (arc[seg[e] + 1] - a0)
    # each piece's sub-segments, in order
    piece = np.repeat(np.arange(len(counts)), counts - 1)  # each segment's piece
    bounds = np.cumsum(np.bincount(piece, weights=nsub, minlength=len(counts)))[:-1]
    bounds = bounds.astype(np.int64)
    out = []
    for (_, a), dm, sa, lf in zip(
        polys, np.split(dmu, bounds), np.split(sarc, bounds), np.split(leaf, bounds)
    ):
        out.append((np.concatenate([[0.0], np.cumsum(dm)]), np.concatenate([sa, [a[-1]]]), lf, dm))
    return out


def split(tree: graded.Quadtree, leaves: np.ndarray) -> graded.Quadtree:
    """``tree`` with ``leaves`` split in four, balanced again."""
    keep = np.ones(tree.n_leaves, dtype=bool)
    keep[leaves] = False
    ls, is_, js = tree.level[leaves] - 1, tree.i[leaves], tree.j[leaves]
    lv = np.concatenate([tree.level[keep], np.repeat(ls, 4)])
    i = np.concatenate([tree.i[keep], np.repeat(is_, 4) * 2 + np.tile([0, 1, 0, 1], len(is_))])
    j = np.concatenate([tree.j[keep], np.repeat(js, 4) * 2 + np.tile([0, 0, 1, 1], len(js))])
    t = graded.Quadtree(tree.x0, tree.y0, tree.hx, tree.hy, tree.top, tree.nx, tree.ny, lv, i, j)
    return graded.balance(t)


def initial_sizes(contour: Contour) -> np.ndarray:
    """Per point: the cell it asks for, ``sqrt(2)`` times the larger axis component of
    its longer edge (cells end one to two times that component), but no more than its
    distance to other parts of the contour (:func:`.graded.local_sizes`)."""
    s = graded.local_sizes(contour)
    edge = contour.edge_lengths()
    prev = prev_on_ring(contour.ring)
    feature = np.where(s < np.minimum(edge, edge[prev]) * (1 - 1e-12), s, np.inf)
    nxt = next_on_ring(contour.ring)
    linf = np.abs(contour.points[nxt] - contour.points).max(axis=1)
    return np.minimum(np.sqrt(2.0) * np.maximum(linf, linf[prev]), feature)


def fit_tree(contour: Contour, tree: graded.Quadtree, max_nodes: int | None = None):
    """Split leaves along the pieces whose cell measure is under :data:`RHO_LOW` times
    their edges; ``(tree, each piece's measure over its edges)``."""
    parts = pieces(contour)
    rho = np.zeros(len(parts))
    for _ in range(ROUNDS):
        deadline.check()  # (a round on a fine tree of a comb's slots: seconds)
        todo = []
        measured = measure_all(tree, [(poly, arc) for _, _, _, poly, arc in parts])
        for p, ((_, i, j, _, _), (mu, _, leaf, dmu)) in enumerate(zip(parts, measured)):
            rho[p] = mu[-1] / (j - i)
            if rho[p] >= RHO_LOW:
                continue
            gain = np.bincount(leaf, weights=dmu, minlength=tree.n_leaves)
            cand = np.flatnonzero((gain > 0) & (tree.level > 0))
            cand = cand[np.argsort(-gain[cand], kind="stable")]
            short = RHO_TARGET * (j - i) - mu[-1]
            todo.append(cand[: int(np.searchsorted(np.cumsum(gain[cand]), short)) + 1])
        if not todo:
            break
        tree = split(tree, np.unique(np.concatenate(todo)))
        if max_nodes is not None and 2 * tree.n_leaves > max_nodes:
            raise SelectionError(f"{contour.source}: the fitted graded grid is over --max-nodes")
    return tree, rho


def copy(contour: Contour, tree: graded.Quadtree) -> Respaced:
    """The contour's points slid along each piece to equal steps of its cell measure
    (corners and each ring's first point stay)."""
    s_copy = arclengths(contour)[0]
    parts = pieces(contour)
    measured = measure_all(tree, [(poly, arc) for _, _, _, poly, arc in parts])
    for (a, i, j, _, _), (mu, sarc, _, _) in zip(parts, measured):
        s_copy[a + i : a + j] = np.interp(mu[-1] * np.arange(j - i) / (j - i), mu, sarc)
    rs = slid_copy(contour, s_copy)
    if rs is None:
        raise SelectionError(f"{contour.source}: the copy fitted to the grid is invalid")
    return rs
