"""Moreau-Jean time stepping (method ``moreau``): a fixed step, one velocity-level LCP per step.

Moreau's sweeping process discretized as in Jean's NSCD scheme (M. Jean, "The non-smooth
contact dynamics method", CMAME 177 (1999); J.J. Moreau, "Unilateral contact and dry friction
in finite freedom dynamics", CISM 302 (1988); Acary & Brogliato, "Numerical methods for
nonsmooth dynamical systems" (2008), ch. 10). Over a step [t_k, t_k + h], with
x_theta = (1 - theta) x_k + theta x_k+1 and the contact impulses p = J_N Lam_N + J_T beta:

    M (v_k+1 - v_k) + h C v_theta + h Q q_theta = h f_theta + p,   q_k+1 = q_k + h v_theta.

Eliminating q_theta = q_k + h theta v_theta gives, with the iteration matrix
W = M + h theta C + h^2 theta^2 Q (factorized once),

    v_k+1 = v_free + W^-1 p,   v_free = v_k + h W^-1 (f_theta - C v_k - Q (q_k + h theta v_k)).

The impulses solve the LCP of the impact law, paper eqs. (30-32), with W in place of M and
v_free as the unconstrained velocity (:func:`~nsfem.lcp.builders.contact_lcp`): Newton's law
0 <= g'_k+1 + eps min(g'_k, 0) _|_ Lam_N >= 0 (as in ``impact_lcp``: a contact separating at
the step start must merely not approach) and the polygonal friction cone on the slip
velocity J_T^T v_k+1. Only the contacts of Jean's active set enter, those whose gap predicted
at mid-step g_k + (h/2) g'_k is <= 0. The scheme is first-order accurate in time through
impacts (and with friction); between them theta = 1/2 (the default) is the second-order,
non-dissipative trapezoidal rule, theta > 1/2 damps high frequencies (algorithmically).

Result: outputs at the output times are the step states there. The step is ``step`` (default
output_dt / 10), shortened to output_dt / ceil(output_dt / step) so that every output time is a
step time (``info['step_s']`` is the step used; a last output interval shorter than output_dt
gets its own equal substeps). ``normal_force`` and ``tangential_force`` are the impulses of the
step ending at the output time divided by h (mean forces; at t = 0 those of the first step);
``state`` 0 open (inactive, or active without impulse), 1 stick, 2 slide (the LCP's slip speed
z > 0, or a frictionless contact under load). ``events`` is empty (no events are located).
``impacts`` lists the steps where a contact with an impulse approached faster than the smooth
forces change its gap velocity within the step (|J_N^T (v_free - v_k)|), with t the step's end
and the kinetic energies at its start and end. Gaps are not projected: ``info['max_penetration_m']`` is the
deepest penetration, O(h) times the approach speeds.

Energy: E = 1/2 v^T M v + 1/2 q^T K q (K, D, P the symmetric parts of Q and C and the skew part
of Q). Multiplying the step equation by v_theta gives exactly

    E_k+1 - E_k + (theta - 1/2) (dv^T M dv + dq^T K dq) = h f_theta.v_theta - h v_theta^T D v_theta
                                                          - h v_theta^T P q_theta + p.v_theta.

The terms are summed per step: work_external_J (h f_theta.v_theta), dissipated_damping_J
(h v_theta^T D v_theta), work_circulatory_J (h v_theta^T P q_theta), and the contact work with the
mean step velocity v_mid = (v_k + v_k+1) / 2 (the kinetic energy an impulse removes):
lost_in_impacts_J = -sum Lam_N.(J_N^T v_mid), dissipated_friction_J = -sum beta.(J_T^T v_mid + a moving
surface's part of the slip velocity, at q), work_spin_J = -sum beta.(that part).
The residual is then exactly minus the algorithmic dissipation
(theta - 1/2) (dv^T M dv + dq^T K dq - p.dv), reported as ``info['numerical_dissipation_J']``:
round-off for theta = 1/2 (the discrete balance is exact), first order in h otherwise. Only the
impulsive part of dv cancels against p.dv: at an impact step under loads the remaining cross
term (of order h times the velocity jump) has either sign, so with theta > 1/2 the energy can
rise by O(h) at an impact even for eps <= 1 (a ball under gravity, eps = 1, theta = 1,
h = 3.3e-4 s: +1.5e-3 relative per impact); theta = 1/2 has no such term. For eps = 1 an
impulse on an approaching contact does no work (J_N^T v_mid = 0); one that stops a contact
separating at the step start (g'_k > 0, g'_k+1 = 0) does the work Lam_N g'_k / 2 > 0.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..contact.ring import ROT, potential, unheld
from ..errors import IntegrationError, NsfemError
from ..lcp.builders import contact_lcp
from ..linalg import Factorization, factorize
from ..result import Result
from .base import EXTRA_METHODS, Integrator, Progress, close_energy, initial_state, output_times
from .problem import ContactSystem

#: slip speed z (relative to the step's velocity scale) above which a contact slides
SLIP_TOL = 1e-9


#: steps per run above which a run is refused before it starts
MAX_STEPS = 1e9


class MoreauJean(Integrator):
    """Moreau-Jean theta-method with one velocity-level contact LCP per step.

    Options: ``step`` (s, default output_dt / 10), ``theta`` in [0.5, 1] (default 0.5),
    ``progress`` (progress bar on a terminal; None = if stderr is one).
    """

    name = "moreau"

    def __init__(self, system: ContactSystem, step: float | None = None, theta: float = 0.5,
                 progress: bool | None = None, **options):
        if options:
            raise NsfemError(f"moreau: unknown option(s) {', '.join(sorted(options))} "
                             "(available: step, theta, progress)")
        super().__init__(system)
        if step is not None:
            if isinstance(step, (bool, str)):
                raise NsfemError(f"moreau: step must be a positive number of seconds, got {step!r}")
            try:
                step = float(step)
            except (TypeError, ValueError):
                raise NsfemError(f"moreau: step must be a positive number of seconds, got {step!r}") from None
            if not (math.isfinite(step) and step > 0):
                raise NsfemError(f"moreau: step must be a positive number of seconds, got {step}")
        if isinstance(theta, (bool, str)):
            raise NsfemError(f"moreau: theta must be a number in [0.5, 1], got {theta!r}")
        try:
            theta = float(theta)
        except (TypeError, ValueError):
            raise NsfemError(f"moreau: theta must be a number in [0.5, 1], got {theta!r}") from None
        if not 0.5 <= theta <= 1.0:
            raise NsfemError(f"moreau: theta must lie in [0.5, 1], got {theta}")
        self.step, self.theta, self.progress = step, theta, progress
        self._W: dict[float, tuple] = {}

    def iteration_matrix(self, h: float, rings: tuple = (), speed: tuple | None = None
                         ) -> tuple[Factorization, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """W = M + h theta C + h^2 theta^2 Q factorized, and the free-velocity maps of step h
        (cached per step size and engaged rings): v_free = A_v v + A_q q + G (f_theta + f_r) with G = h W^-1,
        A_v = I - G (C + h theta Q), A_q = -G Q. ``rings``: engaged elastic rings (ring, region, s), whose
        force law on that region adds to C, Q and f_r (implicit like the structure's). ``speed``: a run-up's
        (t, C(t), Q(t)) to take instead of the constant-speed C and Q (cached for the latest t only)."""
        key = (h, rings) if speed is None else (h, rings, speed[0])
        if speed is not None and key not in self._W:
            for old in [k for k in self._W if len(k) == 3 and k[2] != speed[0]]:
                del self._W[old]
        if key not in self._W:
            s, th = self.system, self.theta
            (C, Q), fr = ((s.C, s.Q) if speed is None else speed[1:]), np.zeros(s.n)
            for i, region, sgn in rings:
                Kr, Cr, f = s.rings[i].terms(region, sgn)
                C, Q, fr = C + Cr, Q + Kr, fr + f
            Wf = factorize(s.M + h * th * C + (h * th) ** 2 * Q, "the Moreau iteration matrix W",
                           "M + h theta C + h^2 theta^2 Q; a smaller step makes it closer to M")
            G = h * Wf.solve(np.eye(s.n))
            self._W[key] = (Wf, np.eye(s.n) - G @ (C + h * th * Q), -G @ Q, G, fr)
        return self._W[key]

    def run(self, t_end: float, output_dt: float, q0=None, v0=None) -> Result:
        sysm, th = self.system, self.theta
        cs = sysm.contacts
        n, m = sysm.n, cs.m
        self._contacts_now = None
        t_out = output_times(t_end, output_dt)
        q, v = initial_state(sysm, q0, v0)
        h_req = output_dt / 10 if self.step is None else self.step
        if h_req > output_dt * (1 + 1e-12):
            raise NsfemError(f"moreau: step ({h_req:g} s) must not exceed simulation.output_dt ({output_dt:g} s)")
        per_output = max(1, math.ceil(output_dt / h_req - 1e-9))
        if (len(t_out) - 1) * per_output > MAX_STEPS:
            raise NsfemError(f"moreau: {(len(t_out) - 1) * per_output:.3g} steps of {h_req:g} s exceed the limit of "
                             f"{MAX_STEPS:.0e}; take a larger simulation.moreau_step")
        wall0 = time.perf_counter()
        K = 0.5 * (sysm.Q + sysm.Q.T)
        P = 0.5 * (sysm.Q - sysm.Q.T)
        D = 0.5 * (sysm.C + sysm.C.T)
        n_out = len(t_out)
        out = {"q": np.zeros((n, n_out)), "v": np.zeros((n, n_out)), "gap": np.zeros((m, n_out)),
               "normal_force": np.zeros((m, n_out)), "tangential_force": np.zeros((m, 2, n_out)),
               "state": np.zeros((m, n_out), dtype=np.int8)}
        out["q"][:, 0], out["v"][:, 0], out["gap"][:, 0] = q, v, cs.gaps(q)
        filled = 1
        impacts: list = []
        rings = sysm.rings
        energy = {"initial_J": 0.5 * float(v @ sysm.M @ v + q @ K @ q) + potential(rings, q), "work_external_J": 0.0,
                  "dissipated_damping_J": 0.0, "work_circulatory_J": 0.0, "dissipated_friction_J": 0.0,
                  "work_spin_J": 0.0, "lost_in_impacts_J": 0.0}
        e_max = abs(energy["initial_J"])
        numerical, pivots, steps, penetration = 0.0, 0, 0, 0.0
        saved = (q, v, dict(energy), numerical, steps, 0)  # the state at the last output
        frictional = set(int(k) for k in cs.frictional)
        progress = Progress(t_end, self.progress)
        completed, failure = True, None
        h_full = output_dt / per_output
        harmonic, damped, circulatory = sysm.harmonic, bool(np.any(D)), bool(np.any(P))
        sched = sysm.schedule
        harmonic = harmonic or sched is not None
        try:
            for i in range(1, n_out):
                t0, span = float(t_out[i - 1]), float(t_out[i] - t_out[i - 1])
                if abs(span - output_dt) <= 1e-9 * output_dt:
                    k_sub, h = per_output, h_full
                else:  # a last interval shorter than output_dt: equal substeps of at most the step
                    k_sub = max(1, math.ceil(span / h_req - 1e-9))
                    h = span / k_sub
                f_next = sysm.load(t0) if harmonic else sysm.f0
                speed = None
                if sched is not None:   # a run-up: C and Q at the interval's middle, the rest of their change explicit
                    t_mid = t0 + 0.5 * span
                    speed = (t_mid, *sched.matrices(t_mid, sysm.C, sysm.Q))
                for j in range(k_sub):
                    t = t0 + j * h
                    f_prev = f_next
                    f_next = sysm.load(t0 + (j + 1) * h) if harmonic else sysm.f0
                    f_th = (1 - th) * f_prev + th * f_next
                    engaged, latent = ring_states(rings, q, v, t) if rings else ((), ())
                    Wf, Av, Aq, G, f_r = self.iteration_matrix(h, engaged, speed)
                    f_step = f_th
                    if sched is not None:
                        t_th = t + th * h
                        f_step = f_th + sched.force(t_th, q, v) - sched.force(t_mid, q, v)
                    v_free = Av @ v + Aq @ q + G @ (f_step + f_r)
                    if sched is not None and sched.surface is not None:   # friction's moving surface at Omega(t)
                        self._contacts_now = sched.contacts_at(t + h, cs)
                    v_new, impulse, forces, state, imp, n_piv = self._contact_step(Wf, q, v, v_free, h, t + h,
                                                                                   frictional)
                    pivots += n_piv
                    v_th = (1 - th) * v + th * v_new
                    q_new = q + h * v_th
                    # energy terms, theta-weighted (exact discrete balance for theta = 1/2)
                    energy["work_external_J"] += h * float(f_th @ v_th)
                    if damped:
                        energy["dissipated_damping_J"] += h * float(v_th @ D @ v_th)
                    if circulatory:
                        energy["work_circulatory_J"] += h * float(v_th @ P @ (q + th * h * v_th))
                    if sched is not None:   # Q(t) - Q(0): circulatory and the drive's (SpeedSchedule.powers)
                        circ, drive = sched.powers(t_th, q + th * h * v_th, v_th)
                        energy["work_circulatory_J"] += h * float(circ)
                        energy["work_spin_J"] += h * float(drive)
                    if rings:
                        _ring_work(rings, engaged, latent, q, q_new, v_th, h, th, energy)
                    dv = v_new - v
                    if impulse is not None:  # contact work with the mean step velocity
                        p_N, p_T, spin = impulse
                        v_mid = v + 0.5 * dv
                        energy["lost_in_impacts_J"] -= float(p_N @ v_mid)
                        # friction's work on the structure p_T . v_mid: the spin's work (through a moving
                        # surface) less the dissipation -Lambda_T . u_T'
                        energy["dissipated_friction_J"] += spin - float(p_T @ v_mid)
                        energy["work_spin_J"] += spin
                    if th != 0.5:
                        dq = q_new - q
                        p = 0.0 if impulse is None else float((impulse[0] + impulse[1]) @ dv)
                        numerical += (th - 0.5) * (float(dv @ sysm.M @ dv + dq @ K @ dq) - p)
                    if imp is not None:
                        impacts.append(imp)
                    q, v = q_new, v_new
                    steps += 1
                    e_max = max(e_max, abs(0.5 * float(v @ sysm.M @ v + q @ K @ q) + potential(rings, q)))
                    if m:
                        penetration = max(penetration, -float(cs.gaps(q).min()))
                        if steps == 1:  # t = 0 shows the forces of the first step
                            out["normal_force"][:, 0], out["tangential_force"][:, :, 0] = forces[0], forces[1]
                            out["state"][:, 0] = state
                    progress(t + h, len(impacts))
                out["q"][:, i], out["v"][:, i], out["gap"][:, i] = q, v, cs.gaps(q)
                if m:
                    out["normal_force"][:, i], out["tangential_force"][:, :, i] = forces[0], forces[1]
                    out["state"][:, i] = state
                filled = i + 1
                saved = (q, v, dict(energy), numerical, steps, len(impacts))
        except (KeyboardInterrupt, NsfemError) as exc:
            # a partial result ends at the last output: the state and work terms as they were there
            completed, failure = False, exc if isinstance(exc, NsfemError) else None
            q, v, energy, numerical, steps, n_imp = saved
            del impacts[n_imp:]
        finally:
            progress.close()
        close_energy(energy, 0.5 * float(v @ sysm.M @ v + q @ K @ q) + potential(rings, q), e_max)
        k = n_out if completed else filled
        info = {**{kk: vv for kk, vv in sysm.info.items() if kk == "ndof_full"},
                "step_s": h_full, "theta": th, "steps": steps, "lcp_pivots_total": pivots,
                "max_penetration_m": max(penetration, 0.0), "numerical_dissipation_J": numerical}
        res = Result(self.name, t_out[:k], out["q"][:, :k], out["v"][:, :k], out["gap"][:, :k],
                     out["normal_force"][:, :k], out["tangential_force"][:, :, :k], out["state"][:, :k],
                     [], impacts, energy, time.perf_counter() - wall0, float(t_out[k - 1]), completed, info)
        if failure is not None:
            res.info["error"] = str(failure)
            raise IntegrationError(str(failure), res) from failure
        return res

    def _contact_step(self, Wf: Factorization, q, v, v_free, h: float, t_new: float, frictional: set):
        """One LCP (30-32) with W over Jean's active set.

        Returns (v_k+1, (J_N Lam_N, J_T beta, the spin's work through friction at moving surfaces) or None,
        (normal force (m,), tangential force (m, 2)),
        state (m,), impact record or None, Lemke pivots).
        """
        sysm = self.system
        cs = self.__dict__.get("_contacts_now")   # a run-up's: its moving surfaces at Omega(t)
        cs = sysm.contacts if cs is None else cs
        m = cs.m
        nf, tf, state = np.zeros(m), np.zeros((m, 2)), np.zeros(m, dtype=np.int8)
        if m == 0:
            return v_free, None, (nf, tf), state, None, 0
        gv = cs.JN.T @ v
        active = np.flatnonzero(cs.gaps(q) + 0.5 * h * gv <= 0.0)
        if active.size == 0:
            return v_free, None, (nf, tf), state, None, 0
        friction = np.array([k for k in active if int(k) in frictional], dtype=int)
        g_free = cs.JN[:, active].T @ v_free
        bN = g_free + cs.eps[active] * np.minimum(gv[active], 0.0)
        bT = cs.JT(friction).T @ v_free
        if friction.size and np.any(cs.moving[friction]):   # the slip velocity of a moving surface (eq. 32)
            bT = bT + cs.surface_offsets(friction, q)
        lcp = contact_lcp(Wf, cs, active, friction, bN, bT, base=v_free)
        res = lcp.solve()
        if not res.success:
            raise NsfemError(f"moreau: contact LCP at t = {t_new:.9g} s: {res.message}")
        v_new = lcp.motion(res.x)
        lamN, beta, z = lcp.split(res.x)
        p_N = cs.JN[:, active] @ lamN
        p_T = lcp.W[:, active.size:] @ beta
        nf[active] = lamN / h
        scale = max(float(np.abs(bN).max(initial=0.0)), float(np.abs(lcp.b).max(initial=0.0)),
                    float(np.abs(gv[active]).max(initial=0.0)), 1e-300)
        slip = dict(zip((int(k) for k in friction), z))
        spin = 0.0
        for k, lam_T in zip(friction, lcp.tangential(res.x)):
            tf[k, :lam_T.size] = lam_T / h
            if cs.moving[k]:
                spin -= float(lam_T @ (cs.JSq[k].T @ q + cs.wS[k]))
        for j, k in enumerate(active):
            if lamN[j] > 0:
                state[k] = 1 if int(k) in slip and slip[int(k)] <= SLIP_TOL * scale else 2
        # an impact: an approach faster than the smooth forces change the gap velocity in the step
        smooth = np.abs(g_free - gv[active])
        hit = (lamN > 0) & (-gv[active] > smooth)
        imp = None
        if np.any(hit):
            imp = {"t": t_new, "contacts": [int(k) for k in active], "impulse_Ns": lamN.tolist(),
                   "approach_m_s": [float(-gv[k]) for k in active], "plastic": [],
                   "kinetic_before_J": 0.5 * float(v @ sysm.M @ v),
                   "kinetic_after_J": 0.5 * float(v_new @ sysm.M @ v_new)}
            if spin:
                imp["work_spin_J"] = spin
        return v_new, (p_N, p_T, spin), (nf, tf), state, imp, res.pivots


EXTRA_METHODS["moreau"] = MoreauJean


def ring_states(rings, q: np.ndarray, v: np.ndarray, t: float) -> tuple[tuple, tuple]:
    """(engaged, latent) rings at a step's start: engaged (ring, law, s) where the force law pushes, s the
    slip's sign (at a slip at rest the friction is left out for that step: the step's force cannot follow
    a stick on an elastic ring, a first-order error of the scheme), latent (ring, region) beyond the
    polygon with the force released."""
    eng, lat = [], []
    for i, ring in enumerate(rings):
        u, du = ring.P @ q, ring.P @ v
        reg = ring.region(u)
        if reg is None:
            continue
        law = ring.law(reg, u, du)
        if law is not None:
            rate = float(ring.slip_rate(law, u, du)) if ring.friction else 0.0
            eng.append((i, law, int(np.sign(rate))))
        else:
            lat.append((i, reg))
    return tuple(eng), tuple(lat)


def _ring_work(rings, engaged, latent, q, q_new, v_th, h: float, th: float, energy: dict) -> None:
    """Book a step's ring work (module :mod:`nsfem.contact.ring`): the damper's h c_s |D u'_theta|^2, the
    friction's dissipation and the spin's work at (q_theta, v_theta); the release of the stored energy its
    law does not hold (all of it when latent) to its damper. The spring's work is the change of the stored
    energy in E."""
    q_th = q + th * h * v_th
    for i, reg, sgn in engaged:
        ring = rings[i]
        S, a, nu = ring.parts(reg)
        u, du = ring.P @ q_th, ring.P @ v_th
        Ddu = ring.damper(reg) @ du
        energy["dissipated_damping_J"] += h * ring.damping * float(Ddu @ Ddu)
        if ring.friction and sgn:
            RN = ROT @ (ring.stiffness * (S @ u - a) + ring.damping * Ddu)
            ws = ring.surface_speed * (ROT @ nu) + ring.frame_spin * (ROT @ u)
            energy["dissipated_friction_J"] += h * ring.friction * sgn * float(RN @ (du + ws))
            energy["work_spin_J"] += h * ring.friction * sgn * float(RN @ ws)
    loose = [(rings[i], None) for i, _ in latent] + [(rings[i], law) for i, law, _ in engaged
                                                     if rings[i].place(law) != law]
    energy["dissipated_damping_J"] += sum(unheld(r, law, q) - unheld(r, law, q_new) for r, law in loose)
