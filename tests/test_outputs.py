"""Output formats, the quality command and pictures."""

import json
import sys

import meshio
import numpy as np
import pytest

from deformesh_cli.quality import mesh_for_contour
from deformesh_cli.readers import load_contour

from .conftest import SAMPLES, contour_file


@pytest.fixture(scope="module")
def bracket(tmp_path_factory):
    """The SVG sample meshed once: (mesh path, --json record)."""
    from click.testing import CliRunner

    from deformesh_cli.cli import cli

    d = tmp_path_factory.mktemp("bracket")
    out = d / "b.msh"
    r = CliRunner().invoke(cli, ["all", str(SAMPLES / "bracket.svg"), "-o", str(out), "--json"])
    assert r.exit_code == 0, r.stderr
    return out, json.loads(r.stdout)


def test_su2_has_a_marker_per_boundary_and_meshio_reads_it(run, tmp_path, bracket):
    out = tmp_path / "b.su2"
    assert run("all", SAMPLES / "bracket.svg", "-o", out, "-q").exit_code == 0
    text = out.read_text().splitlines()
    assert "NDIME= 2" in text
    tags = [ln.split("=")[1].strip() for ln in text if ln.startswith("MARKER_TAG=")]
    assert tags == ["contour", "hole_1"]
    counts = [int(ln.split("=")[1]) for ln in text if ln.startswith("MARKER_ELEMS=")]
    m = meshio.read(out)
    ref = meshio.read(bracket[0])
    assert np.array_equal(m.points[:, :2], ref.points[:, :2])
    assert np.array_equal(m.cells_dict["triangle"], ref.cells_dict["triangle"])
    assert sum(counts) == len(m.cells_dict["line"]) == bracket[1]["boundary_nodes"]


def test_exterior_su2_has_the_box_sides(run, tmp_path):
    out = tmp_path / "n.su2"
    r = run(
        "all", contour_file("naca0012_100.csv"), "--exterior", "--box=-2,-2,3,2", "-o", out, "-q"
    )
    assert r.exit_code == 0, r.stderr
    tags = [
        ln.split("=")[1].strip()
        for ln in out.read_text().splitlines()
        if ln.startswith("MARKER_TAG=")
    ]
    assert tags == ["contour", "bottom", "right", "top", "left"]


def test_ply_is_planar_and_byte_identical_on_rerun(run, tmp_path, bracket):
    a, b = tmp_path / "a.ply", tmp_path / "b.ply"
    for out in (a, b):
        assert run("all", SAMPLES / "bracket.svg", "-o", out, "-q").exit_code == 0
    assert a.read_bytes() == b.read_bytes()
    m = meshio.read(a)
    assert (m.points[:, 2] == 0).all()
    assert np.array_equal(m.cells_dict["triangle"], meshio.read(bracket[0]).cells_dict["triangle"])


def test_xdmf_writes_its_sidecar_and_reads_back(run, tmp_path, bracket):
    out = tmp_path / "b.xdmf"
    assert run("all", SAMPLES / "bracket.svg", "-o", out, "-q").exit_code == 0
    assert (tmp_path / "b.h5").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.h5", "b.xdmf"]  # no temporaries
    m = meshio.read(out)
    tags = m.cell_data_dict["group"]
    assert set(tags["line"]) == {1, 2} and set(tags["triangle"]) == {3}
    assert len(m.cells_dict["triangle"]) == bracket[1]["triangles"]


def test_xdmf_without_h5py_fails_cleanly(run, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "h5py", None)
    out = tmp_path / "b.xdmf"
    r = run("all", SAMPLES / "circle.csv", "-o", out)
    assert r.exit_code == 1 and "needs h5py" in r.stderr
    assert list(tmp_path.iterdir()) == []


def test_xdmf_to_stdout_is_a_usage_error(run):
    r = run("all", SAMPLES / "circle.csv", "-o", "-", "--format", "xdmf")
    assert r.exit_code == 2 and "two files" in r.stderr


# --- quality


