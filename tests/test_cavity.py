"""The re-meshing kernel (``cavity.py``): chords of a polygon, and the triangulation of
its own vertices with the largest smallest angle; extra boundary nodes taken out
of finished meshes as ``--merge-extra`` asks."""

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from deformesh_cli import cavity
from deformesh_cli.geometry import signed_area, signed_areas
from deformesh_cli.quality import measures

from .conftest import SAMPLES
from .test_properties import star_polygons


def test_chords_go_through_the_inside_and_touch_no_other_vertex():

    # a 4 x 2 rectangle with a vertex in the middle of its bottom side, and a notch from
    # the top whose tip (vertex 5) lies on the segment from vertex 0 to vertex 3, a
    # quarter of the way: that segment stays in the polygon, its midpoint inside
    p = np.array([[0, 0], [2, 0], [4, 0], [4, 2], [1.5, 2], [1, 0.5], [0.5, 2], [0, 2]])
    c = cavity.chords(p.astype(float))
    n = len(p)
    assert (c == c.T).all() and all(c[i, (i + 1) % n] for i in range(n))  # the sides
    assert not c[0, 2]  # along the bottom, through vertex 1
    assert not c[0, 3]  # through the notch's tip
    assert not c[4, 6]  # outside, across the notch
    assert c[1, 3] and c[1, 5] and c[2, 5] and c[0, 5] and c[3, 5]


def _every_triangulation(k: int, i: int = 0, j: int | None = None):
    """Every triangulation of the polygon's vertices ``i..j`` (all of them: j = k - 1),
    as lists of index triples."""
    j = k - 1 if j is None else j
    if j - i < 2:
        yield []
        return
    for m in range(i + 1, j):
        for left in _every_triangulation(k, i, m):
            for right in _every_triangulation(k, m, j):
                yield [(i, m, j), *left, *right]


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(star_polygons(r_min=0.15, max_points=8))
def test_the_best_triangulation_has_the_largest_smallest_angle_of_all(points):
    """Against every triangulation of a small polygon whose triangles all lie inside it
    (each side of every triangle a side or a chord: a shapely check of its own)."""
    import shapely

    p = np.asarray(points, dtype=float)
    if signed_area(p) < 0:
        p = p[::-1].copy()
    poly = shapely.Polygon(p)
    best = None
    for t in _every_triangulation(len(p)):
        t = np.array(t)
        if (signed_areas(p, t) <= 0).any():
            continue
        if not all(poly.covers(shapely.Polygon(p[tri])) for tri in t):
            continue
        if abs(signed_areas(p, t).sum() - poly.area) > 1e-9 * poly.area:
            continue
        angle = measures(p, t)[0].min()
        best = angle if best is None else max(best, angle)
    got = cavity.best_triangulation_of.__wrapped__(np.ascontiguousarray(p).tobytes())
    if best is None:
        assert got is None
    else:
        assert got is not None and got[1] == pytest.approx(best, abs=1e-9)
        assert measures(p, got[0])[0].min() == pytest.approx(got[1])


def test_a_kept_triangulation_is_the_one_computed_afresh():

    p = np.array([[0, 0], [2, 0], [3, 1], [2, 2], [0.5, 2.5], [-1, 1]], dtype=float)
    first = cavity.best_triangulation(p)
    assert cavity.best_triangulation(p.copy()) is first  # kept: asked again, not solved
    fresh = cavity.best_triangulation_of.__wrapped__(p.tobytes())
    assert np.array_equal(first[0], fresh[0]) and first[1] == fresh[1]
    with pytest.raises(ValueError):
        first[0][0, 0] = 5  # handed out again: nobody may change it
    moved = p.copy()
    moved[2] = (1, 1)  # another polygon, another answer (a reflex vertex)
    assert cavity.best_triangulation(moved) is not first


def test_auto_keeps_the_uniform_grid_as_the_paper_has_it(run, tmp_path):
    """``auto``: the uniform grid keeps its extra boundary nodes (the paper's form), the
    graded one takes every one out; ``merge`` takes the uniform grid's out too, ``keep``
    keeps the graded one's."""
    out = tmp_path / "m.vtk"

    def report(*args):
        r = run("all", SAMPLES / "peanut.csv", "-o", out, "--json", *args)
        assert r.exit_code == 0, r.stderr
        return json.loads(r.stdout)

    uniform = report("--grid", "uniform")
    assert uniform["extra_boundary_nodes"] > 100 and uniform["recovered_extra_nodes"] == 0
    merged = report("--grid", "uniform", "--merge-extra", "merge")
    assert merged["extra_boundary_nodes"] == 0
    assert merged["recovered_extra_nodes"] == uniform["extra_boundary_nodes"]
    graded = report()
    kept = report("--merge-extra", "keep")
    assert graded["extra_boundary_nodes"] == 0 and graded["recovered_extra_nodes"] > 0
    assert kept["recovered_extra_nodes"] == 0
    assert kept["extra_boundary_nodes"] == graded["recovered_extra_nodes"]
