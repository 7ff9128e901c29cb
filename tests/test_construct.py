"""The constructed graded selection (``select/construct.py``) and boundary recovery
(``recover.py``): what each guarantees so far.  The pipeline does not use them yet."""

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from deformesh_cli import pipeline
from deformesh_cli.contour import make_contour
from deformesh_cli.geometry import signed_areas
from deformesh_cli.mesh import Mesh
from deformesh_cli.readers import load_contour
from deformesh_cli.recover import recover
from deformesh_cli.select import construct

from .conftest import ROOT, SAMPLES
from .random_polygons import comb, fingers, spikes, uneven_star, valid

CORPUS = ROOT / "tests" / "data" / "corpus"


def _square_with_extra_nodes(lift: float) -> Mesh:
    """The unit square, contour points 0-3, extra nodes 4 and 5 at x = 1/3 and 2/3 on
    the bottom edge, interior nodes 6 and 7 above them at ``lift``."""
    pts = np.array(
        [[0, 0], [1, 0], [1, 1], [0, 1], [1 / 3, 0], [2 / 3, 0], [1 / 3, lift], [2 / 3, lift]]
    )
    tri = np.array(
        [[0, 4, 6], [4, 5, 6], [5, 7, 6], [5, 1, 7], [1, 2, 7], [2, 3, 6], [2, 6, 7], [3, 0, 6]]
    )
    lines = np.array([[0, 4], [4, 5], [5, 1], [1, 2], [2, 3], [3, 0]])
    return Mesh(pts, tri, lines, n_contour=4, n_extra=2)


@pytest.mark.parametrize("lift, nodes", [(0.5, 6), (0.01, 4)])
def test_recover_takes_every_extra_node_out(lift, nodes):
    """However close the inner nodes hug the edge, every extra node goes: the boundary
    is the contour's four edges, every triangle counter-clockwise, the area kept.  The
    inner nodes in the edge's diametral disk go with them (at 0.01), the others stay
    (at 0.5, 0.53 from the edge's middle)."""
    before = _square_with_extra_nodes(lift)
    mesh, taken = recover(before)
    assert taken == 2 and mesh.n_extra == 0 and len(mesh.points) == nodes
    assert sorted(map(tuple, mesh.lines.tolist())) == [(0, 1), (1, 2), (2, 3), (3, 0)]
    assert (signed_areas(mesh.points, mesh.triangles) > 0).all()
    assert signed_areas(mesh.points, mesh.triangles).sum() == pytest.approx(1.0)
    assert np.array_equal(mesh.points[:4], before.points[:4])


def test_clearance_is_measured_across_a_thin_part_only():
    """A strip 10 x 1 drawn by its corners: samples along the long edges ask for cells
    of about half the strip's width; a smooth circle's samples ask for nothing below
    its points' spacing (the next edges are the same part of the contour)."""
    strip = make_contour(np.array([[0, 0], [10, 0], [10, 1], [0, 1]], float), source="strip")
    xy, size, s, edge = construct.feature_samples(strip)
    assert np.allclose(s, 1.0)
    along = edge[4:]
    assert (np.isin(along, [0, 2])).sum() >= 16  # the long edges are sampled
    assert size[4:][np.isin(along, [0, 2])].max() <= 0.5 * 1.0 + 1e-12
    t = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    circle = make_contour(np.column_stack([np.cos(t), np.sin(t)]), source="circle")
    xy, size, s, edge = construct.feature_samples(circle)
    spacing = 2 * np.sin(np.pi / 200)
    assert np.allclose(s, spacing) and size.min() >= spacing * (1 - 1e-9)


