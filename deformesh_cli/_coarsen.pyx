# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loop of :func:`deformesh_cli.coarsen._weigh`: per node ``a``, every collapse of
``a`` into a neighbour ``b`` weighed by the module's rules, and the shortest allowed
one chosen.  The arithmetic is the numpy reference's, operation for operation (the
tests compare them), so the choices are the same.
"""

from libc.math cimport INFINITY, sqrt
from libc.stdlib cimport free, malloc


def weigh(
    const double[:, :] pts,
    const long long[:, :] tri,
    const long long[:, :] stars,
    const long long[:] deg,
    const double[:] need,
    const long long[:] nodes,
    const unsigned char[:] boundary,
    double floor_inside,
    double floor_boundary,
    double half_longest,
    long long[:, :] u,
    long long[:, :] v,
    long long[:] nxt,
    double[:, :] d2,
    double[:, :] cr,
    double[:] xs,
    double[:] ys,
    long long[:] b_out,
    double[:] key_out,
):
    """``b_out[i]``: the neighbour node ``nodes[i]`` collapses into (-1: none allowed),
    ``key_out[i]`` its edge's length over the size field; ``u[i, j]``, the next corner
    counter-clockwise in ``a``'s ``j``-th triangle (its neighbours, -1 past its degree).
    ``v``, ``nxt``, ``d2``, ``cr``, ``xs``, ``ys``: scratch, at least the widest star."""
    cdef Py_ssize_t nn = nodes.shape[0]
    cdef Py_ssize_t i, j, k, p, q, m, at, w, tb
    cdef long long a, b, t, c
    cdef double ax, ay, side_j, side_k, cross, total, shortest, fl, half, key, best
    cdef bint closed, ok, dead, new, shared
    with nogil:
        for i in range(nn):
            a = nodes[i]
            w = deg[a]
            for j in range(u.shape[1]):
                u[i, j] = -1
            b_out[i] = -1
            key_out[i] = INFINITY
            for j in range(w):
                t = stars[a, j]
                at = 0
                while at < 3 and tri[t, at] != a:
                    at += 1
                if at == 3:
                    at = 0  # (a star that does not hold a: not closed below)
                u[i, j] = tri[t, (at + 1) % 3]
                v[i, j] = tri[t, (at + 2) % 3]
            closed = True
            for j in range(w):
                nxt[j] = -1
                for p in range(w):
                    if u[i, p] == v[i, j]:
                        nxt[j] = p
                        break
                if nxt[j] < 0:
                    closed = False
            if not closed:
                continue
            ax = pts[a, 0]
            ay = pts[a, 1]
            for j in range(w):
                xs[j] = pts[u[i, j], 0] - ax
                ys[j] = pts[u[i, j], 1] - ay
            for k in range(w):
                for j in range(w):
                    d2[k, j] = (xs[k] - xs[j]) * (xs[k] - xs[j]) + (ys[k] - ys[j]) * (ys[k] - ys[j])
                    cr[k, j] = xs[k] * ys[j] - ys[k] * xs[j]
            best = INFINITY
            for k in range(w):
                ok = True
                for j in range(w):
                    dead = u[i, j] == u[i, k] or v[i, j] == u[i, k]
                    if dead:
                        continue
                    p = nxt[j]
                    side_j = d2[j, p]
                    side_k = d2[k, p]
                    cross = cr[j, p] - cr[k, p] + cr[k, j]
                    total = side_j + side_k + d2[k, j]
                    shortest = side_j if side_j < side_k else side_k
                    shortest = shortest if shortest < d2[k, j] else d2[k, j]
                    if boundary[u[i, k]] or boundary[u[i, j]] or boundary[v[i, j]]:
                        fl = floor_boundary
                    else:
                        fl = floor_inside
                    if not (cross > 0.0 and 2.0 * cross >= fl * (total - 2.0 * shortest)):
                        ok = False
                        break
                    new = u[i, j] != v[i, k]
                    if new:
                        half = half_longest * (need[u[i, k]] + need[u[i, j]])
                        if not d2[k, j] <= half * half:
                            ok = False
                            break
                if not ok:
                    continue
                key = sqrt(xs[k] * xs[k] + ys[k] * ys[k]) / (0.5 * (need[a] + need[u[i, k]]))
                if key < best:
                    best = key
                    b_out[i] = k  # (for now: the position; the node below)
            if b_out[i] < 0:
                continue
            k = b_out[i]
            b = u[i, k]
            # the link condition: no new neighbour of b is one already
            shared = False
            for j in range(w):
                if u[i, j] == u[i, k] or v[i, j] == u[i, k] or u[i, j] == v[i, k]:
                    continue  # (not a new edge b - u_j)
                for q in range(deg[b]):
                    tb = stars[b, q]
                    for m in range(3):
                        c = tri[tb, m]
                        if c != b and c == u[i, j]:
                            shared = True
                if shared:
                    break
            if shared:
                b_out[i] = -1
                continue
            b_out[i] = b
            key_out[i] = best


def collapse_width(
    const long long[:, :] tri,
    const long long[:, :] stars,
    const long long[:] deg,
    const long long[:] wa,
    const long long[:] wb,
):
    """The widest star :func:`collapse` makes: ``b``'s triangles and ``a``'s, less the
    ones on the edge ``a b`` (counted in both)."""
    cdef Py_ssize_t i, j, k
    cdef long long a, b, t, on, width = 0
    with nogil:
        for i in range(wa.shape[0]):
            a = wa[i]
            b = wb[i]
            on = 0
            for j in range(deg[a]):
                t = stars[a, j]
                for k in range(3):
                    if tri[t, k] == b:
                        on += 1
            if deg[a] + deg[b] - 2 * on > width:
                width = deg[a] + deg[b] - 2 * on
    return width


cdef inline bint _among(long long v, const long long *items, Py_ssize_t n) noexcept nogil:
    cdef Py_ssize_t d
    for d in range(n):
        if items[d] == v:
            return True
    return False


def collapse(
    long long[:, :] tri,
    long long[:, :] stars,
    long long[:] deg,
    unsigned char[:] alive,
    const long long[:] wa,
    const long long[:] wb,
):
    """Each ``wa[i]`` collapsed into ``wb[i]`` (no two share a triangle, a ``b``, or a
    ``b`` next to the other's ``a``), one after the other, which for such a set is
    the same as all at once: ``a``'s triangles take ``b`` for ``a``, the ones that
    held ``b`` die, ``b``'s star becomes its own then ``a``'s live triangles (in
    order) and the third corners of the dead lose them; ``stars`` must be wide
    enough (:func:`collapse_width`)."""
    cdef Py_ssize_t i, j, k, m, nd, w = stars.shape[1]
    cdef long long a, b, t, x, c
    cdef bint holds
    cdef long long *dead = <long long *> malloc((w + 1) * sizeof(long long))
    if dead == NULL:
        raise MemoryError("coarsening")
    with nogil:
        for i in range(wa.shape[0]):
            a = wa[i]
            b = wb[i]
            nd = 0
            for j in range(deg[a]):
                t = stars[a, j]
                holds = tri[t, 0] == b or tri[t, 1] == b or tri[t, 2] == b
                for k in range(3):
                    if tri[t, k] == a:
                        tri[t, k] = b
                if holds:
                    alive[t] = 0
                    dead[nd] = t
                    nd += 1
            # b's star: its own, then a's, without the dead (kept in order)
            m = 0
            for j in range(deg[b]):
                t = stars[b, j]
                if not _among(t, dead, nd):
                    stars[b, m] = t
                    m += 1
            for j in range(deg[a]):
                t = stars[a, j]
                if not _among(t, dead, nd):
                    stars[b, m] = t
                    m += 1
            for j in range(m, w):
                stars[b, j] = -1
            deg[b] = m
            # the third corners of the dead lose them
            for j in range(nd):
                for k in range(3):
                    x = tri[dead[j], k]
                    if x == b:
                        continue
                    m = 0
                    for c in range(deg[x]):
                        t = stars[x, c]
                        if not _among(t, dead, nd):
                            stars[x, m] = t
                            m += 1
                    for c in range(m, deg[x]):
                        stars[x, c] = -1
                    deg[x] = m
            deg[a] = 0
    free(dead)
