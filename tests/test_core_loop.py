"""The exact method's per-event path in one compiled call each (issue 33, "fastloop"): the phase's set-up
(``PhaseSetup.start``: phase_start then phase_modal, one buffer) and its state (q, q') at one time
(``PhaseSetup.state``, :meth:`Phase.state_at`) against their Python references.

Tolerances. The state's modal part differs from the reference's (U e^{nu tau}).real only by the order of
each row's sum of 2 p rounded terms and the exponentials' last bits: 4 (2 p + 4) eps |U| |e^{nu tau}|
(as test_core_phase's test of xi_at). q = N x + q_p and q' = N x' are then one sum per entry in the
order of N's columns where the reference calls BLAS on q_map() (N, zeros and q_p): both obey the dot
product's forward error bound (r + 2) eps |N| |x| (+ |q_p|), so they differ by twice that plus |N| times
the modal part's bound: componentwise, on absolute values, a bound and not an estimate. The set-up's
bounds are test_core_phase's (``_check_phase``).

Skipped where the compiled core is not installed (no C compiler at install time) or NSFEM_PURE_PYTHON=1.
"""

from __future__ import annotations

import contextlib
import copy

import numpy as np
import pytest

from nsfem.integrate import core
from nsfem.integrate.configuration import Configuration, Mode, Phase

from test_core_phase import _both, _check_phase, rotor  # noqa: F401 - rotor: the fixture
from test_event_search import KINDS, _phase

kernel = core.compiled("phase")
pytestmark = pytest.mark.skipif(kernel is None, reason="the compiled core part 'phase' is not active (not built, "
                                                       "or NSFEM_PURE_PYTHON=1): the reference runs")
EPS = np.finfo(float).eps


