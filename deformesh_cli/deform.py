"""Stage 2: move the selected nodes onto the contour by the div-curl deformation.

Pseudo-time runs over ``n`` steps.  At each step, on the *current* mesh, the
LSFEM div-curl system (``div U = 0``, ``curl U = 0`` for the uniform size
function ``f = 1``) is solved with Dirichlet data: at each path node the
remaining displacement divided by the remaining steps, ``(Q - phi(P)) /
(n - k)``, and ``U = 0`` on the background boundary.  Every node moves by
``f * U``, so each path node lands exactly on its target at the last step.

After each step every triangle's signed area is checked.  If one would fold,
the step is halved (the solution is linear in the Dirichlet data, so the
half step is half the displacement) and the remaining pseudo-time re-planned;
if even a step of ``2**-max_halvings`` folds, :class:`FoldError` says where.
The last step puts the path nodes exactly on their targets.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .divcurl import Assembler
from .errors import BandError, FoldError, OptionError, SolverError
from .geometry import signed_areas
from .ldl import LDL

#: Default number of pseudo-time steps (the paper's example uses 10).
DEFAULT_STEPS = 10

#: The most pseudo-time steps taken: each is a solve, so the work a run may ask for is
#: bounded (ten thousand solves are hours on a large grid).
MAX_STEPS = 10_000

#: A triangle whose signed area is within this times its longest side squared (and its
#: coordinates' round-off, :func:`flat_margin`) of zero is flat: its sign, and
#: whether its centroid lies in the domain, are round-off (a free node carried onto the
#: line through two path nodes, or three path nodes onto one contour edge).  With
#: ``flat_ok`` the deformation lets it pass, whatever its sign, for stage 3 to mesh it
#: again (:mod:`.untangle`).
FLAT = 1e-12


def flat_margin(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Per triangle, how near zero its signed area is flat: :data:`FLAT` times its
    longest side ``L`` squared, plus :data:`ROUND_OFF` times ``L`` times its corners'
    largest coordinate ``X`` (the round-off of an area computed from differences of
    coordinates that large).  A graded grid's cells differ in size by millions, so a
    margin from their mean would call its finest cells flat; three points on a contour
    edge have an area that is the coordinates' round-off, however short the edge."""
    a, b, c = points[tri[:, 0]], points[tri[:, 1]], points[tri[:, 2]]
    sides = [((q - p) ** 2).sum(axis=1) for p, q in ((a, b), (b, c), (c, a))]
    square = np.maximum(np.maximum(sides[0], sides[1]), sides[2])
    far = np.maximum(
        np.maximum(np.abs(a).max(axis=1), np.abs(b).max(axis=1)), np.abs(c).max(axis=1)
    )
    return FLAT * square + ROUND_OFF * np.sqrt(square) * far


def areas_with_margin(points: np.ndarray, tri: np.ndarray, sign: float) -> np.ndarray:
    """:func:`.geometry.signed_areas` plus ``sign`` times :func:`flat_margin` (``sign``
    0: the signed areas), in one compiled loop (:mod:`._divcurl`), the same bits."""
    return signed_areas(points, tri, sign, FLAT, ROUND_OFF)


#: Four times the double's epsilon: an area computed from differences of coordinates of
#: magnitude ``X`` on sides of length ``L`` is off by at most about ``2 eps L X``
#: (:func:`flat_margin`).
ROUND_OFF = 2.0**-50


#: What a fold message advises: at the last step (the targets themselves cannot be
#: reached), and before it.
ADVICE = (
    "its corners cannot all reach their contour points; give a smaller --h",
    "give a smaller --h or more --steps",
)


@dataclass
class DeformStats:
    steps: int
    solves: int = 0
    halvings: int = 0
    solver: str = ""
    iterations: list[int] = field(default_factory=list)
    moved_nodes: int = 0  # nodes the solves covered (the band, or every node)
    fold: str | None = None  # with ``keep_folds``: what would have been raised, or None


#: Solvers offered by ``--solver``.  "auto" picks "direct" on a narrow band and on
#: the graded grid's side of the path (their nodes crowd along the path and thin out
#: away from it: the factor stays sparse) and, on a whole uniform grid, up to this
#: many free nodes, where the direct solve stopped being the faster one
#: (``benchmarks/MEASURED.md``).
SOLVERS = ("auto", "direct", "amg")
AUTO_DIRECT_MAX = 60_000

#: Relative residual at which a deformation step's iterative solve stops: the step's
#: displacement, a fraction of a cell, is then right to about a millionth of it (the
#: fold check reads the positions reached); fewer iterations than at 1e-8
#: (``benchmarks/MEASURED.md``).
STEP_RTOL = 1e-6

