"""Peer: Triangle on a contour CSV, as a whole process: python triangle_mesh.py IN.csv H OUT.vtk

Triangle's switches `pq30a<h^2/2>Y`: a planar straight-line graph (the contour's
edges as segments), quality (30 degree minimum angle), area bound h^2/2 (a grid
cell's triangle), and -Y: no Steiner points on the boundary, so its boundary
nodes are exactly the contour's points, as with deformesh.
"""

import sys

import meshio
import numpy as np
import triangle


def main(src, h, out):
    h = float(h)
    pts = np.loadtxt(src, delimiter=",", comments="#", ndmin=2, skiprows=1)[:, :2]  # x,y header
    n = len(pts)
    seg = np.column_stack([np.arange(n), (np.arange(n) + 1) % n])
    res = triangle.triangulate({"vertices": pts, "segments": seg}, f"pq30a{h * h / 2:.15f}Y")
    meshio.write(
        out,
        meshio.Mesh(
            np.column_stack([res["vertices"], np.zeros(len(res["vertices"]))]),
            [("triangle", res["triangles"])],
        ),
    )


if __name__ == "__main__":
    main(*sys.argv[1:])
