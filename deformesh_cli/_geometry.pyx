# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loop of :func:`deformesh_cli.geometry.edge_uses`: every triangle side counted
once per direction, grouped by its lower node (a counting sort) and, within a node's
row, sorted by its higher node (rows are a node's few neighbours)."""


def edge_table(
    const long long[:, :] tri,
    long long n,
    long long reverse,
    long long[:] row,
    long long[:] hi,
    long long[:] weight,
    long long[:] out_lo,
    long long[:] out_hi,
    long long[:] out_fwd,
    long long[:] out_rev,
):
    """The edges ``lo < hi`` in order (by ``lo``, then ``hi``) with the count of
    triangles walking each ``lo -> hi`` (``out_fwd``) and ``hi -> lo`` (``out_rev``);
    returns how many, or -1 if a triangle names a node outside ``0 .. n - 1``.
    ``row`` (n + 1), ``hi``, ``weight`` (3 per triangle): scratch."""
    cdef Py_ssize_t nt = tri.shape[0]
    cdef Py_ssize_t t, s, i, j, r, m, a, b, lo, h, w, end
    cdef bint bad = False
    with nogil:
        for t in range(nt):
            for s in range(3):
                if tri[t, s] < 0 or tri[t, s] >= n:
                    bad = True
    if bad:
        return -1
    with nogil:
        for i in range(n + 1):
            row[i] = 0
        for t in range(nt):
            for s in range(3):
                a = tri[t, s]
                b = tri[t, (s + 1) % 3]
                row[(a if a < b else b) + 1] += 1
        for i in range(n):
            row[i + 1] += row[i]
        for t in range(nt):  # (row[lo] is where lo's next entry goes)
            for s in range(3):
                a = tri[t, s]
                b = tri[t, (s + 1) % 3]
                lo = a if a < b else b
                hi[row[lo]] = b if a < b else a
                weight[row[lo]] = 1 if a < b else reverse
                row[lo] += 1
        m = 0
        end = 0
        for r in range(n):
            i = end  # (the row's entries: end .. row[r] - 1, once shifted back)
            end = row[r]
            for j in range(i + 1, end):  # insertion sort by hi
                h = hi[j]
                w = weight[j]
                s = j
                while s > i and hi[s - 1] > h:
                    hi[s] = hi[s - 1]
                    weight[s] = weight[s - 1]
                    s -= 1
                hi[s] = h
                weight[s] = w
            j = i
            while j < end:
                h = hi[j]
                w = 0
                while j < end and hi[j] == h:
                    w += weight[j]
                    j += 1
                out_lo[m] = r
                out_hi[m] = h
                out_fwd[m] = w % reverse
                out_rev[m] = w // reverse
                m += 1
    return m
