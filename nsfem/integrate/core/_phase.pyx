# cython: language_level=3
"""Compiled kernels of a phase's set-up, its state at one time and its closed-form energy (issue 33,
part "phase").

Each mirrors a Python reference, named in its docstring: configuration.Phase.__init__, Phase._motion
and Phase._xi_at, closed_form.ModalPlan.modes, event_driven._exp_integrals, EventDriven._energy_modal,
EventDriven._end_energy and closed_form.group_integrals (the work integrals of divided-difference groups:
C's complex arithmetic there, and Taylor lengths and scalings chosen per column, within 1e-13 of the
reference's entries). Complex arrays come in as float64 views of their interleaved (real,
imaginary) pairs (``a.view(np.float64)``), and each complex product, quotient, exp and expm1 is
written out here with numpy's formula. Where numpy's SIMD loops fuse a multiply-add, the two differ in
the last bit. The matrix products are plain loops, one sum per output entry in the order of its
terms, and round differently from BLAS. The harmonic load's terms of the set-up are reassociated
(phase_modal). tests/test_core_phase.py gives the bounds.
"""

from libc.math cimport fabs, hypot, sin, cos, exp, expm1, NAN
from libc.stdlib cimport malloc, free

include "_modal_sum.pxi"


cdef extern from *:
    """
    #include <complex.h>
    /* e^(x + iy) by the C library's cexp, the function numpy's exp of a complex number calls */
    static inline void nsfem_cexp(double x, double y, double *re, double *im) {
        double _Complex z = cexp(CMPLX(x, y));
        *re = creal(z);
        *im = cimag(z);
    }
    """
    void nsfem_cexp(double x, double y, double* re, double* im) noexcept nogil


cdef inline void cdiv(double ar, double ai, double br, double bi, double* out) noexcept nogil:
    """(ar + i ai) / (br + i bi) as numpy divides complex numbers (Smith's method)."""
    cdef double rat, scl
    cdef double abr = fabs(br), abi = fabs(bi)
    if abr >= abi:
        if abr == 0.0 and abi == 0.0:
            out[0] = ar / abr
            out[1] = ai / abr
            return
        rat = bi / br
        scl = 1.0 / (br + bi * rat)
        out[0] = (ar + ai * rat) * scl
        out[1] = (ai - ar * rat) * scl
    else:
        rat = br / bi
        scl = 1.0 / (bi + br * rat)
        out[0] = (ar * rat + ai) * scl
        out[1] = (ai * rat - ar) * scl


cdef inline void cexpm1(double x, double y, double* out) noexcept nogil:
    """e^(x + iy) - 1 as numpy's expm1 of a complex number forms it."""
    cdef double a = sin(y / 2.0)
    out[0] = expm1(x) * cos(y) - 2.0 * a * a
    out[1] = exp(x) * sin(y)


# -- the phase's set-up ---------------------------------------------------------------------------

cpdef void phase_start(const double[:, ::1] GpinvT, const double[::1] g0, const double[:, ::1] QT,
                       const double[::1] f0_config, const double[:, ::1] BT, const double[:, ::1] N,
                       const double[::1] q0, const double[::1] v0, double[::1] qp, double[::1] f0,
                       double[::1] Bf0, double[::1] x0):
    """Phase.__init__'s products: q_p = -Gpinv g0 (Configuration.particular), the phase's constant load
    f0 = f0_config - Q q_p, B f0, and x0 = (N^T (q0 - q_p), N^T v0). The matrices come transposed
    (GpinvT, QT, BT; N for N^T) so that each product runs along contiguous rows, one independent sum
    per output entry (each summed in the order of its terms)."""
    cdef Py_ssize_t n = QT.shape[0], nc = g0.shape[0], r = N.shape[1], rows = BT.shape[1]
    cdef Py_ssize_t i, j
    cdef double x, y
    if n == 0:
        return
    # read and written without bounds checks: every shape checked here (a ValueError, never a stray write)
    if (QT.shape[1] != n or GpinvT.shape[0] != nc or (nc and GpinvT.shape[1] != n) or f0_config.shape[0] != n
            or BT.shape[0] != n or N.shape[0] != n or q0.shape[0] != n or v0.shape[0] != n or qp.shape[0] != n
            or f0.shape[0] != n or Bf0.shape[0] != rows or x0.shape[0] != 2 * r):
        raise ValueError("phase_start: Q, Gpinv, B and N need the phase's n coordinates (and g0's constraints, "
                         "B f0's and x0's rows) in every array")
    cdef double* pq = &qp[0]
    cdef double* pf = &f0[0]
    cdef double* pb = &Bf0[0] if rows else NULL
    cdef double* px = &x0[0] if r else NULL
    cdef const double* row
    with nogil:
        for i in range(n):
            pq[i] = 0.0
            pf[i] = 0.0
        for i in range(rows):
            pb[i] = 0.0
        for i in range(2 * r):
            px[i] = 0.0
        for j in range(nc):
            x = g0[j]
            row = &GpinvT[j, 0]
            for i in range(n):
                pq[i] = pq[i] + (-row[i]) * x
        for j in range(n):                      # f0 holds Q q_p first
            x = pq[j]
            row = &QT[j, 0]
            for i in range(n):
                pf[i] = pf[i] + row[i] * x
        for i in range(n):
            pf[i] = f0_config[i] - pf[i]
        for j in range(n):
            if rows == 0:
                break
            x = pf[j]
            row = &BT[j, 0]
            for i in range(rows):
                pb[i] = pb[i] + row[i] * x
        for j in range(n):
            if r == 0:
                break
            x = q0[j] - pq[j]
            y = v0[j]
            row = &N[j, 0]
            for i in range(r):
                px[i] = px[i] + row[i] * x
            for i in range(r):
                px[r + i] = px[r + i] + row[i] * y


