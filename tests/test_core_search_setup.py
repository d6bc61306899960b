"""The compiled search's set-up (nsfem/integrate/core/_search.pyx, ``Search``: the band from the state at 33
times, the rows' images of the phase's terms, the plan of the terms the search follows) against its Python
reference (events.band_tolerance, events.modal_images, Phase.search_plan with first_event's plan_from),
issue 33.

Both compute the same sums in the same order where the reference does not call BLAS; where it does (|H| @
|xi|, H V g^T, |H U| @ (|nu|^4 e^{Re nu tau})), the compiled sums run in the order of their terms and the two
differ by round-off: at most (number of terms) * eps times the sum of the magnitudes of the terms summed
(the classical bound of a sum, doubled for the products inside each term). The tolerances below are that
bound, formed from the case's own arrays, never a measured difference. The plan's choices (which modes
are left out, the renewal) are integers and flags: identical, unless a running sum lies within that
round-off of its budget (a tie the two may break either way; counted, and required to be rare).

The random phases are test_event_search's (its generator): every kind, the modal path (both ways of
forming the images: from the rows plan's H V and the amplitudes, and from H U), plus scaled, zero and tied
rows. Skipped where the compiled search is not installed (the reference then runs everywhere).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_event_search import KINDS, _system, make_case

from nsfem.integrate import core, events
from nsfem.integrate.closed_form import power
from nsfem.integrate.configuration import Configuration, Mode, Phase
from nsfem.integrate.events import Rows, first_event

pytestmark = pytest.mark.skipif(core.compiled("search") is None,
                                reason="the compiled search is not installed (no C compiler at install time)")

EPS = np.finfo(float).eps
QUICK = range(8)


def _rows(case_phase, H, with_hv: bool) -> Rows:
    """Rows of H; with the rows plan's arrays (round-off weights, H V) where asked and possible."""
    rows = Rows(np.ascontiguousarray(H), ["close"] * H.shape[0], list(range(H.shape[0])))
    rows.Hd = np.ascontiguousarray(H @ case_phase.A_aug)
    cfg = case_phase.config
    if with_hv and cfg.plan is not None and cfg.k == 0 and case_phase.amplitudes is not None:
        r2 = 2 * cfg.r
        rows.weights = np.abs(H[:, :r2]).sum(axis=1)
        rows.HV = np.vstack([rows.H, rows.Hd])[:, :r2] @ cfg.plan.V
    return rows


def _compiled_setup(phase, rows, t0, t1, monkeypatch):
    """The set-up of the Search the compiled path builds for this search (Search.setup and Search.images as
    constructed: its run may renew the plan), or None off the modal path."""
    search, made = core.compiled("search"), []

    class Spy:
        @staticmethod
        def Search(*args):
            run = search.Search(*args)
            made.append((run.setup(), run.images()))
            return run

    with monkeypatch.context() as m:
        m.setitem(core._active, "search", Spy)
        first_event(phase, rows, t0, t1)
    return made[0] if made else None


def _reference_setup(phase, rows, t0, t1):
    """first_event's set-up on the reference path: (tol, band, bound4, h_step, rate, renew_at, kept terms,
    images, the plan's sizes and budget)."""
    H, Hd, k = rows.H, rows.Hd, rows.size
    tol = events.band_tolerance(phase, H, t0, t1, rows.weights)
    images = events.modal_images(phase, rows)
    budget = np.concatenate([tol / 4.0, np.full(k, np.inf)])
    plan = phase.search_plan(np.vstack([H, Hd]), budget, t1 - phase.t0, t0 - phase.t0, images=images)
    step = phase.max_step(t1 - phase.t0, plan.rate)
    bound4 = plan.bound(4)[:k] * power(step, 4) / 384.0
    renew_at = max(phase.t0 + plan.renew, t0 + step)
    return tol, tol - plan.e[:k], bound4, step, plan.rate, renew_at, plan.rows.terms.nu.size, images


