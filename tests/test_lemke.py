"""Lemke's method (nsfem.lcp): brute-force references, properties, classic hard cases, contact LCPs.

LCP(A, b): find x >= 0 with w = A x + b >= 0 and x^T w = 0.

Theory the assertions rest on (Cottle, Pang & Stone, "The Linear Complementarity Problem"):

- P-matrix (all principal minors > 0, e.g. positive definite, symmetric or not): the solution
  is unique for every b, and Lemke's method finds it.
- Copositive-plus (e.g. positive semi-definite, symmetric or not): Lemke's method with any
  covering vector d > 0 and an anti-cycling rule ends on a secondary ray only if the LCP is
  infeasible, so "solved" <=> "a solution exists". Positive row/column scalings (the solver's
  equilibration) only change the covering vector, so this holds with scale=True as well.
- Monotone LCP with a symmetric PSD A: all solutions share the same w = A x + b
  ((x1 - x2)^T A (x1 - x2) = -x1^T w2 - x2^T w1 <= 0 forces A (x1 - x2) = 0).
- Copositive A and b^T y >= 0 for every y in SOL(0, A): Lemke's method computes a solution
  (Thm 4.4.13; Anitescu & Potra 1997 use it for the frictional contact LCP, section 7 here).
"""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from nsfem.errors import NsfemError
from nsfem.lcp import LCPError, LCPResult, certificate, lemke

STATUSES = {"solved", "ray", "max_pivots", "inaccurate"}

# Accuracy of a "solved" result. Lemke's final basis is re-solved and refined until every
# basis row's residual is <= 4 eps of its own terms (nsfem.lcp.pivoting._refined_solve);
# forming w = A x + b adds <= (n + 1) eps of them: (n + 5) eps = 5.1e-15 for the largest LCP
# in this file (n = 18). ROW_TOL = 1e-13 is a margin of 20 (measured <= 4 eps, all BLAS).
ROW_TOL = 1e-13
# A degenerate entry (a basic x_j or a non-basic w_i that is 0 in exact arithmetic) moves by
# that residual times the amplification |A_NS A_SS^-1| (|A_SS| |x_S| + |b_S|) / (|A| X), which
# is <= 2 on the degenerate rows of every final basis in this file (computed from them):
# <= 2 (n + 5) eps = 1e-14 of |A| X. FLOOR = 1e-12 is a margin of 100 (measured <= 1.3 eps).
FLOOR = 1e-12


# --------------------------------------------------------------------------------------------
# reference solver and independent checks
# --------------------------------------------------------------------------------------------

def brute_force(A, b, cond_max=1e8, tol=1e-9, first=False):
    """All complementary basic solutions of LCP(A, b) with a well-conditioned basis.

    For every index set S: x_S solves A_SS x_S = -b_S, x = 0 elsewhere. Near-singular A_SS
    (cond > cond_max) are skipped: they give huge spurious "solutions" made of round-off.
    x is accepted when it passes the row-wise test of :func:`lcp_violation` with tol = 1e-9 and
    a round-off floor of 1e-8 (the solve is accurate to ~cond * eps relative: 2e-8 at
    cond_max, but the bases of the seeded problems below have cond(A_SS) <= 6.1e4, i.e.
    ~1e-11), so true solutions (exact zeros come out ~1e-16) and infeasible sets (violations
    of order one) are separated by a wide margin on both sides of these thresholds.
    ``first``: stop at the first solution (a solvability test).
    """
    A = np.asarray(A, dtype=float)
    b = np.asarray(b, dtype=float)
    n = b.size
    sols = []
    for k in range(n + 1):
        for S in itertools.combinations(range(n), k):
            x = np.zeros(n)
            if k:
                idx = list(S)
                ASS = A[np.ix_(idx, idx)]
                try:
                    xs = np.linalg.solve(ASS, -b[idx])
                except np.linalg.LinAlgError:
                    continue
                if xs.min() < -1e-8 * np.max(np.abs(xs)):  # cheap early exit: the x < 0 test below
                    continue
                # the subsystem itself must be solved (residual relative to its terms): LU with
                # partial pivoting leaves ~n eps = 1.3e-15 for n <= 6, so 1e-12 only rejects the
                # garbage of an exactly singular A_SS that LAPACK did not flag
                res = ASS @ xs + b[idx]
                if not np.max(np.abs(res)) <= 1e-12 * (np.max(np.abs(ASS) @ np.abs(xs) + np.abs(b[idx])) + 1e-300):
                    continue
                x[idx] = xs
            if lcp_violation(A, b, x, tol=tol, floor=1e-8):
                continue
            if k and not np.linalg.cond(ASS) <= cond_max:  # (checked last: the costly test)
                continue
            sols.append(np.maximum(x, 0.0))
            if first:
                return sols
    return sols


def lcp_violation(A, b, x, tol=ROW_TOL, floor=FLOOR, explain=False, groups=None):
    """Why x fails to solve LCP(A, b), row by row ('' when it solves it).

    Each row is judged against its own terms s_i = |b_i| + sum_j |A_ij| |x_j| (so rows in
    different units, gaps in m and forces in N, or an open contact with a large gap, do not
    hide the others' violations), plus a round-off floor a_i = floor * sum_j |A_ij| X_j,
    X_j the largest |x_k| among the unknowns of x_j's unit group (``groups``: one label per
    unknown, default one group): a degenerate basic x_j that should be 0 comes out of the
    basis solve as ~1e-17 X_j (a contact without normal force carries beta ~ 1e-32), not
    ~1e-17 |x_j|. The defaults ROW_TOL and FLOOR are derived at the top of the file. Requires
    x_j >= -floor X_j, w_i >= -(tol s_i + a_i), and |w_i| <= tol s_i + a_i where
    x_i > floor X_i. ``explain`` adds the numbers (slow: array formatting).
    """
    A = np.asarray(A, dtype=float)
    b = np.asarray(b, dtype=float)
    x = np.asarray(x, dtype=float)
    if not np.all(np.isfinite(x)):
        return "x not finite"
    ax = np.abs(x)
    if groups is None:
        X = np.full(x.shape, float(np.max(ax, initial=0.0)))
    else:
        groups = np.asarray(groups)
        X = np.array([ax[groups == g].max() for g in groups])
    if np.any(x < -floor * X):
        return f"x < 0: {x}" if explain else "x < 0"
    xp = np.maximum(x, 0.0)
    w = A @ xp + b
    allowed = tol * (np.abs(b) + np.abs(A) @ xp) + floor * (np.abs(A) @ X)
    if np.any(w < -allowed):
        return f"w < 0: w = {w}, allowed {allowed}" if explain else "w < 0"
    active = xp > floor * X
    if np.any(np.abs(w[active]) > allowed[active]):
        return f"x > 0 and w > 0: x = {x}, w = {w}, allowed {allowed}" if explain else "x w > 0"
    return ""


def assert_lcp_solution(A, b, x, tol=ROW_TOL, floor=FLOOR, groups=None):
    """Independent check (not the solver's certificate) that x solves LCP(A, b): x >= 0
    exactly (the solver clips) and the row-wise test of :func:`lcp_violation`."""
    x = np.asarray(x, dtype=float)
    assert x.shape == np.shape(b)
    assert x.min(initial=0.0) >= 0.0, x
    why = lcp_violation(A, b, x, tol, floor, groups=groups)
    assert not why, lcp_violation(A, b, x, tol, floor, explain=True, groups=groups)


