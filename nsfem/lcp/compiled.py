"""Lemke's method on the compiled kernels of the event core (nsfem/integrate/core/_lcp.pyx).

The same algorithm as :func:`nsfem.lcp.pivoting.lemke`, its reference: the same input checks, scalings,
pivoting rules and tie-breaking, polish and certificate, so the same basis, status and certificate
verdicts. The kernels run the pivoting loop, the one-unknown path, the equilibration, the polish (LU with
partial pivoting and the reference's refinement) of the basis z0 leaves behind when it ties for leaving
(how nearly every LCP ends) or of the final one, and the certificate in C; the rare branches (a secondary
ray, the refactorization every ``refactor`` pivots, the pivot limit, a basis singular to working precision)
call the reference's own Python helpers. The loops sum left to right where the reference calls BLAS, so
values agree to round-off, not bitwise (tests/test_core_lcp.py); w is numpy's A x + b, as the reference's.
"""

from __future__ import annotations

import math

import numpy as np

from .pivoting import (ACCEPT, LCPResult, _basic_x, _complementary, _covering, _finite, _polish_certified, _ray_end, _refactored,
                       _validated, _z0_tie)

_TRIVIAL = "trivial solution x = 0 (b >= 0)"
#: the certificate's keys, in the order of the kernel's numbers
_CERTIFICATE = ("x_min", "w_min", "complementarity", "relative")


def lemke(lib, A, b, *, d=None, max_pivots=None, scale=True, refactor=None, pivot_tol=1e-11, groups=None,
          scales=None) -> LCPResult:
    """:func:`nsfem.lcp.pivoting.lemke` (same arguments and result) on the kernels ``lib``."""
    A, b, d = _validated(A, b, d, lib.all_finite, groups, scales)
    n = b.size
    max_pivots = 50 * n + 1000 if max_pivots is None else int(max_pivots)
    refactor = max(50, n // 4) if refactor is None else int(refactor)
    # the kernel's counters are int64: limits beyond 2^62 are never reached, so clamping changes nothing
    limits = tuple(min(max(v, -2 ** 62), 2 ** 62) for v in (max_pivots, refactor))
    if scale and n:
        if scales is None:
            r_s, c_s = np.empty(n), np.empty(n)
            lib.equilibrate(A, r_s, c_s)
        else:
            r_s, c_s = (np.ascontiguousarray(s, dtype=float) for s in scales)
        if not math.isfinite(lib.scaled_size(A, b, r_s, c_s)):   # entries near 1e300: unscaled
            r_s, c_s = np.ones(n), np.ones(n)
    else:
        r_s, c_s = np.ones(n), np.ones(n)

    dv1 = 1.0 if d is None or n != 1 else float(r_s[0] * d[0])
    if n == 1 and max_pivots >= 2 and refactor >= 2 and 0.0 < dv1 < math.inf:   # (else: _covering's error)
        one = lemke_one(lib, float(A[0, 0]), float(b[0]), float(r_s[0]), float(c_s[0]), dv1, pivot_tol)
        if one is not None:
            return one

    gid = _group_ids(groups, n)

    def result(x, status, pivots, message):
        w = A @ x + b   # numpy's product, as the reference's result (its certificate is the kernel's)
        cert = dict(zip(_CERTIFICATE, lib.certificate(A, b, x, w, r_s, c_s, gid)))
        return _finite(LCPResult(x, w, status, pivots, cert["relative"], message, cert))

    if min(b.tolist(), default=0.0) >= 0:
        return result(np.zeros(n), "solved", 0, _TRIVIAL)

    As, bs = np.empty((n, n)), np.empty(n)
    lib.scale(A, b, r_s, c_s, As, bs)
    dv = _covering(r_s, d)
    eq = (As, bs, r_s, c_s)
    Binv, xB, basis, c = np.eye(n), bs.copy(), np.arange(n, dtype=np.int64), np.empty(n)
    state = np.array([2 * n, 0, 0, 0], dtype=np.int64)   # entering (z0 first), pivots, since refactor, skip tie
    while True:
        code = lib.pivot(As, dv, Binv, xB, basis, c, state, *limits, pivot_tol, d is None)
        entering, pivots = int(state[0]), int(state[1])
        if code == lib.DONE:
            break
        if code == lib.REFACTOR:
            fresh = _refactored(As, bs, dv, basis.tolist())
            if fresh is not None:
                Binv[:], xB[:] = fresh
            state[2] = 0
        elif code == lib.MAX_PIVOTS:
            return result(_basic_x(basis.tolist(), xB, n) * c_s, "max_pivots", pivots,
                          f"Lemke stopped after the limit of {max_pivots} pivots without a solution")
        elif code == lib.RAY:
            return _ray_end(A, b, basis.tolist(), xB, entering, pivots, eq, groups)
        else:   # Z0_TIE: the basis z0 leaves behind, when it certifies; else the pivoting goes on past the test
            x = np.empty(n)
            code = lib.polished(A, b, As, bs, r_s, c_s, basis, None, entering, gid, x)
            if code == lib.NEEDS_SVD:
                tied = _z0_tie(A, b, basis.tolist(), entering, pivots, eq, groups)
                if tied is not None:
                    return tied
            elif code == lib.FINISHED:
                res = result(x, "solved", pivots + 1, f"solved in {pivots + 1} pivots")
                if res.residual <= ACCEPT:
                    return res
            state[3] = 1

    x = np.empty(n)
    if lib.polished(A, b, As, bs, r_s, c_s, basis, xB, -1, gid, x) == lib.NEEDS_SVD:   # the reference's polish
        x = _polish_certified(A, b, _basic_x(basis.tolist(), xB, n) * c_s, basis.tolist(), n, eq, groups)[0]
    return _complementary(result(x, "solved", pivots, f"solved in {pivots} pivots"))


def lemke_one(lib, a: float, b: float, r_s: float, c_s: float, dv: float, pivot_tol: float) -> LCPResult | None:
    """:func:`lemke`'s result for one unknown (a x + b >= 0, x >= 0, complementary) on the equilibration
    (r_s, c_s) and covering dv, or None where the kernel declines (then :func:`lemke` decides)."""
    one = lib.lemke_one(a, b, r_s, c_s, dv, pivot_tol)
    if one is None:
        return None
    pivots, x, w, x_min, w_min, comp, rel = one
    cert = {"x_min": x_min, "w_min": w_min, "complementarity": comp, "relative": rel}
    # (x is finite: the kernel declines where c x is not, so _finite has nothing to say)
    return LCPResult(np.array([x]), np.array([w]), "solved", pivots, rel,
                     _TRIVIAL if pivots == 0 else "solved in 2 pivots", cert)


def _group_ids(groups, n: int) -> np.ndarray:
    """One int64 label per row for the kernels' certificate (the labels' ranks), or an empty array (no groups)."""
    if groups is None:
        return np.empty(0, dtype=np.int64)
    labels = np.asarray(groups).ravel()
    if labels.size == 0:
        return np.empty(0, dtype=np.int64)
    if labels.dtype.kind in "iub":
        return np.ascontiguousarray(labels, dtype=np.int64)
    # other labels as the reference's certificate keys them: a dict (Python's equality; each nan its own
    # group; labels numpy cannot order, None beside numbers, are labels too)
    ids: dict = {}
    return np.array([ids.setdefault(g, len(ids)) for g in labels.tolist()], dtype=np.int64)
