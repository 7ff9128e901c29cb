"""Size expressions are data: parsed against a small grammar and evaluated without ``eval``.

What the grammar allows gives the same bits as numpy evaluation of the same text; what
it does not allow (attribute access, subscripts, lambdas, other names, huge constants)
is refused before anything is evaluated, from the command line and from a state file."""

import ast
import io
import json
import math
import subprocess
import zipfile

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from deformesh_cli import expression
from deformesh_cli.errors import OptionError
from deformesh_cli.expression import FUNCTIONS, Expression

from .conftest import SAMPLES, deformesh_exe


def _payload(marker) -> str:
    """Runs ``touch marker`` through os.system if evaluated by Python's eval."""
    return (
        "(lambda a=x: [c for c in a.__class__.__mro__[-1].__subclasses__() "
        "if c.__name__=='_wrap_close'][0].__init__.__globals__['system']"
        f"('touch {marker}'))()"
    )


#: the namespace an ``eval`` of the same text would see (the reference, in tests only)
_NUMPY = {name: getattr(np, name) for name in FUNCTIONS if hasattr(np, name)}
_NUMPY.update(min=np.minimum, max=np.maximum, pi=math.pi, e=math.e)


class _ComparisonsAsFloat(ast.NodeTransformer):
    """A comparison is 1.0 or 0.0 in an expression (``expression._chain``), where numpy
    gives booleans, whose ``exp`` is a float16: the reference converts a comparison
    given to a function (elsewhere numpy's booleans give the same numbers)."""

    def visit_Call(self, node):
        self.generic_visit(node)
        node.args = [
            ast.Call(ast.Name("_as_float", ast.Load()), [a], [])
            if isinstance(a, ast.Compare)
            else a
            for a in node.args
        ]
        return node


def _reference(text, env):
    tree = ast.fix_missing_locations(_ComparisonsAsFloat().visit(ast.parse(text, mode="eval")))
    code = compile(tree, "<reference>", "eval")
    with np.errstate(all="ignore"):
        names = {**_NUMPY, "_as_float": lambda v: np.asarray(v, dtype=float), **env}
        return eval(code, {"__builtins__": {}}, names)


def _points(n=257, seed=0):
    rng = np.random.default_rng(seed)
    return {k: rng.uniform(-3, 3, n) for k in "xy"} | {"d": rng.uniform(0, 2, n)}


DOCUMENTED = [
    "0.2 + d",
    "0.1 + d",
    "0.02 + hypot(x - 0.4, y - 0.2)",
    "1 + x**2",
    "exp(-y)",
    "exp(x)",
    "3.7 + 0 * x",
    "where(d < 0.1, 0.5, 1 + d)",
    "clip(0.2 + 2*pi*d/e, 0.3, 4)",
    "max(0.1, min(1, sqrt(abs(x*y)) + log10(2 + d) + tanh(y) + arctan2(y, x + 3)))",
    "maximum(x, y) - minimum(x, -y) + sin(x) * cos(y) + tan(0.1 * x) + log(1 + d)",
    "x // 0.7 + x % 0.3 + (x > 0) * 2 + ((x > 0) & (y < 1) | ~(d > 1))",
]


@pytest.mark.parametrize("text", DOCUMENTED)
def test_documented_expressions_give_numpys_bits(text):
    env = _points()
    got = np.broadcast_to(Expression(text)(**env), (257,))
    want = np.broadcast_to(_reference(text, env), (257,))
    assert got.dtype == np.result_type(want) or got.dtype.kind == want.dtype.kind == "f"
    np.testing.assert_array_equal(got.astype(float), want.astype(float))


_LEAF = st.one_of(
    st.sampled_from(["x", "y", "d", "pi", "e"]),
    st.integers(0, 5).map(str),
    st.floats(0.01, 9, allow_nan=False).map(lambda v: f"{v:.3g}"),
)


def _grow(inner):
    binary = st.tuples(inner, st.sampled_from(["+", "-", "*", "/", "**", "%", "<"]), inner)
    one = st.tuples(st.sampled_from(["sqrt", "exp", "log", "sin", "tanh", "abs", "-"]), inner)
    two = st.tuples(st.sampled_from(["hypot", "arctan2", "min", "max", "minimum"]), inner, inner)
    return st.one_of(
        binary.map(lambda t: f"({t[0]} {t[1]} {t[2]})"),
        one.map(lambda t: f"{t[0]}({t[1]})" if t[0] != "-" else f"-{t[1]}"),
        two.map(lambda t: f"{t[0]}({t[1]}, {t[2]})"),
        st.tuples(inner, inner, inner).map(lambda t: f"where({t[0]} < {t[1]}, {t[1]}, {t[2]})"),
    )


@given(st.recursive(_LEAF, _grow, max_leaves=12))
def test_random_expressions_give_numpys_bits_or_a_refusal(text):
    env = _points(31)
    try:
        code = Expression(text)
    except OptionError as exc:  # only a constant part that is not a finite number
        assert "not a finite number" in str(exc)
        return
    got = np.asarray(code(**env), dtype=float)
    try:
        want = np.asarray(_reference(text, env), dtype=float)
    except (TypeError, OverflowError):  # Python ints or complex numbers: eval's own trouble
        assume(False)
    np.testing.assert_array_equal(np.broadcast_to(got, (31,)), np.broadcast_to(want, (31,)))


def _balanced_sum(n: int) -> str:
    """``x`` summed n times as a balanced tree (2n - 1 parts, about log2 n deep)."""
    return "x" if n == 1 else f"({_balanced_sum(n // 2)}+{_balanced_sum(n - n // 2)})"


