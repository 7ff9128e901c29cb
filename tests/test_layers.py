"""Boundary layers (``--layers``): stacks on the walls' normals, shortened never tangled."""

from __future__ import annotations

import json

import meshio
import numpy as np
import pytest

from deformesh_cli import layers, pipeline, quality
from deformesh_cli.contour import make_contour
from deformesh_cli.errors import OptionError, SelectionError
from deformesh_cli.options import MeshOptions
from deformesh_cli.readers import load_contour

from .conftest import SAMPLES
from .independent import contract_problems
from .random_polygons import catalogue

NACA = SAMPLES / "naca0012.csv"
FAR = (-20.0, -20.0, 21.0, 20.0)
NACA_LAYERS = {
    "layers": 30,
    "first_height": 1e-5,
    "layer_growth": 1.15,
    "exterior": True,
    "box": FAR,
}


def _convex(points: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """Per quad: every corner turns left (numpy only)."""
    q = points[quads]
    e = np.roll(q, -1, axis=1) - q
    f = np.roll(e, -1, axis=1)
    return (e[:, :, 0] * f[:, :, 1] - e[:, :, 1] * f[:, :, 0] > 0).all(axis=1)


def _cells_area(points: np.ndarray, triangles: np.ndarray, quads: np.ndarray) -> float:
    total = 0.0
    for cells in (triangles, quads):
        x, y = points[cells, 0], points[cells, 1]
        total += 0.5 * float((x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y).sum())
    return total


@pytest.fixture(scope="module")
def naca():
    c = load_contour(str(NACA))
    return c, pipeline.mesh_contour(c, MeshOptions(**NACA_LAYERS))


def test_naca_layers_keep_the_points_and_their_normals(naca):
    c, res = naca
    mesh, rep = res.mesh, res.report["layers"]
    assert np.array_equal(mesh.points[: c.n], c.points)  # every contour point a node
    assert _convex(mesh.points, mesh.quads).all()
    x0, y0, x1, y1 = FAR
    area = (x1 - x0) * (y1 - y0) - c.area
    assert abs(_cells_area(mesh.points, mesh.triangles, mesh.quads) - area) < 1e-9 * area
    assert rep["min_wall_angle"] >= 80.0
    assert rep["fans"] >= 2  # (the blunt trailing edge's two corners)
    # the first height within 1% of H at every stack that was not shortened
    st = layers.build(c, layers.LayerSpec(30, 1e-5, 1.15), True, FAR)
    full = st.share == 1.0
    assert full.sum() > 0.9 * len(full)
    first = st.nodes.reshape(len(st.wall), 30, 2)[:, 0] - c.points[st.wall]
    h = np.hypot(first[:, 0], first[:, 1])
    assert np.all(np.abs(h[full] - 1e-5) <= 0.01 * 1e-5)
    # every layer node lies on its wall point's normal, in order
    along = (st.nodes.reshape(len(st.wall), 30, 2) - c.points[st.wall][:, None]) @ np.array(
        [[1.0, 0.0], [0.0, 1.0]]
    )
    cross = along[:, :, 0] * st.direction[:, None, 1] - along[:, :, 1] * st.direction[:, None, 0]
    assert np.abs(cross).max() < 1e-12
    dist = np.hypot(along[:, :, 0], along[:, :, 1])
    assert (np.diff(dist, axis=1) > 0).all()


def test_heights_grow_by_the_ratio():
    h = layers.LayerSpec(5, 0.1, 1.5).heights()
    assert h[0] == 0.0 and h[1] == pytest.approx(0.1)
    assert np.allclose(np.diff(h)[1:] / np.diff(h)[:-1], 1.5)
    assert np.allclose(layers.LayerSpec(4, 0.2, 1.0).heights(), [0, 0.2, 0.4, 0.6, 0.8])


def test_a_square_body_gets_fans_at_its_corners_and_none_inside():
    sq = make_contour(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float))
    out = layers.build(sq, layers.LayerSpec(3, 0.01), exterior=True, box=(-3, -3, 4, 4))
    assert out.fans == 4
    assert len(out.triangles) == 4 * 6  # (90 degrees in steps of at most 15: 6 each)
    inside = layers.build(sq, layers.LayerSpec(3, 0.01), exterior=False)
    assert inside.fans == 0 and len(inside.triangles) == 0
    assert len(inside.wall) == 4


