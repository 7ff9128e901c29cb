"""Meshing a small polygon with new inner points, its sides kept as they are.

:mod:`.merge` uses this where a long contour edge ``A-B`` beside short ones
keeps its extra boundary nodes: no triangulation of the cavity's own vertices
has a fair angle there, because the cavity is one or two cells deep while
``A-B`` is several cells long.  A mesh that keeps exactly the contour's
points needs nodes inside the cavity, graded from ``A-B``'s length down to
the short sides around it.  :func:`fill` places them:

1. a size at every polygon vertex, the shorter of its two sides; inside, the
   smallest of ``size(v) + GRADE * distance(v)`` over the vertices ``v`` (sizes
   grow away from short sides at a bounded rate), and no more than twice the
   distance to the nearest side (a narrow part gets points across its width);
2. candidate points on a lattice inside the polygon, taken nearest the sides
   first, each kept if it is at least :data:`SPACING` times the size there from
   every point kept before and :data:`WALL` times it from every side;
3. the Delaunay triangulation of the vertices and the kept points, whose
   triangles inside the polygon must have every side of the polygon as an
   edge and the polygon's area (the sides are kept, nothing is split);
4. :data:`SMOOTH` rounds of moving each new point to the mean of its
   neighbours, each followed by a new Delaunay triangulation; the round with
   the largest smallest angle is kept.

The polygon's sides are never split and its vertices never move.

It is also the kernel the other re-meshing stages share (:mod:`.merge`,
:mod:`.untangle`, :mod:`.recover`): a cavity grown by whole stars
(:func:`grow`), the nodes it holds inside (:func:`inner_nodes`), its outline
(:func:`outline`, :func:`loop`), the triangulation of an outline with the largest smallest
angle (:func:`best_triangulation` over every chord, cubic in the outline's
length; :func:`delaunay_polygon`, the same angle in O(k log k)), and a mesh
renumbered without the nodes a re-meshing took out (:func:`renumber`).  Nothing
here prints or exits.
"""

from __future__ import annotations

import functools

import numpy as np

from .geometry import signed_areas, sorted_lookup
from .mesh import Mesh
from .quality import measures
from .smoothing import _flip_all, _smooth

#: Sizes grow by this much per unit of distance from a polygon vertex.
GRADE = 0.5

#: A new point keeps this share of the local size from the other points and sides.
SPACING = 0.8

#: ... and this share of it from the sides.
WALL = 0.5

#: Rounds of neighbour-mean smoothing of the new points.
SMOOTH = 6

#: Lattice candidates at most (the lattice step grows to keep under it).
CANDIDATES = 1500


