"""Draw frames of a moving mesh side by side (README, "deformesh move").

Usage: python scripts/frames.py OUT.png XMIN,YMIN,XMAX,YMAX FRAME_FILE...

Each panel shows one frame file (as ``deformesh move`` writes them) inside the
window, its contour nodes in red, titled with its name and smallest angle.
"""

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import meshio

from deformesh_cli.quality import measures


def main(out, window, *files):
    x0, y0, x1, y1 = (float(v) for v in window.split(","))
    fig, axes = plt.subplots(
        1, len(files), figsize=(4 * len(files), 4 * (y1 - y0) / (x1 - x0)), squeeze=False
    )
    for ax, f in zip(axes[0], files):
        m = meshio.read(f)
        tri = m.cells_dict["triangle"]
        pts = m.points[:, :2]
        contour = m.point_data["contour_point"] >= 0
        ax.triplot(pts[:, 0], pts[:, 1], tri, lw=0.3, color="k")
        ax.plot(pts[contour, 0], pts[contour, 1], "r.", ms=2)
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(f"{Path(f).stem}: min angle {measures(pts, tri)[0].min():.1f} deg", fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=80)


if __name__ == "__main__":
    main(*sys.argv[1:])
