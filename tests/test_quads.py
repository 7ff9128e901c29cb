"""Quads (``--cells quad``, ``--cells quad-only``): pairs of triangles recombined by a
matching over the whole mesh, or every cell split into quads."""

from __future__ import annotations

import itertools
import json

import meshio
import numpy as np
import pytest

from deformesh_cli import pipeline, quads
from deformesh_cli.contour import make_contour
from deformesh_cli.options import MeshOptions
from deformesh_cli.readers import load_contour

from .conftest import SAMPLES
from .independent import contract_problems
from .random_polygons import catalogue

CIRCLE = SAMPLES / "circle.csv"
NACA = SAMPLES / "naca0012.csv"
FAR = (-20.0, -20.0, 21.0, 20.0)


def _angles(points: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Per quad corner: its interior angle in degrees, in [0, 360) (numpy only)."""
    p = points[q]
    a, b = np.roll(p, -1, axis=1) - p, np.roll(p, 1, axis=1) - p
    cross = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return np.degrees(np.arctan2(cross, (a * b).sum(axis=-1))) % 360.0


def _sin_min(points: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Per quad: its smallest scaled Jacobian (the sine of its corner angles)."""
    return np.sin(np.radians(_angles(points, q))).min(axis=1)


def _areas(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    x, y = points[cells, 0], points[cells, 1]
    return 0.5 * (x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y).sum(axis=1)


def _split(mesh) -> np.ndarray:
    q = mesh.quads
    return np.concatenate([mesh.triangles, q[:, [0, 1, 2]], q[:, [0, 2, 3]]])


@pytest.fixture(scope="module")
def circle_quads():
    c = load_contour(str(CIRCLE))
    return c, pipeline.mesh_contour(c, MeshOptions(max_h=0.05, cells="quad"))


@pytest.mark.parametrize(
    "path, options, share",
    [
        (CIRCLE, {"max_h": 0.05}, 0.80),
        (NACA, {"exterior": True, "box": FAR}, 0.70),
    ],
)
def test_quad_dominant_meshes_are_mostly_good_quads(path, options, share):
    c = load_contour(str(path))
    res = pipeline.mesh_contour(c, MeshOptions(cells="quad", **options))
    mesh = res.mesh
    q_area = _areas(mesh.points, mesh.quads).sum()
    total = q_area + _areas(mesh.points, mesh.triangles).sum()
    assert q_area / total >= share
    assert res.report["quad_quality"]["area_share"] == pytest.approx(q_area / total)
    angles = _angles(mesh.points, mesh.quads)
    assert angles.min() > 45.0 and angles.max() < 135.0  # (so every quad convex)
    assert _sin_min(mesh.points, mesh.quads).min() >= 0.5
    assert np.array_equal(mesh.points[: c.n], c.points)
    assert res.report["contract"] == "ok"
    if not options.get("exterior"):
        ring = np.zeros(c.n, dtype=np.int64)
        assert contract_problems(mesh.points, _split(mesh), c.points, ring) == []


def test_recombining_keeps_the_nodes_and_the_triangles_area(circle_quads):
    c, res = circle_quads
    tri = pipeline.mesh_contour(c, MeshOptions(max_h=0.05)).mesh
    mesh = res.mesh
    assert np.array_equal(mesh.points, tri.points) and np.array_equal(mesh.lines, tri.lines)
    assert len(mesh.triangles) + 2 * len(mesh.quads) == len(tri.triangles)
    # each quad is two of the triangles: its diagonal's halves are among them
    have = {tuple(sorted(t)) for t in tri.triangles.tolist()}
    for k in range(0, len(mesh.quads), 97):
        a, b, cc, d = mesh.quads[k].tolist()
        halves = ({tuple(sorted((a, b, cc))), tuple(sorted((a, cc, d)))},
                  {tuple(sorted((a, b, d))), tuple(sorted((b, cc, d)))})  # fmt: skip
        assert any(h <= have for h in halves)


def _best_by_enumeration(n, a, b, w) -> float:
    """The weight of a best matching, by trying every subset of edges (small graphs)."""
    best = 0.0
    for r in range(1, n // 2 + 1):
        for pick in itertools.combinations(range(len(a)), r):
            nodes = [a[i] for i in pick] + [b[i] for i in pick]
            if len(set(nodes)) == 2 * r:
                best = max(best, float(sum(w[i] for i in pick)))
    return best


@pytest.mark.parametrize("seed", range(30))
def test_the_matching_is_a_best_one_on_bipartite_graphs(seed):
    """On a bipartite graph the linear relaxation has an integral optimum: the matching
    is a best one.  On any graph it is a matching."""
    rng = np.random.default_rng(seed)
    left, right = int(rng.integers(2, 6)), int(rng.integers(2, 6))
    pairs = [(i, left + j) for i in range(left) for j in range(right) if rng.random() < 0.5]
    if not pairs:
        pairs = [(0, left)]
    a = np.array([p[0] for p in pairs])
    b = np.array([p[1] for p in pairs])
    w = rng.uniform(0.71, 1.0, len(pairs))
    taken = quads.best_matching(left + right, a, b, w)
    ends = np.concatenate([a[taken], b[taken]])
    assert len(np.unique(ends)) == len(ends)
    assert w[taken].sum() == pytest.approx(_best_by_enumeration(left + right, a, b, w))


@pytest.mark.parametrize("k", [3, 5, 7])
def test_an_odd_cycle_leaves_one_node_single(k):
    """A cycle of odd length: the relaxation's optimum is half of every edge; rounded, it
    is every second edge after the one node left single, chosen for the best weight."""
    a = np.arange(k)
    b = (a + 1) % k
    w = np.linspace(0.8, 0.9, k)
    taken = quads.best_matching(k, a, b, w)
    assert len(taken) == k // 2
    assert w[taken].sum() == pytest.approx(_best_by_enumeration(k, a, b, w))


@pytest.mark.parametrize("seed", range(20))
def test_the_matching_on_small_random_graphs(seed, monkeypatch):
    """Any graph: a matching, a best one where the relaxation has no odd cycle, and
    within the heaviest edge's weight per odd cycle of a best one otherwise."""
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(3, 9))
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n) if rng.random() < 0.4]
    if not pairs:
        pairs = [(0, 1)]
    a, b = np.array(pairs).T
    w = rng.uniform(0.71, 1.0, len(pairs))
    rounded = []
    round_cycle = quads._round_cycle
    monkeypatch.setattr(
        quads, "_round_cycle", lambda e, ww: rounded.append(len(e)) or round_cycle(e, ww)
    )
    taken = quads.best_matching(n, a, b, w)
    ends = np.concatenate([a[taken], b[taken]])
    assert len(np.unique(ends)) == len(ends)
    odd = sum(k % 2 for k in rounded)
    best = _best_by_enumeration(n, a, b, w)
    assert w[taken].sum() >= best - odd * w.max() - 1e-12
    if not odd:
        assert w[taken].sum() == pytest.approx(best)