def fill(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
    """A mesh of the simple counter-clockwise polygon ``p`` (k, 2) with new inner
    points (see the module docstring): ``(new points (s, 2), triangles (t, 3) indexing
    the vertices then the new points, smallest angle)``, or None if no conforming
    triangulation was found."""
    import shapely

    k = len(p)
    poly = shapely.Polygon(p)
    if not poly.is_valid or poly.area <= 0:
        return None
    shapely.prepare(poly)
    edges = np.column_stack([np.arange(k), (np.arange(k) + 1) % k])
    size = _side_sizes(p, edges)
    lo, hi = p.min(axis=0), p.max(axis=0)
    step = max(size.min() / 2, np.sqrt(np.prod(hi - lo) / CANDIDATES))
    gx, gy = np.meshgrid(np.arange(lo[0], hi[0], step), np.arange(lo[1], hi[1], step))
    cand = np.column_stack([gx.ravel(), gy.ravel()]) + step / 2
    cand = cand[shapely.contains_xy(poly, cand[:, 0], cand[:, 1])]
    if len(cand) == 0:
        return _best(p, np.empty((0, 2)), edges, poly)
    dist = _segment_distances(cand, p, edges)
    wall = dist.min(axis=1)
    want = (size[None] + GRADE * dist).min(axis=1)
    keep = wall >= WALL * want
    order = np.flatnonzero(keep)[np.argsort(wall[keep] / want[keep], kind="stable")]
    clear = _nearest_vertex(cand[order], p)
    order = order[clear >= SPACING * want[order]]  # (far enough from the vertices)
    kept: list[int] = []
    for c in order.tolist():
        if kept:
            near = np.linalg.norm(cand[kept] - cand[c], axis=1)
            if (near < SPACING * np.maximum(want[kept], want[c])).any():
                continue
        kept.append(c)
    return _best(p, cand[kept], edges, poly)


def _best(p, new, edges, poly):
    """The conforming Delaunay mesh of ``p`` and ``new`` over the smoothing rounds
    with the largest smallest angle (see the module docstring), or None."""
    best = None
    k = len(p)
    for _ in range(SMOOTH + 1):
        tri = _delaunay(p, new, edges, poly)
        if tri is None:
            return best
        pts = np.concatenate([p, new])
        angle = float(measures(pts, tri)[0].min())
        if best is None or angle > best[2]:
            best = (new.copy(), tri, angle)
        if len(new) == 0:
            break
        # each new point to the mean of its neighbours (the vertices stay)
        total = np.zeros((len(pts), 2))
        count = np.zeros(len(pts))
        for a, b in ((0, 1), (1, 2), (2, 0)):
            np.add.at(total, tri[:, a], pts[tri[:, b]])
            np.add.at(total, tri[:, b], pts[tri[:, a]])
            np.add.at(count, tri[:, a], 1)
            np.add.at(count, tri[:, b], 1)
        new = total[k:] / np.maximum(count[k:], 1)[:, None]
    return best if best is None else _polish(p, *best)


#: Rounds of flips and max-min-angle moves of the new points at the end.
POLISH = 4


def _polish(p, new, tri, angle):
    """The quality stage's flips and moves (:mod:`.improve`) on the new points only:
    each move raises the smallest angle of its triangles, so nothing folds."""
    if POLISH == 0 or len(new) == 0:
        return new, tri, angle
    pts = np.concatenate([p, new])
    tri = tri.copy()
    movable = np.arange(len(pts)) >= len(p)
    for _ in range(POLISH):
        if _smooth(pts, tri, movable) + _flip_all(pts, tri, np.inf) == 0:
            break
    return pts[len(p) :], tri, float(measures(pts, tri)[0].min())


def _delaunay(p, new, edges, poly):
    """The constrained Delaunay triangles of ``p`` and ``new`` inside the polygon
    ``p`` (``poly``, its prepared shapely polygon), counter-clockwise, then flipped
    to the largest smallest angle: the Delaunay triangulation with each missing side
    recovered by flipping the edges that cross it (Sloan's method); None if a side
    cannot be recovered or the triangles inside lack the polygon's area."""
    from scipy.spatial import Delaunay, QhullError

    pts = np.concatenate([p, new])
    try:
        tri = Delaunay(pts).simplices.astype(np.int64)
    except QhullError:
        return None
    a = signed_areas(pts, tri)
    tri[a < 0] = tri[a < 0][:, ::-1]
    for u, v in edges[~_has_edges(tri, edges, len(pts))].tolist():
        tri = _recover(pts, tri, u, v)
        if tri is None:
            return None
    import shapely

    centre = pts[tri].mean(axis=1)
    tri = tri[shapely.contains_xy(poly, centre[:, 0], centre[:, 1])]
    a = signed_areas(pts, tri)
    area = poly.area
    if len(tri) == 0 or (a <= 0).any() or not abs(a.sum() - area) <= 1e-9 * abs(area):
        return None  # (a flat triangle, from points on a line: no mesh here)
    if np.bincount(tri.ravel(), minlength=len(pts)).min() == 0:
        return None  # (qhull leaves out a vertex on a straight side: no side recovers it)
    if not _has_edges(tri, edges, len(pts)).all():
        return None
    _flip_all(pts, tri, np.inf)  # (the polygon's sides have one triangle: never flipped)
    return tri


def _has_edges(tri: np.ndarray, edges: np.ndarray, n: int) -> np.ndarray:
    """Whether each of ``edges`` is an edge of the triangles ``tri`` (``n`` nodes)."""
    a, b = tri.ravel(), tri[:, [1, 2, 0]].ravel()
    have = np.sort(np.minimum(a, b) * n + np.maximum(a, b))
    want = np.minimum(edges[:, 0], edges[:, 1]) * n + np.maximum(edges[:, 0], edges[:, 1])
    return sorted_lookup(have, want)[0]


#: Flips at most, per side recovered.
RECOVER_FLIPS = 500


def _recover(pts: np.ndarray, tri: np.ndarray, u: int, v: int) -> np.ndarray | None:
    """``tri`` (counter-clockwise) with the edge ``u-v``: the edges that cross it are
    flipped, where their two triangles make a convex quadrilateral, until none does
    (Sloan's method: a flipped edge that still crosses goes back in the queue); None
    if stuck."""
    tri = tri.copy()
    pu, pv = pts[u], pts[v]
    # each directed edge -> (its triangle, the corner opposite it)
    owner = {}
    for t, (x, y, z) in enumerate(tri.tolist()):
        owner[(x, y)], owner[(y, z)], owner[(z, x)] = (t, z), (t, x), (t, y)

    def crosses(x, y):
        if u in (x, y) or v in (x, y):
            return False
        return bool(_crosses(pts[x], pts[y], pu, pv))

    a, b = tri.ravel(), np.roll(tri, -1, axis=1).ravel()
    first = (a < b) & (a != u) & (a != v) & (b != u) & (b != v)
    first &= _crosses(pts[a], pts[b], pu, pv)
    queue = list(zip(a[first].tolist(), b[first].tolist()))
    stuck = 0
    flips = 0
    while queue:
        if stuck > len(queue) or flips > RECOVER_FLIPS:
            return None
        x, y = queue.pop(0)
        if (x, y) not in owner or (y, x) not in owner:
            continue  # (flipped away already)
        (t1, o1), (t2, o2) = owner[(x, y)], owner[(y, x)]
        one, two = (x, o2, o1), (o2, y, o1)  # the quadrilateral's other diagonal o1-o2
        if signed_areas(pts, np.array([one, two])).min() <= 0:
            queue.append((x, y))  # not convex: another crossing edge first
            stuck += 1
            continue
        stuck = 0
        flips += 1
        for e in ((x, y), (y, x), (y, o1), (o1, x), (x, o2), (o2, y)):
            owner.pop(e, None)
        tri[t1], tri[t2] = one, two
        for t, (a, b, c) in ((t1, one), (t2, two)):
            owner[(a, b)], owner[(b, c)], owner[(c, a)] = (t, c), (t, a), (t, b)
        if crosses(o1, o2):
            queue.append((min(o1, o2), max(o1, o2)))
    return tri


def _crosses(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Whether the segments ``a-b`` (arrays of points) properly cross ``c-d``."""

    def side(p, q, r):
        return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (
            r[..., 0] - p[..., 0]
        )

    return (side(a, b, c) * side(a, b, d) < 0) & (side(c, d, a) * side(c, d, b) < 0)


def _side_sizes(p: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Each side's size: its length, or the distance to the nearest side that does not
    share a vertex with it, if smaller (a narrow part's width)."""
    k = len(edges)
    length = np.linalg.norm(p[edges[:, 1]] - p[edges[:, 0]], axis=1)
    # two segments that do not cross are nearest at an end of one of them
    ends = _segment_distances(p, p, edges)  # (vertex, side)
    near = np.minimum(ends[edges[:, 0]], ends[edges[:, 1]])  # (side s's ends, side t)
    near = np.minimum(near, near.T)
    i, j = np.arange(k)[:, None], np.arange(k)[None]
    touch = (i == j) | (i == (j + 1) % k) | ((i + 1) % k == j)
    near[touch] = np.inf
    return np.minimum(length, near.min(axis=1))


def _nearest_vertex(q: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Distance from each point ``q`` to the nearest of the points ``p``."""
    dx = q[:, :1] - p[:, 0]
    dy = q[:, 1:] - p[:, 1]
    dx *= dx
    dy *= dy
    dx += dy
    return np.sqrt(dx.min(axis=1))


def _segment_distances(q: np.ndarray, p: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Distance from each point ``q`` to each segment ``p[edges]``: (len(q), len(edges)).

    Component by component, in place: a cavity along a long contour edge of the
    uniform grid has about 800 candidates and 700 sides, where (q, edges, 2)
    temporaries took most of a fill's time."""
    a, b = p[edges[:, 0]], p[edges[:, 1]]
    abx, aby = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    qx, qy = q[:, :1], q[:, 1:]
    t = (qx - a[:, 0]) * abx
    t += (qy - a[:, 1]) * aby
    t /= np.maximum(abx * abx + aby * aby, 1e-300)
    np.clip(t, 0.0, 1.0, out=t)
    dx = t * abx
    dx += a[:, 0]
    np.subtract(qx, dx, out=dx)  # (q minus the foot of q on the segment)
    dy = t * aby
    dy += a[:, 1]
    np.subtract(qy, dy, out=dy)
    dx *= dx
    dy *= dy
    dx += dy
    return np.sqrt(dx, out=dx)


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
#: for: each merge pass, and each of stage 3's merge ways, asks again for the runs
#: it could not merge (the largest coastline of the corpus: 3,375 asks for 1,175
#: outlines, ``benchmarks/MEASURED.md``).
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


def delaunay_polygon(p: np.ndarray) -> np.ndarray | None:
    """The constrained Delaunay triangulation of the simple counter-clockwise polygon
    ``p`` (k, 2), its own vertices only, as (k - 2, 3) local indices, every triangle
    counter-clockwise; None if one is not (vertices collinear to round-off).

    Among all triangulations of a polygon's vertices, the constrained Delaunay one
    has the largest smallest angle (Lee and Lin 1986), so this is
    :func:`best_triangulation`'s answer up to ties, in O(k log k) for typical
    polygons (GEOS: ear clipping, then flips to the Delaunay condition)."""
    import shapely

    k = len(p)
    if k < 3:
        return None
    tris = shapely.get_parts(shapely.constrained_delaunay_triangles(shapely.Polygon(p)))
    if len(tris) != k - 2:
        return None
    xy = shapely.get_coordinates(shapely.get_exterior_ring(tris)).reshape(len(tris), 4, 2)[:, :3]
    key = p[:, 0] + 1j * p[:, 1]  # (complex numbers sort by x, then y)
    order = np.argsort(key)
    flat = xy[..., 0].ravel() + 1j * xy[..., 1].ravel()
    at = np.minimum(np.searchsorted(key[order], flat), k - 1)
    # exact coordinates: GEOS hands back the polygon's own vertices
    if (key[order][at] != flat).any():
        return None
    idx = order[at]
    local = idx.reshape(-1, 3)
    area = signed_areas(p, local)
    local[area < 0] = local[area < 0][:, ::-1]
    if (signed_areas(p, local) <= 0).any():
        return None
    return local
