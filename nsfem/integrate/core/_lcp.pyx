# cython: language_level=3
"""Compiled kernels of Lemke's method (nsfem/lcp/pivoting.py holds the Python reference of each:
the function named in each docstring; nsfem/lcp/compiled.py drives them; tests/test_core_lcp.py
compares both paths).

Arrays in, numbers out: the caller allocates every array (C order, float64; int64 for indices) and
the kernels write into them. Dense loops in plain C (no BLAS): their sums run left to right from
0.0, where the reference's BLAS may group and fuse them differently, so values agree to round-off,
not bitwise (the one-unknown path and the equilibration, which use no BLAS, agree bitwise).
"""

from libc.math cimport sqrt, fabs, isnan, isfinite, INFINITY, NAN
from libc.stdlib cimport malloc, free

ctypedef long long i64

#: the reference's constants (nsfem/lcp/pivoting.py: TIE, NEAR_TIE, ACCEPT, FLOOR, REFINE_STEPS)
cdef double TIE = 1e-15
cdef double NEAR_TIE = 1e-6
cdef double ACCEPT = 1e-8
cdef double FLOOR = 1e-10
cdef int REFINE_STEPS = 3
cdef double EPS = 2.220446049250313e-16
cdef double TINY = 2.2250738585072014e-308

cdef enum:
    C_DONE = 0          # z0 left the basis: a complementary basis
    C_RAY = 1           # the entering column has no positive entry (secondary ray)
    C_Z0_TIE = 2        # z0 ties for leaving: the caller tries the complementary basis it leaves behind
    C_MAX_PIVOTS = 3    # the pivot limit
    C_REFACTOR = 4      # the basis inverse is due to be recomputed (the caller does it, as the reference)
    C_FINISHED = 0      # (polished) a point, polished or kept
    C_NEEDS_SVD = 1     # (polished) the basis matrix is singular to working precision: the reference's SVD path

#: what :func:`pivot` stopped on, and what :func:`polished` did (the codes above)
DONE, RAY, Z0_TIE, MAX_PIVOTS, REFACTOR = C_DONE, C_RAY, C_Z0_TIE, C_MAX_PIVOTS, C_REFACTOR
FINISHED, NEEDS_SVD = C_FINISHED, C_NEEDS_SVD


# ----------------------------------------------------------------------------------------------------------
# scaling and input checks

def all_finite(const double[:, :] A, const double[::1] b):
    """Whether every entry of A and b is finite (lemke's input check)."""
    cdef Py_ssize_t i, j
    for i in range(A.shape[0]):
        for j in range(A.shape[1]):
            if not isfinite(A[i, j]):
                return False
    for i in range(b.shape[0]):
        if not isfinite(b[i]):
            return False
    return True


def equilibrate(const double[:, ::1] A, double[::1] r, double[::1] c, int sweeps=8):
    """pivoting._equilibrate: Ruiz's row and column scalings of A written to r and c (bitwise the
    reference's: maxima, correctly rounded square roots and products in the same order)."""
    cdef Py_ssize_t n = A.shape[0], i, j
    cdef double* S = <double*> malloc((n * n + 2 * n + 1) * sizeof(double))
    cdef double* fr = S + n * n
    cdef double* fc = fr + n
    cdef double v
    cdef bint unit
    cdef int sweep
    if S == NULL:
        raise MemoryError()
    for i in range(n):
        r[i] = 1.0
        c[i] = 1.0
        for j in range(n):
            S[i * n + j] = fabs(A[i, j])
    for sweep in range(sweeps):
        for i in range(n):
            fr[i] = 0.0
            fc[i] = 0.0
        for i in range(n):
            for j in range(n):
                v = S[i * n + j]
                if v > fr[i]:
                    fr[i] = v
                if v > fc[j]:
                    fc[j] = v
        unit = True
        for i in range(n):
            fr[i] = 1.0 / sqrt(fr[i]) if fr[i] > 0 else 1.0
            fc[i] = 1.0 / sqrt(fc[i]) if fc[i] > 0 else 1.0
            if fr[i] != 1.0 or fc[i] != 1.0:
                unit = False
        if unit:
            break   # a fixed point
        for i in range(n):
            r[i] *= fr[i]
            c[i] *= fc[i]
        for i in range(n):
            for j in range(n):
                S[i * n + j] = fr[i] * S[i * n + j] * fc[j]
    free(S)