@pytest.mark.parametrize("fmt", ["msh", "vtk", "vtu", "obj", "ply", "su2"])
def test_quality_checks_the_contract_in_every_format(run, tmp_path, fmt):
    out = tmp_path / f"m.{fmt}"
    src = contour_file("square_hole_100.csv")
    r = run("all", src, "-o", out, "--json")
    made = json.loads(r.stdout)
    r = run("quality", out, "--contour", src, "--json")
    assert r.exit_code == 0, r.stdout + r.stderr
    rep = json.loads(r.stdout)
    assert rep["contract"] == "ok" and rep["exterior"] is False
    assert rep["triangles"] == made["triangles"]
    assert rep["min_angle"] == pytest.approx(made["min_angle"])
    assert sum(rep["radius_ratio_histogram"]["counts"]) == rep["triangles"]


def test_quality_finds_an_exterior_mesh_and_its_box(run, tmp_path):
    out = tmp_path / "n.msh"
    src = contour_file("naca0012_100.csv")
    assert run("all", src, "--exterior", "--box=-2,-2,3,2", "-o", out, "-q").exit_code == 0
    r = run("quality", out, "--contour", src, "--json")
    assert r.exit_code == 0, r.stdout
    assert json.loads(r.stdout)["exterior"] is True


def _moved(src_mesh, out, fn):
    m = meshio.read(src_mesh)
    fn(m)
    meshio.write(out, m, file_format="vtk")


def test_quality_reports_violations_with_exit_1(run, tmp_path, bracket):
    src = SAMPLES / "bracket.svg"

    def nudge(m):
        m.points[3, 0] += 1e-9

    def fold(m):
        t = m.cells[0].data
        t[0] = t[0][::-1]

    def drop(m):
        m.cells[0].data = m.cells[0].data[1:]

    cases = [(nudge, "node 3 is at"), (fold, "signed area"), (drop, "boundary")]
    for fn, text in cases:
        bad = tmp_path / f"{fn.__name__}.vtk"
        _moved(bracket[0], bad, fn)
        r = run("quality", bad, "--contour", src)
        assert r.exit_code == 1, fn.__name__
        assert "contract: violated" in r.stdout and text in r.stderr, (fn.__name__, r.stderr)
    # a folded triangle is an error even without a contour
    r = run("quality", tmp_path / "fold.vtk")
    assert r.exit_code == 1 and "1 folded triangle" in r.stderr


