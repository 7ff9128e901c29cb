# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loops of :class:`deformesh_cli.adapt.Walk` and :func:`deformesh_cli.adapt.p1_values`:
each point walks from its last triangle across the side of its most negative
barycentric weight, and a P1 field is read with the weights found, the numpy
versions' operations in order (the same bits; compiled without fused multiply-adds)."""

from ._nanmin cimport nan_min


def walk(
    const double[::1] ax, const double[::1] ay, const double[::1] bx, const double[::1] by,
    const double[::1] cx, const double[::1] cy, const long long[:, ::1] neighbours,
    const double[:, ::1] q, long long limit, double round_off,
    long long[::1] t, double[:, ::1] w,
):
    """Each point ``q[i]`` from the triangle ``t[i]``: its weights there, then at most
    ``limit`` steps across the side of its first least weight while that weight is
    below ``-round_off`` and the side is not the boundary; ``t`` and ``w`` (k, 3) get
    where each stopped.  Returns how many stopped with a weight below ``-round_off``
    (outside the mesh, or out of steps)."""
    cdef Py_ssize_t k = q.shape[0]
    cdef Py_ssize_t i, steps, j
    cdef long long ti, nx
    cdef double dx, dy, w0, w1, w2, least
    cdef long long lost = 0
    with nogil:
        for i in range(k):
            ti = t[i]
            steps = 0
            while True:  # (the weights in triangle ti, then a step while they ask for one)
                dx = q[i, 0] - ax[ti]
                dy = q[i, 1] - ay[ti]
                w1 = bx[ti] * dx + by[ti] * dy
                w2 = cx[ti] * dx + cy[ti] * dy
                w0 = 1.0 - w1 - w2
                least = nan_min(nan_min(w0, w1), w2)  # (np.minimum's, twice)
                if not (least < -round_off and steps < limit):
                    break
                j = 0
                if w1 < w0:
                    j = 1
                if w2 < (w0 if j == 0 else w1):
                    j = 2
                nx = neighbours[ti, j]
                if nx < 0:
                    break
                ti = nx
                steps += 1
            t[i] = ti
            w[i, 0] = w0
            w[i, 1] = w1
            w[i, 2] = w2
            if least < -round_off:
                lost += 1
    return lost


def p1(
    const double[:, ::1] values, const long long[:, ::1] tri, const long long[::1] t,
    const double[:, ::1] w, double[:, ::1] out,
):
    """``out[i] = w[i, 0] v[a] + w[i, 1] v[b] + w[i, 2] v[c]`` for the corners ``a, b, c``
    of triangle ``t[i]``, summed in that order, column by column of ``values``."""
    cdef Py_ssize_t k = t.shape[0]
    cdef Py_ssize_t d = values.shape[1]
    cdef Py_ssize_t i, e
    cdef long long a, b, c
    cdef double s
    with nogil:
        for i in range(k):
            a = tri[t[i], 0]
            b = tri[t[i], 1]
            c = tri[t[i], 2]
            for e in range(d):
                s = w[i, 0] * values[a, e]
                s = s + w[i, 1] * values[b, e]
                s = s + w[i, 2] * values[c, e]
                out[i, e] = s
