# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loop of :func:`deformesh_cli.recover.recover` (one cavity per run of extra
boundary nodes) and the polygon triangulation it meshes each cavity with
(:func:`polygon_cdt`).  The steps are the module's, in its order; the tests run
them against a plain Python reference.

The mesh is held as a growing array of triangles and, per node, a doubly linked
list of the triangle corners at it (its star): a re-meshing kills the cavity's
triangles, unlinks their corners and appends the new ones, so every step costs
the size of its cavity.
"""

from libc.math cimport atan2, fabs
from libc.stdlib cimport free, malloc, qsort

from ._buffers cimport Buf, push, reserve, resize

import numpy as np

ctypedef long long i64


cdef int compare_i64(const void *a, const void *b) noexcept nogil:
    cdef i64 x = (<const i64 *> a)[0]
    cdef i64 y = (<const i64 *> b)[0]
    return (x > y) - (x < y)


# ---------------------------------------------------------------------------
# the constrained Delaunay triangulation of a simple polygon, its vertices only

cdef inline double area(const double *x, const double *y, i64 a, i64 b, i64 c) noexcept nogil:
    """:func:`deformesh_cli.geometry.signed_areas` of one triangle, its operations in order."""
    return 0.5 * ((x[b] - x[a]) * (y[c] - y[a]) - (x[c] - x[a]) * (y[b] - y[a]))


cdef inline bint in_closed(const double *x, const double *y, i64 a, i64 b, i64 c, i64 p) noexcept nogil:
    """``p`` in the closed counter-clockwise triangle ``a b c`` (on a side counts)."""
    return (
        (x[b] - x[a]) * (y[p] - y[a]) - (x[p] - x[a]) * (y[b] - y[a]) >= 0
        and (x[c] - x[b]) * (y[p] - y[b]) - (x[p] - x[b]) * (y[c] - y[b]) >= 0
        and (x[a] - x[c]) * (y[p] - y[c]) - (x[p] - x[c]) * (y[a] - y[c]) >= 0
    )


cdef inline double corner(const double *x, const double *y, i64 a, i64 b, i64 c) noexcept nogil:
    """The angle at ``b`` between ``b a`` and ``b c`` (the same for either order)."""
    cdef double ux = x[a] - x[b], uy = y[a] - y[b], vx = x[c] - x[b], vy = y[c] - y[b]
    return atan2(fabs(ux * vy - uy * vx), ux * vx + uy * vy)


cdef void angles(const double *x, const double *y, i64 a, i64 b, i64 c, i64 d, double *out) noexcept nogil:
    """The six angles of the triangles ``a b c`` and ``a c d``, ascending (each angle
    from its corner's two neighbours, so a triangle's angles do not depend on the
    quadrilateral it is read in)."""
    cdef int i, j
    cdef double v
    out[0] = corner(x, y, c, a, b)
    out[1] = corner(x, y, a, b, c)
    out[2] = corner(x, y, b, c, a)
    out[3] = corner(x, y, d, a, c)
    out[4] = corner(x, y, a, c, d)
    out[5] = corner(x, y, c, d, a)
    for i in range(1, 6):
        v = out[i]
        j = i - 1
        while j >= 0 and out[j] > v:
            out[j + 1] = out[j]
            j -= 1
        out[j + 1] = v


cdef int cdt(const double *x, const double *y, i64 k, i64 *out) noexcept nogil:
    """The constrained Delaunay triangulation of the simple counter-clockwise polygon
    ``x, y`` (k vertices) into ``out`` ((k - 2) rows of three local indices, each from
    its least vertex, rows ascending; every triangle of positive area).  Returns 0, 1
    if the polygon has no such triangulation in floating point (vertices collinear to
    round-off), -1 out of memory.

    Ear clipping (a convex corner whose closed triangle holds no other vertex: one
    exists in every simple polygon) gives a triangulation; then every inner diagonal
    whose quadrilateral is convex is flipped while the flip raises the pair's six
    angles, ascending, lexicographically.  Each flip raises the whole mesh's angles
    the same way, so the flips end, and where none applies every diagonal is locally
    Delaunay: the constrained Delaunay triangulation, whose smallest angle is the
    largest of any triangulation of the polygon's vertices (Lee and Lin 1986)."""
    cdef i64 nt = k - 2, r, i, a, c, j, miss, t, u, m, p, q, s, rr, e, f, o
    cdef i64 *prv
    cdef i64 *nxt
    cdef i64 *nb
    cdef i64 *tr
    cdef bint ear, changed
    cdef double old[6]
    cdef double new[6]
    cdef int res = 0
    cdef i64 row[3]
    if k < 3:
        return 1
    prv = <i64 *> malloc(k * sizeof(i64))
    nxt = <i64 *> malloc(k * sizeof(i64))
    nb = <i64 *> malloc(3 * nt * sizeof(i64))
    tr = out
    if prv == NULL or nxt == NULL or nb == NULL:
        free(prv)
        free(nxt)
        free(nb)
        return -1
    for i in range(k):
        prv[i] = (i + k - 1) % k
        nxt[i] = (i + 1) % k
    r = k
    i = 0
    t = 0
    miss = 0
    while r > 3:
        a = prv[i]
        c = nxt[i]
        ear = area(x, y, a, i, c) > 0
        if ear:
            j = nxt[c]
            while j != a:
                if in_closed(x, y, a, i, c, j):
                    ear = False
                    break
                j = nxt[j]
        if ear:
            tr[3 * t] = a
            tr[3 * t + 1] = i
            tr[3 * t + 2] = c
            t += 1
            nxt[a] = c
            prv[c] = a
            r -= 1
            miss = 0
            i = c
        else:
            i = nxt[i]
            miss += 1
            if miss > r:
                res = 1
                break
    if res == 0:
        a = prv[i]
        c = nxt[i]
        if area(x, y, a, i, c) > 0:
            tr[3 * t] = a
            tr[3 * t + 1] = i
            tr[3 * t + 2] = c
        else:
            res = 1
    if res == 0:
        # neighbours: nb[3 t + j] the triangle across the side opposite corner j
        for t in range(nt):
            for j in range(3):
                nb[3 * t + j] = -1
        for t in range(nt):
            for j in range(3):
                if nb[3 * t + j] >= 0:
                    continue
                p = tr[3 * t + (j + 1) % 3]
                q = tr[3 * t + (j + 2) % 3]
                for u in range(t + 1, nt):
                    for m in range(3):
                        if tr[3 * u + (m + 1) % 3] == q and tr[3 * u + (m + 2) % 3] == p:
                            nb[3 * t + j] = u
                            nb[3 * u + m] = t
                            break
                    if nb[3 * t + j] >= 0:
                        break
        changed = True
        while changed:
            changed = False
            for t in range(nt):
                j = 0
                while j < 3:
                    u = nb[3 * t + j]
                    if u < t:
                        j += 1
                        continue
                    p = tr[3 * t + j]
                    q = tr[3 * t + (j + 1) % 3]
                    rr = tr[3 * t + (j + 2) % 3]
                    m = 0
                    while tr[3 * u + m] == q or tr[3 * u + m] == rr:
                        m += 1
                    s = tr[3 * u + m]
                    # the quadrilateral p q s rr; its diagonal q rr, flipped to p s
                    if not (area(x, y, p, q, s) > 0 and area(x, y, p, s, rr) > 0):
                        j += 1
                        continue
                    angles(x, y, q, s, rr, p, old)  # (u: q s rr; t: q rr p)
                    angles(x, y, p, q, s, rr, new)
                    o = 0
                    while o < 6 and new[o] == old[o]:
                        o += 1
                    if o == 6 or new[o] < old[o]:
                        j += 1
                        continue
                    # neighbours outside the quadrilateral: across p q, rr p (of t),
                    # q s, s rr (of u)
                    e = nb[3 * t + (j + 2) % 3]  # across p q
                    f = nb[3 * t + (j + 1) % 3]  # across rr p
                    c = nb[3 * u + (m + 1) % 3]  # across q s (opposite rr: u is s rr q)
                    a = nb[3 * u + (m + 2) % 3]  # across s rr (opposite q)
                    # t becomes p q s, u becomes p s rr
                    tr[3 * t] = p
                    tr[3 * t + 1] = q
                    tr[3 * t + 2] = s
                    nb[3 * t] = c
                    nb[3 * t + 1] = u
                    nb[3 * t + 2] = e
                    tr[3 * u] = p
                    tr[3 * u + 1] = s
                    tr[3 * u + 2] = rr
                    nb[3 * u] = a
                    nb[3 * u + 1] = f
                    nb[3 * u + 2] = t
                    if c >= 0:
                        for o in range(3):
                            if nb[3 * c + o] == u:
                                nb[3 * c + o] = t
                    if f >= 0:
                        for o in range(3):
                            if nb[3 * f + o] == t:
                                nb[3 * f + o] = u
                    changed = True
                    j = 0
        # each row from its least vertex, rows ascending
        for t in range(nt):
            f = 0
            for j in range(1, 3):
                if tr[3 * t + j] < tr[3 * t + f]:
                    f = j
            row[0] = tr[3 * t + f]
            row[1] = tr[3 * t + (f + 1) % 3]
            row[2] = tr[3 * t + (f + 2) % 3]
            tr[3 * t] = row[0]
            tr[3 * t + 1] = row[1]
            tr[3 * t + 2] = row[2]
        for t in range(1, nt):
            row[0] = tr[3 * t]
            row[1] = tr[3 * t + 1]
            row[2] = tr[3 * t + 2]
            u = t - 1
            while u >= 0 and (
                tr[3 * u] > row[0]
                or (tr[3 * u] == row[0] and (tr[3 * u + 1] > row[1] or (tr[3 * u + 1] == row[1] and tr[3 * u + 2] > row[2])))
            ):
                tr[3 * u + 3] = tr[3 * u]
                tr[3 * u + 4] = tr[3 * u + 1]
                tr[3 * u + 5] = tr[3 * u + 2]
                u -= 1
            tr[3 * u + 3] = row[0]
            tr[3 * u + 4] = row[1]
            tr[3 * u + 5] = row[2]
    free(prv)
    free(nxt)
    free(nb)
    return res


