"""Size expressions (``--size EXPR``), parsed and evaluated without ``eval``.

An expression is parsed by :mod:`ast` and then checked against a small
grammar; anything outside it is refused before any evaluation:

- numbers (``2``, ``0.5``, ``1e-3``), the variables ``x``, ``y``, ``d`` and
  the constants ``pi``, ``e``;
- ``+ - * / // % **``, unary ``+ -``, comparisons ``< <= > >= == !=``
  (chains too) and ``& | ~`` on them (element-wise and, or, not);
- calls of the listed functions by name, with positional arguments only
  (:data:`FUNCTIONS`).

No attribute access, subscripts, keywords, strings, lambdas, comprehensions
or other names exist in the grammar, so an expression can only compute
numbers.  Its cost is bounded too: at most :data:`MAX_LENGTH` characters,
:data:`MAX_NODES` grammar nodes and :data:`MAX_DEPTH` levels, every
constant is a float (so ``9**9**9`` overflows at once instead of building a
huge integer), and every part that does not depend on ``x``, ``y`` or ``d``
is computed once at parse time and refused if it is not finite.  Evaluation
is then one numpy operation per node on arrays of the query points' length.

The operations are Python's operators and numpy's functions applied to the
same operands ``eval`` would see, so a valid expression gives the same bits.
"""

from __future__ import annotations

import ast
import functools
import math
import operator
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .errors import OptionError

#: The longest expression accepted, in characters.
MAX_LENGTH = 2000
#: The most grammar nodes (numbers, names, operators, calls) accepted.
MAX_NODES = 400
#: The deepest nesting accepted.
MAX_DEPTH = 100

VARIABLES = ("x", "y", "d")
CONSTANTS = {"pi": math.pi, "e": math.e}


def _reduce(fn: Callable) -> Callable:
    return lambda *args: functools.reduce(fn, args)


#: name: (function, smallest and largest number of arguments)
FUNCTIONS: dict[str, tuple[Callable, int, int]] = {
    **{
        name: (getattr(np, name), 1, 1)
        for name in ("sqrt", "exp", "log", "log10", "sin", "cos", "tan", "tanh", "abs")
    },
    **{name: (getattr(np, name), 2, 2) for name in ("arctan2", "hypot", "minimum", "maximum")},
    "where": (np.where, 3, 3),
    "clip": (np.clip, 3, 3),
    "min": (_reduce(np.minimum), 2, 8),
    "max": (_reduce(np.maximum), 2, 8),
}

_BINARY = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.FloorDiv: operator.floordiv,
    ast.Mod: operator.mod,
    ast.Pow: operator.pow,
    ast.BitAnd: np.logical_and,
    ast.BitOr: np.logical_or,
}
_UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos, ast.Invert: np.logical_not}
_COMPARE = {
    ast.Lt: operator.lt,
    ast.LtE: operator.le,
    ast.Gt: operator.gt,
    ast.GtE: operator.ge,
    ast.Eq: operator.eq,
    ast.NotEq: operator.ne,
}


@dataclass(frozen=True)
class _Node:
    """One node of a checked expression: ``fn(*args)``, a variable or a constant."""

    fn: Callable | None = None
    args: tuple = ()
    var: str | None = None
    value: float | None = None

    def __call__(self, env: dict):
        if self.value is not None:
            return self.value
        if self.var is not None:
            return env[self.var]
        return self.fn(*(a(env) for a in self.args))


def _chain(ops: tuple, *operands):
    """``a < b <= c`` as ``(a < b) & (b <= c)``, as 1.0 or 0.0 (so that arithmetic on it,
    ``-(x < 1)`` say, works, where numpy refuses it on booleans)."""
    out = None
    for op, a, b in zip(ops, operands, operands[1:]):
        r = op(a, b)
        out = r if out is None else np.logical_and(out, r)
    return np.asarray(out, dtype=float)


