"""The Jeffcott rub on an elastic ring through the onset of backward whirl (issue 36, goal 2b).

The study: studies/rub_backward_whirl.py.

The closed form (:class:`rub_reference.Jeffcott`: the synchronous full annular rub of a Jeffcott rotor on a massless
ring of radial stiffness k_s, its 4 x 4 rotating-frame linearization and Routh-Hurwitz condition) is checked
against rub_reference's elastic-ring linearization (``elastic_rub``, ``elastic_ring_operators``: written from the
system's matrices, not from the closed form) on the same 2-coordinate rotor, then against the shipped rub's reduced
model (its first mode as the Jeffcott rotor), and the exact flow's orbits on the 64-gon against that reference.
The shipped rub on a 2e6 N/m undamped mount at mu = 0.03 loses stability near 20.7 Hz by a whirl 72 % backward in
space at 82 Hz (below the rotor-on-ring frequency sqrt((k + k_s) / m) / 2 pi = 95.7 Hz: the ring is stiff radially
only).
"""

from __future__ import annotations

import functools
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from rub_reference import QUARTER, Jeffcott, eigenvalues, elastic_ring_operators, elastic_rub, hurwitz, jeffcott_onset

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "studies"))

#: a Jeffcott rotor of the shipped rub's size (its first mode's 5.96 kg, 1.547e5 N/m, the 40 N s/m damper,
#: beta k = 1.55 N s/m internal) on the 2e6 N/m ring 0.1 mm away
ROTOR = dict(m=5.9627, k=1.5468e5, c_e=40.0, c_i=1.5468, unbalance=1e-3, k_s=2e6, clearance=1e-4)


def _as_system(rotor: Jeffcott, omega: float):
    """The Jeffcott rotor as rub_reference's generic rotating-frame system (M, C, Q, f0, D = I)."""
    M = rotor.m * np.eye(2)
    C = (rotor.c_e + rotor.c_i) * np.eye(2) + 2.0 * rotor.m * omega * QUARTER
    Q = (rotor.k - rotor.m * omega ** 2) * np.eye(2) + rotor.c_e * omega * QUARTER
    return M, C, Q, np.array([rotor.unbalance * omega ** 2, 0.0]), np.eye(2)


def _generic_eigenvalues(rotor: Jeffcott, omega: float) -> tuple[np.ndarray, float]:
    """rub_reference's elastic-ring linearization of the 2-coordinate rotor: (eigenvalues, radius)."""
    M, C, Q, f0, D = _as_system(rotor, omega)
    rub = elastic_rub(Q, f0, D, rotor.clearance, rotor.mu, 1.0, rotor.k_s)
    r = float(np.linalg.norm(rub.q))
    K, Cr = elastic_ring_operators(rub, r, rotor.mu, rotor.k_s, 0.0)
    return eigenvalues(M, C + Cr, Q + K), r


@pytest.mark.parametrize("mu", [0.0, 0.02, 0.03, 0.1])
@pytest.mark.parametrize("speed_hz", [17.0, 21.0, 30.0])
def test_closed_form_is_the_elastic_ring_linearization(mu, speed_hz):
    """The closed form's radius, 4 x 4 matrices and characteristic polynomial against rub_reference's generic
    elastic ring on the same rotor: radius (both Brent to 1e-15 of c) to 1e-12; the quartic's roots are the
    generic linearization's eigenvalues (companion roots of a well-separated quartic: 1e-9 of |lambda|); the
    Routh-Hurwitz verdict is the eigenvalues' (away from the onset: |max Re| > 1e-3 1/s)."""
    rotor = Jeffcott(mu=mu, **ROTOR)
    omega = 2 * math.pi * speed_hz
    lam, r = _generic_eigenvalues(rotor, omega)
    assert abs(rotor.radius(omega) / r - 1.0) < 1e-12
    a = rotor.characteristic(omega)
    M, C, K, _, _ = rotor.matrices(omega)
    roots = np.roots(a)
    assert np.abs(np.sort_complex(roots) - np.sort_complex(lam)).max() <= 1e-9 * np.abs(lam).max()
    assert np.abs(np.sort_complex(eigenvalues(M, C, K)) - np.sort_complex(lam)).max() <= 1e-9 * np.abs(lam).max()
    D2, D3 = hurwitz(a)
    assert abs(lam.real.max()) > 1e-3
    assert (lam.real.max() < 0) == (D2 > 0 and D3 > 0 and bool(np.all(a > 0)))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(m=st.floats(1.0, 20.0), k=st.floats(1e4, 1e6), c_e=st.floats(0.0, 200.0), c_i=st.floats(0.0, 20.0),
       k_s=st.floats(1e4, 1e7), mu=st.floats(0.0, 0.5), excess=st.floats(1.05, 4.0))
