"""Lemke's complementary pivoting algorithm for LCP(A, b) (paper section 3.1).

Find x with

    w = A x + b >= 0,   x >= 0,   x^T w = 0.

Lemke's method augments the problem with an artificial variable z0 and a strictly
positive covering vector d (w = A x + b + d z0), starts from the almost-complementary
basis where z0 is just large enough to make w >= 0, and pivots complementary pairs in
and out until z0 leaves the basis (a solution) or the entering column has no positive
entry (a secondary ray).

Implementation notes:

- Revised form: the basis inverse B^-1 is kept explicitly (rank-one updates,
  refactorized every ``refactor`` pivots), so one pivot costs O(n^2) (one BLAS rank-one
  update in place).
- Anti-cycling: the lexicographic ratio test on the rows of [x_B, B^-1] / c_i, which
  makes every basis visited distinct, so degenerate problems (ties) terminate.
- Pivot tolerances are relative to the entering column; the problem is first
  equilibrated (positive row and column scaling leaves complementarity unchanged).
- The final basis is polished: x_S solves A_SS x_S = -b_S on the set S of basic x,
  in the original data, which removes the round-off the updates accumulated.
- Every result carries a certificate of w >= 0, x >= 0, x^T w = 0 computed from the
  original A and b; ``success`` is never claimed without it.

>>> import numpy as np
>>> res = lemke(np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-5.0, -6.0]))
>>> res.success, res.x.round(12).tolist(), bool(abs(res.w).max() < 1e-14)
(True, [1.333333333333, 2.333333333333], True)
>>> lemke(np.array([[-1.0]]), np.array([-1.0])).status     # w = -x - 1 >= 0 is infeasible
'ray'
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg as sla
from scipy.linalg.blas import dger as _dger
from scipy.linalg.lapack import dgetrf as _getrf, dgetrs as _getrs

from ..errors import NsfemError

__all__ = ["LCPError", "LCPResult", "lemke", "certificate", "equilibrate"]

#: ratios within this relative distance of the minimum are ties (lexicographic rule)
TIE = 1e-15
#: z0 competes for leaving when its ratio is within this relative distance of the minimum
NEAR_TIE = 1e-6
#: certificate (relative min-map residual) at which a complementary point is accepted
ACCEPT = 1e-8
#: a ray start where z0 vanished to round-off, certifying between ACCEPT and this, is reported
#: ``inaccurate`` (a near-solution), beyond it a ``ray``; a regular termination is ``solved``
#: only within ACCEPT and ``inaccurate`` otherwise
INACCURATE = 1e-4
#: rows whose terms are this small against the largest equilibrated row count as zero rows
FLOOR = 1e-10

_EPS, _TINY = float(np.finfo(float).eps), float(np.finfo(float).tiny)


class LCPError(NsfemError):
    """An LCP that could not be solved (the message carries Lemke's diagnosis)."""


@dataclass(frozen=True)
class LCPResult:
    """The outcome of :func:`lemke`.

    ``status`` is ``solved``, ``ray`` (secondary-ray termination), ``max_pivots`` or ``overflow`` (the
    solution is beyond the floating-point range: entries of A near 1e-300 against b near 1e300).
    ``residual`` is the relative min-map residual max_i |min(x_i / s_x, w_i / s_i)|
    (0 for an exact solution, see :func:`certificate`).
    """

    x: np.ndarray
    w: np.ndarray
    status: str
    pivots: int
    residual: float
    message: str
    certificate: dict

    @property
    def success(self) -> bool:
        return self.status == "solved"

    def check(self) -> LCPResult:
        """Return self when solved, else raise :class:`LCPError` with the diagnosis."""
        if not self.success:
            raise LCPError(self.message)
        return self


def certificate(A: np.ndarray, b: np.ndarray, x: np.ndarray, scales=None, groups=None) -> dict:
    """Residuals of the complementarity conditions of x for LCP(A, b).

    Returns ``x_min`` (most negative x_i, or 0), ``w_min`` (most negative w_i, or 0),
    ``complementarity`` max_i |x_i w_i| (original units), and ``relative``, the min-map
    residual max_i |min(x'_i / max|x'|, w_i / s_i)|: x' = C^-1 x in the equilibrated
    columns (``scales`` = (R, C) diagonals, computed when not given) and, row by row,
    s_i = |b_i| + sum_j |A_ij x_j|, the size of the terms that make w_i. This is a
    componentwise backward error: ``relative`` <= tol means x solves a problem whose
    every entry differs by at most about tol from the given one. ``groups`` (one label
    per row) relaxes it to rows of one physical kind: s_i is then the largest s_j of
    row i's group (gaps are judged against gaps, not against round-off of a zero slip).
    Rows whose terms are all below 1e-10 of the largest row (equilibrated) are judged
    against that floor.
    """
    return _certify(A, b, np.asarray(x, dtype=float), scales, groups)[1]


def _certify(A, b, x, scales, groups) -> tuple[np.ndarray, dict]:
    """(w = A x + b, :func:`certificate` of x)."""
    w = A @ x + b
    return w, _certificate(A, b, x, w, scales, groups)


def _certificate(A, b, x, w, scales, groups) -> dict:
    """:func:`certificate` of x with w = A x + b already formed.

    After the one product |A| |x| the work is per row and done on lists (an LCP of a few rows
    otherwise pays ~1 us per numpy call, ~25 of them); max and min are exact, so the values are
    numpy's. A non-finite x or w never certifies (numpy's nan propagation, kept)."""
    if x.size == 0:
        return {"x_min": 0.0, "w_min": 0.0, "complementarity": 0.0, "relative": 0.0}
    r, c = _equilibrate(A) if scales is None else scales
    xl, wl = x.tolist(), w.tolist()
    if not (all(map(math.isfinite, xl)) and all(map(math.isfinite, wl))):
        return {"x_min": float(min(0.0, x.min())), "w_min": float(min(0.0, w.min())),
                "complementarity": float(np.abs(x * w).max()), "relative": math.nan}
    sw = (np.abs(b) + np.abs(A) @ np.abs(x)).tolist()
    labels = None if groups is None else np.asarray(groups).tolist()
    if labels:
        top = {}
        for g, v in zip(labels, sw):
            if g not in top or v > top[g]:
                top[g] = v
        sw = [top[g] for g in labels]
    # a row whose terms are all below 1e-10 of the largest (equilibrated) row is round-off
    rl = r.tolist()
    floor = FLOOR * max(ri * v for ri, v in zip(rl, sw))
    sw = [max(v, floor / ri) for v, ri in zip(sw, rl)]
    xs = [xi / ci for xi, ci in zip(xl, c.tolist())]
    sx = max(max(map(abs, xs)), _TINY)
    rel = max(abs(min(e / sx, f / (v if v > 0 else 1.0))) for e, f, v in zip(xs, wl, sw))
    return {"x_min": min(0.0, min(xl)), "w_min": min(0.0, min(wl)),
            "complementarity": max(abs(xi * wi) for xi, wi in zip(xl, wl)), "relative": rel}


def equilibrate(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The row and column scalings (r, c) Lemke applies to A (``scales`` of :func:`lemke`)."""
    A = np.asarray(A, dtype=float)
    return _equilibrate(A) if A.size else (np.ones(A.shape[0]), np.ones(A.shape[0]))


def _equilibrate(A: np.ndarray, sweeps: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Positive row and column scalings r, c with r_i |A_ij| c_j of order one (Ruiz)."""
    n = A.shape[0]
    r, c = np.ones(n), np.ones(n)
    S = np.abs(A)
    for _ in range(sweeps):
        rm = S.max(axis=1)
        cm = S.max(axis=0)
        pr, pc = rm > 0, cm > 0
        fr = np.where(pr, 1.0 / np.sqrt(np.where(pr, rm, 1.0)), 1.0)
        fc = np.where(pc, 1.0 / np.sqrt(np.where(pc, cm, 1.0)), 1.0)
        if (fr == 1.0).all() and (fc == 1.0).all():
            break   # a fixed point: the remaining sweeps would change nothing
        r *= fr
        c *= fc
        S = fr[:, None] * S * fc[None, :]
    return r, c


def _lexmin(rows: np.ndarray, idx: np.ndarray) -> int:
    """Index (into idx) of the lexicographically smallest row, columns compared in turn.

    Entries equal to the column's least, or finite and within round-off of it, tie; an infinite entry
    ties only when equal (an overflowed ratio's tolerance is inf); a column holding a nan (overflowed
    data) keeps the first candidate."""
    cand = np.arange(len(idx))
    for k in range(rows.shape[1]):
        col = rows[cand, k]
        lo = col.min()
        with np.errstate(invalid="ignore"):   # (-inf + inf: no tie but the equal ones)
            tied = (col == lo) | (np.isfinite(col) & (col <= lo + 16 * TIE * np.maximum(np.abs(col), abs(lo))))
        cand = cand[tied] if tied.any() else cand[:1]
        if len(cand) == 1:
            break
    return int(cand[0])


def _covering(r_s: np.ndarray, d: np.ndarray | None) -> np.ndarray:
    """The covering vector of the equilibrated problem, R d (ones without d), or NsfemError where the
    scaling takes it out of the floating-point range (an entry of 0 or inf makes no covering vector)."""
    if d is None:
        return np.ones(r_s.size)
    dv = r_s * d
    if not (np.all(dv > 0) and np.all(np.isfinite(dv))):
        raise NsfemError("lemke: the covering vector d leaves the floating-point range once the problem is "
                         "scaled (R d underflows to 0 or overflows): give d of order one, or scale=False")
    return dv


def lemke(A, b, *, d=None, max_pivots: int | None = None, scale: bool = True, refactor: int | None = None,
          pivot_tol: float = 1e-11, groups=None, scales=None) -> LCPResult:
    """Solve LCP(A, b) by Lemke's method with the lexicographic anti-cycling rule.

    ``d`` is the covering vector (strictly positive, default ones in the equilibrated
    problem); ``max_pivots`` defaults to 50 n + 1000; the basis inverse is recomputed
    every ``refactor`` pivots (default max(50, n / 4)). ``groups`` labels rows of one
    physical kind for the certificate (see :func:`certificate`); default: row by row.
    ``scales``: the row and column scalings of A as :func:`equilibrate` returns them, when the
    caller has them (an LCP matrix solved many times with new right-hand sides); used when
    ``scale`` is true. The result is returned, never raised: check ``result.success`` or call
    ``result.check()``.

    Runs on the compiled kernels (:mod:`nsfem.lcp.compiled`) when the event core's part "lcp" is
    built and active (:func:`nsfem.integrate.core.compiled`); this function is their reference.
    """
    lib = _kernels()
    if lib is not None:
        return compiled.lemke(lib, A, b, d=d, max_pivots=max_pivots, scale=scale, refactor=refactor,
                              pivot_tol=pivot_tol, groups=groups, scales=scales)
    A, b, d = _validated(A, b, d, lambda A, b: bool(np.isfinite(A).all()) and all(map(math.isfinite, b.tolist())),
                         groups, scales)
    n = b.size
    bl = b.tolist()
    max_pivots = 50 * n + 1000 if max_pivots is None else int(max_pivots)
    refactor = max(50, n // 4) if refactor is None else int(refactor)

    if scale and n:
        r_s, c_s = _equilibrate(A) if scales is None else scales
        with np.errstate(over="ignore"):
            big = float(np.max(r_s)) * max(float(np.max(np.abs(A))) * float(np.max(c_s)), max(map(abs, bl)))
        if not math.isfinite(big):   # the equilibrated problem would overflow (entries near 1e300): unscaled
            r_s, c_s = np.ones(n), np.ones(n)
    else:
        r_s, c_s = np.ones(n), np.ones(n)

    dv1 = 1.0 if d is None or n != 1 else float(r_s[0] * d[0])
    if n == 1 and max_pivots >= 2 and refactor >= 2 and 0.0 < dv1 < math.inf:   # (else: _covering's error)
        one = _lemke_one(A, b, r_s, c_s, dv1, pivot_tol)
        if one is not None:
            return _finite(one)

    def result(x, status, pivots, message, cert=None):
        w = A @ x + b
        if cert is None:
            cert = _certificate(A, b, x, w, (r_s, c_s), groups)
        return _finite(LCPResult(x, w, status, pivots, cert["relative"], message, cert))

    if min(bl, default=0.0) >= 0:
        return result(np.zeros(n), "solved", 0, "trivial solution x = 0 (b >= 0)")

    As = r_s[:, None] * A * c_s[None, :]
    bs = r_s * b
    dv = _covering(r_s, d)
    eq = (As, bs, r_s, c_s)

    z0 = 2 * n  # variables: w_0..w_{n-1}, x_0..x_{n-1}, z0
    basis = list(range(n))
    Binv = np.eye(n, order="F")  # Fortran order: BLAS dger updates it in place
    xB = bs.copy()

    # first pivot: z0 enters where b_i / d_i is lexicographically smallest; with d = 1 the
    # rows [b_i, e_i] tied on b_i are told apart by e_i: the last of them is the smallest
    if d is None:
        levels = bs.tolist()
        lo = min(levels)
        r = [i for i, v in enumerate(levels) if v <= lo + 16 * TIE * max(abs(v), abs(lo))][-1]
    else:
        r = _lexmin(np.column_stack([xB / dv, Binv / dv[:, None]]), np.arange(n))
    entering = z0
    pivots = 0
    since_refactor = 0
    while True:
        # z0 enters only first, against B = I: its column -B^-1 d is -d exactly
        c = Binv @ _column(As, dv, entering) if entering != z0 else -dv
        if pivots > 0:
            tol, pos, theta, ties = _ratio_test(c, xB, pivot_tol)
            if not pos:   # a secondary ray (its start may still solve the LCP when z0 is ~0 in round-off)
                return _ray_end(A, b, basis, xB, entering, pivots, eq, groups)
            zrow = basis.index(z0)
            if c[zrow] > tol and xB[zrow] / c[zrow] <= theta * (1.0 + NEAR_TIE):
                # z0 ties for leaving (possibly only up to round-off in the data): the complementary
                # basis it leaves behind, accepted if it solves the LCP
                tied = _z0_tie(A, b, basis, entering, pivots, eq, groups)
                if tied is not None:
                    return tied
            if len(ties) == 1:
                r = ties[0]
            else:
                rows = np.column_stack([xB[ties], Binv[ties]]) / c[ties][:, None]
                r = ties[_lexmin(rows, ties)]
        # pivot on (r, entering)
        p = c[r]
        Binv[r] /= p
        xB[r] /= p
        row, cr = Binv[r].copy(), c.copy()
        cr[r] = 0.0
        Binv = _dger(-1.0, cr, row, a=Binv, overwrite_a=True)  # Binv -= outer(c, row), row r kept
        xB -= cr * xB[r]
        leaving = basis[r]
        basis[r] = entering
        pivots += 1
        since_refactor += 1
        np.maximum(xB, 0.0, out=xB)
        if leaving == z0:
            break
        if pivots >= max_pivots:
            x = _basic_x(basis, xB, n) * c_s
            return result(x, "max_pivots", pivots,
                          f"Lemke stopped after the limit of {max_pivots} pivots without a solution")
        if since_refactor >= refactor:
            fresh = _refactored(As, bs, dv, basis)
            if fresh is not None:
                Binv, xB = fresh
            since_refactor = 0
        entering = leaving + n if leaving < n else leaving - n

    x = _basic_x(basis, xB, n) * c_s
    x, cert = _polish_certified(A, b, x, basis, n, eq, groups)
    return _complementary(result(x, "solved", pivots, f"solved in {pivots} pivots", cert))


_core = None   # nsfem.integrate.core, once imported (nsfem.integrate imports this module through the builders)


def _kernels():
    """The compiled module of the event core's part "lcp", or None (the reference runs)."""
    global _core
    if _core is None:
        from ..integrate import core
        _core = core
    return _core.compiled("lcp")


def _validated(A, b, d, all_finite, groups=None, scales=None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(A, b, d) of :func:`lemke` as float arrays (A C-contiguous), or NsfemError naming what is wrong (also
    of ``groups`` and ``scales``: one label and one scaling per row); ``all_finite(A, b)`` tells whether
    every entry is finite."""
    A = np.asarray(A, dtype=float)
    b = np.asarray(b, dtype=float).ravel()
    n = b.size
    if A.shape != (n, n):
        raise NsfemError(f"lemke: A must be {n} x {n} to match b, got shape {A.shape}")
    A = np.ascontiguousarray(A)
    if not all_finite(A, b):
        raise NsfemError("lemke: A and b must be finite (found nan or inf)")
    if d is not None:
        d = np.array(d, dtype=float).ravel()
        if d.shape != (n,) or not np.all(d > 0) or not np.all(np.isfinite(d)):
            raise NsfemError("lemke: the covering vector d must be finite and strictly positive, one entry per row")
    if groups is not None and np.size(groups) != n:
        raise NsfemError(f"lemke: groups must label each of the {n} rows, got {np.size(groups)} labels")
    if scales is not None and (len(scales) != 2 or any(np.shape(s) != (n,) for s in scales)):
        raise NsfemError(f"lemke: scales must be the row and column scalings of equilibrate(A), {n} entries each")
    if scales is not None and not all(0.0 < v < math.inf for s in scales for v in np.asarray(s, dtype=float).tolist()):
        # (a zero row scaling would certify any point: the certificate judges row i against floor / r_i)
        raise NsfemError("lemke: scales must be finite and strictly positive (the row and column scalings of "
                         "equilibrate(A))")
    return A, b, d


def _column(As: np.ndarray, dv: np.ndarray, v: int) -> np.ndarray:
    """The column of variable v in [I, -As, -d] (w_0..w_{n-1}, x_0..x_{n-1}, z0)."""
    n = dv.size
    if v < n:
        e = np.zeros(n)
        e[v] = 1.0
        return e
    if v < 2 * n:
        return -As[:, v - n]
    return -dv


def _refactored(As: np.ndarray, bs: np.ndarray, dv: np.ndarray, basis) -> tuple[np.ndarray, np.ndarray] | None:
    """(B^-1, x_B) of the basis recomputed by LU, or None where the factorization fails (keep the updates)."""
    B = np.column_stack([_column(As, dv, v) for v in basis])
    try:
        lu = sla.lu_factor(B, check_finite=False)
        Binv = np.asfortranarray(sla.lu_solve(lu, np.eye(dv.size), check_finite=False))
        return Binv, np.maximum(sla.lu_solve(lu, bs, check_finite=False), 0.0)
    except (ValueError, np.linalg.LinAlgError):  # pragma: no cover - keep the updated inverse
        return None


def _ray_end(A, b, basis: list, xB: np.ndarray, entering: int, pivots: int, eq: tuple, groups) -> LCPResult:
    """The result where the entering column has no positive entry (a secondary ray).

    Its start may still solve the LCP when z0 is ~0 in round-off. The variable that just left (the
    complement of the entering one) may then have tied with z0 in exact arithmetic: the complementary
    basis with it in place of z0 is tried as well (measured: a stiff friction LCP whose x_7 left at
    3.5e-12 instead of z0 certifies to 1e-16 that way, to 8e-8 without it)."""
    As, bs, r_s, c_s = eq
    n = bs.size
    zrow = basis.index(2 * n)
    x = _polish(A, b, _basic_x(basis, xB, n) * c_s, basis, n, eq, groups)
    if entering < n:
        tied = list(basis)
        tied[zrow] = entering + n
        x = _polish(A, b, x, tied, n, eq, groups)
    w, cert = _certify(A, b, x, (r_s, c_s), groups)
    z0_gone = float(xB[zrow]) <= 1e-14 * max(float(np.max(np.abs(bs))), 1e-300)
    if cert["relative"] <= ACCEPT:
        return LCPResult(x, w, "solved", pivots, cert["relative"],
                         f"solved in {pivots} pivots (z0 vanished to round-off)", cert)
    if z0_gone and cert["relative"] <= INACCURATE:
        return LCPResult(x, w, "inaccurate", pivots, cert["relative"],
                         f"Lemke ended on a ray where z0 vanished to round-off after {pivots} pivots, "
                         f"but the point certifies only to {cert['relative']:.1e}: A is too "
                         "ill-conditioned for this LCP", cert)
    return LCPResult(x, w, "ray", pivots, cert["relative"],
                     _ray_message(pivots, xB[zrow:zrow + 1], _psd_hint(A)), cert)


def _z0_tie(A, b, basis: list, entering: int, pivots: int, eq: tuple, groups) -> LCPResult | None:
    """z0 ties for leaving (possibly only up to round-off in the data): the complementary basis it
    leaves behind, solved, when its point certifies (else None: the pivoting goes on)."""
    n = eq[1].size
    trial = list(basis)
    trial[trial.index(2 * n)] = entering
    x = _polish(A, b, None, trial, n, eq, groups)
    if x is not None:
        w, cert = _certify(A, b, x, eq[2:], groups)
        if cert["relative"] <= ACCEPT:
            return LCPResult(x, w, "solved", pivots + 1, cert["relative"], f"solved in {pivots + 1} pivots", cert)
    return None


def _complementary(res: LCPResult) -> LCPResult:
    """The result of a complementary basis: ``solved`` only when its point certifies.

    A complementary basis is a solution only when its point certifies (componentwise backward error
    ACCEPT); on bases of condition ~1e13 the refined solve can leave rows violated by 1e-7..1e-1 of
    their terms (measured: stiff friction LCPs, tests/test_lemke.py): not 'solved'."""
    if res.success and not res.residual <= ACCEPT:   # (a nan certificate: an overflowed A x is no solution)
        return LCPResult(res.x, res.w, "inaccurate", res.pivots, res.residual,
                         f"Lemke reached a complementary basis after {res.pivots} pivots but the solution is "
                         f"inaccurate (relative residual {res.residual:.1e}): A is too ill-conditioned for this LCP",
                         res.certificate)
    return res


#: LCPs up to this many unknowns take the ratio test on lists (a numpy call costs as much as ~20
#: list entries; measured on random PD LCPs: lists win below ~25 unknowns, lose 40 % at 500)
SMALL = 24


def _ratio_test(c: np.ndarray, xB: np.ndarray, pivot_tol: float) -> tuple[float, list, float | None, list]:
    """(tol, pos, theta, ties): the rows where c_i > tol = pivot_tol max|c| (a nan in c makes tol
    nan: no row, the ray, as np.max would), the least ratio xB_i / c_i over them and the rows
    equal to it or within TIE of it (exact ties and round-off; the first row where a nan ratio leaves
    none). The same values on lists and arrays (but for a nan ratio: numpy's min returns it)."""
    n = c.size
    if n <= SMALL:
        cl, xl = c.tolist(), xB.tolist()
        cmax = max(map(abs, cl)) if not math.isnan(sum(cl)) else math.nan
        tol = pivot_tol * max(cmax, 1e-300)
        pos = [i for i in range(n) if cl[i] > tol]
        if not pos:
            return tol, pos, None, []
        ratios = [xl[i] / cl[i] for i in pos]
        theta = min(ratios)
        ties = [i for i, q in zip(pos, ratios) if q == theta or q <= theta + TIE * abs(theta)]
        return tol, pos, theta, ties or pos[:1]   # (none: a nan ratio, overflowed data: the first)
    tol = pivot_tol * max(np.abs(c).max(), 1e-300)
    pos = np.flatnonzero(c > tol)
    if pos.size == 0:
        return tol, [], None, []
    ratios = xB[pos] / c[pos]
    theta = ratios.min()
    with np.errstate(invalid="ignore"):
        ties = pos[(ratios == theta) | (ratios <= theta + TIE * abs(theta))].tolist()
    return tol, pos.tolist(), theta, ties or pos[:1].tolist()


def _lemke_one(A: np.ndarray, b: np.ndarray, r_s: np.ndarray, c_s: np.ndarray, dv: float,
               pivot_tol: float) -> LCPResult | None:
    """:func:`lemke` on one unknown (most impact LCPs of a run), in float arithmetic: the same
    operations in the same order, so bitwise the same result, without numpy's overhead of ~1 us
    per call on 1-element arrays (~40 calls). x = 0 when b >= 0; else z0 enters, then x enters
    and z0 leaves, and the basis {x} is polished (:func:`_solve_one`) and certified. None where
    the general loop takes another branch (a ray, a basis that does not polish or certify)."""
    a, bb, r, c = float(A[0, 0]), float(b[0]), float(r_s[0]), float(c_s[0])
    if bb >= 0.0:
        return _result_one(a, bb, c, r, 0.0, 0, "trivial solution x = 0 (b >= 0)")
    s = r * a * c                         # the equilibrated a
    if not math.isfinite(r * bb / -dv):   # z0's level after its pivot (inf: the ratio test fails)
        return None
    col = 0.0 + (1.0 / -dv) * -s          # x's column after z0's pivot (0.0 +: BLAS's sum)
    if not col > pivot_tol * max(abs(col), 1e-300):
        return None
    x = _solve_one(s, -r * bb)
    if x is None or not math.isfinite(c * x):
        return None
    y = c * x
    res = _result_one(a, bb, c, r, y if y > 0.0 else 0.0, 2, "solved in 2 pivots")
    return res if res.residual <= ACCEPT else None


def _solve_one(B: float, rhs: float, x0: float | None = None) -> float | None:
    """:func:`_refined_solve` of one equation (B != 0), in floats: the same operations in the
    same order (``0.0 +``: the sum BLAS starts from). None where it would fall back to the SVD or
    find no finite solution."""
    if not abs(B) > _EPS * max(abs(B), 1e-300):
        return None
    x = rhs / B if x0 is None else x0
    if not math.isfinite(x):
        return None
    worst = math.inf
    for _ in range(REFINE_STEPS + 1):
        res = rhs - (0.0 + B * x)
        size = (0.0 + abs(B) * abs(x)) + abs(rhs)
        now = abs(res) / (size if size > 0 else 1.0)
        if not now < worst or now <= 4 * _EPS:
            break
        worst = now
        dx = res / B
        if not math.isfinite(dx):
            break
        x = x + dx
    return x


def _finite(res: LCPResult) -> LCPResult:
    """``res``, or its ``overflow`` verdict when its solution, or A x + b, is not finite."""
    if res.success and not (all(map(math.isfinite, res.x.tolist())) and all(map(math.isfinite, res.w.tolist()))):
        return replace(res, status="overflow",
                       message="the solution, or A x + b, is beyond the floating-point range (overflow)")
    return res


def _result_one(a: float, b: float, c: float, r: float, x: float, pivots: int, message: str) -> LCPResult:
    """The solved :class:`LCPResult` of x for LCP(a, b) with its certificate (:func:`_certificate`
    on one row, in floats)."""
    w = (0.0 + a * x) + b
    xs = x / c
    sw = abs(b) + (0.0 + abs(a) * abs(x))
    floor = FLOOR * (r * sw) / r
    sw = sw if sw > floor else floor
    sw = sw if sw > 0 else 1.0
    e, f = xs / max(abs(xs), _TINY), w / sw
    rel = abs(e if e < f else f)
    cert = {"x_min": min(0.0, x), "w_min": min(0.0, w), "complementarity": abs(x * w), "relative": rel}
    return LCPResult(np.array([x]), np.array([w]), "solved", pivots, rel, message, cert)


def _basic_x(basis, xB: np.ndarray, n: int) -> np.ndarray:
    x = np.zeros(n)
    for i, v in enumerate(basis):
        if n <= v < 2 * n:
            x[v - n] = xB[i]
    return x


def _polish(A: np.ndarray, b: np.ndarray, x: np.ndarray | None, basis: list, n: int, eq: tuple,
            groups=None) -> np.ndarray:
    """Re-solve the complementary basis (A_SS x_S = -b_S, equilibrated: ``eq`` = (R A C, R b, R, C)),
    refined from the pivoting's x where given (:func:`_refined_solve`); keep the better x."""
    return _polish_certified(A, b, x, basis, n, eq, groups)[0]


def _polish_certified(A, b, x, basis, n, eq, groups=None) -> tuple[np.ndarray, dict | None]:
    """:func:`_polish`, with the certificate of the x it keeps when it computed one (else None)."""
    As, bs, r_s, c_s = eq
    S = sorted(v - n for v in basis if n <= v < 2 * n)
    y = [0.0] * n
    if S:
        cS = c_s.take(S)
        xs = _refined_solve(As.take(S, 0).take(S, 1), -bs.take(S), None if x is None else x.take(S) / cS)
        if xs is None:
            return x, None
        for i, v in zip(S, (cS * xs).tolist()):
            y[i] = v
    if not all(map(math.isfinite, y)):
        return x, None
    y = np.array([v if v > 0.0 else 0.0 for v in y])   # np.maximum(y, 0): -0.0 becomes 0.0 too
    if x is None:
        return y, None
    sc = (r_s, c_s)
    cy, cx = certificate(A, b, y, sc, groups), certificate(A, b, x, sc, groups)
    return (y, cy) if cy["relative"] <= cx["relative"] else (x, cx)


#: iterative-refinement steps of the final basis solve (Skeel: one step in working precision
#: already gives a componentwise backward error of a few eps when cond(A) eps << 1)
REFINE_STEPS = 3


def _refined_solve(B: np.ndarray, rhs: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray | None:
    """x with B x = rhs, refined in working precision until every row's residual is a few eps
    of its own terms |B| |x| + |rhs|.

    A direct solve is backward stable in norm only: a row whose terms are small next to the
    other rows' keeps a residual of eps ||B|| ||x||, large relative to that row (measured: 1e-7
    of the row's terms on a stiff friction LCP, cond 1e21, so that a sticking contact's slip row
    read w = -3e-12 where its terms are 2e-5). Each step r = rhs - B x, x += B^+ r brings every
    row to a few eps of its own terms (Skeel 1980; Higham, Accuracy and Stability of Numerical
    Algorithms, section 12.2), whatever the BLAS's summation order. B^+ is B^-1 through LU, or
    the pseudo-inverse (SVD) when B is singular: a basis that ends on a ray with z0 at round-off
    leaves a rank-deficient but consistent A_SS; the correction then stays in its range, so the
    start ``x0`` (the pivoting's nonnegative x) is only nudged. Returns None when no finite
    solution is found. LAPACK's getrf and getrs are called directly: scipy's lu_factor and
    lu_solve wrap the same calls in ~6 us of batching and warning machinery each."""
    b00 = float(B[0, 0]) if B.shape == (1, 1) else 0.0
    if abs(b00) > _EPS * max(abs(b00), 1e-300):
        # one unknown: LU is the pivot itself and its solve a division (bitwise the same)
        x = _solve_one(b00, float(rhs[0]), None if x0 is None else float(x0[0]))
        return None if x is None else np.array([x])
    with np.errstate(all="ignore"):
        svd = None
        lu, piv, info = _getrf(B)
        aB, arhs = np.abs(B), np.abs(rhs)
        small = _EPS * max(float(aB.max()), 1e-300)
        if info != 0 or not all(abs(u) > small for u in lu.diagonal().tolist()):
            lu = None
            try:
                U, sv, Vt = np.linalg.svd(B)
            except np.linalg.LinAlgError:
                return None
            keep = sv > B.shape[0] * _EPS * max(float(sv[0]) if sv.size else 0.0, 1e-300)
            svd = (U[:, keep], sv[keep], Vt[keep])

        def solve(v):
            if lu is not None:
                return _getrs(lu, piv, v)[0]
            U, sv, Vt = svd
            return Vt.T @ ((U.T @ v) / sv)

        x = solve(rhs) if x0 is None else np.array(x0, dtype=float)
        if not all(map(math.isfinite, x.tolist())):
            return None
        worst = np.inf
        for _ in range(REFINE_STEPS + 1):
            r = rhs - B @ x
            size = aB @ np.abs(x) + arhs
            ratios = [abs(ri) / (si if si > 0 else 1.0) for ri, si in zip(r.tolist(), size.tolist())]
            now = max(0.0, *ratios) if not math.isnan(sum(ratios)) else math.nan   # as numpy's max: nan wins
            if not now < worst or now <= 4 * _EPS:
                break
            worst = now
            dx = solve(r)
            if not all(map(math.isfinite, dx.tolist())):
                break
            x = x + dx
    return x


def _psd_hint(A: np.ndarray) -> float | None:
    """Smallest eigenvalue of the symmetric part (relative), or None when too large to check."""
    if A.shape[0] > 2000:
        return None
    with np.errstate(over="ignore", invalid="ignore"):   # (entries near 1e308: no hint)
        H = 0.5 * (A + A.T)
        scale = max(float(np.max(np.abs(H))), 1e-300)
        try:
            return float(np.linalg.eigvalsh(H / scale)[0])
        except np.linalg.LinAlgError:   # not finite (an overflowed sum), or LAPACK did not converge
            return None


def _ray_message(pivots: int, z0_value, eig: float | None) -> str:
    z = float(z0_value[0]) if len(z0_value) else 0.0
    head = f"Lemke ended on a secondary ray after {pivots} pivots (artificial variable z0 = {z:.3g} > 0)"
    if eig is not None and eig >= -1e-14:
        return head + ": A is positive semi-definite, so this proves the LCP has no solution"
    return (head + ": no solution exists if A is copositive-plus; A is not positive semi-definite here, "
            "so a solution may exist that Lemke's method cannot reach")


from . import compiled  # noqa: E402  (the compiled path drives this module's helpers)
