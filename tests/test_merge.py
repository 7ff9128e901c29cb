"""Extra boundary nodes taken out of finished meshes (``merge.py``): the domain, the
contour nodes and the contract are unchanged, only the extra nodes and their
triangles go, and a run is kept where no fair triangulation exists."""

import json
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from deformesh_cli import cavity, deadline, mesh_contour
from deformesh_cli.contour import make_contour
from deformesh_cli.errors import FoldError, LimitError, SelectionError
from deformesh_cli.geometry import signed_area, signed_areas
from deformesh_cli.merge import MIN_ANGLE, merge_extra_nodes
from deformesh_cli.mesh import Mesh
from deformesh_cli.quality import check_contract, measures
from deformesh_cli.readers import load_contour

from .conftest import ROOT, SAMPLES
from .test_properties import MAX_NODES, star_polygons

CORPUS = ROOT / "tests" / "data" / "corpus"


def _square_with_extra(lift: float) -> Mesh:
    """The unit square, contour points 0-3, an extra node 4 at (0.5, 0) on the bottom
    edge and an interior node 5 at (0.5, lift)."""
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0], [0.5, lift]], dtype=float)
    tri = np.array([[0, 4, 5], [4, 1, 5], [1, 2, 5], [2, 3, 5], [3, 0, 5]])
    lines = np.array([[0, 4], [4, 1], [1, 2], [2, 3], [3, 0]])
    return Mesh(pts, tri, lines, n_contour=4, n_extra=1, line_group=np.array([0, 0, 1, 1, 1]),
                groups=("bottom", "rest"))  # fmt: skip


def test_an_extra_node_is_taken_out_and_the_boundary_joined():
    mesh, done = merge_extra_nodes(_square_with_extra(0.5))
    assert (done.merged, done.left) == (1, 0)
    assert mesh.n_extra == 0 and len(mesh.points) == 5
    assert np.array_equal(mesh.points[:4], _square_with_extra(0.5).points[:4])
    assert sorted(map(tuple, mesh.lines.tolist())) == [(0, 1), (1, 2), (2, 3), (3, 0)]
    by_line = dict(zip(map(tuple, mesh.lines.tolist()), mesh.line_group.tolist()))
    assert by_line[(0, 1)] == 0 and by_line[(1, 2)] == 1  # the groups stay
    assert (signed_areas(mesh.points, mesh.triangles) > 0).all()
    assert signed_areas(mesh.points, mesh.triangles).sum() == pytest.approx(1.0)
    assert len(mesh.triangles) == 4


def test_an_inner_node_whose_triangles_all_go_goes_with_them():
    # a triangle 0-1-2 with extra nodes 3, 4, 5 on its bottom edge and an inner node 6
    # each of whose triangles has an extra node: merging takes out all of them (left,
    # node 6 would be a corner of no triangle; coast_india's graded mesh had one)
    pts = np.array([[0, 0], [1, 0], [0.5, 1], [0.25, 0], [0.5, 0], [0.75, 0], [0.5, 0.3]])
    tri = np.array([[0, 3, 2], [3, 4, 6], [4, 5, 6], [5, 2, 6], [2, 3, 6], [5, 1, 2]])
    lines = np.array([[0, 3], [3, 4], [4, 5], [5, 1], [1, 2], [2, 0]])
    mesh, done = merge_extra_nodes(Mesh(pts.astype(float), tri, lines, n_contour=3, n_extra=3))
    assert (done.merged, done.left) == (3, 0)
    assert len(mesh.points) == 3 and mesh.triangles.tolist() == [[0, 1, 2]]
    check_contract(mesh, make_contour(pts[:3].astype(float), source="t"))


def test_merging_does_not_read_the_clock():
    """Past the search's time bound (:mod:`deformesh_cli.deadline`) merging merges
    exactly as without one: no decision of stage 3 reads the clock."""
    free, _ = merge_extra_nodes(_square_with_extra(0.5))
    with deadline.limit(0.0):
        time.sleep(0.01)
        mesh, done = merge_extra_nodes(_square_with_extra(0.5))
    assert (done.merged, done.left) == (1, 0) and mesh.n_extra == 0
    assert np.array_equal(mesh.points, free.points)
    assert np.array_equal(mesh.triangles, free.triangles)


def test_a_run_without_a_fair_triangulation_stays(monkeypatch):
    # the interior node hugs the edge: every triangulation without node 4 has a sliver
    import deformesh_cli.merge as merge

    monkeypatch.setattr(merge, "GROW", 0)
    before = _square_with_extra(0.01)
    mesh, done = merge_extra_nodes(before, fill=False)
    assert (done.merged, done.left, done.filled) == (0, 1, 0)
    assert mesh is before
    # filling accepts down to THIN_ANGLE (the finished mesh is checked against the
    # bound afterwards): the sliver of 1.15 degrees
    mesh, done = merge_extra_nodes(before)
    assert (done.merged, done.left, done.filled) == (1, 0, 1)
    assert measures(mesh.points, mesh.triangles)[0].min() >= merge.THIN_ANGLE
    assert signed_areas(mesh.points, mesh.triangles).sum() == pytest.approx(1.0)


