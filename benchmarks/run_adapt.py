"""r-adaptation: ``deformesh adapt`` next to the ``movement`` package's published numbers.

Usage: python benchmarks/run_adapt.py [--sizes 10000,100000,180000]   (make bench)

Every run is a whole process (``deformesh adapt ... --json``).  Cases:

- ``movement``'s ring: the unit square as 20 x 20 squares split by one diagonal (800
  triangles), ``M = 1 + 20 / cosh^2(200 ((x - 1/2)^2 + (y - 1/2)^2 - 0.15))``;
  ``movement``'s quasi-Newton Monge-Ampere mover reports after 52 iterations a volume
  ratio of 8.84 and sigma/mu 0.348 (its measures, which ``adapt`` reports); on 20 x 20,
  40 x 40 and 71 x 71 grids, the L2 error of the P1 interpolant of the ring's profile
  before and after (how well the ring is resolved, which those measures do not see);
- a front ``u = tanh(30 (y - 1/2 - sin(2 pi x) / 4))`` on a 64 x 64 grid adapted to u
  (``--field u``): the L2 error of u's P1 interpolant before and after (u sampled at
  the new nodes), for both ``--kind`` and several ``--alpha``;
- the far field of ``samples/naca0012.csv`` (``--exterior``) and a wake-like monitor;
- seconds and peak memory on square grids of about 1e4, 1e5 (and more) triangles.
"""

import argparse
import json
import sys
import tempfile
from pathlib import Path

import meshio
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import heading, write_section
from run_contours import EXE, ROOT, run_process

RING = "1 + 20 * (1 - tanh(200 * ((x - 0.5)**2 + (y - 0.5)**2 - 0.15))**2)"
WAKE = "1 + 4 * exp(-((x - 1.3)**2 + 4 * y**2))"


def square_grid(n: int):
    """The unit square as n x n squares, each split by one diagonal."""
    x, y = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1), indexing="ij")
    k = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)[:-1, :-1].ravel()
    tri = np.concatenate([np.c_[k, k + n + 1, k + n + 2], np.c_[k, k + n + 2, k + 1]])
    return np.c_[x.ravel(), y.ravel()], tri


def front(q):
    return np.tanh(30 * (q[:, 1] - 0.5 - 0.25 * np.sin(2 * np.pi * q[:, 0])))


def profile(q):
    """The ring's profile: its monitor is ``1 + 20 (1 - profile^2)``."""
    return np.tanh(200 * ((q[:, 0] - 0.5) ** 2 + (q[:, 1] - 0.5) ** 2 - 0.15))


def l2_error(p, tri, f, levels=3):
    """The L2 norm of ``f`` minus its P1 interpolant: each triangle split into 4^levels
    by its lattice, ``f`` sampled at each small triangle's centroid."""
    n = 2**levels
    b = [((i + 1 / 3) / n, (j + 1 / 3) / n) for i in range(n) for j in range(n - i)]
    b += [((i + 2 / 3) / n, (j + 2 / 3) / n) for i in range(n) for j in range(n - i - 1)]
    w = np.c_[1 - np.sum(b, axis=1), np.array(b)]
    x = np.einsum("kj,tjd->tkd", w, p[tri])
    interp = np.einsum("kj,tj->tk", w, f(p)[tri])
    exact = f(x.reshape(-1, 2)).reshape(x.shape[:2])
    d = p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]]
    area = 0.5 * np.abs(d[0][:, 0] * d[1][:, 1] - d[0][:, 1] * d[1][:, 0])
    return float(np.sqrt(np.sum(area[:, None] * (exact - interp) ** 2) / len(w)))


def write_grid(path: Path, n: int, data=None) -> None:
    p, tri = square_grid(n)
    meshio.write(path, meshio.Mesh(np.c_[p, 0 * p[:, 0]], [("triangle", tri)], data or {}))


