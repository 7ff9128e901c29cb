"""Periodic meshes (``--periodic DX,DY``): boundary nodes paired across a translation,
written where solvers read them."""

from __future__ import annotations

import json

import meshio
import numpy as np
import pytest

from deformesh_cli import pipeline
from deformesh_cli.options import MeshOptions
from deformesh_cli.readers import load_contour

from .conftest import SAMPLES

CHANNEL = SAMPLES / "channel.csv"
CASCADE = SAMPLES / "cascade.csv"
NACA = SAMPLES / "naca0012.csv"


def _pairs_by_coordinates(points: np.ndarray, lines: np.ndarray, shift) -> set:
    """Every boundary node whose translate is a boundary node, found by comparing
    coordinates (numpy only)."""
    b = np.unique(lines)
    key = {(round(x, 9), round(y, 9)): k for k, (x, y) in zip(b.tolist(), points[b].tolist())}
    out = set()
    for k in b.tolist():
        x, y = points[k]
        hit = key.get((round(x + shift[0], 9), round(y + shift[1], 9)))
        if hit is not None:
            out.add((k, hit))
    return out


@pytest.mark.parametrize(
    "path, shift, count", [(CHANNEL, (3.0, 0.0), 11), (CASCADE, (0.0, 1.0), 21)]
)
def test_every_node_of_the_repeating_sides_is_paired(path, shift, count):
    c = load_contour(str(path))
    res = pipeline.mesh_contour(c, MeshOptions(periodic=shift))
    mesh = res.mesh
    got = {tuple(p) for p in mesh.periodic.tolist()}
    assert len(got) == count == res.report["periodic"]["pairs"]
    assert got == _pairs_by_coordinates(mesh.points, mesh.lines, shift)
    a, b = mesh.periodic.T
    # (the file's points repeat to its 10 digits: pairs within 1e-9 of the extent)
    assert np.allclose(mesh.points[b] - mesh.points[a], shift, rtol=0, atol=3e-9)
    assert (mesh.point_data["periodic"][a] == b).all()
    assert (np.delete(mesh.point_data["periodic"], a) == -1).all()


def test_gmsh_reads_the_pairs_back(tmp_path, run):
    gmsh = pytest.importorskip("gmsh")
    out = tmp_path / "c.msh"
    r = run("all", CASCADE, "-o", out, "--periodic", "0,1", "--msh-version", "4.1", "-q")
    assert r.exit_code == 0, r.stderr
    mesh = pipeline.mesh_contour(load_contour(str(CASCADE)), MeshOptions(periodic=(0, 1))).mesh
    want = {(int(b) + 1, int(a) + 1) for a, b in mesh.periodic.tolist()}  # (tag, master)
    gmsh.initialize(["-v", "0"])
    try:
        gmsh.open(str(out))
        got, shifts = set(), []
        for dim, tag in gmsh.model.getEntities(1):
            master, nodes, masters, affine = gmsh.model.mesh.getPeriodicNodes(dim, tag)
            if master != tag:
                got |= set(zip(nodes.tolist(), masters.tolist()))
                shifts.append((affine[3], affine[7]))
    finally:
        gmsh.finalize()
    assert got == want and shifts == [(0.0, 1.0)]


def test_meshio_and_the_vtu_carry_the_pairs(tmp_path, run):
    msh, vtu = tmp_path / "c.msh", tmp_path / "c.vtu"
    for out, extra in ((msh, ["--msh-version", "4.1"]), (vtu, [])):
        r = run("all", CHANNEL, "-o", out, "--periodic", "3,0", "-q", *extra)
        assert r.exit_code == 0, r.stderr
    ((dim, _, affine, pairs),) = meshio.read(msh).gmsh_periodic
    m = meshio.read(vtu)
    partner = m.point_data["periodic"]
    pairs = np.asarray(pairs)  # (node at master + shift, master)
    assert dim == 1 and len(pairs) == 11 and (partner[pairs[:, 1]] == pairs[:, 0]).all()
    assert np.allclose(m.points[pairs[:, 0], 0] - m.points[pairs[:, 1], 0], 3.0)
    text = tmp_path / "c22.msh"
    assert run("all", CHANNEL, "-o", text, "--periodic", "3,0", "-q").exit_code == 0
    assert "$Periodic\n1\n" in text.read_text() and "Affine 1.0" in text.read_text()


