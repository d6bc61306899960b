"""Elastic stator rings: a unilateral spring-damper between the shaft and a ring fixed in space.

The ring is the polygon of F facets tangent to the clearance circle (as a rigid stator's), held by
a spring k_s and damper c_s (its mount, massless, isotropic). The shaft's centre u = (v, w) = P q at
the ring's x pushes the ring out by its distance from the polygon, d = u - p(u) with p the projection
onto the polygon {p : n_k . p <= c}: the ring sits at d while touched (no hidden state). Its force on
the shaft is

    F = -(I + mu s R) N,   N = proj_K (X),   X = k_s d + c_s u'

with K the polygon's normal cone at p(u) (the ray n_k on facet k, the cone of n_k and n_k+1 at the
corner v_k), R the rotation by +90 degrees (friction along the circumference, perpendicular to the
normal force) and s = +-1 the sign of the slip of the shaft surface past the ring. proj_K is the
velocity-level complementarity of the massless ring: facet forces lam >= 0 move the ring at
r' = (sum lam_j n_j - k_s d) / c_s, and a facet with lam_j > 0 keeps up with the shaft, n_j . (r' -
u') = 0, else separates (n_j . (r' - u') > 0, as n_j . (u - r) <= c): the KKT conditions of
min |sum lam_j n_j - X| over lam >= 0. A ring never pulls, on any facet. p(u) is piecewise linear,
so N is linear in (u, u') on the regions of u and the cases of proj_K (the ``law`` codes of :meth:`Ring.parts`):

- ``edge`` k (u beyond facet k, |t_k . u| <= h = c tan(pi / F)): d = (n_k . u - c) n_k and
  N = (n_k . X) n_k = k_s d + c_s n_k n_k^T u' while n_k . X > 0 (code k);
- ``corner`` k (u beyond the corner v_k between facets k and k + 1): d = u - v_k and, with X = a n_k +
  b n_k+1, N = X = k_s d + c_s u' while a, b > 0 (code F + k: both facets push, the ring follows the
  shaft); N = (n_k . X) n_k while b <= 0 < n_k . X (code 2F + k: facet k alone, edge k's law) and
  likewise facet k + 1 alone (code 3F + k).

Elsewhere (n . X <= 0 on an edge, X in the polar cone at a corner) the force is released with u
still beyond the polygon (a damper pulling the shaft back would glue it): the ring is ``latent``.
As F grows the corner regions vanish and N = k_s (r - c) + c_s r' radially, the closed form of an
elastic ring. The force is a function of (q, q') alone, which is what :func:`forces` evaluates; the
exact method follows the regions and cases as configurations (:meth:`Ring.terms`) with events at
their boundaries.

Energy: the ring stores V = k_s |d|^2 / 2 (:func:`potential`). The power it takes from the shaft,
N . u' - dV/dt = |N - k_s d|^2 / c_s - k_s d . (X - N) / c_s, is never negative (X - N is in the
polar cone, d in K). It is dissipated: an engaged law's damper c_s |D u'|^2 (D = n n^T or I), and
the part of V that the law does not hold, V - H with H = k_s |S u - a|^2 / 2 its spring's energy
(all of V when latent, k_s (t_k . d)^2 / 2 for one facet at a corner; :func:`unheld`), released to
the damper as it shrinks.
The slip velocity of the shaft surface past the ring along t = R nu is t . u' + Omega_f nu . u +
Omega R_s (Omega_f = Omega in the rotating frame, 0 in the inertial one; the paper's eq. 27).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

#: facet normals whose cross product is at most this (times 1 + the largest |angle|: an angle's rounding
#: moves its normal by eps |angle|) are parallel: opposite facets of a regular polygon (:attr:`Ring.springs`);
#: distinct facets of F facets lie sin(2 pi / F) apart (6e-6 at F = 1e6)
PARALLEL = 8 * np.finfo(float).eps

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
        """The region of the centre u (2,): None inside the polygon, k for edge k, F + k for corner k."""
        s = self.normals @ u - self.clearance
        k = int(np.argmax(s))
        if s[k] <= 0.0:
            return None
        tk = ROT @ self.normals[k]
        along = float(tk @ u)
        if abs(along) <= self.half_edge:
            return k
        return self.F + (k if along > 0.0 else (k - 1) % self.F)

    def place(self, law: int) -> int:
        """The region of a law code (module docstring): k and F + k are their own, 2F + k and 3F + k
        corner k's."""
        return law if law < 2 * self.F else self.F + law % self.F

    def pushing(self, law: int) -> tuple[int, ...]:
        """The facets a law pushes on."""
        F, k = self.F, law % self.F
        return ((k,), (k, (k + 1) % F), (k,), ((k + 1) % F,))[law // F]

    @cached_property
    def springs(self) -> np.ndarray:
        """S_k = n n^T (F x 2 x 2) of each facet's line: of parallel facets (opposite ones, n_j = -n_k to
        round-off: |n_j x n_k| <= :data:`PARALLEL` (1 + max |angle|), the angles' own rounding) the first one's
        normal forms all, so that they are one linear system under two loads (:meth:`matrix_key`); the other's
        S differs from its own n n^T in the last bits only."""
        n, F = self.normals, self.F
        tol = PARALLEL * (1.0 + float(np.max(np.abs(self.angles), initial=0.0)))
        # parallel facets are neighbours in the order of their lines' angles (mod pi, circular: 0 meets pi)
        order = np.argsort(np.mod(self.angles, np.pi), kind="stable")
        after = np.roll(order, -1)
        par = np.abs(n[order, 0] * n[after, 1] - n[order, 1] * n[after, 0]) <= tol   # order[i] || order[i + 1]
        line = np.arange(F)
        if par.any() and not par.all():
            first = (int(np.flatnonzero(~par)[0]) + 1) % F      # a line's first facet in that order
            group = []
            for step in range(F):
                i = (first + step) % F
                group.append(order[i])
                if not par[i]:                                  # the line's last facet
                    line[group] = min(group)
                    group = []
        out = np.einsum("ki,kj->kij", n[line], n[line])
        out.flags.writeable = False
        return out

    def parts(self, law: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(S, a, nu) of a law (or a region, its own law): N = k_s (S u - a) + c_s D u' (:meth:`damper`),
        nu the direction of the slip's normal (the facet's, the corner's bisector for both facets); formed
        once per law, read-only."""
        cache = self.__dict__.setdefault("_parts", {})
        got = cache.get(law)
        if got is None:
            F = self.F
            if law < F or law >= 2 * F:
                k = self.pushing(law)[0]
                n = self.normals[k]
                got = (self.springs[k], self.clearance * n, n)
            else:
                k = law - F
                got = (np.eye(2), self.corners[k], self.bisectors[k])
            for x in got:
                x.flags.writeable = False
            cache[law] = got
        return got

    def damper(self, law: int) -> np.ndarray:
        """D (2 x 2): the damper's projector, the spring's S (n n^T for one facet, I for both: the ring
        follows u')."""
        return self.parts(law)[0]

    def push(self, region: int, u: np.ndarray, du: np.ndarray) -> np.ndarray:
        """X = k_s d + c_s u' on a region at centres u, velocities du (2,) or (2, t)."""
        S, a, _ = self.parts(region)
        return self.stiffness * (S @ u - (a if u.ndim == 1 else a[:, None])) + self.damping * du

    def switches(self, region: int, law: int | None) -> list[tuple[np.ndarray, int | None]]:
        """The cases of proj_K next to a law (None: latent) on a region as (w, next): it holds while
        w . X >= 0 (X = a n_k + b n_k+1 at a corner: b = t_k . X / sin, a = -t_k+1 . X / sin); past
        it lies ``next`` (None: released)."""
        F = self.F
        if region < F:
            n = self.normals[region]
            return [(n, None)] if law is not None else [(-n, region)]
        k = region - F
        n0, n1 = self.normals[k], self.normals[(k + 1) % F]
        t0, t1 = ROT @ n0, ROT @ n1
        if law is None:
            return [(-n0, 2 * F + k), (-n1, 3 * F + k)]
        return {F + k: [(-t1, 3 * F + k), (t0, 2 * F + k)],
                2 * F + k: [(n0, None), (-t0, F + k)],
                3 * F + k: [(n1, None), (t1, F + k)]}[law]

    def law(self, region: int, u: np.ndarray, du: np.ndarray) -> int | None:
        """The case of proj_K at (u, u') on a region (None: released): :meth:`laws` at one point, in scalars
        (the same products and sums, so the same decisions)."""
        if self.damping == 0.0:   # X = k_s d lies in K
            return region
        x, y = (float(c) for c in self.push(region, u, du))
        F, k = self.F, region % self.F
        (n0x, n0y), (n1x, n1y) = self.normals[k], self.normals[(k + 1) % F]
        p0 = n0x * x + n0y * y
        if region < F:
            return k if p0 > 0 else None
        p1 = n1x * x + n1y * y
        b, a = -n0y * x + n0x * y, -(-n1y * x + n1x * y)     # R n = (-n_y, n_x)
        if a > 0 and b > 0:
            return F + k
        if p0 > 0 and b <= 0:
            return 2 * F + k
        if p1 > 0 and a <= 0:
            return 3 * F + k
        return None

    def laws(self, regions: np.ndarray, X: np.ndarray) -> np.ndarray:
        """The laws (-1: released) of X (2, t) on regions (t,) beyond the polygon."""
        F = self.F
        if self.damping == 0.0:   # X = k_s d lies in K
            return np.array(regions, dtype=int)
        edge = regions < F
        k = regions % F
        n0, n1 = self.normals[k].T, self.normals[(k + 1) % F].T
        p0, p1 = np.einsum("ij,ij->j", n0, X), np.einsum("ij,ij->j", n1, X)
        b, a = np.einsum("ij,ij->j", ROT @ n0, X), -np.einsum("ij,ij->j", ROT @ n1, X)
        corner = np.where((a > 0) & (b > 0), F + k, np.where((p0 > 0) & (b <= 0), 2 * F + k,
                                                             np.where((p1 > 0) & (a <= 0), 3 * F + k, -1)))
        return np.where(edge, np.where(p0 > 0, k, -1), corner)

    def slip_rate(self, law: int, u: np.ndarray, du: np.ndarray) -> np.ndarray:
        """The slip velocity of the shaft surface past the ring along t = R nu (module docstring)."""
        nu = self.parts(law)[2]
        return (ROT @ nu) @ du + self.frame_spin * (nu @ u) + self.surface_speed

    def boundaries(self, region: int) -> list[tuple[np.ndarray, float, int]]:
        """The region's (or a law's region's) exits as (g, g0, next): it holds while g . u + g0 >= 0; past
        it lies ``next`` (None: inside the polygon)."""
        F, h = self.F, self.half_edge
        region = self.place(region)
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
    def terms(self, law: int, s: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Kr, Cr, fr): an engaged law adds Kr q + Cr q' to the left side of M q'' + C q' + Q q = f and
        fr to the load (F = -G (k_s (S u - a) + c_s D u'), G = I + mu s R)."""
        S = self.parts(law)[0]
        G = self.coupling(s)
        P = self.P
        Kr = self.stiffness * (P.T @ (G @ S) @ P)
        Cr = self.damping * (P.T @ (G @ self.damper(law)) @ P)
        return Kr, Cr, self.load(law, s)

    def coupling(self, s: int) -> np.ndarray:
        """G = I + mu s R: the normal force's map to the force on the shaft (friction along the circumference)."""
        return np.eye(2) + self.friction * s * ROT

    def load(self, law: int, s: int) -> np.ndarray:
        """fr of :meth:`terms`: the load k_s P^T G a of the law's offset a (all that differs between the corner
        laws of both facets, whose S = D = I)."""
        return self.stiffness * (self.P.T @ (self.coupling(s) @ self.parts(law)[1]))

    def matrix_key(self, law: int, s: int) -> tuple[bytes, int]:
        """What of (law, s) sets :meth:`terms`' Kr and Cr, by content: the spring's S (the damper's D is S) and the
        slip's sign where there is friction (G). Laws of one key differ in fr alone: a facet alone at a corner
        (codes 2F + k, 3F + k) is that facet's edge law, the corners' laws of both facets (S = I) differ in a
        alone, and so do opposite facets (one line, one spring: :attr:`springs`)."""
        return self.parts(law)[0].tobytes(), (s if self.friction else 0)

    def force_rows(self, law: int, Pq: np.ndarray, Pv: np.ndarray, const: int, damper=None) -> np.ndarray:
        """N (2 x dim) of a law as rows on an augmented state xi (q = Pq xi, q' = Pv xi, xi[const] = 1);
        ``damper`` D in place of the law's (I: the rows of X on its region)."""
        S, a, _ = self.parts(law)
        D = self.damper(law) if damper is None else damper
        rows = self.stiffness * (S @ (self.P @ Pq)) + self.damping * (D @ (self.P @ Pv))
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


def unheld(ring: Ring, law: int | None, q: np.ndarray) -> float:
    """V - H: the ring's stored energy that a law (None: released) does not hold, k_s |d|^2 / 2 less
    k_s |S u - a|^2 / 2 of its spring [J]; released to the damper (module docstring)."""
    if law is not None and ring.place(law) == law:
        return 0.0
    held = 0.0
    if law is not None:
        S, a, _ = ring.parts(law)
        e = S @ (ring.P @ q) - a
        held = 0.5 * ring.stiffness * float(e @ e)
    return potential([ring], q) - held


def forces(ring: Ring, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The ring's force at states q, v (n, t): (N (2, t) the normal force vector proj_K (X), fric (2, t) the
    friction force on the shaft, law (t,) (the region where released, -1 inside), slip (t,) the slip
    velocity); zero where released."""
    u, du = ring.P @ q, ring.P @ v
    F, t = ring.F, u.shape[1]
    cols = np.arange(t)
    s = ring.normals @ u - ring.clearance                      # F x t
    k = np.argmax(s, axis=0)
    outside = s[k, cols] > 0.0
    along = np.einsum("ij,ij->j", (ring.normals @ ROT.T)[k].T, u)   # t_k . u (t_k = R n_k)
    edge = np.abs(along) <= ring.half_edge
    corner = np.where(along > 0.0, k, (k - 1) % F)
    regions = np.where(edge, k, F + corner)
    d = np.where(edge, s[k, cols] * ring.normals[k].T, u - ring.corners[corner].T)
    X = ring.stiffness * d + ring.damping * du
    laws = np.where(outside, ring.laws(regions, X), -1)
    one = (laws < F) | (laws >= 2 * F)
    n = ring.normals[np.where(laws >= 3 * F, (regions + 1) % F, regions % F)].T     # the facet of one
    N = np.where(one, n * np.einsum("ij,ij->j", n, X), X)
    on = laws >= 0
    N[:, ~on] = 0.0
    nu = np.where(one, n, ring.bisectors[corner].T)
    slip = np.where(outside, np.einsum("ij,ij->j", ROT @ nu, du) + ring.frame_spin * np.einsum("ij,ij->j", nu, u)
                    + ring.surface_speed, 0.0)
    fric = -ring.friction * np.sign(slip) * (ROT @ N)
    return N, fric, np.where(on, laws, np.where(outside, regions, -1)), slip


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