def scaled_size(const double[:, ::1] A, const double[::1] b, const double[::1] r, const double[::1] c):
    """max r * max(max|A| * max c, max|b|): lemke's test that the equilibrated problem stays finite."""
    cdef Py_ssize_t n = b.shape[0], i, j
    cdef double rm = -INFINITY, cm = -INFINITY, am = -INFINITY, bm = 0.0, t
    for i in range(n):
        rm = max(rm, r[i])
        cm = max(cm, c[i])
        bm = max(bm, fabs(b[i]))
        for j in range(n):
            am = max(am, fabs(A[i, j]))
    t = am * cm
    return rm * (t if not bm > t else bm)


def scale(const double[:, ::1] A, const double[::1] b, const double[::1] r, const double[::1] c,
          double[:, ::1] As, double[::1] bs):
    """As = R A C, bs = R b (lemke's equilibrated problem, products in the reference's order)."""
    cdef Py_ssize_t n = b.shape[0], i, j
    for i in range(n):
        bs[i] = r[i] * b[i]
        for j in range(n):
            As[i, j] = r[i] * A[i, j] * c[j]


# ----------------------------------------------------------------------------------------------------------
# the certificate

cdef void residual(const double* A, const double* b, const double* x, double* w, Py_ssize_t n) noexcept nogil:
    """w = A x + b (row-major A)."""
    cdef Py_ssize_t i, j
    cdef double s
    for i in range(n):
        s = 0.0
        for j in range(n):
            s = s + A[i * n + j] * x[j]
        w[i] = s + b[i]


cdef double nan_min0(const double* v, Py_ssize_t n) noexcept nogil:
    """min(0.0, numpy's v.min()): 0.0 when v holds a nan."""
    cdef double lo = INFINITY
    cdef Py_ssize_t i
    for i in range(n):
        if isnan(v[i]):
            return 0.0
        if v[i] < lo:
            lo = v[i]
    return lo if lo < 0.0 else 0.0


cdef void certify(const double* A, const double* b, const double* x, const double* w, const double* r,
                  const double* c, const i64* gid, Py_ssize_t n, double* sw, double* out) noexcept nogil:
    """pivoting._certificate of x (w = A x + b given): out = (x_min, w_min, complementarity, relative);
    ``gid`` (or NULL) labels the rows' groups. ``sw`` is work space of n."""
    cdef Py_ssize_t i, j
    cdef double s, top, floor, sx, e, f, m, rel, xmin, wmin, comp
    cdef bint finite = True
    if n == 0:
        out[0] = 0.0
        out[1] = 0.0
        out[2] = 0.0
        out[3] = 0.0
        return
    for i in range(n):
        if not (isfinite(x[i]) and isfinite(w[i])):
            finite = False
    if not finite:   # numpy's min and max of x, w and |x w|: a nan wins (then min(0.0, nan) is 0.0)
        out[0] = nan_min0(x, n)
        out[1] = nan_min0(w, n)
        comp = 0.0
        for i in range(n):
            m = fabs(x[i] * w[i])
            if isnan(m):
                comp = NAN
                break
            if m > comp or i == 0:
                comp = m
        out[2], out[3] = comp, NAN
        return
    xmin, wmin, comp = 0.0, 0.0, 0.0
    for i in range(n):
        s = 0.0
        for j in range(n):
            s = s + fabs(A[i * n + j]) * fabs(x[j])
        sw[i] = fabs(b[i]) + s
    if gid != NULL:   # a row is judged against the largest terms of its group (in place: the maxima stay)
        for i in range(n):
            top = sw[i]
            for j in range(n):
                if gid[j] == gid[i] and sw[j] > top:
                    top = sw[j]
            sw[i] = top
    floor = -INFINITY
    for i in range(n):
        if r[i] * sw[i] > floor:
            floor = r[i] * sw[i]
    floor = FLOOR * floor
    sx = 0.0
    for i in range(n):
        if floor / r[i] > sw[i]:
            sw[i] = floor / r[i]
        e = fabs(x[i] / c[i])
        if e > sx:
            sx = e
    if not sx > TINY:
        sx = TINY
    rel = 0.0
    for i in range(n):
        e = (x[i] / c[i]) / sx
        f = w[i] / (sw[i] if sw[i] > 0 else 1.0)
        m = fabs(f if f < e else e)
        if m > rel or i == 0:
            rel = m
        if x[i] < xmin:
            xmin = x[i]
        if w[i] < wmin:
            wmin = w[i]
        m = fabs(x[i] * w[i])
        if m > comp or i == 0:
            comp = m
    out[0], out[1], out[2], out[3] = xmin, wmin, comp, rel


