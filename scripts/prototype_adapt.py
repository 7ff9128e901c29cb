"""PROTOTYPE (issue 5, not wired into the CLI): a background grid adapted to the contour.

    python scripts/prototype_adapt.py CONTOUR.csv [--gamma 0.05] [--steps 20] [--png OUT.png]

1. spacing field s(x) = min_k (s_k + gamma |x - Q_k|), capped at 4x the median spacing;
2. a uniform reference grid, h so that cells of side 0.64 s(x) tile the box;
3. adapt: deform the reference grid with the size function f = s^2 (geometric path);
4. map the contour points back to the reference grid (point location + barycentric);
5. select on the reference contour (the existing Appendix A / tracing, unchanged);
6. start the final deformation from the adapted positions of the selection's grid
   (piecewise-linear map, so shifted grids work too), targets = the real points;
7. triangulate and check the contract against the real contour.
Prints what each stage took.

Measured (2026-11-23, 2 cores; KAPPA=1.0 in the environment = cell side at a point equal
to its spacing):
- naca0012_100 (spacing ratio 32), gamma 0.2, one geometric stage of 10 steps: the
  reference contour's ratio drops to 5.7; contract ok with the 100 given points, 313
  nodes, 2 extra boundary nodes, angles 3.2-166.6, 3.8 s.  gamma 0.05: ratio 3.6 but
  117-243 extra nodes (the field cannot grow as fast as the spacing: at point k it is
  about s_k (1/r + gamma) for a spacing growing r-fold per point).
- naca0012_1000 (ratio 316): the adaptation folds at the sharp trailing edge at
  pseudo-time 0.5-0.67 for gamma >= 0.1, whatever the steps (10, 20) or a 2x/3x finer
  adaptation grid; gamma 0.05 adapts (87k nodes, 26 halvings, 44 s) but then the
  spacing lag above applies.  Staged clipping (--ratio 4) folds earlier.  Velocities
  V = U/g are smallest exactly where cells must converge (g large), so outer nodes
  overtake inner ones: an explicit-Euler/P1 limit, not a resolution one.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from deformesh_cli import triangulate
from deformesh_cli.contour import make_contour
from deformesh_cli.deform import deform
from deformesh_cli.quality import check_contract, stats
from deformesh_cli.readers import load_contour
from deformesh_cli.select import DIAG_SLASH, Grid, grid_triangles, select
from deformesh_cli.size import SizeFunction, SizePath

KAPPA = float(__import__("os").environ.get("KAPPA", 0.9 / np.sqrt(2)))


def spacing_field(c, gamma):
    e = c.edge_lengths()
    prev = np.empty_like(e)
    from deformesh_cli.geometry import next_on_ring

    nxt = next_on_ring(c.ring)
    prev[nxt] = e
    s_k = np.minimum(e, prev)
    smax = 4 * float(np.median(s_k))
    tree = cKDTree(c.points)
    k = min(64, c.n)

    def s(q):
        d, i = tree.query(q, k=k)
        return np.minimum(np.min(s_k[i] + gamma * d, axis=1), smax)

    return s, s_k


class Between:
    """Geometric path from density 1/g_start to 1/g_end (both with box mean 1): a stage."""

    def __init__(self, g_start, g_end):
        self.g_start, self.g_end = g_start, g_end

    def g_and_rate(self, q, t):
        a, b = (np.ones(len(q)) if self.g_start is None else self.g_start(q)), self.g_end(q)
        g = a ** (1 - t) * b**t
        return g, g * (np.log(b) - np.log(a))


def adapt(grid, tri, s, s_k, box, steps, ratio):
    """Stages: the spacing field clipped from below at smin * ratio^(J-j), j = 1..J, each
    stage a linear path from the previous stage's density to this one's."""
    smin = float(s_k.min())
    smax = float(s(grid.coords()).max())
    levels = int(np.ceil(np.log(smax / smin) / np.log(ratio)))
    pos = grid.coords()
    prev = None
    halvings = 0
    for j in range(levels, -1, -1):
        clip = smin * ratio**j
        f = SizeFunction(lambda q, clip=clip: np.maximum(s(q), clip) ** 2, f"clip {clip:.3g}")
        f.normalise(box, n=512)
        pos, st = deform(
            pos,
            tri,
            np.array([], int),
            np.zeros((0, 2)),
            grid.boundary_nodes(),
            steps=steps,
            size=Between(prev, f.g1),
        )
        halvings += st.halvings
        prev = f.g1
    return pos, halvings


def locate(pos, tri, q):
    """Barycentric coordinates of points q in the (adapted) triangles: (tri index, bary)."""
    cen = pos[tri].mean(axis=1)
    tree = cKDTree(cen)
    out_t = np.full(len(q), -1)
    out_b = np.zeros((len(q), 3))
    for k in (8, 32, 128):
        todo = np.flatnonzero(out_t < 0)
        if not len(todo):
            break
        _, cand = tree.query(q[todo], k=k)
        for j in range(k):
            t = cand[:, j]
            p0, p1, p2 = pos[tri[t, 0]], pos[tri[t, 1]], pos[tri[t, 2]]
            m = np.stack([p1 - p0, p2 - p0], axis=2)
            lam = np.linalg.solve(m, (q[todo] - p0)[:, :, None])[:, :, 0]
            b = np.column_stack([1 - lam.sum(axis=1), lam])
            inside = (b >= -1e-12).all(axis=1) & (out_t[todo] < 0)
            out_t[todo[inside]] = t[inside]
            out_b[todo[inside]] = b[inside]
    return out_t, out_b


def pl_map(grid, tri, image, q):
    """The piecewise-linear map taking the uniform grid's triangles to ``image``, at q."""
    i = np.clip(((q[:, 0] - grid.x0) / grid.hx).astype(int), 0, grid.nx - 1)
    j = np.clip(((q[:, 1] - grid.y0) / grid.hy).astype(int), 0, grid.ny - 1)
    cell = j * grid.nx + i
    u = (q[:, 0] - grid.x0) / grid.hx - i
    v = (q[:, 1] - grid.y0) / grid.hy - j
    upper = v > u  # '/' split: lower triangle (00,10,11), upper (00,11,01)
    t = 2 * cell + upper
    corners = tri[t]
    ref = grid.coords()[corners]
    p0, p1, p2 = ref[:, 0], ref[:, 1], ref[:, 2]
    m = np.stack([p1 - p0, p2 - p0], axis=2)
    lam = np.linalg.solve(m, (q - p0)[:, :, None])[:, :, 0]
    b = np.column_stack([1 - lam.sum(axis=1), lam])
    return (image[corners] * b[:, :, None]).sum(axis=1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("contour")
    ap.add_argument("--gamma", type=float, default=0.05)
    ap.add_argument("--steps", type=int, default=10, help="per stage")
    ap.add_argument(
        "--ratio", type=float, default=0, help="spacing ratio per stage (0: one geometric stage)"
    )
    ap.add_argument("--refine", type=int, default=1, help="adaptation grid = selection / this")
    ap.add_argument("--png")
    a = ap.parse_args()
    t0 = time.perf_counter()
    c = load_contour(a.contour)
    s, s_k = spacing_field(c, a.gamma)
    lo, hi = c.points.min(0), c.points.max(0)
    pad = 0.1 * float((hi - lo).max())
    box = (lo[0] - pad, lo[1] - pad, hi[0] + pad, hi[1] + pad)
    size = SizeFunction(lambda q: s(q) ** 2, "spacing")
    size.normalise(box, n=512)
    h = KAPPA / np.sqrt(size.scale)
    nx, ny = int(np.ceil((box[2] - box[0]) / h)), int(np.ceil((box[3] - box[1]) / h))
    nx, ny = nx * a.refine, ny * a.refine  # adapt on a finer grid, select on the coarse one
    grid = Grid(box[0], box[1], (box[2] - box[0]) / nx, (box[3] - box[1]) / ny, nx, ny)
    tri = grid_triangles(grid, np.full(nx * ny, DIAG_SLASH, dtype=np.uint8))
    print(
        f"spacing ratio {s_k.max() / s_k.min():.0f}; reference grid {nx}x{ny} = "
        f"{grid.n_nodes} nodes, h {h:.3g}"
    )
    t = time.perf_counter()
    if a.ratio > 0:
        adapted, halvings = adapt(grid, tri, s, s_k, box, a.steps, a.ratio)
    else:
        adapted, st = deform(
            grid.coords(),
            tri,
            np.array([], int),
            np.zeros((0, 2)),
            grid.boundary_nodes(),
            steps=a.steps,
            size=SizePath(size.g1, box, geometric=True),
        )
        halvings = st.halvings
    print(f"adapt: {time.perf_counter() - t:.1f} s, {halvings} halvings")
    t = time.perf_counter()
    tt, bb = locate(adapted, tri, c.points)
    assert (tt >= 0).all(), "a contour point outside the adapted grid"
    ref_pts = (grid.coords()[tri[tt]] * bb[:, :, None]).sum(axis=1)
    ref = make_contour(ref_pts, c.lines, c.source, ring_starts=c.starts[:-1])
    e = ref.edge_lengths()
    print(
        f"reference contour: spacing ratio {e.max() / e.min():.1f} "
        f"({time.perf_counter() - t:.2f} s)"
    )
    t = time.perf_counter()
    sel = select(ref, h=h, box=box)
    print(
        f"select: {time.perf_counter() - t:.1f} s, rule {sel.path_rule}, grid "
        f"{sel.grid.nx}x{sel.grid.ny}, {sel.extra_nodes} extra boundary nodes"
    )
    # real targets: contour points exactly; extra nodes at the same fraction of their edge
    src = sel.path_source
    targets = sel.path_targets.copy()
    on = src >= 0
    targets[on] = c.points[src[on]]
    for k in np.flatnonzero(~on):
        a_ = k - 1
        while src[a_] < 0:
            a_ -= 1
        b_ = (k + 1) % len(src)
        while src[b_] < 0:
            b_ = (b_ + 1) % len(src)
        qa, qb = ref.points[src[a_]], ref.points[src[b_]]
        frac = np.dot(sel.path_targets[k] - qa, qb - qa) / np.dot(qb - qa, qb - qa)
        targets[k] = c.points[src[a_]] + frac * (c.points[src[b_]] - c.points[src[a_]])
    start = pl_map(grid, tri, adapted, sel.grid.coords())
    t = time.perf_counter()
    pos, st2 = deform(start, sel.triangles(), sel.path_nodes, targets, sel.grid.boundary_nodes())
    print(f"deform: {time.perf_counter() - t:.1f} s, {st2.halvings} halvings")
    sel.path_targets = targets
    mesh = triangulate.extract(c, sel, pos)
    check_contract(mesh, c)
    r = stats(mesh)
    print(
        f"contract ok: {r['nodes']} nodes, {r['triangles']} triangles, angles "
        f"{r['min_angle']:.1f}-{r['max_angle']:.1f}, {r['extra_boundary_nodes']} extra "
        f"boundary nodes; total {time.perf_counter() - t0:.1f} s"
    )
    if a.png:
        from deformesh_cli import plot

        plot.draw(
            mesh.points,
            mesh.triangles,
            a.png,
            boundary=mesh.lines,
            contour_points=c.points,
            title=Path(a.contour).name,
        )


if __name__ == "__main__":
    main()
