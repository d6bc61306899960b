"""The delaminated shaft (shipped ``default`` scene) near its gravity resonance: the orbit stays open (issue 36).

In the rotating frame each layer's centrifugal force on its offset from the axis holds the interface open; with
damping the synchronous orbit at 22 Hz never touches, so it is the orbit of a linear system, and Liouville's formula
gives its multipliers' product in closed form: det(monodromy) = exp(-trace(M^-1 C) T) = exp(-alpha n T) for
C = alpha M (the gyroscopic matrix is skew, M^-1 G has zero trace), n the reduced coordinates.
studies/delamination_resonance.py follows it through the resonance (docs/validation.md).
"""

import numpy as np
import pytest

from nsfem.fem.assemble import build_model
from nsfem.integrate.problem import ContactSystem
from nsfem.periodic import periodic_orbit
from nsfem.periodic.flow import FlowMap
from nsfem.reduce import scene_reduction
from nsfem.scene.load import load_scene
from nsfem.simulate import initial_state


def _orbit(alpha: float, speed_hz: float, lead: int = 3):
    scene = load_scene("default", [f"damping.rayleigh=[{alpha},0.0]", f"rotation.speed_hz={speed_hz}"])
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    system = ContactSystem.from_model(model, red, scene.rotation, scene.damping)
    q, v = initial_state(scene, model, red, system)
    T = 1.0 / speed_hz
    phi = FlowMap(system, 0.0, T)
    for _ in range(lead):
        f = phi(q, v, jacobian=False)
        q, v = f.q, f.v
    return system, T, periodic_orbit(system, T, q, v, tol=1e-10)


def test_open_orbit_below_resonance_obeys_liouville():
    alpha = 2.0
    system, T, o = _orbit(alpha, 22.0)
    r = o.result
    assert o.converged and o.events_per_period == 0
    # open all period: no contact force, the smallest gap well above the integrator's event tolerance (its size,
    # 1e-4 m measured by the study, is the centrifugal mean opening minus gravity's oscillation)
    assert r.normal_force.max() == 0.0
    assert r.gap.min() > 1e-6
    n = system.n
    assert o.multipliers.size == 2 * n            # no contact closed: every direction admissible
    log_det = float(np.sum(np.log(np.abs(o.multipliers))))
    # Liouville: exact for the linear open flow; the transition matrix is a matrix exponential (round-off ~1e-13 per
    # entry), the sum of 50 logs then carries ~1e-12 absolute (1e-13 measured); 1e-10 relative of alpha n T (= 2.3) covers it
    assert log_det == pytest.approx(-alpha * n * T, rel=1e-10)
    assert o.stable and np.abs(o.multipliers).max() < 1.0


# --- the touching orbit (stiffness-proportional damping) -------------------------------------------------------------
# With C = beta K, beta = 1e-5 s (modal damping ratio 1.4e-3 at the 22.78 Hz resonance, 1.6e-2 at the
# 500 Hz contact modes the plastic impacts excite), the layers touch over the orbit at 22.78 Hz and the shooting
# converges (studies/delamination_resonance.py --touching; docs/validation.md). The orbit's section state is stored
# (tests/data/delamination_touching_orbit.npz: shot with tol 1e-12 in 5 Newton steps to residual 2.3e-15 from the
# state after 200 revolutions at 22.78 Hz from the open orbit of 22.74 Hz, as the study does; the study saves its
# own as delamination_touching_orbit.npz), so the tests below need no transient.

DATA = __import__("pathlib").Path(__file__).parent / "data" / "delamination_touching_orbit.npz"


def _touching_system():
    d = np.load(DATA)
    speed, beta = float(d["speed_hz"]), float(d["beta"])
    scene = load_scene("default", [f"damping.rayleigh=[0.0,{beta!r}]", f"rotation.speed_hz={speed!r}"])
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    system = ContactSystem.from_model(model, red, scene.rotation, scene.damping)
    return system, 1.0 / speed, float(d["t0"]), d["q0"], d["v0"]


def _signature(events, t0, T, k):
    """The events of period k (from t0 + k T) as (contacts, kinds, impact) and their phases in the period."""
    sel = [e for e in events if t0 + k * T <= e["t"] < t0 + (k + 1) * T]
    return [(tuple(e["contacts"]), tuple(e["kinds"]), e["impact"]) for e in sel], \
        np.array([(e["t"] - t0) / T - k for e in sel])