def unique_reference(A, b):
    """The unique solution of a P-matrix LCP by brute force (all accepted sets must agree)."""
    sols = brute_force(A, b)
    assert sols, "brute force found no solution of a P-matrix LCP"
    ref = sols[0]
    for s in sols[1:]:
        # two normwise-stable solves of bases with cond <= 1.1e3 (the Delassus matrices at unit
        # scale; P-matrices here <= 62): 2 n cond eps <= 2.8e-12, margin 3.6 (measured 3 eps)
        assert np.allclose(s, ref, rtol=0, atol=1e-11 * max(np.max(np.abs(ref)), 1e-300))
    return ref


def assert_close(x, ref, rel):
    scale = max(float(np.max(np.abs(ref))), 1e-300) if ref.size else 1.0
    assert np.max(np.abs(x - ref), initial=0.0) <= rel * scale, (x, ref)


def assert_proves_infeasible(message):
    # the ray message for a PSD matrix: Lemke's ray proves that no solution exists
    assert "no solution" in message and "positive semi-definite" in message, message
    assert "not positive semi-definite" not in message, message


def is_p_matrix(A):
    n = A.shape[0]
    return all(np.linalg.det(A[np.ix_(S, S)]) > 0
               for k in range(1, n + 1) for S in map(list, itertools.combinations(range(n), k)))


# --------------------------------------------------------------------------------------------
# random problem classes (n = 1..6)
# --------------------------------------------------------------------------------------------

def spd(rng, n):
    # eigenvalues in [0.1, 10]: cond <= 100
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return (Q * rng.uniform(0.1, 10.0, n)) @ Q.T


def p_nonsymmetric(rng, n):
    kind = rng.integers(3)
    if kind == 0:    # strictly row diagonally dominant, positive diagonal
        A = rng.standard_normal((n, n))
        np.fill_diagonal(A, np.abs(A).sum(axis=1) - np.abs(np.diag(A)) + rng.uniform(0.1, 1.0, n))
    elif kind == 1:  # positive definite, not symmetric: G G^T + cI + skew
        G = rng.standard_normal((n, n))
        K = rng.standard_normal((n, n))
        A = G @ G.T + 0.2 * np.eye(n) + 2.0 * (K - K.T)
    else:            # permuted triangular with positive diagonal and big off-diagonals: P but not PD
        T = np.triu(rng.uniform(-3.0, 3.0, (n, n)), 1) + np.diag(rng.uniform(0.5, 2.0, n))
        p = rng.permutation(n)
        A = T[np.ix_(p, p)]
    return A


def psd_rank_deficient(rng, n):
    k = int(rng.integers(0, n))  # rank 0..n-1
    G = rng.standard_normal((n, k))
    return G @ G.T


def monotone_nonsymmetric(rng, n):
    # PSD (x^T A x = |G^T x|^2 >= 0) but not symmetric and, when k < n, not PD
    k = int(rng.integers(0, n))
    G = rng.standard_normal((n, k))
    K = rng.standard_normal((n, n)) * (rng.random((n, n)) < 0.5)
    return G @ G.T + (K - K.T)


def delassus(rng, m, n_modes):
    """J^T M^-1 J with J (n_modes x m): with m > n_modes it has rank n_modes < m."""
    G = rng.standard_normal((n_modes, n_modes))
    M = G @ G.T + n_modes * np.eye(n_modes)
    J = rng.standard_normal((n_modes, m))
    D = J.T @ np.linalg.solve(M, J)
    return 0.5 * (D + D.T)


def degenerate_b(rng, n):
    # integers with repeats and zeros: ties in the ratio tests, degenerate bases
    return rng.choice([-2.0, -1.0, -1.0, 0.0, 0.0, 1.0], n)


CASES = 200  # per class; n = 1..6


def _sizes(seed):
    rng = np.random.default_rng(seed)
    return rng, int(rng.integers(1, 7))


# --------------------------------------------------------------------------------------------
# 1. brute-force comparison
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["spd", "p-nonsymmetric", "spd-degenerate-b", "p-degenerate-b"])
def test_unique_solution_matches_brute_force(kind):
    # P-matrices: unique solution. Both sides solve the same principal subsystem (cond(A_SS)
    # <= 62 over these 800 problems, n <= 6): x to 2 n cond eps = 1.6e-13 (normwise solve of the
    # reference, refined solve of Lemke) and the certificate to n cond eps = 8e-14 (a
    # non-basic w_i inherits the basis' forward error). 1e-12: margins 6 and 12; measured 9 eps.
    for seed in range(CASES):
        rng, n = _sizes(seed)
        A = spd(rng, n) if kind.startswith("spd") else p_nonsymmetric(rng, n)
        b = degenerate_b(rng, n) if kind.endswith("degenerate-b") else rng.standard_normal(n) * 3
        if kind == "p-nonsymmetric" or kind == "p-degenerate-b":
            assert is_p_matrix(A)
        ref = unique_reference(A, b)
        for scale in (True, False):
            res = lemke(A, b, scale=scale)
            assert res.status == "solved", (seed, scale, res.message, A, b)
            assert_lcp_solution(A, b, res.x)
            assert_close(res.x, ref, 1e-12)
            assert res.certificate["relative"] < 1e-12


@pytest.mark.parametrize("kind", ["psd-rank-deficient", "psd-degenerate-b", "delassus", "monotone-nonsymmetric"])
def test_psd_solved_iff_solvable(kind):
    # copositive-plus: solved <=> brute force finds a solution; symmetric PSD: unique w
    solved = rays = 0
    for seed in range(CASES):
        rng, n = _sizes(seed)
        if kind == "delassus":
            n = max(n, 2)
            A = delassus(rng, n, int(rng.integers(1, n)))   # more contacts than modes
            b = rng.standard_normal(n)
        elif kind == "monotone-nonsymmetric":
            A, b = monotone_nonsymmetric(rng, n), rng.standard_normal(n)
        elif kind == "psd-degenerate-b":
            G = rng.integers(-2, 3, (n, int(rng.integers(0, n)))).astype(float)
            A, b = G @ G.T, degenerate_b(rng, n)            # integer data: exact ties
        else:
            A, b = psd_rank_deficient(rng, n), rng.standard_normal(n)
        sols = brute_force(A, b)
        symmetric = kind != "monotone-nonsymmetric"
        if symmetric and len(sols) > 1:  # the reference itself must respect w-uniqueness
            for s in sols[1:]:
                # bases up to cond 6.1e4 here: w from two solves differs by <= 2 n cond eps s
                # = 1.6e-10 s; 1e-8 is a margin of 60 (measured: exact, or 0.03 eps)
                scale = np.max(np.abs(b)) + np.max(np.abs(A)) * max(np.max(s), np.max(sols[0]))
                assert np.max(np.abs(A @ (s - sols[0]))) <= 1e-8 * scale
        for scale in (True, False):
            res = lemke(A, b, scale=scale)
            assert res.status in ("solved", "ray"), (seed, res.message)
            if sols:
                assert res.status == "solved", (seed, scale, res.message, A, b)
                assert_lcp_solution(A, b, res.x)
                # a non-basic w_i carries the basis' forward error: <= n cond eps = 8e-11 with
                # cond(A_SS) <= 6.1e4 (rank-deficient class); margin 12 (measured 2 eps)
                assert res.certificate["relative"] < 1e-9
                if symmetric:
                    # w = A x + b from two solves with cond <= 6.1e4: bound 2 n cond eps s = 1.6e-10 s,
                    # margin 60; measured <= 12 eps s
                    s = np.max(np.abs(b)) + np.max(np.abs(A)) * max(np.max(res.x), np.max(sols[0]))
                    assert np.max(np.abs(res.w - (A @ sols[0] + b))) <= 1e-8 * s
            else:
                assert res.status == "ray", (seed, scale, res.message, A, b)
                assert_proves_infeasible(res.message)
                with pytest.raises(LCPError):
                    res.check()
        solved += bool(sols)
        rays += not sols
    # the classes must exercise both outcomes (rank 0 matrices alone give rays). Measured on
    # every BLAS config (solvability is decided by order-one violations, not by round-off):
    # 117/83, 104/96, 146/54, 167/33 solved/rays for the four classes; the floors are ~90 %
    # of the smallest of each
    assert solved >= 90 and rays >= 30, (solved, rays)