cdef inline void cmul(double ar, double ai, double br, double bi, double* out) noexcept nogil:
    """(ar + i ai) (br + i bi), each part one difference (sum) of two rounded products."""
    out[0] = ar * br - ai * bi
    out[1] = ar * bi + ai * br


cpdef void phase_modal(const double[:, ::1] ViT, const double[::1] Bf0, const double[::1] x0,
                       const double[:, ::1] harmonic, double ph_re, double ph_im, Py_ssize_t k,
                       const double[:, ::1] V, const double[:, ::1] den, double[::1] z0,
                       double[:, ::1] beta, double[::1] c, double[:, ::1] g, double[:, ::1] U):
    """Phase._motion's modal coefficients and ModalPlan.modes: z0 = Vi x0[k:], beta_0 = Vi (B f0)[k:],
    g_0 = beta_0 / den_0, c = z0 - g_0 - g_1 - ..., U[k:, :m] = V diag(c), U[k:, m] = V g_0 (Vi comes
    transposed, ViT: contiguous columns; the rigid rows U[:k] are left as they are).

    The harmonic load's terms (Configuration.harmonic_b = hb, e^{i w t0} = ph) are the reference's
    beta_1 = Vi conj(hb ph), beta_2 = Vi (hb ph), g = beta / den, U[k:, m + i] = V g_i reassociated:
    ph (or its conjugate) times the configuration's constant vectors ``harmonic`` (Configuration's
    kernel_arrays: rows Vi conj(hb), Vi hb, those over den_1, den_2, and V times these), the same
    values to a few eps of each term (tests/test_core_phase.py) at O(m) instead of O(m^2) per phase.
    Complex pairs interleaved."""
    cdef Py_ssize_t m = ViT.shape[1] // 2
    if m == 0:
        return
    cdef Py_ssize_t ncol = ViT.shape[0], nmu = beta.shape[0], d = V.shape[0], p = U.shape[1] // 2
    # read and written without bounds checks: every shape checked here (a ValueError, never a stray write)
    if (k < 0 or Bf0.shape[0] < k + ncol or x0.shape[0] < k + ncol or V.shape[1] < 2 * m or den.shape[0] < 1
            or den.shape[1] < 2 * m or z0.shape[0] < 2 * m or c.shape[0] < 2 * m or beta.shape[1] != 2 * m
            or g.shape[0] != nmu or g.shape[1] != 2 * m or nmu < 1 or U.shape[0] < k + d or p < m + nmu
            or (nmu > 1 and (harmonic.shape[0] < nmu + 3 or harmonic.shape[1] < 2 * max(m, d)))):
        raise ValueError("phase_modal: Vi, V, den, z0, beta, c, g and U need the configuration's m modes, its "
                         "forcing exponents and rows (U a column per term, harmonic 6 rows of max(m, d) entries)")
    with nogil:
        modal_core(ViT, &Bf0[0], &x0[0], harmonic, ph_re, ph_im, k, V, den, beta.shape[0], U.shape[1] // 2,
                   &z0[0], &beta[0, 0], &c[0], &g[0, 0], &U[0, 0])


