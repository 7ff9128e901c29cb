# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loop of :class:`deformesh_cli.select.nearest.Nearest`: per query point, its
``k`` nearest points (by squared distance, then by number), by a walk down a tree of
bounding boxes (:mod:`deformesh_cli.select.boxtree`) that skips every subtree
farther than the ``k``-th nearest found so far."""

from libc.math cimport INFINITY, sqrt

from ._boxes cimport gap2


def nearest(
    const double[:] qx,
    const double[:] qy,
    const double[:] px,
    const double[:] py,
    const long long[:] order,
    const long long[:] start,
    const double[:] box,
    long long leaf0,
    long long n,
    double[:, :] dist,
    long long[:, :] index,
):
    """``index[q]``: the ``k`` (columns) points nearest query ``q`` in increasing
    squared distance, ties by number (``n`` past the last point); ``dist``: their
    distances (``sqrt`` of the squared distance; inf past the last point)."""
    cdef Py_ssize_t nq = qx.shape[0]
    cdef Py_ssize_t k = dist.shape[1]
    cdef Py_ssize_t q, i, j, c, top, lo, hi
    cdef long long node, e, stack[128]
    cdef double x, y, b0, b1, d2, worst
    cdef long long worst_i
    with nogil:
        for q in range(nq):
            x = qx[q]
            y = qy[q]
            for j in range(k):
                dist[q, j] = INFINITY
                index[q, j] = n
            stack[0] = 1
            top = 1
            while top > 0:
                top -= 1
                node = stack[top]
                if gap2(box, node, x, y, 0.0, 0.0) > dist[q, k - 1]:
                    continue
                if node < leaf0:
                    c = 2 * node
                    b0 = gap2(box, c, x, y, 0.0, 0.0)
                    b1 = gap2(box, c + 1, x, y, 0.0, 0.0)
                    if b0 <= b1:
                        stack[top] = c + 1
                        stack[top + 1] = c
                    else:
                        stack[top] = c
                        stack[top + 1] = c + 1
                    top += 2
                    continue
                lo = start[node - leaf0]
                hi = start[node - leaf0 + 1]
                for i in range(lo, hi):
                    e = order[i]
                    d2 = (px[e] - x) * (px[e] - x) + (py[e] - y) * (py[e] - y)
                    worst = dist[q, k - 1]
                    worst_i = index[q, k - 1]
                    if d2 > worst or (d2 == worst and e > worst_i):
                        continue
                    j = k - 1
                    while j > 0 and (
                        dist[q, j - 1] > d2 or (dist[q, j - 1] == d2 and index[q, j - 1] > e)
                    ):
                        dist[q, j] = dist[q, j - 1]
                        index[q, j] = index[q, j - 1]
                        j -= 1
                    dist[q, j] = d2
                    index[q, j] = e
            for j in range(k):
                dist[q, j] = sqrt(dist[q, j])
