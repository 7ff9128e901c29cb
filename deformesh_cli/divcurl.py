"""Least-squares finite elements for the div-curl system on P1 triangles.

The paper's step 1 solves ``div U = r``, ``curl U = 0`` by LSFEM: minimise
``sum_T |T| ((div U - r)^2 + (curl U)^2)`` over piecewise-linear ``U``.  Per
triangle, with barycentric gradients ``(gx, gy)`` and dofs ``[ux1..3, uy1..3]``,
``div U = d.u`` with ``d = [gx, gy]`` and ``curl U = c.u`` with ``c = [-gy, gx]``;
the element matrix is ``|T| (d d^T + c c^T)`` and the load ``|T| r d``.

The ux-ux and uy-uy blocks are the P1 Laplace stiffness; the ux-uy block
``|T| (gx gy^T - gy gx^T)`` is a discrete null Lagrangian: it couples only
pairs of nodes that both lie on the outer boundary.  deformesh fixes every
node of the background boundary (``U = 0`` there), so on the free dofs the
system splits into two scalar problems with one matrix.  :class:`Assembler`
exploits that; :func:`assemble_coupled` builds the general system (kept for
slip boundaries, and used by the tests to show the split is exact).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def gradients(points: np.ndarray, tri: np.ndarray):
    """Barycentric gradients ``gx, gy`` (t, 3) and twice the signed areas (t,)."""
    x, y = points[tri, 0], points[tri, 1]  # (t, 3) each
    a2 = (x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0])
    b = y[:, [1, 2, 0]] - y[:, [2, 0, 1]]  # y_{k+1} - y_{k+2}
    c = x[:, [2, 0, 1]] - x[:, [1, 2, 0]]  # x_{k+2} - x_{k+1}
    return b / a2[:, None], c / a2[:, None], a2


def assemble_coupled(points: np.ndarray, tri: np.ndarray, rhs: np.ndarray | None = None):
    """The full LSFEM system over dofs ``[ux_0..ux_N-1, uy_0..uy_N-1]``.

    ``rhs`` is the divergence right-hand side per triangle (zero by default).
    Returns ``(A, b)`` with ``A`` a (2N, 2N) CSR matrix.
    """
    import scipy.sparse as sp

    n = len(points)
    gx, gy, a2 = gradients(points, tri)
    area = 0.5 * a2
    d = np.concatenate([gx, gy], axis=1)  # (t, 6) divergence row
    c = np.concatenate([-gy, gx], axis=1)  # (t, 6) curl row
    ke = (d[:, :, None] * d[:, None, :] + c[:, :, None] * c[:, None, :]) * area[:, None, None]
    dofs = np.concatenate([tri, tri + n], axis=1)
    rows = np.repeat(dofs, 6, axis=1).ravel()
    cols = np.tile(dofs, (1, 6)).ravel()
    A = sp.csr_matrix((ke.ravel(), (rows, cols)), shape=(2 * n, 2 * n))
    b = np.zeros(2 * n)
    if rhs is not None:
        np.add.at(b, dofs.ravel(), (d * (area * rhs)[:, None]).ravel())
    return A, b


@dataclass(frozen=True)
class CSR:
    """A sparse matrix as three CSR arrays (or CSC: the same arrays, transposed).

    Enough for the solvers here, which read these arrays, without loading
    scipy.sparse (a noticeable part of start-up) on the default path.
    """

    data: np.ndarray
    indices: np.ndarray
    indptr: np.ndarray
    shape: tuple[int, int]

    @property
    def nnz(self) -> int:
        return len(self.data)


@dataclass(frozen=True)
class SymmetricCSR(CSR):
    """A symmetric matrix in CSR (its whole pattern: both triangles)."""

    def tocsr(self):
        """As a scipy.sparse matrix (for conjugate gradients and multigrid)."""
        import scipy.sparse as sp

        return sp.csr_matrix((self.data, self.indices, self.indptr), shape=self.shape)


class Assembler:
    """Assemble the split div-curl system on a fixed connectivity, many times.

    The sparsity pattern of the free-free block and the map from element
    entries to CSR slots are computed once; each call to :meth:`system` only
    recomputes the element matrices on the current coordinates.
    """

    def __init__(self, tri: np.ndarray, n_nodes: int, dirichlet: np.ndarray):
        self.tri = tri
        self.free = np.flatnonzero(~dirichlet)
        nf = len(self.free)
        self.n_free = nf
        fidx = np.full(n_nodes, -1, dtype=np.int64)
        fidx[self.free] = np.arange(nf)
        self._fidx = fidx
        from ._divcurl import pattern

        self._tri = t = np.ascontiguousarray(tri, dtype=np.int64)
        # the free-free pattern (rows' columns sorted) and, per element entry (9 per
        # triangle, row-major), its CSR slot (free row and column) or -1: a counting
        # sort by row, compiled (:mod:`._divcurl`)
        indptr = np.empty(nf + 1, dtype=np.int64)
        indices = np.empty(9 * len(t), dtype=np.int64)
        self._entry_slot = np.empty(9 * len(t), dtype=np.int64)
        nnz = pattern(t, fidx, nf, indptr, indices, self._entry_slot)
        self._indices = indices[:nnz].astype(np.int32)
        self._indptr = indptr.astype(np.int32)
        self._nnz = nnz

    def load(self, points: np.ndarray, r: np.ndarray) -> np.ndarray:
        """The divergence load ``sum_T |T| r_T (gx, gy)`` on the free dofs, (n_free, 2)."""
        gx, gy, a2 = gradients(points, self.tri)
        w = (0.5 * a2 * r)[:, None]
        nodes = self.tri.ravel()
        free = self._fidx[nodes]
        ok = free >= 0
        out = np.empty((self.n_free, 2))
        for comp, g in enumerate((gx, gy)):
            out[:, comp] = np.bincount(free[ok], weights=(w * g).ravel()[ok], minlength=self.n_free)
        return out

    def system(self, points: np.ndarray, u_dirichlet: np.ndarray):
        """``K_ff`` (:class:`SymmetricCSR`) and right-hand sides (n_free, 2) for given
        Dirichlet values.

        ``u_dirichlet`` is (N, 2); only its rows at Dirichlet nodes are read.  The
        element matrices are the P1 Laplace ones, ``(gx_i gx_j + gy_i gy_j) |T|``, summed
        into their slots in element order (a compiled loop, :mod:`._divcurl`).
        """
        from ._divcurl import assemble

        fidx = self._fidx
        data = np.zeros(self._nnz)
        acc = np.zeros((self.n_free, 2))
        pts = np.ascontiguousarray(points, dtype=np.float64)
        ud = np.ascontiguousarray(u_dirichlet, dtype=np.float64)
        assemble(pts, self._tri, self._entry_slot, fidx, ud, data, acc)
        K = SymmetricCSR(
            data,
            self._indices,
            self._indptr,
            (self.n_free,) * 2,
        )
        return K, -acc