cdef void modal_core(const double[:, ::1] ViT, const double* Bf0, const double* x0,
                     const double[:, ::1] harmonic, double ph_re, double ph_im, Py_ssize_t k,
                     const double[:, ::1] V, const double[:, ::1] den, Py_ssize_t nmu, Py_ssize_t p,
                     double* pz, double* pbeta, double* pc, double* pg, double* pU) noexcept nogil:
    """phase_modal's arithmetic on its arrays' first entries (m > 0; nmu rows of beta and g, p terms per row of
    U), shared with PhaseSetup.start."""
    cdef Py_ssize_t m = ViT.shape[1] // 2, ncol = ViT.shape[0], d = V.shape[0]
    cdef Py_ssize_t i, j, l, a
    cdef double x, y, vr, vi_, sr, si
    cdef double q[2]
    cdef double* out
    cdef const double* row
    cdef const double* h
    for j in range(2 * m):
        pz[j] = 0.0
        pbeta[j] = 0.0
    for l in range(ncol):
        x = Bf0[k + l]
        y = x0[k + l]
        row = &ViT[l, 0]
        if x != 0.0:    # (B f0's displacement rows are zeros: their terms add nothing)
            for j in range(2 * m):
                pbeta[j] = pbeta[j] + row[j] * x
        for j in range(2 * m):
            pz[j] = pz[j] + row[j] * y
    for j in range(m):
        cdiv(pbeta[2 * j], pbeta[2 * j + 1], den[0, 2 * j], den[0, 2 * j + 1], q)
        pg[2 * j] = q[0]
        pg[2 * j + 1] = q[1]
        pc[2 * j] = pz[2 * j] - q[0]
        pc[2 * j + 1] = pz[2 * j + 1] - q[1]
    for i in range(1, nmu):
        # mus[1] = -i w: the conjugate phase; mus[2] = i w
        sr = ph_re
        si = -ph_im if i == 1 else ph_im
        h = &harmonic[i - 1, 0]                 # Vi conj(hb), Vi hb
        for j in range(m):
            cmul(h[2 * j], h[2 * j + 1], sr, si, &pbeta[2 * (i * m + j)])
        h = &harmonic[1 + i, 0]                 # those over den_i
        for j in range(m):
            cmul(h[2 * j], h[2 * j + 1], sr, si, &pg[2 * (i * m + j)])
            pc[2 * j] = pc[2 * j] - pg[2 * (i * m + j)]
            pc[2 * j + 1] = pc[2 * j + 1] - pg[2 * (i * m + j) + 1]
        h = &harmonic[3 + i, 0]                 # V times those
        for a in range(d):
            cmul(h[2 * a], h[2 * a + 1], sr, si, &pU[2 * ((k + a) * p + m + i)])
    for a in range(d):
        # row a of U: V[a] diag(c), then the particular solution V[a] . g_0 (one sum in order of j)
        row = &V[a, 0]
        out = pU + 2 * (k + a) * p
        sr = 0.0
        si = 0.0
        for j in range(m):
            vr = row[2 * j]
            vi_ = row[2 * j + 1]
            out[2 * j] = vr * pc[2 * j] - vi_ * pc[2 * j + 1]
            out[2 * j + 1] = vr * pc[2 * j + 1] + vi_ * pc[2 * j]
            sr = sr + (vr * pg[2 * j] - vi_ * pg[2 * j + 1])
            si = si + (vr * pg[2 * j + 1] + vi_ * pg[2 * j])
        out[2 * m] = sr
        out[2 * m + 1] = si


# -- the closed-form energy -----------------------------------------------------------------------

cdef inline void exp_integral(double sr, double si, double ar, double ai, double br, double bi, double T,
                              double T2, double T3, double* out) noexcept nogil:
    """One entry of _exp_integrals: int_0^T e^{s t} dt for s = a + b (sr + i si), from e^{a T} e^{b T}
    (ar + i ai, br + i bi). T2 = T * T / 2, T3 = T * T * T / 6."""
    cdef double pr, pi_, xr, xi, h
    cdef double e[2]
    # |s| T < 1/2 needs hypot only where both parts are small (|s| >= either part, rounded alike)
    if fabs(sr) * T < 0.5 and fabs(si) * T < 0.5:
        h = hypot(sr, si)
    else:
        h = 1.0 / T
    if h * T < 0.5:
        if h < 1e-8 / T:
            # T + x (T^2 / 2 + x T^3 / 6)
            pr = T2 + (sr * T3)
            pi_ = si * T3
            xr = sr * pr - si * pi_
            xi = sr * pi_ + si * pr
            out[0] = T + xr
            out[1] = xi
        else:
            cexpm1(sr * T, si * T, e)
            cdiv(e[0], e[1], sr, si, out)
        return
    pr = ar * br - ai * bi - 1.0
    pi_ = ar * bi + ai * br
    cdiv(pr, pi_, sr, si, out)


