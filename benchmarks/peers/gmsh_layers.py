"""Peer: Gmsh's BoundaryLayer field on a contour CSV in a far-field box, as a whole process:

    python gmsh_layers.py IN.csv XMIN,YMIN,XMAX,YMAX LAYERS FIRST GROWTH OUT.msh

The contour's points are Gmsh points and its edges Gmsh lines (the body is a hole of
the box); each point's mesh size is its shorter edge, the box corners' a tenth of the
box.  The BoundaryLayer field on the body's lines: first size FIRST, ratio GROWTH,
thickness that of LAYERS layers, quads (recombined), a fan at every point where the
contour turns away from the domain by more than 20 degrees (as deformesh's), set as
the boundary layer of the 2D mesh (Frontal-Delaunay).
"""

import math
import sys

import gmsh
import numpy as np


def main(src, box, layers, first, growth, out):
    layers, first, growth = int(layers), float(first), float(growth)
    x0, y0, x1, y1 = (float(v) for v in box.split(","))
    pts = np.loadtxt(src, delimiter=",", comments="#", ndmin=2, skiprows=1)[:, :2]
    n = len(pts)
    edge = np.hypot(*(np.roll(pts, -1, axis=0) - pts).T)
    size = np.minimum(edge, np.roll(edge, 1))
    thickness = first * (growth**layers - 1) / (growth - 1) if growth != 1 else first * layers
    gmsh.initialize(["-nt", "1"])
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    geo = gmsh.model.geo
    tags = [geo.addPoint(x, y, 0.0, float(s)) for (x, y), s in zip(pts, size)]
    lines = [geo.addLine(tags[i], tags[(i + 1) % n]) for i in range(n)]
    far = 0.1 * max(x1 - x0, y1 - y0)
    corners = [geo.addPoint(x, y, 0.0, far) for x, y in ((x0, y0), (x1, y0), (x1, y1), (x0, y1))]
    sides = [geo.addLine(corners[i], corners[(i + 1) % 4]) for i in range(4)]
    geo.addPlaneSurface([geo.addCurveLoop(sides), geo.addCurveLoop(lines)])
    geo.synchronize()
    # the fans: where the body's outline turns away from the domain (outside it) by more
    # than 20 degrees; the contour is walked counter-clockwise, the domain outside
    ccw = 0.5 * float(
        np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1])
    )
    t = np.roll(pts, -1, axis=0) - pts
    t_in = np.roll(t, 1, axis=0)
    turn = np.arctan2(t_in[:, 0] * t[:, 1] - t_in[:, 1] * t[:, 0], (t_in * t).sum(axis=1))
    turn = turn if ccw > 0 else -turn  # (left turns of a counter-clockwise walk)
    fans = [tags[i] for i in np.flatnonzero(turn > math.radians(20.0))]
    f = gmsh.model.mesh.field.add("BoundaryLayer")
    gmsh.model.mesh.field.setNumbers(f, "CurvesList", lines)
    gmsh.model.mesh.field.setNumber(f, "Size", first)
    gmsh.model.mesh.field.setNumber(f, "Ratio", growth)
    gmsh.model.mesh.field.setNumber(f, "Thickness", thickness)
    gmsh.model.mesh.field.setNumber(f, "Quads", 1)
    if fans:
        gmsh.model.mesh.field.setNumbers(f, "FanPointsList", fans)
    gmsh.model.mesh.field.setAsBoundaryLayer(f)
    gmsh.model.mesh.generate(2)
    gmsh.write(out)
    gmsh.finalize()


if __name__ == "__main__":
    main(*sys.argv[1:])
