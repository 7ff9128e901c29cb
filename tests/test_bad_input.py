"""The catalogue of bad input: every case gets its exit code, a one-line message naming the
file, the problem and where, and leaves no output file behind.  Then the same inputs as
one batch: the good ones still mesh."""

import json
import os
import re
from pathlib import Path

import numpy as np
import pytest

from .conftest import SAMPLES

SVG = "<svg xmlns='http://www.w3.org/2000/svg' width='9' height='9'>{}</svg>"

#: name -> (file content, exit code, regex the message must match)
CASES = {
    "missing.csv": (None, 1, r"missing\.csv: no such file"),
    "empty.csv": ("", 1, r"empty\.csv: empty: no points"),
    "comments.csv": ("# only\n# comments\n", 1, r"comments\.csv: empty: no points"),
    "binary.csv": (b"\x00\x01\x02\xff", 1, r"binary\.csv: binary file"),
    "latin1.csv": (
        b"x,y\n0,0\n1,0\n\xe9,1\n",
        1,
        r"latin1\.csv: line 4: not UTF-8 text \(byte 12\)",
    ),
    "header.csv": ("a,b\n0,0\n1,0\n0,1\n", 1, r"header\.csv: line 1: header 'a,b' must name"),
    "onecolumn.csv": ("0\n1\n2\n", 1, r"onecolumn\.csv: line 1: expected 2 columns x,y, got 1"),
    "ragged.csv": ("0,0,0\n1,0\n0,1,0\n", 1, r"ragged\.csv: line 2: 2 fields, but line 1 has 3"),
    "thousands.csv": (  # 5 x 1,500 written with a thousands separator: never 5 x 1
        "0,0\n5,0\n5,1,500\n0,1,500\n",
        1,
        r"thousands\.csv: line 3: 3 fields, but line 1 has 2",
    ),
    "word.csv": ("0,0\n1,one\n0,1\n", 1, r"word\.csv: line 2: y value 'one' is not a number"),
    "comma.csv": (  # decimal commas, fields split by semicolons: the option is named
        "x;y\n0,0;0,0\n1,5;0,0\n1,5;1,0\n",
        1,
        r"comma\.csv: line 2: x value '0,0' is not a number \(for decimal commas give "
        r"--decimal ,\)",
    ),
    "nan.csv": (
        "0,0\n1,0\nnan,1\n",
        1,
        r"nan\.csv: line 3: point 2 has a non-finite "
        r"coordinate \(nan, 1\.0\)",
    ),
    "inf.csv": ("0,0\n1,-inf\n0,1\n", 1, r"inf\.csv: line 2: point 1 has a non-finite"),
    "two.csv": ("0,0\n1,0\n0,0\n1,0\n", 1, r"two\.csv: .*fewer than 3 distinct points \(2\)"),
    "repeat.csv": (
        "0,0\n1,0\n1,0\n1,1\n",
        1,
        r"repeat\.csv: point 2 \(line 3\) at \(1, 0\) "
        r"repeats the previous point",
    ),
    "collinear.csv": ("0,0\n1,0\n2,0\n3,0\n", 1, r"collinear\.csv: .*encloses no area"),
    "spike.csv": (
        "0,0\n2,0\n2,2\n1,2\n1,3\n1,2\n0,2\n",
        1,
        r"spike\.csv: the contour intersects itself near \(1, [23]\)",
    ),
    "bowtie.csv": (
        "0,0\n1,1\n1,0\n0,1\n",
        1,
        r"bowtie\.csv: the contour intersects itself "
        r"near \(0\.5, 0\.5\): edge from point 0 \(line 1\)",
    ),
    "touching.csv": (
        "x,y,ring\n0,0,0\n4,0,0\n4,4,0\n0,4,0\n1,1,1\n4,2,1\n1,3,1\n",
        1,
        r"touching\.csv: ring 1 touches or crosses ring 0 near \(4, 2\)",
    ),
    "split.csv": (
        "x,y,ring\n0,0,0\n4,0,0\n1,1,1\n2,1,1\n1,2,1\n4,4,0\n",
        1,
        r"split\.csv: line 7: ring 0 starts again",
    ),
    "noshape.svg": (SVG.format(""), 1, r"noshape\.svg: no filled shape"),
    "stroked.svg": (
        SVG.format("<rect width='5' height='5' fill='none' stroke='red'/>"),
        1,
        r"stroked\.svg: no filled shape in the SVG \(1 unfilled",
    ),
    "broken.svg": ("<svg><path d='M0 0", 1, r"broken\.svg: not a readable SVG file"),
}