def test_cells_tri_is_the_default_bytes(run, tmp_path):
    one, two = tmp_path / "a.vtk", tmp_path / "b.vtk"
    assert run("all", CIRCLE, "-o", one, "-q").exit_code == 0
    assert run("all", CIRCLE, "-o", two, "--cells", "tri", "-q").exit_code == 0
    assert one.read_bytes() == two.read_bytes()


def test_stages_give_all_s_bytes(run, tmp_path):
    s1, s2 = tmp_path / "m.selected", tmp_path / "m.deformed"
    assert run("select", NACA, "-o", s1, "--exterior").exit_code == 0
    assert run("deform", s1, "-o", s2).exit_code == 0
    for cells in ("quad", "quad-only"):
        staged, whole = tmp_path / f"s_{cells}.msh", tmp_path / f"a_{cells}.msh"
        r = run("triangulate", s2, "-o", staged, "--cells", cells)
        assert r.exit_code == 0, r.stderr
        r = run("all", NACA, "-o", whole, "--exterior", "--cells", cells)
        assert r.exit_code == 0, r.stderr
        assert staged.read_bytes() == whole.read_bytes()


@pytest.fixture(scope="module")
def quad_only(tmp_path_factory):
    d = tmp_path_factory.mktemp("quad_only")
    c = load_contour(str(CIRCLE))
    res = pipeline.mesh_contour(c, MeshOptions(max_h=0.05, cells="quad-only"))
    return c, res, d


def test_quad_only_is_quads_with_every_contour_point(quad_only):
    c, res, _ = quad_only
    mesh = res.mesh
    assert len(mesh.triangles) == 0 and len(mesh.quads)
    assert (_sin_min(mesh.points, mesh.quads) > 0).all()  # every quad convex
    assert np.array_equal(mesh.points[: c.n], c.points)
    ring = np.zeros(c.n, dtype=np.int64)
    assert contract_problems(mesh.points, _split(mesh), c.points, ring) == []
    # a node at the middle of every boundary edge, counted and said once
    assert res.report["split_boundary_edges"] * 2 == len(mesh.lines)
    notes = [n for n in res.report["notes"] if "quad-only" in n]
    assert len(notes) == 1 and str(res.report["split_boundary_edges"]) in notes[0]
    a, b = mesh.points[mesh.lines[0::2, 0]], mesh.points[mesh.lines[1::2, 1]]
    assert np.allclose(mesh.points[mesh.lines[0::2, 1]], 0.5 * (a + b), rtol=0, atol=1e-15)


