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


def emit(
    const long long[:] level,
    const long long[:] i,
    const long long[:] j,
    const unsigned char[:, :] finer,
    const unsigned char[:] diagonals,
    long long stride,
    long long[:, :] keys,
    long long[:] cell,
):
    """The loop of :meth:`deformesh_cli.select.graded.Quadtree.triangulate`: each leaf's
    triangles in order, as the lattice keys (``x * stride + y``, half finest cells)
    of their corners: a leaf with no finer neighbour two along its diagonal (0:
    ``/``, 1: ``\\``), else a fan from its centre, one triangle per side or two where
    that side has a finer neighbour (its midpoint a node); ``cell[t]``, the leaf."""
    cdef Py_ssize_t n = level.shape[0], leaf, t = 0, s
    cdef long long side, half, x, y, c, m
    cdef long long k[4]
    cdef bint plain
    with nogil:
        for leaf in range(n):
            side = 2 * ((<long long> 1) << level[leaf])
            half = side // 2
            x = i[leaf] * side
            y = j[leaf] * side
            k[0] = x * stride + y
            k[1] = (x + side) * stride + y
            k[2] = (x + side) * stride + (y + side)
            k[3] = x * stride + (y + side)
            plain = not (finer[leaf, 0] or finer[leaf, 1] or finer[leaf, 2] or finer[leaf, 3])
            if plain:
                if diagonals[leaf] == 0:
                    keys[t, 0] = k[0]
                    keys[t, 1] = k[1]
                    keys[t, 2] = k[2]
                    keys[t + 1, 0] = k[0]
                    keys[t + 1, 1] = k[2]
                    keys[t + 1, 2] = k[3]
                else:
                    keys[t, 0] = k[0]
                    keys[t, 1] = k[1]
                    keys[t, 2] = k[3]
                    keys[t + 1, 0] = k[1]
                    keys[t + 1, 1] = k[2]
                    keys[t + 1, 2] = k[3]
                cell[t] = leaf
                cell[t + 1] = leaf
                t += 2
                continue
            c = (x + half) * stride + (y + half)
            for s in range(4):
                if not finer[leaf, s]:
                    keys[t, 0] = k[s]
                    keys[t, 1] = k[(s + 1) % 4]
                    keys[t, 2] = c
                    cell[t] = leaf
                    t += 1
                    continue
                if s == 0:
                    m = (x + half) * stride + y
                elif s == 1:
                    m = (x + side) * stride + (y + half)
                elif s == 2:
                    m = (x + half) * stride + (y + side)
                else:
                    m = x * stride + (y + half)
                keys[t, 0] = k[s]
                keys[t, 1] = m
                keys[t, 2] = c
                keys[t + 1, 0] = m
                keys[t + 1, 1] = k[(s + 1) % 4]
                keys[t + 1, 2] = c
                cell[t] = leaf
                cell[t + 1] = leaf
                t += 2
    return t
