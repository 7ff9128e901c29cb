"""Mesh pictures (PNG): triangles shaded by quality, the boundary, a histogram.

matplotlib is optional (``pip install 'deformesh[plot]'``); it is imported
only here, only when a picture is asked for, with the Agg backend.
"""

from __future__ import annotations

import io as _io

import numpy as np

from . import files, geometry, quality
from .errors import DeformeshError

#: Colour map of the radius ratio: red = poor (sliver), green = equilateral.
CMAP = "RdYlGn"
BOUNDARY_COLOUR = "#1f3fbf"


def _pyplot():
    try:
        import matplotlib
    except ImportError:
        raise DeformeshError("pictures need matplotlib: pip install 'deformesh[plot]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def draw(points: np.ndarray, tri: np.ndarray, path: str, **kw) -> None:
    """Write :func:`render`'s PNG to ``path`` (``-`` = stdout), atomically."""
    files.write_bytes(render(points, tri, **kw), path)


def render(
    points: np.ndarray,
    tri: np.ndarray,
    boundary: np.ndarray | None = None,
    contour_points: np.ndarray | None = None,
    title: str = "",
) -> bytes:
    """PNG bytes of the mesh.

    ``boundary`` are edges (k, 2) drawn over the mesh (default: the mesh's own
    boundary edges); ``contour_points`` are marked as dots.
    """
    plt = _pyplot()
    from matplotlib.collections import LineCollection

    smallest, largest, _, rr = quality.measures(points, tri)
    if boundary is None:
        boundary = geometry.boundary_edges(tri, len(points))
    span = np.ptp(points, axis=0)
    height = float(np.clip(7.5 * span[1] / max(span[0], 1e-300), 3.5, 9.0))  # follow the shape
    fig, (ax, axh) = plt.subplots(
        1, 2, figsize=(9.6, height + 0.8), gridspec_kw={"width_ratios": [4.2, 1]}
    )
    lw = 0.4 if len(tri) < 4000 else 0.15 if len(tri) < 40000 else 0.0
    ax.tripcolor(
        points[:, 0],
        points[:, 1],
        tri,
        facecolors=rr,
        cmap=CMAP,
        vmin=0,
        vmax=1,
        edgecolors="k" if lw else "none",
        linewidth=lw,
    )
    ax.add_collection(LineCollection(points[boundary], colors=BOUNDARY_COLOUR, linewidths=1.2))
    if contour_points is not None and len(contour_points) <= 5000:
        ax.plot(contour_points[:, 0], contour_points[:, 1], ".", color=BOUNDARY_COLOUR, ms=2.5)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=9)
    ax.tick_params(labelsize=7)

    counts, edges = np.histogram(rr, bins=quality.RR_BINS)
    mids = 0.5 * (edges[:-1] + edges[1:])
    axh.barh(mids, counts, height=0.09, color=plt.get_cmap(CMAP)(mids))
    axh.set_xscale("log")  # the few poor triangles stay visible next to thousands of good ones
    axh.set_xlim(0.8, max(10, 2 * counts.max()))
    axh.set_ylim(0, 1)
    axh.set_ylabel("radius ratio 2r/R", fontsize=8)
    axh.set_xlabel("triangles", fontsize=8)
    axh.tick_params(labelsize=7)
    axh.set_title(f"angles {smallest.min():.1f}-{largest.max():.1f} deg", fontsize=8)
    fig.tight_layout()
    buf = _io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()