# --------------------------------------------------------------------------------------------
# 2. properties (hypothesis)
# --------------------------------------------------------------------------------------------

# entries below 1e-300 in magnitude (subnormals) are rounded to 0: exact zeros keep the
# degenerate cases, and subnormals carry no relative precision for the bounds below. (An older
# comment here said 1e-3, which the code never did: entries 1e10 apart, the bug of
# test_pd_with_entries_1e10_apart, are drawn and pass since ties became relative 1e-15.)
unit = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False).map(lambda v: 0.0 if abs(v) < 1e-300 else v)
rhs = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False).map(lambda v: 0.0 if abs(v) < 1e-300 else v)


@st.composite
def pd_problems(draw, symmetric=True, max_n=8):
    n = draw(st.integers(1, max_n))
    G = draw(hnp.arrays(np.float64, (n, n), elements=unit))
    b = draw(hnp.arrays(np.float64, n, elements=rhs))
    A = G @ G.T + 0.1 * np.eye(n)  # eigenvalues in [0.1, 64.1]: cond <= 641
    if not symmetric:
        K = draw(hnp.arrays(np.float64, (n, n), elements=unit))
        A = A + K - K.T  # still positive definite: x^T A x = x^T (G G^T + 0.1 I) x
        # |A y| >= 0.1 |y| and ||A|| <= 64.1 + 2 ||K|| <= 80.1: cond <= 801, for every
        # principal submatrix too
    return A, b


# every hypothesis problem has cond(A_SS) <= 801 and n <= 8: a non-basic w_i (certificate) is
# accurate to n cond eps s = 1.4e-12 s, x to 2 n cond eps = 2.8e-12 relative when two solves
# are compared. PD_TOL = 1e-11 is a margin of 3.5 to 7 over these worst cases (measured on
# ~5500 random draws, two BLAS configs: cond <= 120, errors <= 70 eps = 1.6e-14).
PD_TOL = 1e-11


def assert_pd_solved(A, b, res):
    assert res.status == "solved", res.message
    assert res.certificate["relative"] < PD_TOL
    assert res.residual == res.certificate["relative"]
    assert res.x.min() >= 0.0
    s = np.max(np.abs(b)) + np.max(np.abs(A)) * np.max(res.x, initial=0.0) + 1e-300
    # basic rows: refined residual, (n + 5) eps s; non-basic rows: the basis' forward error,
    # n cond eps s = 1.4e-12 s (the former 1e-12 was below this bound); measured <= 1.4 eps s
    assert res.w.min() >= -PD_TOL * s
    assert np.max(np.abs(res.x * res.w)) <= PD_TOL * s * (np.max(res.x) + 1e-300)
    # exact: w is A @ x + b on the same arrays (a different value means w was not recomputed)
    np.testing.assert_array_equal(res.w, A @ res.x + b)


@settings(derandomize=True, max_examples=80, deadline=None)
@given(pd_problems(symmetric=True))
def test_property_pd_symmetric_solved(prob):
    A, b = prob
    assert_pd_solved(A, b, lemke(A, b))


@settings(derandomize=True, max_examples=80, deadline=None)
@given(pd_problems(symmetric=False))
def test_property_pd_nonsymmetric_solved(prob):
    A, b = prob
    assert_pd_solved(A, b, lemke(A, b))
    assert_pd_solved(A, b, lemke(A, b, scale=False))


@settings(derandomize=True, max_examples=60, deadline=None)
@given(st.data())
def test_property_permutation_invariance(data):
    A, b = data.draw(pd_problems(symmetric=data.draw(st.booleans())))
    n = b.size
    p = np.array(data.draw(st.permutations(range(n))), dtype=int)
    x = lemke(A, b).check().x
    xp = lemke(A[np.ix_(p, p)], b[p]).check().x
    # unique solution: two refined solves, each to n cond eps (PD_TOL; measured <= 16 eps)
    assert_close(xp, x[p], PD_TOL)


@settings(derandomize=True, max_examples=60, deadline=None)
@given(st.data())
def test_property_diagonal_scaling_invariance(data):
    A, b = data.draw(pd_problems(symmetric=data.draw(st.booleans())))
    n = b.size
    D = 10.0 ** data.draw(hnp.arrays(np.float64, n, elements=st.floats(-3.0, 3.0)))
    x = lemke(A, b).check().x
    for scale in (True, False):
        # LCP(D A D, D b) is solved by x / D
        xd = lemke(D[:, None] * A * D[None, :], D * b, scale=scale).check().x
        # cond(DAD) reaches ~1e15, but the refined basis solve is componentwise backward
        # stable, so the error of D xd is |A^-1| (|A| |x| + |b|) times a few eps: the bound
        # of the unscaled problem, 2 n cond eps (PD_TOL). Measured on ~7000 random cases:
        # <= 3e-15 with scaling and 3e-14 without
        assert_close(D * xd, x, PD_TOL)


@settings(derandomize=True, max_examples=50, deadline=None)
@given(pd_problems(symmetric=False), st.floats(-100.0, 100.0))
def test_property_positive_scaling_of_b(prob, e):
    # LCP(A, t b) is solved by t x: same pivots, same basis
    A, b = prob
    t = 10.0 ** e
    # the invariance is exact only while every entry stays a normal float (no underflow)
    nz = np.abs(b[b != 0])
    assume(np.all((nz * t > 1e-290) & (nz * t < 1e290) & (nz > 1e-290)))
    ref = lemke(A, b).check()
    res = lemke(A, t * b).check()
    assert res.pivots == ref.pivots
    # same basis; t b is rounded (t is no power of 2), so each solve is n cond eps off (PD_TOL)
    assert_close(res.x / t, ref.x, PD_TOL)


@settings(derandomize=True, max_examples=100, deadline=None)
@given(st.data())
def test_property_success_is_always_certified(data):
    # any matrix, any b: never raises, status is one of the four, "solved" is a solution (by the
    # independent row-wise check; the solver's own acceptance threshold is its business)
    n = data.draw(st.integers(1, 6))
    A = data.draw(hnp.arrays(np.float64, (n, n), elements=st.floats(-5.0, 5.0).map(lambda v: round(v, 1))))
    b = data.draw(hnp.arrays(np.float64, n, elements=st.sampled_from([-2.0, -1.0, 0.0, 1.0, 0.5])))
    res = lemke(A, b)
    assert isinstance(res, LCPResult)
    assert res.status in STATUSES
    assert res.x.shape == (n,) and res.w.shape == (n,)
    assert res.message
    if res.success:
        assert_lcp_solution(A, b, res.x)
        assert res.check() is res
    else:
        with pytest.raises(LCPError, match=".+"):
            res.check()
    # (a sign test without tolerance: it only decides whether the theorem applies. A PSD matrix
    # whose 0 eigenvalue comes out as -1e-16 merely skips the check; a matrix with a true
    # eigenvalue in (-1e-14, 0) would be misread as PSD, a risk the solver's own -1e-14 shares)
    if res.status == "ray" and np.linalg.eigvalsh(0.5 * (A + A.T))[0] >= 0:
        # a ray on a PSD (copositive-plus) matrix proves infeasibility
        assert not brute_force(A, b, first=True)


