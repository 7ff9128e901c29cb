"""Sparse Cholesky factorisation for the symmetric positive definite systems of the
div-curl solves: CHOLMOD (SuiteSparse, through cvxopt), supernodal.

The ordering (approximate minimum degree) and the symbolic factorisation are done
once per sparsity pattern; a later matrix with the same pattern (the mesh moved, its
connectivity did not) only refactorises the numbers.  The supernodal factorisation
calls BLAS on dense blocks, here under one BLAS thread, so the bits do not depend on
the core count (nor on the load: the blocks' sums run in a fixed order), and in the
same kernels on every x86-64 processor with AVX2 and FMA (:func:`cvxopt_module`).
"""

from __future__ import annotations

import os
import platform
from contextlib import contextmanager

import numpy as np

from .errors import SolverError

#: CHOLMOD's options for every call here (supernodal, postordered); cvxopt keeps them
#: module-wide, so they are set for each call and the caller's put back after it.
OPTIONS = {"supernodal": 2, "postorder": True}


#: The kernels cvxopt's OpenBLAS is held to where the processor runs them (x86-64
#: with AVX2 and FMA: Intel from Haswell on, AMD from Zen on, where it picks these or
#: kernels giving the same bits).  It picks its kernels by the processor it loads on,
#: and two kernels sum a block in different orders: on this project's AMD EPYC the
#: adapted ring's nodes have the same bits with ``Haswell`` as by its own choice,
#: others with ``Sandybridge``, ``Nehalem`` or ``Prescott`` (``benchmarks/MEASURED.md``).
BLAS_KERNELS = "Haswell"


def cvxopt_module():
    """cvxopt, imported with its OpenBLAS held to :data:`BLAS_KERNELS` where the
    processor runs them (OpenBLAS reads ``OPENBLAS_CORETYPE`` when it loads; a value the
    user set is theirs, and the environment is left as it was)."""
    import sys

    fresh = "cvxopt" not in sys.modules and "OPENBLAS_CORETYPE" not in os.environ
    if fresh and _runs_haswell_kernels():
        os.environ["OPENBLAS_CORETYPE"] = BLAS_KERNELS
        try:
            import cvxopt
        finally:
            del os.environ["OPENBLAS_CORETYPE"]
    import cvxopt
    import cvxopt.amd
    import cvxopt.cholmod

    return cvxopt


def _runs_haswell_kernels() -> bool:
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return False
    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:  # (numpy before 2)
        return False
    return bool(features.get("AVX2") and features.get("FMA3"))


def amd_order(rows: np.ndarray, cols: np.ndarray, n: int) -> np.ndarray:
    """An approximate-minimum-degree order of the symmetric pattern with entries at
    ``(rows, cols)`` (upper triangle, repeats allowed), n x n (SuiteSparse AMD)."""
    cvxopt = cvxopt_module()
    graph = cvxopt.spmatrix(1.0, cvxopt.matrix(rows), cvxopt.matrix(cols), (n, n))
    return np.array(cvxopt.amd.order(graph, "U"), dtype=np.int64).ravel()


@contextmanager
def _cholmod():
    """cvxopt's CHOLMOD under :data:`OPTIONS` and one BLAS thread; whatever options
    were set before (another cvxopt user in the process) are restored after."""
    from threadpoolctl import threadpool_limits

    cholmod = cvxopt_module().cholmod

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
        cvxopt = cvxopt_module()

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
        cvxopt = cvxopt_module()

        b = np.asarray(rhs, dtype=np.float64)
        x = cvxopt.matrix(b.reshape(len(b), -1))
        with _cholmod() as cholmod:
            cholmod.solve(self._factor, x)
        return np.array(x).reshape(b.shape)
