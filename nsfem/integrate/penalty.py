"""Penalty regularization of the unilateral contacts (paper section 5.2; design section 6, ``penalty``).

Every contact k becomes a spring-dashpot acting only while it penetrates::

    lam_N,k = max(0, -(c_p g_k + d_p,k g_k'))   if g_k < 0,   else 0

(the paper's ``lam_N = -max(0, c_p g + d_p g')`` in nsfem's sign convention: g < 0 is a
penetration, lam_N >= 0 pushes the bodies apart). The dashpot never pulls: once
c_p g + d_p g' turns positive while the contact separates, the force is cut. **Friction is
neglected, as in the paper: mu (and the tangent directions) of the contact set are ignored.**
The ODE M q'' + C q' + Q q = f(t) + J_N lam_N is integrated by scipy's stiff solvers (BDF,
Radau, LSODA: the solver classes behind ``solve_ivp(method=...)``, stepped here so that an
interrupted run keeps its outputs). Between two switches the set of active contacts is fixed
and the ODE linear, so each such segment gets its own constant analytic Jacobian; switches
(entries ``close`` and exits ``release``) are located on the dense output as roots of
s_k = max(g_k, g_k + (d_p,k / c_p) g_k') (active iff s_k < 0), recorded as events, and the
solver restarts there.

Parameters. Stiffness c_p defaults to :func:`penalty_stiffness`. The implied penetration is
about lam_N / c_p under a static contact force and v sqrt(m_eff / c_p) for an impact at
speed v on a contact point of effective mass m_eff = 1 / (J_N,k^T M^-1 J_N,k). The scene's
restitution eps_k is mapped to a damping ratio zeta_k of that point on the penalty spring
(:func:`damping_ratio`), d_p,k = 2 zeta_k sqrt(c_p m_eff,k): by default inverting the exact
restitution of an isolated impact on this cut spring-dashpot, so that such an impact
rebounds with eps_k (the classical eps = exp(-zeta pi / sqrt(1 - zeta^2)) holds only without
the cut and overestimates the loss: eps = 0 there gives zeta = 1, which rebounds with
exp(-2) = 0.135). eps = 1 gives d_p = 0 (energy conserving); eps -> 0 needs zeta -> inf
(eps ~ 1 / (4 zeta^2)): zeta is capped at :data:`ZETA_MAX` (eps ~ 0.0025).

Energy: as for ``exact``, with the work integrals carried as extra ODE states (exact to the
solver tolerance); ``lost_in_impacts_J`` is the energy absorbed by the contact elements
(dashpot work and the spring energy left behind by the cut), ``final_J`` includes the
penalty spring energy 1/2 c_p g^2 of penetrating contacts.
"""

from __future__ import annotations

import math
import numbers
import time

import numpy as np

from ..errors import IntegrationError, NsfemError
from ..result import Result
from .base import EXTRA_METHODS, Integrator, Progress, close_energy, initial_state, output_times
from .guard import likely_cause
from .problem import ContactSystem

SOLVER_NAMES = ("BDF", "Radau", "LSODA")
#: the stiff solver classes by name, taken from scipy.integrate on first use (:func:`_solver_class`; scipy.integrate
#: costs 0.1 s of every command's start otherwise)
SOLVERS: dict = {}


def _solver_class(name: str):
    """scipy.integrate's solver class ``name`` (one of :data:`SOLVER_NAMES`), or what :data:`SOLVERS` holds for it."""
    if name not in SOLVERS:
        import scipy.integrate

        SOLVERS[name] = getattr(scipy.integrate, name)
    return SOLVERS[name]


#: largest damping ratio used (eps below restitution(ZETA_MAX) ~ 0.0025 is not reachable)
ZETA_MAX = 10.0
#: reference frequency [Hz] of the mass-based stiffness rule (factor 100 -> a 1 kHz contact)
F_REF_HZ = 100.0
#: switches at (nearly) the same time in a row before the run is declared stuck
MAX_STUCK = 200
_NOTE = ("penalty (paper section 5.2): friction neglected (mu ignored); restitution mapped to the "
         "damping ratio of a linear spring-dashpot with the force cut at zero")