def test_a_cavity_grows_to_take_out_the_inner_node_hugging_the_edge():
    before = _square_with_extra(0.01)
    mesh, done = merge_extra_nodes(before)
    assert (done.merged, done.left) == (1, 0)
    assert len(mesh.points) == 4 and len(mesh.triangles) == 2  # node 5 went too
    assert measures(mesh.points, mesh.triangles)[0].min() == pytest.approx(45.0)
    assert signed_areas(mesh.points, mesh.triangles).sum() == pytest.approx(1.0)


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


def test_nothing_to_do_without_extra_nodes():
    m = _square_with_extra(0.5)
    m.n_extra = 0
    assert merge_extra_nodes(m)[1].merged == 0


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(star_polygons(r_min=0.2))
def test_merging_keeps_the_domain_and_the_contract(pts):
    """Random polygons on the uniform grid (where extra nodes are common): with merging,
    only extra nodes and their triangles change, the contract holds, no new triangle
    is under the angle the merge promises."""
    c = make_contour(pts, source="random")
    try:
        keep = mesh_contour(c, grid="uniform", max_nodes=MAX_NODES, improve=False)
    except (LimitError, SelectionError, FoldError):
        return
    merged = mesh_contour(
        c, grid="uniform", max_nodes=MAX_NODES, improve=False, merge_extra="merge"
    )
    k, m = keep.mesh, merged.mesh
    check_contract(m, c)
    assert np.array_equal(m.points[: c.n], c.points)
    gone = k.n_extra - m.n_extra
    assert gone == merged.report["merged_extra_nodes"] >= 0
    assert len(m.points) <= len(k.points) - gone  # (a grown cavity takes inner nodes too)
    area = abs(signed_area(c.points))
    assert abs(signed_areas(m.points, m.triangles).sum() - area) <= 1e-10 * area
    # every triangle is one of the old ones (renumbered) or a new one of fair angles
    old = {tuple(sorted(map(tuple, k.points[t].round(12).tolist()))) for t in k.triangles}
    new = [t for t in m.triangles
           if tuple(sorted(map(tuple, m.points[t].round(12).tolist()))) not in old]  # fmt: skip
    if new:
        assert measures(m.points, np.array(new))[0].min() >= MIN_ANGLE - 1e-9
    assert (gone > 0) == bool(new)


def test_auto_keeps_the_uniform_grid_as_the_paper_has_it(run, tmp_path):
    out = tmp_path / "m.vtk"

    def report(*args):
        r = run("all", SAMPLES / "peanut.csv", "-o", out, "--json", *args)
        assert r.exit_code == 0, r.stderr
        return json.loads(r.stdout)

    uniform = report("--grid", "uniform")
    assert uniform["extra_boundary_nodes"] > 100 and uniform["merged_extra_nodes"] == 0
    merged = report("--grid", "uniform", "--merge-extra", "merge")
    assert merged["merged_extra_nodes"] > 50
    assert (
        merged["extra_boundary_nodes"] + merged["merged_extra_nodes"]
        == (uniform["extra_boundary_nodes"])
    )
    adapt = report("--grid", "adapt")  # auto merges on the other grids
    kept = report("--grid", "adapt", "--merge-extra", "keep")
    assert kept["merged_extra_nodes"] == 0 and adapt["merged_extra_nodes"] > 0
    assert (
        adapt["extra_boundary_nodes"] + adapt["merged_extra_nodes"]
        == (kept["extra_boundary_nodes"])
    )


def test_merging_counts_extra_nodes_only_and_keeps_the_contract():
    """On a graded path with extra nodes (coast_cuba's long edges), merging may take
    inner nodes out with them (a cavity that grows); the count is of extra nodes."""
    from deformesh_cli.readers import load_contour

    c = load_contour(CORPUS / "coast_cuba.csv")
    kept = mesh_contour(c, merge_extra="keep", improve=False)
    assert kept.mesh.n_extra > 0
    mesh, done = merge_extra_nodes(kept.mesh)
    assert done.merged == kept.mesh.n_extra - mesh.n_extra and done.left == mesh.n_extra
    assert mesh.n_contour == kept.mesh.n_contour
    assert len(mesh.points) <= len(kept.mesh.points) - done.merged + done.added
    check_contract(mesh, c)
    assert np.array_equal(mesh.points[: c.n], c.points)


