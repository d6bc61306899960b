"""The compiled kernels of an event's resolution (core part "resolve", issue 33) against their Python
references: transitions._bands (Memory.observe of one state, the gaps, gap rates and their zero bands) and
transitions._rate_bands (the rates after an impulse and their widened bands); and ContactLCP.solve's
direct path for one unknown against lemke (the same compiled kernel: identical results).

Tolerances. The kernels sum J^T x in a plain loop where numpy calls BLAS, whose summation order (and
fused multiply-adds) depend on the CPU; both obey the dot product's forward error bound
|fl(a.x) - a.x| <= n eps |a|.|x|, so they differ by at most twice that: 2 n eps times the sum of the
terms' sizes (|J|^T |x| + |j|), which is what the bands are made of. The bands and scales are sums of
non-negative terms (each within (1 + n eps) relative of the exact one on either side), then scaled by
ZERO and maximised: their difference is at most 2 (n + 2) eps relative. Everything else (the band's
arithmetic, the maxima, nan propagation) is the reference's operation for operation.

Skipped where the compiled core is not installed (no C compiler at install time) or NSFEM_PURE_PYTHON=1.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nsfem.contact.set import ContactSet
from nsfem.errors import NsfemError
from nsfem.integrate import core
from nsfem.integrate.transitions import ZERO, Memory, _bands, _rate_bands
from nsfem.lcp.builders import ContactLCP
from nsfem.lcp.pivoting import equilibrate, lemke

kernel = core.compiled("resolve")
pytestmark = pytest.mark.skipif(kernel is None, reason="the compiled core part 'resolve' is not active (not "
                                                       "built, or NSFEM_PURE_PYTHON=1): the reference runs")
EPS = np.finfo(float).eps


def _contacts(rng: np.random.Generator, n: int, m: int, scale: float, zeros: bool) -> ContactSet:
    """A contact set of m normals on n coordinates: entries over 12 decades around ``scale``, some exactly
    zero (``zeros``), ties (repeated columns)."""
    JN = rng.standard_normal((n, m)) * 10.0 ** rng.uniform(-6, 6, (n, m)) * scale
    if zeros and JN.size:
        JN[rng.random((n, m)) < 0.4] = 0.0
    if m >= 2:
        JN[:, -1] = JN[:, 0]   # a tie: two contacts with the same normal
    jN = rng.standard_normal(m) * scale * 10.0 ** rng.uniform(-8, 0, m)
    return ContactSet.from_arrays(JN, jN)


def _state(rng: np.random.Generator, n: int, scale: float) -> tuple[np.ndarray, np.ndarray]:
    q = rng.standard_normal(n) * scale * 10.0 ** rng.uniform(-10, 0, n)
    v = rng.standard_normal(n) * 10.0 ** rng.uniform(-10, 2, n)
    if n:
        q[rng.random(n) < 0.2] = 0.0
        v[rng.random(n) < 0.2] = 0.0
    return q, v


def _observed(cs: ContactSet, rng: np.random.Generator, n: int, scale: float) -> Memory:
    """A memory that has seen a few states (scales set, as after a run's first event)."""
    mem = Memory(np.zeros(cs.m), np.zeros(cs.m, dtype=int), gap_floor=float(rng.choice([0.0, 1e-15, 1e-3])))
    for _ in range(int(rng.integers(1, 4))):
        mem.observe(cs, *_state(rng, n, scale))
    return mem


def _close(got: np.ndarray, ref: np.ndarray, bound: np.ndarray) -> None:
    got, ref = np.asarray(got, dtype=float), np.asarray(ref, dtype=float)
    assert np.array_equal(np.isnan(got), np.isnan(ref))
    inf = np.isinf(ref)
    assert np.array_equal(got[inf], ref[inf])   # an overflow is the same infinity
    fin = np.isfinite(ref)
    assert np.all(np.abs(got[fin] - ref[fin]) <= bound[fin])


def _check_bands(cs: ContactSet, mem: Memory, q: np.ndarray, v: np.ndarray, gap_tol) -> None:
    n = cs.n
    ref_mem, got_mem = copy.deepcopy(mem), copy.deepcopy(mem)
    g_r, gv_r, tg_r, tv_r = _bands(cs, ref_mem, q, v, gap_tol)
    g_c, gv_c, tg_c, tv_c = _bands(cs, got_mem, q, v, gap_tol, kernel)
    aJ = np.abs(cs.JN)
    gterms, vterms = aJ.T @ np.abs(q) + np.abs(cs.jN), aJ.T @ np.abs(v)
    # the products: twice the dot product's bound; the sums of terms: relative
    dot = 2 * max(n, 1) * EPS
    rel = 2 * (max(n, 1) + 2) * EPS
    _close(g_c, np.array(g_r), dot * gterms)
    _close(gv_c, gv_r, dot * vterms)
    _close(tg_c, np.array(tg_r), rel * np.abs(np.array(tg_r)))
    _close(tv_c, tv_r, rel * np.abs(tv_r))
    _close(got_mem.gap_scale, ref_mem.gap_scale, rel * np.abs(ref_mem.gap_scale))
    _close(got_mem.rate_scale, ref_mem.rate_scale, rel * np.abs(ref_mem.rate_scale))
    assert np.array_equal(got_mem.slip_scale, ref_mem.slip_scale)   # (no friction here: the same zeros)
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
        return
    # what the bands must satisfy whatever the rounding: above the floor, the given tolerances and ZERO
    # times the scales
    tg_c = np.array(tg_c)
    assert np.all(tg_c >= mem.gap_floor) and np.all(tg_c >= ZERO * got_mem.gap_scale)
    assert np.all(tv_c >= ZERO * got_mem.rate_scale) and np.all(tv_c > 0.0)
    if gap_tol is not None:
        assert np.all(tg_c >= gap_tol)


def _check_rates(cs: ContactSet, mem: Memory, v: np.ndarray, tv: np.ndarray) -> None:
    gv_r, tn_r = _rate_bands(cs, mem, v, tv)
    gv_c, tn_c = _rate_bands(cs, mem, v, tv, kernel)
    vterms = np.abs(cs.JN).T @ np.abs(v)
    _close(gv_c, gv_r, 2 * max(cs.n, 1) * EPS * vterms)
    _close(tn_c, tn_r, 2 * (max(cs.n, 1) + 2) * EPS * np.abs(tn_r))
    if np.all(np.isfinite(v)):
        assert np.all(tn_c >= tv)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 40), m=st.integers(1, 12),
       scale=st.sampled_from([1e-300, 1e-9, 1.0, 1e9, 1e150]), zeros=st.booleans(), tol=st.booleans())
