"""The continuation's J_p and its thread safety (issue 36): nsfem.periodic.branch._Problem.parameter_derivative,
scene_branch._Family's cache and nsfem.integrate.blas on several threads.

J_p = d phi_T(u; p) / dp by a forward difference from the flow at p (h = DP of the range, at least DP_FLOOR |p|). At
an orbit u(p) of the branch r(u(p), p) = 0, so J_u u'(p) + J_p = 0: J_p = -(Phi_T - I) u'(p), with u'(p) from the
closed-form orbit (the impact oscillator) or from orbits shot at p +- d (the crack).
"""

from __future__ import annotations

import math
import threading
import time
import warnings

import numpy as np
import pytest

from impact_oscillator import period1_branch
from nsfem.periodic.branch import DP, _Problem
from test_periodic_impact import OSC, impact_system


def _system(w):
    return impact_system(OSC, w)


def _period(w):
    return 2 * math.pi / w


@pytest.mark.parametrize("w", [2.4, 2.6])
def test_jp_on_the_impact_oscillator_is_minus_j_u_times_the_closed_form_orbits_derivative(w):
    """J_p = -(Phi_T - I) u'(w) at the closed-form period-1 orbit (u' by central differences of the closed form at
    h = 1e-5: truncation h^2 |u'''| ~ 1e-10, round-off 1e-16 / h ~ 1e-11). The forward difference's error: its
    truncation h / 2 |phi_ww| (phi_ww bounded by a second difference of the flow at H = 1e-3, whose own noise
    delta / H^2 ~ 1e-7 is negligible) plus the flow's noise 2 delta / h, delta ~ 1e-13 s event times times the
    velocity jump (1 + e) u <= 2: ~2e-13, over h = DP span = 2e-7 -> 2e-6; bound = twice the truncation + 1e-5
    of |J_p| (the noise with a margin of 5)."""
    span = 0.2
    problem = _Problem(_system, _period, 0.0, DP * span, 1)
    ref = period1_branch(OSC, w, -1)
    u = np.array([ref.x0, ref.v0])
    problem.weights = np.ones(2)
    _, ju, jp = problem.residual(u, w)
    h = 1e-5
    up, um = period1_branch(OSC, w + h, -1), period1_branch(OSC, w - h, -1)
    dudw = (np.array([up.x0, up.v0]) - np.array([um.x0, um.v0])) / (2 * h)
    expected = -ju @ dudw
    H = 1e-3
    ends = [problem.flow_map(w + s)(u[:1], u[1:], jacobian=False) for s in (H, 0.0, -H)]
    x = [np.concatenate([f.q, f.v]) for f in ends]
    phi_ww = np.abs(x[0] - 2 * x[1] + x[2]).max() / H ** 2
    bound = 2 * (DP * span / 2) * phi_ww + 1e-5 * np.abs(expected).max()
    assert np.abs(jp - expected).max() <= bound
    assert bound <= 1e-3 * np.abs(expected).max()   # (the check is tighter than the quantity checked)


@pytest.fixture(scope="module")
def crack_problem():
    from nsfem import load_scene
    from nsfem.periodic.scene import orbit_of_scene
    from nsfem.periodic.scene_branch import _Family

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = load_scene("crack")
        so = orbit_of_scene(scene, 1, None, None, 1e-9, section="start")   # (t0 = 0: the shootings at p +- d keep it)
    family = _Family(scene, "rotation.speed_hz", so.system, lambda extra: scene)
    return family, so