cpdef void exp_integrals(const double[::1] a, const double[::1] b, double T, double[:, ::1] phi):
    """event_driven._exp_integrals(a, b, T) into phi (len(a) x len(b) complex, interleaved)."""
    cdef Py_ssize_t na = a.shape[0] // 2, nb = b.shape[0] // 2, j, l
    cdef double T2 = T * T / 2.0, T3 = T * T * T / 6.0
    if phi.shape[0] < na or phi.shape[1] < 2 * nb:
        raise ValueError("exp_integrals: phi needs a row per entry of a and a column per entry of b")
    cdef double* ea = <double*> malloc((2 * (na + nb) + 1) * sizeof(double))
    if ea == NULL:
        raise MemoryError
    cdef double* eb = ea + 2 * na
    with nogil:
        for j in range(na):
            nsfem_cexp(a[2 * j] * T, a[2 * j + 1] * T, &ea[2 * j], &ea[2 * j + 1])
        for l in range(nb):
            nsfem_cexp(b[2 * l] * T, b[2 * l + 1] * T, &eb[2 * l], &eb[2 * l + 1])
        for j in range(na):
            for l in range(nb):
                exp_integral(a[2 * j] + b[2 * l], a[2 * j + 1] + b[2 * l + 1], ea[2 * j], ea[2 * j + 1],
                             eb[2 * l], eb[2 * l + 1], T, T2, T3, &phi[j, 2 * l])
    free(ea)


cpdef double energy_modal(const double[::1] nu, const double[::1] c, const double[:, ::1] g, double T,
                          double t0, const double[:, ::1] E, const double[:, :, ::1] S, double[::1] vals,
                          double[:, ::1] PZ):
    """EventDriven._energy_modal's integrals for z(s) = Z e^{nu s}, Z = [diag(c), g^T] (m modes, then the
    forcing exponents mus = nu[m:]): returns the external work Re sum_i e^{mu_i t0} E_i . PZ_i and writes
    PZ (the rows mus of Phi Z^T) and vals[f] = Re sum S_f * (Z Phi Z^T), Phi = _exp_integrals(nu, nu, T)
    (only its rows mus without forms)."""
    cdef Py_ssize_t p = nu.shape[0] // 2, m = c.shape[0] // 2, nmu = p - m, nf = S.shape[0]
    cdef Py_ssize_t i, j, l, kk, f, rows
    cdef double T2 = T * T / 2.0, T3 = T * T * T / 6.0
    cdef double re, im, zr, zi, yr, yi, sr, si, work, er, ei
    cdef double* en = <double*> malloc((2 * p + 1) * sizeof(double))
    cdef double* phi
    cdef double* zp
    cdef Py_ssize_t first
    rows = p if nf else nmu       # Phi's rows formed: all of nu's, or the mus' only
    first = 0 if nf else m
    # read and written without bounds checks: every shape checked here (a ValueError, never a stray write)
    if (nmu < 0 or g.shape[0] < nmu or g.shape[1] < 2 * m or E.shape[0] < nmu or E.shape[1] < 2 * m
            or (nf and (S.shape[1] < m or S.shape[2] < 2 * m)) or vals.shape[0] < nf or PZ.shape[0] < nmu
            or PZ.shape[1] < 2 * m):
        free(en)
        raise ValueError("energy_modal: g, E and PZ need a row per forcing exponent and the m modes' columns, "
                         "S m x m per form, vals a value per form")
    phi = <double*> malloc((2 * rows * p + 1) * sizeof(double))
    zp = <double*> malloc(2 * (m * p if nf else 1) * sizeof(double))
    if en == NULL or phi == NULL or zp == NULL:
        free(en)
        free(phi)
        free(zp)
        raise MemoryError
    with nogil:
        for j in range(p):
            nsfem_cexp(nu[2 * j] * T, nu[2 * j + 1] * T, &en[2 * j], &en[2 * j + 1])
        # Phi[first + j, l] (exactly symmetric: each entry is formed from a sum and a product, which
        # commute; the full square forms its upper triangle and copies it)
        for j in range(rows):
            for l in range(j if nf else 0, p):
                exp_integral(nu[2 * (first + j)] + nu[2 * l], nu[2 * (first + j) + 1] + nu[2 * l + 1],
                             en[2 * (first + j)], en[2 * (first + j) + 1], en[2 * l], en[2 * l + 1], T, T2, T3,
                             &phi[2 * (j * p + l)])
                if nf and l != j:
                    phi[2 * (l * p + j)] = phi[2 * (j * p + l)]
                    phi[2 * (l * p + j) + 1] = phi[2 * (j * p + l) + 1]
        if nf:
            # ZP = Z Phi (m x p): c_j Phi[j, :] + sum_i g[i, j] Phi[m + i, :]
            for j in range(m):
                for l in range(p):
                    re = c[2 * j] * phi[2 * (j * p + l)] - c[2 * j + 1] * phi[2 * (j * p + l) + 1]
                    im = c[2 * j] * phi[2 * (j * p + l) + 1] + c[2 * j + 1] * phi[2 * (j * p + l)]
                    for i in range(nmu):
                        zr = g[i, 2 * j]
                        zi = g[i, 2 * j + 1]
                        re = re + (zr * phi[2 * ((m + i) * p + l)] - zi * phi[2 * ((m + i) * p + l) + 1])
                        im = im + (zr * phi[2 * ((m + i) * p + l) + 1] + zi * phi[2 * ((m + i) * p + l)])
                    zp[2 * (j * p + l)] = re
                    zp[2 * (j * p + l) + 1] = im
            for i in range(nmu):
                for j in range(m):
                    PZ[i, 2 * j] = zp[2 * (j * p + m + i)]
                    PZ[i, 2 * j + 1] = zp[2 * (j * p + m + i) + 1]
            for f in range(nf):
                vals[f] = 0.0
            # Y = ZP Z^T: Y[j, kk] = ZP[j, kk] c_kk + sum_i ZP[j, m + i] g[i, kk]; vals_f = Re sum S_f * Y
            for j in range(m):
                for kk in range(m):
                    yr = zp[2 * (j * p + kk)] * c[2 * kk] - zp[2 * (j * p + kk) + 1] * c[2 * kk + 1]
                    yi = zp[2 * (j * p + kk)] * c[2 * kk + 1] + zp[2 * (j * p + kk) + 1] * c[2 * kk]
                    for i in range(nmu):
                        zr = zp[2 * (j * p + m + i)]
                        zi = zp[2 * (j * p + m + i) + 1]
                        yr = yr + (zr * g[i, 2 * kk] - zi * g[i, 2 * kk + 1])
                        yi = yi + (zr * g[i, 2 * kk + 1] + zi * g[i, 2 * kk])
                    for f in range(nf):
                        sr = S[f, j, 2 * kk]
                        si = S[f, j, 2 * kk + 1]
                        vals[f] = vals[f] + (sr * yr - si * yi)
        else:
            # PZ = Phi[mus, :m] diag(c) + Phi[mus, m:] g
            for i in range(nmu):
                for j in range(m):
                    re = phi[2 * (i * p + j)] * c[2 * j] - phi[2 * (i * p + j) + 1] * c[2 * j + 1]
                    im = phi[2 * (i * p + j)] * c[2 * j + 1] + phi[2 * (i * p + j) + 1] * c[2 * j]
                    for l in range(nmu):
                        zr = phi[2 * (i * p + m + l)]
                        zi = phi[2 * (i * p + m + l) + 1]
                        re = re + (zr * g[l, 2 * j] - zi * g[l, 2 * j + 1])
                        im = im + (zr * g[l, 2 * j + 1] + zi * g[l, 2 * j])
                    PZ[i, 2 * j] = re
                    PZ[i, 2 * j + 1] = im
        # the load's work: Re sum_i e^{mu_i t0} sum_j E[i, j] PZ[i, j]
        work = 0.0
        for i in range(nmu):
            nsfem_cexp(nu[2 * (m + i)] * t0, nu[2 * (m + i) + 1] * t0, &er, &ei)
            for j in range(m):
                zr = er * E[i, 2 * j] - ei * E[i, 2 * j + 1]
                zi = er * E[i, 2 * j + 1] + ei * E[i, 2 * j]
                work = work + (zr * PZ[i, 2 * j] - zi * PZ[i, 2 * j + 1])
    free(en)
    free(phi)
    free(zp)
    return work


