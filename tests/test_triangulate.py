"""Stage 3: inside/outside by topology (even-odd over the grid paths), checked by geometry."""

import numpy as np
import pytest
import shapely
from hypothesis import given, settings

from deformesh_cli import pipeline, triangulate
from deformesh_cli.contour import make_contour
from deformesh_cli.errors import ContractError, LimitError, SelectionError
from deformesh_cli.readers import load_contour
from deformesh_cli.select import DIAG_BACKSLASH, DIAG_SLASH, Grid

from .conftest import SAMPLES, contour_file
from .test_properties import star_polygons


def _by_shapely(sel, contour, exterior):
    """The reference: shapely on the undeformed centroids against the grid paths."""
    g, tri, gp = sel.grid, sel.triangles(), sel.grid.coords()
    rings = [gp[sel.path_nodes[sel.path_ring == r]] for r in range(contour.n_rings)]
    cen = triangulate._centroids(gp, tri)
    dom = triangulate.domain(rings, g.box if exterior else None)
    return shapely.contains_xy(dom, cen[:, 0], cen[:, 1])


def _by_topology(sel, contour, exterior):
    got = triangulate.topology_inside(
        sel.grid, sel.diagonals, sel.path_nodes, sel.path_ring, contour.n_rings
    )
    return ~got if exterior else got


@pytest.mark.parametrize(
    "path",
    [
        SAMPLES / "peanut.csv",
        SAMPLES / "naca0012.csv",
        contour_file("square_hole_100.csv"),
        contour_file("star_100.csv"),
        contour_file("channel_100.csv"),
    ],
    ids=lambda p: p.stem,
)
@pytest.mark.parametrize("exterior", [False, True])
def test_topology_agrees_with_shapely(path, exterior):
    c = load_contour(path)
    sel = pipeline.run_select(c, exterior=exterior, grid="uniform")  # its topology rule
    got = _by_topology(sel, c, exterior)
    assert got.any() and not got.all()
    assert np.array_equal(got, _by_shapely(sel, c, exterior))


@settings(max_examples=60)
@given(star_polygons())
def test_topology_agrees_with_shapely_on_random_polygons(pts):
    c = make_contour(pts, source="random")
    try:
        sel = pipeline.run_select(c, max_nodes=60_000, grid="uniform")
    except (LimitError, SelectionError):
        return
    assert np.array_equal(_by_topology(sel, c, False), _by_shapely(sel, c, False))


def test_a_mesh_moved_off_its_contour_is_refused():
    c = load_contour(SAMPLES / "peanut.csv")
    sel = pipeline.run_select(c)
    d = pipeline.run_deform(c, sel)
    triangulate.extract(c, sel, d.points)  # as deformed: fine
    shifted = d.points + 3 * sel.h  # every node off by three cells
    with pytest.raises(ContractError, match="inside/outside disagree"):
        triangulate.extract(c, sel, shifted)


def _square_path(grid):
    # the 2x2 block of cells around node (2, 2), walked counter-clockwise
    i = np.array([1, 2, 3, 3, 3, 2, 1, 1])
    j = np.array([1, 1, 1, 2, 3, 3, 3, 2])
    return grid.node_id(i, j)


def test_parity_on_a_hand_made_path():
    g = Grid(0, 0, 1, 1, 4, 4)
    nodes = _square_path(g)
    inside = triangulate.topology_inside(
        g, np.zeros(16, np.uint8), nodes, np.zeros(len(nodes), int), 1
    )
    cells_inside = inside.reshape(-1, 2).all(axis=1)
    want = np.zeros((4, 4), bool)
    want[1:3, 1:3] = True
    assert np.array_equal(cells_inside, want.ravel())
    assert np.array_equal(inside.reshape(-1, 2).any(axis=1), cells_inside)


def test_a_path_that_jumps_or_crosses_a_split_is_refused():
    g = Grid(0, 0, 1, 1, 4, 4)
    jump = g.node_id([1, 3, 3, 1], [1, 1, 3, 3])
    with pytest.raises(SelectionError, match="8-neighbour"):
        triangulate.topology_inside(g, np.zeros(16, np.uint8), jump, np.zeros(4, int), 1)
    # a triangle path (1,1) -> (2,1) -> (2,2) -> back: the diagonal (2,2)-(1,1) lies in
    # cell (1,1), which must then be split '/'
    tri_path = g.node_id([1, 2, 2], [1, 1, 2])
    diag = np.zeros(16, np.uint8)
    diag[1 * 4 + 1] = DIAG_SLASH
    ok = triangulate.topology_inside(g, diag, tri_path, np.zeros(3, int), 1)
    assert ok.sum() == 1 and ok[2 * 5]  # the lower-right triangle of cell 5
    diag[1 * 4 + 1] = DIAG_BACKSLASH
    with pytest.raises(SelectionError, match="crosses its cell.s split"):
        triangulate.topology_inside(g, diag, tri_path, np.zeros(3, int), 1)


@pytest.fixture(scope="module")
def peanut():
    c = load_contour(SAMPLES / "peanut.csv")
    return c, pipeline.mesh_contour(c).mesh


def _with(mesh, **changes):
    from dataclasses import replace

    return replace(mesh, **changes)


def test_the_contract_names_each_broken_clause(peanut):
    from deformesh_cli.quality import check_contract

    c, mesh = peanut
    check_contract(mesh, c)
    pts = mesh.points.copy()
    pts[5] += 1e-9
    with pytest.raises(ContractError, match="node 5 is at"):
        check_contract(_with(mesh, points=pts), c)
    tri = mesh.triangles.copy()
    tri[7] = tri[7, ::-1]
    with pytest.raises(ContractError, match="signed area"):
        check_contract(_with(mesh, triangles=tri), c)
    with pytest.raises(ContractError, match="more than two triangles"):
        check_contract(
            _with(
                mesh, triangles=np.vstack([tri[:7], mesh.triangles[7:], mesh.triangles[100:101]])
            ),
            c,
        )
    # a second triangle on the inner side of boundary edge a -> b: overlap (its third
    # node is not a neighbour of a or b, so its other two edges are new)
    from deformesh_cli.geometry import signed_areas

    a, b = mesh.lines[0]
    t = mesh.triangles
    near = np.unique(t[(t == a).any(axis=1) | (t == b).any(axis=1)])
    cand = np.setdiff1d(np.arange(len(mesh.points)), near)
    left = (
        signed_areas(
            mesh.points, np.column_stack([np.full(len(cand), a), np.full(len(cand), b), cand])
        )
        > 0
    )
    mid = mesh.points[[a, b]].mean(axis=0)
    y = cand[left][np.argmin(np.hypot(*(mesh.points[cand[left]] - mid).T))]
    with pytest.raises(ContractError, match="overlap along the edge"):
        check_contract(_with(mesh, triangles=np.vstack([t, [[a, b, y]]])), c)
    # a hole punched inside: the boundary is no longer the contour
    with pytest.raises(ContractError, match="is not the contour's boundary chain"):
        check_contract(_with(mesh, triangles=np.delete(mesh.triangles, len(tri) // 2, axis=0)), c)
    # a node no triangle uses (a solver's matrix would be singular)
    lone = np.vstack([mesh.points, mesh.points[-1:] + 1e-3])
    with pytest.raises(ContractError, match=f"node {len(pts)} at .* is a corner of no triangle"):
        check_contract(_with(mesh, points=lone), c)
