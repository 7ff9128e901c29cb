"""Boundary recovery's compiled loop (``_recover.pyx``) against the plain Python
reference it replaced: the same cavities, the same outlines, and (where no four
points of a cavity are cocircular, so the constrained Delaunay triangulation is
unique) the same triangles in the same order.  The reference triangulates each
cavity with GEOS's constrained Delaunay triangulation (through shapely)."""

import numpy as np
import pytest
import shapely

from deformesh_cli import pipeline
from deformesh_cli._recover import polygon_cdt as delaunay_polygon
from deformesh_cli.cavity import outline, renumber
from deformesh_cli.contour import make_contour
from deformesh_cli.geometry import signed_areas
from deformesh_cli.mesh import Mesh
from deformesh_cli.options import MeshOptions
from deformesh_cli.recover import recover

from .random_polygons import uneven_star


def _geos_delaunay_polygon(p: np.ndarray) -> np.ndarray | None:
    k = len(p)
    if k < 3:
        return None
    xy = shapely.get_coordinates(shapely.constrained_delaunay_triangles(shapely.Polygon(p)))
    if len(xy) != 4 * (k - 2):
        return None
    index: dict[tuple[float, float], int] = {}
    for i, q in enumerate(map(tuple, p.tolist())):
        index.setdefault(q, i)
    try:
        idx = [index[q] for q in map(tuple, xy.tolist())]
    except KeyError:
        return None
    rows = []
    for t in range(0, len(idx), 4):
        tri = [idx[t], idx[t + 1], idx[t + 2]]
        if signed_areas(p, np.array([tri]))[0] < 0:
            tri = tri[::-1]
        if signed_areas(p, np.array([tri]))[0] <= 0:
            return None
        f = tri.index(min(tri))
        rows.append(tri[f:] + tri[:f])
    return np.array(sorted(rows), dtype=np.int64)


def _recover_reference(mesh: Mesh, only: set[tuple[int, int]] | None = None) -> tuple[Mesh, int]:
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
            tris = _geos_delaunay_polygon(pts[poly])
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
            tris = None if found is None else _geos_delaunay_polygon(pts[found[0]])
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


def _mesh_with_extra_nodes(points: np.ndarray, seed: int) -> Mesh:
    """A mesh of the contour with its extra boundary nodes kept, inner nodes nudged at
    random (within a tenth of the least height of their triangles: all stay positive) so
    no four points of a cavity are cocircular."""
    contour = make_contour(points, source="random")
    o = MeshOptions(merge_extra="keep", improve=False)
    mesh = pipeline.mesh_contour(contour, o).mesh
    rng = np.random.default_rng(seed)
    tri = mesh.triangles
    inner = np.ones(len(mesh.points), dtype=bool)
    inner[mesh.lines.ravel()] = False
    edge = np.linalg.norm(mesh.points[tri] - mesh.points[np.roll(tri, 1, axis=1)], axis=2)
    height = 2 * signed_areas(mesh.points, tri) / edge.max(axis=1)
    short = np.full(len(mesh.points), np.inf)
    for k in range(3):
        np.minimum.at(short, tri[:, k], height)
    pts = mesh.points.copy()
    nudge = rng.uniform(-0.1, 0.1, pts.shape) * np.where(inner, short, 0.0)[:, None]
    pts += nudge
    assert (signed_areas(pts, tri) > 0).all()
    return Mesh(pts, tri, mesh.lines, mesh.n_contour, mesh.n_extra, mesh.line_group, mesh.groups)


def test_recovery_is_the_reference_recovery():
    """The compiled loop takes the same nodes out and leaves the same triangles, in the
    same order, as the Python reference on meshes of random polygons (all runs, and
    a few runs only)."""
    total = 0
    for seed in range(8):
        rng = np.random.default_rng(seed)
        mesh = _mesh_with_extra_nodes(uneven_star(rng, int(rng.integers(20, 200)))[0], seed)
        got, taken = recover(mesh)
        want, taken_ref = _recover_reference(mesh)
        assert taken == taken_ref
        assert np.array_equal(got.points, want.points)
        assert np.array_equal(got.triangles, want.triangles)
        assert np.array_equal(got.lines, want.lines)
        only = set(map(tuple, mesh.lines[::7].tolist()))
        got, _ = recover(mesh, only)
        want, _ = _recover_reference(mesh, only)
        assert np.array_equal(got.triangles, want.triangles)
        total += taken
    assert total > 100


def _star_polygon(rng, k):
    t = np.sort(rng.uniform(0, 2 * np.pi, k))
    r = rng.uniform(0.2, 1.0, k)
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


@pytest.mark.parametrize("seed", range(40))
def test_polygon_triangulation_is_geos_constrained_delaunay(seed):
    """On random star-shaped polygons (no four vertices cocircular) the kernel's
    triangulation is GEOS's constrained Delaunay one, row for row."""
    rng = np.random.default_rng(seed)
    p = _star_polygon(rng, int(rng.integers(3, 60)))
    got = delaunay_polygon(p)
    assert got is not None
    assert np.array_equal(got, _geos_delaunay_polygon(p))


def test_polygon_triangulation_of_a_square_grid_strip_and_of_a_flat_polygon():
    """A strip of grid squares with a vertex at every grid point of its sides (straight
    angles along them): triangles of positive area covering it, every smallest angle
    45 degrees, as in any triangulation of the grid points.  Three or more collinear
    points alone: None (no triangle of positive area)."""
    from deformesh_cli.quality import measures

    bottom = [[x, 0.0] for x in range(6)]
    top = [[x, 1.0] for x in range(5, -1, -1)]
    p = np.array(bottom + top)
    tri = delaunay_polygon(p)
    assert tri is not None and len(tri) == len(p) - 2
    assert (signed_areas(p, tri) > 0).all() and signed_areas(p, tri).sum() == pytest.approx(5.0)
    assert measures(p, tri)[0].min() == pytest.approx(45.0)
    assert delaunay_polygon(np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])) is None
