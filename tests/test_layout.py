"""The shape of the package: options written once, the core free of click, prints and
exits, every core error a one-line message."""

import ast
import re
import subprocess
import sys

import click
import pytest

from deformesh_cli import options as opts
from deformesh_cli.cli import cli
from deformesh_cli.cli.options import AS_MADE
from deformesh_cli.options import MeshOptions, MoveOptions

from .conftest import ROOT, SAMPLES

PACKAGE = ROOT / "deformesh_cli"
#: every module but the command line (cli/ and __main__.py, which runs it)
CORE = sorted(
    p
    for p in PACKAGE.rglob("*.py")
    if "cli" not in p.relative_to(PACKAGE).parts and p.name != "__main__.py"
)


def _cli_params():
    for name, cmd in cli.commands.items():
        if name == "adapt":  # (its options are its own: it meshes nothing)
            continue
        cls = MoveOptions if name == "move" else MeshOptions
        fields = opts.fields(cls)
        for p in cmd.params:
            if p.name in fields:
                yield name, p, fields[p.name]


def test_every_option_of_the_options_objects_is_on_the_command_line():
    seen = {(cmd, p.name) for cmd, p, _ in _cli_params()}
    assert {("all", f) for f in opts.fields(MeshOptions)} <= seen
    assert {("move", f) for f in opts.fields(MoveOptions)} <= seen
    for stage in ("select", "deform", "triangulate"):
        assert {(stage, f) for f in opts.STAGES[stage]} <= seen


@pytest.mark.parametrize("cmd,param,field", list(_cli_params()), ids=lambda v: str(v)[:30])
def test_cli_default_and_help_are_the_options_objects(cmd, param, field):
    assert param.default == field.default, f"{cmd} {param.opts}"
    # (quality and plot read a contour to compare a mesh with: their own texts)
    said = AS_MADE.get(field.name) if cmd in ("quality", "plot") else None
    assert param.help.startswith(said or field.metadata["help"])
    assert opts.flag(field) in param.opts
    if "choices" in field.metadata:
        assert tuple(param.type.choices) == tuple(field.metadata["choices"])


def test_the_library_defaults_are_the_cli_defaults(tmp_path):
    """`deformesh all` with no options writes what mesh_contour with no options gives."""
    from deformesh_cli import formats, mesh_contour
    from deformesh_cli.readers import load_contour

    res = mesh_contour(load_contour(SAMPLES / "peanut.csv"))
    formats.write_mesh(res.mesh, str(tmp_path / "lib.vtk"))
    r = click.testing.CliRunner().invoke(
        cli, ["all", str(SAMPLES / "peanut.csv"), "-o", str(tmp_path / "cli.vtk"), "-q"]
    )
    assert r.exit_code == 0, r.output
    assert (tmp_path / "lib.vtk").read_bytes() == (tmp_path / "cli.vtk").read_bytes()


def test_options_are_frozen_and_keyword_only():
    o = MeshOptions(h=0.1)
    with pytest.raises(AttributeError):
        o.h = 0.2
    with pytest.raises(TypeError):
        MeshOptions(0.1)
    with pytest.raises(TypeError):
        o.replace(no_such_option=1)
    assert o.replace(h=0.2).h == 0.2 and o.h == 0.1


def _calls(tree):
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            if isinstance(f, ast.Name):
                yield f.id
            elif isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name):
                yield f"{f.value.id}.{f.attr}"