def test_cells_are_counter_clockwise_and_convex_on_a_slot():
    c = load_contour(str(SAMPLES / "slot.csv"))
    res = pipeline.mesh_contour(c, MeshOptions(layers=10, first_height=0.002))
    mesh = res.mesh
    assert res.report["layers"]["shortened_stacks"] > 0  # (in the slot)
    assert _convex(mesh.points, mesh.quads).all()
    split = np.concatenate([mesh.triangles, mesh.quads[:, [0, 1, 2]], mesh.quads[:, [0, 2, 3]]])
    assert contract_problems(mesh.points, split, c.points, c.ring) == []


def test_two_bodies_close_together_shorten_and_mesh():
    c = load_contour(str(SAMPLES / "two_bodies.csv"))
    o = MeshOptions(layers=10, first_height=0.002, exterior=True, box=(-3, -2, 4, 2))
    res = pipeline.mesh_contour(c, o)
    assert res.report["layers"]["shortened_stacks"] > 0
    assert _convex(res.mesh.points, res.mesh.quads).all()
    # the stacks across the gap (0.1 wide) leave a fifth of it between their tops
    st = layers.build(c, layers.LayerSpec(10, 0.002), True, (-3, -2, 4, 2))
    full = float(layers.LayerSpec(10, 0.002).heights()[-1])
    x, y = c.points[st.wall].T
    at_gap = np.flatnonzero((np.abs(x - 0.55) < 0.06) & (np.abs(y) < 1e-9))
    assert len(at_gap) == 2
    assert (st.share[at_gap] * full <= 0.4 * 0.1 + 1e-12).all()


@pytest.mark.parametrize(
    "sample, args",
    [("slot.csv", []), ("two_bodies.csv", ["--exterior", "--box=-3,-2,4,2"])],
)
def test_a_gap_under_twice_the_first_height_is_refused_in_one_line(run, tmp_path, sample, args):
    out = tmp_path / "m.vtk"
    r = run("all", SAMPLES / sample, *args, "--layers", 5, "--first-height", 0.06, "-o", out)
    assert r.exit_code == 1
    assert "do not fit near (" in r.stderr and "0.1 wide there" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert not out.exists()


def _random_outcomes(exterior: bool):
    ok = refused = 0
    for name, p, ring in catalogue(100):
        starts = np.flatnonzero(np.r_[True, ring[1:] != ring[:-1]]).tolist()
        c = make_contour(p, source=name, ring_starts=starts)
        size = float(np.ptp(p, axis=0).max())
        o = MeshOptions(layers=5, first_height=0.01 * size, exterior=exterior)
        try:
            res = pipeline.mesh_contour(c, o)
        except SelectionError as exc:
            assert "boundary layers of first height" in str(exc) and "do not fit" in str(exc)
            refused += 1
            continue
        quads_only = pipeline.mesh_contour(c, o.replace(cells="quad-only")).mesh
        for mesh in (res.mesh, quads_only):
            assert _convex(mesh.points, mesh.quads).all(), name
            assert np.array_equal(mesh.points[: c.n], c.points), name
            if not exterior:
                split = np.concatenate(
                    [mesh.triangles, mesh.quads[:, [0, 1, 2]], mesh.quads[:, [0, 2, 3]]]
                )
                assert contract_problems(mesh.points, split, c.points, ring) == [], name
        assert len(quads_only.triangles) == 0, name
        ok += 1
    return ok, refused


@pytest.mark.parametrize("exterior, counts", [(False, (37, 63)), (True, (38, 62))])
def test_random_polygons_mesh_or_are_refused_where_layers_cannot_fit(exterior, counts):
    """Each polygon meshes with the contract holding (every quad convex), also in quads
    alone, or is refused in one line naming where the layers cannot fit; none folds.
    The counts are this construction's on these polygons (their thin parts refuse): a
    change is a change of the construction, to be looked at."""
    assert _random_outcomes(exterior) == counts