def _returns(system, T, t0, q0, v0, periods: int, samples: int = 64):
    """A fresh exact integrator (no trace) from the section state (q0, q0') at t0 over ``periods`` periods, sampled
    ``samples`` times a period: (the run, its relative distance from the start after each whole period, in
    (q, q' / w) over the state's size)."""
    from nsfem.integrate.event_driven import Exact
    from nsfem.periodic.flow import shifted

    res = Exact(shifted(system, t0), progress=False).run(periods * T, T / samples, q0, v0)
    size = max(np.abs(q0).max(), np.abs(v0).max() * T / (2 * np.pi))
    errs = []
    for k in range(1, periods + 1):
        i = int(np.argmin(np.abs(res.t - k * T)))
        assert abs(res.t[i] - k * T) < 1e-12 * T
        errs.append(max(np.abs(res.q[:, i] - q0).max(), np.abs(res.v[:, i] - v0).max() * T / (2 * np.pi)) / size)
    return res, errs


def test_touching_orbit_returns_under_an_independent_flow():
    """The stored touching orbit is a periodic orbit of the exact flow: a fresh integrator (no kept configurations,
    no trace) from its section state returns to it after 1, 2 and 3 periods with the same events each period."""

    system, T, t0, q0, v0 = _touching_system()
    res, errs = _returns(system, T, t0, q0, v0, 3)
    for k, err in enumerate(errs, 1):
        # the orbit was shot to 2.3e-15; each period of the exact flow adds round-off of the event times (located to
        # ~1e-13 s by the root search) times the state's rate, ~1e-11 relative over 73 events; the motion is stable
        # (|mu| 0.99) so errors do not grow: 1e-9 is a margin of 100 over that and 1e5 below the smallest
        # perturbation that changes the orbit's event sequence (1e-6 relative, measured by the study)
        assert err < 1e-9, k
    events = [dict(e, t=e["t"] + t0) for e in res.events]
    sig0, ph0 = _signature(events, t0, T, 0)
    # the layers really touch: many closings at several of the 9 contact points, each period
    assert len(sig0) > 20 and len({c for s in sig0 if "close" in s[1] for c in s[0]}) >= 5
    for k in (1, 2):
        sig, ph = _signature(events, t0, T, k)
        assert sig == sig0
        # event times repeat to the state's error over a period (1e-9 relative) divided by the gap rates (>= 1e-3
        # of their range at a transversal closing): 1e-6 of the period
        assert np.abs(ph - ph0).max() < 1e-6


def test_touching_orbit_residual_and_floquet_contraction():
    """Shooting from the stored state converges at once, with a contact force and a stable verdict; a
    perturbation along the leading Floquet direction decays at the leading multiplier's rate under the exact
    transient (the multipliers describe the non-smooth orbit: the map is smooth within its event sequence)."""
    import warnings

    system, T, t0, q0, v0 = _touching_system()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # (the orbit passes 1.7e-8 m from contact 6 without closing: reported)
        o = periodic_orbit(system, T, q0, v0, t0, tol=1e-11, max_iter=3, attempts=1)
    assert o.converged and o.residual < 1e-11
    assert o.events_per_period > 20 and o.result.normal_force.max() > 1.0
    mu = o.multipliers
    assert o.stable and 0.9 < abs(mu[0]) < 1.0
    # the leading multiplier is real and simple: its eigenvector on the admissible directions is real
    w, V = np.linalg.eig(o.monodromy)
    j = int(np.argmax(np.abs(w)))
    assert abs(w[j].imag) < 1e-12 and abs(abs(w[j]) - abs(mu[1])) > 1e-3
    N = 6
    rate, _ = _departure(system, T, o, np.real(V[:, j]), 1e-7, N)
    # along the eigenvector d_N = mu^N dx + O(|dx|^2): the second order is 1e-7 relative (the perturbation stays
    # below the 1e-6 at which the event sequence changes); the orbit's own error (residual < 1e-11 a period, 6
    # periods) is < 6e-4 of |dx| = 1e-7, < 1e-4 a period after the 6th root; 1e-3 covers both and still tells
    # |mu_1| (0.98986) from |mu_2| (0.98334)
    assert rate == pytest.approx(abs(w[j]), abs=1e-3)


# --- an unstable touching orbit (friction 0.3, stiffness damping) ----------------------------------------------------
# With Coulomb friction mu = 0.3 between the layers (delamination.0.friction; beta = 1e-5 s, 22.76 Hz) the touching
# branch of studies/delamination_variants.py ends at its low-speed side in a period-doubling: the orbit at 22.76 Hz
# (9 events a period: the layers touch briefly once a revolution) has a real multiplier -1.2241, while the touching
# orbits from 22.7625 Hz up are stable and the open orbit at 22.7575 Hz is too (docs/validation.md). Its section state
# is stored (tests/data/delamination_unstable_orbit.npz: shot to residual 6e-15 by natural continuation from the
# touching orbit at 22.78 Hz), so the tests below need no transient.

