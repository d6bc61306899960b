# cython: language_level=3
"""Compiled kernels of an event's resolution outside its LCPs (issue 33, part "resolve").

Each mirrors a Python reference named in its docstring (nsfem/integrate/transitions.py): the state's
gaps and gap rates with their zero bands (``_bands`` with ``Memory.observe``) and the gap rates after an
impulse with their bands (``_rate_bands``). The products J^T x are plain loops, one sum per contact in
the order of the coordinates, and round differently from BLAS (a few ulp of the largest term); the bands'
arithmetic is the reference's, operation for operation. tests/test_core_resolve.py gives the bounds.
"""

from libc.math cimport fabs

#: relative size below which a gap, gap rate or slip rate is zero (transitions.ZERO)
cdef double ZERO = 1e-10


cdef inline double nmax(double a, double b) noexcept nogil:
    """numpy's maximum of two floats: a nan in either gives nan."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a >= b else b


cdef inline double dot(const double[:, ::1] JT, Py_ssize_t k, const double[::1] x) noexcept nogil:
    """Row k of J^T times x, summed over the coordinates in order."""
    cdef Py_ssize_t i
    cdef double s = 0.0
    for i in range(JT.shape[1]):
        s += JT[k, i] * x[i]
    return s


cdef inline double abs_dot(const double[:, ::1] aJT, Py_ssize_t k, const double[::1] x) noexcept nogil:
    """Row k of |J|^T times |x|."""
    cdef Py_ssize_t i
    cdef double s = 0.0
    for i in range(aJT.shape[1]):
        s += aJT[k, i] * fabs(x[i])
    return s


cdef inline double band_floor(const double[::1] terms) noexcept nogil:
    """The floor 1e-3 ZERO max(terms, 0) of transitions._band (numpy's max: a nan propagates)."""
    cdef Py_ssize_t k
    cdef double top = 0.0
    for k in range(terms.shape[0]):
        top = nmax(top, terms[k])
    return 1e-3 * ZERO * top


cpdef void state_bands(const double[:, ::1] JNT, const double[:, ::1] aJT, const double[::1] jN,
                       const double[::1] aj, const double[::1] q, const double[::1] v,
                       const double[::1] gap_scale, const double[::1] rate_scale, const double[::1] gap_tol,
                       double gap_floor, double[:, ::1] out):
    """Mirrors transitions._bands on the path with scales (Memory.observe of one state, then the gaps,
    gap rates and their zero bands): ``out`` rows are the new gap scale, the new rate scale, g, g', the
    gap band and the rate band (6 x m). ``gap_tol``: per contact, or empty for none."""
    cdef Py_ssize_t k, m = JNT.shape[0], n = JNT.shape[1]
    # read and written without bounds checks: every shape checked here (a ValueError, never a stray access)
    if (aJT.shape[0] != m or aJT.shape[1] != n or jN.shape[0] != m or aj.shape[0] != m or q.shape[0] != n
            or v.shape[0] != n or gap_scale.shape[0] != m or rate_scale.shape[0] != m
            or (gap_tol.shape[0] and gap_tol.shape[0] != m) or out.shape[0] != 6 or out.shape[1] != m):
        raise ValueError("state_bands: J_N^T and |J_N|^T m x n, j_N, |j_N|, the scales (and gap_tol when given) "
                         "a value per contact, q and v a value per coordinate, out 6 x m")
    cdef double[::1] gs = out[0], rs = out[1], g = out[2], gv = out[3], tg = out[4], tv = out[5]
    cdef double fg, fv
    # Memory.observe: the terms of the gaps (|J_N|^T |q| + |j_N|) and rates (|J_N|^T |q'|); the scales
    for k in range(m):
        tg[k] = abs_dot(aJT, k, q) + aj[k]
        tv[k] = abs_dot(aJT, k, v)
        gs[k] = nmax(gap_scale[k], tg[k])
        rs[k] = nmax(rate_scale[k], tv[k])
    fg = band_floor(tg)
    fv = band_floor(tv)
    for k in range(m):
        g[k] = dot(JNT, k, q) + jN[k]
        gv[k] = dot(JNT, k, v)
        # max(ZERO scale, _band(terms)) [, gap_tol], then the gap floor
        tg[k] = nmax(ZERO * gs[k], ZERO * tg[k] + fg + 1e-300)
        if gap_tol.shape[0]:
            tg[k] = nmax(tg[k], gap_tol[k])
        tg[k] = nmax(tg[k], gap_floor)
        tv[k] = nmax(ZERO * rs[k], ZERO * tv[k] + fv + 1e-300)


cpdef void rate_bands(const double[:, ::1] JNT, const double[:, ::1] aJT, const double[::1] v,
                      const double[::1] tv, double[:, ::1] out):
    """Mirrors transitions._rate_bands: ``out`` rows are g' = J_N^T v and the band max(tv, _tol(J_N, v))
    (2 x m)."""
    cdef Py_ssize_t k, m = JNT.shape[0], n = JNT.shape[1]
    if (aJT.shape[0] != m or aJT.shape[1] != n or v.shape[0] != n or tv.shape[0] != m or out.shape[0] != 2
            or out.shape[1] != m):
        raise ValueError("rate_bands: J_N^T and |J_N|^T m x n, v a value per coordinate, tv a value per contact, "
                         "out 2 x m")
    cdef double[::1] gv = out[0], tn = out[1]
    cdef double f
    for k in range(m):
        tn[k] = abs_dot(aJT, k, v)
    f = band_floor(tn)
    for k in range(m):
        gv[k] = dot(JNT, k, v)
        tn[k] = nmax(tv[k], ZERO * tn[k] + f + 1e-300)
