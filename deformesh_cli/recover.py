"""Boundary recovery: every extra boundary node taken out, a contour edge at a time.

The extra boundary nodes ``c1 .. ck`` between two consecutive contour points
``a`` and ``b`` lie on the segment ``a b`` (the deformation put them there).
Their *cavity* is every triangle touching one of them, grown by the star of
every inner node it reaches that lies in the diametral disk of ``a b`` (such a
node sees ``a b`` under more than a right angle: it would leave slivers along
the edge, one per extra node).  When the cavity's outline is one simple loop
(through every node of it but the inner ones it covers), the polygon without
``c1 .. ck`` is simple and has the side ``a b``: its constrained Delaunay
triangulation (:func:`.cavity.delaunay_polygon`, the largest smallest angle of
any triangulation of its vertices) replaces the cavity, and the boundary edges
``a c1 .. ck b`` become ``a b``.  The inner nodes it covers go with it, so the
triangle on ``a b`` has its apex outside the disk (an angle under 90 degrees
there) unless a boundary node lies in it.

When the outline is not simple (the cavity touches itself), the run is halved
and each half taken in turn; a run of one node whose grown cavity is not simple
takes its star alone, which is: a boundary node's star is star-shaped from it.  So every
extra node can be taken out, each contour edge in one step where its cavity
allows, and the cost grows with the cavities' sizes, not their squares.  Once
all are out, the mesh's boundary nodes are exactly the contour's points.
"""

from __future__ import annotations

import numpy as np

from .cavity import delaunay_polygon, renumber
from .mesh import Mesh


def _outline(tris: list[tuple[int, int, int]]) -> tuple[list[int], set[int]] | None:
    """The outline of the triangles ``tris`` counter-clockwise and the nodes it
    surrounds, if it is one simple loop; else None."""
    edges = {(u, v) for t in tris for u, v in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))}
    after: dict[int, int] = {}
    for u, v in edges:
        if (v, u) in edges:
            continue
        if u in after:
            return None
        after[u] = v
    if not after:
        return None
    start = min(after)
    ring = [start]
    while after[ring[-1]] != start:
        ring.append(after[ring[-1]])
        if len(ring) > len(after):
            return None
    if len(ring) != len(after):
        return None
    nodes = {v for t in tris for v in t}
    return ring, nodes - set(ring)


def recover(mesh: Mesh) -> tuple[Mesh, int]:
    """``mesh`` with its extra boundary nodes taken out (see the module), and how many.

    A run of one node whose polygon has no counter-clockwise triangulation in
    floating point (its neighbours collinear to round-off) stays, and the
    contract check counts it.
    """
    m, e = mesh.n_contour, mesh.n_extra
    if e == 0:
        return mesh, 0
    tri = [tuple(t) for t in mesh.triangles.tolist()]
    pts = mesh.points
    n = len(pts)
    alive = [True] * len(tri)
    star: list[set[int]] = [set() for _ in range(n)]
    for t, (u, v, w) in enumerate(tri):
        star[u].add(t)
        star[v].add(t)
        star[w].add(t)
    nxt = np.full(n, -1, dtype=np.int64)
    nxt[mesh.lines[:, 0]] = mesh.lines[:, 1]
    gone = np.zeros(n, dtype=bool)
    extra = np.zeros(n, dtype=bool)
    extra[m : m + e] = True
    # runs of extra nodes, each between two contour points
    runs = []
    for a in mesh.lines[~extra[mesh.lines[:, 0]], 0].tolist():
        run = []
        x = int(nxt[a])
        while extra[x]:
            run.append(x)
            x = int(nxt[x])
        if run:
            runs.append((a, run, x))
    boundary = np.zeros(n, dtype=bool)
    boundary[mesh.lines.ravel()] = True

    def take(a: int, run: list[int], b: int, grow: bool = True) -> None:
        cav_set = {t for c in run for t in star[c]}
        # inner nodes in the diametral disk of a b, reached from the run, go too
        mid, r2 = 0.5 * (pts[a] + pts[b]), 0.25 * float(((pts[a] - pts[b]) ** 2).sum())
        seen: set[int] = set()
        todo = {v for t in cav_set for v in tri[t]} if grow else set()
        while todo:
            v = todo.pop()
            seen.add(v)
            if boundary[v] or float(((pts[v] - mid) ** 2).sum()) >= r2:
                continue
            for t in star[v]:
                if t not in cav_set:
                    cav_set.add(t)
                    todo |= {w for w in tri[t] if w not in seen}
        cav = sorted(cav_set)
        found = _outline([tri[t] for t in cav])
        ok = None
        if found is not None:
            ring, inner = found
            drop = set(run)
            poly = [v for v in ring if v not in drop]
            tris = delaunay_polygon(pts[poly])
            ok = (poly, inner, tris) if tris is not None else None
        if ok is None:
            if len(run) > 1:
                half = len(run) // 2
                take(a, run[:half], b)
                take(a, run[half:], b)
            elif grow:
                take(a, run, b, grow=False)  # (its star alone: always simple)
            return
        poly, inner, tris = ok
        for t in cav:
            alive[t] = False
            for v in tri[t]:
                star[v].discard(t)
        for u, v, w in np.asarray(poly)[tris].tolist():
            star[u].add(len(tri))
            star[v].add(len(tri))
            star[w].add(len(tri))
            tri.append((u, v, w))
            alive.append(True)
        gone[run] = True
        gone[list(inner)] = True

    for a, run, b in runs:
        take(a, run, b)
    taken = int(gone[m : m + e].sum())
    if not gone.any():
        return mesh, 0
    kept = np.array(tri, dtype=np.int64)[np.array(alive)]
    return renumber(mesh, kept, gone), taken
