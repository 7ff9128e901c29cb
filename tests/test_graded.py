"""The graded background: a balanced quadtree split into conforming right isosceles
triangles, its cells following the contour's local size."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from deformesh_cli import coarsen
from deformesh_cli.contour import make_contour
from deformesh_cli.errors import InputError, LimitError
from deformesh_cli.geometry import edge_uses, signed_areas
from deformesh_cli.quality import measures
from deformesh_cli.readers import load_contour
from deformesh_cli.select import graded

from .conftest import ROOT, SAMPLES, contour_file, solver_read
from .test_properties import star_polygons

CORPUS = ROOT / "tests" / "data" / "corpus"

CONTOURS = [
    SAMPLES / "peanut.csv",
    SAMPLES / "bracket.svg",
    SAMPLES / "naca0012.csv",
    contour_file("circle_1000.csv"),
    contour_file("naca0012_1000.csv"),
    contour_file("square_hole_100.csv"),
]


def _box(c, grow=0.1):
    lo, hi = c.points.min(axis=0), c.points.max(axis=0)
    e = float((hi - lo).max()) * grow
    return (lo[0] - e, lo[1] - e, hi[0] + e, hi[1] + e)


def _check_triangulation(q, pts, tri, square=True):
    """Conforming, counter-clockwise, tiling the box, and (square cells) 45-45-90."""
    area = signed_areas(pts, tri)
    assert (area > 0).all()
    x0, y0, x1, y1 = q.box
    assert area.sum() == pytest.approx((x1 - x0) * (y1 - y0), rel=1e-12)
    lo, hi, fwd, rev = edge_uses(tri, len(pts))
    assert (fwd <= 1).all() and (rev <= 1).all()  # no edge walked twice the same way
    lone = (fwd + rev) == 1
    a, b = pts[lo[lone]], pts[hi[lone]]
    on_box = (
        (np.isclose(a[:, 0], x0) & np.isclose(b[:, 0], x0))
        | (np.isclose(a[:, 0], x1) & np.isclose(b[:, 0], x1))
        | (np.isclose(a[:, 1], y0) & np.isclose(b[:, 1], y0))
        | (np.isclose(a[:, 1], y1) & np.isclose(b[:, 1], y1))
    )
    assert on_box.all()  # every boundary edge is on the box: no hanging node anywhere
    assert np.hypot(*(a - b).T).sum() == pytest.approx(2 * (x1 - x0 + y1 - y0), rel=1e-12)
    if square:
        amin, amax, _, _ = measures(pts, tri)
        assert np.allclose(amin, 45.0) and np.allclose(amax, 90.0)


def _check_balanced(q):
    for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        holder = q.leaf_index(q.level, q.i + di, q.j + dj)
        ok = holder >= 0
        assert (q.level[holder[ok]] <= q.level[ok] + 1).all()


@pytest.mark.parametrize("path", CONTOURS, ids=lambda p: p.name)
def test_conforming_right_isosceles_and_balanced(path):
    c = load_contour(path)
    q = graded.build(c, _box(c))
    pts, tri, cell = q.triangulate()
    _check_triangulation(q, pts, tri)
    _check_balanced(q)
    assert len(cell) == len(tri) and set(cell.tolist()) == set(range(q.n_leaves))
    assert q.level.min() == 0 and q.level.max() >= 1  # graded: more than one size


@pytest.mark.parametrize("path", CONTOURS, ids=lambda p: p.name)
def test_cells_follow_the_size_field(path):
    """Each leaf is no larger than the size field there (before balancing, which only
    splits), and the leaf holding a contour point no larger than its local size."""
    c = load_contour(path)
    growth = graded.DEFAULT_GROWTH
    s = graded.graded_sizes(c.points, graded.local_sizes(c), growth) * graded.CELL_FACTOR
    q = graded.build(c, _box(c))
    side = q.sizes()
    x0 = q.x0 + q.i * side
    y0 = q.y0 + q.j * side
    dx = np.maximum(np.abs(c.points[None, :, 0] - (x0 + side / 2)[:, None]) - side[:, None] / 2, 0)
    dy = np.maximum(np.abs(c.points[None, :, 1] - (y0 + side / 2)[:, None]) - side[:, None] / 2, 0)
    need = np.min(s[None, :] + (growth - 1) * np.hypot(dx, dy), axis=1)
    assert ((side <= graded.SPLIT_ABOVE * need * (1 + 1e-12)) | (q.level == 0)).all()
    # the finest cells are within a factor SPLIT_ABOVE of the smallest local size
    # (h0 is the largest power-of-two fraction of the root that fits)
    h0 = side[q.level == 0].max()
    top = graded.SPLIT_ABOVE * s.min()
    assert top / 2 < h0 <= top * (1 + 1e-12)


@pytest.mark.parametrize("n", [3, 40, 700])
def test_graded_sizes_are_the_envelope_of_the_cones(n):
    """The growth-limited sizes are the lower envelope of the cones ``s_q' + (growth
    - 1) |q - q'|`` to within the slack (computed here over all pairs), never above
    ``s`` itself, and change between two points by at most the growth times their
    distance (and the slack)."""
    from deformesh_cli.select.cones import SLACK

    rng = np.random.default_rng(n)
    p = rng.random((n, 2)) * [3.0, 1.0]
    s = 10.0 ** rng.uniform(-3, -0.5, n)
    got = graded.graded_sizes(p, s, 1.5)
    d = np.hypot(*(p[:, None] - p[None]).transpose(2, 0, 1))
    exact = np.min(s[None, :] + 0.5 * d, axis=1)
    assert (got >= exact * (1 - 1e-12)).all() and (got <= exact * SLACK * (1 + 1e-12)).all()
    assert (got <= s).all() and (n < 40 or (got < s).any())
    assert (got[:, None] <= (got[None, :] + 0.5 * d) * SLACK * (1 + 1e-12)).all()


def test_graded_sizes_on_one_circle_and_one_line():
    """Points on one circle (all as far from its centre) and points on one line both
    get their sizes."""
    t = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    circle = np.column_stack([np.cos(t), np.sin(t)])
    s = np.full(2000, 1e-2)
    s[0] = 1e-5
    got = graded.graded_sizes(circle, s, 2.0)
    assert got[0] == 1e-5 and np.isclose(got[1], 1e-5 + np.hypot(*(circle[1] - circle[0])))
    line = np.column_stack([np.arange(5.0), np.zeros(5)])
    got = graded.graded_sizes(line, np.array([0.1, 5, 5, 5, 5]), 2.0)
    assert np.allclose(got, [0.1, 1.1, 2.1, 3.1, 4.1])


def test_the_two_sides_of_a_thin_part_get_cells_of_their_own():
    """A strip 0.01 thick and 1 long with points 0.05 apart: the local size is the
    thickness, so no leaf holds points of both sides."""
    x = np.linspace(0, 1, 21)
    pts = np.concatenate(
        [np.column_stack([x, np.zeros(21)]), np.column_stack([x[::-1], np.full(21, 0.01)])]
    )
    c = make_contour(pts, source="strip")
    s = graded.local_sizes(c)
    assert s.max() <= 0.01 + 1e-12
    q = graded.build(c, _box(c, 0.5))
    holder = q.leaf_index(
        np.zeros(c.n, np.int64),
        np.floor((c.points[:, 0] - q.x0) / q.hx).astype(np.int64),
        np.floor((c.points[:, 1] - q.y0) / q.hy).astype(np.int64),
    )
    bottom, top = set(holder[:21].tolist()), set(holder[21:].tolist())
    assert not bottom & top


def test_a_given_box_is_kept_and_cells_stay_nearly_square():
    c = load_contour(SAMPLES / "naca0012.csv")
    for box in ((-20, -20, 21, 20), (-50, -50, 51, 50), (-2, -2, 3, 2)):
        q = graded.build(c, box, box_given=True)
        assert q.box == pytest.approx(box, abs=1e-9)
        assert abs(q.hx / q.hy - 1) <= graded.MAX_STRETCH
        pts, tri, _ = q.triangulate()
        _check_triangulation(q, pts, tri, square=False)
        amin, amax, _, _ = measures(pts, tri)
        assert amin.min() > 43 and amax.max() < 93


def test_a_far_field_grades_to_few_cells():
    """A 41 x 40 box around a unit-chord airfoil: the cells grow from the contour's
    size to the box's, so the whole grid holds a few thousand nodes, not 1e8."""
    c = load_contour(SAMPLES / "naca0012.csv")
    q = graded.build(c, (-20, -20, 21, 20), box_given=True)
    pts, _, _ = q.triangulate()
    assert q.hx * 2**q.top >= 2.0 and len(pts) < 5_000  # root cells 2 chords wide or more


