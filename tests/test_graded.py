"""The graded background: a balanced quadtree split into conforming right isosceles
triangles, its cells following the contour's local size."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from deformesh_cli.contour import make_contour
from deformesh_cli.errors import InputError, LimitError, SelectionError
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
def test_graded_sizes_lie_between_the_growth_and_twice_it(n):
    """The growth-limited sizes are at least the exact lower envelope of the cones
    ``s_q' + (growth - 1) |q - q'|`` and at most the same with twice the slope
    (Delaunay paths are at most about twice the straight distance), and never above
    ``s`` itself; the exact envelope is computed here over all pairs."""
    rng = np.random.default_rng(n)
    p = rng.random((n, 2)) * [3.0, 1.0]
    s = 10.0 ** rng.uniform(-3, -0.5, n)
    got = graded.graded_sizes(p, s, 1.5)
    d = np.hypot(*(p[:, None] - p[None]).transpose(2, 0, 1))
    exact = np.min(s[None, :] + 0.5 * d, axis=1)
    assert (got >= exact * (1 - 1e-12)).all()
    assert (got <= np.min(s[None, :] + 1.0 * d, axis=1) * (1 + 1e-12)).all()
    assert (got <= s).all() and (n < 40 or (got < s).any())


def test_graded_sizes_on_one_circle_and_one_line():
    """Points on one circle (Qhull's slow, degenerate case) and points on one line
    (no triangulation at all) both get sizes."""
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
    from deformesh_cli.select.graded_path import select_graded

    c = load_contour(path)
    sel = select_graded(c)
    assert sel.extra_nodes == 0
    assert sorted(sel.path_source.tolist()) == list(range(c.n))
    assert len(np.unique(sel.path_nodes)) == len(sel.path_nodes)  # a node per point
    assert np.array_equal(sel.path_targets, c.points[sel.path_source])
    tri = sel.triangles()
    lo, hi, _, _ = edge_uses(tri, sel.grid.n_nodes)
    edges = set((lo * sel.grid.n_nodes + hi).tolist())
    for r in np.unique(sel.path_ring):
        ring = sel.path_nodes[sel.path_ring == r]
        a, b = np.minimum(ring, np.roll(ring, -1)), np.maximum(ring, np.roll(ring, -1))
        assert all(int(k) in edges for k in a * sel.grid.n_nodes + b)  # steps are edges
    on = np.zeros(sel.grid.n_nodes, dtype=bool)
    on[sel.path_nodes] = True
    assert not (on[tri[:, 0]] & on[tri[:, 1]] & on[tri[:, 2]]).any()
    _check_triangulation(sel.grid.tree, sel.grid.points, tri)


@pytest.mark.parametrize("path", FITTED, ids=lambda p: p.name)
def test_graded_meshes_meet_the_contract_with_no_extra_node(path):
    from deformesh_cli import mesh_contour

    c = load_contour(path)
    res = mesh_contour(c, grid="graded")  # raises unless the contract holds
    uniform = mesh_contour(c, grid="uniform")
    assert res.report["h_rule"] == "graded" and res.report["extra_boundary_nodes"] == 0
    assert res.report["min_angle"] >= 35.0
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
    assert sized.report["size_correlation"] >= 0.9


def test_graded_falls_back_with_a_note():
    """Where no path keeps every edge (here: an airfoil of 80 points whose sharp
    trailing edge asks for cells far smaller than its points are apart) and extra
    nodes are not allowed (``--strict``), 'all' meshes on the other grids and says
    so."""
    from deformesh_cli import mesh_contour

    res = mesh_contour(load_contour(CORPUS / "airfoil_dae11.csv"), grid="graded", strict=True)
    assert not res.report["h_rule"].startswith("graded")
    assert res.report["notes"][0].startswith("the graded grid did not work here")
    assert res.report["extra_boundary_nodes"] == 0


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

    src = contour_file("naca0012_100.csv")  # slid: the state carries path_slide too
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
    assert {"leaf_level.npy", "leaf_i.npy", "leaf_j.npy", "path_slide.npy"} <= set(members)
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
    "path,floor",
    [
        (contour_file("naca0012_100.csv"), 11.7),
        (contour_file("naca0012_1000.csv"), 11.7),
        (SAMPLES / "bracket.svg", 35.0),
    ],  # fmt: skip
    ids=lambda v: getattr(v, "name", str(v)),
)
def test_graded_slides_where_the_spacing_changes_fast(path, floor):
    """Points clustered at an airfoil's ends, or long edges beside short ones: the path is
    fitted to the points evenly re-spaced between corners and the deformation slides
    each node to its point; still no extra node, and no worse angles than the other
    grids give (floor: what the adapted or uniform grid gives)."""
    from deformesh_cli import mesh_contour
    from deformesh_cli.pipeline import fallback_mode

    c = load_contour(path)
    res = mesh_contour(c)
    assert res.report["h_rule"] == "graded-slid"
    assert res.report["extra_boundary_nodes"] == 0
    assert res.report["min_angle"] >= floor
    assert np.array_equal(res.mesh.points[: c.n], c.points)
    assert res.mesh.n_nodes < mesh_contour(c, grid=fallback_mode(c)).mesh.n_nodes


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
    assert rec["extra_boundary_nodes"] == 0 and rec["merged_extra_nodes"] == 0
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


FIT = [
    SAMPLES / "naca0012.csv",
    CORPUS / "airfoil_n0012.csv",
    CORPUS / "airfoil_sc20714.csv",
    CORPUS / "icon_si_apple.svg",
    CORPUS / "icon_bi_cloud-fill.svg",
]


@pytest.mark.parametrize("path", FIT, ids=lambda p: p.name)
def test_graded_fits_the_grid_to_the_points_where_nothing_else_keeps_them(path):
    """Where neither the points as given nor evenly re-spaced find a path (a blunt
    trailing edge, spacing that jumps), the grid is fitted to the number of points and
    the path to the points slid to equal cell steps: no extra node, fewer nodes than
    the adapted or uniform grid, and no smaller angle than theirs less 5 degrees."""
    from deformesh_cli import mesh_contour
    from deformesh_cli.pipeline import fallback_mode

    c = load_contour(path)
    res = mesh_contour(c)
    assert res.report["h_rule"] == "graded-fit"
    assert res.report["extra_boundary_nodes"] == 0
    default = mesh_contour(c, grid=fallback_mode(c), merge_extra="merge")
    assert res.mesh.n_nodes < default.mesh.n_nodes
    assert res.report["min_angle"] >= default.report["min_angle"] - 5.0
    assert np.array_equal(res.mesh.points[: c.n], c.points)


def test_the_fitted_copy_keeps_corners_order_and_equal_cell_steps():
    from deformesh_cli.select import graded_fit

    c = load_contour(SAMPLES / "naca0012.csv")
    lo, hi = c.points.min(axis=0), c.points.max(axis=0)
    box = (lo[0] - 0.3, lo[1] - 0.3, hi[0] + 0.3, hi[1] + 0.3)
    tree = graded.build(c, box, local=graded_fit.initial_sizes(c), roots=graded_fit.ROOTS)
    before = [graded_fit.measure(tree, p, a)[0][-1] / (j - i)
              for _, i, j, p, a in graded_fit.pieces(c)]  # fmt: skip
    tree, rho = graded_fit.fit_tree(c, tree)
    assert min(before) < graded_fit.RHO_LOW  # the fit had work to do
    for (_, _, _, poly, arc), r in zip(graded_fit.pieces(c), rho):
        # every piece reaches the measure, or crosses only the finest cells already
        leaves = graded_fit.measure(tree, poly, arc)[2]
        assert r >= graded_fit.RHO_LOW or (tree.level[leaves] == 0).all()
    assert rho.max() <= 1.1
    rs = graded_fit.copy(c, tree)
    for a, i, j, poly, arc in graded_fit.pieces(c):
        # the piece's ends stay; inside, equal steps of the cell measure, in order
        assert rs.s_copy[a + i] == rs.s_real[a + i]
        mu, sarc, _, _ = graded_fit.measure(tree, poly, arc)
        at = np.interp(rs.s_copy[a + i : a + j], sarc, mu)
        steps = np.diff(np.append(at, mu[-1]))
        assert np.allclose(steps, mu[-1] / (j - i), rtol=1e-6)
    # and every copied point lies on the contour's polyline
    from shapely import LinearRing, distance, points

    ring = LinearRing(c.points)
    assert distance(ring, points(rs.copy.points)).max() < 1e-9


def test_cell_measure_counts_cell_steps():
    from deformesh_cli.select import graded_fit

    square = make_contour(np.array([[0, 0], [4, 0], [4, 4], [0, 4]], dtype=float))
    tree = graded.build(square, (-2, -2, 6, 6), local=np.full(4, 1.0))
    h = float(tree.sizes().max())
    assert np.allclose(tree.sizes(), h)  # one level here
    mu = graded_fit.measure(tree, np.array([[0.1, 0.3], [3.1, 0.3]]), np.array([0.0, 3.0]))[0]
    assert mu[-1] == pytest.approx(3.0 / h)  # along an axis: its length in cells
    diag = np.array([[0.1, 0.3], [2.1, 2.3]])
    mu = graded_fit.measure(tree, diag, np.array([0.0, np.hypot(2, 2)]))[0]
    assert mu[-1] == pytest.approx(2.0 / h)  # a diagonal: one cell per cell crossed


@pytest.mark.parametrize(
    "path,expr,apart",
    [
        (SAMPLES / "peanut.csv", "1 + x**2", True),
        (SAMPLES / "peanut.csv", "0.1 + d", False),
        (SAMPLES / "circle.csv", "0.02 + hypot(x - 0.4, y - 0.2)", True),
    ],
    ids=["peanut-x2", "peanut-d", "circle-point"],
)
def test_a_size_function_grades_the_graded_grid_too(path, expr, apart):
    """The quadtree is refined where f asks for smaller cells, then the deformation
    smooths it: areas follow f.  Where f does not grow with the distance to the contour
    (``apart``), deforming the unrefined graded grid follows it less well."""
    from deformesh_cli import mesh_contour, pipeline

    c = load_contour(path)
    res = mesh_contour(c, grid="graded", size=expr)
    assert res.report["h_rule"].startswith("graded")
    assert res.report["extra_boundary_nodes"] == 0
    assert res.report["size_correlation"] >= 0.9
    assert res.report["min_angle"] >= 35.0
    # the same graded selection without the refinement follows f less well
    plain = next(pipeline.candidate_selections(c, grid="graded"))
    d = pipeline.run_deform(c, plain, size=expr)
    unrefined = pipeline.run_triangulate(c, d, size=expr)[1]["size_correlation"]
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
def test_long_edges_beside_short_ones_mesh_with_their_extra_nodes_merged(name):
    """Contours whose long edges cross several of the cells their short neighbours
    need: no graded path keeps every edge, so the path steps through grid nodes
    there, and stage 3 merges every one of those extra nodes out again.  The mesh is
    a fraction of the adapted grid's, which splits hundreds of edges (measured:
    coast_cuba 4,367 nodes and 275 extra nodes on the adapted grid).  On icon_si_python
    the cavities by its long straight edges need new inner points (:mod:`.cavity`); on
    icon_si_android and icon_bi_bell-fill a step needs more than MAX_HOPS grid edges."""
    from deformesh_cli import mesh_contour

    c = load_contour(CORPUS / name)
    res = mesh_contour(c)
    assert res.report["h_rule"].startswith("graded")
    assert (res.selection.path_source < 0).any()  # the path had extra nodes
    assert res.report["extra_boundary_nodes"] == 0
    assert res.report["merged_extra_nodes"] == res.selection.extra_nodes
    assert np.array_equal(res.mesh.points[: c.n], c.points)
    assert res.mesh.n_nodes < 3 * len(c.points) + 2000


def test_strict_never_gives_extra_nodes_where_they_would_merge():
    """``--strict``: no attempt with extra nodes, even where they would all merge out
    (coast_cuba, above): a mesh keeping every edge as it is, or a refusal."""
    from deformesh_cli import mesh_contour
    from deformesh_cli.errors import DeformeshError

    c = load_contour(CORPUS / "coast_cuba.csv")
    try:
        res = mesh_contour(c, strict=True)
    except DeformeshError as exc:
        assert str(exc).startswith(str(c.source))
        return
    assert res.selection.extra_nodes == 0 and res.report["merged_extra_nodes"] == 0


# --- the path through extra nodes: hop counts, routes, and re-solving a window


def _laid(name="circle.csv"):
    from deformesh_cli.select import graded_path as gp

    c = load_contour(SAMPLES / name)
    prep = gp._prepare(c, None, None, False, graded.DEFAULT_GROWTH, None, False, None, False, None)
    return c, prep, gp


def _bfs(prep, free, s):
    """Grid edges from ``s`` to every node, through free nodes only (a reference)."""
    n = len(prep.grid.points)
    nbr = {}
    for k in prep.edges.tolist():
        u, v = divmod(k, n)
        nbr.setdefault(u, []).append(v)
        nbr.setdefault(v, []).append(u)
    dist, frontier = {s: 0}, [s]
    while frontier:
        nxt = []
        for u in frontier:
            if u != s and not free[u]:
                continue  # reached, but not passed through
            for v in nbr.get(u, []):
                if v not in dist:
                    dist[v] = dist[u] + 1
                    nxt.append(v)
        frontier = nxt
    return dist


def test_pieces_measured_together_measure_as_each_alone():
    """The fitted grid measures all pieces of a contour in flat arrays: each piece's
    sums, arc lengths and leaves are those it has measured on its own."""
    from deformesh_cli.select import graded_fit

    c = load_contour(ROOT / "tests" / "data" / "corpus" / "coast_iceland.csv")
    lo, hi = c.points.min(axis=0), c.points.max(axis=0)
    box = (*(lo - 1.0), *(hi + 1.0))
    tree = graded.build(c, box, local=graded_fit.initial_sizes(c), roots=graded_fit.ROOTS)
    parts = [(p, a) for _, _, _, p, a in graded_fit.pieces(c)]
    assert len(parts) > 50
    together = graded_fit.measure_all(tree, parts)
    for (poly, arc), got in zip(parts, together):
        alone = graded_fit.measure_all(tree, [(poly, arc)])[0]
        assert all(np.array_equal(x, y) for x, y in zip(got, alone))
        assert len(got[0]) == len(got[1]) == len(got[2]) + 1 and got[1][-1] == arc[-1]


def test_hop_counts_are_breadth_first_distances_through_free_nodes():
    c, prep, gp = _laid()
    n = len(prep.grid.points)
    rng = np.random.default_rng(3)
    free = prep.free.copy()
    free[rng.choice(np.flatnonzero(free), size=free.sum() // 6, replace=False)] = False
    cand = rng.choice(np.flatnonzero(free), size=(10, 4), replace=False)
    # neighbours of the first candidates, so that short and long hops both occur
    cand[1::2, 0] = [int(prep.edges[prep.edges // n == x][0] % n) for x in cand[0::2, 0]]
    # and one point whose candidates are all 11 or 12 edges from the one before's
    a = int(cand[2, 0])
    around = _bfs(prep, free, a)
    cand[2] = [a, *[v for v, d in around.items() if d == 1][:3]]
    cand[3] = [v for v, d in around.items() if d in (11, 12)][:4]
    hops = gp._hop_counts(prep.edges, n, free, cand)
    far = 0
    for t in range(len(cand)):
        nxt = cand[(t + 1) % len(cand)]
        d = np.array([[_bfs(prep, free, int(a)).get(int(b), 10**9) for b in nxt] for a in cand[t]])
        d[cand[t][:, None] == nxt[None]] = 10**9
        # up to MAX_HOPS; where no pair is that near, up to FAR_HOPS
        limit = gp.MAX_HOPS if (d <= gp.MAX_HOPS).any() else gp.FAR_HOPS
        far += limit == gp.FAR_HOPS and ((d > gp.MAX_HOPS) & (d <= gp.FAR_HOPS)).any()
        want = np.where((d >= 2) & (d <= limit), d, 0)
        assert np.array_equal(hops[t], want), (t, d)
    assert far  # (the random candidates include points further apart than MAX_HOPS)


def test_a_route_is_shortest_cuts_no_corner_and_avoids_banned_steps():
    c, prep, gp = _laid()
    pts, free = prep.grid.points, prep.free
    g = gp._Graph(prep.edges, prep.plain.turn_keys, pts)
    xy = g.xy
    a = int(np.flatnonzero(free)[len(pts) // 3])
    dist = _bfs(prep, free, a)
    ends = [v for v, d in dist.items() if d == 4 and free[v]][:5]
    assert ends
    for b in ends:
        route = gp._route(a, b, -1, -1, g.neighbours, free, set(), xy, pts[a], pts[b], g.cuts)
        assert route is not None and len(route) == 3
        walk = [a, *route, b]
        for x, y in zip(walk, walk[1:]):
            assert y in g.neighbours[x]
        for x, y, z in zip(walk, walk[1:], walk[2:]):
            assert not g.cuts(x, y, z)
        n = len(pts)
        ban = {min(a, route[0]) * n + max(a, route[0])}
        other = gp._route(a, b, -1, -1, g.neighbours, free, set(), xy, pts[a], pts[b], g.cuts, ban)
        if other is not None:
            assert other[0] != route[0]
        # what a search saw: its route's nodes untaken; a node taken, seen taken
        seen = (set(), set())
        again = gp._route(
            a, b, -1, -1, g.neighbours, free, set(), xy, pts[a], pts[b], g.cuts, limit=4, seen=seen
        )
        assert again == route and set(route) <= seen[0] and not seen[1]
        seen = (set(), set())
        taken = {route[1]}
        other = gp._route(
            a, b, -1, -1, g.neighbours, free, taken, xy, pts[a], pts[b], g.cuts, seen=seen
        )
        assert route[1] in seen[1] and route[1] not in seen[0]
        assert other is None or route[1] not in other


def test_route_searches_kept_between_rounds_give_the_paths_fresh_ones_give(monkeypatch):
    """A ring assigned over many rounds (its routes failing, steps forbidden, the path
    changing) keeps each route search; one is reused only while the nodes it saw are
    as they were, so every attempt lays the same path as with every search fresh."""
    from deformesh_cli.select import graded_path as gp

    c = load_contour(ROOT / "tests" / "data" / "corpus" / "coast_iceland.csv")
    searched = []
    route = gp._route
    monkeypatch.setattr(gp, "_route", lambda *a, **k: searched.append(1) or route(*a, **k))

    def lay(**attempt):
        try:
            s = gp.select_graded(c, cache=cache, extra=True, **attempt)
        except SelectionError as exc:
            return str(exc)
        return s.path_nodes.tolist(), s.path_targets.tolist()

    cache = {}
    kept = [lay(), lay(fit=True)]
    kept_searches = len(searched)
    through = gp._through
    monkeypatch.setattr(gp, "_through", lambda *a: through(*a[:9], {}))  # (nothing kept)
    searched.clear()
    assert [lay(), lay(fit=True)] == kept
    assert kept_searches < len(searched) / 4  # (the fitted grid's many rounds: 5,304 -> 404)


def test_solving_a_window_again_keeps_the_rest_and_finds_a_valid_path():
    from scipy.spatial import cKDTree

    c, prep, gp = _laid("peanut.csv")
    pts, free, n = prep.grid.points, prep.free, len(prep.grid.points)
    idx = np.flatnonzero(free)
    q = prep.contour.points
    dist, near = cKDTree(pts[idx]).query(q, k=gp.CANDIDATES)
    cand = idx[near]
    cost = (dist / prep.local[:, None]) ** 2
    steps = gp._Steps(cand, prep.edges, prep.plain.turn_keys, n)
    pick = gp._viterbi(cand, cost, steps)
    assert pick is not None
    m = len(cand)

    def total(p):
        w = steps.weight
        return sum(cost[t, p[t]] + w[t, p[t - 1], p[t], p[(t + 1) % m]] for t in range(m))

    for t in (5, m // 2, m - 3):
        worse = cost.copy()
        worse[t, pick[t]] = np.inf  # that node is not to be had any more
        got = gp._window(worse, steps, pick, t - 8, t + 8)
        assert got is not None and got[t] != pick[t]
        outside = np.ones(m, dtype=bool)
        outside[np.arange(t - 8, t + 9) % m] = False
        assert np.array_equal(got[outside], pick[outside])
        cost_saved, cost[:] = cost.copy(), worse
        assert np.isfinite(total(got))
        full = gp._viterbi(cand, cost, steps)
        assert total(full) <= total(got) + 1e-9
        cost[:] = cost_saved


def test_a_point_with_no_step_to_the_next_is_refused_before_the_search(monkeypatch):
    # a star icon as given: its tips sit on cells too fine for the long edges beside
    # them, so some points have no candidate next to the next one's
    from deformesh_cli.errors import SelectionError
    from deformesh_cli.select import graded_path as gp

    c = load_contour(CORPUS / "icon_bi_star-fill.svg")
    searched = []
    real = gp._viterbi
    monkeypatch.setattr(gp, "_viterbi", lambda *a: searched.append(1) or real(*a))
    with pytest.raises(SelectionError, match="a neighbour of the next"):
        gp.select_graded(c)
    assert not searched  # (the assignment was not searched for)
    # where every point has a step, the search runs as before
    gp.select_graded(load_contour(SAMPLES / "circle.csv"))
    assert searched


P, S, F, E = (), ("slide",), ("fit",), ("extra",)


@pytest.mark.parametrize(
    "size, want",
    [
        ("small", [P, S, F, E, S + E, F + E]),  # every way, for the best angle
        ("mid", [P, S, E, F, S + E, F + E]),  # the fitted grid, dearest, after extra nodes
        ("large", [P, E, S, F, S + E, F + E]),  # extra nodes on its own grid second
    ],
)
def test_the_order_of_the_graded_ways_by_contour_size(monkeypatch, size, want):
    from deformesh_cli import pipeline
    from deformesh_cli.errors import SelectionError

    tried = []

    def refuse(contour, **kw):
        tried.append(tuple(k for k in ("slide", "fit", "extra") if kw.get(k)))
        raise SelectionError("no path")

    monkeypatch.setattr(pipeline, "select_graded", refuse)
    n = {
        "small": pipeline.EXTRA_WAYS_POINTS,
        "mid": pipeline.LARGE_ORDER_POINTS,
        "large": pipeline.LARGE_ORDER_POINTS + 1,
    }[size]
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    c = make_contour(np.column_stack([np.cos(t), np.sin(t)]), source="circle")
    assert list(pipeline.candidate_selections(c, fall_back=lambda: False)) == []
    assert tried == want


@pytest.mark.parametrize("more", [0, 1])
def test_a_large_contour_mends_a_fold_at_once_a_small_one_after_every_way(monkeypatch, more):
    # the caller lists each selection whose deformation folded: here every one folds
    from types import SimpleNamespace

    from deformesh_cli import pipeline

    def lay(contour, **kw):
        way = tuple(k for k in ("slide", "fit", "extra") if kw.get(k))
        return SimpleNamespace(way=way, extra_nodes=int("extra" in way), notes=[])

    monkeypatch.setattr(pipeline, "select_graded", lay)
    monkeypatch.setattr(pipeline, "_ungraded", lambda *a: iter(()))  # (no fallback grid)
    n = pipeline.EXTRA_WAYS_POINTS + more
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    c = make_contour(np.column_stack([np.cos(t), np.sin(t)]), source="circle")
    folded, got = [], []
    for sel in pipeline.candidate_selections(c, fall_back=lambda: True, mend=folded):
        mending = any(sel is s for s in folded)
        got.append((sel.way, mending))
        if not mending:
            folded.append(sel)
    ways = [tuple(k for k in ("slide", "fit", "extra") if a.get(k)) for a in
            (pipeline.GRADED_ATTEMPTS_FIRST if more else pipeline.GRADED_ATTEMPTS)]  # fmt: skip
    if more:  # each way, then its mend
        assert got == [(w, m) for w in ways for m in (False, True)]
    else:  # every way, then the mends in the same order
        assert got == [(w, False) for w in ways] + [(w, True) for w in ways]