def test_quality_and_plot_take_quiet(run, tmp_path, bracket):
    """-q: nothing on stdout, errors still one line on stderr with their exit code."""
    r = run("quality", bracket[0], "--contour", SAMPLES / "bracket.svg", "-q")
    assert (r.exit_code, r.stdout, r.stderr) == (0, "", "")
    r = run("quality", bracket[0], "--contour", SAMPLES / "circle.csv", "-q")
    assert r.exit_code == 1 and r.stdout == "" and len(r.stderr.strip().splitlines()) == 1
    r = run("plot", bracket[0], "-o", tmp_path / "p.png", "-q")
    assert (r.exit_code, r.stdout, r.stderr) == (0, "", "")
    assert (tmp_path / "p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_every_subcommand_takes_quiet(run):
    from deformesh_cli.cli import cli

    for name in cli.commands:
        r = run(name, "--help")
        assert "-q, --quiet" in r.stdout, name


def test_quality_against_the_wrong_contour_fails(run, bracket):
    r = run("quality", bracket[0], "--contour", SAMPLES / "circle.csv")
    assert r.exit_code == 1 and "violated" in r.stdout


def test_quality_text_report(run, bracket):
    r = run("quality", bracket[0])
    assert r.exit_code == 0
    lines = r.stdout.splitlines()
    assert lines[0].startswith(f"{bracket[0]}: {bracket[1]['nodes']} nodes")
    assert (
        sum(int(ln.split()[1]) for ln in lines if ln.startswith("  0.")) == bracket[1]["triangles"]
    )
    assert lines[-1] == "contract: unchecked (no --contour)"


@pytest.mark.parametrize(
    "content,text", [(b"garbage", "cannot read mesh|not a mesh"), (None, "no such file")]
)
def test_quality_bad_mesh_file(run, tmp_path, content, text):
    f = tmp_path / "m.vtk"
    if content is not None:
        f.write_bytes(content)
    r = run("quality", f)
    assert r.exit_code == 1 and r.stderr.count("\n") == 1
    assert r.stderr.startswith("deformesh: error:")


def test_mesh_for_contour_rebuilds_groups(bracket):
    m = meshio.read(bracket[0])
    c = load_contour(SAMPLES / "bracket.svg")
    mesh, box = mesh_for_contour(m.points[:, :2], m.cells_dict["triangle"], c)
    assert box is None and mesh.groups == ("contour", "hole_1")
    tags = m.cell_data_dict["gmsh:physical"]["line"]
    # the written group of every boundary edge is the rebuilt one
    written = {tuple(e): t for e, t in zip(m.cells_dict["line"].tolist(), tags)}
    rebuilt = {tuple(e): g + 1 for e, g in zip(mesh.lines.tolist(), mesh.line_group)}
    assert written == rebuilt


# --- pictures


def _png(path):
    import matplotlib.image as mpimg

    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return mpimg.imread(path)


def test_plot_and_png_draw_the_mesh(run, tmp_path, bracket):
    out = tmp_path / "p.png"
    r = run("plot", bracket[0], "-o", out, "--contour", SAMPLES / "bracket.svg")
    assert r.exit_code == 0, r.stderr
    img = _png(out)
    assert img.shape[0] > 500 and img.shape[1] > 800
    # the boundary colour and the quality shades are there, not just a blank canvas
    rgb = (img[..., :3] * 255).round().astype(int)
    blue = np.all(np.abs(rgb - [0x1F, 0x3F, 0xBF]) < 8, axis=-1).sum()
    greens = (rgb[..., 1] > rgb[..., 0] + 40).sum()
    assert blue > 500 and greens > 50_000
    png = tmp_path / "all.png"
    r = run("all", SAMPLES / "bracket.svg", "-o", tmp_path / "m.vtk", "--png", png, "-q")
    assert r.exit_code == 0 and _png(png).shape == img.shape


def test_plot_frames_a_far_fields_body_and_takes_a_window(run, tmp_path):
    mesh = tmp_path / "ff.vtu"
    r = run("all", SAMPLES / "naca0012.csv", "--exterior", "-o", mesh, "-q")
    assert r.exit_code == 0, r.stderr
    shapes = {}
    for name, extra in (
        ("zoomed", []),  # the default: the airfoil (chord 1, thickness 0.12) fills the frame
        ("whole", ["--zoom", "mesh"]),  # the box: about square
        ("window", ["--window", "0.9,-0.05,1.1,0.05", "--colour", "angle"]),
    ):
        out = tmp_path / f"{name}.png"
        r = run("plot", mesh, "-o", out, *extra)
        assert r.exit_code == 0, r.stderr
        shapes[name] = _png(out).shape
    wide = {k: v[1] / v[0] for k, v in shapes.items()}
    assert wide["zoomed"] > wide["whole"] + 0.5 and wide["window"] > wide["whole"] + 0.5
    r = run("plot", mesh, "-o", tmp_path / "bad.png", "--window", "1,0,0,1")
    assert r.exit_code == 2 and "X0 < X1" in r.stderr


def test_plot_draws_edges_finer_the_more_triangles(tmp_path):
    """Every triangle's edges are drawn; the resolution grows with the triangles in view,
    so at 1e5 triangles a triangle is still several pixels across."""
    from deformesh_cli import plot

    def picture(n):  # an n x n grid of squares, each split in two
        x, y = np.meshgrid(np.arange(n + 1.0), np.arange(n + 1.0), indexing="ij")
        k = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)[:-1, :-1].ravel()
        tri = np.concatenate([np.c_[k, k + n + 1, k + n + 2], np.c_[k, k + n + 2, k + 1]])
        path = tmp_path / f"g{n}.png"
        path.write_bytes(plot.render(np.c_[x.ravel(), y.ravel()], tri))
        return _png(path)

    small, large = picture(20), picture(224)  # 800 and 100,352 triangles
    assert large.shape[1] >= 1.6 * small.shape[1]  # (184 dpi against 110)
    # along a row through the grid the edges show as dark pixels between the cells'
    # colour: about one run of dark pixels per cell
    rgb = large[large.shape[0] // 2, :, :3]
    dark = rgb.sum(axis=1) < 1.2
    runs = int(np.count_nonzero(dark[1:] & ~dark[:-1]))
    assert runs > 150, runs


def test_png_without_matplotlib_leaves_no_file(run, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    r = run("all", SAMPLES / "circle.csv", "-o", tmp_path / "m.vtk", "--png", tmp_path / "m.png")
    assert r.exit_code == 1 and "pip install 'deformesh[plot]'" in r.stderr
    assert list(tmp_path.iterdir()) == []


def test_plot_errors(run, tmp_path, bracket):
    r = run("plot", tmp_path / "none.vtk", "-o", tmp_path / "p.png")
    assert r.exit_code == 1 and "no such file" in r.stderr
    r = run("plot", bracket[0], "-o", tmp_path / "nofolder" / "p.png")
    assert r.exit_code == 2 and "does not exist" in r.stderr  # (a usage error)


def test_batch_xdmf_writes_each_sidecar_under_its_own_name(run, tmp_path):
    out = tmp_path / "out"
    r = run(
        "all",
        SAMPLES / "circle.csv",
        SAMPLES / "peanut.csv",
        "--out-dir",
        out,
        "--format",
        "xdmf",
        "-q",
    )
    assert r.exit_code == 0, r.stderr
    assert sorted(p.name for p in out.iterdir()) == [
        "circle.h5",
        "circle.xdmf",
        "peanut.h5",
        "peanut.xdmf",
    ]
    assert "peanut.h5:/" in (out / "peanut.xdmf").read_text()
    m = meshio.read(out / "peanut.xdmf")
    assert len(m.cells_dict["triangle"]) > 500


@pytest.mark.parametrize("exterior", [False, True])
def test_msh22_is_byte_identical_to_meshios_writer(tmp_path, exterior):
    # our writer formats the whole table at once (12 s -> 2 s at a million triangles)
    from deformesh_cli import formats, pipeline

    mesh = pipeline.mesh_contour(load_contour(SAMPLES / "bracket.svg"), exterior=exterior).mesh
    assert len(set(mesh.line_group.tolist())) > 1  # several boundary groups
    formats.write_mesh(mesh, str(tmp_path / "ours.msh"))
    formats.gmsh.write_meshio(mesh, str(tmp_path / "meshio.msh"), "2.2")  # meshio's own writer
    assert (tmp_path / "ours.msh").read_bytes() == (tmp_path / "meshio.msh").read_bytes()


@pytest.mark.parametrize("exterior", [False, True])
def test_vtk_is_meshios_file_but_the_title_and_the_group_names(tmp_path, exterior):
    # our writer skips meshio's import (0.15 s); the bytes are meshio's legacy 4.2
    # writer's, the title line and the dataset's field data (the group names) aside
    from meshio.vtk import _vtk_42

    from deformesh_cli import formats, pipeline
    from deformesh_cli.formats import _common

    mesh = pipeline.mesh_contour(load_contour(SAMPLES / "bracket.svg"), exterior=exterior).mesh
    formats.write_mesh(mesh, str(tmp_path / "ours.vtk"))
    m = _common.meshio_mesh(mesh, dim3=True, cell_data={"group": _common.cell_groups(mesh)})
    _vtk_42.write(tmp_path / "meshio.vtk", m, binary=True)
    table = _common.group_table(mesh)
    field = f"FIELD FieldData {len(table)}\n".encode() + b"".join(
        f"{name} 2 1 int\n".encode() + tag.astype(">i4").tobytes() + b"\n"
        for name, tag in table.items()
    )
    data = (tmp_path / "ours.vtk").read_bytes()
    assert data.count(b"UNSTRUCTURED_GRID\n" + field) == 1
    ours = data.replace(field, b"", 1).split(b"\n", 2)
    theirs = (tmp_path / "meshio.vtk").read_bytes().split(b"\n", 2)
    assert ours[1] == formats.vtk.TITLE.encode() and theirs[1].startswith(b"written by meshio")
    assert ours[0] == theirs[0] and ours[2] == theirs[2]
    back = meshio.read(tmp_path / "ours.vtk")
    assert np.array_equal(back.points[:, :2], mesh.points)
    assert np.array_equal(back.cells_dict["triangle"], mesh.triangles)
    assert np.array_equal(back.cells_dict["line"], mesh.lines)
    assert np.array_equal(
        back.point_data["contour_point"][: mesh.n_contour], np.arange(mesh.n_contour)
    )
    assert np.array_equal(back.cell_data["group"][1], mesh.line_group + 1)


@pytest.mark.parametrize("fmt", ["vtk", "vtu"])
@pytest.mark.parametrize("exterior", [False, True])
def test_vtk_reads_the_point_data_and_the_boundary_groups(tmp_path, fmt, exterior):
    """VTK's own readers (the ``vtk`` package, as ParaView uses): every node, cell,
    ``contour_point`` and ``group`` (the .msh physical tags: which edge is
    ``hole_1``, which a box side)."""
    import vtk  # the test extra installs it
    from vtk.util.numpy_support import vtk_to_numpy

    from deformesh_cli import formats, pipeline
    from deformesh_cli.formats._common import groups

    c = load_contour(contour_file("square_hole_100.csv"))
    mesh = pipeline.mesh_contour(c, exterior=exterior).mesh
    path = tmp_path / f"m.{fmt}"
    formats.write_mesh(mesh, str(path))
    r = vtk.vtkUnstructuredGridReader() if fmt == "vtk" else vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(str(path))
    if fmt == "vtk":
        r.ReadAllScalarsOn()
        r.ReadAllFieldsOn()
    r.Update()
    g = r.GetOutput()
    nt, nl = len(mesh.triangles), len(mesh.lines)
    assert (g.GetNumberOfPoints(), g.GetNumberOfCells()) == (mesh.n_nodes, nt + nl)
    assert np.array_equal(vtk_to_numpy(g.GetPoints().GetData())[:, :2], mesh.points)
    cp = vtk_to_numpy(g.GetPointData().GetArray("contour_point"))
    assert np.array_equal(cp[: mesh.n_contour], np.arange(mesh.n_contour))
    assert (cp[mesh.n_contour :] == -1).all()
    tags = vtk_to_numpy(g.GetCellData().GetArray("group"))
    named = groups(mesh)
    assert (tags[:nt] == named["domain"][0]).all()
    assert np.array_equal(tags[nt:], mesh.line_group + 1)
    assert named["hole_1"][0] in tags[nt:]
    if exterior:
        assert {named[s][0] for s in ("bottom", "right", "top", "left")} <= set(tags[nt:].tolist())
    # which tag is which boundary: the names in the dataset's field data (ParaView shows
    # them; pyvista's field_data reads them), each with its (tag, dimension)
    fd = g.GetFieldData()
    names = {fd.GetArrayName(i): vtk_to_numpy(fd.GetArray(i)).ravel().tolist()
             for i in range(fd.GetNumberOfArrays())}  # fmt: skip
    assert names == {name: list(v) for name, v in named.items()}


def test_edge_uses_counts_each_undirected_edge():
    # against a plain dictionary count, on a soup with shared, repeated and lone edges
    from collections import Counter

    from deformesh_cli.geometry import boundary_edges, edge_uses

    rng = np.random.default_rng(3)
    tri = rng.integers(0, 15, (40, 3))
    tri = tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])]
    directed = Counter(
        map(tuple, np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]).tolist())
    )
    lo, hi, fwd, rev = edge_uses(tri, 15)
    assert (lo < hi).all()
    assert len(set(zip(lo.tolist(), hi.tolist()))) == len(lo)  # each edge once
    assert {(a, b) for a, b in directed} | {(b, a) for a, b in directed} == set(
        zip(lo.tolist(), hi.tolist())
    ) | set(zip(hi.tolist(), lo.tolist()))
    assert fwd.tolist() == [directed[(a, b)] for a, b in zip(lo.tolist(), hi.tolist())]
    assert rev.tolist() == [directed[(b, a)] for a, b in zip(lo.tolist(), hi.tolist())]
    assert {1, 2}.issubset(set((fwd + rev).tolist())) and (fwd + rev).max() > 2
    assert (fwd > 1).any()  # the soup walks some edge twice the same way
    lone = {e for e, k in directed.items() if k == 1 and directed[e[::-1]] == 0}
    assert set(map(tuple, boundary_edges(tri, 15).tolist())) == lone


