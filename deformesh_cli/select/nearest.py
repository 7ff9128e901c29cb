"""The ``k`` nearest of a set of points to each query point (``k`` small): a tree of
bounding boxes (:mod:`.boxtree`) and a compiled walk (:mod:`._nearest`); ties go to
the lower-numbered point, so the answer does not depend on the walk."""

from __future__ import annotations

import numpy as np

from ._nearest import nearest
from .boxtree import box_tree

#: Points per leaf of the tree.
LEAF = 8


class Nearest:
    """The points (n, 2), ready for :meth:`query`."""

    def __init__(self, points: np.ndarray):
        points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        self.n = len(points)
        self.x = np.ascontiguousarray(points[:, 0])
        self.y = np.ascontiguousarray(points[:, 1])
        self.tree = box_tree(points, points, LEAF)

    def query(self, q: np.ndarray, k: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """``(dist, index)``, (m, k) each: per query point its ``k`` nearest points in
        increasing distance (ties: the lower number first); past the last point,
        distance inf and index ``n`` (as scipy's cKDTree)."""
        q = np.asarray(q, dtype=np.float64).reshape(-1, 2)
        k = max(int(k), 0)
        dist = np.empty((len(q), k))
        index = np.empty((len(q), k), dtype=np.int64)
        if k == 0:
            return dist, index
        nearest(
            np.ascontiguousarray(q[:, 0]), np.ascontiguousarray(q[:, 1]), self.x, self.y,
            self.tree.order, self.tree.start, self.tree.box, self.tree.leaf0, self.n,
            dist, index,
        )  # fmt: skip
        return dist, index
