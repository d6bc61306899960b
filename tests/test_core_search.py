"""The compiled search of one phase (nsfem/integrate/core/_search.pyx, ``Search.run``) against its
pure-Python reference (``events.first_event``'s loop under ``core.reference()``), issue 33.

The random phases are test_event_search's (its generator, whose reference search that file checks
against a dense brute force): both paths must find the same event (rows, graze, in_band) or none,
at times within 1e-12 relative. The compiled path reads the rows by plain C sums where the
reference uses BLAS products (and numpy's exp/cos/sin where it uses libm's): the values differ in
their last bits, and a root refined to round-off moves by that over the row's slope. That is
1e-12 of the time except at a near-tangent crossing (the graze kinds: a minimum within a few bands
of zero), where a last-bit change of h moves the root by (round-off) / |h'| with h' near 0; there
the two times must be indistinguishable at the row's resolution instead: between them the row moves
by less than its band plus twice its own round-off (|t_a - t_b| max|h'| <= tol + 2 jitter, jitter:
test_event_search's measure of how far the row read near t strays from a straight line; about 1e-5
tol, but up to 40 tol for a nearly defective mode's closed form, cond(V) eps). The reference itself
moves such roots as much between two OpenBLAS kernels (measured: up to 1e-5 relative on the graze
kinds, whose cases it draws differently there).

Where a row's band lies below its own round-off (eps times the sum of the magnitudes of its terms,
read from its modal coefficients or from the state, reaches the band: terms that nearly cancel, as
the three_roots and wiggle kinds build them, up to 3e4 bands), two evaluations that round
differently may decide either way whether it crossed, grazed or armed, or which of two roots within
that noise comes first; such a disagreement is accepted as marginal, and must stay a small minority
(at most 5 % of the searches: a systematic difference would not be). Measured over the 550 seeds of
the slow run (7872 compiled searches): 31 marginal (graze 4, three_roots 7, wiggle_graze 20), no
other disagreement.

Rows that start inside their band (a gap just after an impact) take the arming path: each case is
also searched with its first row shifted to start at zero, as it is and negated (on the 40 default
cases: 40 in_band events, a row leaving its band downwards, and 24 events of a row armed on its way
up and fired later).

Skipped where the compiled search is not installed (the reference then runs everywhere).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_event_search import KINDS, SEEDS, SLOW_SEEDS, _jitter, make_case

from nsfem.integrate import core, events
from nsfem.integrate.closed_form import divided_exp
from nsfem.integrate.events import Rows, _screen_row, first_event

pytestmark = pytest.mark.skipif(core.compiled("search") is None,
                                reason="the compiled search is not installed (no C compiler at install time)")

#: random phases per kind in the default run (the slow run: all of test_event_search's seeds)
QUICK = range(8)


def _search(phase, H, t0, t1, reference: bool, report=None):
    rows = Rows(H, ["close"] * H.shape[0], list(range(H.shape[0])))
    if reference:
        with core.reference():
            return first_event(phase, rows, t0, t1, report)
    return first_event(phase, rows, t0, t1, report)


def _same_event(case, H, a, b) -> str | None:
    """None when the compiled event a is the reference's b (the module's tolerances), else why not."""
    if a is None or b is None:
        return None if a is b else f"one path finds no event: compiled {a}, reference {b}"
    if (a.rows, a.graze, a.in_band) != (b.rows, b.graze, b.in_band):
        return f"different events: compiled {a.rows, a.graze, a.in_band}, reference {b.rows, b.graze, b.in_band}"
    gap = abs(a.t - b.t)
    if gap <= 1e-12 * max(1.0, abs(b.t)):
        return None
    # a near-tangent root: the row moves by less than its band and its round-off between the two times
    # (h' at 9 points)
    phase = case.phase
    Hd = H @ phase.A_aug
    ts = np.linspace(min(a.t, b.t), max(a.t, b.t), 9)
    noise = _jitter(case.ref, H, b.t)
    for i in b.rows:
        moved = gap * max(abs(float(Hd[i] @ phase.xi(float(t)))) for t in ts)
        if moved > b.tol[i] + 2.0 * noise[i]:
            return f"row {i}: times {a.t!r} and {b.t!r}, the row moves {moved / b.tol[i]:.3g} bands between them"
    return None


def _round_off(phase, Hi, t: float) -> float:
    """eps times the sum of the magnitudes of row Hi's terms at t, read from its modal coefficients or
    from the state (whichever is larger): what two evaluations that round differently may differ by."""
    mot, r2 = phase._modal, 2 * phase.config.r
    tau = np.array([t - phase.t0])
    E = np.abs(np.exp(mot.nu * tau[0]))
    rows, state = np.abs(Hi[:r2] @ mot.U) @ E, np.abs(Hi[:r2]) @ (np.abs(mot.U) @ E)
    for nodes, D in mot.groups:
        F = np.abs(divided_exp(nodes, tau)[:, 0])
        rows, state = rows + np.abs(Hi[:r2] @ D) @ F, state + np.abs(Hi[:r2]) @ (np.abs(D) @ F)
    return float(np.finfo(float).eps * (max(rows, state) + np.abs(Hi[r2:]).sum()))


def _marginal(case, H, a, b) -> bool:
    """True when a row of either event has its band below its own round-off at either event's time."""
    events_ = [e for e in (a, b) if e is not None]
    return any(_round_off(case.phase, H[i], e.t) >= ev.tol[i]
               for ev in events_ for i in ev.rows for e in events_)