def test_bands_match_the_reference(seed, n, m, scale, zeros, tol):
    """Random contact sets and states over 12 decades, with zeros, ties, huge and tiny scales."""
    rng = np.random.default_rng(seed)
    cs = _contacts(rng, n, m, scale, zeros)
    mem = _observed(cs, rng, n, scale)
    q, v = _state(rng, n, scale)
    gap_tol = rng.uniform(0, 1e-6, m) * scale if tol else None
    _check_bands(cs, mem, q, v, gap_tol)
    v_new = v + rng.standard_normal(n) * 10.0 ** rng.uniform(-12, 0, n)
    _check_rates(cs, mem, v_new, rng.uniform(0, 1e-12, m))


def test_cancelled_state_and_empty_sets():
    """A state whose gaps cancel exactly (bands from the terms, not the zero result), all-zero states, and
    contact sets without contacts or coordinates."""
    rng = np.random.default_rng(7)
    JN = np.array([[1.0, -1.0], [1.0, 1.0], [0.0, 3.0]])
    cs = ContactSet.from_arrays(JN, np.array([-2.0, 0.0]))
    mem = _observed(cs, rng, 3, 1.0)
    _check_bands(cs, mem, np.array([1.0, 1.0, 0.0]), np.array([0.5, 0.5, 0.0]), None)   # g = 0, g' = (0, 1)
    _check_bands(cs, mem, np.zeros(3), np.zeros(3), np.zeros(2))
    _check_rates(cs, mem, np.zeros(3), np.zeros(2))
    for n, m in ((3, 0), (0, 2)):
        empty = ContactSet.from_arrays(np.zeros((n, m)), np.zeros(m))
        mem = Memory(np.zeros(m), np.zeros(m, dtype=int))
        mem.observe(empty, np.zeros(n), np.zeros(n))
        _check_bands(empty, mem, np.ones(n), np.ones(n), None)
        _check_rates(empty, mem, np.ones(n), np.zeros(m))