@pytest.mark.parametrize(
    "path",
    [SAMPLES / "peanut.csv", SAMPLES / "naca0012.csv", CORPUS / "icon_si_python.svg"],
    ids=lambda p: p.name,
)
def test_constructed_meshes_keep_exactly_the_contour_points(path):
    """Selection, deformation keeping folds for the mend, recovery, quality stage: the
    boundary nodes are exactly the contour's points (two outer rings with holes
    included), and the contract holds."""
    c = load_contour(path)
    got = pipeline.mesh_contour(c)  # (it checks the contract)
    sel, mesh = got.selection, got.mesh
    assert sel.extra_nodes > 0  # (the loop's nodes between points: all taken out)
    assert mesh.n_extra == 0 and np.array_equal(mesh.points[: c.n], c.points)
    assert len(np.unique(mesh.lines)) == c.n


def test_a_rectangle_by_its_corners_is_constructed():
    c = make_contour(np.array([[0, 0], [10, 0], [10, 1], [0, 1]], float), source="rect")
    mesh = pipeline.mesh_contour(c).mesh
    assert mesh.n_extra == 0 and len(mesh.lines) == 4


def _pocket(z: list[float] | None = None) -> Mesh:
    """The triangle a (0, 0), b (4, 0), v (2, 6), area 12, with extra nodes c1 c2 c3 on
    a-b and inner nodes w1 w2 (outside the diametral disk of a b) whose triangle
    w1 w2 v touches no extra node: the triangles touching the extra nodes surround
    it.  With ``z``, an inner node under w1 w2, between them and the run."""
    pts = [[0, 0], [4, 0], [2, 6], [1, 0], [2, 0], [3, 0], [1.4, 2.2], [2.6, 2.2]]
    A, B, V, C1, C2, C3, W1, W2, Z = range(9)
    if z is None:
        middle = [[C1, C2, W1], [C2, W2, W1], [C2, C3, W2]]
    else:
        pts.append(z)
        middle = [[C1, C2, Z], [C1, Z, W1], [C2, C3, Z], [Z, C3, W2], [Z, W2, W1]]
    tri = np.array([[A, C1, V], [C1, W1, V], *middle, [W1, W2, V], [W2, C3, V], [C3, B, V]])
    lines = np.array([[A, C1], [C1, C2], [C2, C3], [C3, B], [B, V], [V, A]])
    pts = np.array(pts, dtype=float)
    assert (signed_areas(pts, tri) > 0).all() and signed_areas(pts, tri).sum() == 12.0
    return Mesh(pts, tri, lines, n_contour=3, n_extra=3)


def _recovered_pocket(mesh: Mesh, taken: int) -> None:
    assert taken == 3 and mesh.n_extra == 0
    assert sorted(map(tuple, mesh.lines.tolist())) == [(0, 1), (1, 2), (2, 0)]
    assert (signed_areas(mesh.points, mesh.triangles) > 0).all()
    assert signed_areas(mesh.points, mesh.triangles).sum() == pytest.approx(12.0)


def test_recover_halves_a_run_whose_cavity_touches_itself():
    """The triangles touching the extra nodes surround one that does not (w1 w2 v, its
    corners outside the disk of a b, so the cavity does not grow to it): their
    outline meets itself at v, the run is taken out in halves, and every extra node
    still goes; w1 and w2 stay."""
    mesh, taken = recover(_pocket())
    _recovered_pocket(mesh, taken)
    assert len(mesh.points) == 5


