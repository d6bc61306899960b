# Divided differences of x -> e^{x tau} for the compiled search (included by _search.pyx): closed_form.
# divided_exp one column and one time at a time, with NumPy's complex expm1 and division reproduced.

cdef inline void cmul(double ar, double ai, double br, double bi, double* r, double* i) noexcept nogil:
    r[0] = ar * br - ai * bi
    i[0] = ar * bi + ai * br


cdef inline void cdiv(double ar, double ai, double br, double bi, double* r, double* i) noexcept nogil:
    """a / b as NumPy divides complex numbers (Smith's method)."""
    cdef double rat, scl
    if fabs(br) >= fabs(bi):
        if br == 0.0 and bi == 0.0:
            r[0], i[0] = ar / fabs(br), ai / fabs(br)
            return
        rat = bi / br
        scl = 1.0 / (br + bi * rat)
        r[0], i[0] = (ar + ai * rat) * scl, (ai - ar * rat) * scl
    else:
        rat = br / bi
        scl = 1.0 / (bi + br * rat)
        r[0], i[0] = (ar * rat + ai) * scl, (ai * rat - ar) * scl


cdef inline void cexp_(double x, double y, double* r, double* i) noexcept nogil:
    """e^(x + iy) (as NumPy's complex exp)."""
    cdef double e = exp(x), c, s
    sincos(y, &s, &c)
    r[0], i[0] = e * c, e * s


cdef void phi1(double x, double y, double* r, double* i) noexcept nogil:
    """closed_form._phi1: (e^z - 1) / z, 1 at z = 0 (NumPy's complex expm1, then its division)."""
    cdef double a, er, ei
    if x == 0.0 and y == 0.0:
        r[0], i[0] = 1.0, 0.0
        return
    a = sin(y / 2.0)
    er = expm1(x) * cos(y) - 2.0 * a * a
    ei = exp(x) * sin(y)
    cdiv(er, ei, x, y, r, i)


cdef void dexp(const double complex* nodes, int m, double tau, double* r, double* i) noexcept nogil:
    """closed_form.divided_exp for one column (m = 2 or 3 nodes) at one tau >= 0."""
    cdef double x0r = nodes[0].real, x0i = nodes[0].imag
    cdef double br, bi, pr, pi_, d1r, d1i, d2r, d2i, size, hr, hi, p2r, p2i, term, ar, ai, tr, ti
    cdef double g1r, g1i, g2r, g2i, fr, fi, vr, vi, ur, ui
    cdef int k
    cexp_(x0r * tau, x0i * tau, &br, &bi)
    if m == 2:
        d1r, d1i = nodes[1].real - x0r, nodes[1].imag - x0i
        phi1(d1r * tau, d1i * tau, &pr, &pi_)
        cmul(br * tau, bi * tau, pr, pi_, r, i)
        return
    d1r, d1i = nodes[1].real - x0r, nodes[1].imag - x0i
    d2r, d2i = nodes[2].real - x0r, nodes[2].imag - x0i
    size = max(max(hypot(d1r, d1i), hypot(d2r, d2i)), hypot(d2r - d1r, d2i - d1i)) * tau
    if size <= 1.0:
        # F[0, d1, d2](tau) = sum_k tau^(k+2) / (k+2)! h_k(0, d1, d2), h_k = sum_{i<=k} d1^i d2^(k-i)
        hr, hi, p2r, p2i = 1.0, 0.0, 1.0, 0.0
        term = tau * tau / 2.0
        ar, ai = term * hr, term * hi
        for k in range(1, 30):
            cmul(p2r, p2i, d2r, d2i, &p2r, &p2i)
            cmul(hr, hi, d1r, d1i, &tr, &ti)
            hr, hi = tr + p2r, ti + p2i
            term = term * tau / (k + 2)
            ar, ai = ar + term * hr, ai + term * hi
        vr, vi = ar, ai
    else:
        phi1(d1r * tau, d1i * tau, &pr, &pi_)
        g1r, g1i = tau * pr, tau * pi_
        phi1(d2r * tau, d2i * tau, &pr, &pi_)
        g2r, g2i = tau * pr, tau * pi_
        if hypot(d2r - d1r, d2i - d1i) >= max(hypot(d1r, d1i), hypot(d2r, d2i)) * 0.5:
            cdiv(g2r - g1r, g2i - g1i, d2r - d1r, d2i - d1i, &vr, &vi)
        else:
            cexp_(d1r * tau, d1i * tau, &ur, &ui)
            phi1((d2r - d1r) * tau, (d2i - d1i) * tau, &pr, &pi_)
            cmul(ur * tau, ui * tau, pr, pi_, &fr, &fi)
            cdiv(fr - g1r, fi - g1i, d2r, d2i, &vr, &vi)
    cmul(br, bi, vr, vi, r, i)


def divided_exp(nodes, double tau):
    """:func:`dexp` for Python callers (tests: against closed_form.divided_exp): per column of nodes
    (m x K complex, m = 2 or 3), F[nodes](tau)."""
    cdef const double complex[:, ::1] nv = np.ascontiguousarray(np.asarray(nodes, dtype=complex).T)
    cdef int K = nv.shape[0], m = nv.shape[1] if K else 0, j
    if K and m not in (2, 3):
        raise ValueError("divided_exp: 2 or 3 nodes per column")
    out = np.empty(K, dtype=complex)
    cdef double r, i
    for j in range(K):
        dexp(&nv[j, 0], m, tau, &r, &i)
        out[j] = complex(r, i)
    return out
