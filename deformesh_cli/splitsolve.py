"""``K x = b`` for adapt's velocity systems: conjugate gradients preconditioned by the
exact factorisations of two diagonal blocks, one per direction of motion.

The unknowns are split into two groups (for adapt: those that move a node mostly
along one axis of its frame and those mostly along the other), and the preconditioner is ``K``
without the coupling between the groups, its two blocks factorised supernode by
supernode (:class:`.ldl.SupernodalLDL`) in a nested-dissection order of the unknowns'
positions (:func:`.ldl.dissection_order`, made once: the pattern is fixed).  Where
the groups do not couple, one iteration solves the system; on the div-curl systems
they couple only through the density's variation, and the iterations stop at a
residual of :data:`RTOL` of the load after 6-8 (``benchmarks/MEASURED.md``).  The
two blocks are factorised and solved in two threads; every product and sum runs in a
fixed order in compiled loops with no BLAS, so the same system gives the same bits on
every processor, with any number of cores or threads.
"""

from __future__ import annotations

import numpy as np

from ._ldl import dot, upper_matvec
from .divcurl import SymmetricCSR
from .errors import SolverError
from .ldl import SupernodalLDL, dissection_order

#: Conjugate gradients stop when the residual is at most this fraction of the load
#: (the factorised solve it replaces left about 1e-13).
RTOL = 1e-10

#: Systems of at least this many unknowns run their two blocks in two threads; below,
#: a thread's hand-off costs more than a block's solve (the 20 x 20 ring with 80
#: solves: 1.19 s as a whole process in threads, 0.48 s in turn).
PARALLEL_UNKNOWNS = 20_000

#: The most iterations: far above the 6-8 the systems take, a bound on the work of a
#: system that is not positive definite in floating point.
MAX_ITERATIONS = 1000


class SplitSolver:
    """Solves on one symmetric pattern, given by its upper triangle by columns
    (``indptr``, ``indices``: rows ascending in each column), with ``group`` (n,)
    0 or 1 for each unknown and ``points`` (n, 2) where each sits."""

    def __init__(self, indptr, indices, group: np.ndarray, points: np.ndarray):
        self.n = n = len(group)
        self._Ap = np.ascontiguousarray(indptr, dtype=np.int64)
        self._Ai = np.ascontiguousarray(indices, dtype=np.int64)
        col = np.repeat(np.arange(n), np.diff(self._Ap))
        row = self._Ai
        self._members, self._blocks = [], []
        for g in (0, 1):
            members = np.flatnonzero(group == g)
            local = np.full(n, -1)
            local[members] = np.arange(len(members))
            e = np.flatnonzero((group[row] == g) & (group[col] == g))
            diag = row[e] == col[e]
            # the block's whole pattern (both triangles) by rows, and each entry's place
            # in the upper triangle's values
            r = np.concatenate([local[row[e]], local[col[e][~diag]]])
            c = np.concatenate([local[col[e]], local[row[e][~diag]]])
            src = np.concatenate([e, e[~diag]])
            o = np.lexsort((c, r))
            indptr_g = np.searchsorted(r[o], np.arange(len(members) + 1))
            order = dissection_order(points[members], indptr_g, c[o])
            self._members.append(members)
            self._blocks.append((src[o], c[o], indptr_g, order))
        self._factors = None
        self._pool = None  # (the second thread, made at the first use)
        self.iterations = 0  # over all solves

    def factorise(self, values: np.ndarray) -> None:
        """Take the numbers of a new system (``values``: the upper triangle's, in its
        order) and factorise its two diagonal blocks."""
        self._values = np.ascontiguousarray(values, dtype=np.float64)
        mats = [
            SymmetricCSR(self._values[src], indices, indptr, (len(indptr) - 1,) * 2)
            for src, indices, indptr, _ in self._blocks
        ]
        if self._factors is None:
            work = [
                lambda m=m, b=b: SupernodalLDL(m, order=b[3]) for m, b in zip(mats, self._blocks)
            ]
        else:
            work = [lambda m=m, f=f: f.update(m) for m, f in zip(mats, self._factors)]
        made = self._both(*work)
        if self._factors is None:
            self._factors = made

    def _both(self, first, second):
        """``[first(), second()]``, the second in a thread of its own where the system is
        large (the factorisations and solves release the interpreter's lock); an
        exception in either is raised once both have ended."""
        if self.n < PARALLEL_UNKNOWNS:
            return [first(), second()]
        if self._pool is None:
            from concurrent.futures import ThreadPoolExecutor

            self._pool = ThreadPoolExecutor(1)
        later = self._pool.submit(second)
        try:
            a = first()
        except BaseException:
            later.exception()
            raise
        return [a, later.result()]

    def _precondition(self, r: np.ndarray) -> np.ndarray:
        z = np.empty(self.n)

        def part(g):
            m = self._members[g]
            z[m] = self._factors[g].solve(r[m])

        self._both(lambda: part(0), lambda: part(1))
        return z

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``K^-1 b`` for the system last factorised (a :class:`SolverError` if it is
        not positive definite)."""
        b = np.ascontiguousarray(b, dtype=np.float64)
        x = np.zeros(self.n)
        bb = dot(b, b)
        if bb == 0.0:
            return x
        q = np.empty(self.n)
        r = b.copy()
        z = self._precondition(r)
        d = z.copy()
        rz = dot(r, z)
        for _ in range(MAX_ITERATIONS + 1):
            if dot(r, r) <= RTOL * RTOL * bb:
                return x
            self.iterations += 1
            upper_matvec(self._Ap, self._Ai, self._values, d, q)
            dq = dot(d, q)
            if not dq > 0.0:
                break
            alpha = rz / dq
            x += alpha * d
            r -= alpha * q
            z = self._precondition(r)
            rz, before = dot(r, z), rz
            d *= rz / before
            d += z
        raise SolverError(
            "the velocity system is not positive definite in floating point (conjugate "
            f"gradients did not reach {RTOL:g} of the load in {MAX_ITERATIONS} iterations)"
        )
