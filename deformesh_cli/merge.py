"""Removing nodes from a finished mesh: extra boundary nodes, and inner nodes in
sharp corners.

Where a grid path could not give two consecutive contour points neighbouring
grid nodes, it runs through grid nodes between them: extra boundary nodes,
placed on that contour edge ``A-B``.  This stage takes them out again.  For
each run of extra nodes between two contour points ``A`` and ``B``:

1. the *cavity* is the union of the triangles touching those nodes: a
   polygon bounded by the contour edge ``A-B`` (the extra nodes lie on it,
   so the domain does not change) and the path of other nodes around them;
2. the cavity is triangulated again without the extra nodes, by dynamic
   programming over its vertices: of all the triangulations whose diagonals
   lie inside it, the one with the largest smallest angle.

A run is left as it is when its cavity is not a simple polygon (it touches
itself), has more than :data:`MAX_CAVITY` vertices, or its best
triangulation has an angle under :data:`MIN_ANGLE` degrees (on a graded
path's extra nodes: :data:`THIN_ANGLE`); those extra nodes stay and are
reported.  A cavity whose best triangulation is too thin grows by the
triangles around it, their inner nodes taken out too, up to :data:`GROW`
times.  Where no triangulation of the cavity's own vertices is good enough
however it grows, the cavity (growing up to :data:`FILL_GROW` times) is meshed
with new inner points (:func:`.cavity.fill`, with ``fill``), its sides as they
are, down to :data:`THIN_ANGLE`.  The quality stage then works on the new mesh
as on any other, and :func:`.pipeline.run_triangulate` checks the finished
mesh against the quality stage's bound (:func:`.forced.under_bound`).

Merging never reads the clock: each run of extra nodes is tried once per pass,
so the same mesh always merges the same way, on any machine under any load.

:func:`clear_sharp_corners` does the same for an inner node in the tip of a
sharp corner (under :data:`SHARP` degrees), where a coarse cell left the
corner split between two or more triangles: the corner's triangles and that
node's are triangulated again without it, by the same dynamic programming,
and kept only if their smallest angle grows.  The best a corner can have is
one triangle there with the corner's whole angle.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .cavity import best_triangulation, grow, inner_nodes, loop, renumber
from .geometry import node_stars
from .mesh import Mesh
from .quality import measures

#: A run is re-meshed only if its new triangles have no angle under this (degrees);
#: the quality stage raises the angles afterwards.
MIN_ANGLE = 20.0

#: ... or, with ``thin`` (a graded path's extra nodes, laid where a long contour edge
#: crosses cells its short neighbours need), and in cavities filled with new points,
#: under this.  Low, because an extra boundary node breaks the promise of the
#: contour's points as the only boundary nodes, while a thin triangle by a long edge
#: beside short ones is what meshes keeping those points have (Triangle ``pq30Y``: 1.3
#: to 10 degrees on the corpus's coastlines and icons); the quality stage then raises
#: it, and the finished mesh is checked against the bound of what the boundary forces
#: (``benchmarks/MEASURED.md``).
THIN_ANGLE = 1.0

#: Passes of :func:`merge_extra_nodes` (runs on consecutive contour edges share a
#: triangle at their common point: one merges per pass).
PASSES = 3

#: Times a cavity whose best triangulation is too thin grows by the triangles around
#: it (their inner nodes taken out with the extra ones).
GROW = 2

#: Cavities with more vertices than this are left alone (the triangulation costs
#: their cube).
MAX_CAVITY = 40

#: A cavity that no triangulation of its own vertices makes good enough is meshed with
#: new inner points (:mod:`.cavity`), growing up to this many times...
FILL_GROW = 4

#: ... and to at most this many triangles.
MAX_FILL = 300


#: Boundary corners under this angle (degrees) are worked on by
#: :func:`clear_sharp_corners` (two triangles there give at most half of it).
SHARP = 60.0

#: A corner's new triangles must raise its cavity's smallest angle by more than this
#: (degrees).
GAIN = 0.01


@dataclass
class Merged:
    """What :func:`merge_extra_nodes` did: extra nodes removed, and the ones left."""

    merged: int
    left: int
    filled: int = 0  # cavities meshed with new inner points
    added: int = 0  # the new inner points


def merge_extra_nodes(
    mesh: Mesh, passes: int = PASSES, thin: bool = False, fill: bool = True
) -> tuple[Mesh, Merged]:
    """``mesh`` without the extra boundary nodes that can be taken out (see the module
    docstring), renumbered; and what was done.  Up to ``passes`` passes: a run whose
    cavity shares a triangle with one merged before it waits for the next.  ``thin``:
    new triangles down to :data:`THIN_ANGLE` and the bound, not :data:`MIN_ANGLE`."""
    m, e = mesh.n_contour, mesh.n_extra
    if e == 0:
        return mesh, Merged(0, 0)
    pts, tri = mesh.points, mesh.triangles
    n = len(pts)
    nxt = np.full(n, -1, dtype=np.int64)
    nxt[mesh.lines[:, 0]] = mesh.lines[:, 1]
    extra = np.zeros(n, dtype=bool)
    extra[m : m + e] = True
    # the triangles of each extra node
    t_idx, corner = np.nonzero(extra[tri])
    star: dict[int, list[int]] = {}
    for v, t in zip(tri[t_idx, corner].tolist(), t_idx.tolist()):
        star.setdefault(v, []).append(t)
    runs = []
    for a in np.flatnonzero(~extra & extra[np.maximum(nxt, 0)] & (nxt >= 0)):
        run = [int(nxt[a])]
        while extra[nxt[run[-1]]]:
            run.append(int(nxt[run[-1]]))
        runs.append((int(a), run, int(nxt[run[-1]])))
    least = THIN_ANGLE if thin else MIN_ANGLE
    fill = fill and not mesh.point_data  # (new nodes would have no values)
    stars = node_stars(tri)
    on_boundary = np.zeros(n, dtype=bool)
    on_boundary[mesh.lines.ravel()] = True
    dead = np.zeros(len(tri), dtype=bool)
    gone = np.zeros(n, dtype=bool)
    added = []
    new_points: list[np.ndarray] = []  # inner points of filled cavities, numbered from n
    count = n
    for a, run, b in runs:
        first = cavity = sorted({t for x in run for t in star[x]})
        # inner nodes the cavity holds (all of whose triangles it takes), more as it grows
        inner = inner_nodes(tri, stars, cavity, on_boundary)
        new = None
        for _ in range(GROW + 1):
            if dead[cavity].any():  # shares a triangle with a run merged before: later
                break
            new = _retriangulate(pts, tri[cavity], a, b, set(run) | set(inner), least)
            if new is not None:
                break
            # with the cavity's inner neighbours taken out too, the triangle on A-B can
            # reach further from it
            cavity, inner = grow(tri, stars, cavity, on_boundary, MAX_CAVITY)
            if cavity is None:
                break
        if new is None and fill:
            got = _filled(pts, tri, stars, on_boundary, dead, first, a, b, run, count)
            if got is not None:
                cavity, inner, new, inside = got
                new_points.append(inside)
                count += len(inside)
        if new is None:
            continue
        dead[cavity] = True
        gone[run] = True
        gone[inner] = True
        added.append(new)
    merged = int(gone[extra].sum())
    filled, inserted = len(new_points), sum(len(p) for p in new_points)
    if merged == 0:
        return mesh, Merged(0, e)
    triangles = np.concatenate([tri[~dead], *added])
    if new_points:
        grown = np.concatenate([pts, *new_points])
        mesh = replace(mesh, points=grown)
        gone = np.concatenate([gone, np.zeros(len(grown) - n, dtype=bool)])
    out = renumber(mesh, triangles, gone)
    if merged < e and passes > 1:  # (runs next to merged ones)
        out, more = merge_extra_nodes(out, passes - 1, thin, fill)
        merged += more.merged
        filled += more.filled
        inserted += more.added
    return out, Merged(merged, e - merged, filled, inserted)


def _filled(pts, tri, stars, boundary, dead, cavity, a, b, run, base):
    """The first of the cavity and its growths, up to :data:`FILL_GROW` times, that
    :func:`.cavity.fill` meshes with new inner points with no angle under
    :data:`THIN_ANGLE`: ``(cavity, inner nodes taken out, triangles, new points)``,
    the new points numbered from ``base``; or None."""
    from . import cavity as _cavity

    inner = inner_nodes(tri, stars, cavity, boundary)
    for _ in range(FILL_GROW + 1):
        if cavity is None or dead[cavity].any():
            return None
        ring = _outline(tri[cavity], a, b, set(run) | set(inner))
        if ring is not None:
            got = _cavity.fill(pts[ring])
            if got is not None and got[2] >= THIN_ANGLE:
                inside, local, _ = got
                index = np.concatenate([np.asarray(ring), base + np.arange(len(inside))])
                return cavity, inner, index[local], inside
        cavity, inner = grow(tri, stars, cavity, boundary, MAX_FILL)
    return None


def _retriangulate(pts, cavity: np.ndarray, a: int, b: int, run: set[int], least=MIN_ANGLE):
    """The cavity's triangles without the ``run`` nodes, the best by smallest angle,
    or None (see the module docstring) if that is under ``least`` degrees."""
    ring = _outline(cavity, a, b, run)
    if ring is None or len(ring) > MAX_CAVITY:
        return None
    best = best_triangulation(pts[ring])
    if best is None:
        return None
    local, smallest = best
    new = np.asarray(ring, dtype=np.int64)[local]
    if smallest < least:
        return None
    return new


def _outline(cavity: np.ndarray, a: int, b: int, run: set[int]) -> list[int] | None:
    """The cavity's boundary counter-clockwise from ``a``: ``a, b``, then the nodes
    around the run back to ``a``; None if that is not one simple closed path."""
    edges = [
        (u, v)
        for t in cavity.tolist()
        for u, v in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))
        if u not in run and v not in run
    ]
    both = set(edges)
    after: dict[int, int] = {}
    for u, v in edges:
        if (v, u) in both:  # inside the cavity
            continue
        if u in after:  # the path around the run passes a node twice
            return None
        after[u] = v
    if a in after:
        return None
    ring = [a]
    v = b
    while v != a:
        if v in ring or v not in after:
            return None
        ring.append(v)
        v = after[v]
    if len(after) != len(ring) - 1:  # edges around the run that the path missed
        return None
    return ring


def clear_sharp_corners(mesh: Mesh) -> tuple[Mesh, int]:
    """``mesh`` with inner nodes taken out of sharp corners where that raises the
    smallest angle there (see the module docstring), renumbered; and how many."""
    from .forced import corner_angles

    pts, tri = mesh.points, mesh.triangles
    ends, angle = corner_angles(pts, mesh.lines)
    sharp = np.flatnonzero(angle < SHARP)
    if len(sharp) == 0:
        return mesh, 0
    free = np.ones(len(pts), dtype=bool)
    free[mesh.lines.ravel()] = False
    star = node_stars(tri)
    dead = np.zeros(len(tri), dtype=bool)
    gone = np.zeros(len(pts), dtype=bool)
    added = []
    for p in sharp.tolist():
        around = star(p)
        if len(around) < 2:
            continue
        best = None
        for x in sorted({int(v) for v in tri[around].ravel() if free[v] and not gone[v]}):
            cav = sorted(set(around) | set(star(x)))
            if dead[cav].any():
                continue
            ring = loop(tri[cav], {x})
            if ring is None or len(ring) > MAX_CAVITY:
                continue
            got = best_triangulation(pts[ring])
            if got is None or got[1] <= measures(pts, tri[cav])[0].min() + GAIN:
                continue
            if best is None or got[1] > best[0]:
                best = (got[1], cav, np.asarray(ring, dtype=np.int64)[got[0]], x)
        if best is not None:
            _, cav, new, x = best
            dead[cav] = True
            gone[x] = True
            added.append(new)
    if not added:
        return mesh, 0
    return renumber(mesh, np.concatenate([tri[~dead], *added]), gone), len(added)
