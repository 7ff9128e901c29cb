"""The corpus as a user runs it: one whole process per contour, next to Triangle's.

For each contour of tests/data/corpus: ``deformesh all FILE -o m.vtk`` as a process,
and a Triangle ``pq30Y`` process on the same points (python, triangle and meshio
writing .vtk; the points, segments and one point per hole prepared beforehand in an
.npz, as a user's script would hold them), in turn, median of ``--repeat``.  Writes
the ratios' median and largest, and the slowest contours, into the section
"corpus-processes" of benchmarks/RESULTS.md.

Usage: python benchmarks/run_corpus_processes.py [--repeat 3]
"""

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np
import shapely

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import heading, write_section
from run_circles import timed
from run_contours import EXE, ROOT

sys.path.insert(0, str(ROOT))
from deformesh_cli.errors import DeformeshError
from deformesh_cli.readers import load_contour

CORPUS = ROOT / "tests" / "data" / "corpus"

TRIANGLE = """
import sys, meshio, numpy as np, triangle
d = dict(np.load(sys.argv[1]))
if not len(d["holes"]):
    del d["holes"]
r = triangle.triangulate(d, "pq30YQ")
v = r["vertices"]
meshio.write(sys.argv[2], meshio.Mesh(np.column_stack([v, np.zeros(len(v))]),
             [("triangle", r["triangles"])]))
"""


def triangle_input(c, path: Path) -> None:
    segs, holes = [], []
    for r in range(c.n_rings):
        idx = np.arange(c.starts[r], c.starts[r + 1])
        segs.append(np.column_stack([idx, np.roll(idx, -1)]))
        if c.is_hole(r):
            ring = shapely.Polygon(c.points[idx])
            holes.append(shapely.get_coordinates(ring.representative_point())[0])
    np.savez(path, vertices=c.points, segments=np.concatenate(segs),
             holes=np.array(holes).reshape(-1, 2))  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for src in sorted(CORPUS.iterdir()):
            if src.suffix == ".md":
                continue
            try:
                c = load_contour(src)
            except DeformeshError:
                continue
            triangle_input(c, tmp / "t.npz")
            ours, theirs = [], []
            for _ in range(args.repeat):
                try:
                    ours.append(timed([EXE, "all", str(src), "-o", str(tmp / "d.vtk"), "-q"])[0])
                except Exception:  # (refused: a whole process all the same)
                    ours.append(float("nan"))
                theirs.append(
                    timed([sys.executable, "-c", TRIANGLE, str(tmp / "t.npz"), str(tmp / "t.vtk")])[
                        0
                    ]
                )
            d, t = statistics.median(ours), statistics.median(theirs)
            rows.append((d / t, src.name, d, t))
            print(f"{src.name}: {d:.2f} s, Triangle {t:.2f} s", flush=True)
    ok = [r for r in rows if r[0] == r[0]]
    ratios = sorted(r[0] for r in ok)
    lines = heading(
        "## The corpus, one whole process per contour, next to Triangle",
        f"`python benchmarks/run_corpus_processes.py --repeat {args.repeat}`: each contour "
        "of tests/data/corpus meshed by `deformesh all FILE -o m.vtk` and by a Triangle "
        "`pq30Y` process (python, triangle, meshio) on the same points, in turn; the "
        "median of the runs.",
    )
    lines += [
        f"Contours: {len(ok)} meshed.  Our time over Triangle's: median "
        f"{statistics.median(ratios):.2f}, largest {ratios[-1]:.2f}; ours median "
        f"{statistics.median(r[2] for r in ok):.2f} s, Triangle's "
        f"{statistics.median(r[3] for r in ok):.2f} s.",
        "",
        "| slowest against Triangle | deformesh s | Triangle s | ratio |",
        "| --- | ---: | ---: | ---: |",
    ]
    for ratio, name, d, t in sorted(ok, reverse=True)[:8]:
        lines.append(f"| {name} | {d:.2f} | {t:.2f} | {ratio:.2f} |")
    write_section("corpus-processes", "\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
