"""The compiled Lemke (event core part "lcp": nsfem/integrate/core/_lcp.pyx, nsfem/lcp/compiled.py) against
its pure-Python reference (nsfem.lcp.pivoting.lemke under ``core.reference()``).

The contract (issue 33): the same pivoting rules and tie-breaking, so on every problem the same status, the
same number of pivots (the same sequence of bases: a different tie-break changes the count on the degenerate
classes below) and the same message; the same certificate verdicts; x equal within what the certificate
guarantees. The kernels' loops sum left to right where the reference calls BLAS (which may group and fuse
the products), so a value may differ in its last bits: bitwise equality is asserted only where no BLAS
product is involved (the equilibration, LCPs of one unknown).

Skipped where the compiled part is not installed or is switched off (NSFEM_PURE_PYTHON=1): the rest of the
suite then exercises the reference.
"""

from __future__ import annotations

import re
from contextlib import nullcontext

import numpy as np
import pytest
from test_lemke import (delassus, degenerate_b, friction_groups, friction_lcp, monotone_nonsymmetric, murty,
                        p_nonsymmetric, psd_rank_deficient, spd)
from test_set_closure import _frictional_body

import nsfem.lcp.pivoting as pivoting
from nsfem.errors import NsfemError
from nsfem.integrate import core
from nsfem.lcp import impact_lcp, lemke, transition_lcp
from nsfem.lcp.pivoting import ACCEPT, INACCURATE
from nsfem.linalg import factorize

lib = core.compiled("lcp")
pytestmark = pytest.mark.skipif(lib is None, reason="the compiled event core's part 'lcp' is not built or is "
                                                    "switched off (NSFEM_PURE_PYTHON=1)")
EPS = float(np.finfo(float).eps)


def both(A, b, **kw):
    """(compiled, reference) results of lemke(A, b, **kw)."""
    fast = lemke(A, b, **kw)
    with core.reference():
        ref = lemke(A, b, **kw)
    return fast, ref


def _words(message: str) -> str:
    """A message with its numbers blanked (a ray's z0 = 0.731 may differ in a printed digit)."""
    return re.sub(r"-?\d[\d.]*(e[-+]?\d+)?", "#", message)


def assert_same_outcome(fast, ref) -> None:
    """Same status, pivots, message (up to printed numbers) and certificate verdicts; x within the certificate."""
    assert (fast.status, fast.pivots) == (ref.status, ref.pivots), (fast.message, ref.message)
    assert _words(fast.message) == _words(ref.message)
    for level in (ACCEPT, INACCURATE):
        assert (fast.residual <= level) == (ref.residual <= level), (fast.residual, ref.residual)
    assert fast.residual == fast.certificate["relative"]
    # the returned w is A x + b as numpy forms it (as the reference's result)
    assert np.array_equal(fast.w, np.asarray(fast.w)) and fast.x.shape == ref.x.shape


def assert_close(fast, ref, rtol: float) -> None:
    scale = max(float(np.abs(ref.x).max(initial=0.0)), 1e-300)
    assert float(np.abs(fast.x - ref.x).max(initial=0.0)) <= rtol * scale


