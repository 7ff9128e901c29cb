"""A sparse ``L D L^T`` factorisation for the deformation's symmetric positive definite
systems, with no BLAS and no scipy: the same bits on every machine.

The unknowns are ordered by approximate minimum degree (the quotient-graph method of
Amestoy, Davis and Duff, written here), or by nested dissection where they sit at
points of the plane (:func:`dissection_order`), then by a postorder of the elimination tree,
so the factor stays sparse and is read in runs; the ordering and the symbolic
factorisation (elimination tree, column counts) are made once per pattern, and
:meth:`LDL.update` refactors new numbers on the same pattern.  The loops are compiled
(:mod:`._ldl`).
"""

from __future__ import annotations

import numpy as np

from ._ldl import etree, factor, minimum_degree, permute_upper, postorder, solve, solve2
from .errors import OUT_OF_MEMORY, LimitError, SolverError

#: Parts of a nested dissection that are not split further: at most this many unknowns
#: (on the 300 x 300 grid's Laplacian 16 gives 3.7M factor entries, 64 4.1M, 256 5.5M;
#: approximate minimum degree 4.7M, with twice the flops: ``benchmarks/MEASURED.md``).
DISSECTION_LEAF = 16


def dissection_order(
    points: np.ndarray, indptr: np.ndarray, indices: np.ndarray, leaf: int = DISSECTION_LEAF
) -> np.ndarray:
    """A nested-dissection order of a symmetric pattern (CSR ``indptr``, ``indices``)
    whose unknowns sit at ``points`` (n, 2) of the plane, as a mesh's nodes do.

    Each part of more than ``leaf`` unknowns is split at its median along the longer
    side of its bounding box (ties by index); the unknowns of the smaller half that
    are coupled to the other half form its separator, ordered after both halves, which
    are split in turn.  A planar mesh's median line crosses about the square root of its
    nodes, so the factor keeps ``O(n log n)`` entries.  All parts of a level are split
    at once (a sort per level); each unknown's place is a base-3 key of its path (0
    first half, 1 second, 2 separator), so the order is the dissection tree's postorder
    with the unknowns of a part by index.
    """
    n = len(points)
    indptr = np.asarray(indptr, dtype=np.int64)
    row = np.repeat(np.arange(n), np.diff(indptr))
    col = np.asarray(indices, dtype=np.int64)[: indptr[-1]]
    off = row != col
    row, col = row[off], col[off]
    key = np.zeros(n, dtype=np.int64)  # the path so far (a part: the active with one key)
    active = np.ones(n, dtype=bool)
    side = np.zeros(n, dtype=np.int64)
    while active.any():  # (a level halves every part: 3**levels stays < 2**63)
        k = np.flatnonzero(active)
        k = k[np.argsort(key[k], kind="stable")]  # part by part, each by index
        starts = np.flatnonzero(np.r_[True, key[k[1:]] != key[k[:-1]]])
        size = np.diff(np.r_[starts, len(k)])
        pid = np.repeat(np.arange(len(starts)), size)
        x, y = points[k, 0], points[k, 1]
        wide = (np.maximum.reduceat(x, starts) - np.minimum.reduceat(x, starts)) >= (
            np.maximum.reduceat(y, starts) - np.minimum.reduceat(y, starts)
        )
        k = k[np.lexsort((k, np.where(wide[pid], x, y), pid))]  # (pid is already sorted)
        big = size > leaf
        side[k] = np.where(np.arange(len(k)) - starts[pid] >= size[pid] // 2, 1, 0)
        side[k[~big[pid]]] = 0
        active[k[~big[pid]]] = False  # (parts small enough: their order is by index)
        part = np.full(n, -1)
        part[k] = pid
        live = active[row] & active[col]
        row, col = row[live], col[live]
        cut = np.flatnonzero((side[row] == 0) & (side[col] == 1) & (part[row] == part[col]))
        # each part's coupled unknowns on either side (an unknown once), the fewer kept
        first = np.zeros(n, dtype=bool)
        second = np.zeros(n, dtype=bool)
        first[row[cut]] = True
        second[col[cut]] = True
        fewer = np.bincount(part[first], minlength=len(starts)) <= np.bincount(
            part[second], minlength=len(starts)
        )
        sep = np.where(fewer[part], first, second) & (part >= 0)
        key = 3 * key + np.where(active, np.where(sep, 2, side), 0)
        active &= ~sep
    return np.argsort(key, kind="stable")


class LDL:
    """``K = L D L^T`` of a symmetric matrix given by its whole pattern in CSR
    (``indptr``, ``indices``, ``data``; :class:`~.divcurl.SymmetricCSR` or alike),
    in approximate minimum degree order or in the ``order`` given."""

    def __init__(self, K, order: np.ndarray | None = None):
        n = self._analyse(K, order)
        total = int(self._count.sum())
        self._Lp = np.concatenate([[0], np.cumsum(self._count)]).astype(np.int64)
        self._Li = np.empty(max(total, 1), dtype=np.int64)
        self._Lx = np.empty(max(total, 1))
        self._D = np.empty(n)
        self._Dinv = np.empty(n)
        self._scratch = (
            np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64),
            np.empty(n, dtype=np.int64), np.empty(n, dtype=np.uint8), np.empty(n),
        )  # fmt: skip
        self.update(K)

    def _analyse(self, K, order) -> int:
        """The order (``perm``: approximate minimum degree, or ``order``, then the
        elimination tree's postorder), the permuted upper triangle (:meth:`_permute`),
        the elimination tree (``_parent``) and each column's count below the diagonal
        (``_count``); returns the size."""
        n = K.shape[0]
        indptr = np.ascontiguousarray(K.indptr, dtype=np.int64)
        indices = np.ascontiguousarray(K.indices, dtype=np.int64)
        if order is None:
            perm = np.empty(n, dtype=np.int64)
            if minimum_degree(indptr, indices, perm) < 0:
                raise LimitError(OUT_OF_MEMORY)
        else:
            perm = np.asarray(order, dtype=np.int64)
        parent = np.empty(n, dtype=np.int64)
        lnz = np.empty(n, dtype=np.int64)
        work = np.empty(n, dtype=np.int64)
        self._permute(perm, indptr, indices)
        etree(self._Ap, self._Ai, parent, lnz, work)
        post = np.empty(n, dtype=np.int64)
        postorder(parent, post)
        perm = perm[post]  # (the same fill, each subtree's columns together)
        self._permute(perm, indptr, indices)
        etree(self._Ap, self._Ai, parent, lnz, work)
        self.perm = perm
        self._pattern = K.indices
        self.n = n
        self._parent = parent
        self._count = lnz
        return n

    def _permute(self, perm, indptr, indices) -> None:
        """The permuted matrix's upper triangle by columns (``_Ap``, ``_Ai``) and where
        each of its entries comes from in ``K`` (``_src``), compiled."""
        n = len(perm)
        pinv = np.empty(n, dtype=np.int64)
        pinv[perm] = np.arange(n)
        self._Ap = np.empty(n + 1, dtype=np.int64)
        Ai = np.empty(len(indices), dtype=np.int64)
        src = np.empty(len(indices), dtype=np.int64)
        m = permute_upper(indptr, indices, pinv, self._Ap, Ai, src)
        self._Ai, self._src = Ai[:m], src[:m]

    def same_pattern(self, K) -> bool:
        return K.indices is self._pattern

    def update(self, K) -> None:
        """Factor new numbers on the same pattern."""
        ax = np.ascontiguousarray(np.asarray(K.data, dtype=np.float64)[self._src])
        _refuse_pivot(
            factor(
                self._Ap,
                self._Ai,
                ax,
                self._parent,
                self._Lp,
                self._Li,
                self._Lx,
                self._D,
                self._Dinv,
                *self._scratch,
            )  # fmt: skip
        )

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``K^-1 b`` for ``b`` (n,) or (n, k)."""
        b = np.asarray(b, dtype=np.float64)
        cols = b.reshape(len(b), int(np.prod(b.shape[1:])))  # (n, k); k = 1 for (n,)
        x = np.ascontiguousarray(cols[self.perm])  # (in the factor's order)
        self._solve_in_order(x)
        out = np.empty_like(x)
        out[self.perm] = x
        return out.reshape(b.shape)

    def _solve_in_order(self, x: np.ndarray) -> None:
        """``x`` (n, k), in the factor's order, overwritten by the solutions; two columns
        in one pass over the factor."""
        if x.shape[1] == 2:
            solve2(self._Lp, self._Li, self._Lx, self._Dinv, x)
            return
        for k in range(x.shape[1]):
            col = np.ascontiguousarray(x[:, k])
            solve(self._Lp, self._Li, self._Lx, self._Dinv, col)
            x[:, k] = col


def _refuse_pivot(bad: int) -> None:
    """A factor's first pivot that is not positive (``bad >= 0``) as a SolverError."""
    if bad >= 0:
        raise SolverError(
            "the matrix is not positive definite (a pivot of its L D L^T is not "
            "positive): a triangle is flat or folded"
        )