def _sum_bounds(phase, H, t0, t1):
    """Per row, the round-off bound of the band's sums: eps * (terms) * max over the 33 times of |H| (|U|
    |e^{nu tau}|) (each state component's terms by magnitude), the repeated products' 33 eps included."""
    mot, r2 = phase._modal, 2 * phase.config.r
    step = phase.max_step(math.inf)
    window = min(step, t1 - t0) if math.isfinite(step) else t1 - t0
    tau = (t0 - phase.t0) + window / 32.0 * np.arange(33)
    mags = np.abs(mot.U) @ np.abs(np.exp(np.outer(mot.nu, tau)))     # r2 x 33
    states = np.vstack([mags, np.ones((H.shape[1] - r2, 33))])
    n = mot.nu.size + H.shape[1] + 33 + 4
    return 4.0 * n * EPS * (np.abs(H) @ states).max(axis=1), 4.0 * n * EPS * float(mags.max())


def _check_case(phase, H, t0, t1, with_hv, monkeypatch) -> tuple[str | None, bool]:
    """(None or what differs, whether a plan's choice was a tie within round-off)."""
    rows = _rows(phase, H, with_hv)
    made = _compiled_setup(phase, rows, t0, t1, monkeypatch)
    if made is None:   # (the callers' phases are on the modal path: the compiled call must have been built)
        return "no compiled search was built on the modal path: nothing compared", False
    (tol_c, band_c, b4_c, step_c, rate_c, renew_c, keep_c), img_c = made
    tol_r, band_r, b4_r, step_r, rate_r, renew_r, n_kept_r, images_r = _reference_setup(phase, rows, t0, t1)
    k, r2 = rows.size, 2 * phase.config.r
    sums, big = _sum_bounds(phase, H, t0, t1)
    weights = np.abs(H[:, :r2]).sum(axis=1)
    # the band: ZERO times the sums' bound, or round_off's 16 eps weights times the largest state's bound
    allowed = np.maximum(events.ZERO * sums, 16.0 * EPS * weights * big) + 4.0 * EPS * tol_r
    if np.any(np.abs(tol_c - tol_r) > allowed):
        return f"tol {tol_c} vs {tol_r} (allowed {allowed})", False
    # the images: H V diag(c) and H V g^T (or H U) are sums over the state's components and the modes: their
    # round-off is (components + modes) eps times the sums of their terms' magnitudes
    img_c = img_c[:, : images_r.shape[1]]
    HH = np.abs(np.vstack([rows.H, rows.Hd])[:, :r2])
    scale = HH @ np.abs(phase._modal.U)
    if phase.amplitudes is not None and phase.config.plan is not None:
        c, g = phase.amplitudes
        HV = HH @ np.abs(phase.config.plan.V)
        scale = np.maximum(scale, np.hstack([HV * np.abs(c), HV @ np.abs(g).T]))
    if np.any(np.abs(img_c - images_r) > 4.0 * (r2 + scale.shape[1] + 2) * EPS * scale + 1e-300):
        return "images differ beyond the round-off of their sums", False
    # the plan: the same terms kept unless a running sum ties its budget within the images' round-off
    if int(keep_c.sum()) != n_kept_r or rate_c != rate_r:
        mot = phase._modal
        size = np.abs(images_r[:k, : mot.nu.size])
        _, order, _ = phase.config.term_order(mot.nu)
        cum = np.cumsum(size[:, order], axis=1)
        slack = np.abs(cum - (tol_r / 4.0)[:, None]) <= 8.0 * (r2 + order.size + 2) * EPS * (
            np.cumsum((scale[:k, : mot.nu.size])[:, order], axis=1) + np.abs(tol_r / 4.0)[:, None])
        if not slack.any():
            return f"kept {keep_c.sum()} terms (rate {rate_c}) vs {n_kept_r} (rate {rate_r})", False
        return None, True
    # the step from the same rate; bound4 a sum of |images| |nu|^4 decay factors (its terms' count eps)
    if abs(step_c - step_r) > 4.0 * EPS * step_r:
        return f"step {step_c} vs {step_r}", False
    b4_allowed = 8.0 * (phase._modal.nu.size + 4) * EPS * np.abs(b4_r) + 1e-300
    if np.any(np.abs(b4_c - b4_r) > b4_allowed):
        return f"bound4 {b4_c} vs {b4_r}", False
    # band = tol - e: tol's round-off and e's (a running sum of the sizes)
    e_allowed = allowed + 8.0 * (r2 + phase._modal.nu.size) * EPS * np.abs(tol_r - band_r)
    if np.any(np.abs(band_c - band_r) > e_allowed):
        return f"band {band_c} vs {band_r}", False
    # the renewal, log(size / (budget - cum)) / -Re(nu), amplifies round-off by the cancellation of budget -
    # cum and by 1 / |Re nu| (1e18 s for a mode that barely decays); it only says where the search re-plans
    # (each plan is certified from where it starts), and only within the horizon: there, the two agree
    # within 1e-9 of the horizon; beyond it, both are beyond
    if min(renew_c, renew_r) < t1 and abs(renew_c - renew_r) > 1e-9 * (t1 - t0):
        return f"renewal at {renew_c} vs {renew_r}", False
    return None, False


