"""The contact LCPs (28), (29), (30-32) against closed-form mechanics on small systems.

Every system here is a few rigid or spring-supported bodies whose contact state can be
worked out by hand (Signorini + Coulomb with the polygonal cone of eq. 20-21). The
closed forms are exact and the LCPs are tiny and well conditioned, so the builders + Lemke's
method (which re-solves and refines its final basis) must reproduce them to round-off:
RTOL below, relative to the problem's force / velocity / displacement scale. The random
systems of the hypothesis tests and the 64-gon cone have their own, derived tolerances.

Notation: a point mass or spring-supported point q = (x, y, z) touches the plane z = -c
(gap g = z + c: J_N = e_z, j_N = c); its tangent directions are e_x, e_y (J_S = [e_x, e_y]).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from nsfem.contact.set import ContactSet
from nsfem.errors import NsfemError
from nsfem.lcp import impact_lcp, stationary_lcp, transition_lcp
from nsfem.linalg import factorize

# The closed-form systems: final LCP bases of <= 6 unknowns with cond <= 9 (computed over the
# tests using RTOL; a z left alone in a basis is not unique and is not checked), operators
# Q, M with cond <= 6.1: the solution is good to n cond eps = 1.2e-14 relative, and a motion
# q = base + response can cancel terms up to 30 times the scale it is checked against
# (q_x = Fx/kx - Fx/kx = 0 vs c = 0.1): <= 3.6e-13. RTOL = 1e-12 is a margin of ~3 over that
# worst case (measured <= 14 eps = 3e-15; the former 1e-10 was 300x the bound).
RTOL = 1e-12
G = 9.81
E3 = np.eye(3)


def close(actual, expected, scale=1.0, rtol=RTOL):
    """Equal to rtol relative, with an absolute floor rtol * scale for entries that vanish."""
    np.testing.assert_allclose(np.asarray(actual, dtype=float), np.asarray(expected, dtype=float),
                               rtol=rtol, atol=rtol * scale)


def solved(lcp):
    res = lcp.solve()
    assert res.success, res.message
    return res.x


def plane(c=0.0, mu=0.0, r=4, tangents=2, eps=0.0):
    """The point q = (x, y, z) on the plane z = -c, friction along the first ``tangents`` axes."""
    JS = [E3[:, :tangents]] if tangents else None
    return ContactSet.from_arrays(E3[:, 2:], [c], mu=mu, eps=eps, JS=JS, r=r)


# ==================================================================================
# Stationary LCP (28): spring-supported point Q = diag(kx, ky, kz), load f0 = (Fx, Fy, -Fz)
# ==================================================================================
KX, KY, KZ = 2.0, 3.0, 5.0
Q3 = np.diag([KX, KY, KZ])


@pytest.mark.parametrize("Fx, Fy", [(0.0, 0.0), (1.5, -2.0)])
def test_stationary_closed_contact_carries_the_excess_load(Fx, Fy):
    # free deflection z0 = -Fz/kz = -2 overshoots the stop at z = -c = -0.1: the contact
    # closes, z = -c, and the spring force kz c balances Fz - lam_N: lam_N = Fz - kz c = 9.5.
    # Frictionless: the tangential deflections are the free ones Fx/kx, Fy/ky.
    c, Fz = 0.1, 10.0
    cs = plane(c=c)
    lcp = stationary_lcp(cs, factorize(Q3), np.array([Fx, Fy, -Fz]))
    assert lcp.size == 1 and lcp.friction.size == 0
    close(lcp.A, [[1.0 / KZ]])
    close(lcp.b, [c - Fz / KZ])  # the gap under f0 alone
    x = solved(lcp)
    lam = Fz - KZ * c
    close(x, [lam], scale=Fz)
    close(lcp.motion(x), [Fx / KX, Fy / KY, -c], scale=c)
    close(lcp.force(x), [0.0, 0.0, lam], scale=Fz)
    close(cs.gaps(lcp.motion(x)), [0.0], scale=c)


def test_stationary_open_contact_keeps_the_free_deflection():
    # c = 3 > Fz/kz = 2: the point stops short of the plane, gap = c - Fz/kz = 1, lam_N = 0,
    # and the LCP slack w is that gap.
    c, Fz = 3.0, 10.0
    cs = plane(c=c, mu=0.5)
    lcp = stationary_lcp(cs, factorize(Q3), np.array([1.0, 2.0, -Fz]))
    res = lcp.solve()
    assert res.success
    lam, beta, z = lcp.split(res.x)
    close(lam, [0.0], scale=Fz)
    close(beta, np.zeros(4), scale=Fz)
    close(res.w[:1], [c - Fz / KZ], scale=c)
    q = lcp.motion(res.x)
    close(q, [1.0 / KX, 2.0 / KY, -Fz / KZ], scale=c)
    close(cs.gaps(q), [1.0], scale=c)


@pytest.mark.parametrize("tangents", [1, 2])
@pytest.mark.parametrize("ratio", [-1.5, -0.7, 0.0, 0.7, 0.999, 1.001, 1.5])
def test_stationary_friction_along_x_sticks_below_mu_lam_and_slides_above(tangents, ratio):
    # lam_N = Fz - kz c = 9.5 (normal and tangential decouple: Q is diagonal, J_N _|_ J_S).
    # |Fx| <= mu lam_N: stick, x = 0, lam_T = -Fx, the slack z = 0.
    # |Fx| >  mu lam_N: slide, lam_T = -mu lam_N sign(Fx), x = (Fx + lam_T)/kx; the generator
    # opposing the slip carries beta, so its row e^T u + z = 0 gives z = |x|.
    # One tangent gives r = 2 (+-x); two tangents with r = 4 must give the same (Fy = 0).
    mu, c, Fz = 0.4, 0.1, 10.0
    lam = Fz - KZ * c
    Fx = ratio * mu * lam
    cs = plane(c=c, mu=mu, tangents=tangents)
    lcp = stationary_lcp(cs, factorize(Q3), np.array([Fx, 0.0, -Fz]))
    assert lcp.size == 1 + 2 * tangents + 1
    x = solved(lcp)
    lamN, _, z = lcp.split(x)
    q = lcp.motion(x)
    (lamT,) = lcp.tangential(x)
    close(lamN, [lam], scale=Fz)
    if abs(ratio) <= 1:
        close(lamT[0], -Fx, scale=Fz)
        close(q[0], 0.0, scale=c)
        close(z, [0.0], scale=c)
    else:
        close(lamT[0], -mu * lam * np.sign(Fx), scale=Fz)
        close(q[0], (Fx - mu * lam * np.sign(Fx)) / KX, scale=c)
        close(z, [abs(q[0])], scale=c)
    if tangents == 2:
        close(lamT[1], 0.0, scale=Fz)
    close(q[1:], [0.0, -c], scale=c)


@pytest.mark.parametrize("deg", [0.0, 10.0, 30.0, 45.0, 60.0, 135.0, 200.0, 290.0])
@pytest.mark.parametrize("s", [0.999, 1.001])
def test_stationary_oblique_load_stick_boundary_is_the_r4_diamond(deg, s):
    # r = 4 generators +-x, +-y span the diamond |lam_x| + |lam_y| <= mu lam_N: a tangential
    # load F_T sticks (zero slip, lam_T = -F_T) iff |Fx| + |Fy| <= mu lam_N, whatever the
    # (here unequal) tangential stiffnesses. Loads 0.1 % inside / outside that boundary.
    mu, c, Fz = 0.4, 0.1, 10.0
    lam = Fz - KZ * c
    t = np.radians(deg)
    F = s * mu * lam / (abs(np.cos(t)) + abs(np.sin(t))) * np.array([np.cos(t), np.sin(t)])
    cs = plane(c=c, mu=mu, r=4)
    lcp = stationary_lcp(cs, factorize(Q3), np.array([F[0], F[1], -Fz]))
    x = solved(lcp)
    lamN, beta, z = lcp.split(x)
    q = lcp.motion(x)
    (lamT,) = lcp.tangential(x)
    close(lamN, [lam], scale=Fz)
    if s < 1:
        close(q[:2], [0.0, 0.0], scale=c)
        close(lamT, -F, scale=Fz)
        close(z, [0.0], scale=c)
    else:
        assert np.linalg.norm(q[:2]) > 1e-5 * c and z[0] > 1e-5 * c
        close(np.abs(lamT).sum(), mu * lam, scale=Fz)  # on the diamond's boundary
        close(beta.sum(), mu * lam, scale=Fz)


def diamond_slide(F, N, mu, k):
    """Polygonal (r = 4) friction on a point with isotropic tangential stiffness k, load F.

    With p >= q >= 0 the load components' magnitudes (axes swapped if needed) and sliding
    (p + q > mu N): the friction minimizes u . lam over the diamond (maximal dissipation).
    If p - q >= mu N the vertex -mu N e_p is optimal (u_p >= |u_q|): lam = (-mu N, 0),
    u = ((p - mu N)/k, q/k). Otherwise lam lies on the edge between -e_p and -e_q, so
    u _|_ that edge: u_p = u_q, i.e. p - a = q - b with a + b = mu N:
    lam = -((mu N + p - q)/2, (mu N - p + q)/2), u = (p + q - mu N)/(2k) (1, 1).
    """
    sgn = np.where(F < 0, -1.0, 1.0)
    a = np.abs(F)
    swap = a[1] > a[0]
    p, q = (a[1], a[0]) if swap else (a[0], a[1])
    if p - q >= mu * N:
        lam, u = np.array([-mu * N, 0.0]), np.array([(p - mu * N) / k, q / k])
    else:
        lam = -0.5 * np.array([mu * N + p - q, mu * N - p + q])
        u = (p + q - mu * N) / (2 * k) * np.ones(2)
    if swap:
        lam, u = lam[::-1], u[::-1]
    return sgn * lam, sgn * u


@pytest.mark.parametrize("deg", [0.0, 15.0, 40.0, 45.0, 75.0, 160.0, 250.0, 330.0])
@pytest.mark.parametrize("s", [1.3, 3.0])
def test_stationary_r4_slide_matches_the_diamond_closed_form(deg, s):
    # see diamond_slide; kx = ky = k makes the edge case closed-form. s = 1.3 puts most
    # directions on an edge, s = 3 near the axes on a vertex.
    mu, c, Fz, k = 0.4, 0.1, 10.0, 2.0
    lam = Fz - KZ * c
    t = np.radians(deg)
    F = s * mu * lam * np.array([np.cos(t), np.sin(t)])
    cs = plane(c=c, mu=mu, r=4)
    lcp = stationary_lcp(cs, factorize(np.diag([k, k, KZ])), np.array([F[0], F[1], -Fz]))
    x = solved(lcp)
    lamT_exact, u_exact = diamond_slide(F, lam, mu, k)
    close(lcp.tangential(x)[0], lamT_exact, scale=Fz)
    close(lcp.motion(x)[:2], u_exact, scale=c)


@pytest.mark.parametrize("r", [8, 16, 64])
def test_stationary_slide_approaches_the_circular_cone(r):
    # The r-gon inscribed in the friction disc (vertices mu lam_N e_i) lies between the
    # discs of radius mu lam_N cos(pi/r) and mu lam_N, and maximal dissipation puts a sliding
    # friction force on its boundary within the angle pi/r of -u (the normal cone of a
    # vertex spans 2 pi/r; an edge's normal is pi/r from its ends). Both bounds are exact
    # properties of the polygonal law; they shrink to Coulomb's circle as r grows.
    # Tolerance: at r = 64 the final bases have 66 unknowns and cond <= 860, so the forces are
    # good to n cond eps = 1.3e-11 relative; tol = 1e-10 is a margin of 8. It matters only for
    # the upper bound, which a vertex meets with equality (measured excess 0.5 eps); the lower
    # and angle bounds hold with slack >= 5e-6.
    tol = 1e-10
    mu, c, Fz, k = 0.4, 0.1, 10.0, 2.0
    lam = Fz - KZ * c
    cs = plane(c=c, mu=mu, r=r)
    Qf = factorize(np.diag([k, k, KZ]))
    for deg in np.linspace(0.0, 360.0, 23)[:-1] + 1.7:
        t = np.radians(deg)
        F = 2.0 * mu * lam * np.array([np.cos(t), np.sin(t)])  # well outside the cone: slides
        lcp = stationary_lcp(cs, Qf, np.array([F[0], F[1], -Fz]))
        x = solved(lcp)
        (lamT,) = lcp.tangential(x)
        u = lcp.motion(x)[:2]
        mag = np.linalg.norm(lamT)
        assert mu * lam * np.cos(np.pi / r) * (1 - tol) <= mag <= mu * lam * (1 + tol)
        cosang = -(lamT @ u) / (mag * np.linalg.norm(u))
        assert cosang >= np.cos(np.pi / r) - tol
        # equilibrium of the tangential springs: k u = F + lam_T holds for any x (u is the
        # motion it produces through Q = diag(k, k, kz)), so RTOL: a few roundings of terms <= Fz
        close(k * u, F + lamT, scale=Fz)


def test_stationary_frictionless_contacts_have_no_tangential_unknowns():
    # mu = 0 drops J_S (even when given): the LCP has one row per contact, A = J_N^T Q^-1 J_N.
    JN = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    cs = ContactSet.from_arrays(JN, [0.1, 0.2], mu=0.0, JS=[E3[:, :2], E3[:, 1:]], r=4)
    Qm = np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 0.5], [0.0, 0.5, 2.0]])
    lcp = stationary_lcp(cs, factorize(Qm), np.array([-1.0, -2.0, -3.0]))
    assert lcp.size == 2 and lcp.friction.size == 0 and lcp.r.size == 0
    close(lcp.A, JN.T @ np.linalg.solve(Qm, JN))
    assert cs.frictional.size == 0 and all(S.shape == (3, 0) for S in cs.JS)


def test_stationary_only_the_listed_normal_contacts_enter():
    # normal=[1]: contact 0 (gap q, closed by the load) is left out; contact 1 alone is a
    # spring k = 2 pushed by f = -4 onto the stop gap g1 = q + 0.5: the free q = -2 gives
    # g1 = -1.5, so lam = 1.5 k = 3 and q = -0.5 (contact 0 then penetrates: g0 = -0.5).
    cs = ContactSet.from_arrays([[1.0, 1.0]], [0.0, 0.5])
    lcp = stationary_lcp(cs, factorize(np.array([[2.0]])), np.array([-4.0]), normal=[1])
    assert lcp.size == 1 and lcp.normal.tolist() == [1]
    x = solved(lcp)
    close(x, [3.0], scale=4.0)
    close(lcp.motion(x), [-0.5])


# ==================================================================================
# Transition LCP (29): a block of mass m on an incline at angle theta
# dofs (s, n): s down the slope, n the normal; f* = m g (sin theta, -cos theta)
# ==================================================================================
MASS = 2.0
INCLINE = ContactSet.from_arrays([[0.0], [1.0]], [0.0], mu=0.5, JS=[[[1.0], [0.0]]])  # gap n, slip s; r = 2


def incline_fstar(theta):
    return MASS * G * np.array([np.sin(theta), -np.cos(theta)])


@pytest.mark.parametrize("deg", [0.0, 20.0, 26.0, 27.0, 40.0, 70.0, -20.0, -40.0])
def test_transition_block_at_rest_on_incline_sticks_iff_tan_theta_le_mu(deg):
    # Closed contact at zero slip velocity (stick=[0]), mu = 0.5 (tan 26.57 deg = 0.5).
    # Normal: n'' = 0, lam_N = m g cos theta. Stick (tan|theta| <= mu): s'' = 0,
    # lam_T = -m g sin theta. Slide: lam_T = -mu lam_N sign(theta),
    # s'' = g (sin theta - mu cos theta sign(theta)), and z = |s''|.
    mu, th = 0.5, np.radians(deg)
    lcp = transition_lcp(INCLINE, factorize(MASS * np.eye(2)), incline_fstar(th), closed=[0], stick=[0])
    x = solved(lcp)
    lamN, _, z = lcp.split(x)
    a = lcp.motion(x)
    (lamT,) = lcp.tangential(x)
    scale = MASS * G
    close(lamN, [MASS * G * np.cos(th)], scale=scale)
    close(a[1], 0.0, scale=G)
    if abs(np.tan(th)) <= mu:
        close(a[0], 0.0, scale=G)
        close(lamT, [-MASS * G * np.sin(th)], scale=scale)
        close(z, [0.0], scale=G)
    else:
        sg = np.sign(th)
        close(a[0], G * (np.sin(th) - sg * mu * np.cos(th)), scale=G)
        close(lamT, [-sg * mu * MASS * G * np.cos(th)], scale=scale)
        close(z, [abs(a[0])], scale=G)


def test_transition_lifting_load_opens_the_contact():
    # f* pulls away from the plane: lam_N = 0, no friction, q'' = M^-1 f*. (The slack z is
    # then any value >= the slip acceleration |s''|, so it is not checked.)
    fstar = np.array([3.0, 5.0])
    lcp = transition_lcp(INCLINE, factorize(MASS * np.eye(2)), fstar, closed=[0], stick=[0])
    x = solved(lcp)
    lamN, beta, _ = lcp.split(x)
    close(np.concatenate([lamN, beta]), np.zeros(3), scale=G)
    close(lcp.motion(x), fstar / MASS, scale=G)


@pytest.mark.parametrize("deg", [10.0, 26.0, 40.0, 70.0])
def test_transition_sliding_block_decelerates_or_accelerates_by_coulomb(deg):
    # Already sliding down the slope (s' > 0): friction -mu lam_N along s, given as the
    # direction [-1] of the friction force (slide={0: [-1]}, stick=[]). Then the only
    # unknown is lam_N = m g cos theta and s'' = g (sin theta - mu cos theta), negative
    # (decelerating) when tan theta < mu. The generalized force includes the drag.
    mu, th = 0.5, np.radians(deg)
    lcp = transition_lcp(INCLINE, factorize(MASS * np.eye(2)), incline_fstar(th), closed=[0], stick=[],
                         slide={0: [-1.0]})
    assert lcp.size == 1
    x = solved(lcp)
    lam = MASS * G * np.cos(th)
    close(x, [lam], scale=MASS * G)
    close(lcp.motion(x), [G * (np.sin(th) - mu * np.cos(th)), 0.0], scale=G)
    close(lcp.force(x), [-mu * lam, lam], scale=MASS * G)


@pytest.mark.parametrize("deg", [0.0, 30.0, 135.0, 250.0])
def test_transition_sliding_on_a_plane_in_two_tangent_directions(deg):
    # A point mass sliding on the horizontal plane in direction d = (cos phi, sin phi) under
    # gravity: lam_N = m g, friction -mu m g d, acceleration -mu g d in the plane.
    mu, ph = 0.3, np.radians(deg)
    d = np.array([np.cos(ph), np.sin(ph)])
    cs = plane(mu=mu, r=8)
    lcp = transition_lcp(cs, factorize(MASS * np.eye(3)), np.array([0.0, 0.0, -MASS * G]), closed=[0], stick=[],
                         slide={0: -d})
    x = solved(lcp)
    close(x, [MASS * G], scale=MASS * G)
    close(lcp.motion(x), [*(-mu * G * d), 0.0], scale=G)


def painleve_rod(theta, mu):
    """Uniform rod (mass m, half-length l, I = m l^2/3) leaning at theta, lower end on the floor.

    Coordinates (x, y, phi) of the centre; the end sits at (x - l cos phi, y - l sin phi),
    linearized at phi = theta: gap row J_N = (0, 1, -l cos theta), slip row
    J_S = (1, 0, l sin theta). Returns (contact set, M, f*) with gravity only.
    """
    m, half = MASS, 0.7
    JN = np.array([[0.0], [1.0], [-half * np.cos(theta)]])
    JS = np.array([[1.0], [0.0], [half * np.sin(theta)]])
    M = np.diag([m, m, m * half**2 / 3])
    return ContactSet.from_arrays(JN, [0.0], mu=mu, JS=[JS]), M, np.array([0.0, -m * G, 0.0])


@pytest.mark.parametrize("sigma", [1.0, -1.0])
def test_transition_sliding_rod_normal_force_couples_to_friction(sigma):
    # Painleve's rod, end sliding with x_end' sign sigma: friction lam_T = -sigma mu lam_N.
    # Newton-Euler: m y'' = lam_N - m g, I phi'' = -l cos(theta) lam_N + l sin(theta) lam_T,
    # and the end stays on the floor, y'' - l cos(theta) phi'' = 0, give
    #     lam_N = m g / (1 + 3 cos theta (cos theta + sigma mu sin theta)).
    # The friction enters the normal row only through W_N = J_N + mu J_S e (e = -sigma).
    theta, mu = np.radians(50.0), 0.6
    cs, M, fstar = painleve_rod(theta, mu)
    lcp = transition_lcp(cs, factorize(M), fstar, closed=[0], stick=[], slide={0: [-sigma]})
    x = solved(lcp)
    lam = MASS * G / (1 + 3 * np.cos(theta) * (np.cos(theta) + sigma * mu * np.sin(theta)))
    close(x, [lam], scale=MASS * G)
    acc = lcp.motion(x)
    close(cs.JN[:, 0] @ acc, 0.0, scale=G)
    close(acc[:2], [-sigma * mu * lam / MASS, lam / MASS - G], scale=G)


def test_transition_painleve_paradox_has_no_consistent_contact_force():
    # For sigma = -1 and 1 + 3 cos(theta) (cos(theta) - mu sin(theta)) < 0 (theta = 60 deg,
    # mu = 2: 1.75 - 2.598 < 0) the 1 x 1 LCP has A < 0 and b = -g < 0: no lam_N >= 0 keeps
    # the end on the floor (Painleve's inconsistency); Lemke must say so, not return x.
    theta, mu = np.radians(60.0), 2.0
    cs, M, fstar = painleve_rod(theta, mu)
    lcp = transition_lcp(cs, factorize(M), fstar, closed=[0], stick=[], slide={0: [1.0]})
    assert lcp.A[0, 0] < 0 and lcp.b[0] < 0
    assert lcp.solve().status == "ray"


# ==================================================================================
# Impact LCP (30-32)
# ==================================================================================
@pytest.mark.parametrize("eps", [0.0, 0.5, 1.0])
def test_impact_frictionless_point_mass_restitutes_eps_vz(eps):
    # v- = (vx, vy, -vz) on the plane: Lambda_N = m (1 + eps) vz, v+ = (vx, vy, eps vz);
    # kinetic energy loss 0.5 m vz^2 (1 - eps^2), none for eps = 1.
    vx, vy, vz = 0.8, -0.3, 2.0
    cs = plane(eps=eps)
    v = np.array([vx, vy, -vz])
    lcp = impact_lcp(cs, factorize(MASS * np.eye(3)), v, active=[0])
    assert lcp.size == 1
    close(lcp.b, [-(1 + eps) * vz], scale=vz)
    x = solved(lcp)
    close(x, [MASS * (1 + eps) * vz], scale=MASS * vz)
    vp = lcp.motion(x)
    close(vp, [vx, vy, eps * vz], scale=vz)
    close(0.5 * MASS * (vp @ vp), 0.5 * MASS * (v @ v) - 0.5 * MASS * vz**2 * (1 - eps**2), scale=MASS * vz**2)


@pytest.mark.parametrize("eps", [0.0, 0.5, 1.0])
@pytest.mark.parametrize("vx", [-3.0, -1.0, 0.3, 0.9, 1.1, 3.0])
def test_impact_friction_stops_or_slows_the_tangential_velocity(eps, vx):
    # One tangent (r = 2). Normal and tangent decouple (M = m I): Lambda_N = m (1 + eps) vz.
    # Law (33) bounds the tangential impulse by mu times the TOTAL normal impulse:
    # |Lambda_T| <= mu Lambda_N, and it minimizes u+ . Lambda_T. So u+ = 0 if
    # m |vx| <= mu m (1 + eps) vz, else u+ = vx - mu (1 + eps) vz sign(vx) (same sign as vx).
    # With mu = 0.5, vz = 1: the threshold |vx| = 0.5 (1 + eps) is crossed within the list.
    mu, vz = 0.5, 1.0
    cs = plane(mu=mu, eps=eps, tangents=1)
    v = np.array([vx, 0.0, -vz])
    lcp = impact_lcp(cs, factorize(MASS * np.eye(3)), v, active=[0])
    x = solved(lcp)
    lamN, _, z = lcp.split(x)
    vp = lcp.motion(x)
    (lamT,) = lcp.tangential(x)
    close(lamN, [MASS * (1 + eps) * vz], scale=MASS * vz)
    close(vp[2], eps * vz, scale=vz)
    thr = mu * (1 + eps) * vz
    if abs(vx) <= thr:
        close(vp[0], 0.0, scale=vz)
        close(lamT, [-MASS * vx], scale=MASS * vz)
    else:
        close(vp[0], vx - thr * np.sign(vx), scale=vz)
        close(lamT, [-MASS * thr * np.sign(vx)], scale=MASS * vz)
        close(z, [abs(vp[0])], scale=vz)
    # a single decoupled contact never gains energy; here it loses >= 8 % in every case, so
    # RTOL only absorbs the round-off of the two dot products (a few eps)
    assert vp @ vp <= v @ v * (1 + RTOL)


@pytest.mark.parametrize("deg", [0.0, 20.0, 45.0, 100.0, 225.0, 300.0])
@pytest.mark.parametrize("s", [0.999, 1.001, 2.0])
def test_impact_oblique_tangential_velocity_and_the_r4_diamond(deg, s):
    # r = 4: the tangential impulse lies in the diamond |L_x| + |L_y| <= mu Lambda_N, so the
    # contact sticks (u+ = 0) iff m (|vx| + |vy|) <= mu Lambda_N = mu m (1 + eps) vz.
    # Sliding: the diamond closed form of diamond_slide with "load" m u-, "stiffness" m.
    mu, eps, vz = 0.5, 0.4, 1.0
    N = MASS * (1 + eps) * vz
    t = np.radians(deg)
    u = s * mu * (1 + eps) * vz / (abs(np.cos(t)) + abs(np.sin(t))) * np.array([np.cos(t), np.sin(t)])
    cs = plane(mu=mu, eps=eps, r=4)
    lcp = impact_lcp(cs, factorize(MASS * np.eye(3)), np.array([u[0], u[1], -vz]), active=[0])
    x = solved(lcp)
    vp = lcp.motion(x)
    (lamT,) = lcp.tangential(x)
    close(vp[2], eps * vz, scale=vz)
    if s < 1:
        close(vp[:2], [0.0, 0.0], scale=vz)
        close(lamT, -MASS * u, scale=MASS * vz)
    else:
        lam_exact, u_exact = diamond_slide(MASS * u, N, mu, MASS)
        close(lamT, lam_exact, scale=MASS * vz)
        close(vp[:2], u_exact, scale=vz)


def test_impact_separating_contact_gets_no_impulse():
    # g'- = +1 > 0 (already separating, but listed active): Lambda_N = 0, no friction impulse,
    # v+ = v- (the slack z, a multiplier free above |u|, is not unique and not checked).
    cs = plane(mu=0.5, eps=0.5)
    v = np.array([1.0, -2.0, 1.0])
    lcp = impact_lcp(cs, factorize(MASS * np.eye(3)), v, active=[0])
    x = solved(lcp)
    lamN, beta, _ = lcp.split(x)
    close(np.concatenate([lamN, beta]), np.zeros(5), scale=MASS)
    close(lcp.motion(x), v)


def bar(I_over_ml2, half=1.0, m=1.0, eps=0.0):
    """Rigid bar, dofs (heave y, pitch phi), M = diag(m, I); supports under x = -l, +l (l = half).

    Gaps g1 = y - l phi, g2 = y + l phi (+ 0): J_N = [[1, 1], [-l, l]].
    """
    cs = ContactSet.from_arrays([[1.0, 1.0], [-half, half]], [0.0, 0.0], eps=eps)
    return cs, np.diag([m, I_over_ml2 * m * half**2])


@pytest.mark.parametrize("I_rel, v, w, lam_exact, vplus", [
    # Both impulses positive: v+ = 0 (eps = 0), so m v = L1 + L2 and I w = l (L1 - L2):
    # L1 = (m v + I w / l)/2, L2 = (m v - I w / l)/2, valid while m v >= I |w| / l.
    (1 / 3, 1.0, 0.6, [0.6, 0.4], [0.0, 0.0]),           # uniform bar, I = m l^2/3
    (2.0, 1.0, 0.2, [0.7, 0.3], [0.0, 0.0]),
    # I = 2 m l^2, g1'- = -v - l w = -3, g2'- = -v + l w = -0.5 (both approaching): with
    # contact 1 alone, L1 = -g1'- / (1/m + l^2/I) = 2 and g2'+ = g2'- + L1 (1/m - l^2/I) =
    # 0.5 >= 0, so contact 2 gets no impulse although it was approaching; y'+ = -v + L1/m =
    # 0.25, phi'+ = w - l L1 / I = 0.25.
    (2.0, 1.75, 1.25, [2.0, 0.0], [0.25, 0.25]),
])
def test_impact_two_point_bar(I_rel, v, w, lam_exact, vplus):
    cs, M = bar(I_rel)
    vm = np.array([-v, w])
    assert np.all(cs.JN.T @ vm < 0)
    lcp = impact_lcp(cs, factorize(M), vm, active=[0, 1])
    res = lcp.solve()
    assert res.success
    close(res.x, lam_exact, scale=v)
    vp = lcp.motion(res.x)
    close(vp, vplus, scale=v)
    gp = cs.JN.T @ vp
    assert np.all(gp >= -RTOL * v)          # g'+ = 0 to round-off (cond 3) or 0.5 v
    close(res.x * gp, [0.0, 0.0], scale=v**2)
    assert vp @ M @ vp <= vm @ M @ vm       # no tolerance: the kinetic energy drops by >= 97 %


def test_impact_bar_with_restitution_solves_the_2x2_system():
    # eps = 0.5, both contacts active with the data of the first case above (uniform bar):
    # G L = -(1 + eps) g'-, G = J_N^T M^-1 J_N = [[1/m + l^2/I, 1/m - l^2/I], [.., ..]] =
    # [[4, -2], [-2, 4]] (m = l = 1, I = 1/3), g'- = (-1.6, -0.4):
    # L = 1.5 G^-1 (1.6, 0.4) = (0.9, 0.6) > 0, g'+ = -eps g'- = (0.8, 0.2).
    cs, M = bar(1 / 3, eps=0.5)
    vm = np.array([-1.0, 0.6])
    lcp = impact_lcp(cs, factorize(M), vm, active=[0, 1])
    x = solved(lcp)
    close(lcp.A, [[4.0, -2.0], [-2.0, 4.0]])
    close(x, [0.9, 0.6])
    close(cs.JN.T @ lcp.motion(x), [0.8, 0.2])


def test_impact_closed_separating_contact_does_not_penetrate_after_the_impact():
    # Uniform bar (as above), both ends closed (g = 0), eps = 0.5, g'- = (-1, +0.1): end 1
    # hits, end 2 lifts off slowly. An impulse at end 1 pushes end 2 down (1/m - l^2/I = -2/m),
    # so end 2 needs an impulse too. Physically g'+_2 >= 0 (no penetration of a closed contact),
    # e.g. restitution only of approach velocities, b_N = g'- + eps min(g'-, 0):
    # G L = (1.5, -0.1) -> L = (0.4833, 0.2167), g'+ = (0.5, 0). The builder's
    # b_N = (1 + eps) g'- gives L = (0.475, 0.2), g'+_2 = -eps g'-_2 = -0.05 < 0.
    cs, M = bar(1 / 3, eps=0.5)
    vm = np.linalg.solve(cs.JN.T, [-1.0, 0.1])
    lcp = impact_lcp(cs, factorize(M), vm, active=[0, 1])
    x = solved(lcp)
    assert np.all(cs.JN.T @ lcp.motion(x) >= -RTOL)   # g'+_2 = 0 to round-off (cond 3, |v| ~ 1)


# ----------------------------------------------------------------------------------
# properties of the contact laws on random systems (hypothesis)
# ----------------------------------------------------------------------------------
# Tolerance of the random systems below (relative to the scales each check names): cond(M)
# and the normalized Gram cond are < 1e3 (random_system), n <= 8 dofs and <= 20 LCP unknowns:
# n cond eps = 4.4e-12. RANDOM_TOL = 1e-10 is a margin of 23 over that worst case (the
# examples are drawn afresh on every run, so the margin is kept wide; the LCP bases of the
# friction rows are not covered by the Gram bound). Measured over ~6000 draws: <= 76 eps =
# 1.7e-14. (The former 1e-9 was 230x the bound.)
RANDOM_TOL = 1e-10


def random_system(seed, n, m, dims, cond_max=1e3):
    """SPD M and contact Jacobians [J_N, J_S] of full column rank, Gram-conditioned."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    M = A @ A.T + 0.5 * np.eye(n)
    JN = rng.normal(size=(n, m))
    JS = [rng.normal(size=(n, d)) for d in dims]
    W = np.hstack([JN, *JS])
    Gm = W.T @ np.linalg.solve(M, W)
    dg = np.sqrt(np.diag(Gm))
    assume(np.linalg.cond(M) < cond_max and np.linalg.cond(Gm / np.outer(dg, dg)) < cond_max)
    return rng, M, JN, JS


