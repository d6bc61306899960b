# cython: language_level=3
"""The event search of one phase, compiled (issue 33): :class:`Search` runs events.first_event's loop
after its set-up on the modal path (divided differences included), with the kernels it is made of
(the screen, the Hermite cubic's minimum and envelope, the roots, the divided differences). The
Python functions in nsfem/integrate/events.py and closed_form.py are the reference of each, under
the name given in its docstring; tests/test_core_search.py and tests/test_core_equivalence.py
compare the two paths."""

from libc.math cimport (sqrt, fabs, copysign, frexp, ldexp, exp, expm1, log, cos, sin, pow, ceil, hypot, isfinite,
                        isinf, INFINITY, M_PI)
from libc.float cimport DBL_EPSILON
from libc.stdlib cimport malloc, calloc, free, realloc
from cpython.exc cimport PyErr_CheckSignals

cdef extern from *:
    """
    #if defined(__GLIBC__)
    #define nsfem_sincos sincos   /* glibc's: sin(x) and cos(x) at once, the same values */
    #else
    static void nsfem_sincos(double x, double* s, double* c) { *s = sin(x); *c = cos(x); }
    #endif
    """
    void sincos "nsfem_sincos" (double x, double* s, double* c) nogil

cdef extern from *:
    """
    /* Many independent sums side by side, four lanes at a time (GCC's vector extensions: each lane's
       operations are the scalar ones, no contraction: -ffp-contract=off), in an AVX2 clone where the CPU
       has it (GCC on glibc: the clone is chosen at load time; each lane rounds as the scalar code, the
       same value whichever clone runs). */
    #if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__GLIBC__) \
        && defined(__has_attribute)
    #  if __has_attribute(target_clones)
    #    define NSFEM_CLONES __attribute__((target_clones("avx2", "default")))
    #  endif
    #endif
    #ifndef NSFEM_CLONES
    #  define NSFEM_CLONES
    #endif
    #if defined(__GNUC__)
    typedef double nsfem_v4 __attribute__((vector_size(32)));
    /* x[j] = x[j] + (a * u[j] - b * v[j]), j < n (n a multiple of 4) */
    NSFEM_CLONES static void nsfem_lanes_add(double* x, const double* u, const double* v, double a, double b, int n) {
        nsfem_v4 va = {a, a, a, a}, vb = {b, b, b, b}, xv, uv, vv;
        for (int j = 0; j < n; j += 4) {
            __builtin_memcpy(&xv, x + j, sizeof xv);
            __builtin_memcpy(&uv, u + j, sizeof uv);
            __builtin_memcpy(&vv, v + j, sizeof vv);
            xv = xv + (va * uv - vb * vv);
            __builtin_memcpy(x + j, &xv, sizeof xv);
        }
    }
    /* x[j] = x[j] + a * u[j], j < n (n a multiple of 4) */
    NSFEM_CLONES static void nsfem_lanes_axpy(double* x, const double* u, double a, int n) {
        nsfem_v4 va = {a, a, a, a}, xv, uv;
        for (int j = 0; j < n; j += 4) {
            __builtin_memcpy(&xv, x + j, sizeof xv);
            __builtin_memcpy(&uv, u + j, sizeof uv);
            xv = xv + va * uv;
            __builtin_memcpy(x + j, &xv, sizeof xv);
        }
    }
    #else
    static void nsfem_lanes_axpy(double* x, const double* u, double a, int n) {
        for (int j = 0; j < n; j++) x[j] = x[j] + a * u[j];
    }
    static void nsfem_lanes_add(double* x, const double* u, const double* v, double a, double b, int n) {
        for (int j = 0; j < n; j++) x[j] = x[j] + (a * u[j] - b * v[j]);
    }
    #endif
    """
    void lanes_add "nsfem_lanes_add" (double* x, const double* u, const double* v, double a, double b, int n) nogil
    void lanes_axpy "nsfem_lanes_axpy" (double* x, const double* u, double a, int n) nogil

import numpy as np

#: as events.SUBDIVIDE, DEPTH, FIRST_CHUNK, CHUNK
cdef int SUBDIVIDE = 16, DEPTH = 3, FIRST_CHUNK = 4, CHUNK = 256
#: as events.ZERO (a row's band relative to the terms that make it)
cdef double ZERO = 1e-11
#: as events.COARSE, COARSE_GAIN (the coarse pass's budget per row's size, and its least gain)
cdef double COARSE = 1e-3, COARSE_GAIN = 4.0
#: as events.SLOPE (Birkhoff and Priver's slope bound in units of bound4)
cdef double SLOPE = 384.0 * sqrt(3.0) / 216.0
#: as first_event: at most this many arming candidates per row and chunk
cdef int ARM_CANDIDATES = 64
#: remembered (t, h, h', h'') per row (events._Row._memo)
cdef int MEMO = 8
#: as events.MAXITER (Newton steps of a root), events.SAFE (the quadratic's scaling range)
cdef int MAXITER = 200
cdef double SAFE_HI = 2.0 ** 400
cdef double SAFE_LO = 2.0 ** -400


include "_modal_sum.pxi"
include "_search_kernels.pxi"
include "_search_divided.pxi"