def _write(folder: Path, name: str):
    content = CASES[name][0]
    if content is None:
        return
    p = folder / name
    if isinstance(content, bytes):
        p.write_bytes(content)
    else:
        p.write_text(content)


@pytest.mark.parametrize("name", sorted(CASES))
def test_bad_input_catalogue(run, tmp_path, name):
    _, code, pattern = CASES[name]
    src = tmp_path / "in"
    src.mkdir()
    _write(src, name)
    out = tmp_path / "out"
    out.mkdir()
    r = run("all", src / name, "-o", out / "m.msh", "--max-nodes", "200000")
    assert r.exit_code == code
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("deformesh: error: "), r.stderr
    assert re.search(pattern, lines[0]), lines[0]
    assert str(src / name) in lines[0]  # names the file
    assert list(out.iterdir()) == []


def _circle_csv(path, scale=1.0, offset=0.0, n=60):
    t = 2 * np.pi * np.arange(n) / n
    p = np.column_stack([np.cos(t) * (1 + 0.3 * np.cos(3 * t)), np.sin(t)]) * scale + offset
    np.savetxt(path, p, delimiter=",", fmt="%.17g")


@pytest.mark.parametrize(
    "scale,offset", [(1e-9, 0.0), (1e-9, 1e-3), (1e9, 0.0), (1.0, 1e9), (1e-6, -1e6)]
)
def test_tiny_and_huge_coordinates_mesh_with_the_contract(run, tmp_path, scale, offset):
    f = tmp_path / "c.csv"
    _circle_csv(f, scale, offset)
    r = run("all", f, "-o", tmp_path / "m.msh", "--json")
    assert r.exit_code == 0, r.stderr
    assert json.loads(r.stdout)["contract"] == "ok"
    r = run("quality", tmp_path / "m.msh", "--contour", f)
    assert r.exit_code == 0, r.stderr


@pytest.mark.parametrize(
    "args,code,pattern",
    [
        (
            ["-o", "{tmp}/nofolder/m.msh"],
            2,
            r"nofolder/m\.msh: cannot write: folder .* does not exist",
        ),
        (["-o", "{tmp}/m.xyz"], 2, r"unknown output format 'xyz'"),
        (["-o", "{tmp}"], 2, r"is a directory"),
        (["-o", "-"], 2, r"writing a mesh to stdout needs --format"),
        (["-o", "{tmp}/m.msh", "--box", "5,5,6,6"], 2, r"box"),
        (["-o", "{tmp}/m.msh", "--h", "-1"], 2, r"must be a finite number > 0"),
        (["-o", "{tmp}/m.msh", "--out-dir", "{tmp}"], 2, r"not both"),
        (["--jobs", "2", "-o", "{tmp}/m.msh"], 2, r"apply to batches"),
        ([], 2, r"give -o FILE"),
        # numbers no run can use: refused before any work, in one line
        (["-o", "{tmp}/m.msh", "--steps", "9" * 400], 2, r"--steps.*not in the range"),
        (["-o", "{tmp}/m.msh", "--max-nodes", "9" * 400], 2, r"--max-nodes.*not in the range"),
        (["-o", "{tmp}/m.msh", "--margin", "nan"], 2, r"--margin.*finite number > 0"),
        (["-o", "{tmp}/m.msh", "--margin", "inf"], 2, r"--margin.*finite number > 0"),
        (["-o", "{tmp}/m.msh", "--margin=-1"], 2, r"--margin.*finite number > 0"),
        (["-o", "{tmp}/m.msh", "--growth", "inf"], 2, r"--growth.*finite number > 0"),
        (["-o", "{tmp}/m.msh", "--box=-inf,-inf,inf,inf"], 2, r"--box.*four finite numbers"),
        (
            ["-o", "{tmp}/m.msh", "--max-h", "1e-20"],
            1,
            r"circle\.csv: --max-h 1e-20 needs at least",
        ),
        (
            ["-o", "{tmp}/m.msh", "--max-h", "5e-324"],
            1,
            r"circle\.csv: --max-h .* needs at least inf",
        ),
        (["-o", "{tmp}/m.msh", "--max-h", "1e-308"], 1, r"circle\.csv: --max-h .* needs at least"),
        (["-o", "{tmp}/m.msh", "--resample", "1e-300"], 1, r"circle\.csv: --resample 1e-300"),
        (["-o", "{tmp}/m.msh", "--margin", "1e140"], 1, r"circle\.csv: its finest cells"),
        (["-o", "{tmp}/m.msh", "--jobs", "9" * 30, "--out-dir", "{tmp}"], 2, r"--jobs"),
        (["-o", "{tmp}/m.msh", "--margin", "1e308"], 2, r"--margin 1e\+308 puts the box"),
        (["-o", "{tmp}/m.msh", "--margin", "1e200", "--grid", "uniform"], 2, r"puts the box"),
        (["-o", "{tmp}/m.msh", "--margin", "1e200", "--exterior"], 2, r"puts the box"),
        (["-o", "{tmp}/m.msh", "--box=-1e308,-1e308,1e308,1e308"], 2, r"within 1e\+150 of 0"),
    ],
)
def test_bad_options_and_outputs(run, tmp_path, args, code, pattern):
    args = [a.format(tmp=tmp_path) for a in args]
    r = run("all", SAMPLES / "circle.csv", *args)
    assert r.exit_code == code
    assert re.search(pattern, r.stderr), r.stderr
    assert [p for p in tmp_path.iterdir() if p.is_file()] == []