def test_either_diagonal_is_conforming():
    c = load_contour(SAMPLES / "peanut.csv")
    q = graded.build(c, _box(c))
    rng = np.random.default_rng(1)
    pts, tri, cell = q.triangulate(rng.integers(0, 2, q.n_leaves).astype(np.uint8))
    _check_triangulation(q, pts, tri)


def test_too_many_cells_is_a_limit_error():
    c = load_contour(contour_file("circle_1000.csv"))
    with pytest.raises(LimitError, match="graded grid"):
        graded.build(c, _box(c), max_nodes=1000)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(star_polygons(r_min=0.1), st.floats(-3, 3))
def test_random_polygons(pts, log_scale):
    try:
        c = make_contour(pts * 10.0**log_scale, source="random")
    except InputError:
        return
    q = graded.build(c, _box(c, 0.3))
    pts_, tri, _ = q.triangulate()
    _check_triangulation(q, pts_, tri)
    _check_balanced(q)


# -- the path on the graded grid, and meshes made on it --------------------------------

#: Contours the graded path fits today (every point its own node, no extra node).
FITTED = [
    SAMPLES / "peanut.csv",
    SAMPLES / "circle.csv",
    contour_file("circle_100.csv"),
    contour_file("circle_1000.csv"),
    contour_file("star_100.csv"),
    contour_file("star_1000.csv"),
    contour_file("channel_100.csv"),
    contour_file("bean_100.csv"),
    contour_file("bean_1000.csv"),
    contour_file("square_hole_100.csv"),
    SAMPLES / "half_disk.csv",
]


