"""Geometry helpers the stages share: areas, rings, edge tables, node masks.

Pure functions over numpy arrays: points ``(n, 2)`` float64, triangles
``(t, 3)`` int64 node indices.
"""

from __future__ import annotations

import numpy as np

from .errors import InputError

#: :func:`edge_uses`' table: ``(lo, hi, fwd, rev)`` arrays, one entry per undirected edge.
EdgeTable = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def next_on_ring(ring: np.ndarray) -> np.ndarray:
    """Index of the next entry on the same closed ring (each ring's entries contiguous)."""
    idx = np.arange(len(ring))
    change = np.flatnonzero(np.diff(ring)) + 1
    starts = np.concatenate([[0], change])
    sizes = np.diff(np.concatenate([starts, [len(ring)]]))
    start = np.repeat(starts, sizes)
    return start + (idx - start + 1) % np.repeat(sizes, sizes)


def prev_on_ring(ring: np.ndarray) -> np.ndarray:
    """Index of the previous entry on the same closed ring (each ring's entries
    contiguous): the inverse of :func:`next_on_ring`."""
    prev = np.empty(len(ring), dtype=np.int64)
    prev[next_on_ring(ring)] = np.arange(len(ring))
    return prev


def signed_area(p: np.ndarray) -> float:
    """Shoelace area of a closed polygon given without its closing point."""
    x, y = p[:, 0], p[:, 1]
    # subtract a reference point: keeps precision for large offsets
    x = x - x[0]
    y = y - y[0]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def signed_areas(
    points: np.ndarray, tri: np.ndarray, sign: float = 0.0, flat: float = 0.0, round_off=0.0
) -> np.ndarray:
    """Signed area of every triangle: positive when its corners run counter-clockwise;
    plus ``sign`` times a flat margin where ``sign`` is not 0 (``flat`` times its longest
    side squared plus ``round_off`` times that side times its corners' largest
    coordinate: :func:`.deform.areas_with_margin`).

    ``0.5 ((x1 - x0) (y2 - y0) - (x2 - x0) (y1 - y0))`` in one compiled loop
    (:mod:`._divcurl`, without fused multiply-adds: numpy's bits, tested)."""
    from ._divcurl import areas

    t = np.ascontiguousarray(tri, dtype=np.int64).reshape(-1, 3)
    out = np.empty(len(t))
    if len(t):
        if len(points) == 0 or t.min() < 0 or t.max() >= len(points):
            raise InputError(f"a triangle names a node outside 0 .. {len(points) - 1}")
        areas(np.asarray(points, dtype=np.float64), t, float(sign), flat, round_off, out)
    return out


def edge_uses(tri: np.ndarray, n: int) -> EdgeTable:
    """Each undirected edge once: ``(lo, hi, fwd, rev)``, nodes ``lo < hi`` and how many
    triangles walk it ``lo -> hi`` and ``hi -> lo``.

    By a counting sort on ``lo`` and a sort of each node's few neighbours (a compiled
    loop, :mod:`._geometry`): linear in the triangles.  In a conforming
    counter-clockwise mesh an inner edge has ``fwd = rev = 1`` and a boundary edge one
    use.  A triangle naming a node outside ``0 .. n - 1`` is an :class:`InputError`.
    """
    from ._geometry import edge_table

    t = np.ascontiguousarray(tri, dtype=np.int64).reshape(-1, 3)
    k = 3 * len(t)
    # (np.empty's pages are mapped when first written: only the table's are)
    row, hi, lo, fwd, rev = np.empty(n + 1, np.int64), *(np.empty(k, np.int64) for _ in range(4))
    m = edge_table(t, n, row, hi, lo, fwd, rev)
    if m < 0:
        raise InputError(f"a triangle names a node outside 0 .. {n - 1}")
    return lo[:m], hi[:m].copy(), fwd[:m], rev[:m]  # (hi: every side was written there)


