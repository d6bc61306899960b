"""Contact configurations: linear time-invariant motion between events, in closed form.

A configuration (:class:`Mode`) says which contacts are closed (g = 0 held), which of
them stick (tangential slip held) and which slide with their friction force along a fixed
cone generator e_i. Closed and sticking contacts are linear constraints G^T q + g0 = 0; they
are eliminated with an orthonormal null-space basis N (G^T N = 0), q = q_p + N y, so they
hold to round-off without drift. The contact forces W lam (W = G except for sliding
contacts, whose normal column carries mu e_i) are eliminated by projecting the equations
on L, a basis of null(W^T) (L = N without sliding friction):

    L^T M N y'' + L^T C N y' + L^T Q N y = L^T (f(t) - Q q_p).

With x = (y, y') this is x' = A x + B (f(t) - Q q_p), f(t) = f0 + fc cos(w t) + fs sin(w t).
:class:`Phase` propagates it exactly from (t0, q0, v0): by the eigen-decomposition of A and
particular solutions for the constant and harmonic parts when these are well conditioned,
otherwise by the matrix exponential of the augmented matrix

    xi = (x, cos w t, sin w t, 1),   xi' = A_aug xi,

which is exact also for rigid-body modes (singular Q) and resonant forcing. Every output
(q, v, constraint forces lam, event functions) is a linear map of xi.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
import scipy.linalg as sla

from ..errors import NsfemError
from . import core
from .closed_form import ModalPlan, Motion, decay_factors, divided_exp, power
from .problem import ContactSystem

#: relative singular value below which a constraint direction is redundant
RANK_TOL = 1e-10
#: the eigen-decomposition path is used when cond(V) and the particular solves stay below
COND_MAX = 1e8


@dataclass(frozen=True)
class Mode:
    """Closed contacts; of them, sticking ones, sliding ones with the friction force on a
    cone generator ((contact, generator) pairs) and sliding ones with the force on a polygon
    facet ((contact, facet) pairs, ``edge``: facet i lies between generators i and i + 1; the
    slip velocity is along -n_f, the force's position on the facet is a reaction holding it
    there)."""

    closed: tuple[int, ...] = ()
    stick: tuple[int, ...] = ()
    slide: tuple[tuple[int, int], ...] = ()
    edge: tuple[tuple[int, int], ...] = ()
    #: engaged elastic rings (ring, region, s): their force law adds to Q, C and f0 (:meth:`Ring.terms`)
    ring: tuple[tuple[int, int, int], ...] = ()
    #: released rings whose centre is still beyond the polygon (ring, region): no force, but their events
    #: are the force's return and the region's exits
    latent: tuple[tuple[int, int], ...] = ()

    def describe(self) -> dict:
        out = {"closed": list(self.closed), "stick": list(self.stick), "slide": [list(p) for p in self.slide],
               "edge": [list(p) for p in self.edge]}
        if self.ring or self.latent:
            out.update(ring=[list(p) for p in self.ring], latent=[list(p) for p in self.latent])
        return out

    @property
    def dynamics(self) -> Mode:
        """The mode without its latent rings (they do not change the equations: one configuration)."""
        return replace(self, latent=()) if self.latent else self


def matrix_key(system: ContactSystem, mode: Mode) -> tuple:
    """What of a mode sets its configuration's matrices (constraints, M, C, Q): the contacts' states and per engaged
    ring its :meth:`.Ring.matrix_key`. Modes of one key differ in the constant load alone
    (:meth:`Configuration.with_load`)."""
    rings = tuple((i, system.rings[i].matrix_key(law, s)) for i, law, s in mode.ring)
    return mode.closed, mode.stick, mode.slide, mode.edge, rings


def ring_load(system: ContactSystem, mode: Mode) -> np.ndarray:
    """f0 of a configuration: the system's constant load and the engaged rings' (:meth:`.Ring.load`), in the rings'
    order."""
    if not mode.ring:
        return system.f0
    f0 = system.f0.copy()
    for i, law, s in mode.ring:
        f0 += system.rings[i].load(law, s)
    return f0


def _null(A: np.ndarray, n: int) -> tuple[np.ndarray, int]:
    """Orthonormal basis of null(A^T) for A (n x c), and the rank of A."""
    if A.shape[1] == 0:
        return np.eye(n), 0
    U, s, _ = np.linalg.svd(A, full_matrices=True)
    rank = int(np.sum(s > RANK_TOL * s[0])) if s.size and s[0] > 0 else 0
    return U[:, rank:], rank


#: a configuration mode with omega^2 below RIGID times the largest omega^2 (of the configuration, or of
#: the full model's elements, ``system.info["omega2_ref"]``) is a rigid-body motion: stiffness
#: round-off leaves it at about eps * omega_max^2 (1e-14 to 1e-13 relative, measured on free bars
#: and rotors), a real mode of omega < 1e-6 omega_max is beyond what a first-order
#: eigen-decomposition resolves anyway (the same cutoff as the damping check's rigid modes)
RIGID = 1e-12


def _rigid_split(D: np.ndarray, omega2_ref: float) -> tuple[int, np.ndarray | None]:
    """(k, T): the number of rigid-body coordinates of y'' + ... + D y = ... and an orthogonal T
    whose first k columns span them (D T[:, :k] = 0 to round-off); (0, None) without any."""
    ev = np.linalg.eigvals(D)
    scale = max(float(np.max(np.abs(ev), initial=0.0)), omega2_ref)
    if scale == 0.0:   # no stiffness at all: every coordinate is rigid
        return D.shape[0], np.eye(D.shape[0])
    k = _rigid_count(np.abs(ev), omega2_ref)
    if k == 0:
        return 0, None
    Vt = np.linalg.svd(D)[2]
    Z = Vt[-k:].T
    # the null space must be a clear one: its residual at round-off of the largest omega^2
    if np.abs(D @ Z).max() > 1e3 * RIGID * scale:
        return 0, None
    T, _ = np.linalg.qr(Z, mode="complete")
    return k, T


#: modal damping couplings (off-diagonal entries of Phi^T C Phi) below this fraction of the largest
#: modal damping are round-off of a classical (Rayleigh-type) damping: C = a M + b K gives 1e-15 to
#: 1e-13 (eps times the condition of the mode shapes); a non-proportional damping (external damping
#: on translations only, bearings) couples the modes at 1e-3 to 1
CLASSICAL = 1e-9


def _classical_modes(Mr: np.ndarray, Kr: np.ndarray, Cr: np.ndarray):
    """(w2, Phi, c): the undamped modes of a symmetric configuration, Kr Phi = Mr Phi diag(w2) with
    Phi^T Mr Phi = I (ascending w2), and the modal damping c = diag(Phi^T Cr Phi); None when the
    damping couples the modes (no real modes of the damped system)."""
    w2, Phi = sla.eigh(0.5 * (Kr + Kr.T), 0.5 * (Mr + Mr.T))
    Cm = Phi.T @ Cr @ Phi
    c = np.diag(Cm).copy()
    np.fill_diagonal(Cm, 0.0)
    if np.abs(Cm).max(initial=0.0) > CLASSICAL * np.abs(c).max(initial=0.0):
        return None
    return w2, Phi, c


def _rigid_count(w2: np.ndarray, omega2_ref: float) -> int:
    """The number of rigid-body modes among ascending w2 (:data:`RIGID`)."""
    scale = max(float(np.max(np.abs(w2), initial=0.0)), omega2_ref)
    return w2.size if scale == 0.0 else int(np.sum(np.abs(w2) <= RIGID * scale))


#: a damped pair whose two roots lie closer than this (relative) is critically damped: defective
CRITICAL = 1e-6


def _classical_eig(w2, Phi, Mr, Cr, k: int):
    """(lam, V, Vi) of the modal part w = (b, y') of x = (y, y') (b: y without its first k, rigid,
    coordinates) in closed form from real modes: a rigid mode phi moves w along (0, phi) at rate
    -c (its modal damping, 0 without); an elastic one along (phi_b, lam phi) at the roots lam of
    lam^2 + c lam + w^2; the left vectors follow from Phi^T Mr Phi = I (psi = Phi^T Mr; for an
    elastic mode psi_a = 0: it is mass-orthogonal to the rigid ones). None when an elastic mode is
    critically damped (a defective pair)."""
    r = Phi.shape[0]
    c = np.einsum("ij,ij->j", Phi, Cr @ Phi)
    Psi = Phi.T @ Mr
    e = np.arange(k, r)
    disc = np.sqrt(0.25 * c[e] ** 2 - w2[e] + 0j)
    lp, lm = -0.5 * c[e] + disc, -0.5 * c[e] - disc
    if np.any(np.abs(lp - lm) <= CRITICAL * np.maximum(np.abs(lp), np.abs(lm))):
        return None
    m = r - k
    V = np.zeros((m + r, k + 2 * m), dtype=complex)
    Vi = np.zeros((k + 2 * m, m + r), dtype=complex)
    V[m:, :k] = Phi[:, :k]                      # rigid: (0, phi)
    Vi[:k, m:] = Psi[:k]
    lam = np.concatenate([-c[:k] + 0j, lp, lm])
    Pe, Qe = Phi[:, e], Psi[e]
    for i, (l1, l2) in enumerate(((lp, lm), (lm, lp))):
        cols = slice(k + i * m, k + (i + 1) * m)
        V[:m, cols] = Pe[k:]
        V[m:, cols] = Pe * l1[None, :]
        # the left vector of l1: (l2 psi_b, -psi) / (l2 - l1)
        Vi[cols, :m] = (l2 / (l2 - l1))[:, None] * Qe[:, k:]
        Vi[cols, m:] = -(1.0 / (l2 - l1))[:, None] * Qe
    return lam, V, Vi


class Configuration:
    """The constrained LTI system of one :class:`Mode` (cached by the integrator)."""

    def __init__(self, system: ContactSystem, mode: Mode):
        cs, n = system.contacts, system.n
        self.system, self.mode = system, mode
        slide, edge = dict(mode.slide), dict(mode.edge)
        Gc, Wc, self.rows = [], [], []  # rows: (kind, contact, component)
        for k in mode.closed:
            Gc.append(cs.JN[:, k])
            w = cs.JN[:, k].copy()
            if k in slide:
                w += cs.mu[k] * (cs.JS[k] @ cs.generators(k)[:, slide[k]])
            elif k in edge:
                n_f, _, c, _ = cs.facet(k, edge[k])
                w += cs.mu[k] * c * (cs.JS[k] @ n_f)
            Wc.append(w)
            self.rows.append(("normal", k, 0))
        for k in mode.stick:
            for j in range(cs.JS[k].shape[1]):
                Gc.append(cs.JS[k][:, j])
                Wc.append(cs.JS[k][:, j])
                self.rows.append(("tangent", k, j))
        for k, i in mode.edge:  # the slip along the facet's tangent is held
            col = cs.JS[k] @ cs.facet(k, i)[1]
            Gc.append(col)
            Wc.append(col)
            self.rows.append(("tangent", k, 0))
        self.G = np.column_stack(Gc) if Gc else np.zeros((n, 0))
        self.W = np.column_stack(Wc) if Wc else np.zeros((n, 0))
        self.N, rank = _null(self.G, n)
        self.redundant = self.G.shape[1] - rank
        if slide or edge:
            L, rank_w = _null(self.W, n)
            self.L = L if rank_w == rank else self.N
        else:
            self.L = self.N
        r = self.N.shape[1]
        self.r = r
        M, C, Q = system.M, system.C, system.Q
        self.f0 = ring_load(system, mode)
        symmetric = system.symmetric
        if mode.ring:   # engaged elastic rings: their piecewise-linear force on this region
            C, Q = C.copy(), Q.copy()
            for i, region, s in mode.ring:
                ring = system.rings[i]
                Kr, Cr, _ = ring.terms(region, s)
                Q += Kr
                C += Cr
                symmetric = symmetric and not (ring.friction and s)
        self.C, self.Q = C, Q
        Mr = self.L.T @ M @ self.N
        # (with L = N, Mr = N^T M N is positive definite: only sliding friction can make it singular)
        if r and self.L is not self.N and np.linalg.cond(Mr) > 1e12:
            raise NsfemError(f"configuration {mode.describe()}: no consistent acceleration (the sliding friction "
                             "couples the normal constraint into a singular inertia: a Painleve case)")
        Kr = self.L.T @ Q @ self.N
        Cr = self.L.T @ C @ self.N
        # a symmetric configuration with classical damping: its real modes give the first-order
        # eigen-decomposition in closed form (eigh of r x r instead of eig of 2r x 2r)
        modes = _classical_modes(Mr, Kr, Cr) if r and self.L is self.N and symmetric else None
        T = None
        self.k = 0
        if modes is not None:
            w2, Phi, _ = modes
            k = _rigid_count(w2, float(system.info.get("omega2_ref", 0.0)))
            if k:
                T, _ = np.linalg.qr(Phi[:, :k], mode="complete")
        elif r:
            # rigid-body coordinates (no stiffness): split off first, their stiffness set to exactly 0,
            # so that they move as polynomials in time instead of round-off exponentials
            k, T = _rigid_split(np.linalg.inv(Mr) @ Kr, float(system.info.get("omega2_ref", 0.0)))
        if T is not None:
            same = self.L is self.N
            self.N = self.N @ T
            self.L = self.N if same else self.L
            Mr, Kr, Cr = (self.L.T @ X @ self.N for X in (M, Q, C))
            Kr[:, :k] = 0.0
            self.k = k
            if modes is not None:
                modes = (modes[0], T.T @ modes[1], modes[2])
        # (Phi^T Mr Phi = I: Mr^-1 = Phi Phi^T)
        Mi = (modes[1] @ modes[1].T if modes is not None else np.linalg.inv(Mr)) if r else np.zeros((0, 0))
        self.Mi_L = Mi @ self.L.T                           # r x n
        if self.k:
            # the rigid coordinates' damping at round-off (a stiffness-proportional C on a zero
            # stiffness) is exactly 0: entries of 1e-20 next to 1e2 make LAPACK's balancing lose
            # 7 digits of the eigenvectors (measured: V diag(lam) V^-1 off by 1e-7 of |A|)
            Ck = Cr[:, : self.k]
            Ck[np.abs(Ck) <= 64 * np.finfo(float).eps * np.abs(Cr).max(initial=0.0)] = 0.0
        with np.errstate(over="ignore", invalid="ignore"):
            self.A = np.block([[np.zeros((r, r)), np.eye(r)], [-Mi @ Kr, -Mi @ Cr]]) if r else np.zeros((0, 0))
        if not np.all(np.isfinite(self.A)):
            from .guard import describe_mode, likely_cause

            raise NsfemError(f"no progress: the equations of motion of configuration {describe_mode(cs, mode)} "
                             "overflow the "
                             f"floating-point range (M^-1 Q or M^-1 C is not finite){likely_cause(system)}")
        self.B = np.vstack([np.zeros((r, n)), self.Mi_L])   # x' = A x + B phi
        self.Gpinv = np.linalg.pinv(self.G.T) if self.G.shape[1] else np.zeros((n, 0))  # q_p = -Gpinv g0
        # constraint forces: W lam = R_x x + R_phi phi
        self.Wpinv = np.linalg.pinv(self.W) if self.W.shape[1] else np.zeros((0, n))
        MN = M @ self.N
        self.Rx = np.hstack([MN @ (-Mi @ Kr) + Q @ self.N, MN @ (-Mi @ Cr) + C @ self.N]) if r else np.zeros((n, 0))
        self.Rphi = MN @ self.Mi_L - np.eye(n)
        self.eig = None
        k = self.k
        if r and modes is not None:
            self.eig = _classical_eig(modes[0], modes[1], Mr, Cr, k)
        if r and self.eig is not None:
            self.eigenvalues = np.concatenate([np.zeros(k), self.eig[0]])
        elif r:
            # the modal part w = (b, a', b') of x = (a, b, a', b'): x' = A x with A[:, :k] = 0, so
            # w' = A_w w + B_w phi and a' = S w (S picks a' out of w)
            # balance (y, y') before the eigen-decomposition: with y scaled by a frequency per
            # coordinate, sqrt(K_ii / M_ii), an undamped mode's eigenvector has displacement and
            # velocity parts of one size, so cond(V) no longer grows with w_max / w_min
            dm, dk = np.abs(np.diag(Mr)), np.abs(np.diag(Kr))
            wy = np.sqrt(np.where((dm > 0) & (dk > 0), dk / np.where(dm > 0, dm, 1.0), 0.0))
            wy = np.where(wy > 0, wy, max(float(np.median(wy[wy > 0])) if np.any(wy > 0) else 1.0, 1e-300))
            S = np.concatenate([wy, np.ones(r)])[k:]
            lam, W = np.linalg.eig(self.A[k:, k:] * (S[:, None] / S[None, :]))
            self.eigenvalues = np.concatenate([np.zeros(k), lam])
            # cond(W) in the 1-norm from the inverse (an SVD of W costs several inverses)
            with np.errstate(all="ignore"):
                try:
                    Wi = np.linalg.inv(W)
                    cond = np.linalg.norm(W, 1) * np.linalg.norm(Wi, 1)
                except np.linalg.LinAlgError:
                    cond = np.inf
            if np.isfinite(cond) and cond < COND_MAX:
                self.eig = (lam, W / S[:, None], Wi * S[None, :])
        else:
            self.eigenvalues = np.zeros(0)
        self._phase_parts()

    def _phase_parts(self) -> None:
        """What every :class:`Phase` of this configuration shares: the forcing's fixed parts (the harmonic
        loads, ``A_aug_base``: the augmented matrix but for the constant load's column, which q_p changes)
        and on the modal path the :class:`.closed_form.ModalPlan` and the harmonic load in w-space."""
        sysm, r, k = self.system, self.r, self.k
        self.w = sysm.omega if sysm.harmonic else 0.0
        self.loads = [sysm.fc, sysm.fs] if self.w else []        # of the cos and sin components of xi
        dim = 2 * r + 1 + len(self.loads)
        Aa = self.A_aug_base = np.zeros((dim, dim))               # order: x, 1, cos, sin
        Aa[: 2 * r, : 2 * r] = self.A
        for j, f in enumerate(self.loads):
            Aa[: 2 * r, 2 * r + 1 + j] = self.B @ f
        if self.w:
            Aa[2 * r + 1, 2 * r + 2] = -self.w   # d/dt cos = -w sin
            Aa[2 * r + 2, 2 * r + 1] = self.w    # d/dt sin = w cos
        self.plan = None
        if self.eig is None or not r:
            return
        lam, V, Vi = self.eig
        # cos, sin = Re e^{iwt} (fc - i fs): the load at e^{iwt} but for its phase e^{iw t0}, in w-space
        self.harmonic_b = 0.5 * (self.B[k:] @ (sysm.fc - 1j * sysm.fs)) if self.w else None
        mus = [0j] + ([-1j * self.w, 1j * self.w] if self.w else [])
        S = np.zeros((k, 2 * r - k))
        S[np.arange(k), r - k + np.arange(k)] = 1.0      # a' sits at w[r - k + i]
        # nodes closer than 1e-9 of the fastest rate are one (eigenvalue round-off: a zero computed
        # as 1e-14 |A|); divided differences are exact for any nodes, so a generous floor only costs
        floor = 1e-9 * max(float(np.max(np.abs(lam), initial=0.0)), self.w)
        self.plan = ModalPlan(lam, V, mus, k, S, floor)

    def with_load(self, mode: Mode) -> Configuration:
        """The configuration of ``mode``, whose equations differ from this one's in the constant load alone (the
        same :func:`matrix_key`: elastic rings' laws of the same Kr and Cr): everything but ``f0`` shared, f0 as
        its own construction forms it (bit for bit the configuration ``Configuration(system, mode)`` would be,
        without its decompositions)."""
        out = copy.copy(self)
        out.mode, out.f0 = mode, ring_load(self.system, mode)
        arrays = self.__dict__.get("kernel_arrays")
        if arrays is not None:
            out.kernel_arrays = {**arrays, "f0": np.ascontiguousarray(out.f0, dtype=float)}
        return out

    @cached_property
    def kernel_arrays(self) -> dict:
        """The arrays the compiled phase set-up reads (core part "phase"), C-ordered, the complex ones as
        float64 views of their (real, imaginary) pairs; formed on the first compiled phase."""
        out = {"GpinvT": self.Gpinv.T, "QT": self.Q.T, "f0": self.f0, "BT": self.B.T, "N": self.N}
        out = {key: np.ascontiguousarray(a, dtype=float) for key, a in out.items()}
        if self.plan is not None:
            Vi, V, den = self.eig[2], self.plan.V, self.plan.den
            # the harmonic load's modal terms but for the phase e^{i w t0} (kernel phase_modal): Vi conj(hb),
            # Vi hb, those over den_1, den_2, and V times these
            harmonic = np.zeros((6, max(Vi.shape[0], V.shape[0])), dtype=complex)
            if self.harmonic_b is not None:
                beta = np.array([Vi @ np.conj(self.harmonic_b), Vi @ self.harmonic_b])
                g = beta / den[1:]
                harmonic[:2, : Vi.shape[0]], harmonic[2:4, : Vi.shape[0]] = beta, g
                harmonic[4:, : V.shape[0]] = g @ V.T
            out.update({key: np.ascontiguousarray(a, dtype=complex).view(float)
                        for key, a in (("ViT", Vi.T), ("V", V), ("den", den), ("harmonic", harmonic))})
        return out

    # ------------------------------------------------------------------------------
    def particular(self, g0: np.ndarray) -> np.ndarray:
        """q_p with G^T q_p + g0 = 0 (least norm)."""
        return -self.Gpinv @ g0 if g0.size else np.zeros(self.system.n)

    def force_parts(self) -> tuple[np.ndarray, np.ndarray]:
        """(Wpinv Rx, the harmonic loads' Wpinv Rphi f as columns): the parts of every phase's force map
        that the configuration fixes (formed once)."""
        parts = self.__dict__.get("_force_parts")
        if parts is None:
            harmonic = np.column_stack([self.Wpinv @ (self.Rphi @ f) for f in self.loads]) if self.loads else \
                np.zeros((self.W.shape[1], 0))
            parts = self._force_parts = (self.Wpinv @ self.Rx, harmonic)
        return parts

    def term_order(self, nu: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
        """(speed, order, steady) of a phase's exponents nu (the modes', then the forcing's: the same for
        every phase of this configuration, formed once): |nu|, the modes fastest first (stable), and
        whether no term grows. Only modes are left out by a search, never the forcing's particular
        solutions: the rows' direct harmonic terms stay, and without their particular solutions the kept
        slope (from H A_aug) would no longer be the kept value's derivative."""
        cached = self.__dict__.get("_term_order")
        if cached is None or cached[0] is not nu:
            speed = np.abs(nu)
            order = np.argsort(-speed[: self.eig[0].size], kind="stable")
            cached = self._term_order = (nu, speed, order, bool(np.all(nu.real <= 0.0)))
        return cached[1:]

    def state_maps(self) -> tuple[np.ndarray, np.ndarray]:
        """(Pq, Pv) with q = Pq xi, q' = Pv xi for the phases' augmented states xi (x, 1, cos, sin), Pq
        without the particular solution each phase puts in its constant column (formed once, read-only)."""
        maps = self.__dict__.get("_state_maps")
        if maps is None:
            r, n = self.r, self.system.n
            dim = 2 * r + 1 + len(self.loads)
            Pq, Pv = np.zeros((n, dim)), np.zeros((n, dim))
            Pq[:, :r] = self.N
            Pv[:, r: 2 * r] = self.N
            Pq.flags.writeable = Pv.flags.writeable = False
            maps = self._state_maps = (Pq, Pv)
        return maps

    def base_finite(self) -> bool:
        """Whether A_aug_base has finite entries only (its phases' A_aug then have iff their B f0 has; formed once)."""
        cached = self.__dict__.get("_base_finite")
        if cached is None or cached[0] is not self.A_aug_base:
            cached = self._base_finite = (self.A_aug_base, bool(np.all(np.isfinite(self.A_aug_base))))
        return cached[1]

    def fastest_rate(self) -> float:
        """max |eigenvalue| of A [1/s] (0 without coordinates); formed once per set of eigenvalues."""
        cached = self.__dict__.get("_fastest_rate")
        if cached is None or cached[0] is not self.eigenvalues:
            cached = self._fastest_rate = (self.eigenvalues, float(np.max(np.abs(self.eigenvalues), initial=0.0)))
        return cached[1]


