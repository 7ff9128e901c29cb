"""Sparse Cholesky factorisation for the symmetric positive definite systems of the
div-curl solves: CHOLMOD (SuiteSparse, through cvxopt), supernodal.

The ordering (approximate minimum degree) and the symbolic factorisation are done
once per sparsity pattern; a later matrix with the same pattern (the mesh moved, its
connectivity did not) only refactorises the numbers.  The supernodal factorisation
calls BLAS on dense blocks, here under one BLAS thread, so the bits do not depend on
the core count (nor on the load: the blocks' sums run in a fixed order).
"""

from __future__ import annotations

import numpy as np

from .errors import SolverError


class Cholesky:
    """``K x = b`` for a sequence of symmetric positive definite ``K`` given by their
    upper triangles in CSC form (``data``, ``indices``, ``indptr``, ``shape``)."""

    def __init__(self):
        self._factor = None
        self._pattern = None
        self._rows = None
        self._cols = None
        self.symbolic = 0  # orderings computed (one per sparsity pattern)

    def factorise(self, upper) -> None:
        import cvxopt
        import cvxopt.cholmod as cholmod

        indices, indptr = upper.indices, upper.indptr
        old = self._pattern
        same = old is not None and all(
            a is b or np.array_equal(a, b) for a, b in zip((indices, indptr), old)
        )
        if not same:
            self._rows = cvxopt.matrix(np.asarray(indices, dtype=np.int64))
            cols = np.repeat(np.arange(upper.shape[1], dtype=np.int64), np.diff(indptr))
            self._cols = cvxopt.matrix(cols)
        n = upper.shape[0]
        K = cvxopt.spmatrix(
            cvxopt.matrix(np.asarray(upper.data, dtype=np.float64)), self._rows, self._cols, (n, n)
        )
        cholmod.options["supernodal"] = 2
        cholmod.options["postorder"] = True
        if not same:
            self._factor = cholmod.symbolic(K, uplo="U")
            self._pattern = (indices, indptr)
            self.symbolic += 1
        from threadpoolctl import threadpool_limits

        try:
            with threadpool_limits(limits=1, user_api="blas"):
                cholmod.numeric(K, self._factor)
        except ArithmeticError as e:
            raise SolverError(f"the matrix is not positive definite (column {e})") from None

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """``rhs`` (n,) or (n, k) -> the solution, same shape."""
        import cvxopt
        import cvxopt.cholmod as cholmod

        b = np.asarray(rhs, dtype=np.float64)
        from threadpoolctl import threadpool_limits

        x = cvxopt.matrix(b.reshape(len(b), -1))
        with threadpool_limits(limits=1, user_api="blas"):
            cholmod.solve(self._factor, x)
        return np.array(x).reshape(b.shape)
