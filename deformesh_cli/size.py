"""Size functions (paper section 3.2): where cells should be small.

The deformation makes ``det grad phi = f``: a cell of the background grid
ends with ``f`` times its area.  A user gives ``f`` up to a constant, as an
expression in ``x``, ``y`` and ``d`` (distance to the contour), checked and
evaluated without ``eval`` by :mod:`.expression`, or as values on a regular
grid.  It is normalised so that the integral of ``1/f`` over the background
box equals the box's area (the box's boundary does not move, so the cells'
areas must still add up to it).  The deformation then needs ``g1 = 1/f``
(normalised) at the moving nodes: :meth:`SizeFunction.g1`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .contour import Contour
from .errors import InputError, OptionError, SizeError
from .expression import Expression
from .geometry import next_on_ring, signed_areas


class ContourDistance:
    """Distance from points to the nearest contour edge (all rings), vectorised.

    The edges are sampled at most ``spacing`` apart into a k-d tree; the
    nearest sample names an edge, and the exact distance to that edge and its
    two neighbours is returned (an upper bound within ``spacing / 2`` of the
    true distance; exact where the nearest edge is found).
    """

    def __init__(self, contour: Contour, spacing: float | None = None):
        from scipy.spatial import cKDTree

        p = contour.points
        nxt = next_on_ring(contour.ring)
        self.a, self.b = p, p[nxt]
        self.prev = np.empty_like(nxt)
        self.prev[nxt] = np.arange(len(nxt))
        self.next = nxt
        length = np.hypot(*(self.b - self.a).T)
        if spacing is None:
            spacing = max(float(np.median(length)), 1e-300)
        k = np.maximum(1, np.ceil(length / spacing).astype(np.int64))
        edge = np.repeat(np.arange(len(p)), k)
        start = np.repeat(np.cumsum(k) - k, k)
        t = (np.arange(k.sum()) - start + 0.5) / np.repeat(k, k)
        samples = self.a[edge] + t[:, None] * (self.b - self.a)[edge]
        self._edge = edge
        self._tree = cKDTree(samples)

    def __call__(self, q: np.ndarray) -> np.ndarray:
        _, i = self._tree.query(q)
        e = self._edge[i]
        best = np.full(len(q), np.inf)
        for cand in (e, self.prev[e], self.next[e]):
            best = np.minimum(best, _segment_distance(q, self.a[cand], self.b[cand]))
        return best


def box_samples(box, n: int) -> np.ndarray:
    """The centres of an n x n split of ``box``: the midpoint rule's nodes for box means."""
    x0, y0, x1, y1 = box
    xs = x0 + (np.arange(n) + 0.5) * (x1 - x0) / n
    ys = y0 + (np.arange(n) + 0.5) * (y1 - y0) / n
    return np.column_stack([np.repeat(xs, n), np.tile(ys, n)])


def _segment_distance(q, a, b):
    ab = b - a
    t = np.clip(((q - a) * ab).sum(axis=1) / np.maximum((ab * ab).sum(axis=1), 1e-300), 0, 1)
    return np.hypot(*(a + t[:, None] * ab - q).T)


def positive_values(raw, n: int):
    """``(values, k)``: a function's answer for ``n`` points as an (n,) float array (a
    scalar spread over them) and the first point where it is not finite and > 0, or
    None; ``(None, shape)`` if it has another shape."""
    v = np.asarray(raw, dtype=np.float64)
    if v.shape == ():
        v = np.full(n, float(v))
    if v.shape != (n,):
        return None, v.shape
    bad = ~(np.isfinite(v) & (v > 0))
    return v, (int(np.argmax(bad)) if bad.any() else None)