cpdef double end_energy(const double[:, ::1] H, const double[:, ::1] X):
    """EventDriven._end_energy's max_t |X_t^T H X_t| over the rows X_t of X (the states (q, q') at t0 and
    t1; H = diag(K, M) / 2): (X_t H) X_t, the row X_t H formed along H's contiguous rows."""
    cdef Py_ssize_t nt = X.shape[0], n = X.shape[1], t, i, j
    cdef double acc, x, best = 0.0
    cdef bint nan = False
    if n == 0:
        return 0.0
    if H.shape[0] != n or H.shape[1] != n:
        raise ValueError("end_energy: H needs a row and a column per entry of the states X")
    cdef double* row = <double*> malloc(n * sizeof(double))
    if row == NULL:
        raise MemoryError
    cdef const double* h
    with nogil:
        for t in range(nt):
            for i in range(n):
                row[i] = 0.0
            for j in range(n):
                x = X[t, j]
                h = &H[j, 0]
                for i in range(n):
                    row[i] = row[i] + x * h[i]
            acc = 0.0
            for i in range(n):
                acc = acc + row[i] * X[t, i]
            if fabs(acc) > best:
                best = fabs(acc)
            nan = nan or acc != acc
    free(row)
    return NAN if nan else best


# -- the phase's state at one time ----------------------------------------------------------------