def test_measures_match_the_angles_at_every_corner():
    # the law-of-cosines shortcut against arctan2 at each corner, random and sliver triangles
    from deformesh_cli.quality import measures

    rng = np.random.default_rng(5)
    pts = rng.random((3000, 2))
    tri = rng.integers(0, 3000, (5000, 3))
    tri = tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])]
    sliver = np.array([(0.0, 0.0), (1.0, 0.0), (0.5, 1e-8), (0.0, 1e-8)])
    pts = np.vstack([pts, sliver])
    tri = np.vstack([tri, [[3000, 3001, 3002], [3000, 3001, 3003]]])
    corners = pts[tri]
    ang = []
    for k in range(3):
        u = corners[:, (k + 1) % 3] - corners[:, k]
        v = corners[:, (k + 2) % 3] - corners[:, k]
        ang.append(
            np.degrees(
                np.arctan2(np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]), (u * v).sum(axis=1))
            )
        )
    ang = np.column_stack(ang)
    smallest, largest, _, rr = measures(pts, tri)
    assert np.allclose(smallest, ang.min(axis=1), rtol=1e-9, atol=1e-12)
    assert np.allclose(largest, ang.max(axis=1), rtol=1e-12, atol=1e-12)
    assert smallest[-2] == pytest.approx(np.degrees(2e-8), rel=1e-6)  # the slivers
    assert largest[-2] == pytest.approx(180 - 2 * np.degrees(2e-8), rel=1e-12)
    assert smallest[-1] == pytest.approx(np.degrees(1e-8), rel=1e-6)
    assert np.allclose(rr[:-2][ang.min(axis=1)[:-2] > 59.9], 1.0, atol=1e-2)
    assert (rr >= 0).all() and (rr <= 1 + 1e-12).all()