def test_recover_takes_a_long_run_in_one_cavity():
    """A strip 100 x 1 whose bottom edge carries 999 extra nodes under a row of inner
    nodes: all go in one cavity, and the row with them where it lies in the edge's
    diametral disk (where a node sees the edge under more than a right angle): all
    but its two end nodes, over the strip's short sides, just outside the disk."""
    k = 1000
    x = np.linspace(0, 100, k + 1)
    bottom = np.column_stack([x, np.zeros_like(x)])
    top = np.column_stack([x, np.full_like(x, 0.5)])
    pts = np.vstack([[[0, 0], [100, 0], [100, 1], [0, 1]], bottom[1:-1], top])
    extra = np.arange(4, 4 + k - 1)
    row = np.arange(4 + k - 1, 4 + k - 1 + k + 1)
    chain = np.concatenate([[0], extra, [1]])
    lower = np.column_stack([chain[:-1], chain[1:], row[1:]])
    lower2 = np.column_stack([chain[:-1], row[1:], row[:-1]])
    upper = [[row[-1], 2, 3]] + [[row[i], row[i + 1], 3] for i in range(k)]
    tri = np.vstack([lower, lower2, upper])
    lines = np.vstack([np.column_stack([chain[:-1], chain[1:]]), [[1, 2], [2, 3], [3, 0]]])
    before = Mesh(pts, tri, lines, n_contour=4, n_extra=k - 1)
    assert (signed_areas(before.points, before.triangles) > 0).all()
    mesh, taken = recover(before)
    assert taken == k - 1 and mesh.n_extra == 0 and len(mesh.points) == 6
    assert (signed_areas(mesh.points, mesh.triangles) > 0).all()
    assert signed_areas(mesh.points, mesh.triangles).sum() == pytest.approx(100.0)


def _star_polygon(rng, k):
    t = np.sort(rng.uniform(0, 2 * np.pi, k))
    r = rng.uniform(0.2, 1.0, k)
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


@pytest.mark.parametrize("seed", range(20))
def test_delaunay_polygon_has_the_largest_smallest_angle(seed):
    """The constrained Delaunay triangulation of a polygon's vertices has the largest
    smallest angle of all its triangulations: it matches the dynamic programme over
    every chord, on random star-shaped polygons."""
    from deformesh_cli._recover import polygon_cdt as delaunay_polygon
    from deformesh_cli.cavity import best_triangulation
    from deformesh_cli.quality import measures

    rng = np.random.default_rng(seed)
    p = _star_polygon(rng, int(rng.integers(4, 30)))
    tri = delaunay_polygon(p)
    assert tri is not None and len(tri) == len(p) - 2
    assert (signed_areas(p, tri) > 0).all()
    assert signed_areas(p, tri).sum() == pytest.approx(_area(p))
    best = best_triangulation(p)
    assert measures(p, tri)[0].min() == pytest.approx(best[1], abs=1e-7)


def _area(p):
    x, y = p.T
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def test_a_needle_is_one_ear_triangle():
    """A square with a needle 2 long and 0.04 wide at its base: the needle's tip
    (1.1 degrees, its base the ear's shortest side, nothing inside) is cut off
    before the grid is laid and comes back as the one triangle any mesh of these
    points has there; the contract holds on the whole contour."""
    pts = np.array([[0, 0], [1, 0], [1, 1], [0.52, 1], [0.5, 3], [0.48, 1], [0, 1]], float)
    c = make_contour(pts, source="needle")
    grid_contour, kept, ears = construct.cut_ears(c)
    assert ears.tolist() == [[3, 4, 5]] and kept.tolist() == [0, 1, 2, 3, 5, 6]
    assert grid_contour.n == 6
    mesh = pipeline.mesh_contour(c).mesh  # (it checks the contract)
    assert np.array_equal(mesh.points[: c.n], c.points)
    assert sorted(map(tuple, mesh.lines.tolist())) == [(k, (k + 1) % 7) for k in range(7)]
    assert (np.sort(mesh.triangles, axis=1) == [3, 4, 5]).all(axis=1).any()


def test_no_cut_where_no_corner_is_sharp():
    c = make_contour(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float), source="square")
    grid_contour, kept, ears = construct.cut_ears(c)
    assert len(ears) == 0 and grid_contour is c


