"""Draw docs/meshes.png (README's first picture): python scripts/meshes.py OUT.png

The paper's example on its uniform grid (``--h 1 --box 1,1,9,12``, Appendix A's
P1..P18) and samples/circle.csv at default options (the graded grid), each with
its contour points in red.
"""

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from deformesh_cli import mesh_contour
from deformesh_cli.readers import load_contour

ROOT = Path(__file__).resolve().parent.parent
PANELS = [
    ("paper_example.csv", {"h": 1.0, "box": (1, 1, 9, 12)}, "--h 1 --box 1,1,9,12"),
    ("circle.csv", {}, "default options"),
]


def main(out: str) -> None:
    fig, axes = plt.subplots(1, len(PANELS), figsize=(10, 5))
    for ax, (name, options, label) in zip(axes, PANELS):
        c = load_contour(ROOT / "samples" / name)
        m = mesh_contour(c, **options).mesh
        ax.triplot(m.points[:, 0], m.points[:, 1], m.triangles, lw=0.4, color="0.3")
        ring = list(range(c.n)) + [0]
        ax.plot(c.points[ring, 0], c.points[ring, 1], "-", color="tab:red", lw=1)
        ax.plot(c.points[:, 0], c.points[:, 1], ".", color="tab:red", ms=4)
        ax.set_title(f"{name}, {label}: {m.n_nodes} nodes", fontsize=9)
        ax.set_aspect("equal")
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(out, dpi=80)


if __name__ == "__main__":
    main(sys.argv[1])
