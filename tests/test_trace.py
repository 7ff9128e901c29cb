"""The traced path (select's fallback when Appendix A's choice cannot form a simple path)."""

import itertools
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from deformesh_cli import pipeline
from deformesh_cli.contour import make_contour
from deformesh_cli.errors import FoldError, SelectionError
from deformesh_cli.geometry import signed_area
from deformesh_cli.quality import check_contract
from deformesh_cli.select import Grid, select, trace
from deformesh_cli.select.trace import assign, outline, region_cells, thin_features

from .test_properties import star_polygons


def _is_simple_ccw_cycle(grid, path):
    i, j = grid.node_ij(path)
    di, dj = np.roll(i, -1) - i, np.roll(j, -1) - j
    return (
        len(np.unique(path)) == len(path)
        and np.all(np.abs(di) + np.abs(dj) == 1)
        and signed_area(grid.coords(path)) > 0
    )


def test_region_of_a_diagonal_sliver_is_closed_and_its_outline_simple():
    # a sliver along the diagonal through grid nodes: the cells it crosses
    # touch only at corners until the region closes the pinches
    grid = Grid(0.0, 0.0, 1.0, 1.0, 6, 6)
    q = np.array([(0.5, 0.5), (4.5, 4.5), (4.4, 4.5)])
    cells = region_cells(grid, q)
    assert cells.sum() > 5  # more than the diagonal chain of crossed cells
    path = outline(grid, cells)
    assert _is_simple_ccw_cycle(grid, path)
    assert cells[np.floor(q[:, 1]).astype(int), np.floor(q[:, 0]).astype(int)].all()


def test_outline_of_two_corner_touching_cells_needs_closing():
    grid = Grid(0.0, 0.0, 1.0, 1.0, 4, 4)
    cells = np.zeros((4, 4), dtype=bool)
    cells[1, 1] = cells[2, 2] = True
    with pytest.raises(SelectionError):
        outline(grid, cells)


def _brute_force(P, Q):
    L, m = len(P), len(Q)
    best = np.inf
    for s in range(L):
        for rest in itertools.combinations(range(1, L), m - 1):
            pos = [(s + r) % L for r in (0, *rest)]
            best = min(best, sum(np.sum((P[p] - Q[k]) ** 2) for k, p in enumerate(pos)))
    return best


@settings(max_examples=40, deadline=None)
@given(st.integers(3, 6), st.integers(1, 4), st.integers(0, 2**32 - 1))
def test_assign_is_cyclic_monotone_and_optimal(L, m, seed):
    rng = np.random.default_rng(seed)
    m = min(m, L)
    P, Q = rng.random((L, 2)), rng.random((m, 2))
    pos = assign(P, Q)
    steps = (np.roll(pos, -1) - pos) % L
    assert len(set(pos.tolist())) == m
    assert steps[:-1].min(initial=1) >= 1 and steps.sum() == (L if m > 1 else 0)
    cost = sum(np.sum((P[p] - Q[k]) ** 2) for k, p in enumerate(pos))
    assert cost == pytest.approx(_brute_force(P, Q), rel=1e-12, abs=1e-12)


def test_assign_refuses_more_points_than_nodes():
    with pytest.raises(SelectionError):
        assign(np.zeros((3, 2)), np.zeros((4, 2)))


@pytest.mark.parametrize("h", [0.1, 0.05])
def test_thin_wedge_is_traced_where_appendix_a_fails(h):
    # a sliver much thinner than a cell with its points crowded at the tip
    x = np.array([0.0, 0.3, 0.6, 0.8, 0.9, 0.95, 0.98, 0.995, 1.0])
    top = np.column_stack([x[::-1][1:], 0.002 * (1 - x[::-1][1:])])
    bottom = np.column_stack([x[1:-1], -0.002 * (1 - x[1:-1])])
    pts = np.vstack([[(1.0, 0.0)], top, bottom])
    c = make_contour(pts, source="wedge")
    with pytest.raises(SelectionError):
        select(c, h=h, methods=("greedy",))
    sel = select(c, h=h)
    assert sel.path_rule == "traced"
    d = pipeline.run_deform(c, sel)
    mesh, _ = pipeline.run_triangulate(pipeline.Laid.as_is(c), d)
    check_contract(mesh, c)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(star_polygons(), st.floats(0.01, 0.2))
def test_traced_paths_mesh_with_the_contract(pts, rel_h):
    c = make_contour(pts, source="random")
    size = float(np.ptp(c.points, axis=0).max())
    try:
        sel = select(c, h=rel_h * size, methods=("trace",), max_nodes=60_000)
    except SelectionError as exc:
        assert str(exc).startswith("random: the grid path")
        return
    assert sel.path_rule == "traced"
    path = sel.path_nodes
    assert len(np.unique(path)) == len(path)
    # the uniform grid at a step the user gave may fold; then the refusal says where,
    # on one line, and that a smaller --h helps; otherwise the mesh meets the contract
    try:
        d = pipeline.run_deform(c, sel)
    except FoldError as exc:
        msg = str(exc)
        assert "\n" not in msg and re.search(r"folds? a triangle near \(", msg), msg
        assert "give a smaller --h" in msg, msg
        return
    mesh, _ = pipeline.run_triangulate(pipeline.Laid.as_is(c), d)
    check_contract(mesh, c)