def _problem(kind: str, rng):
    """(A, b, keywords, rtol or None) of one random LCP of ``kind`` (rtol: x's agreement where the solution
    is unique and its basis well conditioned, see :data:`KINDS`)."""
    n = int(rng.integers(1, 9))
    if kind == "spd":
        return spd(rng, n), rng.standard_normal(n), {}
    if kind == "p_nonsymmetric":
        return p_nonsymmetric(rng, n), rng.standard_normal(n), {}
    if kind == "psd":
        return psd_rank_deficient(rng, n), rng.standard_normal(n), {}
    if kind == "monotone":
        return monotone_nonsymmetric(rng, n), rng.standard_normal(n), {}
    if kind == "degenerate":
        return spd(rng, n), degenerate_b(rng, n), {"scale": bool(rng.integers(2))}
    if kind == "degenerate_psd":
        return psd_rank_deficient(rng, n), degenerate_b(rng, n), {"scale": False}
    if kind == "covering":
        return spd(rng, n), rng.standard_normal(n), {"d": rng.uniform(0.01, 100.0, n)}
    if kind == "delassus":   # rank deficient (more contacts than modes), ~1e-7 m/N
        m = int(rng.integers(1, 9))
        return delassus(rng, m, int(rng.integers(1, m + 1))) * 1e-7, 1e-5 * rng.standard_normal(m), {}
    if kind == "general":
        return rng.standard_normal((n, n)), rng.standard_normal(n), {}
    if kind == "repeated_rows":   # every ratio test ties (duplicated contacts, integer data)
        base = rng.integers(-2, 3, (int(rng.integers(1, n + 1)), int(rng.integers(1, 4)))).astype(float)
        G = base[rng.integers(0, base.shape[0], n)]
        b = rng.choice([-1.0, 0.0, 0.0, 0.0, 1.0], n)
        b[rng.integers(n)] = -1.0
        return G @ G.T, b, {"scale": bool(rng.integers(2))}
    m = int(rng.integers(1, 4))
    if kind == "friction":   # physical units: compliance 1e-9..1e2, gaps 1e-6..1 (polygonal cones, r = 4)
        A, b = friction_lcp(rng, int(rng.integers(3 * m, 3 * m + 3)), m, rng.uniform(0.05, 1.0),
                            stiffness=10.0 ** rng.uniform(-2, 7), gap=10.0 ** rng.uniform(-6, 0))
    else:                    # "friction_deficient": fewer modes than constraints (rays, inaccurate ends)
        A, b = friction_lcp(rng, int(rng.integers(1, 3 * m)), m, rng.uniform(0.05, 1.0))
    return A, b, {"groups": friction_groups(m)}


#: per class of random LCP, the relative agreement of x asserted besides the certificate's verdicts (None:
#: the verdicts only). Unique solutions of a well-conditioned basis: both paths solve the same basis matrix
#: A_SS (cond <= 100 for spd, <= 801 for the diagonally dominant / PD / triangular P-matrices with these
#: draws, 1e4 with d's scaling) to a componentwise backward error of 4 eps each (the refinement), so their
#: x differ by <= 8 cond eps: 1.8e-13 at cond 100, 1.4e-12 at 801; 1e-11 leaves a margin of 7 (measured
#: <= 3.7e-15). Elsewhere (rank-deficient, monotone, general, frictional) A_SS may be singular to working
#: precision and x not unique, so only the verdicts are the contract (measured: x within 2.9e-10).
KINDS = {"spd": 1e-11, "p_nonsymmetric": 1e-11, "degenerate": 1e-11, "covering": 1e-11, "psd": None,
         "monotone": None, "degenerate_psd": None, "delassus": None, "general": None, "repeated_rows": None,
         "friction": None, "friction_deficient": None}


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_random_lcps_end_alike_on_both_paths(kind):
    rng = np.random.default_rng(sorted(KINDS).index(kind))
    statuses = set()
    for _ in range(150):
        A, b, kw = _problem(kind, rng)
        fast, ref = both(A, b, **kw)
        assert_same_outcome(fast, ref)
        statuses.add(ref.status)
        if KINDS[kind] is not None:
            assert ref.status == "solved"   # P-matrices: the unique solution
            assert_close(fast, ref, KINDS[kind])
    if kind in ("psd", "monotone", "general", "friction_deficient"):
        assert "ray" in statuses   # the class reaches the secondary-ray branch (a test of it)