@dataclass
class SizeFunction:
    """``f`` as given (any positive scale), and its normalisation on a box."""

    raw: Callable[[np.ndarray], np.ndarray]  # points (k, 2) -> f (k,)
    label: str
    scale: float = 1.0  # f_normalised = scale * raw
    notes: list = field(default_factory=list)
    source: str = ""  # the contour it is made for, named in its errors
    rows: np.ndarray | None = None  # a size field's rows x, y, f (a state file keeps them)

    def values(self, q: np.ndarray) -> np.ndarray:
        """``f`` (as given) at points, checked finite and positive."""
        f, k = positive_values(self.raw(q), len(q))
        if f is None:
            raise SizeError(f"size function {self.label}: gave shape {k} for {len(q)} points")
        if k is not None:
            where = f"{self.source}: " if self.source else ""
            raise SizeError(
                f"{where}size function {self.label} is {f[k]:.3g} at "
                f"({q[k, 0]:.6g}, {q[k, 1]:.6g}); it must be finite and > 0 "
                "over the whole background box"
            )
        return f

    def normalise(self, box, n: int = 256) -> None:
        """Scale so that the mean of ``1/f`` over ``box`` is 1 (midpoint rule, n x n)."""
        self.scale = float(np.mean(1.0 / self.values(box_samples(box, n))))

    def g1(self, q: np.ndarray) -> np.ndarray:
        """``1/f`` normalised, at points: the deformation's target density."""
        return 1.0 / (self.scale * self.values(q))


def compile_expression(expr: str, label: str = "--size") -> Expression:
    """``--size EXPR`` parsed and checked (:mod:`.expression`), or an :class:`OptionError`."""
    return Expression(expr, label)


def from_expression(expr: str, contour: Contour, label: str = "--size") -> SizeFunction:
    """``--size EXPR``: an expression in x, y and d (distance to the contour)."""
    code = compile_expression(expr, label)
    dist = ContourDistance(contour) if code.uses_distance else None

    def raw(q):
        env = {"x": q[:, 0], "y": q[:, 1]}
        if dist is not None:
            env["d"] = dist(q)
        try:
            return code(**env)
        except (ArithmeticError, ValueError, TypeError) as exc:
            raise SizeError(
                f"{contour.source}: {label} {expr!r} fails: {type(exc).__name__}: {exc}"
            ) from None

    return SizeFunction(raw, repr(expr), source=contour.source)


def from_field(path: str) -> SizeFunction:
    """``--size-field FILE``: rows ``x, y, f`` on a regular grid (CSV with or without a
    header, or a (k, 3) .npy array), interpolated bilinearly, held constant outside."""
    return from_rows(read_field(path), path)


