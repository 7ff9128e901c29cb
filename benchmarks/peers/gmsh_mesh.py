"""Peer: Gmsh on a contour CSV, as a whole process: python gmsh_mesh.py IN.csv H OUT.vtk

Frontal-Delaunay (Mesh.Algorithm 6) with target size h at every contour point;
the contour's points are Gmsh points and its edges Gmsh lines, so every point
is a node and every edge is kept (Gmsh may split an edge longer than h).
"""

import sys

import gmsh
import meshio
import numpy as np


def main(src, h, out):
    h = float(h)
    pts = np.loadtxt(src, delimiter=",", comments="#", ndmin=2, skiprows=1)[:, :2]  # x,y header
    gmsh.initialize(["-nt", "1"])
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    geo = gmsh.model.geo
    tags = [geo.addPoint(x, y, 0.0, h) for x, y in pts]
    lines = [geo.addLine(tags[i], tags[(i + 1) % len(tags)]) for i in range(len(tags))]
    geo.addPlaneSurface([geo.addCurveLoop(lines)])
    geo.synchronize()
    gmsh.model.mesh.generate(2)
    _, xyz, _ = gmsh.model.mesh.getNodes()
    xyz = xyz.reshape(-1, 3)
    types, _, conn = gmsh.model.mesh.getElements(2)
    tri = conn[list(types).index(2)].reshape(-1, 3).astype(np.int64)
    tags_all, _, _ = gmsh.model.mesh.getNodes()
    index = np.zeros(int(tags_all.max()) + 1, dtype=np.int64)
    index[tags_all.astype(np.int64)] = np.arange(len(tags_all))
    gmsh.finalize()
    meshio.write(out, meshio.Mesh(xyz, [("triangle", index[tri])]))


if __name__ == "__main__":
    main(*sys.argv[1:])
