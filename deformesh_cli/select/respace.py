"""The adapted grid for unevenly spaced contours: select on an evenly spaced copy, then slide.

A uniform grid can give each contour point a node of its own, with
consecutive points on neighbouring nodes, only where the spacing is close to
the grid step.  Real contours are not like that (airfoil files cluster points
at the leading and trailing edges 30 to 300 times closer than mid-chord), and
Appendix A's step, taken from the *smallest* spacing, asks for 1e6 to 1e11
nodes.

So, by default for unevenly spaced contours (``--grid adapt``):

1. :func:`respace` slides every point along its own ring so that, between
   corners (vertices turning by more than :data:`~.contour.CORNER_DEGREES`,
   which stay where they are), the points are evenly spaced.  The shape is the
   same polygon; only where the points sit on it changes.
2. The grid step is the typical (median) spacing of that copy, and nodes are
   selected for the copy as in the core (Appendix A, or tracing).
3. The deformation carries each selected node along the contour itself, from
   its place on the copy to the real point (:class:`Slide`: at pseudo-time
   ``t`` the target is the point at arc length ``(1-t) s_copy + t s_real``),
   so the grid is compressed where the real points are dense.  That is the
   adaptation: cells near dense points end about as wide as their spacing.

Where that fails, :func:`candidate_selections` walks a short ladder of other
steps (:data:`LADDER`) before the caller falls back to Appendix A's grid.

naca0012_1000 (spacing ratio 316) meshes this way with its 1,000 points and
no extra boundary node on a 32k-node grid (``benchmarks/RESULTS.md``,
"Contours"); a uniform grid at Appendix A's step would need 3.6e10 nodes.  A first prototype
that adapted the grid with a size function built from the spacing
(``scripts/prototype_adapt.py``) folded there: the discrete divergence at the
trailing edge was 2-3 times the prescribed one, because the size function
varied 50-fold across one cell.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import deadline
from ..contour import Contour, make_contour
from ..contour import ring_corners as corners
from ..errors import InputError, LimitError, SelectionError
from ..geometry import next_on_ring
from .uniform import DEFAULT_MAX_NODES, select


@dataclass
class Respaced:
    """An evenly spaced copy of a contour and where each point sits along its ring.

    ``s_real[k]`` and ``s_copy[k]`` are arc lengths from the ring's first point
    (in input order) on the real ring; ``lengths[r]`` is ring ``r``'s perimeter.
    """

    real: Contour
    copy: Contour
    s_real: np.ndarray
    s_copy: np.ndarray
    lengths: np.ndarray


def spacing_ratio(contour: Contour) -> float:
    """The typical (median) spacing over the smallest: what makes Appendix A's grid big."""
    e = contour.edge_lengths()
    return float(np.median(e) / e.min())


def respace(contour: Contour) -> Respaced | None:
    """Slide the points so that they are evenly spaced between corners.

    Each ring's first point is kept as a piece end too, so arc lengths never
    wrap.  Returns None when the copy is not a valid contour (a slid point
    cutting a corner made two rings touch, or a ring cross itself); the
    caller then selects on the real points.
    """
    s_real, lengths = arclengths(contour)
    s_copy = s_real.copy()
    for a, i, j, _, cum in pieces(contour):  # points i..j-1 between piece ends i and j
        s_copy[a + i : a + j] = cum[0] + (cum[-1] - cum[0]) * np.arange(j - i) / (j - i)
    return slid_copy(contour, s_copy)


def pieces(contour: Contour):
    """``(ring start, first, last, polyline, arc lengths)`` of every piece between two
    corners (or a corner and its ring's first point, kept so that arc lengths never
    wrap): points ``first..last`` of a ring, ``last`` possibly the ring's size (its
    first point again)."""
    s, lengths = arclengths(contour)
    out = []
    for r in range(contour.n_rings):
        a, b = contour.starts[r], contour.starts[r + 1]
        q, cum = _ring_polyline(contour, s, lengths, r)
        ends = np.union1d([0, b - a], corners(q[:-1]))
        for i, j in zip(ends[:-1], ends[1:]):
            out.append((int(a), int(i), int(j), q[i : j + 1], cum[i : j + 1]))
    return out