class Expression:
    """A checked size expression; call it with ``x``, ``y`` (and ``d``) arrays."""

    def __init__(self, text: str, label: str = "--size"):
        self.text = text
        self.label = label
        self._count = 0
        if not isinstance(text, str):
            raise OptionError(self._say(f"is a {type(text).__name__}, not an expression"))
        if len(text) > MAX_LENGTH:
            raise OptionError(
                self._say(f"is {len(text)} characters long; at most {MAX_LENGTH} are accepted")
            )
        try:
            tree = ast.parse(text.strip(), mode="eval")
        except SyntaxError as exc:
            raise OptionError(self._say(f"is not an expression: {exc.msg}")) from None
        except (ValueError, RecursionError, MemoryError):
            raise OptionError(self._say("is not an expression: too complex to parse")) from None
        self.names: set[str] = set()
        try:
            self._root = self._build(tree.body, 1)
        except RecursionError:
            raise OptionError(
                self._say(f"is nested too deeply (at most {MAX_DEPTH} levels)")
            ) from None

    @property
    def uses_distance(self) -> bool:
        """Whether the expression reads ``d`` (the distance to the contour)."""
        return "d" in self.names

    def __call__(self, **env: np.ndarray):
        """The expression's values (NaN or inf where it has none: the caller checks)."""
        with np.errstate(all="ignore"):
            return self._root(env)

    def _say(self, what: str) -> str:
        return f"{self.label} {_short(self.text)!r} {what}"

    def _build(self, node: ast.AST, depth: int) -> _Node:
        self._count += 1
        if self._count > MAX_NODES:
            raise OptionError(self._say(f"has more than {MAX_NODES} parts"))
        if depth > MAX_DEPTH:
            raise OptionError(self._say(f"is nested too deeply (at most {MAX_DEPTH} levels)"))
        if isinstance(node, ast.Constant):
            v = node.value
            if isinstance(v, bool) or not isinstance(v, int | float):
                raise OptionError(self._say(f"may hold only numbers, not {v!r}"))
            try:
                return self._constant(float(v), self._source(node))
            except OverflowError:
                raise OptionError(
                    self._say("has a number too large for double precision")
                ) from None
        if isinstance(node, ast.Name):
            if node.id in VARIABLES:
                self.names.add(node.id)
                return _Node(var=node.id)
            if node.id in CONSTANTS:
                return _Node(value=CONSTANTS[node.id])
            raise OptionError(self._unknown(node.id))
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            return self._fold(_BINARY[type(node.op)], node, (node.left, node.right), depth)
        if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
            return self._fold(_UNARY[type(node.op)], node, (node.operand,), depth)
        if isinstance(node, ast.Compare) and all(type(op) in _COMPARE for op in node.ops):
            ops = tuple(_COMPARE[type(op)] for op in node.ops)
            fn = functools.partial(_chain, ops)
            return self._fold(fn, node, (node.left, *node.comparators), depth)
        if isinstance(node, ast.Call):
            return self._call(node, depth)
        raise OptionError(self._say(f"uses {_describe(node)}, which size expressions do not allow"))

    def _call(self, node: ast.Call, depth: int) -> _Node:
        if not isinstance(node.func, ast.Name):
            raise OptionError(
                self._say(f"calls {_describe(node.func)}; only the listed functions by name")
            )
        name = node.func.id
        if name not in FUNCTIONS:
            raise OptionError(self._unknown(name))
        if node.keywords:
            raise OptionError(
                self._say(f"passes keyword arguments to {name}(); give them in order")
            )
        fn, lo, hi = FUNCTIONS[name]
        if any(isinstance(a, ast.Starred) for a in node.args):
            raise OptionError(self._say(f"unpacks arguments to {name}()"))
        if not lo <= len(node.args) <= hi:
            want = str(lo) if lo == hi else f"{lo} to {hi}"
            raise OptionError(
                self._say(f"gives {name}() {len(node.args)} arguments; it takes {want}")
            )
        return self._fold(fn, node, tuple(node.args), depth)

    def _fold(self, fn: Callable, node: ast.AST, children: tuple, depth: int) -> _Node:
        args = tuple(self._build(c, depth + 1) for c in children)
        out = _Node(fn=fn, args=args)
        if all(a.value is not None for a in args):  # no variable below: compute it now
            v = math.nan
            try:
                with np.errstate(all="ignore"):
                    v = out({})  # kept as computed (a bool, a numpy scalar), as eval has it
                finite = bool(np.isfinite(v))
            except (ArithmeticError, ValueError, TypeError):
                finite = False
            if np.iscomplexobj(v):  # ((-1)**0.5: Python's power of a negative number)
                raise OptionError(
                    self._say(f"has a part that is not a real number ({self._source(node)})")
                )
            if not finite:
                v = math.nan
            return self._constant(v, self._source(node))
        return out

    def _source(self, node: ast.AST) -> str:
        return _short(ast.get_source_segment(self.text.strip(), node) or "?", 40)

    def _constant(self, v, source: str) -> _Node:
        if not np.isfinite(v):
            raise OptionError(self._say(f"has a part that is not a finite number ({source})"))
        return _Node(value=v)

    def _unknown(self, name: str) -> str:
        allowed = ", ".join([*VARIABLES, *sorted([*CONSTANTS, *FUNCTIONS])])
        return self._say(f"uses unknown name(s) {name}; allowed: {allowed}")


def _short(text, width: int = 80) -> str:
    """``text`` cut to ``width`` characters for a one-line message."""
    text = str(text)
    return text if len(text) <= width else text[: width - 3] + "..."


def _describe(node: ast.AST) -> str:
    return {
        ast.Attribute: "attribute access",
        ast.Subscript: "a subscript",
        ast.Lambda: "a lambda",
        ast.ListComp: "a comprehension",
        ast.GeneratorExp: "a comprehension",
        ast.SetComp: "a comprehension",
        ast.DictComp: "a comprehension",
        ast.BoolOp: "'and'/'or' (use & and | on comparisons, or where)",
        ast.IfExp: "'if'/'else' (use where(condition, a, b))",
        ast.NamedExpr: "an assignment",
    }.get(type(node), f"a {type(node).__name__}")
