# cython: language_level=3
"""Distances to the nodes of :mod:`deformesh_cli.select.boxtree`'s trees, shared by the
walks that search them (``_cones``, ``_segments``, ``_nearest``).  ``box`` holds per
node ``xmin, xmax, ymin, ymax``; an empty node's box is inverted, so every gap to it
is inf.  In floating point too, a node's gap is at most that of every item in it
(rounding is monotone), so a walk that skips a node by its gap skips nothing nearer."""


cdef inline double gap(double lo, double hi, double c, double half) noexcept nogil:
    # the distance along one axis from [lo, hi] to [c - half, c + half]
    cdef double g = lo - c
    cdef double other = c - hi
    if other > g:
        g = other
    g = g - half
    return g if g > 0.0 else 0.0


cdef inline double gap2(
    const double[:] box, Py_ssize_t k, double x, double y, double hw, double hh
) noexcept nogil:
    # the squared distance from node k's box to the box of half sides hw, hh at (x, y)
    cdef double gx = gap(box[4 * k], box[4 * k + 1], x, hw)
    cdef double gy = gap(box[4 * k + 2], box[4 * k + 3], y, hh)
    return gx * gx + gy * gy
