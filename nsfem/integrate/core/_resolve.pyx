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


# ----------------------------------------------------------------------------------------------------------
# an impact after which every contact is open (transitions._impact_fast: resolve's common case)

from libc.math cimport INFINITY, isfinite

ctypedef long long i64

#: approach speeds below this fraction of the contact velocities are settled, not impacts (transitions.CREEP)
cdef double CREEP = 1e-7
#: right-hand side entries at this fraction of the largest are zeros (builders.ROUND_OFF)
cdef double ROUND_OFF = 1e-13

# per-contact flags of an event
cdef enum:
    FORCED = 1         # a candidate whatever its gap: closed before the event, or its gap root just located
    SETTLED = 2        # re-closed after a rebound below resolution: its impact is plastic
    MOVING = 4         # slides on a moving surface (its slip rate and impulses have a drift): not this path's
    CANDIDATE = 8      # touching: g <= its band, or FORCED
    ACTIVE = 16        # a candidate that does not separate (g' <= its band): in the impact LCP
    APPROACHING = 32   # g' < -its band, beyond CREEP of the candidates' velocities: an impact
    PLASTIC = 64       # an approaching contact whose impact is plastic (SETTLED, or Zeno)


cdef inline double kinetic(const double[:, ::1] M, const double* v) noexcept nogil:
    """0.5 v^T M v as (v M) v, each product summed in the order of the coordinates."""
    cdef Py_ssize_t i, j, n = M.shape[0]
    cdef double s, e = 0.0
    for j in range(n):
        s = 0.0
        for i in range(n):
            s += v[i] * M[i, j]
        e += s * v[j]
    return 0.5 * e


cdef class Matrix:
    """The matrix part of an impact LCP (30-32) over its active contacts, as cached by builders._impact_parts:
    A, Y = M^-1 [J_N, J_T], J_T (the friction generators' rows of the right-hand side), the number of normal
    unknowns, Lemke's equilibration (r_s, c_s) and the rows' groups (``A``, ``scales``, ``groups`` kept as
    given for the general solve)."""

    cdef readonly object A, scales, groups
    cdef const double[:, :] a
    cdef const double[:, :] y
    cdef const double[:, :] jt
    cdef const double[::1] r_s
    cdef const double[::1] c_s
    cdef readonly Py_ssize_t normal

    def __init__(self, A, Y, JT, Py_ssize_t normal, scales, groups):
        self.A, self.scales, self.groups, self.normal = A, scales, groups, normal
        self.a, self.y, self.jt, self.r_s, self.c_s = A, Y, JT, scales[0], scales[1]


