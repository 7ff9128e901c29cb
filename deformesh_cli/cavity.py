"""The re-meshing kernel the stages share (:mod:`.recover`, :mod:`.untangle`).

A cavity grown by whole stars (:func:`grow`), the nodes it holds inside
(:func:`inner_nodes`), its outline (:func:`outline`, :func:`loop`), the
triangulation of an outline with the largest smallest angle
(:func:`best_triangulation` over every chord, cubic in the outline's length;
boundary recovery's compiled constrained Delaunay triangulation gives the same
angle faster, :mod:`.recover`), and a mesh renumbered without the nodes a
re-meshing took out (:func:`renumber`).  Nothing here
prints or exits.
"""

from __future__ import annotations

import functools

import numpy as np

from .geometry import signed_areas
from .mesh import Mesh
from .quality import measures


def grow(tri: np.ndarray, stars, cavity: list[int], boundary: np.ndarray, limit: int):
    """``cavity`` with every triangle touching it, and the inner nodes (not on the
    ``boundary`` mask) it then holds inside: ``(cavity, inner nodes)``, or ``(None,
    None)`` past ``limit`` triangles."""
    verts = np.unique(tri[cavity])
    grown = sorted({t for v in verts.tolist() for t in stars(v)})
    if len(grown) > limit:
        return None, None
    return grown, inner_nodes(tri, stars, grown, boundary)


def inner_nodes(tri: np.ndarray, stars, cavity: list[int], boundary: np.ndarray) -> list[int]:
    """The nodes of the triangles ``cavity`` that are not on the ``boundary`` mask and
    have all their triangles in it: re-meshing the cavity takes them out (left in,
    they would be corners of no triangle)."""
    held = set(cavity)
    return [v for v in np.unique(tri[cavity]).tolist() if not boundary[v] and set(stars(v)) <= held]


#: Cavity outlines whose best triangulation is kept for the next time it is asked
#: for (a fold mended as its cavity grows asks again for the same outlines).
KEEP_TRIANGULATIONS = 8192


def best_triangulation(p: np.ndarray) -> tuple[np.ndarray, float] | None:
    """The triangulation of the simple counter-clockwise polygon ``p`` (k, 2) whose
    smallest angle is largest (dynamic programming over its chords), as ``(triangles
    in local indices (read-only), smallest angle)``; None if none has positive
    areas.  A function of ``p``'s coordinates only, so the answers are kept
    (:data:`KEEP_TRIANGULATIONS`)."""
    return best_triangulation_of(np.ascontiguousarray(p, dtype=np.float64).tobytes())


@functools.lru_cache(maxsize=KEEP_TRIANGULATIONS)
def best_triangulation_of(key: bytes) -> tuple[np.ndarray, float] | None:
    p = np.frombuffer(key, dtype=np.float64).reshape(-1, 2)
    k = len(p)
    if k < 3:
        return None
    chord = chords(p)
    r = np.arange(k)
    i, mid, j = np.nonzero((r[:, None, None] < r[None, :, None]) & (r[None, :, None] < r))
    angle = np.full((k, k, k), -1.0)
    tri = np.column_stack([i, mid, j])
    ok = (signed_areas(p, tri) > 0) & chord[i, mid] & chord[mid, j] & chord[i, j]
    # to 1e-9 degrees: angles equal but for round-off (a grid's right angles, carried
    # alike) tie exactly, and the first chord wins, wherever the polygon lies
    angle[i[ok], mid[ok], j[ok]] = np.round(measures(p, tri[ok])[0], 9)
    best = np.full((k, k), -1.0)
    pick = np.full((k, k), -1, dtype=np.int64)
    best[r[:-1], r[1:]] = 180.0
    for span in range(2, k):  # every (i, i + span) at once: each reads shorter spans only
        i = r[: k - span, None]
        j = i + span
        ms = i + 1 + r[None, : span - 1]
        val = np.minimum(np.minimum(angle[i, ms, j], best[i, ms]), best[ms, j])
        at = np.argmax(val, axis=1)
        row = r[: k - span]
        top = val[row, at]
        good = top > 0
        best[row[good], row[good] + span] = top[good]
        pick[row[good], row[good] + span] = ms[row, at][good]
    if best[0, k - 1] <= 0:
        return None
    out, todo = [], [(0, k - 1)]
    while todo:
        i, j = todo.pop()
        if j - i < 2:
            continue
        m = int(pick[i, j])
        out.append((i, m, j))
        todo += [(i, m), (m, j)]
    local = np.array(out, dtype=np.int64)
    local.flags.writeable = False  # (kept, and handed out again)
    return local, float(best[0, k - 1])