@pytest.mark.parametrize("span", [0.2, 2e-5])
def test_jp_on_the_crack_satisfies_the_branchs_tangent_relation(crack_problem, span):
    """On the breathing crack (12.4 Hz) J_u u'(p) + J_p = 0 with u'(p) from orbits shot at p +- d (d = 1e-5 Hz,
    tol 1e-12; the orbit curves fast near its grazing: at 1e-4 Hz the truncation is 0.7 % of u', at 1e-5 Hz
    7e-5): u''s error is its truncation, bounded by Richardson (|D(d) - D(2 d)| / 3 from a pair at 2 d), plus the
    shooting's 1e-12 |u| / d; J_p's error (forward difference at h = 2e-7 Hz): truncation h / 2 |phi_pp| plus the
    flow's noise 2 delta / h. The noise is read from the flow itself (the second difference at h, whose truncation
    h^2 |phi_pp| is below it, is noise: 4 delta at most), |phi_pp| from the second difference at d. Each bound is
    applied through |J_u| for u'. On a wide range (0.2 Hz) h = DP of it, 2e-7 Hz; on a narrow one (2e-5 Hz) DP of it
    would be 2e-11 Hz (1.6e-12 of p), where the flow's noise over h is O(1) of J_p (2.3x measured): h is held at
    DP_FLOOR |p| (1.2e-7 Hz) there, and J_p must resolve as on the wide range."""
    from nsfem.periodic.shooting import periodic_orbit

    family, so = crack_problem
    o = so.orbit
    p = 12.4
    u = np.concatenate([o.q0, o.v0])
    n = u.size // 2
    problem = _Problem(family.system_at, family.period_at, o.t0, DP * span, 1)
    problem.weights = np.ones(u.size)
    _, ju, jp = problem.residual(u, p)

    def orbit(pp):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = periodic_orbit(family.system_at(pp), family.period_at(pp), o.q0, o.v0, o.t0, tol=1e-12)
        assert r.converged and r.t0 == o.t0
        return np.concatenate([r.q0, r.v0])

    d = 1e-5
    x = {k: orbit(p + k * d) for k in (-2, -1, 1, 2)}
    D1 = (x[1] - x[-1]) / (2 * d)
    D2 = (x[2] - x[-2]) / (4 * d)
    du_err = np.abs(D1 - D2) / 3 + 1e-12 * np.abs(u).max() / d
    expected = -ju @ D1

    def end(pp):
        f = problem.flow_map(pp)(u[:n], u[n:], jacobian=False)
        return np.concatenate([f.q, f.v])

    h = problem.jp_step(p)
    e0 = end(p)
    noise = np.abs(end(p + h) - 2 * e0 + end(p - h)) / 4
    phi_pp = np.abs(end(p + d) - 2 * e0 + end(p - d)) / d ** 2
    jp_err = h / 2 * phi_pp + 2 * noise / h
    bound = np.abs(ju) @ du_err + jp_err
    assert np.all(np.abs(jp - expected) <= 2 * bound)
    # (J_p's own size: the check must resolve it)
    assert np.abs(expected).max() >= 20 * (2 * bound).max()


def test_the_speed_familys_systems_are_built_once_per_speed(crack_problem):
    """A branch point's report asks for its corrector's last system again: the family keeps it (the same object),
    and each kept system is the one at its own speed (forcing 2 pi p)."""
    family, _ = crack_problem
    a, b = family.system_at(12.41), family.system_at(12.42)
    assert family.system_at(12.41) is a and a is not b
    assert a.omega == pytest.approx(2 * math.pi * 12.41, rel=1e-15)
    assert b.omega == pytest.approx(2 * math.pi * 12.42, rel=1e-15)


# --- two threads on one family (a multi-threaded Dask worker following both sides of a branch) ---

class _Fake:
    def __init__(self, p):
        self.p, self.n = p, 3


def test_two_threads_on_one_family_load_each_value_once_and_get_its_own_system(monkeypatch):
    """Two threads ask a family for the systems of overlapping values at once (each load takes 20 ms, so the
    second asks while the first loads): every value is loaded once, each thread gets the system of the value it
    asked for, the cache never exceeds its size, no error."""
    from nsfem.integrate import ContactSystem
    from nsfem.periodic import scene as scene_mod
    from nsfem.periodic import scene_branch

    loads: dict[float, int] = {}
    guard = threading.Lock()

    class Scene:
        def __init__(self, p):
            self.p = p

    def load(extra):
        p = float(extra[0].split("=", 1)[1])
        with guard:
            loads[p] = loads.get(p, 0) + 1
        time.sleep(0.02)
        return Scene(p)

    monkeypatch.setattr(ContactSystem, "from_scene", classmethod(lambda cls, scene, *a, **k: _Fake(scene.p)))
    monkeypatch.setattr(scene_mod, "check_scene", lambda scene: None)
    family = scene_branch._Family(Scene(0.0), "stator.0.friction", _Fake(0.0), load)
    values = [0.1 * k for k in range(1, 9)]
    errors, seen = [], []

    def work(order):
        try:
            for p in order:
                s = family.system_at(p)
                seen.append((p, s.p))
                assert len(family._cache) <= scene_branch.CACHED_SYSTEMS
        except Exception as exc:   # noqa: BLE001  (reported by the main thread)
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(values,)), threading.Thread(target=work, args=(values,))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert len(seen) == 2 * len(values) and all(p == q for p, q in seen)
    assert loads == {p: 1 for p in values}
    assert not family._loading


def test_a_family_pickles_without_its_lock():
    """A family sent to a cluster's workers (pickled) arrives with a lock of its own and its cache."""
    import pickle

    from nsfem.periodic import scene_branch

    family = scene_branch._Family(None, "stator.0.friction", _Fake(0.0), None)
    family._cache[0.5] = ("scene", "system")
    copy = pickle.loads(pickle.dumps(family))
    assert copy._cache == family._cache and copy._lock is not family._lock and copy._loading == {}
    with copy._lock:
        pass