def test_quad_only_says_so_once_on_stderr(run, tmp_path):
    r = run("all", CIRCLE, "-o", tmp_path / "m.vtu", "--cells", "quad-only")
    assert r.exit_code == 0, r.stderr
    assert r.stderr.count("quad-only put a node at the middle") == 1
    assert "64 boundary edges" in r.stderr


@pytest.mark.parametrize("suffix", [".vtk", ".vtu", ".msh", ".su2", ".xdmf"])
def test_every_format_holds_a_mesh_of_quads(run, tmp_path, suffix):
    out = tmp_path / f"m{suffix}"
    assert run("all", CIRCLE, "-o", out, "--cells", "quad-only", "-q").exit_code == 0
    m = meshio.read(out)
    kinds = {c.type: len(c.data) for c in m.cells}
    assert "triangle" not in kinds and kinds["quad"] > 0
    assert np.array_equal(m.points[:64, :2], load_contour(str(CIRCLE)).points)


def test_gmsh_reads_the_quads(tmp_path, run):
    gmsh = pytest.importorskip("gmsh")
    for version in ("2.2", "4.1"):
        out = tmp_path / f"m{version}.msh"
        r = run("all", CIRCLE, "-o", out, "--cells", "quad", "--msh-version", version, "-q")
        assert r.exit_code == 0
        gmsh.initialize(["-v", "0"])
        try:
            gmsh.open(str(out))
            types, tags, _ = gmsh.model.mesh.getElements(2)
        finally:
            gmsh.finalize()
        assert sorted(types.tolist()) == [2, 3]  # (triangles and quads)


def test_quality_reports_the_quads(run, tmp_path):
    out = tmp_path / "m.vtu"
    assert run("all", NACA, "-o", out, "--exterior", "--cells", "quad", "-q").exit_code == 0
    r = run("quality", out, "--contour", NACA, "--json")
    assert r.exit_code == 0, r.stderr
    rep = json.loads(r.stdout)
    q = rep["quad_quality"]
    assert rep["contract"] == "ok" and rep["quads"] > 0 and q["non_convex"] == 0
    assert q["min_angle"] > 45 and q["max_angle"] < 135 and q["min_scaled_jacobian"] > 0.7
    assert 0.7 < q["area_share"] < 1 and q["max_aspect_ratio"] >= q["mean_aspect_ratio"] >= 1
    assert "layers" not in rep  # (stacks only with --first-height)
    text = run("quality", out).stdout
    assert "quads: 0 not convex" in text and "% of the area" in text


def test_quad_only_meshes_solve_at_rate_two(tmp_path, run):
    """scikit-fem's bilinear quads on ``--cells quad-only`` meshes of the circle at --max-h
    halved: a Poisson problem with a known solution converges at rate 2 in L2."""
    skfem = pytest.importorskip("skfem")
    from skfem.helpers import dot, grad

    def exact(x, y):
        return np.sin(2 * x) * np.cosh(y) + x * y * y

    def f(x, y):  # -laplace(exact)
        return 3 * np.sin(2 * x) * np.cosh(y) - 2 * x

    errors, sizes = [], []
    for h in (0.1, 0.05, 0.025):
        out = tmp_path / f"m{h}.msh"
        r = run("all", CIRCLE, "-o", out, "--max-h", h, "--cells", "quad-only", "-q")
        assert r.exit_code == 0
        m = skfem.MeshQuad.load(str(out))
        assert "contour" in m.boundaries
        basis = skfem.Basis(m, skfem.ElementQuad1(), intorder=4)
        a = skfem.BilinearForm(lambda u, v, w: dot(grad(u), grad(v))).assemble(basis)
        b = skfem.LinearForm(lambda v, w: f(*w.x) * v).assemble(basis)
        wall = basis.get_dofs().flatten()
        u = np.zeros(basis.N)
        u[wall] = exact(*m.p[:, wall])
        u = skfem.solve(*skfem.condense(a, b, x=u, D=wall))
        err = skfem.Functional(lambda w: (w["uh"] - exact(*w.x)) ** 2)
        errors.append(np.sqrt(err.assemble(basis, uh=basis.interpolate(u))))
        sizes.append(np.sqrt(np.pi / m.t.shape[1]))
    rates = np.log(np.array(errors[:-1]) / errors[1:]) / np.log(np.array(sizes[:-1]) / sizes[1:])
    assert (rates > 1.8).all() and (rates < 2.3).all(), rates


