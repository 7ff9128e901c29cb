"""Mesh quality measures and the mesh contract.

The contract (README, "The contract") is checked on every mesh written:

1. node ``k`` is contour point ``k``, at exactly its input coordinates;
2. the mesh boundary is the contour: every contour edge is a mesh boundary
   edge, or a chain of boundary edges through extra nodes lying on it;
3. every triangle has signed area > 0 (counter-clockwise, no fold), and every
   quad (boundary layers) is convex and counter-clockwise;
4. the mesh area equals the polygon area to round-off.

(Byte-identical output on reruns is checked by the test suite.)
"""

from __future__ import annotations

import functools

import numpy as np

from .contour import Contour
from .errors import ContractError, InputError
from .geometry import EdgeTable, boundary_edges, directed_boundary, edge_uses, signed_areas
from .mesh import Mesh, as_triangles

#: A background box ``(xmin, ymin, xmax, ymax)``.
Box = tuple[float, float, float, float]

#: Relative tolerance on area conservation (measured: ~1e-15).
AREA_RTOL = 1e-10


def measures(
    points: np.ndarray, tri: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per triangle: ``(smallest angle, largest angle, signed area, radius ratio)``.

    Angles in degrees.  All from the squared edge lengths and the cross
    product: the angle opposite edge ``k`` has ``tan = 2 |cross| / (S - 2 s_k)``
    (law of cosines; ``s_k`` the squared lengths, ``S`` their sum), so the
    smallest angle is opposite the shortest edge and the largest opposite the
    longest, two ``arctan2`` calls instead of three; 1-D arrays throughout (a
    reduction over a length-3 axis is slow on a million triangles).
    ``arctan2`` keeps tiny and near-straight angles accurate.
    """
    x, y = points[tri, 0], points[tri, 1]  # (t, 3) each
    # edge k is opposite corner k: e0 = p2 - p1, e1 = p0 - p2, e2 = p1 - p0
    ex0, ex1, ex2 = x[:, 2] - x[:, 1], x[:, 0] - x[:, 2], x[:, 1] - x[:, 0]
    ey0, ey1, ey2 = y[:, 2] - y[:, 1], y[:, 0] - y[:, 2], y[:, 1] - y[:, 0]
    cross = ex1 * ey2 - ey1 * ex2  # = (p1 - p0) x (p2 - p0)
    twice = np.abs(cross)
    s0, s1, s2 = ex0 * ex0 + ey0 * ey0, ex1 * ex1 + ey1 * ey1, ex2 * ex2 + ey2 * ey2
    total = s0 + s1 + s2
    two = 2 * twice
    smallest = np.degrees(np.arctan2(two, total - 2 * np.minimum(np.minimum(s0, s1), s2)))
    largest = np.degrees(np.arctan2(two, total - 2 * np.maximum(np.maximum(s0, s1), s2)))
    a, b, c = np.sqrt(s0), np.sqrt(s1), np.sqrt(s2)
    with np.errstate(all="ignore"):
        # 2 r_in / r_circ = 2 (A / s) / (a b c / 4 A) = 16 A^2 / (2 s a b c)
        rr = 4.0 * twice * twice / ((a + b + c) * a * b * c)
        far = np.flatnonzero(~np.isfinite(rr) & (twice > 0))
        if len(far):  # (A^2 or a b c beyond a double: the triangle scaled by a power
            # of two, which changes no bit of a ratio that fits)
            k = -np.frexp(np.sqrt(np.maximum(np.maximum(s0[far], s1[far]), s2[far])))[1]
            t = np.ldexp(twice[far], 2 * k)
            a, b, c = np.ldexp(a[far], k), np.ldexp(b[far], k), np.ldexp(c[far], k)
            rr[far] = 4.0 * t * t / ((a + b + c) * a * b * c)
    return smallest, largest, 0.5 * cross, np.nan_to_num(rr)


#: The measures of :func:`report` that a meshing summary (``--json``) carries.
SUMMARY_KEYS = (
    "min_angle",
    "max_angle",
    "smallest_area",
    "mean_radius_ratio",
    "min_radius_ratio",
    "area",
)


def stats(mesh: Mesh) -> dict:
    """Summary numbers of a mesh (JSON-ready): counts, then :data:`SUMMARY_KEYS` (the
    triangles' angles and radius ratios; in a mesh of quads only, the quads' angles and
    no radius ratio), and with quads ``quad_quality`` (:func:`.quads.report`)."""
    out = {
        "nodes": int(mesh.n_nodes),
        "triangles": int(len(mesh.triangles)),
        "boundary_nodes": int(len(mesh.lines)),
        "extra_boundary_nodes": int(mesh.n_extra),
    }
    if len(mesh.triangles):
        r = report(mesh.points, mesh.triangles)
        out.update({k: r[k] for k in SUMMARY_KEYS})
    if len(mesh.quads):  # (the area is every cell's)
        from .quads import report as quad_report

        q = quad_report(mesh.points, mesh.quads, mesh.triangles)
        cells = signed_areas(mesh.points, mesh.split)
        out["quads"] = q["quads"]
        if not len(mesh.triangles):
            out.update(
                min_angle=q["min_angle"],
                max_angle=q["max_angle"],
                smallest_area=float((cells[: q["quads"]] + cells[q["quads"] :]).min()),
                mean_radius_ratio=None,
                min_radius_ratio=None,
            )
        out["area"] = float(cells.sum())
        out["quad_quality"] = {k: v for k, v in q.items() if k not in ("quads",)}
    return out


def check_contract(
    mesh: Mesh, contour: Contour, box: Box | None = None, edges: EdgeTable | None = None
) -> None:
    """Raise :class:`ContractError` naming the first clause ``mesh`` breaks.

    ``box`` (XMIN, YMIN, XMAX, YMAX) marks an exterior mesh: the domain is the
    box minus the contour, and the box sides are boundaries too.  ``edges``:
    :func:`edge_uses` of ``mesh.triangles`` when already counted (the
    triangles do not depend on where the nodes went, so stage 3 counts them
    while the deformation runs).
    """
    src = contour.source
    m = contour.n
    pts, tri = mesh.points, mesh.split
    if len(mesh.quads):
        edges = None  # (counted on the triangles alone: counted below, on these)
    if mesh.n_contour != m or len(pts) < m:
        raise ContractError(f"{src}: mesh has {mesh.n_contour} contour nodes, contour has {m}")
    # 1. contour points are nodes 0..m-1, bit for bit
    same = np.all(pts[:m] == contour.points, axis=1)
    if not same.all():
        k = int(np.argmin(same))
        raise ContractError(
            f"{src}: node {k} is at ({float(pts[k, 0])!r}, {float(pts[k, 1])!r}), "
            f"not at {contour.where(k)}"
        )
    # 3. orientation / folding
    area = signed_areas(pts, tri)
    if len(tri) == 0:
        raise ContractError(f"{src}: the mesh has no triangles")
    if not (area > 0).all():
        t = int(np.argmin(area))
        c = pts[tri[t]].mean(axis=0)
        raise ContractError(
            f"{src}: triangle {t} near ({c[0]:.6g}, {c[1]:.6g}) has signed area {area[t]:.3g}"
        )
    if len(mesh.quads):  # (convex: the other diagonal's triangles turn the same way)
        q = mesh.quads
        other = np.minimum(signed_areas(pts, q[:, [1, 2, 3]]), signed_areas(pts, q[:, [1, 3, 0]]))
        if not (other > 0).all():
            k = int(np.argmin(other))
            c = pts[q[k]].mean(axis=0)
            raise ContractError(f"{src}: quad {k} near ({c[0]:.6g}, {c[1]:.6g}) is not convex")
    used = np.bincount(tri.ravel(), minlength=len(pts))
    if not used.all():  # (a node of no triangle leaves a solver's matrix singular)
        k = int(np.argmin(used))
        raise ContractError(
            f"{src}: node {k} at ({pts[k, 0]:.6g}, {pts[k, 1]:.6g}) is a corner of no triangle"
        )
    # 2. the boundary is exactly the rings (and the box)
    _check_boundary(mesh, contour, box, edge_uses(tri, len(pts)) if edges is None else edges)
    # 4. area conservation
    poly = contour.area
    if box is not None:
        poly = (box[2] - box[0]) * (box[3] - box[1]) - poly
    total = float(area.sum())
    if abs(total - poly) > area_tolerance(contour, poly, box):
        raise ContractError(
            f"{src}: mesh area {total:.17g} differs from the domain's {poly:.17g} "
            f"(relative {abs(total - poly) / poly:.2e})"
        )


def area_tolerance(contour: Contour, area: float, box: Box | None = None) -> float:
    """How far the mesh area may be from the domain's: relative :data:`AREA_RTOL`, plus
    the round-off of placing boundary nodes at these coordinates.

    An extra boundary node is rounded to the nearest double, up to
    ``eps * |x|`` off its edge, which moves area by up to that times the edge
    length: far from the origin (a contour at 1e9) that is the larger term.
    """
    length = float(contour.edge_lengths().sum())
    extent = float(np.abs(contour.points).max())
    if box is not None:
        length += 2 * ((box[2] - box[0]) + (box[3] - box[1]))
        extent = max(extent, *map(abs, box))
    return AREA_RTOL * area + 4 * np.finfo(float).eps * extent * length


def _check_boundary(mesh: Mesh, contour: Contour, box, edges=None) -> None:
    src = contour.source
    n = len(mesh.points)
    lo, hi, fwd, rev = edge_uses(mesh.split, n) if edges is None else edges
    if (fwd + rev > 2).any():
        raise ContractError(f"{src}: an edge is shared by more than two triangles")
    if ((fwd > 1) | (rev > 1)).any():
        k = int(np.argmax((fwd > 1) | (rev > 1)))
        raise ContractError(
            f"{src}: two triangles overlap along the edge from node {lo[k]} to "
            f"node {hi[k]} (both on the same side of it)"
        )
    # directed boundary edges (domain on the left) must equal the line cells
    directed = directed_boundary(lo, hi, fwd, rev)
    lines = mesh.lines
    if len(directed) != len(lines) or not np.array_equal(
        np.unique(directed[:, 0] * n + directed[:, 1]), np.unique(lines[:, 0] * n + lines[:, 1])
    ):
        raise ContractError(
            f"{src}: the mesh boundary ({len(directed)} edges) is not the contour's "
            f"boundary chain ({len(lines)} edges)"
        )
    for r in range(contour.n_rings):
        ring_lines = lines[mesh.line_group == r]
        order = contour.ring_order(r)
        if contour.is_hole(r) != (box is not None):  # domain outside: walked clockwise
            ring_lines = ring_lines[::-1, ::-1]
        _check_chain(mesh, contour, ring_lines, order, r)
    if box is not None:
        _check_box(mesh, contour, box)


def _check_chain(
    mesh: Mesh, contour: Contour, lines: np.ndarray, order: np.ndarray, r: int
) -> None:
    """One ring's lines: a closed chain through its points in ``order``, extras on edges."""
    src, pts, m = contour.source, mesh.points, contour.n
    name = contour.ring_name(r)
    if len(lines) == 0 or not np.array_equal(lines[:, 1], np.roll(lines[:, 0], -1)):
        raise ContractError(f"{src}: the {name} boundary edges do not form one closed chain")
    ring = lines[:, 0]
    on_contour = ring < m
    seq = ring[on_contour]
    start = int(np.flatnonzero(seq == order[0])[0]) if (seq == order[0]).any() else -1
    if len(seq) != len(order) or start < 0 or not np.array_equal(np.roll(seq, -start), order):
        raise ContractError(f"{src}: the {name} boundary does not visit its points in order")
    extra_idx = np.flatnonzero(~on_contour)
    if len(extra_idx):
        if (ring[extra_idx] >= m + mesh.n_extra).any():
            raise ContractError(
                f"{src}: the {name} boundary has a node that is not an extra boundary node"
            )
        pos = np.flatnonzero(on_contour)
        before = ring[pos[np.searchsorted(pos, extra_idx) - 1]]
        nxt = np.searchsorted(pos, extra_idx) % len(pos)
        after = ring[pos[nxt]]
        a, b, x = pts[before], pts[after], pts[ring[extra_idx]]
        ab = b - a
        t = ((x - a) * ab).sum(axis=1) / (ab * ab).sum(axis=1)
        dist = np.linalg.norm(a + t[:, None] * ab - x, axis=1)
        scale = float(np.abs(contour.points).max() + np.ptp(contour.points))
        bad = (dist > 1e-12 * scale) | (t <= 0) | (t >= 1)
        if bad.any():
            k = int(np.argmax(bad))
            raise ContractError(
                f"{src}: extra boundary node {ring[extra_idx[k]]} is off the contour edge "
                f"from {contour.where(int(before[k]))} (distance {dist[k]:.3g})"
            )


def _check_box(mesh: Mesh, contour: Contour, box) -> None:
    """The box sides: a closed counter-clockwise chain on the box, each side in its group."""
    src, pts = contour.source, mesh.points
    groups = list(mesh.groups)
    side_lines = mesh.line_group >= contour.n_rings
    lines = mesh.lines[side_lines]
    if len(lines) == 0 or not np.array_equal(lines[:, 1], np.roll(lines[:, 0], -1)):
        raise ContractError(f"{src}: the box boundary edges do not form one closed chain")
    x0, y0, x1, y1 = box
    at = {"bottom": (1, y0), "right": (0, x1), "top": (1, y1), "left": (0, x0)}
    for g, (axis, value) in at.items():
        sel = mesh.line_group[side_lines] == groups.index(g)
        ends = pts[lines[sel].ravel(), axis]
        if not sel.any() or not np.all(ends == value):
            raise ContractError(
                f"{src}: the {g} boundary does not lie on the box side at {'xy'[axis]} = {value:g}"
            )


#: Bin edges of the radius-ratio histogram in quality reports.
RR_BINS = np.linspace(0.0, 1.0, 11)


#: Triangles measured at a time by :func:`report`: its temporaries stay small (a
#: tenth of what one piece takes at a million triangles) and fit the caches better.
CHUNK = 1 << 17


def report(points: np.ndarray, tri: np.ndarray) -> dict:
    """What ``deformesh quality`` prints: angles, areas, radius ratios and their histogram."""
    if len(tri) == 0:
        raise InputError("no triangles to measure")
    lo_angle, hi_angle, below_20, folded, area_sum, rr_sum, rr_min = (
        np.inf,
        -np.inf,
        0,
        0,
        0.0,
        0.0,
        np.inf,
    )
    counts = np.zeros(len(RR_BINS) - 1, dtype=np.int64)
    least = (np.inf, 0)
    for start in range(0, len(tri), CHUNK):
        smallest, largest, area, rr = measures(points, tri[start : start + CHUNK])
        lo_angle, hi_angle = min(lo_angle, smallest.min()), max(hi_angle, largest.max())
        below_20 += int(np.count_nonzero(smallest < 20))
        t = int(np.argmin(area))
        least = min(least, (area[t], start + t))  # the first smallest, as np.argmin
        folded += int(np.count_nonzero(area <= 0))
        area_sum += area.sum()
        rr_sum += rr.sum()
        rr_min = min(rr_min, rr.min())
        counts += np.histogram(rr, bins=RR_BINS)[0]
    c = points[tri[least[1]]].mean(axis=0)
    return {
        "nodes": int(len(points)),
        "triangles": int(len(tri)),
        "min_angle": float(lo_angle),
        "max_angle": float(hi_angle),
        "angles_below_20": below_20,
        "smallest_area": float(least[0]),
        "smallest_area_at": [float(c[0]), float(c[1])],
        "folded": folded,
        "area": float(area_sum),
        "mean_radius_ratio": float(rr_sum / len(tri)),
        "min_radius_ratio": float(rr_min),
        "radius_ratio_histogram": {
            "edges": [round(float(e), 2) for e in RR_BINS],
            "counts": [int(k) for k in counts],
        },
    }


def mesh_for_contour(
    points: np.ndarray, tri: np.ndarray, contour: Contour, quads: np.ndarray | None = None
) -> tuple[Mesh, Box | None]:
    """Rebuild a :class:`Mesh` read from a file (with its ``quads``, if any), for
    :func:`check_contract` against ``contour``.

    The boundary is walked from each ring's first point; boundary edges left
    over mean an exterior mesh if they all lie on the mesh's bounding box (the
    box is returned, else ``None``).  Raises :class:`ContractError` when a
    ring's first point is not on the boundary or a walk does not close.
    """
    src, m, n = contour.source, contour.n, len(points)
    if n < m:
        raise ContractError(f"{src}: the mesh has {n} nodes, fewer than the contour's {m} points")
    quads = np.zeros((0, 4), dtype=np.int64) if quads is None else quads
    edges = boundary_edges(as_triangles(tri, quads), n)
    nxt = np.full(n, -1, dtype=np.int64)
    starts, counts = np.unique(edges[:, 0], return_counts=True)
    if (counts > 1).any():
        k = int(starts[np.argmax(counts > 1)])
        raise ContractError(
            f"{src}: the boundary touches itself at node {k} "
            f"({points[k, 0]:.6g}, {points[k, 1]:.6g})"
        )
    nxt[edges[:, 0]] = edges[:, 1]
    used = np.zeros(n, dtype=bool)
    lines, group = [], []

    def walk(start, what):
        chain = [start]
        while True:
            k = int(nxt[chain[-1]])
            if k < 0 or len(chain) > len(edges):
                raise ContractError(f"{src}: the boundary through {what} does not close")
            if k == start:
                return np.array(chain)
            chain.append(k)

    for r in range(contour.n_rings):
        start = int(contour.ring_order(r)[0])
        if nxt[start] < 0:
            raise ContractError(f"{src}: {contour.where(start)} is not on the mesh boundary")
        if used[start]:
            raise ContractError(
                f"{src}: {contour.ring_name(r)} shares its boundary with another ring"
            )
        ring = walk(start, contour.where(start))
        used[ring] = True
        lines.append(np.column_stack([ring, np.roll(ring, -1)]))
        group.append(np.full(len(ring), r))
    on_rings = np.concatenate([ln[:, 0] for ln in lines])
    extra = on_rings[on_rings >= m]
    n_extra = int(extra.max() - m + 1) if len(extra) else 0
    names = [contour.ring_name(r) for r in range(contour.n_rings)]
    rest = edges[~used[edges[:, 0]]]
    box = None
    lo, hi = points.min(axis=0), points.max(axis=0)
    ends = points[rest.ravel()]
    if len(rest) and np.all((ends == lo).any(axis=1) | (ends == hi).any(axis=1)):
        box = (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))
        corner = rest[np.all(points[rest[:, 0]] == lo, axis=1), 0]
        ring = walk(int(corner[0]) if len(corner) else int(rest[0, 0]), "the box")
        seg = np.column_stack([ring, np.roll(ring, -1)])
        a, b = points[seg[:, 0]], points[seg[:, 1]]
        side = np.select(
            [
                (a[:, 1] == lo[1]) & (b[:, 1] == lo[1]),
                (a[:, 0] == hi[0]) & (b[:, 0] == hi[0]),
                (a[:, 1] == hi[1]) & (b[:, 1] == hi[1]),
            ],
            [0, 1, 2],
            3,
        )
        lines.append(seg)
        group.append(len(names) + side)
        names += ["bottom", "right", "top", "left"]
    mesh = Mesh(
        points,
        tri,
        np.concatenate(lines),
        n_contour=m,
        n_extra=n_extra,
        line_group=np.concatenate(group),
        groups=tuple(names),
        quads=quads,
    )
    return mesh, box