def test_unreadable_input_and_unwritable_output(run, tmp_path, monkeypatch):
    f = tmp_path / "c.csv"
    f.write_text("0,0\n1,0\n0,1\n")
    real = Path.read_bytes

    def deny(self):
        if self.name == "c.csv":
            raise PermissionError(13, "Permission denied")
        return real(self)

    monkeypatch.setattr(Path, "read_bytes", deny)
    r = run("all", f, "-o", tmp_path / "m.msh")
    assert r.exit_code == 1 and "c.csv: cannot read: Permission denied" in r.stderr
    monkeypatch.undo()

    import tempfile

    def no_temp(*a, **k):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(tempfile, "mkstemp", no_temp)
    r = run("all", f, "-o", tmp_path / "m.msh")
    assert r.exit_code == 1 and "m.msh: cannot write: Permission denied" in r.stderr
    assert not (tmp_path / "m.msh").exists()


def test_failure_while_writing_leaves_no_file(run, tmp_path, monkeypatch):
    import dataclasses

    from deformesh_cli import formats

    def boom(mesh, path, version):
        Path(path).write_text("half a mesh")
        raise OSError(28, "No space left on device")

    monkeypatch.setitem(
        formats.FORMATS, "obj", dataclasses.replace(formats.FORMATS["obj"], write=boom)
    )
    r = run("all", SAMPLES / "circle.csv", "-o", tmp_path / "m.obj")
    assert r.exit_code == 1 and "No space left on device" in r.stderr
    assert list(tmp_path.iterdir()) == []


def test_state_file_of_another_kind(run, tmp_path):
    s = tmp_path / "s.state"
    s.write_bytes(b"PK\x03\x04 not really a zip")
    r = run("deform", s, "-o", tmp_path / "o.state")
    assert r.exit_code == 1 and r.stderr.startswith(f"deformesh: error: {s}")
    assert r.stderr.count("\n") == 1 and not (tmp_path / "o.state").exists()


@pytest.mark.parametrize(
    "cmd", ["all {c} -o - --format obj -q", "select {c} -o -", "all {c} -o m.vtk --json -q"]
)
def test_broken_pipe_ends_quietly(sh, tmp_path, cmd):
    """The reader is gone (``true`` reads nothing) long before deformesh writes."""
    c = SAMPLES / "peanut.csv"
    r = sh(
        f"deformesh {cmd.format(c=c)} | true; echo ${{PIPESTATUS[0]}}", cwd=tmp_path, check=False
    )
    assert r.stdout.strip() == b"1"
    assert r.stderr == b""


# --- the same catalogue as one batch, with good contours among them


