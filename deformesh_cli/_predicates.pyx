# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""Exact geometric predicates: the sign of an orientation determinant from float
coordinates, decided in floating point when its error bound allows (Shewchuk's
first filter) and in exact rational arithmetic otherwise; and, with it, whether
segments meet triangles (a touch counts), one pair per loop step."""

from fractions import Fraction

from libc.math cimport fabs
from ._sort cimport sort_run

#: Shewchuk's ``ccwerrboundA``, (3 + 16 eps) eps with eps = 2^-53: where the float
#: determinant's magnitude exceeds this times its terms' sum, its sign is exact.
cdef double BOUND = (3.0 + 16.0 * 2.0 ** -53) * 2.0 ** -53


def _exact(double ax, double ay, double bx, double by, double cx, double cy):
    ax_, ay_ = Fraction(ax), Fraction(ay)
    det = (Fraction(bx) - ax_) * (Fraction(cy) - ay_) - (Fraction(by) - ay_) * (Fraction(cx) - ax_)
    return (det > 0) - (det < 0)


cdef int orient(double ax, double ay, double bx, double by, double cx, double cy) noexcept:
    """The sign of ``(b - a) x (c - a)``, exactly: 1 counter-clockwise, -1 clockwise, 0
    collinear."""
    cdef double l = (bx - ax) * (cy - ay)
    cdef double r = (by - ay) * (cx - ax)
    cdef double det = l - r
    if fabs(det) > BOUND * (fabs(l) + fabs(r)):
        return (det > 0) - (det < 0)
    return _exact(ax, ay, bx, by, cx, cy)


cdef bint between(double a, double b, double c) noexcept:
    return (a <= c <= b) or (b <= c <= a)


cdef bint segments_meet(
    double px, double py, double qx, double qy, double ux, double uy, double vx, double vy
) noexcept:
    """The closed segments ``p q`` and ``u v`` share a point."""
    cdef int d1 = orient(px, py, qx, qy, ux, uy)
    cdef int d2 = orient(px, py, qx, qy, vx, vy)
    cdef int d3 = orient(ux, uy, vx, vy, px, py)
    cdef int d4 = orient(ux, uy, vx, vy, qx, qy)
    if d1 == 0 and d2 == 0:  # (all four on one line: their extents overlap)
        if px != qx or ux != vx:
            return (
                between(px, qx, ux) or between(px, qx, vx)
                or between(ux, vx, px) or between(ux, vx, qx)
            )
        return (
            between(py, qy, uy) or between(py, qy, vy)
            or between(uy, vy, py) or between(uy, vy, qy)
        )
    return d1 * d2 <= 0 and d3 * d4 <= 0


def segments_meet_triangles(
    const double[:, :] points,
    const long long[:, :] tri,
    const long long[:] t,
    const double[:, :] a,
    const double[:, :] b,
    unsigned char[:] out,
):
    """``out[k]``: the segment ``a[k] b[k]`` and the closed counter-clockwise triangle
    ``tri[t[k]]`` share a point (exactly, for these float coordinates)."""
    cdef Py_ssize_t k, s
    cdef long long v0, v1, v2
    cdef double px, py, qx, qy
    cdef bint hit
    cdef double x[3]
    cdef double y[3]
    for k in range(t.shape[0]):
        x[0] = points[tri[t[k], 0], 0]
        y[0] = points[tri[t[k], 0], 1]
        x[1] = points[tri[t[k], 1], 0]
        y[1] = points[tri[t[k], 1], 1]
        x[2] = points[tri[t[k], 2], 0]
        y[2] = points[tri[t[k], 2], 1]
        px, py, qx, qy = a[k, 0], a[k, 1], b[k, 0], b[k, 1]
        # an end inside or on the triangle
        hit = (
            orient(x[0], y[0], x[1], y[1], px, py) >= 0
            and orient(x[1], y[1], x[2], y[2], px, py) >= 0
            and orient(x[2], y[2], x[0], y[0], px, py) >= 0
        )
        s = 0
        while not hit and s < 3:
            hit = segments_meet(px, py, qx, qy, x[s], y[s], x[(s + 1) % 3], y[(s + 1) % 3])
            s += 1
        out[k] = hit


cdef bint segment_meets_box(
    double ax, double ay, double bx, double by, double x0, double x1, double y0, double y1
) noexcept:
    """The closed segment ``a b`` and the closed box ``[x0, x1] x [y0, y1]`` share a
    point: their extents overlap on both axes and the box's corners are not all
    strictly on one side of the segment's line (no separating axis)."""
    cdef int s0, s1, s2, s3
    if (ax < x0 and bx < x0) or (ax > x1 and bx > x1):
        return False
    if (ay < y0 and by < y0) or (ay > y1 and by > y1):
        return False
    s0 = orient(ax, ay, bx, by, x0, y0)
    s1 = orient(ax, ay, bx, by, x1, y0)
    s2 = orient(ax, ay, bx, by, x1, y1)
    s3 = orient(ax, ay, bx, by, x0, y1)
    return not ((s0 > 0 and s1 > 0 and s2 > 0 and s3 > 0) or (s0 < 0 and s1 < 0 and s2 < 0 and s3 < 0))


def boxes_meet_segments(
    const double[:] x0,
    const double[:] x1,
    const double[:] y0,
    const double[:] y1,
    const double[:] ax,
    const double[:] ay,
    const double[:] bx,
    const double[:] by,
    const long long[:] order,
    const long long[:] start,
    const double[:] box,
    long long leaf0,
    long long[:] out_box,
    long long[:] out_seg,
):
    """Every pair of a box ``q`` and a segment ``e`` (``a[e]`` to ``b[e]``, held in the
    tree ``order``, ``start``, ``box``, ``leaf0`` of :mod:`.select.boxtree`) that share a
    point, exactly, by query then segment number into ``out_box``, ``out_seg``;
    returns how many (past the arrays' length only counted: call again with room)."""
    cdef Py_ssize_t nq = x0.shape[0], cap = out_box.shape[0]
    cdef Py_ssize_t q, i, k, top, m = 0, first
    cdef long long e
    cdef long long stack[128]
    for q in range(nq):
        first = m
        stack[0] = 1
        top = 1
        while top > 0:
            top -= 1
            k = stack[top]
            if box[4 * k] > x1[q] or box[4 * k + 1] < x0[q] or box[4 * k + 2] > y1[q] or box[4 * k + 3] < y0[q]:
                continue  # (an empty node's inverted box is skipped here too)
            if k < leaf0:
                stack[top] = 2 * k + 1
                stack[top + 1] = 2 * k
                top += 2
                continue
            for i in range(start[k - leaf0], start[k - leaf0 + 1]):
                e = order[i]
                if segment_meets_box(ax[e], ay[e], bx[e], by[e], x0[q], x1[q], y0[q], y1[q]):
                    if m < cap:
                        out_box[m] = q
                        out_seg[m] = e
                    m += 1
        if m <= cap:  # (this query's segments ascending: insertion sort, a few each)
            sort_run(out_seg, first, m)
    return m