class SupernodalLDL(LDL):
    """:class:`LDL` with the columns that share one row pattern (a supernode) held and
    updated as one dense block (:mod:`._supernodal`): the same factor up to the order
    of its sums, faster where supernodes are wide (a nested-dissection order of a
    mesh's nodes, whose separators are dense).  The same bits on every processor."""

    def __init__(self, K, order: np.ndarray | None = None):
        from ._supernodal import structure, supernodes

        n = self._analyse(K, order)
        # A's upper triangle by rows (row i: its columns j >= i), each entry's place in K
        col = np.repeat(np.arange(n, dtype=np.int64), np.diff(self._Ap))
        by_row = np.argsort(self._Ai, kind="stable")
        self._Rj = np.ascontiguousarray(col[by_row])
        self._Rsrc = self._src[by_row]
        self._Rp = np.searchsorted(self._Ai[by_row], np.arange(n + 1)).astype(np.int64)
        first = np.empty(n + 1, dtype=np.int64)
        ns = supernodes(self._parent, self._count, first)
        self._first = first[: ns + 1].copy()
        width = np.diff(self._first)
        height = width + self._count[self._first[1:] - 1]  # (a block's rows: the last's)
        self._rp = np.concatenate([[0], np.cumsum(height)]).astype(np.int64)
        self._rows = np.empty(int(self._rp[-1]), dtype=np.int64)
        self._owner = np.empty(n, dtype=np.int64)
        per_node = np.empty(n, dtype=np.int64)
        per_block = [np.empty(ns, dtype=np.int64) for _ in range(3)]
        if structure(
            self._first, self._parent, self._Rp, self._Rj, self._rp, self._rows,
            self._owner, per_node, *per_block[:2],
        ) >= 0:  # fmt: skip
            raise SolverError("the factor's row structure does not match its column counts")
        self._xp = np.concatenate([[0], np.cumsum(height * width)]).astype(np.int64)
        self._Lx = np.empty(max(int(self._xp[-1]), 1))
        self._D = np.empty(n)
        self._scratch = (per_node, *per_block, np.empty(n))  # (factor's: rel, link, nxt, at, t)
        self.update(K)

    def update(self, K) -> None:
        """Factor new numbers on the same pattern."""
        from ._supernodal import factor

        rx = np.ascontiguousarray(np.asarray(K.data, dtype=np.float64)[self._Rsrc])
        _refuse_pivot(
            factor(
                self._first,
                self._rp,
                self._rows,
                self._owner,
                self._xp,
                self._Rp,
                self._Rj,
                rx,
                self._Lx,
                self._D,
                *self._scratch,
            )  # fmt: skip
        )

    def _solve_in_order(self, x: np.ndarray) -> None:
        from ._supernodal import solve

        for k in range(x.shape[1]):
            col = np.ascontiguousarray(x[:, k])
            solve(self._first, self._rp, self._rows, self._xp, self._Lx, self._D, col)
            x[:, k] = col
