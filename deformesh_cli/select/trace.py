"""Selection by tracing: the fallback when Appendix A's greedy choice fails.

Appendix A gives each contour point the nearest free corner of its cell, one
point at a time.  Where several points crowd into a few cells (a sharp
trailing edge, a cusp, cosine-clustered airfoil points) those choices can no
longer be joined into a simple path.  Tracing decides the path first and the
points second:

1. **Region.**  A set of cells whose outline will be the path.  First rule:
   cells whose centre is inside plus cells holding a contour point, bridged
   by the cells an edge crosses where consecutive points fall in different
   pieces; this hugs the contour and keeps narrow notches open.  Second
   rule, if the first gives no valid path: every cell the contour crosses,
   plus what they enclose; a feature thinner than a cell then becomes a
   strip one cell wide, so its two sides get distinct nodes.  Either way
   holes are filled and diagonal-only contacts ("pinches") are closed by
   adding the cell nearer the contour, so the outline is one simple closed
   grid path.
2. **Assignment.**  Contour points are assigned to outline nodes in order
   (a monotone, cyclic assignment), each node taking at most one point, by
   dynamic programming that minimises the sum of squared distances.
3. **Spurs and corners.**  Where the path runs three sides of a cell and the
   two middle nodes carry no point, it takes the fourth side instead.  An
   outline corner that carries no point is cut when the cell it turns around
   has no other path node: the path then takes the cell's diagonal, as
   Appendix A's paths do on slanted stretches.

Outline nodes left without a point become extra boundary nodes on the
contour edge between their neighbours, exactly as gaps do in
:func:`deformesh_cli.select.build_path`.
"""

from __future__ import annotations

import itertools

import numpy as np

from ..errors import SelectionError


class TraceError(SelectionError):
    """Tracing failed; ``k`` is the (counter-clockwise) index of the point concerned, if any."""

    def __init__(self, what: str, k: int | None = None):
        super().__init__(what)
        self.what = what
        self.k = k


#: Candidate outline nodes tried for the first contour point.
START_CANDIDATES = 6

#: A point further than this many cell diagonals from its node is refused.
MAX_REACH = 2.0

#: Region rules tried in turn: cells whose centre is inside plus cells
#: holding a contour point, bridged along the contour where that falls apart
#: (hugs the contour, keeps narrow notches open); then every cell the contour
#: crosses (never loses a thin part); then the first rule with the mid-lines
#: of thin peninsulas added and of thin inlets cut out (:func:`thin_features`).
#: A coastline with both an inlet of 16 degrees and a peninsula under a cell
#: wide at a quarter of the median spacing is traced by the third rule only
#: (``benchmarks/MEASURED.md``).
REGION_RULES = ("centres", "crossed", "thin")

#: A feature (peninsula or inlet) narrower than this many cells gets its mid-line
#: marked by the "thin" rule ...
THIN_WIDTH = 2.0

#: ... where its two sides are at least this many cells apart along the contour
#: (nearer, they are one side turning a corner).
THIN_ARC = 3.0

#: Rounds of hole filling and pinch closing or opening before a region with
#: channels is given up (without channels only cells are added, which always ends).
MAX_CLOSE_ROUNDS = 50


