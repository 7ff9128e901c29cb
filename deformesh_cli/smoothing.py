"""Flips and smoothing: the moves that raise a mesh's smallest angle without changing
its boundary (the quality stage's and the cavity kernel's, :mod:`.improve` and
:mod:`.cavity`).

Each flip or node move is kept only if it raises the smallest angle of the triangles
it touches by more than :data:`GAIN` degrees, so nothing folds and the same mesh
always moves the same way.  Nothing here imports another module of the package.
"""

from __future__ import annotations

import numpy as np

from ._smoothing import tan_min

_SQRT3_2 = np.sqrt(3.0) / 2.0
#: Pattern-search steps per smoothing sweep (the step halves when nothing improves).
SEARCH_STEPS = 8

#: A change counts only if it raises the smallest angle by more than this (degrees).
GAIN = 0.01

_DIRS = np.array([(np.cos(a), np.sin(a)) for a in np.arange(8) * np.pi / 4])


def tan_min_angle(ax, ay, bx, by, cx, cy):
    """Tangent of the smallest angle of triangles ``abc`` (coordinates as separate
    arrays that broadcast), ``-inf`` where the triangle is not counter-clockwise.

    The smallest angle (opposite the shortest edge, at most 60 degrees) has
    ``tan = 2 cross / (S - 2 s_min)`` by the law of cosines (``s`` the squared
    edge lengths, ``S`` their sum; the denominator is positive), and the
    tangent orders angles as the angles do: no ``arctan2`` in the search.
    """
    e0x, e0y, e1x, e1y, e2x, e2y = cx - bx, cy - by, ax - cx, ay - cy, bx - ax, by - ay
    cross = e1x * e2y - e1y * e2x
    s0, s1, s2 = e0x * e0x + e0y * e0y, e1x * e1x + e1y * e1y, e2x * e2x + e2y * e2y
    shortest = np.minimum(np.minimum(s0, s1), s2)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = 2 * cross / (s0 + s1 + s2 - 2 * shortest)
    return np.where(cross > 0, t, -np.inf)


def _tan_min(pts, tri):
    """:func:`tan_min_angle` of each triangle of ``tri`` (a compiled loop, the same
    bits: tested)."""
    t = np.ascontiguousarray(tri, dtype=np.int64).reshape(-1, 3)
    out = np.empty(len(t))
    if len(t):
        tan_min(np.asarray(pts, dtype=np.float64), t, out)
    return out


def _flip_all(pts: np.ndarray, tri: np.ndarray, target: float, max_passes: int = 50) -> int:
    """Flip inner edges of ``tri`` (in place) while a flip raises the smallest angle of a
    pair that is under ``target`` (a tangent)."""
    total = 0
    for _ in range(max_passes):
        t1, k1, t2, k2 = _edge_pairs(tri)
        if len(t1) == 0:
            break
        tan = _tan_min(pts, tri)
        before = np.minimum(tan[t1], tan[t2])
        low = before < target  # (only these pairs may flip: the others are not measured)
        t1, k1, t2, k2, before = t1[low], k1[low], t2[low], k2[low], before[low]
        u, w, x = tri[t1, k1], tri[t1, (k1 + 1) % 3], tri[t1, (k1 + 2) % 3]
        y = tri[t2, (k2 + 2) % 3]
        after = np.minimum(
            _tan_min(pts, np.column_stack([u, y, x])), _tan_min(pts, np.column_stack([y, w, x]))
        )
        ok = after > _raised(before)
        gain = after - before
        if not ok.any():
            break
        cand = np.flatnonzero(ok)
        cand = cand[np.argsort(-gain[cand], kind="stable")]
        # one flip per triangle per pass: the best gains first
        taken = np.zeros(len(tri), dtype=bool)
        chosen = []
        for c in cand.tolist():
            a, b = t1[c], t2[c]
            if taken[a] or taken[b]:
                continue
            taken[a] = taken[b] = True
            chosen.append(c)
        chosen = np.array(chosen)
        tri[t1[chosen]] = np.column_stack([u[chosen], y[chosen], x[chosen]])
        tri[t2[chosen]] = np.column_stack([y[chosen], w[chosen], x[chosen]])
        total += len(chosen)
    return total