def certificate(const double[:, ::1] A, const double[::1] b, const double[::1] x, const double[::1] w,
                const double[::1] r, const double[::1] c, const i64[::1] gid):
    """pivoting._certificate of x with w = A x + b given: (x_min, w_min, complementarity, relative);
    ``gid`` holds one integer label per row, or is empty (row by row)."""
    cdef Py_ssize_t n = b.shape[0]
    cdef double out[4]
    cdef double* sw
    if n == 0:
        return 0.0, 0.0, 0.0, 0.0
    sw = <double*> malloc(n * sizeof(double))
    if sw == NULL:
        raise MemoryError()
    certify(&A[0, 0], &b[0], &x[0], &w[0], &r[0], &c[0], &gid[0] if gid.shape[0] else NULL, n, sw, out)
    free(sw)
    return out[0], out[1], out[2], out[3]


# ----------------------------------------------------------------------------------------------------------
# the polish: LU with partial pivoting and refinement

cdef bint lu(double* B, Py_ssize_t m, Py_ssize_t* piv) noexcept nogil:
    """B = P L U in place (unit lower L below the diagonal, U on and above; piv: the row swaps, as
    getrf's); False where a pivot is at or below eps of B's largest entry (the reference's test that
    sends the solve to the SVD)."""
    cdef Py_ssize_t i, j, k, p
    cdef double big = 0.0, small, t, l
    for i in range(m * m):
        if fabs(B[i]) > big:
            big = fabs(B[i])
    small = EPS * (big if big > 1e-300 else 1e-300)
    for k in range(m):
        p = k
        for i in range(k + 1, m):
            if fabs(B[i * m + k]) > fabs(B[p * m + k]):
                p = i
        piv[k] = p
        if p != k:
            for j in range(m):
                t = B[k * m + j]
                B[k * m + j] = B[p * m + j]
                B[p * m + j] = t
        if not fabs(B[k * m + k]) > small:
            return False
        for i in range(k + 1, m):
            l = B[i * m + k] / B[k * m + k]
            B[i * m + k] = l
            for j in range(k + 1, m):
                B[i * m + j] = B[i * m + j] - l * B[k * m + j]
    return True


cdef void lu_solve(const double* LU, const Py_ssize_t* piv, Py_ssize_t m, double* v) noexcept nogil:
    """v := B^-1 v from :func:`lu` (getrs)."""
    cdef Py_ssize_t i, j
    cdef double t
    for i in range(m):
        if piv[i] != i:
            t = v[i]
            v[i] = v[piv[i]]
            v[piv[i]] = t
    for i in range(m):
        t = v[i]
        for j in range(i):
            t = t - LU[i * m + j] * v[j]
        v[i] = t
    for i in range(m - 1, -1, -1):
        t = v[i]
        for j in range(i + 1, m):
            t = t - LU[i * m + j] * v[j]
        v[i] = t / LU[i * m + i]