@pytest.mark.parametrize("path", FITTED, ids=lambda p: p.name)
def test_graded_path_keeps_every_contour_edge(path):
    from deformesh_cli.select.construct import select_constructed

    c = load_contour(path)
    sel = select_constructed(c)
    assert sorted(sel.path_source[sel.path_source >= 0].tolist()) == list(range(c.n))
    assert len(np.unique(sel.path_nodes)) == len(sel.path_nodes)  # a node per point
    on = sel.path_source >= 0
    assert np.array_equal(sel.path_targets[on], c.points[sel.path_source[on]])
    tri = sel.triangles()
    lo, hi, _, _ = edge_uses(tri, sel.grid.n_nodes)
    edges = set((lo * sel.grid.n_nodes + hi).tolist())
    for r in np.unique(sel.path_ring):
        ring = sel.path_nodes[sel.path_ring == r]
        a, b = np.minimum(ring, np.roll(ring, -1)), np.maximum(ring, np.roll(ring, -1))
        assert all(int(k) in edges for k in a * sel.grid.n_nodes + b)  # steps are edges
    # a kept triangle of three loop nodes keeps its orientation at their targets
    on = np.zeros(sel.grid.n_nodes, dtype=bool)
    on[sel.path_nodes] = True
    target = np.zeros((sel.grid.n_nodes, 2))
    target[sel.path_nodes] = sel.path_targets
    full = tri[sel.kept_triangles() & on[tri].all(axis=1)]
    assert (signed_areas(target, full) > 0).all()
    _check_triangulation(sel.grid.tree, sel.grid.points, tri)


