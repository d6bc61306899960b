"""The synchronous full annular rub on a round ring: a reference for the periodic-orbit code (issue 36).

Plain NumPy/SciPy from a system's matrices (no nsfem contact or integrator code), in the rotating
frame, where the synchronous rub of an axisymmetric rotor is a state at rest:

    M q'' + C q' + Q q = f0 + D^T F,    u = D q (the disk centre's lateral displacement, 2 x n rows),

inside a round ring of radius c (the clearance) with Coulomb friction mu. In contact |u| = c; with
n = u / |u| the outward normal and t = J n (J the quarter turn, e_x x n) the circumferential tangent,
the ring pushes with the normal force N >= 0 and friction mu N against the slip,

    F = -N (n + mu s t),    s = sign(t . u_slip'),

where the slip velocity of the shaft's surface (radius R) on the ring, which turns at -Omega in this
frame, is t.u' + Omega (n.u + R): s = sign(Omega) at rest (Omega (c + R) != 0).

*Stationary state.* Q q = f0 - N D^T (I + mu s J) n with D q = c n. With H = D Q^-1 D^T and
b = D Q^-1 f0 (both 2 x 2 / 2), (c I + N H (I + mu s J)) n = b: one scalar equation |n(N)| = 1 for N,
solved by bracketing (|n(0)| = |b| / c > 1 when the free whirl is wider than the clearance).

*Linearization with the contact held.* A perturbation du = D dq turns the normal, dn = (I - n n^T) du / c
= t (t^T du) / c (|u| = c; the radial part of du does not turn it), and with it the tangent,
dt = J dn = -n (t^T du) / c (J t = J J n = -n). So

    dF = -(n + mu s t) dN - N (dn + mu s dt) = -(n + mu s t) dN - (N / c) (t - mu s n) t^T du:

the force turns with the contact point, a geometric stiffness K_geo = (N / c) (t - mu s n) t^T on u that a
facet (whose normal does not turn) lacks. The slip's sign does not change for small perturbations
(|t.du'| << Omega (c + R)), so the friction's size stays mu N. The contact is held (bilateral): n^T du = 0
(|u| = c to first order), and dN is the constraint's multiplier:

    M dq'' + C dq' + (Q + D^T K_geo D) dq = -W dN,   G^T dq = 0,   G = D^T n,  W = D^T (n + mu s t).

With dq = Z y (Z an orthonormal basis of G^T's null space) and L one of W^T's (L^T W = 0: the rows free of
dN), (L^T M Z) y'' + (L^T C Z) y' + (L^T K Z) y = 0, n - 1 coordinates: 2 (n - 1) eigenvalues lambda.

*Elastic round ring* (a mount of radial stiffness k_s and damping c_s, no impacts): the ring pushes while
|u| = r > c with N = k_s (r - c) + c_s r', the same F; no constraint. At rest in the rotating frame (r' = 0),
(r I + k_s (r - c) H (I + mu s J)) n = b gives r by bracketing (c < r < |b|). A perturbation changes N by
k_s n.du + c_s n.du' (dr = n.du; dr' = n.du' + u'.dn = n.du' at rest) and turns n and t as above, with r for c:

    dF = -(K_ring du + C_ring du'),  K_ring = k_s (n + mu s t) n^T + (N / r) (t - mu s n) t^T,
                                     C_ring = c_s (n + mu s t) n^T,

and M dq'' + (C + D^T C_ring D) dq' + (Q + D^T K_ring D) dq = 0: 2 n eigenvalues.

*Inertial frame.* q_inertial = R q and q'_inertial = R (q' + Omega J q) with R = exp(Omega t J) the frame's turn
of every lateral pair (displacements and slopes): x_inertial = P(t) x_rotating, P = [[R, 0], [Omega J R, R]],
and P(T) = P(0) for T = 1 / speed. The inertial orbit's monodromy matrix is P(0) exp(A T) P(0)^-1: its
multipliers are exp(lambda T).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from scipy.optimize import brentq

#: the quarter turn about the shaft axis in the (y, z) plane: J (y, z) = (-z, y)
QUARTER = np.array([[0.0, -1.0], [1.0, 0.0]])


def ring_rows(JN: np.ndarray, jN: np.ndarray) -> tuple[np.ndarray, float, float]:
    """(D, c, fit): the disk's lateral displacement rows D (2 x n) and the clearance c from a polygon ring's gap
    rows g_k = c - n_k . D q, n_k = (cos, sin)(2 pi k / F) (docs/theory.md, stators), by least squares over the
    F facets; ``fit`` is the largest residual relative to |J_N| (round-off when the facets are as assumed)."""
    F = JN.shape[1]
    a = 2.0 * np.pi * np.arange(F) / F
    normals = np.column_stack([np.cos(a), np.sin(a)])      # F x 2
    D = -np.linalg.lstsq(normals, JN.T, rcond=None)[0]      # JN^T = -normals D
    fit = float(np.abs(JN.T + normals @ D).max() / np.abs(JN).max())
    return D, float(np.mean(jN)), fit


@dataclass
class RoundRub:
    """The stationary full annular rub on a round ring (module docstring)."""

    q: np.ndarray        # (n,) the state in the rotating frame
    N: float             # the normal force [N]
    n: np.ndarray        # (2,) the contact's outward normal (the disk's direction)
    t: np.ndarray        # (2,) the circumferential tangent J n
    s: float             # the slip's sign
    drag: float = 0.0    # a tangential force against the whirl besides friction [N] (a polygon's corners)


def ring_force(rub: RoundRub, mu: float) -> np.ndarray:
    """The ring's force on the disk, -N (n + mu s t) - drag s t (2,)."""
    return -rub.N * (rub.n + mu * rub.s * rub.t) - rub.drag * rub.s * rub.t


