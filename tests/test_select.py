import math

import numpy as np
import pytest

from deformesh_cli import state
from deformesh_cli.contour import make_contour
from deformesh_cli.errors import LimitError, OptionError, SelectionError
from deformesh_cli.geometry import signed_areas
from deformesh_cli.readers import load_contour
from deformesh_cli.select import (
    DIAG_BACKSLASH,
    DIAG_SLASH,
    Grid,
    build_path,
    choose_grid,
    force_diagonals,
    grid_triangles,
    select,
    select_nodes,
)

from .conftest import SAMPLES, contour_file

PAPER_P = [
    (1, 4),
    (1, 3),
    (2, 2),
    (3, 2),
    (4, 2),
    (4, 3),
    (5, 3),
    (6, 4),
    (7, 4),
    (8, 5),
    (7, 6),
    (6, 7),
    (5, 8),
    (4, 8),
    (4, 9),
    (3, 9),
    (2, 10),
    (1, 11),
]


def test_paper_example_selects_exactly_p1_to_p18(run, tmp_path):
    out = tmp_path / "pe.state"
    r = run("select", SAMPLES / "paper_example.csv", "--h", 1, "--box", "1,1,9,12", "-o", out)
    assert r.exit_code == 0, r.stderr
    st = state.loads(out.read_bytes(), str(out), want="selected")
    g = st.selection.grid
    assert (g.x0, g.y0, g.hx, g.hy, g.nx, g.ny) == (1, 1, 1, 1, 8, 11)
    src = st.selection.path_source
    xy = g.coords(st.selection.path_nodes)
    by_point = {int(k): tuple(p) for k, p in zip(src, xy) if k >= 0}
    assert [by_point[k] for k in range(18)] == [tuple(map(float, p)) for p in PAPER_P]
    # and the six vertical-boundary nodes select themselves
    assert [by_point[k] for k in range(18, 24)] == [(1.0, y) for y in range(10, 4, -1)]
    assert st.selection.extra_nodes == 0


def test_default_h_is_appendix_a_rule():
    c = load_contour(contour_file("circle_100.csv"))
    g, info = choose_grid(c)
    d_c = c.min_spacing()[0]
    assert info["h"] == pytest.approx(0.9 * d_c / math.sqrt(2))
    assert max(g.hx, g.hy) <= info["h"] * (1 + 1e-12)  # cells never larger than h
    lo = c.points.min(axis=0)
    assert g.x0 == pytest.approx(lo[0] - 3 * info["h"])  # default margin: 3 cells


def test_box_must_contain_contour_and_be_ordered():
    c = make_contour([(0, 0), (2, 0), (2, 2), (0, 2)])
    with pytest.raises(OptionError, match=r"point 1 .* lies outside --box"):
        choose_grid(c, 0.5, box=(0, 0, 1.5, 3))
    with pytest.raises(OptionError, match="XMIN < XMAX"):
        choose_grid(c, 0.5, box=(3, 0, 0, 3))


def test_grid_limit_refused_with_estimate_and_hint():
    c = load_contour(contour_file("naca0012_1000.csv"))
    with pytest.raises(LimitError) as e:
        choose_grid(c)
    msg = str(e.value)
    assert "3.6e+10 nodes" in msg and "--max-nodes" in msg
    # no uniform grid within the limit can give each crowded point its own node
    assert "try --h" not in msg and "re-space it with --resample SPACING" in msg
    assert "--resample 0.00224" in msg  # its median spacing (that it works: test_contour.py)


def test_a_far_field_refusal_names_a_resample_spacing_that_works(run, tmp_path):
    """On a 20-chord far field the median spacing's uniform grid is too large as well:
    the refusal names the finest spacing the box allows instead, and it meshes."""
    import re

    args = ("all", SAMPLES / "naca0012.csv", "--exterior", "--box=-20,-20,21,20")
    r = run(*args, "--grid", "uniform", "-o", tmp_path / "m.vtk")
    assert r.exit_code == 1 and "re-space it with --resample" in r.stderr
    spacing = re.search(r"e\.g\. --resample ([0-9.e-]+), about the finest", r.stderr).group(1)
    r = run(*args, "--grid", "uniform", "--resample", spacing, "-o", tmp_path / "m.vtk", "-q")
    assert r.exit_code == 0, r.stderr


def test_grid_limit_hint_names_an_h_that_works():
    import re

    c = load_contour(contour_file("circle_100.csv"))
    with pytest.raises(LimitError) as e:
        choose_grid(c, max_nodes=2000)
    h = float(re.search(r"try --h ([0-9.e+-]+) ", str(e.value)).group(1))
    sel = select(c, h=h, max_nodes=2000)
    assert sel.grid.n_nodes <= 2000 and sel.extra_nodes == 0


def test_nearest_free_corner_and_wider_search():
    g = Grid(0, 0, 1, 1, 4, 4)
    # four points in one cell take its four corners, a fifth searches further
    q = np.array([(1.1, 1.1), (1.9, 1.1), (1.9, 1.9), (1.1, 1.9), (1.5, 1.5)])
    nodes, further = select_nodes(g, q)
    assert len(set(nodes.tolist())) == 5
    assert [tuple(g.coords([n])[0]) for n in nodes[:4]] == [(1, 1), (2, 1), (2, 2), (1, 2)]
    assert further == 1


