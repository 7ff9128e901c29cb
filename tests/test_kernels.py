"""The compiled kernels against plain numpy references on random inputs: the
reference does every pair; the kernel walks a tree of bounding boxes and must give
the same answers (bit for bit where its arithmetic is the reference's)."""

import numpy as np
import pytest

from deformesh_cli.select.boxtree import box_tree
from deformesh_cli.select.cones import SLACK, Cones
from deformesh_cli.select.segments import Segments


@pytest.mark.parametrize("n", [0, 1, 2, 7, 8, 9, 31, 500])
def test_box_tree_nodes_bound_their_items(n):
    """Every item lies in its leaf's box and every node's box in its parent's; each item
    is in exactly one leaf."""
    rng = np.random.default_rng(n)
    lo = rng.random((n, 2))
    hi = lo + rng.random((n, 2)) * 0.1
    t = box_tree(lo, hi, 4)
    assert sorted(t.order.tolist()) == list(range(n))
    box = t.box.reshape(-1, 4)
    for leaf in range(t.leaf0):
        items = t.order[t.start[leaf] : t.start[leaf + 1]]
        b = box[t.leaf0 + leaf]
        assert (lo[items, 0] >= b[0]).all() and (hi[items, 0] <= b[1]).all()
        assert (lo[items, 1] >= b[2]).all() and (hi[items, 1] <= b[3]).all()
    for k in range(2, 2 * t.leaf0):
        child, parent = box[k], box[k // 2]
        if np.isfinite(child[0]):
            assert parent[0] <= child[0] and parent[1] >= child[1]
            assert parent[2] <= child[2] and parent[3] >= child[3]


def _cones_reference(p, s, alpha, q, hw, hh):
    dx = np.maximum(np.abs(p[None, :, 0] - q[:, None, 0]) - hw[:, None], 0.0)
    dy = np.maximum(np.abs(p[None, :, 1] - q[:, None, 1]) - hh[:, None], 0.0)
    return np.min(s[None] + alpha * np.sqrt(dx * dx + dy * dy), axis=1, initial=np.inf)


@pytest.mark.parametrize("n", [0, 1, 2, 9, 100, 2000])
@pytest.mark.parametrize("alpha", [0.0, 0.4, 3.0])
def test_cones_least_is_the_least_cone_over_all_points(n, alpha):
    """Per query box: at least the least over every point of ``s + alpha d`` and at
    most the slack times it; equal where the slack is not used (points, not boxes,
    spread apart)."""
    rng = np.random.default_rng(n)
    p = rng.random((n, 2)) * [2.0, 1.0]
    s = 10.0 ** rng.uniform(-4, -1, n)
    q = rng.random((700, 2)) * 2.4 - 0.2
    hw = np.where(rng.random(700) < 0.5, 0.0, rng.random(700) * 0.2)
    hh = np.where(hw > 0, rng.random(700) * 0.2, 0.0)
    got = Cones(p, s, alpha).least(q, hw, hh)
    ref = _cones_reference(p, s, alpha, q, hw, hh)
    assert (got >= ref).all() and (got <= ref * SLACK).all()
    assert (got == ref).mean() > 0.9
    pts = Cones(p, s, alpha).least(p)
    assert np.array_equal(pts, np.minimum(s, _cones_reference(p, s, alpha, p, 0 * s, 0 * s)))


def test_cones_on_one_circle_are_quick_and_within_the_slack():
    """Every point of a circle as far from a query at its centre: the walk stops at the
    slack instead of visiting all of them (a result, not a timing: the answer is
    within the slack of the true least)."""
    t = np.linspace(0, 2 * np.pi, 4096, endpoint=False)
    p = np.column_stack([np.cos(t), np.sin(t)])
    s = np.full(len(p), 1e-3)
    q = np.random.default_rng(0).random((300, 2)) - 0.5
    got = Cones(p, s, 1.0).least(q)
    ref = _cones_reference(p, s, 1.0, q, np.zeros(300), np.zeros(300))
    assert (got >= ref).all() and (got <= ref * SLACK).all()


def _in_wedge(w, fwd, back):
    def turn(z):
        ang = np.arctan2(fwd[:, 0] * z[:, 1] - fwd[:, 1] * z[:, 0], np.einsum("ij,ij->i", fwd, z))
        return np.where(ang < 0, ang + 2 * np.pi, ang)

    return turn(w) <= turn(back)


def _clearance_reference(x, x_arc, x_ring, own, wedge, radius, turn, a, b, arc, length, ring, per):
    """Every (query, edge) pair, in numpy."""
    qi, si = (v.ravel() for v in np.meshgrid(np.arange(len(x)), np.arange(len(a)), indexing="ij"))
    ab = b[si] - a[si]
    ll = np.einsum("ij,ij->i", ab, ab)
    t = np.clip(np.einsum("ij,ij->i", x[qi] - a[si], ab) / np.where(ll > 0, ll, 1.0), 0, 1)
    y = a[si] + t[:, None] * ab
    d = np.hypot(*(x[qi] - y).T)
    along = np.abs(x_arc[qi] - (arc[si] + t * length[si]))
    along = np.minimum(along, per[ring[si]] - along)
    ok = (x_ring[qi] != ring[si]) | (along > turn * d)
    ok &= ~(si[:, None] == own[qi]).any(axis=1)
    ok &= _in_wedge(y - x[qi], wedge[0][qi], wedge[1][qi])
    ok &= d <= radius[qi]
    out = np.full(len(x), np.inf)
    np.minimum.at(out, qi[ok], d[ok])
    return out


@pytest.mark.parametrize("seed", range(6))
def test_segment_clearance_matches_every_pair(seed):
    """Random rings (star polygons: their edges, arcs and perimeters), queries at their
    points and along their edges, random wedges and radii: the kernel's clearance is
    the reference's, bit for bit."""
    rng = np.random.default_rng(seed)
    rings = []
    for r in range(1 + seed % 3):
        k = int(rng.integers(3, 60))
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        rad = rng.uniform(0.3, 1.0, k)
        rings.append(np.column_stack([np.cos(ang) * rad + 3 * r, np.sin(ang) * rad]))
    a = np.concatenate(rings)
    ring = np.concatenate([np.full(len(r), i) for i, r in enumerate(rings)])
    starts = np.concatenate([[0], np.cumsum([len(r) for r in rings])])
    nxt = np.arange(len(a)) + 1
    nxt[starts[1:] - 1] = starts[:-1]
    b = a[nxt]
    length = np.hypot(*(b - a).T)
    per = np.add.reduceat(length, starts[:-1])
    pieces = zip(starts, starts[1:])
    arc = np.concatenate([np.cumsum(np.r_[0, length[s:e][:-1]]) for s, e in pieces])
    m = len(a)
    edge = rng.integers(0, m, 400)
    t = rng.random(400)
    t[:50] = 0.0  # (queries at the points themselves)
    x = a[edge] + t[:, None] * (b[edge] - a[edge])
    x_arc = arc[edge] + t * length[edge]
    own = np.column_stack([edge, np.where(t == 0, (edge - 1) % m, edge)])
    fwd = rng.normal(size=(400, 2))
    back = rng.normal(size=(400, 2))
    back[:20] = -fwd[:20]  # (half-planes)
    radius = rng.uniform(0.0, 1.5, 400)
    seg = Segments(a, b, arc, length, ring, per)
    got = seg.clearance(x, x_arc, ring[edge], own, (fwd, back), radius, 2.0)
    ref = _clearance_reference(
        x, x_arc, ring[edge], own, (fwd, back), radius, 2.0, a, b, arc, length, ring, per
    )
    assert np.array_equal(got, ref)
    assert np.isfinite(got).sum() > 20


def _random_mesh(seed, n=400):
    """Random points (some far from the origin) and their Delaunay triangles."""
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(seed)
    p = rng.random((n, 2)) * [3.0, 1.0] + 1e3 * (seed % 2)
    return rng, p, Delaunay(p).simplices.astype(np.int64)


def _stiffness_reference(points: np.ndarray, tri: np.ndarray):
    """P1 Laplace element matrices, flattened row-major to (t, 9), a row of three at a
    time, each entry ``(gx_i gx_j + gy_i gy_j) |T|``: the numpy the assembly replaced."""
    from deformesh_cli.divcurl import gradients

    gx, gy, a2 = gradients(points, tri)
    area = (0.5 * a2)[:, None]
    ke = np.empty((len(tri), 9))
    for i in range(3):
        row = gx[:, i, None] * gx
        row += gy[:, i, None] * gy
        np.multiply(row, area, out=ke[:, 3 * i : 3 * i + 3])
    return ke


def _neighbours_reference(tri, stars, deg, nodes) -> np.ndarray:
    """Per node: its neighbours (the other corners of its triangles; -1 pads)."""
    w = stars.shape[1]
    s = stars[nodes]
    valid = np.arange(w) < deg[nodes, None]
    t = tri[np.where(valid, s, 0)]
    t = np.where(valid[..., None] & (t != nodes[:, None, None]), t, -1)
    return t.reshape(len(nodes), 3 * w)


@pytest.mark.parametrize("seed", range(4))
def test_assembly_is_the_element_matrices_summed_in_order(seed):
    """The compiled pattern and assembly against the numpy ones they replaced: the
    pattern of the sorted unique (row, column) keys, element matrices from
    :func:`_stiffness_reference` gathered by ``np.bincount`` over the free-free entries
    and the free-Dirichlet ones, bit for bit."""
    from deformesh_cli.divcurl import Assembler
    from deformesh_cli.geometry import unique_inverse

    rng, p, tri = _random_mesh(seed)
    n = len(p)
    dirichlet = rng.random(n) < 0.3
    ud = rng.normal(size=(n, 2))
    asm = Assembler(tri, n, dirichlet)
    K, rhs = asm.system(p, ud)
    free = np.flatnonzero(~dirichlet)
    fidx = np.full(n, -1)
    fidx[free] = np.arange(len(free))
    r = tri[:, np.repeat(np.arange(3), 3)].ravel()
    c = tri[:, np.tile(np.arange(3), 3)].ravel()
    fr, fc = fidx[r], fidx[c]
    ke = _stiffness_reference(p, tri).ravel()
    ff = (fr >= 0) & (fc >= 0)
    ukeys, slot = unique_inverse(fr[ff] * len(free) + fc[ff])
    assert np.array_equal(K.data, np.bincount(slot, weights=ke[ff]))
    assert np.array_equal(K.indices, ukeys % len(free))
    assert np.array_equal(K.indptr, np.searchsorted(ukeys // len(free), np.arange(len(free) + 1)))
    fd = (fr >= 0) & (fc < 0)
    for comp in range(2):
        want = -np.bincount(fr[fd], weights=ke[fd] * ud[c[fd], comp], minlength=len(free))
        assert np.array_equal(rhs[:, comp], want)


@pytest.mark.parametrize("seed", range(4))
def test_areas_with_margin_are_the_numpy_ones(seed):
    """Signed areas, and plus or minus the flat margin, bit for bit."""
    from deformesh_cli.deform import areas_with_margin, flat_margin
    from deformesh_cli.geometry import signed_areas

    _, p, tri = _random_mesh(seed)
    tri[::7] = tri[::7, ::-1]  # (some clockwise)
    a = signed_areas(p, tri)
    assert np.array_equal(areas_with_margin(p, tri, 0.0), a)
    for sign in (1.0, -1.0):
        assert np.array_equal(areas_with_margin(p, tri, sign), a + sign * flat_margin(p, tri))
    # the tangled test, area against margin, on triangles flat to round-off as well
    from deformesh_cli.untangle import tangled

    flat = tri[::5].copy()
    q = p.copy()
    q[flat[:, 2]] = 0.5 * (q[flat[:, 0]] + q[flat[:, 1]])  # (on the opposite side)
    for pts in (p, q):
        want = signed_areas(pts, tri) <= flat_margin(pts, tri)
        assert np.array_equal(tangled(pts, tri), want)
    assert tangled(q, tri).sum() > len(tri) // 10


def _weigh_reference(pts, tri, stars, deg, need, nodes, tan_floor, boundary):
    """The numpy weighing the compiled one replaced: ``(a, b, key, rows, nbr, star)``."""
    from deformesh_cli.coarsen import LONGEST

    w = int(deg[nodes].max())
    valid = np.arange(w) < deg[nodes, None]
    t = tri[np.where(valid, stars[nodes, :w], 0)]  # (c, w, 3)
    at = np.argmax(t == nodes[:, None, None], axis=2)
    u = np.take_along_axis(t, ((at + 1) % 3)[..., None], axis=2)[..., 0]  # next ccw
    v = np.take_along_axis(t, ((at + 2) % 3)[..., None], axis=2)[..., 0]
    # candidate k goes into b = u_k: triangle j becomes (b, u_j, v_j) unless it holds
    # b; the new edges are b - u_j for those, but the one across ab (v_k, already one).
    # Sides and areas from the neighbours' pairwise squared distances and cross
    # products, about a (v_j is the neighbour u_p, p = nxt[j])
    dead = (u[:, None, :] == u[:, :, None]) | (v[:, None, :] == u[:, :, None])  # (c, k, j)
    new = valid[:, None, :] & ~dead & (u[:, None, :] != v[:, :, None])
    keep = valid[:, None, :] & ~dead
    pa = pts[nodes]
    x = pts[u, 0] - pa[:, None, 0]
    y = pts[u, 1] - pa[:, None, 1]
    dx = x[:, :, None] - x[:, None, :]
    dy = y[:, :, None] - y[:, None, :]
    d2 = dx * dx + dy * dy  # |u_k - u_j|^2
    cr = x[:, :, None] * y[:, None, :] - y[:, :, None] * x[:, None, :]  # u_k x u_j
    nxt = np.argmax(u[:, None, :] == v[:, :, None], axis=2)  # (c, j)
    # (a star that is no closed fan, in a mesh that is no manifold, is not weighed)
    closed = np.all(~valid | (np.take_along_axis(u, nxt, axis=1) == v), axis=1)
    at_p = (np.arange(len(nodes))[:, None, None] * w + np.arange(w)[:, None]) * w + nxt[:, None]
    at_j = np.arange(len(nodes))[:, None] * w * w + np.arange(w) * w + nxt
    side_j = d2.ravel()[at_j][:, None, :]  # |u_j - u_p|^2
    side_k = d2.ravel()[at_p]  # |u_k - u_p|^2
    cross = cr.ravel()[at_j][:, None, :] - cr.ravel()[at_p] + cr  # 2 area of (u_k, u_j, u_p)
    total = side_j + side_k + d2
    shortest = np.minimum(np.minimum(side_j, side_k), d2)
    at_boundary = boundary[u][:, :, None] | (boundary[u] | boundary[v])[:, None, :]
    floor = np.where(at_boundary, tan_floor[1], tan_floor[0])
    good = (cross > 0) & (2 * cross >= floor * (total - 2 * shortest))
    half = 0.5 * LONGEST * (need[u][:, :, None] + need[u][:, None, :])
    ok = valid & closed[:, None] & np.all((~keep | good) & (~new | (d2 <= half * half)), axis=2)
    key = np.sqrt(x * x + y * y) / (0.5 * (need[nodes][:, None] + need[u]))
    key = np.where(ok, key, np.inf)
    best = np.argmin(key, axis=1)
    rows = np.flatnonzero(np.isfinite(key[np.arange(len(nodes)), best]))
    k = best[rows]
    bb = u[rows, k]
    # the link condition for the chosen edge: no new neighbour of b is one already
    nb = _neighbours_reference(tri, stars, deg, bb)  # (r, 3w)
    shared = (u[rows][:, :, None] == nb[:, None, :]).any(axis=2) & new[rows, k]
    link = ~shared.any(axis=1)
    rows, k, bb = rows[link], k[link], bb[link]
    nbr_valid = valid[rows]
    r_idx = np.repeat(np.arange(len(rows)), nbr_valid.sum(axis=1))
    star = stars[nodes[rows], :w][nbr_valid]
    return nodes[rows], bb, key[rows, k], r_idx, u[rows][nbr_valid], star


@pytest.mark.parametrize("seed", range(5))
def test_weighing_collapses_matches_the_numpy_reference(seed):
    """Every interior node of a random Delaunay mesh, with a random size field and a few
    boundary-marked nodes: the same collapses chosen, the same keys, bit for bit."""
    from scipy.spatial import ConvexHull

    from deformesh_cli import coarsen

    rng, p, tri = _random_mesh(seed, 600)
    tri = tri[np.argsort(rng.random(len(tri)))]
    n = len(p)
    stars, deg = coarsen._stars(tri, n)
    need = 10.0 ** rng.uniform(-1.5, -0.5, n)
    boundary = rng.random(n) < 0.1
    boundary[ConvexHull(p).vertices] = True  # (their stars are open fans)
    nodes = np.flatnonzero(~boundary)
    floor = np.tan(np.radians([coarsen.ANGLE, coarsen.EDGE_ANGLE]))
    got = coarsen._weigh(p, tri, stars, deg, need, nodes, floor, boundary)
    want = _weigh_reference(p, tri, stars, deg, need, nodes, floor, boundary)
    for field, ref in zip(("a", "b", "key", "rows", "nbr", "star"), want):
        assert np.array_equal(getattr(got, field), ref), field
    assert len(got.a) > 10


@pytest.mark.parametrize("seed", range(4))
def test_the_loop_fit_programme_matches_the_numpy_one(seed):
    """Random step costs with forbidden (inf) steps, some points where every choice is
    forbidden: the same back pointers, totals and restarts as the numpy loop."""
    from deformesh_cli.select._monotone import programme

    rng = np.random.default_rng(seed)
    m, k = 300, 8
    between = np.where(rng.random((m, k, k)) < 0.6, rng.random((m, k, k)), np.inf)
    between[rng.integers(1, m, 3)] = np.inf  # (nowhere to go from there)
    cost = rng.random((m, k))
    total0 = np.full(k, np.inf)
    total0[0] = cost[0, 0]
    back = np.zeros((m, k), dtype=np.int64)
    total = total0.copy()
    reset = np.zeros(m, dtype=np.uint8)
    programme(between, cost, back, total, reset)
    want_back = np.zeros((m, k), dtype=np.int64)
    want = total0.copy()
    want_reset = []
    for t in range(1, m):
        step = want[:, None] + between[t]
        want_back[t] = pick = np.argmin(step, axis=0)
        want = step[pick, np.arange(k)] + cost[t]
        if want.min() == np.inf:
            want_reset.append(t)
            want = cost[t].copy()
    assert np.array_equal(back, want_back) and np.array_equal(total, want)
    assert np.flatnonzero(reset).tolist() == want_reset and len(want_reset) >= 1


def test_the_run_time_dependencies_are_not_gpl():
    """The closure of deformesh's own requirements (extras left out) in this
    environment: every distribution has a licence that is not GPL-only."""
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).parents[1] / "scripts" / "licences.py"
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "numpy" in r.stdout and "deformesh" in r.stdout and "cvxopt" not in r.stdout


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("k", [1, 3, 8])
def test_nearest_points_by_distance_then_number(seed, k):
    """Points on a lattice (many equal distances) and at random: each query's ``k``
    nearest by squared distance, ties to the lower number, as every pair says; past
    the last point, inf and ``n``."""
    from deformesh_cli.select.nearest import Nearest

    rng = np.random.default_rng(seed)
    n = [0, 2, 50, 600][seed]
    p = np.where(rng.random((n, 1)) < 0.5, rng.integers(0, 6, (n, 2)) * 0.5, rng.random((n, 2)) * 3)
    q = np.concatenate([rng.integers(0, 7, (100, 2)) * 0.25, rng.random((100, 2)) * 3])
    dist, idx = Nearest(p).query(q, k)
    d2 = (q[:, None, 0] - p[None, :, 0]) ** 2 + (q[:, None, 1] - p[None, :, 1]) ** 2
    want = np.full((len(q), k), n)
    want_d = np.full((len(q), k), np.inf)
    for i in range(len(q)):
        order = np.lexsort((np.arange(n), d2[i]))[:k]
        want[i, : len(order)] = order
        want_d[i, : len(order)] = np.sqrt(d2[i, order])
    assert np.array_equal(idx, want) and np.array_equal(dist, want_d)


@pytest.mark.parametrize("seed", range(3))
def test_edge_table_counts_each_side_per_direction(seed):
    """Random triangles (repeated sides, both directions): each undirected side once,
    in order, with its uses each way, as a plain count says; a node outside the range
    is refused."""
    from deformesh_cli.errors import InputError
    from deformesh_cli.geometry import edge_uses

    rng = np.random.default_rng(seed)
    n = 40
    tri = rng.integers(0, n, (300, 3))
    tri = tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])]
    lo, hi, fwd, rev = edge_uses(tri, n)
    count = {}
    for a, b in np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]).tolist():
        key = (min(a, b), max(a, b))
        f, r = count.get(key, (0, 0))
        count[key] = (f + (a < b), r + (a > b))
    keys = sorted(count)
    assert list(zip(lo.tolist(), hi.tolist())) == keys
    assert list(zip(fwd.tolist(), rev.tolist())) == [count[k] for k in keys]
    with pytest.raises(InputError):
        edge_uses(np.array([[0, 1, n]]), n)


