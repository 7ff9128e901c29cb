# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loop of :func:`deformesh_cli.select.construct._monotone`: the dynamic programme
along the ring, one point after the other (min-plus products of ``k x k`` step costs),
the numpy reference's operations in its order."""

from libc.math cimport INFINITY


def programme(
    const double[:, :, :] between,
    const double[:, :] cost,
    long long[:, :] back,
    double[:] total,
    unsigned char[:] reset,
):
    """For ``t = 1 .. m - 1``: ``step[i, j] = total[i] + between[t, i, j]``,
    ``back[t, j]`` the first ``i`` least in column ``j``, ``total[j] = step[back, j] +
    cost[t, j]``; where every ``total`` is inf, ``reset[t] = 1`` and ``total =
    cost[t]``.  ``total`` holds the start's on entry and the last point's on return."""
    cdef Py_ssize_t m = cost.shape[0]
    cdef Py_ssize_t k = cost.shape[1]
    cdef Py_ssize_t t, i, j, pick
    cdef double best, v, low
    cdef double[64] nxt
    with nogil:
        for t in range(1, m):
            low = INFINITY
            for j in range(k):
                pick = 0
                best = total[0] + between[t, 0, j]
                for i in range(1, k):
                    v = total[i] + between[t, i, j]
                    if v < best:
                        best = v
                        pick = i
                back[t, j] = pick
                nxt[j] = best + cost[t, j]
                if nxt[j] < low:
                    low = nxt[j]
            if low == INFINITY:
                reset[t] = 1
                for j in range(k):
                    total[j] = cost[t, j]
            else:
                for j in range(k):
                    total[j] = nxt[j]
