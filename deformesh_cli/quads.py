"""Quadrilateral cells from a triangle mesh (``--cells``).

``quad``: pairs of neighbouring triangles become quads, chosen by a matching over
the whole mesh (:func:`recombine`); ``quad-only``: every cell split into quads
(:func:`subdivide`), which puts a node at the middle of every edge, the boundary's
included.  Neither moves a node: the contour's points stay the boundary's (with
``quad-only``, every second boundary node).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .errors import ContractError
from .geometry import signed_areas, unique_inverse
from .mesh import Mesh

#: ``--cells``: triangles only (the mesh as built), quads where a pair of triangles
#: makes a good one, or quads only.
CELLS = ("tri", "quad", "quad-only")


def corner_terms(points: np.ndarray, quads: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per quad corner (``(q, 4)`` each): the cross and dot products of the two edges
    leaving it (to the next corner, then to the previous one), and the product of
    their lengths.  The corner's angle is ``atan2(cross, dot)``, its scaled Jacobian
    ``cross / lengths``."""
    p = points[quads]  # (q, 4, 2)
    nxt = np.roll(p, -1, axis=1) - p
    prv = np.roll(p, 1, axis=1) - p
    cross = nxt[..., 0] * prv[..., 1] - nxt[..., 1] * prv[..., 0]
    dot = nxt[..., 0] * prv[..., 0] + nxt[..., 1] * prv[..., 1]
    lengths = np.hypot(nxt[..., 0], nxt[..., 1]) * np.hypot(prv[..., 0], prv[..., 1])
    return cross, dot, lengths