def test_quads_with_layers(run, tmp_path):
    """Layers and recombined quads together: the layers' quads kept, the rest recombined;
    quads with the layers as triangles are refused in one line."""
    c = load_contour(str(CIRCLE))
    o = MeshOptions(layers=4, first_height=0.01)
    plain = pipeline.mesh_contour(c, o).mesh
    mixed = pipeline.mesh_contour(c, o.replace(cells="quad")).mesh
    assert len(mixed.quads) > len(plain.quads)
    assert {tuple(q) for q in plain.quads.tolist()} <= {tuple(q) for q in mixed.quads.tolist()}
    for cells in ("quad", "quad-only"):
        r = run("all", CIRCLE, "-o", tmp_path / "m.vtu", "--layers", 4, "--first-height", 0.01,
                "--cells", cells, "--layer-cells", "tri")  # fmt: skip
        assert r.exit_code == 2 and "Error:" in r.stderr and f"--cells {cells} " in r.stderr
        assert "Traceback" not in r.stderr and not (tmp_path / "m.vtu").exists()


def _random_quads(exterior: bool, count: int) -> int:
    meshed = 0
    for name, p, ring in catalogue(count):
        starts = np.flatnonzero(np.r_[True, ring[1:] != ring[:-1]]).tolist()
        c = make_contour(p, source=name, ring_starts=starts)
        o = MeshOptions(exterior=exterior)
        res = pipeline.mesh_contour(c, o)
        box = res.selection.grid.box if exterior else None
        for cells in ("quad", "quad-only"):  # (each checks the contract as it goes)
            mesh, _ = pipeline.shape_cells(c, res.mesh, res.report, o.replace(cells=cells), box)
            assert (_sin_min(mesh.points, mesh.quads) > 0).all(), name
            assert np.array_equal(mesh.points[: c.n], c.points), name
            if not exterior:
                assert contract_problems(mesh.points, _split(mesh), p, ring) == [], name
        meshed += 1
    return meshed


@pytest.mark.parametrize("exterior, count", [(False, 60), (True, 10)])
def test_random_polygons_mesh_with_quads(exterior, count):
    """Every valid polygon meshes with quads and with quads only, the contract holding
    (the exterior meshes are the slow ones: fewer of them)."""
    assert _random_quads(exterior, count) == count


def test_plot_draws_a_mesh_of_quads(run, tmp_path):
    """A mesh of quads alone is drawn, its histogram the quads' scaled Jacobians."""
    mesh, png = tmp_path / "m.vtu", tmp_path / "m.png"
    assert run("all", CIRCLE, "-o", mesh, "--cells", "quad-only", "-q").exit_code == 0
    r = run("plot", mesh, "-o", png)
    assert r.exit_code == 0, r.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("cells", ["quad", "quad-only"])
def test_move_carries_the_quads(run, tmp_path, cells):
    """A quad mesh follows the pulsating peanut with its own cells: every frame has the
    same triangles and quads, every quad convex (its four corner triangles positive)."""
    frames = sorted((SAMPLES / "pulsating").glob("frame_*.csv"))
    mesh = tmp_path / "m.vtu"
    assert run("all", SAMPLES / "peanut.csv", "-o", mesh, "--cells", cells, "-q").exit_code == 0
    first = meshio.read(mesh)
    r = run("move", mesh, *frames, "--out-dir", tmp_path / "out", "--json", "-q")
    assert r.exit_code == 0, r.stderr
    s = json.loads(r.stdout)
    assert sum(f.get("solves", 0) for f in s["per_frame"]) > 0  # (a change of shape, solved)
    for k in range(len(frames) + 1):
        m = meshio.read(tmp_path / "out" / f"m_{k:04d}.vtu")
        for kind in ("triangle", "quad"):
            a, b = first.cells_dict.get(kind), m.cells_dict.get(kind)
            assert (a is None and b is None) or np.array_equal(a, b)
        p = m.points[:, :2]
        q = m.cells_dict["quad"]
        for corner in ([0, 1, 2], [0, 2, 3], [1, 2, 3], [1, 3, 0]):
            assert (_areas(p, q[:, corner]) > 0).all()
    r = run("move", mesh, *frames, "--out-dir", tmp_path / "again", "--remesh")
    assert r.exit_code == 2 and "--remesh" in r.stderr and "quads" in r.stderr


