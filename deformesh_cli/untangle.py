"""Stage 3, where the deformation folded: the folded triangles of a mesh, mended.

A deformation let go on past a fold (:func:`.deform.deform_` with
``keep_folds``) can leave a few triangles turned over where the path's targets
squeeze the cells between them, at the tip of a tongue thinner than its cells,
or flat: three path nodes of one grid triangle carried onto one contour edge,
whose signed area is then round-off, a hair above or below zero (:func:`tangled`).
Each is mended by re-meshing its cavity:

1. the *cavity*: the tangled triangle and every triangle at its inner corners
   (those not on the boundary);
2. the cavity's inner nodes (all of whose triangles are in it) are taken out;
   its outline must be one simple counter-clockwise loop through all its other
   nodes, and a simple polygon where they now are.  Its signed area is the sum
   of the cavity's signed areas, so the mesh's area does not change;
3. the outline is triangulated again, by the triangulation of its own vertices
   with the largest smallest angle (:func:`.cavity.best_triangulation`), if none
   of its triangles is tangled itself (no new points; however thin, the quality
   stage works on it next);
4. otherwise the cavity grows by the triangles around it, up to :data:`GROW`
   times and :data:`MAX_TRIANGLES` triangles, its outline up to
   :data:`MAX_CAVITY` nodes.

Boundary nodes never move and every boundary edge of the cavity is a side of
its outline, so the boundary is the one the deformation gave.  With no triangle
tangled, that boundary and every triangle counter-clockwise make the mesh an
exact cover of the domain (each point is covered as many times as the boundary
winds round it: once); the contract check afterwards holds the mended mesh to
that as any other.  The quality stage then works on it as on any other.
"""

from __future__ import annotations

import numpy as np

from . import cavity
from .deform import areas_with_margin
from .geometry import node_stars, signed_area
from .mesh import Mesh

#: Cavities with more vertices than this are left alone (the triangulation costs
#: their cube).
MAX_CAVITY = 40

#: A cavity grows at most this many times (by the triangles touching it) ...
GROW = 6
#: ... and to at most this many triangles.
MAX_TRIANGLES = 300

#: What the pipeline mends at most (:func:`most_tangled`): this share of a mesh's
#: triangles, or as many as the contour has points if more (a fold is local to the
#: path's targets: the cells between them squeezed).  More is not a deformation
#: folded in a few places but one that went wrong as a whole (a fold in the first
#: step, carried the whole way), and meshing most of it again would answer with
#: whatever round-off favoured.
MAX_TANGLED_SHARE = 0.01


def most_tangled(mesh: Mesh) -> int:
    """The most tangled triangles the pipeline has ``mesh`` mended
    (:data:`MAX_TANGLED_SHARE`)."""
    return max(mesh.n_contour, int(MAX_TANGLED_SHARE * len(mesh.triangles)))


def tangled(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Which triangles are folded or flat (:data:`.deform.FLAT`): the ones :func:`untangle`
    meshes again.  A flat one's centroid lies on its side, so whether the domain
    holds it is round-off too.  (Area minus margin at most 0, in one compiled loop:
    the same test, as a difference of two finite numbers has the sign of their
    order.)"""
    return areas_with_margin(points, tri, -1.0) <= 0.0


def untangle(mesh: Mesh, most: int | None = None) -> Mesh | None:
    """``mesh`` with no tangled triangle (:func:`tangled`, module docstring),
    renumbered; ``mesh`` itself if none is; None if one cannot be mended, or if
    more than ``most`` are tangled (:func:`mend` says where)."""
    return mend(mesh, most)[0]


def mend(mesh: Mesh, most: int | None = None) -> tuple[Mesh | None, np.ndarray | None]:
    """:func:`untangle`, and where it stopped: ``(mesh, None)`` mended, or ``(None,
    place)``, the centroid of a tangled triangle it could not mend (the first
    one if more than ``most`` are tangled)."""
    folded = np.flatnonzero(tangled(mesh.points, mesh.triangles))
    if most is not None and len(folded) > most:
        return None, mesh.points[mesh.triangles[folded[0]]].mean(axis=0)
    # each mend meshes at least one tangled triangle again and makes none (step 3),
    # so the count falls at every mend
    while len(folded):
        mended = _mend(mesh, int(folded[0]))
        if mended is None:
            return None, mesh.points[mesh.triangles[folded[0]]].mean(axis=0)
        mesh = mended
        folded = np.flatnonzero(tangled(mesh.points, mesh.triangles))
    return mesh, None


def _mend(mesh: Mesh, t: int) -> Mesh | None:
    """``mesh`` with the cavity of its tangled triangle ``t`` meshed again, or None."""
    pts, tri = mesh.points, mesh.triangles
    boundary = np.zeros(len(pts), dtype=bool)
    boundary[mesh.lines.ravel()] = True
    stars = node_stars(tri)
    cav = sorted({t, *(s for v in tri[t].tolist() if not boundary[v] for s in stars(v))})
    inner = cavity.inner_nodes(tri, stars, cav, boundary)
    for _ in range(GROW + 1):
        ring = cavity.loop(tri[cav], set(inner))
        if ring is not None and len(ring) > MAX_CAVITY:
            return None
        local = None if ring is None else _remesh(pts[ring])
        if local is not None:
            dead = np.zeros(len(tri), dtype=bool)
            dead[cav] = True
            gone = np.zeros(len(pts), dtype=bool)
            gone[inner] = True
            new = np.asarray(ring, dtype=np.int64)[local]
            return cavity.renumber(mesh, np.concatenate([tri[~dead], new]), gone)
        cav, inner = cavity.grow(tri, stars, cav, boundary, MAX_TRIANGLES)
        if cav is None:
            return None
    return None


def _remesh(p: np.ndarray) -> np.ndarray | None:
    """The triangles of the outline ``p`` (module docstring, step 3) in its local
    indices, or None if it is not a simple counter-clockwise polygon or its best
    triangulation has a tangled (folded or flat) triangle."""
    import shapely

    if signed_area(p) <= 0:
        return None
    if not shapely.Polygon(p).is_valid:
        return None
    got = cavity.best_triangulation(p)
    if got is None or tangled(p, got[0]).any():
        return None
    return got[0]
