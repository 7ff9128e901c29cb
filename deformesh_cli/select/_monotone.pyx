# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loop of :func:`deformesh_cli.select.construct._monotone`: the dynamic programme
along the ring, one point after the other (min-plus products of ``k x k`` step costs),
the numpy reference's operations in its order."""

from libc.math cimport INFINITY, copysign, fmod


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


cdef inline double _remainder(double a, double b) noexcept nogil:
    # numpy's floating remainder: the sign of the divisor
    cdef double mod = fmod(a, b)
    if mod != 0.0:
        if (b < 0.0) != (mod < 0.0):
            mod += b
    else:
        mod = copysign(0.0, b)
    return mod


def between_costs(
    const double[:, :] loop,
    const double[:] at,
    double perimeter,
    const long long[:, :] cand,
    const double[:, :] q,
    const double[:] s,
    const double[:] share,
    long long widest,
    double[:, :, :] out,
    double[:] running,
):
    """:func:`deformesh_cli.select.construct._between_costs`' table, its numpy
    operations in order: per step ``t`` (from point ``t - 1``, ``t = 0`` from the last)
    and candidate pair ``(a, b)``, inf where the step is not allowed, else the summed
    squared distances (over the first point's size squared) of the loop nodes strictly
    between that lie past an end of the edge.  ``running``: scratch, ``len(loop) + 1``."""
    cdef Py_ssize_t m = cand.shape[0]
    cdef Py_ssize_t k = cand.shape[1]
    cdef Py_ssize_t nl = loop.shape[0]
    cdef Py_ssize_t t, prev, a, b, w, reach, node
    cdef long long gap, start
    cdef long long[64] count
    cdef double run, ax, ay, abx, aby, length2, size, rx, ry, tt, dx, dy, d2
    with nogil:
        for t in range(m):
            prev = t - 1 if t > 0 else m - 1
            ax = q[prev, 0]
            ay = q[prev, 1]
            abx = q[t, 0] - q[prev, 0]
            aby = q[t, 1] - q[prev, 1]
            size = s[prev]
            length2 = abx * abx + aby * aby
            if length2 < 1e-300:
                length2 = 1e-300
            for a in range(k):
                start = cand[prev, a]
                reach = 0
                for b in range(k):
                    gap = (cand[t, b] - start) % nl
                    if gap < 0:
                        gap += nl
                    run = _remainder(at[cand[t, b]] - at[start], perimeter)
                    if gap >= 1 and gap <= widest and run <= 0.5 * (1.0 + share[t]) * perimeter:
                        out[t, a, b] = 0.0
                        count[b] = gap - 1
                    else:
                        out[t, a, b] = INFINITY
                        count[b] = 0
                    if count[b] > reach:
                        reach = count[b]
                if reach == 0:
                    continue
                running[0] = 0.0
                for w in range(1, reach + 1):
                    node = (start + w) % nl
                    rx = loop[node, 0] - ax
                    ry = loop[node, 1] - ay
                    tt = (rx * abx + ry * aby) / length2
                    if tt < 0.0 or tt > 1.0:
                        if tt < 0.0:
                            dx = rx
                            dy = ry
                        else:
                            dx = rx - abx
                            dy = ry - aby
                        d2 = (dx * dx + dy * dy) / (size * size)
                    else:
                        d2 = 0.0
                    running[w] = running[w - 1] + d2
                for b in range(k):
                    out[t, a, b] = out[t, a, b] + running[count[b]]