def slid_copy(contour: Contour, s_copy: np.ndarray) -> Respaced | None:
    """The contour with each point slid along its ring to arc length ``s_copy`` (from
    the ring's first point), or None when that copy is not a valid contour."""
    c = contour
    s_real, lengths = arclengths(c)
    new = np.empty_like(c.points)
    for r in range(c.n_rings):
        a, b = c.starts[r], c.starts[r + 1]
        q, cum = _ring_polyline(c, s_real, lengths, r)
        new[a:b, 0] = np.interp(s_copy[a:b], cum, q[:, 0])
        new[a:b, 1] = np.interp(s_copy[a:b], cum, q[:, 1])
    try:
        copy = make_contour(
            new, c.lines, c.source, ring_starts=list(c.starts[:-1]), ring_labels=list(c.ring_labels)
        )
    except InputError:
        return None
    return Respaced(c, copy, s_real, s_copy, lengths)


def path_arclengths(
    rs: Respaced, source: np.ndarray, ring: np.ndarray, targets_on_copy: np.ndarray
):
    """Start and end arc length of every path node, and its exact final position.

    A node carrying contour point k goes from ``s_copy[k]`` to ``s_real[k]``
    and ends exactly on point k (``ring``: the path's ring of each node).  An
    extra boundary node on the copy's edge
    (a, b), a fraction ``u`` along it, goes to the same fraction of the real
    edge (a, b), so it ends on that contour edge.
    """
    c = rs.real
    n = len(source)
    s0, s1 = np.empty(n), np.empty(n)
    final = np.empty((n, 2))
    on = source >= 0
    s0[on], s1[on] = rs.s_copy[source[on]], rs.s_real[source[on]]
    final[on] = c.points[source[on]]
    nxt = next_on_ring(c.ring)
    # each ring's path is one contiguous, cyclic block: search neighbours within it
    for k in np.flatnonzero(~on):  # extra nodes: few, since h follows the copy's spacing
        block = np.flatnonzero(ring == ring[k])
        lo, size = block[0], len(block)
        a = (k - lo - 1) % size
        while source[lo + a] < 0:
            a = (a - 1) % size
        b = (k - lo + 1) % size
        while source[lo + b] < 0:
            b = (b + 1) % size
        pa, pb = int(source[lo + a]), int(source[lo + b])
        qa, qb = rs.copy.points[pa], rs.copy.points[pb]
        u = float(np.dot(targets_on_copy[k] - qa, qb - qa) / np.dot(qb - qa, qb - qa))
        u = min(max(u, 0.0), 1.0)
        if nxt[pa] != pb:  # the path runs against input order on this ring
            pa, pb, u = pb, pa, 1.0 - u
        length = rs.lengths[c.ring[pa]]
        for out, arc in ((s0, rs.s_copy), (s1, rs.s_real)):
            sa, sb = arc[pa], arc[pb]
            if sb <= sa:
                sb += length
            out[k] = sa + u * (sb - sa)
        final[k] = c.points[pa] + u * (c.points[pb] - c.points[pa])
    return s0, s1, final


def arclengths(contour: Contour) -> tuple[np.ndarray, np.ndarray]:
    """Arc length of every point from its ring's first point, and each ring's perimeter."""
    c = contour
    nxt = next_on_ring(c.ring)
    seg = np.hypot(*(c.points[nxt] - c.points).T)
    s = np.empty(c.n)
    lengths = np.empty(c.n_rings)
    for r in range(c.n_rings):
        a, b = c.starts[r], c.starts[r + 1]
        cum = np.cumsum(seg[a:b])
        s[a] = 0.0
        s[a + 1 : b] = cum[:-1]
        lengths[r] = cum[-1]
    return s, lengths


def _ring_polyline(c: Contour, s: np.ndarray, lengths: np.ndarray, r: int):
    """Ring ``r`` closed (first point repeated) and the arc length at each of its vertices."""
    a, b = c.starts[r], c.starts[r + 1]
    p = c.points[a:b]
    return np.vstack([p, p[:1]]), np.concatenate([s[a:b], [lengths[r]]])