cdef class ImpactPath:
    """resolve's common case on one contact system: an impact after which every contact is open. Holds the
    system's arrays (J_N^T, |J_N|^T, j_N, |j_N|, the restitutions, M, the tangent rows S_k^T stacked (contact
    k's are rows ``srow[k]`` to ``srow[k + 1]`` of ``ST``), the contacts on moving surfaces), work arrays,
    the matrix parts met (``matrices``, by active contacts) and ``one``, the compiled Lemke's one-unknown
    kernel (_lcp.lemke_one) or None. An event is
    :meth:`classify`, then :meth:`open` with the impact LCP's :class:`Matrix`; each mirrors its part of
    transitions.resolve (the reference), and says when the event is not this path's."""

    cdef const double[:, ::1] JNT
    cdef const double[:, ::1] aJT
    cdef const double[:, ::1] M
    cdef const double[::1] jN
    cdef const double[::1] aj
    cdef const double[::1] eps
    cdef const double[:, ::1] ST
    cdef const i64[::1] srow
    cdef const signed char[::1] moving
    cdef signed char[::1] flags
    cdef i64[::1] idx
    cdef double[:, ::1] rates
    cdef Py_ssize_t na
    cdef readonly dict matrices
    cdef readonly object one

    def __init__(self, JNT, aJT, jN, aj, eps, M, ST, srow, moving, one, flags, idx, rates):
        """``moving``: int8 per contact, non-zero on a moving surface; ``flags`` (int8, m), ``idx`` (int64,
        m), ``rates`` (2 x m): work arrays."""
        self.JNT, self.aJT, self.jN, self.aj, self.eps, self.M = JNT, aJT, jN, aj, eps, M
        self.ST, self.srow, self.moving = ST, srow, moving
        self.flags, self.idx, self.rates = flags, idx, rates
        self.one, self.matrices, self.na = one, {}, 0

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        """A cache of its system's arrays with work space used within one event: copies of a Memory share it."""
        return self

    cpdef Py_ssize_t classify(self, const double[::1] q, const double[::1] v, const double[::1] gap_scale,
                              const double[::1] rate_scale, const double[::1] gap_tol, double gap_floor,
                              object closed, object touching, object settled, double[:, ::1] state):
        """Mirrors the head of transitions.resolve on the compiled path: the bands (``state_bands``, into
        ``state``: new gap scale, new rate scale, g, g', gap band, rate band), the candidates (g <= band, or in
        ``closed`` (before the event) or ``touching``), the approaching ones and the creeping test (against
        the candidates' largest |g'| and slip rate |S_k^T q'|).
        Returns the number of active contacts (:meth:`active`), 0 when none approaches, -1 when the event is
        not this path's (a non-finite state, a candidate on a moving surface, a creeping approach, a contact
        index out of range, arrays of other shapes than (n,), (m,) and 6 x m: read without bounds checks):
        nothing outside this object and ``state`` is written."""
        cdef Py_ssize_t k, i, j, m = self.JNT.shape[0], n = self.JNT.shape[1], na = 0
        cdef double vscale = 0.0, s
        cdef bint approach = False
        cdef signed char[::1] flags = self.flags
        self.na = 0
        if (q.shape[0] != n or v.shape[0] != n or gap_scale.shape[0] != m or rate_scale.shape[0] != m
                or gap_tol.shape[0] not in (0, m) or state.shape[0] != 6 or state.shape[1] != m):
            return -1
        for k in range(m):
            flags[k] = MOVING if self.moving[k] else 0
        for group, bit in ((closed, FORCED), (touching, FORCED), (settled, SETTLED)):
            for k in group:
                if not 0 <= k < m:
                    return -1
                flags[k] |= <signed char> bit
        state_bands(self.JNT, self.aJT, self.jN, self.aj, q, v, gap_scale, rate_scale, gap_tol, gap_floor, state)
        cdef const double[::1] g = state[2], gv = state[3], tg = state[4], tv = state[5]
        for k in range(m):
            if not (isfinite(state[0, k]) and isfinite(state[1, k]) and isfinite(g[k]) and isfinite(gv[k])
                    and isfinite(tg[k]) and isfinite(tv[k])):
                return -1
        for k in range(m):
            if g[k] <= tg[k] or flags[k] & FORCED:
                if flags[k] & MOVING:   # the slip rate and the impact law have the surface's drift
                    return -1
                flags[k] |= CANDIDATE
                if fabs(gv[k]) > vscale:
                    vscale = fabs(gv[k])
                for i in range(self.srow[k], self.srow[k + 1]):   # its slip rates
                    s = 0.0
                    for j in range(n):
                        s += self.ST[i, j] * v[j]
                    if fabs(s) > vscale:
                        vscale = fabs(s)
        for k in range(m):
            if flags[k] & CANDIDATE and gv[k] < -tv[k]:
                if -gv[k] <= CREEP * vscale:   # creeping: settled by a projection, not this path's
                    return -1
                flags[k] |= APPROACHING
                approach = True
        if not approach:
            return 0
        for k in range(m):
            if flags[k] & CANDIDATE and gv[k] <= tv[k]:
                flags[k] |= ACTIVE
                self.idx[na] = k
                na += 1
        self.na = na
        return na

    def active(self) -> tuple:
        """The active contacts of the last :meth:`classify`, ascending."""
        return tuple([self.idx[j] for j in range(self.na)])

    def plastic(self) -> list:
        """The approaching contacts of the last :meth:`open` whose impact was plastic, ascending."""
        return [k for k in range(self.flags.shape[0]) if self.flags[k] & PLASTIC]

    cpdef int open(self, Matrix mat, object general, const double[::1] v, const double[:, ::1] state,
                   double[::1] max_approach, i64[::1] impacts, double zeno, double[::1] x, double[::1] v_new,
                   double[::1] ke):
        """Mirrors transitions.resolve from the impact LCP (30-32) on, after :meth:`classify`: the
        restitutions (Zeno memory), the right-hand side (builders.impact_lcp, _assemble: Newton's on the
        normal rows, J_T^T q'^- on the friction generators', zeros on the friction limits), its solution
        (``one(a, b, r_s, c_s, 1.0, 1e-11)`` as ContactLCP.solve for one unknown with its cached equilibration;
        else ``general()``: x from the right-hand side left in ``x``, or None unless solved), q'^+ = q'^- + Y x
        (``motion``), that no touching contact outside the LCP is pushed into approach (``_pushed``), the
        rates after it (``rate_bands``), and that no candidate is closed after it nor lifted without
        impacting (a micro-lift candidate). ``state``: :meth:`classify`'s.

        Returns 1 when all holds: ``x`` (the LCP's unknowns, the normal impulses first), ``v_new``, ``ke``
        (kinetic energy before, after) are the result and the Zeno memory (``max_approach``, ``impacts``) is
        updated; 0 otherwise, the memory untouched (the full path then runs; also for arrays of other shapes
        than :meth:`classify`'s: read and written without bounds checks)."""
        cdef Py_ssize_t i, j, k, n = v.shape[0], m = self.JNT.shape[0], na = self.na
        cdef Py_ssize_t size = mat.a.shape[0], p = mat.jt.shape[1], nw = na + p
        cdef signed char[::1] flags = self.flags
        cdef double g, e, big = 0.0, a, b0, t, scaled, s, top = 0.0, speed
        cdef const double[::1] xs
        if (na == 0 or mat.normal != na or mat.a.shape[1] != size or size < nw or mat.y.shape[1] != nw
                or mat.y.shape[0] != n or mat.jt.shape[0] != n or x.shape[0] != size or n != self.JNT.shape[1]
                or self.M.shape[0] != n or self.M.shape[1] != n or v_new.shape[0] != n or ke.shape[0] < 2
                or max_approach.shape[0] != m or impacts.shape[0] != m or state.shape[0] != 6
                or state.shape[1] != m):
            return 0
        cdef const double[::1] gv = state[3], tv = state[5]
        # restitutions: plastic for a settled contact or a Zeno impact (slower than zeno of its fastest);
        # the right-hand side in x, then the solution in its place
        for j in range(na):
            k = self.idx[j]
            e = self.eps[k]
            if flags[k] & APPROACHING:
                speed = -gv[k]
                if flags[k] & SETTLED or (impacts[k] and speed < zeno * max_approach[k]):
                    e = 0.0
                    flags[k] |= PLASTIC
            g = gv[k]
            x[j] = g + e * (g if g < 0.0 else 0.0)
        for j in range(p):   # J_T^T q'^-
            s = 0.0
            for i in range(n):
                s += mat.jt[i, j] * v[i]
            x[na + j] = s
        for j in range(nw, size):
            x[j] = 0.0
        for j in range(size):
            if fabs(x[j]) > big:
                big = fabs(x[j])
        for j in range(size):
            if fabs(x[j]) <= ROUND_OFF * big:
                x[j] = 0.0
        if size == 1 and self.one is not None:
            a, b0 = mat.a[0, 0], x[0]
            if not (isfinite(a) and 0.0 < mat.r_s[0] < INFINITY and 0.0 < mat.c_s[0] < INFINITY):
                return 0
            t = fabs(a) * mat.c_s[0]
            scaled = mat.r_s[0] * (t if not fabs(b0) > t else fabs(b0))   # _lcp.scaled_size
            if not isfinite(scaled):
                return 0
            res = self.one(a, b0, mat.r_s[0], mat.c_s[0], 1.0, 1e-11)
            if res is None:
                return 0
            x[0] = <double> res[1]
        else:
            sol = general()
            if sol is None:
                return 0
            xs = sol
            if xs.shape[0] != size:
                return 0
            for j in range(size):
                x[j] = xs[j]
        # q'^+ = q'^- + Y x (the response summed first, as ContactLCP.motion)
        for i in range(n):
            s = mat.y[i, 0] * x[0]
            for j in range(1, nw):
                s += mat.y[i, j] * x[j]
            v_new[i] = v[i] + s
        # _pushed: the touching contacts outside the LCP must not approach beyond their band (its floor over
        # those contacts only, as _tol of their columns)
        for k in range(m):
            if flags[k] & CANDIDATE and not flags[k] & ACTIVE:
                top = nmax(top, abs_dot(self.aJT, k, v_new))
        for k in range(m):
            if flags[k] & CANDIDATE and not flags[k] & ACTIVE:
                if dot(self.JNT, k, v_new) < -nmax(tv[k], ZERO * abs_dot(self.aJT, k, v_new) + 1e-3 * ZERO * top
                                                   + 1e-300):
                    return 0
        rate_bands(self.JNT, self.aJT, v_new, tv, self.rates)
        for k in range(m):
            if flags[k] & CANDIDATE:
                if fabs(self.rates[0, k]) <= self.rates[1, k]:   # closed after: the transition LCP decides
                    return 0
                if not flags[k] & APPROACHING and self.rates[0, k] > 0.0:   # a micro-lift candidate
                    return 0
        ke[0] = kinetic(self.M, &v[0])
        ke[1] = kinetic(self.M, &v_new[0])
        for k in range(m):   # the Zeno memory, as resolve updates it
            if flags[k] & APPROACHING:
                speed = -gv[k]
                if speed > max_approach[k]:
                    max_approach[k] = speed
                impacts[k] += 1
        return 1
