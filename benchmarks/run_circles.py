"""How cost grows with the contour: circles of 1,000, 10,000 and 100,000 evenly spaced
points, meshed at default options by ``deformesh all`` and by Triangle ``pq30Y`` (the
same points, no Steiner point on the boundary), each as a whole process writing .vtk.
Seconds and peak memory (``/usr/bin/time``'s maximum resident set), the two tools in
turn in the same run; nodes and the smallest angle of each mesh.  Writes the section
"circles" of benchmarks/RESULTS.md.

Usage: python benchmarks/run_circles.py [--sizes 1000,10000,100000] [--repeat 1]
"""

import argparse
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import meshio
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import heading, write_section
from run_contours import EXE, ROOT

sys.path.insert(0, str(ROOT))
from deformesh_cli.quality import measures

TRIANGLE = """
import sys, meshio, numpy as np, triangle
p = np.loadtxt(sys.argv[1], delimiter=",")
n = len(p)
seg = np.column_stack([np.arange(n), (np.arange(n) + 1) % n])
r = triangle.triangulate({"vertices": p, "segments": seg}, "pq30YQ")
v = r["vertices"]
meshio.write(sys.argv[2], meshio.Mesh(np.column_stack([v, np.zeros(len(v))]),
             [("triangle", r["triangles"])]))
"""


def timed(cmd: list[str]) -> tuple[float, float]:
    """Wall seconds and peak resident megabytes of one process."""
    out = subprocess.run(
        ["/usr/bin/time", "-f", "%e %M", *cmd], capture_output=True, text=True, check=True
    )
    seconds, kb = out.stderr.strip().splitlines()[-1].split()
    return float(seconds), float(kb) / 1024


def describe(path: Path) -> tuple[int, float]:
    m = meshio.read(path)
    tri = m.cells_dict["triangle"]
    return len(m.points), float(measures(m.points[:, :2], tri)[0].min())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1000,10000,100000")
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for n in map(int, args.sizes.split(",")):
            t = np.linspace(0, 2 * np.pi, n, endpoint=False)
            src = tmp / f"circle_{n}.csv"
            np.savetxt(src, np.column_stack([np.cos(t), np.sin(t)]), delimiter=",")
            ours, theirs = [], []
            for _ in range(args.repeat):  # (in turn, so both meet the same load)
                ours.append(timed([EXE, "all", str(src), "-o", str(tmp / "d.vtk"), "-q"]))
                theirs.append(timed([sys.executable, "-c", TRIANGLE, str(src), str(tmp / "t.vtk")]))
            d_nodes, d_angle = describe(tmp / "d.vtk")
            t_nodes, t_angle = describe(tmp / "t.vtk")
            rows.append(
                f"| {n:,} | {statistics.median(s for s, _ in ours):.2f} "
                f"| {max(m for _, m in ours):.0f} | {d_nodes:,} | {d_angle:.1f} "
                f"| {statistics.median(s for s, _ in theirs):.3f} "
                f"| {max(m for _, m in theirs):.0f} | {t_nodes:,} | {t_angle:.1f} |"
            )
            print(rows[-1], flush=True)
    lines = heading(
        "## Circles: how cost grows with the contour (whole processes writing .vtk)",
        f"Evenly spaced points on the unit circle, default options; median of {args.repeat} "
        "run(s), deformesh and Triangle `pq30Y` in turn; peak resident memory in MB.",
    )
    lines += [
        "| points | deformesh s | MB | nodes | min angle | Triangle s | MB | nodes | min angle |",
        "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
        *rows,
    ]
    write_section("circles", "\n".join(lines))


if __name__ == "__main__":
    main()