cdef int refined_solve(const double* B, const double* rhs, double* x, bint start, Py_ssize_t m, double* work,
                       Py_ssize_t* piv) noexcept nogil:
    """pivoting._refined_solve, in place from the start x when ``start``, else from the LU solve: C_FINISHED,
    C_NEEDS_SVD (B singular to working precision) or -1 (x not finite: no solution). ``work``: 2 m^2 + 2 m
    doubles."""
    cdef double* LU = work
    cdef double* r = work + m * m
    cdef double* dx = r + m
    cdef Py_ssize_t i, j, step
    cdef double s, size, now, worst = INFINITY
    cdef bint finite
    for i in range(m * m):
        LU[i] = B[i]
    if not lu(LU, m, piv):
        return C_NEEDS_SVD
    if not start:
        for i in range(m):
            x[i] = rhs[i]
        lu_solve(LU, piv, m, x)
    for i in range(m):
        if not isfinite(x[i]):
            return -1
    for step in range(REFINE_STEPS + 1):
        now = 0.0
        for i in range(m):
            s = 0.0
            size = 0.0
            for j in range(m):
                s = s + B[i * m + j] * x[j]
                size = size + fabs(B[i * m + j]) * fabs(x[j])
            r[i] = rhs[i] - s
            size = size + fabs(rhs[i])
            s = fabs(r[i]) / (size if size > 0 else 1.0)
            if isnan(s) or isnan(now):
                now = NAN
            elif s > now:
                now = s
        if not now < worst or now <= 4 * EPS:
            break
        worst = now
        for i in range(m):
            dx[i] = r[i]
        lu_solve(LU, piv, m, dx)
        finite = True
        for i in range(m):
            if not isfinite(dx[i]):
                finite = False
        if not finite:
            break
        for i in range(m):
            x[i] = x[i] + dx[i]
    return C_FINISHED


cdef int polish(const double* A, const double* b, const double* As, const double* bs, const double* r,
                const double* c, const i64* basis, const double* xB, const i64* gid, Py_ssize_t n, double* x,
                double* w, double* cert, double* mem, Py_ssize_t* S) noexcept nogil:
    """pivoting._polish_certified of the complementary ``basis``: A_SS x_S = -b_S solved (equilibrated) and
    refined, from the pivoting's x_B when given (then the better certified of the two points is kept), else
    from the LU solve; the point in x, A x + b in w, its certificate in cert. Returns C_FINISHED, C_NEEDS_SVD
    (the reference's SVD path decides) or -1 (no finite point from the solve alone: the reference's None).
    ``mem``: 2 n^2 + 8 n doubles, ``S``: 2 n."""
    cdef Py_ssize_t m = 0, i, j, v
    cdef double cy[4]
    cdef int code = C_FINISHED
    cdef bint finite = True
    cdef double* B = mem                      # A_SS, equilibrated
    cdef double* rhs = B + n * n              # -bs_S
    cdef double* xs = rhs + n                 # x_S / c_S, refined
    cdef double* y = xs + n                   # the polished point
    cdef double* wy = y + n
    cdef double* sw = wy + n
    cdef double* work = sw + n                # 2 m^2 + 2 m
    cdef Py_ssize_t* piv = S + n
    for i in range(n):
        x[i] = 0.0
        y[i] = 0.0
        S[i] = 0
    for i in range(n):
        v = basis[i]
        if n <= v < 2 * n:
            if xB != NULL:
                x[v - n] = xB[i]
            S[v - n] = 1
    for j in range(n):
        x[j] = x[j] * c[j]
        if S[j]:
            S[m] = j      # ascending: sorted(...)
            m += 1
    if m:
        for i in range(m):
            for j in range(m):
                B[i * m + j] = As[S[i] * n + S[j]]
            rhs[i] = -bs[S[i]]
            xs[i] = x[S[i]] / c[S[i]]
        code = refined_solve(B, rhs, xs, xB != NULL, m, work, piv)
        if code == C_FINISHED:
            for i in range(m):
                y[S[i]] = c[S[i]] * xs[i]
    if code == C_FINISHED:
        for i in range(n):
            if not isfinite(y[i]):
                finite = False
    if xB == NULL and (code != C_FINISHED or not finite):
        return code if code == C_NEEDS_SVD else -1
    if xB != NULL:
        residual(A, b, x, w, n)
        certify(A, b, x, w, r, c, gid, n, sw, cert)
        if code == C_NEEDS_SVD:
            return code
    if code == C_FINISHED and finite:
        for i in range(n):
            y[i] = y[i] if y[i] > 0.0 else 0.0
        residual(A, b, y, wy, n)
        certify(A, b, y, wy, r, c, gid, n, sw, cy)
        if xB == NULL or cy[3] <= cert[3]:
            for i in range(n):
                x[i] = y[i]
                w[i] = wy[i]
            for i in range(4):
                cert[i] = cy[i]
    return C_FINISHED