@pytest.mark.parametrize("path", FITTED, ids=lambda p: p.name)
def test_graded_meshes_meet_the_contract_with_no_extra_node(path):
    from deformesh_cli import mesh_contour

    c = load_contour(path)
    res = mesh_contour(c, grid="graded")  # raises unless the contract holds
    uniform = mesh_contour(c, grid="uniform")
    assert res.report["h_rule"] == "graded" and res.report["extra_boundary_nodes"] == 0
    # (the coarsening makes no triangle under its ANGLE; the quality stage lifts
    # the rest toward 35 degrees)
    assert res.report["min_angle"] >= coarsen.ANGLE
    assert res.mesh.n_nodes < uniform.mesh.n_nodes  # graded: fewer nodes away from the contour
    assert np.array_equal(res.mesh.points[: c.n], c.points)


@pytest.mark.parametrize("w,h", [(5, 1), (6, 1), (8, 1), (10, 1), (20, 3), (1, 0.2)])
def test_a_rectangle_given_by_its_four_corners_meshes(w, h):
    """The commonest CFD domain, drawn with its corners only, meshes at default
    options with its four corners as the only boundary nodes (a grid too coarse
    for a point to take a node used to end in a traceback)."""
    from deformesh_cli import mesh_contour

    pts = np.array([[0, 0], [w, 0], [w, h], [0, h]], dtype=float)
    c = make_contour(pts, source="rectangle")
    res = mesh_contour(c)  # raises unless the contract holds
    assert res.report["extra_boundary_nodes"] == 0
    assert np.array_equal(res.mesh.points[:4], pts)
    assert np.isclose(signed_areas(res.mesh.points, res.mesh.triangles).sum(), w * h)


def test_graded_exterior_and_size_function():
    from deformesh_cli import mesh_contour

    c = load_contour(SAMPLES / "circle.csv")
    ext = mesh_contour(c, grid="graded", exterior=True, box=(-2.0, -2.0, 2.0, 2.0))
    assert ext.report["h_rule"] == "graded" and ext.report["extra_boundary_nodes"] == 0
    assert set(ext.mesh.groups) >= {"contour", "bottom", "right", "top", "left"}
    sized = mesh_contour(load_contour(SAMPLES / "peanut.csv"), grid="graded", size="0.05 + d")
    assert sized.report["h_rule"] == "graded"
    assert sized.report["size_correlation"] >= 0.85  # (measured 0.861)


def test_graded_cli(run, tmp_path):
    out = tmp_path / "m.msh"
    r = run("all", SAMPLES / "peanut.csv", "--grid", "graded", "-o", out, "--json", "-q")
    assert r.exit_code == 0, r.stderr
    import json

    rec = json.loads(r.stdout)
    assert rec["extra_boundary_nodes"] == 0 and rec["h_rule"] == "graded"
    r = run("all", SAMPLES / "peanut.csv", "--grid", "graded", "--h", "0.1", "-o", out)
    assert r.exit_code == 2 and "--h" in r.stderr


def test_graded_state_files_give_the_same_mesh(sh, tmp_path):
    """select | deform | triangulate on the graded grid writes what all writes, and a
    state file whose leaves do not tile the box is refused in one line."""
    import io
    import zipfile

    src = contour_file("naca0012_100.csv")
    sh(
        f"deformesh select {src} --grid graded -o - -q | deformesh deform - -o s.state -q"
        f" && deformesh triangulate s.state -o pipe.msh -q"
        f" && deformesh all {src} --grid graded -o all.msh -q",
        cwd=tmp_path,
    )
    assert (tmp_path / "pipe.msh").read_bytes() == (tmp_path / "all.msh").read_bytes()
    data = (tmp_path / "s.state").read_bytes()
    with zipfile.ZipFile(io.BytesIO(data)) as zin:
        members = {n: zin.read(n) for n in zin.namelist()}
    assert {"leaf_level.npy", "leaf_i.npy", "leaf_j.npy", "kept.npy"} <= set(members)
    buf = io.BytesIO()
    level = np.lib.format.read_array(io.BytesIO(members["leaf_level.npy"]))
    b = io.BytesIO()
    np.lib.format.write_array(b, level[:-1])  # one leaf missing: the box is not tiled
    members["leaf_level.npy"] = b.getvalue()
    with zipfile.ZipFile(buf, "w") as zout:
        for n, v in members.items():
            zout.writestr(n, v)
    (tmp_path / "bad.state").write_bytes(buf.getvalue())
    r = sh("deformesh triangulate bad.state -o bad.msh", cwd=tmp_path, check=False)
    assert r.returncode == 1 and b"damaged state file" in r.stderr
    assert r.stderr.count(b"\n") == 1 and not (tmp_path / "bad.msh").exists()