@pytest.mark.parametrize("kind", KINDS)
def test_setup_is_the_references_on_random_phases(kind, monkeypatch):
    """Band, images, kept terms, rate, step, bound4 and renewal of the compiled set-up against the reference's
    on random phases of every kind, the images formed both ways; a tie of a running sum with its budget within
    round-off at most once in 10 searches (the phases are drawn, not tuned to ties)."""
    failures, searched, ties = [], 0, 0
    for seed in QUICK:
        case = make_case(seed, kind)
        if case is None or case.phase._modal is None:
            continue
        for with_hv in (True, False):
            bad, tie = _check_case(case.phase, case.H, case.t0, case.t1, with_hv, monkeypatch)
            searched += 1
            ties += tie
            if bad:
                failures.append(f"{kind} seed {seed} (H V {with_hv}): {bad}")
    assert not failures, "\n".join(failures)
    assert searched >= len(QUICK), searched
    assert ties <= 0.1 * searched, (ties, searched)


@pytest.mark.parametrize("scale", [1e-150, 1e-20, 1.0, 1e20, 1e150])
def test_setup_holds_at_any_scale_of_the_rows(scale, monkeypatch):
    """Rows scaled by powers of ten up to 1e+-150 (gaps in metres next to forces in newtons, in any unit
    system): the same set-up as the reference, to the same relative round-off (no under- or overflow on
    either path: the sums' terms stay within the range)."""
    case = make_case(1, "generic")
    bad, _ = _check_case(case.phase, case.H * scale, case.t0, case.t1, True, monkeypatch)
    assert bad is None, bad


def test_setup_of_rows_with_zero_and_tied_entries(monkeypatch):
    """A row without any modal part (a constant: every mode left out at once, its band its round-off
    floor), a row repeated (two equal rows: equal bands and bounds), a zero harmonic column, a window of zero
    length (t_stop = t_start: the 33 samples at one time)."""
    case = make_case(2, "generic")
    H = np.vstack([case.H, case.H[:1]])
    const = np.zeros(H.shape[1])
    const[2 * case.phase.config.r] = 1.0
    H = np.vstack([H, const])
    bad, _ = _check_case(case.phase, H, case.t0, case.t1, True, monkeypatch)
    assert bad is None, bad
    (tol, band, b4, *_), _ = _compiled_setup(case.phase, _rows(case.phase, H, True), case.t0, case.t1, monkeypatch)
    assert tol[0] == tol[-2] and band[0] == band[-2] and b4[0] == b4[-2]   # the same sums of the same terms
    assert b4[-1] == 0.0 and band[-1] == tol[-1] > 0.0                      # nothing moves: nothing bounded
    bad, _ = _check_case(case.phase, H, case.t0, case.t0, True, monkeypatch)
    assert bad is None, bad