def test_a_chained_comparison_is_an_elementwise_and():
    env = _points()
    got = Expression("0 < x <= 1")(**env)
    np.testing.assert_array_equal(got, (env["x"] > 0) & (env["x"] <= 1))


@pytest.mark.parametrize(
    "text,fragment",
    [
        ("x.__class__", "attribute access"),
        ("x[0]", "a subscript"),
        ("(lambda: 1)()", "calls a lambda"),
        ("[1 for v in x]", "a comprehension"),
        ("sqrt(x=1)", "keyword arguments"),
        ("sqrt(*x)", "unpacks arguments"),
        ("sqrt(x, y)", "gives sqrt() 2 arguments; it takes 1"),
        ("where(x > 0, 1)", "takes 3"),
        ("'abc'", "only numbers"),
        ("True + x", "only numbers"),
        ("1j * x", "only numbers"),
        ("__import__('os')", "unknown name(s) __import__"),
        ("open", "unknown name(s) open"),
        ("np.sin(x)", "attribute access"),
        ("x if y else d", "'if'/'else'"),
        ("x and y", "'and'/'or'"),
        ("(z := 1)", "an assignment"),
        ("9**9**9", "not a finite number (9**9**9)"),
        ("x * 10**400", "not a finite number"),
        ("1e999 + x", "not a finite number (1e999)"),
        ("exp(1000) * x", "not a finite number (exp(1000))"),
        ("x + 1/0", "not a finite number (1/0)"),
        ("1 +", "is not an expression"),
        ("x" + " + x" * 600, "characters long"),
        (_balanced_sum(256), "more than 400 parts"),
        ("sqrt(" * 101 + "x" + ")" * 101, "nested too deeply"),
        ("-" * 1990 + "x", "too"),
    ],
)
def test_what_the_grammar_refuses(text, fragment):
    with pytest.raises(OptionError) as exc:
        Expression(text)
    msg = str(exc.value)
    assert fragment in msg
    assert "\n" not in msg and len(msg) < 400


def test_long_expressions_within_the_limits_are_evaluated():
    one = np.ones(2)
    assert Expression("+".join(["x"] * 99))(x=one).tolist() == [99.0, 99.0]  # 99 deep
    assert Expression(_balanced_sum(200))(x=one).tolist() == [200.0, 200.0]  # 399 parts
    assert len(_balanced_sum(200)) < expression.MAX_LENGTH


def test_the_payload_on_the_command_line_is_a_usage_error(run, tmp_path):
    marker = tmp_path / "PWNED"
    out = tmp_path / "m.vtk"
    r = run("all", SAMPLES / "circle.csv", "-o", out, "--size", _payload(marker))
    assert r.exit_code == 2
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("Error:")]
    assert len(errors) == 1 and "calls a lambda" in errors[0]
    assert not marker.exists() and not out.exists()


def _with_size(state: bytes, size) -> bytes:
    """A copy of a state file whose recorded ``size`` option is ``size``."""
    src, buf = zipfile.ZipFile(io.BytesIO(state)), io.BytesIO()
    with zipfile.ZipFile(buf, "w") as dst:
        for name in src.namelist():
            data = src.read(name)
            if name == "meta.json":
                meta = json.loads(data)
                meta["options"]["size"] = size
                data = json.dumps(meta).encode()
            dst.writestr(name, data)
    return buf.getvalue()


@pytest.fixture(scope="module")
def states(tmp_path_factory):
    """A selected and a deformed state of samples/circle.csv (the latter with --size 1)."""
    d = tmp_path_factory.mktemp("states")
    exe = deformesh_exe()
    sel, dfm = d / "s.state", d / "d.state"
    subprocess.run([exe, "select", SAMPLES / "circle.csv", "-o", sel, "-q"], check=True)
    subprocess.run([exe, "deform", sel, "-o", dfm, "-q", "--size", "1"], check=True)
    return {"select": sel.read_bytes(), "deform": dfm.read_bytes()}


@pytest.mark.parametrize("command,stage", [("deform", "select"), ("triangulate", "deform")])
@pytest.mark.parametrize("kind", ["payload", "9**9**9", "not a string"])
def test_a_state_file_never_runs_its_size(states, tmp_path, command, stage, kind):
    marker = tmp_path / "PWNED"
    size = {"payload": _payload(marker), "9**9**9": "9**9**9", "not a string": 5}[kind]
    bad = tmp_path / "bad.state"
    bad.write_bytes(_with_size(states[stage], size))
    out = tmp_path / "out.vtk"
    # a subprocess with a timeout: a size that hangs must fail this test, not the suite
    r = subprocess.run(
        [deformesh_exe(), command, bad, "-o", out],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert r.returncode == 1, r.stderr
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"deformesh: error: {bad}: "), r.stderr
    assert ("not a string" in lines[0]) == (kind == "not a string")
    assert not marker.exists() and not out.exists()


def test_no_eval_exec_or_pickle_in_the_package():
    """The package never evaluates text as Python code nor reads pickled objects."""
    import ast
    from pathlib import Path

    import deformesh_cli

    root = Path(deformesh_cli.__file__).parent
    for path in sorted(root.rglob("*.py")):
        text = path.read_text()
        assert "pickle" not in text, path
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
                assert node.func.id not in {"eval", "exec", "compile", "__import__"}, path


def test_a_valid_state_size_still_works(states, tmp_path):
    good = tmp_path / "good.state"
    good.write_bytes(_with_size(states["deform"], "1 + 0 * x"))
    out = tmp_path / "m.vtk"
    r = subprocess.run(
        [deformesh_exe(), "triangulate", good, "-o", out, "--json", "-q"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["size"] == "'1 + 0 * x'"
    assert out.exists()
