# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loops of :mod:`deformesh_cli.ldl`: a nested-dissection ordering of a sparse
symmetric matrix's graph, and the elimination tree, numeric factorisation and solves
of ``A = L D L^T`` (the up-looking method of QDLDL: Stellato, Banjac, Goulart, Bemporad
and Boyd, "OSQP: an operator splitting solver for quadratic programs", 2020), written
here from the method's description.  Compiled without fused multiply-adds: the same
bits on every processor."""

from libc.stdlib cimport free, malloc


cdef Py_ssize_t _bfs(
    const long long[:] indptr, const long long[:] indices, long long[:] label,
    long long sid, long long root, long long[:] level, long long[:] queue,
) noexcept nogil:
    # breadth-first from root over the nodes labelled sid; level[v] set (from 0) for
    # the nodes reached, which are queue[0 .. count - 1] in order; returns count
    cdef Py_ssize_t head = 0, tail = 1, p
    cdef long long v, w
    queue[0] = root
    level[root] = 0
    label[root] = -sid - 2  # (seen in this search)
    while head < tail:
        v = queue[head]
        head += 1
        for p in range(indptr[v], indptr[v + 1]):
            w = indices[p]
            if label[w] == sid:
                label[w] = -sid - 2
                level[w] = level[v] + 1
                queue[tail] = w
                tail += 1
    for p in range(tail):
        label[queue[p]] = sid
    return tail


def nested_dissection(
    const long long[:] indptr,
    const long long[:] indices,
    long long leaf,
    long long[:] perm,
):
    """``perm[k]``: the node eliminated ``k``-th.  A part of the graph is ordered as: its
    connected components one after the other; a component of more than ``leaf`` nodes
    as its two sides, then its separator, the smallest level of a breadth-first
    search from a far node (found by two searches) among its middle third; a smaller
    one in that search's order."""
    cdef Py_ssize_t n = indptr.shape[0] - 1
    cdef long long *stack_lo = <long long *> malloc((2 * n + 2) * sizeof(long long))
    cdef long long *stack_hi = <long long *> malloc((2 * n + 2) * sizeof(long long))
    cdef long long *stack_out = <long long *> malloc((2 * n + 2) * sizeof(long long))
    cdef long long[:] nodes = perm.copy()
    cdef long long[:] label = perm.copy()
    cdef long long[:] level = perm.copy()
    cdef long long[:] queue = perm.copy()
    cdef long long[:] count = perm.copy()
    cdef Py_ssize_t top, lo, hi, out, size, reached, i, k, far, depth, best, a, b
    cdef long long sid = 0, v, root, m
    with nogil:
        for i in range(n):
            nodes[i] = i
            label[i] = 0
        top = 0
        if n > 0:
            stack_lo[0] = 0
            stack_hi[0] = n
            stack_out[0] = 0
            top = 1
        while top > 0:
            top -= 1
            lo = stack_lo[top]
            hi = stack_hi[top]
            out = stack_out[top]
            size = hi - lo
            sid += 1
            for i in range(lo, hi):
                label[nodes[i]] = sid
            root = nodes[lo]
            reached = _bfs(indptr, indices, label, sid, root, level, queue)
            if reached < size:
                # the component of root first, then the rest (both ordered again)
                for i in range(reached):
                    label[queue[i]] = -1
                k = reached
                for i in range(lo, hi):
                    if label[nodes[i]] != -1:
                        queue[k] = nodes[i]
                        k += 1
                for i in range(size):
                    nodes[lo + i] = queue[i]
                    label[queue[i]] = 0
                stack_lo[top] = lo + reached
                stack_hi[top] = hi
                stack_out[top] = out + reached
                stack_lo[top + 1] = lo
                stack_hi[top + 1] = lo + reached
                stack_out[top + 1] = out
                top += 2
                continue
            if size <= leaf:
                for i in range(size):
                    perm[out + i] = queue[i]
                    label[queue[i]] = 0
                continue
            far = queue[size - 1]  # (a node far from root: search again from it)
            _bfs(indptr, indices, label, sid, far, level, queue)
            depth = level[queue[size - 1]]
            if depth < 2:
                for i in range(size):
                    perm[out + i] = queue[i]
                    label[queue[i]] = 0
                continue
            for i in range(depth + 1):
                count[i] = 0
            for i in range(size):
                count[level[queue[i]]] += 1
            best = depth // 3 if depth // 3 >= 1 else 1
            m = best
            for i in range(best, 2 * depth // 3 + 1):
                if i >= 1 and i <= depth - 1 and count[i] < count[m]:
                    m = i
            # sides: levels below m, then above; the separator (level m) last
            a = 0
            b = 0
            for i in range(size):
                if level[queue[i]] < m:
                    a += 1
                elif level[queue[i]] > m:
                    b += 1
            k = 0
            for i in range(size):
                v = queue[i]
                label[v] = 0
                if level[v] < m:
                    nodes[lo + k] = v
                    k += 1
            for i in range(size):
                v = queue[i]
                if level[v] > m:
                    nodes[lo + k] = v
                    k += 1
            for i in range(size):
                v = queue[i]
                if level[v] == m:
                    perm[out + k] = v
                    k += 1
            stack_lo[top] = lo + a
            stack_hi[top] = lo + a + b
            stack_out[top] = out + a
            stack_lo[top + 1] = lo
            stack_hi[top + 1] = lo + a
            stack_out[top + 1] = out
            top += 2
    free(stack_lo)
    free(stack_hi)
    free(stack_out)


def etree(
    const long long[:] Ap, const long long[:] Ai, long long[:] parent, long long[:] Lnz,
    long long[:] work,
):
    """The elimination tree of the upper triangle (CSC ``Ap``, ``Ai``) and each column
    of L's count; returns their sum, or -1 if an entry lies below the diagonal."""
    cdef Py_ssize_t n = Ap.shape[0] - 1
    cdef Py_ssize_t j, p
    cdef long long i, total = 0
    cdef bint bad = False
    with nogil:
        for i in range(n):
            work[i] = -1
            Lnz[i] = 0
            parent[i] = -1
        for j in range(n):
            work[j] = j
            for p in range(Ap[j], Ap[j + 1]):
                i = Ai[p]
                if i > j:
                    bad = True
                    break
                while work[i] != j:
                    if parent[i] == -1:
                        parent[i] = j
                    Lnz[i] += 1
                    work[i] = j
                    i = parent[i]
            if bad:
                break
        for j in range(n):
            total += Lnz[j]
    return -1 if bad else total


def factor(
    const long long[:] Ap, const long long[:] Ai, const double[:] Ax,
    const long long[:] parent, const long long[:] Lp,
    long long[:] Li, double[:] Lx, double[:] D, double[:] Dinv,
    long long[:] y_idx, long long[:] elim, long long[:] nxt, unsigned char[:] used,
    double[:] y,
):
    """``A = L D L^T`` (unit lower ``L`` in CSC ``Lp``, ``Li``, ``Lx``; ``D``) from the
    upper triangle ``Ap``, ``Ai``, ``Ax`` and its elimination tree; returns the first
    column whose pivot is not positive, or -1."""
    cdef Py_ssize_t n = Ap.shape[0] - 1
    cdef Py_ssize_t k, p, i, j, ny, ne, c, t
    cdef long long b, e
    cdef double yc
    cdef long long bad = -1
    with nogil:
        for i in range(n):
            used[i] = 0
            y[i] = 0.0
            nxt[i] = Lp[i]
        for k in range(n):
            ny = 0
            D[k] = 0.0
            for p in range(Ap[k], Ap[k + 1]):
                b = Ai[p]
                if b == k:
                    D[k] = Ax[p]
                    continue
                y[b] = Ax[p]
                if used[b]:
                    continue
                used[b] = 1
                elim[0] = b
                ne = 1
                e = parent[b]
                while e != -1 and e < k:
                    if used[e]:
                        break
                    used[e] = 1
                    elim[ne] = e
                    ne += 1
                    e = parent[e]
                while ne > 0:
                    ne -= 1
                    y_idx[ny] = elim[ne]
                    ny += 1
            for i in range(ny - 1, -1, -1):
                c = y_idx[i]
                t = nxt[c]
                yc = y[c]
                for j in range(Lp[c], t):
                    y[Li[j]] = y[Li[j]] - Lx[j] * yc
                Li[t] = k
                Lx[t] = yc * Dinv[c]
                D[k] = D[k] - yc * Lx[t]
                nxt[c] = t + 1
                y[c] = 0.0
                used[c] = 0
            if not D[k] > 0.0:
                bad = k
                break
            Dinv[k] = 1.0 / D[k]
    return bad


def solve(
    const long long[:] Lp, const long long[:] Li, const double[:] Lx,
    const double[:] Dinv, double[:] x,
):
    """``x`` overwritten by ``(L D L^T)^-1 x``."""
    cdef Py_ssize_t n = Lp.shape[0] - 1
    cdef Py_ssize_t i, j
    with nogil:
        for i in range(n):
            for j in range(Lp[i], Lp[i + 1]):
                x[Li[j]] = x[Li[j]] - Lx[j] * x[i]
        for i in range(n):
            x[i] = x[i] * Dinv[i]
        for i in range(n - 1, -1, -1):
            for j in range(Lp[i], Lp[i + 1]):
                x[i] = x[i] - Lx[j] * x[Li[j]]
