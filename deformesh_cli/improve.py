"""Stage 3b: better triangles next to the contour.

A deformed Cartesian mesh is right-isosceles inside (45 degrees); its weak
triangles sit between the contour and the first grid rows (and, on an adapted
grid, where a thin part squeezes the cells).  This stage works where a
triangle's smallest angle is under :data:`TARGET`, on the triangles within two
rings of it, and takes only changes that make things better:

- **flips**: an inner edge whose two triangles have a larger smallest angle
  the other way round is flipped (Lawson's rule for the max-min angle; the
  quadrilateral's area, and so the mesh's, is unchanged);
- **smoothing**: a free node of those triangles (or a neighbour) goes where the
  smallest angle of its triangles is largest (the mean of the apexes that would
  make each of its triangles equilateral, then a pattern search over eight
  directions, halving the step), one independent set of nodes at a time; a
  move is taken only if that smallest angle grows, so nothing folds;
- **cavities**: where a triangle stays under the target with no free corner
  (three boundary nodes across a thin part: no move or flip can help), or a
  boundary corner under 60 degrees has a triangle under it, a few triangles
  are re-meshed as a fan from one node (a new one, or the one node inside
  moved), the corner made one triangle with its whole angle; taken only if the
  smallest angle there grows.  :mod:`.forced` says what the boundary allows.

With ``clear_corners``, inner nodes in the tips of sharp corners are first
taken out (:func:`.merge.clear_sharp_corners`, off the uniform grid).

Boundary nodes never move, so the contract is untouched (it is checked
afterwards as always); triangles at 35 degrees or more and away from bad ones,
the grid's interior, are left as they are, and the mesh's smallest angle can
only grow.  Nothing here prints or exits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .forced import corner_angles
from .geometry import node_stars, touching
from .merge import clear_sharp_corners
from .mesh import Mesh

#: Rounds of (flips, smoothing, cavities) at most; a round that changes nothing ends it.
#: No round reads the clock, so the same mesh always improves the same way.
ROUNDS = 16
#: Triangles whose smallest angle is under this (degrees) are worked on, with their
#: neighbours; the others are left as they are.
TARGET = 35.0
#: Pattern-search steps per smoothing sweep (the step halves when nothing improves).
SEARCH_STEPS = 8
#: A change counts only if it raises the smallest angle by more than this (degrees).
GAIN = 0.01

#: Triangles measured at a time (bounds the temporaries on big meshes).
CHUNK = 1 << 17

_DIRS = np.array([(np.cos(a), np.sin(a)) for a in np.arange(8) * np.pi / 4])
_SQRT3_2 = np.sqrt(3.0) / 2.0


@dataclass
class ImproveStats:
    changed: np.ndarray | None = None  # ids of the triangles whose corners changed
    flips: int = 0
    moves: int = 0
    cavities: int = 0  # re-meshed
    added: int = 0  # new nodes: after the mesh's nodes (and their 2 triangles each, after its)
    rounds: int = 0
    moved_nodes: int = 0  # nodes that ended somewhere else
    min_angle_before: float = 0.0
    corners: int = 0  # inner nodes taken out of sharp corners first
    weak: np.ndarray | None = None  # ids of the triangles under 30 degrees at the end


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


def improve(
    mesh: Mesh, rounds: int = ROUNDS, clear_corners: bool = False
) -> tuple[Mesh, ImproveStats]:
    """A copy of ``mesh`` with better triangles where they were under :data:`TARGET`,
    and what was done.  ``clear_corners``: first take inner nodes out of sharp
    corners (:func:`.merge.clear_sharp_corners`); then ``stats.changed`` refers to
    that mesh's triangles, not ``mesh``'s."""
    tan = _tan_all(mesh.points, mesh.triangles)
    stats = ImproveStats(min_angle_before=_degrees(tan.min()))
    if clear_corners:
        mesh, stats.corners = clear_sharp_corners(mesh)
        if stats.corners:
            tan = _tan_all(mesh.points, mesh.triangles)
    pts = np.array(mesh.points, dtype=np.float64, copy=True)
    tri = np.array(mesh.triangles, copy=True)
    n = len(pts)
    free = np.ones(n, dtype=bool)
    free[mesh.lines.ravel()] = False
    target = np.tan(np.radians(TARGET))
    touched = np.zeros(len(tri), dtype=bool)
    ends, angle = corner_angles(pts, mesh.lines)
    sharp = np.flatnonzero(angle < 60)
    for _ in range(rounds):
        bad = tan < target
        if not bad.any():
            break
        stats.rounds += 1
        # work where it is needed: the triangles within two rings of a bad one
        near = np.zeros(len(pts), dtype=bool)
        near[tri[bad].ravel()] = True
        near[tri[touching(near, tri)].ravel()] = True
        local = np.flatnonzero(touching(near, tri))
        part = tri[local]
        old = part.copy()
        flips = _flip_all(pts, part, target)
        part_tan = _tan_min(pts, part)
        # the free nodes of the triangles still under the target, and their neighbours;
        # only nodes of ``near`` (all of whose triangles are in ``part``, where a move
        # is judged)
        act = np.zeros(len(pts), dtype=bool)
        act[part[part_tan < target].ravel()] = True
        act[part[touching(act, part)].ravel()] = True
        moves = _smooth(pts, part, act & free & near)
        part_tan = _tan_min(pts, part)
        # what smoothing cannot reach: triangles still under the target with no free
        # corner (across a thin part), and sharp corners with a triangle under it
        low = part_tan < target
        stuck = low & ~touching(free, part)
        at = np.zeros(len(pts), dtype=bool)
        at[part[low].ravel()] = True
        pts, added, added_nodes, cavities = _insert(
            pts, part, np.flatnonzero(stuck), part_tan, sharp[at[sharp]], ends
        )
        if added_nodes:
            free = np.concatenate([free, np.ones(added_nodes, dtype=bool)])
        changed = (part[:, 0] != old[:, 0]) | (part[:, 1] != old[:, 1]) | (part[:, 2] != old[:, 2])
        touched[local[changed]] = True
        tri[local] = part
        tan[local] = _tan_min(pts, part)
        if added_nodes:
            tri = np.concatenate([tri, added])
            tan = np.concatenate([tan, _tan_min(pts, added)])
            touched = np.concatenate([touched, np.zeros(len(added), dtype=bool)])
        stats.flips += flips
        stats.moves += moves
        stats.added += added_nodes
        stats.cavities += cavities
        if flips == 0 and moves == 0 and cavities == 0:
            break
    stats.weak = np.flatnonzero(tan < np.tan(np.radians(30.0)))
    m = len(mesh.triangles)
    idx = np.flatnonzero(touched[:m])  # changed at some point; maybe flipped back
    stats.changed = idx[np.any(tri[idx] != mesh.triangles[idx], axis=1)]
    stats.moved_nodes = int(
        np.count_nonzero((pts[:n, 0] != mesh.points[:, 0]) | (pts[:n, 1] != mesh.points[:, 1]))
    )
    out = Mesh(
        pts,
        tri,
        mesh.lines,
        n_contour=mesh.n_contour,
        n_extra=mesh.n_extra,
        line_group=mesh.line_group,
        groups=mesh.groups,
        n_box=mesh.n_box,
    )
    return out, stats


def _tan_all(pts, tri):
    """:func:`_tan_min` of every triangle, :data:`CHUNK` at a time."""
    return np.concatenate([_tan_min(pts, tri[k : k + CHUNK]) for k in range(0, len(tri), CHUNK)])


def _degrees(tan_angle: float) -> float:
    return float(np.degrees(np.arctan(tan_angle))) if np.isfinite(tan_angle) else -np.inf


def _tan_min(pts, tri):
    return tan_min_angle(
        pts[tri[:, 0], 0],
        pts[tri[:, 0], 1],
        pts[tri[:, 1], 0],
        pts[tri[:, 1], 1],
        pts[tri[:, 2], 0],
        pts[tri[:, 2], 1],
    )


# --- flips


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
    edge k2 of t2, walked the other way."""
    t = np.repeat(np.arange(len(tri)), 3)
    k = np.tile(np.arange(3), len(tri))
    a = tri.ravel()
    b = tri[:, [1, 2, 0]].ravel()
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo.astype(np.int64) * (int(hi.max(initial=0)) + 1) + hi
    order = np.argsort(key, kind="stable")  # (by lo, then hi: as a lexsort of the two)
    key, t, k, fwd = key[order], t[order], k[order], (a < b)[order]
    same = (key[1:] == key[:-1]) & (fwd[1:] != fwd[:-1])
    i = np.flatnonzero(same)
    return t[i], k[i], t[i + 1], k[i + 1]