UNSTABLE = DATA.with_name("delamination_unstable_orbit.npz")


def _friction_system(path):
    d = np.load(path)
    speed, beta, mu = float(d["speed_hz"]), float(d["beta"]), float(d["mu"])
    scene = load_scene("default", [f"damping.rayleigh=[0.0,{beta!r}]", f"rotation.speed_hz={speed!r}",
                                   f"delamination.0.friction={mu!r}"])
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    system = ContactSystem.from_model(model, red, scene.rotation, scene.damping)
    return system, 1.0 / speed, float(d["t0"]), d["q0"], d["v0"]


def test_unstable_orbit_returns_under_an_independent_flow():
    """The stored unstable orbit is a periodic orbit of the exact flow: a fresh integrator from its section state
    returns to it after 1 and 2 periods, with the same events each period and contact forces at 22.76 Hz."""

    system, T, t0, q0, v0 = _friction_system(UNSTABLE)
    res, errs = _returns(system, T, t0, q0, v0, 2)
    for k, err in enumerate(errs, 1):
        # shot to 6e-15; a period adds the event times' round-off (~1e-13 s located) times the state's rate, ~1e-12
        # relative over 9 events, and the unstable direction multiplies what is there by 1.22 a period: 1e-9 is a
        # margin of 100 over two periods and far below the 1e-6 at which an event sequence changes
        assert err < 1e-9, k
    events = [dict(e, t=e["t"] + t0) for e in res.events]
    sig0, ph0 = _signature(events, t0, T, 0)
    sig1, ph1 = _signature(events, t0, T, 1)
    assert len(sig0) >= 4 and sig1 == sig0
    assert any("close" in s[1] for s in sig0)                     # the layers touch
    assert np.abs(ph1 - ph0).max() < 1e-6                         # (as in the touching orbit's test above)


def test_unstable_orbit_is_left_at_its_multiplier():
    """The orbit's largest multiplier is real, below -1 (a period-doubling loss); a perturbation along its Floquet
    direction grows at |mu_1| a period under the exact transient and changes sign every period."""
    import warnings

    system, T, t0, q0, v0 = _friction_system(UNSTABLE)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # (open points pass within 0.4-1 um of contact without closing: reported)
        o = periodic_orbit(system, T, q0, v0, t0, tol=1e-13, max_iter=3, attempts=1)
    # (the flow's round-off: ~1e-15 relative a period; 1e-13 is reached at once from the stored state)
    assert o.converged and o.residual < 1e-13 and o.result.normal_force.max() > 0.0
    assert not o.stable and o.loss == "period-doubling"
    w, V = np.linalg.eig(o.monodromy)
    j = int(np.argmax(np.abs(w)))
    mu1 = w[j]
    # the leading multiplier is real (to round-off of the eigen-solver on an 86-dimensional matrix) and simple
    assert abs(mu1.imag) < 1e-10 and mu1.real < -1.0
    assert abs(mu1) - np.sort(np.abs(w))[-2] > 0.1
    _check_multiplier_by_central_differences(system, T, o, 1e-9)
    N = 10
    rate, signs = _departure(system, T, o, np.real(V[:, j]), 1e-9, N)
    # along the eigenvector d_N = mu^N dx + O(|d|^2): after 10 periods |d| ~ 7.5 |dx| = 7.5e-9 of the state, so the
    # second order is ~1e-8 of |d|; the orbit's own error (residual < 1e-13 a period: it was stored at 6e-15) is
    # < 1e-4 of |dx| = 1e-9 of the state per period, and enters the 10th root as < 1e-4 of the rate; 1e-3 covers
    # both (the measured agreement is 1e-5) and tells 1.224 from the next modulus (0.990) by far
    assert rate == pytest.approx(abs(mu1), abs=1e-3)
    assert signs == [(-1.0) ** (k + 1) for k in range(N)]   # a negative multiplier: the side flips every period



