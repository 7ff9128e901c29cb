"""Draw meshes to PNG for a visual check: python scripts/look.py OUT.png MESH [CONTOUR] ..."""

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import meshio  # noqa: E402
import numpy as np  # noqa: E402

from deformesh_cli.contour import load_contour  # noqa: E402


def main(out, *pairs):
    n = len(pairs) // 2
    fig, axes = plt.subplots(1, n, figsize=(6 * n, 6))
    axes = np.atleast_1d(axes)
    for ax, mesh_path, contour_path in zip(axes, pairs[::2], pairs[1::2]):
        m = meshio.read(mesh_path)
        tri = m.cells_dict["triangle"]
        ax.triplot(m.points[:, 0], m.points[:, 1], tri, lw=0.4, color="k")
        c = load_contour(contour_path).points
        c = np.vstack([c, c[:1]])
        ax.plot(c[:, 0], c[:, 1], "r-", lw=0.8)
        ax.plot(c[:, 0], c[:, 1], "r.", ms=3)
        ax.set_aspect("equal")
        ax.set_title(mesh_path)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main(*sys.argv[1:])
