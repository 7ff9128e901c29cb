"""Nothing of the user's is lost: every output a run writes, named (``-o``, ``--png``) or
implied (the ``.xdmf``'s ``.h5`` sidecar, a batch's or ``move``'s ``NAME.FORMAT``), is
checked before any work, and refused in one usage line when it is an input of the run,
another of its outputs, an implied file that is a symbolic link, or a sidecar deformesh
did not write (unless ``--force``).  Every input and every link target is unchanged.
A stdout that is full or closed is one line, exit 1."""

import os
import subprocess

import pytest

from .conftest import SAMPLES, deformesh_exe

CIRCLE = SAMPLES / "circle.csv"


def _usage_line(r, *names) -> str:
    """The one ``Error:`` line of a refused run (exit 2), naming each of ``names``."""
    assert r.exit_code == 2, r.stderr
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("Error:")]
    assert len(errors) == 1 and "Traceback" not in r.stderr, r.stderr
    for name in names:
        assert str(name) in errors[0], errors[0]
    return errors[0]


@pytest.fixture
def contour(tmp_path):
    c = tmp_path / "in.csv"
    c.write_bytes(CIRCLE.read_bytes())
    return c


def test_the_picture_may_not_replace_the_mesh(run, tmp_path, contour):
    out = tmp_path / "m.vtk"
    out.write_text("the user's mesh")
    r = run("all", contour, "-o", out, "--png", out)
    _usage_line(r, out)
    assert out.read_text() == "the user's mesh"


def test_the_picture_may_not_replace_the_input(run, tmp_path, contour):
    before = contour.read_bytes()
    r = run("all", contour, "-o", tmp_path / "m.vtk", "--png", contour)
    assert "an input of this run" in _usage_line(r, contour)
    assert contour.read_bytes() == before and not (tmp_path / "m.vtk").exists()


@pytest.mark.parametrize("option", ["-o", "--png"])
def test_a_link_to_the_input_is_refused(run, tmp_path, contour, option):
    link = tmp_path / "link.vtk"
    link.symlink_to(contour)
    before = contour.read_bytes()
    args = ["-o", link] if option == "-o" else ["-o", tmp_path / "m.vtk", "--png", link]
    r = run("all", contour, *args)
    assert "an input of this run" in _usage_line(r, link, contour)
    assert contour.read_bytes() == before and link.is_symlink()


def test_a_hard_link_to_the_input_is_refused(run, tmp_path, contour):
    same = tmp_path / "same.vtk"
    os.link(contour, same)
    r = run("all", contour, "-o", same)
    _usage_line(r, same)
    assert contour.read_bytes() == CIRCLE.read_bytes()


@pytest.fixture
def state(tmp_path, run):
    """A deformed state file named ``X.h5``: the sidecar ``-o X.xdmf`` implies."""
    sel, dfm = tmp_path / "s.state", tmp_path / "X.h5"
    assert run("select", CIRCLE, "-o", sel, "-q").exit_code == 0
    assert run("deform", sel, "-o", dfm, "-q").exit_code == 0
    return dfm


@pytest.mark.parametrize("force", [[], ["--force"]])
def test_the_sidecar_may_not_replace_the_input(run, tmp_path, state, force):
    before = state.read_bytes()
    r = run("triangulate", state, "-o", tmp_path / "X.xdmf", *force)
    assert "an input of this run" in _usage_line(r, state)
    assert state.read_bytes() == before and not (tmp_path / "X.xdmf").exists()


@pytest.mark.parametrize("command", ["select", "deform", "plot"])
def test_an_output_may_not_be_the_input(run, tmp_path, state, contour, command):
    target = {"select": contour, "deform": tmp_path / "s.state", "plot": contour}[command]
    source = {"select": contour, "deform": target, "plot": SAMPLES / "circle.csv"}[command]
    extra = ["--contour", contour] if command == "plot" else []
    before = target.read_bytes()
    if command == "plot":
        mesh = tmp_path / "m.vtk"
        assert run("all", source, "-o", mesh, "-q").exit_code == 0
        source = mesh
    r = run(command, source, "-o", target, *extra)
    _usage_line(r, target)
    assert target.read_bytes() == before


