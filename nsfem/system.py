"""The linear system of eq. (22) without contact forces, for one rotation speed.

    M q'' + C q' + Q q = f(t),   C = G + D_i + D_e,   Q = K0 + Kc + P,
    f(t) = f0 + fc cos(Omega t) + fs sin(Omega t)

with G = Omega G1, Kc = Omega^2 Kc1, P = Omega c_e P1, D_i = alpha M + beta K0,
D_e = c_e De1, f0 = Omega^2 fc1 + Omega c_e fd1 (+ gravity when not rotating) and the
gravity harmonics at the rotation frequency (design section 3). What a scene does not
need is left out: no rotation, no G, Kc, P, f_c; no gravity, no harmonic load; no
damping and no rotation, ``C is None``.

>>> from nsfem import build_model, load_scene
>>> from nsfem.fem.rotating import rotor_operators
>>> ops = rotor_operators(build_model(load_scene(None, ["mesh.elements=20"])))
>>> s = linear_system(ops, speed_hz=21.0, gravity=9.81)
>>> s.C is not None, s.fc is not None, round(s.omega / (2 * 3.141592653589793), 6)
(True, True, 21.0)
>>> linear_system(ops, speed_hz=0.0, gravity=0.0).C is None
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from .errors import SceneError
from .fem.rotating import RotorOperators

if TYPE_CHECKING:
    from .scene import Damping, Rotation, Scene

#: Largest damping ratio zeta of any mode: an overdamped mode decays at two rates whose ratio is
#: 4 zeta^2; beyond 1/eps the slow one is lost in the round-off of the fast one, i.e. beyond
#: zeta = 1 / (2 sqrt(eps)) = 3.4e7 double precision cannot hold the damped system at all.
ZETA_MAX = 0.5 / math.sqrt(np.finfo(float).eps)


def damping_ratio(rayleigh, w: np.ndarray) -> tuple[float, float]:
    """(largest damping ratio, its frequency [rad/s]) of Rayleigh damping C = alpha M + beta K over
    the elastic modes ``w``: zeta(w) = alpha / (2 w) + beta w / 2, convex in w, so largest at the
    lowest or the highest one (rigid modes are left out: alpha merely stops them; round-off puts
    their computed frequencies near sqrt(eps) w_max = 1.5e-8 w_max, so everything below 1e-6 w_max
    counts as rigid)."""
    alpha, beta = rayleigh
    w = np.asarray(w, dtype=float)
    w = w[w > 1e-6 * np.max(w, initial=0.0)]
    if w.size == 0:
        return 0.0, 0.0
    ends = np.array([w.min(), w.max()])
    with np.errstate(over="ignore"):
        zeta = alpha / (2 * ends) + beta * ends / 2
    k = int(np.argmax(zeta))
    return float(zeta[k]), float(ends[k])


def check_damping(rayleigh, w: np.ndarray, external: float = 0.0, mass_per_length: float = math.inf) -> None:
    """Refuse damping beyond :data:`ZETA_MAX` on some mode of the model (``w`` rad/s).

    External damping c_e per unit length acts on the lateral motion like alpha_e M with
    alpha_e <= c_e / min(rho A) (``mass_per_length``): its damping ratio is at most
    c_e / (2 min(rho A) w), largest at the lowest mode."""
    zeta, at = damping_ratio(rayleigh, w)
    if zeta > ZETA_MAX:
        alpha, beta = rayleigh
        raise SceneError("damping.rayleigh", f"[{alpha:g}, {beta:g}] gives the mode at {at / (2 * np.pi):.4g} Hz a "
                         f"damping ratio alpha / (2 w) + beta w / 2 = {zeta:.3g}, beyond {ZETA_MAX:.2g}: its slow and "
                         "fast decay rates differ by 4 zeta^2, more than double precision can hold "
                         "(heavy overdamping up to that ratio runs)")
    if external > 0.0 and mass_per_length > 0.0:
        zeta, at = damping_ratio((external / mass_per_length, 0.0), w)
        if zeta > ZETA_MAX:
            raise SceneError("damping.external", f"{external:g} N s/m^2 gives the lowest mode a damping ratio up "
                             f"to c_e / (2 rho A w) = {zeta:.3g}, beyond {ZETA_MAX:.2g}: its slow and "
                             "fast decay rates differ by 4 zeta^2, more than double precision can hold")


@dataclass(frozen=True)
class LinearSystem:
    """M, C, Q and the load f0 + fc cos(omega t) + fs sin(omega t); absent parts are None."""

    M: sp.csr_matrix
    C: sp.csr_matrix | None
    Q: sp.csr_matrix
    f0: np.ndarray | None
    fc: np.ndarray | None
    fs: np.ndarray | None
    omega: float  # rotation (and gravity forcing) frequency [rad/s]

    @property
    def n(self) -> int:
        return self.M.shape[0]

    def load(self, t: float | np.ndarray) -> np.ndarray:
        """f(t), shape (n,) for a scalar t or (n, len(t))."""
        t = np.asarray(t, dtype=float)
        out = np.zeros((self.n,) + t.shape)
        if self.f0 is not None:
            out += self.f0.reshape((-1,) + (1,) * t.ndim)
        for vec, fn in ((self.fc, np.cos), (self.fs, np.sin)):
            if vec is not None:
                out += np.multiply.outer(vec, fn(self.omega * t))
        return out


def linear_system(ops: RotorOperators, speed_hz: float = 0.0, gravity: float = 0.0, phase_deg: float = 0.0,
                  rayleigh: tuple[float, float] = (0.0, 0.0), external: float = 0.0,
                  frame: str = "rotating") -> LinearSystem:
    """Eq. (22) at ``speed_hz`` from operators assembled once (any basis), in the rotating frame (the
    paper's) or the inertial one (axisymmetric rotors; docs/theory.md, "The inertial frame").

    Rotating: C = Omega G1 + D_i + c_e De1 + C_b, Q = K0 + K_c + Omega^2 Kc1 + Omega (c_e P1 + C_b J),
    f = Omega^2 (fc1 + fu1) + Omega c_e fd1 + gravity turning at Omega.
    Inertial: C = Omega Gp1 + D_i + c_e De1 + C_b, Q = K0 + K_c - Omega D_i J (the rotating internal damping's
    circulatory part), f = gravity along -z + the unbalance turning at Omega.
    D_i = alpha M + beta (K0 - K_b): Rayleigh damping of the rotor, not of its bearings; K_c the bearings'
    cross coupling (skew). Bearings with coefficients tabulated against speed take them at ``speed_hz``."""
    if frame not in ("rotating", "inertial"):
        raise ValueError(f"unknown frame {frame!r}")
    ops = ops.at_speed(speed_hz)   # speed-dependent bearings: their tables read at this speed
    w = 2.0 * math.pi * speed_hz
    alpha, beta = rayleigh
    phi = math.radians(phase_deg)
    inertial = frame == "inertial"
    bearings = ops.Cb.nnz > 0
    parts = []
    if w:
        parts.append(w * (ops.Gp1 if inertial else ops.G1))
    if alpha:
        parts.append(alpha * ops.M)
    if beta:
        parts.append(beta * (ops.K0 - ops.Kb) if ops.Kb.nnz else beta * ops.K0)
    if external:
        parts.append(external * ops.De1)
    if bearings:
        parts.append(ops.Cb)
    parts = [p for p in parts if p.nnz]
    C = sum(parts[1:], parts[0]).tocsr() if parts else None
    Q = ops.K0 + ops.Kbc if ops.Kbc.nnz else ops.K0
    if w and inertial:
        if alpha:
            Q = Q - w * alpha * ops.MJ
        if beta:
            Q = Q - w * beta * ops.KJ
    elif w:
        Q = Q + w**2 * ops.Kc1
        if external:
            Q = Q + w * external * ops.P1
        if bearings:
            Q = Q + w * ops.CbJ
    f0 = fc = fs = None
    unbalanced = bool(np.any(ops.fu1)) and w
    if inertial:
        if gravity:
            f0 = -gravity * ops.Fz
        if unbalanced:
            # m e Omega^2 along the rotating direction (cos phi_u, sin phi_u) turned by Omega t + phi
            c, s = math.cos(phi), math.sin(phi)
            fc = w**2 * (c * ops.fu1 + s * ops.fq1)
            fs = w**2 * (c * ops.fq1 - s * ops.fu1)
    else:
        if w:
            f0 = w**2 * (ops.fc1 + ops.fu1) + (w * external * ops.fd1 if external else 0.0)
        if gravity:
            gy, gz = -gravity * math.sin(phi), -gravity * math.cos(phi)
            if w:
                # g_y = -g sin(wt + phi) = gy cos(wt) - g cos(phi) sin(wt), g_z likewise
                fc = gy * ops.Fy + gz * ops.Fz
                fs = -gravity * math.cos(phi) * ops.Fy + gravity * math.sin(phi) * ops.Fz
            else:
                f0 = gy * ops.Fy + gz * ops.Fz
    return LinearSystem(ops.M, C, sp.csr_matrix(Q), f0, fc, fs, w)


def scene_system(scene: Scene, ops: RotorOperators, speed_hz: float | None = None) -> LinearSystem:
    """The system of a scene's ``[rotation]`` and ``[damping]`` (speed overridable)."""
    return rotor_system(ops, scene.rotation, scene.damping, speed_hz)


def rotor_system(ops: RotorOperators, rotation: Rotation, damping: Damping,
                 speed_hz: float | None = None) -> LinearSystem:
    """The system of ``[rotation]`` and ``[damping]`` on ``ops`` (the speed overridable)."""
    return linear_system(ops, rotation.speed_hz if speed_hz is None else speed_hz, rotation.gravity,
                         rotation.phase_deg, damping.rayleigh, damping.external, rotation.frame)


@dataclass(frozen=True)
class SpeedSchedule:
    """A run-up or coast-down (docs/theory.md, "Run-up and coast-down"): the parts of the equations that follow
    the speed profile Omega(t) on top of a system's constant-speed values at Omega_0 = Omega(0):

        C(t) = C + (Omega - Omega_0) C1
        Q(t) = Q + (Omega - Omega_0) Q1 + (Omega^2 - Omega_0^2) Q2 + Omega' Kst
        f(t) = f_s + Omega f1 + Omega^2 f2 + Omega' fa + cos psi gc + sin psi gs
               + Omega^2 (cos psi u + sin psi w) - Omega' (-sin psi u + cos psi w),   psi = theta(t) + phi

    Inertial frame: C1 = Gp1 (gyroscopic), Q1 = -(alpha M J + beta (K0 - Kb) J), Kst the spin-acceleration couple,
    u, w the unbalance per Omega^2 along its rotating direction and a quarter turn ahead (its load is -m r'' of
    its mass: centripetal, and tangential against the acceleration), f_s gravity. Rotating frame: C1 = G1
    (Coriolis), Q1 = c_e P1 + C_b J, Q2 = Kc1 (centrifugal), Kst = G1 / 2 (the Euler force -rho A Omega' x r),
    f1 = c_e fd1, f2 = fc1 + fu1, fa = fe1 - fq1 (the Euler force on the centroids' offsets and on the unbalance
    mass), gravity turning by psi (gc = -g Fz, gs = -g Fy). Absent parts are None.

    ``profile`` gives Omega(t), Omega'(t) and theta(t) (a :class:`~nsfem.scene.parts.Rotation`: ``omega_at``,
    ``acceleration_at``, ``angle_at``)."""

    profile: object
    C1: np.ndarray
    Q1: np.ndarray
    Kst: np.ndarray
    u: np.ndarray
    w: np.ndarray
    f_s: np.ndarray
    phase: float = 0.0
    #: per rigid contact, its moving surface's slip velocity per unit Omega (``ContactSet.wS`` at Omega = 1 rad/s):
    #: friction against the shaft surface follows Omega(t) (None: no friction at a moving surface)
    surface: tuple | None = None
    Q2: np.ndarray | None = None
    f1: np.ndarray | None = None
    f2: np.ndarray | None = None
    fa: np.ndarray | None = None
    gc: np.ndarray | None = None
    gs: np.ndarray | None = None
    #: rotating frame: the part of the inertial frame's spin-acceleration couple that is not axisymmetric (Lalanne's
    #: S = (Kst + Kst^T) / 2), seen from the turning frame: Omega' (cos^2 psi S0 + cos psi sin psi S1 + sin^2 psi S2)
    Kst_turn: tuple | None = None
    #: speed-dependent bearings: (omegas [rad/s], dK, dC, dCJ) with the changes of the bearings' stiffness (K_b +
    #: K_c), damping C_b and (rotating frame) C_b J from their values at Omega_0, one (n, n) slice per table speed
    #: (ascending): linear in Omega between them, so read by interpolation (None: constant bearings)
    bearing: tuple | None = None

    def bearing_at(self, t: float) -> tuple[np.ndarray, np.ndarray] | None:
        """(dQ, dC): the bearings' change of Q and C from Omega_0 at ``t`` (dQ = dK + Omega dCJ); None without."""
        if self.bearing is None:
            return None
        omegas, dK, dC, dCJ = self.bearing
        om = float(self.profile.omega_at(float(t)))
        if len(omegas) == 1:
            return dK[0] + (om * dCJ[0] if dCJ is not None else 0.0), dC[0]
        k = int(np.clip(np.searchsorted(omegas, om, side="right") - 1, 0, len(omegas) - 2))
        s = (om - omegas[k]) / (omegas[k + 1] - omegas[k])
        dQ = (1.0 - s) * dK[k] + s * dK[k + 1]
        if dCJ is not None:
            dQ = dQ + om * ((1.0 - s) * dCJ[k] + s * dCJ[k + 1])
        return dQ, (1.0 - s) * dC[k] + s * dC[k + 1]

    @property
    def omega0(self) -> float:
        return float(self.profile.omega_at(0.0))

    def speed(self, t) -> tuple:
        """(Omega, Omega', psi) at ``t`` (scalars or arrays)."""
        p = self.profile
        return p.omega_at(t), p.acceleration_at(t), p.angle_at(t) + self.phase

    def load(self, t) -> np.ndarray:
        """f(t), shape (n,) for a scalar t or (n, len(t))."""
        t = np.asarray(t, dtype=float)
        om, al, psi = self.speed(t)
        c, s = np.cos(psi), np.sin(psi)
        out = (np.multiply.outer(self.f_s, np.ones_like(t)) + np.multiply.outer(self.u, om * om * c + al * s)
               + np.multiply.outer(self.w, om * om * s - al * c))
        for vec, coef in ((self.f1, om), (self.f2, om * om), (self.fa, al), (self.gc, c), (self.gs, s)):
            if vec is not None:
                out = out + np.multiply.outer(vec, coef)
        return out

    def _changes(self, t) -> tuple[float, float, float]:
        om, al, _ = self.speed(float(t))
        om0 = self.omega0
        return float(om) - om0, float(om) ** 2 - om0 ** 2, float(al)

    def spin_couple(self, t: float) -> np.ndarray:
        """Kst at ``t`` (its turning part in the rotating frame at psi(t))."""
        if self.Kst_turn is None:
            return self.Kst
        _, _, psi = self.speed(float(t))
        c, s = math.cos(float(psi)), math.sin(float(psi))
        S0, S1, S2 = self.Kst_turn
        return self.Kst + c * c * S0 + c * s * S1 + s * s * S2

    def matrices(self, t: float, C: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(C(t), Q(t)) from the constant-speed ``C`` and ``Q`` at Omega_0."""
        d1, d2, al = self._changes(t)
        Qt = Q + d1 * self.Q1 + al * self.spin_couple(t)
        Ct = C + d1 * self.C1
        bearing = self.bearing_at(t)
        if bearing is not None:
            Qt, Ct = Qt + bearing[0], Ct + bearing[1]
        return Ct, Qt if self.Q2 is None else Qt + d2 * self.Q2

    def force(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The change of the speed-dependent forces from their values at Omega_0 at a state (q, v) (the loads not
        included: :meth:`load`)."""
        d1, d2, al = self._changes(t)
        out = -d1 * (self.C1 @ v + self.Q1 @ q) - al * (self.spin_couple(t) @ q)
        bearing = self.bearing_at(t)
        if bearing is not None:
            out = out - bearing[0] @ q - bearing[1] @ v
        return out if self.Q2 is None else out - d2 * (self.Q2 @ q)

    def powers(self, t, q: np.ndarray, v: np.ndarray) -> tuple:
        """(circulatory, drive): the power of the changes' forces on the structure's motion at times ``t``
        (states as columns, or one state): the circulatory change (Omega - Omega_0) q'^T Q1 q, booked with the
        circulatory work (a left-hand-side force), and the drive's, -q'^T (Omega' Kst + (Omega^2 - Omega_0^2) Q2) q
        (the speed held by the drive: its work on the lateral motion; the gyroscopic change does none). Tabulated
        bearings' changes from Omega_0, q'^T (dQ q + dC q') (their stiffness, cross coupling and damping read at
        Omega(t)), are booked with the circulatory work too: the record's energy keeps the bearings at Omega_0."""
        om, al, psi = self.speed(t)
        om0 = self.omega0
        d1, d2 = om - om0, om * om - om0 * om0

        def form(A):
            return np.einsum("i...,i...->...", v, A @ q)
        circ = d1 * form(self.Q1)
        drive = -al * form(self.Kst) - (d2 * form(self.Q2) if self.Q2 is not None else 0.0)
        if self.Kst_turn is not None:
            c, s = np.cos(psi), np.sin(psi)
            S0, S1, S2 = self.Kst_turn
            drive = drive - al * (c * c * form(S0) + c * s * form(S1) + s * s * form(S2))
        if self.bearing is not None:
            ts = np.asarray(t, dtype=float)
            if ts.ndim == 0:
                dQ, dC = self.bearing_at(float(ts))
                circ = circ + float(v @ (dQ @ q + dC @ v))
            else:
                extra = np.empty(ts.shape)
                for i, ti in enumerate(ts):
                    dQ, dC = self.bearing_at(float(ti))
                    extra[i] = v[:, i] @ (dQ @ q[:, i] + dC @ v[:, i])
                circ = circ + extra
        return circ, drive

    def fastest_rate(self, M: np.ndarray, C: np.ndarray, Q: np.ndarray) -> float:
        """The largest |eigenvalue| [1/s] of the free structure over the profile (at its two end speeds, where the
        gyroscopic splitting is widest) or its fastest speed: what a sampling of the motion must resolve."""
        import scipy.linalg as sla

        p = self.profile
        times = tuple(float(x) for x in getattr(p, "knots", ((0.0,),))[0])[:64]
        n = M.shape[0]
        rate = max(abs(float(p.omega_at(t))) for t in times)
        for t in times:
            Ct, Qt = self.matrices(t, C, Q)
            A = np.block([[np.zeros((n, n)), np.eye(n)], [-sla.solve(M, Qt), -sla.solve(M, Ct)]])
            lam = np.linalg.eigvals(A)
            rate = max(rate, float(np.max(np.abs(lam[np.isfinite(lam)]), initial=0.0)))
        return rate

    def contacts_at(self, t: float, contacts):
        """``contacts`` (a ContactSet) with its moving surfaces at Omega(t)."""
        from dataclasses import replace

        if self.surface is None:
            return contacts
        om = float(self.profile.omega_at(t))
        return replace(contacts, wS=tuple(om * w for w in self.surface))


def spin_acceleration(model, basis) -> sp.csr_matrix:
    """Kst: the couple per unit spin acceleration, Omega' Kst q on the left-hand side (inertial frame), in
    ``basis`` (q_full = basis q).

    A section (or disk) tilted by the slopes V' (a turn about z, the first angle) and then W' (about the
    turned y, the second) and spun by the third angle at Omega has, to second order, the kinetic energy
    I_p (Omega^2 / 2 + Omega V'_dot W') (Lalanne & Ferraris's convention, their psi = V', theta = W'). Its
    Lagrange equations give the gyroscopic couple Omega Gp1 (I_p on (V', W'), -I_p on (W', V')) and, from
    d/dt (I_p Omega W') in the V' equation, I_p Omega' W': Kst is Gp1's (V', W') block alone (one entry per
    disk, not Gp1's skew pair)."""
    from .fem.constraints import project
    from .fem.rotating import full_operators

    Gp = full_operators(model).Gp1
    rows = np.zeros(model.n_full)
    for space in model.spaces.values():
        rows[space.dofs["V"]] = 1.0
    Kst = (sp.diags(rows) @ Gp).tocsr()
    Kst.eliminate_zeros()
    return project(basis, Kst) if Kst.nnz else sp.csr_matrix((basis.shape[1], basis.shape[1]))


def spin_acceleration_turning(model, basis) -> tuple | None:
    """(S0, S1, S2) in ``basis``: Lalanne's couple Kst = Gp1 / 2 + S has a part S = (Kst + Kst^T) / 2 that is not
    axisymmetric; with q_inertial = R(psi) q_rotating, R = cos psi + sin psi J on the lateral pairs, the rotating
    frame sees R^T S R = cos^2 psi S + cos psi sin psi (S J + J^T S) + sin^2 psi J^T S J (the axisymmetric Gp1 / 2
    is in the Euler force G1 / 2). None without polar inertia."""
    from .fem.components import lateral_turn
    from .fem.constraints import dense

    I = sp.identity(model.n_full, format="csr")
    K = spin_acceleration(model, I)
    if not K.nnz:
        return None
    S = 0.5 * (K + K.T)
    J = lateral_turn(model.spaces, model.n_full)
    B = basis if not sp.issparse(basis) else basis.tocsr()

    def proj(A):
        return dense(B.T @ (A @ B))
    return proj(S), proj(S @ J + J.T @ S), proj(J.T @ S @ J)


def euler_load(model, basis) -> np.ndarray:
    """fe1 = int rho A (z_c N_V - y_c N_W) dx + m (z_c, -y_c) per disk, in ``basis``: the Euler force -rho A Omega' x r
    on the sections' centroid offsets per unit Omega' (rotating frame)."""
    from .fem import hermite
    from .fem.components import _node

    stack = model.stack
    out = np.zeros(model.n_full)
    for s in stack.segments:
        yc, zc = s.offset
        if not (yc or zc):
            continue
        space = model.spaces[s.name]
        load = hermite.assemble_weighted(space.x, np.ones_like)
        out[space.dofs["V"]] += s.rho * s.area * zc * load
        out[space.dofs["W"]] += -s.rho * s.area * yc * load
    for d in stack.disks:
        yc, zc = stack.segment(stack.carrier(d.x)).offset
        v, w = _node(stack, model.dof, d.x, ("V", "W"))
        out[v] += d.mass * zc
        out[w] += -d.mass * yc
    return np.asarray(basis.T @ out).ravel()


def speed_schedule(model, basis, ops: RotorOperators, rotation: Rotation, damping: Damping,
                   gravity_load: np.ndarray | None) -> SpeedSchedule:
    """The :class:`SpeedSchedule` of ``rotation``'s ramp on ``ops`` (expressed in ``basis``) in its frame. Refuses
    what a run-up does not carry: a speed outside a bearing's table."""
    from .fem.constraints import dense

    bearing = None
    if ops.bearing_change is not None:
        bearing = bearing_schedule(model, ops, rotation)

    alpha, beta = damping.rayleigh
    n = ops.n
    phase = math.radians(rotation.phase_deg)
    zero = np.zeros(n)
    if rotation.frame == "inertial":
        Q1 = -(alpha * dense(ops.MJ) + beta * dense(ops.KJ))
        return SpeedSchedule(rotation, dense(ops.Gp1), Q1, dense(spin_acceleration(model, basis)),
                             np.asarray(ops.fu1, dtype=float), np.asarray(ops.fq1, dtype=float),
                             zero if gravity_load is None else np.asarray(gravity_load, dtype=float), phase,
                             bearing=bearing)
    ce = damping.external
    G1 = dense(ops.G1)
    Q1 = dense(ops.CbJ) + (ce * dense(ops.P1) if ce else 0.0)
    g = rotation.gravity
    return SpeedSchedule(rotation, G1, Q1, 0.5 * G1, zero, zero, zero, phase, Q2=dense(ops.Kc1),
                         Kst_turn=spin_acceleration_turning(model, basis),
                         f1=ce * np.asarray(ops.fd1, dtype=float) if ce else None,
                         f2=np.asarray(ops.fc1 + ops.fu1, dtype=float),
                         fa=euler_load(model, basis) - np.asarray(ops.fq1, dtype=float),
                         gc=-g * np.asarray(ops.Fz, dtype=float) if g else None,
                         gs=-g * np.asarray(ops.Fy, dtype=float) if g else None, bearing=bearing)


def bearing_schedule(model, ops: RotorOperators, rotation: Rotation) -> tuple:
    """SpeedSchedule.bearing: the tabulated bearings' changes (dK_b + dK_c, dC_b, C_b J or None in the inertial
    frame) at every table speed inside the run's speed range (and its two ends), projected once to ``ops``' basis.
    A run whose speeds leave a table is refused (one line naming the bearing, the key and both ranges)."""
    from .fem.constraints import dense, project

    hz = np.asarray(rotation.knots[1], dtype=float)
    lo, hi = float(hz.min()), float(hz.max())
    table = set()
    for b in model.stack.bearings:
        if not b.table:
            continue
        speeds = b.table[0]
        if lo < speeds[0] or hi > speeds[-1]:
            raise SceneError(f"{b.label or 'bearing'}.speeds_hz", f"the run's speeds [{lo:g}, {hi:g}] Hz leave the "
                             f"bearing's table [{speeds[0]:g}, {speeds[-1]:g}] Hz (coefficients are not "
                             "extrapolated); extend the table or keep the ramp inside it")
        table.update(float(x) for x in speeds if lo < x < hi)
    speeds = sorted(table | {lo, hi})   # one speed (a table of equal speeds): that change throughout
    rotating = rotation.frame != "inertial"
    dK, dC, dCJ = [], [], []
    for f in speeds:
        a, c, d, e = (d if ops.basis is None else project(ops.basis, d) for d in ops.bearing_change(f))
        dK.append(dense(a + c))
        dC.append(dense(d))
        dCJ.append(dense(e))
    return (2.0 * math.pi * np.array(speeds), np.array(dK), np.array(dC), np.array(dCJ) if rotating else None)