def test_layer_cells_tri_splits_every_quad(naca):
    c, res = naca
    tri = pipeline.mesh_contour(c, MeshOptions(**NACA_LAYERS, layer_cells="tri")).mesh
    assert len(tri.quads) == 0
    assert len(tri.triangles) == len(res.mesh.triangles) + 2 * len(res.mesh.quads)
    quality.check_contract(tri, c, FAR)
    assert np.array_equal(tri.points, res.mesh.points)


@pytest.mark.parametrize("suffix", [".vtk", ".vtu", ".msh", ".su2", ".obj", ".ply"])
def test_every_format_holds_the_quads(run, tmp_path, suffix):
    out = tmp_path / f"m{suffix}"
    args = ["--layers", 4, "--first-height", 0.01, "-o", out, "-q"]
    assert run("all", SAMPLES / "circle.csv", *args).exit_code == 0
    m = meshio.read(out)
    kinds = {c.type: len(c.data) for c in m.cells}
    assert kinds["quad"] == 4 * 64
    assert np.array_equal(m.points[:64, :2], load_contour(str(SAMPLES / "circle.csv")).points)


def test_msh_41_holds_the_quads(run, tmp_path):
    out = tmp_path / "m.msh"
    args = ["--layers", 4, "--first-height", 0.01, "--msh-version", "4.1", "-o", out, "-q"]
    assert run("all", SAMPLES / "circle.csv", *args).exit_code == 0
    kinds = {c.type: len(c.data) for c in meshio.read(out).cells}
    assert kinds["quad"] == 4 * 64


def test_json_reports_the_layers(run, tmp_path):
    out = tmp_path / "m.vtk"
    r = run("all", SAMPLES / "circle.csv", "--layers", 3, "--first-height", 0.01, "-o", out,
            "--json", "-q")  # fmt: skip
    rec = json.loads(r.stdout)
    assert rec["quads"] == 3 * 64
    assert rec["layers"]["stacks"] == 64 and rec["layers"]["fans"] == 0
    assert rec["layers"]["first_height_max"] == pytest.approx(0.01)


def test_the_same_bytes_twice(run, tmp_path):
    a, b = tmp_path / "a.vtk", tmp_path / "b.vtk"
    for out in (a, b):
        run("all", NACA, "--exterior", "--layers", 8, "--first-height", 1e-4, "-o", out, "-q")
    assert a.read_bytes() == b.read_bytes()


@pytest.mark.parametrize(
    "args, message",
    [
        (["--layers", 3], "--first-height"),
        (["--layers", 3, "--first-height", 0.01, "--layers-on", "hole_9"], "hole_9"),
        (["--layers", 3, "--first-height", 0.01, "--layer-growth", 0.5], "--layer-growth"),
        (["--layers", 3, "--first-height", 0.01, "--max-h", 0.1], "--max-h"),
        (["--layers", 3, "--first-height", 0.01, "--merge-extra", "keep"], "--merge-extra"),
        (["--layers", 1001, "--first-height", 0.01], "--layers"),
        (["--layers", 3, "--first-height", "nan"], "--first-height"),
        (["--layers", 3, "--first-height", 0.01, "--layer-growth", "inf"], "--layer-growth"),
        (["--layers", 400, "--first-height", 0.01, "--layer-growth", 10], "overflows"),
    ],
)
def test_bad_layer_options_are_usage_errors(run, tmp_path, args, message):
    out = tmp_path / "m.vtk"
    r = run("all", SAMPLES / "circle.csv", *args, "-o", out)
    assert r.exit_code == 2
    assert message in r.stderr
    assert not out.exists()


def test_layers_on_picks_the_rings():
    c = load_contour(str(SAMPLES / "two_bodies.csv"))
    o = MeshOptions(layers=3, first_height=0.002, exterior=True, layers_on="contour_2")
    res = pipeline.mesh_contour(c, o)
    st = res.report["layers"]
    assert st["stacks"] == 80  # (the second circle's points only)


def test_growth_that_overflows_is_refused():
    with pytest.raises(OptionError):
        layers.LayerSpec(1000, 1.0, 1e10).heights()