def _in_band(case, sign: float) -> np.ndarray:
    """The case's rows with the first one (times ``sign``) shifted to start at zero: inside its band."""
    H = case.H.copy()
    u = sign * case.U[0]
    H[0] = u
    H[0, case.ref.const] -= float(u @ case.phase.xi(float(case.t0)))
    return H


def _check(kind: str, seeds) -> None:
    spied, calls = events._compiled_search, []
    events._compiled_search = lambda *a, **k: (calls.append(1), spied(*a, **k))[1]
    failures, searches, exact, marginal = [], 0, 0, 0
    try:
        for seed in seeds:
            case = make_case(seed, kind)
            for H in (case.H, _in_band(case, 1.0), _in_band(case, -1.0)):
                n = len(calls)
                a = _search(case.phase, H, case.t0, case.t1, reference=False)
                if len(calls) == n:
                    continue   # a fallback phase (divided differences, matrix exponential): the reference ran
                b = _search(case.phase, H, case.t0, case.t1, reference=True)
                searches += 1
                bad = _same_event(case, H, a, b)
                if bad and _marginal(case, H, a, b):
                    marginal += 1
                elif bad:
                    failures.append(f"{kind} seed {seed}: {bad}")
                elif a is None or a.t == b.t or abs(a.t - b.t) <= 1e-12 * max(1.0, abs(b.t)):
                    exact += 1
    finally:
        events._compiled_search = spied
    assert not failures, "\n".join(failures)
    # the compiled path ran on the modal cases (two thirds of the seeds), and near-tangent roots are the exception
    assert searches >= len(seeds)
    assert exact >= 0.75 * searches, (exact, searches)
    assert marginal <= 0.05 * searches, (marginal, searches)


@pytest.mark.parametrize("kind", KINDS)
def test_compiled_search_finds_the_references_event(kind):
    _check(kind, QUICK)


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_compiled_search_finds_the_references_event_many(kind):
    _check(kind, list(SEEDS) + list(SLOW_SEEDS))