def read_field(path: str) -> np.ndarray:
    """The rows ``x, y, f`` of a size field file (CSV, or a .npy array of plain
    numbers), as floats; checked by :func:`from_rows`."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{path}: {'not a regular file' if p.exists() else 'no such file'}")
    try:
        if p.suffix.lower() == ".npy":
            rows = np.load(p)  # numpy refuses object arrays by default
            if rows.dtype.kind not in "iuf" or rows.dtype.fields is not None:
                raise InputError(
                    f"{path}: a size field holds real numbers, not {rows.dtype.str!r} values"
                )
        else:
            rows = np.genfromtxt(
                p,
                delimiter=None if b"," not in p.read_bytes()[:4096] else ",",
                comments="#",
                skip_header=_header_lines(p),
            )
    except (ValueError, OSError, EOFError) as exc:
        raise InputError(f"{path}: cannot read the size field: {exc}") from None
    return np.atleast_2d(np.asarray(rows, dtype=np.float64))


#: The most rows a size field may have (a 2,000 x 2,000 grid: 96 MB of floats).
MAX_FIELD_ROWS = 4_000_000


def from_rows(rows: np.ndarray, label: str) -> SizeFunction:
    """A size function from rows ``x, y, f`` on a regular grid (``label`` names them in
    errors): bilinear inside the grid, constant outside."""
    from scipy.interpolate import RegularGridInterpolator

    if rows.ndim != 2 or rows.shape[1] != 3 or not 4 <= len(rows) <= MAX_FIELD_ROWS:
        raise InputError(
            f"{label}: a size field is 4 to {MAX_FIELD_ROWS:,} rows of x, y, f "
            f"(got shape {rows.shape})"
        )
    if not np.isfinite(rows[:, :2]).all():
        raise InputError(f"{label}: a size field's x and y must be finite numbers")
    xs, ys = np.unique(rows[:, 0]), np.unique(rows[:, 1])
    if len(xs) * len(ys) != len(rows) or len(xs) < 2 or len(ys) < 2:
        raise InputError(
            f"{label}: the x, y of a size field must form a regular grid "
            f"({len(xs)} x values, {len(ys)} y values, {len(rows)} rows)"
        )
    grid = np.full((len(xs), len(ys)), np.nan)
    grid[np.searchsorted(xs, rows[:, 0]), np.searchsorted(ys, rows[:, 1])] = rows[:, 2]
    if np.isnan(grid).any():
        raise InputError(f"{label}: the size field has repeated or missing grid points")
    bad = ~(np.isfinite(grid) & (grid > 0))
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise InputError(
            f"{label}: f = {grid[i, j]:g} at ({xs[i]:g}, {ys[j]:g}); it must be finite and > 0"
        )
    interp = RegularGridInterpolator((xs, ys), grid, bounds_error=False, fill_value=None)

    def raw(q):
        c = np.column_stack([np.clip(q[:, 0], xs[0], xs[-1]), np.clip(q[:, 1], ys[0], ys[-1])])
        return interp(c)

    return SizeFunction(raw, label, rows=rows)


def _header_lines(p: Path) -> int:
    first = next(
        (
            ln
            for ln in p.read_text(errors="replace").splitlines()
            if ln.strip() and not ln.lstrip().startswith("#")
        ),
        "",
    )
    try:
        [float(v) for v in first.replace(",", " ").split()]
        return 0
    except ValueError:
        return 1


def spearman(
    points: np.ndarray, tri: np.ndarray, size: SizeFunction, exclude: np.ndarray | None = None
) -> float:
    """Rank correlation of triangle areas with ``f`` at their centroids (``exclude``:
    node ids whose triangles are left out, e.g. the boundary nodes)."""
    from scipy.stats import spearmanr

    keep = np.ones(len(tri), dtype=bool)
    if exclude is not None and len(exclude):
        mask = np.zeros(len(points), dtype=bool)
        mask[exclude] = True
        keep = ~mask[tri].any(axis=1)
    if keep.sum() < 3:
        return math.nan
    t = tri[keep]
    f = size.values(points[t].mean(axis=1))
    if np.ptp(f) == 0:  # a constant f orders nothing
        return math.nan
    return float(spearmanr(signed_areas(points, t), f).statistic)


def check_options(expr: str | None, field_path: str | None) -> None:
    """The usage errors of ``--size`` / ``--size-field``, found before any contour is read."""
    if expr is not None and field_path is not None:
        raise OptionError("give --size or --size-field, not both")
    if expr is not None:
        compile_expression(expr)


def make(expr: str | None, field_path: str | None, contour: Contour) -> SizeFunction | None:
    """The size function of ``--size`` / ``--size-field`` (at most one), or ``None``."""
    check_options(expr, field_path)
    if expr is not None:
        return from_expression(expr, contour)
    if field_path is not None:
        return from_field(field_path)
    return None


class SizePath:
    """``g(x, t)``, the target ``1/f`` along pseudo-time, from ``g0`` at t = 0 to ``g1``
    at t = 1.

    ``g0`` is the background grid's own density (1 on a uniform grid; on a graded
    one, :func:`grid_density`), so the deformation takes the grid from the cells it
    has to the cells ``f`` asks for, not from uniform ones.  ``linear`` (the paper):
    ``g = (1-t) g0 + t g1``, whose box mean stays 1 when ``g0``'s and ``g1``'s are.
    ``geometric``: ``g = g0^(1-t) g1^t / mean(g0^(1-t) g1^t)``, renormalised at
    every ``t`` (the mean over the fixed box, sampled ``n x n``): cells change area
    by the same factor at every step, which large ratios need (a linear path asks
    for nearly all of a 1000-fold shrink in the first step).
    """

    def __init__(
        self,
        g1: Callable[[np.ndarray], np.ndarray],
        box,
        geometric: bool = False,
        n: int = 256,
        g0: Callable[[np.ndarray], np.ndarray] | None = None,
    ):
        self.g1 = g1
        self.g0 = g0
        self.geometric = geometric
        if geometric:
            q = box_samples(box, n)
            self._log1 = np.log(g1(q))
            self._log0 = np.zeros(len(q)) if g0 is None else np.log(g0(q))

    def g_and_rate(self, q: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``g`` and ``dg/dt`` at points ``q`` and pseudo-time ``t``."""
        g1 = self.g1(q)
        if not self.geometric:
            if self.g0 is None:
                return (1.0 - t) + t * g1, g1 - 1.0
            g0 = self.g0(q)
            return (1.0 - t) * g0 + t * g1, g1 - g0
        l0, l1 = self._log0, self._log1
        w = np.exp((1.0 - t) * l0 + t * l1)
        mean, mean_log = w.mean(), (w * (l1 - l0)).mean()
        log0 = 0.0 if self.g0 is None else np.log(self.g0(q))
        log1 = np.log(g1)
        g = np.exp((1.0 - t) * log0 + t * log1) / mean
        return g, g * (log1 - log0 - mean_log / mean)