def assert_coulomb(lcp, cs, x, slips, tol):
    """Each friction contact: lam_T = B beta in the polygon 1^T beta <= mu lam_N, and maximal
    dissipation lam_T . u = mu lam_N min_i e_i . u (the minimum of u . lam over the polygon)
    for the slip (rate) u the motion produces, checked from the motion, not from the LCP rows.
    """
    lamN, beta, _ = lcp.split(x)
    pos = {int(k): j for j, k in enumerate(lcp.normal)}
    row = 0
    for i, k in enumerate(lcp.friction):
        rk = int(lcp.r[i])
        b = beta[row:row + rk]
        row += rk
        lam = lamN[pos[int(k)]]
        lamT = lcp.tangential(x)[i]
        u = slips[i]
        B = cs.generators(int(k))
        assert np.all(b >= -tol) and cs.mu[k] * lam - b.sum() >= -tol
        scale = max(1.0, np.linalg.norm(u)) * max(1.0, lam)
        assert abs(lamT @ u - cs.mu[k] * lam * min(B.T @ u)) <= tol * scale


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(seed=st.integers(0, 2**32 - 1), m=st.integers(1, 3), extra=st.integers(1, 3),
       eps=st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3))
def test_impact_frictionless_energy_never_increases_and_is_kept_at_eps_one(seed, m, extra, eps):
    # Frictionless, active = approaching contacts (g'- <= 0):
    # Delta T = Lambda^T g'- + 0.5 Lambda^T G Lambda with G Lambda = g'+ - g'- and
    # Lambda_i (g'+_i + eps_i g'-_i) = 0 give Delta T = 0.5 sum Lambda_i (1 - eps_i) g'-_i <= 0,
    # = 0 when all eps = 1. Tolerances RANDOM_TOL of |g'-| and of T (see random_system).
    n = m + extra
    rng, M, JN, _ = random_system(seed, n, m, [])
    e = np.array(eps[:m])
    cs = ContactSet.from_arrays(JN, np.zeros(m), eps=e)
    v = rng.normal(size=n)
    active = np.flatnonzero(JN.T @ v <= 0)
    assume(active.size > 0)
    lcp = impact_lcp(cs, factorize(M), v, active)
    x = solved(lcp)
    vp = lcp.motion(x)
    T0, T1 = 0.5 * v @ M @ v, 0.5 * vp @ M @ vp
    gm, gp = JN[:, active].T @ v, JN[:, active].T @ vp
    w = gp + e[active] * gm
    tol = RANDOM_TOL
    assert np.all(x >= 0) and np.all(w >= -tol * np.abs(gm).max())
    assert np.all(np.abs(x * w) <= tol * (1 + x) * np.abs(gm).max())
    close_energy = 0.5 * np.sum(x * (1 - e[active]) * gm)
    assert abs((T1 - T0) - close_energy) <= tol * T0
    assert T1 <= T0 * (1 + tol)
    e1 = ContactSet.from_arrays(JN, np.zeros(m), eps=1.0)
    lcp1 = impact_lcp(e1, factorize(M), v, active)
    v1 = lcp1.motion(solved(lcp1))
    assert abs(0.5 * v1 @ M @ v1 - T0) <= tol * T0


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(seed=st.integers(0, 2**32 - 1), m=st.integers(1, 2), extra=st.integers(0, 2),
       mu=st.lists(st.floats(0.0, 1.0), min_size=2, max_size=2),
       eps=st.lists(st.floats(0.0, 1.0), min_size=2, max_size=2), r=st.sampled_from([2, 4, 6, 8]))
