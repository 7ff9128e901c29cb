"""The mesh contract, checked with numpy and shapely only (none of deformesh's code):
what a user's own script would check on a mesh file it was given."""

from __future__ import annotations

import numpy as np
import shapely


def domain(points: np.ndarray, ring: np.ndarray):
    """The region the rings bound, by the even-odd rule (holes, parts)."""
    region = shapely.Polygon()
    for r in np.unique(ring):
        region = region.symmetric_difference(shapely.Polygon(points[ring == r]))
    return region


def contract_problems(
    nodes: np.ndarray, triangles: np.ndarray, points: np.ndarray, ring: np.ndarray
) -> list[str]:
    """What is wrong with a mesh of the contour ``points`` (rings ``ring``); [] if nothing.

    Node k is contour point k; no triangle folded or degenerate; the triangles cover
    the domain (their areas add up to its area, each one inside it); the mesh's
    boundary edges lie on the contour and add up to its length (so every contour edge
    is there, whole or split at extra nodes)."""
    out = []
    m = len(points)
    if len(nodes) < m or not np.array_equal(nodes[:m, :2], points):
        out.append("node k is not contour point k")
        return out
    p = nodes[:, :2]
    a, b, c = p[triangles[:, 0]], p[triangles[:, 1]], p[triangles[:, 2]]
    area = 0.5 * (
        (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    )
    if not (area > 0).all():
        out.append(f"{np.count_nonzero(area <= 0)} triangle(s) folded or flat")
    region = domain(points, ring)
    scale = max(np.ptp(points, axis=0))
    if abs(area.sum() - region.area) > 1e-9 * max(region.area, scale**2):
        out.append(
            f"triangle areas add up to {area.sum():.12g}, the domain's is {region.area:.12g}"
        )
    cen = (a + b + c) / 3
    inside = shapely.contains_xy(region.buffer(1e-9 * scale), cen[:, 0], cen[:, 1])
    if not inside.all():
        out.append(f"{np.count_nonzero(~inside)} triangle(s) outside the domain")
    e = np.sort(
        np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1
    )
    edges, count = np.unique(e, axis=0, return_counts=True)
    if (count > 2).any():
        out.append("an edge shared by more than two triangles")
    border = edges[count == 1]
    lines = shapely.MultiLineString(
        [points[ring == r][np.r_[0 : (ring == r).sum(), 0]] for r in np.unique(ring)]
    )
    mid = 0.5 * (p[border[:, 0]] + p[border[:, 1]])
    off = shapely.distance(lines, shapely.points(mid))
    if (off > 1e-9 * scale).any():
        out.append(f"{np.count_nonzero(off > 1e-9 * scale)} boundary edge(s) off the contour")
    length = np.hypot(*(p[border[:, 0]] - p[border[:, 1]]).T).sum()
    if abs(length - lines.length) > 1e-9 * lines.length:
        out.append(
            f"boundary edges add up to {length:.12g}, the contour's length is {lines.length:.12g}"
        )
    return out