# --------------------------------------------------------------------------------------------
# 3. classic hard cases
# --------------------------------------------------------------------------------------------

def murty(n):
    """Murty (1978) / Murty's book ch. 6: lower triangular, 1 on and 2 below the diagonal,
    q = (-2^n, -2^n - 2^(n-1), ..., -2^n - ... - 2). With d = e, Lemke's method (the
    complementary pivot method) needs exactly 2^n pivots (the z0 entry and exit included);
    the unique solution (a P-matrix) is x = (2^n, 0, ..., 0)."""
    L = np.eye(n) + 2.0 * np.tril(np.ones((n, n)), -1)
    q = -np.cumsum(2.0 ** np.arange(n, 0, -1))
    return L, q


def test_murty_exponential_example():
    # measured with scale=False: 4, 8, 16, 32, 64, 128, 256 pivots for n = 2..8 (= 2^n,
    # Murty's theorem for d = e); with the default equilibration (a different covering
    # vector) the path is short: 2 pivots for n = 2..8.
    # Accuracy: the final basis is {x_1} with A_11 = 1 and integer data below 2^53, and the
    # polish re-solves it whatever the 2^n updates did: x = 2^n exactly without scaling, and
    # to the few roundings of the equilibration (r_1, c_1 are not powers of 2: ~4 eps) with
    # it. 1e-14 (45 eps) is a margin of ~10 (measured: exact in both).
    counts = {}
    for n in range(2, 9):
        A, b = murty(n)
        x_ref = np.zeros(n)
        x_ref[0] = 2.0 ** n
        res = lemke(A, b, scale=False)
        assert res.status == "solved"
        np.testing.assert_array_equal(res.x, x_ref)
        assert res.pivots == 2 ** n
        counts[n] = res.pivots
        scaled = lemke(A, b)
        assert scaled.status == "solved"
        np.testing.assert_allclose(scaled.x, x_ref, rtol=0, atol=1e-14 * 2 ** n)
        # an explicit covering vector of ones without scaling is Murty's setting too
        assert lemke(A, b, scale=False, d=np.ones(n)).pivots == 2 ** n
        # the b = -e variants (degenerate: the first ratio test is an n-fold tie): measured
        # with scale=False, upper triangular 2 pivots, lower triangular 2^n pivots (the lex
        # rule breaks the tie towards the last row, like q above); with scaling 2 pivots.
        # Only the solutions are asserted: no theorem covers this tie-breaking. x = e_k from a
        # 1 x 1 basis with pivot 1, as above (the former atol=1e-12 came with the default
        # rtol=1e-7 on the entry 1)
        for T_, x_e in ((A.T, np.eye(n)[-1]), (A, np.eye(n)[0])):
            for scale in (True, False):
                np.testing.assert_allclose(lemke(T_, -np.ones(n), scale=scale).check().x, x_e, rtol=0, atol=1e-14)
    assert all(counts[n + 1] == 2 * counts[n] for n in range(2, 8))


def test_murty_refactorization_and_pivot_limit():
    A, b = murty(8)  # 256 pivots: the default refactor=50 already refactorizes 5 times
    ref = lemke(A, b, scale=False)
    for refactor in (1, 7, 1000):
        res = lemke(A, b, scale=False, refactor=refactor)
        assert res.status == "solved" and res.pivots == ref.pivots
        # exact: the polish re-solves the same 1 x 1 integer basis (see the test above), so how
        # often the inverse was refactorized leaves no trace in x
        np.testing.assert_array_equal(res.x, ref.x)
    short = lemke(A, b, scale=False, max_pivots=100)
    assert short.status == "max_pivots" and short.pivots == 100
    assert "100" in short.message
    with pytest.raises(LCPError, match="limit"):
        short.check()


def naive_lemke(A, b, maxit=100):
    """Exact (rational) Lemke's method, d = e, ties in the ratio test broken naively: the
    tied row whose basic variable has the largest index leaves (z0 first when it ties).
    Returns 'solved', 'ray' or 'cycle' (a (basis, entering variable) state repeats: with a
    deterministic rule that is an endless loop)."""
    n = len(b)
    T = [[Fraction(int(i == j)) for j in range(n)] + [Fraction(-A[i][j]) for j in range(n)]
         + [Fraction(-1), Fraction(b[i])] for i in range(n)]
    basis = list(range(n))
    z0 = 2 * n
    r = max(i for i in range(n) if b[i] == min(b))
    entering, seen = z0, set()
    for _ in range(maxit):
        p = T[r][entering]
        T[r] = [v / p for v in T[r]]
        for i in range(n):
            if i != r and T[i][entering] != 0:
                f = T[i][entering]
                T[i] = [a - f * c for a, c in zip(T[i], T[r])]
        leaving, basis[r] = basis[r], entering
        if leaving == z0:
            return "solved"
        entering = leaving + n if leaving < n else leaving - n
        state = (frozenset(basis), entering)
        if state in seen:
            return "cycle"
        seen.add(state)
        pos = [i for i in range(n) if T[i][entering] > 0]
        if not pos:
            return "ray"
        theta = min(T[i][-1] / T[i][entering] for i in pos)
        ties = [i for i in pos if T[i][-1] / T[i][entering] == theta]
        at_z0 = [i for i in ties if basis[i] == z0]
        r = at_z0[0] if at_z0 else max(ties, key=lambda i: basis[i])
    return "max"


# found by a search over small integer problems: monotone (skew-symmetric + diag(1, 0, 0),
# so PSD and copositive-plus) with b = -e; the naive tie-break above cycles forever
CYCLING_A = [[1, 1, -3], [-1, 0, 1], [3, -1, 0]]
CYCLING_B = [-1, -1, -1]


def test_degenerate_example_that_cycles_without_anticycling():
    assert naive_lemke(CYCLING_A, CYCLING_B) == "cycle"
    A, b = np.array(CYCLING_A, float), np.array(CYCLING_B, float)
    assert brute_force(A, b, first=True), "the example is solvable (needed for the assertion below)"
    for scale in (True, False):
        res = lemke(A, b, scale=scale)
        assert res.status == "solved", res.message
        assert_lcp_solution(A, b, res.x)


def test_highly_degenerate_problems_terminate():
    # repeated rows/columns (duplicated contacts), integer data, b with many zeros and ties:
    # every ratio test ties; the lexicographic rule must terminate with a valid answer
    outcomes = {"solved": 0, "ray": 0}
    for seed in range(150):
        rng = np.random.default_rng(1000 + seed)
        n = int(rng.integers(2, 8))
        base = rng.integers(-2, 3, (int(rng.integers(1, n)), int(rng.integers(1, 4)))).astype(float)
        G = base[rng.integers(0, base.shape[0], n)]          # rows repeated at random
        A = G @ G.T
        if seed % 3 == 1:                                    # monotone non-symmetric variant
            K = rng.integers(-1, 2, (n, n)).astype(float)
            A = A + K - K.T
        b = rng.choice([-1.0, 0.0, 0.0, 0.0, 1.0], n)
        b[rng.integers(n)] = -1.0
        sols = brute_force(A, b) if n <= 6 else None
        for scale in (True, False):
            res = lemke(A, b, scale=scale)
            assert res.status in ("solved", "ray"), (seed, res.message)  # no max_pivots: no cycling
            if res.success:
                assert_lcp_solution(A, b, res.x)
            if sols is not None:
                assert res.success == bool(sols), (seed, scale, A, b)
            outcomes[res.status] += 1
    # coverage of both outcomes: measured 242 solved, 58 rays on every BLAS config (for n <= 6
    # pinned by brute force above); the floors are ~90 % of that
    assert outcomes["solved"] >= 220 and outcomes["ray"] >= 50, outcomes