def test_progress_is_reported_as_the_reference_does(monkeypatch):
    """report(t) gets the same times on both paths (chunk ends and coarse skips, computed alike), and
    ``phase.searched_until`` is the last of them; an interrupt raised by report stops the compiled loop
    and leaves searched_until where it was reported (an interrupted run keeps what was searched)."""
    got, lengths = {}, []
    spied, calls = events._compiled_search, []
    monkeypatch.setattr(events, "_compiled_search", lambda *a, **k: (calls.append(1), spied(*a, **k))[1])
    for kind, seed in [(kind, seed) for kind in ("generic", "stiff") for seed in range(3)]:
        case = make_case(seed, kind)   # (stiff: the coarse pass skips; generic: chunk after chunk)
        H = case.H.copy()
        H[:, case.ref.const] += 10.0 * np.abs(H).sum(axis=1)   # lifted far: no event, the whole horizon searched
        for reference in (False, True):
            seen, n = [], len(calls)
            assert _search(case.phase, H, case.t0, case.t1, reference, seen.append) is None
            assert len(calls) == n + (not reference)   # each path ran (not a fallback to the reference twice)
            assert case.phase.searched_until == seen[-1] == case.t1
            got[reference] = seen
        assert len(got[False]) == len(got[True]) > 1
        lengths.append(len(seen))
        assert np.allclose(got[False], got[True], rtol=1e-15, atol=0.0)   # the same linspace, bit for bit
        stop = got[False][len(got[False]) // 2]

        def interrupt(t):
            if t >= stop:
                raise KeyboardInterrupt
        with pytest.raises(KeyboardInterrupt):
            _search(case.phase, H, case.t0, case.t1, False, interrupt)
        assert case.phase.searched_until == stop
    assert max(lengths) >= 4   # searches of several chunks among them (interrupted after the second)


def test_screen_kernel_is_the_reference_bit_for_bit():
    """The compiled screen of one row (screen_row, also the all-rows screen) against events._screen_row on
    random samples: ties, zeros, crossings, dips, huge and tiny scales, infinite bounds, no interval at all.
    Both evaluate the same operations in the same order on doubles: they agree exactly."""
    kernel = core.compiled("search").screen
    rng = np.random.default_rng(33)
    assert kernel([], [0.5], [0.0], 1e-3, [], []) == ([], [], [])
    for trial in range(3000):
        n = int(rng.integers(1, 20))
        scale = 10.0 ** rng.uniform(-300, 300) if trial % 3 == 0 else 1.0
        dt = rng.uniform(0.1, 1.0, n) * (10.0 ** rng.uniform(-8, 2))
        f = rng.normal(size=n + 1) * scale
        hd = rng.normal(size=n + 1) * scale / dt.mean()
        f[rng.random(n + 1) < 0.2] = 0.0
        hd[rng.random(n + 1) < 0.2] = 0.0
        if n > 1:
            f[1] = f[0]          # ties
        tol = abs(rng.normal()) * scale * 10.0 ** rng.uniform(-12, 0)
        b4 = np.abs(rng.normal(size=n)) * tol * 10.0 ** rng.uniform(-4, 4)
        b4[rng.random(n) < 0.1] = math.inf
        sub = rng.random(n) < 0.7
        args = (dt.tolist(), f.tolist(), hd.tolist(), float(tol), b4.tolist(), sub.tolist())
        assert kernel(*args) == _screen_row(*args), args


def test_divided_difference_kernel_is_the_closed_forms():
    """The compiled F[nodes](tau) (resonant pairs, rigid rows' triples) against closed_form.divided_exp on
    random nodes: far apart, nearly equal (down to 1e-12 of their size), with a zero node, over 1e-3 to
    10 of their time scale (both branches of the triples). The same formulas with the same libm; NumPy's
    SIMD complex products round a fused multiply-add once where C rounds twice, about an ulp per product
    over some 60 products of the Taylor series, with no cancellation beyond a factor 2 (the recursion's
    farthest pair): 64 eps of |F| (measured: at most 3 eps)."""
    kernel = core.compiled("search").divided_exp
    rng = np.random.default_rng(34)
    for m in (2, 3):
        for trial in range(2000):
            size = 10.0 ** rng.uniform(-3, 4)
            nodes = (rng.normal(size=(m, 4)) + 1j * rng.normal(size=(m, 4))) * size
            if trial % 2:
                nodes[1] = nodes[0] + (rng.normal(size=4) + 1j * rng.normal(size=4)) * size * 10.0 ** rng.uniform(-12, 0)
            if trial % 5 == 0:
                nodes[0] = 0.0
            tau = 10.0 ** rng.uniform(-3, 1) / size
            got, want = kernel(nodes, tau), divided_exp(nodes, np.array([tau]))[:, 0]
            assert np.all(np.abs(got - want) <= 64 * np.finfo(float).eps * np.abs(want)), (nodes, tau)


@pytest.mark.skipif(not hasattr(__import__("signal"), "setitimer"), reason="no interval timers on this platform")
def test_a_signal_interrupts_the_coarse_pass():
    """Ctrl-C (and SIGTERM, which the command line turns into the same KeyboardInterrupt) stops the compiled
    search while its coarse pass certifies a long stretch, where the loop calls no Python code until the
    stretch ends (the reference's Python loop is interruptible anywhere): the signal handler runs from inside
    the pass, not from the report that follows it. The stiff case lifted far above its bands, over 1e6 of its
    horizons (the whole stretch coarse-certified: tens of seconds of C), interrupted after 0.2 s of CPU."""
    import signal

    case = make_case(0, "stiff")
    H = case.H.copy()
    H[:, case.ref.const] += 10.0 * np.abs(H).sum(axis=1)
    t1 = case.t0 + 1e6 * (case.t1 - case.t0)
    spied, calls = events._compiled_search, []
    events._compiled_search = lambda *a, **k: (calls.append(1), spied(*a, **k))[1]

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    import time

    old = signal.signal(signal.SIGPROF, interrupt)
    try:
        c0 = time.process_time()
        signal.setitimer(signal.ITIMER_PROF, 0.2)
        with pytest.raises(KeyboardInterrupt):
            _search(case.phase, H, case.t0, t1, False, lambda t: None)
        cpu = time.process_time() - c0
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0.0)
        signal.signal(signal.SIGPROF, old)
        events._compiled_search = spied
    assert calls, "the compiled search did not run"
    # the handler runs within a chunk of the signal (a coarse chunk is milliseconds of C), wherever it is
    # taken (inside the pass, or at a report between two plans of the search): not after the stretch's tens
    # of seconds. CPU time, not wall time: the bound is 10 times the signal's own 0.2 s of CPU
    assert cpu < 2.0, cpu
    assert getattr(case.phase, "searched_until", case.t0) < t1


