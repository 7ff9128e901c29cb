import io
import json
import re
import zipfile

import meshio
import numpy as np
import pytest

from deformesh_cli import state
from deformesh_cli.quality import check_contract
from deformesh_cli.readers import load_contour

from .conftest import SAMPLES, contour_file

SAMPLE_FILES = sorted(SAMPLES.glob("*.csv"))
SHARED_DEFAULT = [
    "circle_100.csv",
    "circle_1000.csv",
    "bean_100.csv",
    "star_100.csv",
    "channel_100.csv",
]


def _mesh_ok(run, contour, out, *opts):
    r = run("all", contour, "-o", out, "--json", *opts)
    assert r.exit_code == 0, r.stderr
    rec = json.loads(r.stdout)
    assert rec["contract"] == "ok"
    assert "contract ok" in r.stderr
    # check the contract again, independently, on the file as written
    m = meshio.read(out)
    c = load_contour(contour)
    from deformesh_cli.mesh import Mesh

    line_block = [k for k, block in enumerate(m.cells) if block.type == "line"][0]
    mesh = Mesh(
        m.points[:, :2],
        m.cells_dict["triangle"],
        m.cells_dict["line"],
        c.n,
        rec["extra_boundary_nodes"],
        line_group=np.asarray(m.cell_data["group"][line_block]) - 1,  # (the .msh tags)
    )
    check_contract(mesh, c)
    assert rec["nodes"] == len(m.points) and rec["triangles"] == len(mesh.triangles)
    return rec


@pytest.mark.parametrize("contour", SAMPLE_FILES, ids=lambda p: p.name)
def test_every_sample_meets_the_contract_with_defaults(run, tmp_path, contour):
    _mesh_ok(run, contour, tmp_path / "m.vtu")


@pytest.mark.parametrize("name", SHARED_DEFAULT)
def test_reference_contours_meet_the_contract_with_defaults(run, tmp_path, name):
    rec = _mesh_ok(run, contour_file(name), tmp_path / "m.vtk")
    assert rec["min_angle"] > 5


def test_half_disk_with_its_flat_side_on_the_background_boundary(run, tmp_path):
    rec = _mesh_ok(run, SAMPLES / "half_disk.csv", tmp_path / "m.vtk", "--box", "-1.25,0,1.25,1.25")
    assert rec["box"][1] < 0.0 and rec["contract"] == "ok"  # (room for the loop below)


def test_paper_example_meshes(run, tmp_path):
    rec = _mesh_ok(
        run, SAMPLES / "paper_example.csv", tmp_path / "m.vtk", "--h", "1", "--box", "1,1,9,12"
    )
    assert rec["extra_boundary_nodes"] == 0 and rec["grid_nodes"] == 9 * 12


def test_naca0012_100_with_h_001(run, tmp_path):
    # several points per cell at the sharp trailing edge: Appendix A's greedy
    # choice cannot be joined into a simple path there, the traced path can
    rec = _mesh_ok(run, contour_file("naca0012_100.csv"), tmp_path / "m.vtk", "--h", "0.01")
    assert rec["path_rule"] == "traced"
    assert any("traced the grid path" in n for n in rec["notes"])


def test_uneven_contour_on_the_uniform_grid_refused_with_estimate_and_no_file(run, tmp_path):
    out = tmp_path / "naca.vtk"
    r = run("all", contour_file("naca0012_1000.csv"), "-o", out, "--grid", "uniform")
    assert r.exit_code == 1
    assert "3.6e+10 nodes" in r.stderr and "--resample 0.00224" in r.stderr
    assert r.stderr.count("\n") == 1
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_uneven_contour_meshes_on_the_graded_grid_by_default_and_through_a_pipe(run, tmp_path):
    c = contour_file("naca0012_1000.csv")
    rec = _mesh_ok(run, c, tmp_path / "a.vtk")
    assert rec["h_rule"].startswith("graded") and rec["extra_boundary_nodes"] == 0
    assert run("select", c, "-o", tmp_path / "s").exit_code == 0
    assert run("deform", tmp_path / "s", "-o", tmp_path / "d").exit_code == 0
    assert run("triangulate", tmp_path / "d", "-o", tmp_path / "b.vtk").exit_code == 0
    assert (tmp_path / "a.vtk").read_bytes() == (tmp_path / "b.vtk").read_bytes()


