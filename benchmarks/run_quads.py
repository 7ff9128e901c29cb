"""Quad-dominant meshes next to Gmsh's Blossom recombination, as whole processes.

Usage: python benchmarks/run_quads.py [--repeat N]

samples/circle.csv at ``--max-h 0.05`` and samples/naca0012.csv in the box
-20,-20,21,20: ``deformesh all ... --cells quad -o OUT.msh`` and
``benchmarks/peers/gmsh_quads.py`` (the same boundary points, Frontal-Delaunay then
Blossom), in turn, the median of N runs each.  One code measures both files
(:func:`measure`): the contour's points found among the nodes, the cells, the share
of the area in quads, the quads' smallest and largest corner angles and smallest
scaled Jacobian (the sine of the corner angle farthest from a right angle).
"""

import argparse
import os
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from meshfiles import answered, asked, plain_csv, read_cells
from results import heading, write_section
from run_contours import EXE, run_process

ROOT = Path(__file__).resolve().parent.parent
PEERS = Path(__file__).resolve().parent / "peers"
PY = sys.executable
BOX = "-20,-20,21,20"
CASES = (
    ("circle", "samples/circle.csv", "0.05", None),
    ("naca0012", "samples/naca0012.csv", None, BOX),
)


def measure(mesh_path: str, contour_path: str) -> dict:
    import numpy as np

    p, tri, quads, found = read_cells(mesh_path, contour_path)
    kept = sum(k >= 0 for k in found)

    def area(cells):
        x, y = p[cells, 0], p[cells, 1]
        return np.abs(0.5 * (x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y).sum(axis=1))

    q = p[quads]
    a, b = np.roll(q, -1, axis=1) - q, np.roll(q, 1, axis=1) - q
    cross = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    angle = np.degrees(np.arctan2(np.abs(cross), (a * b).sum(axis=-1)))
    qa, ta = area(quads).sum(), area(tri).sum()
    return {
        "nodes": len(p),
        "triangles": len(tri),
        "quads": len(quads),
        "points_kept": int(kept),
        "points": len(found),
        "share": float(qa / (qa + ta)),
        "min_angle": float(angle.min()),
        "max_angle": float(angle.max()),
        "min_sj": float(np.sin(np.radians(angle)).min()),
    }


def commands(tool: str, src: str, max_h, box, out: str) -> list[str]:
    if tool == "deformesh":
        extra = (["--max-h", max_h] if max_h else []) + (
            ["--exterior", f"--box={box}"] if box else []
        )
        return [EXE, "all", src, "--cells", "quad", *extra, "-o", out, "-q"]
    return [PY, str(PEERS / "gmsh_quads.py"), plain_csv(src), max_h or "-", box or "-", out]


def main():
    if answered("--measure", measure):
        return
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    tools = ("deformesh", "gmsh")
    lines = heading(
        f"## Quad-dominant meshes next to Gmsh's Blossom recombination (whole processes, "
        f"median of {args.repeat})",
        "`python benchmarks/run_quads.py`: samples/circle.csv at --max-h 0.05 and "
        f"samples/naca0012.csv in the box {BOX}, `deformesh all ... --cells quad` and Gmsh 4 "
        "(Frontal-Delaunay, Blossom recombination) on the same boundary points "
        "(benchmarks/peers/gmsh_quads.py), written as .msh. One code measures both files: "
        "the share of the area in quads, the quads' corner angles and smallest scaled "
        "Jacobian (the sine of the corner angle farthest from 90 degrees).",
    ) + [
        "| contour | tool | s | nodes | triangles | quads | contour points kept | area in "
        "quads | quad angles | min scaled Jacobian |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: |",
    ]
    ROOT_ = str(ROOT)
    with tempfile.TemporaryDirectory() as d:
        for name, rel, max_h, box in CASES:
            src = os.path.join(ROOT_, rel)
            res = {t: [] for t in tools}
            for _ in range(args.repeat):
                for tool in tools:
                    out = os.path.join(d, f"{name}_{tool}.msh")
                    dt, _, code, _, err = run_process(commands(tool, src, max_h, box, out))
                    if code != 0:
                        raise SystemExit(f"{tool} failed on {name}: {err}")
                    res[tool].append(dt)
            for tool in tools:
                out = os.path.join(d, f"{name}_{tool}.msh")
                m = asked(__file__, "--measure", out, src)
                lines.append(
                    f"| {name} | {tool} | {statistics.median(res[tool]):.2f} | {m['nodes']} | "
                    f"{m['triangles']} | {m['quads']} | {m['points_kept']} of {m['points']} | "
                    f"{100 * m['share']:.1f}% | {m['min_angle']:.1f}-{m['max_angle']:.1f} | "
                    f"{m['min_sj']:.3f} |"
                )
                print(lines[-1], file=sys.stderr)
    lines += [
        "",
        "In process, on the circle's mesh at each --max-h: `quads.recombine` (candidates, the "
        "assignment, the quads) and `quads.subdivide`, the median of the repeats; the cost "
        "grows with the triangles.",
        "",
        "| --max-h | triangles | recombine s | of it the assignment s | quads | subdivide s |",
        "| ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    lines += scaling(args.repeat)
    write_section("quads", "\n".join(lines))


def scaling(repeat: int) -> list[str]:
    """Rows of the in-process timings of the recombination and the subdivision."""
    import time

    import numpy as np

    from deformesh_cli import pipeline, quads
    from deformesh_cli.options import MeshOptions
    from deformesh_cli.readers import load_contour

    c = load_contour(str(ROOT / "samples" / "circle.csv"))
    rows = []
    for h in (0.05, 0.016, 0.005):
        mesh = pipeline.mesh_contour(c, MeshOptions(max_h=h)).mesh
        a, b, q = quads.candidates(mesh.points, mesh.triangles)
        w = quads.scaled_jacobian(mesh.points, q)
        t_all, t_lap, t_sub = [], [], []
        for _ in range(repeat):
            t0 = time.perf_counter()
            quads.best_matching(len(mesh.triangles), a, b, w)
            t_lap.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            made, _ = quads.recombine(mesh)
            t_all.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            quads.subdivide(made)
            t_sub.append(time.perf_counter() - t0)
        rows.append(
            f"| {h:g} | {len(mesh.triangles)} | {np.median(t_all):.3f} | "
            f"{np.median(t_lap):.3f} | {len(made.quads)} | {np.median(t_sub):.3f} |"
        )
        print(rows[-1], file=sys.stderr)
    return rows


if __name__ == "__main__":
    main()
