"""The forced impact oscillator (Shaw & Holmes 1983; Peterka; Nordmark 1991): the closed form of
tests/impact_oscillator.py checked against brute force (nsfem's exact event-driven integrator on the same
one-degree-of-freedom system), then used as the reference for nsfem.periodic's shooting (issue 36).

The system: m = k = F = 1, c = 2 zeta with zeta = 0.05, e = 0.8, the stop at x = d (d = 0, and d = 0.2 where the
harmonic steady state can graze it). Its numbers (closed form): period-1 multipliers at w = 2.5:
-0.14543 +- 0.69038 i (modulus 0.70553); the period-1 orbit (d = 0) is stable between its period doublings at
w = 1.229735 and w_pd = 2.658884546685; grazing at w_g = 2.448265 (d = 0.2).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm

from impact_oscillator import (Oscillator, flight, grazing_frequencies, harmonic_coefficients, harmonic_gap_min,
                               orbit_state, period1_branch, period1_orbits, period1_roots, period2_orbit,
                               period_doubling_frequency, transition)
from nsfem.contact.set import ContactSet
from nsfem.integrate import ContactSystem, integrate

ZETA = 0.05
OSC = Oscillator(m=1.0, c=2 * ZETA, k=1.0, F=1.0, d=0.0, e=0.8)
OSC_GAP = Oscillator(m=1.0, c=2 * ZETA, k=1.0, F=1.0, d=0.2, e=0.8)


def impact_system(osc: Oscillator, w: float) -> ContactSystem:
    """The oscillator as an nsfem system: gap g = J_N^T q + j_N = d - x (J_N = [[-1]], j_N = [d])."""
    return ContactSystem.from_arrays(M=[[osc.m]], Q=[[osc.k]], C=[[osc.c]], fc=[osc.F], omega=w,
                                     contacts=ContactSet.from_arrays([[-1.0]], [osc.d], eps=osc.e))


def sections(osc: Oscillator, w: float, x0: float, v0: float, periods: int, span: float):
    """Brute force: the exact integrator from (x0, v0) at t = 0; the states at t = 0, span, 2 span, ... and the
    impact records."""
    res = integrate(impact_system(osc, w), periods * span, "exact", output_dt=span, q0=[x0], v0=[v0])
    return np.stack([res.q[0], res.v[0]], axis=1), res.impacts


def multiplier_error(got, ref) -> float:
    """Largest |got_i - ref_pi(i)| / |ref_pi(i)| under the best pairing (conjugate pairs have equal moduli, so
    no sorting order is safe)."""
    got, ref = np.asarray(got, complex), np.asarray(ref, complex)
    assert got.shape == ref.shape
    return min(max(abs(g - r) / abs(r) for g, r in zip(got, perm)) for perm in itertools.permutations(ref))


# --- the closed form itself --------------------------------------------------------------------------------------

@pytest.mark.parametrize("c, k", [(0.1, 1.0), (3.0, 1.0), (2.0, 1.0), (0.0, 4.0)])
def test_transition_is_the_matrix_exponential(c, k):
    """Cayley-Hamilton's closed form against scipy's expm, under-, over- and critically damped and undamped;
    both are exact to round-off of entries of size ~1 (|L| s <= 10): 1e-12."""
    osc = Oscillator(c=c, k=k)
    for s in (0.0, 1e-9, 0.3, 2.0, 5.0):
        np.testing.assert_allclose(transition(osc, s), expm(osc.L * s), rtol=0, atol=1e-12)


@pytest.mark.parametrize("osc, w", [(OSC, 1.5), (OSC, 2.0), (OSC, 2.5), (OSC, 3.0), (OSC_GAP, 1.2), (OSC_GAP, 2.2)])
def test_period1_orbit_closes_with_one_impact(osc, w):
    """The orbit's defining conditions, evaluated independently of how they were solved: the state after the
    impact at tau, (d, -e u), flown over T lands at (d, u); the section state (x0, v0) at t = 0 flown to tau lands
    at (d, u) too. Round-off of states ~1 through a 2 x 2 exponential: 1e-12."""
    orbits = period1_orbits(osc, w)
    assert len(orbits) == 1
    p = orbits[0]
    T = p.period
    np.testing.assert_allclose(flight(osc, w, p.tau, [osc.d, -osc.e * p.u], T), [osc.d, p.u], atol=1e-12)
    np.testing.assert_allclose(flight(osc, w, 0.0, [p.x0, p.v0], p.tau), [osc.d, p.u], atol=1e-12)
    # the multipliers' product is det S det E(T) = e^2 exp(-c T / m) (Liouville and the two impacts' e)
    assert abs(np.prod(p.multipliers) - osc.e ** 2 * math.exp(-osc.c * T / osc.m)) <= 1e-12


@pytest.mark.parametrize("w_lo, w_hi, stable_side", [(1.2, 1.3, +1), (2.5, 2.75, -1)])
def test_period_doubling_frequency_has_a_multiplier_at_minus_one(w_lo, w_hi, stable_side):
    """What the root must satisfy: a multiplier at -1 at w_pd (Brent to 1e-13 relative in w, the multiplier moving
    ~10 per unit w: 1e-10); 1 % to one side the orbit is stable, to the other a real multiplier is < -1. The
    period-1 orbit (d = 0) is stable between the two period doublings, 1.22974 and 2.65888."""
    w_pd = period_doubling_frequency(OSC, w_lo, w_hi)
    at = period1_branch(OSC, w_pd, -1)
    assert at.exists
    assert np.min(np.abs(at.multipliers + 1.0)) <= 1e-10
    inside, outside = (period1_branch(OSC, w_pd * (1 + 0.01 * side), -1) for side in (stable_side, -stable_side))
    assert inside.exists and outside.exists
    assert np.abs(inside.multipliers).max() < 1.0
    assert outside.multipliers[0].real < -1.0 and abs(outside.multipliers[0].imag) == 0.0


def test_period2_orbit_branches_off_at_the_period_doubling_as_a_flip():
    """The normal form of a supercritical flip (the period-2 orbit past w_pd, where the period-1 orbit is
    unstable): the two impact velocities split like sqrt(w - w_pd) and the period-2 orbit's multiplier leaves +1
    like (w - w_pd). Quartering the distance (2.5e-4 -> 6.25e-5 relative) halves the split and quarters 1 - mu,
    up to the next order, O(sqrt(distance)) ~ 1e-2 relative (measured 2.3e-4 and 1.06e-2)."""
    w_pd = period_doubling_frequency(OSC, 2.5, 2.75)
    orbits = [period2_orbit(OSC, w_pd * (1 + delta)) for delta in (2.5e-4, 6.25e-5)]
    assert all(p.exists and p.residual <= 1e-12 for p in orbits)
    split = [abs(p.u[1] - p.u[0]) for p in orbits]
    assert split[0] / split[1] == pytest.approx(2.0, rel=1e-2)
    gap = [1.0 - p.multipliers[0].real for p in orbits]
    assert all(abs(p.multipliers[0].imag) == 0.0 and 0 < g for p, g in zip(orbits, gap))
    assert gap[0] / gap[1] == pytest.approx(4.0, rel=3e-2)


def test_grazing_frequency_and_nordmarks_singularity():
    """At w_g the harmonic steady state's amplitude is d (round-off: 1e-12); below it the impacting orbit's
    approach velocity u -> 0 linearly in w_g - w, and its largest multiplier grows like 1/u (the saltation's
    S_21 ~ 1/u, Nordmark 1991): mu_max u -> (1 + e)(F cos phi - k d) / m E_12(T), to O(u) = 1e-5 relative."""
    (w_g,) = grazing_frequencies(OSC_GAP)
    A, B = harmonic_coefficients(OSC_GAP, w_g)
    assert abs(math.hypot(A, B) - OSC_GAP.d) <= 1e-12
    assert harmonic_gap_min(OSC_GAP, w_g * (1 + 1e-3)) > 0 > harmonic_gap_min(OSC_GAP, w_g * (1 - 1e-3))
    near = [period1_branch(OSC_GAP, w_g * (1 - delta), -1) for delta in (1e-4, 1e-5)]
    assert all(p.exists for p in near)
    assert near[1].u / near[0].u == pytest.approx(0.1, rel=1e-3)       # linear in the distance (O(delta))
    for p in near:
        limit = (1 + OSC_GAP.e) * (OSC_GAP.F * math.cos(p.phi) - OSC_GAP.k * OSC_GAP.d) / OSC_GAP.m \
            * transition(OSC_GAP, p.period)[0, 1]
        assert p.multipliers[0].real * p.u == pytest.approx(limit, rel=1e-3)
    # past w_g no impacting orbit: the only root has u < 0
    assert not period1_orbits(OSC_GAP, w_g * (1 + 1e-4))


def test_bad_parameters_are_refused():
    for kwargs, word in [({"e": 0.0}, "restitution"), ({"m": -1.0}, "m > 0"), ({"c": math.nan}, "c must be finite")]:
        with pytest.raises(ValueError, match=word):
            Oscillator(**kwargs)
    with pytest.raises(ValueError, match="forcing frequency"):
        period1_roots(OSC, 0.0)
    with pytest.raises(ValueError, match="no multiplier crosses -1"):
        period_doubling_frequency(OSC, 1.5, 2.0)
    assert period1_roots(Oscillator(F=0.0), 2.0) == []                  # unforced: no periodic impact motion
    with pytest.raises(ValueError, match="no period-1 orbit to start from"):
        period2_orbit(OSC_GAP, 3.0)                                       # past grazing: nothing impacts


# --- the closed form against brute force (the exact integrator) --------------------------------------------------

@pytest.mark.parametrize("osc, w", [(OSC, 2.0), (OSC, 2.5), (OSC_GAP, 0.8 * 2.448265)])
def test_transient_converges_at_the_rate_of_the_multipliers(osc, w):
    """From the orbit displaced by dx = 1e-4, the exact flow's section states follow the linearized prediction
    M^k dx of the closed-form monodromy (saltation included) for 40 periods: the difference is second order,
    ~dx / (orbit size ~0.5) = 2e-4 of |M^k| dx, plus the integrator's round-off (event times to ~1e-12 s, states
    ~1e-12 m) -- bounded by 1e-2 |M^k| dx + 1e-10. A wrong saltation matrix is off by O(1)."""
    p = period1_branch(osc, w, -1)
    dx = np.array([1e-4, 0.0])
    y, impacts = sections(osc, w, p.x0 + dx[0], p.v0, 40, p.period)
    assert np.abs(p.multipliers).max() < 1.0
    for k in range(41):
        Mk = np.linalg.matrix_power(p.monodromy, k)
        err = np.linalg.norm(y[k] - [p.x0, p.v0] - Mk @ dx)
        assert err <= 1e-2 * np.linalg.norm(Mk, 2) * 1e-4 + 1e-10, (k, err)
    # one impact per period, at tau (mod T) with approach velocity u, once the transient has decayed
    # (|mu|^30 < 1e-4 of dx: 1e-8 s and 1e-8 m/s, far above round-off)
    assert len(impacts) == 40
    for rec in impacts[-5:]:
        assert abs((rec["t"] - p.tau + p.period / 2) % p.period - p.period / 2) <= 1e-8
        assert rec["approach_m_s"][0] == pytest.approx(p.u, abs=1e-8)


def test_unstable_orbit_is_left_at_its_multiplier_and_the_motion_settles_on_period_two():
    """Just past the period doubling (w = 1.02 w_pd, multipliers -1.678, -0.303): from the period-1 orbit
    displaced by 1e-6 the deviation grows by |mu_1| per period (periods 4-10: the other component has decayed
    by (0.303 / 1.678)^4 = 1e-3, the second-order terms are < 1e-4 of it); after 200 periods the motion is the
    closed-form period-2 orbit (its multipliers 0.508 in modulus per 2T: round-off long before), state by state
    at both phases of the section, with its two impacts per 2T."""
    w = 1.02 * period_doubling_frequency(OSC, 2.5, 2.75)
    p1 = period1_branch(OSC, w, -1)
    p2 = period2_orbit(OSC, w)
    T = p1.period
    assert p2.exists and p2.residual <= 1e-12 and np.abs(p2.multipliers).max() < 1.0
    y, impacts = sections(OSC, w, p1.x0 + 1e-6, p1.v0, 200, T)
    dev = np.linalg.norm(y - [p1.x0, p1.v0], axis=1)
    assert dev[4:11][1:] / dev[4:11][:-1] == pytest.approx(abs(p1.multipliers[0]), rel=2e-3)
    phases = orbit_state(OSC, w, list(zip(p2.tau, p2.u)), 2 * T, np.array([0.0, T]))
    tail = y[-10:]
    # which phase the transient locked on is not fixed: match either
    lock = 0 if np.linalg.norm(tail[0] - phases[0]) < np.linalg.norm(tail[0] - phases[1]) else 1
    for i, state in enumerate(tail):
        np.testing.assert_allclose(state, phases[(i + lock) % 2], atol=1e-9)
    velocities = sorted(rec["approach_m_s"][0] for rec in impacts[-2:])
    np.testing.assert_allclose(velocities, np.sort(p2.u), atol=1e-9)


@settings(max_examples=40, deadline=None, derandomize=True, database=None)
@given(zeta=st.floats(0.01, 0.2), e=st.floats(0.3, 1.0), d=st.floats(0.0, 0.4), ratio=st.floats(0.5, 4.0),
       k=st.floats(0.5, 2.0))
def test_every_closed_form_orbit_is_an_orbit_of_the_exact_flow(zeta, e, d, ratio, k):
    """Property: wherever the closed form reports a period-1 orbit (u > 0, flight off the stop), the exact
    integrator flown one period from its section state returns to it with exactly one impact at (tau, u).
    Tolerance: round-off of the flight (1e-12 of the orbit's size) amplified by the largest multiplier;
    orbits within 1e-2 of grazing (u < 1e-2 w F / k) are left out (there the exact flow's own event location
    meets the stop tangentially), and so are impacts within 1e-6 T of the section (then counted in this period
    or the next)."""
    osc = Oscillator(m=1.0, c=2 * zeta * math.sqrt(k), k=k, F=1.0, d=d, e=e)
    w = ratio * math.sqrt(k)
    for p in period1_orbits(osc, w):
        if p.u < 1e-2 * w / k or min(p.tau, p.period - p.tau) < 1e-6 * p.period:
            continue                                     # near grazing, or the impact on the section
        size = abs(p.x0) + abs(p.v0) / w + d + 1.0 / k
        y, impacts = sections(osc, w, p.x0, p.v0, 1, p.period)
        tol = 1e-10 * size * max(1.0, float(np.abs(p.multipliers).max()))
        assert np.linalg.norm(y[1] - [p.x0, p.v0]) <= tol
        assert len(impacts) == 1 and impacts[0]["approach_m_s"][0] == pytest.approx(p.u, abs=tol * w)


# --- nsfem.periodic's shooting against the closed form (issue 36; nsfem.periodic lands with the lead's merge) ---
# Tolerances: the shooting converges to residual 1e-9 and its monodromy is exact to round-off (closed-form phase
# transitions and saltation matrices), so section states agree to ~1e-9 of the orbit's size and the multipliers
# to ~1e-7 relative (an error 1e-9 in the state moves the impact's S_21 ~ 1/u by 1e-9 / u, u ~ 0.1-1).

def _shoot(osc, w, x0, v0, period):
    from nsfem.periodic import periodic_orbit

    return periodic_orbit(impact_system(osc, w), period, q0=[x0], v0=[v0], t0=0.0, tol=1e-9)


@pytest.mark.parametrize("w", [2.0, 2.5])
def test_shooting_finds_the_closed_form_period1_orbit(w):
    p = period1_branch(OSC, w, -1)
    orbit = _shoot(OSC, w, p.x0 + 1e-3, p.v0 - 1e-3, p.period)
    assert orbit.converged and orbit.residual <= 1e-9
    assert orbit.period_s == pytest.approx(p.period, rel=1e-15)
    assert orbit.events_per_period == 1
    size = abs(p.x0) + abs(p.v0) / w
    assert abs(orbit.q0[0] - p.x0) <= 1e-8 * size and abs(orbit.v0[0] - p.v0) <= 1e-8 * size * w
    assert multiplier_error(orbit.multipliers, p.multipliers) <= 1e-7
    assert orbit.stable and orbit.loss is None
    assert not orbit.grazing


def test_shooting_verdict_turns_to_period_doubling_across_w_pd():
    w_pd = period_doubling_frequency(OSC, 2.5, 2.75)
    for factor, stable in ((0.99, True), (1.01, False)):
        p = period1_branch(OSC, factor * w_pd, -1)
        orbit = _shoot(OSC, factor * w_pd, p.x0 + 1e-4, p.v0, p.period)
        assert orbit.converged and orbit.events_per_period == 1
        assert multiplier_error(orbit.multipliers, p.multipliers) <= 1e-7
        assert bool(orbit.stable) == stable
        assert orbit.loss == (None if stable else "period-doubling")


def test_shooting_period2_orbit_past_the_period_doubling():
    """period_s = 2 T at 1.02 w_pd: the closed-form period-2 orbit, two impacts per period, stable."""
    w = 1.02 * period_doubling_frequency(OSC, 2.5, 2.75)
    p2 = period2_orbit(OSC, w)
    orbit = _shoot(OSC, w, p2.x0 + 1e-4, p2.v0, 4 * math.pi / w)
    assert orbit.converged and orbit.events_per_period == 2
    size = abs(p2.x0) + abs(p2.v0) / w
    assert abs(orbit.q0[0] - p2.x0) <= 1e-8 * size and abs(orbit.v0[0] - p2.v0) <= 1e-8 * size * w
    assert multiplier_error(orbit.multipliers, p2.multipliers) <= 1e-7
    assert orbit.stable and orbit.loss is None


def test_shooting_near_grazing():
    """d = 0.2. Just below w_g the impacting orbit (u = 1.8e-3 at w_g (1 - 1e-3)) is violently unstable
    (Nordmark: mu ~ -1/u, here -571), which the shooting must reproduce; just above, the orbit is the harmonic
    steady state without impact whose smallest gap d - amplitude (4e-9 m at w_g (1 + 1e-8)) is recorded as
    grazing contact 0."""
    (w_g,) = grazing_frequencies(OSC_GAP)
    w = w_g * (1 - 1e-3)
    p = period1_branch(OSC_GAP, w, -1)
    orbit = _shoot(OSC_GAP, w, p.x0, p.v0 + 1e-6, p.period)
    assert orbit.converged and orbit.events_per_period == 1
    # S_21 ~ 1/u magnifies the state's error 1e-9 by 1/u = 550: the largest multiplier to 1e-6 relative; the
    # small one (-8.7e-4) is det M / mu_1 with det M = e^2 exp(-c T / m) (det S = e^2 whatever S_21): their product
    mu = orbit.multipliers[np.argmax(np.abs(orbit.multipliers))]
    assert abs(mu - p.multipliers[0]) <= 1e-6 * abs(p.multipliers[0])
    assert abs(np.prod(orbit.multipliers) - np.prod(p.multipliers)) <= 1e-6 * abs(np.prod(p.multipliers))
    assert not orbit.stable and orbit.loss == "period-doubling"

    w = w_g * (1 + 1e-8)
    A, B = harmonic_coefficients(OSC_GAP, w)
    # started 1e-10 m inside the harmonic orbit: any start farther out than the gap (4.8e-9 m) would hit the stop
    orbit = _shoot(OSC_GAP, w, A - 1e-10, w * B, 2 * math.pi / w)
    assert orbit.converged and orbit.events_per_period == 0
    assert abs(orbit.q0[0] - A) <= 1e-9 * OSC_GAP.d and abs(orbit.v0[0] - w * B) <= 1e-9 * OSC_GAP.d * w
    # no impact: the multipliers are exp(lambda T) of the free oscillator (the monodromy is one-sided: no event)
    lam = np.linalg.eigvals(OSC_GAP.L)
    assert multiplier_error(orbit.multipliers, np.exp(lam * 2 * math.pi / w)) <= 1e-7
    graze = [g for g in orbit.grazing if g["contact"] == 0]
    assert len(graze) == 1, orbit.grazing
    # the gap's minimum located (not sampled): d - amplitude to the states' accuracy 1e-9 d; at the time of the
    # harmonic maximum x_p = R cos(w t - psi), t = psi / w (mod T), which a gap error 2e-10 m fixes only to
    # sqrt(2 * 2e-10 / (w^2 R)) = 2e-5 s: 1e-4 s
    assert graze[0]["gap_min"] == pytest.approx(harmonic_gap_min(OSC_GAP, w), abs=1e-9 * OSC_GAP.d)
    T = 2 * math.pi / w
    t_max = math.atan2(B, A) / w % T
    assert abs((graze[0]["t"] - t_max + T / 2) % T - T / 2) <= 1e-4


def test_a_section_on_the_impact_moves_off_it():
    """The section put at the impact's time (the map is not smooth there: the impact falls before or after the
    section with the perturbation): the shooting moves its section to the middle of the flight, where the state
    is the closed form's at that time; the multipliers do not depend on the section."""
    from nsfem.periodic import periodic_orbit

    w = 2.0
    p = period1_branch(OSC, w, -1)
    T = 2 * math.pi / w
    x = orbit_state(OSC, w, [(p.tau, p.u)], T, np.array([p.tau - 1e-9]))[0]
    orbit = periodic_orbit(impact_system(OSC, w), T, [x[0] - 1e-6], [x[1]], t0=p.tau - 1e-9, tol=1e-10)
    assert orbit.converged and orbit.events_per_period == 1
    # moved by about half a period (the flight is the whole period but the impact)
    assert abs(((orbit.t0 - p.tau) % T) - T / 2) <= 1e-3 * T
    ref = orbit_state(OSC, w, [(p.tau, p.u)], T, np.array([orbit.t0]))[0]
    size = abs(p.x0) + abs(p.v0) / w
    assert abs(orbit.q0[0] - ref[0]) + abs(orbit.v0[0] - ref[1]) / w <= 1e-8 * size
    assert multiplier_error(orbit.multipliers, p.multipliers) <= 1e-7