def test_centre_rule_keeps_a_narrow_notch_the_crossed_rule_fills():
    # a square with a V-shaped notch 4 cells wide at the mouth and 7 deep
    grid = Grid(-1.0, -1.0, 1.0, 1.0, 12, 12)
    q = np.array([(0, 0), (3, 0), (5.2, 7), (7, 0), (10, 0), (10, 10), (0, 10)], dtype=float)

    def reach(rule):  # how close the outline comes to the notch's tip
        path = outline(grid, region_cells(grid, q, rule))
        return np.hypot(*(grid.coords(path) - q[2]).T).min()

    assert reach("centres") < 1.5 < 3.5 < reach("crossed")


def test_random_star_polygons_all_mesh_at_the_default_h():
    # measured: 400 of 400 such polygons mesh (395 by Appendix A, 5 traced);
    # before tracing, 5 of them were refused
    rng = np.random.default_rng(1)
    rules = set()
    for _ in range(100):
        n = rng.integers(3, 41)
        gaps = rng.uniform(0.2, 1, n)
        theta = 2 * np.pi * np.cumsum(gaps) / gaps.sum()
        r = rng.uniform(0.4, 1, n)
        c = make_contour(np.column_stack([r * np.cos(theta), r * np.sin(theta)]), source="r")
        sel = select(c, max_nodes=60_000)
        # (the quality stage has tests of its own; here the path, the deformation and
        # the contract)
        d = pipeline.run_deform(c, sel)
        mesh, _ = pipeline.run_triangulate(pipeline.Laid.as_is(c), d, improve=False)
        check_contract(mesh, c)
        rules.add(sel.path_rule)
    assert "traced" in rules


def _side(a, b, n):
    t = np.arange(n)[:, None] / n
    return np.asarray(a, float) + t * (np.subtract(b, a))


def _comb(w, n=3):
    """A 10 x 10 square with an inlet ``w`` wide and 6 deep cut in from below and a
    peninsula ``w`` wide and 5 long on top, ``n`` points on each of their sides."""
    return make_contour(
        np.vstack(
            [
                _side((0, 0), (4, 0), 4),
                _side((4, 0), (4 + w / 2, 6), n),
                _side((4 + w / 2, 6), (4 + w, 0), n),
                _side((4 + w, 0), (10, 0), 6),
                _side((10, 0), (10, 10), 10),
                _side((10, 10), (6 + w, 10), 4),
                _side((6 + w, 10), (6 + w / 2, 15), n),
                _side((6 + w / 2, 15), (6, 10), n),
                _side((6, 10), (0, 10), 6),
                _side((0, 10), (0, 0), 10),
            ]
        ),
        source="comb",
    )


def test_thin_rule_keeps_an_inlet_and_a_peninsula_thinner_than_a_cell():
    c = _comb(0.3)
    grid = Grid(-1.0, -1.0, 1.0, 1.0, 12, 17)
    inlet_tip, peninsula_tip = (4.15, 6.0), (6.15, 15.0)

    def reach(rule, tip):  # how close the outline comes to a tip, in cells
        path = outline(grid, region_cells(grid, c.ccw_points, rule))
        return np.hypot(*(grid.coords(path) - tip).T).min()

    for rule in ("centres", "crossed"):  # both fill the inlet in
        assert reach(rule, inlet_tip) > 4 and reach(rule, peninsula_tip) < 1
    assert reach("thin", inlet_tip) < 1.5 and reach("thin", peninsula_tip) < 1.5
    strips, channels = thin_features(grid, c.ccw_points)
    assert channels[1:6, 5].all() and not channels[:, 6:].any()  # the inlet's column only
    assert strips[11:15, 7].all() and not strips[:10].any()  # the peninsula's only


def test_corners_are_not_thin_features():
    # a square at 1/4-cell spacing: its sides meet at right angles, none faces another
    grid = Grid(-1.0, -1.0, 0.5, 0.5, 8, 8)
    q = np.vstack(
        [
            _side((0, 0), (2, 0), 8),
            _side((2, 0), (2, 2), 8),
            _side((2, 2), (0, 2), 8),
            _side((0, 2), (0, 0), 8),
        ]
    )
    strips, channels = thin_features(grid, q)
    assert not strips.any() and not channels.any()


@pytest.mark.parametrize("w", [0.3, 0.1])
@pytest.mark.parametrize("h", [0.7, 0.35])
def test_comb_is_traced_only_with_the_thin_rule(monkeypatch, w, h):
    c = _comb(w)
    monkeypatch.setattr(trace, "REGION_RULES", ("centres", "crossed"))
    with pytest.raises(SelectionError):
        select(c, h=h, methods=("trace",))
    monkeypatch.undo()
    sel = select(c, h=h, methods=("trace",))
    mesh, _ = pipeline.run_triangulate(pipeline.Laid.as_is(c), pipeline.run_deform(c, sel))
    check_contract(mesh, c)


def test_coast_india_is_traced_at_half_its_median_spacing():
    # real data: the Mumbai harbour inlet and a peninsula near point 1140 are both
    # under a cell wide here; the first two rules fail on every shift (measured)
    from deformesh_cli.readers import load_contour

    from .conftest import ROOT

    c = load_contour(ROOT / "tests" / "data" / "corpus" / "coast_india.csv")
    h = float(np.median(c.edge_lengths())) / 2
    sel = select(c, h=h, methods=("trace",))
    assert sel.path_rule == "traced"
    assert np.isin(np.arange(len(c.points)), sel.path_source).all()