def region_cells(grid, q: np.ndarray, rule: str = "crossed") -> np.ndarray:
    """Boolean ``(ny, nx)`` array of region cells by ``rule`` (see :data:`REGION_RULES`)."""
    nx, ny = grid.nx, grid.ny
    ci, cj, edge = _crossed(grid, q)
    cells = np.zeros((ny, nx), dtype=bool)
    if rule == "crossed":
        cells[cj, ci] = True
        return _close(grid, cells, q)
    import shapely
    from scipy import ndimage

    gi, gj = np.meshgrid(np.arange(nx), np.arange(ny))
    cells |= shapely.contains_xy(
        shapely.polygons(q), grid.x0 + (gi + 0.5) * grid.hx, grid.y0 + (gj + 0.5) * grid.hy
    )
    pi, pj = _cell_of(grid, q)
    channels = None
    if rule == "thin":  # thin peninsulas are kept by their strips instead of point cells
        strips, channels = thin_features(grid, q)
        cells |= strips
        cells &= ~channels
    else:
        cells[pj, pi] = True
    cells = _close(grid, cells, q, channels)
    # bridge: where consecutive points lie in different pieces, add the cells
    # their edges cross (not channel cells), until one piece is left or
    # nothing is left to add; points in a channel cell are skipped over
    for _ in range(len(q)):
        labels, count = ndimage.label(cells)
        if count <= 1:
            break
        lab = labels[pj, pi]
        on = np.flatnonzero(lab > 0)
        if len(on) == 0:
            break
        jump = lab[on] != lab[np.roll(on, -1)]
        # each edge belongs to the last point at or before it that lies in a piece
        split = jump[np.searchsorted(on, np.arange(len(q)), side="right") - 1]
        add = split[edge]
        if channels is not None:
            add &= ~channels[cj, ci]
        if cells[cj[add], ci[add]].all():
            break
        cells[cj[add], ci[add]] = True
        cells = _close(grid, cells, q, channels)
    return cells


def thin_features(grid, q: np.ndarray):
    """Cells on the mid-lines of features narrower than :data:`THIN_WIDTH` cells.

    Returns ``(strips, channels)``, boolean ``(ny, nx)`` arrays: mid-line
    cells inside the contour (peninsulas, which must stay in the region so
    that their two sides get distinct nodes) and outside it (inlets, which
    must stay out of it for the same reason).  A mid-line point is the middle
    of two contour samples (a quarter cell apart along each edge) that are
    closer than :data:`THIN_WIDTH` cells, :data:`THIN_ARC` cells or more apart
    along the contour, on edges facing each other (normals within 60 degrees
    of opposite; a corner is not a thin feature), each on the other's outer
    side (an inlet) or each on the other's inner side (a peninsula).  ``q``
    runs counter-clockwise.
    """
    from scipy.spatial import cKDTree

    h = max(grid.hx, grid.hy)
    a, b = q, np.roll(q, -1, axis=0)
    seg = np.hypot(*(b - a).T)
    n = np.maximum(1, np.ceil(seg / (0.25 * h)).astype(np.int64))
    k = np.repeat(np.arange(len(q)), n)
    f = np.concatenate([np.arange(c) / c for c in n])
    s = a[k] + f[:, None] * (b[k] - a[k])
    arc = np.concatenate([[0.0], np.cumsum(seg)])[k] + f * seg[k]
    t = (b - a) / seg[:, None]
    out = np.column_stack([t[:, 1], -t[:, 0]])[k]  # outward normal of a counter-clockwise ring
    i, j = cKDTree(s).query_pairs(THIN_WIDTH * h, output_type="ndarray").T
    apart = np.abs(arc[i] - arc[j])
    d = s[j] - s[i]
    side_i = np.sum(d * out[i], axis=1)  # > 0: j lies on i's outer side
    side_j = -np.sum(d * out[j], axis=1)
    keep = (
        (np.minimum(apart, seg.sum() - apart) >= THIN_ARC * h)
        & (np.sum(out[i] * out[j], axis=1) < -0.5)
        & (side_i * side_j > 0)
    )
    i, j, outside = i[keep], j[keep], side_i[keep] > 0
    ci, cj = _cell_of(grid, 0.5 * (s[i] + s[j]))
    strips = np.zeros((grid.ny, grid.nx), dtype=bool)
    channels = strips.copy()
    strips[cj[~outside], ci[~outside]] = True
    channels[cj[outside], ci[outside]] = True
    return strips, channels


def _cell_of(grid, xy: np.ndarray):
    ci = np.clip(np.floor((xy[:, 0] - grid.x0) / grid.hx).astype(np.int64), 0, grid.nx - 1)
    cj = np.clip(np.floor((xy[:, 1] - grid.y0) / grid.hy).astype(np.int64), 0, grid.ny - 1)
    return ci, cj


