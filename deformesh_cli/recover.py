"""Boundary recovery: every extra boundary node taken out, a contour edge at a time.

The extra boundary nodes ``c1 .. ck`` between two consecutive contour points
``a`` and ``b`` lie on the segment ``a b`` (the deformation put them there).
Their *cavity* is the triangles touching any of them, grown by the star of
every inner node it reaches in the diametral disk of ``a b`` (such a node sees
``a b`` under more than a right angle; along a long edge those nodes would
leave a sliver each).  When the cavity's outline is one simple loop (through
every node of it but the ones it surrounds), the polygon without ``c1 .. ck``
is simple and has the side ``a b``: its constrained Delaunay triangulation
(compiled, ``_recover.polygon_cdt``'s loop: the largest smallest angle of any
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

from ._recover import recover_runs, runs
from .cavity import renumber
from .mesh import Mesh


def recover(mesh: Mesh, only: set[tuple[int, int]] | None = None) -> tuple[Mesh, int]:
    """``mesh`` with its extra boundary nodes taken out (see the module), and how many.
    ``only``: the runs between these pairs of contour points (either order) alone.

    A run of one node whose polygon has no counter-clockwise triangulation in
    floating point (its neighbours collinear to round-off) stays, and the
    contract check counts it.  The loop over the runs is compiled
    (``_recover.pyx``).
    """
    m, e = mesh.n_contour, mesh.n_extra
    if e == 0:
        return mesh, 0
    n = len(mesh.points)
    lines = np.ascontiguousarray(mesh.lines, dtype=np.int64)
    nxt = np.full(n, -1, dtype=np.int64)
    nxt[lines[:, 0]] = lines[:, 1]
    extra = np.zeros(n, dtype=np.uint8)
    extra[m : m + e] = 1
    # runs of extra nodes, each between two contour points, in the boundary's order
    starts = lines[(extra[lines[:, 0]] == 0) & (extra[lines[:, 1]] == 1), 0]
    ptr, nodes, ends = runs(nxt, extra, starts)
    if only is not None:
        pairs = np.array(sorted({(min(a, b), max(a, b)) for a, b in only}), dtype=np.int64)
        pairs = pairs.reshape(-1, 2)
        key = np.minimum(starts, ends) * n + np.maximum(starts, ends)
        pick = np.isin(key, pairs[:, 0] * n + pairs[:, 1])
        lengths = np.diff(ptr)[pick]
        nodes = nodes[np.repeat(pick, np.diff(ptr))]
        ptr = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
        starts, ends = starts[pick], ends[pick]
    boundary = np.zeros(n, dtype=np.uint8)
    boundary[lines.ravel()] = 1
    kept, gone = recover_runs(
        np.ascontiguousarray(mesh.points, dtype=np.float64),
        np.ascontiguousarray(mesh.triangles, dtype=np.int64),
        ptr,
        nodes,
        np.ascontiguousarray(starts),
        np.ascontiguousarray(ends),
        boundary,
    )
    if not gone.any():
        return mesh, 0
    return renumber(mesh, kept, gone), int(gone[m : m + e].sum())