cpdef void xi_at(const double[:, ::1] U, const double[::1] nu, double tau, double w, double t,
                 double[::1] out):
    """Phase._xi_at: out[:d] = Re(U e^{nu tau}) (U: d x p complex, interleaved), each row one sum over the
    terms in order, four rows at a time (_modal_sum.pxi's modal_rows, shared with the compiled search); then
    the harmonic components 1 (and cos w t, sin w t when w != 0)."""
    cdef Py_ssize_t d = U.shape[0], p = nu.shape[0] // 2, j
    cdef const double* u
    cdef Py_ssize_t ld = 2 * p
    if (d and U.shape[1] != ld) or out.shape[0] < d + (3 if w != 0.0 else 1):
        raise ValueError("xi_at: U needs a column per term of nu, out the state's entries (with 1, cos, sin)")
    out[d] = 1.0
    if w != 0.0:
        out[d + 1] = cos(w * t)
        out[d + 2] = sin(w * t)
    if d == 0:
        return
    cdef double* e = <double*> malloc((2 * p + 1) * sizeof(double))
    if e == NULL:
        raise MemoryError
    u = &U[0, 0]
    with nogil:
        for j in range(p):
            nsfem_cexp(nu[2 * j] * tau, nu[2 * j + 1] * tau, &e[2 * j], &e[2 * j + 1])
        modal_rows(u, ld, 0, d, 1, e, &e[1], 2, p, &out[0])
    free(e)


# -- work integrals of divided-difference groups ------------------------------------------------------

cdef inline double complex zexp(double complex z) noexcept nogil:
    cdef double re, im
    nsfem_cexp(z.real, z.imag, &re, &im)
    return re + im * 1j


cdef inline double complex zphi1(double complex z) noexcept nogil:
    """(e^z - 1) / z, 1 at z = 0 (closed_form._phi1)."""
    cdef double e[2]
    cdef double q[2]
    if z.real == 0.0 and z.imag == 0.0:
        return 1.0
    cexpm1(z.real, z.imag, e)
    cdiv(e[0], e[1], z.real, z.imag, q)
    return q[0] + q[1] * 1j


cdef inline double zabs(double complex z) noexcept nogil:
    return hypot(z.real, z.imag)


cdef int taylor_terms(double rho, int n) noexcept nogil:
    """closed_form._terms."""
    cdef double t = 1.0
    cdef int k
    if rho == 0.0:
        return 1
    for k in range(1, 30):
        t *= rho * (k + n - 1) / k / (k + n)
        if t <= 1e-18:
            return k
    return 30


cdef double complex divided_exp_one(const double complex* x, int N, double T) noexcept nogil:
    """closed_form.divided_exp_at for one column of N <= 4 nodes."""
    cdef double complex y[4]
    cdef double complex d[3]
    cdef double complex H[3]
    cdef double complex acc
    cdef double gap, best = -1.0, rho = 0.0, term
    cdef int i, j, k, bi = 0, bj = 0, nt
    if N == 1:
        return zexp(x[0] * T)
    if N == 2:
        return zexp(x[0] * T) * T * zphi1((x[1] - x[0]) * T)
    for i in range(N):
        for j in range(N):
            gap = zabs(x[i] - x[j])
            if gap > best:
                best, bi, bj = gap, i, j
    if best * T <= 1.0:
        for j in range(N - 1):
            d[j] = x[j + 1] - x[0]
            H[j] = 1.0
            rho = max(rho, zabs(d[j]))
        term = 1.0
        for k in range(1, N):
            term = term * T / k
        acc = term * H[N - 2]
        nt = taylor_terms(rho * T, N - 1)
        for k in range(1, nt):
            H[0] = H[0] * d[0]
            for j in range(1, N - 1):
                H[j] = H[j - 1] + d[j] * H[j]
            term = term * T / (k + N - 1)
            acc = acc + term * H[N - 2]
        return zexp(x[0] * T) * acc
    k = 1
    for i in range(N):
        if i != bi and i != bj:
            y[k] = x[i]
            k += 1
    y[0], y[N - 1] = x[bi], x[bj]
    return (divided_exp_one(&y[1], N - 1, T) - divided_exp_one(y, N - 1, T)) / (y[N - 1] - y[0])


