"""Elastic stator rings: a unilateral spring-damper between the shaft and a ring fixed in space.

The ring is the polygon of F facets tangent to the clearance circle (as a rigid stator's), held by
a radial spring k_s and damper c_s (its mount, massless). The shaft's centre u = (v, w) = P q at the
ring's x pushes the ring out by its distance from the polygon, d = u - p(u) with p the projection
onto the polygon {p : n_k . p <= c}. Its force on the shaft is

    F = -(I + mu s R) N,   N = k_s d + c_s nu nu^T u'   (while nu . N > 0, else 0)

with R the rotation by +90 degrees (friction along the circumference, perpendicular to the normal
force), s = +-1 the sign of the slip of the shaft surface past the ring and nu the region's normal.
p(u) is piecewise linear, so F is, on the regions of u:

- ``edge`` k (u beyond facet k, |t_k . u| <= h = c tan(pi / F)): d = (n_k . u - c) n_k, nu = n_k;
- ``vertex`` k (u beyond the corner v_k between facets k and k + 1): d = u - v_k, nu = m_k its
  bisector (the damper acts along it).

As F grows the vertex regions vanish and N = k_s (r - c) + c_s r' radially, the closed form of an
elastic ring. The force is released (clipped at zero) when nu . N reaches zero, also with u still
beyond the polygon (a damper pulling the shaft back would glue it): the contact is then ``latent``
until nu . N rises again or u re-enters the polygon. Without a moving coordinate the force is a
function of (q, q') alone (no hidden state), which is what :func:`forces` evaluates; the exact
method follows the regions as configurations (:func:`terms`) with events at their boundaries.

Energy: the ring stores V = k_s |d|^2 / 2 (:func:`potential`); an engaged ring's damper dissipates
c_s (nu . u')^2; a latent ring's release of V (from a damper that lets go) is dissipated by it.
The slip velocity of the shaft surface past the ring along t = R nu is t . u' + Omega_f nu . u +
Omega R_s (Omega_f = Omega in the rotating frame, 0 in the inertial one; the paper's eq. 27).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

#: R: the rotation by +90 degrees in the y-z plane (from the normal to the circumferential direction)
ROT = np.array([[0.0, -1.0], [1.0, 0.0]])


@dataclass(frozen=True)
class Ring:
    """One elastic stator ring in n coordinates: ``P`` (2 x n) maps q to the shaft centre (v, w) at x.
    ``angles`` [rad] of the facet normals (n_k = (cos, sin)), ``facets`` the indices of the facets in the
    model's contact list (for outputs), ``spin`` Omega [rad/s] and ``rotating`` the frame of q."""

    label: str
    P: np.ndarray
    angles: np.ndarray
    clearance: float
    stiffness: float
    damping: float = 0.0
    friction: float = 0.0
    radius: float = 0.0
    spin: float = 0.0
    rotating: bool = True
    facets: tuple[int, ...] = ()

    @property
    def F(self) -> int:
        return int(self.angles.size)

    @cached_property
    def normals(self) -> np.ndarray:
        """n_k (F x 2)."""
        return np.column_stack([np.cos(self.angles), np.sin(self.angles)])

    @cached_property
    def half_edge(self) -> float:
        """h = c tan(pi / F): half a facet's length on the clearance polygon of the centre."""
        return self.clearance * math.tan(math.pi / self.F)

    @cached_property
    def bisectors(self) -> np.ndarray:
        """m_k (F x 2): the unit bisector of n_k and n_k+1 (the corner v_k's direction)."""
        b = self.normals + np.roll(self.normals, -1, axis=0)
        return b / np.linalg.norm(b, axis=1)[:, None]

    @cached_property
    def corners(self) -> np.ndarray:
        """v_k (F x 2): the polygon's corner between facets k and k + 1 (n_k . v = n_k+1 . v = c)."""
        cos_half = self.normals[0] @ self.bisectors[0]
        return self.clearance / cos_half * self.bisectors

    @property
    def surface_speed(self) -> float:
        """Omega R_s: the constant part of the slip velocity [m/s]."""
        return self.spin * self.radius

    @property
    def frame_spin(self) -> float:
        """Omega_f: the slip's part Omega_f nu . u (the ring turns at -Omega in rotating coordinates)."""
        return self.spin if self.rotating else 0.0

    # -- regions -----------------------------------------------------------------------
    def region(self, u: np.ndarray) -> int | None:
        """The region of the centre u (2,): None inside the polygon, k for edge k, F + k for vertex k."""
        s = self.normals @ u - self.clearance
        k = int(np.argmax(s))
        if s[k] <= 0.0:
            return None
        tk = ROT @ self.normals[k]
        along = float(tk @ u)
        if abs(along) <= self.half_edge:
            return k
        return self.F + (k if along > 0.0 else (k - 1) % self.F)

    def parts(self, region: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(S, a, nu) of a region: d = S u - a, the damper along nu."""
        F = self.F
        if region < F:
            n = self.normals[region]
            return np.outer(n, n), self.clearance * n, n
        k = region - F
        return np.eye(2), self.corners[k], self.bisectors[k]

    def normal_force(self, region: int, u: np.ndarray, du: np.ndarray) -> np.ndarray:
        """nu . N of a region at centres u, velocities du (2,) or (2, t)."""
        S, a, nu = self.parts(region)
        d = S @ u - (a if u.ndim == 1 else a[:, None])
        return self.stiffness * (nu @ d) + self.damping * (nu @ du)

    def slip_rate(self, region: int, u: np.ndarray, du: np.ndarray) -> np.ndarray:
        """The slip velocity of the shaft surface past the ring along t = R nu (module docstring)."""
        nu = self.parts(region)[2]
        return (ROT @ nu) @ du + self.frame_spin * (nu @ u) + self.surface_speed

    def boundaries(self, region: int) -> list[tuple[np.ndarray, float, int]]:
        """The region's exits as (g, g0, next): it holds while g . u + g0 >= 0; past it lies ``next``
        (None: inside the polygon)."""
        F, h = self.F, self.half_edge
        if region < F:
            k = region
            n, t = self.normals[k], ROT @ self.normals[k]
            return [(n, -self.clearance, None), (-t, h, F + k), (t, h, F + (k - 1) % F)]
        k = region - F
        v = self.corners[k]
        tk, tk1 = ROT @ self.normals[k], ROT @ self.normals[(k + 1) % F]
        # u - v_k = alpha n_k + beta n_k+1 with alpha, beta >= 0: t_k . (u - v) = beta sin, -t_k+1 . (u - v) = alpha sin
        return [(tk, -float(tk @ v), k), (-tk1, float(tk1 @ v), (k + 1) % F)]

    # -- the linear terms of a region --------------------------------------------------
    def terms(self, region: int, s: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Kr, Cr, fr): an engaged region adds Kr q + Cr q' to the left side of M q'' + C q' + Q q = f and
        fr to the load (F = -G (k_s (S u - a) + c_s nu nu^T u'), G = I + mu s R)."""
        S, a, nu = self.parts(region)
        G = np.eye(2) + self.friction * s * ROT
        P = self.P
        Kr = self.stiffness * (P.T @ (G @ S) @ P)
        Cr = self.damping * (P.T @ (G @ np.outer(nu, nu)) @ P)
        fr = self.stiffness * (P.T @ (G @ a))
        return Kr, Cr, fr

    def force_rows(self, region: int, Pq: np.ndarray, Pv: np.ndarray, const: int) -> np.ndarray:
        """N (2 x dim) as rows on an augmented state xi (q = Pq xi, q' = Pv xi, xi[const] = 1)."""
        S, a, nu = self.parts(region)
        rows = self.stiffness * (S @ (self.P @ Pq)) + self.damping * np.outer(nu, nu @ (self.P @ Pv))
        rows[:, const] -= self.stiffness * a
        return rows


def potential(rings, q: np.ndarray) -> float:
    """The rings' stored energy sum k_s |u - p(u)|^2 / 2 [J]."""
    total = 0.0
    for ring in rings:
        u = ring.P @ q
        reg = ring.region(u)
        if reg is not None:
            S, a, _ = ring.parts(reg)
            d = S @ u - a
            total += 0.5 * ring.stiffness * float(d @ d)
    return total


def engaged(ring: Ring, region: int | None, u: np.ndarray, du: np.ndarray) -> bool:
    """Whether the ring pushes at (u, u'): beyond the polygon and nu . N > 0."""
    return region is not None and float(ring.normal_force(region, u, du)) > 0.0


def forces(ring: Ring, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The ring's force at states q, v (n, t): (N (2, t) the normal force vector, fric (2, t) the friction
    force on the shaft, region (t,) (-1 inside), slip (t,) the slip velocity); zero where released."""
    u, du = ring.P @ q, ring.P @ v
    F, t = ring.F, u.shape[1]
    cols = np.arange(t)
    s = ring.normals @ u - ring.clearance                      # F x t
    k = np.argmax(s, axis=0)
    outside = s[k, cols] > 0.0
    along = np.einsum("ij,ij->j", (ring.normals @ ROT.T)[k].T, u)   # t_k . u (t_k = R n_k)
    edge = np.abs(along) <= ring.half_edge
    corner = np.where(along > 0.0, k, (k - 1) % F)
    regions = np.where(outside, np.where(edge, k, F + corner), -1)
    nu = np.where(edge, ring.normals[k].T, ring.bisectors[corner].T)        # 2 x t
    d = np.where(edge, s[k, cols] * ring.normals[k].T, u - ring.corners[corner].T)
    rate = np.einsum("ij,ij->j", nu, du)
    N = ring.stiffness * d + ring.damping * nu * rate
    on = outside & (np.einsum("ij,ij->j", nu, N) > 0.0)
    N[:, ~on] = 0.0
    slip = np.where(outside, np.einsum("ij,ij->j", ROT @ nu, du) + ring.frame_spin * np.einsum("ij,ij->j", nu, u)
                    + ring.surface_speed, 0.0)
    fric = -ring.friction * np.sign(slip) * (ROT @ N)
    return N, fric, regions, slip


def generalized_force(rings, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """sum P^T F of the rings at one state (n,): what they add to the load (moreau, penalty)."""
    out = np.zeros(q.shape[0])
    for ring in rings:
        N, fric, _, _ = forces(ring, q[:, None], v[:, None])
        out -= ring.P.T @ (N[:, 0] - fric[:, 0])
    return out


def compliance(contacts) -> np.ndarray | None:
    """The elastic rings' compliance in LCP (28) (m x m over the model's ``contacts``, None without rings):
    facet forces lam_j push the ring's polygon out by sum_j lam_j n_j / k_s, which opens facet i's gap by
    n_i . n_j lam_j / k_s (frictionless, the minimum of the energy with the ring's k_s |u - p|^2 / 2)."""
    idx = [k for k, c in enumerate(contacts) if c.stiffness > 0.0]
    if not idx:
        return None
    C = np.zeros((len(contacts), len(contacts)))
    groups: dict[str, list[int]] = {}
    for k in idx:
        groups.setdefault(contacts[k].label.rsplit(".", 1)[0], []).append(k)
    for ks in groups.values():
        a = np.array([contacts[k].angle for k in ks])
        C[np.ix_(ks, ks)] = np.cos(a[:, None] - a[None, :]) / contacts[ks[0]].stiffness
    return C


def from_facets(label: str, JN: np.ndarray, contacts, indices, spin: float, rotating: bool) -> Ring:
    """The ring of a stator's facets (model contacts ``contacts`` at ``indices``, all of one ``[[stator]]``),
    with their gap columns J_N (n x F): J_N[:, k] = -P^T n_k, so P = -pinv(normals) J_N^T."""
    cs = [contacts[i] for i in indices]
    angles = np.array([c.angle for c in cs], dtype=float)
    normals = np.column_stack([np.cos(angles), np.sin(angles)])
    P = -np.linalg.pinv(normals) @ JN.T
    c0 = cs[0]
    return Ring(label, P, angles, c0.clearance, c0.stiffness, c0.damping, c0.friction, c0.radius, spin, rotating,
                tuple(int(i) for i in indices))