class Slide:
    """Targets along the contour over pseudo-time: path node i at arc length
    ``(1-t) s0[i] + t s1[i]`` on its ring, exactly ``final[i]`` at ``t = 1``."""

    def __init__(
        self, contour: Contour, ring: np.ndarray, s0: np.ndarray, s1: np.ndarray, final: np.ndarray
    ):
        self.s0, self.s1, self.final = s0, s1, final
        s, lengths = arclengths(contour)
        self._groups = [
            (np.flatnonzero(ring == r), *_ring_polyline(contour, s, lengths, r), lengths[r])
            for r in range(contour.n_rings)
        ]

    def at(self, t: float) -> np.ndarray:
        if t >= 1.0:
            return self.final.copy()
        out = np.empty_like(self.final)
        for members, q, cum, length in self._groups:
            s = np.mod((1.0 - t) * self.s0[members] + t * self.s1[members], length)
            out[members, 0] = np.interp(s, cum, q[:, 0])
            out[members, 1] = np.interp(s, cum, q[:, 1])
        return out


#: The ladder: (slide?, divisor of the typical spacing), tried in order.  Sliding
#: suits smooth, densely sampled curves (airfoils); on jagged outlines (coastlines)
#: a slid node crosses details the grid does not resolve, and selecting the real
#: points on a finer grid gave better meshes (measured on three coastlines of the
#: corpus: slid at h/2, smallest angles 0.1-1.7 degrees; unslid at h/4, 14-18
#: degrees).  Each halving doubles the grid's cost.
LADDER = ((True, 1), (False, 2), (False, 4), (True, 2), (False, 8))

#: A ring with at least this fraction of corners is jagged: the copy is nearly the
#: real contour, and sliding only costs time (a coastline's first slid rung took
#: a minute to fail); jagged contours skip the slid rungs.  Corpus: coastlines
#: 0.20-0.39, airfoils 0.00-0.12, icons 0.00-0.80.
JAGGED = 0.2


def corner_fraction(contour: Contour) -> float:
    n = sum(
        len(corners(contour.points[contour.starts[r] : contour.starts[r + 1]]))
        for r in range(contour.n_rings)
    )
    return n / contour.n


#: The ``h_rule`` of every selection on the adapted grid (its step from the
#: contour's typical spacing): what tells an adapted rung from the other grids'.
ADAPTED = "typical-spacing"


def candidate_selections(
    contour: Contour,
    h=None,
    box=None,
    margin=None,
    strict: bool = False,
    max_nodes: int = DEFAULT_MAX_NODES,
    exterior: bool = False,
):
    """Selections for an adapted grid, in the order of :data:`LADDER`.

    The typical spacing ``h0`` is the median spacing of the evenly spaced
    copy (a given ``h`` replaces it).  A slid rung selects on the copy at
    ``h0 / d`` and records each node's slide; an unslid rung selects on the
    real points at the real median spacing ``/ d``.  Rungs whose path touches
    itself or whose grid is over ``max_nodes`` are skipped, and so are the
    slid ones on a jagged contour (:data:`JAGGED`).
    The caller deforms each until one does not fold, and falls back to the
    uniform grid when none is left.
    """
    rs = respace(contour) if corner_fraction(contour) < JAGGED else None
    h_copy = float(np.median(rs.copy.edge_lengths())) if rs is not None else None
    h_real = float(np.median(contour.edge_lengths()))
    if h is not None:
        h_copy = h_real = float(h)
    for slide, d in LADDER:
        if slide and rs is None:
            continue
        deadline.check()
        ref, step = (rs.copy, h_copy / d) if slide else (contour, h_real / d)
        try:
            sel = select(
                ref,
                h=step,
                box=box,
                margin=margin,
                strict=strict,
                max_nodes=max_nodes,
                exterior=exterior,
            )
        except (LimitError, SelectionError):  # the estimate is made before any work
            continue
        sel.h_rule = ADAPTED
        if slide:
            s0, s1, sel.path_targets = path_arclengths(
                rs, sel.path_source, sel.path_ring, sel.path_targets
            )
            sel.path_slide = np.column_stack([s0, s1])
            sel.notes.insert(
                0,
                f"adapted grid: h = {step:.4g}, the median spacing of the "
                "points evenly re-spaced between corners"
                + (f" / {d}" if d > 1 else "")
                + "; the deformation slides each node along the contour to its "
                "point",
            )
        else:
            sel.notes.insert(
                0,
                f"adapted grid: h = {step:.4g}, the median spacing of the "
                f"points / {d}, on the points as given (not slid)",
            )
        yield sel