def test_impact_frictional_laws_hold_and_eps_zero_dissipates(seed, m, extra, mu, eps, r):
    # Full column rank [J_N, J_S] (n >= 3 m): there is v' with J_N^T v' = (1 + eps) g'- and
    # J_S^T v' = J_S^T v-, so the LCP is the eps = 0 LCP of v', solvable (M pd). Checked from
    # the motion: 0 <= g'+ + eps g'- _|_ Lambda_N >= 0 and Coulomb's law (33) on u+.
    # Energy: with eps = 0, Delta T = P^T v+ - 0.5 dv^T M dv with P^T v+ = Lambda^T g'+ +
    # lam_T . u+ = 0 - mu Lambda z <= 0 (Moreau): never increases. With eps > 0 and friction
    # no such bound holds (Kane's paradox: Newton's kinematic restitution can gain energy),
    # so energy is only checked for eps = 0.
    n = 3 * m + extra
    rng, M, JN, JS = random_system(seed, n, m, [2] * m)
    Mf = factorize(M)
    v = rng.normal(size=n)
    active = np.flatnonzero(JN.T @ v <= 0)
    assume(active.size > 0)
    tol = RANDOM_TOL
    for e in (np.zeros(m), np.array(eps[:m])):
        cs = ContactSet.from_arrays(JN, np.zeros(m), mu=mu[:m], eps=e, JS=JS, r=r)
        lcp = impact_lcp(cs, Mf, v, active)
        x = solved(lcp)
        vp = lcp.motion(x)
        close(M @ (vp - v), lcp.force(x), scale=1 + np.abs(lcp.force(x)).max(), rtol=tol)
        gm, gp = JN[:, active].T @ v, JN[:, active].T @ vp
        lamN = lcp.split(x)[0]
        w = gp + e[active] * gm
        sc = np.abs(v).max() * (1 + np.abs(x).max())
        assert np.all(lamN >= 0) and np.all(w >= -tol * sc) and np.all(np.abs(lamN * w) <= tol * sc**2)
        assert_coulomb(lcp, cs, x, [cs.JS[k].T @ vp for k in lcp.friction], tol * sc)
        if not e.any():
            assert vp @ M @ vp <= v @ M @ v * (1 + tol)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(seed=st.integers(0, 2**32 - 1), m=st.integers(1, 2), extra=st.integers(0, 2),
       mu=st.floats(0.0, 1.0), r=st.sampled_from([2, 4, 8]))