def _crossed(grid, q: np.ndarray):
    """Cells the contour's edges cross: ``(i, j, edge)`` arrays, one row per sample."""
    a, b = q, np.roll(q, -1, axis=0)
    seg = np.hypot(*((b - a) / (grid.hx, grid.hy)).T)
    # sample each edge at an eighth of a cell so no crossed cell is skipped
    # except by a sliver at its corner (a pinch, closed later)
    n = np.maximum(1, np.ceil(seg * 8).astype(np.int64))
    k = np.repeat(np.arange(len(q)), n + 1)
    f = np.concatenate([np.arange(c + 1) / c for c in n])
    ci, cj = _cell_of(grid, a[k] + f[:, None] * (b[k] - a[k]))
    return ci, cj, k


def _close(grid, cells: np.ndarray, q: np.ndarray, channels=None) -> np.ndarray:
    """Fill holes and close pinches until the region's outline is simple.

    A pinch whose empty cells include a ``channels`` cell is opened instead:
    one of its two region cells is removed (and kept out from then on), so a
    channel running diagonally stays one open, edge-connected strip; the
    removed cell joins ``channels`` (updated in place, so that the caller does
    not add it back).  A channel cell left enclosed by the region is filled
    like any hole.
    """
    import shapely
    from scipy import ndimage

    ring = shapely.linearrings(q)

    def nearer(pi, pj):  # per row, the column (0 or 1) whose cell centre is nearer the contour
        centres = np.stack([grid.x0 + (pi + 0.5) * grid.hx, grid.y0 + (pj + 0.5) * grid.hy], -1)
        d = shapely.distance(shapely.points(centres), ring)
        return (d[:, 1] < d[:, 0]).astype(np.int64)

    cells = ndimage.binary_fill_holes(cells)
    # only adding cells always ends; opening channels could go back and forth
    for _ in itertools.count() if channels is None else range(MAX_CLOSE_ROUNDS):
        pi, pj = _pinches(cells)
        if len(pi) == 0:
            return cells
        chan = np.zeros(len(pi), dtype=bool) if channels is None else channels[pj, pi].any(axis=1)
        # close: of the two empty cells (columns 0 and 1), add the one whose
        # centre is nearer the contour (the first on a tie)
        r = np.flatnonzero(~chan)
        pick = nearer(pi[r], pj[r])
        cells[pj[r, pick], pi[r, pick]] = True
        # open: the block's two region cells are the other diagonal
        r = np.flatnonzero(chan)
        if len(r):
            oi = np.column_stack([pi[r, 1], pi[r, 0]])
            oj = np.column_stack([pj[r, 0], pj[r, 1]])
            pick = nearer(oi, oj)
            rr = np.arange(len(r))
            cells[oj[rr, pick], oi[rr, pick]] = False
            channels[oj[rr, pick], oi[rr, pick]] = True
        cells = ndimage.binary_fill_holes(cells)
    raise TraceError(f"has no simple outline after {MAX_CLOSE_ROUNDS} rounds of closing pinches")


def _pinches(cells: np.ndarray):
    """The two empty cells of each 2x2 block whose region cells touch only at a corner.

    Returns ``(i, j)`` arrays of shape ``(n, 2)``.
    """
    a, b = cells[:-1, :-1], cells[:-1, 1:]
    c, d = cells[1:, :-1], cells[1:, 1:]
    slash = a & d & ~b & ~c  # lower-left and upper-right: add lower-right or upper-left
    back = b & c & ~a & ~d  # lower-right and upper-left: add lower-left or upper-right
    js, is_ = np.nonzero(slash)
    jb, ib = np.nonzero(back)
    pi = np.concatenate([np.column_stack([is_ + 1, is_]), np.column_stack([ib, ib + 1])])
    pj = np.concatenate([np.column_stack([js, js + 1]), np.column_stack([jb, jb + 1])])
    return pi, pj


