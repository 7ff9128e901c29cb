# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loop of :class:`deformesh_cli.select.segments.Segments`: per query point, the
distance to the nearest point of a contour edge that is another part of the contour,
on the domain's side, within a radius; by a walk down a tree of bounding boxes
(:mod:`deformesh_cli.select.boxtree`) that skips every subtree farther than the
radius or than the best distance found.  Compiled without contraction to fused
multiply-adds: the arithmetic is the same on every processor.
"""

from libc.math cimport INFINITY, fabs, hypot, sqrt

from ._boxes cimport gap2


cdef inline int _half(double fx, double fy, double zx, double zy) noexcept nogil:
    # 0 where z turns from f counter-clockwise by [0, pi), 1 by [pi, 2 pi)
    cdef double c = fx * zy - fy * zx
    cdef double d = fx * zx + fy * zy
    if c < 0.0 or (c == 0.0 and d < 0.0):
        return 1
    return 0


cdef inline bint _in_wedge(
    double wx, double wy, double fx, double fy, double bx, double by
) noexcept nogil:
    # w turns from f counter-clockwise no farther than b does (closed)
    cdef int hw = _half(fx, fy, wx, wy)
    cdef int hb = _half(fx, fy, bx, by)
    if hw != hb:
        return hw < hb
    return wx * by - wy * bx >= 0.0


def clearance(
    const double[:] qx,
    const double[:] qy,
    const double[:] q_arc,
    const long long[:] q_ring,
    const long long[:] own0,
    const long long[:] own1,
    const long long[:] own2,
    const double[:] fwd_x,
    const double[:] fwd_y,
    const double[:] back_x,
    const double[:] back_y,
    const double[:] radius,
    const double[:] ax,
    const double[:] ay,
    const double[:] bx,
    const double[:] by,
    const double[:] arc,
    const double[:] length,
    const long long[:] ring,
    const double[:] perimeter,
    const long long[:] order,
    const long long[:] start,
    const double[:] box,
    long long leaf0,
    double turn,
    double[:] out,
):
    """``out[q]``: the least distance from query point ``q`` to a point ``y`` of an edge
    ``e`` (``a[e]`` to ``b[e]``, not ``own0[q]``, ``own1[q]`` or ``own2[q]``) with ``|q - y| <=
    radius[q]``, ``y`` another part of the contour (on another ring, or farther along
    it than ``turn`` times the distance) and ``y - q`` in the wedge turning
    counter-clockwise from ``fwd`` to ``back``; inf where there is none."""
    cdef Py_ssize_t nq = qx.shape[0]
    cdef Py_ssize_t q, i, e, k, lo, hi, top
    cdef long long stack[128]
    cdef double best, x, y, r, bound, ex, ey, ll, t, px, py, d, along, other, wrap
    with nogil:
        for q in range(nq):
            x = qx[q]
            y = qy[q]
            r = radius[q]
            best = INFINITY
            stack[0] = 1
            top = 1
            while top > 0:
                top -= 1
                k = stack[top]
                bound = sqrt(gap2(box, k, x, y, 0.0, 0.0))
                if bound > r or not bound < best:
                    continue
                if k < leaf0:
                    stack[top] = 2 * k + 1
                    stack[top + 1] = 2 * k
                    top += 2
                    continue
                lo = start[k - leaf0]
                hi = start[k - leaf0 + 1]
                for i in range(lo, hi):
                    e = order[i]
                    if e == own0[q] or e == own1[q] or e == own2[q]:
                        continue
                    ex = bx[e] - ax[e]
                    ey = by[e] - ay[e]
                    ll = ex * ex + ey * ey
                    t = ((x - ax[e]) * ex + (y - ay[e]) * ey) / (ll if ll > 0.0 else 1.0)
                    if t < 0.0:
                        t = 0.0
                    elif t > 1.0:
                        t = 1.0
                    px = ax[e] + t * ex
                    py = ay[e] + t * ey
                    d = hypot(x - px, y - py)
                    if d > r or not d < best:
                        continue
                    if q_ring[q] == ring[e]:
                        along = fabs(q_arc[q] - (arc[e] + t * length[e]))
                        wrap = perimeter[ring[e]] - along
                        if wrap < along:
                            along = wrap
                        if not along > turn * d:
                            continue
                    if not _in_wedge(px - x, py - y, fwd_x[q], fwd_y[q], back_x[q], back_y[q]):
                        continue
                    best = d
            out[q] = best