def adapt(mesh: Path, out: Path, *opts: str) -> tuple[float, float, dict]:
    dt, mb, code, text, err = run_process(
        [EXE, "adapt", str(mesh), "-o", str(out), "--json", "-q", *opts]
    )
    if code:
        raise SystemExit(f"{mesh}: {err}")
    return dt, mb, json.loads(text)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="10000,100000,180000", help="triangles, about")
    args = ap.parse_args()
    lines = heading(
        "## Adaptation: deformesh adapt next to movement (whole processes)",
        "Each row one `deformesh adapt ... --json` process. sigma/mu and volume ratio are "
        "`movement`'s measures (the monitor at the nodes integrated over each cell, over "
        "that cell's area in the input mesh). `movement`'s Monge-Ampere mover, on the same "
        "ring mesh and monitor, reports 0.348 and 8.84 after 52 iterations (its demo).",
    )
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        lines += [
            "| case | triangles | options | solves | sigma/mu before | after "
            "| volume ratio before | after | smallest angle | seconds | peak RSS MB |",
            "| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
        ]
        ring = d / "ring.vtu"
        write_grid(ring, 20)
        for opts in ([], ["--boundary", "fixed"], ["--steps", "80"]):
            dt, mb, r = adapt(ring, d / "o.vtu", "--monitor", RING, *opts)
            lines.append(
                f"| movement's ring, 20 x 20 | {r['triangles']} | {' '.join(opts) or 'defaults'} "
                f"| {r['solves']} "
                f"| {r['sigma_over_mu_before']:.3f} | {r['sigma_over_mu']:.3f} "
                f"| {r['volume_ratio_before']:.2f} | {r['volume_ratio']:.2f} "
                f"| {r['smallest_angle']:.1f} | {dt:.2f} | {mb:.0f} |"
            )
        ff = d / "ff.vtu"
        code = run_process([EXE, "all", str(ROOT / "samples" / "naca0012.csv"), "--exterior",
                            "-o", str(ff), "-q"])[2]  # fmt: skip
        if code:
            raise SystemExit("naca0012 far field failed")
        dt, mb, r = adapt(ff, d / "o.vtu", "--monitor", WAKE)
        lines.append(
            f"| samples/naca0012.csv far field, `{WAKE}` | {r['triangles']} | defaults "
            f"| {r['solves']} "
            f"| {r['sigma_over_mu_before']:.3f} | {r['sigma_over_mu']:.3f} "
            f"| {r['volume_ratio_before']:.2f} | {r['volume_ratio']:.2f} "
            f"| {r['smallest_angle']:.1f} | {dt:.2f} | {mb:.0f} |"
        )
        for size in [int(s) for s in args.sizes.split(",") if s]:
            n = int(round(np.sqrt(size / 2)))
            grid = d / f"grid{n}.vtu"
            write_grid(grid, n)
            dt, mb, r = adapt(grid, d / "o.vtu", "--monitor", RING)
            lines.append(
                f"| ring, {n} x {n} | {r['triangles']} | defaults | {r['solves']} "
                f"| {r['sigma_over_mu_before']:.3f} | {r['sigma_over_mu']:.3f} "
                f"| {r['volume_ratio_before']:.2f} | {r['volume_ratio']:.2f} "
                f"| {r['smallest_angle']:.1f} | {dt:.2f} | {mb:.0f} |"
            )
        lines += [
            "",
            "How well the ring adapted to is resolved, not only evened out (the measures above "
            "take M at the nodes only): the L2 error of the P1 interpolant of the ring's "
            "profile `tanh(200 ((x - 1/2)^2 + (y - 1/2)^2 - 0.15))` (each triangle sampled at "
            "256 points), before and after, with sigma/mu after.",
            "",
            "| grid | profile L2 error before | after | sigma/mu after |",
            "| --- | ---: | ---: | ---: |",
        ]
        for n in (20, 40, 71):
            p, tri = square_grid(n)
            grid = d / f"profile{n}.vtu"
            write_grid(grid, n)
            out = d / "profile_out.vtu"
            _, _, r = adapt(grid, out, "--monitor", RING)
            before = l2_error(p, tri, profile, levels=4)
            after = l2_error(meshio.read(out).points[:, :2], tri, profile, levels=4)
            lines.append(f"| {n} x {n} | {before:.4f} | {after:.4f} | {r['sigma_over_mu']:.3f} |")
        lines += [
            "",
            "The front `u = tanh(30 (y - 1/2 - sin(2 pi x) / 4))` on a 64 x 64 grid (8,192 "
            "triangles), `--field u`: the L2 error of u's P1 interpolant (u at the nodes, "
            "each triangle sampled at 64 points) before and after.",
            "",
            "| --kind | --alpha | L2 error before | after | after / before | smallest angle "
            "| seconds |",
            "| --- | ---: | ---: | ---: | ---: | ---: | ---: |",
        ]
        p, tri = square_grid(64)
        mesh = d / "front.vtu"
        write_grid(mesh, 64, {"u": front(p)})
        before = l2_error(p, tri, front)
        for kind in ("gradient", "hessian"):
            for alpha in ("3", "10", "20"):
                out = d / "front_out.vtu"
                dt, _, r = adapt(mesh, out, "--field", "u", "--kind", kind, "--alpha", alpha)
                after = l2_error(meshio.read(out).points[:, :2], tri, front)
                lines.append(
                    f"| {kind} | {alpha} | {before:.5f} | {after:.5f} | {after / before:.3f} "
                    f"| {r['smallest_angle']:.1f} | {dt:.2f} |"
                )
    write_section("adapt", "\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
