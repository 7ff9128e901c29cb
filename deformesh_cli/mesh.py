"""The mesh every stage after ``triangulate`` works on: plain numpy arrays."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Mesh:
    """A 2D triangle mesh with its boundary.

    Node numbering: nodes ``0 .. n_contour-1`` are the input contour points in
    input order, then come the extra boundary nodes (in boundary order), then
    the nodes on the box sides of an exterior mesh (counter-clockwise from
    the lower left corner), then the interior nodes.  ``lines`` are the
    boundary edges with the domain on their left, ring by ring in boundary
    order; ``line_group[e]`` indexes ``groups``, the boundary names
    (``contour``, ``hole_1``, ..., and ``bottom``, ``right``, ``top``,
    ``left`` for the box of an exterior mesh).  The triangles form the 2D
    group ``domain``, with the ``quads`` (counter-clockwise, convex) where
    boundary layers put them.
    """

    points: np.ndarray  # (n, 2) float64
    triangles: np.ndarray  # (t, 3) int64, counter-clockwise
    lines: np.ndarray  # (l, 2) int64
    n_contour: int
    n_extra: int = 0
    line_group: np.ndarray | None = None  # (l,) int64
    groups: tuple[str, ...] = field(default=("contour",))
    n_box: int = 0
    #: extra per-node arrays to write with the mesh where the format has point data
    #: (.vtk, .vtu, .xdmf): name -> (n,) or (n, k) array (``move``: ``velocity``)
    point_data: dict = field(default_factory=dict)
    #: (q, 4) int64: quadrilateral cells, counter-clockwise, convex (boundary layers',
    #: ``--cells``'); none on a triangle mesh
    quads: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), dtype=np.int64))
    #: (k, 2) int64: periodic pairs ``(node, partner)``, ``partner`` the boundary node at
    #: ``node + shift`` (``--periodic``); none otherwise
    periodic: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    shift: tuple[float, float] | None = None

    def __post_init__(self):
        if self.line_group is None:
            self.line_group = np.zeros(len(self.lines), dtype=np.int64)

    @property
    def split(self) -> np.ndarray:
        """The triangles with each quad as two (corners 0 1 2 and 0 2 3): the mesh as
        the triangle-only checks and measures read it."""
        return as_triangles(self.triangles, self.quads)

    @property
    def n_nodes(self) -> int:
        return len(self.points)


def guarded(triangles: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """``triangles`` and each of ``quads``' four corner triangles (both diagonals'
    halves): all of them positive, and every quad is convex.  What ``move`` and
    ``adapt`` keep unfolded."""
    q = quads
    return np.concatenate(
        [triangles, q[:, [0, 1, 2]], q[:, [0, 2, 3]], q[:, [1, 2, 3]], q[:, [1, 3, 0]]]
    )


def as_triangles(triangles: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """``triangles`` and each of ``quads`` as two (corners 0 1 2 and 0 2 3)."""
    if not len(quads):
        return triangles
    return np.concatenate([triangles, quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