def test_unstable_orbit_impacts_are_not_grazing():
    """The unstable orbit is not the open orbit's grazing continued: a touching orbit born at a grazing starts with
    impacts of vanishing approach velocity (and, with plastic impacts, multipliers growing without bound as that
    velocity goes to zero), while this one's impacts arrive at up to a third of the gap's own velocity amplitude
    (omega times half its range over the period: the open motion's scale) and the layers stay closed under
    newtons. (The open orbit grazes 1e-4 Hz below, between 22.7593 and 22.7594 Hz; docs/validation.md.)"""
    from nsfem.integrate.event_driven import Exact
    from nsfem.periodic.flow import shifted

    system, T, t0, q0, v0 = _friction_system(UNSTABLE)
    res = Exact(shifted(system, t0), progress=False).run(T, T / 256, q0, v0)
    w = 2.0 * np.pi / T
    # (each impact's approach velocity per contact against that contact's gap velocity scale)
    ratios = [a / (w * 0.5 * np.ptp(res.gap[c])) for imp in res.impacts
              for c, a in zip(imp["contacts"], imp["approach_m_s"]) if a > 0]
    # a gap a cos(omega t) + mean whose free motion would reach a depth delta below contact arrives at
    # omega sqrt(2 a delta), i.e. sqrt(2 delta / a) of the scale omega a (a ~ 1.07 mm here). Measured: 0.33 at the
    # first impact (0.050 m/s at contact 4 against 0.15 m/s: delta ~ 60 um). An orbit continued from the grazing
    # 1e-4 Hz below would reach a few um at most (the open orbit's smallest gap changes 4.3 um over the 3e-4 Hz
    # before it grazes), sqrt(2 x 5 um / a) ~ 0.1 of the scale: 0.1 is the bound, with a factor 3 to the measured
    assert max(ratios) > 0.1
    assert res.normal_force.max() > 1.0

# --- the estimate of the bend (studies/delamination_variants.py) -----------------------------------------------------

def _variants():
    import importlib
    import sys
    from pathlib import Path

    studies = str(Path(__file__).resolve().parents[1] / "studies")
    if studies not in sys.path:
        sys.path.insert(0, studies)
    return importlib.import_module("delamination_variants")


def test_bend_share_is_the_first_harmonic_of_a_one_sided_spring():
    """bend_share(a) is the first Fourier coefficient of a unit one-sided spring max(x - 1, 0) under x = a cos(phi),
    divided by a: checked against the integral by the trapezoid rule (an independent computation), and its limits
    (0 below the threshold, 1/2 for a -> infinity: the spring then acts half of each period)."""
    V = _variants()
    a = np.array([0.3, 1.0, 1.01, 1.43, 2.0, 6.5, 50.0])
    phi = np.linspace(-np.pi, np.pi, 200001)
    x = a[:, None] * np.cos(phi)
    f = np.maximum(x - 1.0, 0.0) * np.cos(phi)
    quad = np.trapezoid(f, phi, axis=1) / np.pi / a
    # the integrand is continuous with a kink where x = 1: the trapezoid rule's error there is O(h^2) = 1e-9 of the
    # coefficient (h = 3e-5); 1e-8 covers it
    assert np.allclose(V.bend_share(a), quad, rtol=0, atol=1e-8)
    assert V.bend_share(1.0) == 0.0 and V.bend_share(0.5) == 0.0
    assert V.bend_share(1e12) == pytest.approx(0.5, abs=1e-11)   # 1/2 - (2/pi)/a + ...: 6e-13 left at a = 1e12


def test_open_amplitude_is_the_exact_flows_open_orbit():
    """open_amplitude (one harmonic of the linear open system) is the exact flow's orbit where the layers stay
    open: at 22.70 Hz (beta 1e-5 s) the shot orbit has no event and the same midspan amplitude."""
    import sys
    import warnings

    V = _variants()
    dr = sys.modules["delamination_resonance"]
    system, T, q, v = V.build(22.70, 1e-5, 0.0)
    for _ in range(3):
        f = FlowMap(system, 0.0, T)(q, v, jacobian=False)
        q, v = f.q, f.v
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        o = periodic_orbit(system, T, q, v, tol=1e-10)
    assert o.converged and o.events_per_period == 0
    shot = dr.midspan(system, 22.70, np.asarray(o.result.t), o.result.q)
    # both are half the peak-to-peak of samples of a sinusoid (256 and 512 a period), short of its amplitude by
    # at most 1 - cos(pi / 256) = 7.5e-5 relative; 2e-4 covers both and is 100 times below the 2 % the damping
    # term makes here (the shot orbit's own error, 1e-10, is negligible)
    assert shot == pytest.approx(V.open_amplitude(22.70, 1e-5), rel=2e-4)