# --- insertions


def _insert(
    pts: np.ndarray,
    tri: np.ndarray,
    stuck: np.ndarray,
    tan: np.ndarray,
    corners: np.ndarray,
    ends: np.ndarray,
):
    """Re-mesh small cavities where the triangles ``stuck`` (rows of ``tri``, no free
    corner; ``tan`` the tangents of ``tri``) or sharp ``corners`` are, where that
    helps.

    A *cavity* (some triangles) is replaced by a fan of triangles from one node
    over its outline, the node placed where the fan's smallest angle is largest
    (as in smoothing): a new node, or the cavity's one inner node moved.  At a
    sharp corner node ``p`` (``ends[p]``: its next and previous boundary node)
    the *ear* (previous, p, next), one triangle with the corner's whole angle,
    takes p's place in the outline.  Tried for each stuck triangle: it with one
    neighbour across an inner edge (an edge split), with all of them, and with
    their neighbours too; for each corner with a triangle under the target: its
    triangles, and its triangles with those of one inner neighbour.  A cavity is
    kept only if its new triangles beat its old ones' smallest angle, the best
    one for each stuck triangle or corner, and kept cavities share no triangle,
    the worst choosing first.

    ``tri`` is changed in place (a cavity's rows take its first new triangles);
    returns the points (new nodes appended, inner nodes moved), the new
    triangles beyond those rows (to append to ``tri``), how many nodes were
    added and how many cavities re-meshed.
    """
    none = (pts, np.empty((0, 3), dtype=tri.dtype), 0, 0)
    if len(stuck) == 0 and len(corners) == 0:
        return none
    t1, k1, t2, k2 = _edge_pairs(tri)
    nb = np.full((len(tri), 3), -1, dtype=np.int64)  # the triangle across edge k
    nb[t1, k1] = t2
    nb[t2, k2] = t1
    owner, cavities, loops, ears, hubs = [], [], [], [], []

    def consider(key, cav, ear=None):
        got = _outline(tri, nb, cav, ear)
        if got is not None:
            owner.append(key)
            cavities.append(cav)
            loops.append(got[0])
            hubs.append(got[1])
            ears.append(ear)

    for s in stuck.tolist():
        ring = [t for t in nb[s].tolist() if t >= 0]
        for t in ring:
            consider(s, [s, t])
        if len(ring) > 1:
            consider(s, [s] + ring)
        far = [t for r in ring for t in nb[r].tolist() if t >= 0 and t != s and t not in ring]
        if far:
            consider(s, [s] + ring + sorted(set(far)))
    if len(corners):
        star = node_stars(tri)
    for p in corners.tolist():
        around = star(p)
        ear = (p, int(ends[p, 0]), int(ends[p, 1]))
        key = len(tri) + p  # (not a triangle id)
        consider(key, around, ear)
        for x in set(tri[around].ravel().tolist()) - {p, ear[1], ear[2]}:
            consider(key, sorted(set(around) | set(star(x))), ear)
    if not loops:
        return none
    owner = np.array(owner)
    k = len(loops)
    q = len(pts) + np.arange(k)  # the hub of each fan while it is judged
    size = np.array([len(loop) for loop in loops])
    fans = np.concatenate(
        [
            np.column_stack([np.full(len(loop), q[i]), loop, np.roll(loop, -1)])
            for i, loop in enumerate(loops)
        ]
    )
    first = np.concatenate([[0], np.cumsum(size)[:-1]])
    col = np.arange(int(size.max()))
    inc = np.where(col < size[:, None], first[:, None] + col, -1)
    slot = np.zeros_like(inc)
    # two starts: the mean of the outline, and the centroid of the worst old triangle
    worst = np.array([cav[int(np.argmin(tan[cav]))] for cav in cavities])
    starts = [np.array([pts[loop].mean(axis=0) for loop in loops]), pts[tri[worst]].mean(axis=1)]
    best_at, best = None, None
    for start in starts:
        ext = np.concatenate([pts, start])
        _move(ext, fans, q, inc, slot)
        got = np.where(inc >= 0, _tan_min(ext, fans)[np.maximum(inc, 0)], np.inf).min(axis=1)
        if best is None:
            best_at, best = ext[q], got
        else:
            better = got > best
            best_at[better], best[better] = ext[q][better], got[better]
    eared = [i for i, ear in enumerate(ears) if ear is not None]
    if eared:  # a corner's fan with its ear: the worse of the two counts
        best[eared] = np.minimum(best[eared], _tan_min(pts, np.array([ears[i] for i in eared])))
    before = np.array([tan[cav].min() for cav in cavities])
    gain = np.where(best > _raised(before), best - before, -np.inf)
    # each owner's best cavity, then cavities sharing no triangle, worst first
    taken = np.zeros(len(tri), dtype=bool)
    chosen = []
    for o in dict.fromkeys(owner[np.argsort(before, kind="stable")].tolist()):
        rows = np.flatnonzero(owner == o)
        i = rows[np.argmax(gain[rows])]
        if not np.isfinite(gain[i]) or taken[cavities[i]].any():
            continue
        taken[cavities[i]] = True
        chosen.append(i)
    if not chosen:
        return none
    pts = pts.copy()
    new_pts, extra = [], []
    for i in chosen:
        fan = fans[first[i] : first[i] + size[i]].copy()
        if hubs[i] >= 0:  # the inner node, moved
            fan[:, 0] = hubs[i]
            pts[hubs[i]] = best_at[i]
        else:
            fan[:, 0] = len(pts) + len(new_pts)
            new_pts.append(best_at[i])
        if ears[i] is not None:
            fan = np.concatenate([np.array([ears[i]]), fan])
        rows = cavities[i]
        tri[rows] = fan[: len(rows)]
        extra.append(fan[len(rows) :])
    if new_pts:
        pts = np.concatenate([pts, np.array(new_pts)])
    return pts, np.concatenate(extra), len(new_pts), len(chosen)


