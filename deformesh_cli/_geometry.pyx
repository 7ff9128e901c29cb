# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loops of :func:`deformesh_cli.geometry.edge_uses` and
:func:`deformesh_cli.smoothing._edge_pairs`: every triangle side grouped by its lower
node (a counting sort) and, within a node's row, stably sorted by its higher node
(rows are a node's few neighbours)."""

from ._sort cimport sort_run, sort_run_with


cdef void _sort_sides(
    const long long[:, :] tri, long long n, long long[:] row, long long[:] ent,
    long long[:] hi,
) noexcept nogil:
    """Every side (entry ``3 t + s``: triangle ``t`` from corner ``s`` to ``s + 1``) into
    ``ent``, with its higher node in ``hi``, by its lower node, then its higher, equals
    in entry order; ``row[r]``: where node ``r``'s row ends (it starts where ``r - 1``'s
    ends).  The nodes must lie in ``0 .. n - 1``."""
    cdef Py_ssize_t nt = tri.shape[0]
    cdef Py_ssize_t t, s, i, start, end
    cdef long long a, b, lo
    for i in range(n + 1):
        row[i] = 0
    for t in range(nt):
        for s in range(3):
            a = tri[t, s]
            b = tri[t, (s + 1) % 3]
            row[(a if a < b else b) + 1] += 1
    for i in range(n):
        row[i + 1] += row[i]
    for t in range(nt):  # (row[lo] is where lo's next entry goes; in entry order)
        for s in range(3):
            a = tri[t, s]
            b = tri[t, (s + 1) % 3]
            lo = a if a < b else b
            ent[row[lo]] = 3 * t + s
            hi[row[lo]] = b if a < b else a
            row[lo] += 1
    start = 0
    for i in range(n):
        end = row[i]
        sort_run_with(hi, ent, start, end)  # (stable: equal ends keep entry order)
        start = end


cdef inline bint _forward(const long long[:, :] tri, long long e) noexcept nogil:
    """Side ``e`` (``3 t + s``) walks from its lower node to its higher."""
    return tri[e // 3, e % 3] < tri[e // 3, (e % 3 + 1) % 3]


def edge_table(
    const long long[:, ::1] tri,
    long long n,
    long long[::1] row,
    long long[::1] buf,
    long long[::1] out_lo,
    long long[::1] out_fwd,
    long long[::1] out_rev,
):
    """The edges ``lo < hi`` in order (by ``lo``, then ``hi``) with the count of
    triangles walking each ``lo -> hi`` (``out_fwd``) and ``hi -> lo`` (``out_rev``),
    each ``hi`` left in ``buf``; returns how many, or -1 if a triangle names a node
    outside ``0 .. n - 1``.  Every side goes into its lower node's row (a counting
    sort) as ``2 hi + 1`` walked forwards, ``2 hi`` backwards; each row (a node's few
    neighbours) is sorted, and its runs of one ``hi`` counted.  ``row`` (n + 1),
    ``buf`` and the outputs (3 per triangle; only the first ones are written)."""
    cdef Py_ssize_t nt = tri.shape[0]
    cdef Py_ssize_t t, j, r, m = 0, start = 0, end
    cdef long long a, b, lo, h, f, c
    cdef bint bad = False
    with nogil:
        for t in range(nt):
            for j in range(3):
                if tri[t, j] < 0 or tri[t, j] >= n:
                    bad = True
    if bad:
        return -1
    with nogil:
        for r in range(n + 1):
            row[r] = 0
        for t in range(nt):
            for j in range(3):
                a = tri[t, j]
                b = tri[t, 0 if j == 2 else j + 1]
                row[(a if a < b else b) + 1] += 1
        for r in range(n):
            row[r + 1] += row[r]
        for t in range(nt):  # (row[lo] is where lo's next side goes)
            for j in range(3):
                a = tri[t, j]
                b = tri[t, 0 if j == 2 else j + 1]
                if a < b:
                    buf[row[a]] = 2 * b + 1
                    row[a] += 1
                else:
                    buf[row[b]] = 2 * a
                    row[b] += 1
        for r in range(n):  # (row[r] is now where row r ends)
            end = row[r]
            sort_run(buf, start, end)  # (a row is a few sides)
            j = start
            while j < end:
                h = buf[j] >> 1
                f = 0
                c = 0
                while j < end and (buf[j] >> 1) == h:
                    f += buf[j] & 1
                    c += 1
                    j += 1
                out_lo[m] = r  # (m is at most the run's start: read already)
                buf[m] = h
                out_fwd[m] = f
                out_rev[m] = c - f
                m += 1
            start = end
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
    cdef Py_ssize_t j, m = 0, r, end, start = 0
    with nogil:
        _sort_sides(tri, n, row, ent, hi)
        for r in range(n):
            end = row[r]
            for j in range(start, end - 1):
                if hi[j] != hi[j + 1]:
                    continue
                # the same edge: walked opposite ways?
                if _forward(tri, ent[j]) != _forward(tri, ent[j + 1]):
                    t1[m] = ent[j] // 3
                    k1[m] = ent[j] % 3
                    t2[m] = ent[j + 1] // 3
                    k2[m] = ent[j + 1] % 3
                    m += 1
            start = end
    return m


def touching(const unsigned char[::1] mask, const long long[:, ::1] tri, unsigned char[::1] out):
    """``out[t]``: 1 where a corner of triangle ``t`` is set in ``mask``, else 0; returns
    the first triangle naming a node outside ``mask``, or -1."""
    cdef Py_ssize_t t
    cdef unsigned long long n = mask.shape[0]
    cdef long long a, b, c
    cdef long long bad = -1
    with nogil:
        for t in range(tri.shape[0]):
            a = tri[t, 0]
            b = tri[t, 1]
            c = tri[t, 2]
            if <unsigned long long> a >= n or <unsigned long long> b >= n or <unsigned long long> c >= n:
                bad = t
                break
            out[t] = mask[a] | mask[b] | mask[c]
    return bad