def test_open_resonance_half_width_is_the_damped_modes():
    """The open resonance's -3 dB half-width in speed is the resonant mode's decay rate sigma over
    2 pi |1 - df_rot/dOmega| (the forcing's detuning from the rotating-frame frequency f_rot changes with the
    speed at 1 - df_rot/dOmega = 2 here): the single-mode law, independent of the harmonic balance."""
    from nsfem.analysis.damped import scene_damped_modes

    V = _variants()
    lin = V.open_resonance(1e-5)
    sp = lin["peak_hz"]
    scene = load_scene("default", ["damping.rayleigh=[0.0,1e-05]", f"rotation.speed_hz={sp!r}"])
    model = build_model(scene)
    modes = scene_damped_modes(scene, model, sp, 2, scene_reduction(scene.reduction, model), "open")
    sigma = -modes.eigenvalues[0].real
    slope = (V.rotating_frequency(sp + 0.02, "open") - V.rotating_frequency(sp - 0.02, "open")) / 0.04
    # the single-mode law holds up to the other modes' background (the nearest 45 Hz away: ~1e-3 relative) and the
    # averaging of the two -3 dB sides (their 3.5 % asymmetry cancels to first order); measured 4e-4, 2e-3 allowed,
    # while the single-mode fit through two flank points that the study used before gave 0.013 Hz (20 % off)
    assert lin["half_width_hz"] == pytest.approx(sigma / (2 * np.pi * abs(1.0 - slope)), rel=2e-3)
    # the peak lies at the open resonance speed (f_rot = speed, 22.7765 Hz) within a fraction of the half-width
    assert abs(sp - 22.7765) < 0.05 * lin["half_width_hz"]


def test_bonded_resonance_is_the_bonded_shafts_model():
    """The closed form the study uses for the stuck layers (half the Euler-Bernoulli pinned-pinned frequency of the
    full section) agrees with the model: the delaminated shaft's y bending (the delamination splits z only) at rest,
    from nsfem's modes, is that frequency; the Hermite elements (40) make its error ~1e-9 relative, the
    Craig-Bampton reduction (16 modes) keeps the first mode to ~1e-9 as well: 1e-6 is a wide margin that still
    catches a factor in the closed form."""
    from nsfem.analysis.modes import natural_frequencies

    V = _variants()
    scene = load_scene("default", [])
    model = build_model(scene)
    f = natural_frequencies(model, "open", 2, scene_reduction(scene.reduction, model)).frequencies_hz
    assert 2.0 * V.bonded_speed() == pytest.approx(f[1], rel=1e-6)


# --- the fold at twice the gravity (studies/delamination_variants.py --fold) -----------------------------------------
# Frictionless, beta 1e-5 s, rotation.gravity = 20 m/s^2: the touching branch, followed by pseudo-arclength, bends to
# higher speeds and ends where the speed turns (steps 1.9e-3 -> 1.2e-7 Hz) and a real multiplier rises towards +1: a
# fold. Its last point (22.813003629 Hz, shot to 5e-11 by the continuation's corrector) is stored in
# tests/data/delamination_fold_orbit.npz.
# (The continuation that crosses grazings passes this point: it is a grazing, contact 4 at 4.4e-10 m, not a turn;
# the branch goes on, stable, to 22.81415 Hz. What is asserted below holds of the stored orbit either way.)

FOLD = DATA.with_name("delamination_fold_orbit.npz")


def _fold_system(offset_hz: float = 0.0, path=FOLD):
    """(system, period, t0, q0, v0) of a stored orbit at 2 g (default the branch's first end, "fold");
    ``offset_hz`` moves the speed from the stored one."""
    d = np.load(path)
    speed, beta, g = float(d["speed_hz"]) + offset_hz, float(d["beta"]), float(d["gravity"])
    scene = load_scene("default", [f"damping.rayleigh=[0.0,{beta!r}]", f"rotation.speed_hz={speed!r}",
                                   f"rotation.gravity={g!r}"])
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    system = ContactSystem.from_model(model, red, scene.rotation, scene.damping)
    return system, 1.0 / speed, float(d["t0"]), d["q0"], d["v0"]


def test_orbit_at_the_fold_has_a_real_multiplier_near_one():
    """The orbit where the 2 g branch ends is a periodic orbit of the exact flow (a fresh integrator returns to it
    after one period, with contact), stable, and its leading multiplier is real and near +1, with a clear gap to the
    rest; the multiplier is checked against central differences of the flow along its eigenvector (independent of
    the saltation matrices). What ends the branch is a grazing, not the saddle-node: the next test."""
    import warnings

    system, T, t0, q0, v0 = _fold_system()
    res, (err,) = _returns(system, T, t0, q0, v0, 1)
    # stored at the corrector's 5e-11 (relative, in the same norm) plus a period's round-off (~1e-12): 1e-9 is a
    # margin of 20 and far below the 1e-6 at which an event sequence changes
    assert err < 1e-9
    assert len(res.events) > 20 and res.normal_force.max() > 1.0   # the layers touch, many times a period
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # (near-grazing passages are reported)
        o = periodic_orbit(system, T, q0, v0, t0, tol=1e-10, max_iter=4, attempts=1)
    assert o.converged and o.stable
    mu = o.multipliers
    # the leading multiplier: real (its imaginary part at the eigen-solver's round-off, 1e-12 on a 40-dimensional
    # monodromy) and 0.9972 (measured): nearer +1 than at any regular point of the branch (at most 0.9947, at
    # 22.80 Hz), and still rising over the last steps (0.9948 one step before): 0.9965 separates the two with
    # margins far above round-off; below 1: the stable side of the fold
    assert abs(mu[0].imag) < 1e-10 and 0.9965 < mu[0].real < 1.0
    # the next modulus is 0.9855: the fold's multiplier stands apart
    assert abs(mu[0]) - abs(mu[1]) > 0.005
    _check_multiplier_by_central_differences(system, T, o, 1e-9)


