"""Boundary layers: stacks of cells along the walls, grown from the contour's own points.

Each wall point gets a straight *stack*: a direction into the domain (the bisector
of its two edges' normals, or at a sharp convex corner a *fan* of directions from
one edge's normal to the other's) and ``N`` layer nodes along it, layer ``k`` at

    h_k = H (r^k - 1) / (r - 1),

``H`` the first height and ``r`` the growth: ``R`` on a full stack, less on a
shortened one so that it ends at its thickness (:func:`stack_heights`).
Consecutive stacks are joined by quads, layer by layer (a fan's first cells,
which share their wall point, are triangles).  The top nodes of the stacks form
the boundary of the rest of the domain, which the construction meshes with exactly
those nodes (:mod:`.pipeline`).

Where a full stack would not fit, it is made shorter, by these rules of geometry,
then smoothly along the wall:

- **converging neighbours**: a stack reaches at most :data:`MEET_SHARE` of the way
  to the line of the next stack's or the previous stack's direction, where it heads
  towards it (a concave bend).  Every layer node of two neighbouring stacks then
  lies on the boundary of the convex region between their rays and their wall
  edge, in order, so each quad between them is convex;
- **other parts of the contour**: a stack takes at most :data:`GAP_SHARE` of its
  clearance across the domain (the distance to another part of the contour on the
  domain's side, :mod:`.select.segments`), and of its distance to a far-field
  box's side, so two facing stacks leave the rest of the gap to the core mesh;
- **smoothly**: the thickness changes by at most :data:`SLOPE` per unit of wall
  length (the least over the wall of each stack's bound plus the slope times the
  distance along the ring, taken both ways round).

A stack is never tangled: only shortened.  A gap narrower than ``2 H`` (where
the first layers of its two sides cannot both fit) is refused in one line naming
the place and the width there.  Nothing here prints or exits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .contour import MIN_RELATIVE_EDGE, Contour, make_contour
from .errors import InputError, LimitError, OptionError, SelectionError

#: A wall point whose two edges turn away from the domain by more than this (its
#: angle on the domain's side over 180 + FAN_TURN degrees) gets a fan: a single
#: bisector there would meet each edge at more than 90 + FAN_TURN / 2 degrees, so
#: the layer edges leaving the wall stay within 10 degrees of the wall normal.
FAN_TURN = 20.0

#: A fan's directions are at most this many degrees apart.
FAN_STEP = 15.0

#: A stack reaches at most this share of the way to a converging neighbour's line.
MEET_SHARE = 0.5

#: A stack takes at most this share of its clearance across the domain.
GAP_SHARE = 0.4

#: The stacks' thickness changes by at most this much per unit of wall length.
SLOPE = 0.5

#: Default growth of the layer heights.
DEFAULT_GROWTH = 1.2

#: Most layers a stack may have.
MAX_LAYERS = 1000

#: ``--layer-cells``: quads between layers, or each quad split in two triangles.
LAYER_CELLS = ("quad", "tri")


@dataclass(frozen=True)
class LayerSpec:
    """``layers`` layers of first height ``first`` growing by ``growth`` on the rings
    ``rings`` (ring indices of the contour; None: every ring)."""

    layers: int
    first: float
    growth: float = DEFAULT_GROWTH
    rings: tuple[int, ...] | None = None

    def __post_init__(self):
        if self.layers < 1:
            raise OptionError(f"--layers must be at least 1, got {self.layers}")
        if not (math.isfinite(self.first) and self.first > 0):
            raise OptionError(f"--first-height must be a positive number, got {self.first}")
        if not (math.isfinite(self.growth) and self.growth >= 1.0):
            raise OptionError(f"--layer-growth must be at least 1, got {self.growth}")
        with np.errstate(over="ignore"):
            full = float(self.heights()[-1])
        if not math.isfinite(full):
            raise OptionError(
                f"--layers {self.layers} growing by {self.growth:g} from {self.first:g} "
                "overflows a double: give fewer layers or a smaller --layer-growth"
            )

    def heights(self) -> np.ndarray:
        """The full stack's heights ``h_0 = 0, h_1 = H, ..., h_N`` (N + 1,)."""
        k = np.arange(self.layers + 1, dtype=np.float64)
        if self.growth == 1.0:
            return self.first * k
        return self.first * (self.growth**k - 1.0) / (self.growth - 1.0)