def test_integer_degenerate_lcps_take_the_same_pivots():
    """Small integer matrices (half of them A A^T) with b in {-1, 0, 1}: ratio tests tie exactly, often at
    theta = 0, and the lexicographic rule decides. There a basic variable that is 0 in exact arithmetic may be
    +1e-17 on one path and 0 on the other (the reference's BLAS fuses and groups the rank-one update and the
    column products, the kernel does not), which can change a decision. Measured on 3000 such problems: no
    status or pivot count differs on OpenBLAS's Haswell and Sandybridge kernels, 4 (0.13 %) on its SkylakeX
    kernel; a tie rule that merely took the last tied row (not the lexicographic one) differs in 20 %. So at
    most 1 % may differ; where both solve in the same pivots they solved the same basis: x within 1e-9
    (two solves of one basis, backward error 4 eps each: 8 cond eps, cond up to 5e5 allowed; measured 4e-13)."""
    differ, solved = 0, 0
    for seed in range(600):
        rng = np.random.default_rng(seed)
        n = int(rng.integers(2, 7))
        A = rng.integers(-2, 3, (n, n)).astype(float)
        if seed % 2:
            A = A @ A.T
        b = rng.choice([-1.0, -1.0, 0.0, 0.0, 1.0], n)
        fast, ref = both(A, b, scale=bool(seed % 3))
        if (fast.status, fast.pivots) != (ref.status, ref.pivots):
            differ += 1
            continue
        assert_same_outcome(fast, ref)
        if ref.status == "solved":
            solved += 1
            assert_close(fast, ref, 1e-9)
    assert differ <= 6 and solved >= 300, (differ, solved)


def _reference_row(c, xB, Binv, pivot_tol):
    """The leaving row of pivoting.lemke's ratio test and lexicographic rule (None: a ray)."""
    _, pos, _, ties = pivoting._ratio_test(c, xB, pivot_tol)
    if not pos:
        return None
    if len(ties) == 1:
        return ties[0]
    rows = np.column_stack([xB[ties], Binv[ties]]) / c[ties][:, None]
    return ties[pivoting._lexmin(rows, ties)]


def test_one_pivot_leaves_the_reference_row():
    """The kernel's ratio test and tie-breaking against the reference's (_ratio_test, _lexmin) on states made
    of small integers and halves, some a few ulps off (ties in the ratios and in the rows of B^-1, exact and
    up to round-off: the lexicographic rule decides), one pivot each: the same leaving row (or the same ray),
    and the same updated B^-1 and x_B up to the rounding of the update (numpy's may fuse its products: 2 eps
    of the entries' terms, which are <= 16 here: 1e-13 absolute is a margin of 14)."""
    rng = np.random.default_rng(12)
    decided, rays = 0, 0
    for _ in range(3000):
        n = int(rng.integers(1, 8))
        Binv = rng.integers(-2, 3, (n, n)) / 2.0
        xB = rng.choice([0.0, 0.0, 0.5, 1.0, 1.0, 2.0], n)
        Binv[rng.random((n, n)) < 0.1] *= 1.0 + 2 * EPS   # ties up to round-off (16 TIE) in the rows
        xB[rng.random(n) < 0.1] *= 1.0 + 2 * EPS          # and in the ratios (TIE)
        basis = np.arange(n, 2 * n, dtype=np.int64)   # x_0..x_{n-1} basic, z0 out (no z0-tie test)
        v = int(rng.integers(n))                      # w_v enters: its column is B^-1 e_v, exactly
        c = Binv[:, v].copy()
        if not c.any() and rng.random() < 0.8:
            continue
        r = _reference_row(c, xB, Binv, 1e-11)
        B, x, bas = Binv.copy(), xB.copy(), basis.copy()
        state = np.array([v, 1, 0, 1], dtype=np.int64)
        code = lib.pivot(np.eye(n), np.ones(n), B, x, bas, np.empty(n), state, 2, 100, 1e-11, True)
        if r is None:
            assert code == lib.RAY and np.array_equal(bas, basis)
            rays += 1
            continue
        assert code == lib.MAX_PIVOTS and list(np.flatnonzero(bas != basis)) == [r] and bas[r] == v
        decided += len(pivoting._ratio_test(c, xB, 1e-11)[3]) > 1
        ref_B, ref_x = Binv.copy(), xB.copy()
        ref_B[r] /= c[r]
        ref_x[r] /= c[r]
        cr = c.copy()
        cr[r] = 0.0
        ref_B -= np.outer(cr, ref_B[r])
        ref_x = np.maximum(ref_x - cr * ref_x[r], 0.0)
        np.testing.assert_allclose(B, ref_B, rtol=0, atol=1e-13)
        np.testing.assert_allclose(x, ref_x, rtol=0, atol=1e-13)
    assert decided >= 300 and rays >= 100, (decided, rays)   # ties the lexicographic rule broke; rays


