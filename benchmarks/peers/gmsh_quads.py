"""Peer: Gmsh's Blossom recombination on a contour CSV, as a whole process:

    python gmsh_quads.py IN.csv MAX_H|- XMIN,YMIN,XMAX,YMAX|- OUT.msh

The contour's points are Gmsh points and its edges Gmsh lines, each edge longer than
MAX_H split into equal pieces as deformesh's ``--max-h`` splits it (the same boundary
points); each point's mesh size is its shorter edge (at most MAX_H).  With a box, the
contour is a hole of it (box corners sized a tenth of the box).  Frontal-Delaunay
triangles, then recombined into quads by Blossom (Gmsh's default recombination, a
minimum-cost perfect matching), quad-dominant: no subdivision.
"""

import math
import sys

import gmsh
import numpy as np


def _split(pts: np.ndarray, max_h: float | None) -> np.ndarray:
    """The points with each edge longer than ``max_h`` cut into equal pieces."""
    if max_h is None:
        return pts
    out = []
    for a, b in zip(pts, np.roll(pts, -1, axis=0)):
        k = max(1, math.ceil(float(np.hypot(*(b - a))) / max_h))
        out += [a + (b - a) * (j / k) for j in range(k)]
    return np.array(out)


def main(src, max_h, box, out):
    max_h = None if max_h == "-" else float(max_h)
    pts = np.loadtxt(src, delimiter=",", comments="#", ndmin=2, skiprows=1)[:, :2]
    pts = _split(pts, max_h)
    n = len(pts)
    edge = np.hypot(*(np.roll(pts, -1, axis=0) - pts).T)
    size = np.minimum(edge, np.roll(edge, 1))
    gmsh.initialize(["-nt", "1"])
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    gmsh.option.setNumber("Mesh.RecombineAll", 1)
    gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 1)  # (Blossom)
    if max_h is not None:
        gmsh.option.setNumber("Mesh.MeshSizeMax", max_h)
    geo = gmsh.model.geo
    tags = [geo.addPoint(x, y, 0.0, float(s)) for (x, y), s in zip(pts, size)]
    lines = [geo.addLine(tags[i], tags[(i + 1) % n]) for i in range(n)]
    loops = [geo.addCurveLoop(lines)]
    if box != "-":
        x0, y0, x1, y1 = (float(v) for v in box.split(","))
        far = 0.1 * max(x1 - x0, y1 - y0)
        c = [geo.addPoint(x, y, 0.0, far) for x, y in ((x0, y0), (x1, y0), (x1, y1), (x0, y1))]
        loops.insert(0, geo.addCurveLoop([geo.addLine(c[i], c[(i + 1) % 4]) for i in range(4)]))
    geo.addPlaneSurface(loops)
    geo.synchronize()
    gmsh.model.mesh.generate(2)
    gmsh.write(out)
    gmsh.finalize()


if __name__ == "__main__":
    main(*sys.argv[1:])