def round_rub(Q: np.ndarray, f0: np.ndarray, D: np.ndarray, c: float, mu: float, s: float,
              drag: float = 0.0) -> RoundRub:
    """The stationary rub on the round ring of radius c (module docstring): N from |n(N)| = 1 by Brent's method.
    ``drag`` adds a constant force against the whirl, -drag s t (a polygon's corner impacts, on average)."""
    Qi_f0 = np.linalg.solve(Q, f0)
    H = D @ np.linalg.solve(Q, D.T)
    b = D @ Qi_f0
    turn = np.eye(2) + mu * s * QUARTER

    def normal(N: float) -> np.ndarray:
        return np.linalg.solve(c * np.eye(2) + H @ (N * turn + drag * s * QUARTER), b)

    if np.linalg.norm(b) <= c:
        raise ValueError(f"the free whirl {np.linalg.norm(b):.3g} m stays inside the clearance {c:.3g} m: no rub")
    hi = 1.0
    while np.linalg.norm(normal(hi)) > 1.0:
        hi *= 2.0
        if hi > 1e12:
            raise ValueError("no normal force holds the disk at the clearance")
    N = brentq(lambda N_: np.linalg.norm(normal(N_)) - 1.0, 0.0, hi, xtol=1e-14 * hi, rtol=1e-15)
    n = normal(N)
    n /= np.linalg.norm(n)
    q = Qi_f0 - np.linalg.solve(Q, D.T @ ((N * turn + drag * s * QUARTER) @ n))
    return RoundRub(q, float(N), n, QUARTER @ n, float(s), float(drag))


def geometric_stiffness(rub: RoundRub, c: float, mu: float) -> np.ndarray:
    """K_geo = (N / c) (t - mu s n) t^T (2 x 2, on u): -dF/du with N held (module docstring); a drag turns
    with t too, adding -(drag s / c) n t^T."""
    return np.outer(rub.N * rub.t - (mu * rub.N + rub.drag) * rub.s * rub.n, rub.t) / c