@pytest.mark.parametrize(
    "args, code, text",
    [
        (["all", "{c}"], 2, "give -o FILE (one contour) or --out-dir DIR"),
        (["all", "{c}", "-o", "{t}/m.vtk", "--box", "1,2,3"], 2, "expected XMIN,YMIN,XMAX,YMAX"),
        (["all", "{c}", "-o", "{t}/m.xyz"], 2, "unknown output format 'xyz'"),
        (["all", "{c}", "-o", "{t}/m.vtk", "--steps", "0"], 2, "--steps"),
        (["all", "{c}", "-o", "{t}/m.vtk", "--h", "-1"], 2, "--h"),
        (["all", "{c}", "-o", "{t}/m.vtk", "--box", "5,5,6,6"], 2, "lies outside --box"),
        (["all", "{t}/missing.csv", "-o", "{t}/m.vtk"], 1, "missing.csv: no such file"),
        (["all", "{c}", "-o", "{t}/nodir/m.vtk"], 2, "does not exist"),
        (["all", "{c}", "-o", "{t}/m.vtk", "--png", "{t}/nodir/m.png"], 2, "does not exist"),
        (["all", "{c}", "-o", "-", "--json"], 2, "both use stdout"),
        (["deform", "{c}", "-o", "{t}/s"], 1, "not a deformesh state file"),
    ],
)
def test_exit_codes_and_messages(run, tmp_path, args, code, text):
    c = SAMPLES / "circle.csv"
    r = run(*[a.format(c=c, t=tmp_path) for a in args])
    assert r.exit_code == code, (r.stdout, r.stderr)
    assert text in r.stderr
    assert "Traceback" not in r.stderr
    assert not (tmp_path / "m.vtk").exists()