@pytest.mark.parametrize(
    "path",
    [contour_file("naca0012_100.csv"), contour_file("naca0012_1000.csv"), SAMPLES / "bracket.svg"]
    + [CORPUS / n for n in ("airfoil_n0012.csv", "airfoil_sc20714.csv", "icon_si_apple.svg")],
    ids=lambda v: v.name,
)
def test_graded_meshes_where_the_spacing_changes_fast(path):
    """Points clustered at an airfoil's ends, a blunt trailing edge, long edges beside
    short ones: the cells follow the points' sizes, the boundary nodes are exactly the
    points, and the mesh has fewer nodes than Appendix A's uniform grid's."""
    from deformesh_cli import mesh_contour

    c = load_contour(path)
    res = mesh_contour(c)
    assert res.report["h_rule"] == "graded"
    assert res.report["extra_boundary_nodes"] == 0
    assert np.array_equal(res.mesh.points[: c.n], c.points)
    if path.name == "naca0012_1000.csv":  # (its trailing edge's spacing: 3.6e10 nodes)
        with pytest.raises(LimitError, match="would need"):
            mesh_contour(c, grid="uniform")
    else:
        assert res.mesh.n_nodes < mesh_contour(c, grid="uniform").mesh.n_nodes


@pytest.mark.parametrize("box", [(-20, -20, 21, 20), (-50, -50, 51, 50)])
def test_graded_far_field_opens_in_gmsh_and_scikit_fem(run, tmp_path, box):
    """The usual CFD far field around samples/naca0012.csv, at default options: the
    uniform grid refuses it (6.4e8 nodes); the graded grid, the default for far fields,
    meshes it with under 3 times Triangle's nodes and no extra boundary node, its box
    sides and the airfoil named groups the solvers read."""
    import json

    out = tmp_path / "far.msh"
    arg = "--box=" + ",".join(str(v) for v in box)
    r = run("all", SAMPLES / "naca0012.csv", "--exterior", arg, "-o", out, "--json", "-q")
    assert r.exit_code == 0, r.stderr
    rec = json.loads(r.stdout)
    assert rec["h_rule"].startswith("graded") and rec["contract"] == "ok"
    assert rec["extra_boundary_nodes"] == 0
    refused = run("all", SAMPLES / "naca0012.csv", "--exterior", arg, "--grid", "uniform",
                  "-o", tmp_path / "u.msh")  # fmt: skip
    assert refused.exit_code == 1 and "would need" in refused.stderr
    assert rec["nodes"] < 3 * 700  # Triangle pq30Y: 654 and 668 nodes on these boxes
    c = load_contour(SAMPLES / "naca0012.csv")
    assert rec["area"] == pytest.approx((box[2] - box[0]) * (box[3] - box[1]) - c.area, rel=1e-12)
    phys, sk = solver_read(out)
    assert phys == {"contour": 1, "bottom": 1, "right": 1, "top": 1, "left": 1, "domain": 2}
    assert set(sk.boundaries) == {"contour", "bottom", "right", "top", "left"}
    assert len(sk.boundaries["contour"]) == c.n + rec["extra_boundary_nodes"]


def test_growth_and_max_h_shape_the_graded_grid():
    from deformesh_cli import mesh_contour
    from deformesh_cli.errors import OptionError

    c = load_contour(contour_file("circle_1000.csv"))
    nodes = [mesh_contour(c, grid="graded", growth=g).mesh.n_nodes for g in (1.5, 2.0, 3.0)]
    assert nodes[0] > nodes[1] > nodes[2]  # faster growth: fewer nodes away from the contour
    res = mesh_contour(c, grid="graded", max_h=0.1)
    assert res.selection.grid.tree.sizes().max() <= 0.1 * (1 + graded.MAX_STRETCH)
    assert res.mesh.n_nodes > nodes[1]
    with pytest.raises(OptionError, match="--growth"):
        mesh_contour(c, grid="graded", growth=1.0)


