"""Boundary recovery: every extra boundary node taken out, a contour edge at a time.

The extra boundary nodes ``c1 .. ck`` between two consecutive contour points
``a`` and ``b`` lie on the segment ``a b`` (the deformation put them there).
Their *cavity* is the triangles touching any of them, grown by the star of
every inner node it reaches in the diametral disk of ``a b`` (such a node sees
``a b`` under more than a right angle; along a long edge those nodes would
leave a sliver each).  When the cavity's outline is one simple loop (through
every node of it but the ones it surrounds), the polygon without ``c1 .. ck``
is simple and has the side ``a b``: its constrained Delaunay triangulation
(:func:`.cavity.delaunay_polygon`, the largest smallest angle of any
triangulation of its vertices) replaces the cavity, the boundary edges
``a c1 .. ck b`` become ``a b``, and the nodes it surrounds go with it.

Where that outline is not simple (the cavity touches itself), the triangles
touching the run alone are taken the same way, the run halved while their
outline is not simple (a run of one node is a boundary node's star,
star-shaped from it, always simple); then, while the apex of the triangle on
``a b`` is an inner node in the disk, that node is taken out and its star
meshed again (star-shaped from it: the polygon of its neighbours is simple).
Either way the apex on ``a b`` ends outside the disk, or at a boundary node.

Every step succeeds, the cost grows with the cavities' sizes, not their
squares, and once all are done the mesh's boundary nodes are exactly the
contour's points.
"""

from __future__ import annotations

import numpy as np

from .cavity import delaunay_polygon, outline, renumber
from .mesh import Mesh


def recover(mesh: Mesh, only: set[tuple[int, int]] | None = None) -> tuple[Mesh, int]:
    """``mesh`` with its extra boundary nodes taken out (see the module), and how many.
    ``only``: the runs between these pairs of contour points (either order) alone.

    A run of one node whose polygon has no counter-clockwise triangulation in
    floating point (its neighbours collinear to round-off) stays, and the
    contract check counts it.
    """
    m, e = mesh.n_contour, mesh.n_extra
    if e == 0:
        return mesh, 0
    tri = mesh.triangles.tolist()
    pts = mesh.points
    n = len(pts)
    alive = [True] * len(tri)
    star = _Stars(mesh.triangles, n)
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
        if run and (only is None or (a, x) in only or (x, a) in only):
            runs.append((a, run, x))
    boundary = np.zeros(n, dtype=bool)
    boundary[mesh.lines.ravel()] = True

    def replace(cav: list[int], poly: list[int], tris: np.ndarray) -> None:
        """The triangles ``cav`` replaced by ``tris`` over the polygon ``poly``."""
        for t in cav:
            alive[t] = False
            for v in tri[t]:
                star[v].discard(t)
        for u, v, w in np.asarray(poly)[tris].tolist():
            star[u].add(len(tri))
            star[v].add(len(tri))
            star[w].add(len(tri))
            tri.append([u, v, w])
            alive.append(True)

    def in_disk(v: int, a: int, b: int) -> bool:
        """``v`` is an inner node strictly inside the diametral disk of ``a b`` (it sees
        the segment under more than a right angle: ``(v - a) . (v - b) < 0``)."""
        return not boundary[v] and float(np.dot(pts[v] - pts[a], pts[v] - pts[b])) < 0.0

    def take(run: list[int], a: int = -1, b: int = -1) -> bool:
        cav_set = {t for c in run for t in star[c]}
        if a >= 0:  # grown by the inner nodes in the disk of a b it reaches
            seen: set[int] = set()
            todo = {v for t in cav_set for v in tri[t]}
            while todo:
                v = todo.pop()
                seen.add(v)
                if not in_disk(v, a, b):
                    continue
                for t in star[v]:
                    if t not in cav_set:
                        cav_set.add(t)
                        todo |= {w for w in tri[t] if w not in seen}
        cav = sorted(cav_set)
        found = outline([tri[t] for t in cav])
        tris = None
        if found is not None:
            ring, inner = found
            drop = set(run)
            poly = [v for v in ring if v not in drop]
            tris = delaunay_polygon(pts[poly])
        if tris is None:
            if a < 0 and len(run) > 1:
                half = len(run) // 2
                take(run[:half])
                take(run[half:])
            return False
        replace(cav, poly, tris)
        gone[run] = True
        gone[list(inner)] = True
        return True

    def clear(a: int, b: int) -> None:
        """Inner nodes in the diametral disk of ``a b`` taken out while one is the apex
        of the triangle on ``a b``, each by meshing its star again (star-shaped from
        it, so the polygon of its neighbours is simple)."""
        while True:
            on = list(star[a] & star[b])  # (stars hold live triangles only)
            if len(on) != 1:
                return
            x = next(v for v in tri[on[0]] if v != a and v != b)
            if not in_disk(x, a, b):
                return
            cav = sorted(star[x])
            found = outline([tri[t] for t in cav])  # (x's star: its neighbours around it)
            tris = None if found is None else delaunay_polygon(pts[found[0]])
            if tris is None:
                return
            replace(cav, found[0], tris)
            gone[x] = True

    for a, run, b in runs:
        if not take(run, a, b):
            take(run)
            if gone[run].all():
                clear(a, b)
    taken = int(gone[m : m + e].sum())
    if not gone.any():
        return mesh, 0
    kept = np.array(tri, dtype=np.int64)[np.array(alive)]
    return renumber(mesh, kept, gone), taken


class _Stars:
    """Each node's triangles, as a set made when first asked for (from one sort of the
    mesh's corners): recovery reads and changes the stars of the few nodes near the
    boundary, not of all."""

    def __init__(self, tri: np.ndarray, n: int):
        flat = np.asarray(tri, dtype=np.int64).ravel()
        self._order = (np.argsort(flat, kind="stable") // 3).tolist()
        self._start = np.concatenate([[0], np.cumsum(np.bincount(flat, minlength=n))]).tolist()
        self._made: dict[int, set[int]] = {}

    def __getitem__(self, v: int) -> set[int]:
        s = self._made.get(v)
        if s is None:
            s = self._made[v] = set(self._order[self._start[v] : self._start[v + 1]])
        return s