def _captured(monkeypatch) -> tuple[list, object]:
    """(the arguments of the compiled Search calls of one generic random phase's search, that case)."""
    search = core.compiled("search")
    captured = []

    class Spy:
        @staticmethod
        def Search(*args):
            captured.append(args)
            return search.Search(*args)

    monkeypatch.setitem(core._active, "search", Spy)
    case = make_case(0, "generic")
    _search(case.phase, case.H, case.t0, case.t1, reference=False)
    return captured, case


def test_search_refuses_arrays_of_the_wrong_shape(monkeypatch):
    """The compiled search reads its arrays without bounds checks: a call whose shapes disagree (a row too few
    in Hd or in the rows' images, a column too few in the images, a band or tol or weight per row missing,
    A_aug not square, a harmonic part of 2 components, a term order naming a term that is not a mode, a divided
    difference of one node) is a ValueError, never a read past an array. The arguments are those of a real
    compiled search (captured), each spoilt in turn; the captured ones themselves are accepted."""
    search = core.compiled("search")
    captured, case = _captured(monkeypatch)
    assert captured
    args = list(captured[0])
    names = ("nu", "gnodes", "gm", "U", "H", "Hd", "A", "t0", "w", "HU", "order", "steady", "weights", "gb",
             "node_rate", "fastest", "t_start", "t_stop", "tol", "band")
    a = dict(zip(names, args))
    search.Search(*args)
    pad = lambda X: np.ascontiguousarray(np.hstack([X, np.zeros((X.shape[0], 1))]))  # noqa: E731
    one_node = {"gm": np.ones(1, dtype=np.intc), "gnodes": np.zeros((1, 3), dtype=complex), "U": pad(a["U"]),
                "HU": pad(a["HU"]), "gb": np.ones((2, 1))}
    bad_order = a["order"].copy()
    bad_order[0] = a["order"].size
    for spoilt in ({"Hd": np.ascontiguousarray(a["Hd"][:-1])}, {"band": np.empty(a["band"].size - 1)},
                   {"tol": np.empty(a["tol"].size + 1)}, {"weights": a["weights"][:-1]},
                   {"A": np.ascontiguousarray(a["A"][:, :-1])},
                   {"H": np.ascontiguousarray(np.hstack([a["H"], a["H"][:, -1:]]))},
                   {"HU": np.ascontiguousarray(a["HU"][:-1])}, {"HU": np.ascontiguousarray(a["HU"][:, :-1])},
                   {"order": bad_order}, one_node):
        bad = [spoilt.get(name, value) for name, value in zip(names, args)] + args[len(names):]
        with pytest.raises(ValueError):
            search.Search(*bad)
    with pytest.raises(ValueError):
        search.divided_exp(np.ones((1, 2), dtype=complex), 1.0)