@pytest.mark.parametrize(
    "path,expr,apart,floor",
    [
        (SAMPLES / "peanut.csv", "1 + x**2", True, 0.9),  # (measured 0.94)
        (SAMPLES / "peanut.csv", "0.1 + d", False, 0.85),  # (0.886)
        (SAMPLES / "circle.csv", "0.02 + hypot(x - 0.4, y - 0.2)", True, 0.83),  # (0.855)
    ],
    ids=["peanut-x2", "peanut-d", "circle-point"],
)
def test_a_size_function_grades_the_graded_grid_too(path, expr, apart, floor):
    """The quadtree is refined where f asks for smaller cells, then the deformation
    smooths it: areas follow f.  Where f does not grow with the distance to the contour
    (``apart``), deforming the unrefined graded grid follows it less well."""
    from deformesh_cli import mesh_contour, pipeline
    from deformesh_cli.options import MeshOptions

    c = load_contour(path)
    res = mesh_contour(c, grid="graded", size=expr)
    assert res.report["h_rule"].startswith("graded")
    assert res.report["extra_boundary_nodes"] == 0
    assert res.report["size_correlation"] >= floor
    assert res.report["min_angle"] >= 35.0
    # the same graded selection without the refinement follows f less well
    laid = pipeline.lay(c, MeshOptions())
    plain = pipeline.run_select(laid.grid)
    d = pipeline.run_deform(laid.grid, plain, size=expr)
    unrefined = pipeline.run_triangulate(laid, d, size=expr)[1]["size_correlation"]
    if apart:
        assert unrefined < res.report["size_correlation"] - 0.1


def test_a_size_field_file_grades_the_graded_grid(tmp_path):
    from deformesh_cli import mesh_contour

    xs, ys = np.meshgrid(np.linspace(-3, 3, 31), np.linspace(-2, 2, 21), indexing="ij")
    rows = np.column_stack([xs.ravel(), ys.ravel(), 1 + xs.ravel() ** 2])
    path = tmp_path / "f.csv"
    np.savetxt(path, rows, delimiter=",", header="x,y,f", comments="")
    res = mesh_contour(load_contour(SAMPLES / "peanut.csv"), grid="graded", size_field=str(path))
    assert res.report["h_rule"].startswith("graded")
    assert res.report["size_correlation"] >= 0.9


def test_a_size_function_given_to_select_reaches_the_pipeline(sh, tmp_path):
    """select --size refines the graded grid and records f for deform, so the pipeline
    writes the bytes 'all' writes; deform's own --size overrides it."""
    src = SAMPLES / "peanut.csv"
    f = "--size '1 + x**2'"
    r = sh(
        f"deformesh select {src} --grid graded {f} -o - -q | deformesh deform - -o - -q | "
        f"deformesh triangulate - -o {tmp_path}/p.vtk --json -q"
    )
    import json

    rec = json.loads(r.stdout)
    assert rec["size"] == "'1 + x**2'" and rec["size_correlation"] >= 0.9
    sh(f"deformesh all {src} --grid graded {f} -o {tmp_path}/a.vtk -q")
    assert (tmp_path / "p.vtk").read_bytes() == (tmp_path / "a.vtk").read_bytes()
    r = sh(
        f"deformesh select {src} --grid graded {f} -o - -q | "
        "deformesh deform - -o - -q --size '2 + y' | "
        f"deformesh triangulate - -o {tmp_path}/q.vtk --json -q"
    )
    assert json.loads(r.stdout)["size"] == "'2 + y'"
    both = sh(f"deformesh select {src} {f} --size-field x.csv -o {tmp_path}/s", check=False)
    assert both.returncode == 2 and b"not both" in both.stderr


def test_a_python_size_function_refines_the_graded_grid_as_the_expression_does():
    from deformesh_cli import mesh_contour
    from deformesh_cli.size import SizeFunction

    c = load_contour(SAMPLES / "peanut.csv")
    f = SizeFunction(lambda q: 1 + q[:, 0] ** 2, "1 + x**2 in Python")
    py = mesh_contour(c, grid="graded", size_function=f)
    expr = mesh_contour(c, grid="graded", size="1 + x**2")
    assert py.mesh.n_nodes == expr.mesh.n_nodes
    assert py.report["size_correlation"] == pytest.approx(expr.report["size_correlation"])
    assert py.report["size_correlation"] >= 0.9


