"""Extra boundary nodes taken out of finished meshes (``merge.py``): the domain, the
contour nodes and the contract are unchanged, only the extra nodes and their
triangles go, and a run is kept where no fair triangulation exists."""

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from deformesh_cli import mesh_contour
from deformesh_cli.contour import make_contour
from deformesh_cli.errors import FoldError, LimitError, SelectionError
from deformesh_cli.geometry import signed_area, signed_areas
from deformesh_cli.merge import MIN_ANGLE, merge_extra_nodes
from deformesh_cli.mesh import Mesh
from deformesh_cli.quality import check_contract, measures

from .conftest import ROOT, SAMPLES
from .test_properties import MAX_NODES, star_polygons

CORPUS = ROOT / "tests" / "data" / "corpus"


def _square_with_extra(lift: float) -> Mesh:
    """The unit square, contour points 0-3, an extra node 4 at (0.5, 0) on the bottom
    edge and an interior node 5 at (0.5, lift)."""
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0], [0.5, lift]], dtype=float)
    tri = np.array([[0, 4, 5], [4, 1, 5], [1, 2, 5], [2, 3, 5], [3, 0, 5]])
    lines = np.array([[0, 4], [4, 1], [1, 2], [2, 3], [3, 0]])
    return Mesh(pts, tri, lines, n_contour=4, n_extra=1, line_group=np.array([0, 0, 1, 1, 1]),
                groups=("bottom", "rest"))  # fmt: skip


def test_an_extra_node_is_taken_out_and_the_boundary_joined():
    mesh, done = merge_extra_nodes(_square_with_extra(0.5))
    assert (done.merged, done.left) == (1, 0)
    assert mesh.n_extra == 0 and len(mesh.points) == 5
    assert np.array_equal(mesh.points[:4], _square_with_extra(0.5).points[:4])
    assert sorted(map(tuple, mesh.lines.tolist())) == [(0, 1), (1, 2), (2, 3), (3, 0)]
    by_line = dict(zip(map(tuple, mesh.lines.tolist()), mesh.line_group.tolist()))
    assert by_line[(0, 1)] == 0 and by_line[(1, 2)] == 1  # the groups stay
    assert (signed_areas(mesh.points, mesh.triangles) > 0).all()
    assert signed_areas(mesh.points, mesh.triangles).sum() == pytest.approx(1.0)
    assert len(mesh.triangles) == 4


def test_a_run_without_a_fair_triangulation_stays(monkeypatch):
    # the interior node hugs the edge: every triangulation without node 4 has a sliver
    import deformesh_cli.merge as merge

    monkeypatch.setattr(merge, "GROW", 0)
    before = _square_with_extra(0.01)
    mesh, done = merge_extra_nodes(before, fill=False)
    assert (done.merged, done.left, done.filled) == (0, 1, 0)
    assert mesh is before
    # filling accepts down to THIN_ANGLE (the finished mesh is checked against the
    # bound afterwards): the sliver of 1.15 degrees
    mesh, done = merge_extra_nodes(before)
    assert (done.merged, done.left, done.filled) == (1, 0, 1)
    assert measures(mesh.points, mesh.triangles)[0].min() >= merge.THIN_ANGLE
    assert signed_areas(mesh.points, mesh.triangles).sum() == pytest.approx(1.0)


def test_a_cavity_grows_to_take_out_the_inner_node_hugging_the_edge():
    before = _square_with_extra(0.01)
    mesh, done = merge_extra_nodes(before)
    assert (done.merged, done.left) == (1, 0)
    assert len(mesh.points) == 4 and len(mesh.triangles) == 2  # node 5 went too
    assert measures(mesh.points, mesh.triangles)[0].min() == pytest.approx(45.0)
    assert signed_areas(mesh.points, mesh.triangles).sum() == pytest.approx(1.0)


def test_nothing_to_do_without_extra_nodes():
    m = _square_with_extra(0.5)
    m.n_extra = 0
    assert merge_extra_nodes(m)[1].merged == 0


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(star_polygons(r_min=0.2))
def test_merging_keeps_the_domain_and_the_contract(pts):
    """Random polygons on the uniform grid (where extra nodes are common): with merging,
    only extra nodes and their triangles change, the contract holds, no new triangle
    is under the angle the merge promises."""
    c = make_contour(pts, source="random")
    try:
        keep = mesh_contour(c, grid="uniform", max_nodes=MAX_NODES, improve=False)
    except (LimitError, SelectionError, FoldError):
        return
    merged = mesh_contour(
        c, grid="uniform", max_nodes=MAX_NODES, improve=False, merge_extra="merge"
    )
    k, m = keep.mesh, merged.mesh
    check_contract(m, c)
    assert np.array_equal(m.points[: c.n], c.points)
    gone = k.n_extra - m.n_extra
    assert gone == merged.report["merged_extra_nodes"] >= 0
    assert len(m.points) <= len(k.points) - gone  # (a grown cavity takes inner nodes too)
    area = abs(signed_area(c.points))
    assert abs(signed_areas(m.points, m.triangles).sum() - area) <= 1e-10 * area
    # every triangle is one of the old ones (renumbered) or a new one of fair angles
    old = {tuple(sorted(map(tuple, k.points[t].round(12).tolist()))) for t in k.triangles}
    new = [t for t in m.triangles
           if tuple(sorted(map(tuple, m.points[t].round(12).tolist()))) not in old]  # fmt: skip
    if new:
        assert measures(m.points, np.array(new))[0].min() >= MIN_ANGLE - 1e-9
    assert (gone > 0) == bool(new)


def test_auto_keeps_the_uniform_grid_as_the_paper_has_it(run, tmp_path):
    out = tmp_path / "m.vtk"

    def report(*args):
        r = run("all", SAMPLES / "peanut.csv", "-o", out, "--json", *args)
        assert r.exit_code == 0, r.stderr
        return json.loads(r.stdout)

    uniform = report("--grid", "uniform")
    assert uniform["extra_boundary_nodes"] > 100 and uniform["merged_extra_nodes"] == 0
    merged = report("--grid", "uniform", "--merge-extra", "merge")
    assert merged["merged_extra_nodes"] > 50
    assert (
        merged["extra_boundary_nodes"] + merged["merged_extra_nodes"]
        == (uniform["extra_boundary_nodes"])
    )
    adapt = report("--grid", "adapt")  # auto merges on the other grids
    kept = report("--grid", "adapt", "--merge-extra", "keep")
    assert kept["merged_extra_nodes"] == 0 and adapt["merged_extra_nodes"] > 0
    assert (
        adapt["extra_boundary_nodes"] + adapt["merged_extra_nodes"]
        == (kept["extra_boundary_nodes"])
    )


def test_merging_counts_extra_nodes_only_and_keeps_the_contract():
    """On a graded path with extra nodes (coast_cuba's long edges), merging may take
    inner nodes out with them (a cavity that grows); the count is of extra nodes."""
    from deformesh_cli.readers import load_contour

    c = load_contour(CORPUS / "coast_cuba.csv")
    kept = mesh_contour(c, merge_extra="keep", improve=False)
    assert kept.mesh.n_extra > 0
    mesh, done = merge_extra_nodes(kept.mesh)
    assert done.merged == kept.mesh.n_extra - mesh.n_extra and done.left == mesh.n_extra
    assert mesh.n_contour == kept.mesh.n_contour
    assert len(mesh.points) <= len(kept.mesh.points) - done.merged + done.added
    check_contract(mesh, c)
    assert np.array_equal(mesh.points[: c.n], c.points)
