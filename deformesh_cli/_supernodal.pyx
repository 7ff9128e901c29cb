# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The loops of :class:`deformesh_cli.ldl.SupernodalLDL`: ``A = L D L^T`` with the
columns of ``L`` that share one row pattern (a supernode) held as one dense block,
row by row, so that the updates run over contiguous numbers.

Left-looking, as in Ng and Peyton's supernodal Cholesky ("Block sparse Cholesky
algorithms on advanced uniprocessor computers", 1993), written here from the
method's description: each supernode gathers its columns of ``A``, subtracts the
update of every earlier supernode with a row among its columns (linked lists keep
them), then factorises its block.  Every sum runs in a fixed order and the module is
compiled without fused multiply-adds: the same bits on every processor."""

from ._sort cimport sort_run

def supernodes(const long long[::1] parent, const long long[::1] count, long long[::1] first):
    """The columns ``0 .. n - 1`` (in elimination order: a parent after its children) in
    runs where column ``j + 1`` is ``j``'s parent and has one row fewer below the
    diagonal (``count``): then ``j``'s rows are ``j + 1``'s and ``j + 1``.  ``first``
    (n + 1) gets each run's first column and then ``n``; returns the runs' count."""
    cdef Py_ssize_t n = parent.shape[0]
    cdef Py_ssize_t j, s = 0
    with nogil:
        for j in range(n):
            if j == 0 or not (parent[j - 1] == j and count[j] == count[j - 1] - 1):
                first[s] = j
                s += 1
        first[s] = n
    return s


def structure(
    const long long[::1] first,
    const long long[::1] parent,
    const long long[::1] Rp,
    const long long[::1] Rj,
    const long long[::1] rp,
    long long[::1] rows,
    long long[::1] owner,
    long long[::1] mark,
    long long[::1] head,
    long long[::1] nxt,
):
    """Each supernode's rows: its own columns, then, ascending, the rows below them of
    its columns in ``A`` (``Rp``, ``Rj``: ``A``'s upper triangle by rows) and of its
    children's blocks, into ``rows[rp[s]:rp[s + 1]]`` (``rp`` from the column counts);
    ``owner`` (n): each column's supernode.  ``mark`` (n), ``head``, ``nxt`` (one per
    supernode): scratch.  Returns the first supernode whose rows are not as many as
    ``rp`` says (the counts are not this pattern's), or -1."""
    cdef Py_ssize_t ns = first.shape[0] - 1
    cdef Py_ssize_t n = parent.shape[0]
    cdef Py_ssize_t s, k, p, c, m, below, end
    cdef long long f, l, i, sp
    cdef long long bad = -1
    with nogil:
        for k in range(n):
            mark[k] = -1
        for s in range(ns):
            head[s] = -1
            for k in range(first[s], first[s + 1]):
                owner[k] = s
        for s in range(ns):
            f = first[s]
            l = first[s + 1] - 1
            m = rp[s]
            end = rp[s + 1]
            for k in range(f, l + 1):
                rows[m] = k
                mark[k] = s
                m += 1
            for k in range(f, l + 1):  # A's rows below the block
                for p in range(Rp[k], Rp[k + 1]):
                    i = Rj[p]
                    if i > l and mark[i] != s:
                        if m == end:
                            bad = s
                            break
                        mark[i] = s
                        rows[m] = i
                        m += 1
            c = head[s]  # the children's rows below the block
            while c != -1 and bad < 0:
                for p in range(rp[c], rp[c + 1]):
                    i = rows[p]
                    if i > l and mark[i] != s:
                        if m == end:
                            bad = s
                            break
                        mark[i] = s
                        rows[m] = i
                        m += 1
                c = nxt[c]
            if bad >= 0 or m != end:
                bad = s
                break
            below = rp[s] + (l - f + 1)
            sort_run(rows, below, m)  # (a block's rows are few)
            if parent[l] >= 0:
                sp = owner[parent[l]]
                nxt[s] = head[sp]
                head[sp] = s
    return bad


def factor(
    const long long[::1] first,
    const long long[::1] rp,
    const long long[::1] rows,
    const long long[::1] owner,
    const long long[::1] xp,
    const long long[::1] Rp,
    const long long[::1] Rj,
    const double[::1] Rx,
    double[::1] Lx,
    double[::1] D,
    long long[::1] rel,
    long long[::1] link,
    long long[::1] nxt,
    long long[::1] at,
    double[::1] t,
):
    """The numeric factorisation: supernode ``s``'s block is ``Lx[xp[s]:]``, its rows
    (``rows[rp[s]:rp[s + 1]]``) by its columns, row by row, the unit diagonal's place
    holding the block's ``L``; ``D`` the pivots.  ``Rp``, ``Rj``, ``Rx``: ``A``'s upper
    triangle by rows.  ``rel``, ``t`` (n), ``link``, ``nxt``, ``at`` (one per
    supernode): scratch.  Returns the first column whose pivot is not positive, or
    -1."""
    cdef Py_ssize_t ns = first.shape[0] - 1
    cdef Py_ssize_t s, k, p, c, r, q, jj, ii, p1, p2, w, m, wk, mk
    cdef long long f, l, col, fk
    cdef double d, acc
    cdef double *F
    cdef const double *LK
    cdef long long bad = -1
    cdef long long K, nextK
    with nogil:
        for s in range(ns):
            link[s] = -1
        for s in range(ns):
            f = first[s]
            l = first[s + 1] - 1
            w = l - f + 1
            m = rp[s + 1] - rp[s]
            F = &Lx[xp[s]]
            for q in range(m):
                rel[rows[rp[s] + q]] = q
            for q in range(m * w):
                F[q] = 0.0
            for k in range(f, l + 1):  # A's columns (its upper rows k: A[k, i], i >= k)
                for p in range(Rp[k], Rp[k + 1]):
                    F[rel[Rj[p]] * w + (k - f)] += Rx[p]
            K = link[s]  # every earlier supernode with a row among these columns
            while K != -1:
                nextK = nxt[K]
                fk = first[K]
                wk = first[K + 1] - fk
                mk = rp[K + 1] - rp[K]
                LK = &Lx[xp[K]]
                p1 = at[K]
                p2 = p1
                while p2 < mk and rows[rp[K] + p2] <= l:
                    p2 += 1
                for jj in range(p1, p2):
                    col = rows[rp[K] + jj] - f
                    for c in range(wk):
                        t[c] = LK[jj * wk + c] * D[fk + c]
                    for ii in range(jj, mk):
                        acc = 0.0
                        for c in range(wk):
                            acc = acc + LK[ii * wk + c] * t[c]
                        F[rel[rows[rp[K] + ii]] * w + col] -= acc
                at[K] = p2
                if p2 < mk:
                    q = owner[rows[rp[K] + p2]]
                    nxt[K] = link[q]
                    link[q] = K
                K = nextK
            for c in range(w):  # the block itself, left-looking column by column
                for k in range(c):
                    t[k] = F[c * w + k] * D[f + k]
                for r in range(c, m):
                    acc = 0.0
                    for k in range(c):
                        acc = acc + F[r * w + k] * t[k]
                    F[r * w + c] -= acc
                d = F[c * w + c]
                if not d > 0.0:
                    bad = f + c
                    break
                D[f + c] = d
                F[c * w + c] = 1.0
                for r in range(c + 1, m):
                    F[r * w + c] = F[r * w + c] / d
            if bad >= 0:
                break
            if m > w:
                at[s] = w
                q = owner[rows[rp[s] + w]]
                nxt[s] = link[q]
                link[q] = s
    return bad


def solve(
    const long long[::1] first,
    const long long[::1] rp,
    const long long[::1] rows,
    const long long[::1] xp,
    const double[::1] Lx,
    const double[::1] D,
    double[::1] x,
):
    """``x`` overwritten by ``(L D L^T)^-1 x`` (the factor :func:`factor` made)."""
    cdef Py_ssize_t ns = first.shape[0] - 1
    cdef Py_ssize_t s, r, c, w, m
    cdef long long f
    cdef double acc, v
    cdef const double *F
    with nogil:
        for s in range(ns):
            f = first[s]
            w = first[s + 1] - f
            m = rp[s + 1] - rp[s]
            F = &Lx[xp[s]]
            for r in range(w):  # the block's unit lower triangle
                acc = x[f + r]
                for c in range(r):
                    acc = acc - F[r * w + c] * x[f + c]
                x[f + r] = acc
            for r in range(w, m):  # the rows below
                acc = 0.0
                for c in range(w):
                    acc = acc + F[r * w + c] * x[f + c]
                x[rows[rp[s] + r]] = x[rows[rp[s] + r]] - acc
        for r in range(first[ns]):
            x[r] = x[r] / D[r]
        for s in range(ns - 1, -1, -1):
            f = first[s]
            w = first[s + 1] - f
            m = rp[s + 1] - rp[s]
            F = &Lx[xp[s]]
            for r in range(w, m):
                v = x[rows[rp[s] + r]]
                for c in range(w):
                    x[f + c] = x[f + c] - F[r * w + c] * v
            for r in range(w - 1, -1, -1):
                v = x[f + r]
                for c in range(r):
                    x[f + c] = x[f + c] - F[r * w + c] * v