def test_stationary_and_transition_solutions_satisfy_the_contact_laws(seed, m, extra, mu, r):
    # Stationary (22-24 with Q, displacement-level friction): Q q = f0 + W x,
    # 0 <= g(q) _|_ lam_N >= 0, Coulomb on the tangential displacement J_S^T q.
    # Transition (29), all contacts closed and sticking: M q'' = f* + W x,
    # 0 <= J_N^T q'' _|_ lam_N >= 0, Coulomb on the slip acceleration J_S^T q''.
    n = 3 * m + extra
    rng, M, JN, JS = random_system(seed, n, m, [2] * m)
    cs = ContactSet.from_arrays(JN, rng.uniform(-0.5, 0.5, m), mu=mu, JS=JS, r=r)
    f = rng.normal(size=n)
    tol = RANDOM_TOL
    for kind in ("stationary", "transition"):
        lcp = (stationary_lcp(cs, factorize(M), f) if kind == "stationary" else
               transition_lcp(cs, factorize(M), f, closed=np.arange(m), stick=np.arange(m) if mu > 0 else []))
        x = solved(lcp)
        q = lcp.motion(x)
        sc = (1 + np.abs(x).max()) * (1 + np.abs(q).max())
        close(M @ q, f + lcp.force(x), scale=sc, rtol=tol)
        g = cs.gaps(q) if kind == "stationary" else JN.T @ q
        lamN = lcp.split(x)[0]
        assert np.all(lamN >= 0) and np.all(g >= -tol * sc) and np.all(np.abs(lamN * g) <= tol * sc**2)
        assert_coulomb(lcp, cs, x, [cs.JS[k].T @ q for k in lcp.friction], tol * sc)