#: A stack goes on up while its next edge turns from its first by under this (radians):
#: a stack's nodes lie on one line, up to round-off.
STRAIGHT = 1e-6


def layer_report(
    points: np.ndarray,
    quads: np.ndarray,
    tri: np.ndarray,
    first: float | None = None,
    walls: np.ndarray | None = None,
) -> dict:
    """What ``deformesh quality`` says of a mesh's quads (boundary layers, corners in
    deformesh's order: 0 and 1 on the side nearer the wall, 3 above 0 and 2 above 1).

    ``non_convex``: quads not strictly convex and counter-clockwise; the aspect
    ratio (the longer over the shorter of a quad's mean widths along and across the
    layers); per *stack* (a boundary node with one node above it; a fan's point,
    which has several, is left out, as is one whose node above is a boundary
    neighbour; ``walls``: the nodes a stack may stand on, say the contour's rings',
    or any boundary node), on up while each next node is the
    only one above and on the stack's line (within :data:`STRAIGHT`): its first
    height, its wall angle (between the first layer edge and the two boundary edges
    at the node, 90 at best) and the growth between its layers (each layer's height
    over the one below).  With ``first``: how many first heights are within 1% of
    it, and the largest relative difference."""
    from .quads import report as quad_report

    q = quads
    n = len(points)
    cells = quad_report(points, q, tri) if len(q) else {}

    def dist(a, b):
        d = points[a] - points[b]
        return np.hypot(d[:, 0], d[:, 1])

    # the stacks: each node's node above; a node with two is a fan's
    pairs = np.unique(np.concatenate([q[:, [0, 3]], q[:, [1, 2]]]), axis=0)
    lower, count = np.unique(pairs[:, 0], return_counts=True)
    above = np.full(n, -1, dtype=np.int64)
    single = lower[count == 1]
    above[pairs[np.isin(pairs[:, 0], single), 0]] = pairs[np.isin(pairs[:, 0], single), 1]
    lines = boundary_edges(as_triangles(tri, q), n)
    nxt = np.full(n, -1, dtype=np.int64)
    prv = np.full(n, -1, dtype=np.int64)
    nxt[lines[:, 0]], prv[lines[:, 1]] = lines[:, 1], lines[:, 0]
    leaves = (above >= 0) & (nxt != above) & (prv != above)  # (not along the boundary)
    wall = np.flatnonzero((nxt >= 0) & leaves & (True if walls is None else walls))
    out = {
        "quads": int(len(q)),
        "non_convex": cells.get("non_convex", 0),
        "max_aspect_ratio": cells.get("max_aspect_ratio"),
        "mean_aspect_ratio": cells.get("mean_aspect_ratio"),
        "stacks": int(len(wall)),
        "fans": int(np.count_nonzero(np.isin(lower[count > 1], lines[:, 0]))),
    }
    if not len(wall):
        return out
    h1 = dist(above[wall], wall)
    up = points[above[wall]] - points[wall]

    def angle(t: np.ndarray) -> np.ndarray:
        c = np.abs((t * up).sum(axis=1)) / (np.hypot(t[:, 0], t[:, 1]) * h1)
        return np.degrees(np.arccos(np.clip(c, 0.0, 1.0)))

    wall_angle = np.minimum(
        angle(points[nxt[wall]] - points[wall]), angle(points[prv[wall]] - points[wall])
    )
    growth_lo, growth_hi = np.inf, -np.inf
    cur, below, line = above[wall], h1, up / h1[:, None]
    while True:
        nxt_up = above[cur]
        step = points[np.maximum(nxt_up, 0)] - points[cur]
        h = np.hypot(step[:, 0], step[:, 1])
        with np.errstate(divide="ignore", invalid="ignore"):
            turn = np.abs(step[:, 0] * line[:, 1] - step[:, 1] * line[:, 0]) / h
        go = (nxt_up >= 0) & ((step * line).sum(axis=1) > 0) & (turn < STRAIGHT)
        if not go.any():
            break
        ratio = h[go] / below[go]
        growth_lo, growth_hi = min(growth_lo, ratio.min()), max(growth_hi, ratio.max())
        cur, below, line = nxt_up[go], h[go], line[go]
    out.update(
        first_height_min=float(h1.min()),
        first_height_max=float(h1.max()),
        min_wall_angle=float(wall_angle.min()),
        growth_min=None if growth_lo == np.inf else float(growth_lo),
        growth_max=None if growth_hi == -np.inf else float(growth_hi),
    )
    if first is not None:
        off = np.abs(h1 - first) / first
        out["first_height_within_1pct"] = int(np.count_nonzero(off <= 0.01))
        out["first_height_max_difference"] = float(off.max())
    return out