@pytest.mark.parametrize("full", ["png", "mesh"])
def test_a_full_disk_leaves_neither_the_mesh_nor_the_picture(run, tmp_path, monkeypatch, full):
    """ENOSPC while writing the picture, or the mesh after it: one line naming the file,
    exit 1, and no file at all in the output folder (both or neither)."""
    import errno
    import io

    from deformesh_cli import files

    class Full(io.BytesIO):  # a file on a full disk: its write fails
        def write(self, data):
            raise OSError(errno.ENOSPC, "No space left on device")

    def open_(path, mode="r", *args, **kw):  # the staged picture is .m.png.*.tmp
        if full == "png" and ".m.png." in str(path) and "w" in mode:
            return Full()
        return open(path, mode, *args, **kw)

    monkeypatch.setattr(files, "open", open_, raising=False)
    if full == "mesh":  # the .vtk writer writes its file itself: fail it there
        import dataclasses

        from deformesh_cli.formats import FORMATS

        def full_disk(mesh, path, version=None):
            raise OSError(errno.ENOSPC, "No space left on device")

        monkeypatch.setitem(FORMATS, "vtk", dataclasses.replace(FORMATS["vtk"], write=full_disk))
    out = tmp_path / "out"
    out.mkdir()
    r = run("all", SAMPLES / "circle.csv", "-o", out / "m.vtk", "--png", out / "m.png")
    assert r.exit_code == 1 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert "No space left on device" in r.stderr
    assert (f"m.{'png' if full == 'png' else 'vtk'}: cannot write") in r.stderr
    assert list(out.iterdir()) == []


