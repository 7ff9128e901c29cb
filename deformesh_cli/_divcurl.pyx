# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loops of :mod:`deformesh_cli.divcurl` and of the deformation's fold check, per
triangle: the same operations, in the same order, as the numpy expressions they
replace (:func:`~deformesh_cli.divcurl.stiffness_entries` with ``np.bincount``,
:func:`~deformesh_cli.geometry.signed_areas` and
:func:`~deformesh_cli.deform.flat_margin`), so the results are the same bits.
"""

from libc.math cimport fabs, sqrt
from ._sort cimport sort_run


def assemble(
    const double[:, :] points,
    const long long[:, :] tri,
    const long long[:] slot,
    const long long[:] fidx,
    const double[:, :] ud,
    double[:] data,
    double[:, :] rhs,
):
    """Per triangle, its P1 Laplace element matrix ``ke[i, j] = (gx_i gx_j + gy_i gy_j)
    |T|``; entry ``e = 9 t + 3 i + j`` is added to ``data[slot[e]]`` where ``slot[e] >=
    0`` (free row and column), and ``ke * ud[col]`` to ``rhs[fidx[row]]`` where the row's
    node is free and the column's not (``fidx``: a node's free index, -1 for a Dirichlet
    node).  ``data`` and ``rhs`` start at 0;
    the sums run in the order of ``e``."""
    cdef Py_ssize_t nt = tri.shape[0]
    cdef Py_ssize_t t, i, j, e, col
    cdef long long fr
    cdef double x0, x1, x2, y0, y1, y2, a2, area, v
    cdef double gx[3]
    cdef double gy[3]
    with nogil:
        for t in range(nt):
            x0 = points[tri[t, 0], 0]
            x1 = points[tri[t, 1], 0]
            x2 = points[tri[t, 2], 0]
            y0 = points[tri[t, 0], 1]
            y1 = points[tri[t, 1], 1]
            y2 = points[tri[t, 2], 1]
            a2 = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
            gx[0] = (y1 - y2) / a2
            gx[1] = (y2 - y0) / a2
            gx[2] = (y0 - y1) / a2
            gy[0] = (x2 - x1) / a2
            gy[1] = (x0 - x2) / a2
            gy[2] = (x1 - x0) / a2
            area = 0.5 * a2
            for i in range(3):
                for j in range(3):
                    e = 9 * t + 3 * i + j
                    v = (gx[i] * gx[j] + gy[i] * gy[j]) * area
                    if slot[e] >= 0:
                        data[slot[e]] += v
                    else:
                        fr = fidx[tri[t, i]]
                        col = tri[t, j]
                        if fr >= 0 and fidx[col] < 0:
                            rhs[fr, 0] += v * ud[col, 0]
                            rhs[fr, 1] += v * ud[col, 1]


def areas(
    const double[:, :] points,
    const long long[:, :] tri,
    double sign,
    double flat,
    double round_off,
    double[:] out,
):
    """Per triangle its signed area, plus ``sign`` times its flat margin (``flat``
    times its longest side squared plus ``round_off`` times that side times its
    corners' largest coordinate) where ``sign`` is not 0."""
    cdef Py_ssize_t nt = tri.shape[0]
    cdef Py_ssize_t t
    cdef double ax, ay, bx, by, cx, cy, area, s0, s1, s2, sq, far, f
    with nogil:
        for t in range(nt):
            ax = points[tri[t, 0], 0]
            ay = points[tri[t, 0], 1]
            bx = points[tri[t, 1], 0]
            by = points[tri[t, 1], 1]
            cx = points[tri[t, 2], 0]
            cy = points[tri[t, 2], 1]
            area = 0.5 * ((bx - ax) * (cy - ay) - (cx - ax) * (by - ay))
            if sign != 0.0:
                s0 = (bx - ax) * (bx - ax) + (by - ay) * (by - ay)
                s1 = (cx - bx) * (cx - bx) + (cy - by) * (cy - by)
                s2 = (ax - cx) * (ax - cx) + (ay - cy) * (ay - cy)
                sq = s0 if s0 > s1 else s1
                sq = sq if sq > s2 else s2
                far = fabs(ax) if fabs(ax) > fabs(ay) else fabs(ay)
                f = fabs(bx) if fabs(bx) > fabs(by) else fabs(by)
                far = far if far > f else f
                f = fabs(cx) if fabs(cx) > fabs(cy) else fabs(cy)
                far = far if far > f else f
                area = area + sign * (flat * sq + round_off * sqrt(sq) * far)
            out[t] = area


def pattern(
    const long long[:, :] tri,
    const long long[:] fidx,
    long long n_free,
    long long[:] indptr,
    long long[:] indices,
    long long[:] entry_slot,
):
    """The free-free block's CSR pattern (rows' columns sorted, each once) and each
    element entry's slot in it (``e = 9 t + 3 i + j``: row ``fidx[tri[t, i]]``, column
    ``fidx[tri[t, j]]``; -1 where either is not free).  ``indices`` is filled by rows
    from a counting sort (at most 9 per triangle) and compacted; returns the count of
    entries.  ``indptr``: ``n_free + 1``."""
    cdef Py_ssize_t nt = tri.shape[0]
    cdef Py_ssize_t t, a, b, r, k, lo, hi, mid, out, begin, end
    cdef long long fr, fc, v
    with nogil:
        for r in range(n_free + 1):
            indptr[r] = 0
        for t in range(nt):
            for a in range(3):
                fr = fidx[tri[t, a]]
                if fr < 0:
                    continue
                for b in range(3):
                    if fidx[tri[t, b]] >= 0:
                        indptr[fr + 1] += 1
        for r in range(n_free):
            indptr[r + 1] += indptr[r]
        for t in range(nt):  # (indptr[r] is where row r's next column goes)
            for a in range(3):
                fr = fidx[tri[t, a]]
                if fr < 0:
                    continue
                for b in range(3):
                    fc = fidx[tri[t, b]]
                    if fc >= 0:
                        indices[indptr[fr]] = fc
                        indptr[fr] += 1
        out = 0
        begin = 0
        for r in range(n_free):  # each row sorted, each column once, compacted
            end = indptr[r]
            sort_run(indices, begin, end)
            indptr[r] = out
            k = begin
            while k < end:
                v = indices[k]
                indices[out] = v
                out += 1
                while k < end and indices[k] == v:
                    k += 1
            begin = end
        indptr[n_free] = out
        for t in range(nt):
            for a in range(3):
                fr = fidx[tri[t, a]]
                for b in range(3):
                    fc = fidx[tri[t, b]]
                    if fr < 0 or fc < 0:
                        entry_slot[9 * t + 3 * a + b] = -1
                        continue
                    lo = indptr[fr]
                    hi = indptr[fr + 1]
                    while lo < hi:
                        mid = (lo + hi) // 2
                        if indices[mid] < fc:
                            lo = mid + 1
                        else:
                            hi = mid
                    entry_slot[9 * t + 3 * a + b] = lo
    return out


def normal_equations(
    const double[:, ::1] d,
    const double[:, ::1] c,
    const double[::1] half,
    const long long[::1] first,
    const long long[::1] second,
    const long long[::1] entry,
    double[::1] out,
):
    """adapt's normal equations: for each pair ``k`` of slots (``first[k]``,
    ``second[k]``) and each cell ``t``, ``(d[p, t] d[q, t] + c[p, t] c[q, t]) half[t]``
    added to ``out[entry[k T + t]]`` (``out`` starts at 0), pair by pair and cell by
    cell: the order, and so the bits, of ``np.bincount`` over the pairs' rows."""
    cdef Py_ssize_t nt = half.shape[0]
    cdef Py_ssize_t k, t, p, q
    cdef double v
    with nogil:
        for k in range(first.shape[0]):
            p = first[k]
            q = second[k]
            for t in range(nt):
                v = d[p, t] * d[q, t]
                v = v + c[p, t] * c[q, t]
                v = v * half[t]
                out[entry[k * nt + t]] += v


def load_vector(
    const double[:, ::1] d, const double[::1] coef, const long long[::1] dof, double[::1] out
):
    """adapt's load: ``coef[t] d[k, t]`` added to ``out[dof[k T + t]]`` (``out`` starts at
    0), slot by slot and cell by cell: the order, and so the bits, of ``np.bincount``
    over ``(coef * d).ravel()``."""
    cdef Py_ssize_t nt = coef.shape[0]
    cdef Py_ssize_t k, t
    with nogil:
        for k in range(d.shape[0]):
            for t in range(nt):
                out[dof[k * nt + t]] += coef[t] * d[k, t]