def _departure(system, T, o, y, size: float, periods: int):
    """A perturbation of ``size`` (relative to the orbit's largest coordinate) along the Floquet vector ``y`` (on the
    admissible directions) followed by the exact flow over ``periods``: (its growth a period, the sign of its
    projection on the start's after each period)."""
    n = system.n
    dx = o.directions @ y
    dx *= size * max(np.abs(o.q0).max(), 1e-300) / np.abs(dx[:n]).max()
    phi = FlowMap(system, o.t0, T)
    q, v = o.q0 + dx[:n], o.v0 + dx[n:]
    signs = []
    for _ in range(periods):
        f = phi(q, v, jacobian=False)
        q, v = f.q, f.v
        signs.append(np.sign(np.dot(np.concatenate([q - o.q0, v - o.v0]), dx)))
    d = np.concatenate([q - o.q0, v - o.v0])
    return (np.linalg.norm(d) / np.linalg.norm(dx)) ** (1.0 / periods), signs


def _check_multiplier_by_central_differences(system, T, o, h):
    """The flow's central difference along the leading eigenvector y of the monodromy (a relative state step
    ``h``) equals mu_1 y: the multiplier from the flow alone, without the saltation matrices."""
    n = system.n
    w, V = np.linalg.eig(o.monodromy)
    j = int(np.argmax(np.abs(w)))
    y = np.real(V[:, j])
    dx = o.directions @ y
    s = h * np.abs(o.q0).max() / np.abs(dx[:n]).max()
    phi = FlowMap(system, o.t0, T)
    plus = phi(o.q0 + s * dx[:n], o.v0 + s * dx[n:], jacobian=False)
    minus = phi(o.q0 - s * dx[:n], o.v0 - s * dx[n:], jacobian=False)
    # the perturbed flows keep the orbit's events (the difference quotient is of one smooth piece)
    assert len(plus.result.events) == len(minus.result.events) == o.events_per_period
    d = o.directions.T @ np.concatenate([plus.q - minus.q, plus.v - minus.v]) / (2.0 * s)
    # the flow's end state repeats to ~5e-16 of the state (event times found by root search), so the difference
    # quotient carries ~5e-16 / h (measured: 8e-8, 6e-7, 5e-6 at h = 1e-8, 1e-9, 1e-10: the 1/h law), its truncation
    # O(h^2) is far below; 1e-5 is a margin of ~15 at h = 1e-9 and 1000 below the gap to the next multiplier, so a
    # monodromy with a saltation matrix left out or wrong fails
    assert np.linalg.norm(d - w[j].real * y) / np.linalg.norm(y) < 1e-5


def test_fold_branch_ends_at_a_grazing_before_its_saddle_node():
    """Where the first 2 g continuation stopped (22.813003629 Hz, stored) there is no fold (a real multiplier through
    +1): contact 4's closest passage falls to zero first, and the 43-event piece ends there (the continuation with
    the section at the quiet phase passes it on other event sequences, stable: docs/validation.md). From the stored orbit and the one 1e-7 Hz below (same 43 events):
    - the grazing: the closest passage g(p) falls with a growing slope (0.124, then 0.185 m/Hz over the last two
      1e-7 Hz steps: concave), so the secant through the two orbits reaches zero no earlier than the gap does;
    - the saddle-node of the smooth piece: at a fold 1 - mu_1 ~ sqrt(p_fold - p), so (1 - mu_1)^2 is linear in p
      there and its secant locates p_fold.
    The grazing comes within 1e-8 Hz of the stored speed, the saddle-node no nearer than 3e-8 Hz beyond: the
    branch ends at the grazing with mu_1 = 0.9972, and shooting beyond it (22.81300365-22.8130039 Hz: docs) fails
    with contact 4 at 1e-12 m."""
    import warnings

    delta = 1e-7

    def end(offset):
        system, T, t0, q0, v0 = _fold_system(offset)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")   # (the near-grazing passages are what is measured)
            o = periodic_orbit(system, T, q0, v0, t0, tol=1e-10, max_iter=6, attempts=1)
        assert o.converged and o.events_per_period == 43
        return o

    o0, o1 = end(0.0), end(-delta)
    mu0, mu1 = o0.multipliers[0], o1.multipliers[0]
    assert abs(mu0.imag) < 1e-10 and abs(mu1.imag) < 1e-10   # (the pair met on the real axis ~2e-7 Hz below)
    k = min(o0.grazing, key=lambda x: x["gap_min"])["contact"]
    g0 = min(x["gap_min"] for x in o0.grazing if x["contact"] == k)
    g1 = min(x["gap_min"] for x in o1.grazing if x["contact"] == k)
    # the closest passages are refined on the closed-form motion (Brent to 1e-12 of the phase: ~1e-15 m at a
    # minimum), far below the 4.4e-10 and 1.9e-8 m measured
    assert 0.0 < g0 < 1e-9 < g1
    grazing = g0 * delta / (g1 - g0)
    fold = delta * (1.0 - mu0.real) ** 2 / ((1.0 - mu1.real) ** 2 - (1.0 - mu0.real) ** 2)
    # measured 2.4e-9 and 5.3e-8 Hz: each bound with a margin of 4 and 1.8 (the multipliers are exact to ~1e-7,
    # the central differences above, the speeds to round-off)
    assert grazing < 1e-8 < 3e-8 < fold
    # the leading multiplier at the grazing (linear in p over 2.4e-9 Hz from mu0, rising 2e-2 per 1e-6 Hz): not +1
    assert mu0.real + grazing * (mu0.real - mu1.real) / delta < 0.998




