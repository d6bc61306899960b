"""Orbits in a continuum (issue 36): a contact that sticks all period (nsfem.periodic.neutral).

The scene: a block (x1, y1) pressed on a floor by P (gap y1, Coulomb friction mu, plastic) and tied by a spring k and a
damper c to a forced mass x2 (m2 x2'' + c (x2' - x1') + k (x2 - x1) = F cos w t); the block also has a spring k0 to
the ground along x and ky, cy normal to the floor. While the block sticks (its tangential force within mu P) the
mass is a linear oscillator about the block: its orbit is the harmonic response x2 = x1 + A cos w t + B sin w t
(A = F (k - m2 w^2) / D, B = F c w / D, D = (k - m2 w^2)^2 + (c w)^2), whatever the stick position x1: the orbits
form a continuum, the monodromy maps the static shift (x1, x2) += (s, s) onto itself (a multiplier exactly +1) and
Phi_T - I is singular. The other multipliers are the mass's: exp(lambda T), m2 lambda^2 + c lambda + k = 0.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nsfem.contact import ContactSet
from nsfem.integrate import ContactSystem, integrate
from nsfem.periodic import periodic_orbit
from nsfem.periodic.neutral import NEUTRAL, deflated, newton_step, stick_continuum, stick_positions

M1, M2, K, C, K0, KY, CY, P, MU, F = 1.0, 1.0, 1.0, 0.1, 0.5, 100.0, 1.0, 10.0, 0.5, 0.5


def block_system(w: float, mu: float = MU) -> ContactSystem:
    """The block and the mass (module docstring), forced at w [rad/s]: q = (x1, y1, x2)."""
    Q = np.array([[K0 + K, 0, -K], [0, KY, 0], [-K, 0, K]])
    Cm = np.array([[C, 0, -C], [0, CY, 0], [-C, 0, C]])
    cs = ContactSet.from_arrays([[0.0], [1.0], [0.0]], [0.0], mu=mu, eps=0.0, JS=[np.array([[1.0], [0.0], [0.0]])])
    return ContactSystem.from_arrays(M=np.diag([M1, M1, M2]), Q=Q, C=Cm, f0=[0.0, -P, 0.0], fc=[0.0, 0.0, F],
                                     omega=w, contacts=cs)


def harmonic(w: float) -> tuple[float, float]:
    """(A, B) of the mass's response about the block (module docstring)."""
    D = (K - M2 * w * w) ** 2 + (C * w) ** 2
    return F * (K - M2 * w * w) / D, F * C * w / D


def mass_multipliers(w: float) -> np.ndarray:
    return np.exp(np.roots([M2, C, K]) * 2 * math.pi / w)


@pytest.mark.parametrize("x1", [0.0, 0.4, -1.2])
def test_a_sticking_block_is_an_orbit_of_a_continuum_with_a_neutral_multiplier(x1):
    """From the block stuck at x1 (at rest) and the mass at rest, the shooting converges to the orbit with the
    block at x1 (the start's stick position is kept: the step is the least-squares one off the continuum) and the
    mass's closed-form response; the multiplier +1 is flagged neutral and left out of the verdict; the others are
    the mass's exp(lambda T). The tangential force stays within the cone for these x1: |K0 x1 + k (A, B)| <= 1.85 <
    mu P = 5. Tolerances: the residual is below tol 1e-9 of the orbit's size, so the state is to ~1e-9 of it
    (J's condition on the complement ~ 1 / (1 - |mu_2|) = 1.3); the multipliers from an exact monodromy to
    round-off (1e-12) of entries of size ~1."""
    w = 1.3
    o = periodic_orbit(block_system(w), 2 * math.pi / w, [x1, 0.0, x1], [0.0, 0.0, 0.0])
    A, B = harmonic(w)
    size = max(abs(x1) + abs(A), 1.0)
    assert o.converged and o.residual <= 1e-9
    np.testing.assert_allclose(o.q0, [x1, 0.0, x1 + A], rtol=0, atol=1e-8 * size)
    np.testing.assert_allclose(o.v0, [0.0, 0.0, B * w], rtol=0, atol=1e-8 * size * w)
    assert len(o.neutral) == 1 and o.neutral[0]["note"] == NEUTRAL
    mu = np.asarray(o.multipliers)
    assert abs(mu[o.neutral[0]["index"]] - 1.0) <= 1e-10
    rest = np.delete(mu, o.neutral[0]["index"])
    assert np.abs(np.sort_complex(rest) - np.sort_complex(mass_multipliers(w))).max() <= 1e-10
    assert o.stable and o.loss is None