@pytest.mark.parametrize("uniform", [True, False])
def test_first_pivot_takes_the_reference_row(uniform):
    """z0 enters first where b_i / d_i is lexicographically smallest: with d = 1 the last of the rows tied on b
    (their rows of B = I tell them apart), else the lexicographic rule on [b / d, I / d]."""
    rng = np.random.default_rng(13)
    for _ in range(500):
        n = int(rng.integers(1, 8))
        bs = rng.choice([-2.0, -1.0, -1.0, 0.0, 1.0], n)
        dv = np.ones(n) if uniform else rng.choice([0.5, 1.0, 1.0, 2.0], n)
        levels = bs.tolist()
        if uniform:
            lo = min(levels)
            r = [i for i, v in enumerate(levels) if v <= lo + 16 * pivoting.TIE * max(abs(v), abs(lo))][-1]
        else:
            r = pivoting._lexmin(np.column_stack([bs / dv, np.eye(n) / dv[:, None]]), np.arange(n))
        basis = np.arange(n, dtype=np.int64)
        state = np.array([2 * n, 0, 0, 0], dtype=np.int64)
        lib.pivot(np.eye(n), dv, np.eye(n), bs.copy(), basis, np.empty(n), state, 1, 100, 1e-11, uniform)
        assert basis[r] == 2 * n and np.count_nonzero(basis == 2 * n) == 1


def test_one_unknown_is_the_reference_loop_bitwise(monkeypatch):
    # one unknown: no product has two terms, so no summation order: the compiled one-unknown path and the
    # compiled loop give the reference loop's result to the bit, certificate and message included (where the
    # solution overflows, x is inf or nan as the loop meets it: the status says overflow on both)
    rng = np.random.default_rng(5)
    edge = [0.0, -0.0, 1.0, -1.0, 3.0, -7.5, 1e-17, 1e-300, -1e-300, 1e300, -1e300, 5e-324]
    cases = [(a, b, {}) for a in edge for b in edge]
    for _ in range(300):
        a, b = rng.standard_normal(2) * 10.0 ** rng.integers(-12, 12, 2)
        cases.append((a, b, {"d": [rng.uniform(0.01, 2.0)]} if rng.random() < 0.3 else {}))
    monkeypatch.setattr(pivoting, "_lemke_one", lambda *args: None)   # the reference takes its loop
    with np.errstate(all="ignore"):
        for a, b, kw in cases:
            for fast in (lemke([[a]], [b], **kw), lemke([[a]], [b], refactor=1, **kw)):   # (refactor=1: loop)
                with core.reference():
                    ref = lemke([[a]], [b], **kw)
                assert (fast.status, fast.pivots, fast.message) == (ref.status, ref.pivots, ref.message)
                if ref.status == "overflow":
                    assert not np.isfinite(fast.x).any() and not np.isfinite(ref.x).any()
                    continue
                assert fast.x.tobytes() == ref.x.tobytes() and fast.w.tobytes() == ref.w.tobytes()
                assert repr(fast.certificate) == repr(ref.certificate)


def test_equilibration_is_the_reference_bitwise():
    # maxima, correctly rounded square roots and products in the same order: bitwise, at any scale
    rng = np.random.default_rng(3)
    for _ in range(300):
        n = int(rng.integers(1, 10))
        A = rng.standard_normal((n, n)) * 10.0 ** rng.uniform(-150, 150, (n, n))
        A[rng.random((n, n)) < 0.3] = 0.0   # zero entries, rows and columns
        r, c = np.empty(n), np.empty(n)
        lib.equilibrate(A, r, c)
        ref = pivoting._equilibrate(A)
        assert r.tobytes() == ref[0].tobytes() and c.tobytes() == ref[1].tobytes()