cdef double complex product_integral(const double complex* A, int m, const double complex* B, int n,
                                     double T) noexcept nogil:
    """closed_form.product_integrals for one pair of columns (m, n <= 3 nodes): the corner of the
    exponential of T [[J_A (x) I + I (x) J_B, e], [0, 0]] by closed_form._expm_triangular's steps."""
    cdef double complex Z[100]
    cdef double complex E[100]
    cdef double complex W[100]
    cdef double complex acc
    cdef int S = m * n + 1, i, l, q, a, b, s = 0, j, nt, k
    cdef double shift = 0.0, norm = 0.0, col, rho, t
    for i in range(S * S):
        Z[i] = 0.0
    for i in range(m * n):
        a, b = i // n, i % n
        Z[i * S + i] = A[a] + B[b]
        shift = max(shift, (A[a] + B[b]).real)
        if a + 1 < m:
            Z[i * S + i + n] = 1.0
        if b + 1 < n:
            Z[i * S + i + 1] = 1.0
    Z[(m * n - 1) * S + S - 1] = 1.0
    for i in range(S):
        Z[i * S + i] = Z[i * S + i] - shift
    for i in range(S * S):
        Z[i] = Z[i] * T
    for l in range(S):
        col = 0.0
        for i in range(l + 1):
            col += zabs(Z[i * S + l])
        norm = max(norm, col)
    while norm / (2.0 ** s) > 0.5:
        s += 1
    for i in range(S * S):
        Z[i] = Z[i] / (2.0 ** s)
    rho, j, t = norm / (2.0 ** s), 1, 1.0
    while j < 24 and t * rho > 1e-18:
        j += 1
        t *= rho / j
    nt = S - 1 + j
    for i in range(S * S):
        E[i] = Z[i] / nt
    for i in range(S):
        E[i * S + i] = E[i * S + i] + 1.0
    for k in range(nt - 1, 0, -1):
        for i in range(S):
            for l in range(i, S):
                acc = 0.0
                for q in range(i, l + 1):
                    acc = acc + Z[i * S + q] * E[q * S + l]
                W[i * S + l] = acc / k
        for i in range(S):
            for l in range(i, S):
                E[i * S + l] = W[i * S + l] + (1.0 if i == l else 0.0)
    for k in range(s):
        for i in range(S):
            for l in range(i, S):
                acc = 0.0
                for q in range(i, l + 1):
                    acc = acc + E[i * S + q] * E[q * S + l]
                W[i * S + l] = acc
        for i in range(S):
            for l in range(i, S):
                E[i * S + l] = W[i * S + l]
    return exp(shift * T) * E[S - 1]


cpdef void group_integrals(const double complex[::1] nu, const double complex[:, ::1] cols,
                           const long[::1] sizes, double T, double complex[:, ::1] Pe,
                           double complex[:, ::1] Pg):
    """closed_form.group_integrals: Pe[c, j] = int_0^T e^{nu_j s} F[X_c](s) ds and, when Pg has rows,
    Pg[c, d] = int_0^T F[X_c](s) F[X_d](s) ds for the columns X_c = cols[c, :sizes[c]] (at most 3 nodes)."""
    cdef Py_ssize_t Kt = cols.shape[0], p = nu.shape[0], c, dd, j, i
    cdef double complex x[4]
    cdef double complex v
    # the kernels hold at most 4 nodes (x, divided_exp_one) and 3 x 3 + 1 (product_integral) on the stack
    if sizes.shape[0] != Kt or Pe.shape[0] != Kt or Pe.shape[1] < p or not (
            Pg.shape[0] == 0 or (Pg.shape[0] == Kt and Pg.shape[1] == Kt)):
        raise ValueError("group_integrals: a size per column of nodes, Pe a row per column and an entry per "
                         "exponent, Pg none or one per pair of columns")
    for c in range(Kt):
        if not 1 <= sizes[c] <= 3 or sizes[c] > cols.shape[1]:
            raise ValueError("group_integrals: 1 to 3 nodes per column (within cols' row)")
    with nogil:
        for c in range(Kt):
            x[0] = 0.0
            for j in range(p):
                for i in range(sizes[c]):
                    x[i + 1] = cols[c, i] + nu[j]
                Pe[c, j] = divided_exp_one(x, <int> sizes[c] + 1, T)
        if Pg.shape[0]:
            for c in range(Kt):
                for dd in range(c, Kt):
                    v = product_integral(&cols[c, 0], <int> sizes[c], &cols[dd, 0], <int> sizes[dd], T)
                    Pg[c, dd] = v
                    Pg[dd, c] = v


# -- one call per phase: its set-up, and its state at the event ---------------------------------------