def test_closed_form_property_random_rotors(m, k, c_e, c_i, k_s, mu, excess):
    """Any Jeffcott rotor on any elastic ring at 20 Hz, the free whirl ``excess`` times the clearance (the unbalance
    chosen so), where the rub lies inside the free whirl: the closed form's radius balances the unbalance (Brent
    to 1e-15: 1e-12 relative),
    its quartic's roots are the eigenvalues of its 4 x 4 matrices and of rub_reference's generic linearization
    (1e-8 of |lambda|: a quartic's roots lose up to half the digits near a double root, measured 1e-12 here), and
    Routh-Hurwitz says stable exactly when every eigenvalue has Re < 0 (checked where |max Re| > 1e-6 |lambda|)."""
    omega = 2 * math.pi * 20.0
    c0 = 1e-4
    free = abs(complex(k - m * omega ** 2, c_e * omega))          # the free whirl m_u e Omega^2 / free
    rotor = Jeffcott(m=m, k=k, c_e=c_e, c_i=c_i, unbalance=excess * c0 * free / omega ** 2, k_s=k_s,
                     clearance=c0, mu=mu)
    r = rotor.radius(omega)
    # rub_reference's generic elastic_rub brackets the radius below the free whirl's (excess c0): above the critical
    # speed the rub may lie beyond it (the ring's push moves the disk out), outside that reference's reach
    assume(r < excess * c0 * (1.0 - 1e-9))
    N = k_s * (r - c0)
    balance = abs(complex(k - m * omega ** 2 + N / r, c_e * omega + mu * N / r)) * r
    assert abs(balance / (rotor.unbalance * omega ** 2) - 1.0) < 1e-12
    lam, r_generic = _generic_eigenvalues(rotor, omega)
    assert abs(r_generic / r - 1.0) < 1e-12
    scale = np.abs(lam).max()
    roots = np.roots(rotor.characteristic(omega))
    M, C, K, _, _ = rotor.matrices(omega)
    for other in (roots, eigenvalues(M, C, K)):
        # pair each eigenvalue with the nearest of the other set (sorting complex numbers can interleave close ones)
        assert max(np.abs(other - x).min() for x in lam) <= 1e-8 * scale
    a = rotor.characteristic(omega)
    assume(abs(lam.real.max()) > 1e-6 * scale)
    D2, D3 = hurwitz(a)
    assert (lam.real.max() < 0) == (bool(np.all(a > 0)) and D2 > 0 and D3 > 0)


def test_onset_is_a_hopf_point_of_a_backward_whirl():
    """mu = 0.03: D3 changes sign at the onset; there the generic linearization has a pair on the imaginary axis at
    w = sqrt(a1 / a3) (Re within 1e-6 of |lambda|: Brent's speed to 1e-10 Hz times the slope, with the roots'
    round-off), stable 0.1 Hz below, unstable 0.1 Hz above; its disk motion is mostly backward in space, at
    w - Omega, near the rotor-on-ring frequency. No onset without friction (mu = 0: the rub stays stable 15.7-40 Hz)
    nor at mu = 0.015; the onset falls with mu (friction drives the whirl)."""
    rotor = Jeffcott(mu=0.03, **ROTOR)
    on = jeffcott_onset(rotor, 15.7, 40.0)
    assert on is not None and 17.0 < on["speed_hz"] < 30.0
    omega = 2 * math.pi * on["speed_hz"]
    lam, _ = _generic_eigenvalues(rotor, omega)
    k = int(np.argmax(lam.real))
    assert abs(lam[k].real) <= 1e-6 * abs(lam[k])
    assert abs(abs(lam[k].imag) - on["w_rotating"]) <= 1e-6 * on["w_rotating"]
    below, _ = _generic_eigenvalues(rotor, omega - 2 * math.pi * 0.1)
    above, _ = _generic_eigenvalues(rotor, omega + 2 * math.pi * 0.1)
    assert below.real.max() < 0.0 < above.real.max()
    assert on["backward_share"] > 0.5
    rotor_on_ring = math.sqrt((ROTOR["k"] + ROTOR["k_s"]) / ROTOR["m"]) / (2 * math.pi)
    assert 0.7 * rotor_on_ring < on["backward_hz"] < rotor_on_ring
    for mu in (0.0, 0.015):   # stable all through 15.7-40 Hz (every Hurwitz condition on a 0.05 Hz grid)
        rotor_ = Jeffcott(mu=mu, **ROTOR)
        for f in np.linspace(15.7, 40.0, 487):
            a = rotor_.characteristic(2 * math.pi * f)
            assert np.all(a > 0) and min(hurwitz(a)) > 0
        assert jeffcott_onset(rotor_, 15.7, 40.0) is None
    assert jeffcott_onset(Jeffcott(mu=0.02, **ROTOR), 15.7, 40.0)["speed_hz"] > on["speed_hz"]