cdef class _Terms:
    """Rows t -> Re(C e^{nu (t - t0)}) + their harmonic part (events' rows_at, _Row.samples: the
    closed form's Motion.evaluate with Phase._harmonics), C's rows j < k those of H, the others Hd's
    (or xi's modal part: then C is U). The exponents come first, then the divided differences.

    A conjugate pair of exponents (an underdamped mode's two roots, the forcing's e^{+-iwt}; equal but
    for the sign of the imaginary part, bit for bit) is summed once: Re(c e^{nu tau}) + Re(c' e^{nu*
    tau}) = Re((c + conj(c')) e^{nu tau}), exactly in exact arithmetic whatever c and c' (the real
    part of a conjugate is the same); only where the sum rounds changes. ``C`` keeps the columns
    summed (R x nact, interleaved complex; a pair's combined); without coefficients given, the
    pairs are ``like``'s and C is formed by the owner (the full rows, per row when first sampled)."""
    cdef const double complex[::1] nu      # the exponents (pe of them)
    cdef const double complex[:, ::1] gnodes   # the K divided differences: their nodes (K x 3)
    cdef const int[::1] gm                 # and how many of the 3 each has (2 or 3)
    cdef double* C
    cdef int* act                          # the terms summed (indices into exponents, then K)
    cdef int* partner                      # per term summed: its conjugate's index, or -1
    cdef int pe, K, p, R, nact

    def __cinit__(self):
        self.C = NULL
        self.act = NULL
        self.partner = NULL

    def __dealloc__(self):
        free(self.C)
        free(self.act)
        free(self.partner)

    def __init__(self, nu, gnodes, gm, C, int R, _Terms like=None, keep=None):
        cdef const double complex[:, ::1] Cv
        cdef const char[::1] kept
        cdef const char* flags = NULL
        cdef const double* src = NULL
        if keep is not None:
            kept = keep
            if kept.shape[0] != len(nu):
                raise ValueError("Search: a kept term's flag per exponent")
            flags = &kept[0] if kept.shape[0] else NULL
        if C is not None:
            Cv = C
            if Cv.shape[0] != R or Cv.shape[1] != len(nu) + len(gm):
                raise ValueError("Search: the coefficients need a row per row and a column per term")
            src = <const double*>&Cv[0, 0] if Cv.shape[0] * Cv.shape[1] else NULL
        self._set(nu, gnodes, gm, src, C is not None, R, like, flags)

    cdef void _set(self, const double complex[::1] nu, const double complex[:, ::1] gnodes, const int[::1] gm,
                   const double* C, bint given, int R, _Terms like, const char* keep) except *:
        """The terms of exponents nu and divided differences (gnodes, gm) with the coefficients C (R rows
        of p interleaved complex: exponents, then divided differences; ``given`` False: none, formed by
        the owner) paired as ``like``'s (or afresh), those ``keep`` flags (NULL: all)."""
        cdef int idx, r, m, j
        self.nu, self.gnodes, self.gm = nu, gnodes, gm
        self.pe, self.K = self.nu.shape[0], self.gm.shape[0]
        self.p = self.pe + self.K
        self.R = R
        # the kernels read 3 nodes per divided difference and, from ``like``, its pairs of these exponents
        if self.gnodes.shape[0] != self.K or (self.K and self.gnodes.shape[1] != 3):
            raise ValueError("Search: the divided differences need 3 nodes each (2 or 3 used)")
        for m in range(self.K):
            if self.gm[m] != 2 and self.gm[m] != 3:
                raise ValueError("Search: the divided differences need 3 nodes each (2 or 3 used)")
        if like is not None and (like.pe != self.pe or like.K != self.K):
            raise ValueError("Search: terms paired as another set's take the same exponents")
        if not given and like is None:
            raise ValueError("Search: terms without coefficients take another set's pairs of the same exponents")
        self.act = <int*>malloc(max(self.p, 1) * sizeof(int))
        self.partner = <int*>malloc(max(self.p, 1) * sizeof(int))
        if self.act == NULL or self.partner == NULL:
            raise MemoryError
        if like is None or not self._pairs_of(like, keep):
            self._pair(keep)
        self.C = <double*>malloc(max(2 * R * self.nact, 1) * sizeof(double))
        if self.C == NULL:
            raise MemoryError
        cdef const double* src
        cdef double* dst
        cdef int p = self.p, n = self.nact
        if given and R * p:
            for r in range(R):
                src, dst = &C[2 * r * p], &self.C[2 * r * n]
                for idx in range(n):
                    m, j = self.act[idx], self.partner[idx]
                    if j < 0:
                        dst[2 * idx], dst[2 * idx + 1] = src[2 * m], src[2 * m + 1]
                    else:   # c + conj(c')
                        dst[2 * idx], dst[2 * idx + 1] = src[2 * m] + src[2 * j], src[2 * m + 1] - src[2 * j + 1]

    cdef bint _pairs_of(self, _Terms like, const char* keep):
        """act, partner, nact: ``like``'s pairs, those ``keep`` flags (all without it; a divided difference
        always): the pairs :meth:`_pair` forms on the kept exponents, unless a pair is kept in part (then
        False: :meth:`_pair` forms them)."""
        cdef int idx, m, j, n = 0
        for idx in range(like.nact):
            m, j = like.act[idx], like.partner[idx]
            if keep != NULL and m < self.pe:
                if j >= 0 and keep[m] != keep[j]:
                    return False
                if not keep[m]:
                    continue
            self.act[n], self.partner[n] = m, j
            n += 1
        self.nact = n
        return True

    cdef void _pair(self, const char* keep):
        """act, partner, nact: the exponents summed (those ``keep`` flags, all without it), each with its
        conjugate's index (or -1); then the divided differences (always kept)."""
        cdef int m, j, n = 0, partner
        cdef char* used = <char*>calloc(max(self.pe, 1), 1)
        if used == NULL:
            raise MemoryError
        if keep != NULL:
            for m in range(self.pe):
                used[m] = not keep[m]
        for m in range(self.pe):
            if used[m]:
                continue
            partner = -1
            if self.nu[m].imag != 0.0:
                for j in range(m + 1, self.pe):
                    if not used[j] and self.nu[j].real == self.nu[m].real and self.nu[j].imag == -self.nu[m].imag:
                        partner = j
                        used[j] = True
                        break
            self.act[n], self.partner[n] = m, partner
            n += 1
        for m in range(self.K):
            self.act[n], self.partner[n] = self.pe + m, -1
            n += 1
        self.nact = n
        free(used)


cdef void terms_at(_Terms T, double tau, double* er, double* ei):
    """The summed terms' time functions at tau: e^{nu tau} (Motion.evaluate's exponentials, one at a
    time), the divided differences F[nodes](tau)."""
    cdef int idx, m
    cdef double e, a, b, x, y
    for idx in range(T.nact):
        m = T.act[idx]
        if m < T.pe:
            e = exp(T.nu[m].real * tau)
            sincos(T.nu[m].imag * tau, &b, &a)
            x, y = e * a, e * b
        else:
            dexp(&T.gnodes[m - T.pe, 0], T.gm[m - T.pe], tau, &x, &y)
        er[idx], ei[idx] = x, y


