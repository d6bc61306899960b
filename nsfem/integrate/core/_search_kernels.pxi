# The scalar kernels of the event search (included by _search.pyx): each mirrors the function of
# nsfem/integrate/events.py its docstring names, operation for operation (no fused multiply-adds: see
# setup.py), so that both round alike.

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
    """events._envelope_min (the kernel :func:`envelope` for Python callers)."""
    return envelope(f0, f1, d0, d1, dt, bound4, s_hi)


cdef double envelope(double f0, double f1, double d0, double d1, double dt, double bound4,
                     double s_hi) noexcept nogil:
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


cdef inline void cubic(double f0, double f1, double d0, double d1, double dt, double* c) noexcept nogil:
    """events._cubic: the Hermite cubic's coefficients in s = (t - a) / dt."""
    cdef double m0 = dt * d0, m1 = dt * d1, df = f1 - f0
    c[0] = f0
    c[1] = m0
    c[2] = 3.0 * df - 2.0 * m0 - m1
    c[3] = m0 + m1 - 2.0 * df


cdef inline double cubic_at(const double* c, double s) noexcept nogil:
    return c[0] + s * (c[1] + s * (c[2] + s * c[3]))


cdef double hermite_min(double f0, double f1, double d0, double d1, double dt) noexcept nogil:
    """events._hermite_min for one interval: the cubic's minimum, at an end or a root of its slope."""
    cdef double c[4]
    cdef double r[2]
    cdef double out = f0 if f0 <= f1 else f1, v
    cdef int nr, j
    cubic(f0, f1, d0, d1, dt, c)
    nr = roots2(3.0 * c[3], 2.0 * c[2], c[1], r)
    for j in range(nr):
        if 0.0 < r[j] < 1.0:
            v = cubic_at(c, r[j])
            if v < out:
                out = v
    return out


cdef double cubic_argmax(const double* c) noexcept nogil:
    """events._cubic_argmax: where on [0, 1] the cubic is largest (the first of equal values)."""
    cdef double ss[4]
    cdef double r[2]
    cdef int n = 2, nr, j
    cdef double best = 0.0, vbest = 0.0, v
    cdef bint have = False
    ss[0] = 0.0
    ss[1] = 1.0
    nr = roots2(3.0 * c[3], 2.0 * c[2], c[1], r)
    for j in range(nr):
        ss[n] = r[j]
        n += 1
    for j in range(n):
        if 0.0 <= ss[j] <= 1.0:
            v = cubic_at(c, ss[j])
            if not have or v > vbest:
                best, vbest, have = ss[j], v, True
    return best


cdef bint convex(double f0, double f1, double d0, double d1, double dt, double bound4) noexcept nogil:
    """events._convex: the cubic's curvature less its error bound positive at both ends."""
    cdef double c[4]
    cubic(f0, f1, d0, d1, dt, c)
    return min(2.0 * c[2], 2.0 * c[2] + 6.0 * c[3]) > 32.0 * bound4


cdef bint first_root(double f0, double f1, double d0, double d1, double dt, double s_r, double bound4,
                     double tol) noexcept nogil:
    """events._first_root: no earlier point of the interval than s_r can be below -tol."""
    cdef double c[4]
    cdef double r[2]
    cdef double e1 = SLOPE * bound4, s_x = 0.0
    cdef int nr, j
    cdef bint have = False
    cubic(f0, f1, d0, d1, dt, c)
    if not c[1] + e1 + s_r * (2.0 * c[2] + 3.0 * c[3] * s_r) < 0.0:
        return False
    nr = roots2(3.0 * c[3], 2.0 * c[2], c[1] + e1, r)
    for j in range(nr):
        if 0.0 < r[j] < s_r and (not have or r[j] > s_x):
            s_x, have = r[j], True
    return s_x == 0.0 or envelope(f0, f1, d0, d1, dt, bound4, s_x) >= -tol