def _outline(tri: np.ndarray, nb: np.ndarray, cav: list[int], ear=None):
    """The outline of the triangles ``cav`` as a counter-clockwise node loop, and the
    one node inside it (-1 if none); None unless the outline is one simple loop
    and at most one node is inside.  With an ``ear`` (p, next, previous), p must
    be on the loop between the other two, and is left out of it."""
    inside = set(cav)
    nxt = {}
    for t in cav:
        for k in range(3):
            if nb[t, k] not in inside:
                a, b = int(tri[t, k]), int(tri[t, (k + 1) % 3])
                if a in nxt:
                    return None
                nxt[a] = b
    start = next(iter(nxt))
    loop = [start]
    while nxt[loop[-1]] != start:
        loop.append(nxt[loop[-1]])
        if len(loop) > len(nxt):
            return None
    if len(loop) != len(nxt):
        return None
    inner = set(tri[cav].ravel().tolist()) - set(loop)
    if len(inner) > 1 or len(cav) != len(loop) - 2 + 2 * len(inner):
        return None  # (the count fails if the cavity has a hole)
    if ear is not None:
        p, after, before = ear
        if nxt.get(p) != after:
            return None
        k = loop.index(p)
        loop = loop[k + 1 :] + loop[:k]
        if loop[-1] != before:
            return None
    return np.array(loop), (inner.pop() if inner else -1)