@pytest.mark.parametrize("path", CORE, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_the_core_never_prints_exits_or_imports_click(path):
    tree = ast.parse(path.read_text())
    calls = set(_calls(tree))
    assert not calls & {"print", "exit", "quit", "sys.exit", "os._exit", "click.echo"}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            assert all(a.name.split(".")[0] != "click" for a in node.names)
        if isinstance(node, ast.ImportFrom) and node.level == 0:
            assert node.module.split(".")[0] != "click"
        if isinstance(node, ast.ImportFrom) and node.level > 0:
            assert not (node.module or "").startswith("cli"), f"the core imports the CLI: {path}"


def test_meshing_and_moving_from_the_library_load_no_click_and_print_nothing(tmp_path):
    """The library runs `deformesh all` and `deformesh move`'s work without click."""
    frames = sorted((SAMPLES / "pulsating").glob("frame_*.csv"))[:3]
    code = f"""
import sys
from deformesh_cli import formats, mesh_contour
from deformesh_cli.move import move_frames
from deformesh_cli.options import MoveOptions
from deformesh_cli.readers import load_contour
res = mesh_contour(load_contour({str(frames[0])!r}))
formats.write_mesh(res.mesh, {str(tmp_path / "m.vtu")!r})
s = move_frames({str(tmp_path / "m.vtu")!r}, {[str(f) for f in frames[1:]]!r},
                {str(tmp_path / "frames")!r}, MoveOptions(steps=5))
assert s["frames"] == 3 and s["pvd"] == "m.pvd", s
assert "click" not in sys.modules, "click was imported"
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout == "" and r.stderr == ""
    written = sorted(p.name for p in (tmp_path / "frames").iterdir())
    assert written == ["m.pvd", "m_0000.vtu", "m_0001.vtu", "m_0002.vtu"]


def test_a_solver_that_does_not_converge_is_a_one_line_error(run, tmp_path, monkeypatch):
    import scipy.sparse.linalg as spla

    monkeypatch.setattr(spla, "cg", lambda K, b, **kw: (b * 0, 1))  # never converges
    out = tmp_path / "m.vtk"
    r = run("all", SAMPLES / "circle.csv", "--solver", "amg", "-o", out)
    assert r.exit_code == 1
    assert r.stderr.count("\n") == 1
    assert r.stderr.startswith(f"deformesh: error: {SAMPLES / 'circle.csv'}: deformation failed")
    assert "did not converge" in r.stderr and "--solver direct" in r.stderr
    assert not out.exists()


def test_only_deformesh_errors_reach_the_cli_layer():
    """Every exception class the core raises on purpose is a DeformeshError."""
    from deformesh_cli import errors

    raised = set()
    for path in CORE:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call):
                f = node.exc.func
                raised.add(f.id if isinstance(f, ast.Name) else getattr(f, "attr", None))
    ours = {n for n in dir(errors) if isinstance(getattr(errors, n), type)}
    # SelectionError subclasses of select, trace and construct; state's InputError
    local = {
        "NoFreeNode",
        "TraceError",
        "_Damaged",
        "_Crowded",
        "_Stray",
        "_Pinch",
    }
    assert raised - ours - local == set(), "the core raises non-deformesh errors"


def test_no_rule_of_the_package_names_a_corpus_contour():
    """A rule is one of geometry: no constant, comment or docstring of the package names
    a contour of tests/data/corpus (measurements on them live in benchmarks/)."""
    names = [p.stem for p in (ROOT / "tests" / "data" / "corpus").iterdir() if p.suffix != ".md"]
    assert len(names) >= 40
    # and the place or thing alone ("norway", "nodedotjs"), as a word of four letters or
    # more; "python" is also the language (``python -m deformesh_cli``)
    words = {re.sub(r"^(airfoil|coast|icon_si|icon_bi)_", "", n) for n in names}
    words = {w for w in words if len(w) >= 4} - {"python"}
    assert {"norway", "nodedotjs", "madagascar"} <= words
    named = [
        f"{path.relative_to(ROOT)}: {name}"
        for path in sorted((ROOT / "deformesh_cli").rglob("*.py"))
        for name in names
        if name in path.read_text()
    ] + [
        f"{path.relative_to(ROOT)}: {w}"
        for path in sorted((ROOT / "deformesh_cli").rglob("*.py"))
        for w in sorted(words)
        if re.search(rf"\b{re.escape(w)}\b", path.read_text())
    ]
    assert named == []


def test_the_package_imports_one_way():
    """No import cycle among the package's modules, counting imports inside functions."""
    modules = {}
    for path in sorted((ROOT / "deformesh_cli").rglob("*.py")):
        rel = path.relative_to(ROOT).with_suffix("")
        name = ".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)
        modules[name] = path
    edges = {m: set() for m in modules}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.ImportFrom) or not node.level:
                continue
            base = package.split(".")
            base = base[: len(base) - node.level + 1]
            target = ".".join(base + ([node.module] if node.module else []))
            for alias in node.names:
                full = f"{target}.{alias.name}"
                hit = full if full in modules else target if target in modules else None
                if hit and hit != name:
                    edges[name].add(hit)
    seen, stack, cycle = set(), [], []

    def visit(m):
        if m in stack:
            cycle.append(stack[stack.index(m) :] + [m])
            return
        if m in seen:
            return
        seen.add(m)
        stack.append(m)
        for n in sorted(edges[m]):
            visit(n)
        stack.pop()

    for m in sorted(modules):
        visit(m)
    assert cycle == [], cycle[:3]


def test_the_pipeline_asks_its_selections_rather_than_their_types():
    """``pipeline.py`` runs the stages through what a selection says of itself
    (triangles, band, kept side, whether folds are mended), not by its class."""
    tree = ast.parse((ROOT / "deformesh_cli" / "pipeline.py").read_text())
    calls = [
        node.lineno
        for node in ast.walk(tree)
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "isinstance"
    ]
    assert calls == []