def test_degenerate_p_matrix_with_all_ties():
    # b = -e with A = I + tie-generating identical off-diagonals: every first ratio ties.
    # Eigenvalues 0.5 and 1 + 0.5 (n - 1): cond = n + 1 <= 9, so any basis solve is good to
    # n cond eps = 1.6e-14 (x = e_1 below is even exact from its 1 x 1 basis); 1e-12 is a
    # margin of 60 (measured <= 5e-16)
    for n in range(1, 9):
        A = np.eye(n) + 0.5 * (np.ones((n, n)) - np.eye(n))  # SPD
        b = -np.ones(n)
        res = lemke(A, b, scale=False).check()
        np.testing.assert_allclose(res.x, np.full(n, 1.0 / (1 + 0.5 * (n - 1))), rtol=1e-12)
        b0 = np.zeros(n)
        b0[0] = -1.0
        res = lemke(A, b0, scale=False).check()   # zeros: degenerate from the first pivot
        x_ref = np.zeros(n)
        x_ref[0] = 1.0
        np.testing.assert_allclose(res.x, x_ref, rtol=0, atol=1e-12)


# --------------------------------------------------------------------------------------------
# 4. trivial cases and input validation
# --------------------------------------------------------------------------------------------

def test_nonnegative_b_gives_zero_without_pivots():
    rng = np.random.default_rng(3)
    for n in (1, 2, 5):
        A = -np.abs(rng.standard_normal((n, n)))  # even a hopeless matrix
        b = np.abs(rng.standard_normal(n))
        b[0] = 0.0
        res = lemke(A, b)
        assert res.status == "solved" and res.pivots == 0
        np.testing.assert_array_equal(res.x, np.zeros(n))
        np.testing.assert_array_equal(res.w, b)
        assert res.residual == 0.0


def test_one_dimensional():
    for a, bb in [(2.0, -3.0), (1e-6, -1e-3), (5e6, -7.0)]:
        res = lemke([[a]], [bb]).check()
        # x = c xs with xs = (r b) / (r a c): a handful of roundings through the equilibration,
        # <= 5 eps = 1.1e-15 (measured 0.7 eps); 1e-14 is a margin of 9. Then |w| = |a dx| plus
        # one rounding of a x + b: <= 6 eps |b| = 1.3e-15 |b| (above the former 1e-15 |b|;
        # measured 1.1 eps), hence 1e-14 |b| as for x
        assert res.x[0] == pytest.approx(-bb / a, rel=1e-14)
        assert res.w[0] == pytest.approx(0.0, abs=1e-14 * abs(bb))
    res = lemke([[0.0]], [-1.0])          # w = -1 whatever x
    assert res.status == "ray" and not res.success
    assert_proves_infeasible(res.message)
    with pytest.raises(LCPError, match="secondary ray"):
        res.check()
    res = lemke([[-1.0]], [-1.0])         # w = -x - 1 < 0: infeasible, A not PSD
    assert res.status == "ray"
    assert "not positive semi-definite" in res.message
    with pytest.raises(LCPError):
        res.check()
    assert issubclass(LCPError, NsfemError)


@pytest.mark.parametrize("scale", [True, False])
def test_empty_problem(scale):
    # (n = 0 with scale=True raised ValueError in _equilibrate before 3be2973)
    res = lemke(np.zeros((0, 0)), np.zeros(0), scale=scale)
    assert res.status == "solved" and res.pivots == 0
    assert res.x.shape == (0,) and res.w.shape == (0,)
    assert certificate(np.zeros((0, 0)), np.zeros(0), np.zeros(0))["relative"] == 0.0


@pytest.mark.parametrize("A, b, kw", [
    (np.eye(2), np.ones(3), {}),                         # size mismatch
    (np.ones((2, 3)), -np.ones(2), {}),                  # not square
    (np.eye(2)[None], -np.ones(2), {}),                  # 3-d
    (np.array([[1.0, np.nan], [0.0, 1.0]]), -np.ones(2), {}),
    (np.eye(2), np.array([-1.0, np.inf]), {}),
    (np.eye(2), np.array([-1.0, np.nan]), {}),
    (np.eye(2), -np.ones(2), {"d": [1.0, 0.0]}),         # covering vector not positive
    (np.eye(2), -np.ones(2), {"d": [1.0, -1.0]}),
    (np.eye(2), -np.ones(2), {"d": [1.0, np.nan]}),
    (np.eye(2), -np.ones(2), {"d": [1.0, np.inf]}),
    (np.eye(2), -np.ones(2), {"d": [1.0, 1.0, 1.0]}),    # wrong length
])
def test_bad_input_raises(A, b, kw):
    with pytest.raises(NsfemError):
        lemke(A, b, **kw)


def test_covering_vector_does_not_change_a_unique_solution():
    rng = np.random.default_rng(11)
    for _ in range(30):
        n = int(rng.integers(1, 7))
        A, b = spd(rng, n), 3 * rng.standard_normal(n)
        ref = lemke(A, b).check().x
        for scale in (True, False):
            res = lemke(A, b, d=rng.uniform(0.01, 100.0, n), scale=scale).check()
            # unique solution, spd cond <= 100, n <= 6: 2 n cond eps = 2.7e-13, margin 4
            # (measured 1.5 eps)
            assert_close(res.x, ref, 1e-12)


def test_certificate_measures_violations():
    A = np.array([[2.0, 1.0], [1.0, 2.0]])
    b = np.array([-5.0, -6.0])
    x = np.array([4.0, 7.0]) / 3.0
    c = certificate(A, b, x)
    assert set(c) >= {"x_min", "w_min", "complementarity", "relative"}
    # x is the exact solution rounded (eps / 2 each) and w = A x + b is formed with <= 3
    # roundings of terms that sum to s_i = 10: |w_i| / s_i <= 3.3 eps = 7.2e-16 in the worst
    # case (measured 0)
    assert c["relative"] < 1e-15 and c["x_min"] == 0.0
    # the violations below are of order one: relative 1, 0.27 and 0.29
    bad = certificate(A, b, np.array([0.0, 0.0]))         # w = b < 0
    assert bad["w_min"] == -6.0 and bad["relative"] > 0.1
    neg = certificate(A, b, np.array([-1.0, 4.0]))        # x < 0
    assert neg["x_min"] == -1.0 and neg["relative"] > 0.1
    comp = certificate(A, b, np.array([3.0, 3.0]))        # x > 0 and w > 0
    assert comp["complementarity"] == 12.0 and comp["relative"] > 0.1   # x w = (3 * 4, 3 * 3): exact


