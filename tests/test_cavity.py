"""cavity.fill: a polygon meshed with new inner points, its sides and vertices kept."""

import numpy as np
import pytest
import shapely
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from deformesh_cli.cavity import _delaunay, _recover, fill
from deformesh_cli.geometry import signed_areas
from deformesh_cli.quality import measures


def check_fill(p, got=None):
    got = fill(p) if got is None else got
    assert got is not None
    new, tri, angle = got
    pts = np.concatenate([p, new])
    poly = shapely.Polygon(p)
    # the new points are strictly inside, the triangles counter-clockwise and inside
    assert shapely.contains_xy(poly, new[:, 0], new[:, 1]).all()
    area = signed_areas(pts, tri)
    assert (area > 0).all()
    assert area.sum() == pytest.approx(poly.area, rel=1e-9)
    # every side is an edge of exactly one triangle; every inner edge of two
    uses: dict = {}
    for t in tri.tolist():
        for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
            uses[frozenset((a, b))] = uses.get(frozenset((a, b)), 0) + 1
    k = len(p)
    sides = {frozenset((i, (i + 1) % k)) for i in range(k)}
    assert all(uses.get(s) == 1 for s in sides)
    assert all(n == 2 for e, n in uses.items() if e not in sides)
    # every vertex and every new point is used
    assert set(np.unique(tri).tolist()) == set(range(len(pts)))
    assert angle == pytest.approx(measures(pts, tri)[0].min())
    return new, tri, angle


def long_edge_cavity(length, depth, steps):
    """A contour edge from (0, 0) to (length, 0), and above it a chain of ``steps``
    segments ``depth`` up: what a graded path's cavity looks like (counter-clockwise,
    starting at the edge's ends)."""
    xs = np.linspace(length, 0, steps + 1)
    chain = np.column_stack([xs, np.full_like(xs, depth)])
    return np.concatenate([[[0.0, 0.0], [length, 0.0]], chain])


def test_a_long_edge_over_a_shallow_cavity_gets_inner_points_and_a_fair_angle():
    """A cavity 8 long and 4 deep, unit sides but the contour edge and its two ends:
    the best triangulation of its own vertices fans the short sides out to the far
    ones (8.1 degrees).  Inner points graded from the short sides more than double
    the smallest angle."""
    from deformesh_cli.cavity import best_triangulation

    p = long_edge_cavity(8.0, 4.0, 8)
    new, tri, angle = check_fill(p)
    assert len(new) > 0
    assert angle > 2 * best_triangulation(p)[1]


@settings(max_examples=200)
@given(
    st.lists(st.tuples(st.floats(0.2, 3.0), st.floats(-0.4, 0.4)), min_size=3, max_size=24),
    st.floats(0.5, 6.0),
)
def test_random_cavities_are_filled_conformingly(radii, stretch):
    """Star-shaped polygons around the origin (random radii, stretched): whenever fill
    answers, the sides are kept, the vertices stay, the area is the polygon's; on a
    convex one it always answers."""
    k = len(radii)
    ang = 2 * np.pi * (np.arange(k) + np.array([j for _, j in radii]) * 0.9) / k
    r = np.array([q for q, _ in radii])
    p = np.column_stack([stretch * r * np.cos(ang), r * np.sin(ang)])
    poly = shapely.Polygon(p)
    assume(poly.is_valid and poly.exterior.is_ccw and poly.area > 1e-3)
    got = fill(p)
    if got is not None:
        check_fill(p, got)
    else:  # (a convex one always has its Delaunay triangulation, sides and all)
        assert not np.isclose(poly.convex_hull.area, poly.area, rtol=1e-12)


def test_recover_flips_a_missing_side_in():
    """A square's Delaunay diagonal is 0-2 or 1-3; asking for the other one flips it."""
    pts = np.array([[0, 0], [1, 0], [1, 1.1], [0, 1]], dtype=float)
    tri = np.array([[0, 1, 2], [0, 2, 3]])
    out = _recover(pts, tri, 1, 3)
    edges = {frozenset(e) for t in out.tolist() for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))}
    assert frozenset((1, 3)) in edges and frozenset((0, 2)) not in edges
    assert (signed_areas(pts, out) > 0).all()


def test_the_long_edge_cavity_shape_is_what_merge_sees():
    p = long_edge_cavity(6.0, 1.0, 6)
    assert shapely.Polygon(p).is_valid and shapely.Polygon(p).exterior.is_ccw
    check_fill(p)


def test_a_triangulation_without_one_of_the_vertices_is_refused(monkeypatch):
    """qhull may leave out a vertex lying on a straight side (seen on a cavity along a
    contour edge, its points there only to the nearest double): the triangles then
    cover the polygon, but without that vertex, and no flip can put the side back."""
    import scipy.spatial

    p = np.array([[0, 0], [1, 0], [2, 0], [2, 1], [0, 1]], dtype=float)  # (1, 0) on a side
    edges = np.column_stack([np.arange(5), (np.arange(5) + 1) % 5])
    poly = shapely.Polygon(p)

    class WithoutVertex1:
        def __init__(self, pts):
            self.simplices = np.array([[0, 2, 3], [0, 3, 4]])

    assert _delaunay(p, np.empty((0, 2)), edges, poly) is not None  # (qhull keeps it here)
    monkeypatch.setattr(scipy.spatial, "Delaunay", WithoutVertex1)
    assert _delaunay(p, np.empty((0, 2)), edges, poly) is None