@dataclass
class SearchPlan:
    """What :meth:`Phase.search_plan` gives a search: ``rows(t)`` (the rows without the terms left
    out), the fastest ``rate`` kept, ``e`` the left-out terms' bound per row, ``bound(order)`` the kept
    part's derivative bound per row (None for xi itself), ``renew`` (from the phase's start) the time
    from which a new plan leaves out more."""

    rows: object
    rate: float
    e: np.ndarray
    bound: object
    renew: float = math.inf


def _renewal(nu, size, order, n_drop, cum, budget, since) -> float:
    """The tau (>= since) from which the fastest terms kept (those of order[n_drop]'s speed), if they
    decay, fit the budget next to those already left out: sizes at since times e^{Re(nu) (tau - since)}
    (the left-out ones decay or stay: their sum at since bounds it later too); inf if they do not decay
    or no term is left to leave out."""
    if n_drop >= order.size:
        return math.inf
    speed = np.abs(nu[order])
    group = order[n_drop:][speed[n_drop:] == speed[n_drop]]
    rate = float(np.max(nu[group].real))
    if not rate < 0.0:
        return math.inf
    s = size[:, group].sum(axis=1)
    room = budget - (cum[:, n_drop - 1] if n_drop else 0.0)
    need = s > 0.0
    if not np.any(need):
        return math.inf
    if np.any(room[need] <= 0.0):
        return math.inf
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(need, s / np.where(need, room, 1.0), 0.0)
    wait = float(np.log(ratio.max())) / -rate
    return since + wait if wait > 0.0 else math.inf   # (it would fit already: nothing to wait for)