@pytest.mark.parametrize(
    "name",
    [
        "coast_cuba.csv",
        "coast_sri_lanka.csv",
        "icon_bi_star-fill.svg",
        "icon_si_python.svg",
        "icon_si_android.svg",
        "icon_bi_bell-fill.svg",
    ],
)
def test_long_edges_beside_short_ones_mesh_with_their_extra_nodes_recovered(name):
    """Contours whose long edges cross several of the cells their short neighbours
    need: the loop steps through grid nodes there, and stage 3 takes every one of
    those extra nodes out again (:mod:`.recover`)."""
    from deformesh_cli import mesh_contour

    c = load_contour(CORPUS / name)
    res = mesh_contour(c)
    assert res.report["h_rule"].startswith("graded")
    assert (res.selection.path_source < 0).any()  # the path had extra nodes
    assert res.report["extra_boundary_nodes"] == 0
    assert res.report["recovered_extra_nodes"] == res.selection.extra_nodes
    assert np.array_equal(res.mesh.points[: c.n], c.points)
    assert res.mesh.n_nodes < 3 * len(c.points) + 2000


def test_strict_on_the_graded_grid_gives_no_extra_node():
    """``--strict`` on the graded grid: the loop's extra nodes are all taken out, so the
    mesh has none (a mesh with one left would be refused)."""
    from deformesh_cli import mesh_contour

    c = load_contour(CORPUS / "coast_cuba.csv")
    res = mesh_contour(c, strict=True)
    assert res.mesh.n_extra == 0 and res.report["recovered_extra_nodes"] > 0


def _balance_every_leaf_asks(tree):
    """Balancing where every leaf asks in every round (the reference)."""
    lv, i, j = tree.level, tree.i, tree.j
    while True:
        t = graded.Quadtree(
            tree.x0, tree.y0, tree.hx, tree.hy, tree.top, tree.nx, tree.ny, lv, i, j
        )
        marks = np.zeros(len(lv), dtype=bool)
        for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            holder = t.leaf_index(lv, i + di, j + dj)
            ok = holder >= 0
            too_big = ok.copy()
            too_big[ok] = lv[holder[ok]] > lv[ok] + 1
            marks[holder[too_big]] = True
        if not marks.any():
            return t
        keep = ~marks
        ls, is_, js = lv[marks] - 1, i[marks], j[marks]
        lv = np.concatenate([lv[keep], np.repeat(ls, 4)])
        i = np.concatenate([i[keep], np.repeat(is_, 4) * 2 + np.tile([0, 1, 0, 1], len(is_))])
        j = np.concatenate([j[keep], np.repeat(js, 4) * 2 + np.tile([0, 0, 1, 1], len(js))])


@pytest.mark.parametrize("name", ["peanut.csv", "naca0012.csv", "half_disk.csv"])
def test_balance_asks_again_only_where_a_neighbour_split(name):
    """Refined but unbalanced trees of samples (a steep growth, so many rounds): the
    balance where only new leaves and those whose neighbour split ask again is the
    one where every leaf asks every round, leaf for leaf and in the same order."""
    c = load_contour(SAMPLES / name)
    lo, hi = c.points.min(axis=0), c.points.max(axis=0)
    box = (*(lo - 2.0), *(hi + 2.0))
    s = graded.graded_sizes(c.points, graded.local_sizes(c), 8.0) * 0.3
    nx, ny, top, h0 = graded.root_cells(box[2] - box[0], box[3] - box[1], float(s.min()))
    ii, jj = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    root = graded.Quadtree(
        box[0], box[1], h0, h0, top, nx, ny,
        np.full(nx * ny, top, np.int64), ii.ravel().astype(np.int64), jj.ravel().astype(np.int64),
    )  # fmt: skip
    tree = graded.refine(root, c.points, s, 8.0)
    got, want = graded.balance(tree), _balance_every_leaf_asks(tree)
    assert got.n_leaves > tree.n_leaves
    for f in ("level", "i", "j"):
        assert np.array_equal(getattr(got, f), getattr(want, f))