def good(points: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """Whether each quad is one :func:`recombine` keeps: every corner's angle strictly
    between 45 and 135 degrees (``|dot| < cross``: exact in floating point for the
    grid's own right-angled triangles, whose 45-degree parallelograms are left out)."""
    cross, dot, _ = corner_terms(points, quads)
    return (np.abs(dot) < cross).all(axis=1)


def scaled_jacobian(points: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """Each quad's smallest scaled Jacobian: the sine of its corner angle farthest from
    a right angle (1 for a rectangle, <= 0 for a quad that is not convex)."""
    cross, _, lengths = corner_terms(points, quads)
    return _smallest_sine(cross, lengths)


def _smallest_sine(cross: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.nan_to_num(cross / lengths).min(axis=1)


def candidates(points: np.ndarray, tri: np.ndarray) -> tuple[np.ndarray, ...]:
    """The pairs of triangles across an interior edge whose union is a good quad
    (:func:`good`): ``(first, second, quads)``, the quads counter-clockwise from the
    first triangle's corner opposite the shared edge, in the order of the edges sorted
    by their nodes."""
    t = len(tri)
    # edge k of a triangle is opposite its corner k
    edges = np.concatenate([tri[:, [1, 2]], tri[:, [2, 0]], tri[:, [0, 1]]])
    owner = np.tile(np.arange(t, dtype=np.int64), 3)
    corner = np.repeat(np.arange(3, dtype=np.int64), t)
    key = np.sort(edges, axis=1)
    order = np.lexsort((key[:, 1], key[:, 0]))
    k = key[order]
    same = np.flatnonzero((k[1:] == k[:-1]).all(axis=1))
    a, b = order[same], order[same + 1]
    ta, ca, tb, cb = owner[a], corner[a], owner[b], corner[b]
    quads = np.stack(
        [tri[ta, ca], tri[ta, (ca + 1) % 3], tri[tb, cb], tri[ta, (ca + 2) % 3]], axis=1
    )
    keep = good(points, quads)
    return ta[keep], tb[keep], quads[keep]


#: The matching's weights are rounded to this many bits after the point (integers
#: to its solver: :func:`best_matching`).
WEIGHT_BITS = 20


def best_matching(n: int, a: np.ndarray, b: np.ndarray, w: np.ndarray) -> np.ndarray:
    """A matching of the graph on nodes ``0 .. n-1`` with edges ``(a, b)`` of weights
    ``w > 0``: the indices of the edges taken.

    The matching problem's linear relaxation is solved exactly, as an assignment on
    the graph's bipartite double cover (each node a row and a column; edge ``(a, b)``
    the entries ``(a, b)`` and ``(b, a)``, a node left single its diagonal entry):
    scipy's sparse Jonker-Volgenant solver.  Its optimum is a permutation whose cycles
    of two are matched pairs and whose fixed points are single nodes; a longer cycle
    is a half-integral part, which is rounded to its best matching (every second edge
    of an even cycle, and of an odd one the best leaving one node single).  Where no
    cycle is longer than two, the matching is a best one; each longer odd cycle costs
    at most one edge's weight.

    The weights are rounded to multiples of ``2^-WEIGHT_BITS`` and scaled to integers
    first: the solver's arithmetic on them is then exact, so it ends (on fractions its
    reduction step can lower a price by an amount lost to round-off, and loop), and
    gives the same matching on every machine."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import min_weight_full_bipartite_matching

    m = len(a)
    if m == 0:
        return np.zeros(0, dtype=np.int64)
    nodes = np.arange(n, dtype=np.int64)
    rows = np.concatenate([a, b, nodes])
    cols = np.concatenate([b, a, nodes])
    # (weights must be non-zero: one unit more each, the same for every full assignment)
    unit = float(2**WEIGHT_BITS)
    w = np.round(np.asarray(w, dtype=np.float64) * unit)
    weight = np.concatenate([unit + w, unit + w, np.full(n, unit)])
    biadj = sp.csr_array((weight, (rows, cols)), shape=(n, n))
    r, c = min_weight_full_bipartite_matching(biadj, maximize=True)
    sigma = np.empty(n, dtype=np.int64)
    sigma[r] = c
    # the edge of each node's entry (-1: single), by its (row, column) key
    keys = np.concatenate([a * n + b, b * n + a])
    order = np.argsort(keys)
    at = np.searchsorted(keys[order], nodes * n + sigma)
    used = np.where(sigma == nodes, -1, order[np.minimum(at, 2 * m - 1)] % m)
    pairs = (sigma != nodes) & (sigma[sigma] == nodes) & (nodes < sigma)
    taken = [used[pairs]]
    longer = np.flatnonzero((sigma != nodes) & (sigma[sigma] != nodes))
    seen = np.zeros(n, dtype=bool)
    for start in longer.tolist():
        if seen[start]:
            continue
        cycle = [start]
        seen[start] = True
        v = int(sigma[start])
        while v != start:
            cycle.append(v)
            seen[v] = True
            v = int(sigma[v])
        taken.append(_round_cycle(used[cycle], w))
    return np.sort(np.concatenate(taken))


def _round_cycle(edges: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The best matching among the edges of one cycle (``edges[i]`` joins its nodes
    ``i`` and ``i + 1``): every second edge on an even cycle; on an odd one, every
    second edge after the node left single, that node chosen for the largest weight
    (the first such)."""
    k = len(edges)
    if k % 2 == 0:
        even, odd = edges[0::2], edges[1::2]
        return even if w[even].sum() >= w[odd].sum() else odd
    # node ``s`` left out: the k // 2 edges s + 1, s + 3, ... (mod k), summed for every
    # ``s`` at once from running sums of every second weight around the cycle, twice
    twice = np.tile(w[edges], 2)
    first = np.arange(k) + 1
    total = np.empty(k)
    for parity in (0, 1):
        run = np.concatenate([[0.0], np.cumsum(twice[parity::2])])
        on = first % 2 == parity
        start = first[on] // 2
        total[on] = run[start + k // 2] - run[start]
    single = int(np.argmax(total))  # (the first of the best)
    return edges[(single + 1 + 2 * np.arange(k // 2)) % k]


def recombine(mesh: Mesh) -> tuple[Mesh, int]:
    """``mesh`` with pairs of its triangles made quads (its own quads kept): of the pairs
    whose union is a good quad (:func:`candidates`), a matching over the whole mesh
    (:func:`best_matching`) weighted by each quad's smallest scaled Jacobian
    (:func:`scaled_jacobian`, above ``sin 45`` for every candidate, so two quads always
    outweigh one).  Returns the mesh and the number of quads made."""
    tri = mesh.triangles
    a, b, quads = candidates(mesh.points, tri)
    w = scaled_jacobian(mesh.points, quads)
    taken = best_matching(len(tri), a, b, w)
    single = np.ones(len(tri), dtype=bool)
    single[a[taken]] = single[b[taken]] = False
    out = dataclasses.replace(
        mesh, triangles=tri[single], quads=np.concatenate([mesh.quads, quads[taken]])
    )
    return out, int(len(taken))


@dataclasses.dataclass(frozen=True)
class Columns:
    """What :func:`subdivide` keeps of a boundary layer's cells.

    ``rays`` ((k, 2) node pairs): the layer edges leaving the wall, kept whole, so
    each layer keeps its height.  ``fans``: each fan's wall node ``wall[f]`` and its
    first layer's nodes ``nodes[starts[f]:starts[f + 1]]`` (``a_1 .. a_m``, ``m >= 3``)
    counter-clockwise round it; the mesh's triangles ``(w, a_i, a_(i+1))`` are the
    fan's first cells."""

    rays: np.ndarray
    wall: np.ndarray
    nodes: np.ndarray
    starts: np.ndarray


def subdivide(
    mesh: Mesh, box_groups: tuple[str, ...] = (), columns: Columns | None = None
) -> tuple[Mesh, int]:
    """``mesh`` with every cell split into quads: a node at the middle of every edge and
    at the centre of every cell (a triangle's centroid, a quad's corner average), each
    triangle into three quads and each quad into four, all counter-clockwise and
    convex (a triangle's pieces: its centroid is inside; a quad's: the images of the
    unit square's quarters under its bilinear map, which a convex quad keeps convex).

    With a boundary layer's ``columns`` its rays stay whole: a quad between two rays
    is split in two through the middles of its other two sides (the segment between
    two points of a convex quad's opposite sides leaves two convex quads), and a
    fan's first cells, triangles ``(w, a_i, a_(i+1))``, become ``2 m - 3`` quads
    (:func:`_fan_quads`).

    Every boundary edge gets a middle node too (a mesh of quads only has an even
    number of boundary edges).  Numbering as :class:`.mesh.Mesh` wants: the contour's
    points first, then the other ring nodes (the middles among them) in boundary
    order, then the box sides' (``box_groups``), then the interior nodes.  Point data
    is carried linearly.  Returns the mesh and the number of boundary nodes added."""
    pts, tri, quads = mesh.points, mesh.triangles, mesh.quads
    n = mesh.n_nodes
    sides = np.concatenate(
        [
            tri[:, [0, 1]],
            tri[:, [1, 2]],
            tri[:, [2, 0]],
            *(quads[:, [k, (k + 1) % 4]] for k in range(4)),
        ]
    )
    key = np.sort(sides, axis=1)
    code, side_edge = unique_inverse(key[:, 0] * (n + 1) + key[:, 1])  # (sorted)
    edges = np.column_stack([code // (n + 1), code % (n + 1)])
    whole = np.zeros(len(edges), dtype=bool)
    if columns is not None:
        rays = np.sort(columns.rays, axis=1)
        whole[np.searchsorted(code, rays[:, 0] * (n + 1) + rays[:, 1])] = True
    split = np.flatnonzero(~whole)
    ne = len(split)
    # provisional numbering: old nodes, edge middles, cell centres, fans' ray middles
    mid = np.full(len(edges), -1, dtype=np.int64)
    mid[split] = n + np.arange(ne)
    side_mid = mid[side_edge]
    nt, nq = len(tri), len(quads)
    t_mid = side_mid[: 3 * nt].reshape(3, nt).T  # (middle of 01, 12, 20)
    q_mid = side_mid[3 * nt :].reshape(4, nq).T  # (middle of 01, 12, 23, 30)
    fan_tri = (t_mid < 0).any(axis=1)
    four = (q_mid >= 0).all(axis=1)
    two = ~four
    if ((t_mid[fan_tri] >= 0).sum(axis=1) != 1).any() or not _opposite_whole(q_mid[two]):
        raise ContractError(
            "the boundary layers' edges leaving the wall bound a cell that is neither "
            "a layer's nor a fan's first"
        )
    tri_g, t_mid_g = tri[~fan_tri], t_mid[~fan_tri]
    quad_f, q_mid_f = quads[four], q_mid[four]
    nc = len(tri_g) + len(quad_f)
    tc = n + ne + np.arange(len(tri_g))
    qc = n + ne + len(tri_g) + np.arange(len(quad_f))
    cells = []
    for k in range(3):  # corner k, the middle after it, the centre, the middle before it
        cells.append(np.stack([tri_g[:, k], t_mid_g[:, k], tc, t_mid_g[:, (k + 2) % 3]], axis=1))
    for k in range(4):
        cells.append(np.stack([quad_f[:, k], q_mid_f[:, k], qc, q_mid_f[:, (k + 3) % 4]], axis=1))
    if two.any():  # (columns: sides 1 and 3 whole, after turning those with 0 and 2)
        q, qm = quads[two], q_mid[two]
        turn = qm[:, 0] < 0
        q = np.where(turn[:, None], np.roll(q, -1, axis=1), q)
        qm = np.where(turn[:, None], np.roll(qm, -1, axis=1), qm)
        cells.append(np.stack([q[:, 0], qm[:, 0], qm[:, 2], q[:, 3]], axis=1))
        cells.append(np.stack([qm[:, 0], q[:, 1], q[:, 2], qm[:, 2]], axis=1))
    fan_ends = np.zeros((0, 2), dtype=np.int64)
    if columns is not None and len(columns.wall):

        def mids(u: np.ndarray, v: np.ndarray) -> np.ndarray:
            lo, hi = np.minimum(u, v), np.maximum(u, v)
            return mid[np.searchsorted(code, lo * (n + 1) + hi)]

        fan_cells, fan_ends = _fan_quads(columns, mids, n + ne + nc)
        cells.append(fan_cells)
    new_quads = np.concatenate(cells)
    ends = np.concatenate([edges[split], fan_ends])  # (the middles, in their order)

    def carried(v: np.ndarray) -> np.ndarray:
        """A per-node array at the new nodes too: the middles' the mean of their ends',
        the centres' that of their cell's corners."""
        middle = 0.5 * (v[ends[:, 0]] + v[ends[:, 1]])
        at = [v, middle[:ne], v[tri_g].mean(axis=1), v[quad_f].mean(axis=1), middle[ne:]]
        return np.concatenate(at)

    new_pts = carried(pts)
    # the boundary: each line split at its middle
    line_key = np.sort(mesh.lines, axis=1)
    line_mid = mid[np.searchsorted(code, line_key[:, 0] * (n + 1) + line_key[:, 1])]
    lines = np.stack([mesh.lines[:, 0], line_mid, line_mid, mesh.lines[:, 1]], axis=1).reshape(
        -1, 2
    )
    groups = np.repeat(mesh.line_group, 2)
    # renumbered: contour points, ring nodes, box nodes, the rest
    box_ids = [g for g, name in enumerate(mesh.groups) if name in box_groups]
    on_box = np.isin(groups, box_ids)
    m = mesh.n_contour
    ring_walk = lines[~on_box, 0]
    box_walk = lines[on_box, 0]
    ring_extra = _first_seen(ring_walk[ring_walk >= m])
    box_nodes = _first_seen(box_walk[box_walk >= m])
    box_nodes = box_nodes[~np.isin(box_nodes, ring_extra)]
    total = len(new_pts)
    placed = np.zeros(total, dtype=bool)
    placed[:m] = True
    placed[ring_extra] = placed[box_nodes] = True
    perm = np.concatenate([np.arange(m), ring_extra, box_nodes, np.flatnonzero(~placed)])
    inv = np.empty(total, dtype=np.int64)
    inv[perm] = np.arange(total)
    data = {name: carried(v)[perm] for name, v in mesh.point_data.items()}
    out = Mesh(
        new_pts[perm],
        np.zeros((0, 3), dtype=np.int64),
        inv[lines],
        n_contour=m,
        n_extra=len(ring_extra),
        line_group=groups,
        groups=mesh.groups,
        n_box=len(box_nodes),
        point_data=data,
        quads=inv[new_quads],
    )
    return out, int(len(mesh.lines))


def _opposite_whole(q_mid: np.ndarray) -> bool:
    """Whether each quad with whole sides (middle -1) has exactly two, opposite."""
    w = q_mid < 0
    return bool(
        (
            (w[:, 0] & w[:, 2] & ~w[:, 1] & ~w[:, 3]) | (w[:, 1] & w[:, 3] & ~w[:, 0] & ~w[:, 2])
        ).all()
    )


def _fan_quads(columns: Columns, mids, first: int) -> tuple[np.ndarray, np.ndarray]:
    """The quads of each fan's first cells, numbering new nodes from ``first``.

    The fan's wall node ``w``, its first layer's nodes ``a_1 .. a_m`` round it and the
    middles ``b_i`` of their edges ``a_i a_(i+1)`` (split with the cells above) bound
    it; a node ``c_i`` at the middle of each inner ray ``w a_i`` (``1 < i < m``) gives

        (w, a_1, b_1, c_2), (c_i, b_(i-1), a_i, b_i), (w, c_i, b_i, c_(i+1)),
        (w, c_(m-1), b_(m-1), a_m),

    ``2 m - 3`` quads whose angles, the ``a_i`` on a circle round ``w`` at a fan's
    steps ``delta`` (10 to 15 degrees), lie between ``delta`` and ``180 - delta``:
    the fan's triangles' own corner at ``w``.  Returns the quads and, per new node,
    the two nodes it is the middle of."""
    a, starts = columns.nodes, columns.starts
    m = np.diff(starts)
    fan = np.repeat(np.arange(len(m)), m)
    i = np.arange(len(a)) - starts[fan]  # (0-based place in its fan)
    w = columns.wall[fan]
    last = i == m[fan] - 1
    b = np.full(len(a), -1, dtype=np.int64)
    b[~last] = mids(a[~last], a[np.flatnonzero(~last) + 1])
    inner = (i > 0) & ~last
    c = np.full(len(a), -1, dtype=np.int64)
    c[inner] = first + np.arange(int(inner.sum()))
    j0 = starts[:-1]
    jl = starts[1:] - 1
    jk = np.flatnonzero(inner)
    jb = np.flatnonzero((i > 0) & (i < m[fan] - 2))
    quads = np.concatenate(
        [
            np.stack([columns.wall, a[j0], b[j0], c[j0 + 1]], axis=1),
            np.stack([c[jk], b[jk - 1], a[jk], b[jk]], axis=1),
            np.stack([w[jb], c[jb], b[jb], c[jb + 1]], axis=1),
            np.stack([columns.wall, c[jl - 1], b[jl - 1], a[jl]], axis=1),
        ]
    )
    return quads, np.stack([w[inner], a[inner]], axis=1)


def _first_seen(nodes: np.ndarray) -> np.ndarray:
    """``nodes`` without repeats, in the order each first appears."""
    _, at = np.unique(nodes, return_index=True)
    return nodes[np.sort(at)]


def report(points: np.ndarray, quads: np.ndarray, tri: np.ndarray) -> dict:
    """What ``quality`` says of a mesh's quads: their count, how many are not strictly
    convex and counter-clockwise, their smallest and largest corner angles, their
    smallest scaled Jacobian, their aspect ratios (the longer over the shorter of the
    mean widths between opposite sides) and the share of the mesh's area in them."""
    q = quads
    cross, dot, lengths = corner_terms(points, q)
    angle = np.degrees(np.arctan2(cross, dot)) % 360.0
    # a corner's cross product is twice the area of the triangle it makes with its two
    # neighbours: the four are both diagonals' halves, all positive in a convex quad
    bad = (cross <= 0).any(axis=1)

    def dist(i, j):
        d = points[q[:, i]] - points[q[:, j]]
        return np.hypot(d[:, 0], d[:, 1])

    one = 0.5 * (dist(1, 0) + dist(2, 3))
    two = 0.5 * (dist(3, 0) + dist(2, 1))
    with np.errstate(divide="ignore", invalid="ignore"):
        aspect = np.maximum(one, two) / np.minimum(one, two)
    quad_area = float(0.5 * (cross[:, 0] + cross[:, 2]).sum())  # (the halves of 1-3)
    total = quad_area + float(signed_areas(points, tri).sum()) if len(tri) else quad_area
    return {
        "quads": int(len(q)),
        "non_convex": int(bad.sum()),
        "min_angle": float(angle.min()),
        "max_angle": float(angle.max()),
        "min_scaled_jacobian": float(_smallest_sine(cross, lengths).min()),
        "mean_aspect_ratio": float(aspect.mean()),
        "max_aspect_ratio": float(aspect.max()),
        "area_share": quad_area / total if total else None,
    }