def test_search_hands_over_where_the_bound_does_not_screen(monkeypatch):
    """A growing mode bounded at the end of a long horizon (e^{Re(nu) T} = e^{60}) makes a bound4 that no
    subdivision brings down to the band: the compiled call hands the search back to the Python loop (a
    _Handover, its band the call's), which finds the reference's event."""
    rng = np.random.default_rng(5)
    w = np.array([20.0, 300.0])
    S, Pi = _system(rng, w, np.array([-0.01, 0.02]))     # mode 0 grows at 0.2 1/s
    Phi = np.linalg.inv(Pi)
    phase = Phase(Configuration(S, Mode()), 0.0, Phi @ np.array([1e-3, 1e-4]), Phi @ np.array([0.0, 0.0]),
                  np.zeros(0))
    assert phase._modal is not None
    H = np.zeros((1, phase.dim))
    H[0, : phase.config.r] = Pi[0] @ phase.config.N     # the growing modal coordinate, plus a level
    H[0, 2 * phase.config.r] = 5e-3
    t1 = 300.0
    handed = []

    class Handover(events._Handover):
        def __new__(cls, x):
            handed.append(x)
            return super().__new__(cls, x)

    monkeypatch.setattr(events, "_Handover", Handover)
    rows = Rows(H, ["close"], [0])
    a = first_event(phase, rows, 0.0, t1)
    assert handed, "the compiled call did not hand over"
    # by the reference's rule (events._compilable) too: the plan from the start cannot be screened
    rows.Hd = H @ phase.A_aug
    tol, band, bound4, *_ = _reference_setup(phase, rows, 0.0, t1)
    plan = phase.search_plan(np.vstack([H, rows.Hd]), np.concatenate([tol / 4.0, [np.inf]]), t1, 0.0)
    assert not events._compilable(phase, plan.rows, band, bound4)
    # handed over at the start, before any row was armed, with the call's band (the reference's, to round-off)
    assert handed[0][1] == 0.0 and handed[0][2] is None
    assert np.allclose(handed[0][0], tol, rtol=1e-12, atol=0.0)
    with core.reference():
        b = first_event(phase, Rows(H, ["close"], [0]), 0.0, t1)
    assert a is not None and b is not None
    assert (a.rows, a.graze, a.in_band) == (b.rows, b.graze, b.in_band)
    # the root refined from the state on both paths: within the contract's 1e-12 relative
    assert abs(a.t - b.t) <= 1e-12 * max(1.0, abs(b.t))


def test_the_band_lanes_round_as_scalar_code():
    """The band's sums run four times side by side in vector lanes (an AVX2 clone where the CPU has it): each
    lane's x + (a u - b v) and x + a u must be the scalar C expression's double bit for bit (no contraction, no
    reassociation), on random values of every scale, signed zeros, subnormals, infinities and nan, and on
    lengths that are not multiples of four."""
    search = core.compiled("search")
    rng = np.random.default_rng(11)
    specials = np.array([0.0, -0.0, 5e-324, -5e-324, 1e-310, 1e308, -1e308, np.inf, -np.inf, np.nan, 1.0, -1.0])

    def draw(n):
        return np.where(rng.random(n) < 0.2, rng.choice(specials, n),
                        rng.standard_normal(n) * 10.0 ** rng.uniform(-300, 300, n))

    for n in (0, 1, 3, 4, 5, 33, 36):
        for trial in range(20):
            x, u, v = draw(n), draw(n), draw(n)
            a, b = (float(draw(1)[0]) for _ in range(2))
            vec_add, ref_add, vec_axpy, ref_axpy = (np.array(r, dtype=float) for r in search.lanes(x, u, v, a, b))
            # bit for bit (a nan's payload aside: any nan is the same answer)
            for got, want in ((vec_add, ref_add), (vec_axpy, ref_axpy)):
                same = (got.view(np.int64) == want.view(np.int64)) | (np.isnan(got) & np.isnan(want))
                assert same.all(), (n, trial, got[~same], want[~same])