@pytest.mark.parametrize(
    "pts",
    [
        [[0, 0], [10, 0], [0.1, 0.2]],  # a triangle keeps its three points
        # the sharp corner's ear holds a hole
        [[0, 0], [2, 0.05], [0, 0.1], [-0.1, 0.1], [-0.1, 0], [1, 0.045], [1, 0.055], [1.1, 0.05]],
    ],
)
def test_a_sharp_corner_whose_ear_stays_has_its_tip_cut(pts):
    """Where a ring would drop under three points, or another point lies in the ear,
    the sharp corner's tip is cut instead: two points on its sides, a third of its
    reach (its shorter side, its distance to the rest) from it; they come back as
    extra boundary nodes, which the mesh takes out."""
    pts = np.array(pts, float)
    starts = [0, 5] if len(pts) == 8 else None
    c = make_contour(pts, source="x", ring_starts=starts)
    grid_contour, kept, ears = construct.cut_ears(c)
    assert len(ears) == 1
    a, tip, b = ears[0]
    assert tip == 1 and a >= c.n and b >= c.n  # (the two added points)
    assert grid_contour.n == c.n + 1
    xa, xb = grid_contour.points[kept == a][0], grid_contour.points[kept == b][0]
    p = c.points
    rest = [np.linalg.norm(p[1] - p[0]), np.linalg.norm(p[1] - p[2])]
    if len(pts) == 8:  # (the hole's nearest point)
        rest.append(np.linalg.norm(p[1] - p[7]))
    d = min(rest) / 3
    assert np.linalg.norm(xa - p[1]) == pytest.approx(d)
    assert np.linalg.norm(xb - p[1]) == pytest.approx(d)
    assert _area(np.array([xa, p[1], xb])) > 0  # (counter-clockwise, in the domain)
    res = pipeline.mesh_contour(c)  # (it checks the contract)
    assert np.array_equal(res.mesh.points[: c.n], c.points)
    assert res.mesh.n_extra == 0 and res.report["extra_boundary_nodes"] == 0


def test_an_ear_within_a_third_of_its_bound_is_cut():
    """A spike whose sides differ (2 and 1.4): the ear's angle at its short side's end
    is 0.43 of the tip's, under half but over a third of the bound its tip and sides
    force there, so it is cut; the contract holds on the whole contour."""
    pts = np.array([[0, 0], [1, 0], [1, 1], [3, 1.06], [2.4, 1.08], [0, 1.2]], float)
    c = make_contour(pts, source="spike")
    grid_contour, kept, ears = construct.cut_ears(c)
    assert ears[0].tolist() == [2, 3, 4]
    tip = construct._angle_between(pts[2] - pts[3], pts[4] - pts[3])
    at_a = construct._angle_between(pts[3] - pts[2], pts[4] - pts[2])
    assert tip / 3 <= at_a < tip / 2
    mesh = pipeline.mesh_contour(c).mesh  # (it checks the contract)
    assert np.array_equal(mesh.points[: c.n], c.points)


def test_recover_clears_the_disk_one_star_at_a_time():
    """As above, with an inner node z in the disk of a b under the run: the cavity grown
    by z's star still surrounds w1 w2 v, so the run goes by its own triangles in
    halves, and then z, the apex on a b in its disk, goes by its star: no inner node
    is left in the disk."""
    mesh, taken = recover(_pocket(z=[2, 0.5]))
    _recovered_pocket(mesh, taken)
    inner = mesh.points[3:]
    assert len(inner) == 2 and (np.hypot(*(inner - [2, 0]).T) > 2).all()  # (w1, w2)


def _rounded_rectangle(w: float, h: float, r: float, per_corner: int) -> np.ndarray:
    """A ``w`` by ``h`` rectangle with corners rounded by ``r``, each corner
    ``per_corner`` points: long straight sides between closely spaced fillets (an icon's
    outline)."""
    out = []
    for cx, cy, a0 in ((w - r, r, -90), (w - r, h - r, 0), (r, h - r, 90), (r, r, 180)):
        a = np.radians(a0 + np.linspace(0, 90, per_corner))
        out.append(np.column_stack([cx + r * np.cos(a), cy + r * np.sin(a)]))
    return np.vstack(out)


