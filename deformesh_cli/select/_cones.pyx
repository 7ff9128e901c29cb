# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loop of :class:`deformesh_cli.select.cones.Cones`: per query box, the least over
all points ``p`` of ``s_p + alpha * d(p, box)``, by a walk down a tree of bounding
boxes that skips every subtree whose bound cannot beat the best found so far.

The tree is built by the Python side (nodes in heap order: node ``k`` has children
``2k`` and ``2k + 1``; nodes ``leaf0 .. 2 * leaf0 - 1`` are leaves holding points
``start[k - leaf0] .. start[k - leaf0 + 1] - 1`` of the sorted arrays).  Every value
is computed as ``s + alpha * sqrt(dx * dx + dy * dy)`` with ``dx = max(|px - cx| -
hw, 0)`` (compiled without contraction to fused multiply-adds), and a node's bound
by the same operations on its box, which rounding keeps at or below every value
inside it.  A subtree is skipped unless its bound is below the best value found
divided by ``slack``: each result is at most ``slack`` times the least computed
value (exactly the least for ``slack`` 1), and the walk's order is fixed by the
tree, so the result is the same on every run and machine.
"""

from libc.math cimport INFINITY, fabs, sqrt

from ._boxes cimport gap2


def least(
    const double[:] cx,
    const double[:] cy,
    const double[:] half_w,
    const double[:] half_h,
    const double[:] px,
    const double[:] py,
    const double[:] ps,
    const double[:] box,
    const double[:] node_s,
    const long long[:] start,
    long long leaf0,
    double alpha,
    double slack,
    double[:] out,
):
    """``out[q]``: the least over every point of ``ps + alpha * distance(point, box q)``,
    to within a factor ``slack`` (>= 1: a subtree is skipped when its bound times
    ``slack`` is no lower than the best value found).

    ``box``: (4 * nodes) per node xmin, xmax, ymin, ymax (inverted for an empty node);
    ``node_s``: per node the least ``ps`` under it (inf for an empty node)."""
    cdef Py_ssize_t nq = cx.shape[0]
    cdef Py_ssize_t q, p, k, a, b, top
    cdef long long stack[128]
    cdef double best, x, y, hw, hh, bound, ba, bb, dx, dy, v
    with nogil:
        for q in range(nq):
            x = cx[q]
            y = cy[q]
            hw = half_w[q]
            hh = half_h[q]
            best = INFINITY
            top = 0
            stack[0] = 1
            top = 1
            while top > 0:
                top -= 1
                k = stack[top]
                bound = node_s[k] + alpha * sqrt(gap2(box, k, x, y, hw, hh))
                if not bound * slack < best:
                    continue
                if k >= leaf0:
                    a = start[k - leaf0]
                    b = start[k - leaf0 + 1]
                    for p in range(a, b):
                        dx = fabs(px[p] - x) - hw
                        dy = fabs(py[p] - y) - hh
                        if dx < 0.0:
                            dx = 0.0
                        if dy < 0.0:
                            dy = 0.0
                        v = ps[p] + alpha * sqrt(dx * dx + dy * dy)
                        if v < best:
                            best = v
                    continue
                # (both children, the one with the lower bound on top: walked first)
                a = 2 * k
                b = 2 * k + 1
                ba = node_s[a] + alpha * sqrt(gap2(box, a, x, y, hw, hh))
                bb = node_s[b] + alpha * sqrt(gap2(box, b, x, y, hw, hh))
                if ba < bb:
                    stack[top] = b
                    stack[top + 1] = a
                else:
                    stack[top] = a
                    stack[top + 1] = b
                top += 2
            out[q] = best