# ==================================================================================
# Structure of the assembled LCP and of the contact set
# ==================================================================================
# (RTOL here: products of O(1) matrices and solves with cond(Q) = 2.4, or angles from
# arctan2: a few eps, measured <= 6 eps; RTOL = 1e-12 leaves a margin of ~100)
def mixed_set():
    """Three contacts in 4 dofs: 0 with two tangents (r = 6), 1 frictionless, 2 with one (r -> 2)."""
    rng = np.random.default_rng(7)
    JN = rng.normal(size=(4, 3))
    JS = [rng.normal(size=(4, 2)), rng.normal(size=(4, 2)), rng.normal(size=(4, 1))]
    return ContactSet.from_arrays(JN, [0.1, -0.2, 0.3], mu=[0.3, 0.0, 0.5], eps=[0.2, 0.4, 0.9], JS=JS, r=6,
                                  labels=["a", "b", "c"]), rng


def test_lcp_blocks_and_maps_are_consistent():
    cs, rng = mixed_set()
    assert cs.r.tolist() == [6, 0, 2] and [S.shape[1] for S in cs.JS] == [2, 0, 1]
    Qm = rng.normal(size=(4, 4)) + 4 * np.eye(4)  # non-symmetric (Q = K + P): S = Q^-1, not Q^-T
    f0 = rng.normal(size=4)
    lcp = stationary_lcp(cs, factorize(Qm), f0)
    m, p, nf = 3, 8, 2
    assert lcp.size == m + p + nf
    assert lcp.normal.tolist() == [0, 1, 2] and lcp.friction.tolist() == [0, 2] and lcp.r.tolist() == [6, 2]
    JT = np.hstack([cs.JS[0] @ cs.generators(0), cs.JS[2] @ cs.generators(2)])
    W = np.hstack([cs.JN, JT])
    Sinv = np.linalg.inv(Qm)
    q0 = Sinv @ f0
    close(lcp.W, W)
    close(lcp.A[: m + p, : m + p], W.T @ Sinv @ W)
    E = np.zeros((p, nf))
    E[:6, 0] = E[6:, 1] = 1.0
    close(lcp.A[m: m + p, m + p:], E)
    close(lcp.A[m + p:, m: m + p], -E.T)
    close(lcp.A[m + p:, :m], [[0.3, 0.0, 0.0], [0.0, 0.0, 0.5]])
    close(lcp.A[:m, m + p:], np.zeros((m, nf)))
    close(lcp.A[m + p:, m + p:], np.zeros((nf, nf)))
    close(lcp.b, np.concatenate([cs.JN.T @ q0 + cs.jN, JT.T @ q0, np.zeros(nf)]))
    close(lcp.base, q0)
    x = rng.uniform(0.1, 1.0, size=lcp.size)
    lamN, beta, z = lcp.split(x)
    assert (lamN.size, beta.size, z.size) == (m, p, nf)
    close(np.concatenate([lamN, beta, z]), x)
    force = cs.JN @ lamN + JT @ beta
    close(lcp.force(x), force)
    close(lcp.response(x), np.linalg.solve(Qm, force))
    close(lcp.motion(x), q0 + np.linalg.solve(Qm, force))
    tang = lcp.tangential(x)
    assert [t.shape for t in tang] == [(2,), (1,)]
    close(tang[0], cs.generators(0) @ beta[:6])
    close(tang[1], cs.generators(2) @ beta[6:])
    # the tangential forces map to the generalized force through J_S
    close(cs.JN @ lamN + cs.JS[0] @ tang[0] + cs.JS[2] @ tang[1], force)


