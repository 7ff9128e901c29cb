"""Boundary layers next to Gmsh's BoundaryLayer field, as whole processes.

Usage: python benchmarks/run_layers.py [--repeat N]

samples/naca0012.csv in the box -20,-20,21,20 with 30 layers from a first height of
1e-5 growing by 1.15: ``deformesh all ... --layers 30 --first-height 1e-5
--layer-growth 1.15 -o OUT.msh`` (and again with ``--cells quad-only``) and
``benchmarks/peers/gmsh_layers.py`` (the same
points, the same first height, ratio and thickness, quads, fans at the trailing
edge's corners), in turn, the median of N runs each.  Both files are measured by
one code (:func:`measure`), which reads no cell order: the contour's points found
among the nodes, the extra nodes on the body's boundary, the cells, and at each
wall node with one edge into the domain (the others are fans') that edge's length
(the first height) and its angle with the wall edges; a quad's aspect ratio is its
longer over its shorter pair of opposite sides (each pair's mean).
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
SAMPLE = ROOT / "samples" / "naca0012.csv"
BOX = "-20,-20,21,20"
LAYERS, FIRST, GROWTH = 30, 1e-5, 1.15


def measure(mesh_path: str, contour_path: str) -> dict:
    import numpy as np

    from deformesh_cli.geometry import boundary_edges

    p, tri, quads, found = read_cells(mesh_path, contour_path)
    split = np.concatenate([tri, quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    bnd = boundary_edges(split, len(p))
    lo, hi = p.min(axis=0), p.max(axis=0)
    on_box = ((p[bnd] == lo) | (p[bnd] == hi)).any(axis=2).all(axis=1)
    body = bnd[~on_box]
    body_nodes = np.unique(body)
    # every cell edge, once; those on the boundary left out
    edges = np.concatenate(
        [tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]
        + [quads[:, [k, (k + 1) % 4]] for k in range(4)]
    )
    edges = np.unique(np.sort(edges, axis=1), axis=0)
    bkey = set(map(tuple, np.sort(bnd, axis=1).tolist()))
    inner = np.array([e for e in edges.tolist() if tuple(e) not in bkey])
    nxt = dict(zip(body[:, 0].tolist(), body[:, 1].tolist()))
    prv = dict(zip(body[:, 1].tolist(), body[:, 0].tolist()))
    leaving = {}
    for a, b in inner.tolist():
        for u, v in ((a, b), (b, a)):
            if u in nxt:
                leaving.setdefault(u, []).append(v)
    angles, first = [], []
    fans = 0
    for w in body_nodes.tolist():
        out = leaving.get(w, [])
        if len(out) != 1:
            fans += 1
            continue
        up = p[out[0]] - p[w]
        h = float(np.hypot(*up))
        first.append(h)
        best = 90.0
        for t in (p[nxt[w]] - p[w], p[prv[w]] - p[w]):
            cos = abs(float(np.dot(up, t))) / (h * float(np.hypot(*t)))
            best = min(best, float(np.degrees(np.arccos(min(cos, 1.0)))))
        angles.append(best)
    q = p[quads]

    def side(a, b):
        return np.hypot(*(q[:, b] - q[:, a]).T)

    one = 0.5 * (side(0, 1) + side(2, 3))
    two = 0.5 * (side(1, 2) + side(3, 0))
    aspect = np.maximum(one, two) / np.minimum(one, two)
    return {
        "nodes": len(p),
        "triangles": len(tri),
        "quads": len(quads),
        "points_kept": int(sum(k >= 0 for k in found)),
        "points": len(found),
        "extra": int(len(body_nodes) - sum(k >= 0 for k in found)),
        "fans": fans,
        "min_wall_angle": min(angles) if angles else None,
        "first_height": [min(first), max(first)] if first else None,
        "max_aspect": float(aspect.max()) if len(quads) else None,
    }


#: The rows: deformesh's default cells, deformesh in quads alone, Gmsh.
TOOLS = ("deformesh", "deformesh quad-only", "gmsh")


def commands(tool: str, out: str) -> list[str]:
    if tool.startswith("deformesh"):
        return [
            EXE, "all", str(SAMPLE), "--exterior", f"--box={BOX}", "--layers", str(LAYERS),
            "--first-height", repr(FIRST), "--layer-growth", repr(GROWTH), "-o", out, "-q",
            *(["--cells", "quad-only"] if tool.endswith("quad-only") else []),
        ]  # fmt: skip
    return [PY, str(PEERS / "gmsh_layers.py"), plain_csv(SAMPLE), BOX, str(LAYERS), repr(FIRST),
            repr(GROWTH), out]  # fmt: skip


def main():
    if answered("--measure", measure):
        return
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    tools = TOOLS
    res = {t: {"times": [], "rss": 0.0} for t in tools}
    with tempfile.TemporaryDirectory() as d:
        for _ in range(args.repeat):
            for tool in tools:
                out = os.path.join(d, f"{tool.replace(' ', '_')}.msh")
                dt, rss, code, _, err = run_process(commands(tool, out))
                if code != 0:
                    raise SystemExit(f"{tool} failed: {err}")
                res[tool]["times"].append(dt)
                res[tool]["rss"] = max(res[tool]["rss"], rss)
        for tool in tools:
            out = os.path.join(d, f"{tool.replace(' ', '_')}.msh")
            res[tool]["m"] = asked(__file__, "--measure", out, SAMPLE)
    lines = heading(
        f"## Boundary layers next to Gmsh's BoundaryLayer field (whole processes, median of "
        f"{args.repeat})",
        f"`python benchmarks/run_layers.py`: samples/naca0012.csv (160 points, blunt "
        f"trailing edge) in the box {BOX}, {LAYERS} layers from a first height of {FIRST:g} "
        f"growing by {GROWTH:g}, quads (and with `--cells quad-only`, quads alone: the "
        "layers cut along the wall only), written as .msh; Gmsh 4 with the same points, first "
        "size, ratio and thickness, fans at the trailing edge's corners "
        "(benchmarks/peers/gmsh_layers.py). One code measures both files: the wall angle "
        "and first height at each wall node with one edge into the domain (fans left out), "
        "a quad's aspect ratio as its longer over its shorter pair of opposite sides.",
    ) + [
        "| tool | s | MB | nodes | triangles | quads | contour points kept | extra wall "
        "nodes | fan nodes | min wall angle | first height | max aspect ratio |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: |",
    ]
    for tool in tools:
        r, m = res[tool], res[tool]["m"]
        h = m["first_height"]
        lines.append(
            f"| {tool} | {statistics.median(r['times']):.2f} | {r['rss']:.0f} | {m['nodes']} | "
            f"{m['triangles']} | {m['quads']} | {m['points_kept']} of {m['points']} | "
            f"{m['extra']} | {m['fans']} | {m['min_wall_angle']:.1f} | "
            f"{h[0]:.3g}-{h[1]:.3g} | {m['max_aspect']:.0f} |"
        )
        print(lines[-1], file=sys.stderr)
    write_section("layers", "\n".join(lines))


if __name__ == "__main__":
    main()
