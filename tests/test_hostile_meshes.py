"""Meshes read back by ``quality``, ``plot`` and ``move``: a node that is not finite or
beyond what double precision squares is refused in one line naming the file; ``--json``
is always strict JSON; text from a file never breaks the one line."""

import io
import json
import zipfile

import meshio
import numpy as np
import pytest

from .conftest import SAMPLES

pytestmark = pytest.mark.filterwarnings("error")  # (no numpy warning may leak either)

POINTS = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
TRIANGLES = np.array([[0, 1, 2], [0, 2, 3]])


def _mesh(path, value=None):
    p = POINTS.copy()
    if value is not None:
        p[2, 1] = value
    meshio.write(path, meshio.Mesh(np.c_[p, np.zeros(4)], [("triangle", TRIANGLES)]))
    return path


def _strict(text: str):
    def refuse(name):
        raise ValueError(f"{name} is not JSON")

    return json.loads(text, parse_constant=refuse)


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf, 1e308, 1e200])
@pytest.mark.parametrize("command", ["quality", "quality --json", "plot", "move"])
def test_a_node_far_out_or_not_finite_is_one_line(run, tmp_path, value, command):
    mesh = _mesh(tmp_path / "m.vtu", value)
    args = command.split()
    if args[0] == "plot":
        args += ["-o", tmp_path / "m.png"]
    if args[0] == "move":
        frame = tmp_path / "f.csv"
        np.savetxt(frame, POINTS, delimiter=",")
        args += [frame, "--out-dir", tmp_path / "out"]
    r = run(args[0], mesh, *args[1:])
    assert r.exit_code == 1, r.stderr
    assert r.stderr.count("\n") == 1 and r.stdout == "", (r.stderr, r.stdout)
    assert r.stderr.startswith(f"deformesh: error: {mesh}: node 2 is at (1, ")
    assert "finite and within 1e+150" in r.stderr
    assert not (tmp_path / "m.png").exists() and not (tmp_path / "out").exists()


def test_quality_json_is_strict_json_for_a_flat_triangle(run, tmp_path):
    """A flat triangle has no finite radius ratio: null in the JSON, never NaN."""
    mesh = tmp_path / "flat.vtk"
    p = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [0.0, 1.0]])
    t = np.array([[0, 1, 2], [0, 1, 3]])
    meshio.write(mesh, meshio.Mesh(np.c_[p, np.zeros(4)], [("triangle", t)]))
    r = run("quality", mesh, "--json")
    assert r.exit_code == 1  # (a flat triangle counts as folded)
    rep = _strict(r.stdout)
    assert rep["folded"] == 1 and rep["triangles"] == 2


def test_every_json_output_is_strict(run, tmp_path):
    mesh = tmp_path / "m.vtk"
    r = run("all", SAMPLES / "circle.csv", "-o", mesh, "--json", "-q")
    assert r.exit_code == 0 and _strict(r.stdout)["contract"] == "ok"
    assert _strict(run("quality", mesh, "--json").stdout)["folded"] == 0


def _state_with_source(run, tmp_path, source: str):
    sel = tmp_path / "s.state"
    assert run("select", SAMPLES / "circle.csv", "-o", sel, "-q").exit_code == 0
    zf = zipfile.ZipFile(sel)
    members = {n: zf.read(n) for n in zf.namelist()}
    meta = json.loads(members["meta.json"])
    meta["source"] = source
    members["meta.json"] = json.dumps(meta).encode()
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as out:
        for n, b in members.items():
            out.writestr(n, b)
    bad = tmp_path / "bad.state"
    bad.write_bytes(buf.getvalue())
    return bad


def test_text_from_a_state_cannot_break_the_line(run, tmp_path):
    """A state's recorded contour name carrying a newline, a fake message and a terminal
    escape: the error stays one line, the characters written as escapes."""
    bad = _state_with_source(run, tmp_path, "c.csv\nTraceback (most recent call last):\x1b[2J")
    r = run("deform", bad, "-o", tmp_path / "d.state", "--size", "x - 5")
    assert r.exit_code == 2, r.stderr
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("Error:")]
    assert len(errors) == 1 and "\x1b" not in r.stderr and "\nTraceback" not in r.stderr
    assert "c.csv\\nTraceback (most recent call last):\\x1b[2J" in errors[0]
    r = run("deform", bad, "-o", tmp_path / "d.state")  # (its notes on stderr: one line each)
    assert r.exit_code == 0 and "\x1b" not in r.stderr
    assert all(ln.startswith("deformesh: ") for ln in r.stderr.splitlines()), r.stderr


