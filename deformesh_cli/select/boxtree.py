"""A binary tree of bounding boxes over items with boxes (points: boxes of no size),
for the compiled walks that find, per query, the best item without visiting all.

The items are sorted along a Morton curve of their boxes' centres and cut into
leaves of ``leaf`` items; the leaves are padded to a power of two and stacked into a
complete binary tree in heap order (node ``k`` has children ``2k`` and ``2k + 1``;
nodes ``leaf0 .. 2 * leaf0 - 1`` are the leaves).  An empty node's box is inverted
(``+inf .. -inf``), so every distance to it is inf.  Built by numpy, level by level.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import morton


@dataclass(frozen=True)
class BoxTree:
    """``order``: the items in tree order; leaf ``k - leaf0`` holds items ``order[start[k
    - leaf0] : start[k - leaf0 + 1]]``; ``box``: (2 * leaf0 * 4,) per node ``xmin, xmax,
    ymin, ymax``."""

    order: np.ndarray
    start: np.ndarray
    leaf0: int
    box: np.ndarray

    def reduce(self, values: np.ndarray, ufunc, empty: float) -> np.ndarray:
        """Per node: ``ufunc`` (``np.minimum``, ``np.maximum``) of the items' ``values``
        under it (``empty`` for an empty node)."""
        out = np.full(2 * self.leaf0, empty)
        leaves = _leaves(len(self.order), self.start)
        if leaves:
            out[self.leaf0 : self.leaf0 + leaves] = ufunc.reduceat(
                values[self.order], self.start[:leaves]
            )
        width = self.leaf0
        while width > 1:
            width //= 2
            a = np.arange(width, 2 * width)
            out[a] = ufunc(out[2 * a], out[2 * a + 1])
        return out


def _leaves(n: int, start: np.ndarray) -> int:
    return int(np.searchsorted(start, n, "left")) if n else 0


def box_tree(lo: np.ndarray, hi: np.ndarray, leaf: int) -> BoxTree:
    """The tree over items with boxes ``lo`` .. ``hi`` ((n, 2) each, finite)."""
    lo = np.asarray(lo, dtype=np.float64).reshape(-1, 2)
    hi = np.asarray(hi, dtype=np.float64).reshape(-1, 2)
    n = len(lo)
    centre = (lo + hi) / 2
    if n:
        base = centre.min(axis=0)
        span = np.maximum(np.ptp(centre, axis=0), np.finfo(float).tiny)
        cell = np.minimum((centre - base) / span * (1 << 20), (1 << 20) - 1).astype(np.int64)
        order = np.argsort(morton(cell[:, 0], cell[:, 1]), kind="stable")
    else:
        order = np.zeros(0, dtype=np.int64)
    leaves = -(-n // leaf)
    leaf0 = 1 << max(0, (leaves - 1).bit_length())
    start = np.minimum(np.arange(leaf0 + 1, dtype=np.int64) * leaf, n)
    tree = BoxTree(order, start, leaf0, np.empty(0))
    box = np.column_stack(
        [
            tree.reduce(lo[:, 0], np.minimum, np.inf),
            tree.reduce(hi[:, 0], np.maximum, -np.inf),
            tree.reduce(lo[:, 1], np.minimum, np.inf),
            tree.reduce(hi[:, 1], np.maximum, -np.inf),
        ]
    )
    return BoxTree(order, start, leaf0, np.ascontiguousarray(box.ravel()))