# --- the shipped rub's reduced model and its exact flow --------------------------------------------------------------

@functools.lru_cache(maxsize=None)
def _rubs(mu: float, facets: int = 64):
    from rub_backward_whirl import ElasticRub

    return ElasticRub(2e6, mu, facets), ElasticRub(2e6, mu, facets, "inertial")


def test_closed_form_onset_is_the_reduced_models():
    """The shipped rub's reduced model (13 coordinates, distributed shaft mass, the second mode at 383 Hz, disk
    gyroscopics) on the elastic round ring against its first mode's Jeffcott rotor: onsets at mu = 0.02 and 0.03
    within 1 % (measured 0.37 % and 0.54 %: what the Jeffcott leaves out is the higher modes' share of the disk's
    flexibility and mass, of order (f / f_2)^2 ~ (96 / 383)^2 = 6 % of the ring's coupling, which moves
    the onset by a fraction of that); whirl frequencies in space within 0.5 %, and both mostly backward."""
    from rub_backward_whirl import modal_jeffcott, reduced_onset, rub_start

    for mu in (0.02, 0.03):
        rub_r, _ = _rubs(mu)
        jeff = modal_jeffcott(rub_r)
        assert abs(jeff.m / 5.96 - 1.0) < 0.01 and abs(jeff.c_e - 40.0) < 1e-9   # 5 kg disk + half the shaft's 1.97 kg
        start = rub_start(jeff)
        closed = jeffcott_onset(jeff, start + 1e-3, 40.0)
        reduced = reduced_onset(rub_r, start + 1e-3, 40.0)
        assert abs(reduced["speed_hz"] / closed["speed_hz"] - 1.0) < 0.01
        assert abs(reduced["backward_hz"] / closed["backward_hz"] - 1.0) < 0.005
        assert reduced["backward_share"] > 0.5 and closed["backward_share"] > 0.5


def _orbit_errors(F: int) -> dict:
    """At 18 and 24 Hz (the reduced onset 20.67 Hz between), mu = 0.03, F facets, inertial frame: the orbit's largest
    multiplier against the round ring's exp(lambda T), |log(mu / mu_ref)|, asserting what holds at every F."""
    from rub_backward_whirl import exact_orbit

    rub_r, rub_i = _rubs(0.03, F)
    errors, verdicts = {}, []
    for f in (18.0, 24.0):
        orbit, ref = exact_orbit(rub_r, rub_i, f)
        assert orbit.converged and orbit.events_per_period == 2 * F and not orbit.approximations
        k = int(np.argmax(np.abs(orbit.multipliers)))
        mu_ref = np.exp(ref["lam"] / f)
        # the pair's member nearest the reference's (its conjugate has the other sign of argument)
        m = orbit.multipliers[np.argmin(np.abs(orbit.multipliers - mu_ref))]
        assert abs(abs(m) - abs(orbit.multipliers[k])) < 1e-12 and abs(m.imag) > 1e-3
        errors[f] = abs(np.log(m / mu_ref))
        assert errors[f] <= (math.pi / F) ** 2 * abs(ref["lam"]) / f
        verdicts.append(orbit.stable)
    assert verdicts == [True, False]
    return errors


def test_exact_orbits_cross_the_unit_circle_where_the_round_ring_does():
    """64-gon elastic ring (2 F law changes a period, no impacts): the orbit is stable at 18 Hz and unstable at 24 Hz
    by a complex pair, and its largest multiplier is the round ring's exp(lambda T) within the polygon's error. The
    polygon changes the ring's stiffness by a relative (pi / F)^2 / 2 (a facet's 1 - cos(pi / F)), so the eigenvalue
    by at most (pi / F)^2 |lambda| and the multiplier's log by (pi / F)^2 |lambda| T (mostly its argument,
    w T = 36 rad here): bound 0.085 and 0.066, measured 0.0108 and 0.0062 (the modulus: 2.4e-5 and 1.0e-5)."""
    _orbit_errors(64)


@pytest.mark.slow
def test_exact_orbits_converge_at_second_order():
    """64, 128, 256 facets: the multipliers' log errors at 18 Hz 0.0108, 0.0027, 0.00068 (ratio 0.25 per doubling:
    second order); each at most 0.35 of the previous."""
    e = [_orbit_errors(F) for F in (64, 128, 256)]
    for f in (18.0, 24.0):
        assert e[1][f] <= 0.35 * e[0][f] and e[2][f] <= 0.35 * e[1][f]