def test_a_periodic_poisson_problem_in_scikit_fem(tmp_path, run):
    """The channel with its inlet tied to its outlet: each paired node's unknown is its
    partner's (a prolongation ``P``, as docs/formats.md shows), and the periodic
    solution of ``-laplace u = k^2 u`` with ``u = 0`` on the walls is found, the error
    falling at rate 2 as ``--max-h`` halves."""
    skfem = pytest.importorskip("skfem")
    import scipy.sparse as sp
    from skfem.helpers import dot, grad

    def exact(x, y):
        return np.sin(2 * np.pi * x / 3 + 0.3) * np.sin(np.pi * y)

    k2 = (2 * np.pi / 3) ** 2 + np.pi**2
    errors = []
    for h in (0.1, 0.05):
        out = tmp_path / f"c{h}.msh"
        r = run("all", CHANNEL, "-o", out, "--periodic", "3,0", "--max-h", h,
                "--msh-version", "4.1", "-q")  # fmt: skip
        assert r.exit_code == 0, r.stderr
        mm = meshio.read(out)
        pairs = np.asarray(mm.gmsh_periodic[0][3])
        m = skfem.MeshTri(mm.points[:, :2].T.copy(), mm.cells_dict["triangle"].T.copy())
        basis = skfem.Basis(m, skfem.ElementTriP1())
        a = skfem.BilinearForm(lambda u, v, w: dot(grad(u), grad(v))).assemble(basis)
        b = skfem.LinearForm(lambda v, w: k2 * exact(*w.x) * v).assemble(basis)
        n = basis.N
        to = np.arange(n)
        to[pairs[:, 0]] = pairs[:, 1]
        keep = np.unique(to)
        p = sp.csr_array((np.ones(n), (np.arange(n), np.searchsorted(keep, to))))
        y = m.p[1, keep]
        wall = np.flatnonzero((np.abs(y) < 1e-9) | (np.abs(y - 1) < 1e-9))
        u = p @ skfem.solve(*skfem.condense((p.T @ a @ p).tocsr(), p.T @ b, D=wall))
        err = skfem.Functional(lambda w: (w["uh"] - exact(*w.x)) ** 2)
        errors.append(np.sqrt(err.assemble(basis, uh=basis.interpolate(u))))
    assert errors[1] < 0.01 and 3.0 < errors[0] / errors[1] < 5.0


def test_a_translation_that_pairs_nothing_is_refused(run, tmp_path):
    out = tmp_path / "m.msh"
    r = run("all", SAMPLES / "circle.csv", "-o", out, "--periodic", "3,0")
    assert r.exit_code == 1 and r.stderr.count("\n") == 1 and not out.exists()
    assert "--periodic 3,0 pairs no boundary edge" in r.stderr and "contour point 0" in r.stderr
    r = run("all", SAMPLES / "circle.csv", "-o", out, "--periodic", "0,0")
    assert r.exit_code == 2 and "not a translation" in r.stderr
    r = run("all", CHANNEL, "-o", out, "--periodic=1e-300,0")
    assert r.exit_code == 1 and "shorter than the pairing tolerance" in r.stderr


def test_stages_give_all_s_bytes(run, tmp_path):
    s1, s2 = tmp_path / "m.selected", tmp_path / "m.deformed"
    whole, staged = tmp_path / "a.msh", tmp_path / "s.msh"
    assert run("select", CASCADE, "-o", s1, "--periodic", "0,1").exit_code == 0
    assert run("deform", s1, "-o", s2).exit_code == 0
    assert run("triangulate", s2, "-o", staged).exit_code == 0
    assert run("all", CASCADE, "-o", whole, "--periodic", "0,1").exit_code == 0
    assert staged.read_bytes() == whole.read_bytes()


def test_the_summary_says_how_many_pairs(run, tmp_path):
    r = run("all", CHANNEL, "-o", tmp_path / "m.vtk", "--periodic", "3,0", "--json")
    assert r.exit_code == 0, r.stderr
    assert json.loads(r.stdout)["periodic"] == {"shift": [3.0, 0.0], "pairs": 11}


def _side_x(mesh, side: str) -> np.ndarray:
    on = np.unique(mesh.lines[mesh.line_group == list(mesh.groups).index(side)])
    return np.sort(mesh.points[on, 0])


@pytest.mark.parametrize(
    "box, shift",
    [((-20.0, -20.0, 21.0, 20.0), (0.0, 40.0)), ((-0.2, -0.08, 1.3, 1.0), (0.0, 1.08))],
)
def test_exterior_box_sides_carry_the_same_nodes(box, shift):
    """The far field's bottom and top carry the same x coordinates, node for node, every
    one paired; in a box whose bottom hugs the airfoil the top is refined to match."""
    c = load_contour(str(NACA))
    o = MeshOptions(exterior=True, box=box)
    mesh = pipeline.mesh_contour(c, o.replace(periodic=shift)).mesh
    bottom, top = _side_x(mesh, "bottom"), _side_x(mesh, "top")
    assert np.array_equal(bottom, top)
    assert len(mesh.periodic) == len(bottom)
    if box[1] > -1:  # (without --periodic the sides differ there)
        plain = pipeline.mesh_contour(c, o).mesh
        assert len(_side_x(plain, "bottom")) != len(_side_x(plain, "top"))