cdef double cubic_root(double c0, double c1, double c2, double c3) noexcept nogil:
    """events._cubic_root: a root in [0, 1] of the cubic (Newton's method kept in the bracket)."""
    cdef double lo = 0.0, hi = 1.0, f_lo = c0
    cdef double f1 = c0 + c1 + c2 + c3
    cdef double s = c0 / (c0 - f1), f, d, s_new
    cdef int it
    for it in range(8):
        f = c0 + s * (c1 + s * (c2 + s * c3))
        if (f > 0) == (f_lo > 0):
            lo, f_lo = s, f
        else:
            hi = s
        d = c1 + s * (2.0 * c2 + 3.0 * s * c3)
        s_new = s - f / d if d != 0.0 else -1.0
        if not (lo < s_new < hi):
            s_new = 0.5 * (lo + hi)
        if fabs(s_new - s) <= 1e-12:
            return s_new
        s = s_new
    return s


cdef void screen_row(const double* dt, const double* f, const double* hd, int n, double tol, const double* b4,
                     const char* subdivide, char* cross, char* turn, char* near) noexcept nogil:
    """events._screen_row (and events._screen, the same rule on arrays): per interval of one row, a
    crossing of -tol, a turn of h' from - to +, and whether the interval is near (its cubic less the
    error bound comes within the band)."""
    cdef int k
    cdef double f0, f1, d0, d1, lo
    cdef bint a0, a1, hit
    for k in range(n):
        f0, f1, d0, d1 = f[k], f[k + 1], hd[k], hd[k + 1]
        a0 = f0 >= -tol
        a1 = f1 >= -tol
        cross[k] = a0 and not a1
        turn[k] = d0 < 0 and d1 >= 0
        near[k] = False
        if not (a0 and a1 and (turn[k] or subdivide[k])):
            continue
        if not min(f0, f1) - 4.0 / 27.0 * dt[k] * (fabs(d0) + fabs(d1)) - b4[k] <= tol:
            continue
        lo = hermite_min(f0, f1, d0, d1, dt[k]) - b4[k]
        hit = lo <= tol if turn[k] else lo < -tol
        if hit and isfinite(b4[k]):
            lo = envelope(f0, f1, d0, d1, dt[k], b4[k], 1.0)
            hit = lo <= tol if turn[k] else lo < -tol
        near[k] = hit


cdef inline void pick(const double* v, int which, double thr, double* f, double* d) noexcept nogil:
    """The function and slope a root is sought of: which 0, (h - thr, h'); 1, (h', h'')."""
    if which == 0:
        f[0], d[0] = v[0] - thr, v[1]
    else:
        f[0], d[0] = v[1], v[2]


def screen(dt, f, hd, double tol, b4, subdivide):
    """:func:`screen_row` for Python callers (tests: against events._screen_row): lists of bools
    (cross, turn, near) per interval."""
    cdef int n = len(dt), k
    cdef double[::1] dtv = np.ascontiguousarray(dt, dtype=float), fv = np.ascontiguousarray(f, dtype=float)
    cdef double[::1] hdv = np.ascontiguousarray(hd, dtype=float), b4v = np.ascontiguousarray(b4, dtype=float)
    cdef char[::1] sub = np.ascontiguousarray(subdivide, dtype=np.int8)
    cdef char[::1] out = np.zeros(3 * n + 1, dtype=np.int8)
    if len(f) != n + 1 or len(hd) != n + 1 or len(b4) != n or len(subdivide) != n:
        raise ValueError("screen: f and hd need one sample more than dt, b4 and subdivide")
    if n:
        screen_row(&dtv[0], &fv[0], &hdv[0], n, tol, &b4v[0], &sub[0], &out[0], &out[n], &out[2 * n])
    return ([bool(out[k]) for k in range(n)], [bool(out[n + k]) for k in range(n)],
            [bool(out[2 * n + k]) for k in range(n)])


cdef void linspace(double a, double b, int num, double* out) noexcept nogil:
    """numpy.linspace(a, b, num) bit for bit (j step + a, the last b)."""
    cdef int div = num - 1, j
    cdef double delta = b - a, step
    if div <= 0:
        out[0] = a
        return
    step = delta / div
    for j in range(num):
        if step == 0.0:
            out[j] = (<double>j / div) * delta + a
        else:
            out[j] = <double>j * step + a
    out[num - 1] = b