@pytest.mark.slow
def test_branch_locates_the_neimark_sacker_point_at_the_round_rings_onset():
    """The exact flow's orbit branch over 20.5-20.8 Hz (64-gon, inertial frame, mu = 0.03) locates one Neimark-Sacker
    point. There a complex pair lies on the unit circle (what the located point must satisfy: |mu| = 1 within 1e-5,
    a location to 1e-3 Hz, as |mu| changes by 8e-3 per Hz there). It is the reduced round ring's onset (20.6686 Hz)
    within 0.01 Hz: the multipliers' modulus error at 64 facets is 2.4e-5 in log (a rate error 5e-4 1/s, against
    the rate's slope of 0.167 1/s per Hz: 3e-3 Hz); measured 1.8e-3 Hz."""
    from nsfem.periodic import periodic_orbit
    from nsfem.periodic.branch import orbit_branch
    from rub_backward_whirl import inertial_section, reduced_onset, reduced_reference

    rub_r, rub_i = _rubs(0.03)
    t0, q, v = inertial_section(rub_i, reduced_reference(rub_r, 20.5))
    br = orbit_branch(rub_i.system, lambda f: 1.0 / f, q, v, 20.5, 20.8, key="rotation.speed_hz", t0=t0,
                      max_steps=12, switch=False)
    ns = [b for b in br.bifurcations if b["kind"] == "neimark-sacker"]
    assert len(ns) == 1
    f = ns[0]["value"]
    onset = reduced_onset(rub_r, 20.0, 21.5)["speed_hz"]
    assert abs(f - onset) <= 0.01
    t0, q, v = inertial_section(rub_i, reduced_reference(rub_r, f))
    orbit = periodic_orbit(rub_i.system(f), 1.0 / f, q, v, t0=t0)
    top = orbit.multipliers[np.argsort(-np.abs(orbit.multipliers))[:2]]
    assert np.abs(np.abs(top) - 1.0).max() <= 1e-5 and abs(top[0].imag) > 0.1


@pytest.mark.slow
def test_transient_past_the_onset_whirls_backward_at_the_linear_rate():
    """24 Hz (past the 20.67 Hz onset), 64-gon, 60 periods from the orbit moved by 1e-3 of its size along the unstable
    eigenvector: the disk's deviation grows at the orbit's ln|mu| / T (within 1 %: the per-period maxima of two
    whirl components, 75 % backward and 25 % forward, ripple the fitted line; measured 0.04 %), and its spectrum
    peaks at the round ring's backward whirl, -(w - Omega) = -81.05 Hz, within the FFT's resolution (0.4 Hz;
    measured -81.20 Hz): negative, a backward whirl in space."""
    from rub_backward_whirl import transient

    out = transient(2e6, 0.03, 64, 24.0, 60, lambda s: None, kick=1e-3)
    assert out["stop"] is None and out["linear_periods"] == 60
    assert abs(out["transient_rate_per_s"] / out["orbit_rate_per_s"] - 1.0) < 0.01
    assert out["whirl_hz"] < 0.0
    assert abs(out["whirl_hz"] - out["reference_backward_hz"]) <= out["resolution_hz"]


# --- issue 36: review A (whirl direction in the study's figure) ---
@pytest.mark.parametrize("whirl_hz,word", [(-81.0, "backward"), (+81.0, "forward")])
def test_figure_names_the_transients_whirl_by_its_sign(whirl_hz, word, monkeypatch, tmp_path):
    """The figure's legend calls a transient's whirl backward or forward by the sign of its spectrum's peak
    (negative: against the spin), not backward whatever it is."""
    import rub_backward_whirl

    figs = []
    monkeypatch.setattr(rub_backward_whirl, "save_figure", lambda fig, path: figs.append(fig))
    curve = [{"mu": 0.03, "rub_start_hz": 15.67, "closed_hz": 20.78}]
    rates = [{"facets": 64, "speed_hz": 20.0, "reference_rate_per_s": -0.1, "rate_per_s": -0.1}]
    run = {"speed_hz": 24.0, "transient_rate_per_s": 0.54, "whirl_hz": whirl_hz}
    rub_backward_whirl.figure(curve, [], rates, [], [run], 0.03, tmp_path / "f.png")
    texts = [t.get_text() for ax in figs[0].axes if ax.get_legend() for t in ax.get_legend().get_texts()]
    label = next(t for t in texts if t.startswith("transient"))
    assert f"({word})" in label and f"({'forward' if word == 'backward' else 'backward'})" not in label
