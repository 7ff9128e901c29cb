"""Sparse Cholesky factorisation for the symmetric positive definite systems of the
div-curl solves: CHOLMOD (SuiteSparse, through cvxopt), supernodal.

The ordering (approximate minimum degree) and the symbolic factorisation are done
once per sparsity pattern; a later matrix with the same pattern (the mesh moved, its
connectivity did not) only refactorises the numbers.  The supernodal factorisation
calls BLAS on dense blocks, here under one BLAS thread, so the bits do not depend on
the core count (nor on the load: the blocks' sums run in a fixed order).
"""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np

from .errors import SolverError

#: CHOLMOD's options for every call here (supernodal, postordered); cvxopt keeps them
#: module-wide, so they are set for each call and the caller's put back after it.
OPTIONS = {"supernodal": 2, "postorder": True}


@contextmanager
def _cholmod():
    """cvxopt's CHOLMOD under :data:`OPTIONS` and one BLAS thread; whatever options
    were set before (another cvxopt user in the process) are restored after."""
    import cvxopt.cholmod as cholmod
    from threadpoolctl import threadpool_limits

    saved = {k: cholmod.options[k] for k in OPTIONS if k in cholmod.options}
    cholmod.options.update(OPTIONS)
    try:
        with threadpool_limits(limits=1, user_api="blas"):
            yield cholmod
    finally:
        for k in OPTIONS:
            if k in saved:
                cholmod.options[k] = saved[k]
            else:
                del cholmod.options[k]


class Cholesky:
    """``K x = b`` for a sequence of symmetric positive definite ``K`` given by their
    upper triangles in CSC form (``data``, ``indices``, ``indptr``, ``shape``; rows
    sorted within each column)."""

    def __init__(self, order: np.ndarray | None = None):
        self.order = order  # a fill-reducing permutation; None: CHOLMOD's own (AMD)
        self._factor = None
        self._pattern = None
        self._K = None
        self.symbolic = 0  # orderings computed (one per sparsity pattern)

    def factorise(self, upper) -> None:
        import cvxopt

        indices, indptr = upper.indices, upper.indptr
        old = self._pattern
        same = old is not None and all(
            a is b or np.array_equal(a, b) for a, b in zip((indices, indptr), old)
        )
        values = cvxopt.matrix(np.asarray(upper.data, dtype=np.float64))
        if same:
            self._K.V = values  # the same pattern, its entries in the same (CCS) order
        else:
            n = upper.shape[0]
            rows = cvxopt.matrix(np.asarray(indices, dtype=np.int64))
            cols = cvxopt.matrix(np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr)))
            self._K = cvxopt.spmatrix(values, rows, cols, (n, n))
            given = {}
            if self.order is not None:
                given["p"] = cvxopt.matrix(np.asarray(self.order, dtype=np.int64))
            with _cholmod() as cholmod:
                self._factor = cholmod.symbolic(self._K, uplo="U", **given)
            self._pattern = (indices, indptr)
            self.symbolic += 1
        try:
            with _cholmod() as cholmod:
                cholmod.numeric(self._K, self._factor)
        except ArithmeticError as e:
            raise SolverError(f"the matrix is not positive definite (column {e})") from None

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """``rhs`` (n,) or (n, k) -> the solution, same shape."""
        import cvxopt

        b = np.asarray(rhs, dtype=np.float64)
        x = cvxopt.matrix(b.reshape(len(b), -1))
        with _cholmod() as cholmod:
            cholmod.solve(self._factor, x)
        return np.array(x).reshape(b.shape)
