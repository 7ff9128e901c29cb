"""Mesh pictures (PNG): triangles shaded by quality, the boundary, a histogram.

matplotlib is optional (``pip install 'deformesh[plot]'``); it is imported
only here, only when a picture is asked for, with the Agg backend.
"""

from __future__ import annotations

import io as _io

import numpy as np

from . import files, geometry, quality
from .errors import DeformeshError, OptionError
from .mesh import as_triangles

#: Colour map of the radius ratio: red = poor (sliver), green = equilateral.
CMAP = "RdYlGn"
BOUNDARY_COLOUR = "#1f3fbf"
#: Colour map of other values (``render``'s ``values``: an adaptation's monitor).
VALUES_CMAP = "viridis"


def _pyplot():
    try:
        import matplotlib
    except ImportError:
        raise DeformeshError("pictures need matplotlib: pip install 'deformesh[plot]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


#: What ``--colour`` shades the triangles by: (measure, its range, histogram bins, label).
COLOURS = {
    "radius-ratio": ("radius ratio 2r/R", 1.0, quality.RR_BINS),
    "angle": ("smallest angle (degrees)", 60.0, np.linspace(0.0, 60.0, 11)),
}

#: The fill of quads (boundary layers), which the triangles' shading does not measure.
QUAD_COLOUR = "#c8d8ec"

#: Pixels across a triangle in view that the resolution aims at (110 to 300 dpi), so
#: that its edges can be told apart.
PIXELS_ACROSS = 6.0

#: ``--zoom contour``: the window is the contour's points' box grown by this share of its
#: larger side on every side.
ZOOM_MARGIN = 0.1


def draw(points: np.ndarray, tri: np.ndarray, path: str, **kw) -> None:
    """Write :func:`render`'s PNG to ``path`` (``-`` = stdout), atomically."""
    files.write_bytes(render(points, tri, **kw), path)


def zoom_window(xy: np.ndarray) -> tuple[float, float, float, float]:
    """The window around the points ``xy``: their box grown by :data:`ZOOM_MARGIN` of its
    larger side."""
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    pad = ZOOM_MARGIN * float(max(hi - lo))
    return (lo[0] - pad, lo[1] - pad, hi[0] + pad, hi[1] + pad)


#: A window side shorter than this share of the mesh's extent draws nothing one can see.
MIN_WINDOW = 1e-9


def clipped_window(points: np.ndarray, window, path: str) -> tuple[float, float, float, float]:
    """``--window`` cut to the mesh's box grown by its extent on every side (a window
    further out shows only white); one that then holds none of that, or has a side
    under :data:`MIN_WINDOW` of the extent, is an :class:`OptionError` naming the file."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    ext = float(max(np.ptp(points, axis=0).max(), np.finfo(float).tiny))
    x0, y0 = max(window[0], lo[0] - ext), max(window[1], lo[1] - ext)
    x1, y1 = min(window[2], hi[0] + ext), min(window[3], hi[1] + ext)
    if not (x1 - x0 >= MIN_WINDOW * ext and y1 - y0 >= MIN_WINDOW * ext):
        raise OptionError(
            f"{path}: --window {','.join(f'{v:g}' for v in window)} shows none of the mesh "
            f"(its box is {lo[0]:g},{lo[1]:g},{hi[0]:g},{hi[1]:g}), or a side under "
            f"{MIN_WINDOW:g} of its extent"
        )
    return float(x0), float(y0), float(x1), float(y1)


def contour_window(
    points: np.ndarray, marked: np.ndarray | None, contour: np.ndarray | None = None
) -> tuple[float, float, float, float] | None:
    """``--zoom contour``'s window: :func:`zoom_window` around the contour's points
    (``contour``, else the nodes ``marked``: :func:`.formats.read.contour_nodes`), or
    None (the whole mesh) where neither says which they are."""
    if contour is None and marked is not None:
        contour = points[marked]
    return None if contour is None or not len(contour) else zoom_window(contour)


def render(
    points: np.ndarray,
    tri: np.ndarray,
    boundary: np.ndarray | None = None,
    contour_points: np.ndarray | None = None,
    title: str = "",
    window: tuple[float, float, float, float] | None = None,
    colour: str = "radius-ratio",
    values: tuple[str, np.ndarray] | None = None,
    quads: np.ndarray | None = None,
) -> bytes:
    """PNG bytes of the mesh.

    ``boundary`` are edges (k, 2) drawn over the mesh (default: the mesh's own
    boundary edges); ``contour_points`` are marked as dots.  ``window``
    (x0, y0, x1, y1): the part drawn, with the whole mesh's outline in an inset where
    the window leaves some out (default: the whole mesh).  Every triangle's edges
    are drawn, thinner as more are in view (rasterised).  ``colour``: a key of
    :data:`COLOURS`; the histogram counts every triangle of the mesh.  ``values``
    (label, one number per triangle) shades by those instead, from their least to
    their largest.  ``quads`` (boundary layers) are drawn in one light colour with
    their edges; the shading and the histogram are the triangles' (a mesh of quads
    alone: the histogram of their smallest scaled Jacobians).
    """
    plt = _pyplot()
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Rectangle

    label, top, bins = COLOURS[colour]
    smallest, largest, _, rr = quality.measures(points, tri)
    value = rr if colour == "radius-ratio" else smallest
    base, cmap_name = 0.0, CMAP
    if values is not None:
        label, value = values[0], np.asarray(values[1], dtype=np.float64)
        base, top = float(value.min()), float(value.max())
        top = top if top > base else base + 1.0
        bins, cmap_name = np.linspace(base, top, 11), VALUES_CMAP
    quads = np.zeros((0, 4), dtype=np.int64) if quads is None else quads
    if boundary is None:
        boundary = geometry.boundary_edges(as_triangles(tri, quads), len(points))
    lo, hi = points.min(axis=0), points.max(axis=0)
    whole = (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))
    view = whole if window is None else tuple(float(v) for v in window)
    shown = _in_view(points[tri], view)
    part = view[0] > whole[0] or view[1] > whole[1] or view[2] < whole[2] or view[3] < whole[3]
    wide, tall = view[2] - view[0], view[3] - view[1]
    height = float(np.clip(7.5 * tall / max(wide, 1e-300), 3.5, 9.0))  # follow the shape
    fig, (ax, axh) = plt.subplots(
        1, 2, figsize=(9.6, height + 0.8), gridspec_kw={"width_ratios": [4.2, 1]}
    )
    cmap = plt.get_cmap(cmap_name)
    t = tri[shown]
    # a triangle in view about PIXELS_ACROSS pixels wide (the plot is some 800 at 110 dpi)
    dpi = float(np.clip(110.0 * PIXELS_ACROSS * np.sqrt(len(t) / 2.0) / 800.0, 110.0, 300.0))
    if len(t):
        ax.tripcolor(
            points[:, 0], points[:, 1], t, facecolors=value[shown], cmap=cmap, vmin=base,
            vmax=top, edgecolors="none", rasterized=True,
        )  # fmt: skip
        edges = np.unique(
            np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), 1), axis=0
        )
        # edges half a pixel wide at the least (about 72 points to the inch)
        lw = float(np.clip(0.4 * np.sqrt(4000.0 / len(t)), 36.0 / dpi, 0.4))
        ax.add_collection(
            LineCollection(points[edges], colors="#202020", linewidths=lw, rasterized=True)
        )
    if len(quads):
        from matplotlib.collections import PolyCollection

        qc = points[quads]
        seen = _in_view(qc, view)
        qlw = float(np.clip(0.4 * np.sqrt(4000.0 / max(seen.sum(), 1)), 36.0 / dpi, 0.4))
        ax.add_collection(
            PolyCollection(
                qc[seen], facecolors=QUAD_COLOUR, edgecolors="#202020", linewidths=qlw,
                rasterized=True,
            )
        )  # fmt: skip
    ax.add_collection(LineCollection(points[boundary], colors=BOUNDARY_COLOUR, linewidths=1.2))
    if contour_points is not None and len(contour_points) <= 5000:
        ax.plot(contour_points[:, 0], contour_points[:, 1], ".", color=BOUNDARY_COLOUR, ms=2.5)
    ax.set_xlim(view[0], view[2])
    ax.set_ylim(view[1], view[3])
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=9)
    ax.tick_params(labelsize=7)
    if part:  # the whole mesh's outline, the window on it
        inset = ax.inset_axes([0.74, 0.74, 0.25, 0.25])
        inset.add_collection(
            LineCollection(points[boundary], colors=BOUNDARY_COLOUR, linewidths=0.6)
        )
        inset.add_patch(
            Rectangle((view[0], view[1]), wide, tall, fill=False, edgecolor="k", linewidth=0.8)
        )
        inset.set_xlim(whole[0], whole[2])
        inset.set_ylim(whole[1], whole[3])
        inset.set_aspect("equal")
        inset.set_xticks([])
        inset.set_yticks([])
        inset.set_facecolor("white")

    what = "triangles"
    if not len(tri) and len(quads):  # (a mesh of quads only: their scaled Jacobians)
        from .quads import scaled_jacobian

        label, value, what = (
            "quads' smallest scaled Jacobian",
            scaled_jacobian(points, quads),
            "quads",
        )
        base, top, bins = 0.0, 1.0, np.linspace(0.0, 1.0, 11)
    counts, edges_ = np.histogram(value, bins=bins)
    mids = 0.5 * (edges_[:-1] + edges_[1:])
    axh.barh(
        mids, counts, height=0.9 * (bins[1] - bins[0]), color=cmap((mids - base) / (top - base))
    )
    axh.set_xscale("log")  # the few poor triangles stay visible next to thousands of good ones
    axh.set_xlim(0.8, max(10, 2 * counts.max()))
    axh.set_ylim(base, top)
    axh.set_ylabel(label, fontsize=8)
    axh.set_xlabel(what, fontsize=8)
    axh.tick_params(labelsize=7)
    if len(tri):
        axh.set_title(f"angles {smallest.min():.1f}-{largest.max():.1f} deg", fontsize=8)
    elif len(quads):  # (a mesh of quads only: their corners' angles)
        from .quads import report as quad_report

        q = quad_report(points, quads, tri)
        axh.set_title(f"quad angles {q['min_angle']:.1f}-{q['max_angle']:.1f} deg", fontsize=8)
    fig.tight_layout()
    buf = _io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def _in_view(corners: np.ndarray, view) -> np.ndarray:
    """Per cell (its ``corners``, (c, k, 2)): whether its bounding box meets ``view``."""
    lo, hi = corners.min(axis=1), corners.max(axis=1)
    return (
        (hi[:, 0] >= view[0])
        & (lo[:, 0] <= view[2])
        & (hi[:, 1] >= view[1])
        & (lo[:, 1] <= view[3])
    )
