"""The graded background grid next to Triangle ``pq30Y`` on the same points.

Usage: python benchmarks/run_graded.py   (make bench; needs the bench extra)

For each contour, the graded quadtree background (``select/graded.py``) is built
for a few growth rates and cell factors, and its nodes in the domain (inside the
contour, or for a far field in the box outside it) are counted, next to the
nodes of Triangle ``pq30Y`` on the same points: a planar straight-line graph of
the contour (and the box), 30 degree minimum angle, no area bound (Triangle
grades as fast as its angle rule lets it) and no Steiner point on the boundary.
The background's nodes bound what the mesh will hold once the grid is cut, so
the ratio says which growth and factor can meet "at most 3 times Triangle's
nodes".  Seconds: building and triangulating the quadtree, in this process.

Then whole meshes: deformesh at default options and with ``--grid graded``,
next to Triangle ``pq30Y`` on the same points (nodes, triangles, seconds,
smallest angle, boundary nodes beyond the input), for the samples, the
reference contours, the two far fields and the corpus.
"""

import statistics
import sys
import time
from pathlib import Path

import numpy as np
import shapely

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import heading, write_section
from run_contours import REFERENCE, ROOT

from deformesh_cli.readers import load_contour
from deformesh_cli.select import graded

#: (growth, cell factor); the first is the default
SETTINGS = [(2.0, 1.0), (1.5, 1.0), (3.0, 1.0), (2.0, 0.8)]
SAMPLES = ["peanut.csv", "circle.csv", "half_disk.csv", "naca0012.csv", "bracket.svg"]
REFERENCES = ["circle_1000.csv", "bean_1000.csv", "star_1000.csv", "naca0012_1000.csv",
              "square_hole_100.csv", "channel_100.csv"]  # fmt: skip
FAR_FIELDS = [(-20, -20, 21, 20), (-50, -50, 51, 50)]


def triangle_run(c, box=None) -> dict:
    """Triangle ``pq30Y`` on the contour's points (and the box's corners, as segments):
    nodes, triangles, seconds, smallest angle and boundary nodes beyond the input."""
    import triangle

    from deformesh_cli.quality import measures

    pts, segs, holes = [c.points], [], []
    for r in range(c.n_rings):
        idx = np.arange(c.starts[r], c.starts[r + 1])
        segs.append(np.column_stack([idx, np.roll(idx, -1)]))
        ring = shapely.Polygon(c.points[idx])
        if c.is_hole(r) or box is not None:
            holes.append(shapely.get_coordinates(ring.representative_point())[0])
    n_in = c.n
    if box is not None:
        x0, y0, x1, y1 = box
        n = c.n
        pts.append(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))
        segs.append(n + np.column_stack([np.arange(4), (np.arange(4) + 1) % 4]))
        n_in += 4
    d = {"vertices": np.concatenate(pts), "segments": np.concatenate(segs)}
    if holes:
        d["holes"] = np.array(holes)
    t0 = time.perf_counter()
    out = triangle.triangulate(d, "pq30Y")
    dt = time.perf_counter() - t0
    v, t = out["vertices"], out["triangles"]
    marked = int(np.count_nonzero(out.get("vertex_markers", np.zeros(len(v))).ravel()))
    return {
        "nodes": len(v),
        "triangles": len(t),
        "seconds": dt,
        "min_angle": float(measures(v, t)[0].min()),
        "extra": max(0, marked - n_in),
    }


def domain_nodes(c, pts, box=None) -> int:
    rings = [c.points[c.starts[r] : c.starts[r + 1]] for r in range(c.n_rings)]
    polys = [shapely.Polygon(r) for r in rings]
    inside = np.zeros(len(pts), dtype=bool)
    for p in polys:
        hit = shapely.contains_xy(p, pts[:, 0], pts[:, 1])
        inside ^= hit  # even-odd: holes and islands
    on = shapely.intersects_xy(shapely.MultiLineString(rings), pts[:, 0], pts[:, 1])
    keep = ~inside if box is not None else inside
    return int((keep & ~on).sum() + c.n)


def cases():
    for name in SAMPLES:
        yield f"samples/{name}", load_contour(ROOT / "samples" / name), None
    for name in REFERENCES:
        yield name, load_contour(REFERENCE / name), None
    naca = load_contour(ROOT / "samples" / "naca0012.csv")
    for box in FAR_FIELDS:
        yield f"samples/naca0012.csv far field {box}", naca, box
    for p in sorted((ROOT / "tests" / "data" / "corpus").glob("*")):
        if p.suffix in (".csv", ".svg"):
            try:
                yield f"corpus/{p.name}", load_contour(p), None
            except Exception:  # the two invalid icons: refused before any grid
                continue


def _deformesh(c, box, **kw) -> dict | None:
    from deformesh_cli import mesh_contour

    if box is not None:
        kw.update(exterior=True, box=box)
    t0 = time.perf_counter()
    try:
        r = mesh_contour(c, **kw).report
    except Exception:  # a refusal: reported as such
        return None
    r["seconds"] = time.perf_counter() - t0
    return r