@dataclass
class Stacks:
    """The layers of a contour.

    ``wall[s]``: the contour point stack ``s`` stands on; ``direction[s]``: its unit
    direction; ``share[s]``: its thickness over the full one.  ``nodes`` ((S N, 2)):
    stack ``s``'s layer ``k`` (1..N) is row ``s N + k - 1``.  ``quads`` and
    ``triangles``: the cells, counter-clockwise, numbering contour points ``0 ..
    n-1`` and layer nodes ``n + row``.  ``rings[r]``: the stacks of layered ring
    ``r`` in the domain's order (the domain on the left), or None for a ring without
    layers.  ``top``: the contour of the rest of the domain (a layered ring's points
    are its stacks' top nodes, in the domain's order; other rings as given), and
    ``top_node[k]`` the final node of its point ``k``."""

    spec: LayerSpec
    wall: np.ndarray
    direction: np.ndarray
    share: np.ndarray
    nodes: np.ndarray
    quads: np.ndarray
    triangles: np.ndarray
    rings: list
    top: Contour
    top_node: np.ndarray
    exterior: bool = False
    fans: int = 0
    shortened: int = 0


def _domain_order(contour: Contour, r: int, exterior: bool) -> np.ndarray:
    """Ring ``r``'s points with the domain on the left."""
    order = contour.ring_order(r)
    return order[::-1] if contour.is_hole(r) != exterior else order