def polygon_cdt(const double[:, ::1] p):
    """:func:`cdt` of the polygon ``p`` (k, 2): (k - 2, 3) local indices, or None."""
    cdef i64 k = p.shape[0], i
    cdef int res
    if k < 3:
        return None
    x = np.ascontiguousarray(p[:, 0])
    y = np.ascontiguousarray(p[:, 1])
    cdef double[::1] xv = x
    cdef double[::1] yv = y
    out = np.empty((k - 2, 3), dtype=np.int64)
    cdef i64[:, ::1] ov = out
    with nogil:
        res = cdt(&xv[0], &yv[0], k, &ov[0, 0])
    if res < 0:
        raise MemoryError("polygon triangulation")
    return out if res == 0 else None


# ---------------------------------------------------------------------------
# recovery: the mesh as triangles and per-node lists of corners

cdef struct Work:
    const double *x
    const double *y
    const unsigned char *boundary
    unsigned char *gone
    i64 n
    i64 *tri       # 3 per triangle
    unsigned char *alive
    i64 *tmark     # per triangle: the stamp of the cavity holding it
    i64 *cnext     # per corner: the next / previous corner at the same node
    i64 *cprev
    i64 nt
    i64 cap
    i64 *head      # per node: its first corner (-1: none)
    i64 *vmark     # per node stamps
    i64 *vmark2
    i64 *after
    i64 *amark
    i64 stamp
    Buf cav
    Buf todo
    Buf keys
    Buf ring
    Buf inner
    Buf poly
    Buf out
    double *px
    double *py
    i64 pcap