def polished(const double[:, ::1] A, const double[::1] b, const double[:, ::1] As, const double[::1] bs,
             const double[::1] r, const double[::1] c, i64[::1] basis, xB, i64 entering,
             const i64[::1] gid, double[::1] x):
    """The point of a complementary basis written to x (see :func:`polish`): the basis at the end of the
    pivoting (``xB`` its values, the point kept then the better certified of x_B and its polish), or, with
    ``xB`` None, the basis with ``entering`` in place of z0 (pivoting._z0_tie's trial, solved afresh).
    Returns FINISHED, NEEDS_SVD (the reference's polish decides) or -1 (the trial has no finite point)."""
    cdef Py_ssize_t n = b.shape[0], i, zrow = 0
    cdef double cert[4]
    cdef double* w = <double*> malloc((n + 1) * sizeof(double))
    cdef const double[::1] xv
    cdef int code
    cdef const i64* g = &gid[0] if gid.shape[0] else NULL
    cdef const double* xp = NULL
    cdef i64 saved = 0
    cdef double* mem = <double*> malloc((2 * n * n + 8 * n + 1) * sizeof(double))
    cdef Py_ssize_t* S = <Py_ssize_t*> malloc((2 * n + 1) * sizeof(Py_ssize_t))
    if mem == NULL or S == NULL or w == NULL:
        free(mem)
        free(S)
        free(w)
        raise MemoryError()
    if xB is not None:
        xv = xB
        xp = &xv[0]
    else:
        while zrow < n and basis[zrow] != 2 * n:
            zrow += 1
        if zrow == n:   # no z0 in the basis: no trial
            free(mem)
            free(S)
            free(w)
            return -1
        saved = basis[zrow]
        basis[zrow] = entering
    with nogil:
        code = polish(&A[0, 0], &b[0], &As[0, 0], &bs[0], &r[0], &c[0], &basis[0], xp, g, n, &x[0], w, cert,
                      mem, S)
    if xB is None:
        basis[zrow] = saved
    free(mem)
    free(S)
    free(w)
    return code


# ----------------------------------------------------------------------------------------------------------
# the pivoting

cdef Py_ssize_t lexmin(const double* xB, const double* Binv, const double* div, Py_ssize_t* cand,
                       Py_ssize_t nc, Py_ssize_t n) noexcept nogil:
    """pivoting._lexmin over the rows [xB_t, Binv_t] / div_t of the candidates t (overwritten): the
    lexicographically smallest, columns compared in turn; equal to the least, or finite and within 16 TIE of
    it, ties; a column holding a nan keeps the first candidate."""
    cdef Py_ssize_t k, i, t, keep
    cdef double lo, val, a
    for k in range(n + 1):
        lo = INFINITY
        for i in range(nc):
            t = cand[i]
            val = (xB[t] if k == 0 else Binv[t * n + k - 1]) / div[t]
            if isnan(val):
                lo = NAN   # as numpy's min
                break
            if val < lo or i == 0:
                lo = val
        keep = 0
        for i in range(nc):
            t = cand[i]
            val = (xB[t] if k == 0 else Binv[t * n + k - 1]) / div[t]
            a = fabs(val)
            if val == lo or (isfinite(val) and val <= lo + 16 * TIE * (a if a > fabs(lo) else fabs(lo))):
                cand[keep] = t
                keep += 1
        nc = keep if keep else 1   # (none kept: the first candidate, still in cand[0])
        if nc == 1:
            break
    return cand[0]


