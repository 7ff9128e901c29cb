"""What the contour itself forces on the smallest angle.

Every boundary edge of a mesh belongs to exactly one triangle, which lies in
the domain.  If that triangle has all three angles at least ``phi``, it
contains the isosceles triangle with the same base and base angles ``phi``
(from the base's ends, a point of the small one is seen at most ``phi`` off the
base, so within the big one's base angles), and so that isosceles triangle lies
in the domain too.  Hence the **forced angle** of a boundary edge,

    F(e) = the largest phi <= 60 degrees such that the isosceles triangle on e
           with base angles phi, on the domain's side, lies in the domain,

bounds the smallest angle of e's triangle in *every* mesh whose boundary
nodes are exactly the contour's points, ours or anyone's.  A corner of angle
``theta`` gives its two edges ``F <= theta``; a part thinner than ``w`` gives
an edge of length ``L`` across from it about ``atan(2 w / L)``.  At a boundary
node, :func:`node_angles` bounds the worst of its triangles: one triangle there
is the ear, or two or more share the corner's angle ``theta`` and, side by side,
must also grade the length of one boundary edge to the other's.  In a triangle
with angle ``alpha`` at the node and all angles at least ``phi``, its two sides at
the node differ at most ``sin(alpha + phi) / sin(phi)`` times (law of sines), so
``k`` triangles grade at most ``(sin(theta / k + phi) / sin(phi)) ** k`` times (equal
angles grade most: ``log sin`` is concave).  Edges that differ more than that
force a smaller angle (:func:`fan_angles`; Mitchell's bound, that edges in line
differing over 27 times force an angle under 30 degrees, is the case ``theta =
180``, ``k = 6``).  A thin strip
between two facing edges forces about half of F in tangent (the two triangles'
apexes share the width), which is why the bound we test is ``min(30, B) / 3``,
``B`` the smallest of these near a triangle (README, "What the boundary forces,
and the bound we test"; ``tests/test_improve.py``).

Nothing here prints or exits.
"""

from __future__ import annotations

import numpy as np
import shapely

#: Bisection steps on the angle: 60 / 2**24 degrees apart at the end.
STEPS = 24

#: A side forced under this (degrees) after :data:`STEPS` goes on being bisected, down
#: to the smallest double (:data:`FINER_STEPS`), until its bound is within 2**-STEPS of
#: itself: a part 1e-7 wide and 3 long is forced to 3.8e-6 degrees, which 60 / 2**STEPS
#: (3.6e-6) does not resolve.
FINE_BELOW = 60.0 * 2.0 ** -(STEPS // 2)
FINER_STEPS = 1100


def edge_angles(points: np.ndarray, lines: np.ndarray, geom) -> np.ndarray:
    """F(e) in degrees for each directed boundary edge ``lines`` (domain on its left)
    of the domain ``geom`` (a shapely geometry; edges on its boundary).

    The upper end of the bisection is returned, so the value is never below
    the true F (within 60 / 2**24 degrees above it, or, for a side forced under that,
    within 2**-24 of itself: :data:`FINE_BELOW`).
    """
    a = np.asarray(points[lines[:, 0]], dtype=np.float64)
    b = np.asarray(points[lines[:, 1]], dtype=np.float64)
    d = b - a
    half = 0.5 * np.hypot(d[:, 0], d[:, 1])
    normal = np.column_stack([-d[:, 1], d[:, 0]]) / (2 * half)[:, None]
    mid = 0.5 * (a + b)
    shapely.prepare(geom)
    lo = np.zeros(len(a))
    hi = np.full(len(a), 60.0)
    top = _fits(geom, a, b, mid + normal * (half * np.tan(np.radians(60.0)))[:, None])
    lo[top] = 60.0
    fine = None
    for step in range(STEPS + FINER_STEPS):
        if step < STEPS:
            open_ = lo < hi
        else:  # (only a side forced under FINE_BELOW goes on, to 2**-STEPS of itself)
            fine = hi < FINE_BELOW if fine is None else fine
            open_ = fine & (hi > 0) & ((lo == 0) | (hi - lo > hi * 2.0**-STEPS))
        if not open_.any():
            break
        phi = 0.5 * (lo + hi)
        apex = mid + normal * (half * np.tan(np.radians(phi)))[:, None]
        ok = np.zeros(len(a), dtype=bool)
        ok[open_] = _fits(geom, a[open_], b[open_], apex[open_])
        lo = np.where(open_ & ok, phi, lo)
        hi = np.where(open_ & ~ok, phi, hi)
    return hi


def mesh_domain(points: np.ndarray, lines: np.ndarray):
    """The region the boundary ``lines`` enclose (ring by ring, in boundary order, as a
    :class:`.Mesh` keeps them; even-odd), with the boundary nodes where the mesh has
    them: extra boundary nodes, put on contour edges to the nearest double, are
    vertices of it."""
    from .geometry import domain

    rings, start = [], 0
    first = lines[:, 0].tolist()
    for k, end in enumerate(lines[:, 1].tolist()):  # a ring closes back on its start
        if end == first[start]:
            rings.append(points[lines[start : k + 1, 0]])
            start = k + 1
    return domain(rings)


def corner_angles(pts: np.ndarray, lines: np.ndarray):
    """For each node: its next and previous boundary node (-1 inside) and the angle
    (degrees; 360 inside) between the two boundary edges on the domain's side."""
    ends = np.full((len(pts), 2), -1, dtype=np.int64)
    ends[lines[:, 0], 0] = lines[:, 1]
    ends[lines[:, 1], 1] = lines[:, 0]
    angle = np.full(len(pts), 360.0)
    p = lines[:, 0]
    a, b = pts[ends[p, 0]] - pts[p], pts[ends[p, 1]] - pts[p]
    angle[p] = np.mod(
        np.degrees(np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], (a * b).sum(axis=1))), 360
    )
    return ends, angle


