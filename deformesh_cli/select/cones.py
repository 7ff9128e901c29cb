"""The least of cones over points: ``min over p of s_p + alpha * d(p, B)`` for many
query boxes ``B`` (points are boxes of no size), to within :data:`SLACK`, in about
``log n`` steps each where the nearest points decide.

Size fields grow away from the points where they are given: a cell may be as large
as ``s_p`` plus ``alpha`` times its distance from any point ``p``, whichever ``p``
allows least.  :class:`Cones` holds a tree of bounding boxes over the points
(:mod:`.boxtree`), each node with the least ``s`` under it; a query walks down from
the root and skips a subtree when its bound (its least ``s`` plus ``alpha`` times the
gap between the boxes) cannot beat the best value found by more than :data:`SLACK`.
The walk is the compiled loop (:mod:`._cones`); the answer is within the slack of
the least over every point, not over a few near ones, and the same on every run.
"""

from __future__ import annotations

import numpy as np

from ._cones import least
from .boxtree import box_tree

#: Points per leaf of the tree.
LEAF = 8

#: The walk skips a subtree unless its bound is below the best value found divided by
#: this: each answer is at most this times the least value (points equally far from
#: a query, as from the centre of a circle, would otherwise all be visited).
SLACK = 1.0 + 2.0**-10


class Cones:
    """The cones ``s_p + alpha |q - p|`` of ``points`` (n, 2), ready for
    :meth:`least` (``points`` and ``s`` finite, ``alpha`` >= 0: the callers' points
    are a validated contour's; with no points every answer is inf)."""

    def __init__(self, points: np.ndarray, s: np.ndarray, alpha: float):
        points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        s = np.asarray(s, dtype=np.float64).ravel()
        self.alpha = float(alpha)
        self._tree = tree = box_tree(points, points, LEAF)
        self._low = tree.reduce(s, np.minimum, np.inf)
        self.x = np.ascontiguousarray(points[tree.order, 0])
        self.y = np.ascontiguousarray(points[tree.order, 1])
        self.s = np.ascontiguousarray(s[tree.order])

    def least(self, centre: np.ndarray, half_w=0.0, half_h=0.0) -> np.ndarray:
        """Per box (``centre`` (k, 2), half sides ``half_w``, ``half_h``: arrays or
        scalars; 0 for points): the least over every point ``p`` of ``s_p + alpha *
        d``, ``d`` the distance from ``p`` to the box, computed as ``sqrt(dx * dx + dy
        * dy)`` with ``dx = max(|p_x - c_x| - half_w, 0)``."""
        centre = np.asarray(centre, dtype=np.float64).reshape(-1, 2)
        k = len(centre)
        hw = np.ascontiguousarray(np.broadcast_to(np.asarray(half_w, dtype=np.float64), (k,)))
        hh = np.ascontiguousarray(np.broadcast_to(np.asarray(half_h, dtype=np.float64), (k,)))
        out = np.empty(k)
        least(
            np.ascontiguousarray(centre[:, 0]),
            np.ascontiguousarray(centre[:, 1]),
            hw,
            hh,
            self.x,
            self.y,
            self.s,
            self._tree.box,
            self._low,
            self._tree.start,
            self._tree.leaf0,
            self.alpha,
            SLACK,
            out,
        )
        return out