def test_bad_contour_is_one_line_naming_file_and_line(run, tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("x,y\n0,0\n1,0\n1,abc\n0,1\n")
    out = tmp_path / "m.vtk"
    r = run("all", bad, "-o", out)
    assert r.exit_code == 1
    assert r.stderr == f"deformesh: error: {bad}: line 4: y value 'abc' is not a number\n"
    assert not out.exists()


def test_state_file_errors(run, tmp_path):
    s = tmp_path / "s.state"
    assert run("select", SAMPLES / "circle.csv", "-o", s).exit_code == 0
    data = s.read_bytes()
    # truncated
    (tmp_path / "t.state").write_bytes(data[: len(data) // 2])
    r = run("deform", tmp_path / "t.state", "-o", tmp_path / "o.state")
    assert r.exit_code == 1 and "truncated" in r.stderr
    # another version
    zin = zipfile.ZipFile(io.BytesIO(data))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zout:
        for item in zin.infolist():
            payload = zin.read(item)
            if item.filename == "meta.json":
                meta = json.loads(payload)
                meta["version"] = 99
                payload = json.dumps(meta).encode()
            zout.writestr(item, payload)
    (tmp_path / "v.state").write_bytes(buf.getvalue())
    r = run("deform", tmp_path / "v.state", "-o", tmp_path / "o.state")
    assert r.exit_code == 1 and "state file version 99" in r.stderr
    # wrong stage
    r = run("triangulate", s, "-o", tmp_path / "m.vtk")
    assert r.exit_code == 1 and "expected 'deformed'" in r.stderr
    assert not (tmp_path / "o.state").exists() and not (tmp_path / "m.vtk").exists()


def test_state_round_trip_is_lossless(run, tmp_path):
    s = tmp_path / "s.state"
    run("select", SAMPLES / "peanut.csv", "-o", s)
    st = state.loads(s.read_bytes(), "s")
    assert state.dumps(st) == s.read_bytes()


@pytest.mark.parametrize("fmt", ["vtk", "vtu", "msh", "obj"])
def test_output_is_byte_identical_on_rerun(run, tmp_path, fmt):
    a, b = tmp_path / f"a.{fmt}", tmp_path / f"b.{fmt}"
    for out in (a, b):
        assert run("all", SAMPLES / "peanut.csv", "-o", out, "-q").exit_code == 0
    assert a.read_bytes() == b.read_bytes()


def test_gmsh_file_has_named_physical_groups(run, tmp_path):
    out = tmp_path / "m.msh"
    run("all", SAMPLES / "circle.csv", "-o", out)
    text = out.read_text()
    assert text.startswith("$MeshFormat\n2.2 0 8\n")
    assert '$PhysicalNames\n2\n1 1 "contour"\n2 2 "domain"\n' in text
    m = meshio.read(out)
    assert set(m.field_data) == {"contour", "domain"}
    phys = dict(zip([c.type for c in m.cells], m.cell_data["gmsh:physical"]))
    assert (phys["triangle"] == 2).all() and (phys["line"] == 1).all()


def test_obj_has_faces_and_boundary_lines(run, tmp_path):
    out = tmp_path / "m.obj"
    r = run("all", SAMPLES / "circle.csv", "-o", out, "--json")
    rec = json.loads(r.stdout)
    lines = out.read_text().splitlines()
    assert sum(ln.startswith("v ") for ln in lines) == rec["nodes"]
    assert sum(ln.startswith("f ") for ln in lines) == rec["triangles"]
    assert sum(ln.startswith("l ") for ln in lines) == rec["boundary_nodes"]
    assert all(ln.endswith(" 0") for ln in lines if ln.startswith("v "))


def test_real_pipe_gives_the_same_mesh_as_all(sh, tmp_path):
    c = SAMPLES / "peanut.csv"
    sh(
        f"deformesh select {c} -o - | deformesh deform - -o - | "
        f"deformesh triangulate - -o {tmp_path}/pipe.vtk",
        cwd=tmp_path,
    )
    sh(f"deformesh all {c} -o {tmp_path}/all.vtk", cwd=tmp_path)
    assert (tmp_path / "pipe.vtk").read_bytes() == (tmp_path / "all.vtk").read_bytes()


def test_contour_from_stdin_and_mesh_to_stdout(sh, tmp_path):
    c = SAMPLES / "circle.csv"
    r = sh(f"cat {c} | deformesh all - -o - --format obj -q", cwd=tmp_path)
    assert r.stderr == b""
    assert r.stdout.startswith(b"# deformesh mesh")


def test_clockwise_input_keeps_node_numbering(run, tmp_path):
    pts = load_contour(SAMPLES / "circle.csv").points[::-1]
    f = tmp_path / "cw.csv"
    np.savetxt(f, pts, delimiter=",", header="x,y", comments="")
    out = tmp_path / "m.vtk"
    assert run("all", f, "-o", out).exit_code == 0
    m = meshio.read(out)
    assert np.array_equal(m.points[: len(pts), :2], pts)


def test_resample_meshes_an_uneven_contour_and_quality_follows(run, tmp_path):
    src = contour_file("naca0012_100.csv")  # spacing varies 32x
    out = tmp_path / "m.msh"
    r = run("all", src, "-o", out, "--resample", "3%", "--json")
    assert r.exit_code == 0, r.stderr
    rec = json.loads(r.stdout)
    assert any("resampled 100 points to" in n for n in rec["notes"])
    # quality checks the contract against the same resampled contour
    r = run("quality", out, "--contour", src, "--resample", "3%")
    assert r.exit_code == 0 and r.stdout.endswith("contract: ok\n")
    r = run("quality", out, "--contour", src)
    assert r.exit_code == 1  # against the given points it is not their mesh


def test_a_contract_message_writes_numbers_as_people_do(run, tmp_path):
    out = tmp_path / "m.vtu"
    assert run("all", SAMPLES / "peanut.csv", "-o", out, "-q").exit_code == 0
    r = run("quality", out, "--contour", SAMPLES / "circle.csv")
    assert r.exit_code == 1
    assert re.search(r"node 0 is at \(-?[0-9.e+-]+, -?[0-9.e+-]+\), not at point 0", r.stderr)
    assert "np." not in r.stdout + r.stderr and "float64" not in r.stdout + r.stderr


@pytest.mark.parametrize("command", ["quality", "plot"])
def test_commands_that_only_measure_or_draw_describe_their_own_options(run, command):
    text = " ".join(run(command, "--help").stdout.split())
    assert "mesh only" not in text and "no longer all boundary nodes" not in text
    assert "read only the element with this id, as the mesh was made" in text
    assert "Re-space the contour at SPACING, as the mesh was made" in text