@pytest.fixture(scope="module")
def circle_files(tmp_path_factory):
    """The circle with 4 layers, quads and split, in .msh 2.2, 4.1 and .vtu/.vtk."""
    from deformesh_cli import formats

    d = tmp_path_factory.mktemp("layers")
    c = load_contour(str(SAMPLES / "circle.csv"))
    out = {}
    for cells in layers.LAYER_CELLS:
        mesh = pipeline.mesh_contour(
            c, MeshOptions(layers=4, first_height=0.01, layer_cells=cells)
        ).mesh
        for name, version in (("m22.msh", "2.2"), ("m41.msh", "4.1"), ("m.vtu", None),
                              ("m.vtk", None), ("m.su2", None)):  # fmt: skip
            path = d / f"{cells}_{name}"
            formats.write_mesh(mesh, str(path), msh_version=version or "2.2")
            out[cells, name] = (path, mesh)
    return out


@pytest.mark.parametrize("name", ["m22.msh", "m41.msh"])
def test_gmsh_reads_the_quads_and_the_groups(circle_files, name):
    import gmsh  # the test extra installs it

    path, mesh = circle_files["quad", name]
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(path))
        kinds, tags, _ = gmsh.model.mesh.getElements(2)
        count = dict(zip(kinds.tolist(), [len(t) for t in tags]))
        names = {gmsh.model.getPhysicalName(d, t) for d, t in gmsh.model.getPhysicalGroups()}
    finally:
        gmsh.finalize()
    assert count == {2: len(mesh.triangles), 3: len(mesh.quads)}
    assert {"contour", "domain"} <= names


@pytest.mark.parametrize("name", ["m22.msh", "m41.msh", "m.vtu"])
def test_scikit_fem_reads_the_split_layers_with_their_boundary(circle_files, name):
    import skfem

    path, mesh = circle_files["tri", name]
    m = skfem.MeshTri.load(str(path))
    assert m.nelements == len(mesh.triangles)
    assert np.array_equal(m.p.T, mesh.points)
    assert "contour" in m.boundaries and len(m.boundaries["contour"]) == 64


@pytest.mark.parametrize("name", ["m.vtu", "m.vtk"])
def test_vtk_reads_both_cell_types(circle_files, name):
    import vtk

    path, mesh = circle_files["quad", name]
    r = (
        vtk.vtkXMLUnstructuredGridReader()
        if name.endswith("vtu")
        else (vtk.vtkUnstructuredGridReader())
    )
    r.SetFileName(str(path))
    r.Update()
    g = r.GetOutput()
    kinds = [g.GetCellType(k) for k in range(g.GetNumberOfCells())]
    assert kinds.count(vtk.VTK_QUAD) == len(mesh.quads)
    assert kinds.count(vtk.VTK_TRIANGLE) == len(mesh.triangles)


def test_meshio_reads_the_su2_quads(circle_files):
    path, mesh = circle_files["quad", "m.su2"]
    kinds = {c.type: len(c.data) for c in meshio.read(path).cells}
    assert kinds["quad"] == len(mesh.quads) and kinds["triangle"] == len(mesh.triangles)


def test_quality_measures_the_layers_and_checks_the_contract(run, circle_files):
    path, mesh = circle_files["quad", "m.vtu"]
    r = run("quality", path, "--contour", SAMPLES / "circle.csv", "--first-height", 0.01,
            "--json")  # fmt: skip
    assert r.exit_code == 0, r.stderr
    rep = json.loads(r.stdout)
    lay = rep["layers"]
    assert rep["contract"] == "ok" and rep["quads"] == len(mesh.quads)
    assert rep["quad_quality"]["non_convex"] == 0 and lay["stacks"] == 64 and lay["fans"] == 0
    assert lay["first_height_within_1pct"] == 64
    assert lay["growth_min"] == pytest.approx(1.2) and lay["growth_max"] == pytest.approx(1.2)
    assert lay["min_wall_angle"] == pytest.approx(90.0 - 360.0 / 64 / 2)  # (the bisector)
    total = _cells_area(mesh.points, mesh.triangles, mesh.quads)
    assert rep["area"] == pytest.approx(total, rel=1e-12)
    text = run("quality", path, "--first-height", 0.01).stdout
    assert "quads: 0 not convex" in text and "layers: 64 stacks" in text
    plain = run("quality", path).stdout  # (no stacks read into quads without H)
    assert "quads: 0 not convex" in plain and "stacks" not in plain