def test_a_sidecar_is_never_written_through_a_link(run, tmp_path):
    victim = tmp_path / "victim"
    victim.write_text("not yours")
    (tmp_path / "m.h5").symlink_to(victim)
    r = run("all", CIRCLE, "-o", tmp_path / "m.xdmf")
    assert "symbolic link" in _usage_line(r, tmp_path / "m.h5")
    assert victim.read_text() == "not yours" and not (tmp_path / "m.xdmf").exists()
    r = run("all", CIRCLE, "-o", tmp_path / "m.xdmf", "--force")
    _usage_line(r, tmp_path / "m.h5")
    assert victim.read_text() == "not yours"


def test_a_sidecar_deformesh_did_not_write_needs_force(run, tmp_path):
    side = tmp_path / "m.h5"
    side.write_text("a user's data")
    r = run("all", CIRCLE, "-o", tmp_path / "m.xdmf")
    assert "--force" in _usage_line(r, side)
    assert side.read_text() == "a user's data"
    assert run("all", CIRCLE, "-o", tmp_path / "m.xdmf", "--force", "-q").exit_code == 0
    first = side.read_bytes()
    assert first.startswith(b"deformesh xdmf sidecar")
    # a sidecar deformesh wrote is its own output: replaced without --force
    assert run("all", CIRCLE, "-o", tmp_path / "m.xdmf", "-q").exit_code == 0
    assert side.read_bytes() == first  # (the same mesh: the same bytes)


def test_a_batch_output_is_never_written_through_a_link(run, tmp_path, contour):
    victim = tmp_path / "victim"
    victim.write_text("not yours")
    out = tmp_path / "out"
    out.mkdir()
    (out / "in.vtk").symlink_to(victim)
    r = run("all", contour, "--out-dir", out, "--format", "vtk")
    _usage_line(r, out / "in.vtk")
    assert victim.read_text() == "not yours"


def test_a_batch_sidecar_deformesh_did_not_write_needs_force(run, tmp_path, contour):
    out = tmp_path / "out"
    out.mkdir()
    (out / "in.h5").write_text("a user's data")
    r = run("all", contour, "--out-dir", out, "--format", "xdmf")
    _usage_line(r, out / "in.h5")
    assert (out / "in.h5").read_text() == "a user's data"
    r = run("all", contour, "--out-dir", out, "--format", "xdmf", "--force", "-q")
    assert r.exit_code == 0 and (out / "in.h5").read_bytes().startswith(b"deformesh")


def test_move_does_not_overwrite_its_own_mesh(run, tmp_path):
    """``--name m`` makes frame 0's file ``m_0000.vtu``: here, the input mesh itself."""
    out = tmp_path / "out"
    out.mkdir()
    mesh = out / "m_0000.vtu"
    assert run("all", CIRCLE, "-o", mesh, "-q").exit_code == 0
    before = mesh.read_bytes()
    r = run("move", mesh, CIRCLE, "--out-dir", out, "--name", "m")
    assert "an input of this run" in _usage_line(r, mesh)
    assert mesh.read_bytes() == before and sorted(p.name for p in out.iterdir()) == [mesh.name]


STDOUT_COMMANDS = [
    f"all {CIRCLE} -o - --format vtk -q",
    f"all {CIRCLE} -o {{tmp}}/m.vtk --json -q",
    f"select {CIRCLE} -o - -q",
    f"plot {CIRCLE} -o -",
    "quality {tmp}/m.vtk --json",
    "quality {tmp}/m.vtk",
]


@pytest.mark.parametrize("command", STDOUT_COMMANDS)
@pytest.mark.parametrize("stdout", ["> /dev/full", ">&-"])
def test_a_stdout_that_cannot_be_written_is_one_line(tmp_path, command, stdout):
    exe = deformesh_exe()
    subprocess.run([exe, "all", CIRCLE, "-o", tmp_path / "m.vtk", "-q"], check=True)
    if command.startswith("plot"):
        command = command.replace(str(CIRCLE), str(tmp_path / "m.vtk"))
    line = f"{exe} {command.format(tmp=tmp_path)} {stdout}"
    r = subprocess.run(["bash", "-c", line], capture_output=True, text=True)
    assert r.returncode == 1, (line, r.stderr)
    why = "No space left on device" if "full" in stdout else "is closed"
    assert r.stderr.startswith("deformesh: error: stdout: "), r.stderr
    assert r.stderr.count("\n") == 1 and why in r.stderr, r.stderr