def test_the_mass_multipliers_are_the_transients_decay():
    """A transient from the orbit with the mass displaced by 1e-3 (the block stays stuck: its force changes by
    1e-3): the perturbations e_k of the mass's (x2, x2') at the sections k T obey e_(k+1) = A e_k exactly (the block
    sticks throughout, the motion is linear); A fitted by least squares over 8 periods has the shooting's two
    non-neutral multipliers as eigenvalues. The integrator's error (~1e-12 of states of size ~1, against
    perturbations >= 1e-3 * 0.785^8 = 1.4e-4) bounds the fit's relative error by ~1e-8: 1e-6."""
    w = 1.3
    T = 2 * math.pi / w
    o = periodic_orbit(block_system(w), T, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    periods = 8
    res = integrate(block_system(w), periods * T, "exact", output_dt=T, q0=o.q0 + [0.0, 0.0, 1e-3], v0=o.v0)
    e = np.stack([res.q[2] - o.q0[2], res.v[2] - o.v0[2]])[:, : periods + 1]
    np.testing.assert_allclose(res.q[0], o.q0[0], atol=1e-12)          # the block stuck throughout
    A = np.linalg.lstsq(e[:, :-1].T, e[:, 1:].T, rcond=None)[0].T
    rest = np.delete(np.asarray(o.multipliers), o.neutral[0]["index"])
    got = np.sort_complex(np.linalg.eigvals(A))
    assert np.abs(got - np.sort_complex(rest)).max() <= 1e-6 * np.abs(rest).max()


def test_without_a_stick_there_is_no_neutral_direction():
    """Friction too weak to hold the block (mu P = 0.05 < the mass's force ~0.7): the block slides, no continuum,
    nothing flagged (the start's flow slides at the section)."""
    w = 1.3
    o = periodic_orbit(block_system(w, mu=0.005), 2 * math.pi / w, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    assert o.neutral == []


def test_the_neutral_direction_is_the_static_shift_and_deflation_makes_j_regular():
    """stick_continuum finds (s, 0, s, 0, 0, 0) (the block and the mass shifted together) as Phi_T's fixed
    direction; Phi_T - I is singular along it (smallest singular value at round-off) and deflated(...) is regular
    (smallest singular value of order the others) with a step that keeps the stick position x1."""
    w = 1.3
    T = 2 * math.pi / w
    o = periodic_orbit(block_system(w), T, [0.2, 0.0, 0.2], [0.0, 0.0, 0.0])
    from nsfem.periodic.flow import flow

    fl = flow(block_system(w), 0.0, o.q0, o.v0, T)
    Z = o.directions
    scale = np.array([1, 1, 1, 1 / w, 1 / w, 1 / w])
    W = stick_continuum(fl.monodromy, Z, True, scale)
    assert W.shape == (6, 1)
    wv = W[:, 0] / W[0, 0]
    np.testing.assert_allclose(wv, [1, 0, 1, 0, 0, 0], atol=1e-10)
    J = fl.monodromy - np.eye(6)
    assert np.linalg.norm(J @ W) <= 1e-10 * np.linalg.norm(W)
    L = stick_positions(block_system(w), fl.start_mode)
    Jd = deflated(J, W, L, np.ones(6))
    s = np.linalg.svd(Jd, compute_uv=False)
    assert s[-1] >= 1e-3 * s[0]
    r = J @ np.array([0.1, 0.0, -0.3, 0.02, 0.0, 0.05])    # a residual in J's range
    dx = np.linalg.solve(Jd, -r)
    assert abs(L @ dx).max() <= 1e-12 and np.linalg.norm(J @ dx + r) <= 1e-12 * np.linalg.norm(r)


def test_a_branch_of_sticking_orbits_keeps_its_stick_position():
    """The continuation over w of the block stuck at x1 = 0.3 (its tangential force within the cone over 1.2-1.4
    rad/s: |K0 x1| + k |(A, B)| <= 0.15 + 1.2 < 5): without deflation J_u is singular along the continuum and the
    bordered corrector fails; with it every point is the closed-form orbit at the same stick position, its
    multiplier +1 at 1 and the others the mass's (tolerances as in the shooting's test above: 1e-8 of the orbit,
    the multipliers to 1e-10)."""
    from nsfem.periodic import orbit_branch

    x1 = 0.3
    A, B = harmonic(1.2)
    br = orbit_branch(block_system, lambda w: 2 * math.pi / w, [x1, 0.0, x1 + A], [0.0, 0.0, B * 1.2], 1.2, 1.4,
                      key="w", step=0.05, max_steps=20)
    assert br.stop == "end" and len(br.points) >= 4
    for pt in br.points:
        w = pt["value"]
        A, B = harmonic(w)
        size = abs(x1) + abs(A)
        np.testing.assert_allclose(pt["q0"], [x1, 0.0, x1 + A], rtol=0, atol=1e-8 * size)
        np.testing.assert_allclose(pt["v0"], [0.0, 0.0, B * w], rtol=0, atol=1e-8 * size * w)
        mu = np.array([complex(*m) for m in pt["multipliers"]])
        i = int(np.argmin(np.abs(mu - 1.0)))
        assert abs(mu[i] - 1.0) <= 1e-10
        assert np.abs(np.sort_complex(np.delete(mu, i)) - np.sort_complex(mass_multipliers(w))).max() <= 1e-10
        assert pt["stable"]


def test_the_verdict_and_json_name_the_neutral_multiplier():
    """nsfem periodic's verdict says the orbit is stable with one multiplier +1 neutral (not 'marginally' stable:
    that names undamped modes), and its JSON lists it under "neutral"."""
    from types import SimpleNamespace

    from nsfem.periodic.scene import SceneOrbit

    w = 1.3
    o = periodic_orbit(block_system(w), 2 * math.pi / w, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    so = SimpleNamespace(orbit=o)
    so.on_unit_circle = lambda: SceneOrbit.on_unit_circle(so)
    text = SceneOrbit.verdict(so)
    assert text.startswith("stable; 1 multiplier(s) +1 neutral (a continuum of stick positions")
    assert "marginally" not in text


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1), k=st.integers(1, 2))
def test_the_step_off_a_continuum_solves_the_consistent_system_and_keeps_the_stick_positions(seed, k):
    """For any J (2n x d on admissible directions Z) singular exactly along k static shifts W and a right-hand side
    in its range: newton_step's dz solves J dz = rhs (to round-off of J's condition on the complement, ~1e-12) with
    the stick positions L Z dz = 0; deflated(J_full) is regular and gives the same step (the system J dx = rhs,
    L dx = 0 has one solution: J's null space is W and L W is invertible)."""
    rng = np.random.default_rng(seed)
    n = 4
    Z = np.linalg.qr(rng.standard_normal((2 * n, 2 * n)))[0]          # all directions admissible
    W = np.zeros((2 * n, k))
    W[:n] = rng.standard_normal((n, k))                                 # static shifts
    L = np.hstack([rng.standard_normal((k, n)), np.zeros((k, n))])     # stick positions they move
    Pw = np.eye(2 * n) - W @ np.linalg.pinv(W)
    Jfull = rng.standard_normal((2 * n, 2 * n)) @ Pw                    # J W = 0
    rhs = Jfull @ rng.standard_normal(2 * n)
    dz = newton_step(Jfull @ Z, rhs, Z, W, L)
    dx = Z @ dz
    scale = np.linalg.norm(rhs) * np.linalg.cond(Jfull @ Pw + W @ W.T)
    assert np.linalg.norm(Jfull @ dx - rhs) <= 1e-10 * scale
    assert np.abs(L @ dx).max() <= 1e-10 * np.linalg.norm(dx) + 1e-300
    Jd = deflated(Jfull, W, L, np.ones(2 * n))
    dx2 = np.linalg.solve(Jd, rhs)
    # both are the one solution of J dx = rhs, L dx = 0 (L W invertible): equal to round-off times the conditions
    assert np.linalg.norm(dx2 - dx) <= 1e-13 * (np.linalg.cond(Jd) + scale / np.linalg.norm(rhs)) * np.linalg.norm(dx)
