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