def _ring_nodes(mesh: Mesh, contour: Contour) -> np.ndarray:
    """Which nodes of ``mesh`` (:func:`mesh_for_contour`'s) lie on ``contour``'s rings."""
    on = np.zeros(mesh.n_nodes, dtype=bool)
    on[mesh.lines[mesh.line_group < contour.n_rings].ravel()] = True
    return on


def assess(
    points: np.ndarray,
    tri: np.ndarray,
    contour: Contour | None = None,
    quads: np.ndarray | None = None,
    first: float | None = None,
) -> tuple[dict, str | None]:
    """:func:`report` plus the contract verdict: ``(report, problem or None)``.

    Folded triangles (and quads not convex) are a problem with or without a contour;
    with one, the whole contract is checked (:func:`mesh_for_contour`,
    :func:`check_contract`).  ``quads``: the mesh's quads, measured by
    :func:`.quads.report` (``quad_quality``) and, with ``first`` (the first height of
    boundary layers), their stacks by :func:`layer_report` (``layers``); the angle
    measures at the top level are the triangles'.
    """
    quads = np.zeros((0, 4), dtype=np.int64) if quads is None else quads
    rep = report(points, tri) if len(tri) else {"nodes": int(len(points)), "triangles": 0}
    problem = None

    @functools.cache
    def walked() -> tuple[tuple[Mesh, Box | None] | None, str | None]:
        """The boundary walked along the contour's rings (once), or why it cannot be."""
        try:
            return mesh_for_contour(points, tri, contour, quads), None
        except ContractError as exc:
            return None, str(exc)

    if len(quads):
        from .quads import report as quad_report

        q = quad_report(points, quads, tri)
        rep["quads"] = q.pop("quads")
        rep["quad_quality"] = q
        if first is not None:
            walk = walked()[0] if contour is not None else None
            walls = None if walk is None else _ring_nodes(walk[0], contour)
            rep["layers"] = layer_report(points, quads, tri, first, walls)
        rep["area"] = float(signed_areas(points, as_triangles(tri, quads)).sum())
        if q["non_convex"]:
            problem = f"{q['non_convex']} quad(s) not convex"
    if rep.get("folded"):  # checked first: a fold also breaks the boundary walk
        x, y = rep["smallest_area_at"]
        problem = (
            f"{rep['folded']} folded triangle(s); the worst, near ({x:.6g}, {y:.6g}), "
            f"has signed area {rep['smallest_area']:.3g}"
        )
    rep["contract"] = "unchecked (no --contour)"
    if contour is not None:
        rep["contour"] = contour.source
        if problem is None:
            walk, problem = walked()
            if walk is not None:
                try:
                    check_contract(walk[0], contour, walk[1])
                    rep["exterior"] = walk[1] is not None
                except ContractError as exc:
                    problem = str(exc)
        rep["contract"] = f"violated: {problem}" if problem else "ok"
    return rep, problem