@pytest.mark.parametrize("command", ["plot", "adapt"])
@pytest.mark.parametrize(
    "values", [np.c_[np.arange(4), np.arange(4)], np.array([0.0, 1.0, np.nan, -1.0])]
)
def test_a_contour_point_array_that_is_not_one_number_a_node_is_one_line(
    run, tmp_path, command, values
):
    mesh = tmp_path / "m.vtu"
    meshio.write(
        mesh,
        meshio.Mesh(np.c_[POINTS, np.zeros(4)], [("triangle", TRIANGLES)],
                    point_data={"contour_point": values}),
    )  # fmt: skip
    out = tmp_path / ("o.png" if command == "plot" else "o.vtu")
    extra = ["--monitor", "1"] if command == "adapt" else []
    r = run(command, mesh, "-o", out, *extra)
    assert r.exit_code == 1, r.stderr
    assert r.stderr.startswith(f"deformesh: error: {mesh}: its point data 'contour_point' is ")
    assert r.stderr.count("\n") == 1 and not out.exists()


@pytest.mark.parametrize(
    "window, code",
    [("0,0,1e308,1", 0), ("-1e308,-1e308,1e308,1e308", 0), ("0,0,1e300,1e-300", 2),
     ("5,5,6,6", 2), ("0.2,0.2,0.8,0.8", 0)],
)  # fmt: skip
def test_a_window_far_out_or_thin_is_cut_to_the_mesh_or_refused(run, tmp_path, window, code):
    mesh = _mesh(tmp_path / "m.vtu")
    out = tmp_path / "o.png"
    r = run("plot", mesh, "-o", out, f"--window={window}")
    assert r.exit_code == code, r.stderr
    assert out.exists() == (code == 0)
    if code:
        assert f"{mesh}: --window" in r.stderr and "shows none of the mesh" in r.stderr


@pytest.mark.parametrize("scale", [1.0, 1e150, 1e-150])
def test_quality_measures_shapes_at_any_accepted_scale(run, tmp_path, scale):
    """A right isosceles triangle's radius ratio is 2 (sqrt 2 - 1) however large or
    small it is drawn (its area squared, or the product of its sides, beyond a double)."""
    mesh = tmp_path / "m.vtu"
    meshio.write(mesh, meshio.Mesh(np.c_[POINTS * scale, np.zeros(4)], [("triangle", TRIANGLES)]))
    r = run("quality", mesh, "--json")
    assert r.exit_code == 0, r.stderr
    rec = _strict(r.stdout)
    assert rec["min_radius_ratio"] == pytest.approx(2 * (np.sqrt(2) - 1), rel=1e-12)
    assert rec["min_angle"] == pytest.approx(45.0)


@pytest.mark.parametrize(
    "monitor", ["1e300", "5e-324", "2**900 * (1 + x)", "2**-1000 * (1 + x)", "1e-310 * (1 + x)"]
)
def test_a_monitors_scale_changes_nothing(run, tmp_path, monitor):
    """Cells follow M up to a constant: a monitor of 1e300 or 5e-324 moves nothing and
    measures evenly (sigma/mu 0 to round-off, not inf or nan); 2**900 (1 + x) moves the
    nodes as 1 + x does, to the bit, and a subnormal one (fewer digits) moves them too."""
    p, tri = np.meshgrid(np.linspace(0, 1, 9), np.linspace(0, 1, 9)), None
    pts = np.c_[p[0].ravel(), p[1].ravel()]
    k = np.arange(81).reshape(9, 9)[:-1, :-1].ravel()
    tri = np.concatenate([np.c_[k, k + 1, k + 10], np.c_[k, k + 10, k + 9]])
    mesh = tmp_path / "g.vtu"
    meshio.write(mesh, meshio.Mesh(np.c_[pts, np.zeros(len(pts))], [("triangle", tri)]))
    r = run("adapt", mesh, "-o", tmp_path / "a.vtu", "--monitor", monitor, "--json")
    assert r.exit_code == 0, r.stderr
    rec = _strict(r.stdout)
    if "x" not in monitor:
        assert rec["sigma_over_mu"] < 1e-12 and rec["moved_nodes"] == 0
        return
    assert rec["moved_nodes"] > 0 and np.isfinite(rec["sigma_over_mu"])
    if monitor.startswith("2**"):
        r = run("adapt", mesh, "-o", tmp_path / "b.vtu", "--monitor", "1 + x")
        assert r.exit_code == 0
        moved = meshio.read(tmp_path / "a.vtu").points
        assert np.array_equal(moved, meshio.read(tmp_path / "b.vtu").points)