def test_quality_finds_a_quad_that_is_not_convex(run, tmp_path, circle_files):
    from deformesh_cli import formats

    _, mesh = circle_files["quad", "m.vtu"]
    bent = mesh.points.copy()
    q = mesh.quads[0]
    bent[q[2]] = bent[q[0]] + 0.01 * (bent[q[2]] - bent[q[0]])  # (corner 2 pulled in past 0-1-3)
    path = tmp_path / "bent.vtu"
    from dataclasses import replace

    formats.write_mesh(replace(mesh, points=bent), str(path))
    r = run("quality", path)
    assert r.exit_code == 1 and "not convex" in r.stderr


def test_plot_draws_the_quads(run, tmp_path, circle_files):
    path, _ = circle_files["quad", "m.vtu"]
    png = tmp_path / "m.png"
    assert run("plot", path, "-o", png).exit_code == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_adapt_carries_the_layers(run, tmp_path, circle_files):
    path, _ = circle_files["quad", "m.vtu"]
    out = tmp_path / "a.vtu"
    r = run("adapt", path, "-o", out, "--monitor", "1 + x*x", "-q")
    assert r.exit_code == 0, r.stderr
    before, after = meshio.read(path), meshio.read(out)
    assert np.array_equal(before.cells_dict["quad"], after.cells_dict["quad"])
    assert _convex(after.points[:, :2], after.cells_dict["quad"]).all()


def test_move_carries_the_layers(run, tmp_path):
    """The pulsating peanut with 5 layers: the same cells in every frame, every quad
    convex (checked by move's contract on each frame), the stacks' nodes still stacked."""
    mesh = tmp_path / "m.vtu"
    args = ["--layers", 5, "--first-height", 0.01, "-o", mesh, "-q"]
    assert run("all", SAMPLES / "peanut.csv", *args).exit_code == 0
    frames = sorted((SAMPLES / "pulsating").glob("frame_*.csv"))
    r = run("move", mesh, *frames, "--out-dir", tmp_path / "o", "-q")
    assert r.exit_code == 0, r.stderr
    first, last = meshio.read(mesh), meshio.read(tmp_path / "o" / f"m_{len(frames):04d}.vtu")
    assert np.array_equal(first.cells_dict["quad"], last.cells_dict["quad"])
    assert _convex(last.points[:, :2], last.cells_dict["quad"]).all()


def test_a_top_whose_ear_would_leave_a_needle_meshes():
    """sonar.svg (simple-icons) with layers: its layers' top has a sharp corner whose
    ear, cut, leaves a corner of 4 degrees that is no ear; the corner is kept, and the
    mesh is made."""
    from .conftest import DATA

    c = load_contour(str(DATA / "layers" / "sonar.svg"))
    size = float(np.ptp(c.points, axis=0).max())
    res = pipeline.mesh_contour(c, MeshOptions(layers=10, first_height=1e-3 * size))
    assert res.report["contract"] == "ok"
    assert _convex(res.mesh.points, res.mesh.quads).all()


def test_stacks_that_cross_stop_half_way_to_the_crossing():
    """Two stacks whose segments cross (not neighbours: a wedge's two sides) each reach at
    most half the way to the crossing; stacks that do not cross, and a fan's (one wall
    point), keep their lengths."""
    start = np.array([[0.0, 0.0], [2.0, 0.0], [5.0, 0.0], [5.0, 0.0]])
    d = np.array([[0.6, 0.8], [-0.6, 0.8], [0.0, 1.0], [0.6, 0.8]])
    d = d / np.hypot(d[:, 0], d[:, 1])[:, None]
    bound = np.array([3.0, 3.0, 3.0, 3.0])
    out = layers._crossing_bounds(start, d, bound, np.array([0, 1, 2, 2]))
    # the first two meet at (1, 4/3), 5/3 along each
    assert out[0] == pytest.approx(0.5 * 5.0 / 3.0) and out[1] == pytest.approx(0.5 * 5.0 / 3.0)
    assert out[2] == 3.0 and out[3] == 3.0
    short = layers._crossing_bounds(start, d, np.array([1.0, 1.0, 3.0, 3.0]), np.arange(4))
    assert short[0] == 1.0 and short[1] == 1.0  # (they end before they meet)