def test_xdmf_onto_a_full_disk_is_one_line_and_no_crash(run, tmp_path, monkeypatch):
    """The .xdmf and its .h5 are made in memory, then written next to the target: a
    write that does not fit is one line, nothing left (h5py writing onto a full disk
    itself crashes the process after its message)."""
    import errno
    import pathlib

    import h5py  # noqa: F401  (the test extra installs it; .xdmf needs it)

    def full(self, data):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(pathlib.Path, "write_bytes", full)
    out = tmp_path / "out"
    out.mkdir()
    r = run("all", SAMPLES / "circle.csv", "-o", out / "m.xdmf")
    assert r.exit_code == 1 and r.stderr.count("\n") == 1
    assert "m.xdmf: cannot write: No space left on device" in r.stderr
    assert list(out.iterdir()) == []


@pytest.mark.parametrize("error", ["oserror", "other"])
def test_a_failing_writer_names_the_users_file_not_the_staged_one(
    run, tmp_path, monkeypatch, error
):
    import dataclasses

    from deformesh_cli.formats import FORMATS

    def failing(mesh, path, version=None):  # (writers get the staged file's path)
        if error == "oserror":
            raise OSError(5, f"Input/output error on {path}", path)
        raise ValueError(f"cannot encode {path}")

    monkeypatch.setitem(FORMATS, "vtk", dataclasses.replace(FORMATS["vtk"], write=failing))
    r = run("all", SAMPLES / "circle.csv", "-o", tmp_path / "m.vtk")
    assert r.exit_code == 1 and r.stderr.count("\n") == 1
    assert "m.vtk: cannot write" in r.stderr and ".tmp" not in r.stderr, r.stderr
    assert list(tmp_path.iterdir()) == []