def outline(grid, cells: np.ndarray) -> np.ndarray:
    """The region's outline as a counter-clockwise cycle of grid node ids."""
    from scipy import ndimage

    labels, count = ndimage.label(cells)
    if count != 1:
        raise TraceError("falls apart into separate pieces")
    nx = grid.nx
    w = nx + 1
    pad = np.pad(cells, 1)
    cj, ci = np.nonzero(cells)
    pj, pi = cj + 1, ci + 1
    src, dst = [], []
    n00 = cj * w + ci
    for free, s, d in (
        (~pad[pj - 1, pi], n00, n00 + 1),  # bottom edge, left to right
        (~pad[pj, pi + 1], n00 + 1, n00 + w + 1),  # right edge, upwards
        (~pad[pj + 1, pi], n00 + w + 1, n00 + w),  # top edge, right to left
        (~pad[pj, pi - 1], n00 + w, n00),  # left edge, downwards
    ):
        src.append(s[free])
        dst.append(d[free])
    src_a, dst_a = np.concatenate(src), np.concatenate(dst)
    order = np.argsort(src_a, kind="stable")
    src_a, dst_a = src_a[order], dst_a[order]
    if (src_a[1:] == src_a[:-1]).any():  # pragma: no cover - pinches were closed
        raise TraceError("touches itself")
    nxt = dict(zip(src_a.tolist(), dst_a.tolist()))
    start = int(src_a[0])
    path = [start]
    node = nxt[start]
    while node != start:
        path.append(node)
        node = nxt[node]
    if len(path) != len(src_a):
        raise TraceError("encloses a hole")
    return np.asarray(path, dtype=np.int64)


