"""The sparse factorisation of adapt's velocity systems: QDLDL's LDL^T (Apache-2.0),
its own approximate-minimum-degree order, symbolic analysis once per pattern and then
only refactorised.  QDLDL uses no BLAS, so the same system gives the same bits on every
processor, with no kernel or thread setting (the deformation's solves use :mod:`.ldl`)."""

from __future__ import annotations

import numpy as np

from .errors import SolverError


class Cholesky:
    """``K x = b`` for a sequence of symmetric positive definite ``K`` given by their
    upper triangles in CSC form (``data``, ``indices``, ``indptr``, ``shape``; rows
    sorted within each column)."""

    def __init__(self):
        self._ldl = None
        self._pattern = None
        self.symbolic = 0  # analyses made (one per sparsity pattern)

    def factorise(self, upper) -> None:
        import qdldl

        indices, indptr = upper.indices, upper.indptr
        old = self._pattern
        same = old is not None and all(
            a is b or np.array_equal(a, b) for a, b in zip((indices, indptr), old)
        )
        try:
            if same:
                self._ldl.update(upper, upper=True)  # the same pattern: new numbers only
            else:
                self._ldl = qdldl.Solver(upper, upper=True)
                self._pattern = (indices, indptr)
                self.symbolic += 1
        except (RuntimeError, ValueError) as exc:
            self._ldl = self._pattern = None
            raise SolverError(f"the system is singular ({exc})") from None

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """``rhs`` (n,) or (n, k) -> the solution, same shape."""
        b = np.asarray(rhs, dtype=np.float64)
        cols = b.reshape(len(b), -1)
        x = np.column_stack(
            [self._ldl.solve(np.ascontiguousarray(cols[:, k])) for k in range(cols.shape[1])]
        )
        return x.reshape(b.shape)
