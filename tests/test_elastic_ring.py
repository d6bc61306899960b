"""An elastic stator ring (a polygon on a radial spring-damper, nsfem.contact.ring) around a Jeffcott rotor:
the ring's force law against an independent projection, the synchronous full annular rub against its closed
form ((k - m w^2) r + N)^2 + (c w r + mu N)^2 = (m e w^2)^2 with N = k_s (r - c), from `stationary` and as the
limit of a damped transient; the event-driven regions against an independent integration of the force law;
energy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq
from test_stator import C_E, CLEARANCE, K, M, ME, rub_tree

from nsfem.analysis.stationary import scene_stationary
from nsfem.contact.ring import ROT, Ring, forces, potential
from nsfem.errors import NsfemError, SceneError
from nsfem.integrate import integrate
from nsfem.integrate.problem import ContactSystem
from nsfem.integrate.rings import initial_rings
from nsfem.scene import scene_from_tree
from nsfem.simulate import run_scene

KS = 2e6     # the ring's mount, 13 times the shaft's midspan stiffness: the rub penetrates 5 to 10 % of the clearance


def elastic_tree(facets=64, mu=0.0, ks=KS, cs=20.0, **kw):
    tree = rub_tree(facets, friction=mu, **kw)
    tree["stator"][0].update(stiffness=ks, damping=cs)
    return tree


def circle_radius(w, ks, mu):
    """The whirl radius r > c of the synchronous rub on a circular elastic ring: the root of the closed form
    (a quadratic in r, negative at r = c when the free whirl is wider: one root above c)."""
    def f(r):
        n = ks * (r - CLEARANCE)
        return ((K - M * w * w) * r + n) ** 2 + (C_E * w * r + mu * n) ** 2 - (ME * w * w) ** 2
    return brentq(f, CLEARANCE, 1.0, xtol=1e-18, rtol=1e-15)


def polygon_state(w, ks, mu, facets):
    """The disk's position z (complex y + i z, rotating frame) on the polygon's elastic ring: on facet k's
    region (A z + (1 + i mu) k_s (n_k . z - c) n_k = m e w^2, real 2 x 2) or at corner k's
    (A z + (1 + i mu) k_s (z - v_k) = m e w^2), whichever holds its region's inequalities; and the ring's
    force k_s (z - p(z))."""
    A, G, rhs = K - M * w * w + 1j * C_E * w, (1 + 1j * mu) * ks, ME * w * w
    h = CLEARANCE * math.tan(math.pi / facets)
    for k in range(facets):
        n = np.exp(2j * math.pi * k / facets)
        gn = G * n
        mat = np.array([[A.real + gn.real * n.real, -A.imag + gn.real * n.imag],
                        [A.imag + gn.imag * n.real, A.real + gn.imag * n.imag]])
        x, y = np.linalg.solve(mat, [rhs + gn.real * CLEARANCE, gn.imag * CLEARANCE])
        z = x + 1j * y
        along = (z * np.conj(1j * n)).real
        if (z * np.conj(n)).real > CLEARANCE and abs(along) <= h:
            return z, ks * ((z * np.conj(n)).real - CLEARANCE) * n
        n1 = np.exp(2j * math.pi * (k + 1) / facets)
        v = CLEARANCE / math.cos(math.pi / facets) * (n + n1) / abs(n + n1)
        z = (rhs + G * v) / (A + G)
        d = z - v   # inside the corner's cone: d = a n + b n1, a, b >= 0
        a, b = np.linalg.solve([[n.real, n1.real], [n.imag, n1.imag]], [d.real, d.imag])
        if a >= 0 and b >= 0:
            return z, ks * d
    raise AssertionError("no region holds the polygon's state")


@pytest.mark.parametrize("mu", [0.0, 0.1, 0.3])
def test_elastic_rub_is_a_stationary_state_and_the_closed_form(mu):
    """Rotating frame: LCP (28) with the ring's compliance n_i . n_j / k_s gives the polygon's closed form
    (to the light shaft's mass, ratio 5e-5 of the disk's: measured 1.8e-5), and the
    resultant is the circle's N = k_s (r - c) within the polygon's distance from the circle."""
    scene = scene_from_tree(elastic_tree(mu=mu))
    w = 2 * math.pi * scene["rotation"]["speed_hz"]
    st = scene_stationary(scene)
    on = np.flatnonzero(st.normal_force > 0)
    assert 1 <= on.size <= 2 and np.all(st.gap[on] < 0)           # the ring is pushed out: negative gaps
    assert all(st.state[k] == "slip" for k in on)
    z, force = polygon_state(w, KS, mu, 64)
    total = sum(st.normal_force[j] * np.exp(2j * math.pi * j / 64) for j in on)
    assert abs(total - force) <= 1e-4 * abs(force)
    for k in on if mu else ():   # the friction on the shaft opposes the surface's forward slide: -mu N along t
        assert st.tangential_force[k][0] == pytest.approx(-mu * st.normal_force[k], rel=1e-12)
    r = circle_radius(w, KS, mu)
    n_circle = KS * (r - CLEARANCE)
    # the polygon lies within c (1 / cos(pi / 64) - 1) = 1.2e-3 c of the circle; the ring force follows the
    # penetration (r - c = 0.06 c) on a spring 13 times the shaft's: about that distance over the penetration
    # (2e-2) at worst (measured 1.4e-5 to 1.1e-3)
    tol = (1 / math.cos(math.pi / 64) - 1) * CLEARANCE / (r - CLEARANCE)
    assert abs(abs(total) / n_circle - 1) <= tol
    assert abs(abs(z) / r - 1) <= 1.5 * (1 / math.cos(math.pi / 64) - 1)


def test_damped_transient_from_rest_ends_in_the_elastic_stationary_state():
    """Frictionless, exact from rest (engaging and releasing the ring, its latent state after a release with
    the damper), ends in LCP (28)'s state: the slowest mode in contact decays as e^-4t (the damper at the
    disk, c / 2m), 1e-7 of the force after 4 s. moreau (step 1e-4 s, the same regions taken at each step's
    start) reaches it within its first-order error. The work balance closes to round-off."""
    scene = scene_from_tree(elastic_tree(mu=0.0, beta=1e-5, simulation={"t_end": 4.0, "output_dt": 1e-3}))
    st = scene_stationary(scene)
    on = np.flatnonzero(st.normal_force > 0)
    res, _ = run_scene(scene, "exact")
    assert np.flatnonzero(res.normal_force[:, -1] > 0).tolist() == on.tolist()
    np.testing.assert_allclose(res.normal_force[on, -1], st.normal_force[on], rtol=1e-6)
    kinds = {k for e in res.events for k in e["kinds"]}
    assert {"ring_engage", "ring_release", "ring_exit"} <= kinds
    assert any(e["after"].get("latent") for e in res.events)     # released while still beyond the polygon
    assert res.energy["dissipated_damping_J"] > 0
    # round-off of some 400 events' closed forms (measured 2e-10)
    assert abs(res.energy["relative_residual"]) < 1e-8
    mor, _ = run_scene(scene, "moreau")
    np.testing.assert_allclose(mor.normal_force[on, -1], st.normal_force[on], rtol=1e-4)


def test_frictional_elastic_rub_dissipates_what_the_spin_drives():
    """From the stationary state (mu = 0.3) the rotor stays in it (for 0.05 s: it is unstable, see below); the
    friction dissipates the power of its force against the surface sliding past (in the rotating frame at
    Omega (R + nu . u) along the ring), and the spin does that work; exact, rk and moreau agree."""
    mu, T = 0.3, 0.05
    scene = scene_from_tree(elastic_tree(mu=mu, simulation={"t_end": T, "output_dt": 1e-3},
                                         initial={"state": "stationary"}))
    st = scene_stationary(scene)
    on = np.flatnonzero(st.normal_force > 0)
    w = 2 * math.pi * scene["rotation"]["speed_hz"]
    runs = {m: run_scene(scene, m) for m in ("exact", "rk", "moreau")}
    res, sysm = runs["exact"]
    ring = sysm.rings[0]
    u = ring.P @ res.q[:, -1]
    N, _, reg, slip = forces(ring, res.q[:, -1:], res.v[:, -1:])
    nu = ring.parts(int(reg[0]))[2]
    assert slip[0] == pytest.approx(w * (0.01 + nu @ u), rel=1e-12)      # R = 0.01: half the shaft's diameter
    # the friction -mu s R N on the shaft against the surface's velocity Omega (R_s R nu + R u): its power
    # mu Omega (R_s N . nu + N . u) (= mu (nu . N) times the slip on an edge, where N is along nu; here a corner)
    rate = mu * w * (0.01 * float(N[:, 0] @ nu) + float(N[:, 0] @ u))
    # How far each method may drift from the (unstable) stationary state: the LCP's state is a fixed point of
    # each method to round-off, so the only drift is round-off grown by the instability. The round-off of one
    # step, d, is read from the run itself: the larger of the drift at t = 0 (one rounding of the state; the
    # force is k_s times a penetration of 6 % of the radius, a cancellation that makes it 1e-12 to 6e-12
    # against eps = 2.2e-16, depending on the BLAS kernel and numpy's SIMD loops) and at the first output (one
    # step of the method besides). Each of the n output steps adds at most such a rounding, and the linearized
    # motion about the state, x' = A x, grows a deviation at most by cond(V) e^(rate t) (V: A's eigenvectors,
    # cond 640 here; rate 84 1/s): |N(t)/N_st - 1| <= d (1 + n(t)) cond(V) e^(rate t). (Measured: exact reaches
    # 20 to 660 d at T, on AVX-512 and AVX2 loops, and 1.1 d (1 + n) e^(rate t) at 3 ms without cond(V); a
    # state that left the LCP's solution would be off by O(1).)
    (i, region, s), = initial_rings(sysm.rings, res.q[:, 0], res.v[:, 0])[0]
    A = _jeffcott_matrix(w, ring, region, s, mu)
    growth = float(np.linalg.eigvals(A).real.max())
    transient = float(np.linalg.cond(np.linalg.eig(A)[1]))
    assert 80.0 < growth < 90.0
    rate_drift = float(np.abs(res.normal_force[on] / st.normal_force[on, None] - 1).max())
    for name, (r, _) in runs.items():
        e = r.energy
        drift = np.abs(r.normal_force[on] / st.normal_force[on, None] - 1).max(axis=0)
        d0 = max(drift[0], drift[1], 16 * np.finfo(float).eps)
        steps = np.arange(r.t.size)
        bound = d0 * (1 + steps) * transient * np.exp(growth * r.t)
        assert np.all(drift <= bound), (name, float(np.max(drift / bound)))
        # the energy terms are the rates times T, integrals of the force against the slip: off by at most the
        # largest drift of the force (1e-12 to 2e-9), that of exact's final state the rate is read from (up to
        # 2.3e-10: moreau's own energy and rate agree to 7e-16, measured, and it failed on OpenBLAS's Sandybridge
        # kernels without this term) and the accuracy of the integral: round-off of the closed form (exact,
        # moreau: 1e-12), rk's own tolerance (rtol 1e-8; measured 8e-12)
        tol = drift.max() + rate_drift + (scene.simulation.rtol if name == "rk" else 1e-12)
        assert e["dissipated_friction_J"] == pytest.approx(T * rate, rel=tol), name
        assert e["work_spin_J"] == pytest.approx(e["dissipated_friction_J"], rel=tol), name
        assert abs(e["relative_residual"]) < 1e-9


def _jeffcott_matrix(w, ring, region, s, mu):
    """The state matrix of small motions about the sliding rub of the rigid-disk Jeffcott rotor in the rotating
    frame, from its own equations: M (z'' + 2 Omega J z' - Omega^2 z) + C_E (z' + Omega J z) + K z
    = -(I + mu s J)(k_s S z + c_s D z') on the ring's law (J: +90 degrees)."""
    S = ring.parts(region)[0]
    J = np.array([[0.0, -1.0], [1.0, 0.0]])
    G = np.eye(2) + mu * s * J
    Keff = (K - M * w * w) * np.eye(2) + C_E * w * J + ring.stiffness * G @ S
    Ceff = 2 * M * w * J + C_E * np.eye(2) + ring.damping * G @ ring.damper(region)
    return np.block([[np.zeros((2, 2)), np.eye(2)], [-Keff / M, -Ceff / M]])


def _jeffcott_rate(w, ring, region, s, mu):
    """The fastest growth rate of small motions about the sliding rub (the largest real part of
    :func:`_jeffcott_matrix`'s eigenvalues)."""
    return float(np.linalg.eigvals(_jeffcott_matrix(w, ring, region, s, mu)).real.max())


def test_sliding_elastic_rub_is_unstable_at_the_jeffcott_rate():
    """Friction-induced instability: with mu = 0.3 the sliding rub on the elastic ring is a stationary state
    but an unstable one. Started exactly there, exact's motion leaves it at the growth rate of the Jeffcott
    rotor's own linearized equations (84 1/s); the envelope, read per 25 ms window on 0.2 ms outputs of an
    800 rad/s oscillation, is within 0.3 % of the true one, and the slower modes are gone by then (the next
    rate is below 10 1/s: e^-75 t): 1 % tolerance. Without friction the same state is stable."""
    mu = 0.3
    scene = scene_from_tree(elastic_tree(mu=mu, simulation={"t_end": 0.25, "output_dt": 2e-4},
                                         initial={"state": "stationary"}))
    w = 2 * math.pi * scene["rotation"]["speed_hz"]
    res, sysm = run_scene(scene, "exact")
    ring = sysm.rings[0]
    (i, region, s), = initial_rings(sysm.rings, res.q[:, 0], res.v[:, 0])[0]
    rate = _jeffcott_rate(w, ring, region, s, mu)
    u = ring.P @ res.q
    d = np.linalg.norm(u - u[:, :1], axis=0)
    first, last = (res.t >= 0.15) & (res.t < 0.175), (res.t >= 0.2) & (res.t < 0.225)
    measured = math.log(d[last].max() / d[first].max()) / 0.05
    assert 80.0 < rate < 90.0
    assert measured == pytest.approx(rate, rel=1e-2)
    assert _jeffcott_rate(w, ring, region, 0, 0.0) < 0.0


def test_undamped_elastic_ring_keeps_the_energy():
    """Inertial frame, no damping anywhere (shaft, damper, ring), frictionless: the ring stores and returns
    energy (k_s |u - p(u)|^2 / 2 in E), the balance closes to the closed form's round-off."""
    scene = scene_from_tree(elastic_tree(32, frame="inertial", damper=0.0, cs=0.0,
                                         simulation={"t_end": 0.3, "output_dt": 1e-4}))
    res, sysm = run_scene(scene, "exact")
    assert res.normal_force.max() > 1.0 and len(res.events) > 20
    e = res.energy
    assert e["dissipated_damping_J"] == 0.0 and e["dissipated_friction_J"] == 0.0
    assert abs(e["relative_residual"]) < 1e-9        # measured 1e-12
    stored = [potential(sysm.rings, res.q[:, j]) for j in range(0, res.t.size, 10)]
    assert max(stored) > 0.01 * e["max_J"]


def _jeffcott_ring(mu=0.0, cs=30.0, facets=12, rotating=False):
    """A point-mass Jeffcott rotor (1 kg, 1e4 N/m, 2 N s/m) with a harmonic unbalance load inside an elastic ring
    of 12 facets (1e5 N/m), as arrays."""
    w = 120.0
    fc, fs = np.array([2.0, 0.0]), np.array([0.0, 2.0])     # 2 N turning with the rotor
    ring = Ring("ring", np.eye(2), 2 * np.pi * np.arange(facets) / facets, 1e-4, 1e5, cs, mu, 0.01, w, rotating)
    sysm = ContactSystem.from_arrays(np.eye(2), 1e4 * np.eye(2), 2.0 * np.eye(2), fc=fc, fs=fs, omega=w, rings=(ring,))
    return sysm, ring


def _reference(sysm, ring, t_end):
    """The same motion by solve_ivp on the force law itself (forces(), a function of the state), with steps
    short against the contact's 3e-3 s period: an independent integration of the ring's model."""
    def rhs(t, x):
        q, v = x[:2], x[2:]
        N, fric, _, _ = forces(ring, q[:, None], v[:, None])
        f = sysm.load(t) - sysm.C @ v - sysm.Q @ q - N[:, 0] + fric[:, 0]
        return np.concatenate([v, np.linalg.solve(sysm.M, f)])
    return solve_ivp(rhs, (0.0, t_end), np.zeros(4), method="DOP853", rtol=1e-11, atol=1e-15, max_step=2e-5,
                     dense_output=True)


# the frictionless case passes the same regions as mu = 0.2 (which adds friction's): slow (20 s each on a shared core)
@pytest.mark.parametrize("mu", [pytest.param(0.0, marks=pytest.mark.slow), 0.2])
def test_ring_regions_and_events_against_an_independent_integration(mu):
    """The exact method's regions (edges, corners, latent releases with a strong damper) reproduce an
    independent integration of the force law to its accuracy (rtol 1e-11 on a 2e-4 m motion, through some 90
    kinks of its right-hand side: 1e-10 m, 1e-6 of the motion; measured 2e-13 m)."""
    sysm, ring = _jeffcott_ring(mu=mu)
    res = integrate(sysm, 0.2, "exact", 1e-3)
    kinds = {k for e in res.events for k in e["kinds"]}
    assert {"ring_engage", "ring_release", "ring_exit"} <= kinds
    ref = _reference(sysm, ring, 0.2)
    np.testing.assert_allclose(res.q, ref.sol(res.t)[:2], atol=1e-10)
    assert abs(res.energy["relative_residual"]) < 1e-11      # measured 1.4e-14
    if mu:
        assert res.energy["dissipated_friction_J"] > 0 and res.energy["work_spin_J"] > 0


def _law_force(ring, law, u, du):
    """N of a law (None: released) at (u, u')."""
    if law is None:
        return np.zeros(2)
    S, a, _ = ring.parts(law)
    return ring.stiffness * (S @ u - a) + ring.damping * ring.damper(law) @ du


@pytest.mark.parametrize("facets, cs", [(4, 100.0), (12, 300.0)])
def test_ring_state_follows_the_region_it_exits_to(facets, cs, monkeypatch):
    """A ring_exit changes the normal cone K (n_k's ray on an edge, n_k and n_k+1's cone at a corner), so the
    ring can engage or release with the region: after every event a ring's law (released, or which facets
    push) gives the force of the case of proj_K (X) that the state is in, in the ring's region (to round-off
    of the event's state, 1e-9 of k_s c), and the motion follows the independent integration (these rings' first such crossing comes at 0.021 s and 0.038 s; kept latent, they erred by 3e-7 and 6e-6 m).
    Tolerance: the reference's own error (rtol 1e-11 on a 1.7e-4 m motion through 12 and 22 kinks), against a
    run at rtol 1e-13 and steps of 5e-6 s, is 1e-14 and 2e-14 m; 1e-12 m."""
    import nsfem.integrate.event_driven as event_driven

    wrong, turned, after_event = [], [], event_driven.after_event

    def checked(rings, mode, fired, q, v, t):
        eng, lat = after_event(rings, mode, fired, q, v, t)
        if {k for k, _ in fired} == {"ring_exit"} and bool(mode.latent) != bool(lat) and (eng or lat):
            turned.append(t)    # a lone exit that engages or releases
        for i, law, *_ in eng + lat:
            ring, u, du = rings[i], rings[i].P @ q, rings[i].P @ v
            region, law = (law, None) if (i, law) in lat else (ring.place(law), law)
            N = _law_force(ring, law, u, du) - _law_force(ring, ring.law(region, u, du), u, du)
            if np.linalg.norm(N) > 1e-9 * ring.stiffness * ring.clearance:
                wrong.append((t, law, N))
        return eng, lat

    monkeypatch.setattr(event_driven, "after_event", checked)
    sysm, ring = _jeffcott_ring(mu=0.2, cs=cs, facets=facets)
    res = integrate(sysm, 0.05, "exact", 1e-3)
    assert not wrong and turned
    ref = _reference(sysm, ring, 0.05)
    np.testing.assert_allclose(res.q, ref.sol(res.t)[:2], atol=1e-12)
    assert abs(res.energy["relative_residual"]) < 1e-11


def test_ring_force_is_the_projection_onto_the_polygon():
    """k_s (u - p(u)) with p the nearest point of the polygon (found here by projecting onto each facet's
    segment and keeping the nearest); continuous across the region boundaries; its energy's gradient."""
    _, ring = _jeffcott_ring(cs=0.0)
    rng = np.random.default_rng(3)
    corners = np.roll(ring.corners, 1, axis=0), ring.corners          # facet k runs from v_k-1 to v_k
    for u in rng.normal(scale=1.4e-4, size=(400, 2)):
        best = None
        for a, b in zip(*corners):
            s = np.clip((u - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
            p = a + s * (b - a)
            if best is None or np.linalg.norm(u - p) < np.linalg.norm(u - best):
                best = p
        inside = np.all(ring.normals @ u <= ring.clearance)
        N, _, reg, _ = forces(ring, u[:, None], np.zeros((2, 1)))
        expect = np.zeros(2) if inside else ring.stiffness * (u - best)
        np.testing.assert_allclose(N[:, 0], expect, atol=1e-9 * ring.stiffness * ring.clearance)
        assert (reg[0] < 0) == inside
        # the stored energy's gradient is the force
        e = 1e-10
        grad = [(potential([ring], u + e * d) - potential([ring], u - e * d)) / (2 * e) for d in np.eye(2)]
        np.testing.assert_allclose(grad, N[:, 0], atol=1e-6 * ring.stiffness * ring.clearance)


@pytest.mark.parametrize("facets", [3, 4, 12])
def test_ring_force_with_damping_and_friction_against_the_cone_projection(facets):
    """N = proj_K (k_s (u - p) + c_s u') with p the nearest point of the polygon (segments, as above) and K its
    normal cone there (one facet's n inside a segment, n_k and n_k+1 at a corner), the projection by NNLS on
    K's generators; the friction -mu s R N with s the sign of the slip past the facet (the corner's bisector
    when both push), the surface sliding at Omega (R_s + nu . u) in the rotating frame. The ring never pulls,
    and takes power: N . u' - dV/dt >= 0."""
    from scipy.optimize import nnls

    ring = Ring("ring", np.eye(2), 2 * np.pi * np.arange(facets) / facets + 0.3, 1e-4, 1e5, 50.0, 0.3, 0.01, 120.0,
                True)
    rng = np.random.default_rng(5)
    u, du = rng.normal(scale=1.6e-4, size=(2, 600)), rng.normal(scale=0.05, size=(2, 600))
    N, fric, laws, slip = forces(ring, u, du)
    F = facets
    ends = np.roll(ring.corners, 1, axis=0), ring.corners          # facet k runs from v_k-1 to v_k
    pushed = 0
    for j in range(u.shape[1]):
        if np.all(ring.normals @ u[:, j] <= ring.clearance):
            assert laws[j] == -1 and not N[:, j].any()
            continue
        sk = [np.clip((u[:, j] - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0) for a, b in zip(*ends)]
        k = int(np.argmin([np.linalg.norm(u[:, j] - a - s_ * (b - a)) for a, b, s_ in zip(*ends, sk)]))
        K = [k] if 0.0 < sk[k] < 1.0 else ([k, (k + 1) % F] if sk[k] == 1.0 else [(k - 1) % F, k])
        p = ends[0][k] + sk[k] * (ends[1][k] - ends[0][k])
        X = ring.stiffness * (u[:, j] - p) + ring.damping * du[:, j]
        lam = nnls(ring.normals[K].T, X)[0]
        expect = ring.normals[K].T @ lam
        np.testing.assert_allclose(N[:, j], expect, atol=1e-9 * ring.stiffness * ring.clearance)
        on = lam > 1e-12 * ring.stiffness * ring.clearance
        nu = ring.bisectors[K[0]] if on.sum() == 2 else ring.normals[K[int(np.argmax(lam))]]
        rate = (ROT @ nu) @ du[:, j] + ring.spin * (nu @ u[:, j] + ring.radius)
        if on.any():
            pushed += 1
            assert slip[j] == pytest.approx(rate, rel=1e-9)
            np.testing.assert_allclose(fric[:, j], -ring.friction * np.sign(rate) * ROT @ expect, atol=1e-12)
        power = N[:, j] @ du[:, j] - ring.stiffness * (u[:, j] - p) @ du[:, j]
        assert power >= -1e-12 * ring.stiffness * ring.clearance * np.abs(du[:, j]).max()
    assert pushed > 100


def test_elastic_ring_inputs():
    for key, value, match in (("damping", 10.0, "damping belongs to an elastic ring"),):
        tree = rub_tree(16)
        tree["stator"][0][key] = value
        with pytest.raises(SceneError, match=match):
            scene_from_tree(tree)
    tree = elastic_tree()
    tree["stator"][0]["restitution"] = 0.5
    with pytest.raises(SceneError, match="stator.0.restitution: an elastic ring"):
        scene_from_tree(tree)
    with pytest.raises(NsfemError, match="penalty: stator.0 is an elastic ring"):
        run_scene(scene_from_tree(elastic_tree(simulation={"t_end": 0.01})), "penalty")