def test_non_finite_entries_propagate_as_in_numpy():
    """An overflowed state (inf, nan) gives nan or inf where numpy's products and maxima give them."""
    cs = ContactSet.from_arrays(np.array([[1.0, 0.0], [2.0, 1.0]]), np.array([0.0, 1.0]))
    mem = _observed(cs, np.random.default_rng(3), 2, 1.0)
    for bad in (np.inf, -np.inf, np.nan):
        with np.errstate(invalid="ignore"):
            _check_bands(cs, mem, np.array([bad, 0.0]), np.array([1.0, 0.0]), None)
            _check_bands(cs, mem, np.array([0.0, 1.0]), np.array([0.0, bad]), None)
            _check_rates(cs, mem, np.array([0.0, bad]), np.zeros(2))


@settings(max_examples=80, deadline=None)
@given(a=st.floats(1e-300, 1e300),
       b=st.one_of(st.floats(-1e300, 1e300), st.sampled_from([0.0, -0.0, 5e-324, math.nan, math.inf, -math.inf])))
def test_one_unknown_lcp_is_lemkes_result(a, b):
    """An impact LCP of one unknown (most impacts) goes straight to the compiled kernel from its cached
    equilibration: the same result as lemke's (x, w, status, pivots, message and certificate, exactly: the
    same kernel on the same numbers), including where it declines (scaled entries near overflow)."""
    if core.compiled("lcp") is None:
        pytest.skip("the compiled core part 'lcp' is not active")
    A = np.array([[a]])
    scales = equilibrate(A)
    lcp = ContactLCP(A, np.array([b]), np.array([0]), np.zeros(0, dtype=int), np.zeros(0, dtype=int),
                     np.ones((1, 1)), np.ones((1, 1)), (), np.zeros(1), scales)
    if not math.isfinite(b):   # lemke's own error, from its checks (the direct path declines)
        with pytest.raises(NsfemError) as ref_err:
            lemke(A, np.array([b]), groups=lcp.groups, scales=scales)
        with pytest.raises(NsfemError) as got_err:
            lcp.solve()
        assert str(got_err.value) == str(ref_err.value)
        return
    got = lcp.solve()
    ref = lemke(A, np.array([b]), groups=lcp.groups, scales=scales)
    assert (got.status, got.pivots, got.message) == (ref.status, ref.pivots, ref.message)
    assert np.array_equal(got.x, ref.x, equal_nan=True) and np.array_equal(got.w, ref.w, equal_nan=True)
    same = lambda x, y: x == y or (x != x and y != y)   # noqa: E731 - (a nan residual is the same nan)
    assert got.certificate.keys() == ref.certificate.keys()
    assert all(same(got.certificate[k], ref.certificate[k]) for k in ref.certificate)
    assert same(got.residual, ref.residual)
    # what a solved answer must satisfy: x >= 0, and x = 0 where b >= 0 (nothing to push)
    if got.success:
        assert got.x[0] >= 0.0 and (b < 0.0 or got.x[0] == 0.0)


def test_bands_of_a_number_or_a_short_array_are_the_references():
    """Reproduction (review-b): the kernels read gap_tol[k], q[i] without bounds checks; a gap tolerance given as
    one number (the reference broadcasts it to every contact) was read as a one-entry array, the other
    contacts' bands from whatever lay past it, and a state two coordinates short summed memory past its end.
    Now such calls take the reference: the same bands, or numpy's ValueError."""
    rng = np.random.default_rng(0)
    m, n = 6, 4
    cs = ContactSet.from_arrays(rng.standard_normal((n, m)), rng.standard_normal(m) * 1e-3)
    mem = Memory(np.zeros(m), np.zeros(m, dtype=int))
    mem.observe(cs, rng.standard_normal(n), rng.standard_normal(n))
    q, v = rng.standard_normal(n), rng.standard_normal(n)
    for tol in (0.5, np.array([0.5])):
        tg = _bands(cs, copy.deepcopy(mem), q, v, tol, kernel)[2]
        assert tg == _bands(cs, copy.deepcopy(mem), q, v, tol)[2] and min(tg) == 0.5   # each band is the tolerance
    for args in ((q, v, np.full(3, 0.5)), (q[:2], v[:2], None)):
        with pytest.raises(ValueError):
            _bands(cs, copy.deepcopy(mem), *args, kernel)
    with pytest.raises(ValueError):
        _rate_bands(cs, mem, v[:2], np.ones(m), kernel)


