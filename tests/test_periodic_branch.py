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