def held_pencil(M, C, Q, D, rub: RoundRub, c: float, mu: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(L^T M Z, L^T C Z, L^T K Z), K = Q + D^T K_geo D: the linearization with the contact held, n - 1
    coordinates (module docstring)."""
    G = D.T @ rub.n
    W = D.T @ (rub.n + mu * rub.s * rub.t)
    Z = sla.null_space(G[None, :])
    L = sla.null_space(W[None, :])
    K = Q + D.T @ geometric_stiffness(rub, c, mu) @ D
    return L.T @ M @ Z, L.T @ C @ Z, L.T @ K @ Z


def elastic_rub(Q: np.ndarray, f0: np.ndarray, D: np.ndarray, c: float, mu: float, s: float,
                stiffness: float) -> RoundRub:
    """The stationary rub on an elastic round ring of radial stiffness k_s (module docstring): the disk at
    r = c + N / k_s; r by Brent's method."""
    b = D @ np.linalg.solve(Q, f0)
    H = D @ np.linalg.solve(Q, D.T)
    turn = np.eye(2) + mu * s * QUARTER

    def normal(r: float) -> np.ndarray:
        return np.linalg.solve(r * np.eye(2) + stiffness * (r - c) * H @ turn, b)

    if np.linalg.norm(b) <= c:
        raise ValueError(f"the free whirl {np.linalg.norm(b):.3g} m stays inside the clearance {c:.3g} m: no rub")
    r = brentq(lambda r_: np.linalg.norm(normal(r_)) - 1.0, c, np.linalg.norm(b), xtol=1e-15 * c, rtol=1e-15)
    n = normal(r)
    n /= np.linalg.norm(n)
    N = stiffness * (r - c)
    q = np.linalg.solve(Q, f0 - N * (D.T @ (turn @ n)))
    return RoundRub(q, float(N), n, QUARTER @ n, float(s))


def elastic_ring_operators(rub: RoundRub, radius: float, mu: float, stiffness: float, damping: float
                           ) -> tuple[np.ndarray, np.ndarray]:
    """(K_ring, C_ring) (2 x 2 on u, u'): the elastic round ring's force linearized at the rub, radius r = |u|
    (module docstring)."""
    along = np.outer(rub.n + mu * rub.s * rub.t, rub.n)
    return stiffness * along + geometric_stiffness(rub, radius, mu), damping * along


def corner_terms(M: np.ndarray, D: np.ndarray, rub: RoundRub, omega: float, c: float, facets: int
                 ) -> tuple[float, float]:
    """(drag [N], damping [N s/m]): a fixed polygon of F facets seen as a round ring, in the inertial frame,
    averaged over its corners (a model of the polygon's error, not of the round ring).

    At a corner the disk, sliding at V along facet k, meets facet k + 1 (its normal turned by theta = 2 pi / F)
    at V sin(theta); a plastic impact removes that part, leaving V cos(theta) along the new facet: a loss of
    V theta^2 / 2 each c theta / V, a drag d = m_eff V^2 theta / (2 c) = m_eff V^2 pi / (F c) against the whirl
    (m_eff = 1 / (n^T D M^-1 D^T n), the disk's mass for an impulse). With V = Omega c at the rub,
    d = m_eff Omega^2 c pi / F, and a change dV of the disk's speed along the ring changes it by
    2 pi m_eff Omega / F dV: a damping on t.u' (in the rotating frame, V = t.u' + Omega n.u and n.du = 0 held).
    Both are first order in 1 / F."""
    m_eff = 1.0 / float(rub.n @ D @ np.linalg.solve(M, D.T) @ rub.n)
    return m_eff * omega ** 2 * c * np.pi / facets, 2.0 * np.pi * m_eff * abs(omega) / facets


def eigenvalues(Mr: np.ndarray, Cr: np.ndarray, Kr: np.ndarray) -> np.ndarray:
    """The 2 m eigenvalues of Mr y'' + Cr y' + Kr y = 0 (first-order form)."""
    m = Mr.shape[0]
    A = np.block([[np.zeros((m, m)), np.eye(m)], [-np.linalg.solve(Mr, Kr), -np.linalg.solve(Mr, Cr)]])
    return np.linalg.eigvals(A)


def multipliers(lam: np.ndarray, period: float) -> np.ndarray:
    """exp(lambda T), largest modulus first (ties by argument, so conjugate pairs stay together)."""
    mu = np.exp(np.asarray(lam) * period)
    return mu[np.lexsort((-mu.imag, -np.round(np.abs(mu), 12)))]


# --- the Jeffcott rotor's synchronous rub on an elastic ring, in closed form (issue 36, backward whirl) -------------

@dataclass
class Jeffcott:
    """A Jeffcott rotor (or one rotor mode): disk mass m [kg], shaft stiffness k [N/m], external damping c_e (on the
    fixed-frame rates) and internal c_i (on the rotating-frame rates) [N s/m], unbalance m_u e [kg m], inside a
    massless isotropic ring of radial stiffness k_s [N/m] at clearance c0 [m] with Coulomb friction mu.

    Rotating frame (turning at Omega), disk at w = y + i z; the ring pushes while |w| = r > c0 with
    N = k_s (r - c0), F = -N (1 + i mu s) w / |w|, s = sign(Omega) (the surface slips forward on the ring):

        m (w'' + 2 i Omega w' - Omega^2 w) + c_e (w' + i Omega w) + c_i w' + k w = m_u e Omega^2 + F.

    *Synchronous full annular rub* (w' = 0): |(k - m Omega^2 + N / r + i (c_e Omega + mu s N / r))| r = m_u e Omega^2,
    one equation for r > c0. Its left side is |(k - m Omega^2 + k_s) r - k_s c0 + i ((c_e Omega + mu s k_s) r -
    mu s k_s c0)|, the modulus of an affine function of r: convex, so it has exactly one root above c0 when it is
    below the unbalance force at c0 (the free whirl wider than the clearance). Above the critical speed that root may
    lie beyond the free whirl's radius (the ring's push moves the disk out), where :func:`elastic_rub`'s bracket
    does not reach.

    *Linearization* with w = e^{i phi} (r + xi + i eta) (xi radial, eta along the ring): the ring's force changes by
    -(1 + i mu s) (k_s xi + i (N / r) eta) (the radial spring, and the force turning with the contact point), so

        m x'' + (c I + 2 m Omega J) x' + K x = 0,   x = (xi, eta),   c = c_e + c_i,   J = [[0, -1], [1, 0]],
        K = [[k - m Omega^2 + k_s,            -(c_e Omega + mu s N / r)],
             [c_e Omega + mu s k_s,           k - m Omega^2 + N / r   ]].

    Its characteristic polynomial a4 l^4 + a3 l^3 + a2 l^2 + a1 l + a0 (K_rr, K_tt the diagonal):

        a4 = m^2,  a3 = 2 m c,  a2 = m (K_rr + K_tt) + c^2 + 4 m^2 Omega^2,
        a1 = c (K_rr + K_tt) + 2 m Omega (2 c_e Omega + mu s (k_s + N / r)),
        a0 = K_rr K_tt + (c_e Omega + mu s N / r) (c_e Omega + mu s k_s).

    Routh-Hurwitz: stable iff every a_i > 0, D2 = a3 a2 - a4 a1 > 0 and D3 = a1 D2 - a3^2 a0 > 0. a0 = 0 is a fold
    of the stationary rub (a real eigenvalue through 0); D3 = 0 with D2 > 0 a Hopf point, at l = +- i w with
    w^2 = a1 / a3. The friction enters as the skew part mu s (k_s + N / r) / 2 of K: a follower force along the ring
    against the spin, which feeds a backward whirl and damps a forward one (for a mode at w in the inertial frame,
    m l^2 + c l + k + i q = 0 gives Re l = -(c w + q) / (2 m w): unstable backward (w < 0) for q > c |w|)."""

    m: float
    k: float
    c_e: float
    c_i: float
    unbalance: float
    k_s: float
    clearance: float
    mu: float

    def radius(self, omega: float) -> float:
        """r of the synchronous rub at Omega [rad/s] (ValueError: no rub, the free whirl inside the clearance)."""
        s = math.copysign(1.0, omega)
        force = self.unbalance * omega ** 2

        def excess(r: float) -> float:
            N = self.k_s * (r - self.clearance)
            return abs(complex(self.k - self.m * omega ** 2 + N / r,
                               self.c_e * omega + self.mu * s * N / r)) * r - force

        if excess(self.clearance) >= 0.0:
            raise ValueError(f"the free whirl stays inside the clearance {self.clearance:.3g} m at "
                             f"{omega / (2 * math.pi):.4g} Hz: no rub")
        hi = 2.0 * self.clearance
        while excess(hi) < 0.0:
            hi *= 2.0
            if hi > 1e6 * self.clearance:
                raise ValueError("no radius balances the unbalance")
        return float(brentq(excess, self.clearance, hi, xtol=1e-15 * self.clearance, rtol=1e-15))

    def matrices(self, omega: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
        """(M, C, K, r, N): the rotating-frame linearization at the rub (class docstring), on (xi, eta)."""
        s = math.copysign(1.0, omega)
        r = self.radius(omega)
        N = self.k_s * (r - self.clearance)
        soft = self.k - self.m * omega ** 2
        K = np.array([[soft + self.k_s, -(self.c_e * omega + self.mu * s * N / r)],
                      [self.c_e * omega + self.mu * s * self.k_s, soft + N / r]])
        C = (self.c_e + self.c_i) * np.eye(2) + 2.0 * self.m * omega * QUARTER
        return self.m * np.eye(2), C, K, r, N

    def characteristic(self, omega: float) -> np.ndarray:
        """(a4, a3, a2, a1, a0): det(M l^2 + C l + K) (class docstring)."""
        s = math.copysign(1.0, omega)
        r = self.radius(omega)
        N = self.k_s * (r - self.clearance)
        m, c = self.m, self.c_e + self.c_i
        trace = 2.0 * (self.k - m * omega ** 2) + self.k_s + N / r
        Krr, Ktt = self.k - m * omega ** 2 + self.k_s, self.k - m * omega ** 2 + N / r
        a1 = c * trace + 2.0 * m * omega * (2.0 * self.c_e * omega + self.mu * s * (self.k_s + N / r))
        a0 = Krr * Ktt + (self.c_e * omega + self.mu * s * N / r) * (self.c_e * omega + self.mu * s * self.k_s)
        return np.array([m ** 2, 2.0 * m * c, m * trace + c ** 2 + 4.0 * m ** 2 * omega ** 2, a1, a0])


def hurwitz(a: np.ndarray) -> tuple[float, float]:
    """(D2, D3) of a quartic a4 l^4 + ... + a0 with positive coefficients: its roots lie left of the imaginary axis
    iff both are positive (Routh-Hurwitz)."""
    a4, a3, a2, a1, a0 = a
    D2 = a3 * a2 - a4 * a1
    return float(D2), float(a1 * D2 - a3 ** 2 * a0)


def jeffcott_onset(rotor: Jeffcott, lo_hz: float, hi_hz: float) -> dict | None:
    """The speed in [lo, hi] Hz where D3 changes sign (the Hopf point of the synchronous rub), its whirl frequency
    w = sqrt(a1 / a3) in the rotating frame, and the disk's whirl at onset in the inertial frame: the eigenvector
    x = (xi, eta) e^{i w t} makes the disk move as a e^{i (w + Omega) t} + b e^{-i (w - Omega) t} there, with
    a = (xi + i eta) / 2, b = conj(xi - i eta) / 2; None if D3 keeps its sign."""
    def d3(f: float) -> float:
        a = rotor.characteristic(2 * math.pi * f)
        return hurwitz(a)[1] / (a[0] * a[2] ** 2)   # scaled to order one

    if d3(lo_hz) * d3(hi_hz) > 0.0:
        return None
    f = float(brentq(d3, lo_hz, hi_hz, xtol=1e-10, rtol=1e-14))
    omega = 2 * math.pi * f
    a = rotor.characteristic(omega)
    w = math.sqrt(a[3] / a[1])
    M, C, K, r, N = rotor.matrices(omega)
    P = -w ** 2 * M + 1j * w * C + K
    x = np.array([-P[0, 1], P[0, 0]])                 # the null vector of P's first row (P singular at onset)
    fwd, bwd = abs(x[0] + 1j * x[1]) / 2.0, abs(x[0] - 1j * x[1]) / 2.0
    return {"speed_hz": f, "radius": r, "N": N, "w_rotating": w, "forward_hz": (w + omega) / (2 * math.pi),
            "backward_hz": (w - omega) / (2 * math.pi), "backward_share": float(bwd / (fwd + bwd)),
            "D2": hurwitz(a)[0]}