# --------------------------------------------------------------------------------------------
# 5. secondary-ray termination on infeasible monotone problems
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("A, b", [
    ([[1.0, -1.0], [-1.0, 1.0]], [-1.0, -1.0]),    # x1 - x2 >= 1 and x2 - x1 >= 1
    ([[1.0, -1.0], [-1.0, 1.0]], [-1.0, -3.0]),
    ([[0.0, 1.0], [-1.0, 0.0]], [-1.0, -1.0]),     # skew (monotone, not symmetric): -x1 >= 1
    ([[1.0, -1.0, 0.0], [-1.0, 1.0, 0.0], [0.0, 0.0, 0.0]], [-1.0, -1.0, 2.0]),  # zero row and column
    ([[0.0, 0.0], [0.0, 0.0]], [1.0, -1.0]),      # A = 0: w = b
    ([[2.0, -2.0, 0.0], [-2.0, 2.0, 0.0], [0.0, 0.0, 1.0]], [-1.0, -1.0, -1.0]),
])
def test_infeasible_monotone_problem_ends_on_a_ray(A, b):
    A, b = np.array(A), np.array(b)
    assert not brute_force(A, b, first=True)
    for scale in (True, False):
        res = lemke(A, b, scale=scale)
        assert res.status == "ray"
        assert_proves_infeasible(res.message)
        with pytest.raises(LCPError, match="no solution"):
            res.check()


# --------------------------------------------------------------------------------------------
# 6. badly scaled blocks (contact mechanics units)
# --------------------------------------------------------------------------------------------

def friction_lcp(rng, n_modes, m, mu, stiffness=1.0, gap=1.0):
    """The frictional contact LCP (paper LCP 28/29 structure), r = 4 generators per contact:

        [ J_N^T S J_N   J_N^T S J_T   0 ]        [ b_N ]
    A = [ J_T^T S J_N   J_T^T S J_T   E ],  b =  [ b_T ],  x = (lam_N, beta, z),
        [ mu            -E^T          0 ]        [ 0   ]

    S = M^-1 (entries ~ 1/stiffness), J_T = J_S B with B_k = [[1, -1, 0, 0], [0, 0, 1, -1]]
    (+-t1, +-t2), b_N < 0 (penetrating, ~gap), b_T = B^T v_T (a tangential motion, ~gap).
    With n_modes >= 3 m, [J_N, J_S] has full column rank (see section 7).
    """
    G = rng.standard_normal((n_modes, n_modes))
    M = (G @ G.T + n_modes * np.eye(n_modes)) * stiffness
    JN = rng.standard_normal((n_modes, m))
    JS = rng.standard_normal((n_modes, 2 * m))
    B = np.kron(np.eye(m), np.array([[1.0, -1.0, 0.0, 0.0], [0.0, 0.0, 1.0, -1.0]]))
    J = np.hstack([JN, JS @ B])
    D = J.T @ np.linalg.solve(M, J)
    D = 0.5 * (D + D.T)
    p = 4 * m
    E = np.kron(np.eye(m), np.ones((4, 1)))
    A = np.zeros((6 * m, 6 * m))
    A[: m + p, : m + p] = D
    A[m: m + p, m + p:] = E
    A[m + p:, :m] = mu * np.eye(m)
    A[m + p:, m: m + p] = -E.T
    b = np.concatenate([-gap * rng.uniform(0.1, 1.0, m), B.T @ (gap * rng.standard_normal(2 * m)), np.zeros(m)])
    return A, b


def assert_friction_physics(x, m, mu, tol=1e-11):
    """lam_N >= 0, sum_j beta_kj <= mu lam_N,k (inside the polygonal cone) and, where z_k > 0
    (contact k slides), sum_j beta_kj = mu lam_N,k (on the cone). Tolerances relative to the
    largest contact force: a sticking contact with lam = 0 may carry beta ~ 1e-16 of round-off.

    These are the LCP's z rows, w = mu lam - sum beta: a sliding contact's row is a basis row
    ((n + 5) eps of its terms <= 2 force: 1e-14 force), a sticking one's a degenerate non-basic
    row (<= 2 (n + 5) eps of |A| X <= (mu + 4) X <= 41 force for mu >= 0.1: 4e-13 force, see
    FLOOR). tol = 1e-11 is a margin of 25 (measured <= 1.5 eps); it also separates a sliding
    z from a degenerate z, which comes out at ~1e-14 of the largest."""
    lam, beta, z = x[:m], x[m: 5 * m].reshape(m, 4), x[5 * m:]
    assert lam.min() >= 0 and beta.min() >= 0 and z.min() >= 0
    total = beta.sum(axis=1)
    force = float(np.max(mu * lam + total)) + np.finfo(float).tiny
    assert np.all(total <= mu * lam + tol * force), (total, mu * lam)
    sliding = z > tol * max(float(np.max(z)), np.finfo(float).tiny)
    assert np.all(np.abs(total - mu * lam)[sliding] <= tol * force), (total, mu * lam, z)


def test_badly_scaled_delassus_same_solution_with_and_without_scaling():
    # gaps ~1e-5 m, compliance ~1e-7 m/N (forces ~1e2 N), plus a row block in mm: unique
    # solution (PD Delassus, m <= n_modes), so both runs and the unit-scale reference agree.
    # A = R D_unit (positive row scaling R), and the refined basis solve is componentwise
    # backward stable, so its error is that of the unit-scale problem: cond(D_unit) <= 1.05e3,
    # n <= 6: certificate n cond eps = 1.4e-12, x 2 n cond eps = 2.8e-12 per comparison;
    # 1e-11 is a margin of 3.6 to 7 (measured: certificate 0.8 eps, x <= 42 eps = 9e-15)
    for seed in range(40):
        rng = np.random.default_rng(seed)
        n_modes = int(rng.integers(2, 7))
        m = int(rng.integers(1, n_modes + 1))
        D1 = delassus(rng, m, n_modes) * 1e-7
        rowscale = np.where(rng.random(m) < 0.5, 1.0, 1e3)     # some gaps measured in mm
        A = rowscale[:, None] * D1
        b = rowscale * 1e-5 * rng.standard_normal(m)
        ref = unique_reference(D1 / 1e-7, b / rowscale / 1e-5) * 1e-5 / 1e-7   # solved at unit scale
        res_s = lemke(A, b)
        res_u = lemke(A, b, scale=False)
        for res in (res_s, res_u):
            assert res.status == "solved", res.message
            assert res.certificate["relative"] < 1e-11
            assert_lcp_solution(A, b, res.x)
            assert_close(res.x, ref, 1e-11)
        assert_close(res_s.x, res_u.x, 1e-11)


def friction_groups(m):
    """Unit groups of the friction LCP unknowns: lam_N and beta are forces, z a slip rate."""
    return np.array([0] * (5 * m) + [1] * m)


def scaled_friction(seed, mu, stiffness=1.0, gap=1.0):
    """A full-rank friction LCP in physical units, and the map x_phys = C x_unit to the same
    problem at unit scale (same seed): forces scale with gap * stiffness, z with gap (the LCP
    in physical units is exactly R A_unit C, b = R b_unit for positive diagonals R, C)."""
    rng = np.random.default_rng(seed)
    m = int(rng.integers(1, 4)) if seed % 2 else 1
    A, b = friction_lcp(rng, int(rng.integers(3 * m, 3 * m + 3)), m, mu, stiffness=stiffness, gap=gap)
    C = np.concatenate([np.full(5 * m, gap * stiffness), np.full(m, gap)])
    return A, b, m, C


