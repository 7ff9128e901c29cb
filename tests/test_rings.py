"""Several rings: holes, islands, separate parts, and exterior meshes in a box."""

import json

import meshio
import numpy as np
import pytest

from deformesh_cli import mesh_contour
from deformesh_cli.contour import make_contour
from deformesh_cli.errors import InputError
from deformesh_cli.geometry import signed_area
from deformesh_cli.mesh import Mesh
from deformesh_cli.quality import check_contract
from deformesh_cli.readers import load_contour, parse_csv

from .conftest import contour_file, solver_read


def _circle(cx, cy, r, n, cw=False):
    t = 2 * np.pi * np.arange(n) / n
    if cw:
        t = -t
    return np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t)])


def _reread(path, contour, rec, box=None):
    """Check the contract again on the file as written (groups from gmsh:physical)."""
    m = meshio.read(path)
    names = {int(v[0]): k for k, v in m.field_data.items() if int(v[1]) == 1}
    tags = m.cell_data_dict["gmsh:physical"]["line"]
    groups = tuple(names[t] for t in sorted(names))
    mesh = Mesh(
        m.points[:, :2],
        m.cells_dict["triangle"],
        m.cells_dict["line"],
        contour.n,
        rec["extra_boundary_nodes"],
        line_group=tags - 1,
        groups=groups,
        n_box=0,
    )
    check_contract(mesh, contour, box)
    return m, groups


def test_square_with_hole_keeps_both_rings(run, tmp_path):
    src = contour_file("square_hole_100.csv")
    out = tmp_path / "m.msh"
    r = run("all", src, "-o", out, "--json")
    assert r.exit_code == 0, r.stderr
    rec = json.loads(r.stdout)
    c = load_contour(src)
    assert c.n_rings == 2 and c.depth == (0, 1)
    m, groups = _reread(out, c, rec)
    assert groups == ("contour", "hole_1")
    assert "domain" in m.field_data
    # every point of both rings is a node at its exact coordinates
    assert np.array_equal(m.points[: c.n, :2], c.points)
    hole = abs(signed_area(c.points[c.starts[1] :]))
    assert rec["area"] == pytest.approx(4 - hole, rel=1e-12)


def test_islands_and_separate_parts_mesh_on_one_grid():
    outer = _circle(0, 0, 1.0, 48)
    hole = _circle(0, 0, 0.6, 36, cw=True)
    island = _circle(0, 0, 0.3, 24)
    apart = _circle(2.5, 0, 0.5, 30)
    pts = np.vstack([outer, hole, island, apart])
    starts = np.cumsum([0, 48, 36, 24])
    c = make_contour(pts, source="parts", ring_starts=starts)
    assert c.depth == (0, 1, 2, 0)
    assert [c.ring_name(r) for r in range(4)] == ["contour", "hole_1", "contour_2", "contour_3"]
    res = mesh_contour(c)
    check_contract(res.mesh, c)
    expected = np.pi * (1 - 0.36 + 0.09 + 0.25)
    assert res.report["area"] == pytest.approx(expected, rel=0.02)  # polygons, not circles
    assert res.report["area"] == pytest.approx(c.area, rel=1e-12)


def test_touching_rings_are_refused_with_the_place():
    text = "x,y,ring\n0,0,0\n2,0,0\n2,2,0\n0,2,0\n1,1,1\n2,1.5,1\n1,1.5,1\n"
    with pytest.raises(InputError, match=r"ring 1 touches or crosses ring 0 near \(2, 1\.5\)"):
        parse_csv(text, "t.csv")


def test_ring_points_must_be_together():
    text = "x,y,ring\n0,0,0\n4,0,0\n4,4,0\n1,1,1\n2,1,1\n2,2,1\n0,4,0\n"
    with pytest.raises(InputError, match=r"line 8: ring 0 starts again"):
        parse_csv(text, "t.csv")


def test_a_bad_ring_is_named():
    text = "x,y,ring\n0,0,0\n4,0,0\n4,4,0\n0,4,0\n1,1,1\n2,1,1\n"
    with pytest.raises(InputError, match=r"ring 1: fewer than 3 distinct points"):
        parse_csv(text, "t.csv")


def test_exterior_airfoil_in_a_far_field_box(run, tmp_path):
    src = contour_file("naca0012_100.csv")
    out = tmp_path / "naca.msh"
    r = run("all", src, "--exterior", "--box=-2,-2,3,2", "-o", out, "--json")
    assert r.exit_code == 0, r.stderr
    rec = json.loads(r.stdout)
    assert rec["exterior"] is True and rec["contract"] == "ok"
    # a far field is graded by default: cells grow away from the airfoil (Appendix A's
    # step would need 5e7 nodes in this box), every contour point a node and no other
    assert rec["h_rule"].startswith("graded") and rec["grid_nodes"] < 20_000
    assert rec["extra_boundary_nodes"] == 0
    c = load_contour(src)
    m, groups = _reread(out, c, rec, box=(-2.0, -2.0, 3.0, 2.0))
    assert groups == ("contour", "bottom", "right", "top", "left")
    assert rec["area"] == pytest.approx(20 - c.area, rel=1e-12)

    phys, sk = solver_read(out)
    assert phys == {"contour": 1, "bottom": 1, "right": 1, "top": 1, "left": 1, "domain": 2}
    assert set(sk.boundaries) == {"contour", "bottom", "right", "top", "left"}
    assert set(sk.subdomains) == {"domain"}
    # the contour's boundary facets are exactly the airfoil's edges (with extra nodes)
    assert len(sk.boundaries["contour"]) == c.n + rec["extra_boundary_nodes"]
    assert np.isclose(sk.p[1, np.unique(sk.facets[:, sk.boundaries["bottom"]])], -2).all()


def test_exterior_needs_room_around_the_contour(run, tmp_path):
    r = run(
        "all",
        contour_file("circle_100.csv"),
        "--exterior",
        "--box=-1,-1,1,1",
        "-o",
        tmp_path / "m.vtk",
    )
    assert r.exit_code == 2 and "exterior mesh needs room" in r.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("version", ["2.2", "4.1"])
def test_msh_versions_keep_every_named_group(run, tmp_path, version):
    import gmsh

    out = tmp_path / "m.msh"
    r = run("all", contour_file("square_hole_100.csv"), "--msh-version", version, "-o", out)
    assert r.exit_code == 0, r.stderr
    assert out.read_text().split("\n")[1].startswith(version.split(".")[0])
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(out))
        phys = {gmsh.model.getPhysicalName(d, t): d for d, t in gmsh.model.getPhysicalGroups()}
        n_nodes = len(gmsh.model.mesh.getNodes()[0])
    finally:
        gmsh.finalize()
    assert phys == {"contour": 1, "hole_1": 1, "domain": 2}
    assert n_nodes == len(meshio.read(out).points)
