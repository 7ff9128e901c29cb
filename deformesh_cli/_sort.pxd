# cython: language_level=3
"""Insertion sorts of short runs, for the compiled loops that sort a row, a column or a
query's hits of a few entries each (stable: equal keys keep their order)."""


cdef inline void sort_run(long long[:] a, Py_ssize_t lo, Py_ssize_t hi) noexcept nogil:
    """``a[lo:hi]`` ascending."""
    cdef Py_ssize_t j, t
    cdef long long v
    for j in range(lo + 1, hi):
        v = a[j]
        t = j
        while t > lo and a[t - 1] > v:
            a[t] = a[t - 1]
            t -= 1
        a[t] = v


cdef inline void sort_run_with(
    long long[:] key, long long[:] other, Py_ssize_t lo, Py_ssize_t hi
) noexcept nogil:
    """``key[lo:hi]`` ascending, ``other[lo:hi]`` moved with it."""
    cdef Py_ssize_t j, t
    cdef long long v, w
    for j in range(lo + 1, hi):
        v = key[j]
        w = other[j]
        t = j
        while t > lo and key[t - 1] > v:
            key[t] = key[t - 1]
            other[t] = other[t - 1]
            t -= 1
        key[t] = v
        other[t] = w
