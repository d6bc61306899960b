"""The crack's orbit faster (issue 36, goal 1): the shooting's section, the run from a section, the cached transition.

- :func:`nsfem.periodic.flow.quiet_phase` against hand-made event times (the middle of the longest event-free
  stretch, wrapping round the period);
- ``Exact.run(t_start=...)`` against a run from 0 of the system with its forcing's phase moved
  (:func:`nsfem.periodic.flow.shifted`): the same motion on another clock;
- the phase transition from the configuration's eigen-decomposition (formed once per configuration) against
  scipy's expm of the phase's matrix (Van Loan), the tolerance from the decomposition's conditioning;
- the crack's orbit shot at the quiet section of a 3-period lead: the same orbit as at t = 0 (a flow carries one
  to the other), its monodromy exact there (the closed contacts' round-off approach is no impact at the start).
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
import scipy.linalg as sla
from hypothesis import given, settings
from hypothesis import strategies as st

from nsfem import load_scene
from nsfem.errors import NsfemError
from nsfem.fem.assemble import build_model
from nsfem.integrate import ContactSystem
from nsfem.integrate.base import single_threaded_blas
from nsfem.integrate.event_driven import Exact
from nsfem.integrate.configuration import Configuration, Mode
from nsfem.periodic import periodic_orbit
from nsfem.periodic.flow import START_SETTLING, FlowMap, quiet_phase, shifted
from nsfem.periodic.variational import constraint_projector, modal_transition, phase_transition
from nsfem.reduce import scene_reduction
from nsfem.simulate import initial_state

EPS = np.finfo(float).eps


@functools.lru_cache(maxsize=1)
def _crack():
    scene = load_scene("crack")
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    system = ContactSystem.from_model(model, red, scene.rotation, scene.damping)
    system.info.update(model=model, reduction=red)
    q0, v0 = initial_state(scene, model, red, system)
    return system, 1.0 / scene.rotation.speed_hz, q0, v0


def test_quiet_phase_is_the_middle_of_the_longest_event_free_stretch():
    # events at 0.1, 0.2, 0.7 of a period 1: stretches 0.1, 0.5 (0.2 -> 0.7), 0.4 (0.7 -> 1.1): middle 0.45
    assert quiet_phase([0.1, 0.2, 0.7], 1.0) == pytest.approx(0.45, abs=1e-15)
    # the longest stretch wraps round the period (0.8 -> 1.3): its middle 1.05 is the phase 0.05
    assert quiet_phase([0.3, 0.5, 0.8], 1.0) == pytest.approx(0.05, abs=1e-15)
    # times of later periods count by their phase; one event: the phase half a period from it
    assert quiet_phase([2.1, 3.2, 5.7], 1.0) == pytest.approx(0.45, abs=1e-12)
    assert quiet_phase([0.25], 2.0) == pytest.approx(1.25, abs=1e-15)
    assert quiet_phase([], 0.3) == 0.0


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(0.0, 0.999), min_size=1, max_size=12), st.floats(0.01, 10.0))
def test_quiet_phase_lies_farthest_from_the_events(fractions, period):
    """Property: no phase lies farther from the nearest event (round the period) than the quiet phase (checked
    against a brute-force maximum over a fine grid of phases)."""
    times = [f * period for f in fractions]
    s = quiet_phase(times, period)
    assert 0.0 <= s < period

    def clearance(t):
        return min(min(abs(t - e) % period, period - abs(t - e) % period) for e in times)

    grid = np.linspace(0.0, period, 2001)
    # the grid's best lies within half a grid step of the true maximum; the quiet phase is that maximum (to
    # round-off of the phases, ~1e-15 period)
    assert clearance(s) >= max(clearance(t) for t in grid) - 0.5 * period / 2000 - 1e-12 * period


@pytest.mark.parametrize("times, period, match", [
    ([0.1, float("nan")], 1.0, "not finite"),
    (["a"], 1.0, "must be numbers"),
    ([0.1], 0.0, "period"),
    ([0.1], float("inf"), "period"),
])
def test_quiet_phase_refuses_bad_input(times, period, match):
    with pytest.raises(NsfemError, match=match) as info:
        quiet_phase(times, period)
    assert "\n" not in str(info.value)


def test_a_run_from_a_start_time_is_the_run_of_the_shifted_system():
    """Exact.run(t_start=s) of the crack from a state is the run from 0 of the system whose forcing starts at phase s
    (:func:`shifted`): the same motion, its events and outputs s later. The two clocks round differently, and a
    closure is located anywhere within its gap row's zero band (events.ZERO, 1e-11 relative): the event times agree
    to ~1e-11 of the period (2.5e-11 seen over the transient's 18 events), the positions to ~1e-11 of their size
    (6e-12 seen) and the velocities to that times the fast contact modes' rate (1.6e-9 seen). Bounds 1e-9 T, 1e-9
    and 2e-8 leave margins of 12-150; a wrong forcing phase changes the motion at O(1)."""
    system, T, q0, v0 = _crack()
    s = 0.3 * T
    with single_threaded_blas(), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        a = Exact(system, progress=False, energy_balance=False).run(s + 2 * T, T / 16, q0, v0, t_start=s)
        b = Exact(shifted(system, s), progress=False, energy_balance=False).run(2 * T, T / 16, q0, v0)
    assert a.completed and b.completed and len(a.events) == len(b.events) >= 4
    assert a.t[0] == s and a.t[-1] == s + 2 * T
    assert np.abs(a.t - s - b.t).max() <= 4 * EPS * T
    assert np.abs(a.q - b.q).max() <= 1e-9 * np.abs(b.q).max()
    assert np.abs(a.v - b.v).max() <= 2e-8 * np.abs(b.v).max()
    assert max(abs(ea["t"] - s - eb["t"]) for ea, eb in zip(a.events, b.events)) <= 1e-9 * T
    # the share of time with a contact closed is of the run's own span, whatever its start
    assert a.info["closed_fraction"] == pytest.approx(b.info["closed_fraction"], abs=1e-9)


@pytest.mark.parametrize("t_start", [float("nan"), float("inf"), 2.0, "0.1", True, np.float64(2.5), None])
def test_a_run_refuses_a_bad_start_time(t_start):
    system = ContactSystem.from_arrays(M=[[1.0]], Q=[[1.0]])
    with pytest.raises(NsfemError, match="t_start") as info:
        Exact(system, progress=False).run(2.0, 0.5, [1.0], None, t_start=t_start)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("t_start", [np.int64(-1), np.float32(-0.5), -1])
def test_a_run_takes_a_numpy_start_time_as_its_value(t_start):
    """A start time given as a numpy scalar (an event time read from a result) is that time: the run's grid starts
    there, the same run as from the Python float (bit for bit: one clock)."""
    system = ContactSystem.from_arrays(M=[[1.0]], Q=[[1.0]], fc=[1.0], omega=2.0)
    a = Exact(system, progress=False).run(1.0, 0.25, [1.0], None, t_start=t_start)
    b = Exact(system, progress=False).run(1.0, 0.25, [1.0], None, t_start=float(t_start))
    assert a.t[0] == float(t_start) and np.array_equal(a.t, b.t) and np.array_equal(a.q, b.q)


def _van_loan(config, s):
    """The phase's transition from scipy's expm of [[A, I], [0, 0]] s (module docstring of .variational)."""
    n, r = config.system.n, config.r
    big = np.zeros((4 * r, 4 * r))
    big[: 2 * r, : 2 * r] = config.A * s
    big[: 2 * r, 2 * r:] = np.eye(2 * r) * s
    E = sla.expm(big)
    eA, iA = E[: 2 * r, : 2 * r], E[: 2 * r, 2 * r:]
    PH, N = constraint_projector(config), config.N
    Phi = np.zeros((2 * n, 2 * n))
    Phi[:n, :n] = PH
    dx = np.hstack([eA[:, :r] @ N.T, eA[:, r:] @ N.T])
    if config.G.shape[1]:
        dx[:, :n] -= iA @ (config.B @ (config.Q @ PH))
    Phi[:n] += N @ dx[:r]
    Phi[n:] = N @ dx[r:]
    return Phi


@pytest.mark.parametrize("closed", [(), (0,), (0, 1)])
def test_cached_transition_is_the_matrix_exponential(closed):
    """The transition formed from the configuration's eigen-decomposition A = V diag(lam) V^-1 (its products with V,
    V^-1, N and B Q P_H formed once) against expm of the phase's Van Loan matrix, for the crack open, half and fully
    closed, over a short phase, a tenth and a whole period. The modal form's error is round-off amplified by the
    decomposition's conditioning, ~cond(V) eps of the largest term |V| |e^{lam s}| |V^-1| (the largest entries are
    O(1) here: the states' damping keeps |e^{lam s}| <= 1); expm's (scaling and squaring) ~|A s| eps. The bound
    50 (cond(V) + |A s|) eps |Phi| holds both with a margin; a wrong product (a missing N, P_H or the forcing
    column) is an O(1) error."""
    system, T, _, _ = _crack()
    config = Configuration(system, Mode(closed=closed))
    assert modal_transition(config) is not None, "the crack's configurations have a usable decomposition"
    lam, V, Vi = config.eig
    cond = np.linalg.cond(V)
    for s in (1e-4 * T, 0.1 * T, T):
        ref = _van_loan(config, s)
        tol = 50 * (cond + np.abs(config.A).max() * s) * EPS * max(1.0, np.abs(ref).max())
        assert np.abs(phase_transition(config, s) - ref).max() <= tol, (closed, s, cond)
    assert modal_transition(config) is modal_transition(config)   # (formed once)


def test_crack_orbit_at_the_quiet_section_is_the_orbit_at_t0():
    """The crack's orbit shot from a 3-period lead at the quiet phase of its last period and at t = 0 (the
    command's section): one orbit, the first carried by a flow to t = 0 lands on the second within the shootings'
    tolerances (1e-10 each, times cond ~ 1e2 of Phi - I on the admissible directions at the quiet section: 1e-7
    leaves a margin); the multipliers are section independent (conjugate monodromies), equal to the same 1e-7;
    at the quiet section both contacts are closed and the monodromy is exact (no approximation: their round-off
    approach is below START_SETTLING of the velocity)."""
    system, T, q0, v0 = _crack()
    kept = {}
    with single_threaded_blas(), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        res = Exact(system, progress=False, energy_balance=False, configurations=kept).run(3 * T, T, q0, v0)
    q, v = res.q[:, -1].copy(), res.v[:, -1].copy()
    s = quiet_phase([e["t"] for e in res.events + res.impacts if e["t"] >= 2 * T], T)
    assert 0.3 * T < s < 0.8 * T   # (the stretch with both contacts closed)
    to_s = FlowMap(system, 0.0, s)
    assert to_s.share(kept)
    f = to_s(q, v, jacobian=False)
    quiet = periodic_orbit(system, T, f.q, f.v, s, tol=1e-10, lead=kept)
    at0 = periodic_orbit(system, T, q, v, 0.0, tol=1e-10, lead=kept)
    assert quiet.converged and at0.converged and quiet.t0 == s
    assert not quiet.approximations
    assert quiet.directions.shape[1] == 2 * system.n - 4   # two closed gaps and their rates held
    back = FlowMap(system, s, (at0.t0 - s) % T)(quiet.q0, quiet.v0, jacobian=False)
    w = 2 * math.pi / T
    size = max(np.abs(at0.q0).max(), np.abs(at0.v0).max() / w)
    assert max(np.abs(back.q - at0.q0).max(), np.abs(back.v - at0.v0).max() / w) <= 1e-7 * size
    assert np.abs(np.sort_complex(quiet.multipliers[:6]) - np.sort_complex(at0.multipliers[:6])).max() <= 1e-7
    assert START_SETTLING < 1e-9   # (a real impact's velocity change is far above it)


def test_study_compares_the_shooting_with_the_reference_at_its_section():
    """studies/periodic.py's shooting (3-period lead, quiet section) against its reference orbit at t = 0: the
    distance is taken at one phase (the reference carried to the shooting's section by ``at_phase``), within the
    accuracy asked; taken across phases (the section's state against t = 0's) it would be O(1), which the
    study's earlier comparison did whenever a section moved."""
    import sys
    from pathlib import Path

    studies = str(Path(__file__).resolve().parents[1] / "studies")
    if studies not in sys.path:
        sys.path.insert(0, studies)
    import periodic as study

    system, T, q0, v0 = _crack()
    _, orbit = study.shooting(system, T, q0, v0, 1e-4, 3, None, "quiet")
    assert orbit.converged and orbit.t0 > 0.0
    ref = periodic_orbit(system, T, orbit.q0, orbit.v0, orbit.t0, tol=1e-12)
    w = 2 * math.pi / T
    assert study.distance(orbit.q0, orbit.v0, study.at_phase(system, T, ref, orbit.t0), w) <= 1e-4
    at0 = study.at_phase(system, T, ref, 0.0)
    assert study.distance(orbit.q0, orbit.v0, at0, w) > 0.1   # (another phase: not the same state)


def test_transition_without_pairs_is_the_matrix_exponential(monkeypatch):
    """Where a decomposition's conjugate pairs are not exact (a repeated eigenvalue: two partners; left vectors off
    by more than PAIR_TOL) every term is kept: the same transition (against expm as above); the pair finder falls
    back on such input."""
    from nsfem.periodic import variational

    lam = np.array([-1 + 2j, -1 - 2j, -1 + 2j, -1 - 2j, -3.0 + 0j])
    V = np.eye(5, dtype=complex)
    keep, weights, partner = variational._one_of_each_pair(lam, V, V)
    assert keep.tolist() == [0, 1, 2, 3, 4] and np.all(weights == 1.0) and not partner
    lam2 = np.array([-1 + 2j, -1 - 2j, -3.0 + 0j])
    V2 = np.array([[1, 1, 0], [1j, -1j, 0], [0, 0, 1]], dtype=complex)
    Vi2 = np.linalg.inv(V2)
    keep, weights, partner = variational._one_of_each_pair(lam2, V2, Vi2)
    assert keep.tolist() == [0, 2] and weights.tolist() == [2.0, 1.0] and partner == {0: 1}
    Vi2[1, 0] += 1e-6   # a left vector off its partner's conjugate: no pairs
    assert not variational._one_of_each_pair(lam2, V2, Vi2)[2]
    system, T, _, _ = _crack()
    every = lambda lam, V, Vi: (np.arange(lam.size), np.ones(lam.size), {})  # noqa: E731
    monkeypatch.setattr(variational, "_one_of_each_pair", every)
    config = Configuration(system, Mode(closed=(1,)))
    assert modal_transition(config)[0].size == config.eig[0].size
    cond = np.linalg.cond(config.eig[1])
    for s in (0.1 * T, T):
        ref = _van_loan(config, s)
        tol = 50 * (cond + np.abs(config.A).max() * s) * EPS * max(1.0, np.abs(ref).max())
        assert np.abs(phase_transition(config, s) - ref).max() <= tol


@pytest.mark.parametrize("theta", [0.0, 0.7, 1.5707963267948966, 2.5, 3.141592653589793])
def test_modal_exponentials_phi_is_accurate_across_its_series_threshold(theta):
    """phi(lam, s) = (e^{lam s} - 1) / lam, by its series where |lam s| < 1e-3 and by the quotient above, against
    s sum_k z^k / (k + 1)! (z = lam s, 25 terms: exact to a few eps for |z| <= 0.1), for |z| from 1e-9 to 0.1 on a
    ray of the complex plane (decaying, oscillating, growing) and z = 0. The series' truncation is |z|^4 / 120 <=
    8.4e-15 below 1e-3, the quotient's cancellation ~2 eps / |z| <= 4.5e-13 above: 1e-12 bounds both; a series cut
    one term short is off by |z|^3 / 24 (4e-11 at 1e-3), two terms short by |z|^2 / 6."""
    from nsfem.periodic.variational import _modal_exponentials

    s = 0.37
    z = np.concatenate([[0.0], np.logspace(-9, -1, 81)]) * np.exp(1j * theta)
    lam = z / s
    e, phi = _modal_exponentials(lam, s)
    ref = np.zeros_like(z)
    term = np.ones_like(z)
    for k in range(25):
        ref += term
        term = term * z / (k + 2)
    ref *= s
    assert np.abs(e - np.exp(z)).max() <= 4 * EPS
    assert np.all(np.abs(phi - ref) <= 1e-12 * np.abs(ref))


@pytest.mark.parametrize("closed, stick", [((0,), (0,)), ((0,), ()), ((), ())])
def test_transition_by_van_loan_is_the_modal_one(monkeypatch, closed, stick):
    """phase_transition's fallback (expm of the Van Loan matrix: rigid coordinates, no usable decomposition) against
    its modal form, on the block of tests/test_periodic_stick.py stuck (P_H = the held stick position: the forcing
    column -int e^{A s} B Q P_H matters), pressed without friction held and free, over a short phase, a period and
    three. Both are exact up to round-off: cond(V) eps of the modal form and |A s| eps of expm's scaling and squaring
    (as in the test above); a wrong sign or a missing term is an O(1) error (the stuck block's forcing column is
    O(k / m2))."""
    from test_periodic_stick import block_system

    from nsfem.periodic import variational

    w = 1.3
    T = 2 * math.pi / w
    system = block_system(w)
    mode = Mode(closed=closed, stick=stick)
    modal = Configuration(system, mode)
    assert modal_transition(modal) is not None
    expm_ = Configuration(system, mode)
    monkeypatch.setattr(variational, "_has_modal_exponentials", lambda config: False)
    assert modal_transition(expm_) is None
    cond = np.linalg.cond(modal.eig[1])
    for s in (1e-3 * T, T, 3 * T):
        a, b = phase_transition(modal, s), phase_transition(expm_, s)
        tol = 50 * (cond + np.abs(modal.A).max() * s) * EPS * max(1.0, np.abs(a).max())
        assert np.abs(a - b).max() <= tol, (closed, stick, s)
    if stick:
        assert np.abs(constraint_projector(modal)).max() == 1.0   # (the held stick position: the column is there)