cdef class PhaseSetup:
    """A configuration's arrays for its phases' set-up (Configuration.kernel_arrays), held once per
    configuration so that a phase costs one call: :meth:`start` is phase_start then phase_modal (Phase.__init__
    and Phase._motion), :meth:`state` the state (q, q') at one time (Phase._xi_at, then q_map() @ xi and
    v_map() @ xi). ``layout`` gives where start's results lie in its one output buffer."""

    cdef const double[:, ::1] GpinvT, QT, BT, N, ViT, harmonic, V, den
    cdef const double[::1] f0
    cdef Py_ssize_t n, r, k, m, nmu, p, d
    cdef readonly tuple layout

    def __init__(self, GpinvT, QT, f0, BT, N, ViT=None, harmonic=None, V=None, den=None, Py_ssize_t k=0,
                 Py_ssize_t nmu=0, Py_ssize_t p=0):
        self.GpinvT, self.QT, self.f0, self.BT, self.N = GpinvT, QT, f0, BT, N
        self.n, self.r, self.k, self.nmu, self.p = QT.shape[0], N.shape[1], k, nmu, p
        self.m = self.d = 0
        if ViT is not None:
            self.ViT, self.harmonic, self.V, self.den = ViT, harmonic, V, den
            self.m, self.d = ViT.shape[1] // 2, V.shape[0]
        # (qp, f0, B f0, x0, z0, beta, c, g, U): their offsets in the buffer, then its size
        sizes = (self.n, self.n, 2 * self.r, 2 * self.r, 2 * self.m, 2 * self.nmu * self.m, 2 * self.m,
                 2 * self.nmu * self.m, 2 * (self.k + self.d) * self.p)
        offsets, at = [], 0
        for size in sizes:
            offsets.append(at)
            at += size
        self.layout = (*offsets, at)

    cpdef void start(self, const double[::1] g0, const double[::1] q0, const double[::1] v0, double w, double t0,
                     double[::1] out):
        """Phase.__init__'s set-up into ``out`` (``layout``): phase_start's (q_p, f0, B f0, x0), then with a
        modal plan phase_modal's (z0, beta, c, g, U; U's rigid rows left to ModalPlan.complete) with the
        phase e^{i w t0} as the reference forms it (numpy's exp of i w t0: the C library's cexp)."""
        cdef tuple lay = self.layout
        cdef Py_ssize_t o_qp = lay[0], o_f0 = lay[1], o_b = lay[2], o_x = lay[3], o_z = lay[4], o_beta = lay[5]
        cdef Py_ssize_t o_c = lay[6], o_g = lay[7], o_U = lay[8]
        cdef double ph_re = 0.0, ph_im = 0.0
        if out.shape[0] < lay[9]:
            raise ValueError(f"PhaseSetup.start: its output needs {lay[9]} entries (layout), got {out.shape[0]}")
        phase_start(self.GpinvT, g0, self.QT, self.f0, self.BT, self.N, q0, v0, out[o_qp: o_f0], out[o_f0: o_b],
                    out[o_b: o_x], out[o_x: o_z])
        if self.m == 0:
            return
        if w != 0.0:
            nsfem_cexp(0.0, w * t0, &ph_re, &ph_im)
        with nogil:
            modal_core(self.ViT, &out[o_b], &out[o_x], self.harmonic, ph_re, ph_im, self.k, self.V, self.den,
                       self.nmu, self.p, &out[o_z], &out[o_beta], &out[o_c], &out[o_g], &out[o_U])

    cpdef void state(self, const double[:, ::1] U, const double[::1] nu, double tau, const double[::1] qp,
                     double[::1] q, double[::1] v):
        """(q, q') at t0 + tau of a phase on the modal path without divided differences: x = Re(U e^{nu tau})
        as xi_at forms it, then q = N x[:r] + q_p, q' = N x[r:] (Phase.q_map() @ xi, v_map() @ xi; each entry
        one sum in the order of N's columns, BLAS's products round otherwise)."""
        cdef Py_ssize_t d = U.shape[0], p = nu.shape[0] // 2, n = self.n, r = self.r, i, j
        cdef double sq, sv
        cdef const double* row
        if n == 0:
            return
        if q.shape[0] < n or v.shape[0] < n or qp.shape[0] < n or d < 2 * r or U.shape[1] < 2 * p:
            raise ValueError("PhaseSetup.state: U needs the phase's 2 r state rows and a column pair per exponent, "
                             "q, q' and q_p the configuration's n coordinates")
        cdef double* e = <double*> malloc((2 * p + d + 1) * sizeof(double))
        if e == NULL:
            raise MemoryError("PhaseSetup.state: no memory for its work space")
        cdef double* x = e + 2 * p
        with nogil:
            for j in range(p):
                nsfem_cexp(nu[2 * j] * tau, nu[2 * j + 1] * tau, &e[2 * j], &e[2 * j + 1])
            if d:
                modal_rows(&U[0, 0], 2 * p, 0, d, 1, e, &e[1], 2, p, x)
            for i in range(n):
                row = &self.N[i, 0]
                sq = 0.0
                sv = 0.0
                for j in range(r):
                    sq = sq + row[j] * x[j]
                    sv = sv + row[j] * x[r + j]
                q[i] = sq + qp[i]
                v[i] = sv
        free(e)