@pytest.mark.parametrize("grid", [["--h", "0.05"], ["--grid", "uniform"]])
def test_layers_on_the_uniform_grid_take_the_extra_nodes_out(run, tmp_path, grid):
    """The paper's grid keeps extra boundary nodes; under layers they would sit between
    the top nodes, so the core takes them out: the layers' top is its boundary."""
    out = tmp_path / "m.vtu"
    r = run("all", SAMPLES / "circle.csv", "--layers", 3, "--first-height", 0.01, *grid,
            "-o", out, "--json", "-q")  # fmt: skip
    assert r.exit_code == 0, r.stderr
    rec = json.loads(r.stdout)
    assert rec["contract"] == "ok" and rec["extra_boundary_nodes"] == 0 and rec["quads"] == 192


@pytest.mark.parametrize(
    "sample, args",
    [
        ("naca0012.csv", ["--exterior", "--box=-20,-20,21,20", "--layers", 30,
                          "--first-height", 1e-5, "--layer-growth", 1.15]),
        ("slot.csv", ["--layers", 10, "--first-height", 0.002, "--layer-cells", "tri"]),
        ("circle.csv", ["--exterior", "--box=-3,-3,4,3"]),  # (a far field given tight)
    ],
)  # fmt: skip
def test_the_stages_give_alls_bytes(run, tmp_path, sample, args):
    """select | deform | triangulate records the layer options and gives ``all``'s mesh
    byte for byte (and so does a far field in a given box, whose sides the coarsening's
    sizes see in both)."""
    a, s, d, b = (tmp_path / n for n in ("a.vtk", "s.state", "d.state", "b.vtk"))
    assert run("all", SAMPLES / sample, *args, "-o", a, "-q").exit_code == 0
    assert run("select", SAMPLES / sample, *args, "-o", s, "-q").exit_code == 0
    assert run("deform", s, "-o", d, "-q").exit_code == 0
    assert run("triangulate", d, "-o", b, "-q").exit_code == 0
    assert a.read_bytes() == b.read_bytes()


def test_the_stages_give_alls_bytes_in_quads_alone(run, tmp_path):
    """``--cells quad-only`` given to stage 3: the layers kept whole there too."""
    args = ["--layers", 10, "--first-height", 0.002]
    a, s, d, b = (tmp_path / n for n in ("a.vtk", "s.state", "d.state", "b.vtk"))
    slot = SAMPLES / "slot.csv"
    assert run("all", slot, *args, "--cells", "quad-only", "-o", a, "-q").exit_code == 0
    assert run("select", slot, *args, "-o", s, "-q").exit_code == 0
    assert run("deform", s, "-o", d, "-q").exit_code == 0
    assert run("triangulate", d, "--cells", "quad-only", "-o", b, "-q").exit_code == 0
    assert a.read_bytes() == b.read_bytes()
    s2, d2 = tmp_path / "s2.state", tmp_path / "d2.state"
    assert run("select", slot, *args, "--layer-cells", "tri", "-o", s2).exit_code == 0
    assert run("deform", s2, "-o", d2, "-q").exit_code == 0
    r = run("triangulate", d2, "--cells", "quad-only", "-o", tmp_path / "c.vtk")
    assert r.exit_code == 2 and "--layer-cells tri" in r.stderr
    assert not (tmp_path / "c.vtk").exists()


def test_a_ring_too_narrow_for_one_first_layer_is_refused(run, tmp_path):
    """Inside the unit circle every stack converges on the centre (none thicker than
    half the radius): a first height of 0.9 fits nowhere, which no point's clearance
    shows (the far side is the same part of the ring)."""
    out = tmp_path / "m.vtk"
    r = run("all", SAMPLES / "circle.csv", "--layers", 3, "--first-height", 0.9, "-o", out)
    assert r.exit_code == 1 and "do not fit on contour" in r.stderr
    assert "no stack there can be thicker than 0.5" in r.stderr and not out.exists()