def _triangulate_reference(self, diagonals):
    """The quadtree's triangulation in numpy: every kind of triangle at once, then
    sorted by leaf (what the compiled loop must give, in the same order)."""
    lay = self.layout()
    n = self.n_leaves
    finer = lay.finer
    side = 2 * (1 << self.level.astype(np.int64))  # (lattice units: half finest cells)
    half = side // 2
    x, y = self.i * side, self.j * side
    corners = np.stack(
        [np.column_stack(c) for c in ((x, y), (x + side, y), (x + side, y + side), (x, y + side))],
        axis=1,
    )
    mids = np.stack(
        [
            np.column_stack(c)
            for c in ((x + half, y), (x + side, y + half), (x + half, y + side), (x, y + half))
        ],
        axis=1,
    )
    centre = np.column_stack([x + half, y + half])
    if diagonals is None:
        diagonals = np.zeros(n, dtype=np.uint8)
    plain = lay.plain
    tris: list[np.ndarray] = []  # (t, 3, 2) lattice coordinates
    cells: list[np.ndarray] = []
    # plain leaves: two triangles along the diagonal
    for d, (a, b) in ((0, ((0, 1, 2), (0, 2, 3))), (1, ((0, 1, 3), (1, 2, 3)))):
        on = np.flatnonzero(plain & (diagonals == d))
        for tri in (a, b):
            tris.append(corners[on][:, list(tri)])
            cells.append(on)
    # fan leaves: per side, one or two triangles to the centre
    fan = np.flatnonzero(~plain)
    for s in range(4):
        a, b = corners[fan, s], corners[fan, (s + 1) % 4]
        c = centre[fan]
        split = finer[fan, s]
        whole = ~split
        tris.append(np.stack([a[whole], b[whole], c[whole]], axis=1))
        cells.append(fan[whole])
        m = mids[fan, s]
        tris.append(np.stack([a[split], m[split], c[split]], axis=1))
        cells.append(fan[split])
        tris.append(np.stack([m[split], b[split], c[split]], axis=1))
        cells.append(fan[split])
    lattice = np.concatenate(tris)
    cell = np.concatenate(cells)
    flat = lattice.reshape(-1, 2)
    keys = flat[:, 0].astype(np.int64) * lay.stride + flat[:, 1]
    ukey, inv = np.unique(keys, return_inverse=True)
    li, lj = ukey // lay.stride, ukey % lay.stride
    points = np.column_stack([self.x0 + li * (self.hx / 2), self.y0 + lj * (self.hy / 2)])
    triangles = inv.reshape(-1, 3).astype(np.int64)
    order = np.argsort(cell, kind="stable")
    return points, triangles[order], cell[order]


def test_the_compiled_triangulation_is_the_numpy_one():
    """Same nodes, triangles and leaves, in the same order, for random diagonals."""
    c = load_contour(SAMPLES / "bracket.svg")
    q = graded.build(c, _box(c))
    rng = np.random.default_rng(2)
    diagonals = rng.integers(0, 2, q.n_leaves).astype(np.uint8)
    got = q.triangulate(diagonals)
    want = _triangulate_reference(q, diagonals)
    assert (~q.layout().plain).sum() > 10
    for g, w in zip(got, want):
        assert np.array_equal(g, w)


@pytest.mark.parametrize("name", ["peanut.csv", "bracket.svg", "naca0012.csv"])
def test_balance_keeps_the_leaves_morton_order_as_a_sort_gives_it(name):
    """The Morton order balance carries from round to round (each split leaf's place
    taken by its four children) is the one sorting the final leaves' codes gives."""
    c = load_contour(SAMPLES / name)
    q = graded.build(c, _box(c))
    kept = q._sorted
    fresh = graded.Quadtree(q.x0, q.y0, q.hx, q.hy, q.top, q.nx, q.ny, q.level, q.i, q.j)
    assert kept is not None
    for a, b in zip(kept, fresh._morton_order()):
        assert np.array_equal(a, b)