@pytest.mark.parametrize(
    "w, h, r, k", [(400, 300, 20, 10), (250, 250, 3, 8), (300, 500, 4, 7), (800, 300, 15, 9)]
)
def test_long_sides_whose_cells_reach_the_box_still_mesh(w, h, r, k):
    """Along a long straight side the cells grow from its ends (nothing there asks for
    small ones) to wider than the margin the points' sizes give the box, so the
    domain's loop runs along the box's side.  The domain's side is bounded by its loops
    alone, whose nodes all go to contour points: such a loop node is a path node like
    any other, and the mesh is made, strict."""
    c = make_contour(_rounded_rectangle(w, h, r, k), None, "rounded.csv")
    sel = pipeline.run_select(c, pipeline.MeshOptions())
    on_box = np.intersect1d(sel.grid.boundary_nodes(), sel.path_nodes)
    assert len(on_box) > 0  # (the case this test is about)
    res = pipeline.mesh_contour(c, strict=True)
    m = res.mesh
    assert res.report["contract"] == "ok"
    assert np.array_equal(m.points[: c.n], c.points)
    assert (signed_areas(m.points, m.triangles) > 0).all()


def test_thin_fingers_are_meshed_from_their_own_points():
    """A finger far thinner than it is long forces a sliver on its sides in every mesh of
    these points (forced bound under construct.THIN_ANGLE): its ears are cut before the
    grid is laid, so the grid follows the base and the points, not the fingers' width
    along their length: ten times thinner fingers cost a few more cells where they meet
    the base (the grid grades down to their width there), not ten times the cells (five
    fingers 0.001 wide took minutes before)."""
    nodes = []
    for width in (1e-3, 1e-4, 1e-5, 1e-6):
        c = make_contour(fingers(width, 10.0), None, "fingers.csv")
        res = pipeline.mesh_contour(c, strict=True)
        m = res.mesh
        assert res.report["contract"] == "ok" and res.report["ears"] >= 10
        assert np.array_equal(m.points[: c.n], c.points)
        assert (signed_areas(m.points, m.triangles) > 0).all()
        nodes.append(res.report["grid_nodes"])
    assert all(b < 2 * a for a, b in zip(nodes, nodes[1:])), nodes


def test_a_side_forced_no_thinner_than_the_thin_angle_keeps_the_grid():
    """A rectangle 1 x 0.02 (its long sides forced to about 2.3 degrees) is laid on the
    grid as before: only sides forced under the thin angle have their ears cut."""
    c = make_contour(np.array([[0, 0], [1, 0], [1, 0.02], [0, 0.02]]), None, "r.csv")
    res = pipeline.mesh_contour(c)
    assert res.report["ears"] == 0 and res.report["contract"] == "ok"


@pytest.mark.parametrize("width", [1e-5, 1e-6, 1e-7])
def test_a_thin_rectangle_is_its_own_two_triangles(run, tmp_path, width):
    """A rectangle 1 long and far thinner: one ear is cut as a thin part's end, and the
    triangle left is meshed as itself (construct.own_triangles), not laid on a grid that
    would resolve its width along its length; the stages give all's bytes."""
    pts = np.array([[0, 0], [1, 0], [1, width], [0, width]])
    c = make_contour(pts, None, "thin.csv")
    res = pipeline.mesh_contour(c, strict=True)
    m = res.mesh
    assert res.report["contract"] == "ok" and len(m.triangles) == 2
    assert res.report["path_rule"] == construct.OWN_TRIANGLES and res.report["grid_nodes"] == 4
    assert np.array_equal(m.points, pts) and (signed_areas(m.points, m.triangles) > 0).all()
    src = tmp_path / "thin.csv"
    np.savetxt(src, pts, delimiter=",")
    state = tmp_path / "s.npz"
    assert run("select", src, "-o", tmp_path / "a.state", "-q").exit_code == 0
    assert run("deform", tmp_path / "a.state", "-o", state, "-q").exit_code == 0
    assert run("triangulate", state, "-o", tmp_path / "p.vtk", "-q").exit_code == 0
    assert run("all", src, "-o", tmp_path / "a.vtk", "-q").exit_code == 0
    assert (tmp_path / "p.vtk").read_bytes() == (tmp_path / "a.vtk").read_bytes()