def test_a_shortened_stack_keeps_its_first_height_and_grows_less():
    """Stacks of thickness T: the full one grows by R; one between N H and the full one
    keeps H and grows by less (the same ratio layer to layer); one under N H has N equal
    layers; every stack ends at its thickness."""
    spec = layers.LayerSpec(10, 0.01, 1.2)
    full = float(spec.heights()[-1])
    thick = np.array([full, 0.5 * (full + 0.1), 0.1, 0.05])
    h = layers.stack_heights(spec, thick)
    assert np.allclose(h[0], spec.heights())
    assert h[1, 1] == pytest.approx(0.01) and h[2, 1] == pytest.approx(0.01)
    ratio = np.diff(h[1])[1:] / np.diff(h[1])[:-1]
    assert np.allclose(ratio, ratio[0]) and 1.0 < ratio[0] < 1.2
    assert np.allclose(np.diff(h[3]), 0.005)
    assert np.array_equal(h[:, -1], thick) and (np.diff(h, axis=1) > 0).all()


def _edges(cells: np.ndarray) -> set:
    k = cells.shape[1]
    return {tuple(sorted(e)) for j in range(k) for e in cells[:, [j, (j + 1) % k]].tolist()}


@pytest.mark.parametrize(
    "sample, options",
    [
        ("naca0012.csv", NACA_LAYERS),
        ("slot.csv", {"layers": 10, "first_height": 0.002}),
        ("two_bodies.csv", {"layers": 1, "first_height": 0.002, "exterior": True,
                            "box": (-3, -2, 4, 2)}),
    ],
)  # fmt: skip
def test_quad_only_keeps_every_layer_whole(sample, options):
    """``--cells quad-only`` with layers: quads alone, each convex, every node of the
    mixed mesh kept where it was, and every edge leaving the wall (each layer's height
    on each stack) still an edge: the layers are split along the wall only."""
    c = load_contour(str(SAMPLES / sample))
    o = MeshOptions(**options)
    plain = pipeline.mesh_contour(c, o)
    mixed = plain.mesh
    res = pipeline.mesh_contour(c, o.replace(cells="quad-only"))
    mesh = res.mesh
    assert len(mesh.triangles) == 0 and _convex(mesh.points, mesh.quads).all()
    assert np.array_equal(mesh.points[: c.n], c.points)
    at = {tuple(p): k for k, p in enumerate(mesh.points.tolist())}
    old = np.array([at[tuple(p)] for p in mixed.points.tolist()])  # (KeyError: a node lost)
    rays = old[np.concatenate([mixed.quads[:, [0, 3]], mixed.quads[:, [1, 2]]])]
    assert {tuple(sorted(e)) for e in rays.tolist()} <= _edges(mesh.quads)
    total = _cells_area(mesh.points, mesh.triangles, mesh.quads)
    assert total == pytest.approx(_cells_area(mixed.points, mixed.triangles, mixed.quads))
    if not o.exterior:
        split = np.concatenate([mesh.quads[:, [0, 1, 2]], mesh.quads[:, [0, 2, 3]]])
        assert contract_problems(mesh.points, split, c.points, c.ring) == []
    assert res.report["layers"] == plain.report["layers"]


