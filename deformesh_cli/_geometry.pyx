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


def edge_pairs(
    const long long[:, :] tri,
    long long n,
    long long[:] row,
    long long[:] ent,
    long long[:] hi,
    long long[:] t1,
    long long[:] k1,
    long long[:] t2,
    long long[:] k2,
):
    """The loop of :func:`deformesh_cli.smoothing._edge_pairs`: every triangle side (the
    side ``k`` of ``t`` from corner ``k`` to ``k + 1``) sorted by its lower node, then its
    higher (stably: by ``t``, then ``k``, among equals, as a stable sort of ``lo n +
    hi`` orders them), and each two sides next in that order that are the same edge
    walked opposite ways, into ``t1``, ``k1``, ``t2``, ``k2``; returns how many.  ``row``
    (n + 1), ``ent``, ``hi`` (3 per triangle): scratch.  The nodes must lie in
    ``0 .. n - 1``."""
    cdef Py_ssize_t nt = tri.shape[0]
    cdef Py_ssize_t t, s, i, j, m = 0, r, end, start
    cdef long long a, b, lo, e, h
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
        for t in range(nt):  # (in entry order: stable)
            for s in range(3):
                a = tri[t, s]
                b = tri[t, (s + 1) % 3]
                lo = a if a < b else b
                ent[row[lo]] = 3 * t + s
                hi[row[lo]] = b if a < b else a
                row[lo] += 1
        start = 0
        for r in range(n):
            end = row[r]  # (row r's entries: start .. end - 1)
            for j in range(start + 1, end):  # stable insertion sort by hi
                h = hi[j]
                e = ent[j]
                i = j
                while i > start and hi[i - 1] > h:
                    hi[i] = hi[i - 1]
                    ent[i] = ent[i - 1]
                    i -= 1
                hi[i] = h
                ent[i] = e
            for j in range(start, end - 1):
                if hi[j] != hi[j + 1]:
                    continue
                # the same edge: walked opposite ways?
                a = tri[ent[j] // 3, ent[j] % 3]
                b = tri[ent[j + 1] // 3, ent[j + 1] % 3]
                if (a == r) != (b == r):
                    t1[m] = ent[j] // 3
                    k1[m] = ent[j] % 3
                    t2[m] = ent[j + 1] // 3
                    k2[m] = ent[j + 1] % 3
                    m += 1
            start = end
    return m
