"""Branches of periodic orbits (issue 36, item 2) against the impact oscillator's closed form
(tests/impact_oscillator.py: period-1 and period-2 orbits, their multipliers and the period-doubling frequency).

The continuation runs on the exact flow: J_u = monodromy - I (exact), J_p by central differences in the forcing
frequency; it locates the period doubling by bisection on the multipliers (to 1e-6 of the range, the default
locate_tol, plus the corrector's error) and switches onto the doubled branch there.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from impact_oscillator import orbit_state, period1_branch, period2_orbit, period_doubling_frequency
from nsfem.errors import NsfemError
from nsfem.periodic import orbit_branch
from test_periodic_impact import OSC, impact_system


def _system(w):
    return impact_system(OSC, w)


def _period(w):
    return 2 * math.pi / w


@pytest.fixture(scope="module")
def branch():
    p = period1_branch(OSC, 2.55, -1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return orbit_branch(_system, _period, [p.x0], [p.v0], 2.55, 2.75, key="w", step=0.02, depth=1)


def test_branch_is_the_closed_form_period1_orbit_and_its_period_doubling_is_located(branch):
    w_pd = period_doubling_frequency(OSC, 2.5, 2.75)
    assert branch.stop == "end" and branch.points[-1]["value"] == pytest.approx(2.75, abs=1e-12)
    for pt in branch.points:
        ref = period1_branch(OSC, pt["value"], -1)
        # each point corrected to tol 1e-9 of the orbit's size: the state to 1e-8 of it (Newton's error times
        # the condition of J ~ 1 / (1 - |mu|) <= 10 here, away from the located point)
        size = abs(ref.x0) + abs(ref.v0) / pt["value"]
        assert abs(pt["q0"][0] - ref.x0) + abs(pt["v0"][0] - ref.v0) / pt["value"] <= 1e-8 * size
        mu = np.array([complex(*m) for m in pt["multipliers"]])
        assert np.abs(np.sort_complex(mu) - np.sort_complex(ref.multipliers)).max() <= 1e-7
        assert pt["stable"] == (pt["value"] < w_pd)
    kinds = [(b["kind"], b["value"]) for b in branch.bifurcations]
    assert len(kinds) == 1 and kinds[0][0] == "period-doubling"
    # located to the bisection's 1e-6 of the range (0.2) plus the corrector's error: 1e-6 absolute
    assert abs(kinds[0][1] - w_pd) <= 1e-6


def test_doubled_branch_is_the_closed_form_period2_orbit(branch):
    assert len(branch.doubled) == 1
    doubled = branch.doubled[0]
    assert doubled.multiple == 2 and len(doubled.points) >= 3
    for pt in doubled.points:
        w = pt["value"]
        p2 = period2_orbit(OSC, w)
        T = 2 * math.pi / w
        # the section state of a period-2 orbit is either of its two states T apart
        halves = orbit_state(OSC, w, list(zip(p2.tau, p2.u)), 2 * T, np.array([0.0, T]))
        size = abs(p2.x0) + abs(p2.v0) / w
        err = min(abs(pt["q0"][0] - s[0]) + abs(pt["v0"][0] - s[1]) / w for s in halves)
        assert err <= 1e-8 * size
        mu = np.array([complex(*m) for m in pt["multipliers"]])
        assert np.abs(np.sort(np.abs(mu)) - np.sort(np.abs(p2.multipliers))).max() <= 1e-7
    # just past the doubling the period-2 orbit is stable (a supercritical flip)
    assert doubled.points[0]["stable"]


def test_branch_refuses_an_empty_range_and_a_start_that_is_no_orbit():
    with pytest.raises(NsfemError, match="range"):
        orbit_branch(_system, _period, [0.0], [0.0], 2.5, 2.5)
    with pytest.raises(NsfemError, match="range"):
        orbit_branch(_system, _period, [0.0], [0.0], 2.5, float("nan"))
    # a period that is not the forcing's (the frequency w in Hz taken for rad/s) and a fractional multiple
    with pytest.raises(NsfemError, match="not a multiple of the forcing period"):
        orbit_branch(_system, lambda w: 1.0 / w, [0.0], [0.0], 2.5, 2.6)
    with pytest.raises(NsfemError, match="multiple must be an integer"):
        orbit_branch(_system, _period, [0.0], [0.0], 2.5, 2.6, multiple=1.5)


def _resting_block(w):
    """A block held on a frictionless floor by its load (the contact closed all period), forced along it."""
    from nsfem.contact.set import ContactSet
    from nsfem.integrate.problem import ContactSystem

    cs = ContactSet.from_arrays([[0.0], [1.0]], [0.0], eps=0.0)
    return ContactSystem.from_arrays(M=np.eye(2), Q=np.array([[4.0, 0.3], [0.3, 50.0]]), C=0.05 * np.eye(2),
                                     f0=[0.0, -5.0], fc=[0.5, 0.0], omega=w, contacts=cs)


def test_branch_of_an_orbit_with_a_contact_closed_at_the_section_is_the_constrained_harmonic_solution():
    """The contact stays closed over the period (normal force 5 + 0.3 x > 0): the orbit is the harmonic solution
    of the x equation alone, X = 0.5 / (4 - w^2 + 0.05 i w), its multipliers exp(lambda T) of x'' + 0.05 x' + 4 x.
    The continuation runs Newton on all of (q, q'): the held gap's row of J_u must not be zero (it was: the
    phase transition kept a closed gap's perturbation, so the corrector's system was singular and the branch
    stopped at its first step)."""
    x = 0.5 / (4.0 - 1.5 ** 2 + 0.05j * 1.5)
    br = orbit_branch(_resting_block, _period, [x.real, 0.0], [(1.5j * x).real, 0.0], 1.5, 1.8, key="w", step=0.05)
    assert br.stop == "end" and len(br.points) >= 4
    lam = np.roots([1.0, 0.05, 4.0])
    for pt in br.points:
        w = pt["value"]
        X = 0.5 / (4.0 - w * w + 0.05j * w)
        # corrected to tol 1e-9 of the orbit's size; the state within that times cond(J_u) ~ 1 / (1 - |mu|) < 15
        # (|mu| = exp(-0.025 T) >= 0.90): 1e-8 of |X|
        assert abs(pt["q0"][0] - X.real) <= 1e-8 * abs(X) and abs(pt["q0"][1]) <= 1e-12
        assert abs(pt["v0"][0] - (1j * w * X).real) <= 1e-8 * w * abs(X) and abs(pt["v0"][1]) <= 1e-12
        mu = np.array([complex(*m) for m in pt["multipliers"]])
        # the closed form's exponentials to round-off (|lambda T| ~ 8): 1e-12
        assert np.abs(np.sort_complex(mu) - np.sort_complex(np.exp(lam * 2 * np.pi / w))).max() <= 1e-12


def test_shipped_rub_continued_in_speed_in_the_rotating_frame_stays_a_stationary_full_annular_rub():
    """The shipped rub in the rotating frame: the full annular rub is a stationary state, one facet closed and
    sliding the whole period. Continued from 22.4 to 23 Hz (step 0.2 Hz, 8 steps allowed: 3 suffice), every point is
    a fixed point of the exact flow with zero velocity (stationary: q' = 0 to the corrector's tol 1e-9 of the
    orbit's velocity scale w |q| times cond(J_u) ~ 1 / (1 - |mu|) = 4, |mu| <= 0.75: 1e-8) and stable. Before the
    closed gap's row of Phi_T - I was made regular the corrector's system was singular there and the steps shrank
    to 1e-3 Hz (stopped at 22.417 Hz)."""
    from nsfem.integrate.problem import ContactSystem
    from nsfem.periodic import flow, periodic_orbit
    from nsfem.scene.load import load_scene

    def system_at(p):
        return ContactSystem.from_scene(load_scene("rub", [f"rotation.speed_hz={p}"]))

    s = system_at(22.4)
    T = 1 / 22.4
    start = flow(s, 0.0, None, None, 40 * T, jacobian=False)
    orbit = periodic_orbit(s, T, start.q, start.v)
    assert orbit.converged
    br = orbit_branch(system_at, lambda p: 1.0 / p, orbit.q0, orbit.v0, 22.4, 23.0, key="speed_hz", step=0.2,
                      max_steps=8)
    assert br.stop == "end", br.reason
    for pt in br.points:
        size = np.abs(pt["q0"]).max()
        assert np.abs(pt["v0"]).max() <= 1e-8 * 2 * np.pi * pt["value"] * size
        assert pt["stable"] and pt["converged"]


def test_branch_started_with_its_section_on_the_impact_runs_at_the_section_the_shooting_moved_to():
    """The start's section 1e-6 T before the impact: periodic_orbit moves the section off the event (to the middle
    of the impact-free stretch) and returns the orbit there. The branch must go on at that section (it went on at
    the given one with the moved section's state: the first flow started 0.67 m inside the stop, and the branch
    failed at its start); every point is then the closed-form orbit at the branch's t0, to 1e-8 of its size
    (Newton's tol 1e-9 times cond(J) <= 10)."""
    w0 = 2.55
    p = period1_branch(OSC, w0, -1)
    T = 2 * math.pi / w0
    t_near = p.tau - 1e-6 * T
    (x, u), = orbit_state(OSC, w0, [(p.tau, p.u)], T, np.array([t_near]))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        br = orbit_branch(_system, _period, [x], [u], w0, 2.6, key="w", step=0.02, t0=t_near, switch=False)
    assert br.stop == "end", br.reason
    assert abs((br.t0 - t_near) % T) > 0.1 * T    # moved off the impact
    for pt in br.points:
        w = pt["value"]
        ref = period1_branch(OSC, w, -1)
        (xr, vr), = orbit_state(OSC, w, [(ref.tau, ref.u)], 2 * math.pi / w, np.array([br.t0]))
        size = abs(xr) + abs(vr) / w
        assert abs(pt["q0"][0] - xr) + abs(pt["v0"][0] - vr) / w <= 1e-8 * size


# --- issue 36: the section moves when an event drifts onto it ---

def _drifting_branch(w_end=2.1):
    """The period-1 orbit from w = 1.95 with its section at t0 = 0.9 s: its impact (closed form: at 0.72 s at
    w 1.95, 0.90 s at 2.038, 1.03 s at 2.1) drifts onto that section inside the range, where a branch with one
    section used to stop ("the initial state penetrates ...", measured at 2.0381 from 1.8)."""
    p = period1_branch(OSC, 1.95, -1)
    s = orbit_state(OSC, 1.95, [(p.tau, p.u)], p.period, np.array([0.9]))[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return orbit_branch(_system, _period, [s[0]], [s[1]], 1.95, w_end, key="w", t0=0.9, step=0.01, switch=False)


def _check_points_at_their_sections(br):
    for pt in br.points:
        w = pt["value"]
        ref = period1_branch(OSC, w, -1)
        # each point's state at its own section t0_s is the closed-form orbit's there (tolerance as in
        # test_branch_is_the_closed_form_period1_orbit...: 1e-9 corrected, times J's condition <= 10)
        x = orbit_state(OSC, w, [(ref.tau, ref.u)], ref.period, np.array([pt["t0_s"] % ref.period]))[0]
        size = abs(x[0]) + abs(x[1]) / w
        assert abs(pt["q0"][0] - x[0]) + abs(pt["v0"][0] - x[1]) / w <= 1e-8 * size
        # the multipliers do not depend on the section (the period maps at two sections are conjugate)
        mu = np.array([complex(*m) for m in pt["multipliers"]])
        assert np.abs(np.sort_complex(mu) - np.sort_complex(ref.multipliers)).max() <= 1e-7


def test_branch_moves_its_section_off_a_drifting_impact_and_goes_through():
    br = _drifting_branch()
    assert br.stop == "end" and br.points[-1]["value"] == pytest.approx(2.1, abs=1e-12)
    assert br.reanchors and not any(r["forced"] for r in br.reanchors)
    assert br.t0 == 0.9 and br.points[0]["t0_s"] == 0.9
    assert len({pt["t0_s"] for pt in br.points}) == len(br.reanchors) + 1
    _check_points_at_their_sections(br)
    for r in br.reanchors:
        # the moved point's multipliers at the old and the new section: the same spectrum (conjugate maps), to the
        # eigenvalues' round-off times the monodromy's size (~10) and the correction's 1e-9
        before, after = (np.sort_complex([complex(*m) for m in r[k]]) for k in ("multipliers_before",
                                                                               "multipliers_after"))
        assert np.abs(before - after).max() <= 1e-7
        # the new section lies in the middle of the impact-free period: half a period from the impact
        ref = period1_branch(OSC, r["value"], -1)
        assert abs((r["t0_s"] - ref.tau) % ref.period - 0.5 * ref.period) <= 1e-6 * ref.period
    assert br.summary()["reanchors"] == br.reanchors and "t0_s" in br.summary()["branch"][-1]


def test_a_step_that_fails_at_the_section_moves_it(monkeypatch):
    import nsfem.periodic.branch as branch_module

    monkeypatch.setattr(branch_module, "RECENTER", 0.0)   # no move ahead of time: only when a step fails
    br = _drifting_branch()
    assert br.stop == "end"
    assert [r["forced"] for r in br.reanchors] == [True]
    # the impact reaches t0 = 0.9 s at w = 2.0381 (closed form): the step from the last point before it failed
    assert 2.0 < br.reanchors[0]["value"] < period_crossing(0.9)
    _check_points_at_their_sections(br)


def period_crossing(t0):
    """The w in (1.95, 2.1) where the impact time tau(w) (closed form) reaches t0."""
    from scipy.optimize import brentq

    return brentq(lambda w: period1_branch(OSC, w, -1).tau - t0, 1.95, 2.1, xtol=1e-12)


@pytest.mark.slow
def test_the_rub_branch_runs_through_the_corners_drifting_onto_its_section():
    """The shipped rub at mu 0.55 on 64 facets, inertial frame, from the round ring's state at a facet's middle at
    26 Hz: with one section the branch stopped at 26.9926 Hz (a corner passage reached it: "the initial state
    penetrates stator.0.58"); now it runs to 27.1 Hz, moving its section ahead of the corners (measured: twice). The
    Neimark-Sacker point lies between 26.5 Hz (stable) and 27.0 Hz (unstable; tests/test_rub_whirl.py), the
    located point has |mu| = 1 to its bracket's accuracy (|d|mu|/df| ~ 5e-3 per Hz times 1e-6 of the range, plus
    the multipliers' own ~1e-9), and the multipliers at a moved point are the same at both sections (conjugate
    period maps: round-off of the eigenvalues, ~1e-12 measured, 1e-7 allowed as in the oscillator's test)."""
    from rub_reference import ring_rows, round_rub
    from nsfem import load_scene
    from nsfem.fem.assemble import build_model
    from nsfem.fem.components import lateral_turn
    from nsfem.integrate import ContactSystem
    from nsfem.periodic.flow import flow
    from nsfem.reduce import scene_reduction
    import scipy.linalg as sla

    scene = load_scene("rub", ["stator.0.friction=0.55", "stator.0.facets=64", "rotation.frame=inertial"])
    rotating = load_scene("rub", ["stator.0.friction=0.55", "stator.0.facets=64"])
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    T = np.asarray(red.T)
    J = np.linalg.lstsq(T, lateral_turn(model.spaces, T.shape[0]) @ T, rcond=None)[0]
    R = ContactSystem.from_scene(rotating, model, red, speed_hz=26.0)
    D, c, _ = ring_rows(R.contacts.JN, R.contacts.jN)
    rub = round_rub(R.Q, R.f0, D, c, 0.55, 1.0)
    w = R.omega
    t0 = ((-math.atan2(rub.n[1], rub.n[0])) % (2.0 * math.pi / 64)) / w
    q = sla.expm(w * t0 * J) @ rub.q

    def system_at(f):
        return ContactSystem.from_scene(scene, model, red, speed_hz=f)

    br = orbit_branch(system_at, lambda f: 1.0 / f, q, w * J @ q, 26.0, 27.1, key="f", t0=t0, switch=False)
    assert br.stop == "end" and br.points[-1]["value"] == pytest.approx(27.1, abs=1e-12)
    assert br.reanchors and not any(r["forced"] for r in br.reanchors)
    for r in br.reanchors:
        before, after = (np.sort_complex([complex(*m) for m in r[k]]) for k in ("multipliers_before",
                                                                               "multipliers_after"))
        assert np.abs(before - after).max() <= 1e-7
    (ns,) = [b for b in br.bifurcations]
    assert ns["kind"] == "neimark-sacker" and 26.5 < ns["value"] < 27.0
    for pt in br.points:
        assert pt["stable"] == (pt["value"] < ns["value"])
    # the points next to the last move are orbits at their own sections: one period back to the state (the
    # corrector's 1e-9 of the size times J's condition, ~1 / (1 - |mu|) <= 1e3 near the onset: 1e-6)
    k = br.reanchors[-1]["index"]
    for pt in br.points[k:k + 2]:
        fl = flow(system_at(pt["value"]), pt["t0_s"], pt["q0"], pt["v0"], pt["period_s"], jacobian=False)
        assert np.abs(fl.q - pt["q0"]).max() <= 1e-6 * np.abs(pt["q0"]).max()
    assert br.points[k]["t0_s"] != br.points[k + 1]["t0_s"]


def test_the_period_doubling_is_located_and_switched_on_after_the_section_moved():
    # the section starts 0.2 T after the impact at w 2.55 (within a quarter period of it): it moves at the start,
    # before the first step; the period doubling is then located in the moved coordinates as on the fixed section (1e-6, as in
    # test_branch_is_the_closed_form_period1_orbit...) and the doubled branch starts at the bifurcation's own
    # section (its points: period-2 orbits with the closed form's multipliers)
    p = period1_branch(OSC, 2.55, -1)
    t0 = p.tau + 0.2 * p.period
    s = orbit_state(OSC, 2.55, [(p.tau, p.u)], p.period, np.array([t0]))[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        br = orbit_branch(_system, _period, [s[0]], [s[1]], 2.55, 2.75, key="w", t0=t0, step=0.02, depth=1)
    assert br.stop == "end" and br.reanchors and br.reanchors[0]["index"] == 0 and not br.reanchors[0]["forced"]
    w_pd = period_doubling_frequency(OSC, 2.5, 2.75)
    (pd,) = br.bifurcations
    assert pd["kind"] == "period-doubling" and abs(pd["value"] - w_pd) <= 1e-6
    assert pd["t0_s"] == br.reanchors[-1]["t0_s"] or pd["index"] < br.reanchors[-1]["index"]
    (doubled,) = br.doubled
    assert len(doubled.points) >= 3
    for pt in doubled.points:
        mu = np.array([complex(*m) for m in pt["multipliers"]])
        ref = period2_orbit(OSC, pt["value"])
        # the corrector's 1e-9 of the orbit's size, amplified by J's condition 1 / |1 - |mu|| (160 just past the
        # doubling, where the period-2 orbit's multiplier is near 1), times 10 for the multipliers' sensitivity
        bound = 10 * 1e-9 / np.abs(1.0 - np.abs(ref.multipliers)).min()
        assert np.abs(np.sort(np.abs(mu)) - np.sort(np.abs(ref.multipliers))).max() <= bound


# --- issue 36: review (the tangent carried into a moved section) ---

@pytest.mark.parametrize("t0", [0.9, 0.87])    # the impact (0.887 s at w 2.03) 0.013 s before / 0.017 s after
def test_a_moved_sections_state_changes_with_w_as_the_closed_form_orbit_there(t0):
    """The section's move maps the branch's tangent into the new coordinates: du'/dw = M du/dw + du'/dw|_u (the
    state at the new section depends on w at a fixed old state too: the flow over the shift is w's). Both against
    the closed form: the orbit's state at the new section t0_s, differenced in w. M du/dw alone misses the second
    term (here by 7 % of the tangent), which could orient the new tangent against the branch. With the section just
    before the impact the new one lies more than half a period on and is taken a period earlier (t0_s = t0 + shift -
    T): at w' the state there is the flow's over shift - T + T(w'), T's change with w included."""
    from nsfem.periodic.branch import DP, _Problem

    w, span = 2.03, 0.15    # the impact within 0.017 s of the section: the move is due
    p = period1_branch(OSC, w, -1)
    u = orbit_state(OSC, w, [(p.tau, p.u)], p.period, np.array([t0]))[0]
    problem = _Problem(_system, _period, t0, DP * span, 1)
    problem.weights = np.ones(2)
    _, ju, jp = problem.residual(u, w)
    dudw = -np.linalg.solve(ju, jp)               # along the branch at the old section: J_u du + J_p dw = 0
    u_new, M, dudp = problem.reanchor(u, w, False)
    t1 = problem.t0
    h = 1e-5

    def at_t1(wi):
        ref = period1_branch(OSC, wi, -1)
        return orbit_state(OSC, wi, [(ref.tau, ref.u)], ref.period, np.array([t1]))[0]

    exact = (at_t1(w + h) - at_t1(w - h)) / (2 * h)
    scale = np.array([1.0, 1.0 / w])              # (x, x'/w): one size for both
    size = np.abs(scale * exact).max()
    # central differences: the closed form's truncation h^2 |u'''| ~ 1e-10 relative; the flow's dp = 1.5e-7 with
    # event times located to ~1e-13 s gives ~1e-6 relative; J_u's solve ~1e-9 (cond <= 10, Newton-level tol): 1e-4
    assert np.abs(scale * (M @ dudw + dudp - exact)).max() <= 1e-4 * size
    assert np.abs(scale * (M @ dudw - exact)).max() > 0.03 * size
    assert (t1 < t0) == (t0 == 0.87)


# --- issue 36: continuation across grazing points ---

def _grazing_branch(w_start, w_end):
    """The period-1 orbit of the impact oscillator with its stop at d = 0.2 (OSC_GAP), continued over w through the
    grazing frequency w_g = 2.448265 (closed form: the harmonic orbit's amplitude is d there): below it the orbit
    impacts once a period (approach speed u ~ w_g - w, its multiplier ~ -1/u: Nordmark), above it it is the harmonic
    orbit without impact. Without crossing the branch stopped 7e-4 short of w_g from below and 2.4e-5 from above
    (steps down to min_step: measured)."""
    from impact_oscillator import grazing_frequencies, harmonic_coefficients
    from test_periodic_impact import OSC_GAP

    if w_start < grazing_frequencies(OSC_GAP)[0]:
        p = period1_branch(OSC_GAP, w_start, -1)
        q0, v0 = [p.x0], [p.v0]
    else:
        A, B = harmonic_coefficients(OSC_GAP, w_start)
        q0, v0 = [A], [w_start * B]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return orbit_branch(lambda w: impact_system(OSC_GAP, w), _period, q0, v0, w_start, w_end, key="w", step=0.02,
                            max_steps=80, switch=False)


def _check_grazing_branch(br, events):
    from impact_oscillator import grazing_frequencies, harmonic_coefficients
    from test_periodic_impact import OSC_GAP

    (w_g,) = grazing_frequencies(OSC_GAP)
    assert br.stop == "end", br.reason
    (graze,) = [b for b in br.bifurcations if b["kind"] == "grazing"]
    assert graze["events_per_period"] == events
    # the grazing frequency: the margin (the free orbit's smallest gap over its range, or the impact's approach
    # speed) is smooth on the side it is located from, where the secant converges; the kept point lies within its
    # accuracy (<= 1e-9 of the range 0.3, GRAZE_LOCATE locate_tol) of the zero of the margin as computed, whose
    # error is the corrector's (tol 1e-9 of the orbit's size: its margin to ~1e-9, over dmargin/dw ~ 1): 1e-9 more
    assert graze["accuracy"] <= 3e-10
    assert abs(graze["value"] - w_g) <= graze["accuracy"] + 1e-9
    # every point is the closed form's orbit of its side (tolerances as in
    # test_branch_is_the_closed_form_period1_orbit...: 1e-9 corrected, times J's condition; near grazing the
    # impacting orbit's J ~ 1/u: 1e-6 of its size there) and its verdict is its side's own
    impacting = free = 0
    for pt in br.points:
        w = pt["value"]
        if abs(w - w_g) <= 2e-9:
            continue                                    # (the grazing orbit: both sides' limit)
        size = 0.2 + 0.2 * w
        if w < w_g:
            ref = period1_branch(OSC_GAP, w, -1)
            x, v = ref.x0, ref.v0
            impacting += 1
            assert not pt["stable"]                       # Nordmark's -1/u (and |mu| > 2.9 from w = 2.3 on)
        else:
            A, B = harmonic_coefficients(OSC_GAP, w)
            x, v = A, w * B
            free += 1
            assert pt["stable"]                           # the damped free oscillator's exp(lambda T)
        assert abs(pt["q0"][0] - x) + abs(pt["v0"][0] - v) / w <= 1e-6 * size
    assert impacting >= 3 and free >= 3 and len(br.points) <= 45
    return graze


def test_branch_crosses_grazing_from_the_impacting_side():
    br = _grazing_branch(2.3, 2.6)
    graze = _check_grazing_branch(br, [1, 0])
    # the steps are back to the size they had before the grazing (they restart at the last full step, halving only
    # where the corrector fails): no creep on either side
    values = [p["value"] for p in br.points]
    i = graze["index"] + 1
    assert np.diff(values[i + 1:]).max() >= 0.9 * np.diff(values[:i]).max()


def test_branch_crosses_grazing_from_the_free_side():
    _check_grazing_branch(_grazing_branch(2.6, 2.3), [0, 1])


@pytest.mark.slow
def test_the_crack_branch_passes_its_changes_of_events_without_locating_them():
    """The shipped crack over 12.400-12.402 Hz (measured: its events per period change 5 -> 6 -> 5 -> 4 there, its
    closings at rest, approach speeds 1e-19..1e-16 relative, are not counted as grazing): the branch reaches its end,
    every point an orbit (the corrector's residual <= tol 1e-9), the changes passed by steps and not listed as
    located grazings (a failed step would have located one)."""
    from nsfem.periodic.scene_branch import branch_of_scene
    from nsfem.scene import load_scene

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sb = branch_of_scene(load_scene("crack"), "rotation.speed_hz", 12.4, 12.402, steps=60)
    assert sb.stop == "end", sb.reason
    assert all(p["converged"] and p["residual"] <= 1e-9 for p in sb.points)
    assert len({p["events_per_period"] for p in sb.points}) >= 2
    assert not [b for b in sb.bifurcations if b["kind"] == "grazing"]


@pytest.mark.parametrize("name, value", [("switch", "no"), ("grazing", 1), ("grazing", None), ("switch", 0.0)])
def test_orbit_branch_refuses_a_switch_that_is_not_a_boolean(name, value):
    """review (session 3): any truthy value turned the grazing crossing or the switch onto doubled branches on."""
    from nsfem.errors import NsfemError
    from nsfem.periodic.branch import orbit_branch

    with pytest.raises(NsfemError, match=f"{name} must be True or False"):
        orbit_branch(lambda p: None, lambda p: 1.0, [0.0], [0.0], 1.0, 2.0, **{name: value})
