"""Property tests over random simple polygons.

Every random polygon either gives a mesh meeting the contract or is refused
with one of the documented errors; and meshing commutes with translation and
scaling by powers of two (the grid is laid relative to the contour).
"""

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from deformesh_cli import mesh_contour
from deformesh_cli.contour import make_contour, signed_area
from deformesh_cli.errors import FoldError, LimitError, SelectionError
from deformesh_cli.quality import check_contract, signed_areas

REFUSALS = (LimitError, SelectionError, FoldError)
MAX_NODES = 60_000  # keeps each example well under a second


@st.composite
def star_polygons(draw):
    """Simple polygons: star-shaped around the origin with random angles and radii."""
    n = draw(st.integers(3, 40))
    gaps = np.array(draw(st.lists(st.floats(0.2, 1.0), min_size=n, max_size=n)))
    theta = 2 * np.pi * np.cumsum(gaps) / gaps.sum()
    r = np.array(draw(st.lists(st.floats(0.4, 1.0), min_size=n, max_size=n)))
    pts = np.column_stack([r * np.cos(theta), r * np.sin(theta)])
    if draw(st.booleans()):
        pts = pts[::-1]  # clockwise input too
    return pts


settings.register_profile("default", max_examples=40, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("default")


@given(star_polygons(), st.floats(-3, 3), st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)))
def test_contract_or_documented_refusal(pts, log_scale, shift):
    pts = pts * 10.0**log_scale + np.array(shift)
    c = make_contour(pts, source="random")
    try:
        res = mesh_contour(c, max_nodes=MAX_NODES)
    except REFUSALS as exc:
        assert str(exc).startswith("random: ") or "fold" in str(exc)
        return
    m = res.mesh
    check_contract(m, c)  # again, explicitly
    assert (signed_areas(m.points, m.triangles) > 0).all()
    assert np.array_equal(m.points[: c.n], c.points)
    assert abs(signed_areas(m.points, m.triangles).sum() - abs(signed_area(c.points))) <= (
        1e-10 * abs(signed_area(c.points)))


@given(star_polygons(), st.integers(-4, 4), st.integers(-50, 50), st.integers(-50, 50))
def test_translation_and_power_of_two_scaling_commute(pts, k, dx, dy):
    base = make_contour(pts, source="a")
    moved = make_contour(pts * 2.0**k + np.array([dx, dy]) * 0.25, source="b")
    try:
        a = mesh_contour(base, max_nodes=MAX_NODES)
    except REFUSALS:
        return
    b = mesh_contour(moved, max_nodes=MAX_NODES)
    assert np.array_equal(a.mesh.triangles, b.mesh.triangles)
    assert np.allclose(a.mesh.points * 2.0**k + np.array([dx, dy]) * 0.25, b.mesh.points,
                       atol=1e-9 * 2.0**k * (1 + abs(dx) + abs(dy)))