def test_shooting_started_on_the_impact_moves_the_section_and_finds_the_closed_form_multipliers():
    """The start exactly at the stop with the orbit's approach velocity u at t0 = tau (an impact of the start
    itself, no event of the run): the map is one-sided there (a perturbation off the stop meets the impact later,
    one into it penetrates) and the start's impact matrix alone has no time shift. The shooting claimed
    convergence there with multipliers -0.836, 0.748 against the closed form's -0.320 +- 0.631 i, and from u 1 %
    off it did not converge in 30 steps; the section now moves off the impact. Tolerances as above (1e-7)."""
    from nsfem.periodic import flow, periodic_orbit

    w = 2.55
    p = period1_branch(OSC, w, -1)
    for u in (p.u, 1.01 * p.u):
        orbit = periodic_orbit(impact_system(OSC, w), p.period, q0=[OSC.d], v0=[u], t0=p.tau, tol=1e-9)
        assert orbit.converged and orbit.events_per_period == 1
        assert abs((orbit.t0 - p.tau + p.period / 2) % p.period - p.period / 2) > 1e-3 * p.period
        assert multiplier_error(orbit.multipliers, p.multipliers) <= 1e-7
    start = flow(impact_system(OSC, w), p.tau, [OSC.d], [p.u], p.period)
    assert [a["why"] for a in start.approximations] == ["an impact at the start (the map is one-sided there)"]
