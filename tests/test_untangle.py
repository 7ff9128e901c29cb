"""Folded triangles of a mesh meshed again (``untangle.py``): afterwards every triangle
is counter-clockwise, the boundary nodes, the boundary edges and the area are as
they were, and where no cavity can be meshed the answer is None, never a mesh."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import Delaunay

from deformesh_cli import mesh_contour
from deformesh_cli.contour import make_contour
from deformesh_cli.geometry import edge_uses, signed_areas
from deformesh_cli.mesh import Mesh
from deformesh_cli.quality import check_contract
from deformesh_cli.readers import load_contour
from deformesh_cli.untangle import untangle

from .conftest import ROOT


def _disc(seed: int, m: int = 24, inner: int = 40) -> tuple[Mesh, np.ndarray]:
    """A Delaunay mesh of ``m`` points on the unit circle (contour nodes 0..m-1) and
    ``inner`` random points inside it; and the contour's points."""
    rng = np.random.default_rng(seed)
    t = 2 * np.pi * np.arange(m) / m
    ring = np.column_stack([np.cos(t), np.sin(t)])
    r = 0.9 * np.sqrt(rng.random(inner))
    a = 2 * np.pi * rng.random(inner)
    pts = np.concatenate([ring, np.column_stack([r * np.cos(a), r * np.sin(a)])])
    tri = Delaunay(pts).simplices.astype(np.int64)
    flip = signed_areas(pts, tri) < 0
    tri[flip] = tri[flip][:, ::-1]
    lines = np.column_stack([np.arange(m), (np.arange(m) + 1) % m])
    return Mesh(pts, tri, lines, n_contour=m, line_group=np.zeros(m, dtype=np.int64)), ring


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 3))
def test_a_tangle_is_mended_into_the_same_domain(seed, moved):
    mesh, ring = _disc(seed)
    rng = np.random.default_rng(seed + 1)
    # move a few inner nodes somewhere else inside: their stars fold
    pts = mesh.points.copy()
    for v in rng.choice(np.arange(len(ring), len(pts)), size=moved, replace=False):
        r, a = 0.85 * np.sqrt(rng.random()), 2 * np.pi * rng.random()
        pts[v] = (r * np.cos(a), r * np.sin(a))
    tangled = Mesh(pts, mesh.triangles, mesh.lines, mesh.n_contour, line_group=mesh.line_group)
    before = signed_areas(pts, mesh.triangles)
    got = untangle(tangled)
    if (before > 0).all():
        assert got is tangled  # nothing folded: the mesh itself
        return
    if got is None:
        return  # (refused: allowed, never a wrong mesh)
    assert (signed_areas(got.points, got.triangles) > 0).all()
    assert np.array_equal(got.points[: len(ring)], ring)
    assert np.array_equal(got.lines, mesh.lines)
    assert abs(signed_areas(got.points, got.triangles).sum() - before.sum()) < 1e-12
    # the contour's edges are used once, every other edge twice, once each way
    lo, hi, fwd, rev = edge_uses(got.triangles, len(got.points))
    assert ((fwd + rev == 2) & (fwd == 1) | (fwd + rev == 1)).all()
    assert (fwd + rev == 1).sum() == len(ring)
    check_contract(got, make_contour(ring, source="disc"))  # (every node in a triangle too)


def test_most_tangles_of_one_node_are_mended():
    mended = tried = 0
    for seed in range(30):
        mesh, ring = _disc(seed)
        pts = mesh.points.copy()
        pts[len(ring)] = -pts[len(ring)]  # an inner node to the other side of the disc
        tangled = Mesh(pts, mesh.triangles, mesh.lines, mesh.n_contour)
        if (signed_areas(pts, mesh.triangles) > 0).all():
            continue
        tried += 1
        mended += untangle(tangled) is not None
    assert tried >= 20 and mended >= 0.9 * tried


def test_a_cavity_that_only_thin_triangles_fill_is_mended():
    """A 100 x 1 rectangle fanned round an inner node, the node carried outside: the
    cavity's only triangulations have a 0.57 degree angle; mended with them (the
    quality stage raises angles afterwards), never refused for being thin."""
    pts = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 1.0], [0.0, 1.0], [150.0, 0.5]])
    tri = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    lines = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])
    got = untangle(Mesh(pts, tri, lines, 4))
    assert got is not None and len(got.triangles) == 2
    area = signed_areas(got.points, got.triangles)
    assert (area > 0).all() and area.sum() == 100.0


def test_a_folded_triangle_of_boundary_nodes_alone_is_refused():
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    clockwise = Mesh(pts, np.array([[0, 2, 1]]), np.array([[0, 2], [2, 1], [1, 0]]), 3)
    assert untangle(clockwise) is None


def test_coast_norways_graded_mesh_is_mended_where_a_tongue_folds_it():
    # its tongue at (6.69, 62.47) is thinner than its cells: the path with extra nodes
    # folds the cells at its tip; mended, the graded mesh has no extra node left and
    # keeps the bound, where the fallback grid's had 18,915 nodes
    c = load_contour(ROOT / "tests" / "data" / "corpus" / "coast_norway.csv")
    res = mesh_contour(c)
    assert res.report["h_rule"].startswith("graded")
    assert res.deform_stats.fold is not None
    assert any("flat triangles of the deformed grid were meshed" in n for n in res.report["notes"])
    assert res.report["extra_boundary_nodes"] == 0 and res.report["nodes"] < 8000


#: A 16-point star from tests/random_polygons (catalogue(400, 400, seed=7), number 120):
#: its deformed grid of 173 triangles folds two, one more than 1% of them.
UNEVEN_STAR = [
    (0.905200888804399, 0.2401240346185177), (0.2898707517579271, 0.07786515937682695),
    (0.7415371071000869, 0.36954247265088463), (0.16959791335128654, 0.164023234999104),
    (0.11760360253774434, 0.7631710944304511), (-0.018542600650738532, 0.421526808205531),
    (-0.10893079273048097, 0.762120912947301), (-0.3469589083862027, 0.33488297897125613),
    (-0.8398889401283276, -0.14967630273001345), (-0.2475273448580518, -0.08125985753381532),
    (-0.7305794844253074, -0.3218253663669595), (-0.5229912786657859, -0.24111037788266218),
    (-0.6068956480737319, -0.5323618882454073), (0.15318289087420833, -0.29904970239310275),
    (0.4003984783410818, -0.6278735178912364), (0.04998536056553185, -0.044117658116182144),
]  # fmt: skip


def test_a_small_mesh_has_as_many_folds_mended_as_it_has_contour_points():
    c = make_contour(np.array(UNEVEN_STAR), source="star")
    res = mesh_contour(c)
    assert res.deform_stats.fold is not None
    assert any("flat triangles of the deformed grid were meshed" in n for n in res.report["notes"])
    check_contract(res.mesh, c)