def test_blas_blocks_on_two_threads_keep_one_thread_until_the_last_ends(monkeypatch):
    """single_threaded_blas from two threads whose blocks overlap (A enters, B enters, A leaves, B leaves): one
    BLAS thread while either is inside, the count before them restored after the last (each thread restoring its
    own entry's count raised it under B and then left the process at one thread). The BLAS count is the
    process's: here a stand-in for threadpoolctl's limiter on one process-wide count of 4 (the library's own count
    is the machine's and the environment's, 1 under OPENBLAS_NUM_THREADS=1, where a real one shows nothing)."""
    from nsfem.integrate import blas

    state = {"threads": 4}

    class Limiter:
        def __init__(self, limits, user_api):
            self.saved, state["threads"] = state["threads"], limits

        def restore_original_limits(self):
            state["threads"] = self.saved

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.restore_original_limits()

    monkeypatch.setattr(blas, "threadpool_limits", Limiter)
    a_in, b_in, a_out = threading.Event(), threading.Event(), threading.Event()
    seen = {}

    def a():
        with blas.single_threaded_blas():
            a_in.set()
            b_in.wait(5)
        a_out.set()

    def b():
        a_in.wait(5)
        with blas.single_threaded_blas():
            b_in.set()
            a_out.wait(5)
            seen["after A left"] = state["threads"]

    ta, tb = threading.Thread(target=a), threading.Thread(target=b)
    ta.start(), tb.start()
    ta.join(), tb.join()
    assert seen["after A left"] == 1
    assert state["threads"] == 4


def test_a_failed_load_leaves_no_waiting_entry_and_the_waiting_thread_loads_it(monkeypatch):
    """Thread A's load of a value fails (after 50 ms) while thread B waits for that value: A gets its error, B is
    woken and loads the value itself (a second load, which succeeds), nothing is left in the family's loads under
    way and its lock is free. Joined with a timeout: a waiting entry left behind would hang B, reported as such."""
    from nsfem.errors import NsfemError
    from nsfem.integrate import ContactSystem
    from nsfem.periodic import scene as scene_mod
    from nsfem.periodic import scene_branch

    calls, a_loading = [], threading.Event()

    class Scene:
        def __init__(self, p):
            self.p = p

    def load(extra):
        calls.append(extra)
        if len(calls) == 1:
            a_loading.set()
            time.sleep(0.05)
            raise NsfemError("--continue stator.0.friction: a load that fails")
        return Scene(float(extra[0].split("=", 1)[1]))

    monkeypatch.setattr(ContactSystem, "from_scene", classmethod(lambda cls, scene, *a, **k: _Fake(scene.p)))
    monkeypatch.setattr(scene_mod, "check_scene", lambda scene: None)
    family = scene_branch._Family(Scene(0.0), "stator.0.friction", _Fake(0.0), load)
    got = {}

    def a():
        try:
            family.system_at(0.3)
        except NsfemError as exc:
            got["a"] = exc

    def b():
        a_loading.wait(5)
        got["b"] = family.system_at(0.3)

    ta, tb = threading.Thread(target=a, daemon=True), threading.Thread(target=b, daemon=True)
    ta.start(), tb.start()
    ta.join(10), tb.join(10)
    assert not ta.is_alive() and not tb.is_alive(), "a thread still waits for a load that failed"
    assert isinstance(got["a"], NsfemError) and got["b"].p == 0.3
    assert len(calls) == 2 and not family._loading
    assert family._lock.acquire(blocking=False)
    family._lock.release()


def test_a_blas_block_left_by_an_exception_restores_the_count(monkeypatch):
    """An exception inside a single_threaded_blas block (nested or not) leaves the process's BLAS count as it was
    and the next block sets one thread again (the counting is not left at a block that never ended)."""
    from nsfem.integrate import blas

    state = {"threads": 4, "limiters": 0}

    class Limiter:
        def __init__(self, limits, user_api):
            self.saved, state["threads"] = state["threads"], limits
            state["limiters"] += 1

        def restore_original_limits(self):
            state["threads"] = self.saved

    monkeypatch.setattr(blas, "threadpool_limits", Limiter)
    with pytest.raises(ZeroDivisionError):
        with blas.single_threaded_blas():
            with blas.single_threaded_blas():
                assert state["threads"] == 1
                1 / 0
    assert state["threads"] == 4 and blas._active == 0 and getattr(blas._depth, "n", 0) == 0
    with blas.single_threaded_blas():
        assert state["threads"] == 1 and state["limiters"] == 2
    assert state["threads"] == 4
