"""Moreau-Jean time stepping (method ``moreau``) against closed forms and ``exact``."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

import nsfem.integrate.moreau as moreau
from nsfem.contact.set import ContactSet
from nsfem.errors import IntegrationError, NsfemError
from nsfem.integrate import ContactSystem, integrate
from nsfem.integrate.base import EXTRA_METHODS

M1, K1 = 2.0, 50.0  # oscillator of tests/test_integrate.py: w = 5 rad/s
C_STOP = 0.1        # stop at q = -C_STOP
G = 9.81


def oscillator(eps: float) -> ContactSystem:
    """m q'' + k q = 0 with a stop at q = -c (g = q + c)."""
    return ContactSystem.from_arrays(M=[[M1]], Q=[[K1]], contacts=ContactSet.from_arrays([[1.0]], [C_STOP], eps=eps))


def ball(eps: float, mass: float = 1.0) -> ContactSystem:
    """A point mass over the floor g = q under gravity."""
    return ContactSystem.from_arrays(M=[[mass]], Q=[[0.0]], f0=[-mass * G],
                                     contacts=ContactSet.from_arrays([[1.0]], [0.0], eps=eps))


def mechanical_energy(res, sysm) -> np.ndarray:
    q, v = res.q, res.v
    return 0.5 * (np.einsum("it,it->t", v, sysm.M @ v) + np.einsum("it,it->t", q, sysm.Q @ q))


def test_registered():
    assert EXTRA_METHODS["moreau"] is moreau.MoreauJean


# --------------------------------------------------------------------------------------------
# 1. first-order convergence through impacts
# --------------------------------------------------------------------------------------------

def test_oscillator_with_stop_converges_at_first_order():
    """q(T) at T = 1 s, after two impacts (eps = 0.5), against ``exact``. The error of one run
    depends on where the impact falls inside its step (an O(h) shift of the impact time, but
    with a factor that jumps with h), so it is averaged over five initial speeds before the
    least-squares slope over four halvings of h is taken (measured: 1.16; mean errors
    2.3e-3, 1.6e-3, 5.4e-4, 2.2e-4 m for h = 2, 1, 0.5, 0.25 ms)."""
    sysm, T = oscillator(0.5), 1.0
    hs = np.array([2e-3, 1e-3, 5e-4, 2.5e-4])
    err = np.zeros((hs.size, 5))
    for j, v0 in enumerate(np.linspace(1.3, 1.7, 5)):
        ref = integrate(sysm, T, "exact", output_dt=0.1, v0=[-v0])
        assert len(ref.impacts) == 2
        for i, h in enumerate(hs):
            res = integrate(sysm, T, "moreau", output_dt=0.1, v0=[-v0], step=h)
            assert res.completed and res.info["steps"] == round(T / h) and res.info["step_s"] == h
            assert len(res.impacts) == 2
            err[i, j] = abs(res.q[0, -1] - ref.q[0, -1])
    e = err.mean(axis=1)
    order = np.polyfit(np.log(hs), np.log(e), 1)[0]
    # discretization error, not round-off (1 dof: the same under every BLAS kernel): first order
    # expects 1 (measured 1.16); the window excludes 1/2 and 2 (a wrong or a smoothed order)
    assert 0.7 < order < 1.5, (order, e)
    assert e[-1] < e[0] / 4  # three halvings: 1/8 at first order (measured 0.099); 1/4 allows order >= 2/3


# --------------------------------------------------------------------------------------------
# 2. bouncing ball: the impact sequence accumulates into persistent contact
# --------------------------------------------------------------------------------------------

def test_bouncing_ball_ends_in_persistent_contact():
    """Dropped from 1 m with eps = 0.5: impacts accumulate at t_inf = t_1 (1 + 2 eps / (1 - eps)),
    t_1 = sqrt(2 / g) (= 1.3546 s). The time stepping resolves a few bounces (8 at h = 1 ms,
    the last at 1.344 s) and then rests: lam_N / h = m g exactly (the impulse cancels one step
    of gravity), v = 0, no stall, and the discrete energy balance holds to round-off."""
    mass, h = 1.5, 1e-3
    sysm = ball(0.5, mass)
    res = integrate(sysm, 2.0, "moreau", output_dt=1e-2, q0=[1.0], step=h)
    assert res.completed and res.info["steps"] == 2000 and res.events == []
    t1 = math.sqrt(2 / G)
    t_inf = t1 * (1 + 2 * 0.5 / 0.5)
    first = res.impacts[0]
    # the contact joins the active set at the step t_k whose mid-step prediction g + (h/2) g' <= 0
    # first holds, so |t_k - t1| <= h/2 (measured 0.48 h) and the impact is dated t_k + h
    assert abs(first["t"] - t1) <= 2 * h
    # approach speed g t_k: off by g |t_k - t1| <= g h / 2 (measured 0.48 g h)
    assert first["approach_m_s"][0] == pytest.approx(G * t1, abs=2 * G * h)
    # impulse m (1 + eps) g t_k + m g h: relative (h/2) / t1 + h / (1.5 t1) = 0.26 % at most (measured
    # 0.25 %); allowed twice that
    assert first["impulse_Ns"][0] == pytest.approx(mass * 1.5 * G * t1, rel=5e-3)
    # Newton's law holds exactly in the LCP (w = 0): v_k+1 = -eps v_k up to a few roundings in
    # v_free + lam / m (~4 eps in v, 8 eps in v^2; measured 3e-16)
    assert first["kinetic_after_J"] == pytest.approx(0.25 * first["kinetic_before_J"], rel=1e-13)
    # an impact needs an approach faster than g h; the k-th approach is g t1 eps^(k-1), so there are
    # at most 1 + log2(t1 / h) = 9.8 of them (measured 8); flights of 2 t1 eps^k >= 10 h (k <= 6.5) are
    # resolved, so at least 6
    assert 5 <= len(res.impacts) <= 10
    assert res.impacts[-1]["t"] < t_inf + 0.01  # each of <= 10 impacts is late by at most one step h
    rest = res.t > t_inf + 0.05
    # at rest lam_N = m g h cancels v_free = -g h: a few roundings of m g (measured exactly m g, v = 0)
    np.testing.assert_allclose(res.normal_force[0, rest], mass * G, rtol=1e-12)
    np.testing.assert_allclose(res.v[0, rest], 0.0, atol=1e-12)  # m/s; eps g t1 = 1e-15 per rounding
    assert np.all(res.state[0, rest] == 2)  # closed, frictionless
    assert np.all(np.abs(res.gap[0, rest]) <= res.info["max_penetration_m"])
    assert res.info["max_penetration_m"] < G * t1 * h  # at most one step at the approach speed
    # energy: all of gravity's work went into the impacts. theta = 1/2 makes the discrete balance
    # exact; 2000 steps adding one rounding of E each give at most 2000 eps = 4.4e-13 (measured 9e-15).
    # E(0) = E(T) = 0, so lost - W is the residual itself (W = max E to 0.2 %)
    assert res.energy["relative_residual"] < 1e-12
    assert res.energy["lost_in_impacts_J"] == pytest.approx(res.energy["work_external_J"], rel=1e-12)


# --------------------------------------------------------------------------------------------
# 3. energy
# --------------------------------------------------------------------------------------------

def test_elastic_impacts_conserve_energy():
    """eps = 1, mu = 0, theta = 1/2: the impulse on an approaching contact reverses g' and does no
    work with the mean velocity, and the trapezoidal rule conserves the quadratic energy, so E is
    constant to round-off through 4 impacts (measured drift 7e-14 relative)."""
    sysm = oscillator(1.0)
    res = integrate(sysm, 3.0, "moreau", output_dt=1e-3, v0=[-1.5], step=1e-3)
    assert len(res.impacts) == 4
    E = mechanical_energy(res, sysm)
    # one step changes E by its roundings only, a few eps E (measured 3.9e-16 E)
    assert np.all(np.diff(E) <= 1e-13 * E[0])
    # 3000 steps of a few eps E each: 3000 eps = 6.7e-13 if they all added up (measured 6.6e-14)
    np.testing.assert_allclose(E, E[0], rtol=1e-12)
    assert res.energy["relative_residual"] < 1e-12
    assert abs(res.energy["lost_in_impacts_J"]) < 1e-12 * E[0]  # exactly 0 measured (g'_mid = 0)


@pytest.mark.parametrize("theta", [0.5, 1.0])
@pytest.mark.parametrize("eps", [0.0, 0.5, 1.0])
def test_energy_never_grows(eps, theta):
    """E(t) is non-increasing (theta = 1 adds algorithmic damping: 8 % of E over 3 s at eps = 1),
    eps < 1 loses energy in the impacts, and the reported terms close the balance up to the
    algorithmic dissipation info['numerical_dissipation_J'] (zero for theta = 1/2)."""
    sysm = oscillator(eps)
    res = integrate(sysm, 3.0, "moreau", output_dt=1e-3, v0=[-1.5], step=1e-3, theta=theta)
    E = mechanical_energy(res, sysm)
    assert np.all(np.diff(E) <= 1e-13 * E[0])  # round-off of one step, a few eps E (measured 3.9e-16 E)
    en = res.energy
    if eps < 1:  # physics, not accuracy: measured E(T) <= 0.13 E0, losses >= 0.86 E0
        assert E[-1] < 0.5 * E[0]
        assert en["lost_in_impacts_J"] > 0.4 * E[0]
    # an identity up to round-off: 3000 steps x eps = 6.7e-13 E0 at most (measured <= 1.0e-13 E0)
    assert en["residual_J"] == pytest.approx(-res.info["numerical_dissipation_J"], abs=1e-12 * E[0])
    if theta == 0.5:
        assert res.info["numerical_dissipation_J"] == 0.0 and en["relative_residual"] < 1e-12
    else:
        assert res.info["numerical_dissipation_J"] > 0


def rotor_like_system() -> ContactSystem:
    """4 dofs with damping, gyroscopic and circulatory terms, a harmonic load and two contacts
    (2-D friction with r = 8 and eps = 0.6; 1-D friction, plastic)."""
    rng = np.random.default_rng(3)
    n = 4
    A, B = rng.normal(size=(n, n)), rng.normal(size=(n, n))
    Gy, P = rng.normal(size=(n, n)), rng.normal(size=(n, n))
    JN = rng.normal(size=(n, 2))
    cs = ContactSet.from_arrays(JN, [0.05, 0.08], mu=[0.3, 0.2], eps=[0.6, 0.0],
                                JS=[rng.normal(size=(n, 2)), rng.normal(size=(n, 1))], r=[8, 2])
    return ContactSystem.from_arrays(M=A @ A.T + n * np.eye(n), Q=20 * B @ B.T + 10 * np.eye(n) + 0.5 * (P - P.T),
                                     C=0.3 * np.eye(n) + Gy - Gy.T, f0=-3 * JN[:, 0] - 2 * JN[:, 1],
                                     fc=5 * rng.normal(size=n), fs=2 * rng.normal(size=n), omega=7.0, contacts=cs)


@pytest.mark.parametrize("theta", [0.5, 0.75])
def test_energy_balance_with_damping_gyroscopic_circulatory_friction(theta):
    """Every work term is theta-weighted so that the discrete balance is exact for theta = 1/2
    (measured 7e-15) and misses exactly the algorithmic dissipation otherwise; the motion agrees
    with ``exact`` to 0.8 % of its amplitude at h = 1 ms (first order: 0.26 % at 0.5 ms)."""
    sysm = rotor_like_system()
    res = integrate(sysm, 1.0, "moreau", output_dt=1e-2, step=1e-3, theta=theta)
    en = res.energy
    assert en["dissipated_damping_J"] > 0 and en["dissipated_friction_J"] > 0 and en["lost_in_impacts_J"] > 0
    assert en["work_circulatory_J"] != 0 and len(res.impacts) > 5
    # 1000 steps of a few eps max E each (measured <= 9e-15 max E under four BLAS kernels)
    assert en["residual_J"] == pytest.approx(-res.info["numerical_dissipation_J"], abs=1e-12 * en["max_J"])
    if theta == 0.5:
        assert en["relative_residual"] < 1e-12
        ref = integrate(sysm, 1.0, "exact", output_dt=1e-2)
        # the O(h) error of the time stepping (0.79 % at 1 ms, 0.26 % at 0.5 ms); allowed about twice
        assert np.abs(res.q - ref.q).max() < 0.015 * np.abs(ref.q).max()
        assert (res.state == ref.state).mean() > 0.95  # outputs whose contact states differ: 1 % measured


# --------------------------------------------------------------------------------------------
# 4. Coulomb block on a plane
# --------------------------------------------------------------------------------------------

MU = 0.4


def block(r: int, mass: float = 2.0, pull=(0.0, 0.0)) -> ContactSystem:
    """A block (x, y, z) on the plane z = 0 under gravity, pulled by (Fx, Fy); 2-D friction."""
    JS = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
    cs = ContactSet.from_arrays([[0.0], [0.0], [1.0]], [0.0], mu=MU, JS=[JS], r=r)
    return ContactSystem.from_arrays(M=np.eye(3) * mass, Q=np.zeros((3, 3)),
                                     f0=[pull[0], pull[1], -mass * G], contacts=cs)


@pytest.mark.parametrize("r", [4, 8])
def test_block_sticks_below_the_friction_limit(r):
    """|F| = 0.6 mu m g at 30 degrees, inside the polygonal cone (inscribed radius
    cos(pi / r) >= 0.707): the block stays, friction balances the pull, lam_N = m g."""
    mass = 2.0
    F = 0.6 * MU * mass * G * np.array([math.cos(math.pi / 6), math.sin(math.pi / 6)])
    res = integrate(block(r, mass, F), 0.5, "moreau", output_dt=1e-2, step=1e-3)
    # v_k+1 = v_free + W^-1 p with |v_free| = g h = 1e-2 m/s cancels to a few eps of it, ~1e-17 m/s
    # per step (measured 1.7e-18 m/s, q 8.7e-19 m)
    np.testing.assert_allclose(res.q, 0.0, atol=1e-14)
    np.testing.assert_allclose(res.v, 0.0, atol=1e-14)
    assert np.all(res.state[0] == 1) and res.impacts == []
    np.testing.assert_allclose(res.normal_force[0], mass * G, rtol=1e-12)  # a few eps (measured 2.2e-16)
    # Lemke's certificate: componentwise n eps ||A|| ||x||, n <= 10 unknowns: ~2e-15 of the forces
    # (measured 2e-16); allowed 1e-13
    np.testing.assert_allclose(res.tangential_force[0], -F[:, None] * np.ones(res.t.size), rtol=1e-13)
    assert res.energy["dissipated_friction_J"] == pytest.approx(0.0, abs=1e-14)  # 4.7 N x 1e-17 m/s x 0.5 s


@pytest.mark.parametrize("r, direction", [(4, 0), (4, 1), (8, 0), (8, 1)])
def test_block_slides_above_the_friction_limit(r, direction):
    """F = 1.5 mu m g along a cone generator: it slides with a = (F - mu m g) / m from the first
    step, so v = a t and x = a t^2 / 2 (the trapezoidal rule is exact for constant acceleration;
    the closed form is met to round-off, well within O(h)); friction = mu m g against the slip and
    its dissipation mu m g x(T)."""
    mass, h, T = 2.0, 1e-3, 0.5
    F = np.zeros(2)
    F[direction] = 1.5 * MU * mass * G
    res = integrate(block(r, mass, F), T, "moreau", output_dt=1e-2, step=h)
    a = (F[direction] - MU * mass * G) / mass
    # 500 steps each adding one rounding: at most 500 eps = 1.1e-13 relative (measured 2.1e-14 in v,
    # 9e-15 in q); allowed 1e-12
    np.testing.assert_allclose(res.v[direction], a * res.t, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(res.q[direction], 0.5 * a * res.t**2, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(res.q[1 - direction], 0.0, atol=1e-14)  # exactly 0 measured
    np.testing.assert_allclose(res.q[2], 0.0, atol=1e-14)  # h x eps g h per step: 9e-19 m measured
    assert np.all(res.state[0] == 2)
    np.testing.assert_allclose(res.normal_force[0], mass * G, rtol=1e-12)  # a few eps (measured 2.2e-16)
    np.testing.assert_allclose(res.tangential_force[0, direction], -MU * mass * G, rtol=1e-12)
    # a sum of 500 step works, each exact in exact arithmetic: 500 eps = 1.1e-13 (measured 8.9e-15)
    assert res.energy["dissipated_friction_J"] == pytest.approx(MU * mass * G * 0.5 * a * T**2, rel=1e-12)
    assert res.energy["relative_residual"] < 1e-12  # 500 eps at most (measured 3.3e-14)


# --------------------------------------------------------------------------------------------
# 5. options, outputs, interruption, failure
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("options, match", [
    ({"step": 0.0}, "step"), ({"step": -1e-3}, "step"), ({"step": float("nan")}, "step"), ({"step": "x"}, "step"),
    ({"theta": 0.4}, "theta"), ({"theta": 1.1}, "theta"), ({"theta": "a"}, "theta"),
    ({"gamma": 0.5}, "gamma"), ({"step": True}, "step"), ({"step": "1e-3"}, "step"), ({"theta": True}, "theta"),
])
def test_bad_options(options, match):
    with pytest.raises(NsfemError, match=match):
        integrate(oscillator(0.5), 1.0, "moreau", output_dt=0.1, **options)


def test_step_must_not_exceed_output_dt():
    with pytest.raises(NsfemError, match="step"):
        integrate(oscillator(0.5), 1.0, "moreau", output_dt=0.01, step=0.02)


def test_step_is_fitted_to_the_outputs():
    """step 0.3 ms with output_dt 1 ms -> 4 steps of 0.25 ms per output; a last output
    interval of 0.5 ms (t_end = 10.5 ms) gets two substeps of 0.25 ms."""
    res = integrate(oscillator(0.5), 10.5e-3, "moreau", output_dt=1e-3, v0=[-1.5], step=3e-4)
    assert res.info["step_s"] == 2.5e-4  # output_dt / 4: a division by a power of two is exact
    assert res.info["steps"] == 42
    assert res.t[-1] == 10.5e-3 and res.t.size == 12  # the last output is t_end itself
    # no contact yet: theta = 1/2 is the trapezoidal rule, whose phase lags by w^3 h^2 t / 12:
    # 0.3 m x 6.8e-9 rad = 2.05e-9 m at t = 10.5 ms (measured 2.05e-9 m); allowed twice that
    w = math.sqrt(K1 / M1)
    np.testing.assert_allclose(res.q[0], -(1.5 / w) * np.sin(w * res.t), rtol=0, atol=4e-9)


def test_interrupt_returns_partial_result(monkeypatch):
    class Interrupting:
        calls = 0

        def __init__(self, *a, **k):
            pass

        def __call__(self, t, events):
            Interrupting.calls += 1
            if Interrupting.calls == 25:
                raise KeyboardInterrupt

        def close(self):
            pass

    monkeypatch.setattr(moreau, "Progress", Interrupting)
    res = integrate(oscillator(0.5), 1.0, "moreau", output_dt=1e-2, v0=[-1.5], step=1e-3)
    assert not res.completed
    assert res.t.size == 3 and res.t_end == 0.02  # two full output intervals (2 x 0.01 is exact)
    assert res.q.shape == (1, 3) and res.info["steps"] == 20
    # state and work terms are those of the last output: the (exact, theta = 1/2) balance closes there;
    # final_J is the same sum rounded in another order (a few eps)
    assert res.energy["final_J"] == pytest.approx(0.5 * M1 * res.v[0, -1] ** 2 + 0.5 * K1 * res.q[0, -1] ** 2,
                                                  rel=1e-14)
    assert res.energy["relative_residual"] < 1e-12  # 20 steps: 20 eps at most


def test_lcp_failure_raises_with_partial_result(monkeypatch):
    real = moreau.contact_lcp

    def failing(*args, **kw):
        lcp = real(*args, **kw)
        return SimpleNamespace(solve=lambda: lcp.solve(max_pivots=0))

    monkeypatch.setattr(moreau, "contact_lcp", failing)
    with pytest.raises(IntegrationError, match="moreau: contact LCP") as info:
        integrate(oscillator(0.5), 1.0, "moreau", output_dt=1e-2, v0=[-1.5], step=1e-3)
    res = info.value.result
    # first contact at t = 0.068 s: the last output (every 0.01 s) before it
    assert not res.completed and res.t[-1] < 0.07 < res.t[-1] + 0.02
    assert "error" in res.info


def test_too_many_steps_are_refused_before_running():
    with pytest.raises(NsfemError, match="moreau_step"):
        integrate(oscillator(0.5), 1.0, "moreau", 0.1, step=1e-12)