def test_match_sides_cuts_opposite_sides_alike():
    from deformesh_cli.select import graded

    def row(t, first: bool, across_y: bool):
        i, j = (t.i, t.j) if across_y else (t.j, t.i)
        far = (t.ny if across_y else t.nx) * 2**t.top
        on = (j == 0) if first else ((j + 1) << t.level) == far
        return sorted(zip((i[on] << t.level[on]).tolist(), t.level[on].tolist()))

    for point, across_y in (((0.5, 0.01), True), ((0.99, 0.3), False)):
        t = graded._lay(np.array([point]), np.array([0.002]), (0, 0, 1, 1), 1.3, None, True,
                        None, None, None)  # fmt: skip
        assert row(t, True, across_y) != row(t, False, across_y)
        m = graded.match_sides(t, not across_y, across_y)
        assert row(m, True, across_y) == row(m, False, across_y)
        assert not m.overlapping() and int((4**m.level).sum()) == m.nx * m.ny * 4**m.top


def _random_passage(rng: np.random.Generator):
    """A random cascade passage: a lower side of random points (random spacing and
    wave), the same points shifted by the pitch as the upper side, inlet and outlet
    with the same random heights: ``(points, pitch, lower side's count)``."""
    n = int(rng.integers(5, 40))
    x = np.sort(rng.uniform(0.0, 1.0, n - 2))
    x = np.concatenate([[0.0], x[np.diff(np.r_[0.0, x]) > 0.01], [1.0]])
    x = x[np.r_[True, np.diff(x) > 0.01]]
    x[-1] = 1.0
    y = 0.15 * np.sin(rng.uniform(1, 6) * x + rng.uniform(0, 6)) + rng.uniform(-0.2, 0.2) * x
    pitch = float(rng.uniform(0.4, 1.5))
    k = int(rng.integers(1, 8))
    h = np.sort(rng.uniform(0.05, 0.95, k)) * pitch
    h = h[np.r_[True, np.diff(h) > 0.01 * pitch]]
    lower = np.column_stack([x, y])
    outer = np.concatenate(
        [
            lower[:-1],
            np.column_stack([np.full(len(h) + 1, 1.0), y[-1] + np.r_[0.0, h]]),
            (lower + [0.0, pitch])[::-1][:-1],
            np.column_stack([np.zeros(len(h) + 1), y[0] + np.r_[pitch, h[::-1]]]),
        ]
    )
    return outer, pitch, len(lower)


@pytest.mark.parametrize("seed", range(12))
def test_random_passages_pair_their_sides(seed):
    """Random passages (unseen shapes, spacings and pitches), with quads only too: every
    point of the lower side is paired with its translate on the upper side, and the
    contract holds."""
    from deformesh_cli.contour import make_contour

    rng = np.random.default_rng(seed)
    pts, pitch, count = _random_passage(rng)
    c = make_contour(pts, source=f"passage-{seed}")
    for cells, pairs in (("tri", count), ("quad-only", 2 * count - 1)):
        res = pipeline.mesh_contour(c, MeshOptions(periodic=(0.0, pitch), cells=cells))
        mesh = res.mesh
        assert len(mesh.periodic) == pairs, (seed, cells)
        a, b = mesh.periodic.T
        assert np.allclose(mesh.points[b] - mesh.points[a], (0.0, pitch), rtol=0, atol=1e-9)
        assert res.report["contract"] == "ok"


def test_layers_keep_the_pairs(run, tmp_path):
    """A channel with boundary layers on every wall: the pairs are the whole mesh's
    (its inlet and outlet points), found once the layers are joined, never on the
    rest of the domain alone (whose boundary is the layers' top)."""
    c = load_contour(str(CHANNEL))
    o = MeshOptions(periodic=(3.0, 0.0), layers=3, first_height=0.005)
    for cells in ("quad", "tri"):
        res = pipeline.mesh_contour(c, o.replace(cells=cells))
        mesh = res.mesh
        assert res.report["periodic"]["pairs"] == 11 and len(mesh.quads)
        assert (mesh.periodic[:, 0] < c.n).all() and (mesh.periodic[:, 1] < c.n).all()
    s1, s2, staged = tmp_path / "m.selected", tmp_path / "m.deformed", tmp_path / "s.vtu"
    args = ["--periodic", "3,0", "--layers", 3, "--first-height", 0.005]
    assert run("select", CHANNEL, "-o", s1, *args).exit_code == 0
    assert run("deform", s1, "-o", s2).exit_code == 0
    r = run("triangulate", s2, "-o", staged, "--json")
    assert r.exit_code == 0, r.stderr
    assert json.loads(r.stdout)["periodic"]["pairs"] == 11