def test_certificate_agrees_with_the_reference():
    # the same formula; |A| |x| summed in another order: each s_i moves by <= n eps of itself, w is given, so
    # every ratio w_i / s_i and the floor move by <= (n + 1) eps relative: |d relative| <= 2 (n + 1) eps of it
    rng = np.random.default_rng(8)
    for k in range(400):
        n = int(rng.integers(1, 10))
        A = rng.standard_normal((n, n)) * 10.0 ** rng.integers(-8, 8, (n, 1))
        A[rng.random((n, n)) < 0.2] = 0.0
        b = rng.standard_normal(n) * (rng.random(n) < 0.8)
        x = np.maximum(rng.standard_normal(n), 0.0) * 10.0 ** rng.integers(-8, 8, n)
        if k % 7 == 0:
            x[rng.integers(n)] = rng.choice([np.nan, np.inf, -np.inf])
        with np.errstate(all="ignore"):
            w = A @ x + b
        r, c = pivoting._equilibrate(A)
        labels = rng.integers(0, 3, n) if k % 2 else None
        gid = np.empty(0, dtype=np.int64) if labels is None else labels.astype(np.int64)
        with np.errstate(all="ignore"):
            ref = pivoting._certificate(A, b, x, w, (r, c), labels)
        got = dict(zip(("x_min", "w_min", "complementarity", "relative"), lib.certificate(A, b, x, w, r, c, gid)))
        for key in ("x_min", "w_min", "complementarity"):   # exact: the same products, min and max
            assert got[key] == ref[key] or (np.isnan(got[key]) and np.isnan(ref[key])), (key, got, ref)
        if np.isnan(ref["relative"]):
            assert np.isnan(got["relative"])
        else:
            assert abs(got["relative"] - ref["relative"]) <= 2 * (n + 1) * EPS * ref["relative"]


def test_string_groups_certify_as_the_reference():
    # labels of any kind: rows of one label are judged against the largest terms among them
    A, b = friction_lcp(np.random.default_rng(2), 7, 2, 0.3)
    names = np.array(["motion"] * 10 + ["limit"] * 2)
    fast, ref = both(A, b, groups=names)
    assert_same_outcome(fast, ref)
    assert fast.certificate["relative"] <= ACCEPT


@pytest.mark.parametrize("seeds", [range(150), pytest.param(range(150, 600), marks=pytest.mark.slow)],
                         ids=["150", "450_more"])
def test_frictional_bodies_impacts_and_transitions_alike(seeds):
    # the set-closure tests' random 4-dof bodies with two frictional contacts (8-sided pyramids, eps 0.9):
    # their impact LCPs (30-32) and transition LCPs (29, both contacts sticking) through both paths
    statuses = {}
    for seed in seeds:
        sysm, M, J, v = _frictional_body(seed)
        Mf = factorize(M, "M")
        cs = sysm.contacts
        active = [k for k in range(2) if J[:, k] @ v <= 0.0]
        lcps = [impact_lcp(cs, Mf, v, active, eps=np.full(2, 0.9), q=np.zeros(4)),
                transition_lcp(cs, Mf, np.random.default_rng(seed).normal(size=4), [0, 1], [0, 1])]
        for lcp in lcps:
            fast = lcp.solve()
            with core.reference():
                ref = lcp.solve()
            assert_same_outcome(fast, ref)
            statuses[ref.status] = statuses.get(ref.status, 0) + 1
    # measured: 96-97 % solved, the rest rays (Lemke's method has no solution for some frictional bodies)
    assert statuses.get("solved", 0) >= 1.6 * len(seeds) and statuses.get("ray", 0) >= 1, statuses


@pytest.mark.parametrize("n", [3, 6, 9])
def test_murty_refactorization_and_pivot_limit_alike(n):
    # 2^n pivots (z0 in and out included): the refactorization every 7 and the pivot limit at 20 on both paths
    A, q = murty(n)
    for kw in ({"scale": False}, {}, {"scale": False, "refactor": 7}, {"scale": False, "max_pivots": 20}):
        fast, ref = both(A, q, **kw)
        assert_same_outcome(fast, ref)
        if kw.get("scale") is False:   # (the equilibration changes the covering vector: fewer pivots)
            assert fast.pivots == min(2 ** n, kw.get("max_pivots", 2 ** n))
        np.testing.assert_array_equal(fast.x, ref.x)   # integers: (2^n, 0, ...) exactly, or the stop's x