def pivot(const double[:, ::1] As, const double[::1] dv, double[:, ::1] Binv, double[::1] xB,
          i64[::1] basis, double[::1] c, i64[::1] st, i64 max_pivots, i64 refactor, double pivot_tol,
          bint uniform):
    """The pivoting loop of pivoting.lemke on the equilibrated (As, dv) from the state (Binv, xB, basis;
    st = [entering, pivots, since_refactor, skip_tie]) until it stops: C_DONE, C_RAY, C_Z0_TIE (the caller tries
    the complementary basis z0 leaves behind, and resumes with skip_tie = 1 when it fails), C_MAX_PIVOTS or
    C_REFACTOR (the caller recomputes Binv and xB, sets since_refactor = 0 and resumes). The state is updated
    in place; c holds the last entering column. ``uniform``: d = 1 (the first pivot's tie rule on b)."""
    cdef Py_ssize_t n = xB.shape[0], z0 = 2 * n, i, j, k, r = 0, nt, zrow, leaving
    cdef i64 entering = st[0], pivots = st[1], since = st[2]
    cdef bint skip = st[3] != 0, bad
    cdef double tol, cmax, theta, q, p, lo, s, a
    cdef int code
    cdef Py_ssize_t* ties = <Py_ssize_t*> malloc((n + 1) * sizeof(Py_ssize_t))
    cdef double* row = <double*> malloc((n + 1) * sizeof(double))
    cdef double* B = &Binv[0, 0]
    if ties == NULL or row == NULL:
        free(ties)
        free(row)
        raise MemoryError()
    st[3] = 0
    with nogil:
        while True:
            # the entering column B^-1 a (z0 enters only first, against B = I: -d exactly)
            if entering == z0:
                for i in range(n):
                    c[i] = -dv[i]
            elif entering < n:
                for i in range(n):
                    c[i] = B[i * n + entering]
            else:
                j = entering - n
                for i in range(n):
                    s = 0.0
                    for k in range(n):
                        s = s + B[i * n + k] * -As[k, j]
                    c[i] = s
            if pivots > 0:
                # ratio test (pivoting._ratio_test)
                cmax = 0.0
                bad = False
                for i in range(n):
                    if isnan(c[i]):
                        bad = True
                    elif fabs(c[i]) > cmax:
                        cmax = fabs(c[i])
                if bad:
                    code = C_RAY
                    break
                tol = pivot_tol * (cmax if cmax > 1e-300 else 1e-300)
                nt = 0
                theta = INFINITY
                for i in range(n):
                    if c[i] > tol:
                        q = xB[i] / c[i]
                        if nt == 0 or q < theta:
                            theta = q
                        nt += 1
                if nt == 0:
                    code = C_RAY
                    break
                if not skip:   # (z0 is basic until it leaves; the bound guards a caller's state)
                    zrow = 0
                    while zrow < n and basis[zrow] != z0:
                        zrow += 1
                    if zrow < n and c[zrow] > tol and xB[zrow] / c[zrow] <= theta * (1.0 + NEAR_TIE):
                        code = C_Z0_TIE
                        break
                skip = False
                nt = 0
                for i in range(n):
                    if c[i] > tol:
                        q = xB[i] / c[i]
                        if q == theta or q <= theta + TIE * fabs(theta):
                            ties[nt] = i
                            nt += 1
                if nt == 0:   # a nan ratio (overflowed data): the first row
                    i = 0
                    while i < n - 1 and not c[i] > tol:
                        i += 1
                    ties[0] = i
                    nt = 1
                r = ties[0] if nt == 1 else lexmin(&xB[0], B, &c[0], ties, nt, n)
            elif uniform:
                # the rows [b_i, e_i] tied on b_i are told apart by e_i: the last of them is the smallest
                lo = INFINITY
                for i in range(n):
                    if xB[i] < lo or i == 0:
                        lo = xB[i]
                for i in range(n):
                    a = fabs(xB[i])
                    if xB[i] <= lo + 16 * TIE * (a if a > fabs(lo) else fabs(lo)):
                        r = i
            else:
                for i in range(n):
                    ties[i] = i
                r = lexmin(&xB[0], B, &dv[0], ties, n, n)
            # pivot on (r, entering)
            p = c[r]
            for j in range(n):
                B[r * n + j] = B[r * n + j] / p
                row[j] = B[r * n + j]
            xB[r] = xB[r] / p
            for i in range(n):
                if i == r:
                    continue
                q = c[i]
                for j in range(n):
                    B[i * n + j] = B[i * n + j] - q * row[j]
                xB[i] = xB[i] - q * xB[r]
            leaving = basis[r]
            basis[r] = entering
            pivots += 1
            since += 1
            for i in range(n):
                if xB[i] < 0.0:
                    xB[i] = 0.0
            if leaving == z0:
                code = C_DONE
                break
            if pivots >= max_pivots:
                code = C_MAX_PIVOTS
                break
            entering = leaving + n if leaving < n else leaving - n
            if since >= refactor:
                code = C_REFACTOR
                break
    st[0], st[1], st[2] = entering, pivots, since
    free(ties)
    free(row)
    return code


