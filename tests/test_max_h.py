"""``--max-h H``: a mesh size a user can ask for, in the contour's units.  Contour edges
longer than H are split into equal pieces (the given points stay nodes 0..m-1 in order,
the added boundary nodes follow them), and no grid cell is larger than H."""

import json

import meshio
import numpy as np
import pytest

from deformesh_cli.contour import make_contour, split_edges

from .conftest import SAMPLES
from .independent import contract_problems

RECTANGLE = [(0, 0), (10, 0), (10, 1), (0, 1)]
L_SHAPE = [(0, 0), (10, 0), (10, 1), (1, 1), (1, 10), (0, 10)]


def test_split_edges_keeps_the_given_points_and_bounds_every_piece():
    pts = np.array([(0, 0), (3, 0), (3, 0.5), (0, 2)], dtype=float)
    hole = np.array([(1, 1), (1.2, 1.1), (1, 1.3)])
    c = make_contour(np.r_[pts, hole], ring_starts=[0, 4])
    fine, given = split_edges(c, 0.4)
    assert np.array_equal(fine.points[given], c.points)  # bit for bit, in order
    assert np.all(np.diff(given) > 0) and fine.starts == (0, int(given[4]), fine.n)
    for r in range(2):
        ring = fine.points[fine.starts[r] : fine.starts[r + 1]]
        piece = np.hypot(*(np.roll(ring, -1, axis=0) - ring).T)
        assert piece.max() <= 0.4 * (1 + 1e-12)
    # each added point lies on the edge from the given point before it to the one after
    for k in range(4):
        a, b = c.points[k], c.points[(k + 1) % 4]
        end = given[k + 1] if k < 3 else fine.starts[1]
        q = fine.points[given[k] + 1 : end]
        cross = (b[0] - a[0]) * (q[:, 1] - a[1]) - (b[1] - a[1]) * (q[:, 0] - a[0])
        assert np.abs(cross).max(initial=0) < 1e-12
        n = int(np.ceil(np.hypot(*(b - a)) / 0.4))
        assert len(q) == n - 1
    for h in (10.0, None):  # (nothing longer, or no --max-h: the contour itself)
        fine, given = split_edges(c, h)
        assert fine is c and given is None


def _mesh(run, tmp_path, points, *args):
    src = tmp_path / "c.csv"
    np.savetxt(src, np.asarray(points, dtype=float), delimiter=",")
    out = tmp_path / "m.vtu"
    r = run("all", src, "-o", out, "--json", "-q", *args)
    assert r.exit_code == 0, r.stderr
    m = meshio.read(out)
    return np.loadtxt(src, delimiter=",", ndmin=2), m, json.loads(r.stdout)


@pytest.mark.parametrize("shape", [RECTANGLE, L_SHAPE], ids=["10x1", "L"])
def test_a_coarse_polygon_with_max_h_has_every_angle_over_30(run, tmp_path, shape):
    given, m, rep = _mesh(run, tmp_path, shape, "--max-h", "0.1")
    tri = m.cells_dict["triangle"]
    assert contract_problems(m.points, tri, given, np.zeros(len(given), int)) == []
    assert rep["min_angle"] >= 30 and rep["contract"] == "ok"
    perimeter = np.hypot(*(np.roll(given, -1, axis=0) - given).T).sum()
    assert rep["split_nodes"] == round(perimeter / 0.1) - len(given)
    assert rep["extra_boundary_nodes"] >= rep["split_nodes"]
    # every edge of the mesh at most H (the cells' diagonals: H and no more)
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    length = np.hypot(*(m.points[e[:, 0], :2] - m.points[e[:, 1], :2]).T)
    assert length.max() <= 0.1 * np.sqrt(2) * (1 + 1e-9)


def test_stages_give_the_same_mesh_as_all(run, tmp_path):
    src = tmp_path / "L.csv"
    np.savetxt(src, np.asarray(L_SHAPE, dtype=float), delimiter=",")
    a, s, d, b = (tmp_path / n for n in ("a.vtk", "s.state", "d.state", "b.vtk"))
    assert run("all", src, "-o", a, "--max-h", "0.5", "-q").exit_code == 0
    assert run("select", src, "-o", s, "--max-h", "0.5", "-q").exit_code == 0
    assert run("deform", s, "-o", d, "-q").exit_code == 0
    assert run("triangulate", d, "-o", b, "-q").exit_code == 0
    assert a.read_bytes() == b.read_bytes()


def test_halving_max_h_converges_at_second_order():
    """P1 Poisson on the mesh of samples/circle.csv, u = sin(pi x) sin(pi y): halving
    --max-h from 0.1 three times, the L2 error falls four times each time."""
    pytest.importorskip("skfem")
    from skfem import Basis, ElementTriP1, Functional, LinearForm, MeshTri, asm, condense, solve
    from skfem.models.poisson import laplace

    from deformesh_cli.pipeline import mesh_contour
    from deformesh_cli.readers import load_contour

    c = load_contour(str(SAMPLES / "circle.csv"))

    def exact(x, y):
        return np.sin(np.pi * x) * np.sin(np.pi * y)

    @LinearForm
    def rhs(v, w):
        return 2 * np.pi**2 * exact(w.x[0], w.x[1]) * v

    @Functional
    def l2(w):
        return (w["uh"] - exact(w.x[0], w.x[1])) ** 2

    errors = []
    for h in (0.1, 0.05, 0.025, 0.0125):
        mesh = mesh_contour(c, max_h=h).mesh
        basis = Basis(MeshTri(mesh.points.T.copy(), mesh.triangles.T.copy()), ElementTriP1())
        u = np.zeros(basis.N)
        boundary = basis.get_dofs().all()
        u[boundary] = exact(*basis.mesh.p[:, boundary])
        u = solve(*condense(asm(laplace, basis), asm(rhs, basis), x=u, D=boundary))
        errors.append(np.sqrt(l2.assemble(basis, uh=basis.interpolate(u))))
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(rates - 2) <= 0.1), rates


@pytest.mark.parametrize("shape", [RECTANGLE, L_SHAPE], ids=["10x1", "L"])
def test_without_max_h_a_note_names_the_forced_angle_and_the_max_h_that_lifts_it(
    run, tmp_path, shape
):
    import re

    given, m, rep = _mesh(run, tmp_path, shape)
    assert rep["min_angle"] < 10 and rep["contract"] == "ok"
    assert rep["extra_boundary_nodes"] == 0  # (the given points are the boundary)
    note = next(n for n in rep["notes"] if "--max-h" in n)
    assert f"{rep['forced_angle']:.1f} there" in note
    src, s, d = tmp_path / "c.csv", tmp_path / "s.state", tmp_path / "d.state"
    assert run("select", src, "-o", s, "-q").exit_code == 0
    assert run("deform", s, "-o", d, "-q").exit_code == 0
    staged = run("triangulate", d, "-o", tmp_path / "t.vtu", "--json", "-q")
    assert note in json.loads(staged.stdout)["notes"]  # (the stages say it too)
    h = re.search(r"--max-h (\S+) splits them", note).group(1)
    _, _, lifted = _mesh(run, tmp_path, shape, "--max-h", h)
    assert lifted["min_angle"] >= 2 * rep["forced_angle"]  # (measured: 29.7 on the L)


def test_a_mesh_over_10_degrees_has_no_such_note(run, tmp_path):
    _, _, rep = _mesh(run, tmp_path, [(0, 0), (1, 0), (1, 1), (0, 1)])
    assert rep["min_angle"] >= 10 and not any("--max-h" in n for n in rep["notes"])