def test_several_thin_parts_are_each_their_own_triangles():
    """Two thin triangles and a thin rectangle, apart: each is meshed as itself."""
    rings = [
        [[0, 0], [1, 0], [0, 1e-4]],
        [[2, 0], [3, 0], [3, 1e-6], [2, 1e-6]],
        [[0, 1], [0.5, 1.00001], [0, 1.00002]],
    ]
    starts = np.cumsum([0] + [len(r) for r in rings])[:-1]
    c = make_contour(np.concatenate(rings), None, "parts.csv", ring_starts=starts)
    res = pipeline.mesh_contour(c, strict=True)
    assert res.report["contract"] == "ok" and len(res.mesh.triangles) == 4
    assert res.report["path_rule"] == construct.OWN_TRIANGLES


def test_a_fat_triangle_keeps_the_grid():
    """A triangle with no side forced under the thin angle is meshed on the grid."""
    c = make_contour(np.array([[0, 0], [1, 0], [0.4, 0.5]]), None, "t.csv")
    res = pipeline.mesh_contour(c)
    assert res.report["path_rule"] != construct.OWN_TRIANGLES
    assert len(res.mesh.triangles) >= 1 and res.report["contract"] == "ok"


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.floats(-7.0, -3.5),  # log10 of the width
    st.floats(0.5, 20.0),  # length
    st.floats(0.0, 3.14159),  # turn
    st.integers(1, 6),  # fingers
)
def test_random_thin_parts_mesh_from_their_own_points(log_width, length, turn, count):
    """Rectangles and combs of fingers far thinner than they are long, turned any way:
    each meshes with the contract, and its grid follows the points (a few thousand nodes
    at most), never the inverse width."""
    width = 10.0**log_width
    c, s = np.cos(turn), np.sin(turn)
    rot = np.array([[c, -s], [s, c]])
    for pts in (np.array([[0, 0], [length, 0], [length, width], [0, width]]),
                fingers(width, length, n=count)):  # fmt: skip
        contour = make_contour(pts @ rot.T, None, "thin.csv")
        res = pipeline.mesh_contour(contour, strict=True)
        m = res.mesh
        assert res.report["contract"] == "ok"
        assert np.array_equal(m.points[: contour.n], contour.points)
        assert (signed_areas(m.points, m.triangles) > 0).all()
        assert res.report["grid_nodes"] < 20_000, res.report["grid_nodes"]


@settings(max_examples=30, deadline=None, derandomize=True)
@given(st.integers(0, 2**32 - 1))
def test_the_ear_prefilter_leaves_out_no_ear(seed):
    """cut_ears tests only the points _maybe_ears lets through: the same ears and kept
    points as testing every point, on polygons with spikes, combs and uneven stars."""
    rng = np.random.default_rng(seed)
    make = [spikes, comb, uneven_star][seed % 3]
    points, ring = make(rng, int(rng.integers(8, 120)))
    assert (ring == 0).all()
    assume(valid(points, ring))
    c = make_contour(points, source="random")  # (one ring each)
    filtered = construct.cut_ears(c)
    prefilter = construct._maybe_ears
    try:
        construct._maybe_ears = lambda p, prv, nxt: np.arange(len(p))
        every = construct.cut_ears(c)
    finally:
        construct._maybe_ears = prefilter
    assert np.array_equal(every[1], filtered[1]) and np.array_equal(every[2], filtered[2])


def test_the_grid_contour_names_the_given_points():
    """With an ear cut, the grid's contour has fewer points; its messages still name each
    point by its index in the given contour (a refusal points at the user's point)."""
    pts = np.array([[0, 0], [1, 0], [1, 1], [0.52, 1.0], [0.5, 3.0], [0.48, 1.0], [0, 1]])
    c = make_contour(pts.astype(float), None, "spike.csv")
    grid, kept, ears = construct.cut_ears(c)
    assert ears.tolist() == [[3, 4, 5]] and grid.n == 6
    assert grid.where(4) == c.where(5) and grid.where(5) == c.where(6)
