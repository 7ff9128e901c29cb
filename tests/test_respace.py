"""The adapted grid: select on the contour evenly re-spaced between corners,
then slide every node along the contour to its real point."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from deformesh_cli.contour import make_contour
from deformesh_cli.errors import LimitError
from deformesh_cli.pipeline import (
    MIN_ADAPTED_ANGLE,
    candidate_selections,
    fallback_mode,
    grid_mode,
    mesh_contour,
    run_select,
)
from deformesh_cli.quality import check_contract
from deformesh_cli.readers import load_contour
from deformesh_cli.select import respace

from .conftest import ROOT, contour_file

CORPUS = ROOT / "tests" / "data" / "corpus"


def _on_polygon(p, q):
    """Distance from each point of p to the closed polygon q."""
    a, b = q, np.roll(q, -1, axis=0)
    ab = b - a
    t = np.clip(((p[:, None, :] - a) * ab).sum(-1) / (ab * ab).sum(-1), 0, 1)
    return np.hypot(*(a + t[..., None] * ab - p[:, None, :]).transpose(2, 0, 1)).min(axis=1)


def _cosine_airfoil(n=200, clockwise=False):
    th = np.linspace(0, 2 * np.pi, n, endpoint=False)
    x = (1 + np.cos(th)) / 2
    y = (
        0.12
        / 0.2
        * np.sign(np.sin(th))
        * (0.2969 * np.sqrt(x) - 0.126 * x - 0.3516 * x**2 + 0.2843 * x**3 - 0.1036 * x**4)
    )
    p = np.column_stack([x, y])
    return make_contour(p[::-1] if clockwise else p)


def test_naca0012_1000_meshes_with_exactly_its_points_and_no_extra_node():
    c = load_contour(contour_file("naca0012_1000.csv"))
    res = mesh_contour(c, grid="adapt")  # raises unless the contract holds
    r = res.report
    assert r["h_rule"] == "typical-spacing"
    assert r["extra_boundary_nodes"] == 0
    assert len(res.mesh.lines) == 1000  # boundary edges: exactly the contour's
    on = np.unique(res.mesh.lines.ravel())
    assert len(on) == 1000
    np.testing.assert_array_equal(np.sort(res.mesh.points[on], axis=0), np.sort(c.points, axis=0))
    # the grid followed the typical spacing, not the smallest (Appendix A: 3.6e10 nodes)
    assert r["grid_nodes"] < 50_000


@pytest.mark.parametrize("clockwise", [False, True])
def test_copy_lies_on_the_contour_evenly_spaced_between_corners(clockwise):
    c = _cosine_airfoil(clockwise=clockwise)
    rs = respace.respace(c)
    assert rs is not None
    assert _on_polygon(rs.copy.points, c.points).max() < 1e-12
    e_real, e_copy = c.edge_lengths(), rs.copy.edge_lengths()
    assert e_real.max() / e_real.min() > 30
    corners = respace.corners(c.points)
    np.testing.assert_array_equal(rs.copy.points[corners], c.points[corners])
    # between consecutive piece ends the copy's points are an even arc-length split: its
    # chords are the arc step, a little less where the contour bends
    ends = np.union1d([0, c.n], corners)
    for i, j in zip(ends[:-1], ends[1:]):
        step = (rs.s_real[j] if j < c.n else rs.lengths[0]) - rs.s_real[i]
        chords = e_copy[i : j - 1]
        assert np.all(chords <= step / (j - i) * (1 + 1e-9))
        assert np.all(chords >= 0.9 * step / (j - i))
    assert np.all(np.diff(rs.s_copy) > 0) and np.all(np.diff(rs.s_real) > 0)


def test_slide_starts_on_the_copy_and_ends_exactly_on_the_points():
    c = _cosine_airfoil(clockwise=True)
    rs = respace.respace(c)
    sel = next(respace.candidate_selections(c))
    s0, s1 = sel.path_slide.T
    sl = respace.Slide(c, sel.path_ring, s0, s1, sel.path_targets)
    on = sel.path_source >= 0
    np.testing.assert_allclose(sl.at(0.0)[on], rs.copy.points[sel.path_source[on]], atol=1e-12)
    np.testing.assert_array_equal(sl.at(1.0)[on], c.points[sel.path_source[on]])
    # half way, every node is on the contour
    assert _on_polygon(sl.at(0.5), c.points).max() < 1e-12


def _with_hole():
    outer = _cosine_airfoil(n=120, clockwise=True).points * 4
    th = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    th = th + 0.6 * np.sin(th)  # uneven on the hole too
    hole = np.column_stack([1.2 + 0.08 * np.cos(th), 0.08 * np.sin(th)])
    return make_contour(np.vstack([outer, hole]), ring_starts=[0, 120])


@pytest.mark.parametrize("shape", ["airfoil", "with hole"])
def test_extra_nodes_end_on_their_contour_edge(shape):
    c = _cosine_airfoil(n=120, clockwise=True) if shape == "airfoil" else _with_hole()
    sel = run_select(c, h=float(np.median(c.edge_lengths())) / 4, grid="adapt")
    assert sel.path_slide is not None
    extra = np.flatnonzero(sel.path_source < 0)
    assert len(extra) > 10
    for r in range(c.n_rings):  # each extra node lies on an edge of its own ring
        mine = extra[sel.path_ring[extra] == r]
        ring = c.points[c.starts[r] : c.starts[r + 1]]
        assert _on_polygon(sel.path_targets[mine], ring).max() < 1e-12 if len(mine) else True
    res = mesh_contour(c, h=float(np.median(c.edge_lengths())) / 4, grid="adapt")
    check_contract(res.mesh, c)


def test_grid_mode_rules():
    even = make_contour(
        np.column_stack(
            [
                np.cos(np.linspace(0, 6.28, 50, endpoint=False)),
                np.sin(np.linspace(0, 6.28, 50, endpoint=False)),
            ]
        )
    )
    uneven = _cosine_airfoil()
    assert grid_mode(even) == grid_mode(uneven) == "graded"
    assert grid_mode(uneven, exterior=True) == "graded"  # a far field
    assert grid_mode(uneven, h=0.01) == grid_mode(uneven, h=0.01, exterior=True) == "uniform"
    assert grid_mode(even, "adapt") == "adapt"
    # where the graded grid finds no path: the adapted grid for uneven spacing
    assert fallback_mode(even) == "uniform"
    assert fallback_mode(uneven) == "adapt"
    assert fallback_mode(uneven, exterior=True) == "uniform"


def test_when_no_rung_selects_the_uniform_grid_meshes_and_says_so(monkeypatch):
    monkeypatch.setattr(respace, "LADDER", ())  # as if every rung's path touched itself
    c = _cosine_airfoil(n=60)
    res = mesh_contour(c, grid="adapt")
    assert res.report["h_rule"] == "appendix-a"
    assert "fell back to the uniform grid" in res.report["notes"][0]


def test_a_slit_meshes_on_a_rung_or_is_refused_by_the_uniform_grid():
    # a slit 1e-7 wide (the graded grid meshes it: tests/test_kept_side.py): the fallback
    # would be the uniform grid (the median spacing is only twice the smallest), which
    # is out of reach; its refusal names the two close points
    c = make_contour(
        np.array([[0, 0], [1, 0], [1, 1], [0.5, 1], [0.5, 1e-7], [0.4999999, 1], [0, 1]])
    )
    assert fallback_mode(c) == "uniform"
    with pytest.raises(LimitError, match=r"points 3 and 5"):
        mesh_contour(c, grid="uniform", max_nodes=200_000)
    # forced onto the ladder it meshes, with the sliver the 1e-7 gap forces
    res = mesh_contour(c, grid="adapt", max_nodes=200_000)
    assert res.report["h_rule"] == "typical-spacing" and res.report["min_angle"] < 1e-3


def test_a_nearly_flat_rung_gives_way_to_the_next():
    c = load_contour(CORPUS / "icon_si_spotify.svg")  # slid at h: a 3e-10 degree triangle
    first = next(candidate_selections(c, grid="adapt"))
    assert first.path_slide is not None
    # the ladder's rule, without the quality stage
    flat = mesh_contour(c, grid="adapt", max_nodes=400_000, improve=False)
    assert flat.report["min_angle"] >= MIN_ADAPTED_ANGLE
    assert flat.selection.path_slide is None  # a later rung
    from deformesh_cli.pipeline import run_deform, run_triangulate

    d = run_deform(c, first)
    _, report = run_triangulate(c, d, improve=False)
    assert report["min_angle"] < MIN_ADAPTED_ANGLE
    # the quality stage lifts that rung's sliver over the bar, so by default it is kept
    _, report = run_triangulate(c, d)
    assert report["improve"]["min_angle_before"] < MIN_ADAPTED_ANGLE <= report["min_angle"]
    assert mesh_contour(c, grid="adapt", max_nodes=400_000).selection.path_slide is not None


@st.composite
def clustered_rings(draw):
    """Star-shaped rings whose points cluster: angles from a random monotone warp."""
    n = draw(st.integers(12, 80))
    k = draw(st.integers(1, 3))
    amp = draw(st.floats(0.0, 0.35)) / draw(st.floats(1.5, 4.0))
    u = np.arange(n) / n
    # warp' = 1 - c cos(2 pi k u) in [1 - c, 1 + c]: spacing ratios up to 99
    warp = u - np.sin(2 * np.pi * k * u) / (2 * np.pi * k) * draw(st.floats(0.5, 0.98))
    th = 2 * np.pi * warp
    th = np.sort(np.mod(th + 0.1, 2 * np.pi))
    if np.min(np.diff(np.r_[th, th[0] + 2 * np.pi])) < 1e-4:
        th = 2 * np.pi * u
    r = 1 + amp * np.cos(draw(st.integers(2, 6)) * th) ** 2 * np.sign(np.cos(th))
    return np.column_stack([r * np.cos(th), r * np.sin(th)])


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(clustered_rings())
def test_adapted_grid_meets_the_contract_on_clustered_rings(pts):
    c = make_contour(pts)
    res = mesh_contour(c, grid="adapt", max_nodes=400_000)  # raises on any contract breach
    assert res.report["h_rule"] == "typical-spacing"  # a rung of the ladder, not the fallback
    on = np.unique(res.mesh.lines.ravel())
    assert len(on) == c.n + res.report["extra_boundary_nodes"]