def test_leaf_index_matches_the_numpy_search():
    """A balanced quadtree of a sample, random cells of every level (some outside the
    box, some split): the leaf holding each, as a searchsorted over the Morton codes
    says."""
    from deformesh_cli.geometry import morton
    from deformesh_cli.readers import load_contour
    from deformesh_cli.select import graded

    from .conftest import SAMPLES

    c = load_contour(SAMPLES / "peanut.csv")
    lo, hi = c.points.min(axis=0), c.points.max(axis=0)
    tree = graded.build(c, (*(lo - 0.5), *(hi + 0.5)))
    rng = np.random.default_rng(0)
    level = rng.integers(0, tree.top + 2, 5000)
    width, height = tree.nx * 2**tree.top, tree.ny * 2**tree.top
    i = rng.integers(-2, width // 2**level + 2)
    j = rng.integers(-2, height // 2**level + 2)
    got = tree.leaf_index(level, i, j)
    start = morton(tree.i << tree.level, tree.j << tree.level)
    order = np.argsort(start, kind="stable")
    starts = start[order]
    want = np.full(len(level), -1)
    inside = (i >= 0) & (j >= 0) & (i * 2**level < width) & (j * 2**level < height)
    idx = np.flatnonzero(inside & (level <= tree.top))
    lv = level[idx]
    at = np.searchsorted(starts, morton(i[idx] << lv, j[idx] << lv), "right") - 1
    leaf = order[at]
    hit = tree.level[leaf] >= lv
    want[idx[hit]] = leaf[hit]
    assert np.array_equal(got, want)
    assert (got >= 0).sum() > 500 and (got < 0).sum() > 500


def _between_costs_reference(loop, cand, q, s, widest, CHUNK=1 << 18):
    """The numpy table the compiled one replaced (chunked by powers of two)."""
    nl, (m, k) = len(loop), cand.shape
    prev = np.roll(np.arange(m), 1)
    gap = (cand[:, None, :] - cand[prev][:, :, None]) % nl  # (m, k from, k to)
    seg = np.hypot(*(np.roll(loop, -1, axis=0) - loop).T)
    at = np.concatenate([[0.0], np.cumsum(seg)[:-1]])  # (the loop's length to each node)
    perimeter = float(seg.sum())
    run = (at[cand][:, None, :] - at[cand[prev]][:, :, None]) % perimeter
    edge = np.hypot(*(q - q[prev]).T)
    share = edge / edge.sum()  # (each edge's share of its ring, at most a half)
    ok = (gap >= 1) & (gap <= widest) & (run <= 0.5 * (1.0 + share[:, None, None]) * perimeter)
    out = np.where(ok, 0.0, np.inf).reshape(m * k, k)  # (rows: a step and its start)
    count = np.where(ok, gap - 1, 0).reshape(m * k, k)  # (nodes strictly between)
    reach = count.max(axis=1)
    rows = np.flatnonzero(reach > 0)
    step = rows // k
    start = cand[prev].ravel()[rows]
    a, ab, size = q[prev][step], (q - q[prev])[step], s[prev][step]
    length2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300)
    # rows grouped by their reach rounded up to a power of two: a block of width w
    width = 1 << np.ceil(np.log2(reach[rows])).astype(np.int64)
    for w in np.unique(width):
        group = np.flatnonzero(width == w)
        per = max(1, CHUNK // int(w))
        for lo in range(0, len(group), per):
            g = group[lo : lo + per]
            xy = loop[(start[g, None] + np.arange(1, w + 1)) % nl]  # (rows, w, 2)
            rel = xy - a[g, None, :]
            t = np.einsum("rwi,ri->rw", rel, ab[g]) / length2[g, None]
            d = rel - np.where(t < 0.0, 0.0, 1.0)[..., None] * ab[g, None, :]
            past = (t < 0.0) | (t > 1.0)
            d2 = np.where(past, np.einsum("rwi,rwi->rw", d, d) / size[g, None] ** 2, 0.0)
            total = np.concatenate([np.zeros((len(g), 1)), np.cumsum(d2, axis=1)], axis=1)
            # (an allowed pair's 0 takes its sum; a pair not allowed counts 0 nodes and
            # stays inf)
            out[rows[g]] += np.take_along_axis(total, count[rows[g]], axis=1)
    return out.reshape(m, k, k)


@pytest.mark.parametrize("seed", range(5))
def test_between_costs_match_the_numpy_table(seed):
    """A loop of random nodes round a ring of random points, each point's candidates
    random loop nodes: the same table, bit for bit (the loop's order makes steps of
    every kind: back, too far, allowed with nodes past the edge's ends)."""
    from deformesh_cli.select.construct import _between_costs

    rng = np.random.default_rng(seed)
    nl, m, k = 120, 30, 8
    ang = np.sort(rng.uniform(0, 2 * np.pi, nl))
    loop = np.column_stack([np.cos(ang), np.sin(ang)]) * rng.uniform(0.9, 1.1, (nl, 1))
    qa = np.sort(rng.uniform(0, 2 * np.pi, m))
    q = np.column_stack([np.cos(qa), np.sin(qa)])
    cand = np.sort(rng.integers(0, nl, (m, k)), axis=1)
    s = rng.uniform(0.05, 0.2, m)
    got = _between_costs(loop, cand, q, s, nl - (m - 1))
    want = _between_costs_reference(loop, cand, q, s, nl - (m - 1))
    assert np.array_equal(got, want)
    assert np.isfinite(got).mean() > 0.1 and (got[np.isfinite(got)] > 0).any()


def _laplacian(seed, n, parts=1):
    """The deformation's matrix on random Delaunay meshes (``parts`` apart: a graph of
    several components), hull nodes held."""
    from scipy.spatial import ConvexHull, Delaunay

    from deformesh_cli.divcurl import Assembler

    rng = np.random.default_rng(seed)
    pts, tris, held = [], [], []
    for k in range(parts):
        p = rng.random((n, 2)) + [3.0 * k, 0.0]
        tris.append(Delaunay(p).simplices + k * n)
        h = np.zeros(n, dtype=bool)
        h[ConvexHull(p).vertices] = True
        pts.append(p)
        held.append(h)
    p, tri, held = np.concatenate(pts), np.concatenate(tris), np.concatenate(held)
    asm = Assembler(tri.astype(np.int64), len(p), held)
    return rng, asm.system(p, rng.normal(size=(len(p), 2)))


@pytest.mark.parametrize("seed, n, parts", [(0, 30, 1), (1, 400, 1), (2, 300, 3), (3, 2500, 1)])
def test_ldl_solves_the_deformation_systems(seed, n, parts):
    """The minimum-degree LDL^T: its order is a permutation, its solution the dense
    solver's to round-off, the same bits on a second factorisation, and an update with
    new numbers on the same pattern solves the new system."""
    from deformesh_cli.ldl import LDL

    _, (K, rhs) = _laplacian(seed, n, parts)
    f = LDL(K)
    assert sorted(f.perm.tolist()) == list(range(K.shape[0]))
    dense = K.tocsr().toarray()
    x = f.solve(rhs)
    assert np.allclose(dense @ x, rhs, rtol=0, atol=1e-10 * np.abs(rhs).max())
    assert np.array_equal(LDL(K).solve(rhs), x)
    K2 = type(K)(K.data * 2.0, K.indices, K.indptr, K.shape)
    f.update(K2)
    assert np.allclose(f.solve(rhs), x / 2.0, rtol=1e-12, atol=1e-15)


def test_ldl_refuses_a_matrix_that_is_not_positive_definite():
    """A negated system has negative pivots: a SolverError, not a wrong answer."""
    from deformesh_cli.errors import SolverError
    from deformesh_cli.ldl import LDL

    _, (K, _) = _laplacian(5, 50)
    neg = type(K)(-K.data, K.indices, K.indptr, K.shape)
    with pytest.raises(SolverError):
        LDL(neg)


def test_apex_quality_is_the_numpy_expression():
    """Random stars and candidate positions (some turning triangles clockwise, one
    corner NaN): each node's worst tangent as the numpy expression gives it, bit for
    bit, -inf included."""
    from deformesh_cli.smoothing import _ApexQuality

    rng = np.random.default_rng(7)
    n, c = 60, 8
    count = rng.integers(1, 9, n)
    first = np.concatenate([[0], np.cumsum(count)[:-1]])
    row = np.repeat(np.arange(n), count)
    t = len(row)
    ax, ay, bx, by = (rng.normal(size=(t, 1)) for _ in range(4))
    ax[5] = np.nan
    px, py = rng.normal(size=(n, c)), rng.normal(size=(n, c))
    got = _ApexQuality(first, ax, ay, bx, by)(px, py)
    x, y = px[row], py[row]
    e1x, e1y, e2x, e2y = x - bx, y - by, ax - x, ay - y
    cross = e1x * e2y - e1y * e2x
    s0 = (bx - ax) ** 2 + (by - ay) ** 2
    s1, s2 = e1x * e1x + e1y * e1y, e2x * e2x + e2y * e2y
    shortest = np.minimum(np.minimum(s0, s1), s2)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.where(cross > 0, 2 * cross / (s0 + s1 + s2 - 2 * shortest), -np.inf)
    want = np.minimum.reduceat(q, first, axis=0)
    assert np.array_equal(got, want, equal_nan=True)
    assert np.isinf(got).any() and np.isfinite(got).any()
    one = _ApexQuality(first, ax, ay, bx, by)(px[:, :1], py[:, :1])
    assert np.array_equal(one, want[:, :1], equal_nan=True)


@pytest.mark.parametrize("seed", range(4))
def test_segments_meet_triangles_is_shapely_intersects(seed):
    """Exact predicates: the same answers as GEOS's ``intersects`` for segments against
    closed triangles, on small-integer coordinates where touches, shared vertices and
    collinear overlaps are common, and on random ones."""
    import shapely

    from deformesh_cli._predicates import segments_meet_triangles

    rng = np.random.default_rng(seed)
    k = 3000
    if seed % 2:
        pts = rng.integers(0, 5, (3 * k, 2)).astype(float)
        a, b = rng.integers(0, 5, (k, 2)).astype(float), rng.integers(0, 5, (k, 2)).astype(float)
    else:
        pts = rng.random((3 * k, 2))
        a, b = rng.random((k, 2)), rng.random((k, 2))
    tri = np.arange(3 * k).reshape(k, 3)
    area = (pts[tri[:, 1], 0] - pts[tri[:, 0], 0]) * (pts[tri[:, 2], 1] - pts[tri[:, 0], 1]) - (
        pts[tri[:, 2], 0] - pts[tri[:, 0], 0]
    ) * (pts[tri[:, 1], 1] - pts[tri[:, 0], 1])
    tri[area < 0] = tri[area < 0][:, ::-1]
    t = np.flatnonzero(area != 0)
    ok = a[t] != b[t]
    t = t[ok.any(axis=1)]
    out = np.empty(len(t), dtype=np.uint8)
    segments_meet_triangles(pts, tri, t, a[t], b[t], out)
    want = shapely.intersects(
        shapely.polygons(pts[tri[t]]), shapely.linestrings(np.stack([a[t], b[t]], axis=1))
    )
    assert len(t) > 2000
    assert np.array_equal(out.view(bool), want)
    # a point on a side, in exact arithmetic but not in the float determinant's
    p = np.array([[0.1, 0.1], [0.3, 0.3], [0.0, 1.0]])
    q = np.array([[0.2, 0.2], [0.2, 0.9]])
    out = np.empty(1, dtype=np.uint8)
    segments_meet_triangles(p, np.array([[0, 1, 2]]), np.array([0]), q[:1], q[1:], out)
    assert out[0] == shapely.intersects(shapely.Polygon(p), shapely.LineString(q))


@pytest.mark.parametrize("seed", range(4))
def test_boxes_meet_segments_is_the_strtree_query(seed):
    """Every (box, segment) pair that shares a point, as GEOS finds them (STRtree query
    with ``intersects``), by box then segment: on small-integer coordinates, where
    segments along a box's side or through its corner are common, and random ones."""
    import shapely

    from deformesh_cli._predicates import boxes_meet_segments

    rng = np.random.default_rng(seed)
    nb, ns = 400, 300
    if seed % 2:
        lo = rng.integers(0, 8, (nb, 2)).astype(float)
        hi = lo + rng.integers(1, 3, (nb, 2))
        a = rng.integers(0, 10, (ns, 2)).astype(float)
        b = rng.integers(0, 10, (ns, 2)).astype(float)
    else:
        lo = rng.random((nb, 2))
        hi = lo + 0.1 * rng.random((nb, 2))
        a, b = rng.random((ns, 2)), rng.random((ns, 2))
    t = box_tree(np.minimum(a, b), np.maximum(a, b), 4)
    leaf = np.empty(10, dtype=np.int64)
    seg = np.empty(10, dtype=np.int64)
    f8 = np.ascontiguousarray
    args = (f8(lo[:, 0]), f8(hi[:, 0]), f8(lo[:, 1]), f8(hi[:, 1]))
    args += (f8(a[:, 0]), f8(a[:, 1]), f8(b[:, 0]), f8(b[:, 1]), t.order, t.start, t.box, t.leaf0)
    m = boxes_meet_segments(*args, leaf, seg)  # (too little room: counted only)
    leaf, seg = np.empty(m, dtype=np.int64), np.empty(m, dtype=np.int64)
    assert boxes_meet_segments(*args, leaf, seg) == m
    tree = shapely.STRtree(shapely.linestrings(np.stack([a, b], axis=1)))
    want = tree.query(shapely.box(lo[:, 0], lo[:, 1], hi[:, 0], hi[:, 1]), predicate="intersects")
    want = want[:, np.lexsort((want[1], want[0]))]
    assert m > 100
    assert np.array_equal(leaf, want[0]) and np.array_equal(seg, want[1])


@pytest.mark.parametrize("seed", range(3))
def test_pattern_search_is_the_numpy_loop(seed):
    """The compiled pattern search takes the same steps as the numpy loop it replaced
    (every node at once: the best of the eight directions where it beats the raised
    best, else the step halved): the same positions, tangents and steps, bit for bit."""
    from deformesh_cli.smoothing import _DIRS, SEARCH_STEPS, _ApexQuality, _raised

    rng = np.random.default_rng(seed)
    n, d = 300, 7
    first = np.arange(n) * d
    ang = np.sort(rng.uniform(0, 2 * np.pi, (n, d + 1)), axis=1)
    ang[:, -1] = ang[:, 0] + 2 * np.pi
    r = rng.uniform(0.5, 1.5, (n, d + 1))
    ring_x, ring_y = r * np.cos(ang), r * np.sin(ang)
    ax, ay = ring_x[:, :-1].reshape(-1, 1), ring_y[:, :-1].reshape(-1, 1)
    bx, by = ring_x[:, 1:].reshape(-1, 1), ring_y[:, 1:].reshape(-1, 1)
    quality = _ApexQuality(first, ax, ay, bx, by)
    px, py = rng.uniform(-0.3, 0.3, n), rng.uniform(-0.3, 0.3, n)
    best = quality(px[:, None], py[:, None])[:, 0]
    step = rng.uniform(0.05, 0.3, n)
    x0 = px.copy()
    wx, wy, wbest, wstep = (v.copy() for v in (px, py, best, step))
    quality.search(px, py, best, step)
    rows = np.arange(n)
    bar = _raised(wbest)
    for _ in range(SEARCH_STEPS):
        cx = wx[:, None] + wstep[:, None] * _DIRS[None, :, 0]
        cy = wy[:, None] + wstep[:, None] * _DIRS[None, :, 1]
        q = quality(cx, cy)
        k = np.argmax(q, axis=1)
        qk = q[rows, k]
        take = qk > bar
        wx[take], wy[take], wbest[take] = cx[take, k[take]], cy[take, k[take]], qk[take]
        bar[take] = _raised(wbest[take])
        wstep = np.where(take, wstep, 0.5 * wstep)
    assert (wx != x0).any()  # (it moved)
    for got, ref in zip((px, py, best, step), (wx, wy, wbest, wstep)):
        assert np.array_equal(got, ref)


def test_raised_is_the_angle_raised_by_the_gain():
    """The tangent addition formula is the tangent of the angle GAIN degrees larger (to
    round-off), capped short of a right angle; NaN stays NaN; -inf is GAIN over -90."""
    from deformesh_cli.smoothing import _RIGHT, GAIN, _raised

    t = np.tan(np.radians(np.linspace(-89, 89.98, 1001)))
    want = np.tan(np.minimum(np.arctan(t) + np.radians(GAIN), np.pi / 2 - 1e-12))
    assert np.allclose(_raised(t), want, rtol=1e-9)
    assert _raised(np.array([np.inf]))[0] == _RIGHT
    assert np.isnan(_raised(np.array([np.nan]))[0])
    assert _raised(np.array([-np.inf]))[0] == pytest.approx(np.tan(np.radians(GAIN - 90)))


@pytest.mark.parametrize("seed, n", [(0, 2500), (1, 6000)])
def test_minimum_degree_keeps_the_factor_as_sparse_as_superlus_ordering(seed, n):
    """The approximate minimum degree order (then postordered) gives a factor no fuller
    than a quarter more than SuperLU's multiple minimum degree on the same matrix;
    after the postorder every subtree of the elimination tree is a run of columns
    ending at its root."""
    import scipy.sparse.linalg as spla

    from deformesh_cli.ldl import LDL

    _, (K, _) = _laplacian(seed, n)
    f = LDL(K)
    ours = int(f._Lp[-1]) + K.shape[0]
    lu = spla.splu(
        K.tocsr().tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
        options={"SymmetricMode": True},
    )  # fmt: skip
    assert ours <= 1.25 * lu.L.nnz
    parent = f._parent
    size = np.ones(len(parent), dtype=np.int64)
    for j in range(len(parent)):  # (a parent comes after its children)
        if parent[j] >= 0:
            size[parent[j]] += size[j]
    j = np.flatnonzero(parent >= 0)
    assert ((j >= parent[j] - size[parent[j]] + 1) & (j < parent[j])).all()


def _edge_pairs_reference(tri: np.ndarray):
    """(numpy) Inner edges as (t1, k1, t2, k2): edge k1 of t1 (from corner k1 to k1 + 1) is
    edge k2 of t2, walked the other way."""
    t = np.repeat(np.arange(len(tri)), 3)
    k = np.tile(np.arange(3), len(tri))
    a = tri.ravel()
    b = tri[:, [1, 2, 0]].ravel()
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo.astype(np.int64) * (int(hi.max(initial=0)) + 1) + hi
    order = np.argsort(key, kind="stable")  # (by lo, then hi: as a lexsort of the two)
    key, t, k, fwd = key[order], t[order], k[order], (a < b)[order]
    same = (key[1:] == key[:-1]) & (fwd[1:] != fwd[:-1])
    i = np.flatnonzero(same)
    return t[i], k[i], t[i + 1], k[i + 1]


@pytest.mark.parametrize("seed", range(3))
def test_edge_pairs_are_the_numpy_ones(seed):
    """The compiled pairing of sides walked both ways: the same pairs in the same order
    as the stable sort, on meshes with some triangles repeated (a side used three
    times) and some turned round."""
    from deformesh_cli.smoothing import _edge_pairs

    _, p, tri = _random_mesh(seed)
    tri = np.concatenate([tri, tri[::9], tri[::11, ::-1]])
    got = _edge_pairs(tri)
    want = _edge_pairs_reference(tri)
    assert len(got[0]) > len(tri) // 2
    for g, w in zip(got, want):
        assert np.array_equal(g, w)


@pytest.mark.parametrize("seed", range(3))
def test_the_compiled_smallest_angles_and_areas_are_numpys(seed):
    """The compiled smallest-angle tangent and signed area of each triangle against the
    numpy expressions, bit for bit, with flat, repeated-corner and non-finite ones."""
    from deformesh_cli.geometry import signed_areas
    from deformesh_cli.smoothing import _tan_min, tan_min_angle

    rng = np.random.default_rng(seed)
    p = rng.normal(size=(3000, 2)) * 10.0 ** rng.integers(-3, 4)
    p[5], p[7, 0], p[9] = np.nan, np.inf, p[8] * 2  # (8, 9 and the origin: collinear)
    tri = rng.integers(0, len(p), size=(20000, 3))
    tri[:6] = [[1, 1, 2], [3, 4, 3], [5, 6, 7], [7, 8, 9], [0, 0, 0], [8, 9, 10]]
    with np.errstate(invalid="ignore"):
        want = tan_min_angle(*(p[tri[:, k], d] for k in range(3) for d in range(2)))
    assert np.array_equal(_tan_min(p, tri), want, equal_nan=True)
    x, y = p[tri, 0], p[tri, 1]
    with np.errstate(invalid="ignore"):
        area = 0.5 * (
            (x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0])
        )
    assert np.array_equal(signed_areas(p, tri), area, equal_nan=True)
    assert np.array_equal(signed_areas(p, tri.astype(np.int32)), area, equal_nan=True)
    from deformesh_cli.errors import InputError

    with pytest.raises(InputError, match="outside"):
        signed_areas(p, np.array([[0, 1, len(p)]]))


def _walk_reference(frame, neighbours, hint, q, limit, round_off):
    """(numpy) Every point's walk, a step for all at a time."""
    from deformesh_cli.adapt import weights

    t = hint.copy()
    w = weights(frame, t, q)
    least = np.minimum(np.minimum(w[:, 0], w[:, 1]), w[:, 2])
    todo = np.flatnonzero(least < -round_off)
    for _ in range(limit):
        if not len(todo):
            break
        j = np.argmin(w[todo], axis=1)
        nxt = neighbours[t[todo], j]
        out = nxt < 0
        todo = todo[~out]
        t[todo] = nxt[~out]
        w[todo] = weights(frame, t[todo], q[todo])
        ww = w[todo]
        least[todo] = np.minimum(np.minimum(ww[:, 0], ww[:, 1]), ww[:, 2])
        todo = todo[least[todo] < -round_off]
    return t, w


@pytest.mark.parametrize("seed, limit", [(0, 256), (1, 3)])
def test_the_compiled_walk_and_p1_field_are_the_numpy_ones(seed, limit):
    """Points moved off their nodes (some far, some out of the mesh): the compiled walk
    stops in the same triangles with the same weights as the numpy loop, bit for bit
    (also when the steps run out), and the P1 field read there is the numpy sum's."""
    from scipy.spatial import Delaunay

    from deformesh_cli._walk import p1, walk
    from deformesh_cli.adapt import frames, p1_values, start_triangles, triangle_neighbours

    rng = np.random.default_rng(seed)
    p = rng.random((400, 2))
    tri = Delaunay(p).simplices.astype(np.int64)
    a2 = (p[tri[:, 1]] - p[tri[:, 0]])[:, 0] * (p[tri[:, 2]] - p[tri[:, 0]])[:, 1] - (
        p[tri[:, 2]] - p[tri[:, 0]]
    )[:, 0] * (p[tri[:, 1]] - p[tri[:, 0]])[:, 1]
    tri[a2 < 0] = tri[a2 < 0][:, ::-1]
    frame = frames(p, tri)
    nb = triangle_neighbours(tri)
    hint = start_triangles(tri, len(p))
    q = p + rng.normal(size=p.shape) * rng.choice([0.001, 0.05, 0.5], size=(len(p), 1))
    want_t, want_w = _walk_reference(frame, nb, hint, q, limit, 1e-12)
    t, w = hint.copy(), np.empty((len(q), 3))
    lost = walk(*frame, nb, np.ascontiguousarray(q), limit, 1e-12, t, w)
    assert np.array_equal(t, want_t) and np.array_equal(w, want_w)
    assert lost == int((np.minimum(np.minimum(w[:, 0], w[:, 1]), w[:, 2]) < -1e-12).sum())
    assert lost > 0  # (some left the mesh)
    values = rng.normal(size=(len(p), 2))
    c = tri[t]
    ref = w[:, 0, None] * values[c[:, 0]]
    ref += w[:, 1, None] * values[c[:, 1]]
    ref += w[:, 2, None] * values[c[:, 2]]
    out = np.empty_like(ref)
    p1(values, tri, t, w, out)
    assert np.array_equal(out, ref) and np.array_equal(p1_values(values, tri, t, w), ref)


def test_touching_is_the_numpy_mask_and_refuses_a_node_outside_it():
    from deformesh_cli.errors import InputError
    from deformesh_cli.geometry import touching

    rng = np.random.default_rng(3)
    tri = rng.integers(0, 5000, size=(20000, 3))
    mask = rng.random(5000) < 0.02
    want = mask[tri[:, 0]] | mask[tri[:, 1]] | mask[tri[:, 2]]
    assert np.array_equal(touching(mask, tri), want)
    assert np.array_equal(touching(mask, tri.astype(np.int32)[::2]), want[::2])
    assert touching(mask, np.empty((0, 3), dtype=np.int64)).shape == (0,)
    with pytest.raises(InputError, match="outside"):
        touching(mask[:100], tri)
    with pytest.raises(InputError, match="outside"):
        touching(mask, np.array([[0, -1, 2]]))


def test_two_columns_solved_in_one_pass_are_each_columns_solve():
    from deformesh_cli._ldl import solve
    from deformesh_cli.ldl import LDL

    _, (K, rhs) = _laplacian(7, 2000)
    f = LDL(K)
    both = f.solve(rhs)
    for k in range(2):
        x = np.ascontiguousarray(rhs[f.perm, k])
        solve(f._Lp, f._Li, f._Lx, f._Dinv, x)
        one = np.empty_like(x)
        one[f.perm] = x
        assert np.array_equal(both[:, k], one)


@pytest.mark.parametrize("seed", range(2))
def test_adapts_sums_are_bincounts(seed):
    """adapt's normal equations and load, summed by the compiled loops, are
    ``np.bincount`` over the same products in the same order, bit for bit."""
    from deformesh_cli._divcurl import load_vector, normal_equations

    rng = np.random.default_rng(seed)
    T, size = 500, 300
    d, c = rng.normal(size=(6, T)), rng.normal(size=(6, T))
    half = rng.random(T)
    pairs = np.array([(a, b) for a in range(6) for b in range(a, 6)], dtype=np.int64).T.copy()
    entry = rng.integers(0, size + 1, size=len(pairs[0]) * T)
    block = np.stack([d[p] * d[q] + c[p] * c[q] for p, q in pairs.T]) * half
    want = np.bincount(entry, weights=block.ravel(), minlength=size + 1)
    got = np.zeros(size + 1)
    normal_equations(d, c, half, pairs[0], pairs[1], entry, got)
    assert np.array_equal(got, want)
    dof = rng.integers(0, size + 1, size=6 * T)
    coef = rng.normal(size=T)
    want = np.bincount(dof, weights=(coef * d).ravel(), minlength=size + 1)
    got = np.zeros(size + 1)
    load_vector(d, coef, dof, got)
    assert np.array_equal(got, want)