cdef int grow(Work *w, i64 need) noexcept nogil:
    """Room for ``need`` triangles."""
    cdef i64 cap
    if need <= w.cap:
        return 0
    cap = max(need, 2 * w.cap)
    if (
        resize(<void **> &w.tri, 3 * cap * sizeof(i64)) < 0
        or resize(<void **> &w.cnext, 3 * cap * sizeof(i64)) < 0
        or resize(<void **> &w.cprev, 3 * cap * sizeof(i64)) < 0
        or resize(<void **> &w.tmark, cap * sizeof(i64)) < 0
        or resize(<void **> &w.alive, cap * sizeof(unsigned char)) < 0
    ):
        return -1
    w.cap = cap
    return 0


cdef void link(Work *w, i64 t) noexcept nogil:
    cdef i64 k, c, v
    for k in range(3):
        c = 3 * t + k
        v = w.tri[c]
        w.cprev[c] = -1
        w.cnext[c] = w.head[v]
        if w.head[v] >= 0:
            w.cprev[w.head[v]] = c
        w.head[v] = c


cdef void kill(Work *w, i64 t) noexcept nogil:
    cdef i64 k, c
    w.alive[t] = 0
    for k in range(3):
        c = 3 * t + k
        if w.cprev[c] >= 0:
            w.cnext[w.cprev[c]] = w.cnext[c]
        else:
            w.head[w.tri[c]] = w.cnext[c]
        if w.cnext[c] >= 0:
            w.cprev[w.cnext[c]] = w.cprev[c]


