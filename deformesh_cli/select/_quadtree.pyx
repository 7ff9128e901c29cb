# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loop of :meth:`deformesh_cli.select.graded.Quadtree.leaf_index`: per cell, the
leaf holding it, by a binary search over the leaves' Morton codes."""


cdef long long M32 = 0xFFFFFFFF
cdef long long M16 = 0x0000FFFF0000FFFF
cdef long long M8 = 0x00FF00FF00FF00FF
cdef long long M4 = 0x0F0F0F0F0F0F0F0F
cdef long long M2 = 0x3333333333333333
cdef long long M1 = 0x5555555555555555


cdef inline long long _spread(long long v) noexcept nogil:
    # (as deformesh_cli.geometry.morton)
    v = v & M32
    v = (v | (v << 16)) & M16
    v = (v | (v << 8)) & M8
    v = (v | (v << 4)) & M4
    v = (v | (v << 2)) & M2
    v = (v | (v << 1)) & M1
    return v


def leaf_index(
    const long long[:] starts,
    const long long[:] order,
    const long long[:] leaf_level,
    const long long[:] level,
    const long long[:] i,
    const long long[:] j,
    long long width,
    long long height,
    long long top,
    long long[:] out,
):
    """``out[c]``: the leaf (a position in ``leaf_level``) holding cell ``(level[c],
    i[c], j[c])``, or -1 where it lies outside the ``width`` x ``height`` finest cells,
    above level ``top``, or is split into finer leaves.  ``starts``: the leaves'
    Morton codes of their first finest cell, sorted; ``order``: the leaves in that
    order."""
    cdef Py_ssize_t nc = level.shape[0]
    cdef Py_ssize_t nl = starts.shape[0]
    cdef Py_ssize_t c, lo, hi, mid
    cdef long long lv, ci, cj, code, leaf
    with nogil:
        for c in range(nc):
            out[c] = -1
            lv = level[c]
            ci = i[c]
            cj = j[c]
            if ci < 0 or cj < 0 or lv > top or lv < 0:
                continue
            if (ci << lv) >= width or (cj << lv) >= height:
                continue
            code = _spread(ci << lv) | (_spread(cj << lv) << 1)
            lo = 0  # (the last start at or before the code: searchsorted right, minus 1)
            hi = nl
            while lo < hi:
                mid = (lo + hi) // 2
                if starts[mid] <= code:
                    lo = mid + 1
                else:
                    hi = mid
            if lo == 0:
                continue
            leaf = order[lo - 1]
            if leaf_level[leaf] >= lv:
                out[c] = leaf