def node_angles(points: np.ndarray, lines: np.ndarray, geom, nodes=None) -> np.ndarray:
    """C(p) in degrees for each boundary node ``nodes`` (default ``lines[:, 0]``; the
    boundary is ``lines``, domain on their left): in any mesh with these boundary
    nodes, the worst of p's triangles has no larger smallest angle.  One triangle
    there is the *ear* (previous node, it, next node), which must lie in the
    domain; two or more share the corner's angle and grade its two edges' lengths
    (:func:`fan_angles`, at most half the angle).  So C(p) = max(the fan's bound,
    the ear's smallest angle if the ear lies in the domain)."""
    from .quality import measures

    ends, angle = corner_angles(points, lines)
    p = lines[:, 0] if nodes is None else nodes
    before = np.linalg.norm(points[ends[p, 1]] - points[p], axis=1)
    after = np.linalg.norm(points[ends[p, 0]] - points[p], axis=1)
    fan = fan_angles(angle[p], np.maximum(before, after) / np.minimum(before, after))
    ears = np.column_stack([p, ends[p, 0], ends[p, 1]])
    convex = angle[p] < 180
    ear = np.zeros(len(p))
    if convex.any():
        e = ears[convex]
        fits = _fits(geom, points[e[:, 0]], points[e[:, 1]], points[e[:, 2]])
        ear[convex] = np.where(fits, measures(points, e)[0], 0.0)
    return np.maximum(fan, ear)


#: :func:`fan_angles` tries fans of up to this many triangles; a fan of more has one
#: whose angle at the node is under ``angle / FANS``, which it allows for.
FANS = 64


def fan_angles(angle: np.ndarray, ratio: np.ndarray) -> np.ndarray:
    """For boundary corners of ``angle`` degrees between edges whose lengths differ
    ``ratio`` (>= 1) times: the largest ``phi`` (degrees, at most half the angle and
    60) such that two or more triangles with no angle under ``phi`` can fill the
    corner and grade one edge's length to the other's (module docstring).

    Bisected like :func:`edge_angles`: the value returned is never below the true
    one, so in any mesh with two or more triangles at such a corner, one of them has
    no larger smallest angle.
    """
    angle = np.asarray(angle, dtype=np.float64)
    grade = np.log(np.asarray(ratio, dtype=np.float64))
    k = np.arange(2, FANS + 1, dtype=np.float64)
    top = np.minimum(angle / 2, 60.0)

    def fits(phi: np.ndarray, rows: np.ndarray) -> np.ndarray:
        p = np.radians(phi)[:, None]
        a = np.radians(angle[rows])[:, None] / k  # each triangle's angle at the node
        with np.errstate(divide="ignore", invalid="ignore"):
            most = k * np.log(np.sin(a + p) / np.sin(p))
        real = (a >= p * (1 - 1e-12)) & (a + 2 * p <= np.pi)  # a triangle, angles >= phi
        return (real & (most >= grade[rows, None])).any(axis=1)

    out = top.copy()
    rows = np.flatnonzero(~fits(top, np.arange(len(angle))))
    lo, hi = np.zeros(len(rows)), top[rows]
    for _ in range(STEPS):
        if len(rows) == 0:
            break
        mid = 0.5 * (lo + hi)
        ok = fits(mid, rows)
        lo = np.where(ok, mid, lo)
        hi = np.where(ok, hi, mid)
    out[rows] = np.maximum(hi, angle[rows] / FANS)
    return out


def _fits(geom, a, b, apex) -> np.ndarray:
    return shapely.covers(geom, shapely.polygons(np.stack([a, b, apex, a], axis=1)))


