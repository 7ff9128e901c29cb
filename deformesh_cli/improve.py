"""Stage 3b: better triangles next to the contour.

A deformed Cartesian mesh is right-isosceles inside (45 degrees); its weak
triangles sit between the contour and the first grid rows.  This stage works where a
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

Boundary nodes never move, so the contract is untouched (it is checked
afterwards as always); triangles at 35 degrees or more and away from bad ones,
the grid's interior, are left as they are, and the mesh's smallest angle can
only grow.  Nothing here prints or exits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cavity import outline
from .forced import corner_angles
from .geometry import node_stars, touching
from .mesh import Mesh
from .smoothing import (  # noqa: F401 (tan_min_angle, GAIN: the quality stage's measure)
    GAIN,
    _edge_pairs,
    _flip_all,
    _move,
    _raised,
    _smooth,
    _tan_min,
    tan_min_angle,
)

#: Rounds of (flips, smoothing, cavities) at most; a round that changes nothing ends it.
#: No round reads the clock, so the same mesh always improves the same way.
ROUNDS = 16
#: Triangles whose smallest angle is under this (degrees) are worked on, with their
#: neighbours; the others are left as they are.
TARGET = 35.0


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
    weak: np.ndarray | None = None  # ids of the triangles under 30 degrees at the end


def improve(mesh: Mesh, rounds: int = ROUNDS) -> tuple[Mesh, ImproveStats]:
    """A copy of ``mesh`` with better triangles where they were under :data:`TARGET`,
    and what was done."""
    tan = _tan_min(mesh.points, mesh.triangles)
    stats = ImproveStats(min_angle_before=_degrees(tan.min()))
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


def _degrees(tan_angle: float) -> float:
    return float(np.degrees(np.arctan(tan_angle))) if np.isfinite(tan_angle) else -np.inf


# --- flips


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
        got = _outline(tri, cav, ear)
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


def _outline(tri: np.ndarray, cav: list[int], ear=None):
    """The outline of the triangles ``cav`` as a counter-clockwise node loop
    (:func:`.cavity.outline`), and the one node inside it (-1 if none); None unless
    the outline is one simple loop and at most one node is inside.  With an ``ear``
    (p, next, previous), p must be on the loop between the other two, and is left
    out of it."""
    found = outline(tri[cav].tolist())
    if found is None:
        return None
    loop, inner = found
    if len(inner) > 1 or len(cav) != len(loop) - 2 + 2 * len(inner):
        return None  # (the count fails if the cavity has a hole)
    if ear is not None:
        p, after, before = ear
        if p not in loop:
            return None
        k = loop.index(p)
        if loop[(k + 1) % len(loop)] != after:
            return None
        loop = loop[k + 1 :] + loop[:k]
        if loop[-1] != before:
            return None
    return np.array(loop), (inner.pop() if inner else -1)


# --- smoothing
