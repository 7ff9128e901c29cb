# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loops of :mod:`deformesh_cli.ldl`: an approximate minimum degree ordering of a
sparse symmetric matrix's graph, the elimination tree and its postorder, and the
numeric factorisation and solves
of ``A = L D L^T`` (the up-looking method of QDLDL: Stellato, Banjac, Goulart, Bemporad
and Boyd, "OSQP: an operator splitting solver for quadratic programs", 2020), written
here from the method's description; the dot product and symmetric product of conjugate
gradients.  Compiled without fused multiply-adds: the same bits on every processor."""

from libc.stdlib cimport calloc, free, malloc

from ._buffers cimport Buf, push, release
from ._sort cimport sort_run_with


cdef inline void _unlink(long long i, long long *head, long long *nxt, long long *prv,
                         long long *deg) noexcept nogil:
    if prv[i] >= 0:
        nxt[prv[i]] = nxt[i]
    else:
        head[deg[i]] = nxt[i]
    if nxt[i] >= 0:
        prv[nxt[i]] = prv[i]


cdef inline void _link(long long i, long long d, long long *head, long long *nxt,
                       long long *prv, long long *deg) noexcept nogil:
    deg[i] = d
    prv[i] = -1
    nxt[i] = head[d]
    if head[d] >= 0:
        prv[head[d]] = i
    head[d] = i


cdef int _gather(const Buf *src, Buf *lp, long long *mark, const unsigned char *state,
                 long long stamp) noexcept nogil:
    """The variables of ``src`` not yet marked ``stamp`` appended to ``lp`` and marked;
    -1 out of memory."""
    cdef long long q, v
    for q in range(src.n):
        v = src.d[q]
        if state[v] == 0 and mark[v] != stamp:
            mark[v] = stamp
            if push(lp, v) < 0:
                return -1
    return 0


def minimum_degree(const long long[:] indptr, const long long[:] indices, long long[:] perm):
    """``perm[k]``: the node eliminated ``k``-th, by approximate minimum degree on the
    quotient graph (Amestoy, Davis and Duff, 1996): each step eliminates a node of
    least approximate degree (the first in its degree's list; a node's list place is
    where its last degree update put it, so the order is a function of the graph),
    makes it an element whose variables are its variable neighbours and those of the
    elements it absorbs, and bounds each such variable's degree by its variable
    neighbours, the new element's other variables and, per other element, the
    variables that element holds outside the new one (elements held wholly inside
    are absorbed too).  Returns 0, or -1 out of memory."""
    cdef Py_ssize_t n = indptr.shape[0] - 1
    cdef Buf *var = <Buf *> calloc(n + 1, sizeof(Buf))
    cdef Buf *elem = <Buf *> calloc(n + 1, sizeof(Buf))
    cdef Buf *lst = <Buf *> calloc(n + 1, sizeof(Buf))
    cdef long long *head = <long long *> malloc((n + 1) * sizeof(long long))
    cdef long long *nxt = <long long *> malloc((n + 1) * sizeof(long long))
    cdef long long *prv = <long long *> malloc((n + 1) * sizeof(long long))
    cdef long long *deg = <long long *> malloc((n + 1) * sizeof(long long))
    cdef long long *mark = <long long *> calloc(n + 1, sizeof(long long))
    cdef long long *wmark = <long long *> calloc(n + 1, sizeof(long long))
    cdef long long *w = <long long *> malloc((n + 1) * sizeof(long long))
    cdef unsigned char *state = <unsigned char *> calloc(n + 1, sizeof(unsigned char))
    cdef Buf lp
    cdef Py_ssize_t i, j, q, k, m
    cdef long long v, e, pv, d, stamp = 0, mindeg = 0, bad = 0
    lp.d = NULL
    lp.n = 0
    lp.cap = 0
    if (var == NULL or elem == NULL or lst == NULL or head == NULL or nxt == NULL
            or prv == NULL or deg == NULL or mark == NULL or wmark == NULL or w == NULL
            or state == NULL):
        bad = -1
    with nogil:
        if bad == 0:
            for i in range(n + 1):
                head[i] = -1
            # state: 0 a variable, 1 an element, 2 absorbed
            for i in range(n - 1, -1, -1):  # (so that the first node heads its list)
                for q in range(indptr[i], indptr[i + 1]):
                    v = indices[q]
                    if v != i and push(&var[i], v) < 0:
                        bad = -1
                _link(i, var[i].n, head, nxt, prv, deg)
        k = 0
        while bad == 0 and k < n:
            while head[mindeg] < 0:
                mindeg += 1
            pv = head[mindeg]
            _unlink(pv, head, nxt, prv, deg)
            perm[k] = pv
            k += 1
            state[pv] = 1
            stamp += 1
            lp.n = 0
            if _gather(&var[pv], &lp, mark, state, stamp) < 0:
                bad = -1
            for q in range(elem[pv].n):
                e = elem[pv].d[q]
                if state[e] != 1:
                    continue
                if _gather(&lst[e], &lp, mark, state, stamp) < 0:
                    bad = -1
                state[e] = 2
                release(&lst[e])
            release(&var[pv])
            release(&elem[pv])
            for q in range(lp.n):
                if push(&lst[pv], lp.d[q]) < 0:
                    bad = -1
            # each variable of the new element: its elements (the absorbed gone, the
            # new one added) and its variable neighbours (those now in it gone)
            for q in range(lp.n):
                i = lp.d[q]
                m = 0
                for j in range(elem[i].n):
                    e = elem[i].d[j]
                    if state[e] == 1:
                        elem[i].d[m] = e
                        m += 1
                elem[i].n = m
                if push(&elem[i], pv) < 0:
                    bad = -1
                m = 0
                for j in range(var[i].n):
                    v = var[i].d[j]
                    if state[v] == 0 and mark[v] != stamp:
                        var[i].d[m] = v
                        m += 1
                var[i].n = m
            # |Le \ Lp| for every other element of those variables
            for q in range(lp.n):
                i = lp.d[q]
                for j in range(elem[i].n):
                    e = elem[i].d[j]
                    if e == pv:
                        continue
                    if wmark[e] != stamp:
                        wmark[e] = stamp
                        w[e] = lst[e].n
                    w[e] -= 1
            for q in range(lp.n):
                i = lp.d[q]
                d = var[i].n + lp.n - 1
                for j in range(elem[i].n):
                    e = elem[i].d[j]
                    if e == pv or state[e] != 1:
                        continue
                    if w[e] == 0:  # (held wholly in the new element: absorbed)
                        state[e] = 2
                        release(&lst[e])
                        continue
                    d += w[e]
                if d > n - k - 1:
                    d = n - k - 1
                _unlink(i, head, nxt, prv, deg)
                _link(i, d, head, nxt, prv, deg)
                if d < mindeg:
                    mindeg = d
    for i in range(n + 1):
        if var != NULL:
            free(var[i].d)
        if elem != NULL:
            free(elem[i].d)
        if lst != NULL:
            free(lst[i].d)
    free(var)
    free(elem)
    free(lst)
    free(head)
    free(nxt)
    free(prv)
    free(deg)
    free(mark)
    free(wmark)
    free(w)
    free(state)
    free(lp.d)
    return bad


def postorder(const long long[:] parent, long long[:] out):
    """``out``: the nodes of the forest ``parent`` (-1 at a root) in postorder, each
    node's children in increasing order, the trees by their roots' order (so a
    subtree's columns are eliminated together: the factor is read in runs)."""
    cdef Py_ssize_t n = parent.shape[0]
    cdef long long *first = <long long *> malloc((n + 1) * sizeof(long long))
    cdef long long *sibling = <long long *> malloc((n + 1) * sizeof(long long))
    cdef long long *stack = <long long *> malloc((n + 1) * sizeof(long long))
    cdef Py_ssize_t j, k = 0, top
    cdef long long v, c
    if first == NULL or sibling == NULL or stack == NULL:
        free(first)
        free(sibling)
        free(stack)
        raise MemoryError("postorder")
    with nogil:
        for j in range(n):
            first[j] = -1
        for j in range(n - 1, -1, -1):  # (children linked in increasing order)
            if parent[j] >= 0:
                sibling[j] = first[parent[j]]
                first[parent[j]] = j
        for j in range(n):
            if parent[j] >= 0:
                continue
            stack[0] = j
            top = 1
            while top > 0:
                v = stack[top - 1]
                c = first[v]
                if c >= 0:
                    first[v] = sibling[c]  # (the next child, when v comes up again)
                    stack[top] = c
                    top += 1
                else:
                    top -= 1
                    out[k] = v
                    k += 1
    free(first)
    free(sibling)
    free(stack)


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
    const long long[::1] Ap, const long long[::1] Ai, const double[::1] Ax,
    const long long[::1] parent, const long long[::1] Lp,
    long long[::1] Li, double[::1] Lx, double[::1] D, double[::1] Dinv,
    long long[::1] y_idx, long long[::1] elim, long long[::1] nxt, unsigned char[::1] used,
    double[::1] y,
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
    const long long[::1] Lp, const long long[::1] Li, const double[::1] Lx,
    const double[::1] Dinv, double[::1] x,
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


def permute_upper(
    const long long[:] indptr, const long long[:] indices, const long long[:] pinv,
    long long[:] Ap, long long[:] Ai, long long[:] src,
):
    """The upper triangle of the symmetric matrix (CSR ``indptr``, ``indices``) with its
    rows and columns renumbered by ``pinv``, by columns (``Ap``, ``Ai``: rows
    ascending within each) and each entry's place in ``indices`` (``src``): a
    counting sort by column, then each column's few rows sorted; returns its
    entries' count."""
    cdef Py_ssize_t n = indptr.shape[0] - 1
    cdef Py_ssize_t i, q, t, m = 0
    cdef long long r, c
    with nogil:
        for i in range(n + 1):
            Ap[i] = 0
        for i in range(n):
            r = pinv[i]
            for q in range(indptr[i], indptr[i + 1]):
                c = pinv[indices[q]]
                if r <= c:
                    Ap[c + 1] += 1
        for i in range(n):
            Ap[i + 1] += Ap[i]
        m = Ap[n]
        for i in range(n):
            r = pinv[i]
            for q in range(indptr[i], indptr[i + 1]):
                c = pinv[indices[q]]
                if r <= c:
                    t = Ap[c]
                    Ai[t] = r
                    src[t] = q
                    Ap[c] += 1
        for i in range(n, 0, -1):  # (Ap[c] ran to the column's end: shift back)
            Ap[i] = Ap[i - 1]
        Ap[0] = 0
        for c in range(n):
            sort_run_with(Ai, src, Ap[c], Ap[c + 1])  # (by row)
    return m


def dot(const double[::1] x, const double[::1] y):
    """``x . y`` summed in index order (no BLAS: the same bits on every processor)."""
    cdef Py_ssize_t i
    cdef double s = 0.0
    with nogil:
        for i in range(x.shape[0]):
            s = s + x[i] * y[i]
    return s


def upper_matvec(
    const long long[::1] Ap, const long long[::1] Ai, const double[::1] Ax,
    const double[::1] x, double[::1] out,
):
    """``out = A x`` for the symmetric ``A`` given by its upper triangle by columns
    (``Ap``, ``Ai``, ``Ax``), each entry added in storage order."""
    cdef Py_ssize_t n = Ap.shape[0] - 1
    cdef Py_ssize_t j, p
    cdef long long i
    cdef double xj, s
    with nogil:
        for j in range(n):
            out[j] = 0.0
        for j in range(n):
            xj = x[j]
            s = 0.0
            for p in range(Ap[j], Ap[j + 1]):
                i = Ai[p]
                if i == j:
                    s = s + Ax[p] * xj
                else:
                    out[i] = out[i] + Ax[p] * xj
                    s = s + Ax[p] * x[i]
            out[j] = out[j] + s


def solve2(
    const long long[::1] Lp, const long long[::1] Li, const double[::1] Lx,
    const double[::1] Dinv, double[:, ::1] x,
):
    """:func:`solve` of both columns of ``x`` (n, 2) in one pass over the factor: each
    column's operations are :func:`solve`'s, in its order (the same bits)."""
    cdef Py_ssize_t n = Lp.shape[0] - 1
    cdef Py_ssize_t i, j
    cdef long long r
    cdef double a, b, l
    with nogil:
        for i in range(n):
            a = x[i, 0]
            b = x[i, 1]
            for j in range(Lp[i], Lp[i + 1]):
                r = Li[j]
                l = Lx[j]
                x[r, 0] = x[r, 0] - l * a
                x[r, 1] = x[r, 1] - l * b
        for i in range(n):
            x[i, 0] = x[i, 0] * Dinv[i]
            x[i, 1] = x[i, 1] * Dinv[i]
        for i in range(n - 1, -1, -1):
            a = x[i, 0]
            b = x[i, 1]
            for j in range(Lp[i], Lp[i + 1]):
                r = Li[j]
                l = Lx[j]
                a = a - l * x[r, 0]
                b = b - l * x[r, 1]
            x[i, 0] = a
            x[i, 1] = b