def _edge_pairs(tri: np.ndarray):
    """Inner edges as (t1, k1, t2, k2): edge k1 of t1 (from corner k1 to k1 + 1) is
    edge k2 of t2, walked the other way; by their lower node, then their higher
    (a counting sort, compiled: :mod:`._geometry`)."""
    from ._geometry import edge_pairs

    tri = np.ascontiguousarray(tri, dtype=np.int64)
    n = int(tri.max(initial=-1)) + 1
    e = 3 * len(tri)
    out = [np.empty(e, dtype=np.int64) for _ in range(4)]
    scratch = (
        np.empty(n + 1, dtype=np.int64),
        np.empty(e, dtype=np.int64),
        np.empty(e, dtype=np.int64),
    )
    m = edge_pairs(tri, n, *scratch, *out)
    return tuple(o[:m] for o in out)


def _smooth(pts: np.ndarray, tri: np.ndarray, movable: np.ndarray) -> int:
    """One sweep over the movable nodes of ``tri``, an independent set at a time."""
    nodes = np.unique(tri[movable[tri]])
    if len(nodes) == 0:
        return 0
    local = np.full(int(tri.max()) + 1, -1, dtype=np.int64)  # node id -> position in nodes
    local[nodes] = np.arange(len(nodes))
    inc, slot = _incidence(tri, local, len(nodes))
    moves = 0
    for group in _independent_sets(tri, nodes, local):
        moves += _move(pts, tri, nodes[group], inc[group], slot[group])
    return moves


def _incidence(tri: np.ndarray, local: np.ndarray, count: int):
    """For each of ``count`` nodes (``local`` maps node ids to 0..count-1, or -1), its
    triangles (padded with -1) and its corner in each."""
    t = np.repeat(np.arange(len(tri)), 3)
    k = np.tile(np.arange(3), len(tri))
    v = local[tri.ravel()]
    keep = v >= 0
    v, t, k = v[keep], t[keep], k[keep]
    order = np.argsort(v, kind="stable")
    v, t, k = v[order], t[order], k[order]
    counts = np.bincount(v, minlength=count)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    col = np.arange(len(v)) - start[v]
    width = int(counts.max())
    inc = np.full((count, width), -1, dtype=np.int64)
    slot = np.zeros((count, width), dtype=np.int64)
    inc[v, col] = t
    slot[v, col] = k
    return inc, slot


def _independent_sets(tri: np.ndarray, nodes: np.ndarray, local: np.ndarray) -> list[np.ndarray]:
    """Split ``nodes`` (positions into it) into sets of which no two share a triangle.

    Jones-Plassmann colouring: in each round, every node whose priority beats all
    its neighbours' still left joins the round's set.  Priorities are a fixed
    hash of the node id (deterministic, and scattered, so that a round takes
    many nodes: ids in grid order would let only a few win per row).
    """
    e = local[np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])]
    e = e[(e[:, 0] >= 0) & (e[:, 1] >= 0)]
    e = np.concatenate([e, e[:, ::-1]])
    prio = (nodes.astype(np.uint64) * np.uint64(2654435761)) % np.uint64(2**32)
    prio = prio.astype(np.int64) * len(nodes) + np.arange(len(nodes))  # no ties
    sets = []
    left = np.ones(len(nodes), dtype=bool)
    while left.any():
        both = left[e[:, 0]] & left[e[:, 1]]
        pick = left.copy()
        pick[e[both & (prio[e[:, 1]] > prio[e[:, 0]]), 0]] = False
        chosen = np.flatnonzero(pick)
        sets.append(chosen)
        left[chosen] = False
    return sets