def test_lcp_rows_follow_the_order_of_the_normal_contacts():
    # normal=[2, 0]: the friction contacts follow that order, mu sits in the column of its
    # own normal force, E keeps the block sizes (2 for contact 2, then 6 for contact 0).
    cs, rng = mixed_set()
    Qm = np.diag([1.0, 2.0, 3.0, 4.0])
    lcp = stationary_lcp(cs, factorize(Qm), rng.normal(size=4), normal=[2, 0])
    assert lcp.normal.tolist() == [2, 0] and lcp.friction.tolist() == [2, 0] and lcp.r.tolist() == [2, 6]
    m, p = 2, 8
    close(lcp.A[m + p:, :m], [[0.5, 0.0], [0.0, 0.3]])
    E = np.zeros((p, 2))
    E[:2, 0] = E[2:, 1] = 1.0
    close(lcp.A[m: m + p, m + p:], E)
    JT = np.hstack([cs.JS[2] @ cs.generators(2), cs.JS[0] @ cs.generators(0)])
    close(lcp.W, np.hstack([cs.JN[:, [2, 0]], JT]))


def test_impact_and_transition_right_hand_sides():
    # impact: b = (g' + eps min(g', 0), J_T^T v, 0) with g' = J_N^T v; transition: b = (J_N^T M^-1 f*, J_T^T M^-1 f*, 0)
    # with only the `stick` contacts carrying friction rows, and a sliding contact's W_N column
    # J_N + mu J_S e.
    cs, rng = mixed_set()
    Mm = np.diag([1.0, 2.0, 3.0, 4.0])
    v = rng.normal(size=4)
    lcp = impact_lcp(cs, factorize(Mm), v, active=[0, 1, 2])
    JT = cs.JT([0, 2])
    gv = cs.JN.T @ v
    close(lcp.b, np.concatenate([gv + cs.eps * np.minimum(gv, 0.0), JT.T @ v, np.zeros(2)]))
    close(lcp.base, v)
    fs = rng.normal(size=4)
    e0 = np.array([0.6, 0.8])
    tr = transition_lcp(cs, factorize(Mm), fs, closed=[0, 1, 2], stick=[2], slide={0: e0})
    a0 = fs / np.diag(Mm)
    assert tr.friction.tolist() == [2] and tr.size == 3 + 2 + 1
    close(tr.b, np.concatenate([cs.JN.T @ a0, cs.JT([2]).T @ a0, [0.0]]))
    WN = cs.JN.copy()
    WN[:, 0] += 0.3 * cs.JS[0] @ e0
    close(tr.W, np.hstack([WN, cs.JT([2])]))
    close(tr.A[:3, :3], cs.JN.T @ np.linalg.solve(Mm, WN))  # rows: gap kinematics, J_N (not W_N)


