"""r-adaptation: a mesh's nodes moved so that its cells follow a monitor ``M > 0``, the
triangles unchanged (the paper's section 3.2 deformation, driven by a solution).

Where ``M`` is large the cells shrink: the target is equidistribution, every cell's
integral of ``M`` the same.  Relative to a reference mesh's cells (the input mesh
itself by default), a cell at ``y`` should end ``c / M(y)`` times its reference
area: the deformation's size function ``f = c / M``, density ``g = 1/f = M / c``.
The deformation goes from ``g = 1`` (the reference's cells as they are) to it over
pseudo-time on the paper's linear path ``g = (1 - t) + t M / c``, its velocity ``V``
from the paper's div-curl system on ``U = g V`` (``div U = -dg/dt``, ``curl U =
0``), discretised so that the divergence equation is the rate of each cell's mass
``|K| gbar_K`` (:class:`VelocitySystem`): the mass is the cell's reference area at
the start and, where the equations hold, stays so; at the end it is the cell's P1
integral of ``M / c``.  ``c`` makes the masses sum to the domain's area on the mesh
as it is at each solve.  Between solves ``U`` (which the path leaves unchanged) is
frozen as a P1 field and the nodes move through ``U / g`` by midpoint substeps;
every substep is checked for folds and the interval halved where one would appear,
and a run that cannot avoid one is refused.  ``M`` equal at every node gives back
the reference coordinates unchanged (``g`` stays 1, no node moves).

Boundary nodes either stay where they are, bit for bit (the user's contour points,
corners, and every boundary node with ``slide=False``), or slide along the straight
run of boundary they sit on (their two boundary neighbours collinear with them, to
:data:`COLLINEAR` relative): only their velocity along it is solved for, so a node on
an axis-parallel side keeps that coordinate to the bit, and the domain keeps its
shape.

The equidistribution measures are ``movement``'s: ``M`` interpolated at the nodes,
integrated over each cell of the adapted mesh (P1), divided by that cell's area in
the reference mesh; their ``sigma / mu`` and ``max / min`` (its "volume ratio").
Nothing here prints or exits.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ._divcurl import load_vector, normal_equations
from .divcurl import gradients
from .errors import FoldError, InputError, MonitorError, OptionError
from .geometry import boundary_edges, signed_areas, unique_inverse
from .quality import measures
from .size import positive_values
from .splitsolve import SplitSolver

#: Solves of the velocity at least, each on the mesh as it then is: the time between
#: two solves is at most ``1 / ADAPT_STEPS`` (where the velocity is steep,
#: :data:`STRETCH` asks for more: 12 on the ``movement`` ring on a 300 x 300 grid).
#: On that ring 10 end at sigma/mu 0.0194, 5 at 0.0195, 20 at 0.0178; on its 20 x 20
#: grid 10 at 0.183, 5 at 0.202 (``benchmarks/MEASURED.md``).
ADAPT_STEPS = 10

#: The most ``steps`` taken: the least number of solves bounds the work a run may ask
#: for (each solve factorises the whole mesh's system).
MAX_ADAPT_STEPS = 1000

#: The time between two solves is also at most ``STRETCH / max_K |grad v|_K``, the
#: velocity's P1 gradient on each cell at the solve (spectral norm): the field's own
#: Euler map over that time keeps every cell's singular values within ``[1 - STRETCH,
#: 1 + STRETCH]``, so the frozen field is not read where the cells have changed shape
#: by more than that.
STRETCH = 0.8

#: Midpoint-rule substeps in each interval between solves: each substep's Euler map
#: keeps the cells' singular values within ``[1 - STRETCH / SUBSTEPS, 1 + STRETCH /
#: SUBSTEPS]``.  On the 300 x 300 ring, where the intervals' length is what the stretch
#: allows, the result follows the substeps' length, not the solves' count: sigma/mu
#: 0.0194 with STRETCH 0.5 and 2 substeps (18 solves) and with 0.8 and 4 (12 solves),
#: 0.0242 with 0.8 and 2 (``benchmarks/MEASURED.md``).
SUBSTEPS = 4

#: Halvings of the time between two solves allowed where a substep folds a triangle,
#: before the fold is reported (the time then 1/1024 of what it was).  The shortest
#: time between solves, ``1 / (steps * 2**MAX_HALVINGS)``, bounds :data:`STRETCH`'s
#: too: a velocity whose gradient asks for less (cells collapsing) is refused.
MAX_HALVINGS = 10

#: A boundary node slides when the cross product of its two boundary edges is at most
#: this fraction of their lengths' product (collinear up to coordinates' round-off).
COLLINEAR = 1e-12

#: The step of the central differences that give a monitor's gradient (one without a
#: gradient of its own: an expression), relative to the mesh's extent: about 1e-6 of
#: it, far below any length a mesh of a million cells resolves, while the round-off of
#: ``M`` stays ~1e-10 of the difference.
GRADIENT_STEP = 2.0**-20

#: Monitors built from a point field (``--field``): ``gradient``, ``1 + alpha |grad u|^2
#: / max |grad u|^2``; ``hessian``, ``1 + alpha |H u| / max |H u|`` (Frobenius norm),
#: with gradients recovered at the nodes by area-weighted averages of the cells'.
KINDS = ("gradient", "hessian")

#: ``alpha`` by default: the front benchmark's L2 interpolation error is within a few
#: per cent of its best over alpha in 1..100 here (``benchmarks/MEASURED.md``).
DEFAULT_ALPHA = 10.0


@dataclass
class Adapted:
    """The adapted node positions and what was measured."""

    points: np.ndarray
    report: dict


def monitor_values(
    monitor: Callable[[np.ndarray], np.ndarray], q: np.ndarray, source: str = "<mesh>"
) -> np.ndarray:
    """``monitor`` at the points ``q``, checked finite and positive (a
    :class:`MonitorError` naming the mesh ``source`` and the first point where it is
    not)."""
    m, k = positive_values(monitor(q), len(q))
    if m is None:
        raise MonitorError(f"{source}: the monitor gave shape {k} for {len(q)} points")
    if k is not None:
        raise MonitorError(
            f"{source}: the monitor is {float(m[k]):.6g} at ({float(q[k, 0]):.6g}, "
            f"{float(q[k, 1]):.6g}); it must be finite and > 0 wherever the mesh's nodes go"
        )
    return m


class ScaledMonitor:
    """``monitor`` times ``2**exponent`` (exactly: a power of two), its ``gradient`` too
    where it has one."""

    def __init__(self, monitor, exponent: int):
        self.monitor, self.exponent = monitor, exponent
        if getattr(monitor, "gradient", None) is not None:
            self.gradient = lambda q: np.ldexp(monitor.gradient(q), exponent)

    def __call__(self, q: np.ndarray) -> np.ndarray:
        v = np.asarray(self.monitor(q), dtype=np.float64)
        if v.ndim == 0:  # (a constant expression gives one number for all points)
            v = np.full(len(q), float(v))
        return np.ldexp(v, self.exponent)


def equidistribution(
    points: np.ndarray, tri: np.ndarray, m_nodes: np.ndarray, ref_area: np.ndarray
) -> tuple[float, float]:
    """``(sigma / mu, max / min)`` of each cell's P1 integral of the monitor (nodal
    values ``m_nodes``) over its area in the reference mesh ``ref_area``."""
    q = np.abs(signed_areas(points, tri)) * m_nodes[tri].mean(axis=1) / ref_area
    return float(q.std() / q.mean()), float(q.max() / q.min())


def check_mesh(points: np.ndarray, tri: np.ndarray, source: str) -> np.ndarray:
    """The triangles' signed areas, all > 0 (else an :class:`InputError` naming the
    first folded or flat one and where it is)."""
    if len(tri) == 0:
        raise InputError(f"{source}: no triangles to adapt")
    area = signed_areas(points, tri)
    if not (area > 0).all():
        k = int(np.argmax(~(area > 0)))
        c = points[tri[k]].mean(axis=0)
        raise InputError(
            f"{source}: triangle {k} near ({float(c[0]):.6g}, {float(c[1]):.6g}) is folded or "
            "flat; adapt needs a mesh whose triangles are all counter-clockwise"
        )
    return area


def boundary_motion(
    points: np.ndarray, tri: np.ndarray, held: np.ndarray | None = None, slide: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Which nodes may not move and the direction the sliding ones move along.

    Returns ``(fixed, tangent)``: ``fixed`` (N,) is True at the nodes ``held`` names
    (a mask, or None), at every boundary node without ``slide``, and at every
    boundary node that is not on a straight run (a corner, a node of a curve, a
    node where boundaries touch); ``tangent`` (N, 2) is the unit direction of the
    run at a sliding node (from its previous to its next boundary neighbour) and 0
    elsewhere.
    """
    n = len(points)
    edges = boundary_edges(tri, n)
    fixed = np.zeros(n, dtype=bool) if held is None else np.array(held, dtype=bool)
    tangent = np.zeros((n, 2))
    on = np.zeros(n, dtype=bool)
    on[edges.ravel()] = True
    if not slide:
        return fixed | on, tangent
    # each boundary node's next and previous boundary neighbour (the domain on the left)
    out_count = np.bincount(edges[:, 0], minlength=n)
    nxt = np.full(n, -1)
    prv = np.full(n, -1)
    nxt[edges[:, 0]] = edges[:, 1]
    prv[edges[:, 1]] = edges[:, 0]
    simple = on & (out_count == 1) & (np.bincount(edges[:, 1], minlength=n) == 1)
    k = np.flatnonzero(simple)
    a, b = points[k] - points[prv[k]], points[nxt[k]] - points[k]
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    la, lb = np.hypot(*a.T), np.hypot(*b.T)
    run = (np.abs(cross) <= COLLINEAR * la * lb) & ((a * b).sum(axis=1) > 0)
    sliding = np.zeros(n, dtype=bool)
    sliding[k[run]] = True
    sliding &= ~fixed
    fixed |= on & ~sliding
    s = np.flatnonzero(sliding)
    d = points[nxt[s]] - points[prv[s]]
    tangent[s] = d / np.hypot(*d.T)[:, None]
    return fixed, tangent