def _cells(r: dict | None) -> str:
    if r is None:
        return "refused | | | | | "
    return (f"{r['h_rule']} | {r['nodes']} | {r['triangles']} | {r['seconds']:.2f} | "
            f"{r['min_angle']:.1f} | {r['extra_boundary_nodes']}")  # fmt: skip


def meshes() -> list[str]:
    """Whole meshes, deformesh at default options and with ``--grid graded`` (in this
    process, after a warm-up), next to Triangle ``pq30Y`` on the same points."""
    from deformesh_cli import mesh_contour

    out = [
        "Whole meshes on the same points: deformesh at default options and with "
        "`--grid graded` (seconds in this process, after a warm-up; `grid` is the h_rule, "
        "which says where the graded path did not fit and `all` fell back), and "
        "Triangle `pq30Y` (no area bound; `Y`: no Steiner point on the boundary). "
        "Extra = boundary nodes beyond the input points.",
        "",
        "| contour | default: grid | nodes | triangles | seconds | min angle | extra "
        "| graded: grid | nodes | triangles | seconds | min angle | extra "
        "| Triangle: nodes | triangles | seconds | min angle | graded / Triangle nodes |",
        "| --- | --- |" + " ---: |" * 5 + " --- |" + " ---: |" * 5 + " ---: |" * 5,
    ]
    mesh_contour(load_contour(ROOT / "samples" / "circle.csv"), grid="graded")  # warm-up
    corpus = {"meshed": 0, "on the graded grid": 0, "no extra node": 0, "over 3 s": 0}
    default_zero = 0
    ratios = []
    for name, c, box in cases():
        tri = triangle_run(c, box)
        default = _deformesh(c, box)
        graded_ = _deformesh(c, box, grid="graded")
        ratio = "" if graded_ is None else f"{graded_['nodes'] / tri['nodes']:.2f}"
        out.append(
            f"| {name} | {_cells(default)} | {_cells(graded_)} | {tri['nodes']} | "
            f"{tri['triangles']} | {tri['seconds']:.3f} | {tri['min_angle']:.1f} | {ratio} |"
        )
        print(name, ratio, file=sys.stderr)
        if name.startswith("corpus/") and graded_ is not None:
            corpus["meshed"] += 1
            corpus["on the graded grid"] += graded_["h_rule"].startswith("graded")
            corpus["no extra node"] += graded_["extra_boundary_nodes"] == 0
            corpus["over 3 s"] += graded_["seconds"] > 3
            ratios.append(graded_["nodes"] / tri["nodes"])
            default_zero += default is not None and default["extra_boundary_nodes"] == 0
    out += [
        "",
        "The corpus (tests/data/corpus, its 48 valid contours) with `--grid graded`: "
        + ", ".join(f"{k} {v}" for k, v in corpus.items())
        + f"; median nodes over Triangle's {statistics.median(ratios):.2f}. At default "
        f"options {default_zero} have no extra node.",
    ]
    return out


def main() -> None:
    rows, ratios = [], {s: [] for s in SETTINGS}
    for name, c, box in cases():
        lo, hi = c.points.min(axis=0), c.points.max(axis=0)
        e = float((hi - lo).max())
        grid_box = box or (lo[0] - 0.1 * e, lo[1] - 0.1 * e, hi[0] + 0.1 * e, hi[1] + 0.1 * e)
        tri = triangle_run(c, box)["nodes"]
        cells = []
        for growth, factor in SETTINGS:
            t0 = time.perf_counter()
            q = graded.build(c, grid_box, growth=growth, factor=factor, box_given=box is not None)
            pts, _, _ = q.triangulate()
            dt = time.perf_counter() - t0
            n = domain_nodes(c, pts, box)
            ratios[(growth, factor)].append((name, n / tri))
            cells.append(f"{n} ({n / tri:.1f}x, {dt:.2f} s)")
        rows.append(f"| {name} | {c.n} | {tri} | " + " | ".join(cells) + " |")
        print(name, tri, cells, file=sys.stderr)
    head = " | ".join(f"growth {g}, factor {f}" for g, f in SETTINGS)
    lines = heading(
        "## Graded grid: background nodes next to Triangle pq30Y (same points)",
        "Nodes of the graded background in the domain (inside the contour; for a far "
        "field, in the box outside it), with the ratio to Triangle `pq30Y`'s nodes on the "
        "same points and the seconds to build and triangulate the quadtree. The mesh "
        "keeps about these nodes once the grid is cut.",
    ) + [f"| contour | points | Triangle pq30Y nodes | {head} |",
         "| --- | ---: | ---: |" + " ---: |" * len(SETTINGS)]  # fmt: skip
    lines += rows
    lines += ["", "| setting | median ratio | corpus median ratio | worst ratio (contour) |",
              "| --- | ---: | ---: | --- |"]  # fmt: skip
    for s in SETTINGS:
        r = ratios[s]
        corpus = [v for n, v in r if n.startswith("corpus/")]
        worst = max(r, key=lambda t: t[1])
        lines.append(
            f"| growth {s[0]}, factor {s[1]} | {statistics.median(v for _, v in r):.2f} | "
            f"{statistics.median(corpus):.2f} | {worst[1]:.1f} ({worst[0]}) |"
        )
    lines += ["", *meshes()]
    write_section("graded", "\n".join(lines))


if __name__ == "__main__":
    main()