def effective_masses(system: ContactSystem) -> np.ndarray:
    """m_eff,k = 1 / (J_N,k^T M^-1 J_N,k) of every contact point (m,); inf for a point that cannot move (a stop
    where a support holds the shaft: J_N,k = 0)."""
    JN = system.contacts.JN
    inverse = np.einsum("ik,ik->k", JN, np.linalg.solve(system.M, JN))
    with np.errstate(divide="ignore"):
        return np.where(inverse > 0.0, 1.0 / np.where(inverse > 0.0, inverse, 1.0), np.inf)


def penalty_stiffness(system: ContactSystem, factor: float = 100.0) -> float:
    """Default c_p [N/m]: ``factor`` times the largest contact-point stiffness.

    The static stiffness k_k = 1 / (J_N,k^T Q^-1 J_N,k); where it is undefined (Q singular,
    reciprocal condition < 1e-12, or a non-positive compliance, e.g. beyond a critical speed)
    the mass-based k_k = (2 pi F_REF_HZ)^2 m_eff,k, so that the default factor puts such a
    contact point at 1 kHz on its penalty spring.
    """
    cs = system.contacts
    if cs.m == 0:
        return 1.0
    m_eff = effective_masses(system)
    if not np.any(np.isfinite(m_eff)):
        return 1.0          # no contact point can move: the penalty springs never act
    # a point that cannot move (infinite mass, zero compliance) never penetrates: it sets no stiffness
    k_mass = np.where(np.isfinite(m_eff), (2 * math.pi * F_REF_HZ) ** 2 * np.where(np.isfinite(m_eff), m_eff, 0.0),
                      0.0)
    k = k_mass
    Q = system.Q
    if np.any(Q) and 1.0 / np.linalg.cond(Q) > 1e-12:
        comp = np.einsum("ik,ik->k", cs.JN, np.linalg.solve(Q, cs.JN))
        k = np.where(comp > 0, 1.0 / np.where(comp > 0, comp, 1.0), k_mass)
        k = np.where(np.isfinite(m_eff), k, 0.0)
    return float(factor * np.max(k))


def restitution(zeta: float, rule: str = "cut") -> float:
    """Restitution of an isolated impact on a linear spring-dashpot of damping ratio ``zeta``.

    ``cut``: the force max(0, c x + d x') (penetration x) ends when it reaches zero, before x
    does (Schwager & Poeschel 2007); ``linear``: the classical exp(-zeta pi / sqrt(1 - zeta^2)).
    Computed for unit mass, frequency and approach speed (the ratio is scale free).
    """
    if zeta <= 0:
        return 1.0
    if rule == "linear":
        return 0.0 if zeta >= 1 else math.exp(-zeta * math.pi / math.sqrt(1 - zeta * zeta))
    if zeta < 1:  # x = e^(-zeta t) sin(wd t) / wd; the force vanishes at wd t = theta
        wd = math.sqrt(1 - zeta * zeta)
        theta = math.pi - math.atan2(2 * zeta * wd, 1 - 2 * zeta * zeta)
        return -math.exp(-zeta * theta / wd) * (math.cos(theta) - zeta * math.sin(theta) / wd)
    if zeta == 1:
        return math.exp(-2.0)
    s = math.sqrt(zeta * zeta - 1)
    r1, r2 = -1 / (zeta + s), -zeta - s
    t = math.log((1 + 2 * zeta * r2) / (1 + 2 * zeta * r1)) / (2 * s)
    return -(r1 * math.exp(r1 * t) - r2 * math.exp(r2 * t)) / (2 * s)


def damping_ratio(eps: float, rule: str = "cut") -> float:
    """zeta with restitution(zeta, rule) = eps (the inverse of :func:`restitution`)."""
    if eps >= 1:
        return 0.0
    if rule == "linear":
        if eps <= 0:
            return 1.0
        a = -math.log(eps)
        return a / math.sqrt(math.pi ** 2 + a * a)
    if eps <= restitution(ZETA_MAX):
        return ZETA_MAX
    from scipy.optimize import brentq

    return brentq(lambda z: restitution(z) - eps, 0.0, ZETA_MAX, xtol=1e-14, rtol=1e-13)


_damping_ratio = damping_ratio  # Penalty's option of that name shadows the function


