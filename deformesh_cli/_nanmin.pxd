# cython: language_level=3
"""``np.minimum``'s rule for the compiled loops: the lesser, NaN where either is NaN."""

from libc.math cimport isnan


cdef inline double nan_min(double a, double b) noexcept nogil:
    if isnan(a) or isnan(b):
        return a + b
    return a if a < b else b
