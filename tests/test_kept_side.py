"""On the graded grid the deformation solves for the domain's side of the path only.

With the path nodes given, a free node on one side never shares a triangle with a
free node on the other, so the kept side's solution is the two-sided one; what
changes is that a fold among the dropped triangles no longer halves the steps or
stops the deformation.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from deformesh_cli import pipeline
from deformesh_cli.contour import make_contour
from deformesh_cli.deform import deform_band
from deformesh_cli.errors import FoldError
from deformesh_cli.geometry import signed_areas
from deformesh_cli.quality import check_contract
from deformesh_cli.readers import load_contour
from deformesh_cli.select.construct import select_constructed

ROOT = Path(__file__).resolve().parent.parent


def _two_ways(sel):
    """The band deformation of ``sel`` on both sides of the path, and on the kept side."""
    g = sel.grid
    args = (g.coords(), sel.triangles(), sel.path_nodes, sel.path_targets, g.boundary_nodes())
    band = sel.band_nodes()
    return args, band


def test_kept_side_solution_is_the_two_sided_one_where_nothing_folds():
    c = load_contour(ROOT / "tests" / "data" / "contours" / "square_hole_100.csv")
    sel = select_constructed(c)
    args, band = _two_ways(sel)
    both, _ = deform_band(*args, band)
    kept = sel.kept_triangles()
    one, _ = deform_band(*args, band, kept=kept)
    tri = sel.triangles()
    on_kept = np.zeros(len(both), dtype=bool)
    on_kept[tri[kept].ravel()] = True
    scale = float(np.abs(args[0]).max())
    assert np.allclose(one[on_kept], both[on_kept], rtol=0, atol=1e-12 * scale)
    # the other side's free nodes stay in place; the two-sided solve moved them
    other = ~on_kept
    assert np.array_equal(one[other], args[0][other])
    assert (both[other] != args[0][other]).any()


def test_a_fold_on_the_dropped_side_does_not_stop_the_deformation():
    # the peanut's loop folds a triangle outside the peanut
    c = load_contour(ROOT / "samples" / "peanut.csv")
    sel = select_constructed(c)
    args, band = _two_ways(sel)
    with pytest.raises(FoldError):
        deform_band(*args, band)
    kept = sel.kept_triangles()
    pos, _ = deform_band(*args, band, kept=kept)
    tri = sel.triangles()
    assert (signed_areas(pos, tri[kept]) > 0).all()
    assert (signed_areas(pos, tri[~kept]) <= 0).any()  # (what stopped the two-sided one)
    res = pipeline.mesh_contour(c)
    assert res.report["h_rule"].startswith("graded")
    check_contract(res.mesh, c)


def test_a_slit_far_narrower_than_any_cell_meshes():
    # 1e-7 wide and 1 deep: the two sides of the slit take distinct nodes, the
    # triangles between them fold outside the square, and the mesh keeps the points
    pts = np.array([(0, 0), (1, 0), (1, 1), (0.5, 1), (0.5, 1e-7), (0.4999999, 1), (0, 1)])
    c = make_contour(pts.astype(float), source="slit")
    res = pipeline.mesh_contour(c)
    check_contract(res.mesh, c)
    assert np.array_equal(res.mesh.points[: c.n], c.points)
    area = signed_areas(res.mesh.points, res.mesh.triangles).sum()
    assert abs(area - c.area) <= 1e-12
