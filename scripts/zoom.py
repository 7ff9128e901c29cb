"""Draw a mesh whole and zoomed: python scripts/zoom.py OUT.png MESH CONTOUR CX,CY,HALF ...

Each CX,CY,HALF adds a panel showing the square of half-width HALF around (CX, CY);
quads (boundary layers) are filled.  Used for docs/farfield.png and docs/layers.png.
"""

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import meshio

from deformesh_cli.readers import load_contour


def main(out, mesh_path, contour_path, *windows):
    from matplotlib.collections import PolyCollection

    m = meshio.read(mesh_path)
    tri = m.cells_dict["triangle"]
    quads = m.cells_dict.get("quad")
    c = load_contour(contour_path).points
    fig, axes = plt.subplots(1, len(windows), figsize=(5 * len(windows), 5), squeeze=False)
    axes = axes[0]
    for ax, w in zip(axes, windows):
        cx, cy, half = (float(v) for v in w.split(","))
        ax.triplot(m.points[:, 0], m.points[:, 1], tri, lw=0.3, color="k")
        if quads is not None:  # (boundary layers)
            ax.add_collection(
                PolyCollection(m.points[quads, :2], facecolors="#c8d8ec", edgecolors="k", lw=0.2)
            )
        ax.plot(c[:, 0], c[:, 1], "r.", ms=2)
        ax.set_xlim(cx - half, cx + half)
        ax.set_ylim(cy - half, cy + half)
        ax.set_aspect("equal")
        ax.set_title(f"({cx:g}, {cy:g}) +- {half:g}")
    fig.tight_layout()
    fig.savefig(out, dpi=80)


if __name__ == "__main__":
    main(*sys.argv[1:])
