"""Outputs are regular files: special files and links to them are refused before any work,
unchanged; a link to a regular file is written through, the link kept."""

import os
import stat
import subprocess

import pytest

from deformesh_cli import files
from deformesh_cli.errors import OptionError

from .conftest import SAMPLES, deformesh_exe

CIRCLE = SAMPLES / "circle.csv"


@pytest.fixture(scope="module")
def states(tmp_path_factory):
    """State files of samples/circle.csv after select and after deform."""
    d = tmp_path_factory.mktemp("states")
    exe = deformesh_exe()
    sel, dfm = d / "s.state", d / "d.state"
    subprocess.run([exe, "select", CIRCLE, "-o", sel, "-q"], check=True)
    subprocess.run([exe, "deform", sel, "-o", dfm, "-q"], check=True)
    return {"select": sel, "deform": dfm}


#: command -> (arguments before the output path, given tmp_path and states; its option)
COMMANDS = {
    "all": (lambda tmp, st: ["all", CIRCLE, "--format", "vtk"], "-o"),
    "all --png": (lambda tmp, st: ["all", CIRCLE, "-o", tmp / "m.vtk"], "--png"),
    "select": (lambda tmp, st: ["select", CIRCLE], "-o"),
    "deform": (lambda tmp, st: ["deform", st["select"]], "-o"),
    "triangulate": (lambda tmp, st: ["triangulate", st["deform"], "--format", "vtk"], "-o"),
    "plot": (lambda tmp, st: ["plot", CIRCLE], "-o"),
}


_PIPES: list = []


def _pipe() -> int:
    r, w = os.pipe()
    _PIPES.extend([r, w])
    return w


def _special(tmp_path, kind):
    """An output path of ``kind``, and how to see that it is unchanged afterwards."""
    if kind == "fifo":
        p = tmp_path / "pipe"
        os.mkfifo(p)
        return p, lambda: stat.S_ISFIFO(os.lstat(p).st_mode)
    if kind == "folder":
        p = tmp_path / "dir"
        p.mkdir()
        return p, lambda: p.is_dir() and not any(p.iterdir())
    if kind == "link-to-null":
        target = "/dev/null"
    elif kind == "link-to-pipe":  # as /dev/stdout is, when stdout is a pipe
        target = f"/proc/self/fd/{_pipe()}"
    else:  # a dangling link
        target = str(tmp_path / "nowhere")
    p = tmp_path / "link"
    p.symlink_to(target)
    return p, lambda: os.readlink(p) == target and not (tmp_path / "nowhere").exists()


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("kind", ["fifo", "folder", "link-to-null", "link-to-pipe", "dangling"])
def test_special_outputs_are_refused_unchanged(run, tmp_path, states, command, kind):
    before, option = COMMANDS[command]
    args = before(tmp_path, states)
    path, unchanged = _special(tmp_path, kind)
    try:
        r = run(*args, option, path)
    finally:
        while _PIPES:
            os.close(_PIPES.pop())
    assert r.exit_code == 2, r.stderr
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("Error:")]
    assert len(errors) == 1 and str(path) in errors[0], r.stderr
    assert unchanged()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary left


def test_dev_null_itself_is_refused_by_the_core():
    with pytest.raises(OptionError, match="is a character device; outputs are regular files"):
        files.output_target("/dev/null")
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_a_character_device_is_refused_and_unchanged(run, tmp_path):
    dev = tmp_path / "null"
    try:
        os.mknod(dev, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    except (PermissionError, OSError):
        pytest.skip("cannot create a device node here (needs root); the core test covers it")
    r = run("all", CIRCLE, "-o", dev, "--format", "vtk")
    assert r.exit_code == 2 and "is a character device" in r.stderr
    assert stat.S_ISCHR(os.lstat(dev).st_mode)


@pytest.mark.parametrize("fmt", ["vtk", "xdmf"])
def test_a_link_to_a_regular_file_is_written_through(run, tmp_path, fmt):
    real_dir = tmp_path / "real"
    real_dir.mkdir()
    real = real_dir / f"mesh.{fmt}"
    real.write_text("old")
    link = tmp_path / f"link.{fmt}"
    link.symlink_to(real)
    r = run("all", CIRCLE, "-o", link)
    assert r.exit_code == 0, r.stderr
    assert link.is_symlink() and os.readlink(link) == str(real)
    assert real.read_bytes() != b"old" and real.stat().st_size > 500
    if fmt == "xdmf":  # the sidecar sits next to the file that names it
        assert (real_dir / "mesh.h5").exists() and not (tmp_path / "link.h5").exists()
    plain = tmp_path / f"plain.{fmt}"
    assert run("all", CIRCLE, "-o", plain).exit_code == 0
    if fmt == "vtk":
        assert plain.read_bytes() == real.read_bytes()


def test_stdout_and_new_files_are_still_fine(run, tmp_path):
    r = run("all", CIRCLE, "-o", "-", "--format", "vtk")
    assert r.exit_code == 0 and r.stdout_bytes.startswith(b"# vtk")
    out = tmp_path / "new.vtk"
    assert run("all", CIRCLE, "-o", out).exit_code == 0 and out.is_file()
    assert run("all", CIRCLE, "-o", out).exit_code == 0  # an existing regular file
