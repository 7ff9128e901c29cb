"""r-adaptation: a mesh's nodes moved so that its cells follow a monitor ``M > 0``, the
triangles unchanged (the paper's section 3.2 deformation, driven by a solution).

Where ``M`` is large the cells shrink: the target is equidistribution, every cell's
integral of ``M`` the same.  Relative to a reference mesh's cells (the input mesh
itself by default), a cell at ``y`` should end ``c / M(y)`` times its reference
area, ``c`` chosen so the domain keeps its area: that is the deformation's size
function ``f = c / M`` (density ``g = 1/f = M / c``, whose integral over the domain
is its area, by the P1 rule on the reference mesh).  The div-curl deformation goes
from ``g = 1`` (the reference's cells as they are) to it over pseudo-time on the
paper's linear path ``g = (1 - t) + t M / c``: at every time the velocity is
``U / g`` with ``div U = -dg/dt = 1 - M / c``, ``curl U = 0`` on the current mesh,
integrated by the midpoint rule (second order: :data:`ADAPT_STEPS` steps reach what
several hundred first-order ones do, ``benchmarks/MEASURED.md``).  Every stage is
checked for folds and its step halved where one would appear; if none can be
avoided the run is refused.  ``M`` constant gives back the reference coordinates
unchanged (``g`` stays 1, no node moves).

Boundary nodes either stay where they are, bit for bit (the user's contour points,
corners, and every boundary node with ``slide=False``), or slide along the straight
run of boundary they sit on (their two boundary neighbours collinear with them, to
:data:`COLLINEAR` relative): only their tangential velocity is solved for, so a node
on an axis-parallel side keeps that coordinate to the bit, and the domain keeps its
shape.  The least-squares functional couples the two velocity components only
through the boundary (its ``ux``-``uy`` block is ``oint ux d(uy)``, a null
Lagrangian), which :class:`SlipSystem` assembles edge by edge.

The equidistribution measures are ``movement``'s: ``M`` interpolated at the nodes,
integrated over each cell of the adapted mesh (P1), divided by that cell's area in
the reference mesh; their ``sigma / mu`` and ``max / min`` (its "volume ratio").
Nothing here prints or exits.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .cholesky import Cholesky
from .divcurl import Assembler, divergence_load, gradients, stiffness_entries
from .errors import FoldError, InputError, MonitorError, OptionError
from .geometry import boundary_edges, signed_areas
from .quality import measures
from .size import positive_values

#: Solves of the velocity at least, each on the mesh as it then is: the time between
#: two solves is at most ``1 / ADAPT_STEPS`` (where the velocity is steep,
#: :data:`STRETCH` asks for more: 18 on the ``movement`` ring on a 300 x 300 grid).
#: On that ring 10 solves end where 40 do (sigma/mu 0.023 both; 8 give 0.025, 6
#: 0.027), ``benchmarks/MEASURED.md``.
ADAPT_STEPS = 10

#: The time between two solves is also at most ``STRETCH / max_K |grad v|_K``, the
#: velocity's P1 gradient on each cell at the solve (spectral norm): the field's own
#: Euler map over that time then keeps every cell's singular values within
#: ``[1 - STRETCH, 1 + STRETCH]``, so no cell folds or falls below a quarter of its
#: area in it, and the frozen field is never read far from the mesh it was solved on.
STRETCH = 0.5

#: Midpoint-rule substeps in each solve's velocity field (frozen between solves): on
#: the 300 x 300 ring sigma/mu 0.033 with 1, 0.022 with 2, 0.020 with 4 at twice the
#: point location (``benchmarks/MEASURED.md``).
SUBSTEPS = 2

#: Halvings of the time between two solves allowed where a substep folds a triangle,
#: before the fold is reported (the time then 1/1024 of what it was).  The shortest
#: time between solves, ``1 / (steps * 2**MAX_HALVINGS)``, bounds :data:`STRETCH`'s
#: too: a velocity whose gradient asks for less (cells collapsing) is refused.
MAX_HALVINGS = 10

#: A boundary node slides when the cross product of its two boundary edges is at most
#: this fraction of their lengths' product (collinear up to coordinates' round-off).
COLLINEAR = 1e-12

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


class SlipSystem:
    """The div-curl least-squares system on the motions a mesh's nodes may make.

    Unknowns: ``(ux, uy)`` at a free inner node, ``w`` at a sliding node (its
    velocity ``w t`` along its tangent ``t``), none at a fixed node.  The functional
    ``sum_T |T| ((div U - r)^2 + (curl U)^2)`` has the P1 Laplace stiffness ``L`` on
    each component and couples them by ``B``, ``ux . B uy = oint ux d(uy)``: on each
    boundary edge ``a -> b``, ``(ux_a + ux_b) (uy_b - uy_a) / 2``, whatever the
    coordinates.  The reduced matrix ``P^T [[L, B], [B^T, L]] P`` is factorised
    (:class:`.cholesky.Cholesky`) once, and refactorised with new numbers on later
    solves while its pattern holds.

    Where every sliding node moves along an axis (a box, a grid's square) ``B``
    couples no two unknowns (a boundary edge's ends are a fixed ``ux`` or ``uy`` on
    one side, or a corner) and the system is two scalar Laplace problems, each
    component held where its node may not move that way: they are assembled and
    solved on meshing's assembly (:class:`.divcurl.Assembler`), one matrix for both
    where the held sets agree.
    """

    def __init__(self, tri: np.ndarray, fixed: np.ndarray, tangent: np.ndarray):
        import scipy.sparse as sp

        n = len(fixed)
        self.n = n
        self.tri = tri
        slide = np.flatnonzero(tangent.any(axis=1) & ~fixed)
        inner = np.flatnonzero(~fixed & ~tangent.any(axis=1))
        ni, ns = len(inner), len(slide)
        rows = np.concatenate([inner, n + inner, slide, n + slide])
        cols = np.concatenate([np.arange(2 * ni), 2 * ni + np.arange(ns), 2 * ni + np.arange(ns)])
        vals = np.concatenate([np.ones(2 * ni), tangent[slide, 0], tangent[slide, 1]])
        self.P = sp.csr_matrix((vals, (rows, cols)), shape=(2 * n, 2 * ni + ns))
        self.P.eliminate_zeros()  # (a side parallel to an axis: one component only)
        e = boundary_edges(tri, n)
        a, b = e[:, 0], e[:, 1]
        half = np.full(len(e), 0.5)
        self.B = sp.csr_matrix(
            (np.concatenate([half, -half, half, -half]),
             (np.concatenate([a, a, b, b]), np.concatenate([b, a, b, a]))),
            shape=(n, n),
        )  # fmt: skip
        self._ldl = None
        along = np.zeros(n, dtype=bool)
        along[slide] = True
        self.split = bool((tangent[slide] == 0).any(axis=1).all())
        if self.split:
            hold_x = fixed | (along & (tangent[:, 0] == 0))
            hold_y = fixed | (along & (tangent[:, 1] == 0))
            x = (Assembler(tri, n, hold_x), Cholesky())
            same = np.array_equal(hold_x, hold_y)
            self._parts = [x] if same else [x, (Assembler(tri, n, hold_y), Cholesky())]
        else:
            self.asm = Assembler(tri, n, np.zeros(n, dtype=bool))

    def velocity(self, points: np.ndarray, r: np.ndarray, geometry=None) -> np.ndarray:
        """``U`` (N, 2) with ``div U = r`` (per triangle), ``curl U = 0``, in the least-
        squares sense on the allowed motions (``geometry``: :func:`.divcurl.gradients`
        of the mesh at ``points``, if the caller has them)."""
        import scipy.sparse as sp

        U = np.zeros((self.n, 2))
        if self.P.shape[1] == 0:
            return U
        if geometry is None:
            geometry = gradients(points, self.tri)
        ke = stiffness_entries(points, self.tri, geometry=geometry).ravel()
        load = divergence_load(self.tri, geometry, r, self.n)
        if self.split:  # (held components are 0: no Dirichlet load)
            for k, (asm, chol) in enumerate(self._parts):
                if asm.n_free:
                    chol.factorise(asm.matrix(ke).upper())
                    if len(self._parts) == 1:
                        U[asm.free] = chol.solve(load[asm.free])
                    else:
                        U[asm.free, k] = chol.solve(load[asm.free, k])
            return U
        L = self.asm.matrix(ke)
        L = L.tocsr()
        A = sp.bmat([[L, self.B], [self.B.T, L]], format="csr")
        K = (self.P.T @ A @ self.P).tocsr()
        upper = sp.triu(K, format="csc")
        upper.sort_indices()
        if self._ldl is None:
            self._ldl = Cholesky()
        self._ldl.factorise(upper)
        rhs = self.P.T @ np.concatenate([load[:, 0], load[:, 1]])
        u = self.P @ self._ldl.solve(rhs)
        U[:, 0], U[:, 1] = u[: self.n], u[self.n :]
        return U


def adapt(
    points: np.ndarray,
    tri: np.ndarray,
    monitor: Callable[[np.ndarray], np.ndarray],
    steps: int = ADAPT_STEPS,
    source: str = "<mesh>",
    held: np.ndarray | None = None,
    slide: bool = True,
) -> Adapted:
    """``points`` (the reference mesh) moved to follow ``monitor`` (points (k, 2) -> M
    (k,)); ``tri`` (counter-clockwise) unchanged; boundary nodes as
    :func:`boundary_motion` says (``held``: a node mask of the user's points)."""
    points = np.asarray(points, dtype=np.float64)
    tri = np.asarray(tri, dtype=np.int64)
    area = check_mesh(points, tri, source)
    if steps < 1:
        raise OptionError(f"--steps must be >= 1, got {steps}")
    m0 = monitor_values(monitor, points, source)
    # g = M / c, its P1 integral over the domain its area (the reference's cells);
    # relative to the first node's value and summed alike, so that a monitor equal at
    # every node gives c that value exactly: g = 1, dg/dt = 0, and no node moves
    share = (m0[tri] / m0[0]).mean(axis=1)
    c = float(m0[0]) * float(np.sum(area * share) / np.sum(area))
    fixed, tangent = boundary_motion(points, tri, held, slide)
    before = equidistribution(points, tri, m0, area)
    system = SlipSystem(tri, fixed, tangent)

    neighbours = triangle_neighbours(tri)
    start = np.empty(len(points), dtype=np.int64)
    start[tri.ravel()] = np.repeat(np.arange(len(tri)), 3)  # a triangle at each node
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
        return not (signed_areas(q, tri) > 0).all()

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
        g1 = g_at(pos)
        geometry = gradients(pos, tri)
        U = system.velocity(pos, (1.0 - g1)[tri].mean(axis=1), geometry)
        solves += 1
        spread = stretch(tri, geometry, allowed(U / density(g1, t)[:, None]))
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
        field = FrozenField(pos, tri, U, neighbours, start)
        while True:
            new, worst = substeps(field, pos, g1, t, span)
            if new is not None:
                break
            if halved == MAX_HALVINGS:
                x, y = worst[tri[int(np.argmin(signed_areas(worst, tri)))]].mean(axis=0)
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
        "tangled": int((signed_areas(pos, tri) <= 0).sum()),
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


def frames(points: np.ndarray, tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each triangle's first corner ``a`` (T, 2) and the inverse of ``[b - a, c - a]``
    (T, 2, 2): the barycentric weights of ``q`` are ``1 - wb - wc, wb, wc`` with
    ``(wb, wc) = inverse (q - a)``."""
    a, b, c = (points[tri[:, j]] for j in range(3))
    e1, e2 = b - a, c - a
    den = e1[:, 0] * e2[:, 1] - e2[:, 0] * e1[:, 1]
    inv = np.stack([[e2[:, 1], -e2[:, 0]], [-e1[:, 1], e1[:, 0]]]).transpose(2, 0, 1)
    return a, inv / den[:, None, None]


def weights(frame: tuple[np.ndarray, np.ndarray], t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(k, 3): the barycentric weights of the points ``q`` in the triangles ``t``
    (``frame``: :func:`frames` of the mesh)."""
    a, inv = frame
    d = q - a[t]
    m = inv[t]
    wb = m[:, 0, 0] * d[:, 0] + m[:, 0, 1] * d[:, 1]
    wc = m[:, 1, 0] * d[:, 0] + m[:, 1, 1] * d[:, 1]
    return np.column_stack([1.0 - wb - wc, wb, wc])


#: A barycentric weight this far below 0 is 0 up to round-off: a point on a side
#: shared by two triangles is in both (a walk does not step back and forth).
WEIGHT_ROUND_OFF = 1e-12


class FrozenField:
    """A P1 field on a fixed mesh (``values`` at its nodes), evaluated at points that
    each started at a node and move a little between calls: every point walks from
    the triangle it was found in last (at first, one at its node), across the side
    of its most negative barycentric weight, until all weights are >= 0 (to
    :data:`WEIGHT_ROUND_OFF`) or the walk meets the boundary; a point that stops
    outside the mesh, or walks :data:`WALK_LIMIT` steps, is found by the
    :class:`Locator` (within :data:`ROUND_OFF` of the mesh).  At the mesh's own nodes
    the values are returned to the bit."""

    def __init__(self, points, tri, values, neighbours, start):
        self.points, self.tri, self.values = points, tri, values
        self.neighbours = neighbours
        self.hint = start.copy()
        self.frame = frames(points, tri)
        self._locator = None

    def at(self, q: np.ndarray) -> np.ndarray:
        if np.array_equal(q, self.points):
            return self.values.copy()
        t = self.hint
        w = np.empty((len(q), 3))
        todo = np.arange(len(q))
        for _ in range(WALK_LIMIT):
            ww = weights(self.frame, t[todo], q[todo])
            j = np.argmin(ww, axis=1)
            nxt = self.neighbours[t[todo], j]
            done = (ww[np.arange(len(todo)), j] >= -WEIGHT_ROUND_OFF) | (nxt < 0)
            w[todo[done]] = ww[done]
            t[todo[~done]] = nxt[~done]
            todo = todo[~done]
            if not len(todo):
                break
        least = np.minimum(np.minimum(w[:, 0], w[:, 1]), w[:, 2])  # (not min(axis=1): slow)
        lost = np.union1d(todo, np.flatnonzero(least < -WEIGHT_ROUND_OFF))
        if len(lost):
            if self._locator is None:
                self._locator = Locator(self.points, self.tri)
            t[lost], w[lost] = self._locator.find(q[lost])
        return p1_values(self.values, self.tri, t, w)


def p1_values(values: np.ndarray, tri: np.ndarray, t: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``values`` (one row per node) interpolated linearly at points in the triangles
    ``t`` with barycentric weights ``w`` (k, 3)."""
    return np.einsum("mj,mj...->m...", w, values[tri[t]])


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
    grad = recovered_gradient(points, tri, u)
    if kind == "gradient":
        s = (grad**2).sum(axis=1)
    else:
        hx = recovered_gradient(points, tri, grad[:, 0])
        hy = recovered_gradient(points, tri, grad[:, 1])
        s = np.sqrt((hx**2).sum(axis=1) + (hy**2).sum(axis=1))
    top = s.max()
    return np.ones(len(u)) if top == 0 else 1.0 + alpha * s / top


def interpolated(points: np.ndarray, tri: np.ndarray, values: np.ndarray):
    """``values`` at the nodes of the mesh ``(points, tri)`` as a function of points, by
    P1 interpolation (a point at a node gets that node's value to the bit)."""
    values = np.asarray(values, dtype=np.float64)
    locator = Locator(points, tri)

    def at(q: np.ndarray) -> np.ndarray:
        if q.shape == points.shape and np.array_equal(q, points):
            return values.copy()
        return p1_values(values, tri, *locator.find(q))

    return at