# --- the unstable branch at twice the gravity (studies/delamination_variants.py --unstable) ---------------------------
# Continued downwards from the open orbit at 22.83 Hz (nsfem periodic --continue, which crosses grazings), the open
# branch grazes at 22.819182 Hz and goes on as touching orbits (15-19 events a period) that are stable down to a
# grazing at 22.817900 Hz, where the leading multiplier jumps from 0.989 (complex pair) to a real 1.466: the touching
# orbits below it are unstable with one real multiplier > 1 (saddles; each next to a stable orbit with one brief
# contact less, born at the same grazing: not the middle branch of the fold at 22.813 Hz; docs/validation.md). One
# of them (22.817846160 Hz, 16 events, re-shot from the continuation's point to residual 8e-15) is stored in
# tests/data/delamination_fold_unstable_orbit.npz.

FOLD_UNSTABLE = DATA.with_name("delamination_fold_unstable_orbit.npz")


def test_unstable_orbit_at_twice_the_gravity_returns_under_an_independent_flow():
    """The stored orbit is a periodic orbit of the exact flow: a fresh integrator from its section state returns to
    it after 1 and 2 periods, with the same events (the layers touching) in both periods."""

    system, T, t0, q0, v0 = _fold_system(path=FOLD_UNSTABLE)
    res, errs = _returns(system, T, t0, q0, v0, 2)
    for k, err in enumerate(errs, 1):
        # stored at 8e-15; a period adds the event times' round-off (~1e-13 s located) times the state's rate, ~1e-12
        # relative over 16 events, and the unstable direction multiplies what is there by ~1.6 a period: 1e-9 is a
        # margin of 100 over two periods and far below the 5e-8 m (5e-6 relative) at which contact 1 would touch
        assert err < 1e-9, k
    events = [dict(e, t=e["t"] + t0) for e in res.events]
    sig0, ph0 = _signature(events, t0, T, 0)
    sig1, ph1 = _signature(events, t0, T, 1)
    assert len(sig0) >= 4 and sig1 == sig0
    # the layers touch: closings every period (briefly: 0.2 % of the time closed, between the output samples)
    assert any("close" in s[1] for s in sig0) and res.info["closed_fraction"] > 0.0
    assert np.abs(ph1 - ph0).max() < 1e-6