# --- smoothing


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
    row = np.nonzero(valid)[0]
    first = np.concatenate([[0], np.cumsum(valid.sum(axis=1))[:-1]])
    quality = _apex_quality(row, first, *(v[valid][:, None] for v in (ax, ay, bx, by)))

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
    rows = np.arange(len(nodes))
    bar = _raised(best)  # what a candidate must beat, kept as ``best`` changes
    for _ in range(SEARCH_STEPS):
        cx = px[:, None] + step[:, None] * _DIRS[None, :, 0]
        cy = py[:, None] + step[:, None] * _DIRS[None, :, 1]
        q = quality(cx, cy)
        k = np.argmax(q, axis=1)
        qk = q[rows, k]
        take = qk > bar
        px[take], py[take], best[take] = cx[take, k[take]], cy[take, k[take]], qk[take]
        bar[take] = _raised(best[take])
        step = np.where(take, step, 0.5 * step)
    moved = best > _raised(start)
    pts[nodes[moved], 0] = px[moved]
    pts[nodes[moved], 1] = py[moved]
    return int(moved.sum())


def _apex_quality(row, first, ax, ay, bx, by):
    """``quality(px, py)``: for (n, c) candidate positions of n nodes, the tangent of
    the smallest angle of each node's worst triangle ``(p, a, b)`` (``row``: each
    triangle's node; ``first``: each node's first triangle; ``a``, ``b``: (t, 1)).

    :func:`tan_min_angle`'s arithmetic operation for operation, so the same bits,
    but with the side ``a -> b``, which no candidate moves, squared once, and in
    place: the quality stage spends most of its time here."""
    s0 = bx - ax
    s0 *= s0
    e0y = by - ay
    e0y *= e0y
    s0 += e0y

    def quality(px, py):
        x, y = px[row], py[row]
        e1x, e1y = x - bx, y - by
        x = np.subtract(ax, x, out=x)  # e2
        y = np.subtract(ay, y, out=y)
        cross = e1x * y
        cross -= e1y * x
        e1x *= e1x  # s1
        e1y *= e1y
        e1x += e1y
        x *= x  # s2
        y *= y
        x += y
        shortest = np.minimum(s0, e1x)
        np.minimum(shortest, x, out=shortest)
        den = np.add(s0, e1x, out=e1x)
        den += x
        shortest *= 2
        den -= shortest
        ccw = cross > 0
        cross *= 2
        with np.errstate(divide="ignore", invalid="ignore"):
            cross /= den
        cross[~ccw] = -np.inf
        return np.minimum.reduceat(cross, first, axis=0)

    return quality


_GAIN_RADIANS = np.radians(GAIN)
_BELOW_RIGHT = np.pi / 2 - 1e-12


def _raised(tan_angle: np.ndarray) -> np.ndarray:
    """The tangent of an angle :data:`GAIN` degrees larger (a move must beat it); NaN
    stays NaN, -inf (a folded triangle) the tangent of GAIN over -90 degrees."""
    a = np.arctan(tan_angle)
    a += _GAIN_RADIANS
    np.minimum(a, _BELOW_RIGHT, out=a)
    return np.tan(a, out=a)
