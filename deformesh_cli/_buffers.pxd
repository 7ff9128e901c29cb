# cython: language_level=3
"""Growable arrays for the compiled kernels that build lists of unknown length
(:mod:`._recover`'s cavities, :mod:`._ldl`'s quotient graph): each grows by doubling
and reports running out of memory by returning -1, leaving what it held intact."""

from libc.stdlib cimport free, realloc


cdef struct Buf:
    long long *d
    long long n
    long long cap


cdef inline int resize(void **p, size_t nbytes) noexcept nogil:
    """``*p`` reallocated to ``nbytes``; -1 (``*p`` kept) if there is no room."""
    cdef void *q = realloc(p[0], nbytes)
    if q == NULL:
        return -1
    p[0] = q
    return 0


cdef inline int reserve(Buf *b, long long size) noexcept nogil:
    """Room for ``size`` items."""
    if size > b.cap:
        if resize(<void **> &b.d, size * sizeof(long long)) < 0:
            return -1
        b.cap = size
    return 0


cdef inline int push(Buf *b, long long v) noexcept nogil:
    """``v`` appended."""
    if b.n == b.cap and reserve(b, 2 * b.cap + 8) < 0:
        return -1
    b.d[b.n] = v
    b.n += 1
    return 0


cdef inline void release(Buf *b) noexcept nogil:
    """Its memory freed; empty again."""
    free(b.d)
    b.d = NULL
    b.n = 0
    b.cap = 0