@pytest.mark.parametrize("scale", [1e-310, 1e308, 2.0**1000])
def test_a_fields_scale_changes_nothing(run, tmp_path, scale):
    """--field follows the field's shape, not its size: u and 2**1000 u move the nodes
    the same, to the bit; 1e308 u and a subnormal 1e-310 u (fewer digits) move them
    too, and nothing is refused."""
    x, y = np.meshgrid(np.linspace(0, 1, 9), np.linspace(0, 1, 9))
    pts = np.c_[x.ravel(), y.ravel()]
    k = np.arange(81).reshape(9, 9)[:-1, :-1].ravel()
    tri = np.concatenate([np.c_[k, k + 1, k + 10], np.c_[k, k + 10, k + 9]])
    u = np.tanh(5 * (pts[:, 0] + pts[:, 1] - 1))
    outs = []
    for name, values in (("one", u), ("scaled", u * scale)):
        mesh = tmp_path / f"{name}.vtu"
        meshio.write(mesh, meshio.Mesh(np.c_[pts, np.zeros(81)], [("triangle", tri)],
                                       point_data={"u": values}))  # fmt: skip
        r = run("adapt", mesh, "-o", tmp_path / f"a_{name}.vtu", "--field", "u", "--json")
        assert r.exit_code == 0, r.stderr
        assert _strict(r.stdout)["moved_nodes"] > 0
        outs.append(meshio.read(tmp_path / f"a_{name}.vtu").points)
    if scale == 2.0**1000:
        assert np.array_equal(outs[0], outs[1])


def test_an_expression_with_a_complex_part_is_refused(run, tmp_path):
    mesh = _mesh(tmp_path / "m.vtu")
    r = run("adapt", mesh, "-o", tmp_path / "a.vtu", "--monitor", "2 + x*(-1)**0.5")
    assert r.exit_code == 2
    assert "has a part that is not a real number ((-1)**0.5)" in r.stderr
    r = run("all", SAMPLES / "circle.csv", "-o", tmp_path / "c.vtk", "--size", "(-8)**(1/3) + 3")
    assert r.exit_code == 2 and "not a real number" in r.stderr


def test_a_vtu_that_would_inflate_past_the_bound_is_refused_before_it_is(run, tmp_path):
    """A compressed .vtu is read only after its arrays' headers say how large they inflate:
    a few MB that would inflate to 4 GiB are refused in one line, unread."""
    import base64
    import struct
    import zlib

    small = tmp_path / "small.vtu"
    meshio.write(
        small, meshio.Mesh(np.c_[POINTS, np.zeros(4)], [("triangle", TRIANGLES)]),
        compression="zlib",
    )  # fmt: skip
    block, blocks = 2**26, 64  # (64 blocks of 64 MiB of zeros: 4 GiB)
    one = zlib.compress(bytes(block), 9)
    header = struct.pack(f"<{3 + blocks}I", blocks, block, 0, *[len(one)] * blocks)
    payload = base64.b64encode(header) + base64.b64encode(one * blocks)
    array = (b'<PointData><DataArray type="Float64" Name="bomb" format="binary">' + payload
             + b"</DataArray></PointData>")  # fmt: skip
    bomb = tmp_path / "bomb.vtu"
    bomb.write_bytes(small.read_bytes().replace(b"<Points>", array + b"<Points>", 1))
    assert bomb.stat().st_size < 8 * 2**20
    for args in (["quality"], ["plot", "-o", tmp_path / "p.png"],
                 ["adapt", "-o", tmp_path / "a.vtu", "--monitor", "1"]):  # fmt: skip
        r = run(args[0], bomb, *args[1:])
        assert r.exit_code == 1, r.stderr
        assert r.stderr.startswith(f"deformesh: error: {bomb}: its compressed arrays would ")
        assert r.stderr.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bomb.vtu", "small.vtu"]
    assert run("quality", small).exit_code == 0


@pytest.mark.parametrize("value", ["nan", "inf", "1e300", "0.5"])
@pytest.mark.parametrize("suffix", [".vtu", ".msh", ".xdmf", ".vtk"])
def test_field_data_that_is_no_group_is_left_out(run, tmp_path, value, suffix):
    """A .vtu's field data that is not a group's (tag, dimension) (a NaN, a time value)
    names no group: adapt leaves it out and writes a file that reads back."""
    src = tmp_path / "m.vtu"
    r = run("all", SAMPLES / "circle.csv", "-o", src, "-q")
    assert r.exit_code == 0
    text = src.read_text()
    start = text.index('Name="contour"')
    end = text.index("</DataArray>", start)
    head = text[:start].rsplit("<DataArray", 1)
    src.write_text(head[0] + '<DataArray type="Float64" Name="contour" NumberOfComponents="1" '
                   f'NumberOfTuples="2" format="ascii">{value} 1' + text[end:])  # fmt: skip
    out = tmp_path / f"a{suffix}"
    r = run("adapt", src, "-o", out, "--monitor", "1 + x * x", "-q")
    assert r.exit_code == 0, r.stderr
    m = meshio.read(out)
    assert "contour" not in m.field_data and len(m.points) > 0