#: ``--solve`` choices: ``band`` deforms only the cells near the path
#: (the selection's ``band_nodes``), ``full`` the whole background grid
#: (the paper's form).
SOLVES = ("band", "full")


class LinearSolver:
    """Solves the per-step scalar systems ``K X = rhs`` (two right-hand sides).

    ``direct`` factorises ``K = L D L^T`` (:class:`.ldl.LDL`: approximate minimum
    degree, compiled here, no scipy).  The ordering and the symbolic factorisation
    are done once; later
    steps, whose matrices share the sparsity pattern (the mesh moves, its
    connectivity does not), only refactor the numbers, a tenth of the first
    factorisation's cost (``benchmarks/MEASURED.md``).  ``amg`` runs conjugate
    gradients preconditioned by a smoothed-aggregation hierarchy (pyamg) built on the first step's
    matrix and reused while it keeps converging fast (the mesh changes little
    per step), warm-started from the previous step's displacement.
    """

    def __init__(self, method: str = "auto", rtol: float = 1e-8, rebuild_after: int = 40):
        if method not in SOLVERS:
            raise OptionError(f"--solver must be one of {', '.join(SOLVERS)}, got {method!r}")
        self.method = method
        self.rtol = rtol
        self.rebuild_after = rebuild_after
        self._ml = None
        self._ldl = None
        self._pattern = None
        self.iterations: list[int] = []
        self.setups = 0

    def solve(self, K, rhs: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
        """``K`` is a :class:`~deformesh_cli.divcurl.SymmetricCSR`."""
        method = self.method
        if method == "auto":
            method = "direct" if K.shape[0] <= AUTO_DIRECT_MAX else "amg"
        if method == "direct":
            return self._solve_ldl(K, rhs)
        return self._solve_amg(K, rhs, x0)

    def _solve_ldl(self, K, rhs):
        if self._ldl is not None and K.indices is self._pattern:
            self._ldl.update(K)  # same pattern: new numbers only
        else:
            self._ldl = LDL(K)
            self._pattern = K.indices
            self.setups += 1
        return self._ldl.solve(rhs)

    def _solve_amg(self, K, rhs, x0):
        import scipy.sparse.linalg as spla

        K = K.tocsr()
        if self._ml is None:
            self._ml = _sa_hierarchy(K)
            self.setups += 1
        M = self._ml.aspreconditioner(cycle="V")
        out = np.empty_like(rhs)
        worst = 0
        for k in range(rhs.shape[1]):
            count = [0]

            def cb(_x, count=count):
                count[0] += 1

            guess = None if x0 is None else x0[:, k]
            x, info = spla.cg(
                K, rhs[:, k], x0=guess, rtol=self.rtol, atol=0.0, M=M, maxiter=500, callback=cb
            )
            if info != 0:  # preconditioner too stale: rebuild once and retry
                self._ml = _sa_hierarchy(K)
                self.setups += 1
                M = self._ml.aspreconditioner(cycle="V")
                x, info = spla.cg(
                    K, rhs[:, k], x0=guess, rtol=self.rtol, atol=0.0, M=M, maxiter=2000, callback=cb
                )
                if info != 0:
                    raise SolverError(
                        f"conjugate gradients did not converge in 2,000 iterations on "
                        f"{K.shape[0]} unknowns; try --solver direct"
                    )
            out[:, k] = x
            worst = max(worst, count[0])
        self.iterations.append(worst)
        if worst > self.rebuild_after:
            self._ml = None
        return out


def _sa_hierarchy(K):
    """pyamg's smoothed-aggregation hierarchy, reproducibly.

    pyamg estimates spectral radii from ``np.random.rand`` start vectors, so
    an unseeded build gives different bits on every run (measured: meshes
    differing in the 16th digit).  The global generator is seeded for the
    build and restored after it.
    """
    import pyamg

    state = np.random.get_state()
    np.random.seed(20240229)
    try:
        return pyamg.smoothed_aggregation_solver(K, symmetry="hermitian")
    finally:
        np.random.set_state(state)


def deform(*args, **kwargs) -> tuple[np.ndarray, DeformStats]:
    """:func:`deform_` with one BLAS thread: the same bits on every machine.

    OpenBLAS splits dot products over its threads, so the summation order, and
    with it the last bits of every node, depended on the thread count
    (measured: samples/naca0012.csv with 1 and 2 threads differed in the 16th
    digit).  The solves here are sparse, so BLAS threads bought no speed.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return deform_(*args, **kwargs)


def deform_band(
    points: np.ndarray,
    tri: np.ndarray,
    path_nodes: np.ndarray,
    targets: np.ndarray,
    fixed_nodes: np.ndarray,
    active: np.ndarray | None,
    describe=None,
    kept: np.ndarray | None = None,
    **kwargs,
) -> tuple[np.ndarray, DeformStats]:
    """:func:`deform` on the triangles whose three corners are all ``active`` (a band),
    and, with ``kept`` (a triangle mask), that are kept; ``active=None``: every kept
    triangle.

    Only those triangles move.  An active node that also belongs to a kept
    triangle outside the band is held (``U = 0``, like the box), so every other
    kept triangle keeps its shape exactly and cannot fold.  The path nodes must
    lie strictly inside the band.

    ``kept``: the triangles on the domain's side of the path.  A triangle
    outside them is neither solved for nor checked for folds: its free nodes
    stay where they are, while those of the path move, so it may fold, and the
    mesh drops it.  With the path's nodes given, the two sides' systems share
    no unknown, so the kept side's solution is the one a direct solve on both
    sides gives, as long as no fold on the other side halves a step.
    """
    # (t, 3) reductions and np.unique are slow on a whole grid's triangles: per-corner
    # masks and scatters instead
    edge = np.zeros(len(points), dtype=bool)
    if active is None:
        inside = np.ones(len(tri), dtype=bool) if kept is None else kept
    else:
        corner = [active[tri[:, k]] for k in range(3)]
        inside = corner[0] & corner[1] & corner[2]
        rim = ~inside & (corner[0] | corner[1] | corner[2])  # touch the band
        if kept is not None:
            inside &= kept
            rim &= kept
        edge[tri[rim].ravel()] = True
    sub_tri = tri[inside]
    used = np.zeros(len(points), dtype=bool)
    used[sub_tri.ravel()] = True
    nodes = np.flatnonzero(used)
    edge[fixed_nodes] = True
    held = nodes[edge[nodes]]
    if edge[path_nodes].any():
        raise BandError("a path node lies on the band's edge: widen the band")
    remap = np.full(len(points), -1, dtype=np.int64)
    remap[nodes] = np.arange(len(nodes))
    sub_describe = None if describe is None else (lambda t: describe(nodes[t]))
    if (active is not None or kept is not None) and kwargs.get("solver", "auto") == "auto":
        kwargs["solver"] = "direct"  # a band, or the graded grid's side: see SOLVERS
    sub, st = deform(
        points[nodes],
        remap[sub_tri],
        remap[path_nodes],
        targets,
        remap[held],
        describe=sub_describe,
        **kwargs,
    )
    out = np.array(points, dtype=np.float64, copy=True)
    out[nodes] = sub
    return out, st


def deform_(
    points: np.ndarray,
    tri: np.ndarray,
    path_nodes: np.ndarray,
    targets: np.ndarray,
    fixed_nodes: np.ndarray,
    steps: int = DEFAULT_STEPS,
    max_halvings: int = 10,
    callback: Callable[[float, DeformStats], None] | None = None,
    describe: Callable[[int], str] | None = None,
    solver: str = "auto",
    size=None,
    advice: tuple[str, str] = ADVICE,
    keep_folds: bool = False,
    flat_ok: bool = False,
) -> tuple[np.ndarray, DeformStats]:
    """Deform ``points`` so that ``points[path_nodes] == targets`` exactly, never folding
    (unless ``keep_folds``).

    With ``size`` (a :class:`deformesh_cli.size.SizePath`: ``g = 1/f`` and
    ``dg/dt`` along pseudo-time) the cells also take the areas ``f`` asks for:
    at pseudo-time ``t`` the step solves ``div U = -dg/dt``, ``curl U = 0`` on
    the current mesh (on the paper's linear path ``g = (1-t) + t g1``, so
    ``div U = 1 - g1``), and every node moves by ``f(t) U``, ``f = 1/g``; a
    selected node's ``U`` is its share of the way to its target divided by its
    ``f``.  (The paper prints ``div U = dg/dt``; with ``V = f U``,
    ``d(J g)/dt = J (div U + dg/dt)``, so ``J = f`` needs the minus sign, and
    the plus sign measurably grows the cells where ``f`` is small.)

    Parameters
    ----------
    points : (N, 2) start coordinates (not modified).
    tri : (T, 3) counter-clockwise triangles, all of positive area.
    path_nodes, targets : nodes to move and where they must land.
    fixed_nodes : nodes held in place (``U = 0``), typically the box boundary.
    steps : pseudo-time steps ``n``.
    callback : called with (pseudo-time done in [0, 1], stats) after each accepted step.
    describe : turns a node id into words for error messages.
    solver : one of :data:`SOLVERS`.
    advice : what a fold message tells the user to do (:data:`ADVICE`: at the
        last step, and before it).
    keep_folds : at the first step that would fold a triangle, go the rest of the
        way to the targets in one step instead,
        without halving (this step's solution, scaled), and keep the fold's message
        in the stats' ``fold``.  The result may then have folded triangles
        (:mod:`.untangle` mends those of a mesh).
    flat_ok : a triangle flat at the end (:data:`FLAT`) is not a fold, whatever the
        sign of its area (the caller meshes it again); one flat before the end is a
        fold, whatever its sign (the next step's solve divides by its area).

    Returns the new coordinates and :class:`DeformStats`.
    """
    if not 1 <= steps <= MAX_STEPS:
        raise OptionError(f"--steps must be from 1 to {MAX_STEPS:,}, got {steps}")
    n = len(points)
    pos = np.array(points, dtype=np.float64, copy=True)
    dirichlet = np.zeros(n, dtype=bool)
    dirichlet[fixed_nodes] = True
    dirichlet[path_nodes] = True
    asm = Assembler(tri, n, dirichlet)
    stats = DeformStats(steps=steps, solver=solver, moved_nodes=n)
    remaining = float(steps)  # pseudo-time left, in units of 1/steps
    ud = np.zeros((n, 2))
    lin = LinearSolver(solver, rtol=STEP_RTOL)
    prev = None  # last free-node solution (U) per unit of step, for warm starts
    while remaining > 0:
        dt = min(1.0, remaining)
        frac = dt / remaining
        share = (targets - pos[path_nodes]) * frac
        f = None
        if size is not None:
            g, rate = size.g_and_rate(pos, 1.0 - remaining / steps)
            f = 1.0 / g
            ud[path_nodes] = share / f[path_nodes, None]
        else:
            ud[path_nodes] = share
        disp = np.zeros((n, 2))
        disp[path_nodes] = ud[path_nodes]
        if asm.n_free:
            K, rhs = asm.system(pos, ud)
            if size is not None:  # div U = -dg/dt, over this step's pseudo-time
                rhs += asm.load(pos, -rate[tri].mean(axis=1) * dt / steps)
            # the remaining displacement shrank by the fraction taken last step
            x0 = None if prev is None else prev * frac
            u_free = lin.solve(K, rhs, x0)
            disp[asm.free] = u_free
        if f is not None:
            disp *= f[:, None]
        stats.solves += 1
        theta = 1.0
        while True:
            new = pos + theta * disp
            last = theta == 1.0 and frac == 1.0
            if last:
                new[path_nodes] = targets
            # flat: at the end either sign passes; before it, a fold (the next solve
            # would divide by its area, and magnify round-off into the nodes)
            sign = (1.0 if last else -1.0) if flat_ok else 0.0
            area = areas_with_margin(new, tri, sign)
            if (area > 0).all():
                break
            if keep_folds or stats.halvings >= max_halvings * steps or theta <= 2.0**-max_halvings:
                message = _fold_message(new, tri, area, steps, remaining, last, describe, advice)
                if not keep_folds:
                    raise FoldError(message)
                # the rest of the way in one step, solved on this (unfolded) mesh: solves on
                # folded or flat triangles would magnify round-off into the free nodes.  No
                # halving first: each halved step accepted close to a fold turns on whether
                # a nearly flat triangle's area is a hair above zero, so where the rest of
                # the way starts from would be round-off
                stats.fold = message
                pos = pos + disp / frac
                pos[path_nodes] = targets
                break
            theta *= 0.5
            stats.halvings += 1
        if stats.fold is not None:
            break
        pos = new
        if asm.n_free:
            prev = u_free / frac * (1.0 - theta * frac)  # U, not f U: what the solve returns
        remaining = 0.0 if (theta == 1.0 and frac == 1.0) else remaining - theta * dt
        stats.iterations = list(lin.iterations)
        if callback is not None:
            callback(1.0 - remaining / steps, stats)
    return pos, stats


def _fold_message(pos, tri, area, steps, remaining, last, describe, advice=ADVICE) -> str:
    t = int(np.argmin(area))
    where = pos[tri[t]].mean(axis=0)
    time = 1.0 - remaining / steps
    node = describe(tri[t]) if describe else ""
    if last:
        return (
            f"the final mesh would fold a triangle near ({where[0]:.6g}, {where[1]:.6g})"
            f"{node}: {advice[0]}"
        )
    return (
        f"the deformation folds a triangle near ({where[0]:.6g}, {where[1]:.6g}){node} at "
        f"pseudo-time {time:.3f} even with the step refined; {advice[1]}"
    )
