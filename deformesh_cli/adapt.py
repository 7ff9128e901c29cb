"""r-adaptation: a mesh's nodes moved so that its cells follow a monitor ``M > 0``, the
triangles unchanged (the paper's section 3.2 deformation, driven by a solution).

Where ``M`` is large the cells shrink: the target is equidistribution, every cell's
integral of ``M`` the same.  Relative to the input mesh's own cells, a cell at ``y``
should end ``c / M(y)`` times its area, ``c`` chosen so the domain keeps its area:
that is the deformation's size function ``f = c / M`` (density ``g = 1/f = M / c``,
whose integral over the domain is its area, by the P1 rule on the input mesh).  The
div-curl deformation goes from ``g = 1`` (the input's cells as they are) to it over
pseudo-time (:func:`.deform.deform_`, linear path): at every step ``div U = -dg/dt``,
``curl U = 0`` on the current mesh, ``U = 0`` on the boundary nodes, which stay
where they are, bit for bit.  Every step is checked for folds and halved where one
would appear, as in meshing; if none can be avoided the run is refused.  ``M = 1``
gives back the input coordinates unchanged (``g`` stays 1, no node moves).

The equidistribution measures are ``movement``'s: ``M`` interpolated at the nodes,
integrated over each cell of the adapted mesh (P1), divided by that cell's area in
the input mesh; their ``sigma / mu`` and ``max / min`` (its "volume ratio").
Nothing here prints or exits.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .deform import DEFAULT_STEPS, deform_
from .errors import InputError, MonitorError, OptionError
from .geometry import boundary_edges, signed_areas
from .size import SizePath, positive_values

#: Pseudo-time steps by default: the measures improve little past this many on the
#: ``movement`` ring (``benchmarks/MEASURED.md``).
ADAPT_STEPS = 4 * DEFAULT_STEPS


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


def adapt(
    points: np.ndarray,
    tri: np.ndarray,
    monitor: Callable[[np.ndarray], np.ndarray],
    steps: int = ADAPT_STEPS,
    source: str = "<mesh>",
) -> Adapted:
    """``points`` moved to follow ``monitor`` (points (k, 2) -> M (k,)); ``tri`` (counter-
    clockwise) unchanged, the boundary nodes held (see the module)."""
    points = np.asarray(points, dtype=np.float64)
    tri = np.asarray(tri, dtype=np.int64)
    area = signed_areas(points, tri)
    if len(tri) == 0:
        raise InputError(f"{source}: no triangles to adapt")
    if not (area > 0).all():
        k = int(np.argmax(~(area > 0)))
        c = points[tri[k]].mean(axis=0)
        raise InputError(
            f"{source}: triangle {k} near ({float(c[0]):.6g}, {float(c[1]):.6g}) is folded or "
            "flat; adapt needs a mesh whose triangles are all counter-clockwise"
        )
    if steps < 1:
        raise OptionError(f"--steps must be >= 1, got {steps}")
    m0 = monitor_values(monitor, points, source)
    # g = M / c, its P1 integral over the domain its area (the input mesh's cells);
    # relative to the first node's value and summed alike, so that a monitor equal at
    # every node gives c that value exactly: g = 1, dg/dt = 0, and no node moves
    share = (m0[tri] / m0[0]).mean(axis=1)
    c = float(m0[0]) * float(np.sum(area * share) / np.sum(area))
    fixed = np.unique(boundary_edges(tri, len(points)))
    before = equidistribution(points, tri, m0, area)

    def g1(q):
        return monitor_values(monitor, q, source) / c

    lo, hi = points.min(axis=0), points.max(axis=0)
    new, stats = deform_(
        points,
        tri,
        np.zeros(0, dtype=np.int64),
        np.zeros((0, 2)),
        fixed,
        steps=steps,
        # (direct: one ordering for every step, whose matrices share their pattern; the
        # 300 x 300 ring grid took 15 s so against 52 s with multigrid, MEASURED.md)
        solver="direct",
        size=SizePath(g1, (lo[0], lo[1], hi[0], hi[1])),
        advice=(
            "the monitor asks for more than these cells can give; give a smoother monitor",
            "give a smoother monitor or more --steps",
        ),
    )
    after = equidistribution(new, tri, monitor_values(monitor, new, source), area)
    report = {
        "nodes": len(points),
        "triangles": len(tri),
        "boundary_nodes_held": len(fixed),
        "steps": steps,
        "halvings": stats.halvings,
        "sigma_over_mu_before": before[0],
        "volume_ratio_before": before[1],
        "sigma_over_mu": after[0],
        "volume_ratio": after[1],
        "moved_nodes": int((new != points).any(axis=1).sum()),
    }
    return Adapted(new, report)


def carry(old: np.ndarray, tri: np.ndarray, new: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``values`` (one row per node of the mesh at ``old``) at the points ``new``, by P1
    interpolation in the old mesh: each point in a triangle that holds it (shapely's
    STRtree over the triangles; a point on a shared side takes the first, equal up to
    round-off); a node that did not move keeps its value to the bit."""
    import shapely

    values = np.asarray(values)
    out = np.array(values, dtype=np.float64, copy=True)
    moved = np.flatnonzero((new != old).any(axis=1))
    if not len(moved):
        return out
    polys = shapely.polygons(old[tri])
    at, hit = shapely.STRtree(polys).query(shapely.points(new[moved]), predicate="intersects")
    first = np.full(len(moved), len(tri))
    np.minimum.at(first, at, hit)  # (the lowest-numbered triangle holding each point)
    if (first == len(tri)).any():  # (the mesh's nodes stay inside it: round-off at its side)
        k = moved[int(np.argmax(first == len(tri)))]
        raise InputError(f"node {k} moved out of the mesh to ({new[k, 0]:.6g}, {new[k, 1]:.6g})")
    a, b, c = (old[tri[first, j]] for j in range(3))
    p = new[moved]
    den = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    wb = (
        (p[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (p[:, 1] - a[:, 1])
    ) / den
    wc = (
        (b[:, 0] - a[:, 0]) * (p[:, 1] - a[:, 1]) - (p[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    ) / den
    w = np.column_stack([1.0 - wb - wc, wb, wc])
    v = values[tri[first]].astype(np.float64)  # (m, 3, ...)
    out[moved] = np.einsum("mj,mj...->m...", w, v)
    return out