def test_search_hands_over_after_a_renewal_with_rows_armed(monkeypatch):
    """Review of issue 33 (csetup): the hand-over after a renewal, with rows already armed. An overdamped stiff
    mode (exponents -536 and -7464 1/s) sets the first plans' step, so they screen; once it has decayed into
    the budget (renewal at about 3 ms) the plan follows the slow mode, which grows at 0.2 1/s over a horizon of
    150 s (e^30): its bound no longer screens and the compiled call hands the search back to the Python loop.
    By then two rows are armed at 0 (they start above their bands), a zero row sits in its band (unarmed), and
    a row that started 1e-6 below zero is still rising towards its band (unarmed, its threshold the start's
    h - band). The hand-over carries exactly that, and the Python loop finds the reference's event."""
    rng = np.random.default_rng(5)
    S, Pi = _system(rng, np.array([20.0, 2000.0]), np.array([-0.01, 2.0]))
    Phi = np.linalg.inv(Pi)
    phase = Phase(Configuration(S, Mode()), 0.0, Phi @ np.array([1e-3, 1e-3]), np.zeros(2), np.zeros(0))
    assert phase._modal is not None
    r, c = phase.config.r, 2 * phase.config.r
    N = phase.config.N
    H = np.zeros((4, phase.dim))
    H[0, :r], H[0, c] = (Pi[0] + Pi[1]) @ N, 5e-3           # both modes, 5e-3 above zero
    H[1, :r], H[1, c] = (Pi[0] - 0.5 * Pi[1]) @ N, 6e-3
    H[3, :r], H[3, c] = -0.01 * Pi[0] @ N, 1e-5 - 1e-6     # -1e-6 at the start, rising as 1e-5 (1 - cos 20t)
    handed = []

    class Handover(events._Handover):
        def __new__(cls, x):
            # (copies: the Python loop goes on arming the rows in the arrays it was handed)
            handed.append(tuple(None if a is None else np.array(a, copy=True) for a in x[2:]) + (x[1],))
            return super().__new__(cls, x)

    monkeypatch.setattr(events, "_Handover", Handover)
    rows = lambda: Rows(H, ["close"] * 4, [0, 1, 2, 3])  # noqa: E731
    a = first_event(phase, rows(), 0.0, 150.0)
    assert handed, "the compiled call did not hand over"
    armed, thr, t_h = handed[0]
    # after a renewal (the first plan screens), before the rising row reaches its band (about 23 ms)
    assert 0.0 < t_h < 0.01, t_h
    assert armed is not None and armed.tolist() == [True, True, False, False]
    assert thr[0] == thr[1] == 0.0
    # the zero row and the rising row keep the thresholds set at the start, min(-band, h(t_start) - band): the
    # bands are ZERO (1e-11) times the rows' terms (<= 1e-13 here), so the rising row's threshold is h(0) to
    # 1e-12; read again at the hand-over it would be 1.7e-8 higher (the row's rise by then)
    h0 = H @ phase.xi(0.0)
    assert -1e-12 <= thr[2] < 0.0
    assert abs(thr[3] - h0[3]) <= 1e-12, (thr[3], h0[3])
    assert H[3] @ phase.xi(float(t_h)) - h0[3] > 1e-8
    with core.reference():
        b = first_event(phase, rows(), 0.0, 150.0)
    assert a is not None and b is not None
    assert (a.rows, a.graze, a.in_band) == (b.rows, b.graze, b.in_band)
    # the root refined from the state on both paths: within the contract's 1e-12 relative
    assert abs(a.t - b.t) <= 1e-12 * max(1.0, abs(b.t))


def test_the_compiled_core_has_no_fused_multiply_adds():
    """Review of issue 33: setup.py builds the kernels with -ffp-contract=off so that each product and sum
    rounds as the reference's formula, but GCC's vectorizer still formed fused complex multiply-adds
    (vfmaddsub: the compiled search's images H V diag(c), the phase kernels' complex products) when CFLAGS let
    the target have FMA (-march=haswell, x86-64-v3, native); the vectorizer is off now. The x86-64 build's
    machine code holds no FMA instruction of any width (skipped elsewhere, or without objdump)."""
    import platform
    import shutil
    import subprocess

    if platform.machine() not in ("x86_64", "AMD64") or shutil.which("objdump") is None:
        pytest.skip("an x86-64 check of the machine code (needs objdump)")
    for part in core.PARTS:
        module = core.compiled(part)
        if module is None or not getattr(module, "__file__", None):
            continue
        code = subprocess.run(["objdump", "-d", "--no-show-raw-insn", module.__file__], capture_output=True,
                              text=True, check=True).stdout
        fused = [line for line in code.splitlines() if "\tvfm" in line or "\tvfnm" in line]
        assert not fused, (part, fused[:5])