class Phase:
    """Exact motion of one configuration from (t0, q0, v0); all outputs are maps of xi(t).

    ``amplitudes``: (c, g) with x(t0 + s) = V (c e^{lam s} + sum_mu g_mu e^{mu s}) when the motion is modes
    and particular solutions only (no rigid coordinates, no divided differences); None otherwise."""

    def __init__(self, config: Configuration, t0: float, q0: np.ndarray, v0: np.ndarray, g0: np.ndarray):
        self.config, self.t0 = config, float(t0)
        self.g0 = np.asarray(g0, dtype=float)
        N, r = config.N, config.r
        self.w = config.w
        kernel = core.compiled("phase")
        if kernel is not None and not _fits_setup(config, self.g0, q0, v0):
            kernel = None   # (the set-up kernel reads without bounds checks: the reference broadcasts or refuses)
        modes = None
        if kernel is None:
            self.qp = config.particular(self.g0)
            # forcing phi(t) = (f0 - Q q_p) + fc cos + fs sin as extra state components
            f0 = config.f0 - config.Q @ self.qp
            self.x0 = np.concatenate([N.T @ (q0 - self.qp), N.T @ v0])
            Bf0 = config.B @ f0
        else:   # the set-up and the modal coefficients in one call
            self.qp, f0, self.x0, Bf0, modes = _compiled_setup(kernel, config, self.g0, q0, v0, self.t0)
        self.forcing = [f0] + config.loads
        self.dim = 2 * r + len(self.forcing)
        # augmented matrix (order: x, 1, cos, sin): the configuration's, with this phase's constant load
        self.A_aug = config.A_aug_base.copy()
        self.A_aug[: 2 * r, 2 * r] = self._Bf0 = Bf0
        self._modal = self.amplitudes = None
        self._xi_kernel = None
        #: samples the event search evaluated on this phase (its fine passes; set by ``events.first_event``)
        self.search_samples = 0
        if config.plan is not None:
            self._modal = self._motion(Bf0, modes)
            if kernel is not None:   # _xi_at's modal sum compiled: the kernel, its arrays' float views, the set-up
                self._xi_kernel = (kernel.xi_at, self._modal.U.view(float), self._modal.nu.view(float),
                                   phase_setup(kernel, config)[0])
        if self._modal is None:
            self._xi0 = np.concatenate([self.x0, self._harmonics(self.t0)])

    # -- propagation -----------------------------------------------------------------
    def _harmonics(self, t):
        t = np.asarray(t, dtype=float)
        parts = [np.ones_like(t)]
        if self.w:
            parts += [np.cos(self.w * t), np.sin(self.w * t)]
        return np.array(parts)

    def _motion(self, Bf0: np.ndarray, modes: tuple | None = None) -> Motion:
        """x(t - t0) in closed form (:class:`.closed_form.ModalPlan`): modes, particular solutions, and
        divided differences where the forcing is resonant or a rigid-body coordinate integrates a load.
        Without those (modes and particular solutions only) ``amplitudes`` keeps its modal coefficients.
        ``modes``: (z0, beta, U, c, g) as the compiled set-up formed them (None: this reference)."""
        cfg, k = self.config, self.config.k
        if modes is None:
            Vi = cfg.eig[2]
            beta = np.empty((len(cfg.plan.mus), Vi.shape[0]), dtype=complex)     # mus: 0, -iw, iw
            beta[0] = Vi @ Bf0[k:]
            if self.w:
                b = cfg.harmonic_b * np.exp(1j * self.w * self.t0)
                beta[1] = Vi @ np.conj(b)
                beta[2] = Vi @ b
            z0 = Vi @ self.x0[k:]
            U, c, g = cfg.plan.modes(z0, beta)
        else:
            z0, beta, U, c, g = modes
        mot = cfg.plan.complete(U, z0, beta, self.x0[:k])
        if not k and not mot.groups:
            self.amplitudes = (c, g)
        return mot

    def xi(self, t) -> np.ndarray:
        """The augmented state at times t (scalar -> (dim,), array -> (dim, len(t)))."""
        if self._modal is not None and isinstance(t, float):
            return self._xi_at(t)
        t = np.asarray(t, dtype=float)
        scalar = t.ndim == 0
        tt = np.atleast_1d(t)
        r2 = 2 * self.config.r
        out = np.empty((self.dim, tt.size))
        out[r2:] = self._harmonics(tt)
        if r2:
            if self._modal is not None:
                out[:r2] = self._modal.evaluate(tt - self.t0)
            else:
                out[:r2] = self._expm_states(tt)[:r2]
        return out[:, 0] if scalar else out

    def xi_on_grid(self, t: float, dt: float, n: int) -> np.ndarray:
        """xi at the n times t + j dt (dim x n); on the modal path by repeated products of the exponentials
        (:meth:`.closed_form.Motion.on_grid`), whatever the round-off of the times."""
        ts = t + dt * np.arange(n)
        if self._modal is None or not self.config.r:
            return self.xi(ts)
        out = np.empty((self.dim, n))
        out[2 * self.config.r:] = self._harmonics(ts)
        out[: 2 * self.config.r] = self._modal.on_grid(t - self.t0, dt, n)
        return out

    def state_at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(q, q') at one time: ``q_map() @ xi(t)``, ``v_map() @ xi(t)`` (the loop's state at an event); on the
        modal path without divided differences one compiled call (``PhaseSetup.state``) when the core has it."""
        if self._xi_kernel is not None and not self._modal.groups and self._modal.U.shape[0] == 2 * self.config.r:
            n = self.config.system.n
            q, v = np.empty(n), np.empty(n)
            _, U, nu, setup = self._xi_kernel
            setup.state(U, nu, t - self.t0, self.qp, q, v)
            return q, v
        xi = self.xi(t)
        return self.q_map() @ xi, self.v_map() @ xi

    def _xi_at(self, t: float) -> np.ndarray:
        """xi at one time on the modal path (root refinement reads rows from it many times per
        event): the same sums as :meth:`xi`, without its array set-up."""
        mot, tau = self._modal, t - self.t0
        if self._xi_kernel is not None:
            xi_at, Uv, nuv, _ = self._xi_kernel
            out = np.empty(self.dim)
            xi_at(Uv, nuv, tau, self.w, t, out)
            for nodes, D in mot.groups:
                out[: mot.U.shape[0]] += (D @ divided_exp(nodes, np.array([tau]))[:, 0]).real
            return out
        x = (mot.U @ np.exp(mot.nu * tau)).real
        for nodes, D in mot.groups:
            x += (D @ divided_exp(nodes, np.array([tau]))[:, 0]).real
        if self.w:
            return np.concatenate((x, (1.0, math.cos(self.w * t), math.sin(self.w * t))))
        return np.append(x, 1.0)

    def row_map(self, H: np.ndarray):
        """t -> H xi(t) (rows x len(t)), cheaper than ``H @ xi(t)`` on the modal path: the
        products of H with the mode shapes and particular solutions are formed once."""
        r2 = 2 * self.config.r
        if not r2 or self._modal is None:
            return lambda t: H @ self.xi(np.atleast_1d(np.asarray(t, dtype=float)))
        return self._rows(self._modal, H)

    def _rows(self, mot: Motion, H: np.ndarray | None):
        """t -> H xi(t) with xi's modal part from ``mot`` (H's products with it formed once); xi(t)
        itself without H."""
        r2 = 2 * self.config.r
        if H is None:
            return self._states_of(mot)
        return self._rows_of(Motion(mot.nu, H[:, :r2] @ mot.U, [(nodes, H[:, :r2] @ D) for nodes, D in mot.groups]),
                             H[:, r2:])

    def _states_of(self, mot: Motion):
        """t -> xi(t) with its modal part from ``mot``."""
        def states(t):
            tt = np.atleast_1d(np.asarray(t, dtype=float))
            return np.vstack([mot.evaluate(tt - self.t0), self._harmonics(tt)])

        return states

    def _rows_of(self, Hm: Motion, Hh: np.ndarray):
        """t -> Hm(t - t0) + Hh (harmonic components of xi)(t): rows whose modal products are formed."""
        def rows(t):
            tt = np.atleast_1d(np.asarray(t, dtype=float))
            return Hm.evaluate(tt - self.t0) + Hh @ self._harmonics(tt)

        rows.terms = Hm    # what the compiled search samples (events._compiled_search)
        return rows

    def search_map(self, H: np.ndarray, budget: np.ndarray, horizon: float):
        """(rows, rate, e, bound) of :meth:`search_plan` over the whole horizon."""
        plan = self.search_plan(H, budget, horizon)
        return plan.rows, plan.rate, plan.e, plan.bound

    def search_plan(self, H: np.ndarray | None, budget: np.ndarray, horizon: float, since: float = 0.0,
                    images: np.ndarray | None = None) -> SearchPlan:
        """The rows H xi(t) a search follows over tau = t - t0 in [since, horizon]: without the fastest
        exponential terms whose contributions to row i sum to at most budget[i] there (e[i] that sum; a
        decaying term counts at its size at ``since``, a growing one at the horizon), ``rate`` the fastest
        rate left (it sets the sampling step), ``bound(order)`` per row of H the bound of the order-th
        derivative of what is left on [since, horizon], ``renew`` the tau from which the fastest term
        kept, if it decays, has decayed into the budget (a plan from there leaves it out; inf if never).
        Without a modal form: the full rows. H None: xi itself (budget per component of its modal part;
        for quadratures). ``images``: H[:, :r2] U when the caller has formed it (events.modal_images)."""
        r2 = 2 * self.config.r
        if H is None and (not r2 or self._modal is None):
            return SearchPlan(self.xi, self.config.fastest_rate(), np.zeros(self.dim), None)
        if not r2 or self._modal is None:
            return SearchPlan(self.row_map(H), self.config.fastest_rate(), np.zeros(H.shape[0]),
                              lambda order: self.derivative_bound(H, order, horizon))
        mot = self._modal
        # formed once: for the sizes, the rows and their bound
        HU = mot.U if H is None else (H[:, :r2] @ mot.U if images is None else images)
        speed, order, steady = self.config.term_order(mot.nu)
        size = np.abs(HU)
        if since or not steady:
            size *= decay_factors(mot.nu, horizon, since)[None, :]
        modes = order.size
        cum = np.cumsum(size[:, order], axis=1)
        fits = np.all(cum <= budget[:, None], axis=0)            # a prefix (cum is nondecreasing)
        n_drop = int(np.argmin(fits)) if not fits.all() else fits.size
        # terms of one speed (a conjugate pair) are left out together or not at all
        while 0 < n_drop < order.size and speed[order[n_drop]] == speed[order[n_drop - 1]]:
            n_drop -= 1
        groups = mot.groups if H is None else [(nodes, H[:, :r2] @ D) for nodes, D in mot.groups]
        if n_drop == 0:
            kept, rate, e = Motion(mot.nu, HU, groups), self.config.fastest_rate(), np.zeros(HU.shape[0])
        else:
            keep = np.concatenate([np.sort(order[n_drop:]), np.arange(modes, speed.size)])
            kept, e = Motion(mot.nu[keep], HU[:, keep], groups), cum[:, n_drop - 1]
            rate = float(np.max(speed[keep], initial=0.0))
            for nodes, _ in mot.groups:
                rate = max(rate, float(np.max(np.abs(nodes), initial=0.0)))
        # (a kept term that does not decay: no renewal)
        renew = _renewal(mot.nu, size, order, n_drop, cum, budget, since) \
            if n_drop < order.size and mot.nu[order[n_drop]].real < 0.0 else math.inf

        if H is None:
            return SearchPlan(self._states_of(kept), rate, e, None, renew)

        def bound(order_):
            b = kept.bound(None, order_, horizon, since)
            if self.w:
                b = b + (np.abs(H[:, r2 + 1]) + np.abs(H[:, r2 + 2])) * power(self.w, order_)
            return b

        return SearchPlan(self._rows_of(kept, H[:, r2:]), rate, e, bound, renew)

    def pruned_xi(self, rel: float, horizon: float):
        """(xi_fun, rate): xi(t) without the fastest terms whose sum stays below ``rel`` of the
        positions' (velocities') total size over the horizon (round-off amplitudes of stiff
        modes), and the fastest rate left; for quadratures of the work integrals."""
        r, r2 = self.config.r, 2 * self.config.r
        if not r2 or self._modal is None:
            return self.xi, self.config.fastest_rate()
        size = self._modal.bound(None, 0, horizon)   # with a rigid body's travel, a resonant growth
        budget = np.concatenate([np.full(r, rel * size[:r].max(initial=0.0)),
                                 np.full(r, rel * size[r:].max(initial=0.0)), np.full(self.dim - r2, np.inf)])
        rows, rate, _, _ = self.search_map(None, budget[:r2], horizon)
        return rows, rate

    def _expm_states(self, tt: np.ndarray) -> np.ndarray:
        """xi at times tt by the matrix exponential, stepping through the sorted times and
        reusing exp(A_aug dt) for repeated steps dt (uniform grids, quadrature patterns)."""
        order = np.argsort(tt)
        out = np.empty((self.dim, tt.size))
        cache = self.__dict__.setdefault("_expm_cache", {})
        t_prev, xi = self.t0, self._xi0
        for j in order:
            dt = float(tt[j] - t_prev)
            if dt != 0.0:
                key = float(f"{dt:.13e}")
                E = cache.get(key)
                if E is None:
                    E = sla.expm(self.A_aug * dt)
                    if len(cache) < 64:
                        cache[key] = E
                xi = E @ xi
                t_prev = tt[j]
            out[:, j] = xi
        return out

    def exponential_terms(self):
        """xi(t) = Re sum_j U[:, j] exp(mu_j (t - t0)) (modal path without divided differences), or None.

        Terms: the configuration's modes, the particular solutions with the constant component,
        and the harmonic particular solutions with the cos/sin components split into exp(+-i w t).
        """
        if self._modal is None or self._modal.groups:
            return None
        return self.closed_form_terms()[:2]

    def closed_form_terms(self):
        """(U, nu, groups): xi(t) = Re[sum_j U[:, j] exp(nu_j (t - t0)) + sum over groups D F[nodes](t - t0)]
        on the modal path (:meth:`exponential_terms` and the divided-difference groups, each (nodes (m, K),
        D (dim x K)) with D's rows beyond the modal part zero), or None."""
        if self._modal is None:
            return None
        mot = self._modal
        r2 = 2 * self.config.r
        # the constant, cos and sin components of xi as exponentials: 1, (e^{iwt} +- e^{-iwt}) / (2, 2i)
        extra = {0j: {r2: 1.0}}
        if self.w:
            ph = np.exp(1j * self.w * self.t0)
            extra[1j * self.w] = {r2 + 1: 0.5 * ph, r2 + 2: -0.5j * ph}
            extra[-1j * self.w] = {r2 + 1: 0.5 * np.conj(ph), r2 + 2: 0.5j * np.conj(ph)}
        m = self.config.eig[0].size           # mot.nu: the modes, then the forcing's exponents
        U = np.zeros((self.dim, mot.nu.size + len(extra)), dtype=complex)
        U[:r2, : mot.nu.size] = mot.U
        nu = np.concatenate([mot.nu, np.zeros(len(extra), dtype=complex)])
        for i, (mu, comps) in enumerate(extra.items()):
            hit = np.flatnonzero(mot.nu[m:] == mu)
            j = m + int(hit[0]) if hit.size else mot.nu.size + i
            nu[j] = mu
            for row, val in comps.items():
                U[row, j] += val
        groups = []
        for nodes, D in mot.groups:
            Dx = np.zeros((self.dim, D.shape[1]), dtype=complex)
            Dx[: D.shape[0]] = D
            groups.append((nodes, Dx))
        return U, nu, groups

    def derivative_bound(self, H: np.ndarray, order: int, horizon: float, images: np.ndarray | None = None
                         ) -> np.ndarray:
        """Per row of H, a bound of the order-th time derivative of H xi over [t0, t0 + horizon] (``images``:
        H[:, :r2] U when the caller has it)."""
        r2 = 2 * self.config.r
        if self._modal is not None:
            b = self._modal.bound(H[:, :r2], order, horizon, HU=images)
            if self.w:
                b = b + (np.abs(H[:, r2 + 1]) + np.abs(H[:, r2 + 2])) * power(self.w, order)
            return b
        # crude: |H A_aug^order xi| <= |H| ||A_aug||^order max|xi| (with growth)
        nA = np.linalg.norm(self.A_aug, 2)
        with np.errstate(over="ignore"):
            xi_max = np.linalg.norm(self._xi0) * np.exp(min(nA * horizon, 700.0))
            return np.minimum(np.linalg.norm(H, axis=1) * nA ** order * xi_max, np.inf)


    # -- maps ----------------------------------------------------------------------
    def q_map(self) -> np.ndarray:
        """q = Pq xi (formed once per phase, read-only)."""
        P = self.__dict__.get("_Pq")
        if P is None:
            P = self.config.state_maps()[0].copy()
            P[:, 2 * self.config.r] = self.qp   # the constant component is 1
            P.flags.writeable = False
            self._Pq = P
        return P

    @property
    def system_n(self) -> int:
        return self.config.system.n

    def v_map(self) -> np.ndarray:
        """q' = Pv xi (the configuration's, read-only)."""
        return self.config.state_maps()[1]

    def force_map(self) -> np.ndarray:
        """lam (constraint forces, one per row of the configuration) = P xi (formed once per phase, read-only;
        its columns but the constant load's once per configuration)."""
        P = self.__dict__.get("_Pf")
        if P is None:
            cfg, r = self.config, self.config.r
            P = np.zeros((cfg.W.shape[1], self.dim))
            if cfg.W.shape[1]:
                P[:, : 2 * r], harmonic = cfg.force_parts()
                P[:, 2 * r] = self.constant_forces()
                P[:, 2 * r + 1:] = harmonic
            P.flags.writeable = False
            self._Pf = P
        return P

    def constant_forces(self) -> np.ndarray:
        """The force map's constant column, Wpinv Rphi f0 of this phase's constant load (formed once per phase,
        without the rest of the map: the event rows need this column alone)."""
        lam = self.__dict__.get("_lam0")
        if lam is None:
            cfg = self.config
            lam = self._lam0 = cfg.Wpinv @ (cfg.Rphi @ self.forcing[0]) if cfg.W.shape[1] else np.zeros(0)
        return lam

    def finite(self) -> bool:
        """Whether A_aug has finite entries only: the configuration's part (A_aug_base, its constant column 0)
        and this phase's B f0 (a finite sum has no non-finite term; an overflowing one is judged term by term)."""
        Bf0 = self._Bf0
        return self.config.base_finite() and (math.isfinite(Bf0.sum()) or bool(np.all(np.isfinite(Bf0))))

    def max_step(self, horizon: float, rate: float | None = None) -> float:
        """Sampling step for event search: 1/8 of the fastest period (or time constant), of the
        configuration or of the given ``rate`` (the fastest term a search follows)."""
        rate = max(self.config.fastest_rate() if rate is None else rate, self.w)
        h = math.pi / (4.0 * rate) if rate > 0 else math.inf
        return min(h, horizon / 8.0) if horizon > 0 else h


def _fits_setup(config: Configuration, g0: np.ndarray, q0, v0) -> bool:
    """Whether the compiled set-up may read these: q0 and v0 of the n coordinates, g0 one value per constraint
    row of the configuration (or none: q_p = 0, as :meth:`Configuration.particular`)."""
    n = (config.system.n,)
    return getattr(q0, "shape", None) == n and getattr(v0, "shape", None) == n \
        and g0.ndim == 1 and g0.size in (0, config.Gpinv.shape[1])


def _compiled_setup(kernel, config: Configuration, g0: np.ndarray, q0: np.ndarray, v0: np.ndarray, t0: float):
    """(q_p, f0, x0, B f0, modes) of :meth:`Phase.__init__` by one call of the compiled kernel
    ``PhaseSetup.start`` (phase_start, then phase_modal with a modal plan): views into one buffer; modes the
    (z0, beta, U, c, g) of :meth:`Phase._motion` and :meth:`.closed_form.ModalPlan.modes` (U's rigid rows left
    to :meth:`.closed_form.ModalPlan.complete`), None without a modal plan."""
    setup, lay, shapes = phase_setup(kernel, config)
    buf = np.empty(lay[9])
    setup.start(np.ascontiguousarray(g0, dtype=float), np.ascontiguousarray(q0, dtype=float),
                np.ascontiguousarray(v0, dtype=float), config.w, t0, buf)
    qp, f0, Bf0, x0 = buf[lay[0]: lay[1]], buf[lay[1]: lay[2]], buf[lay[2]: lay[3]], buf[lay[3]: lay[4]]
    if shapes is None:
        return qp, f0, x0, Bf0, None
    z0, beta, c, g, U = (buf[lay[i]: lay[i + 1]].view(complex) for i in range(4, 9))
    return qp, f0, x0, Bf0, (z0, beta.reshape(shapes[0]), U.reshape(shapes[1]), c, g.reshape(shapes[0]))


def phase_setup(kernel, config: Configuration) -> tuple:
    """(the compiled ``PhaseSetup`` of ``config``'s kernel_arrays, its buffer's layout, the shapes (beta and g,
    U) or None without a modal plan), formed once per configuration (again when its kernel_arrays change:
    :meth:`Configuration.with_load`)."""
    arrays = config.kernel_arrays
    hit = config.__dict__.get("_phase_setup")
    if hit is None or hit[0] is not arrays:
        a, plan = arrays, config.plan
        if plan is None:
            setup, shapes = kernel.PhaseSetup(a["GpinvT"], a["QT"], a["f0"], a["BT"], a["N"]), None
        else:
            nmu, p = len(plan.mus), plan.nu.size
            setup = kernel.PhaseSetup(a["GpinvT"], a["QT"], a["f0"], a["BT"], a["N"], a["ViT"], a["harmonic"],
                                      a["V"], a["den"], config.k, nmu, p)
            shapes = ((nmu, config.eig[2].shape[0]), (config.k + plan.V.shape[0], p))
        hit = config.__dict__["_phase_setup"] = (arrays, setup, setup.layout, shapes)
    return hit[1:]