def _mixed_folder(folder: Path):
    folder.mkdir()
    for name in CASES:
        _write(folder, name)
    for good in ("circle.csv", "peanut.csv", "bracket.svg"):
        (folder / good).write_bytes((SAMPLES / good).read_bytes())
    return sorted(p.name for p in folder.iterdir())


def test_batch_meshes_the_good_and_reports_every_bad(run, tmp_path):
    names = _mixed_folder(tmp_path / "in")
    out = tmp_path / "out"
    r = run(
        "all", tmp_path / "in", "--out-dir", out, "--jobs", "2", "--json", "--max-nodes", "200000"
    )
    assert r.exit_code == 1
    recs = [json.loads(ln) for ln in r.stdout.splitlines()]
    assert [Path(x["input"]).name for x in recs] == names  # input order
    ok = {Path(x["input"]).name for x in recs if x["status"] == "ok"}
    assert ok == {"circle.csv", "peanut.csv", "bracket.svg"}
    assert sorted(p.name for p in out.iterdir()) == ["bracket.msh", "circle.msh", "peanut.msh"]
    for x in recs:
        assert set(x) == {
            "input",
            "output",
            "status",
            "error",
            "seconds",
            "nodes",
            "triangles",
            "min_angle",
            "extra_boundary_nodes",
            "contract",
        }
        if x["status"] != "ok":
            name = Path(x["input"]).name
            assert re.search(CASES[name][2], x["error"]), x["error"]
            assert f"deformesh: error: {x['error']}" in r.stderr
    # the summary table: a count line and a row per input
    assert f"{len(names)} contour(s): 3 ok, {len(names) - 3} failed" in r.stderr
    # run again into the same folder (one job this time): the same bytes, nothing added
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    r2 = run(
        "all", tmp_path / "in", "--out-dir", out, "--jobs", "1", "--json", "--max-nodes", "200000"
    )
    assert r2.exit_code == 1
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_batch_is_byte_identical_across_runs_and_jobs(run, tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    for good in ("circle.csv", "peanut.csv", "bracket.svg", "naca0012.csv"):
        (src / good).write_bytes((SAMPLES / good).read_bytes())
    outs = []
    for k, jobs in enumerate(["1", "2", "2"]):
        out = tmp_path / f"out{k}"
        r = run("all", src, "--out-dir", out, "--jobs", jobs, "--format", "vtu", "-q")
        assert r.exit_code == 0, r.stderr
        outs.append({p.name: p.read_bytes() for p in out.iterdir()})
    assert outs[0] == outs[1] == outs[2] and len(outs[0]) == 4


def test_batch_fail_fast_skips_the_rest(run, tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    (src / "a_bad.csv").write_text("0,0\n1,0\n")
    (src / "b.csv").write_bytes((SAMPLES / "circle.csv").read_bytes())
    r = run("all", src, "--out-dir", tmp_path / "out", "--jobs", "1", "--fail-fast", "--json")
    assert r.exit_code == 1
    recs = [json.loads(ln) for ln in r.stdout.splitlines()]
    assert [x["status"] for x in recs] == ["failed", "skipped"]
    assert list((tmp_path / "out").iterdir()) == []


def test_batch_inputs_globs_and_collisions(run, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    (a / "c.csv").write_bytes((SAMPLES / "circle.csv").read_bytes())
    (b / "c.csv").write_bytes((SAMPLES / "circle.csv").read_bytes())
    r = run("all", a / "c.csv", b / "c.csv", "--out-dir", tmp_path / "out")
    assert r.exit_code == 2 and "would both write" in r.stderr
    r = run("all", str(tmp_path / "a" / "*.csv"), "--out-dir", tmp_path / "out", "--json")
    assert r.exit_code == 0, r.stderr
    assert [json.loads(ln)["status"] for ln in r.stdout.splitlines()] == ["ok"]
    r = run("all", str(tmp_path / "nothing*.csv"), "--out-dir", tmp_path / "out")
    assert r.exit_code == 1 and "no such file" in r.stderr
    empty = tmp_path / "empty"
    empty.mkdir()
    r = run("all", empty, "--out-dir", tmp_path / "out")
    assert r.exit_code == 2 and "holds no contour files" in r.stderr


PLATE = {
    "type": "Polygon",
    "coordinates": [[[0, 0], [4, 0], [4, 3], [0, 3], [0, 0]], [[1, 1], [1, 2], [2, 2], [1, 1]]],
}


def test_a_folder_batch_meshes_every_contour_format_and_lists_what_it_passed_over(run, tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    (src / "closed.csv").write_bytes((SAMPLES / "circle.csv").read_bytes())
    (src / "plate.geojson").write_text(json.dumps(PLATE))
    (src / "README.md").write_text("contours for the wing\n")
    (src / ".hidden").write_text("x")
    out = tmp_path / "out"
    r = run("all", src, "--out-dir", out, "--json", "-q")
    assert r.exit_code == 0, r.stderr
    recs = {Path(x["input"]).name: x for x in map(json.loads, r.stdout.splitlines())}
    assert set(recs) == {"closed.csv", "plate.geojson", "README.md"}  # hidden: left out
    assert recs["closed.csv"]["status"] == recs["plate.geojson"]["status"] == "ok"
    assert sorted(p.name for p in out.iterdir()) == ["closed.msh", "plate.msh"]
    note = recs["README.md"]
    assert note["status"] == "skipped" and note["output"] is None
    assert ".md" in note["error"] and ".geojson" in note["error"]
    assert r.stderr == ""  # -q: errors only; the record says why it was passed over
    r = run("all", src, "--out-dir", tmp_path / "out1", "--json")
    assert f"deformesh: {note['error']}" in r.stderr  # without -q, said on stderr too
    # --strict-inputs: the same file fails the batch (the contours are still meshed)
    r = run("all", src, "--out-dir", tmp_path / "out2", "--json", "-q", "--strict-inputs")
    assert r.exit_code == 1
    recs = {Path(x["input"]).name: x for x in map(json.loads, r.stdout.splitlines())}
    assert recs["README.md"]["status"] == "failed"
    assert "deformesh: error: " in r.stderr and ".md" in r.stderr
    assert sorted(p.name for p in (tmp_path / "out2").iterdir()) == ["closed.msh", "plate.msh"]
    r = run("all", src / "closed.csv", "-o", tmp_path / "one.msh", "--strict-inputs")
    assert r.exit_code == 2 and "apply to batches" in r.stderr


def test_batch_on_a_dask_cluster_gives_the_same_files(run, tmp_path):
    distributed = pytest.importorskip("distributed")  # in the test extra: never skipped in CI
    src = tmp_path / "in"
    _mixed_folder(src)
    ref = tmp_path / "ref"
    r1 = run("all", src, "--out-dir", ref, "--jobs", "2", "--json", "--max-nodes", "200000")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        out = tmp_path / "dask"
        r2 = run(
            "all",
            src,
            "--out-dir",
            out,
            "--scheduler",
            cluster.scheduler_address,
            "--json",
            "--max-nodes",
            "200000",
        )
    assert r1.exit_code == r2.exit_code == 1

    def strip(stdout, folder):
        recs = [json.loads(ln) for ln in stdout.splitlines()]
        for x in recs:
            x.pop("seconds")
            x["output"] = os.path.basename(x["output"])
        return recs

    assert strip(r1.stdout, ref) == strip(r2.stdout, out)
    assert {p.name: p.read_bytes() for p in ref.iterdir()} == {
        p.name: p.read_bytes() for p in out.iterdir()
    }


def test_scheduler_unreachable_is_one_line(run, tmp_path):
    pytest.importorskip("distributed")
    r = run(
        "all",
        SAMPLES / "circle.csv",
        "--out-dir",
        tmp_path / "o",
        "--scheduler",
        "tcp://127.0.0.1:9",
    )
    assert r.exit_code == 1 and "cannot connect" in r.stderr
    assert r.stderr.count("\n") == 1


def _on_a_terminal(args, cwd, stdout=False):
    """Run deformesh with stderr (and with ``stdout``, stdout too) on a pseudo-terminal;
    return what the terminal got."""
    import pty
    import subprocess

    from .conftest import deformesh_exe

    main, sub = pty.openpty()
    p = subprocess.Popen(
        [deformesh_exe(), *map(str, args)],
        cwd=cwd,
        stdout=sub if stdout else subprocess.PIPE,
        stderr=sub,
        stdin=subprocess.DEVNULL,
    )
    os.close(sub)
    chunks = []
    while True:
        try:
            data = os.read(main, 4096)
        except OSError:  # the child closed the terminal
            break
        if not data:
            break
        chunks.append(data)
    p.wait()
    os.close(main)
    return p.returncode, b"".join(chunks).decode(errors="replace")


def test_binary_output_is_never_written_to_a_terminal(run, tmp_path):
    c = SAMPLES / "circle.csv"
    assert run("select", c, "-o", tmp_path / "s.state").exit_code == 0
    assert run("all", c, "-o", tmp_path / "m.vtu", "-q").exit_code == 0
    for args in (
        ["select", c, "-o", "-"],
        ["all", c, "-o", "-", "--format", "vtk"],
        ["all", c, "-o", "-", "--format", "ply"],
        ["triangulate", tmp_path / "s.state", "-o", "-", "--format", "vtk"],
        ["plot", tmp_path / "m.vtu", "-o", "-"],
    ):
        code, tty = _on_a_terminal(args, tmp_path, stdout=True)
        assert code == 2, (args, tty)
        assert "refusing to write binary data to a terminal" in tty and len(tty) < 400, tty
    # a text format may go to the terminal
    code, tty = _on_a_terminal(["all", c, "-o", "-", "--format", "su2", "-q"], tmp_path, True)
    assert code == 0 and "NPOIN=" in tty


def test_progress_bars_on_a_terminal_only(run, tmp_path):
    # a mesh made in under two seconds: its summary alone, no line drawn before it
    code, tty = _on_a_terminal(["all", SAMPLES / "peanut.csv", "-o", "m.vtk"], tmp_path)
    assert code == 0 and "\x1b" not in tty and tty.count("\n") == 1
    code, tty = _on_a_terminal(["all", SAMPLES / "peanut.csv", "-o", "m.vtk", "-q"], tmp_path)
    assert code == 0 and tty == ""
    code, tty = _on_a_terminal(
        ["all", SAMPLES / "circle.csv", SAMPLES / "peanut.csv", "--out-dir", "o", "--jobs", "1"],
        tmp_path,
    )
    assert code == 0 and "meshing" in tty and "2 contour(s): 2 ok" in tty
    # not a terminal: no bar, just the summary
    r = run("all", SAMPLES / "peanut.csv", "-o", tmp_path / "n.vtk")
    assert "deforming" not in r.stderr and r.stderr.count("\n") == 1


def test_a_dying_worker_fails_its_input_only(tmp_path, monkeypatch):
    """A worker killed mid-task (out of memory, say) is one failed record, not a crash."""
    from deformesh_cli import batch
    from deformesh_cli.options import MeshOptions

    src = tmp_path / "in"
    src.mkdir()
    for name in ("a.csv", "b.csv"):
        (src / name).write_bytes((SAMPLES / "circle.csv").read_bytes())
    inputs = [f for f, _ in batch.expand_inputs([str(src)])]
    tasks = batch.make_tasks(inputs, str(tmp_path / "o"), MeshOptions(fmt="msh"))
    monkeypatch.setattr(batch, "run_task", _die_on_b)
    recs = {Path(t.source).name: r for t, r, _ in batch.run(tasks, jobs=2)}
    assert recs["a.csv"]["status"] == "ok"
    assert recs["b.csv"]["status"] == "failed"
    assert "the worker process running it died" in recs["b.csv"]["error"]


def _die_on_b(task):
    if task.source.endswith("b.csv"):
        os._exit(9)
    return _RUN_TASK(task)


def _load_run_task():
    from deformesh_cli import batch

    return batch.run_task


_RUN_TASK = _load_run_task()


def test_batch_fail_fast_with_a_pool_reports_every_input(run, tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    (src / "a_bad.csv").write_text("0,0\n1,0\n")
    for k in range(4):
        (src / f"b{k}.csv").write_bytes((SAMPLES / "peanut.csv").read_bytes())
    r = run("all", src, "--out-dir", tmp_path / "out", "--jobs", "2", "--fail-fast", "--json")
    assert r.exit_code == 1
    recs = [json.loads(ln) for ln in r.stdout.splitlines()]
    assert len(recs) == 5 and recs[0]["status"] == "failed"
    assert "skipped" in {x["status"] for x in recs}
    written = {p.name for p in (tmp_path / "out").iterdir()}
    assert written == {Path(x["output"]).name for x in recs if x["status"] == "ok"}


def test_collinear_runs_inside_a_contour_are_fine(run, tmp_path):
    """Points in a straight row are boundary nodes like any other (only a contour that is
    all one line, or doubles back on itself, is refused: see the catalogue)."""
    f = tmp_path / "c.csv"
    pts = [(i / 10, 0) for i in range(10)] + [(1, 0), (1, 0.5), (1, 1), (0.5, 1), (0, 1)]
    f.write_text("\n".join(f"{x},{y}" for x, y in pts))
    r = run("all", f, "-o", tmp_path / "m.msh", "--json")
    assert r.exit_code == 0, r.stderr
    r = run("quality", tmp_path / "m.msh", "--contour", f)
    assert r.exit_code == 0 and "contract: ok" in r.stdout


def test_batch_usage_errors_come_first_and_create_nothing(run, tmp_path):
    out = tmp_path / "out"
    r = run("all", SAMPLES / "circle.csv", "--out-dir", out, "--size", "1 +")
    assert r.exit_code == 2 and "is not an expression" in r.stderr
    r = run("all", SAMPLES / "circle.csv", SAMPLES / "circle.csv", "--out-dir", out)
    assert r.exit_code == 2 and "would both write" in r.stderr
    assert not out.exists()


def _odd_folder(tmp_path):
    """A folder of one contour and entries with a contour extension that are no regular
    files: a pipe with no writer, a link loop, a dangling link, a link to /dev/zero."""
    import os

    d = tmp_path / "in"
    d.mkdir()
    (d / "a.csv").write_text((SAMPLES / "circle.csv").read_text())
    os.mkfifo(d / "fifo.csv")
    os.symlink("loop.csv", d / "loop.csv")
    os.symlink("nowhere.csv", d / "dangling.csv")
    os.symlink("/dev/zero", d / "zero.csv")
    (d / "notes.md").write_text("not a contour")
    return d


@pytest.mark.parametrize("how", ["folder", "glob", "folder-strict", "folder-quiet"])
def test_entries_that_are_no_regular_files_are_named_never_read(run, tmp_path, how):
    d = _odd_folder(tmp_path)
    what = str(d / "*.csv") if how == "glob" else str(d)
    extra = {"folder-strict": ["--strict-inputs"], "folder-quiet": ["-q"]}.get(how, [])
    r = run("all", what, "--out-dir", tmp_path / "out", *extra)  # (a read would hang here)
    assert r.exit_code == 1
    assert f"{d}/fifo.csv: is not a regular file" in r.stderr
    assert f"{d}/zero.csv: is not a regular file" in r.stderr
    assert f"{d}/loop.csv: is a symbolic link that leads to no file" in r.stderr
    assert f"{d}/dangling.csv: is a symbolic link that leads to no file" in r.stderr
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["a.msh"]
    assert ("notes.md: not meshed" in r.stderr) == (how in ("folder",))


def test_a_link_loop_given_by_name_is_called_one(run, tmp_path):
    import os

    os.symlink("loop.csv", tmp_path / "loop.csv")
    r = run("all", tmp_path / "loop.csv", "-o", tmp_path / "m.vtk")
    assert r.exit_code == 1
    assert f"{tmp_path}/loop.csv: is a symbolic link that leads to no file" in r.stderr


def test_an_error_deep_in_the_core_is_said_with_its_files_name(tmp_path):
    """errors.naming: a message that names no file gets the contour's in front, once,
    however deep the stages nest; one that starts with another file's name keeps it."""
    from deformesh_cli.errors import SelectionError, naming

    closed = pytest.raises(SelectionError, match=r"^a\.csv: the loops do not close$")
    with closed, naming("a.csv"), naming("a.csv"):
        raise SelectionError("the loops do not close")
    field = tmp_path / "f.npy"
    field.write_bytes(b"")
    kept = pytest.raises(SelectionError, match=rf"^{re.escape(str(field))}: bad rows$")
    with kept, naming("a.csv"):
        raise SelectionError(f"{field}: bad rows")
    with pytest.raises(SelectionError, match=r"^nothing$"), naming("<contour>"):
        raise SelectionError("nothing")