def test_inputs_of_any_layout_and_errors_alike():
    rng = np.random.default_rng(4)
    A, b = spd(rng, 5), rng.standard_normal(5)
    ref = lemke(A, b)
    for layout in (np.asfortranarray(A), np.repeat(np.repeat(A, 2, 0), 2, 1)[::2, ::2], A.tolist()):
        assert lemke(layout, b.tolist()).x.tobytes() == ref.x.tobytes()
    frozen = A.copy()
    frozen.setflags(write=False)
    scales = pivoting._equilibrate(A)
    for s in scales:
        s.setflags(write=False)
    assert lemke(frozen, b, scales=scales).x.tobytes() == ref.x.tobytes()   # cached, read-only parts
    for bad_A, bad_b, kw in ((np.eye(2), np.ones(3), {}), (np.array([[1.0, np.nan], [0.0, 1.0]]), -np.ones(2), {}),
                             (np.eye(2), np.array([-1.0, np.inf]), {}), (np.eye(2), -np.ones(2), {"d": [1.0, 0.0]}),
                             (np.eye(2)[None], -np.ones(2), {}),
                             # labels and scalings of another size (the kernels would read past them)
                             (np.eye(2), -np.ones(2), {"groups": [0, 1, 1]}), (np.eye(2), -np.ones(2), {"groups": [0]}),
                             (np.eye(2), -np.ones(2), {"scales": (np.ones(3), np.ones(2))}),
                             (np.eye(2), -np.ones(2), {"scales": (np.ones(2),)})):
        with pytest.raises(NsfemError) as fast:
            lemke(bad_A, bad_b, **kw)
        with core.reference(), pytest.raises(NsfemError) as slow:
            lemke(bad_A, bad_b, **kw)
        assert str(fast.value) == str(slow.value)
    for n in (0, 3):   # empty, and b >= 0: x = 0 without pivots
        fast, ref = both(np.ones((n, n)), np.ones(n))
        assert_same_outcome(fast, ref)
        assert fast.pivots == 0 and not fast.x.any()


def test_singular_basis_goes_to_the_reference_polish():
    # a basis matrix singular to working precision is the reference's (its SVD path); the kernel says so
    A = np.array([[1.0, 1.0], [1.0, 1.0]])
    b = np.array([-1.0, -1.0])
    x = np.empty(2)
    basis = np.array([2, 3], dtype=np.int64)   # both x basic: A_SS = A, rank 1
    code = lib.polished(A, b, A, b, np.ones(2), np.ones(2), basis, np.array([0.5, 0.5]), -1,
                        np.empty(0, dtype=np.int64), x)
    assert code == lib.NEEDS_SVD
    fast, ref = both(A, b)   # and the whole solve of that rank-one problem ends alike
    assert_same_outcome(fast, ref)


def test_frictional_stop_scene_runs_alike():
    """The stop scene of tests/test_core_equivalence.py with friction on the stop (mu 0.3, 4 generators):
    frictional impact LCPs of 6 unknowns at most of its 164 events. Its impact sequences amplify a last-bit
    change of an LCP solution: the reference alone, on OpenBLAS's Haswell, Sandybridge and SkylakeX kernels,
    gives the same event sequence with event times up to 1.2e-8 s apart and gaps up to 3.1e-8 of their range
    apart (measured), so the harness's 1e-12 cannot hold here whatever the core. The compiled path must stay
    within that spread: the same sequence, times within 1e-7 s and gaps within 3e-7 of their range (margins
    8 and 10; measured 0 and 0 on the Haswell and Sandybridge kernels, 6.5e-11 s and 1.7e-10 on SkylakeX)."""
    from nsfem import load_scene
    from nsfem.simulate import run_scene

    scene = load_scene("default", ['obstacle=[{x=0.5, normal="-z", clearance=2e-4, restitution=0.5, friction=0.3}]',
                                   "simulation.t_end=0.03"])
    fast = run_scene(scene, "exact")[0]
    with core.reference():
        ref = run_scene(scene, "exact")[0]
    assert len(fast.events) == len(ref.events) >= 100 and len(fast.impacts) == len(ref.impacts)
    for a, b in zip(fast.events, ref.events):
        assert {k: v for k, v in a.items() if k != "t"} == {k: v for k, v in b.items() if k != "t"}
        assert abs(a["t"] - b["t"]) <= 1e-7
    assert np.array_equal(fast.state, ref.state)
    assert np.max(np.abs(fast.gap - ref.gap)) <= 3e-7 * float(np.ptp(ref.gap))