@pytest.mark.parametrize("r", [2, 4, 6, 8, 12, 32])
def test_generators_are_unit_vectors_in_opposite_pairs(r):
    cs = plane(mu=0.3, r=r)
    B = cs.generators(0)
    d = 1 if r == 2 else 2  # r = 2 on a plane keeps the first tangent only (the second is frictionless)
    assert B.shape == (d, r) and cs.JS[0].shape == (3, d)
    close(np.linalg.norm(B, axis=0), np.ones(r))
    close(B.sum(axis=1), np.zeros(d), scale=1.0)
    close(B[:, : r // 2], -B[:, r // 2:])  # e_i = -e_{i + r/2}
    if r == 2:
        close(B, [[1.0, -1.0]])  # along the first tangent
    else:
        ang = np.arctan2(B[1], B[0]) % (2 * np.pi)
        close(ang, 2 * np.pi * np.arange(r) / r, scale=1.0)
    close(cs.JT([0]), E3[:, :d] @ B)
    close(cs.E([0]), np.ones((r, 1)))


def test_one_tangent_direction_gives_two_generators():
    cs = ContactSet.from_arrays(E3[:, 2:], [0.0], mu=0.3, JS=[E3[:, 0]], r=8)
    assert cs.r.tolist() == [2]
    close(cs.generators(0), [[1.0, -1.0]])
    close(cs.JT([0]), np.column_stack([E3[:, 0], -E3[:, 0]]))


def test_block_diagonal_E_and_stacked_JT():
    cs, _ = mixed_set()
    E = cs.E([2, 0])
    expect = np.zeros((8, 2))
    expect[:2, 0] = expect[2:, 1] = 1.0
    close(E, expect)
    assert cs.JT([]).shape == (4, 0) and cs.E([]).shape == (0, 0)
    close(cs.JT([2, 0]), np.hstack([cs.JS[2] @ cs.generators(2), cs.JS[0] @ cs.generators(0)]))


def test_subset_keeps_the_given_order():
    cs, _ = mixed_set()
    sub = cs.subset([2, 0])
    close(sub.JN, cs.JN[:, [2, 0]])
    close(sub.jN, [0.3, 0.1])
    close(sub.mu, [0.5, 0.3])
    close(sub.eps, [0.9, 0.2])
    assert sub.r.tolist() == [2, 6] and sub.labels == ("c", "a") and sub.tangents == (("t1",), ("t1", "t2"))
    close(sub.JS[0], cs.JS[2])
    close(sub.JS[1], cs.JS[0])
    close(sub.generators(1), cs.generators(0))
    assert sub.m == 2 and sub.n == 4


def test_gaps_and_slip():
    cs, rng = mixed_set()
    q = rng.normal(size=4)
    close(cs.gaps(q), cs.JN.T @ q + cs.jN)
    qs = rng.normal(size=(4, 5))
    close(cs.gaps(qs), cs.JN.T @ qs + cs.jN[:, None])
    close(cs.slip(0, q), cs.JS[0].T @ q)


@pytest.mark.parametrize("kwargs, match", [
    (dict(jN=[0.0, 0.0]), "j_N"),
    (dict(mu=-0.1), "mu"),
    (dict(eps=-0.1), "eps"),
    (dict(eps=1.5), "eps"),
    (dict(r=3), "even"),
    (dict(r=0), "even"),
    (dict(JS=[np.eye(3)]), "tangent directions"),
    (dict(JN=[[np.nan], [0.0], [1.0]]), "finite"),
    (dict(JS=[E3[:, [0, 2]]]), "dependent"),            # a tangent along the normal
    (dict(JS=[np.array([[1.0, 2.0], [0, 0], [0, 0]])]), "dependent"),   # two parallel tangents
    (dict(JN=[[0.0], [1.0]], JS=[np.eye(2)]), "dependent"),              # 2 dofs: no room for 2 tangents
])
def test_from_arrays_rejects_bad_input(kwargs, match):
    args = dict(JN=E3[:, 2:], jN=[0.0], mu=0.3, eps=0.5, JS=[E3[:, :2]], r=4)
    args.update(kwargs)
    with pytest.raises(NsfemError, match=match):
        ContactSet.from_arrays(**args)


def test_from_arrays_rejects_a_transposed_slip_jacobian():
    # J_S given as rows (2 x 3) instead of columns (3 x 2): reshape(3, -1) of the row-major
    # data makes [[1, 0], [0, 0], [1, 0]] -- tangents e_x + e_z and 0 -- without complaint.
    with pytest.raises(NsfemError):
        ContactSet.from_arrays(E3[:, 2:], [0.0], mu=0.3, JS=[E3[:2]])


def test_transition_lcp_rejects_inconsistent_configurations():
    """stick/slide contacts must be closed, not both, with a unit slide direction of d_k components."""
    cs = ContactSet.from_arrays(np.eye(3)[:, 2:], [0.0], mu=0.3, JS=[np.eye(3)[:, :2]])
    M = factorize(np.eye(3))
    f = np.array([0.0, 0.0, -1.0])
    for kw, match in (({"closed": [], "stick": [0]}, "not closed"),
                      ({"closed": [0], "stick": [0], "slide": {0: [1.0, 0.0]}}, "both"),
                      ({"closed": [0], "stick": [], "slide": {0: [1.0]}}, "unit vector with 2"),
                      ({"closed": [0], "stick": [], "slide": {0: [2.0, 0.0]}}, "unit vector")):
        with pytest.raises(NsfemError, match=match):
            transition_lcp(cs, M, f, **kw)
    # a frictionless contact listed as sticking gets no tangential unknowns
    free = ContactSet.from_arrays(np.eye(3)[:, 2:], [0.0])
    assert transition_lcp(free, M, f, closed=[0], stick=[0]).size == 1


@pytest.mark.parametrize("kw, match", [({"mu": [0.1, 0.2]}, "mu needs one value"),
                                       ({"eps": [np.nan]}, "eps must be finite"),
                                       ({"mu": 0.3, "JS": []}, "JS needs one entry")])
def test_from_arrays_rejects_per_contact_arrays_of_the_wrong_length(kw, match):
    with pytest.raises(NsfemError, match=match):
        ContactSet.from_arrays(np.eye(3)[:, 2:], [0.0], **kw)
