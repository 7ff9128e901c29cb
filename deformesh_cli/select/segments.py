"""Clearances across the domain: from query points to the nearest point of the
contour's edges that is another part of the contour, on the domain's side.

:class:`Segments` holds the contour's edges in a tree of bounding boxes
(:mod:`.boxtree`); :meth:`Segments.clearance` walks it once per query point (the
compiled loop, :mod:`._segments`), skipping every subtree farther than the query's
radius or than the nearest edge found.
"""

from __future__ import annotations

import numpy as np

from ._segments import clearance
from .boxtree import box_tree

#: Edges per leaf of the tree.
LEAF = 4


class Segments:
    """The edges ``a[e]`` to ``b[e]`` of a contour: ``arc[e]``, how far along its ring
    ``a[e]`` lies, ``length[e]``, ``ring[e]``, and each ring's ``perimeter``."""

    def __init__(self, a, b, arc, length, ring, perimeter):
        f8 = lambda v: np.ascontiguousarray(v, dtype=np.float64)  # noqa: E731
        self.ax, self.ay = f8(a[:, 0]), f8(a[:, 1])
        self.bx, self.by = f8(b[:, 0]), f8(b[:, 1])
        self.arc, self.length, self.perimeter = f8(arc), f8(length), f8(perimeter)
        self.ring = np.ascontiguousarray(ring, dtype=np.int64)
        self.tree = box_tree(np.minimum(a, b), np.maximum(a, b), LEAF)

    def clearance(self, x, x_arc, x_ring, own, wedge, radius, turn: float) -> np.ndarray:
        """Per query point ``x[q]`` (at ``x_arc[q]`` along ring ``x_ring[q]``): the
        distance to the nearest point ``y`` of an edge other than ``own[q]`` ((k, 2) or
        (k, 3) edge numbers) with ``|x - y| <= radius[q]``, where ``y`` is another part of the
        contour (another ring, or more than ``turn`` times ``|x - y|`` away along
        the ring, either way round) and ``y - x`` lies in the wedge turning
        counter-clockwise from ``wedge[0][q]`` to ``wedge[1][q]`` (closed: the
        domain's side); inf where no edge is."""
        f8 = lambda v: np.ascontiguousarray(v, dtype=np.float64)  # noqa: E731
        i8 = lambda v: np.ascontiguousarray(v, dtype=np.int64)  # noqa: E731
        x = np.asarray(x, dtype=np.float64).reshape(-1, 2)
        k = len(x)
        own = np.asarray(own, dtype=np.int64).reshape(k, -1)
        own = np.column_stack([own, own[:, :1]]) if own.shape[1] == 2 else own
        fwd, back = (np.asarray(w, dtype=np.float64).reshape(k, 2) for w in wedge)
        out = np.empty(k)
        clearance(
            f8(x[:, 0]), f8(x[:, 1]), f8(np.broadcast_to(x_arc, (k,))),
            i8(np.broadcast_to(x_ring, (k,))), i8(own[:, 0]), i8(own[:, 1]), i8(own[:, 2]),
            f8(fwd[:, 0]), f8(fwd[:, 1]), f8(back[:, 0]), f8(back[:, 1]),
            f8(np.broadcast_to(radius, (k,))),
            self.ax, self.ay, self.bx, self.by, self.arc, self.length, self.ring,
            self.perimeter, self.tree.order, self.tree.start, self.tree.box,
            self.tree.leaf0, float(turn), out,
        )  # fmt: skip
        return out