def _directions(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Per point of a closed ring ``p`` (the domain on the left), its stacks'
    directions: the bisector of its edges' normals, or a fan from the incoming
    edge's normal to the outgoing one's where the ring turns away from the domain
    by more than :data:`FAN_TURN`; returns (point of each stack, directions (S, 2),
    fans), the stacks in the ring's order."""
    e = np.roll(p, -1, axis=0) - p
    t = e / np.hypot(e[:, 0], e[:, 1])[:, None]
    nu = np.column_stack([-t[:, 1], t[:, 0]])  # (left normals: into the domain)
    t_in, nu_in = np.roll(t, 1, axis=0), np.roll(nu, 1, axis=0)
    turn = np.arctan2(t_in[:, 0] * t[:, 1] - t_in[:, 1] * t[:, 0], (t_in * t).sum(axis=1))
    fan = turn < -math.radians(FAN_TURN)
    steps = np.where(fan, np.ceil(-turn / math.radians(FAN_STEP)), 0.0).astype(np.int64)
    owner = np.repeat(np.arange(len(p)), steps + 1)
    j = np.arange(len(owner)) - np.repeat(np.cumsum(steps + 1) - (steps + 1), steps + 1)
    b = nu_in + nu
    bis = b / np.hypot(b[:, 0], b[:, 1])[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):  # (a fan's angle; no fan: unused)
        phi = np.arctan2(nu_in[owner, 1], nu_in[owner, 0]) + turn[owner] * j / np.maximum(
            steps[owner], 1
        )
    dirs = np.where(fan[owner][:, None], np.column_stack([np.cos(phi), np.sin(phi)]), bis[owner])
    return owner, dirs, int(fan.sum())


def _meet_bounds(a: np.ndarray, da: np.ndarray, b: np.ndarray, db: np.ndarray) -> np.ndarray:
    """Per pair of rays ``a + u da`` and ``b + v db``: how far along the first its line
    meets the second's line, where that is ahead (inf where not, or parallel)."""
    # a + u da = b + v db  ->  u = cross(b - a, db) / cross(da, db)
    w = b - a
    den = da[:, 0] * db[:, 1] - da[:, 1] * db[:, 0]
    num = w[:, 0] * db[:, 1] - w[:, 1] * db[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = num / den
    return np.where((den != 0) & (u > 0), u, np.inf)


def stack_heights(spec: LayerSpec, thick: np.ndarray) -> np.ndarray:
    """Per stack of thickness ``thick`` (at most the full one), its layer heights
    ``h_0 = 0 .. h_N = thick`` ((S, N + 1)).  A stack keeps the first height ``H``
    and grows its layers by the ratio ``r`` in ``[1, R]`` that gives its thickness,
    ``H (r^N - 1) / (r - 1)`` (the full stack: ``R``); one thinner than ``N H`` has
    ``N`` equal layers.  ``r`` is found by bisection, a fixed number of halvings (the
    same bits on every machine)."""
    n, h = spec.layers, spec.first
    k = np.arange(n + 1, dtype=np.float64)
    thick = np.asarray(thick, dtype=np.float64)
    even = thick[:, None] * k[None, :] / n
    if spec.growth == 1.0:
        return even
    lo = np.ones(len(thick))
    hi = np.full(len(thick), spec.growth)
    target = thick / h
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        with np.errstate(invalid="ignore", divide="ignore"):
            total = np.where(mid > 1.0, (mid**n - 1.0) / (mid - 1.0), float(n))
        low = total < target
        lo, hi = np.where(low, mid, lo), np.where(low, hi, mid)
    r = np.where(thick >= float(spec.heights()[-1]), spec.growth, lo)
    with np.errstate(invalid="ignore", divide="ignore"):
        grown = h * np.where(
            (r > 1.0)[:, None], (r[:, None] ** k[None, :] - 1.0) / (r[:, None] - 1.0), k[None, :]
        )
    grown[:, -1] = thick  # (the stack's top exactly where its bounds put it)
    return np.where((thick >= n * h)[:, None], grown, even)


#: Halvings of the growth interval when a shortened stack's ratio is sought.
BISECTIONS = 60


def _thickness(p, wall, d, per_ring, arc_all, rings, full: float, near) -> np.ndarray:
    """Each stack's thickness: the full one, lowered by the neighbours' rule, the
    domain's width by it (``near``, per contour point), the crossings, then smoothly
    along each ring."""
    bound = np.full(len(wall), full)
    for r in rings:  # converging neighbours
        s = per_ring[r]
        nxt = np.roll(s, -1)
        a, b = p[wall[s]], p[wall[nxt]]
        differ = wall[s] != wall[nxt]
        u = np.where(differ, _meet_bounds(a, d[s], b, d[nxt]), np.inf)
        v = np.where(differ, _meet_bounds(b, d[nxt], a, d[s]), np.inf)
        bound[s] = np.minimum(bound[s], MEET_SHARE * u)
        bound[nxt] = np.minimum(bound[nxt], MEET_SHARE * v)
    bound = np.minimum(bound, GAP_SHARE * near[wall])
    # any two stacks that cross (a wedge's two sides, a bend's stacks beyond neighbours)
    bound = _crossing_bounds(p[wall], d, bound, wall)
    thick = np.empty(len(wall))
    for r, (arc_r, per) in zip(rings, arc_all):
        s = per_ring[r]
        thick[s] = _smooth(bound[s], arc_r, per)
    return thick


def _crossing_bounds(
    start: np.ndarray, d: np.ndarray, bound: np.ndarray, wall: np.ndarray
) -> np.ndarray:
    """``bound`` lowered where two stacks (from ``start`` along ``d``, ``bound`` long;
    a fan's, which share their wall point, aside) cross: each then reaches at most
    :data:`MEET_SHARE` of the way to the crossing, so no two cross.  The pairs come
    from a tree of the segments (shapely's STRtree), not from all pairs."""
    import shapely

    ends = start + bound[:, None] * d
    segs = shapely.linestrings(np.stack([start, ends], axis=1))
    i, j = shapely.STRtree(segs).query(segs, predicate="intersects")
    keep = (i < j) & (wall[i] != wall[j])
    i, j = i[keep], j[keep]
    if not len(i):
        return bound
    u = _meet_bounds(start[i], d[i], start[j], d[j])
    v = _meet_bounds(start[j], d[j], start[i], d[i])
    out = bound.copy()
    np.minimum.at(out, i, np.where(np.isfinite(u), MEET_SHARE * u, out[i]))
    np.minimum.at(out, j, np.where(np.isfinite(v), MEET_SHARE * v, out[j]))
    return out


def _smooth(bound: np.ndarray, arc: np.ndarray, perimeter: float) -> np.ndarray:
    """The least over the ring's stacks ``j`` of ``bound[j] + SLOPE d(i, j)``, ``d``
    along the ring either way round (``arc``: the stacks' places, non-decreasing)."""
    a2 = np.concatenate([arc, arc + perimeter, arc + 2 * perimeter])
    b2 = np.tile(bound, 3)
    fwd = SLOPE * a2 + np.minimum.accumulate(b2 - SLOPE * a2)
    back = -SLOPE * a2 + np.minimum.accumulate((b2 + SLOPE * a2)[::-1])[::-1]
    n = len(arc)
    out = np.minimum(fwd, back)[n : 2 * n]
    # (a stack's own bound comes back through a sum and its difference: the round-off
    # is not a shortening)
    return np.where(out >= bound * (1.0 - 1e-12), bound, out)


def _clearances(
    contour: Contour, exterior: bool, box, walls: np.ndarray, reach: float, first: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """How wide the domain is by the walls: per contour point (inf but at ``walls``),
    the least clearance across the domain (the distance to another part of the
    contour on the domain's side, :class:`~.select.segments.Segments`, looked for
    within ``reach``) at the point and along its two edges, and twice its distance to
    the box's sides; then the narrowest place found, as ``(width, x, y)``.

    A point does not see its two edges, nor a piece of an edge the edges before and
    after it: the two sides of a corner converge, which bounds the stacks there (the
    neighbours' rule), and is no gap.  Along an edge, pieces are bisected while longer
    than half the clearance at their middle (and than half ``first``); a piece
    counts its middle's clearance less half its length, at most what any of its
    points has."""
    from .geometry import next_on_ring, prev_on_ring
    from .select.construct import TURN, _domain_walk, _to_box, contour_segments

    p, m, ring = contour.points, contour.n, contour.ring
    nxt, prv = next_on_ring(ring), prev_on_ring(ring)
    length = contour.edge_lengths()
    segments, arc, _ = contour_segments(contour)
    dom_next, dom_prev = _domain_walk(contour, exterior)
    is_wall = np.zeros(m, dtype=bool)
    is_wall[walls] = True
    # at the points
    own = np.column_stack([np.arange(m), prv])
    wedge = (p[dom_next] - p, p[dom_prev] - p)
    out = segments.clearance(p, arc, ring, own, wedge, np.full(m, reach), TURN)
    if box is not None:  # (the box's sides have no layers of their own)
        out = np.minimum(out, 2.0 * _to_box(p, box))
    out[~is_wall] = np.inf
    k = int(np.argmin(out))
    narrowest = (float(out[k]), *p[k].tolist())
    # along the edges from or to a wall point
    seg = np.flatnonzero(is_wall | is_wall[nxt])
    along = np.where((dom_next == nxt)[:, None], p[nxt] - p, p - p[nxt])
    t0, t1 = np.zeros(len(seg)), np.ones(len(seg))
    while len(seg):
        ell = (t1 - t0) * length[seg]
        tm = (t0 + t1) / 2
        mid = p[seg] + tm[:, None] * (p[nxt[seg]] - p[seg])
        own = np.column_stack([seg, prv[seg], nxt[seg]])
        c = segments.clearance(
            mid, arc[seg] + tm * length[seg], ring[seg], own, (along[seg], -along[seg]),
            reach + ell, TURN,
        )  # fmt: skip
        if box is not None:
            c = np.minimum(c, 2.0 * _to_box(mid, box))
        split = (ell > 0.5 * c) & (ell > 0.5 * first)
        done = ~split
        low = np.maximum(c - 0.5 * ell, 0.0)
        np.minimum.at(out, seg[done], np.where(is_wall[seg[done]], low[done], np.inf))
        np.minimum.at(out, nxt[seg[done]], np.where(is_wall[nxt[seg[done]]], low[done], np.inf))
        if done.any() and c[done].min() < narrowest[0]:
            k = int(np.argmin(np.where(done, c, np.inf)))
            narrowest = (float(c[k]), *mid[k].tolist())
        seg, t0, t1, tm = seg[split], t0[split], t1[split], tm[split]
        seg = np.repeat(seg, 2)
        t0, t1 = np.column_stack([t0, tm]).ravel(), np.column_stack([tm, t1]).ravel()
    return out, narrowest


def build(
    contour: Contour,
    spec: LayerSpec,
    exterior: bool = False,
    box: tuple[float, float, float, float] | None = None,
    max_nodes: int | None = None,
) -> Stacks:
    """The layers of ``spec`` on ``contour`` (``box``: an exterior mesh's far-field
    box, whose sides bound the stacks too; more layer nodes than ``max_nodes`` is a
    :class:`LimitError`)."""
    rings = range(contour.n_rings) if spec.rings is None else spec.rings
    for r in rings:
        if not 0 <= r < contour.n_rings:
            raise OptionError(f"{contour.source}: no ring {r} to put layers on")
    heights = spec.heights()
    full = float(heights[-1])
    p = contour.points
    least = MIN_RELATIVE_EDGE * float(np.abs(p).max())
    if not spec.first > least:
        raise OptionError(
            f"{contour.source}: --first-height {spec.first:g} is under the coordinates' "
            f"resolution ({least:.3g} at this contour's distance from the origin)"
        )
    m = contour.n
    starts = np.asarray(contour.starts)
    rings = list(rings)
    owner_all, dir_all, arc_all = [], [], []
    fans = 0
    per_ring: list = [None] * contour.n_rings
    for r in rings:
        order = _domain_order(contour, r, exterior)
        owner, dirs, ring_fans = _directions(p[order])
        fans += ring_fans
        start = sum(len(o) for o in owner_all)
        per_ring[r] = np.arange(start, start + len(owner))
        owner_all.append(order[owner])
        dir_all.append(dirs)
        q = p[order]
        seg = np.hypot(*(np.roll(q, -1, axis=0) - q).T)
        arc_all.append((np.concatenate([[0.0], np.cumsum(seg)[:-1]])[owner], float(seg.sum())))
    wall = np.concatenate(owner_all).astype(np.int64)
    d = np.concatenate(dir_all).astype(np.float64).reshape(-1, 2)
    if max_nodes is not None and len(wall) * spec.layers > max_nodes:
        raise LimitError(
            f"{contour.source}: {spec.layers} layers on {len(wall):,} stacks are "
            f"{len(wall) * spec.layers:,} nodes, over --max-nodes {max_nodes:,}"
        )
    # other parts of the contour, across the domain, and the box
    near, (width, x, y) = _clearances(
        contour, exterior, box, np.unique(wall), full / GAP_SHARE, spec.first
    )
    if width < 2.0 * spec.first:
        raise SelectionError(
            f"{contour.source}: boundary layers of first height {spec.first:g} do not fit "
            f"near ({x:.6g}, {y:.6g}): the domain is {width:.3g} wide there, under twice "
            "the first height; give a smaller --first-height, or leave that ring out "
            "(--layers-on)"
        )
    thick = _thickness(p, wall, d, per_ring, arc_all, rings, full, near)
    for r in rings:  # (a ring none of whose stacks holds the first height: a small hole)
        most = float(thick[per_ring[r]].max())
        if most < spec.first:
            raise SelectionError(
                f"{contour.source}: boundary layers of first height {spec.first:g} do not "
                f"fit on {contour.ring_name(r)} ({contour.ring_labels[r]}): no stack there can "
                f"be thicker than {most:.3g} (its walls converge or face each other); give a "
                "smaller --first-height, or leave that ring out (--layers-on)"
            )
    share = np.minimum(thick / full, 1.0)
    # nodes and cells
    n_layers = spec.layers
    along = stack_heights(spec, np.minimum(thick, full))
    nodes = p[wall][:, None, :] + along[:, 1:, None] * d[:, None, :]
    nodes = nodes.reshape(-1, 2)

    def node(s: np.ndarray, k: int) -> np.ndarray:
        return wall[s] if k == 0 else m + s * n_layers + (k - 1)

    quads, tris = [], []
    top_rings, top_ids = [], []
    for r in range(contour.n_rings):
        s = per_ring[r]
        if s is None:
            order = np.arange(starts[r], starts[r + 1])
            top_rings.append(p[order])
            top_ids.append(order)
            continue
        t = np.roll(s, -1)
        fan = wall[s] == wall[t]
        for k in range(n_layers):
            cell = np.column_stack([node(s, k), node(t, k), node(t, k + 1), node(s, k + 1)])
            if k == 0:
                tris.append(cell[fan][:, [0, 2, 3]])
                quads.append(cell[~fan])
            else:
                quads.append(cell)
        top = node(s, n_layers)
        top_rings.append(nodes[top - m])
        top_ids.append(top)
    try:  # (validated as any contour: the bounds above keep it simple and apart)
        top_contour = make_contour(
            np.concatenate(top_rings),
            source=f"{contour.source} (the boundary layers' top)",
            ring_starts=np.cumsum([0] + [len(x) for x in top_rings[:-1]]).tolist(),
            ring_labels=[contour.ring_labels[r] for r in range(contour.n_rings)],
        )
    except InputError as exc:  # (its messages name it: the file, then "the ... top")
        raise SelectionError(str(exc)) from None
    return Stacks(
        spec,
        wall,
        d,
        share,
        nodes,
        np.concatenate(quads).astype(np.int64) if quads else np.zeros((0, 4), np.int64),
        np.concatenate(tris).astype(np.int64) if tris else np.zeros((0, 3), np.int64),
        per_ring,
        top_contour,
        np.concatenate(top_ids).astype(np.int64),
        exterior=exterior,
        fans=fans,
        shortened=int((share < 1.0).sum()),
    )


def combine(contour: Contour, stacks: Stacks, core, exterior: bool = False):
    """The mesh of ``contour``: the layer cells of ``stacks`` and ``core``, the mesh of
    ``stacks.top`` (its point ``k`` is ``stacks.top_node[k]``).  Nodes: the contour's
    points, the core's extra boundary nodes on rings without layers, its box nodes, the
    layer nodes, then the core's other nodes; the boundary is the contour's rings (a
    layered ring's edges in the domain's order) and the core's box sides."""
    from .mesh import Mesh

    n, n_top = contour.n, stacks.top.n
    n_layer = len(stacks.nodes)
    layered = np.array([s is not None for s in stacks.rings])
    # the core's extra nodes: on a ring without layers they stay boundary nodes
    extra = np.arange(n_top, n_top + core.n_extra)
    on_line = np.full(len(core.points), -1)
    on_line[core.lines[:, 0]] = core.line_group
    keep_extra = extra[
        (on_line[extra] >= 0) & ~layered[np.minimum(on_line[extra], len(layered) - 1)]
    ]
    inner_extra = np.setdiff1d(extra, keep_extra)
    box_nodes = np.arange(n_top + core.n_extra, n_top + core.n_extra + core.n_box)
    rest = np.arange(n_top + core.n_extra + core.n_box, len(core.points))
    first_layer = n + len(keep_extra) + len(box_nodes)
    new = np.empty(len(core.points), dtype=np.int64)
    top = stacks.top_node
    new[:n_top] = np.where(top < n, top, top - n + first_layer)
    new[keep_extra] = n + np.arange(len(keep_extra))
    new[box_nodes] = n + len(keep_extra) + np.arange(len(box_nodes))
    after = first_layer + n_layer
    new[inner_extra] = after + np.arange(len(inner_extra))
    new[rest] = after + len(inner_extra) + np.arange(len(rest))
    points = np.empty((after + len(inner_extra) + len(rest), 2))
    points[:n] = contour.points
    points[new] = core.points
    points[first_layer:after] = stacks.nodes
    points[:n] = contour.points  # (bit for bit: the wall's points as given)

    def layer_ids(cells: np.ndarray) -> np.ndarray:
        return np.where(cells < n, cells, cells - n + first_layer)

    lines, groups = [], []
    for r in range(contour.n_rings):
        if layered[r]:
            order = _domain_order(contour, r, exterior)
            lines.append(np.column_stack([order, np.roll(order, -1)]))
        else:
            lines.append(new[core.lines[core.line_group == r]])
        groups.append(np.full(len(lines[-1]), r))
    side = core.line_group >= contour.n_rings
    lines.append(new[core.lines[side]])
    groups.append(core.line_group[side])
    return Mesh(
        points,
        np.concatenate([new[core.triangles], layer_ids(stacks.triangles)]),
        np.concatenate(lines).astype(np.int64),
        n_contour=n,
        n_extra=len(keep_extra),
        line_group=np.concatenate(groups).astype(np.int64),
        groups=core.groups,
        n_box=core.n_box,
        quads=layer_ids(stacks.quads),
    )


def columns(stacks: Stacks, mesh):
    """The rays and fans of ``stacks`` (:class:`.quads.Columns`) in the numbering of
    ``mesh``, :func:`combine`'s: the layer nodes after the contour's points and the
    mesh's other boundary nodes."""
    from .quads import Columns

    m, n_layers = mesh.n_contour, stacks.spec.layers
    first_layer = m + mesh.n_extra + mesh.n_box
    count = len(stacks.wall)
    ids = first_layer + np.arange(count * n_layers).reshape(count, n_layers)
    column = np.column_stack([stacks.wall, ids])  # (stack s: its nodes, wall first)
    rays = np.stack([column[:, :-1], column[:, 1:]], axis=2).reshape(-1, 2)
    # a fan: a run of stacks on one wall point (a ring's stacks are consecutive, and a
    # point's too); its first layer's nodes counter-clockwise round it: last stack first
    cut = np.flatnonzero(np.diff(stacks.wall) != 0) + 1
    start = np.concatenate([[0], cut])
    size = np.diff(np.concatenate([start, [count]]))
    fan = size > 1
    starts = np.concatenate([[0], np.cumsum(size[fan])])
    j = np.arange(starts[-1]) - np.repeat(starts[:-1], size[fan])
    order = np.repeat(start[fan] + size[fan] - 1, size[fan]) - j
    return Columns(
        rays.astype(np.int64),
        stacks.wall[start[fan]].astype(np.int64),
        ids[order, 0].astype(np.int64),
        starts.astype(np.int64),
    )


def split_quads(mesh):
    """``mesh`` with each quad as two triangles, along the diagonal whose two triangles'
    smallest angle is larger (the first on a tie)."""
    from dataclasses import replace

    from .quality import measures

    q = mesh.quads
    if not len(q):
        return mesh
    a = np.minimum(
        measures(mesh.points, q[:, [0, 1, 2]])[0], measures(mesh.points, q[:, [0, 2, 3]])[0]
    )
    b = np.minimum(
        measures(mesh.points, q[:, [1, 2, 3]])[0], measures(mesh.points, q[:, [1, 3, 0]])[0]
    )
    other = b > a
    first = np.where(other[:, None], q[:, [1, 2, 3]], q[:, [0, 1, 2]])
    second = np.where(other[:, None], q[:, [1, 3, 0]], q[:, [0, 2, 3]])
    tri = np.concatenate([mesh.triangles, np.column_stack([first, second]).reshape(-1, 3)])
    return replace(mesh, triangles=tri, quads=np.zeros((0, 4), dtype=np.int64))


def summary(stacks: Stacks, mesh) -> dict:
    """What a meshing summary says of the layers: the construction's counts, and the
    measures ``deformesh quality`` takes of the quads of ``mesh`` (the layers joined to
    the rest, before any split: :func:`.quality.layer_report`): the first heights, the
    smallest wall angle (both over the stacks outside fans) and the largest aspect
    ratio."""
    from .quality import layer_report

    measured = layer_report(mesh.points, mesh.quads, mesh.triangles)
    return {
        "layers": stacks.spec.layers,
        "first_height": stacks.spec.first,
        "growth": stacks.spec.growth,
        "stacks": int(len(stacks.wall)),
        "fans": int(stacks.fans),
        "shortened_stacks": int(stacks.shortened),
        "first_height_min": measured.get("first_height_min"),
        "first_height_max": measured.get("first_height_max"),
        "min_wall_angle": measured.get("min_wall_angle"),
        "max_aspect_ratio": measured["max_aspect_ratio"],
        "layer_quads": int(len(stacks.quads)),
        "layer_triangles": int(len(stacks.triangles)),
    }