def chords(p: np.ndarray) -> np.ndarray:
    """``chord[i, j]``: the segment ``p[i] - p[j]`` lies inside the polygon ``p`` (its
    sides count)."""
    import shapely

    k = len(p)
    poly = shapely.Polygon(p)
    ok = np.zeros((k, k), dtype=bool)
    idx = np.arange(k)
    ok[idx, (idx + 1) % k] = ok[(idx + 1) % k, idx] = True
    pairs = [(i, j) for i in range(k) for j in range(i + 2, k) if not (i == 0 and j == k - 1)]
    if pairs:
        ij = np.array(pairs)
        lines = shapely.linestrings(np.stack([p[ij[:, 0]], p[ij[:, 1]]], axis=1))
        inside = shapely.covers(poly, lines)
        # and not along the boundary: a chord through another vertex is not a chord (its
        # interior meets the boundary; a DE-9IM test, without building the intersection)
        clean = shapely.relate_pattern(lines, shapely.boundary(poly), "F********")
        good = inside & clean & shapely.contains_xy(poly, *(0.5 * (p[ij[:, 0]] + p[ij[:, 1]])).T)
        ok[ij[good, 0], ij[good, 1]] = ok[ij[good, 1], ij[good, 0]] = True
    return ok


def renumber(mesh: Mesh, tri: np.ndarray, gone: np.ndarray) -> Mesh:
    """The mesh without the ``gone`` nodes: later nodes move down, boundary edges
    through a gone node join its neighbours (keeping the first edge's group)."""
    keep = ~gone
    new_id = np.cumsum(keep) - 1
    lines, groups = mesh.lines, mesh.line_group
    after = np.full(len(gone), -1, dtype=np.int64)
    after[lines[:, 0]] = lines[:, 1]
    start = ~gone[lines[:, 0]]
    ends = lines[start, 1].copy()
    while gone[ends].any():  # follow the boundary past removed nodes
        g = gone[ends]
        ends[g] = after[ends[g]]
    return Mesh(
        points=mesh.points[keep],
        triangles=new_id[tri],
        lines=np.column_stack([new_id[lines[start, 0]], new_id[ends]]),
        n_contour=mesh.n_contour,
        n_extra=mesh.n_extra - int(gone[mesh.n_contour : mesh.n_contour + mesh.n_extra].sum()),
        line_group=groups[start],
        groups=mesh.groups,
        n_box=mesh.n_box,
        point_data={k: v[keep] for k, v in mesh.point_data.items()},
    )


def outline(cavity) -> tuple[list[int], set[int]] | None:
    """The outline of the triangles ``cavity`` (rows of three nodes) counter-clockwise,
    from the first edge used once, and the nodes of theirs it leaves inside; None
    unless it is one simple loop."""
    edges = [(int(t[k]), int(t[(k + 1) % 3])) for t in cavity for k in range(3)]
    both = set(edges)
    after: dict[int, int] = {}
    for u, v in edges:
        if (v, u) in both:
            continue
        if u in after:
            return None
        after[u] = v
    if not after:  # (every edge paired: triangles folded onto each other)
        return None
    start = next(iter(after))
    ring = [start]
    while after.get(ring[-1], start) != start:
        ring.append(after[ring[-1]])
        if len(ring) > len(after):
            return None
    if len(ring) != len(after):
        return None
    return ring, {v for t in cavity for v in t} - set(ring)


def loop(cavity: np.ndarray, inner: set[int]) -> list[int] | None:
    """The outline of the triangles ``cavity`` counter-clockwise, if it is one simple
    loop through every node of them but the ``inner`` ones; else None."""
    found = outline(cavity.tolist())
    return found[0] if found is not None and found[1] == inner else None