def test_quad_only_fans_are_quads_between_the_fan_step_and_its_supplement():
    """A square body's four fans (six steps of 15 degrees each): their first cells
    become ``2 m - 3`` quads each, no angle under the step or over 180 less it."""
    sq = make_contour(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float))
    o = MeshOptions(layers=3, first_height=0.01, exterior=True, box=(-3, -3, 4, 4))
    mesh = pipeline.mesh_contour(sq, o.replace(cells="quad-only")).mesh
    assert len(mesh.triangles) == 0 and _convex(mesh.points, mesh.quads).all()
    for corner in range(4):  # (seven directions: 2 m - 3 = 11 quads, m - 1 at the corner,
        # and a half column either side)
        assert np.count_nonzero((mesh.quads == corner).any(axis=1)) == 7 - 1 + 2
    q = mesh.points[mesh.quads]
    near = np.abs(q[:, :, None, :] - sq.points[None, None]).max(axis=-1).min(axis=-1)
    q = q[(near <= 0.01 + 1e-12).all(axis=1)]  # (the fans' first cells)
    assert len(q) == 4 * 11
    a, b = np.roll(q, -1, axis=1) - q, np.roll(q, 1, axis=1) - q
    angle = np.degrees(np.arctan2(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
                                  (a * b).sum(axis=-1)))  # fmt: skip
    assert angle.min() >= 15.0 - 1e-9 and angle.max() <= 165.0 + 1e-9


def test_quad_only_with_layers_loads_in_scikit_fem(tmp_path):
    """The layered circle in quads alone loads as scikit-fem's MeshQuad, its contour's
    boundary named (each edge split in two), as the split one loads as MeshTri."""
    import skfem

    from deformesh_cli import formats

    c = load_contour(str(SAMPLES / "circle.csv"))
    mesh = pipeline.mesh_contour(
        c, MeshOptions(layers=4, first_height=0.01, cells="quad-only")
    ).mesh
    for version in ("2.2", "4.1"):
        path = tmp_path / f"m{version}.msh"
        formats.write_mesh(mesh, str(path), msh_version=version)
        m = skfem.MeshQuad.load(str(path))
        assert m.nelements == len(mesh.quads) and np.array_equal(m.p.T, mesh.points)
        assert len(m.boundaries["contour"]) == 2 * 64


def test_quality_reads_the_stacks_of_a_quads_only_mesh_on_its_contour(run, tmp_path):
    """On a mesh of quads alone, with ``--contour``: a stack on every ring node (the
    points and the middles of their edges), each first height within 1% of H, the
    growth the layers' and no step into the core's quads; without it, the box's nodes
    with a single quad above them read as stacks too."""
    out = tmp_path / "m.vtu"
    circle = SAMPLES / "circle.csv"
    r = run("all", circle, "-o", out, "--exterior", "--box=-3,-3,3,3", "--layers", 4,
            "--first-height", 0.01, "--cells", "quad-only", "-q")  # fmt: skip
    assert r.exit_code == 0, r.stderr
    r = run("quality", out, "--contour", circle, "--first-height", 0.01, "--json")
    lay = json.loads(r.stdout)["layers"]
    assert json.loads(r.stdout)["contract"] == "ok"
    assert lay["stacks"] == 2 * 64 and lay["first_height_within_1pct"] == 2 * 64
    assert lay["growth_min"] == pytest.approx(1.2) and lay["growth_max"] == pytest.approx(1.2)
    assert lay["min_wall_angle"] == pytest.approx(90.0 - 360.0 / 64 / 2)
    plain = json.loads(run("quality", out, "--first-height", 0.01, "--json").stdout)
    assert plain["layers"]["stacks"] > 2 * 64


def test_quads_alone_with_fans_pass_scikit_fems_patch_test(tmp_path):
    """A square body's layers and fans in quads alone, loaded as scikit-fem's MeshQuad:
    bilinear elements on it reproduce a linear solution at every node (the patch test:
    every cell a valid element, the connectivity whole)."""
    import skfem
    from skfem.models.poisson import laplace

    from deformesh_cli import formats

    sq = make_contour(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float))
    o = MeshOptions(layers=5, first_height=0.005, exterior=True, box=(-2, -2, 3, 3))
    mesh = pipeline.mesh_contour(sq, o.replace(cells="quad-only")).mesh
    path = tmp_path / "m.msh"
    formats.write_mesh(mesh, str(path), msh_version="4.1")
    m = skfem.MeshQuad.load(str(path))
    basis = skfem.Basis(m, skfem.ElementQuad1())
    A = laplace.assemble(basis)
    exact = m.p[0] + 2.0 * m.p[1]
    uh = skfem.solve(*skfem.condense(A, np.zeros(basis.N), x=exact, D=m.boundary_nodes()))
    assert np.abs(uh - exact).max() < 1e-9