@pytest.mark.parametrize("cells", ["quad", "quad-only"])
def test_adapt_carries_the_quads(run, tmp_path, cells):
    """A monitor's bump on a quad mesh: the same cells, every quad's four corner
    triangles positive, the monitor equidistributed better."""
    mesh, out = tmp_path / "m.vtu", tmp_path / "a.vtu"
    assert run("all", SAMPLES / "peanut.csv", "-o", mesh, "--cells", cells, "-q").exit_code == 0
    r = run("adapt", mesh, "-o", out, "--monitor", "1 + 10*exp(-20*((x-0.5)**2+y**2))",
            "--json", "-q")  # fmt: skip
    assert r.exit_code == 0, r.stderr
    rep = json.loads(r.stdout)
    assert rep["sigma_over_mu"] < rep["sigma_over_mu_before"] and rep["tangled"] == 0
    before, after = meshio.read(mesh), meshio.read(out)
    assert rep["quads"] == len(before.cells_dict["quad"])
    for kind in ("triangle", "quad"):
        a, b = before.cells_dict.get(kind), after.cells_dict.get(kind)
        assert (a is None and b is None) or np.array_equal(a, b)
    p, q = after.points[:, :2], after.cells_dict["quad"]
    assert not np.array_equal(p, before.points[:, :2])
    for corner in ([0, 1, 2], [0, 2, 3], [1, 2, 3], [1, 3, 0]):
        assert (_areas(p, q[:, corner]) > 0).all()


@pytest.mark.parametrize(
    "path", sorted(SAMPLES.glob("*.csv")) + sorted(SAMPLES.glob("*.svg")), ids=lambda p: p.name
)
def test_every_sample_meshes_in_quads_only(path):
    c = load_contour(str(path))
    res = pipeline.mesh_contour(c, MeshOptions(cells="quad-only"))
    mesh = res.mesh
    assert len(mesh.triangles) == 0 and len(mesh.quads)
    assert (_sin_min(mesh.points, mesh.quads) > 0).all()
    assert np.array_equal(mesh.points[: c.n], c.points)
    assert res.report["contract"] == "ok"


def test_a_long_odd_cycle_is_rounded_whole():
    """An odd cycle of 100,001 nodes: every second edge but at the one node left single,
    the lightest to leave (its two edges the lightest pair)."""
    k = 100_001
    a = np.arange(k)
    b = (a + 1) % k
    w = np.full(k, 0.9)
    w[[500, 501]] = 0.75  # (node 501 ends edges 500 and 501: leaving it costs least)
    taken = quads.best_matching(k, a, b, w)
    ends = np.concatenate([a[taken], b[taken]])
    assert len(taken) == k // 2 and len(np.unique(ends)) == len(ends)
    assert 501 not in ends


def test_the_matching_ends_where_fractional_weights_make_the_solver_loop():
    """The assignment solver on a graph whose fractional weights made it loop for ever
    (tests/data/matching): on the integer weights the matching ends, and is one."""
    import subprocess
    import sys

    from .conftest import DATA

    graph = DATA / "matching" / "naca_layers.npz"
    code = (
        "import sys, numpy as np\n"
        "from deformesh_cli.quads import best_matching\n"
        f"g = np.load({str(graph)!r})\n"
        "t = best_matching(int(g['n']), g['a'].astype(np.int64), g['b'].astype(np.int64), g['w'])\n"
        "ends = np.concatenate([g['a'][t], g['b'][t]])\n"
        "assert len(np.unique(ends)) == len(ends) and len(t) > 0\n"
        "print(len(t))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert int(done.stdout) > 1000


def test_rays_that_leave_a_triangle_with_one_whole_side_are_refused():
    """Kept-whole edges must bound layer columns and fans' first cells: one whole side of
    a triangle (an odd number of nodes round it) is refused as a broken contract."""
    from deformesh_cli.errors import ContractError
    from deformesh_cli.mesh import Mesh

    pts = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    tri = np.array([[0, 1, 2], [0, 2, 3]])
    lines = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])
    mesh = Mesh(pts, tri, lines, n_contour=4)
    assert len(quads.subdivide(mesh)[0].quads) == 6
    none = np.zeros(0, dtype=np.int64)
    cols = quads.Columns(np.array([[0, 2]]), none, none, np.zeros(1, dtype=np.int64))
    with pytest.raises(ContractError, match="neither a layer's nor a fan's"):
        quads.subdivide(mesh, (), cols)
