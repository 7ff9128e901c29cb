"""Boundary recovery: every extra boundary node taken out, one at a time.

An extra boundary node ``c`` lies on the contour edge between its two boundary
neighbours ``a`` and ``b`` (the deformation put it there).  Its triangles form a
simple polygon, star-shaped from ``c``, with ``a``, ``c`` and ``b`` on one
straight side; without ``c`` the same polygon has the vertices ``a, b`` and the
chain of ``c``'s other neighbours.  A simple polygon always has a triangulation
of its own vertices with every triangle counter-clockwise, so the node can
always be taken out: its triangles are replaced by the triangulation of that
polygon with the largest smallest angle (:func:`.cavity.best_triangulation`),
and the boundary edges ``a c``, ``c b`` by ``a b``.  Nodes are taken out in
boundary order; once all are out, the mesh's boundary nodes are exactly the
contour's points.  The cost is one small polygon per extra node.
"""

from __future__ import annotations

import numpy as np

from .cavity import best_triangulation, renumber
from .mesh import Mesh


def recover(mesh: Mesh) -> tuple[Mesh, int]:
    """``mesh`` with its extra boundary nodes taken out (see the module), and how many.

    A node whose polygon has no counter-clockwise triangulation in floating point
    (its neighbours collinear to round-off) stays, and the contract check counts it.
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
    prv = np.full(n, -1, dtype=np.int64)
    nxt[mesh.lines[:, 0]] = mesh.lines[:, 1]
    prv[mesh.lines[:, 1]] = mesh.lines[:, 0]
    gone = np.zeros(n, dtype=bool)
    for c in range(m, m + e):
        a, b = int(prv[c]), int(nxt[c])
        link: dict[int, int] = {}  # c's triangles (c, u, v) counter-clockwise: u -> v
        for t in star[c]:
            u, v, w = tri[t]
            if u == c:
                link[v] = w
            elif v == c:
                link[w] = u
            else:
                link[u] = v
        ring = [a, b]
        x = link.get(b, -1)
        while x != a and x >= 0 and len(ring) <= len(link) + 1:
            ring.append(x)
            x = link.get(x, -1)
        if x != a or len(ring) < 3:
            continue
        best = best_triangulation(pts[ring])
        if best is None:
            continue
        for t in star[c]:
            alive[t] = False
            for v in tri[t]:
                if v != c:
                    star[v].discard(t)
        star[c] = set()
        for u, v, w in np.asarray(ring)[best[0]].tolist():
            star[u].add(len(tri))
            star[v].add(len(tri))
            star[w].add(len(tri))
            tri.append((u, v, w))
            alive.append(True)
        gone[c] = True
        nxt[a], prv[b] = b, a
    taken = int(gone.sum())
    if taken == 0:
        return mesh, 0
    kept = np.array(tri, dtype=np.int64)[np.array(alive)]
    return renumber(mesh, kept, gone), taken