cdef class Search:
    """One phase's search (events.first_event on the modal path, its set-up included): the band from the
    state at 33 times, the plans of the terms the search follows (Phase.search_plan), the state of the
    loop, the rows read from the state, the coarse pass. Arrays in (the closed form's terms, the rows H
    and Hd = H A_aug, A_aug, the rows' images of the terms, the configuration's term order), the event
    out (:meth:`run`); the bands written to the arrays ``tol`` and ``band`` given."""
    cdef int k, r2, dim, nh, p, pe, K, m
    cdef double t0, w
    cdef const double[:, ::1] H, Hd, A
    cdef const double complex[:, ::1] HUv    # the rows' images of the terms when given as such
    cdef double* hu                         # the rows' images of the terms (2k x (pe + K), interleaved)
    cdef double* hu_own                     # (formed here: from H V and the amplitudes)
    cdef const double complex[::1] nu
    cdef const double complex[:, ::1] gnodes
    cdef const int[::1] gm
    cdef const int[::1] order               # the modes, fastest first (Configuration.term_order)
    cdef const double[::1] weights
    cdef const double[:, ::1] gb            # per divided difference, its bound of order 4 (row 0) and 0 (row 1)
    cdef bint steady
    cdef double node_rate, fastest
    cdef char* keep                         # per exponent: kept by the current plan
    cdef char* ckeep                        # kept by the coarse pass
    cdef char* all                          # every exponent
    cdef double* budget                     # per H row: a quarter of its tol
    cdef double* cbud                       # the coarse pass's: COARSE of its size
    cdef _Terms state, kept, full, coarse  # xi's modal part (C: U), the kept rows, all rows, coarse
    cdef char* hdd_ok                      # per row: its Hd_i A_aug formed (in Hdd)
    cdef int* nmemo
    cdef double* Hdd                       # k x dim
    cdef double* memo                      # per row MEMO x (t, h, h', h'')
    cdef double* er
    cdef double* ei
    cdef double* sr
    cdef double* si
    cdef double* acc
    cdef double* xi
    cdef double* speed                     # |nu| (pe)
    cdef double* size                      # the plan's term sizes (k x pe) and their sums (k x m)
    cdef double* cum
    cdef double* absHU                     # |H U| of the H rows (k x (pe + K))
    cdef double* nan_from                  # per mode in the term order: 1 where an Hd row's size is nan
    cdef double* work
    cdef double[::1] tol, band
    cdef double* bound4
    cdef double h_step, t_start, t_stop, rate, renew_at
    cdef public bint compilable            # the current plan's bound screens every row (no local bound)
    cdef public long sampled               # the fine passes' samples so far (events' Phase.search_samples)
    # the coarse pass (events._Coarse)
    cdef double* margin
    cdef double* b4c
    cdef double step_c, start_c
    cdef double* cts
    cdef char* cclear
    cdef int cn, ccap

    def __cinit__(self):
        self.cts = self.work = self.hu_own = NULL
        self.cclear = self.hdd_ok = NULL
        self.nmemo = NULL
        self.cn = self.ccap = 0
        self.sampled = 0

    def __dealloc__(self):
        free(self.cts)
        free(self.cclear)
        free(self.work)
        free(self.hdd_ok)
        free(self.nmemo)
        free(self.hu_own)

    def __init__(self, nu, gnodes, gm, U, H, Hd, A, double t0, double w, images, order, bint steady, weights, gb,
                 double node_rate, double fastest, double t_start, double t_stop, tol, band):
        """``images``: the rows' images of the terms, (H; Hd)[:, :r2] U then their divided differences' (2k x
        (pe + K) complex), or (HV, c, g) without divided differences: (H; Hd)[:, :r2] V (2k x m) and the
        phase's amplitudes, the images then HV diag(c) and HV g^T (events.modal_images)."""
        cdef int j
        cdef const double complex[:, ::1] HV, g
        cdef const double complex[::1] c
        self.H, self.Hd, self.A = H, Hd, A
        self.k, self.dim = self.H.shape[0], self.H.shape[1]
        self.r2 = U.shape[0]
        self.nh = self.dim - self.r2
        self.nu, self.gnodes, self.gm, self.order, self.weights, self.gb = nu, gnodes, gm, order, weights, gb
        self.tol, self.band = tol, band
        self.pe, self.m, self.K = self.nu.shape[0], self.order.shape[0], self.gb.shape[1]
        # every index below is read without bounds checks: the shapes are checked here
        if (self.Hd.shape[0] != self.k or self.Hd.shape[1] != self.dim or self.A.shape[0] != self.dim
                or self.A.shape[1] != self.dim or self.nh not in (1, 3) or self.tol.shape[0] != self.k
                or self.band.shape[0] != self.k or self.weights.shape[0] != self.k):
            raise ValueError("Search: H and Hd need k rows of the state's size (the modal part's rows and 1 or 3 "
                             "harmonic components), A_aug that size square, tol, band and weights a value per row")
        cdef bint bad = self.m > self.pe or self.gb.shape[0] != 2
        for j in range(self.m):
            bad = bad or not 0 <= self.order[j] < self.m
        cdef bint formed = isinstance(images, tuple)
        if formed:
            HV, c, g = images
            bad = (bad or self.K or HV.shape[0] != 2 * self.k or HV.shape[1] != self.m or c.shape[0] != self.m
                   or g.shape[1] != self.m or g.shape[0] != self.pe - self.m)
        else:
            self.HUv = images
            bad = bad or self.HUv.shape[0] != 2 * self.k or self.HUv.shape[1] != self.pe + self.K
        if bad:
            raise ValueError("Search: the rows' images need a row per row of H and Hd and a column per term (or "
                             "per mode, with an amplitude per mode and forcing term), the order an index per mode")
        self.t0, self.w, self.steady, self.node_rate, self.fastest = t0, w, steady, node_rate, fastest
        cdef const double complex[:, ::1] Uv = U
        # (checked before U is read: its columns are the terms', exponents then divided differences)
        if self.gm.shape[0] != self.K or Uv.shape[1] != self.pe + self.K:
            raise ValueError("Search: a bound per divided difference, a column of U per term")
        self.state = _Terms.__new__(_Terms)
        self.state._set(self.nu, self.gnodes, self.gm, <const double*>&Uv[0, 0] if Uv.shape[0] * Uv.shape[1] else NULL,
                        True, self.r2, None, NULL)
        if self.state.K != self.K or Uv.shape[1] != self.pe + self.K:
            raise ValueError("Search: a bound per divided difference, a column of U per term")
        cdef int P = self.pe + self.K
        if not formed:
            self.hu = <double*>&self.HUv[0, 0] if 2 * self.k * P else NULL
        else:
            self.hu_own = self.hu = <double*>malloc((4 * self.k * P + 1) * sizeof(double))
            if self.hu == NULL:
                raise MemoryError
            self._images(HV, c, g)
        self.full = _Terms.__new__(_Terms)
        self.full._set(self.nu, self.gnodes, self.gm, self.hu, True, 2 * self.k, self.state, NULL)
        self.p = self.state.nact
        self.t_start, self.t_stop = t_start, t_stop
        self.coarse = None
        cdef int m = self.state.p + 1, k = self.k   # (kept and coarse terms are fewer)
        # one block of work space: Hdd, memo, er, ei, sr, si, acc, xi, speed, size, cum, absHU, nan_from, bound4
        self.work = <double*>malloc((k * self.dim + 4 * MEMO * k + 4 * m + 2 * k + self.dim + self.pe
                                     + k * (2 * self.pe + self.m + self.K) + self.m + 5 * k + 1) * sizeof(double))
        self.hdd_ok = <char*>malloc(k + 3 * self.pe + 1)
        self.nmemo = <int*>malloc((k + 1) * sizeof(int))
        if self.work == NULL or self.hdd_ok == NULL or self.nmemo == NULL:
            raise MemoryError
        for j in range(k):
            self.hdd_ok[j] = False
            self.nmemo[j] = 0
        self.Hdd = self.work
        self.memo = &self.Hdd[k * self.dim]
        self.er = &self.memo[4 * MEMO * k]
        self.ei, self.sr, self.si = &self.er[m], &self.er[2 * m], &self.er[3 * m]
        self.acc = &self.er[4 * m]
        self.xi = &self.acc[2 * k]
        self.speed = &self.xi[self.dim]
        self.size = &self.speed[self.pe]
        self.cum = &self.size[k * self.pe]
        self.absHU = &self.cum[k * self.m]
        self.nan_from = &self.absHU[k * (self.pe + self.K)]
        self.bound4 = &self.nan_from[self.m]
        self.budget, self.cbud = &self.bound4[k], &self.bound4[2 * k]
        self.margin, self.b4c = &self.bound4[3 * k], &self.bound4[4 * k]
        self.keep, self.ckeep, self.all = &self.hdd_ok[k], &self.hdd_ok[k + self.pe], &self.hdd_ok[k + 2 * self.pe]
        for j in range(self.pe):
            self.all[j] = True
        for j in range(self.pe):
            self.speed[j] = hypot(self.nu[j].real, self.nu[j].imag)
        self._sizes()
        self._tolerance()
        for j in range(k):
            self.budget[j] = self.tol[j] / 4.0
        self._plan(t_start)

    # -- the set-up -------------------------------------------------------------------------
    cdef double _max_step(self, double horizon, double rate) noexcept:
        """Phase.max_step: 1/8 of the fastest period of ``rate`` (or of the forcing), within horizon / 8."""
        cdef double h
        if self.w > rate:
            rate = self.w
        h = M_PI / (4.0 * rate) if rate > 0 else INFINITY
        if horizon > 0:
            return horizon / 8.0 if horizon / 8.0 < h else h
        return h

    cdef void _tolerance(self):
        """events.band_tolerance: per row, ZERO times the largest |H| |xi(t)| at 33 times over the next 4
        periods of the fastest mode (or to t_stop), never below events.round_off's 16 eps |H[:, :r2]| max|xi|.
        The state at the 33 times is Phase.xi_on_grid's (repeated products of the exponentials); each of its
        components, and each row's |H| |xi|, summed in the reference's order, the times side by side (lanes)."""
        cdef int n = 33, L = 36, k = self.k, dim = self.dim, r2 = self.r2, p = self.p, i, j, l, m
        cdef double step = self._max_step(INFINITY, self.fastest), window, dtau, a, b, big = 0.0, c, sn, h
        cdef bint finite = True
        cdef double* X = <double*>calloc(dim * L + 2 * p * L + L + 1, sizeof(double))
        if X == NULL:
            raise MemoryError
        cdef double* E = &X[dim * L]            # the terms' values: real parts (p x L), then imaginary
        cdef double* S = &E[2 * p * L]          # a row's |H| |xi| per time
        cdef double* x
        window = self.t_stop - self.t_start
        if isfinite(step) and step < window:
            window = step
        dtau = window / 32.0
        # Phase.xi_on_grid: the exponentials by repeated products (closed_form.Motion.on_grid)
        self._steps(self.state, dtau)
        for j in range(n):
            self._terms_on(self.state, self.t_start - self.t0, dtau, j, True)
            for m in range(p):
                E[m * L + j] = self.er[m]
                E[(p + m) * L + j] = self.ei[m]
        for l in range(r2):                     # xi's modal part: Re(U e^{nu tau}), each sum over the terms
            for m in range(p):
                lanes_add(&X[l * L], &E[m * L], &E[(p + m) * L], self.state.C[2 * (l * p + m)],
                          self.state.C[2 * (l * p + m) + 1], L)
        for j in range(n):
            X[r2 * L + j] = 1.0
            if self.nh == 3:
                sincos(self.w * (self.t_start + dtau * <double>j), &sn, &c)
                X[(r2 + 1) * L + j], X[(r2 + 2) * L + j] = c, sn
        for l in range(dim):
            for j in range(n):
                X[l * L + j] = fabs(X[l * L + j])
                finite = finite and isfinite(X[l * L + j])
        for l in range(r2):                     # (NumPy's max: a nan anywhere is the answer)
            for j in range(n):
                if X[l * L + j] > big or X[l * L + j] != X[l * L + j]:
                    big = X[l * L + j]
            if big != big:
                break
        for i in range(k):                      # |H| |xi|: each sum over the components in order
            for j in range(L):
                S[j] = 0.0
            for l in range(dim):
                h = fabs(self.H[i, l])
                if h == 0.0 and finite:         # (adds exactly nothing: 0 |xi| = 0)
                    continue
                lanes_axpy(S, &X[l * L], h, L)
            a = S[0]
            for j in range(1, n):
                if S[j] > a or S[j] != S[j]:
                    a = S[j]
                    if a != a:
                        break
            a = ZERO * (a + 1e-300)
            b = 16.0 * DBL_EPSILON * self.weights[i] * big if r2 else 0.0
            self.tol[i] = a if (a >= b or a != a) else b
        free(X)

    cdef void _sizes(self) noexcept:
        """|H U| of the H rows (np.abs: hypot), formed once; of the Hd rows, whose budget is unbounded, only
        where their size is nan (a cumulative sum that fits no budget), by mode in the term order."""
        cdef int k = self.k, pe = self.pe, P = self.pe + self.K, i, j, q
        cdef double re, im
        cdef bint nan
        for i in range(k):
            for j in range(P):
                self.absHU[i * P + j] = hypot(self.hu[2 * (i * P + j)], self.hu[2 * (i * P + j) + 1])
        nan = False
        for q in range(self.m):
            j = self.order[q]
            for i in range(k, 2 * k):
                re, im = self.hu[2 * (i * P + j)], self.hu[2 * (i * P + j) + 1]
                if (re != re or im != im) and not (isinf(re) or isinf(im)):
                    nan = True
            self.nan_from[q] = nan

    cdef int _leave_out(self, double since, const double* budget, char* keep, double* rate) noexcept:
        """Phase.search_plan's choice from tau = since on: the fastest modes whose sizes (|H U| of the H rows,
        a decaying term at its size at since, a growing one at the horizon: decay_factors) sum, in the term
        order, to at most each row's budget are left out (keep False), a conjugate pair together; the
        fastest rate kept. Returns how many modes are left out; their sums per row stay in ``cum``, the
        sizes in ``size``, the decay factors in er. (The Hd rows' budget is unbounded: they leave out any
        term; their sizes only where nan.)"""
        cdef int k = self.k, pe = self.pe, P = self.pe + self.K, m = self.m, i, j, q, n_drop
        cdef double horizon = self.t_stop - self.t0, re, x, fac, s
        cdef double* size = self.size
        cdef double* cum = self.cum
        cdef bint fits, scaled = since != 0.0 or not self.steady
        for j in range(pe):
            re = self.nu[j].real
            fac = exp(re * horizon if re > 0.0 else re * since)
            self.er[j] = fac
            for i in range(k):
                x = self.absHU[i * P + j]
                size[i * pe + j] = x * fac if scaled else x
        for i in range(k):                          # cumsum in the term order
            s = 0.0
            for q in range(m):
                s = s + size[i * pe + self.order[q]]
                cum[i * m + q] = s
        n_drop = m
        for q in range(m):
            fits = not self.nan_from[q]
            for i in range(k):
                if not cum[i * m + q] <= budget[i]:
                    fits = False
                    break
            if not fits:
                n_drop = q
                break
        # terms of one speed (a conjugate pair) are left out together or not at all
        while 0 < n_drop < m and self.speed[self.order[n_drop]] == self.speed[self.order[n_drop - 1]]:
            n_drop -= 1
        for j in range(pe):
            keep[j] = True
        for q in range(n_drop):
            keep[self.order[q]] = False
        if n_drop == 0:
            rate[0] = self.fastest
        else:
            rate[0] = 0.0
            for j in range(pe):
                if keep[j] and self.speed[j] > rate[0]:
                    rate[0] = self.speed[j]
            if self.K and self.node_rate > rate[0]:
                rate[0] = self.node_rate
        return n_drop

    cdef double _renewal(self, int n_drop, double since, const double* budget) noexcept:
        """configuration._renewal: the tau (>= since) from which the fastest kept modes, if they decay, fit
        the budget next to those left out (inf if never)."""
        cdef int k = self.k, pe = self.pe, m = self.m, i, q, ng
        cdef double rate_r = -INFINITY, best = 0.0, s, room, ratio, a
        cdef bint need_any = False, bad = False
        if not (n_drop < m and self.nu[self.order[n_drop]].real < 0.0):
            return INFINITY
        ng = n_drop
        while ng < m and self.speed[self.order[ng]] == self.speed[self.order[n_drop]]:
            if self.nu[self.order[ng]].real > rate_r:
                rate_r = self.nu[self.order[ng]].real
            ng += 1
        if not rate_r < 0.0:
            return INFINITY
        for i in range(k):
            s = 0.0
            for q in range(n_drop, ng):
                s = s + self.size[i * pe + self.order[q]]
            room = budget[i] - (self.cum[i * m + n_drop - 1] if n_drop else 0.0)
            if s > 0.0:
                need_any = True
                if room <= 0.0:
                    bad = True
                ratio = s / room
                if ratio > best or ratio != ratio:
                    best = ratio
        if not need_any or bad:
            return INFINITY
        a = log(best) / -rate_r
        return since + a if a > 0.0 else INFINITY

    cdef double _bound(self, int i, const char* keep, int order) noexcept:
        """Motion.bound's order-th derivative bound (order 0 or 4) of the kept part of H row i over the
        horizon, |H U| (|nu|^order decay factors, er), the divided differences' bounds (gb), the harmonic
        part's w^order (closed_form.power: explicit products)."""
        cdef int pe = self.pe, P = self.pe + self.K, j
        cdef double b = 0.0, bg, a, p
        for j in range(pe):
            if keep[j]:
                a = self.speed[j]
                p = a * a * a * a if order == 4 else 1.0
                b = b + self.absHU[i * P + j] * (p * self.er[j])
        if self.K:
            bg = 0.0
            for j in range(self.K):
                bg = bg + self.absHU[i * P + pe + j] * self.gb[0 if order == 4 else 1, j]
            b = b + bg
        if self.nh == 3 and self.w != 0.0:
            p = self.w * self.w * self.w * self.w if order == 4 else 1.0
            b = b + (fabs(self.H[i, self.r2 + 1]) + fabs(self.H[i, self.r2 + 2])) * p
        return b

    cdef void _plan(self, double t):
        """events.first_event's plan_from(t): Phase.search_plan with a quarter of each row's tol as its
        budget, from tau = t - t0 on: the kept rows' terms, the rate they set, the renewal time, band =
        tol - e (e: the left-out terms' sum), h_step and bound4 (the kept part's 4th-derivative bound
        times h_step^4 / 384); ``compilable``: every row's bound screens."""
        cdef int k = self.k, m = self.m, i, n_drop
        cdef double horizon = self.t_stop - self.t0, since = t - self.t0, step, s4
        n_drop = self._leave_out(since, self.budget, self.keep, &self.rate)
        self.renew_at = self.t0 + self._renewal(n_drop, since, self.budget)
        step = self._max_step(horizon, self.rate)
        s4 = step * step * step * step       # (closed_form.power: 1 * s * s * s * s)
        self.compilable = True
        for i in range(k):
            self.bound4[i] = self._bound(i, self.keep, 4) * s4 / 384.0
            self.band[i] = self.tol[i] - (self.cum[i * m + n_drop - 1] if n_drop else 0.0)
            if not self.bound4[i] <= self.band[i] * 281474976710656.0:    # 16^12: SUBDIVIDE^(4 DEPTH)
                self.compilable = False
        self.h_step = step
        if self.renew_at < t + step:                # (a renewal that rounds to where the plan starts: a step on)
            self.renew_at = t + step
        self.kept = _Terms.__new__(_Terms)
        self.kept._set(self.nu, self.gnodes, self.gm, self.hu, True, 2 * k, self.state, self.keep)

    cdef void _coarse_plan(self, double t):
        """events._Coarse.of from t: the rows without the fastest terms up to COARSE of each row's size (its
        terms' amplitudes over the horizon and its constant), sampled at the step of the rate left, the
        margin band + e and that step's bound4 (self.coarse None when it would not sample COARSE_GAIN
        times slower than the fine search, or the stretch to t_stop is under 4 of its steps)."""
        cdef int k = self.k, m = self.m, pe = self.pe, i, j, n_drop
        cdef double horizon = self.t_stop - self.t0, re, rate, step, s4
        self.coarse = None
        for j in range(pe):                         # the sizes over the whole horizon (since 0)
            re = self.nu[j].real
            self.er[j] = exp(re * horizon if re > 0.0 else re * 0.0)
        for i in range(k):
            self.cbud[i] = COARSE * (self._bound(i, self.all, 0) + fabs(self.H[i, self.r2]))
        n_drop = self._leave_out(t - self.t0, self.cbud, self.ckeep, &rate)
        step = self._max_step(horizon, rate)
        if step < COARSE_GAIN * self._max_step(horizon, self.rate) or step * 4.0 > self.t_stop - t:
            return
        s4 = step * step * step * step
        for i in range(k):
            self.b4c[i] = self._bound(i, self.ckeep, 4) * s4 / 384.0
            self.margin[i] = self.band[i] + (self.cum[i * m + n_drop - 1] if n_drop else 0.0)
        self.step_c, self.start_c, self.cn = step, t, 0
        self.coarse = _Terms.__new__(_Terms)
        self.coarse._set(self.nu, self.gnodes, self.gm, self.hu, True, 2 * k, self.state, self.ckeep)

    def setup(self):
        """The set-up's results, for tests against the reference (events.band_tolerance, plan_from):
        (tol, band, bound4, h_step, rate, renew_at, kept flags per exponent)."""
        return (np.asarray(self.tol).copy(), np.asarray(self.band).copy(),
                np.array([self.bound4[i] for i in range(self.k)]), self.h_step, self.rate, self.renew_at,
                np.array([bool(self.keep[j]) for j in range(self.pe)], dtype=bool))

    def images(self):
        """The rows' images of the terms the search uses (2k x (pe + K) complex; tests)."""
        cdef int P = self.pe + self.K
        return np.array([[complex(self.hu[2 * (i * P + j)], self.hu[2 * (i * P + j) + 1]) for j in range(P)]
                         for i in range(2 * self.k)], dtype=complex).reshape(2 * self.k, P)

    cdef void _images(self, const double complex[:, ::1] HV, const double complex[::1] c,
                      const double complex[:, ::1] g) noexcept:
        """events.modal_images from the rows' images of the modes HV and the amplitudes: HV diag(c), then per
        forcing term HV g_i (each entry one sum over the modes in order)."""
        cdef int R = 2 * self.k, m = self.m, P = self.pe, i, j, l
        cdef double sr, si, hr, hi, gr, gi
        cdef double* out
        for i in range(R):
            out = &self.hu[2 * i * P]
            for j in range(m):
                hr, hi = HV[i, j].real, HV[i, j].imag
                out[2 * j] = hr * c[j].real - hi * c[j].imag
                out[2 * j + 1] = hr * c[j].imag + hi * c[j].real
            for l in range(P - m):
                sr = si = 0.0
                for j in range(m):
                    hr, hi = HV[i, j].real, HV[i, j].imag
                    gr, gi = g[l, j].real, g[l, j].imag
                    sr = sr + (hr * gr - hi * gi)
                    si = si + (hr * gi + hi * gr)
                out[2 * (m + l)], out[2 * (m + l) + 1] = sr, si

    def terms(self):
        """(terms, terms summed) of the state's closed form and of the kept rows (a conjugate pair summed
        once)."""
        return (self.state.p, self.state.nact), (self.kept.p, self.kept.nact)

    # -- the rows ---------------------------------------------------------------------------
    cdef bint _grid(self, _Terms T, const double* ts, int n) noexcept:
        """Whether the times ts are a uniform grid of more than 8 (closed_form.exponentials: then e^{nu tau}
        by repeated products); if so, the exponents' steps into sr, si (:meth:`_steps`)."""
        cdef int j
        cdef double d0
        if n <= 8:
            return False
        d0 = (ts[1] - self.t0) - (ts[0] - self.t0)
        for j in range(1, n):
            if not fabs(((ts[j] - self.t0) - (ts[j - 1] - self.t0)) - d0) <= 1e-12 * fabs(d0):
                return False
        self._steps(T, d0)
        return True

    cdef void _steps(self, _Terms T, double d0) noexcept:
        """The exponents' steps e^{nu d0} into sr, si (a divided difference's unused)."""
        cdef int idx, m
        cdef double e, a, b
        for idx in range(T.nact):
            m = T.act[idx]
            if m < T.pe:
                e = exp(T.nu[m].real * d0)
                sincos(T.nu[m].imag * d0, &b, &a)
                self.sr[idx], self.si[idx] = e * a, e * b

    cdef void _terms_on(self, _Terms T, double tau0, double dtau, int j, bint uniform) noexcept:
        """The terms' values at tau0 + j dtau into er, ei: on a uniform grid (steps in sr, si) the
        exponentials as the product of those at j - 1 with their step, else (and at j = 0) afresh
        (terms_at); ``dtau`` 0 for the times of an explicit grid: tau0 is then the time's own."""
        cdef int idx, m
        cdef double x, y, tau = tau0 + dtau * <double>j
        cdef double* er = self.er
        cdef double* ei = self.ei
        if uniform and j > 0:
            for idx in range(T.nact):
                m = T.act[idx]
                if m < T.pe:
                    x = er[idx] * self.sr[idx] - ei[idx] * self.si[idx]
                    y = er[idx] * self.si[idx] + ei[idx] * self.sr[idx]
                    er[idx], ei[idx] = x, y
                else:
                    dexp(&T.gnodes[m - T.pe, 0], T.gm[m - T.pe], tau, &er[idx], &ei[idx])
        else:
            terms_at(T, tau, er, ei)

    cdef void _sample(self, _Terms T, int j0, int nj, int jstep, const double* ts, int n, double* out):
        """Rows j0, j0 + jstep, ... (nj of them) of T at the times ts (n), into out (nj x n):
        Motion.evaluate (e^{nu tau} by repeated products on a uniform grid of more than 8 times, as
        closed_form.exponentials) plus the rows' harmonic part (Phase._harmonics)."""
        cdef int p = T.nact, j, q, row
        cdef double c = 0.0, sn = 0.0
        cdef double* acc = self.acc
        cdef const double* hrow
        cdef bint uniform = self._grid(T, ts, n)
        for j in range(n):
            self._terms_on(T, ts[j] - self.t0, 0.0, j, uniform)
            # the rows' sums over the terms, each in order, four rows at a time (independent sums)
            modal_rows(T.C, 2 * p, j0, nj, jstep, self.er, self.ei, 1, p, acc)
            if self.nh == 3:
                sincos(self.w * ts[j], &sn, &c)
            for q in range(nj):
                row = j0 + q * jstep
                hrow = &self.H[row, self.r2] if row < self.k else &self.Hd[row - self.k, self.r2]
                if self.nh == 3:
                    out[q * n + j] = acc[q] + (hrow[0] + hrow[1] * c + hrow[2] * sn)
                else:
                    out[q * n + j] = acc[q] + hrow[0]

    cdef void samples(self, int i, const double* ts, int n, double* out):
        """events._Row.samples: (h, h') of row i at the times ts (2 x n), from all its terms (the rows'
        images H_i U, Hd_i U given)."""
        self._sample(self.full, i, 2, self.k, ts, n, out)

    cdef const double* at(self, int i, double t):
        """events._Row._eval: (h, h', h'') of row i at t, read from the state xi(t) (Phase._xi_at);
        the last MEMO times remembered."""
        cdef double* mem = &self.memo[4 * MEMO * i]
        cdef int j, m, l
        cdef double tau = t - self.t0, e, s, a, b, c, s0, s1, s2, s3
        cdef const double* U = self.state.C
        cdef const double* u0
        cdef const double* u1
        cdef const double* u2
        cdef const double* u3
        cdef double* xi = self.xi
        cdef double* hdd = &self.Hdd[i * self.dim]
        for j in range(self.nmemo[i]):
            if mem[4 * j] == t:
                return &mem[4 * j + 1]
        if not self.hdd_ok[i]:   # Hd_i A_aug (each entry summed in the order of l)
            for j in range(self.dim):
                hdd[j] = 0.0
            for l in range(self.dim):
                e = self.Hd[i, l]
                for j in range(self.dim):
                    hdd[j] += e * self.A[l, j]
            self.hdd_ok[i] = True
        terms_at(self.state, tau, self.er, self.ei)
        # xi's modal part, Re(U e^{nu tau}): each component summed over the terms in order, four
        # components at a time (independent sums: they overlap)
        modal_rows(U, 2 * self.p, 0, self.r2, 1, self.er, self.ei, 1, self.p, xi)
        xi[self.r2] = 1.0
        if self.nh == 3:
            sincos(self.w * t, &xi[self.r2 + 2], &xi[self.r2 + 1])
        a = b = c = 0.0
        for l in range(self.dim):
            a += self.H[i, l] * xi[l]
            b += self.Hd[i, l] * xi[l]
            c += hdd[l] * xi[l]
        if self.nmemo[i] >= MEMO:
            self.nmemo[i] = 0
        j = self.nmemo[i]
        mem[4 * j], mem[4 * j + 1], mem[4 * j + 2], mem[4 * j + 3] = t, a, b, c
        self.nmemo[i] = j + 1
        return &mem[4 * j + 1]

    # -- roots ------------------------------------------------------------------------------
    cdef bint root(self, int i, int which, double thr, double a, double b, double* out):
        """events._root on row i: which 0, a root of h - thr (with h'); 1, of h' (with h''). False
        when the re-evaluated ends show no sign change."""
        cdef const double* v
        cdef double fa, da, fb, db, xtol, x, prev, fx, dx, step, tol, x_new
        cdef double c[4]
        cdef bint overshot = False
        cdef int it
        pick(self.at(i, a), which, thr, &fa, &da)
        pick(self.at(i, b), which, thr, &fb, &db)
        if fa == 0.0:
            out[0] = a
            return True
        if fb == 0.0:
            out[0] = b
            return True
        if (fa > 0) == (fb > 0):
            return False
        xtol = 4e-16 * max(1.0, fabs(b))
        cubic(fa, fb, da, db, b - a, c)
        x = a + (b - a) * cubic_root(c[0], c[1], c[2], c[3])
        prev = b - a
        for it in range(MAXITER):
            pick(self.at(i, x), which, thr, &fx, &dx)
            if fx == 0.0:
                out[0] = x
                return True
            if (fx > 0) == (fa > 0):
                a, fa = x, fx
            else:
                b = x
            step = fx / dx if dx != 0.0 else INFINITY
            tol = xtol + 8.9e-16 * fabs(x)
            if fabs(step) <= tol:
                out[0] = min(max(x - step, a), b)
                return True
            if b - a <= 2.0 * tol:
                out[0] = 0.5 * (a + b)
                return True
            x_new = x - step
            if a < x_new < b and fabs(step) <= 0.5 * prev:
                overshot = False
            elif not overshot and a < x - 2.0 * step < b:
                x_new, step, overshot = x - 2.0 * step, 2.0 * step, True
            else:
                x_new = 0.5 * (a + b)
                step, overshot = x - x_new, False
            prev, x = fabs(step), x_new
        out[0] = x
        return True

    # -- scans ------------------------------------------------------------------------------
    cdef bint finer(self, int i, double a, double b, double thr, double tol, double b4, double limit, int depth,
                    double* t_out, bint* graze):
        """_scan's finer(k): the interval [a, b] on SUBDIVIDE finer intervals, scanned again."""
        cdef double sub[17]
        cdef double hh[34]
        cdef double bs[16]
        cdef int j
        linspace(a, b, SUBDIVIDE + 1, sub)
        self.samples(i, sub, SUBDIVIDE + 1, hh)
        for j in range(SUBDIVIDE):
            bs[j] = b4 / 65536.0
        return self.scan(i, sub, hh, &hh[SUBDIVIDE + 1], SUBDIVIDE + 1, thr, tol, bs, limit, depth + 1, NULL, NULL,
                         NULL, t_out, graze)

    cdef bint scan(self, int i, const double* ts, const double* h, const double* hd, int n, double thr, double tol,
                   const double* b4, double limit, int depth, const char* cross_in, const char* turn_in,
                   const char* near_in, double* t_out, bint* graze):
        """events._scan on row i: the first root of h - thr on the samples (crossing or dip), refined:
        True with (t_out, graze), or False. b4 per interval; cross_in/turn_in/near_in: the screen of
        these samples when the caller has formed it (else NULL)."""
        if n < 2:
            return False
        cdef int ni = n - 1, k, kk, k_c = -1, j
        cdef double reach = tol * pow(<double>SUBDIVIDE, <double>(4 * (DEPTH - depth)))
        cdef char* buf = <char*>malloc(4 * ni)
        cdef double* dbuf = <double*>malloc((n + ni) * sizeof(double))
        if buf == NULL or dbuf == NULL:
            free(buf)
            free(dbuf)
            raise MemoryError
        cdef char* sub = buf
        cdef char* cross
        cdef char* turn
        cdef char* near
        cdef double* f = dbuf
        cdef double* dt = &dbuf[n]
        cdef double a, b, t_r, u, tm, fm
        cdef const double* v
        cdef bint found = False, ok
        for k in range(n):
            f[k] = h[k] - thr
        for k in range(ni):
            sub[k] = (b4[k] <= reach) if depth < DEPTH else False
            dt[k] = ts[k + 1] - ts[k]
        if cross_in != NULL:
            cross, turn, near = <char*>cross_in, <char*>turn_in, <char*>near_in
        else:
            cross, turn, near = &buf[ni], &buf[2 * ni], &buf[3 * ni]
            screen_row(dt, f, hd, ni, tol, b4, sub, cross, turn, near)
        for k in range(ni):
            if cross[k]:
                k_c = k
                break
        # the candidates: near intervals before the first crossing, then the crossing
        for kk in range(ni if k_c < 0 else k_c + 1):
            k = kk
            if k == k_c:
                pass
            elif not near[k]:
                continue
            a, b = ts[k], ts[k + 1]
            if a > limit:
                break
            if sub[k] and k != k_c and not turn[k]:
                if self.finer(i, a, b, thr, tol, b4[k], limit, depth, t_out, graze):
                    found = True
                    break
                continue
            if k == k_c:
                if self.at(i, a)[0] - thr < 0:   # the sample before is itself (round-off) below
                    t_out[0], graze[0], found = a, False, True
                    break
                if not self.root(i, 0, thr, a, b, &t_r):
                    t_r = b
                # first(k, t_r): t_r unless an earlier root may hide before it
                graze[0], found = False, True
                t_out[0] = t_r
                if not sub[k] or first_root(f[k], f[k + 1], hd[k], hd[k + 1], dt[k], (t_r - ts[k]) / dt[k], b4[k],
                                            tol):
                    break
                u = (t_r - ts[k]) / dt[k]
                if u > 0.0:
                    v = self.at(i, t_r)
                    if envelope(f[k], v[0] - thr, hd[k], v[1], t_r - ts[k], b4[k] * pow(u, 4.0), 1.0) >= -tol:
                        break
                if not self.finer(i, a, b, thr, tol, b4[k], limit, depth, t_out, graze):
                    t_out[0], graze[0] = t_r, False
                break
            if not turn[k]:
                continue
            if sub[k] and not convex(f[k], f[k + 1], hd[k], hd[k + 1], dt[k], b4[k]):
                # two minima may hide in the interval: scanned again on finer samples
                if self.finer(i, a, b, thr, tol, b4[k], limit, depth, t_out, graze):
                    found = True
                    break
                continue
            # dip: the minimum inside [a, b]
            if not self.root(i, 1, 0.0, a, b, &tm):
                tm = a if f[k] <= f[k + 1] else b
            fm = self.at(i, tm)[0] - thr
            if fm < -tol:
                if not self.root(i, 0, thr, a, tm, &t_r):
                    t_r = tm
                t_out[0], graze[0], found = t_r, False, True
                break
            if fm <= tol and thr == 0.0:
                t_out[0], graze[0], found = tm, True, True
                break
        free(buf)
        free(dbuf)
        return found

    cdef int arm(self, int i, const double* ts, const double* h, const double* hd, int n, double tol, double bound4,
                 double* t_arm):
        """events._arm: the interval k where a row that starts in its zero band first rises above it
        (t_arm: at a sample or a maximum between samples), or -1."""
        cdef int k, j, cnt = 0, best
        cdef double a, b, hmax, tc, hm, tm
        cdef double c[4]
        cdef double grid[33]
        cdef double vals[66]
        if n < 2:
            return -1
        for k in range(n - 1):
            a, b = ts[k], ts[k + 1]
            hmax = -hermite_min(-h[k], -h[k + 1], -hd[k], -hd[k + 1], b - a)
            if not (h[k + 1] > tol or hmax + bound4 > tol):
                continue
            cnt += 1
            if cnt > ARM_CANDIDATES:
                break
            if hmax - bound4 > tol:
                cubic(h[k], h[k + 1], hd[k], hd[k + 1], b - a, c)
                tc = a + (b - a) * cubic_argmax(c)
                if self.at(i, tc)[0] > tol:
                    t_arm[0] = tc
                    return k
            if not (hd[k] > 0 >= hd[k + 1] and self.root(i, 1, 0.0, a, b, &tm)):
                # no sign change of h' (left): the maximum on a fine grid
                linspace(a, b, 33, grid)
                self.samples(i, grid, 33, vals)
                best = 0
                for j in range(1, 33):
                    if vals[j] > vals[best]:
                        best = j
                tm, hm = grid[best], vals[best]
            else:
                hm = self.at(i, tm)[0]
            if hm > tol:
                t_arm[0] = tm
                return k
            if h[k + 1] > tol:
                t_arm[0] = b
                return k
        return -1

    # -- the coarse pass --------------------------------------------------------------------
    cdef void extend(self):
        """events._Coarse._extend: the next CHUNK coarse intervals sampled and judged. A pending signal's
        handler runs first (Ctrl-C, SIGTERM): a certified stretch calls no Python code until it ends."""
        PyErr_CheckSignals()
        cdef double t0c = self.cts[self.cn] if self.cn > 0 else self.start_c
        cdef double nd = ceil((self.t_stop - t0c) / self.step_c), lo, s0, s1, d0, d1, dt, mn
        cdef int n = 1 if nd < 1 else (CHUNK if nd > CHUNK else <int>nd), j, q, off
        cdef int k = self.k
        cdef double* ts = <double*>malloc((n + 1) * sizeof(double))
        cdef double* ss = <double*>malloc(2 * k * (n + 1) * sizeof(double))
        cdef bint clear
        cdef double* grown_ts
        cdef char* grown_clear
        if ts == NULL or ss == NULL:
            free(ts)
            free(ss)
            raise MemoryError
        linspace(t0c, min(self.t_stop, t0c + n * self.step_c), n + 1, ts)
        self._sample(self.coarse, 0, 2 * k, 1, ts, n + 1, ss)
        for q in range(k):
            for j in range(n + 1):
                ss[q * (n + 1) + j] -= self.margin[q]
        off = 0 if self.cn == 0 else 1
        if self.cn + n + 2 > self.ccap:
            grown_ts = <double*>realloc(self.cts, 2 * (self.cn + n + 2) * sizeof(double))
            if grown_ts != NULL:
                self.cts = grown_ts
            grown_clear = <char*>realloc(self.cclear, 2 * (self.cn + n + 2))
            if grown_clear != NULL:
                self.cclear = grown_clear
            if grown_ts == NULL or grown_clear == NULL:
                free(ts)
                free(ss)
                raise MemoryError
            self.ccap = 2 * (self.cn + n + 2)
        if self.cn == 0:
            self.cts[0] = ts[0]
        for j in range(n):
            dt = ts[j + 1] - ts[j]
            clear = True
            for q in range(k):
                s0, s1 = ss[q * (n + 1) + j], ss[q * (n + 1) + j + 1]
                d0, d1 = ss[(k + q) * (n + 1) + j], ss[(k + q) * (n + 1) + j + 1]
                mn = s0 if s0 <= s1 else s1
                lo = mn - 4.0 / 27.0 * dt * (fabs(d0) + fabs(d1))
                lo -= self.b4c[q]
                if lo <= 0.0:
                    lo = hermite_min(s0, s1, d0, d1, dt) - self.b4c[q]
                if not lo > 0.0:
                    clear = False
                    break
            self.cclear[self.cn + j] = clear
            self.cts[self.cn + j + 1] = ts[j + 1]
        self.cn += n
        free(ts)
        free(ss)

    cdef double unclear(self, double t, double* t_b):
        """events._Coarse.unclear: (a, b), the first stretch at or after t not certified clear."""
        cdef int lo = 0, hi = self.cn + 1 if self.cn > 0 else 0, mid, j
        cdef double a
        while lo < hi:   # searchsorted(ts, t, side="right")
            mid = (lo + hi) // 2
            if self.cts[mid] <= t:
                lo = mid + 1
            else:
                hi = mid
        j = lo - 1 if lo > 0 else 0
        while True:
            while j >= self.cn:
                if self.cn > 0 and self.cts[self.cn] >= self.t_stop:
                    t_b[0] = self.t_stop
                    return self.t_stop
                self.extend()
            if not self.cclear[j]:
                break
            j += 1
        a = max(t, self.cts[j])
        while True:
            if j >= self.cn:
                if self.cts[self.cn] >= self.t_stop:
                    t_b[0] = self.t_stop
                    return a
                self.extend()
                continue
            if self.cclear[j]:
                t_b[0] = self.cts[j]
                return a
            j += 1

    # -- the loop ---------------------------------------------------------------------------
    def run(self, progress, carry=None):
        """events.first_event's loop: (t, rows, graze, in_band) of the earliest event, or None; a float t
        where a plan's bound does not screen every row (events._compilable): the search goes on from t in
        Python. ``progress(t)`` is called after each chunk and each coarse skip (no event before t).
        ``carry``: None, or a list [armed, thr] continuing a search of the same phase (None, None: from its
        start); on return it holds the rows' arming and thresholds (for the Python loop after a float)."""
        cdef int k = self.k, n, ns, i, j, q, ka, cnt, nfound = 0
        cdef int cap = CHUNK + 2
        cdef double t_a = self.t_start, t_b, t_c, t_skip, nd, limit, t_arm, t_e, rt, step
        cdef bint handover = False
        cdef int chunk = FIRST_CHUNK
        cdef bint tried = False, started = False, all_armed, ok, g, in_band
        # work space in three blocks: doubles, flags, indices
        cdef double* dwork = <double*>malloc((cap * (11 + 3 * k) + 2 * k) * sizeof(double))
        cdef char* cwork = <char*>malloc(cap * (1 + 4 * k) + 4 * k)
        cdef int* iwork = <int*>malloc(3 * k * sizeof(int))
        if dwork == NULL or cwork == NULL or iwork == NULL:
            free(dwork)
            free(cwork)
            free(iwork)
            raise MemoryError
        cdef double* ts = dwork
        cdef double* hh = &dwork[cap]                    # 2k x cap
        cdef double* f = &hh[2 * k * cap]                # k x cap
        cdef double* dt = &f[k * cap]
        cdef double* b4 = &dt[cap]
        cdef double* cut = &b4[cap]                      # 6 x cap
        cdef double* thr = &cut[6 * cap]
        cdef double* ft = &thr[k]
        cdef char* flags = cwork                         # 4k x cap
        cdef char* sub = &flags[4 * k * cap]
        cdef char* armed = &sub[cap]
        cdef char* maybe = &armed[k]
        cdef char* fg = &maybe[k]
        cdef char* fb = &fg[k]
        cdef int* first = iwork
        cdef int* order = &iwork[k]
        cdef int* fi = &iwork[2 * k]
        cdef char* cross
        cdef char* turn
        cdef char* near
        cdef double* h
        cdef double* hd
        cdef double* ts1
        cdef double* h1
        cdef double* hd1
        cdef double* ts2
        cdef double* h2
        cdef double* hd2
        cdef double band, bnd4
        cdef const double* v
        cdef int n1, n2
        result = None
        try:   # (the work space is freed on every way out: a return, a bad carry, an exception from progress)
            if carry is not None and carry[0] is not None:
                # a later window of one search: the rows keep their arming and thresholds
                if len(carry[0]) != k or len(carry[1]) != k:
                    raise ValueError("Search.run: the carried arming and thresholds need a value per row")
                started = True
                for i in range(k):
                    armed[i] = bool(carry[0][i])
                    thr[i] = float(carry[1][i])
            if not self.compilable:   # the first plan's bound does not screen: the Python loop from the start
                return float(t_a)
            while t_a < self.t_stop:
                if t_a >= self.renew_at:
                    # the fastest term kept has decayed into its budget: it no longer sets the step (an
                    # overdamped stiff mode after an impact), nor the coarse pass's
                    self._plan(t_a)
                    if not self.compilable:   # the Python loop from here on, the rows' arming carried
                        handover = True
                        break
                    self.coarse, tried = None, False
                t_b = self.t_stop if self.t_stop <= self.renew_at else self.renew_at
                if not tried and started:
                    all_armed = True
                    for i in range(k):
                        if not armed[i]:
                            all_armed = False
                            break
                    if all_armed:
                        # formed once a first chunk has found nothing
                        tried = True
                        self._coarse_plan(t_a)
                if self.coarse is not None:
                    # every row armed at 0: skip what the coarse pass certifies, search the rest finely
                    t_skip = self.unclear(t_a, &t_c)
                    if t_c < t_b:
                        t_b = t_c
                    if t_skip > t_a:
                        t_a = t_skip
                        chunk = FIRST_CHUNK
                        progress(t_a)
                        if t_a >= self.t_stop:
                            break
                        if t_a >= t_b:
                            continue
                nd = ceil((t_b - t_a) / self.h_step)
                n = chunk if nd > chunk else <int>nd
                if n < 1:
                    n = 1
                chunk = min(CHUNK, 4 * chunk)
                ns = n + 1
                linspace(t_a, min(t_b, t_a + n * self.h_step), ns, ts)
                self._sample(self.kept, 0, 2 * k, 1, ts, ns, hh)
                self.sampled += ns
                if not started:
                    # a row that starts inside its zero band is armed once it has left it upwards; unarmed
                    # rows fire by going down by the band from where they start
                    started = True
                    for i in range(k):
                        armed[i] = hh[i * ns] > self.band[i]
                        thr[i] = 0.0 if armed[i] else min(-self.band[i], hh[i * ns] - self.band[i])
                for j in range(n):
                    dt[j] = ts[j + 1] - ts[j]
                    sub[j] = True
                # all rows screened at once (first_event's _screened: every row's bound screens here)
                for i in range(k):
                    h = &hh[i * ns]
                    hd = &hh[(k + i) * ns]
                    for j in range(ns):
                        f[i * ns + j] = h[j] - thr[i]
                    for j in range(n):
                        b4[j] = self.bound4[i]
                    cross, turn, near = &flags[3 * i * ns], &flags[(3 * i + 1) * ns], &flags[(3 * i + 2) * ns]
                    screen_row(dt, &f[i * ns], hd, n, self.band[i], b4, sub, cross, turn, near)
                    maybe[i] = not armed[i]
                    for j in range(n):
                        if cross[j] or near[j]:
                            maybe[i] = True
                            break
                    # the first sample below threshold (rows are refined in that order)
                    first[i] = ns
                    for j in range(ns):
                        if f[i * ns + j] < -self.band[i]:
                            first[i] = j
                            break
                    # stable insertion into the order
                    q = i
                    while q > 0 and first[order[q - 1]] > first[i]:
                        order[q] = order[q - 1]
                        q -= 1
                    order[q] = i
                nfound = 0
                limit = INFINITY
                step = ts[1] - ts[0]
                for q in range(k):
                    i = order[q]
                    if not maybe[i]:
                        continue
                    h = &hh[i * ns]
                    hd = &hh[(k + i) * ns]
                    band, bnd4 = self.band[i], self.bound4[i]
                    ok = False
                    in_band = False
                    if not armed[i]:
                        # the row starts in its zero band: it fires from there only by leaving it downwards
                        # (root at -tol, flagged); once it has left the band upwards it is armed at 0
                        ka = self.arm(i, ts, h, hd, ns, band, bnd4, &t_arm)
                        if ka < 0:
                            for j in range(n):
                                b4[j] = bnd4
                            ok = self.scan(i, ts, h, hd, ns, thr[i], band, b4, limit, 0, NULL, NULL, NULL, &rt, &g)
                        else:
                            # _cut: the samples up to the arming point and from it on
                            ts1, h1, hd1 = cut, &cut[cap], &cut[2 * cap]
                            ts2, h2, hd2 = &cut[3 * cap], &cut[4 * cap], &cut[5 * cap]
                            v = self.at(i, t_arm)
                            for j in range(ka + 1):
                                ts1[j], h1[j], hd1[j] = ts[j], h[j], hd[j]
                            n1 = ka + 1
                            if not t_arm <= ts[ka]:
                                ts1[n1], h1[n1], hd1[n1] = t_arm, v[0], v[1]
                                n1 += 1
                            ts2[0], h2[0], hd2[0] = t_arm, v[0], v[1]
                            n2 = 1
                            for j in range(ka + 1, ns):
                                ts2[n2], h2[n2], hd2[n2] = ts[j], h[j], hd[j]
                                n2 += 1
                            for j in range(n1 - 1):   # _shorter
                                b4[j] = bnd4 * pow(min((ts1[j + 1] - ts1[j]) / step, 1.0), 4.0)
                            ok = self.scan(i, ts1, h1, hd1, n1, thr[i], band, b4, limit, 0, NULL, NULL, NULL, &rt, &g)
                        if ok and ka >= 0 and rt <= t_arm and (rt <= ts[0] or self.at(i, rt)[1] > 0.0):
                            # round-off of evaluating the row near its start, not a descent by tol
                            ok = False
                        if ok and (ka < 0 or rt <= t_arm):
                            in_band = True
                        elif ka >= 0:
                            armed[i], thr[i] = True, 0.0
                            for j in range(n2 - 1):
                                b4[j] = bnd4 * pow(min((ts2[j + 1] - ts2[j]) / step, 1.0), 4.0)
                            ok = self.scan(i, ts2, h2, hd2, n2, 0.0, band, b4, limit, 0, NULL, NULL, NULL, &rt, &g)
                    else:
                        for j in range(n):
                            b4[j] = bnd4
                        ok = self.scan(i, ts, h, hd, ns, thr[i], band, b4, limit, 0, &flags[3 * i * ns],
                                       &flags[(3 * i + 1) * ns], &flags[(3 * i + 2) * ns], &rt, &g)
                    if ok:
                        ft[nfound], fi[nfound], fg[nfound], fb[nfound] = rt, i, g, in_band
                        nfound += 1
                        limit = min(limit, rt + 1e-12 * max(1.0, fabs(rt)))
                if nfound:
                    t_e = ft[0]
                    for j in range(1, nfound):
                        if ft[j] < t_e:
                            t_e = ft[j]
                    rows, graze, inb = [], [], []
                    for i in range(k):   # the rows within 1e-12 of the earliest, by index
                        for j in range(nfound):
                            if fi[j] == i and ft[j] <= t_e + 1e-12 * max(1.0, fabs(t_e)):
                                rows.append(i)
                                graze.append(bool(fg[j]))
                                inb.append(bool(fb[j]))
                    result = (t_e, rows, graze, inb)
                    break
                t_a = ts[n]
                progress(t_a)   # no event before this time (an interrupted run keeps it)
            if carry is not None and started:
                carry[0] = [bool(armed[i]) for i in range(k)]
                carry[1] = [thr[i] for i in range(k)]
        finally:
            free(dwork)
            free(cwork)
            free(iwork)
        return float(t_a) if handover else result


def lanes(x, u, v, double a, double b):
    """For tests: (x + (a u - b v), x + a u) by the four-lane kernels the band's sums use (the clone this CPU
    runs) and by plain scalar loops, as four lists; each lane must round as the scalar code."""
    cdef int n = len(x), j
    cdef int L = (n + 3) // 4 * 4
    cdef double[::1] X = np.zeros(L + 1), Y = np.zeros(L + 1), U = np.zeros(L + 1), V = np.zeros(L + 1)
    cdef double xj, uj, vj
    for j in range(n):
        X[j], Y[j], U[j], V[j] = x[j], x[j], u[j], v[j]
    lanes_add(&X[0], &U[0], &V[0], a, b, L)
    lanes_axpy(&Y[0], &U[0], a, L)
    add, axpy = [], []
    for j in range(n):
        xj, uj, vj = x[j], u[j], v[j]
        add.append(xj + (a * uj - b * vj))
        axpy.append(xj + a * uj)
    return [X[j] for j in range(n)], add, [Y[j] for j in range(n)], axpy