def triangle_bound(
    points: np.ndarray,
    tri: np.ndarray,
    lines: np.ndarray,
    forced: np.ndarray,
    reach: float = 1.0,
    tree=None,
) -> np.ndarray:
    """For each triangle, the smallest ``forced`` (one per boundary edge) of the edges
    within ``reach`` times the triangle's longest edge of it (60 where there is none).
    ``tree``: :func:`line_tree` of ``lines``, when asked about many triangle sets."""
    if tree is None:
        tree = line_tree(points, lines)
    t, e = _near_edges(points, tri, tree, reach)
    return _smallest_near(len(tri), t, e, forced)


def line_tree(points: np.ndarray, lines: np.ndarray):
    """A shapely STRtree of the boundary edges ``lines`` (for :func:`triangle_bound`)."""
    return shapely.STRtree(
        shapely.linestrings(np.stack([points[lines[:, 0]], points[lines[:, 1]]], axis=1))
    )


def weakest_bound(
    points: np.ndarray, tri: np.ndarray, lines: np.ndarray, weak: np.ndarray
) -> float:
    """The smallest :func:`edge_bounds` over the boundary edges with an end within one
    ring of the triangles ``weak`` (60 if none): no mesh with these boundary nodes
    has a larger smallest angle.  Only near the weak triangles, because that is
    where it matters and a whole fine boundary costs a noticeable share of a run
    (``benchmarks/MEASURED.md``)."""
    from .geometry import touching

    near = np.zeros(len(points), dtype=bool)
    near[tri[weak].ravel()] = True
    near[tri[touching(near, tri)].ravel()] = True
    which = near[lines[:, 0]] | near[lines[:, 1]]
    return float(edge_bounds(points, lines, which=which).min()) if which.any() else 60.0


def edge_bounds(
    points: np.ndarray, lines: np.ndarray, geom=None, which: np.ndarray | None = None
) -> np.ndarray:
    """For each boundary edge (or those of the mask ``which``): min(F(e), C(its two
    ends)), in degrees: in any mesh with these boundary nodes, the edge's triangle
    or the worst triangle at one of its ends has no larger smallest angle.
    ``geom``: the domain (default: :func:`mesh_domain`)."""
    if geom is None:
        geom = mesh_domain(points, lines)
    sub = lines if which is None else lines[which]
    ends = np.unique(sub)
    c = np.full(len(points), 60.0)
    c[ends] = node_angles(points, lines, geom, nodes=ends)
    return np.minimum(edge_angles(points, sub, geom), np.minimum(c[sub[:, 0]], c[sub[:, 1]]))


def under_bound(points: np.ndarray, tri: np.ndarray, lines: np.ndarray) -> int:
    """How many triangles have a smallest angle under the bound the quality stage
    keeps: ``min(30, B) / 3``, ``B`` the smallest :func:`edge_bounds` of the boundary
    edges near the triangle (:func:`triangle_bound`; README, "What the boundary
    forces, and the bound we test").

    Only triangles under :data:`BOUND_CAP` degrees can be under it, and only the
    boundary edges near them are bounded (a uniform-grid mesh of 1.4e6 triangles
    and 3e4 boundary edges: 10 s with every edge bounded)."""
    from .quality import measures

    ang = measures(points, tri)[0]
    low = np.flatnonzero(ang < BOUND_CAP)
    if len(low) == 0:
        return 0
    t, e = _near_edges(points, tri[low], line_tree(points, lines))
    which = np.zeros(len(lines), dtype=bool)
    which[e] = True
    forced = np.full(len(lines), 60.0)
    forced[which] = edge_bounds(points, lines, which=which)
    bound = _smallest_near(len(low), t, e, forced)
    return int(np.count_nonzero(ang[low] < np.minimum(30.0, bound) / 3))


#: The quality stage's bound, ``min(30, B) / 3``, is never above this (degrees).
BOUND_CAP = 10.0


def _near_edges(points: np.ndarray, tri: np.ndarray, tree, reach: float = 1.0):
    """Pairs ``(triangle, boundary edge)`` (indices into ``tri`` and ``tree``'s lines)
    with the edge within ``reach`` times the triangle's longest edge of it."""
    p = points[tri]
    longest = np.sqrt(np.max(((p - np.roll(p, 1, axis=1)) ** 2).sum(axis=2), axis=1))
    polys = shapely.polygons(np.concatenate([p, p[:, :1]], axis=1))
    return tree.query(polys, predicate="dwithin", distance=reach * longest)


def _smallest_near(count: int, t: np.ndarray, e: np.ndarray, forced: np.ndarray) -> np.ndarray:
    """For each of ``count`` triangles, the smallest ``forced[e]`` over its pairs
    ``(t, e)`` from :func:`_near_edges` (60 where it has none)."""
    out = np.full(count, 60.0)
    np.minimum.at(out, t, forced[e])
    return out