def assign(P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """Positions ``t_k`` on the closed path ``P`` for the points ``Q``, in cyclic order.

    Minimises ``sum |P[t_k] - Q[k]|^2`` over ``t_0 < t_1 < ... < t_{m-1} <
    t_0 + L`` (indices modulo ``L``).  The first point's position is tried
    among its :data:`START_CANDIDATES` nearest path nodes.
    """
    L, m = len(P), len(Q)
    if m > L:
        raise TraceError(f"has {L} nodes for {m} contour points")
    d0 = np.sum((P - Q[0]) ** 2, axis=1)
    starts = np.argsort(d0, kind="stable")[:START_CANDIDATES]
    best_total, best = np.inf, None
    idx = np.arange(L)
    # squared distances point x path node, once for every start (when it fits in memory)
    dist = None
    if m * L <= 20_000_000:
        dist = (Q[:, None, 0] - P[None, :, 0]) ** 2 + (Q[:, None, 1] - P[None, :, 1]) ** 2
    for s in starts:
        cols = np.roll(idx, -int(s))  # path positions counted from this start
        Ps = P[cols]
        cost = np.full(L, np.inf)
        cost[0] = d0[s]
        back = np.zeros((m, L), dtype=np.int32)
        for k in range(1, m):
            prev = np.concatenate([[np.inf], cost[:-1]])  # strictly earlier position
            run = np.minimum.accumulate(prev)
            newmin = prev < np.concatenate([[np.inf], run[:-1]])
            back[k] = np.maximum.accumulate(np.where(newmin, idx, 0)) - 1
            cost = run + (dist[k, cols] if dist is not None else np.sum((Ps - Q[k]) ** 2, axis=1))
            cost[:k] = np.inf
            cost[L - (m - k) + 1 :] = np.inf
        t = int(np.argmin(cost))
        if cost[t] < best_total:
            best_total = cost[t]
            pos = np.empty(m, dtype=np.int64)
            for k in range(m - 1, 0, -1):
                pos[k] = t
                t = int(back[k, t])
            pos[0] = 0
            best = (pos + s) % L
    return best


def cut_corners(grid, path: np.ndarray, carried: np.ndarray):
    """Drop outline nodes carrying no point where the path can do without them.

    ``carried`` marks path positions that carry a contour point.  First,
    spurs: where the path runs three sides of one cell (a -> b -> c -> d)
    and neither b nor c carries a point, both go and the path takes the
    fourth side (such a cell sticks out past the contour or dents into it;
    kept, its U-turn would need a flat triangle of three contour-edge
    nodes).  Then corners: a corner carrying no point is cut to the cell's
    diagonal, convex corners (left turns) first, then concave ones, only when
    the cell's fourth corner is not on the path (no cell gets two path
    diagonals).  Returns the kept positions.
    """
    w = grid.nx + 1
    nodes = path.tolist()
    ij = [(n % w, n // w) for n in nodes]
    keep = list(range(len(nodes)))
    on_path = set(nodes)

    def step(u, v):
        return ij[v][0] - ij[u][0], ij[v][1] - ij[u][1]

    t = 0
    while t < len(keep) and len(keep) > 6:
        n = len(keep)
        a, b, c, d = (keep[(t + r) % n] for r in range(4))
        s1, s2, s3 = step(a, b), step(b, c), step(c, d)
        if (
            not carried[b]
            and not carried[c]
            and abs(s1[0]) + abs(s1[1]) == 1
            and abs(s2[0]) + abs(s2[1]) == 1
            and s1[0] * s2[0] + s1[1] * s2[1] == 0
            and s3 == (-s1[0], -s1[1])
        ):
            on_path.difference_update((nodes[b], nodes[c]))
            for pos in sorted(((t + 1) % n, (t + 2) % n), reverse=True):
                del keep[pos]
            t = max(t - 2, 0)
            continue
        t += 1
    for want_left in (True, False):
        changed = True
        while changed:
            changed = False
            t = 0
            while t < len(keep) and len(keep) > 4:
                a, c, b = keep[(t - 1) % len(keep)], keep[t], keep[(t + 1) % len(keep)]
                (ai, aj), (ci, cj), (bi, bj) = ij[a], ij[c], ij[b]
                fourth = (ai + bi - ci) + (aj + bj - cj) * w
                if (
                    carried[c]
                    or abs(ai - bi) != 1
                    or abs(aj - bj) != 1
                    or ((ci - ai) * (bj - cj) - (cj - aj) * (bi - ci) > 0) != want_left
                    or fourth in on_path
                ):
                    t += 1
                    continue
                on_path.discard(nodes[c])
                del keep[t]
                changed = True
    return np.asarray(keep, dtype=np.int64)


def trace_path(grid, q: np.ndarray, src: np.ndarray, rule: str = "crossed"):
    """Path by tracing (see module docstring): ``(nodes, targets, source)`` arrays.

    ``q`` holds the contour points counter-clockwise and ``src`` their input
    indices.  Raises :class:`TraceError` when the contour cannot be traced on
    this grid; the caller words the message.
    """
    cells = region_cells(grid, q, rule)
    path = outline(grid, cells)
    P = grid.coords(path)
    pos = assign(P, q)
    reach = np.hypot(*(P[pos] - q).T) / np.hypot(grid.hx, grid.hy)
    if reach.max() > MAX_REACH:
        k = int(np.argmax(reach))
        raise TraceError(f"passes {reach[k]:.2g} cell diagonals from its point", k)
    carried = np.zeros(len(path), dtype=bool)
    carried[pos] = True
    point_at = np.full(len(path), -1, dtype=np.int64)
    point_at[pos] = np.arange(len(q))
    keep = cut_corners(grid, path, carried)
    path, point_at = path[keep], point_at[keep]
    # rotate so the path starts at point 0
    first = int(np.flatnonzero(point_at == 0)[0])
    path, point_at = np.roll(path, -first), np.roll(point_at, -first)
    at = np.flatnonzero(point_at >= 0)
    m = len(q)
    targets = np.empty((len(path), 2))
    source = np.full(len(path), -1, dtype=np.int64)
    for r, t in enumerate(at):
        k = point_at[t]
        t2 = at[r + 1] if r + 1 < len(at) else len(path)
        targets[t] = q[k]
        source[t] = src[k]
        gap = t2 - t - 1
        if gap:
            f = np.arange(1, gap + 1) / (gap + 1)
            targets[t + 1 : t2] = q[k] + f[:, None] * (q[(k + 1) % m] - q[k])
    return path, targets, source