cdef inline bint in_disk(Work *w, i64 v, i64 a, i64 b) noexcept nogil:
    """``v`` an inner node strictly inside the diametral disk of ``a b``."""
    return not w.boundary[v] and (
        (w.x[v] - w.x[a]) * (w.x[v] - w.x[b]) + (w.y[v] - w.y[a]) * (w.y[v] - w.y[b]) < 0.0
    )


cdef i64 find(const i64 *keys, i64 n, i64 key) noexcept nogil:
    cdef i64 lo = 0, hi = n, mid
    while lo < hi:
        mid = (lo + hi) // 2
        if keys[mid] < key:
            lo = mid + 1
        else:
            hi = mid
    return lo < n and keys[lo] == key


cdef int outline(Work *w) noexcept nogil:
    """The outline of the triangles ``w.cav`` counter-clockwise into ``w.ring``, from
    the first side used once, and their nodes it leaves inside into ``w.inner``.
    Returns 0, 1 unless it is one simple loop, -1 out of memory."""
    cdef i64 e, ne = 3 * w.cav.n, u, v, t, k, start = -1, count = 0, last, st, nv
    if reserve(&w.keys, ne) < 0:
        return -1
    for e in range(ne):
        t = w.cav.d[e // 3]
        k = e % 3
        w.keys.d[e] = w.tri[3 * t + k] * w.n + w.tri[3 * t + (k + 1) % 3]
    w.keys.n = ne
    qsort(w.keys.d, ne, sizeof(i64), compare_i64)
    w.stamp += 1
    st = w.stamp
    for e in range(ne):
        t = w.cav.d[e // 3]
        k = e % 3
        u = w.tri[3 * t + k]
        v = w.tri[3 * t + (k + 1) % 3]
        if find(w.keys.d, ne, v * w.n + u):
            continue
        if w.amark[u] == st:
            return 1
        w.amark[u] = st
        w.after[u] = v
        count += 1
        if start < 0:
            start = u
    if count == 0:  # (every side paired: triangles folded onto each other)
        return 1
    w.ring.n = 0
    if push(&w.ring, start) < 0:
        return -1
    while True:
        last = w.ring.d[w.ring.n - 1]
        nv = w.after[last] if w.amark[last] == st else start
        if nv == start:
            break
        if push(&w.ring, nv) < 0:
            return -1
        if w.ring.n > count:
            return 1
    if w.ring.n != count:
        return 1
    w.stamp += 1
    st = w.stamp
    for e in range(w.ring.n):
        w.vmark2[w.ring.d[e]] = st
    w.inner.n = 0
    for e in range(ne):
        u = w.tri[3 * w.cav.d[e // 3] + e % 3]
        if w.vmark2[u] != st:
            w.vmark2[u] = st
            if push(&w.inner, u) < 0:
                return -1
    return 0


cdef int remesh(Work *w) noexcept nogil:
    """The triangles ``w.cav`` replaced by the triangulation of the polygon ``w.poly``.
    Returns 0, 1 if the polygon has none (nothing changed), -1 out of memory."""
    cdef i64 k = w.poly.n, i, t, res
    if k < 3:
        return 1
    if k > w.pcap:
        if (
            resize(<void **> &w.px, k * sizeof(double)) < 0
            or resize(<void **> &w.py, k * sizeof(double)) < 0
        ):
            return -1
        w.pcap = k
    for i in range(k):
        w.px[i] = w.x[w.poly.d[i]]
        w.py[i] = w.y[w.poly.d[i]]
    if reserve(&w.out, 3 * (k - 2)) < 0:
        return -1
    res = cdt(w.px, w.py, k, w.out.d)
    if res != 0:
        return res
    if grow(w, w.nt + k - 2) < 0:
        return -1
    for i in range(w.cav.n):
        kill(w, w.cav.d[i])
    for i in range(k - 2):
        t = w.nt
        w.tri[3 * t] = w.poly.d[w.out.d[3 * i]]
        w.tri[3 * t + 1] = w.poly.d[w.out.d[3 * i + 1]]
        w.tri[3 * t + 2] = w.poly.d[w.out.d[3 * i + 2]]
        w.alive[t] = 1
        w.tmark[t] = 0
        link(w, t)
        w.nt += 1
    return 0


cdef int take(Work *w, const i64 *run, i64 length, i64 a, i64 b) noexcept nogil:
    """The run's cavity (grown by the stars of the inner nodes it reaches in the disk of
    ``a b``, if ``a >= 0``) meshed again without the run.  Without ``a b``, a cavity
    that cannot be is taken in halves.  Returns 1 if taken, 0 if not, -1 out of memory."""
    cdef i64 i, k, c, t, v, u, st, sv, size, res, half
    w.stamp += 1
    st = w.stamp
    w.cav.n = 0
    for i in range(length):
        c = w.head[run[i]]
        while c >= 0:
            t = c // 3
            if w.tmark[t] != st:
                w.tmark[t] = st
                if push(&w.cav, t) < 0:
                    return -1
            c = w.cnext[c]
    if a >= 0:
        w.stamp += 1
        sv = w.stamp
        w.todo.n = 0
        size = w.cav.n
        for i in range(size):
            for k in range(3):
                v = w.tri[3 * w.cav.d[i] + k]
                if w.vmark[v] != sv:
                    w.vmark[v] = sv
                    if push(&w.todo, v) < 0:
                        return -1
        while w.todo.n > 0:
            w.todo.n -= 1
            v = w.todo.d[w.todo.n]
            if not in_disk(w, v, a, b):
                continue
            c = w.head[v]
            while c >= 0:
                t = c // 3
                if w.tmark[t] != st:
                    w.tmark[t] = st
                    if push(&w.cav, t) < 0:
                        return -1
                    for k in range(3):
                        u = w.tri[3 * t + k]
                        if w.vmark[u] != sv:
                            w.vmark[u] = sv
                            if push(&w.todo, u) < 0:
                                return -1
                c = w.cnext[c]
    qsort(w.cav.d, w.cav.n, sizeof(i64), compare_i64)
    res = outline(w)
    if res < 0:
        return -1
    if res == 0:
        w.stamp += 1
        for i in range(length):
            w.vmark[run[i]] = w.stamp
        w.poly.n = 0
        for i in range(w.ring.n):
            if w.vmark[w.ring.d[i]] != w.stamp:
                if push(&w.poly, w.ring.d[i]) < 0:
                    return -1
        res = remesh(w)
        if res < 0:
            return -1
        if res == 0:
            for i in range(length):
                w.gone[run[i]] = 1
            for i in range(w.inner.n):
                w.gone[w.inner.d[i]] = 1
            return 1
    if a < 0 and length > 1:
        half = length // 2
        if take(w, run, half, -1, -1) < 0 or take(w, run + half, length - half, -1, -1) < 0:
            return -1
    return 0


cdef int clear(Work *w, i64 a, i64 b) noexcept nogil:
    """While the apex of the one triangle on ``a b`` is an inner node in its disk, that
    node taken out by meshing its star again.  Returns 0, -1 out of memory."""
    cdef i64 c, t, on, count, x, k, res
    while True:
        w.stamp += 1
        c = w.head[a]
        while c >= 0:
            w.tmark[c // 3] = w.stamp
            c = w.cnext[c]
        count = 0
        on = -1
        c = w.head[b]
        while c >= 0:
            if w.tmark[c // 3] == w.stamp:
                count += 1
                on = c // 3
            c = w.cnext[c]
        if count != 1:
            return 0
        x = -1
        for k in range(3):
            if w.tri[3 * on + k] != a and w.tri[3 * on + k] != b:
                x = w.tri[3 * on + k]
        if x < 0 or not in_disk(w, x, a, b):
            return 0
        w.cav.n = 0
        c = w.head[x]
        while c >= 0:
            if push(&w.cav, c // 3) < 0:
                return -1
            c = w.cnext[c]
        qsort(w.cav.d, w.cav.n, sizeof(i64), compare_i64)
        res = outline(w)
        if res != 0:
            return -1 if res < 0 else 0
        w.poly.n = 0
        for k in range(w.ring.n):
            if push(&w.poly, w.ring.d[k]) < 0:
                return -1
        res = remesh(w)
        if res != 0:
            return -1 if res < 0 else 0
        w.gone[x] = 1


cdef i64 fill(Work *w, i64[:, ::1] kept) noexcept:
    cdef i64 i, k = 0
    for i in range(w.nt):
        if w.alive[i]:
            kept[k, 0] = w.tri[3 * i]
            kept[k, 1] = w.tri[3 * i + 1]
            kept[k, 2] = w.tri[3 * i + 2]
            k += 1
    return k


def recover_runs(
    const double[:, :] pts,
    const i64[:, :] tri,
    const i64[::1] run_ptr,
    const i64[::1] run_nodes,
    const i64[::1] run_a,
    const i64[::1] run_b,
    const unsigned char[::1] boundary,
):
    """Every run ``run_nodes[run_ptr[r]:run_ptr[r + 1]]`` of extra boundary nodes between
    the contour points ``run_a[r]`` and ``run_b[r]`` taken out as
    :mod:`deformesh_cli.recover` says: ``(the live triangles in the order made, the
    nodes gone as a mask)``."""
    cdef i64 n = pts.shape[0], nt = tri.shape[0], i, k, r, length, res = 0
    cdef bint every
    cdef const i64 *run
    x = np.ascontiguousarray(pts[:, 0])
    y = np.ascontiguousarray(pts[:, 1])
    gone = np.zeros(n, dtype=np.uint8)
    cdef double[::1] xv = x
    cdef double[::1] yv = y
    cdef unsigned char[::1] gv = gone
    cdef Work w
    w.x = &xv[0] if n else NULL
    w.y = &yv[0] if n else NULL
    w.boundary = &boundary[0] if n else NULL
    w.gone = &gv[0] if n else NULL
    w.n = n
    w.tri = NULL
    w.alive = NULL
    w.tmark = NULL
    w.cnext = NULL
    w.cprev = NULL
    w.nt = 0
    w.cap = 0
    w.stamp = 0
    w.cav = Buf(NULL, 0, 0)
    w.todo = Buf(NULL, 0, 0)
    w.keys = Buf(NULL, 0, 0)
    w.ring = Buf(NULL, 0, 0)
    w.inner = Buf(NULL, 0, 0)
    w.poly = Buf(NULL, 0, 0)
    w.out = Buf(NULL, 0, 0)
    w.px = NULL
    w.py = NULL
    w.pcap = 0
    w.head = <i64 *> malloc((n + 1) * sizeof(i64))
    w.vmark = <i64 *> malloc((n + 1) * sizeof(i64))
    w.vmark2 = <i64 *> malloc((n + 1) * sizeof(i64))
    w.after = <i64 *> malloc((n + 1) * sizeof(i64))
    w.amark = <i64 *> malloc((n + 1) * sizeof(i64))
    try:
        if w.head == NULL or w.vmark == NULL or w.vmark2 == NULL or w.after == NULL or w.amark == NULL:
            raise MemoryError("boundary recovery")
        with nogil:
            for i in range(n):
                w.head[i] = -1
                w.vmark[i] = 0
                w.vmark2[i] = 0
                w.amark[i] = 0
            res = grow(&w, nt + nt // 4 + 16)
            if res == 0:
                for i in range(nt):
                    for k in range(3):
                        w.tri[3 * i + k] = tri[i, k]
                    w.alive[i] = 1
                    w.tmark[i] = 0
                    link(&w, i)
                w.nt = nt
                for r in range(run_a.shape[0]):
                    run = &run_nodes[run_ptr[r]]
                    length = run_ptr[r + 1] - run_ptr[r]
                    res = take(&w, run, length, run_a[r], run_b[r])
                    if res < 0:
                        break
                    if res == 0:
                        res = take(&w, run, length, -1, -1)
                        if res < 0:
                            break
                        every = True
                        for i in range(length):
                            if not w.gone[run[i]]:
                                every = False
                        if every:
                            res = clear(&w, run_a[r], run_b[r])
                            if res < 0:
                                break
                    res = 0
        if res < 0:
            raise MemoryError("boundary recovery")
        kept = np.empty((w.nt, 3), dtype=np.int64)
        kv = kept
        k = fill(&w, kv)
        return kept[:k].copy(), gone.view(bool)
    finally:
        free(w.head)
        free(w.vmark)
        free(w.vmark2)
        free(w.after)
        free(w.amark)
        free(w.tri)
        free(w.alive)
        free(w.tmark)
        free(w.cnext)
        free(w.cprev)
        free(w.cav.d)
        free(w.todo.d)
        free(w.keys.d)
        free(w.ring.d)
        free(w.inner.d)
        free(w.poly.d)
        free(w.out.d)
        free(w.px)
        free(w.py)



def runs(const i64[::1] nxt, const unsigned char[::1] extra, const i64[::1] starts):
    """From each node ``starts[r]``, the nodes after it (``nxt``) while they are
    ``extra``: ``(ptr, nodes, ends)``, run ``r`` being ``nodes[ptr[r]:ptr[r + 1]]`` and
    ``ends[r]`` the first node after it that is not extra."""
    cdef i64 r, v, total = 0, nr = starts.shape[0]
    ptr = np.zeros(nr + 1, dtype=np.int64)
    ends = np.empty(nr, dtype=np.int64)
    cdef i64[::1] pv = ptr
    cdef i64[::1] ev = ends
    with nogil:
        for r in range(nr):
            v = nxt[starts[r]]
            while extra[v]:
                total += 1
                v = nxt[v]
            pv[r + 1] = total
            ev[r] = v
    nodes = np.empty(total, dtype=np.int64)
    cdef i64[::1] nv = nodes
    with nogil:
        total = 0
        for r in range(nr):
            v = nxt[starts[r]]
            while extra[v]:
                nv[total] = v
                total += 1
                v = nxt[v]
    return ptr, nodes, ends