# ----------------------------------------------------------------------------------------------------------
# one unknown

cdef bint solve_one(double B, double rhs, double* x) noexcept nogil:
    """pivoting._solve_one from the start x (bitwise: the same operations in the same order); False where
    the reference returns None."""
    cdef double worst = INFINITY, res, size, now, dx, y = x[0]
    cdef int step
    if not fabs(B) > EPS * (fabs(B) if fabs(B) > 1e-300 else 1e-300):
        return False
    if not isfinite(y):
        return False
    for step in range(REFINE_STEPS + 1):
        res = rhs - (0.0 + B * y)
        size = (0.0 + fabs(B) * fabs(y)) + fabs(rhs)
        now = fabs(res) / (size if size > 0 else 1.0)
        if not now < worst or now <= 4 * EPS:
            break
        worst = now
        dx = res / B
        if not isfinite(dx):
            break
        y = y + dx
    x[0] = y
    return True


cdef tuple result_one(double a, double b, double c, double r, double x):
    """pivoting._result_one's numbers: (x, w, x_min, w_min, complementarity, relative)."""
    cdef double w = (0.0 + a * x) + b, xs = x / c, sw = fabs(b) + (0.0 + fabs(a) * fabs(x))
    cdef double floor = FLOOR * (r * sw) / r, e, f
    sw = sw if sw > floor else floor
    sw = sw if sw > 0 else 1.0
    e = xs / (fabs(xs) if fabs(xs) > TINY else TINY)
    f = w / sw
    return x, w, (x if x < 0.0 else 0.0), (w if w < 0.0 else 0.0), fabs(x * w), fabs(e if e < f else f)


def lemke_one(double a, double b, double r, double c, double dv, double pivot_tol):
    """pivoting._lemke_one: (pivots, x, w, x_min, w_min, complementarity, relative) of LCP(a, b), bitwise the
    reference's, or None where the general loop takes another branch."""
    cdef double s, col, x, y
    cdef tuple res
    if b >= 0.0:
        return (0,) + result_one(a, b, c, r, 0.0)
    s = r * a * c
    if not isfinite(r * b / -dv):
        return None
    col = 0.0 + (1.0 / -dv) * -s
    if not col > pivot_tol * (fabs(col) if fabs(col) > 1e-300 else 1e-300):
        return None
    if not fabs(s) > EPS * (fabs(s) if fabs(s) > 1e-300 else 1e-300):
        return None
    x = -r * b / s
    if not solve_one(s, -r * b, &x) or not isfinite(c * x):
        return None
    y = c * x
    res = result_one(a, b, c, r, y if y > 0.0 else 0.0)
    return (2,) + res if res[5] <= ACCEPT else None
