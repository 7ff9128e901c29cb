"""The mesh every stage after ``triangulate`` works on: plain numpy arrays."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Mesh:
    """A 2D triangle mesh with its boundary.

    Node numbering: nodes ``0 .. n_contour-1`` are the input contour points in
    input order, then come the extra boundary nodes (in boundary order), then
    the interior nodes.  ``lines`` are the boundary edges, counter-clockwise
    around the domain (the domain is on their left), in boundary order.
    """

    points: np.ndarray  # (n, 2) float64
    triangles: np.ndarray  # (t, 3) int64, counter-clockwise
    lines: np.ndarray  # (l, 2) int64
    n_contour: int
    n_extra: int = 0

    @property
    def n_nodes(self) -> int:
        return len(self.points)