def _number(value) -> bool:
    """A finite real number (not a bool)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)


class Penalty(Integrator):
    """Spring-dashpot penalty contacts, stiff ODE solver (see the module docstring).

    Options: ``solver`` BDF (default), Radau or LSODA; ``stiffness`` c_p [N/m] (None:
    :func:`penalty_stiffness` with ``factor``, default 100); ``damping`` d_p [N s/m]
    for every contact (None: from ``damping_ratio`` if given, else from each contact's eps by
    ``restitution_rule`` "cut" (default) or "linear"); ``rtol`` (1e-6), ``atol`` (1e-10),
    ``max_step`` [s] (None: unbounded); ``progress`` as for ``exact``.
    """

    name = "penalty"

    def __init__(self, system: ContactSystem, solver: str = "BDF", stiffness: float | None = None,
                 factor: float = 100.0, damping: float | None = None, damping_ratio: float | None = None,
                 restitution_rule: str = "cut", rtol: float = 1e-6, atol: float = 1e-10,
                 max_step: float | None = None, progress: bool | None = None, **options):
        if system.rings:
            raise NsfemError(f"penalty: {system.rings[0].label} is an elastic ring, a spring-damper already, which "
                             "the penalty method (a regularization of rigid contacts) does not carry: run this "
                             f"scene with method {'exact, ' if system.schedule is None else ''}rk or moreau")
        if options:
            raise NsfemError(f"penalty: unknown option(s) {', '.join(sorted(options))} (known: solver, stiffness, "
                             "factor, damping, damping_ratio, restitution_rule, rtol, atol, max_step, "
                             "progress)")
        super().__init__(system)
        if solver not in SOLVER_NAMES:
            raise NsfemError(f"penalty: solver must be one of {', '.join(SOLVER_NAMES)}, got {solver!r}")

        def positive(value, name):
            if not (_number(value) and value > 0):
                raise NsfemError(f"penalty: {name} must be a finite positive number, got {value!r}")
            return float(value)

        def nonnegative(value, name):
            if not (_number(value) and value >= 0):
                raise NsfemError(f"penalty: {name} must be a finite number >= 0, got {value!r}")
            return float(value)

        positive(factor, "factor")
        c_p = penalty_stiffness(system, factor) if stiffness is None else positive(stiffness, "stiffness")
        if restitution_rule not in ("cut", "linear"):
            raise NsfemError(f"penalty: restitution_rule must be 'cut' or 'linear', got {restitution_rule!r}")
        if not (isinstance(rtol, numbers.Real) and 1e-13 <= rtol < 1):
            raise NsfemError(f"simulation.rtol: penalty needs a relative tolerance in [1e-13, 1) (its BDF error "
                             f"estimate is round-off below), got {rtol!r}")
        positive(atol, "atol")
        if max_step is not None:
            positive(max_step, "max_step")
        cs = system.contacts
        m_eff = effective_masses(system) if cs.m else np.zeros(0)
        if damping is not None:
            d_p = np.full(cs.m, nonnegative(damping, "damping"))
        else:
            if damping_ratio is not None:
                zeta = np.full(cs.m, nonnegative(damping_ratio, "damping_ratio"))
            else:
                zeta = np.array([_damping_ratio(e, restitution_rule) for e in cs.eps])
            # (a point that cannot move needs no dashpot: its gap rate is 0, and 0 * inf would be nan)
            d_p = np.where(np.isfinite(m_eff), 2.0 * zeta * np.sqrt(c_p * np.where(np.isfinite(m_eff), m_eff, 0.0)),
                           0.0)
        self.solver, self.rtol, self.atol = solver, float(rtol), float(atol)
        self.max_step = np.inf if max_step is None else float(max_step)
        self.c_p, self.d_p, self.progress = c_p, d_p, progress
        self._cache: dict = {}

    # --- the ODE of one set of active contacts: x = [q, v, W_ext, D_damp, W_circ, W_contact] -----------
    def _segment(self, active: tuple):
        if active in self._cache:
            return self._cache[active]
        if len(self._cache) > 256:
            self._cache.clear()
        sysm, cs = self.system, self.system.contacts
        n = sysm.n
        idx = list(active)
        J = cs.JN[:, idx]
        d = self.d_p[idx]
        Minv = np.linalg.inv(sysm.M)
        Kq = Minv @ (sysm.Q + self.c_p * J @ J.T)
        Cv = Minv @ (sysm.C + (J * d) @ J.T)
        b0 = Minv @ (sysm.f0 - self.c_p * J @ cs.jN[idx])
        bc, bs = Minv @ sysm.fc, Minv @ sysm.fs
        D = 0.5 * (sysm.C + sysm.C.T)
        P = 0.5 * (sysm.Q - sysm.Q.T)
        harmonic, w = sysm.harmonic, sysm.omega
        sched = sysm.schedule
        A = np.zeros((2 * n + 5, 2 * n + 5))
        A[:n, n:2 * n] = np.eye(n)
        A[n:2 * n, :n], A[n:2 * n, n:2 * n] = -Kq, -Cv
        if not np.all(np.isfinite(A)):
            raise NsfemError("penalty: the equations of motion overflow the floating-point range (M^-1 (Q + c_p J J^T) "
                             f"or M^-1 C is not finite){likely_cause(sysm)}")

        f0, fc, fs, jN = sysm.f0, sysm.fc, sysm.fs, cs.jN[idx]

        if sched is not None:   # a run-up: M^-1 of the speed-dependent parts (nsfem.system.SpeedSchedule)
            MC1, MQ1, MKst = Minv @ sched.C1, Minv @ sched.Q1, Minv @ sched.Kst
            Q2 = np.zeros((n, n)) if sched.Q2 is None else sched.Q2
            MQ2 = Minv @ Q2
            om0 = sched.omega0

        def fun(t, x):
            q, v = x[:n], x[n:2 * n]
            acc = b0 - Kq @ q - Cv @ v
            f, w_circ, w_drive = f0, v @ P @ q, 0.0
            if sched is not None:
                om, al, _ = sched.speed(t)
                dw, d2, al = float(om) - om0, float(om) ** 2 - om0 ** 2, float(al)
                f = sched.load(t)
                acc = acc + Minv @ (f - f0) - dw * (MC1 @ v + MQ1 @ q) - d2 * (MQ2 @ q)
                acc = acc - al * (MKst @ q if sched.Kst_turn is None else Minv @ (sched.spin_couple(t) @ q))
                bearing = sched.bearing_at(t)
                if bearing is not None:   # tabulated bearings at Omega(t) (their power is in powers' circ)
                    acc = acc - Minv @ (bearing[0] @ q + bearing[1] @ v)
                circ, w_drive = sched.powers(t, q, v)
                w_circ += float(circ)
            elif harmonic:
                co, si = math.cos(w * t), math.sin(w * t)
                acc = acc + bc * co + bs * si
                f = f0 + fc * co + fs * si
            g, gd = J.T @ q + jN, J.T @ v
            return np.concatenate([v, acc, [f @ v, v @ D @ v, w_circ, gd @ (self.c_p * g + d * gd), w_drive]])

        def jac(t, x):
            q, v = x[:n], x[n:2 * n]
            g, gd = J.T @ q + cs.jN[idx], J.T @ v
            Jx = A.copy()
            Jx[2 * n, n:2 * n] = sysm.load(t)
            Jx[2 * n + 1, n:2 * n] = 2 * D @ v
            Jx[2 * n + 2, :n], Jx[2 * n + 2, n:2 * n] = -P @ v, P @ q
            Jx[2 * n + 3, :n] = J @ (self.c_p * gd)
            Jx[2 * n + 3, n:2 * n] = J @ (self.c_p * g + 2 * d * gd)
            if sched is not None:
                om, al, _ = sched.speed(t)
                dw, d2, al = float(om) - om0, float(om) ** 2 - om0 ** 2, float(al)
                Kt = sched.spin_couple(t)
                Jx[n:2 * n, :n] -= dw * MQ1 + al * (MKst if sched.Kst_turn is None else Minv @ Kt) + d2 * MQ2
                Jx[n:2 * n, n:2 * n] -= dw * MC1
                Jx[2 * n + 2, :n] += dw * (sched.Q1.T @ v)
                Jx[2 * n + 2, n:2 * n] += dw * (sched.Q1 @ q)
                bearing = sched.bearing_at(t)
                if bearing is not None:
                    dQ, dC = bearing
                    Jx[n:2 * n, :n] -= Minv @ dQ
                    Jx[n:2 * n, n:2 * n] -= Minv @ dC
                    Jx[2 * n + 2, :n] += dQ.T @ v
                    Jx[2 * n + 2, n:2 * n] += dQ @ q + (dC + dC.T) @ v
                Kd = al * Kt + d2 * Q2
                Jx[2 * n + 4, :n], Jx[2 * n + 4, n:2 * n] = -(Kd.T @ v), -(Kd @ q)
            return Jx

        self._cache[active] = (fun, jac)
        return fun, jac

    def _switch(self, x: np.ndarray) -> np.ndarray:
        """s_k = max(g, g + (d_p / c_p) g') per contact (active iff < 0), for x (N,) or (N, t)."""
        cs, n = self.system.contacts, self.system.n
        g = cs.gaps(x[:n])
        gd = cs.JN.T @ x[n:2 * n]
        tau = self.d_p / self.c_p
        return np.maximum(g, g + (tau if g.ndim == 1 else tau[:, None]) * gd)

    def _force(self, x: np.ndarray) -> np.ndarray:
        """lam_N (m, t) at states x (N, t) by the penalty law."""
        cs, n = self.system.contacts, self.system.n
        g = cs.gaps(x[:n])
        gd = cs.JN.T @ x[n:2 * n]
        lam = -(self.c_p * g + self.d_p[:, None] * gd)
        return np.where((g < 0) & (lam > 0), lam, 0.0)

    def run(self, t_end: float, output_dt: float, q0=None, v0=None) -> Result:
        sysm, cs = self.system, self.system.contacts
        n, m = sysm.n, cs.m
        t_out = output_times(t_end, output_dt)
        q, v = initial_state(sysm, q0, v0)
        wall0 = time.perf_counter()
        X = np.zeros((2 * n + 5, len(t_out)))
        x = np.concatenate([q, v, np.zeros(5)])
        X[:, 0] = x
        filled = 1
        events: list = []
        active = np.zeros(m, dtype=bool)
        nfev = njev = 0
        max_pen = 0.0
        progress = Progress(t_end, self.progress)
        completed, failure = True, None
        t, stuck = 0.0, 0
        try:
            while t < t_end:
                fun, jac = self._segment(tuple(np.flatnonzero(active)))
                solver = _solver_class(self.solver)(fun, t, x, t_end, rtol=self.rtol, atol=self.atol,
                                                     max_step=self.max_step, jac=jac)
                s_prev = self._switch(x)
                switched = None
                while solver.status == "running":
                    try:
                        msg = solver.step()
                    except (ValueError, ZeroDivisionError, np.linalg.LinAlgError) as exc:  # inf/nan in its solves
                        raise NsfemError(f"penalty ({self.solver}) failed at t = {solver.t:.6g} s: {exc}"
                                         f"{likely_cause(sysm)}") from exc
                    if solver.status == "failed" or not np.all(np.isfinite(solver.y)):
                        raise NsfemError(f"penalty ({self.solver}) failed at t = {solver.t:.6g} s: "
                                         f"{msg or 'non-finite state'}")
                    t_a, t_b = solver.t_old, solver.t
                    sol = solver.dense_output()
                    s_new = self._switch(solver.y)
                    # a switch: an open contact whose s drops below 0, an active one whose s rises above 0
                    fire = np.flatnonzero(np.where(active, (s_prev <= 0) & (s_new > 0), (s_prev >= 0) & (s_new < 0)))
                    if fire.size:
                        roots = [self._root(sol, k, t_a, t_b, active[k]) for k in fire]
                        t_e = min(roots)
                        switched = [int(k) for k, r in zip(fire, roots) if r <= t_e + 1e-12 * max(1.0, t_e)]
                        t_b = t_e
                    upto = int(np.searchsorted(t_out, t_b, side="right"))
                    if upto > filled:
                        X[:, filled:upto] = sol(t_out[filled:upto])
                        filled = upto
                    max_pen = max(max_pen, self._penetration(sol, t_a, t_b, active))
                    if switched is not None:
                        x = sol(t_b)
                        break
                    x, s_prev = solver.y, s_new
                    progress(t_b, len(events))
                nfev, njev = nfev + solver.nfev, njev + solver.njev
                t_new = solver.t if switched is None else t_b
                if switched is None:
                    t = t_new
                    continue
                stuck = stuck + 1 if t_new - t <= 1e-12 * max(1.0, t_new) else 0
                if stuck > MAX_STUCK:
                    raise NsfemError(f"no progress at t = {t_new:.12g} s: {stuck} contact switches in a row at the "
                                     "same time; the penalty contacts chatter")
                before = [int(k) for k in np.flatnonzero(active)]
                for k in switched:
                    active[k] = not active[k]
                after = [int(k) for k in np.flatnonzero(active)]
                for k in switched:
                    events.append({"t": float(t_new), "kinds": ["close" if active[k] else "release"], "contacts": [k],
                                   "graze": False, "impact": False, "before": {"closed": before},
                                   "after": {"closed": after}})
                t = t_new
        except (KeyboardInterrupt, NsfemError) as exc:
            completed = False
            failure = exc if isinstance(exc, NsfemError) else None
        finally:
            progress.close()
        k_out = len(t_out) if completed else filled
        X = X[:, :k_out]
        q, v = X[:n], X[n:2 * n]
        gap = cs.gaps(q)
        lam = self._force(X)
        K = 0.5 * (sysm.Q + sysm.Q.T)
        E = 0.5 * (np.einsum("it,it->t", v, sysm.M @ v) + np.einsum("it,it->t", q, K @ q)
                   + self.c_p * np.sum(np.minimum(gap, 0.0) ** 2, axis=0))
        w_ext, d_damp, w_circ, w_contact, w_drive = X[2 * n:, -1]
        energy = {"initial_J": float(E[0]), "work_external_J": float(w_ext), "dissipated_damping_J": float(d_damp),
                  "work_circulatory_J": float(w_circ), "dissipated_friction_J": 0.0, "work_spin_J": float(w_drive),
                  "lost_in_impacts_J": float(w_contact - 0.5 * self.c_p * np.sum(np.minimum(gap[:, -1], 0.0) ** 2))}
        close_energy(energy, float(E[-1]), float(np.max(np.abs(E))))
        max_pen = max(max_pen, float(-gap.min(initial=0.0)))
        info = {**{kk: vv for kk, vv in sysm.info.items() if kk == "ndof_full"},
                "stiffness_N_m": self.c_p, "damping_N_s_m": self.d_p.tolist(), "solver": self.solver,
                "nfev": int(nfev), "njev": int(njev), "max_penetration_m": max_pen, "note": _NOTE}
        res = Result(self.name, t_out[:k_out], q, v, gap, lam, np.zeros((m, 2, k_out)),
                     np.where(lam > 0, 2, 0).astype(np.int8), events, [], energy, time.perf_counter() - wall0,
                     float(t_out[k_out - 1]), completed, info)
        if failure is not None:
            res.info["error"] = str(failure)
            raise IntegrationError(str(failure), res) from failure
        return res

    def _root(self, sol, k: int, t_a: float, t_b: float, was_active: bool) -> float:
        """The switch time of contact k in [t_a, t_b]: the end of a bisection bracket on the new side."""
        def s(t):
            return float(self._switch(sol(t))[k])

        def new_side(t):
            return s(t) > 0 if was_active else s(t) < 0

        a, b = t_a, t_b
        for _ in range(200):
            if b - a <= 4 * np.finfo(float).eps * max(1.0, abs(b)):
                break
            mid = 0.5 * (a + b)
            a, b = (a, mid) if new_side(mid) else (mid, b)
        return b

    def _penetration(self, sol, t_a: float, t_b: float, active: np.ndarray) -> float:
        """The largest penetration of the active contacts in [t_a, t_b] (at the ends or where g' = 0)."""
        if not active.any() or t_b <= t_a:
            return 0.0
        cs, n = self.system.contacts, self.system.n
        xa, xb = sol(t_a), sol(t_b)
        pen = float(max(-cs.gaps(xa[:n]).min(), -cs.gaps(xb[:n]).min(), 0.0))
        gda, gdb = cs.JN.T @ xa[n:2 * n], cs.JN.T @ xb[n:2 * n]
        from scipy.optimize import brentq

        for k in np.flatnonzero(active & (gda < 0) & (gdb >= 0)):
            tm = brentq(lambda t: float(cs.JN[:, k] @ sol(t)[n:2 * n]), t_a, t_b, xtol=1e-15)
            pen = max(pen, float(-cs.gaps(sol(tm)[:n])[k]))
        return pen


EXTRA_METHODS["penalty"] = Penalty