#: Where a graded grid's deformation with f folds, its second part asks each place for
#: at most this factor more or fewer nodes than the grid has there (the grid already
#: follows f to a level of the quadtree, a factor of 4 in area; more, and the nodes by
#: the contour, which its points hold, fold against it: ``benchmarks/MEASURED.md``).
MAX_DENSITY_RATIO = 2.0


def limited_target(g1, g0, box, ratio: float = MAX_DENSITY_RATIO, n: int = 256):
    """``g1`` kept within ``ratio`` of the grid's density ``g0`` (after scaling ``g1`` to
    ``g0`` by their geometric means), then normalised to box mean 1 again."""
    q = box_samples(box, n)
    log_k = float(np.mean(np.log(g1(q)) - np.log(g0(q))))
    lo, hi = -np.log(ratio), np.log(ratio)

    def raw(p):
        return g0(p) * np.exp(np.clip(np.log(g1(p)) - np.log(g0(p)) - log_k, lo, hi))

    scale = float(np.mean(raw(q)))
    return lambda p: raw(p) / scale


def grid_density(points: np.ndarray, triangles: np.ndarray, box, n: int = 256):
    """A graded grid's own density, as a function of position: at each node the mean
    of one over the areas of its triangles (a node on the box's sides has half the
    triangles of one inside, not twice the density), linear in between (the nodes of
    none of ``triangles`` left out; outside their hull, the median), scaled so its
    mean over ``box`` is 1 as :meth:`SizeFunction.g1`'s is."""
    from scipy.interpolate import LinearNDInterpolator

    from .geometry import signed_areas

    inv = np.repeat(1.0 / np.abs(signed_areas(points, triangles)), 3)
    count = np.bincount(triangles.ravel(), minlength=len(points))
    rho = np.bincount(triangles.ravel(), inv, minlength=len(points)) / np.maximum(count, 1)
    used = count > 0
    # linear over the Delaunay triangulation scipy builds of the nodes: nearly the
    # grid's own triangles
    interp = LinearNDInterpolator(points[used], rho[used], fill_value=float(np.median(rho[used])))
    scale = float(np.mean(interp(box_samples(box, n))))

    def g0(q: np.ndarray) -> np.ndarray:
        return interp(q) / scale

    return g0