def test_unstable_orbit_at_twice_the_gravity_is_left_at_its_real_multiplier():
    """The orbit is unstable through one real multiplier > 1 (the loss of a fold's middle branch, not a
    period-doubling or a Neimark-Sacker), set apart from the rest; a perturbation along its Floquet direction grows
    at that multiplier a period under the exact transient, without changing sign."""
    import warnings

    system, T, t0, q0, v0 = _fold_system(path=FOLD_UNSTABLE)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # (contact 1 passes 5e-8 m from contact without closing: reported)
        o = periodic_orbit(system, T, q0, v0, t0, tol=1e-12, max_iter=3, attempts=1)
    # (stored at 8e-15; a period's round-off is ~1e-15 relative, times the multiplier 1.6)
    assert o.converged and o.residual < 1e-12 and o.events_per_period > 0
    assert not o.stable and o.loss == "fold"
    w, V = np.linalg.eig(o.monodromy)
    j = int(np.argmax(np.abs(w)))
    mu1 = w[j]
    # real to the eigen-solver's round-off on a ~40-dimensional matrix (1e-12), outside the unit circle, and simple:
    # every other modulus is below 1 (the orbit has one unstable direction: a saddle)
    assert abs(mu1.imag) < 1e-10 and mu1.real > 1.0
    assert np.sort(np.abs(w))[-2] < 1.0
    N = 8
    rate, signs = _departure(system, T, o, np.real(V[:, j]), 1e-9, N)
    # along the eigenvector d_N = mu^N dx + O(|d|^2): after 8 periods |d| ~ 40 |dx| = 4e-8 of the state (4e-10 m,
    # far from contact 1's 5e-8 m margin), so the second order is ~4e-8 of |d|; the orbit's own error (< 1e-12 a
    # period) is < 1e-3 of |dx| per period and enters the 8th root as < 1e-3 of the rate; 3e-3 covers both and tells
    # the real multiplier (> 1) from the next modulus (< 1) by far
    assert rate == pytest.approx(abs(mu1), abs=3e-3)
    assert signs == [1.0] * N   # a positive real multiplier: the same side every period


PAIR = DATA.with_name("delamination_fold_grazing_pair.npz")


def test_grazing_pair_at_twice_the_gravity_is_a_stable_and_an_unstable_orbit_at_one_speed():
    """At 22.817818 Hz, below the grazing at 22.817900 Hz, two touching period-1 orbits coexist on one section: a
    saddle (one real multiplier > 1) and a stable orbit with another event sequence, where pushes of 1e-6 along the
    saddle's direction end (studies/delamination_variants.py --unstable). Each is a fixed point of the exact flow."""
    import warnings

    d = np.load(PAIR)
    speed, beta, g = float(d["speed_hz"]), float(d["beta"]), float(d["gravity"])
    scene = load_scene("default", [f"damping.rayleigh=[0.0,{beta!r}]", f"rotation.speed_hz={speed!r}",
                                   f"rotation.gravity={g!r}"])
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    system = ContactSystem.from_model(model, red, scene.rotation, scene.damping)
    T = 1.0 / speed
    orbits = {}
    for kind in ("stable", "unstable"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")   # (near-grazing passages are reported)
            o = periodic_orbit(system, T, d[f"{kind}_q0"], d[f"{kind}_v0"], float(d[f"{kind}_t0"]), tol=1e-12,
                               max_iter=3, attempts=1)
        # both stored at <= 6e-15 (relative); a period's round-off ~1e-15 times the largest multiplier (1.6)
        assert o.converged and o.residual < 1e-12 and o.events_per_period > 0, kind
        orbits[kind] = o
    s, u = orbits["stable"], orbits["unstable"]
    assert s.stable and np.abs(s.multipliers).max() < 1.0
    assert not u.stable and u.loss == "fold"
    assert abs(u.multipliers[0].imag) < 1e-10 and u.multipliers[0].real > 1.0
    assert s.events_per_period != u.events_per_period          # a different contact sequence
    # two distinct orbits, not one found twice: their section states differ by far more than either's residual
    # (1e-12) carried by the saddle's multiplier
    assert s.t0 == u.t0
    assert np.abs(s.q0 - u.q0).max() / np.abs(u.q0).max() > 1e-8


BETWEEN = DATA.with_name("delamination_fold_unstable_between.npz")


def test_unstable_orbit_between_the_fold_and_the_grazing_pair_has_two_real_multipliers_above_one():
    """At 22.8135 Hz, between the 2 g branch's turn (22.813004 Hz) and the grazing pair (22.8179 Hz), Newton from the
    turn's orbit converges to a touching orbit that is a fixed point of the exact flow with two real multipliers
    above 1 (two unstable directions: not a fold's middle branch, which has one)."""
    import warnings

    system, T, t0, q0, v0 = _fold_system(path=BETWEEN)
    res, (err,) = _returns(system, T, t0, q0, v0, 1)
    # shot to 3e-13; a period's round-off over ~40 events (~1e-12) times the largest multiplier (2.4): 1e-9 is a
    # margin of 100s and far below the 1e-6 at which an event sequence changes
    assert err < 1e-9
    assert len(res.events) > 20                                    # the layers touch, many times a period
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # (near-grazing passages are reported)
        o = periodic_orbit(system, T, q0, v0, t0, tol=1e-11, max_iter=3, attempts=1)
    assert o.converged and not o.stable and o.loss == "fold"
    # real to the eigen-solver's round-off on a ~40-dimensional matrix (1e-12), and two of them outside the circle
    above = [m for m in o.multipliers if abs(m.imag) < 1e-10 and m.real > 1.0]
    assert len(above) == 2
    assert np.sum(np.abs(o.multipliers) > 1.0) == 2