def _state_bound(phase: Phase, tau: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The bounds of (q, q')'s differences (module docstring) for the modal part x at tau."""
    mot, cfg = phase._modal, phase.config
    r = cfg.r
    bx = 4 * (2 * mot.nu.size + 4) * EPS * (np.abs(mot.U) @ np.abs(np.exp(mot.nu * tau)))
    N = np.abs(cfg.N)
    bq = N @ bx[:r] + 2 * (r + 2) * EPS * (N @ np.abs(x[:r]) + np.abs(phase.qp))
    bv = N @ bx[r:] + 2 * (r + 2) * EPS * (N @ np.abs(x[r:]))
    return bq, bv


@pytest.mark.parametrize("scale", [1e-100, 1.0, 1e100])
@pytest.mark.parametrize("kind", KINDS)
def test_state_at_matches_the_reference(kind, scale):
    """Random phases of test_event_search's generator (modal, harmonic, gyroscopic, resonant, rigid, defective),
    their states scaled (the map is linear in the state: scales must not matter), at random times over 40
    periods of the fastest term and at the phase's start: compiled where the phase has a modal form without
    divided differences, else the reference itself (bit for bit)."""
    compiled = 0
    for seed in range(20):
        rng = np.random.default_rng([35, KINDS.index(kind), seed])
        path = "expm" if rng.random() < 1 / 3 else "modal"
        with core.reference():
            base, *_ = _phase(rng, kind, path)
        cfg = base.config
        q0 = scale * (cfg.N @ base.x0[: cfg.r] + base.qp)
        v0 = scale * (cfg.N @ base.x0[cfg.r:])
        phase = Phase(cfg, base.t0, q0, v0, base.g0)
        fast = float(np.max(np.abs(phase._modal.nu), initial=1.0)) if phase._modal is not None else 1.0
        for t in [phase.t0, *(phase.t0 + rng.uniform(0.0, 40 * 2 * np.pi / fast, 4))]:
            t = float(t)
            q, v = phase.state_at(t)
            if phase._modal is None or phase._modal.groups:
                xi = phase.xi(t)
                assert np.array_equal(q, phase.q_map() @ xi) and np.array_equal(v, phase.v_map() @ xi)
                continue
            compiled += 1
            mot = phase._modal
            x = (mot.U @ np.exp(mot.nu * (t - phase.t0))).real
            xi = np.concatenate([x, phase.xi(t)[x.size:]])
            bq, bv = _state_bound(phase, t - phase.t0, x)
            assert np.all(np.abs(q - phase.q_map() @ xi) <= bq)
            assert np.all(np.abs(v - phase.v_map() @ xi) <= bv)
    assert compiled > 0


def test_state_at_with_closed_contacts(rotor):  # noqa: F811
    """The rotor with a stop (gyroscopic, an unbalance) with random contact sets closed (q_p from the gaps),
    states from 1e-9 to 1e3 and zeros: the compiled state against the reference products."""
    rng = np.random.default_rng(36)
    n, m = rotor.n, rotor.contacts.m
    for _ in range(20):
        closed = tuple(sorted(rng.choice(m, size=int(rng.integers(0, 4)), replace=False).tolist()))
        cfg = Configuration(rotor, Mode(closed=closed))
        scale = 10.0 ** rng.uniform(-9, 3)
        q0 = scale * rng.standard_normal(n) * (rng.random(n) < 0.8)
        v0 = scale * rng.standard_normal(n) * (rng.random() < 0.8)
        g0 = scale * rng.standard_normal(len(closed)) * (rng.random(len(closed)) < 0.7)
        phase = Phase(cfg, float(rng.uniform(0, 10)), q0, v0, g0)
        assert phase._modal is not None and not phase._modal.groups
        fast = float(np.max(np.abs(phase._modal.nu)))
        for t in phase.t0 + np.concatenate([[0.0], rng.uniform(0.0, 40 * 2 * np.pi / fast, 3)]):
            t = float(t)
            q, v = phase.state_at(t)
            x = (phase._modal.U @ np.exp(phase._modal.nu * (t - phase.t0))).real
            xi = np.concatenate([x, phase.xi(t)[x.size:]])
            bq, bv = _state_bound(phase, t - phase.t0, x)
            assert np.all(np.abs(q - phase.q_map() @ xi) <= bq)
            assert np.all(np.abs(v - phase.v_map() @ xi) <= bv)


def test_phase_setup_follows_a_changed_load(rotor):  # noqa: F811
    """A configuration copied with another constant load (Configuration.with_load: the same matrices, its own
    f0 and kernel_arrays) gets its own compiled set-up, not the one its original cached: its phases match the
    reference of the new load (the old set-up would give the old load's q_p-free forcing)."""
    rng = np.random.default_rng(37)
    n = rotor.n
    cfg = Configuration(rotor, Mode(closed=(0,)))
    q0, v0, g0 = 1e-4 * rng.standard_normal(n), 1e-3 * rng.standard_normal(n), np.array([1e-5])
    Phase(cfg, 0.0, q0, v0, g0)                     # the original's set-up cached
    other = copy.copy(cfg)
    other.f0 = cfg.f0 + 10.0 * rng.standard_normal(n)
    other.kernel_arrays = {**cfg.kernel_arrays, "f0": np.ascontiguousarray(other.f0)}
    ref, got = _both(other, 0.0, q0, v0, g0)
    _check_phase(ref, got, q0, v0)
    assert not np.allclose(got.forcing[0], Phase(cfg, 0.0, q0, v0, g0).forcing[0])


def test_phase_setup_gives_each_phase_its_own_arrays(rotor):  # noqa: F811
    """Two phases of one configuration: their set-up's arrays (views into one buffer per phase) share no
    memory with each other, and their coefficients U none with the configuration."""
    cfg = Configuration(rotor, Mode(closed=(1,)))
    rng = np.random.default_rng(38)
    a, b = (Phase(cfg, 0.0, rng.standard_normal(rotor.n), rng.standard_normal(rotor.n), np.array([0.0]))
            for _ in range(2))
    for x, y in [(a.qp, b.qp), (a.x0, b.x0), (a.forcing[0], b.forcing[0]), (a._modal.U, b._modal.U),
                 (a.amplitudes[0], b.amplitudes[0]), (a.amplitudes[1], b.amplitudes[1])]:
        assert not np.shares_memory(x, y)
    for x, y in [(a.qp, a.x0), (a.x0, a.forcing[0]), (a._modal.U, a.amplitudes[1]), (a.amplitudes[0], a._modal.U)]:
        assert not np.shares_memory(x, y)
    assert not np.shares_memory(a._modal.U, cfg.plan.V)


def test_state_at_keeps_the_core_its_phase_was_built_on(rotor):  # noqa: F811
    """A phase built on the compiled core evaluates its state with its own set-up's kernel inside a
    ``core.reference()`` block too (the same values, bit for bit: the same call), and a phase built inside the
    block evaluates it as the reference (q_map() @ xi, bit for bit)."""
    rng = np.random.default_rng(39)
    cfg = Configuration(rotor, Mode(closed=(2,)))
    q0, v0 = 1e-4 * rng.standard_normal(rotor.n), 1e-2 * rng.standard_normal(rotor.n)
    phase = Phase(cfg, 0.3, q0, v0, np.array([2e-5]))
    t = 0.3 + 1e-3
    q, v = phase.state_at(t)
    with core.reference():
        q2, v2 = phase.state_at(t)
        ref = Phase(cfg, 0.3, q0, v0, np.array([2e-5]))
        xi = ref.xi(t)
        q3, v3 = ref.state_at(t)
    assert np.array_equal(q, q2) and np.array_equal(v, v2)
    assert np.array_equal(q3, ref.q_map() @ xi) and np.array_equal(v3, ref.v_map() @ xi)


def test_a_phase_of_other_shapes_is_the_references():
    """Phase's compiled set-up reads g0, q0 and q0' without bounds checks: a g0 longer than the configuration's
    constraint rows (it read q_p from past them: -4.7e-310 seen, review-c), or a state one entry short or long, take
    the reference: its result bit for bit (numpy broadcasts a one-entry state) or its ValueError. An empty g0
    (q_p = 0) stays compiled."""
    for kind in KINDS[:3]:
        rng = np.random.default_rng([36, KINDS.index(kind)])
        with core.reference():
            base, *_ = _phase(rng, kind, "modal")
        cfg = base.config
        q0, v0 = cfg.N @ base.x0[: cfg.r] + base.qp, cfg.N @ base.x0[cfg.r:]
        for args in ((q0, v0, np.r_[base.g0, 1.0, 2.0]), (q0[:-1], v0, base.g0), (q0, v0[:-1], base.g0),
                     (np.r_[q0, 1.0], v0, base.g0), (q0, np.r_[v0, 1.0], base.g0)):
            outcome = []
            for reference in (True, False):
                try:
                    with core.reference() if reference else contextlib.nullcontext():
                        p = Phase(cfg, 0.0, *args)
                    outcome.append((p.qp, p.x0))
                except ValueError:
                    outcome.append(None)
            assert (outcome[0] is None and outcome[1] is None) or (
                outcome[1] is not None and all(np.array_equal(a, b) for a, b in zip(*outcome)))
        with core.reference():
            ref = Phase(cfg, 0.0, q0, v0, np.zeros(0))
        # (q_p = 0 either way; x0 = N^T q0: one sum per entry, within the dot product's bound twice)
        got = Phase(cfg, 0.0, q0, v0, np.zeros(0))
        assert not got.qp.any() and not ref.qp.any()
        bound = 2 * (cfg.system.n + 2) * EPS * (np.abs(cfg.N).T @ np.abs(np.r_[q0, v0].reshape(2, -1)).T)
        assert np.all(np.abs(got.x0 - ref.x0) <= bound.T.ravel())


def test_phase_setup_refuses_outputs_and_states_of_other_shapes(rotor):  # noqa: F811
    """PhaseSetup.start and .state write into their outputs without bounds checks and were ``noexcept`` (an
    error inside was printed and ignored, the call went on): an output shorter than the layout, a q or q' a
    coordinate short, or a U without the phase's state rows, is a ValueError now, before any write; the real
    calls are accepted."""
    from nsfem.integrate.configuration import phase_setup

    rng = np.random.default_rng(40)
    cfg = Configuration(rotor, Mode(closed=(0,)))
    setup, lay, _ = phase_setup(kernel, cfg)
    q0, v0, g0 = 1e-4 * rng.standard_normal(rotor.n), 1e-3 * rng.standard_normal(rotor.n), np.array([1e-5])
    setup.start(g0, q0, v0, 0.0, 0.0, np.empty(lay[9]))
    with pytest.raises(ValueError, match="PhaseSetup.start"):
        setup.start(g0, q0, v0, 0.0, 0.0, np.empty(lay[9] - 1))
    phase = Phase(cfg, 0.0, q0, v0, g0)
    mot, n = phase._modal, rotor.n
    U, nu = np.ascontiguousarray(mot.U).view(float), np.ascontiguousarray(mot.nu).view(float)
    q, v = np.empty(n), np.empty(n)
    setup.state(U, nu, 1e-4, phase.qp, q, v)
    for bad in [(U, nu, 1e-4, phase.qp, q[:-1], v), (U, nu, 1e-4, phase.qp, q, v[:-1]),
                (U, nu, 1e-4, phase.qp[:-1], q, v), (np.ascontiguousarray(U[:1]), nu, 1e-4, phase.qp, q, v)]:
        with pytest.raises(ValueError, match="PhaseSetup.state"):
            setup.state(*bad)