def patch_edge_uses(edges: EdgeTable, n: int, removed: np.ndarray, added: np.ndarray) -> EdgeTable:
    """:func:`edge_uses` after replacing triangles ``removed`` by ``added``, from the
    table ``edges`` of the mesh before: the same table a recount would give (tested),
    at the cost of the changed triangles only."""
    lo, hi, fwd, rev = edges
    key = lo * n + hi  # sorted: by lo, then hi
    r_lo, r_hi, r_f, r_r = edge_uses(removed, n)
    a_lo, a_hi, a_f, a_r = edge_uses(added, n)
    dkey = np.concatenate([r_lo * n + r_hi, a_lo * n + a_hi])
    df = np.concatenate([-r_f, a_f])
    dr = np.concatenate([-r_r, a_r])
    ukey, inv = np.unique(dkey, return_inverse=True)
    df = np.bincount(inv, weights=df, minlength=len(ukey)).astype(np.int64)
    dr = np.bincount(inv, weights=dr, minlength=len(ukey)).astype(np.int64)
    pos = np.searchsorted(key, ukey)
    found = (pos < len(key)) & (key[np.minimum(pos, len(key) - 1)] == ukey)
    fwd, rev = fwd.astype(np.int64), rev.astype(np.int64)  # copies
    p = pos[found]
    fwd[p] += df[found]
    rev[p] += dr[found]
    empty = p[(fwd[p] == 0) & (rev[p] == 0)]  # (edges no triangle uses any more)
    if len(empty):
        keep = np.ones(len(lo), dtype=bool)
        keep[empty] = False
        lo, hi, fwd, rev = lo[keep], hi[keep], fwd[keep], rev[keep]
    new = ~found  # (edges of added triangles only: used)
    if new.any():
        at = pos[new] - np.searchsorted(empty, pos[new])  # (where, once the empty went)
        k = ukey[new]
        lo, hi = np.insert(lo, at, k // n), np.insert(hi, at, k % n)
        fwd, rev = np.insert(fwd, at, df[new]), np.insert(rev, at, dr[new])
    return lo, hi, fwd, rev


def directed_boundary(
    lo: np.ndarray, hi: np.ndarray, fwd: np.ndarray, rev: np.ndarray
) -> np.ndarray:
    one = fwd + rev == 1
    return np.where(
        (fwd[one] == 1)[:, None],
        np.column_stack([lo[one], hi[one]]),
        np.column_stack([hi[one], lo[one]]),
    )


def boundary_edges(tri: np.ndarray, n: int) -> np.ndarray:
    """Directed edges used by one triangle only (domain on their left for CCW triangles)."""
    return directed_boundary(*edge_uses(tri, n))


def touching(mask: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Triangles with a corner in the node mask ``mask``: one compiled pass
    (:mod:`._geometry`; a node outside ``mask`` is an :class:`InputError`)."""
    from ._geometry import touching as kernel

    t = np.ascontiguousarray(tri, dtype=np.int64).reshape(-1, 3)
    out = np.empty(len(t), dtype=bool)
    if len(t):
        m = np.ascontiguousarray(mask, dtype=bool).view(np.uint8)
        if kernel(m, t, out.view(np.uint8)) >= 0:
            raise InputError(f"a triangle names a node outside 0 .. {len(mask) - 1}")
    return out


def node_stars(tri: np.ndarray):
    """A lookup: node -> the rows of ``tri`` it is a corner of (a list)."""
    flat = tri.ravel()
    order = np.argsort(flat, kind="stable")
    nodes = flat[order]
    rows = (order // 3).tolist()

    def star(v: int) -> list[int]:
        lo, hi = np.searchsorted(nodes, [v, v + 1])
        return rows[lo:hi]

    return star


def sorted_lookup(sorted_keys: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(found, position)`` of each of ``k`` in ``sorted_keys`` (ascending)."""
    pos = np.clip(np.searchsorted(sorted_keys, k), 0, max(len(sorted_keys) - 1, 0))
    found = sorted_keys[pos] == k if len(sorted_keys) else np.zeros(len(k), dtype=bool)
    return found, pos


def domain(rings: list[np.ndarray], box: tuple | None = None):
    """Shapely geometry of the region the rings enclose (even-odd), or ``box`` minus it."""
    from functools import reduce

    import shapely

    polys = [shapely.Polygon(r) for r in rings]
    inside = reduce(shapely.symmetric_difference, polys)
    if box is None:
        return inside
    return shapely.box(*box).difference(inside)


def unique_inverse(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(keys, return_inverse=True)``, by a stable sort: the keys of a mesh's
    element entries come in runs (triangles in grid order), which a merge sort takes
    fast (0.25 s against 0.54 s for 3.8 million element entries)."""
    order = np.argsort(keys, kind="stable")
    sk = keys[order]
    new = np.empty(len(sk), dtype=bool)
    new[:1] = True
    np.not_equal(sk[1:], sk[:-1], out=new[1:])
    inverse = np.empty(len(sk), dtype=np.int64)
    inverse[order] = np.cumsum(new) - 1
    return sk[new], inverse


def morton(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Morton (Z-order) codes of lattice cells ``(x, y)``, each below 2**28: their bits
    interleaved, x's in the even places (sorted, nearby cells come mostly together)."""

    def spread(v):
        v = np.asarray(v, dtype=np.int64) & 0xFFFFFFFF
        for shift, mask in (
            (16, 0x0000FFFF0000FFFF),
            (8, 0x00FF00FF00FF00FF),
            (4, 0x0F0F0F0F0F0F0F0F),
            (2, 0x3333333333333333),
            (1, 0x5555555555555555),
        ):
            v = (v | (v << shift)) & mask
        return v

    return spread(x) | (spread(y) << 1)