def _move(pts, tri, nodes, inc, slot) -> int:
    """Move each of ``nodes`` (no two share a triangle) to raise its worst angle."""
    valid = inc >= 0
    t = np.where(valid, inc, 0)
    a = tri[t, (slot + 1) % 3]  # the two other corners, counter-clockwise after the node
    b = tri[t, (slot + 2) % 3]
    ax, ay, bx, by = pts[a, 0], pts[a, 1], pts[b, 0], pts[b, 1]  # (n, d)
    # each node's triangles one after the other, without the padding (a node of high
    # valence pads every other node's row to its width)
    first = np.concatenate([[0], np.cumsum(valid.sum(axis=1))[:-1]])
    quality = _ApexQuality(first, *(v[valid][:, None] for v in (ax, ay, bx, by)))

    px, py = pts[nodes, 0].copy(), pts[nodes, 1].copy()
    best = quality(px[:, None], py[:, None])[:, 0]
    start = best.copy()
    # the mean of the apexes that make each triangle equilateral (left of a -> b)
    count = valid.sum(axis=1)
    ex = np.where(valid, 0.5 * (ax + bx) - _SQRT3_2 * (by - ay), 0.0).sum(axis=1) / count
    ey = np.where(valid, 0.5 * (ay + by) + _SQRT3_2 * (bx - ax), 0.0).sum(axis=1) / count
    q = quality(ex[:, None], ey[:, None])[:, 0]
    take = q > _raised(best)
    px[take], py[take], best[take] = ex[take], ey[take], q[take]
    length = np.where(valid, np.hypot(ax - px[:, None], ay - py[:, None]), 0.0)
    step = 0.2 * length.sum(axis=1) / count
    # the pattern search, every node at once (compiled: :mod:`._smoothing`)
    quality.search(px, py, best, step)
    moved = best > _raised(start)
    pts[nodes[moved], 0] = px[moved]
    pts[nodes[moved], 1] = py[moved]
    return int(moved.sum())


class _ApexQuality:
    """``quality(px, py)``: for (n, c) candidate positions of n nodes, the tangent of
    the smallest angle of each node's worst triangle ``(p, a, b)`` (``first``: each
    node's first triangle, its triangles in a run; ``a``, ``b``: (t, 1)).

    :func:`tan_min_angle`'s arithmetic operation for operation, so the same bits,
    but with the side ``a -> b``, which no candidate moves, squared once, in a
    compiled loop (:mod:`._smoothing`): the quality stage spends most of its time
    here.  :meth:`search` runs :func:`_move`'s pattern search on the same triangles,
    compiled too."""

    def __init__(self, first, ax, ay, bx, by):
        self._flat = [np.ascontiguousarray(v, dtype=np.float64).ravel() for v in (ax, ay, bx, by)]
        s0 = bx - ax
        s0 *= s0
        e0y = by - ay
        e0y *= e0y
        s0 += e0y
        self._s0 = np.ascontiguousarray(s0).ravel()
        self._first = np.ascontiguousarray(first, dtype=np.int64)

    def __call__(self, px, py):
        from ._smoothing import apex_quality

        shape = np.broadcast_shapes(np.shape(px), np.shape(py))
        px = np.ascontiguousarray(np.broadcast_to(px, shape), dtype=np.float64)
        py = np.ascontiguousarray(np.broadcast_to(py, shape), dtype=np.float64)
        out = np.empty(shape)
        apex_quality(self._first, *self._flat, self._s0, px, py, out)
        return out

    def search(self, px, py, best, step):
        """:data:`SEARCH_STEPS` rounds from the (n,) positions ``(px, py)`` (each node's
        worst tangent ``best``): along :data:`_DIRS` at ``step``, the best taken where
        it beats the raised ``best``, else the step halved; all four updated in
        place."""
        from ._smoothing import search

        search(
            self._first, *self._flat, self._s0, _DIRS, SEARCH_STEPS, _GAIN_TAN, _RIGHT,
            px, py, best, step,
        )  # fmt: skip


#: The tangent of :data:`GAIN` degrees (``math.tan(math.radians(GAIN))``, written out:
#: the raise below is plain arithmetic, the same bits on every machine).
_GAIN_TAN = 0.0001745329269716253

#: No raise goes past this tangent (of an angle 1e-12 radians short of a right angle).
_RIGHT = 1e12


def _raised(tan_angle: np.ndarray) -> np.ndarray:
    """The tangent of an angle :data:`GAIN` degrees larger (a move must beat it), by the
    tangent addition formula ``(t + g) / (1 - t g)`` (no ``arctan``/``tan``, whose SIMD
    versions differ in the last bits between processors), at most :data:`_RIGHT`;
    NaN stays NaN, -inf (a folded triangle) gives ``-1 / g``, the tangent of GAIN
    over -90 degrees.  The compiled search (:mod:`._smoothing`) does the same
    operations."""
    t = np.asarray(tan_angle, dtype=np.float64)
    with np.errstate(all="ignore"):
        den = 1.0 - t * _GAIN_TAN
        r = np.where(den > 0, np.minimum((t + _GAIN_TAN) / den, _RIGHT), _RIGHT)
    r = np.where(np.isnan(t), t, r)
    return np.where(t == -np.inf, -1.0 / _GAIN_TAN, r)