#: A random star (hypothesis found it) whose adapted-grid mesh has a cavity with an
#: extra node of the next run on a straight side: qhull left that vertex out of the
#: fill's Delaunay triangulation, the fill was taken without it, and the next pass
#: met an extra node with no triangle (a KeyError).
STAR_WITH_A_LOST_VERTEX = [
    (0.995749856, 0.091990354),
    (0.523875183, 0.0911074974),
    (0.85048033, 0.423300376),
    (0.232121065, 0.199374195),
    (0.537336425, 0.696496258),
    (0.171397371, 0.424968605),
    (0.0562892547, 0.640986238),
    (-0.0370467425, 0.608005671),
    (-0.0310108523, 0.118809518),
    (-0.117202945, 0.347848703),
    (-0.0597211652, 0.12649054),
    (-0.385779057, 0.399195202),
    (-0.680696758, 0.441901259),
    (-0.318728558, 0.0975869741),
    (-0.923885517, 0.0502066829),
    (-0.374042869, -0.108566132),
    (-0.780184394, -0.288838373),
    (-0.186425502, -0.128406316),
    (-0.139935247, -0.142892011),
    (-0.612094831, -0.718978604),
    (-0.038097947, -0.0924583497),
    (-0.0225880369, -0.146783487),
    (0.140663472, -0.709659343),
    (0.259250599, -0.908663125),
    (0.0790956928, -0.131107937),
    (0.137924621, -0.11472043),
    (0.46249073, -0.209753697),
    (0.412231614, -0.116950568),
    (0.621470601, -0.117601157),
    (0.625087966, -1.53102395e-16),
]


def test_a_fill_that_leaves_out_a_cavity_vertex_is_not_taken():
    c = make_contour(np.array(STAR_WITH_A_LOST_VERTEX), source="star")
    res = mesh_contour(c, max_nodes=MAX_NODES)
    used = np.zeros(len(res.mesh.points), dtype=bool)
    used[res.mesh.triangles.ravel()] = True
    assert used.all()
    check_contract(res.mesh, c)


def test_a_merge_way_that_would_repeat_one_measured_is_not_run(monkeypatch):
    # airfoil_e387: its graded mesh's extra nodes all merge down to 1 degree without
    # filling a cavity, and the quality stage leaves a triangle under the bound, so
    # the ways after the first are asked for; without new points the thin way would
    # give the very mesh the first gave
    from deformesh_cli import pipeline

    real, real_stage = pipeline._merge_and_improve, pipeline.run_triangulate
    runs = []  # per stage 3 run: its ways, the cavities each filled, the triangles under

    def stage(*a, **k):
        runs.append([])
        return real_stage(*a, **k)

    def record(mesh, edges, o, thin, fill):
        got = real(mesh, edges, o, thin, fill)
        m = got[0]
        under = pipeline.forced.under_bound(m.points, m.triangles, m.lines)
        runs[-1].append((thin, fill, got[2].filled if got[2] is not None else None, under))
        return got

    monkeypatch.setattr(pipeline, "run_triangulate", stage)
    monkeypatch.setattr(pipeline, "_merge_and_improve", record)
    mesh_contour(load_contour(CORPUS / "airfoil_e387.csv"))
    case = [w for w in runs if w[0][:3] == (True, True, 0) and w[0][3] > 0]
    assert case  # (the case)
    for ways in runs:
        for k, (thin, fill, _, _) in enumerate(ways):
            if not fill:
                assert not any(t == thin and f and done == 0 for t, f, done, _ in ways[:k])
    assert all((True, False) not in [w[:2] for w in ways] for ways in case)


def test_once_new_points_did_worse_the_later_meshes_skip_them(monkeypatch):
    # icon_si_nodedotjs: long edges down bars one cell wide.  On its graded mesh the
    # way with new points leaves more triangles under the bound than the way
    # without; the fallback grid's mesh then tries no way with new points, and the
    # mesh kept is the one it would keep after trying them (its way without new
    # points is the only one that keeps the bound)
    from deformesh_cli import pipeline

    real = pipeline.run_triangulate
    runs = []  # (h_rule, fill asked, the ways measured)

    def stage(contour, d, *a, **k):
        mesh, report = real(contour, d, *a, **k)
        runs.append((d.selection.h_rule, k.get("fill", True), report["merge_ways"]))
        return mesh, report

    monkeypatch.setattr(pipeline, "run_triangulate", stage)
    res = mesh_contour(load_contour(CORPUS / "icon_si_nodedotjs.svg"))
    graded = [r for r in runs if r[0] == "graded"]
    assert graded and graded[0][1] and pipeline._fill_lost(graded[0][2])  # (the case)
    after = runs[runs.index(graded[0]) + 1 :]
    assert after and all(not fill for _, fill, _ in after)
    assert all(not w["fill"] for _, _, ways in after for w in ways)
    assert res.report["h_rule"] != "graded" and res.report["merge_ways"][-1]["under_bound"] == 0
    check_contract(res.mesh, load_contour(CORPUS / "icon_si_nodedotjs.svg"))


@pytest.mark.parametrize(
    "unders, lost",
    [
        (((True, 5), (False, 2)), True),  # (fill, triangles under the bound) per way
        (((True, 2), (False, 2)), False),
        (((True, 0),), False),
        (((False, 0),), False),
        (((True, 9), (True, 3), (False, 4)), False),
        (((True, 9), (True, 5), (False, 4)), True),
    ],
)
def test_new_points_lose_only_to_a_way_without_them_that_left_fewer_under(unders, lost):
    from deformesh_cli.pipeline import _fill_lost

    ways = [
        {"fill": f, "under_bound": u, "thin": True, "extra_boundary_nodes": 0} for f, u in unders
    ]
    assert _fill_lost(ways) is lost