def test_one_unknown_lcp_on_degenerate_entries_is_lemkes_result():
    """The direct path of a one-unknown LCP on the entries hypothesis's range leaves out: A zero (either sign),
    negative, subnormal, at the float limit, non-finite (then no cached equilibration: lemke decides), against b
    of every kind. The same kernel on the same numbers: lemke's result or error, exactly (review-b)."""
    if core.compiled("lcp") is None:
        pytest.skip("the compiled core part 'lcp' is not active")
    special = [0.0, -0.0, 5e-324, -5e-324, -1.0, 1.0, -1e300, 1e300, 1.7e308, -1.7e308, math.inf, -math.inf, math.nan]
    for a in special:
        for b in special:
            A = np.array([[a]])
            scales = equilibrate(A) if math.isfinite(a) else None   # (a cached matrix part equilibrates finite A)
            lcp = ContactLCP(A, np.array([b]), np.array([0]), np.zeros(0, dtype=int), np.zeros(0, dtype=int),
                             np.ones((1, 1)), np.ones((1, 1)), (), np.zeros(1), scales)
            with np.errstate(all="ignore"):
                try:
                    ref = lemke(A, np.array([b]), groups=lcp.groups, scales=scales)
                except NsfemError as exc:
                    with pytest.raises(NsfemError) as got_err:
                        lcp.solve()
                    assert str(got_err.value) == str(exc)
                    continue
                got = lcp.solve()
            assert repr((got.status, got.pivots, got.message, got.x, got.w, got.residual, got.certificate)) == \
                repr((ref.status, ref.pivots, ref.message, ref.x, ref.w, ref.residual, ref.certificate)), (a, b)


def test_kernels_refuse_arrays_of_the_wrong_shape():
    """Review of issue 33: state_bands and rate_bands read and write without bounds checks and had no shape
    checks: a memory whose scales were formed for another contact set (a value per contact of that set), an
    output or a state a row short, were read or written past their ends. Each is a ValueError now, before any
    access; the arrays transitions._bands and _rate_bands pass are accepted."""
    rng = np.random.default_rng(7)
    n, m = 5, 3
    cs = _contacts(rng, n, m, 1.0, False)
    mem = _observed(cs, rng, n, 1.0)
    q, v = _state(rng, n, 1.0)
    JNT, aJT, jN, aj = mem.kernel_arrays(cs)
    args = [JNT, aJT, jN, aj, q, v, mem.gap_scale, mem.rate_scale, np.zeros(0), 0.0, np.empty((6, m))]
    kernel.state_bands(*args)
    short = lambda a: np.ascontiguousarray(a[:-1])  # noqa: E731
    for j, bad in ((0, short(JNT)), (1, np.ascontiguousarray(aJT[:, :-1])), (2, short(jN)), (3, short(aj)),
                   (4, short(q)), (5, short(v)), (6, short(mem.gap_scale)), (7, short(mem.rate_scale)),
                   (8, np.ones(m + 1)), (10, np.empty((5, m))), (10, np.empty((6, m - 1)))):
        spoilt = list(args)
        spoilt[j] = bad
        with pytest.raises(ValueError, match="state_bands"):
            kernel.state_bands(*spoilt)
    args = [JNT, aJT, v, np.ones(m), np.empty((2, m))]
    kernel.rate_bands(*args)
    for j, bad in ((1, short(aJT)), (2, short(v)), (3, short(np.ones(m))), (4, np.empty((1, m))),
                   (4, np.empty((2, m - 1)))):
        spoilt = list(args)
        spoilt[j] = bad
        with pytest.raises(ValueError, match="rate_bands"):
            kernel.rate_bands(*spoilt)
