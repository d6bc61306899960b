"""Accumulations of impacts over a set of contacts (issue 32, section 3): each impact drives another
touching contact into approach, that one's impact drives the first back, ... The sequence is resolved
within the event (nsfem.integrate.transitions, docs/theory.md "Impact accumulation over a set of
contacts"): impact LCPs over the touching contacts that do not separate, each with its restitution,
until none approaches; after SET_STAGES, a plastic closure of the set.

Why plastic faces close at once. A plastic (eps = 0) impact at contact k alone is the M-orthogonal
projection of q' onto {j_k^T q' = 0}. Two touching contacts whose Delassus coupling W_AB = j_A^T M^-1 j_B
is negative (an impulse that opens one closes the other) take turns: the projections alternate, each
leaves the other contact approaching with kappa^2 = W_AB^2 / (W_AA W_BB) of the speed, and by von
Neumann's theorem (two hyperplanes; the multipliers stay positive since W_AB < 0) the iterates converge
to the projection onto both: the plastic impact LCP over the two, which the second stage solves (the
first contact, at g' = 0, takes part). Over three or more contacts alternating projections onto
half-spaces need not converge to the projection. The flights in between last gap / speed, with gaps
inside the zero band of the gap (below the structure's position resolution on the cracked shaft): no
time passes in the limit that the model resolves.

Tolerances are stated where used; the closed-form system is in exact arithmetic but for round-off.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from nsfem import load_scene
from nsfem.contact.set import ContactSet
from nsfem.integrate import ContactSystem, integrate
from nsfem.integrate.configuration import Mode
from nsfem.integrate.transitions import SET_STAGES, Memory, resolve
from nsfem.linalg import factorize
from nsfem.simulate import run_scene

KAPPA, OMEGA, DELTA = 0.9, 1.0, 5e-4


def rocker() -> tuple[ContactSystem, np.ndarray, float]:
    """Two frictionless plastic contacts on a 2-dof body with M = I and Delassus matrix
    W = [[1, -kappa], [-kappa, 1]]: gaps g = J^T q, free gap accelerations b(t) = (-1, -cos(w t)).

    Contact B (1) starts closed, its force cos(w t) vanishes at t_r = pi / (2 w): it lifts, its gap
    rate (1 - sin(w t)) / w = w (t - t_r)^2 / 2 + ... and gap ~ w (t - t_r)^3 / 6. Contact A (0)
    falls from the height h that lands it at t1 = t_r + DELTA: there B is 2e-11 (inside the gap's zero
    band) above its stop, separating at 1.25e-7 m/s (beyond the rate's band). Returns (system, q0, t1)."""
    s = math.sqrt(1.0 - KAPPA ** 2)
    J = np.array([[1.0, -KAPPA], [0.0, s]])
    f0 = np.linalg.solve(J.T, [-1.0, 0.0])
    fc = np.linalg.solve(J.T, [0.0, -1.0])
    tr = math.pi / (2.0 * OMEGA)
    # while B is closed A falls with -1 - kappa cos(w t) (the force on B pulls it down), then with -1
    h = tr ** 2 / 2 + KAPPA / OMEGA ** 2 + (tr + KAPPA / OMEGA) * DELTA + DELTA ** 2 / 2
    q0 = np.linalg.solve(J.T, [h, 0.0])
    sysm = ContactSystem.from_arrays(M=np.eye(2), Q=np.zeros((2, 2)), f0=f0, fc=fc, omega=OMEGA,
                                     contacts=ContactSet.from_arrays(J, [0.0, 0.0], eps=0.0))
    return sysm, q0, tr + DELTA


def test_rocker_closes_both_contacts_in_one_impact():
    sysm, q0, t1 = rocker()
    res = integrate(sysm, 2.0, "exact", 0.01, q0, np.zeros(2))
    assert res.completed
    assert [e["kinds"] for e in res.events] == [["release"], ["close"]]
    (imp,) = res.impacts
    # the event is located on the closed-form gap to its zero band: |dt| <= band / speed, band 1e-10 of
    # the gap's terms (~1.3 m here), speed 2.47 m/s: 5e-11 s
    assert imp["t"] == pytest.approx(t1, abs=1e-10, rel=0)
    assert imp["contacts"] == [0, 1] and imp["set_closure"] == [1] and res.events[-1]["set_closure"] == [1]
    assert res.events[-1]["after"]["closed"] == [0, 1]
    # kinetic energy before: q' = J^-T g' with g'_A = -(t_r + kappa / w) - DELTA, g'_B = (1 - sin w t1) / w;
    # with two independent constraints on two dofs it is all lost (round-off of the 16 J: 1e-14 J)
    s = math.sqrt(1.0 - KAPPA ** 2)
    J = np.array([[1.0, -KAPPA], [0.0, s]])
    v_before = np.linalg.solve(J.T, [-(math.pi / 2 + KAPPA) - DELTA, (1.0 - math.sin(t1)) / OMEGA])
    assert imp["kinetic_before_J"] == pytest.approx(0.5 * v_before @ v_before, rel=1e-12)
    assert imp["kinetic_after_J"] == pytest.approx(0.0, abs=1e-14)
    assert res.energy["lost_in_impacts_J"] == pytest.approx(imp["kinetic_before_J"], rel=1e-12)
    # afterwards LCP (29) with both closed: lam = W^-1 (-b(t)) = ((1 + k cos wt), (k + cos wt)) / (1 - k^2),
    # positive until cos wt = -kappa (t = 2.69 s): the set stays closed with these forces (round-off of the
    # solve, cond(W) = 19: 1e-13 relative; allowed 1e-10)
    after = res.t > t1
    c = np.cos(OMEGA * res.t[after])
    lam = np.array([1.0 + KAPPA * c, KAPPA + c]) / (1.0 - KAPPA ** 2)
    np.testing.assert_allclose(res.normal_force[:, after], lam, rtol=1e-10, atol=0)
    assert np.all(res.state[:, after] != 0)
    # gaps held at zero to their band (1e-10 of ~1.3 m)
    assert np.max(np.abs(res.gap[:, after])) <= 2e-10


def random_body(rng: np.random.Generator, n: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    """A random n-dof body's mass matrix (symmetric, eigenvalues >= n) and m contacts' normals (n, m)."""
    L = rng.normal(size=(n, n))
    return L @ L.T + n * np.eye(n), rng.normal(size=(n, m))


def alternating_limit(M: np.ndarray, J: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The independent reference: plastic impacts one contact at a time, always at the most approaching
    touching contact, until none approaches (each a projection in the kinetic metric; von Neumann)."""
    Minv_J = np.linalg.solve(M, J)
    for _ in range(100_000):
        g = J.T @ v
        k = int(np.argmin(g))
        if g[k] >= -1e-15 * np.abs(J).T.max() * np.abs(v).max():
            return v
        v = v - Minv_J[:, k] * g[k] / (J[:, k] @ Minv_J[:, k])
    raise AssertionError("alternating projections did not converge")


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(st.integers(0, 2 ** 31 - 1))
def test_set_closure_is_the_limit_of_alternating_plastic_impacts(seed):
    """A random 3-dof body, two touching plastic contacts with negative coupling, A approaching and B
    separating slower than A's impulse drives it back: resolve() gives the limit of the alternation."""
    rng = np.random.default_rng(seed)
    n = 3
    M, J = random_body(rng, n, 2)
    W = J.T @ np.linalg.solve(M, J)
    if W[0, 1] > 0:            # make the coupling negative: an impulse opening A closes B
        J[:, 1] *= -1.0
        W = J.T @ np.linalg.solve(M, J)
    assume(-W[0, 1] / math.sqrt(W[0, 0] * W[1, 1]) > 0.05)   # a coupling that matters
    # gap rates: A approaches at 1, B separates at a fraction of what A's plastic impulse drives into it
    gA, gB = -1.0, rng.uniform(0.05, 0.9) * (-W[0, 1] / W[0, 0])
    v = np.linalg.lstsq(J.T, [gA, gB], rcond=None)[0]
    sysm = ContactSystem.from_arrays(M=M, Q=np.eye(n), contacts=ContactSet.from_arrays(J, [0.0, 0.0], eps=0.0))
    Mf = factorize(M, "M")
    memory = Memory(np.zeros(2), np.zeros(2, dtype=int))
    mode, v_after, imp = resolve(sysm, Mf, 0.0, np.zeros(n), v, Mode(), memory)
    assert imp["set_closure"] == [1] and imp["contacts"] == [0, 1]
    ref = alternating_limit(M, J, v)
    # the iteration converges with kappa^2 per cycle to 1e-15 of |v|; the LCP's round-off is cond(W) eps
    scale = np.abs(v).max()
    np.testing.assert_allclose(v_after, ref, rtol=0, atol=1e-10 * scale)
    assert np.all(J.T @ v_after >= -1e-12 * scale)
    assert v_after @ M @ v_after <= v @ M @ v * (1.0 + 1e-12)


@settings(max_examples=80, deadline=None, derandomize=True, database=None)
@given(st.integers(0, 2 ** 31 - 1), st.integers(2, 4), st.floats(0.0, 1.0))
def test_no_touching_contact_approaches_after_an_impact(seed, m, eps):
    """Property: after the impact at an event no contact at zero gap is left approaching (it would
    penetrate at once), and the impact never adds kinetic energy (eps <= 1, no friction): the change of
    the first LCP is sum_k Lambda_k (g'-_k + g'+_k) / 2 = -(1 - eps) sum Lambda_k |g'-_k| / 2 <= 0 over the
    approaching contacts (g'+ = -eps g'-), that of the set's projection onto a cone containing 0 is <= 0."""
    rng = np.random.default_rng(seed)
    n = m + 2
    M, J = random_body(rng, n, m)
    v = rng.normal(size=n)
    sysm = ContactSystem.from_arrays(M=M, Q=np.eye(n), contacts=ContactSet.from_arrays(J, np.zeros(m), eps=eps))
    Mf = factorize(M, "M")
    memory = Memory(np.zeros(m), np.zeros(m, dtype=int))
    _, v_after, imp = resolve(sysm, Mf, 0.0, np.zeros(n), v, Mode(), memory)
    # the gap rates are resolved to the LCP's round-off relative to the velocities' terms (1e-12 allowed)
    scale = float((np.abs(J).T @ np.abs(v)).max())
    assert np.all(J.T @ v_after >= -1e-10 * scale)
    assert v_after @ M @ v_after <= v @ M @ v * (1.0 + 1e-12)


CRACKED_SHAFT = """
title = "issue 32: unreduced cracked rectangular shaft"
[shaft]
length = 1.0
section = "rectangle"
width = 0.04
height = 0.01
E = 2.1e11
rho = 7800.0
supports = "pinned-pinned"
[[crack]]
x = 0.4
depth = 0.3
side = "-z"
[rotation]
speed_hz = 5.0
[damping]
external = 0.5
[reduction]
method = "none"
[mesh]
elements = 100
[simulation]
method = "exact"
t_end = 2.0
output_dt = 1e-3
"""


def _cracked_run(tmp_path, *sets):
    path = tmp_path / "cracked.toml"
    path.write_text(CRACKED_SHAFT)
    res, _ = run_scene(load_scene(str(path), list(sets)))
    return res


def _check_cracked(res):
    assert res.completed
    # the alternation's signature (issue 32): chains of impacts each within 1e-9 s of the previous, at the
    # two ends of the crack front in turn (64 in 2e-7 s before the fix). A contact that another's impact
    # drives into approach now closes in the same impact; what remains is at most a pair (an impact at one
    # end, then the other end landing from a flight above the zero band)
    times = np.array([i["t"] for i in res.impacts])
    chain, longest = 1, 1
    for dt in np.diff(times):
        chain = chain + 1 if dt < 1e-9 else 1
        longest = max(longest, chain)
    assert longest <= 2
    assert any("set_closure" in e for e in res.events)   # the resolution is reported
    # impacts never add kinetic energy (plastic faces; 1e-12 relative: round-off of the 1e-7 J)
    for imp in res.impacts:
        assert imp["kinetic_after_J"] <= imp["kinetic_before_J"] * (1.0 + 1e-12)
    # the energy balance closes (closed-form phases, Gauss quadrature: measured 1e-13..1e-9 of max E; a
    # lost or invented impact loss of the 1e-16..1e-15 J booked here would not show, the check below is
    # of the integration); the faces never interpenetrate beyond the position resolution of the 1 m
    # shaft (4 eps x 1 m = 9e-16 m)
    assert res.energy["relative_residual"] < 1e-6
    assert res.gap.min() >= -1e-15


def test_unreduced_cracked_shaft_short(tmp_path):
    """The issue's shaft on 40 elements (the same alternation: 194 impacts in 5e-5 s before the fix, 14 now)."""
    _check_cracked(_cracked_run(tmp_path, "mesh.elements=40", "simulation.t_end=5e-5", "simulation.output_dt=1e-5"))


@pytest.mark.slow
@pytest.mark.parametrize("state", ["rest", "stationary"])
def test_unreduced_cracked_shaft_issue_case(tmp_path, state):
    """The issue's case (100 elements, 502 dofs, 2 s) from rest and from the stationary state (before the
    fix: 90 impacts in 1.4e-9 s at 2.78e-5 s, and the run stopped at 2.8e-5 s; now 335 events, about
    1 min of computing each)."""
    _check_cracked(_cracked_run(tmp_path, f'initial.state="{state}"', "simulation.output_dt=1e-2"))


# --- review of the set closure: restitution within the set ---


def sequential_impacts(M: np.ndarray, J: np.ndarray, v: np.ndarray, eps: np.ndarray,
                       limit: int) -> tuple[np.ndarray, int]:
    """The independent reference for restitution: the impacts the event search would locate one after the
    other, with no flight in between: each an impact LCP (30-32) over the contacts that do not separate
    (g' <= 1e-10 of its terms), Newton's eps on the approaching ones (plastic below 1e-8 of a contact's
    earlier approach, the one-contact Zeno rule), solved by enumerating the active sets. Returns the
    velocity and the number of impacts (``limit`` + 1 when the sequence has not ended)."""
    Minv_J = np.linalg.solve(M, J)
    top = np.zeros(J.shape[1])
    for n in range(limit + 1):
        g = J.T @ v
        tol = 1e-10 * (np.abs(J).T @ np.abs(v))
        if np.all(g >= -tol):
            return v, n
        part = np.flatnonzero(g <= tol)
        gp = g[part]
        speed = np.maximum(-gp, 0.0)
        e = np.where(speed < 1e-8 * top[part], 0.0, eps[part])
        top[part] = np.maximum(top[part], speed)
        b = gp + e * np.minimum(gp, 0.0)
        W = J[:, part].T @ Minv_J[:, part]
        for r in range(len(part) + 1):
            sols = []
            for S in itertools.combinations(range(len(part)), r):
                lam = np.zeros(len(part))
                lam[list(S)] = np.linalg.solve(W[np.ix_(S, S)], -b[list(S)]) if S else []
                w = W @ lam + b
                if lam.min(initial=0.0) >= -1e-12 * np.abs(b).max() and w.min() >= -1e-12 * np.abs(b).max():
                    sols.append(lam)
            if sols:
                break
        v = v + Minv_J[:, part] @ sols[0]
    return v, limit + 1


def test_rebound_within_the_set_keeps_restitution():
    """Reproduction (review of issue 32's set closure): the rocker's two contacts with eps = 0.9, A approaching
    at 1, B separating at 0.3 (unit Delassus diagonal, coupling -0.94). A's impulse drives B into approach at
    once; the integrator would resolve 8 impacts in turn (eps = 0.9 keeps most of the energy, 0.87 of 2.26 J).
    The set closure took the plastic projection over both: everything lost (0 J). Now the sequence is resolved
    within the event, with each contact's restitution."""
    k = 0.94
    J = np.array([[1.0, -k], [0.0, math.sqrt(1.0 - k * k)]])
    M = np.eye(2)
    v = np.linalg.solve(J.T, [-1.0, 0.3])
    sysm = ContactSystem.from_arrays(M=M, Q=np.eye(2), contacts=ContactSet.from_arrays(J, [0.0, 0.0], eps=0.9))
    memory = Memory(np.zeros(2), np.zeros(2, dtype=int))
    _, v_after, imp = resolve(sysm, factorize(M, "M"), 0.0, np.zeros(2), v, Mode(), memory)
    ref, n = sequential_impacts(M, J, v, np.full(2, 0.9), 100)
    assert n == 8 and imp["set_stages"] == n - 1 and "set_limit" not in imp
    # each of the 8 LCPs is solved to its round-off (cond(W) = 17: 1e-14 of the unit speeds; 1e-12 allowed)
    np.testing.assert_allclose(J.T @ v_after, J.T @ ref, rtol=0, atol=1e-12)
    # both separate: 0.149 and 0.307 m/s, energy 0.868 J of 2.26 J (not the 0 J of a plastic closure)
    assert np.all(J.T @ v_after > 0.1)
    assert imp["kinetic_after_J"] == pytest.approx(0.5 * ref @ ref, rel=1e-12)


def test_accumulating_set_closes_at_its_limit():
    """eps = 0.2 and the same rocker: A and B take turns, each turn leaving a fraction of the speeds; one by
    one the sequence runs for 193 impacts, until the one-contact Zeno rule (an approach below 1e-8 of the
    contact's first) makes them plastic. After SET_STAGES (100) impacts within the set it is closed
    plastically instead, at the sequence's limit: both gap rates 0, all energy lost."""
    k = 0.94
    J = np.array([[1.0, -k], [0.0, math.sqrt(1.0 - k * k)]])
    v = np.linalg.solve(J.T, [-1.0, 0.3])
    sysm = ContactSystem.from_arrays(M=np.eye(2), Q=np.eye(2), contacts=ContactSet.from_arrays(J, [0.0, 0.0], eps=0.2))
    memory = Memory(np.zeros(2), np.zeros(2, dtype=int))
    _, v_after, imp = resolve(sysm, factorize(np.eye(2), "M"), 0.0, np.zeros(2), v, Mode(), memory)
    ref, n = sequential_impacts(np.eye(2), J, v, np.full(2, 0.2), 1000)
    assert n > SET_STAGES + 1 and imp["set_limit"] is True and imp["set_stages"] == SET_STAGES + 1
    # the limit: both gap rates zero (round-off of the projection, 1e-15 of the unit speeds; 1e-12 allowed),
    # where the one-by-one sequence ends too (its last approach below 1e-8 of the first: 1e-8 allowed)
    np.testing.assert_allclose(J.T @ v_after, 0.0, atol=1e-12)
    np.testing.assert_allclose(J.T @ ref, 0.0, atol=1e-8)
    assert imp["kinetic_after_J"] <= 1e-24


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(st.integers(0, 2 ** 31 - 1), st.integers(2, 3), st.floats(0.05, 1.0))
def test_impacts_within_a_set_follow_the_sequence(seed, m, eps):
    """Property: at zero gaps, the impact at an event (restitution eps on all contacts, some touching ones
    separating) ends where the one-by-one sequence of impacts ends, whenever that sequence is finite within
    SET_STAGES; kinetic energy never grows."""
    rng = np.random.default_rng(seed)
    n = m + 1
    M, J = random_body(rng, n, m)
    v = rng.normal(size=n)
    assume(np.any(J.T @ v < 0))
    ref, count = sequential_impacts(M, J, v, np.full(m, eps), 50)
    assume(count <= 50)
    sysm = ContactSystem.from_arrays(M=M, Q=np.eye(n), contacts=ContactSet.from_arrays(J, np.zeros(m), eps=eps))
    memory = Memory(np.zeros(m), np.zeros(m, dtype=int))
    _, v_after, imp = resolve(sysm, factorize(M, "M"), 0.0, np.zeros(n), v, Mode(), memory)
    # each of up to 50 LCPs adds round-off of cond(W) eps relative to the velocities' terms (1e-13 each);
    # 1e-9 allowed for the accumulation over the sequence
    scale = float((np.abs(J).T @ np.abs(v)).max())
    np.testing.assert_allclose(J.T @ v_after, J.T @ ref, rtol=0, atol=1e-9 * scale)
    assert v_after @ M @ v_after <= v @ M @ v * (1.0 + 1e-12)


def _frictional_body(seed: int):
    """A random 4-dof body, two touching contacts with mu = 1 (8-sided pyramids), eps = 0.9, fixed surfaces."""
    rng = np.random.default_rng(seed)
    M, J = random_body(rng, 4, 2)
    JS = [rng.normal(size=(4, 2)) for _ in range(2)]
    v = rng.normal(size=4)
    if np.all(J.T @ v > 0.0):   # (an impact: one contact at least approaching)
        v = -v
    cs = ContactSet.from_arrays(J, np.zeros(2), mu=1.0, eps=0.9, JS=JS, r=8)
    return ContactSystem.from_arrays(M=M, Q=np.eye(4), contacts=cs), M, J, v


@pytest.mark.parametrize("seed", [170, 351] + list(range(10)))
def test_impacts_within_a_set_add_no_energy_with_friction(seed):
    """Newton's restitution with Coulomb friction can add kinetic energy in one impact LCP (Kane's example;
    the paper's law 30-33, not changed here). Repeated within a set
    such gains compounded: seeds 170 and 351 ended with 1.7e4 and 2.3e5 times the kinetic energy after 100
    stages. A stage that would add energy now ends the sequence with the plastic closure, so the impact
    ends with no more energy than its first LCP left (1e-12: round-off of the energies)."""
    from nsfem.lcp.builders import impact_lcp
    sysm, M, J, v = _frictional_body(seed)
    Mf = factorize(M, "M")
    first = [k for k in range(2) if J[:, k] @ v <= 0.0]
    lcp = impact_lcp(sysm.contacts, Mf, v, first, eps=np.full(2, 0.9), q=np.zeros(4))
    res = lcp.solve()
    if not res.success:          # (Lemke has no solution for some random frictional bodies: not this test's subject)
        pytest.skip("first impact LCP without solution")
    v1 = lcp.motion(res.x)
    memory = Memory(np.zeros(2), np.zeros(2, dtype=int))
    _, v_after, imp = resolve(sysm, Mf, 0.0, np.zeros(4), v, Mode(), memory)
    bound = max(float(v @ M @ v), float(v1 @ M @ v1))
    assert float(v_after @ M @ v_after) <= bound * (1.0 + 1e-12)
