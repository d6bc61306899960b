# cython: language_level=3
"""Compiled kernels of the event search (nsfem/integrate/events.py holds the Python reference of
each, under the same name with a leading underscore; tests/test_core_equivalence.py compares them)."""

from libc.math cimport sqrt, fabs, copysign, frexp, ldexp, INFINITY

cdef int MAXITER = 200
cdef double SAFE_HI = 2.0 ** 400
cdef double SAFE_LO = 2.0 ** -400


cdef int roots2(double a, double b, double c, double* out) noexcept nogil:
    """The real roots of a s^2 + b s + c (as events._roots2): their number, written to out[0:2]."""
    cdef double m = fabs(a)
    cdef int k
    cdef double disc, q
    if fabs(b) > m:
        m = fabs(b)
    if fabs(c) > m:
        m = fabs(c)
    if 0.0 < m < INFINITY and not (SAFE_LO <= m <= SAFE_HI):
        frexp(m, &k)
        a = ldexp(a, -k)
        b = ldexp(b, -k)
        c = ldexp(c, -k)
    if a == 0.0:
        if b != 0.0:
            out[0] = -c / b
            return 1
        return 0
    disc = b * b - 4.0 * a * c
    if not disc >= 0.0:
        return 0
    q = -0.5 * (b + copysign(sqrt(disc), b))
    if q != 0.0:
        out[0] = q / a
        out[1] = c / q
        return 2
    out[0] = 0.0
    return 1


cpdef double envelope_min(double f0, double f1, double d0, double d1, double dt, double bound4,
                          double s_hi=1.0):
    """events._envelope_min: the lowest the row can be on [0, s_hi] of the interval, the Hermite cubic
    less its pointwise error bound 16 bound4 s^2 (1 - s)^2 (a quartic p), at the ends or at the minimum
    of each piece where p' goes from - to + (Newton's method kept inside the piece)."""
    cdef double m0 = dt * d0, m1 = dt * d1, df = f1 - f0
    cdef double c0 = f0, c1 = m0, c2 = 3.0 * df - 2.0 * m0 - m1, c3 = m0 + m1 - 2.0 * df
    cdef double e = 16.0 * bound4
    cdef double a3 = -4.0 * e, a2 = 3.0 * c3 + 6.0 * e, a1 = 2.0 * c2 - 2.0 * e
    cdef double r[2]
    cdef double knots[4]
    cdef int nk = 0, nr, i, j, it
    cdef double low, val, s, u, v, fu, fv, x, fx, d2, x_new, tmp, w
    nr = roots2(3.0 * a3, 2.0 * a2, a1, r)
    knots[nk] = 0.0
    nk += 1
    # the inner roots in increasing order (as sorted() does)
    if nr == 2 and r[1] < r[0]:
        tmp = r[0]
        r[0] = r[1]
        r[1] = tmp
    for i in range(nr):
        if 0.0 < r[i] < s_hi:
            knots[nk] = r[i]
            nk += 1
    knots[nk] = s_hi
    nk += 1
    low = INFINITY
    for i in range(nk):
        s = knots[i]
        w = s * (1.0 - s)
        val = c0 + s * (c1 + s * (c2 + s * c3)) - e * (w * w)
        if val < low or i == 0:
            low = val
    for i in range(nk - 1):
        u = knots[i]
        v = knots[i + 1]
        fu = c1 + u * (a1 + u * (a2 + u * a3))
        fv = c1 + v * (a1 + v * (a2 + v * a3))
        if not (fu < 0.0 < fv):
            continue
        x = u - fu * (v - u) / (fv - fu)
        for it in range(MAXITER):
            fx = c1 + x * (a1 + x * (a2 + x * a3))
            if fx == 0.0:
                break
            if fx < 0.0:
                u = x
            else:
                v = x
            d2 = a1 + x * (2.0 * a2 + 3.0 * a3 * x)
            x_new = x - fx / d2 if d2 > 0.0 else 0.5 * (u + v)
            if not (u < x_new < v):
                x_new = 0.5 * (u + v)
            if fabs(x_new - x) <= 4e-16 * max(1.0, fabs(x)) or v - u <= 4e-16 * max(1.0, fabs(v)):
                x = x_new
                break
            x = x_new
        w = x * (1.0 - x)
        val = c0 + x * (c1 + x * (c2 + x * c3)) - e * (w * w)
        if val < low:
            low = val
    return low
