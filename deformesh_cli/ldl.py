"""A sparse ``L D L^T`` factorisation for the deformation's symmetric positive definite
systems, with no BLAS and no scipy: the same bits on every machine.

The unknowns are ordered by approximate minimum degree (the quotient-graph method of
Amestoy, Davis and Duff, written here), then by a postorder of the elimination tree,
so the factor stays sparse and is read in runs; the ordering and the symbolic
factorisation (elimination tree, column counts) are made once per pattern, and
:meth:`LDL.update` refactors new numbers on the same pattern.  The loops are compiled
(:mod:`._ldl`).
"""

from __future__ import annotations

import numpy as np

from ._ldl import etree, factor, minimum_degree, permute_upper, postorder, solve
from .errors import OUT_OF_MEMORY, LimitError, SolverError


class LDL:
    """``K = L D L^T`` of a symmetric matrix given by its whole pattern in CSR
    (``indptr``, ``indices``, ``data``; :class:`~.divcurl.SymmetricCSR` or alike)."""

    def __init__(self, K):
        n = K.shape[0]
        indptr = np.ascontiguousarray(K.indptr, dtype=np.int64)
        indices = np.ascontiguousarray(K.indices, dtype=np.int64)
        perm = np.empty(n, dtype=np.int64)
        if minimum_degree(indptr, indices, perm) < 0:
            raise LimitError(OUT_OF_MEMORY)
        parent = np.empty(n, dtype=np.int64)
        lnz = np.empty(n, dtype=np.int64)
        work = np.empty(n, dtype=np.int64)
        self._permute(perm, indptr, indices)
        etree(self._Ap, self._Ai, parent, lnz, work)
        post = np.empty(n, dtype=np.int64)
        postorder(parent, post)
        perm = perm[post]  # (the same fill, each subtree's columns together)
        self._permute(perm, indptr, indices)
        total = etree(self._Ap, self._Ai, parent, lnz, work)
        self.perm = perm
        self._pattern = K.indices
        self.n = n
        self._parent = parent
        self._Lp = np.concatenate([[0], np.cumsum(lnz)]).astype(np.int64)
        self._Li = np.empty(max(total, 1), dtype=np.int64)
        self._Lx = np.empty(max(total, 1))
        self._D = np.empty(n)
        self._Dinv = np.empty(n)
        self._scratch = (
            np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64),
            np.empty(n, dtype=np.int64), np.empty(n, dtype=np.uint8), np.empty(n),
        )  # fmt: skip
        self.update(K)

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
        bad = factor(
            self._Ap, self._Ai, ax, self._parent, self._Lp, self._Li, self._Lx,
            self._D, self._Dinv, *self._scratch,
        )  # fmt: skip
        if bad >= 0:
            raise SolverError(
                "the matrix is not positive definite (a pivot of its L D L^T is not "
                "positive): a triangle is flat or folded"
            )

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``K^-1 b`` for ``b`` (n,) or (n, k)."""
        b = np.asarray(b, dtype=np.float64)
        cols = b.reshape(self.n, -1)
        out = np.empty_like(cols)
        for k in range(cols.shape[1]):
            x = np.ascontiguousarray(cols[self.perm, k])
            solve(self._Lp, self._Li, self._Lx, self._Dinv, x)
            out[self.perm, k] = x
        return out.reshape(b.shape)
