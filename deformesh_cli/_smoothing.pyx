# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loop of :func:`deformesh_cli.smoothing._apex_quality`: per node and candidate
position, the tangent of the smallest angle of the node's worst triangle, the numpy
reference's operations in order (the same bits; compiled without fused multiply-adds)."""

from libc.math cimport INFINITY, isnan


def apex_quality(
    const long long[:] first,
    const double[:] ax,
    const double[:] ay,
    const double[:] bx,
    const double[:] by,
    const double[:] s0,
    const double[:, :] px,
    const double[:, :] py,
    double[:, :] out,
):
    """``out[i, j]``: over node ``i``'s triangles ``t`` (``first[i]`` to ``first[i +
    1]``, the last to the end) with apex ``(px[i, j], py[i, j])`` and far side ``a_t ->
    b_t`` (its length squared ``s0[t]``), the least of ``2 cross / (s0 + s1 + s2 - 2
    shortest)``, ``-inf`` where the triangle is not counter-clockwise (NaN spreads)."""
    cdef Py_ssize_t n = px.shape[0]
    cdef Py_ssize_t c = px.shape[1]
    cdef Py_ssize_t nt = ax.shape[0]
    cdef Py_ssize_t i, j, t, end
    cdef double x, y, e1x, e1y, e2x, e2y, cross, s1, s2, shortest, den, v, m
    with nogil:
        for i in range(n):
            end = first[i + 1] if i + 1 < n else nt
            for j in range(c):
                x = px[i, j]
                y = py[i, j]
                m = 0.0
                for t in range(first[i], end):
                    e1x = x - bx[t]
                    e1y = y - by[t]
                    e2x = ax[t] - x
                    e2y = ay[t] - y
                    cross = e1x * e2y
                    cross = cross - e1y * e2x
                    s1 = e1x * e1x
                    s1 = s1 + e1y * e1y
                    s2 = e2x * e2x
                    s2 = s2 + e2y * e2y
                    shortest = s0[t] if s0[t] < s1 else s1
                    if isnan(s0[t]) or isnan(s1):
                        shortest = s0[t] + s1
                    if s2 < shortest or isnan(s2):
                        shortest = s2 if not isnan(shortest) else shortest
                    den = s0[t] + s1
                    den = den + s2
                    shortest = shortest * 2.0
                    den = den - shortest
                    if cross > 0.0:
                        v = (cross * 2.0) / den
                    else:
                        v = -INFINITY
                    if t == first[i]:
                        m = v
                    elif isnan(m) or isnan(v):
                        m = m + v
                    elif v < m:
                        m = v
                out[i, j] = m