def test_a_real_full_disk_on_a_small_tmpfs(tmp_path, sh):
    """Where this machine lets the test mount a 4 KiB tmpfs (root in a container):
    .xdmf, .vtk with --png and a state file, each onto the full disk, as a user runs
    them: exit 1, one line, no crash, nothing left."""
    import subprocess

    disk = tmp_path / "tiny"
    disk.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=4k", "tmpfs", str(disk)], capture_output=True
    )
    if mounted.returncode != 0:
        pytest.skip("cannot mount a tmpfs here (not root, or no mount in this container)")
    try:
        big = SAMPLES / "peanut.csv"  # (each output is over 4 KiB)
        for cmd in (
            f"deformesh all {big} -o {disk}/m.xdmf -q",
            f"deformesh all {big} -o {disk}/m.vtk --png {disk}/m.png -q",
            f"deformesh select {big} -o {disk}/m.state -q",
        ):
            r = sh(cmd, check=False)
            err = r.stderr.decode()
            assert r.returncode == 1, (cmd, r.returncode, err)
            assert err.count("\n") == 1 and "No space left on device" in err, err
            assert list(disk.iterdir()) == [], cmd
        # the system's temporary folder full: .xdmf does not use it
        out = tmp_path / "m.xdmf"
        r = sh(f"TMPDIR={disk} deformesh all {big} -o {out} -q", check=False)
        assert r.returncode == 0 and r.stderr == b"", r.stderr
        assert out.is_file() and out.with_suffix(".h5").is_file()
    finally:
        subprocess.run(["umount", str(disk)], capture_output=True)


@pytest.mark.parametrize("options", [[], ["--solve", "full"]])
def test_meshes_and_adapted_meshes_do_not_depend_on_the_blas(sh, tmp_path, options):
    """Whole processes under other OpenBLAS kernels (Prescott's against this processor's)
    and thread counts write the same bytes: no result rests on which BLAS kernel sums."""
    got = set()
    for k, blas in enumerate(["", "OPENBLAS_CORETYPE=Prescott OPENBLAS_NUM_THREADS=2"]):
        mesh, moved = tmp_path / f"m{k}.vtu", tmp_path / f"a{k}.vtu"
        sh(f"{blas} deformesh all {SAMPLES / 'naca0012.csv'} -o {mesh} -q {' '.join(options)}")
        sh(f"{blas} deformesh adapt {mesh} -o {moved} -q --monitor '1 + 10*exp(-50*y*y)'")
        got.add((mesh.read_bytes(), moved.read_bytes()))
    assert len(got) == 1