#: The 21 pairs of a cell's 6 unknown slots (node j's first and second slot at 2j
#: and 2j + 1) whose products make the upper triangle of its normal-equation block.
_PAIRS = np.array([(a, b) for a in range(6) for b in range(a, 6)], dtype=np.int64).T.copy()


class VelocitySystem:
    """The paper's div-curl system for the node velocity ``V`` (``U = g V``: ``div U =
    -dg/dt``, ``curl U = 0``), discretised cell by cell so that its divergence equation
    is the rate of each cell's mass, in least squares.

    A cell's mass is its P1 integral of the density, ``|K| gbar_K`` (``gbar_K`` the
    mean of ``g`` at its nodes, where the nodes are): it starts as the cell's reference
    area (``g = 1``) and is to stay so.  With the nodes moving at ``V`` its rate over
    ``|K|`` is exactly ``gbar_K div_K V + (1/3) sum_i (dg/dt(x_i) + grad g(x_i) . V_i)``,
    linear in ``V``; on the path ``g = (1 - t) + t g1`` that is ``gbar_K div_K V +
    (t/3) sum_i grad g1(x_i) . V_i + (1/3) sum_i (g1(x_i) - 1)``.  The curl equation is
    the paper's on ``U``: ``sum_i g(x_i) (dphi_i/dx V_iy - dphi_i/dy V_ix) = 0``.  The
    velocity minimises ``sum_K |K| (rate_K^2 + curl_K^2)``.

    Unknowns: a free inner node's velocity along the two axes of :func:`frame` (x and
    y unless sliding sides turn it), ``w`` at a sliding node (velocity ``w t`` along its
    tangent ``t``), none at a fixed node, numbered node by node.  Each cell's two rows
    (six entries over its nodes' unknowns) give a 6 x 6 block of the normal equations,
    summed into a pattern fixed by the triangles.  The normal equations are solved by
    :class:`.splitsolve.SplitSolver`, its two groups the unknowns that move a node
    mostly along one axis and those mostly along the other (at ``g = 1`` the two couple
    only through sliding nodes off the axes: the cross term of ``div^2 + curl^2`` is a
    null Lagrangian, whatever the frame), its order from the nodes' places in
    ``points``.
    """

    def __init__(self, points: np.ndarray, tri: np.ndarray, fixed: np.ndarray, tangent: np.ndarray):
        n = len(fixed)
        self.n, self.tri = n, tri
        slide = tangent.any(axis=1) & ~fixed
        inner = ~fixed & ~slide
        count = np.where(inner, 2, np.where(slide, 1, 0))
        first = np.concatenate([[0], np.cumsum(count)[:-1]])
        self.size = size = int(count.sum())
        # each node's two unknown slots (-1: none) and the direction each moves it in
        self.slot = np.column_stack(
            [np.where(count > 0, first, -1), np.where(count == 2, first + 1, -1)]
        )
        # a free node's two unknowns: its velocity along the frame's axes, the frame
        # turned so that the sliding nodes' sides lie along its axes as nearly as may be
        # (:func:`frame`): the two groups of the solver then barely couple through them
        self.axes = axes = frame(tangent[slide])
        self.dirs = np.zeros((n, 2, 2))  # (node, slot, component)
        self.dirs[inner] = axes
        self.dirs[slide, 0] = tangent[slide]
        dof = self.slot[tri].reshape(-1, 6)  # (cell, 2 j + slot of its node j)
        # a cell's rows on its six slots are its rows' x, y parts, but at a sliding node
        # (slot 2 j: the component along its tangent) and where there is no unknown
        self._cell, self._corner = np.nonzero(slide[tri])
        self._tangent = tangent[tri[self._cell, self._corner]]
        a, b = dof[:, _PAIRS[0]].T.ravel(), dof[:, _PAIRS[1]].T.ravel()  # pair by pair
        real = (a >= 0) & (b >= 0)
        keys = np.where(real, np.maximum(a, b) * size + np.minimum(a, b), size * size)
        # (column by column, rows sorted: CSC of the upper triangle; the last key, for
        # pairs without an unknown, is dropped)
        ukeys, self._entry = unique_inverse(keys)
        if ukeys[-1] == size * size:
            ukeys = ukeys[:-1]
        self._indices = (ukeys % size).astype(np.int32)
        self._indptr = np.searchsorted(ukeys // size, np.arange(size + 1))
        self._dof = np.where(dof >= 0, dof, size).T.ravel()  # slot by slot (size: dropped)
        node = np.empty(size, dtype=np.int64)  # each unknown's node and direction
        direction = np.empty((size, 2))
        for s in range(2):
            has = self.slot[:, s] >= 0
            node[self.slot[has, s]] = np.flatnonzero(has)
            direction[self.slot[has, s]] = self.dirs[has, s]
        along = [np.abs(direction[:, 0] * a + direction[:, 1] * b) for a, b in axes]
        along_second = along[1] > along[0]
        self.solver = SplitSolver(self._indptr, self._indices, along_second, points[node])

    def rows(self, gx, gy, g, grad, t):
        """(6, T) each: every cell's rate and curl rows on its six slots."""
        tri = self.tri
        gt = g[tri]
        gbar = gt.mean(axis=1, keepdims=True)
        out = []
        for x, y in (
            (gbar * gx + (t / 3.0) * grad[tri, 0], gbar * gy + (t / 3.0) * grad[tri, 1]),
            (-gy * gt, gx * gt),
        ):
            r = np.empty((6, len(tri)))
            if self.axes is _AXES:
                r[0::2], r[1::2] = x.T, y.T
            else:
                (ax, ay), (bx, by) = self.axes
                r[0::2], r[1::2] = (x * ax + y * ay).T, (x * bx + y * by).T
            c, j = self._cell, self._corner
            r[2 * j, c] = x[c, j] * self._tangent[:, 0] + y[c, j] * self._tangent[:, 1]
            out.append(r)
        return out

    def velocity(self, geometry, g: np.ndarray, grad: np.ndarray, g1: np.ndarray, t: float):
        """``V`` (N, 2) at pseudo-time ``t``: ``g`` the path's density at the nodes,
        ``grad`` the gradient of ``g1`` (its end) there, ``geometry``
        :func:`.divcurl.gradients` of the mesh where the nodes are."""
        V = np.zeros((self.n, 2))
        if not self.size:
            return V
        gx, gy, a2 = geometry
        d, c = self.rows(gx, gy, g, grad, t)
        half = 0.5 * a2
        values = np.zeros(len(self._indices) + 1)  # (the last: pairs without an unknown)
        normal_equations(d, c, half, _PAIRS[0], _PAIRS[1], self._entry, values)
        self.solver.factorise(values[:-1])
        rhs = np.zeros(self.size + 1)  # (the last: slots without an unknown)
        load_vector(d, half * (1.0 - g1[self.tri].mean(axis=1)), self._dof, rhs)
        x = np.concatenate([self.solver.solve(rhs[:-1]), [0.0]])  # (slot -1: no unknown)
        w = x[self.slot]  # (N, 2 slots)
        return w[:, 0, None] * self.dirs[:, 0] + w[:, 1, None] * self.dirs[:, 1]


#: The x and y axes: the frame of a free node's two unknowns unless sliding nodes turn it.
_AXES = np.eye(2)
_AXES.flags.writeable = False


def frame(tangents: np.ndarray) -> np.ndarray:
    """The axes (2, 2: rows) along which the sides with these unit ``tangents`` lie as
    nearly as may be: turned by a quarter of the argument of ``z = sum (t_x + i
    t_y)^4`` (the fourth power maps both axes of a frame, either way, to one
    direction; ``z`` is the tangents' summed such direction), or :data:`_AXES` where
    ``z`` points along the positive real axis (every side along x or y, exactly, or
    none).  Plain arithmetic, square roots and correctly rounded sums only (no
    ``atan2``, ``cos``, ``sin``, whose last bits differ between libraries): the same
    axes on every machine."""
    tx, ty = tangents[:, 0], tangents[:, 1]
    x2, y2 = tx * tx - ty * ty, 2.0 * tx * ty
    zx, zy = math.fsum(x2 * x2 - y2 * y2), math.fsum(2.0 * x2 * y2)
    if zy == 0.0 and zx >= 0.0:
        return _AXES
    size = math.sqrt(zx * zx + zy * zy)
    c, s = _half(*_half(zx / size, zy / size))
    return np.array([[c, s], [-s, c]])


def _half(c: float, s: float) -> tuple[float, float]:
    """The unit vector at half the angle (in (-pi, pi]) of the unit vector ``(c, s)``."""
    if c >= 0.0:
        ch = math.sqrt((1.0 + c) / 2.0)
        return ch, s / (2.0 * ch)
    sh = math.sqrt((1.0 - c) / 2.0)
    sh = sh if s >= 0.0 else -sh
    return s / (2.0 * sh), sh


def normaliser(tri: np.ndarray, area2: np.ndarray, m: np.ndarray) -> float:
    """``c`` such that ``g = M / c`` has the mesh's area as its P1 integral (``m``: M at
    the nodes, ``area2``: twice the cells' areas).  Summed relative to the first
    node's value, so that M equal at every node gives that value exactly (``g = 1``)."""
    share = (m[tri] / m[0]).mean(axis=1)
    return float(m[0]) * float(np.sum(area2 * share) / np.sum(area2))


def monitor_gradient(
    monitor: Callable[[np.ndarray], np.ndarray], q: np.ndarray, step: float, source: str
) -> np.ndarray:
    """(k, 2): ``grad M`` at the points ``q``: the monitor's own ``gradient`` if it has
    one (a P1 field's, :class:`P1Field`), else central differences with ``step``
    (a :class:`MonitorError` where they are not finite)."""
    own = getattr(monitor, "gradient", None)
    if own is not None:
        return own(q)
    out = np.empty((len(q), 2))
    for k in range(2):
        e = np.zeros(2)
        e[k] = step
        out[:, k] = np.asarray(monitor(q + e), dtype=np.float64) - monitor(q - e)
    out /= 2.0 * step
    bad = ~np.isfinite(out).all(axis=1)
    if bad.any():
        j = int(np.argmax(bad))
        raise MonitorError(
            f"{source}: the monitor's gradient is not finite at ({float(q[j, 0]):.6g}, "
            f"{float(q[j, 1]):.6g}) (central differences {step:.3g} either side); adapt "
            "needs a monitor differentiable wherever the mesh's nodes go"
        )
    return out


def adapt(
    points: np.ndarray,
    tri: np.ndarray,
    monitor: Callable[[np.ndarray], np.ndarray],
    steps: int = ADAPT_STEPS,
    source: str = "<mesh>",
    held: np.ndarray | None = None,
    slide: bool = True,
    guard: np.ndarray | None = None,
    progress: Callable[[float, int], None] | None = None,
) -> Adapted:
    """``points`` (the reference mesh) moved to follow ``monitor`` (points (k, 2) -> M
    (k,)); ``tri`` (counter-clockwise) unchanged; boundary nodes as
    :func:`boundary_motion` says (``held``: a node mask of the user's points).  A node
    no triangle uses stays where it is (the report counts it held).  ``guard``: the
    triangles kept unfolded (default ``tri``; with quads split into ``tri``, each
    quad's four corner triangles too, so every quad stays convex).  ``progress(t,
    solves)`` is called after each solve (``t`` the pseudo-time reached)."""
    points = np.asarray(points, dtype=np.float64)
    tri = np.asarray(tri, dtype=np.int64)
    area = check_mesh(points, tri, source)
    if not 1 <= steps <= MAX_ADAPT_STEPS:
        raise OptionError(f"--steps must be from 1 to {MAX_ADAPT_STEPS:,}, got {steps}")
    used = np.zeros(len(points), dtype=bool)
    used[tri.ravel()] = True
    if not used.all():  # (adapted without them, and put back)
        keep = np.flatnonzero(used)
        index = np.full(len(points), -1)
        index[keep] = np.arange(len(keep))
        part = adapt(
            points[keep], index[tri], monitor, steps, source,
            None if held is None else np.asarray(held, dtype=bool)[keep], slide,
            None if guard is None else index[guard], progress,
        )  # fmt: skip
        out = points.copy()
        out[keep] = part.points
        report = part.report
        report["nodes"] = len(points)
        report["boundary_nodes_held"] += len(points) - len(keep)
        return Adapted(out, report)
    guard = tri if guard is None else np.asarray(guard, dtype=np.int64)
    m0 = monitor_values(monitor, points, source)
    # M by a power of two near its largest value at the nodes: everything here depends
    # on M / c only, and a power of two scales each product and sum exactly, so the
    # result is the same bits, while a monitor of 1e300 or 5e-324 stays in range
    monitor = ScaledMonitor(monitor, -int(np.frexp(m0.max())[1]))
    m0 = monitor(points)
    fixed, tangent = boundary_motion(points, tri, held, slide)
    before = equidistribution(points, tri, m0, area)
    system = VelocitySystem(points, tri, fixed, tangent)
    step = GRADIENT_STEP * float(np.ptp(points, axis=0).max())

    neighbours = triangle_neighbours(tri)
    start = start_triangles(tri, len(points))
    slides = np.flatnonzero(tangent.any(axis=1))

    def allowed(v: np.ndarray) -> np.ndarray:
        # held nodes stay, sliding ones move along their run (exactly: a zero tangent
        # component gives a zero velocity component)
        v[fixed] = 0.0
        v[slides] = (v[slides] * tangent[slides]).sum(axis=1)[:, None] * tangent[slides]
        return v

    def density(g: np.ndarray, t: float) -> np.ndarray:
        # the path from 1 to g = M / c
        return (1.0 - t) + t * g

    def g_at(q: np.ndarray) -> np.ndarray:
        return monitor_values(monitor, q, source) / c

    def folded(q: np.ndarray) -> bool:
        return not (signed_areas(q, guard) > 0).all()

    def substeps(field: FrozenField, pos: np.ndarray, g: np.ndarray, t: float, span: float):
        # SUBSTEPS midpoint steps over [t, t + span] in the frozen field: the end
        # positions, or (None, positions with a fold) as soon as a substep folds
        # (the midpoints are only where the field is read, not a mesh: not checked)
        # (g: g_at(pos), known at the start)
        h = span / SUBSTEPS
        for i in range(SUBSTEPS):
            s = t + i * h
            g = g if i == 0 else g_at(pos)
            mid = pos + (0.5 * h) * allowed(field.at(pos) / density(g, s)[:, None])
            pos = pos + h * allowed(field.at(mid) / density(g_at(mid), s + 0.5 * h)[:, None])
            if folded(pos):
                return None, pos
        return pos, None

    pos = points.copy()
    t, halvings, solves = 0.0, 0, 0
    while t < 1.0:
        m = m0 if solves == 0 else monitor_values(monitor, pos, source)
        geometry = gradients(pos, tri)
        c = normaliser(tri, geometry[2], m)
        g1 = m / c
        grad = monitor_gradient(monitor, pos, step, source) / c
        g = density(g1, t)
        V = system.velocity(geometry, g, grad, g1, t)
        U = V * g[:, None]  # (the paper's U, which the path leaves unchanged: frozen)
        solves += 1
        if progress is not None:
            progress(t, solves)
        spread = stretch(tri, geometry, V)
        k = int(np.argmax(spread))
        most = float(spread[k])
        if STRETCH * steps * 2**MAX_HALVINGS < most:
            # the stretch rule asks for a time shorter than the halvings' floor
            x, y = pos[tri[k]].mean(axis=0)
            raise FoldError(
                f"{source}: the adaptation collapses the cells near ({x:.6g}, {y:.6g}) at "
                f"pseudo-time {t:.3f} (the velocity's gradient there is {most:.3g}, which "
                f"would take over {steps * 2**MAX_HALVINGS} solves); give a smoother monitor"
            )
        span = min(1.0 / steps, 1.0 - t, STRETCH / most if most > 0 else np.inf)
        halved = 0
        field = FrozenField(pos, tri, U, neighbours, start, geometry)
        while True:
            new, worst = substeps(field, pos, g1, t, span)
            if new is not None:
                break
            if halved == MAX_HALVINGS:
                x, y = worst[guard[int(np.argmin(signed_areas(worst, guard)))]].mean(axis=0)
                raise FoldError(
                    f"{source}: the adaptation folds a triangle near ({x:.6g}, {y:.6g}) at "
                    f"pseudo-time {t:.3f} even with the step refined; give a smoother "
                    "monitor or more --steps"
                )
            span *= 0.5
            halved += 1
        halvings += halved
        pos = new
        # (the end within round-off of pseudo-time 1 is 1: no solve for a sliver)
        t = 1.0 if t + span > 1.0 - 2.0**-40 else t + span
    fixed_count = int(fixed.sum())
    after = equidistribution(pos, tri, monitor_values(monitor, pos, source), area)
    report = {
        "nodes": len(points),
        "triangles": len(tri),
        "boundary_nodes_held": fixed_count,
        "boundary_nodes_sliding": int(tangent.any(axis=1).sum()),
        "steps": steps,
        "substeps": SUBSTEPS,
        "solves": solves,
        "halvings": halvings,
        "sigma_over_mu_before": before[0],
        "volume_ratio_before": before[1],
        "sigma_over_mu": after[0],
        "volume_ratio": after[1],
        "smallest_angle": float(measures(pos, tri)[0].min()),
        "tangled": int((signed_areas(pos, guard) <= 0).sum()),
        "moved_nodes": int((pos != points).any(axis=1).sum()),
    }
    return Adapted(pos, report)


#: A point within this fraction of a mesh's extent of it, outside by round-off (a node
#: sliding along a slanted side), is located in the lowest-numbered triangle within that
#: reach.
ROUND_OFF = 1e-9


class Locator:
    """Finds points in a fixed triangle mesh: shapely's STRtree over its triangles,
    built once."""

    def __init__(self, points: np.ndarray, tri: np.ndarray):
        import shapely

        self.points, self.tri = points, tri
        self.frames = frames(points, tri)
        self.tree = shapely.STRtree(shapely.polygons(points[tri]))
        self.reach = ROUND_OFF * float(np.ptp(points, axis=0).max())

    def find(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For each point of ``q``: the lowest-numbered triangle holding it (else, for a
        point outside by no more than :data:`ROUND_OFF` of the mesh's extent, the
        lowest-numbered one within that reach), and its barycentric weights there (k,
        3).  A point further out is an :class:`InputError`."""
        import shapely

        tri = self.tri
        first = np.full(len(q), len(tri))
        at, hit = self.tree.query(shapely.points(q), predicate="intersects")
        np.minimum.at(first, at, hit)
        out = np.flatnonzero(first == len(tri))
        if len(out):
            at, hit = self.tree.query(
                shapely.points(q[out]), predicate="dwithin", distance=self.reach
            )
            np.minimum.at(first, out[at], hit)
        if (first == len(tri)).any():
            k = int(np.argmax(first == len(tri)))
            raise InputError(f"the point ({q[k, 0]:.6g}, {q[k, 1]:.6g}) is outside the mesh")
        return first, weights(self.frames, first, q)


def cell_gradients(tri: np.ndarray, geometry, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``d u/dx, d u/dy`` (T,) each: the gradient of the P1 field ``u`` (N,) on each
    triangle (``geometry``: :func:`.divcurl.gradients` of the mesh)."""
    gx, gy, _ = geometry
    ut = u[tri]
    return np.einsum("ij,ij->i", gx, ut), np.einsum("ij,ij->i", gy, ut)


def stretch(tri: np.ndarray, geometry, v: np.ndarray) -> np.ndarray:
    """(T,): the spectral norm of the gradient of the P1 field ``v`` (N, 2) on each
    triangle; ``geometry``: :func:`.divcurl.gradients` of the mesh."""
    a, b = cell_gradients(tri, geometry, v[:, 0])
    c, d = cell_gradients(tri, geometry, v[:, 1])
    fro = a * a + b * b + c * c + d * d
    det = a * d - b * c
    return np.sqrt(0.5 * (fro + np.sqrt(np.maximum(fro * fro - 4.0 * det * det, 0.0))))


#: Steps a walk takes before the STRtree locates the point instead (a walk by the most
#: negative barycentric weight can circle on a mesh that is not Delaunay).
WALK_LIMIT = 256


def triangle_neighbours(tri: np.ndarray) -> np.ndarray:
    """(T, 3): the triangle across the side opposite each vertex, -1 on the boundary."""
    n_tri = len(tri)
    sides = np.concatenate([tri[:, [1, 2]], tri[:, [2, 0]], tri[:, [0, 1]]])
    owner = np.tile(np.arange(n_tri), 3)
    vertex = np.repeat(np.arange(3), n_tri)
    key = np.sort(sides, axis=1)
    order = np.lexsort((key[:, 1], key[:, 0]))
    k = key[order]
    pair = (k[1:] == k[:-1]).all(axis=1)
    a, b = order[:-1][pair], order[1:][pair]
    out = np.full((n_tri, 3), -1, dtype=np.int64)
    out[owner[a], vertex[a]] = owner[b]
    out[owner[b], vertex[b]] = owner[a]
    return out


def frames(points: np.ndarray, tri: np.ndarray, geometry=None) -> tuple[np.ndarray, ...]:
    """Each triangle's first corner ``(ax, ay)`` and the gradients of its second and third
    barycentric coordinates ``(bx, by, cx, cy)``, (T,) each: the weights of ``q`` are
    ``1 - wb - wc, wb, wc`` with ``wb = (bx, by) . (q - a)``, ``wc`` alike (``geometry``:
    :func:`.divcurl.gradients` of the mesh, if the caller has them)."""
    gx, gy, _ = gradients(points, tri) if geometry is None else geometry
    a = points[tri[:, 0]]
    return (
        np.ascontiguousarray(a[:, 0]), np.ascontiguousarray(a[:, 1]),
        np.ascontiguousarray(gx[:, 1]), np.ascontiguousarray(gy[:, 1]),
        np.ascontiguousarray(gx[:, 2]), np.ascontiguousarray(gy[:, 2]),
    )  # fmt: skip


def weights(frame: tuple[np.ndarray, ...], t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(k, 3): the barycentric weights of the points ``q`` in the triangles ``t``
    (``frame``: :func:`frames` of the mesh)."""
    ax, ay, bx, by, cx, cy = frame
    dx, dy = q[:, 0] - ax[t], q[:, 1] - ay[t]
    w = np.empty((len(t), 3))
    w[:, 1] = bx[t] * dx + by[t] * dy
    w[:, 2] = cx[t] * dx + cy[t] * dy
    w[:, 0] = 1.0 - w[:, 1] - w[:, 2]
    return w


#: A barycentric weight this far below 0 is 0 up to round-off: a point on a side
#: shared by two triangles is in both (a walk does not step back and forth).
WEIGHT_ROUND_OFF = 1e-12


class Walk:
    """Finds points in a fixed triangle mesh that each started at a node and move a
    little between calls (point ``i`` of every call is the same moving point): each
    walks from the triangle it was found in last (at first, one at its node), across
    the side of its most negative barycentric weight, until all weights are >= 0 (to
    :data:`WEIGHT_ROUND_OFF`) or the walk meets the boundary; a point that stops
    outside the mesh, or walks :data:`WALK_LIMIT` steps, is found by the
    :class:`Locator` (within :data:`ROUND_OFF` of the mesh)."""

    def __init__(self, points, tri, neighbours, start, geometry=None):
        self.points, self.tri = points, tri
        self.neighbours = neighbours
        self.hint = start.copy()
        self.frame = frames(points, tri, geometry)
        self._locator = None

    def find(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each point's triangle (N,) and barycentric weights there (N, 3) (the walks
        compiled: :mod:`._walk`)."""
        from ._walk import walk

        t = self.hint
        q = np.ascontiguousarray(q, dtype=np.float64)
        w = np.empty((len(q), 3))
        walk(*self.frame, self.neighbours, q, WALK_LIMIT, WEIGHT_ROUND_OFF, t, w)
        least = np.minimum(np.minimum(w[:, 0], w[:, 1]), w[:, 2])
        lost = np.flatnonzero(least < -WEIGHT_ROUND_OFF)  # (the walk's last todo among them)
        if len(lost):
            if self._locator is None:
                self._locator = Locator(self.points, self.tri)
            t[lost], w[lost] = self._locator.find(q[lost])
        return t.copy(), w


def start_triangles(tri: np.ndarray, n: int) -> np.ndarray:
    """(n,): a triangle at each node (a node no triangle uses: triangle 0)."""
    start = np.zeros(n, dtype=np.int64)
    start[tri.ravel()] = np.repeat(np.arange(len(tri)), 3)
    return start


class FrozenField:
    """A P1 field on a fixed mesh (``values`` at its nodes), evaluated at points that
    each started at a node and move a little between calls (found by a :class:`Walk`).
    At the mesh's own nodes the values are returned to the bit."""

    def __init__(self, points, tri, values, neighbours, start, geometry=None):
        self.points, self.tri, self.values = points, tri, values
        self.walk = Walk(points, tri, neighbours, start, geometry)

    def at(self, q: np.ndarray) -> np.ndarray:
        if np.array_equal(q, self.points):
            return self.values.copy()
        return p1_values(self.values, self.tri, *self.walk.find(q))


def p1_values(values: np.ndarray, tri: np.ndarray, t: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``values`` (one row per node) interpolated linearly at points in the triangles
    ``t`` with barycentric weights ``w`` (k, 3)."""
    if values.ndim == 1:
        return (w * values[tri[t]]).sum(axis=1)
    from ._walk import p1

    out = np.empty((len(t), values.shape[1]))
    p1(
        np.ascontiguousarray(values, dtype=np.float64), np.ascontiguousarray(tri, dtype=np.int64),
        np.ascontiguousarray(t, dtype=np.int64), np.ascontiguousarray(w, dtype=np.float64), out,
    )  # fmt: skip
    return out


def carry(old: np.ndarray, tri: np.ndarray, new: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``values`` (one row per node of the mesh at ``old``) at the points ``new``, by P1
    interpolation in the old mesh (:class:`Locator`; a point on a shared side takes the
    lower-numbered triangle, equal up to round-off); a node that did not move keeps its
    value to the bit."""
    values = np.asarray(values)
    out = np.array(values, dtype=np.float64, copy=True)
    moved = np.flatnonzero((new != old).any(axis=1))
    if not len(moved):
        return out
    first, w = Locator(old, tri).find(new[moved])
    out[moved] = p1_values(values.astype(np.float64), tri, first, w)
    return out


def recovered_gradient(points: np.ndarray, tri: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``grad u`` (N, 2) at the nodes: the area-weighted mean of the P1 gradients of the
    cells around each node."""
    geometry = gradients(points, tri)
    a2 = geometry[2]
    g = np.column_stack(cell_gradients(tri, geometry, u))
    n = len(points)
    w = np.bincount(tri.ravel(), weights=np.repeat(a2, 3), minlength=n)
    out = np.empty((n, 2))
    for k in range(2):
        out[:, k] = np.bincount(tri.ravel(), weights=np.repeat(a2 * g[:, k], 3), minlength=n) / w
    return out


def field_monitor(
    points: np.ndarray,
    tri: np.ndarray,
    u: np.ndarray,
    alpha: float = DEFAULT_ALPHA,
    kind: str = "gradient",
    name: str = "the field",
) -> np.ndarray:
    """The monitor at the nodes built from the point field ``u`` (see :data:`KINDS`);
    a field constant over the mesh gives ``M = 1``."""
    if kind not in KINDS:
        raise OptionError(f"--kind must be one of {', '.join(KINDS)}, got {kind!r}")
    if not (np.isfinite(alpha) and alpha >= 0):
        raise OptionError(f"--alpha must be finite and >= 0, got {alpha}")
    u = np.asarray(u, dtype=np.float64)
    if u.ndim == 2 and u.shape[1] == 1:
        u = u[:, 0]
    if u.ndim != 1:
        raise InputError(f"{name} has {u.shape[1]} components; adapt follows a scalar field")
    if not np.isfinite(u).all():
        k = int(np.argmax(~np.isfinite(u)))
        raise InputError(f"{name} is {u[k]} at node {k}; it must be finite")
    # (each derivative scaled by a power of two near its largest value: exact, and the
    # monitor, a ratio, is the same bits, while a field of 1e-310 or 1e308 neither
    # underflows nor overflows when squared)
    grad = _unit(recovered_gradient(points, tri, _unit(u)))
    if kind == "gradient":
        s = (grad**2).sum(axis=1)
    else:
        hx = recovered_gradient(points, tri, grad[:, 0])
        hy = recovered_gradient(points, tri, grad[:, 1])
        h = _unit(np.column_stack([hx, hy]))  # (one scale for the four)
        s = np.sqrt((h[:, :2] ** 2).sum(axis=1) + (h[:, 2:] ** 2).sum(axis=1))
    top = s.max()
    return np.ones(len(u)) if top == 0 else 1.0 + alpha * s / top


def _unit(a: np.ndarray) -> np.ndarray:
    """``a`` times the power of two that brings its largest magnitude into [0.5, 1)."""
    top = float(np.abs(a).max(initial=0.0))
    return a if top == 0.0 else np.ldexp(a, -int(np.frexp(top)[1]))


def interpolated(points: np.ndarray, tri: np.ndarray, values: np.ndarray) -> P1Field:
    """``values`` at the nodes of the mesh ``(points, tri)`` as a function of points (a
    :class:`P1Field`)."""
    return P1Field(points, tri, values)


class P1Field:
    """``values`` at the nodes of the mesh ``(points, tri)`` as a function of points, by
    P1 interpolation (a point at a node gets that node's value to the bit), with its
    gradient: that of the triangle each point is found in.  Called with one point per
    node (the nodes of a mesh with this one's triangles, moving: adapt's calls), the
    points are found by a :class:`Walk` from where they were last; other points by the
    :class:`Locator` (the lowest-numbered triangle on a shared side)."""

    def __init__(self, points: np.ndarray, tri: np.ndarray, values: np.ndarray):
        self.points, self.tri = points, tri
        self.values = np.asarray(values, dtype=np.float64)
        self._cell = np.column_stack(cell_gradients(tri, gradients(points, tri), self.values))
        self._walk = None
        self._locator = None
        self._last = None

    def _find(self, q: np.ndarray):
        if self._last is None or not np.array_equal(self._last[0], q):
            if len(q) == len(self.points):
                if self._walk is None:
                    start = start_triangles(self.tri, len(self.points))
                    self._walk = Walk(self.points, self.tri, triangle_neighbours(self.tri), start)
                found = self._walk.find(q)
            else:
                if self._locator is None:
                    self._locator = Locator(self.points, self.tri)
                found = self._locator.find(q)
            self._last = (q.copy(), *found)
        return self._last[1:]

    def __call__(self, q: np.ndarray) -> np.ndarray:
        if q.shape == self.points.shape and np.array_equal(q, self.points):
            return self.values.copy()
        return p1_values(self.values, self.tri, *self._find(q))

    def gradient(self, q: np.ndarray) -> np.ndarray:
        return self._cell[self._find(q)[0]]