def test_badly_scaled_friction_lcp():
    # Delassus blocks ~1e-7 m/N, gaps and slips ~1e-5 m, friction rows with entries ~1 (mu, -1),
    # forces ~1e2 N. Full rank and b_T = B^T v: solvable by Lemke (module docstring). Where
    # the unit-scale problem has a unique solution (brute force, one contact: 2^6 sets) both
    # runs must return it. Compared at unit scale (x / C), so that the slip rates z (1e7 times
    # smaller than the forces in physical units) are checked too: the refined solve's error is
    # that of the unit-scale problem (A = R A_unit C), whose bases have cond <= 116 (n = 6):
    # 2 n cond eps = 3.1e-13, 1e-12 is a margin of 3 (measured: forces 5 eps, z 15 eps).
    mu, compared = 0.3, 0
    for seed in range(40):
        A, b, m, C = scaled_friction(seed, mu, stiffness=1e7, gap=1e-5)
        res = lemke(A, b)
        assert res.status == "solved", (seed, res.message)
        assert_lcp_solution(A, b, res.x, groups=friction_groups(m))
        assert_friction_physics(res.x, m, mu)
        raw = lemke(A, b, scale=False)
        if raw.success:
            assert_lcp_solution(A, b, raw.x, groups=friction_groups(m))
        if m == 1:
            A1, b1, _, _ = scaled_friction(seed, mu)
            sols = brute_force(A1, b1)
            assert sols
            # (a classification: distinct solutions differ at order one, copies of one solution
            # by 2 n cond eps = 3e-13)
            if all(np.allclose(s, sols[0], rtol=0, atol=1e-9 * np.max(sols[0])) for s in sols):
                compared += 1
                for r in (res, raw) if raw.success else (res,):
                    assert_close(r.x / C, sols[0], 1e-12)
    # a coverage floor. Measured on every BLAS config: all 26 one-contact instances are unique
    # (decided at order one, so the count does not move with round-off)
    assert compared >= 20, compared


# a minimal stiff contact: one contact, two generators (+-t), compliance 1e-7..1e-13 m/N (the
# stationary LCP 28 of a stiff shaft), gap and slip 1e-5 m. It is exactly R A1 C, R b1 with the
# unit-scale A1, b1 below, whose unique solution is (10/43, 3/43, 0, 27/43) (brute force):
# x = (1e-5 / k * 10/43, 1e-5 / k * 3/43, 0, 1e-5 * 27/43) for compliance k.
STIFF_A1 = np.array([[4.0, 1.0, -1.0, 0.0], [1.0, 2.0, -2.0, 1.0], [-1.0, -2.0, 2.0, 1.0], [0.3, -1.0, -1.0, 0.0]])
STIFF_B1 = np.array([-1.0, -1.0, 1.0, 0.0])
STIFF_GROUPS = [0, 0, 0, 1]


def stiff_contact(k):
    A = STIFF_A1.copy()
    A[:3, :3] *= k
    return A, 1e-5 * STIFF_B1, np.array([1e-5 / k * 10 / 43, 1e-5 / k * 3 / 43, 0.0, 1e-5 * 27 / 43])


def stiff_units(k):
    """The unit of each unknown of stiff_contact(k): x / stiff_units(k) is the unit-scale x."""
    return np.array([1e-5 / k] * 3 + [1e-5])


# Accuracy of the stiff contact at unit scale: the basis {0, 1, 3} of A1 has cond 9.4 (n = 4),
# so a refined solve (componentwise backward stable, hence independent of R and C) and the
# closed form (3 roundings) agree to 2 n cond eps = 1.7e-14 per unit group; 1e-13 is a margin
# of 6 (measured <= 1.7 eps). Comparing at unit scale also checks z, which in physical units
# is 1e2..1e8 times smaller than the forces.
STIFF_REL = 1e-13


def test_stiff_contact_reference():
    sols = brute_force(STIFF_A1, STIFF_B1)
    assert len(sols) == 1
    # normwise solve, cond 9.4: n cond eps = 8e-15 of max|x| = 0.63, i.e. 7e-14 of the smallest
    # nonzero entry 3/43 (x_2 = 0 is exact: not in the basis); margin 14
    np.testing.assert_allclose(sols[0], [10 / 43, 3 / 43, 0, 27 / 43], rtol=1e-12)
    for k in (1e-7, 1e-10, 1e-12):
        A, b, x = stiff_contact(k)
        assert_lcp_solution(A, b, x, groups=STIFF_GROUPS)
        raw = lemke(A, b, scale=False).check()       # unscaled Lemke solves all three
        assert_close(raw.x / stiff_units(k), x / stiff_units(k), STIFF_REL)


LIMIT_STIFF = (
    "LIMITATION: friction LCPs with a contact compliance of 1e-10 m/N and below (condition ~1e10 against the "
    "friction rows) are sometimes reported 'inaccurate' (componentwise certificate > ACCEPT = 1e-8): measured "
    "with the tie tolerance at 1e-15, 1 of 40 seeds at 1e10, 9 at 1e11, 11 at 1e13 (never a false 'solved': six "
    "of those at 1e13, certificates 5e-8..8e-5 with rows violated by up to 13 % of their terms, were reported "
    "'solved' while INACCURATE = 1e-4 was the cut). The beam models of nsfem have compliances of 1e-8 to 1e-6 m/N.")


@pytest.mark.parametrize("k", [1e-7, 1e-10,
                               1e-12,
                               1e-13])
def test_stiff_contact(k):
    # (at 688847e, k = 1e-10 gave a false 'solved' x = (25000, 0, 0, 0), w_1 = -7.5e-6)
    A, b, x = stiff_contact(k)
    res = lemke(A, b)
    if res.success:
        assert_lcp_solution(A, b, res.x, groups=STIFF_GROUPS)   # never a false success
    assert res.status == "solved", res.message
    assert_close(res.x / stiff_units(k), x / stiff_units(k), STIFF_REL)


@pytest.mark.parametrize("stiffness", [
    1e9,
    pytest.param(1e10, marks=pytest.mark.xfail(strict=True, reason=LIMIT_STIFF)),
    pytest.param(1e13, marks=pytest.mark.xfail(strict=True, reason=LIMIT_STIFF)),
])
def test_stiff_friction_lcp(stiffness):
    # compliance 1/stiffness m/N, gaps 1e-5 m, mu = 0.3, 40 seeds: never a false success (an early
    # version accepted near-tie points on a global certificate: 8 of 40 wrong at 1e9, 19 at 1e10)
    mu = 0.3
    for seed in range(40):
        A, b, m, C = scaled_friction(seed, mu, stiffness=stiffness, gap=1e-5)
        res = lemke(A, b)
        if res.success:
            assert_lcp_solution(A, b, res.x, groups=friction_groups(m))
            assert_friction_physics(res.x, m, mu)
        assert res.status == "solved", (seed, res.message)


# an open contact with a large gap (row 0, w_0 = 1e4) next to a closing one, on a positive
# definite matrix with cond 11 (at 688847e: 'solved' with x = (0, 0.909, 0), w_2 = -9.1e-8: the
# z0 near-tie shortcut accepted a basis on a certificate normalized by the largest row)
PD_A = np.array([[1.0, 0.0, 0.0], [0.0, 1.1, -1e-7], [0.0, -1e-7, 0.1]])
PD_B = np.array([1e4, -1.0, 0.0])