def test_wildly_scaled_lcps_end_alike_but_for_rounding_at_thresholds():
    """Random LCPs (n <= 10) whose entries spread over 1e-150..1e150 within one matrix, with and without
    scaling, covering vectors and labels. Measured on 20 000 of them: the same status and pivots on all with
    OpenBLAS's Sandybridge kernel, all but 1 with Haswell's, all but 93 (0.47 %) with SkylakeX's, whose
    products round differently at a tie or threshold (z0 at 1e-14 of b, a ratio at 1e-15 of another). So
    at most 2 % of 1000 may differ; every result either path calls solved is certified (finite x, residual
    <= ACCEPT), and errors are the same."""
    rng = np.random.default_rng(99)
    differ = 0
    for _ in range(1000):
        n = int(rng.integers(0, 11))
        A = rng.standard_normal((n, n)) * 10.0 ** rng.integers(-150, 150, (n, n)) * (rng.random((n, n)) < 0.7)
        b = rng.standard_normal(n) * 10.0 ** rng.integers(-150, 150, n) * (rng.random(n) < 0.8)
        kw = {}
        if rng.random() < 0.3:
            kw["d"] = 10.0 ** rng.uniform(-5, 5, n)
        if rng.random() < 0.3:
            kw["scale"] = False
        if rng.random() < 0.3:
            kw["groups"] = rng.integers(0, 2, n)
        outcomes = []
        for reference in (False, True):
            with np.errstate(all="ignore"), (core.reference() if reference else nullcontext()):
                try:
                    res = lemke(A, b, **kw)
                except NsfemError as exc:
                    outcomes.append(("error", str(exc)))
                    continue
            assert not res.success or (res.residual <= ACCEPT and np.isfinite(res.x).all()), res.message
            outcomes.append((res.status, res.pivots))
        differ += outcomes[0] != outcomes[1]
        if outcomes[0][0] == "error" or outcomes[1][0] == "error":
            assert outcomes[0] == outcomes[1]
    assert differ <= 20, differ


def test_pivot_limits_beyond_int64_end_alike():
    # max_pivots and refactor are Python ints: the reference compares them as they are; the kernel's are
    # int64 (a limit beyond 2^63 raised OverflowError there). No run reaches 2^62 pivots: the same outcome
    A, b = np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-5.0, -6.0])
    for kw in ({"max_pivots": 10 ** 20}, {"refactor": 10 ** 20}, {"max_pivots": -10 ** 20}, {"refactor": -10 ** 20}):
        fast, ref = both(A, b, **kw)
        assert_same_outcome(fast, ref)
        assert fast.message == ref.message   # (the limit printed as given)


def test_labels_of_any_kind_group_as_the_reference():
    """``groups``: labels the reference keys a dict by (its certificate's groups: equal labels, Python's
    equality, each nan its own): the compiled path groups them the same (np.unique raised TypeError on
    labels numpy cannot order, None beside numbers, and merged the nans)."""
    A, b = friction_lcp(np.random.default_rng(2), 7, 2, 0.3)
    n = b.size
    rng = np.random.default_rng(6)
    for labels in ([None if i % 3 else 1.5 for i in range(n)], [np.nan] * n, [float(i % 2) for i in range(n)],
                   [("motion" if i < n - 2 else 7) for i in range(n)], [True] * (n - 2) + [2, 2]):
        fast, ref = both(A, b, groups=labels)
        assert_same_outcome(fast, ref)
        # the certificate alone, at a point that is no solution (a value that depends on the grouping)
        x = np.abs(rng.standard_normal(n))
        w = A @ x + b
        r, c = pivoting._equilibrate(A)
        want = pivoting._certificate(A, b, x, w, (r, c), labels)["relative"]
        from nsfem.lcp.compiled import _group_ids
        got = lib.certificate(A, b, x, w, r, c, _group_ids(labels, n))[3]
        assert abs(got - want) <= 2 * (n + 1) * EPS * want   # (test_certificate_agrees_with_the_reference)