def test_search_checks_the_terms_before_reading_them(monkeypatch):
    """Review of issue 33 (csetup): U's columns (the terms') and the divided differences' count were checked
    after the state's terms had been copied from U, so a U without columns was read through a NULL pointer
    (a segfault) and a U a column short was read past its end. Each is a ValueError before any read now; the
    captured arguments themselves are accepted."""
    search = core.compiled("search")
    captured, case = _captured(monkeypatch)
    args = list(captured[0])
    U, gb = args[3], args[13]
    assert U.shape[1] > 1
    search.Search(*args)
    for spoilt in ({3: np.zeros((U.shape[0], 0), dtype=complex)}, {3: np.ascontiguousarray(U[:, :1])},
                   {13: np.ones((2, gb.shape[1] + 1))}):   # (a bound for a divided difference that gm lacks)
        bad = [spoilt.get(j, value) for j, value in enumerate(args)]
        with pytest.raises(ValueError):
            search.Search(*bad)


@pytest.mark.skipif(not __import__("os").path.exists("/proc/self/status"), reason="reads VmData (Linux)")
def test_a_bad_carry_is_refused_and_frees_the_work_space(monkeypatch):
    """Review of issue 33 (csetup): Search.run read the carried arming and thresholds after allocating its work
    space and outside the block that frees it: a carry a row short (an IndexError) or with a value that is no
    number leaked the work space (about 40 kB per call here). A carry of the wrong length is a ValueError now,
    and every way out frees: 2000 refused calls grow the process's data segment by less than a tenth of what
    the leak took (the allocator may keep a few pages; the leak grew it by 2000 work spaces)."""
    search = core.compiled("search")
    captured, case = _captured(monkeypatch)
    run = search.Search(*captured[0])
    k = case.H.shape[0]
    with pytest.raises(ValueError, match="a value per row"):
        run.run(lambda t: None, [[True] * (k - 1), [0.0] * (k - 1)])

    def vm_data() -> int:
        with open("/proc/self/status") as f:
            return next(int(line.split()[1]) for line in f if line.startswith("VmData:")) * 1024

    work = (258 * (11 + 3 * k) + 2 * k) * 8 + 258 * (1 + 4 * k) + 4 * k   # run's three blocks, in bytes
    before = vm_data()
    for _ in range(2000):
        with pytest.raises(ValueError):
            run.run(lambda t: None, [[True] * k, ["not a number"] * k])
    assert vm_data() - before < 0.1 * 2000 * work, (vm_data() - before, work)