@pytest.mark.parametrize("scale", [True, False])
def test_large_gap_does_not_hide_a_closing_contact(scale):
    # Componentwise, so that the small force x_2 ~ 9e-7 is checked at its own size. The basis
    # {1, 2} is nearly diagonal: LU needs no cancellation (a few roundings) and its
    # componentwise condition (|A^-1| |A| |x|)_i / x_i is <= 3. Brute force vs the closed form
    # (2 roundings): <= 8 eps = 1.8e-15, rtol 1e-14 a margin of 5; Lemke's refined solve adds
    # (n + 5) eps times 3 = 21 eps: rtol 1e-13 a margin of 3.5 (measured: 0.5 eps for both)
    ref = unique_reference(PD_A, PD_B)
    np.testing.assert_allclose(ref, [0.0, 1 / (1.1 - 1e-13), 1e-6 / (1.1 - 1e-13)], rtol=1e-14)
    res = lemke(PD_A, PD_B, scale=scale)
    assert res.status == "solved"
    np.testing.assert_allclose(res.x, ref, rtol=1e-13, atol=0)


# entries 1e10 apart: an early tie tolerance (1e-10 relative) merged the ratios 10 - 1e-11 and 10,
# let z0 leave first and clipped w_0 = -1e-12 to 0 ('inaccurate' x = (0, 10)); ties are now 1e-15
@pytest.mark.parametrize("A, b", [
    (0.1 * np.eye(2), [-1e-12, -1.0]),
    (0.1 * np.eye(2), [-1.0, -1e-12]),
    ([[1.1, -1e-12], [-1e-12, 0.1]], [-1.0, 0.0]),
])
def test_pd_with_entries_1e10_apart(A, b):
    A, b = np.array(A), np.array(b)
    res = lemke(A, b)
    assert res.status == "solved", res.message
    # all of x > 0, each to its own size: diagonal or nearly diagonal A (componentwise
    # condition <= 3, no cancellation), so both solves are ~(n + 5) eps 3 = 21 eps = 5e-15
    # componentwise; 1e-13 is a margin of ~20 (measured <= 1.6 eps)
    np.testing.assert_allclose(res.x, np.linalg.solve(A, -b), rtol=1e-13)


# --------------------------------------------------------------------------------------------
# 7. frictional contact LCP structure
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("mu", [0.1, 0.3, 1.0, 2.0])
def test_friction_lcp_full_rank_always_solved(mu):
    # n_modes >= 3m and b_T = B^T v: A is copositive (x^T A x = |J(lam, beta)|^2_S + mu z.lam)
    # and b^T y = 0 on SOL(0, A) = {J(lam, beta) = 0, ...} = {lam = 0, B beta = 0, ...}, so
    # Lemke's method must compute a solution for every mu (Cottle-Pang-Stone Thm 4.4.13)
    for seed in range(60):
        rng = np.random.default_rng(seed)
        m = int(rng.integers(1, 4))
        A, b = friction_lcp(rng, int(rng.integers(3 * m, 3 * m + 4)), m, mu)
        res = lemke(A, b)
        assert res.status == "solved", (seed, res.message)
        assert_lcp_solution(A, b, res.x, groups=friction_groups(m))
        assert_friction_physics(res.x, m, mu)


def friction_success_rate(mu, cases=100):
    """Generic instances (n_modes 2..7, possibly fewer modes than constraints, random b_N < 0):
    some are infeasible (penetrations the modes cannot all undo). Returns (solved, solvable,
    total, unreached) where unreached counts solvable instances (brute force) Lemke missed."""
    solved = solvable = unreached = 0
    for seed in range(cases):
        rng = np.random.default_rng(seed)
        n_modes, m = int(rng.integers(2, 8)), int(rng.integers(1, 3))
        A, b = friction_lcp(rng, n_modes, m, mu)
        res = lemke(A, b)
        assert res.status in ("solved", "ray"), res.message
        if res.success:
            solved += 1
            solvable += 1
            assert_lcp_solution(A, b, res.x, groups=friction_groups(m))
            assert_friction_physics(res.x, m, mu)
        # (with cond_max 1e10 a basis solve may be 2e-6 off, above brute_force's 1e-8 floor: a
        # true solution there can be missed, which only lowers `solvable`, i.e. eases the floors)
        elif brute_force(A, b, cond_max=1e10, first=True):
            solvable += 1
            unreached += 1
    return solved, solvable, cases, unreached


@pytest.mark.parametrize("mu", [0.1, 0.3])
def test_friction_lcp_small_mu_success_rate(mu):
    # measured (100 seeds): mu = 0.1: 99 solved, the other one infeasible (brute force);
    # mu = 0.3: 96 solved, 4 infeasible. The matrix is copositive but not copositive-plus
    # (x^T A x = 0 does not force (A + A^T) x = 0) and b is arbitrary, so Lemke may miss a
    # solution; at small mu it must reach (almost) every solvable instance. The counts are the
    # same on every BLAS config (ratio tests decide with order-one gaps, ties at 1e-15): the
    # slack of ~3 instances is for a change of the pivoting rule, not for round-off.
    solved, solvable, total, unreached = friction_success_rate(mu)
    assert solved >= 0.97 * solvable
    assert solved >= 0.93 * total


@pytest.mark.parametrize("mu", [1.0, 2.0])
def test_friction_lcp_large_mu_success_rate(mu):
    # measured (100 seeds): mu = 1: 89 solved, 1 solvable instance ended on a ray, 10
    # infeasible; mu = 2: 87 solved, 1 unreached, 12 infeasible. Every returned solution is
    # checked (physics included). Same counts on every BLAS config; the floors allow ~3 more
    # missed instances than measured (a change of the pivoting rule, not round-off)
    solved, solvable, total, unreached = friction_success_rate(mu)
    assert solved >= 0.96 * solvable
    assert solved >= 0.85 * total


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")   # the 1e+-300 entries
@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")  # (their overflowing x)
def test_one_unknown_in_floats_is_the_pivot_loop_bitwise(monkeypatch):
    # lemke solves LCPs of one unknown (most impact LCPs of a run) in float arithmetic
    # (pivoting._lemke_one); it repeats the pivot loop's operations in order, so the result,
    # certificate and message are the loop's to the bit, on every branch it takes or leaves
    import nsfem.lcp.pivoting as pivoting

    rng = np.random.default_rng(5)
    edge = [0.0, -0.0, 1.0, -1.0, 3.0, -7.5, 1e-17, 1e-300, -1e-300, 1e300, -1e300, 5e-324]
    cases = [(a, b, {}) for a in edge for b in edge]
    for _ in range(400):
        a, b = rng.standard_normal(2) * 10.0 ** rng.integers(-12, 12, 2)
        kw = {"d": [rng.uniform(0.01, 2.0)]} if rng.random() < 0.3 else {}
        cases.append((a, b, kw))
    for a, b, kw in cases:
        with monkeypatch.context() as m:
            m.setattr(pivoting, "_lemke_one", lambda *args: None)
            loop = lemke([[a]], [b], **kw)   # (a = 1e-300, b = -1e300: both report an overflow)
        fast = lemke([[a]], [b], **kw)
        assert (fast.status, fast.pivots, fast.message) == (loop.status, loop.pivots, loop.message)
        assert fast.x.tobytes() == loop.x.tobytes() and fast.w.tobytes() == loop.w.tobytes()
        assert repr(fast.certificate) == repr(loop.certificate)


def test_overflowing_solution_is_reported_not_raised():
    """x = 1e600 solves LCP([[1e-300]], [-1e300]) but is beyond the floating-point range: the result
    says so (status ``overflow``, success False) instead of raising or calling nan a solution."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for A, b in (([[1e-300]], [-1e300]), ([[1e-300, 0.0], [0.0, 1.0]], [-1e300, -1.0])):
            res = lemke(A, b)
            assert res.status == "overflow" and not res.success