def test_gap_fill_puts_extra_nodes_on_the_contour_edge():
    g = Grid(0, 0, 1, 1, 10, 10)
    q = np.array([(1.0, 1.0), (5.0, 2.0), (5.0, 5.0)])
    sel = g.node_id([1, 5, 5], [1, 2, 5])
    nodes, targets, source = build_path(g, sel, q, np.arange(3))
    ij = np.column_stack(g.node_ij(nodes))
    steps = np.abs(np.diff(np.vstack([ij, ij[:1]]), axis=0)).max(axis=1)
    assert (steps[:-1] == 1).all()  # 8-neighbour steps (the closing edge is left open here)
    extra = source < 0
    assert extra.sum() == 3 + 2 + (4 - 1)
    # extra targets are evenly spaced on their contour edge
    first = targets[1:4]
    assert np.allclose(first, [(2, 1.25), (3, 1.5), (4, 1.75)])


def test_lturn_splits_corner_cell_through_corner_node():
    g = Grid(0, 0, 1, 1, 3, 3)
    # a path round one cell: its four L-turns ask cell (1,1) for both splits
    ring = [(1, 1), (2, 1), (2, 2), (1, 2)]
    diag, bad = force_diagonals(g, g.node_id(*np.array(ring).T))
    assert diag is None and bad is not None
    cell = lambda i, j: j * g.nx + i  # noqa: E731
    path = [(0, 0), (1, 0), (2, 0), (3, 0), (3, 1), (3, 2), (2, 3), (1, 3), (0, 2), (0, 1)]
    nodes = g.node_id(*np.array(path).T)
    diag, bad = force_diagonals(g, nodes)
    assert bad is None
    assert diag[cell(2, 0)] == DIAG_BACKSLASH  # L-turn at (3,0): split through (3,0)
    assert diag[cell(2, 2)] == DIAG_BACKSLASH  # diagonal step (3,2)->(2,3)
    assert diag[cell(0, 1)] == DIAG_SLASH  # diagonal step (1,3)->(0,2) is '/'
    tri = grid_triangles(g, diag)
    assert (signed_areas(g.coords(), tri) > 0).all()
    # at the L-turn (2,0)->(3,0)->(3,1) no triangle has those three path nodes
    lturn = set(g.node_id([2, 3, 3], [0, 0, 1]).tolist())
    assert not any(lturn <= set(t.tolist()) for t in tri)
    # with the default '/' split instead, that triangle would exist
    plain = grid_triangles(g, np.zeros(g.nx * g.ny, np.uint8))
    assert any(lturn <= set(t.tolist()) for t in plain)


def test_crossing_diagonal_steps_are_a_conflict():
    g = Grid(0, 0, 1, 1, 3, 3)
    path = [(0, 0), (1, 1), (1, 0), (0, 1)]  # steps (0,0)->(1,1) and (1,0)->(0,1) cross
    nodes = g.node_id(*np.array(path).T)
    diag, bad = force_diagonals(g, nodes)
    assert diag is None and bad is not None


def test_strict_refuses_extra_nodes():
    c = load_contour(contour_file("circle_100.csv"))
    with pytest.raises(SelectionError, match="--strict"):
        select(c, strict=True)
    # with h near the spacing consecutive nodes are neighbours and strict passes
    spacing = float(np.hypot(*(c.points[1] - c.points[0])))
    sel = select(c, h=spacing, strict=True)
    assert sel.extra_nodes == 0


def test_touching_path_with_given_h_fails_clearly():
    # a slot narrower than h whose sides carry more points than the grid has
    # nodes there: neither Appendix A's choice nor the traced outline fits
    ys = np.arange(3.0, 0.15, -0.1)
    pts = (
        [(0, 0), (3, 0), (3, 3)]
        + [(1.6, y) for y in ys]
        + [(1.6, 0.1), (1.5, 0.1)]
        + [(1.5, y) for y in ys[::-1]]
        + [(0, 3)]
    )
    c = make_contour(np.array(pts), source="slot.csv")
    for h in (0.5, 0.2):
        with pytest.raises(SelectionError) as e:
            select(c, h=h)
        assert str(e.value).startswith("slot.csv: ")
        assert "give a smaller --h" in str(e.value)
    # a grid as fine as the slot follows it
    assert select(c, h=0.1).path_rule == "appendix-a"


def test_grid_triangles_cover_each_cell_by_its_split():
    # against a per-cell construction: two counter-clockwise triangles per cell, meeting
    # on the cell's diagonal, for the whole grid and for a subset of cells in given order
    g = Grid(0, 0, 1, 1, 5, 4)
    rng = np.random.default_rng(2)
    diag = rng.integers(0, 2, g.nx * g.ny).astype(np.uint8)
    want = []
    for c in range(g.nx * g.ny):
        i, j = c % g.nx, c // g.nx
        ids = g.node_id([i, i + 1, i, i + 1], [j, j, j + 1, j + 1])
        n00, n10, n01, n11 = (int(x) for x in ids)
        if diag[c] == DIAG_SLASH:
            want += [(n00, n10, n11), (n00, n11, n01)]
        else:
            want += [(n00, n10, n01), (n10, n11, n01)]
    want = np.array(want)
    assert np.array_equal(grid_triangles(g, diag), want)
    cells = np.array([7, 0, 19, 3])
    assert np.array_equal(
        grid_triangles(g, diag, cells), want.reshape(-1, 2, 3)[cells].reshape(-1, 3)
    )
    assert (signed_areas(g.coords(), want) > 0).all()
