# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loops of :mod:`deformesh_cli.smoothing`: per node and candidate position, the
tangent of the smallest angle of the node's worst triangle (:func:`apex_quality`, the
numpy reference's operations in order: the same bits), and the pattern search that
moves each node of an independent set (:func:`search`).  Compiled without fused
multiply-adds: the same bits on every processor."""

from libc.math cimport INFINITY, isnan

from ._nanmin cimport nan_min


cdef inline double worst(
    Py_ssize_t lo, Py_ssize_t end,
    const double[:] ax, const double[:] ay, const double[:] bx, const double[:] by,
    const double[:] s0, double x, double y,
) noexcept nogil:
    """The least ``2 cross / (s0 + s1 + s2 - 2 shortest)`` over the triangles ``lo`` to
    ``end`` with apex ``(x, y)`` (``-inf`` for one not counter-clockwise; NaN spreads)."""
    cdef Py_ssize_t t
    cdef double e1x, e1y, e2x, e2y, cross, s1, s2, shortest, den, v, m = 0.0
    for t in range(lo, end):
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
        if t == lo:
            m = v
        elif isnan(m) or isnan(v):
            m = m + v
        elif v < m:
            m = v
    return m


cdef inline double raised(double t, double c, double cap) noexcept nogil:
    """:func:`deformesh_cli.smoothing._raised`, the same operations."""
    cdef double den, r
    if isnan(t):
        return t
    if t == -INFINITY:
        return -1.0 / c
    den = t * c
    den = 1.0 - den
    if not den > 0.0:
        return cap
    r = (t + c) / den
    return r if r < cap else cap


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
    cdef Py_ssize_t i, j, end
    with nogil:
        for i in range(n):
            end = first[i + 1] if i + 1 < n else nt
            for j in range(c):
                out[i, j] = worst(first[i], end, ax, ay, bx, by, s0, px[i, j], py[i, j])


def search(
    const long long[:] first,
    const double[:] ax,
    const double[:] ay,
    const double[:] bx,
    const double[:] by,
    const double[:] s0,
    const double[:, :] dirs,
    long long steps,
    double c,
    double cap,
    double[:] px,
    double[:] py,
    double[:] best,
    double[:] step,
):
    """Per node ``i`` (its triangles as for :func:`apex_quality`), ``steps`` rounds of
    the pattern search from ``(px[i], py[i])`` whose worst triangle's tangent is
    ``best[i]``: of the positions ``step[i]`` along each of ``dirs``, the best (the
    first of equals; none if one is NaN) is taken where it beats ``best`` raised by
    the gain (:func:`raised`; ``c`` the gain's tangent, ``cap`` the tangent of the
    largest raise), else the step halves.  ``px``, ``py``, ``best``, ``step``
    updated in place."""
    cdef Py_ssize_t n = px.shape[0]
    cdef Py_ssize_t nt = ax.shape[0]
    cdef Py_ssize_t nd = dirs.shape[0]
    cdef Py_ssize_t i, s, d, k, end
    cdef double bar, q, qk, x, y, kx, ky
    with nogil:
        for i in range(n):
            end = first[i + 1] if i + 1 < n else nt
            bar = raised(best[i], c, cap)
            for s in range(steps):
                k = -1
                qk = 0.0
                kx = 0.0
                ky = 0.0
                for d in range(nd):
                    x = step[i] * dirs[d, 0]
                    x = px[i] + x
                    y = step[i] * dirs[d, 1]
                    y = py[i] + y
                    q = worst(first[i], end, ax, ay, bx, by, s0, x, y)
                    if isnan(q):
                        k = -2
                        break
                    if k == -1 or q > qk:
                        k = d
                        qk = q
                        kx = x
                        ky = y
                if k >= 0 and qk > bar:
                    px[i] = kx
                    py[i] = ky
                    best[i] = qk
                    bar = raised(qk, c, cap)
                else:
                    step[i] = 0.5 * step[i]


def tan_min(const double[:, :] points, const long long[:, ::1] tri, double[::1] out):
    """Per triangle ``abc`` the tangent of its smallest angle, ``2 cross / (s0 + s1 + s2 -
    2 shortest)`` (``s`` the squared sides opposite ``a``, ``b``, ``c``), ``-inf`` where
    ``cross`` is not positive: the numpy expression's operations in order (NaN spreads
    through the least as ``np.minimum`` spreads it)."""
    cdef Py_ssize_t t
    cdef double ax, ay, bx, by, cx, cy, e0x, e0y, e1x, e1y, e2x, e2y
    cdef double cross, s0, s1, s2, shortest
    with nogil:
        for t in range(tri.shape[0]):
            ax = points[tri[t, 0], 0]
            ay = points[tri[t, 0], 1]
            bx = points[tri[t, 1], 0]
            by = points[tri[t, 1], 1]
            cx = points[tri[t, 2], 0]
            cy = points[tri[t, 2], 1]
            e0x = cx - bx
            e0y = cy - by
            e1x = ax - cx
            e1y = ay - cy
            e2x = bx - ax
            e2y = by - ay
            cross = e1x * e2y
            cross = cross - e1y * e2x
            s0 = e0x * e0x
            s0 = s0 + e0y * e0y
            s1 = e1x * e1x
            s1 = s1 + e1y * e1y
            s2 = e2x * e2x
            s2 = s2 + e2y * e2y
            shortest = nan_min(nan_min(s0, s1), s2)
            if cross > 0.0:
                out[t] = (2.0 * cross) / (((s0 + s1) + s2) - 2.0 * shortest)
            else:
                out[t] = -INFINITY
