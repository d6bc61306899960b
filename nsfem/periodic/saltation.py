"""Saltation matrices: how a perturbation crosses an event of the exact flow.

An event at t_e is the root of an event row h(q, q', t) (a gap, a gap rate, a contact force, a
slip rate, the distance of a friction force to its cone's facet; :mod:`nsfem.integrate.events`),
followed by a jump x+ = g(x-) (the impact LCP 30-32; the identity at a transition) and the
vector field f+ of the configuration after it. A perturbed trajectory meets the event at
t_e + dt with dt = -grad h . dx- / h', h' the row's total time derivative along the flow
(its explicit time dependence included), so at t_e

    dx+ = S dx-,   S = Dg + (f+ - Dg f-) grad h^T / h'

(Aizerman & Gantmakher 1958; Leine & Nijmeijer 2004, ch. 7; Muller 1995). At a transition
(Dg = I) where the forces are continuous (a contact opening at lam_N = 0, a stick force reaching
its cone) f+ = f- and S = I; a slip stopping (its force jumps from the cone to the stick force)
and an impact change the vector field. A grazing event (h' = 0) has no saltation matrix
(Nordmark's square-root map): it is reported, not differentiated.

The impact's Dg is the derivative of LCP (30-32)'s solution with its outcome held: per contact
with an impulse, Newton's law g'+ = -eps g'- (eps = 0 where the impact was plastic, settled or
an accumulation closed it), and for frictional ones either sticking (slip'+ = 0, the tangential
impulse free), sliding with the impulse on the generator that opposes the slip after it, or
sliding with the impulse on a polygon facet (two generators oppose the slip alike: the slip after
it lies along the facet's normal, its component along the facet held at 0, the impulse's position
on the facet free); the impulses W Lambda then solve a linear system whose solution is linear in
(q, q'-). Contacts settled after the LCP without an impulse in it (a micro-lift, a creeping
approach: the integrator projects v onto g' = 0 of the contacts at rest) make a second stage, the
projection. The outcome is read from the velocities before and after the event, and the linearized
map is checked to reproduce the impact: where it does not (a sequence of impacts with restitution
within a set), ``exact`` is False and the matrix is that of the outcome read.
"""

from __future__ import annotations

import numpy as np

from ..integrate.events import _Basis, _event_rows
from .variational import constraint_projector

#: relative size below which a velocity after an impact counts as Newton's law or zero (the LCP's certificate
#: is relative to its largest entry; its round-off is ~1e-13 of the velocities)
OUTCOME_TOL = 1e-8


#: relative size below which a contact's velocities after an impact are read as obeying Newton's law (or zero): a
#: contact settled after the impact LCP (a micro-lift, projected onto g' = 0) moves an impacting contact's g'+ off
#: -eps g'- through their coupling (2.8e-7 relative on the retainer_drop polygons); a misread law is caught by the
#: exactness check of the linear map
READ_TOL = 1e-6


def row_coefficients(config, mode) -> np.ndarray:
    """The event rows of ``mode`` as coefficients of (q, q', lam, 1) (rows x (2n + nf + 1)), formed once per
    configuration and mode (the maps the event search's rows are made of)."""
    cache = config.__dict__.setdefault("_periodic_rows", {})
    R = cache.get(mode)
    if R is None:
        n, nf = config.system.n, config.W.shape[1]
        R = cache[mode] = _event_rows(_Basis(config, n, nf), mode).H
    return R


def row_gradient(config, mode, i: int) -> np.ndarray | None:
    """grad h of event row i with respect to (q, q') at fixed time (2n,); None for rows that are not the
    configuration's own (a round ring's wedge). Formed once per configuration, mode and row (read-only)."""
    R = row_coefficients(config, mode)
    if i >= R.shape[0]:
        return None
    cache = config.__dict__.setdefault("_periodic_gradients", {})
    grad = cache.get((mode, i))
    if grad is None:
        grad = cache[(mode, i)] = _row_gradient(config, R, i)
        grad.flags.writeable = False
    return grad


def _row_gradient(config, R: np.ndarray, i: int) -> np.ndarray:
    """:func:`row_gradient` of row i of the coefficients R."""
    n, nf, r = config.system.n, config.W.shape[1], config.r
    Rq, Rv, Rf = R[i, :n], R[i, n:2 * n], R[i, 2 * n:2 * n + nf]
    gq, gv = Rq.copy(), Rv.copy()
    if nf and np.any(Rf):
        # lam = Wpinv (Rx (N^T q, N^T q') + Rphi (f(t) - Q P_H q)): the constraint forces of the state
        # (P_H: variational.constraint_projector)
        lam_q = config.Wpinv @ (config.Rx[:, :r] @ config.N.T - config.Rphi @ (config.Q @ constraint_projector(config)))
        lam_v = config.Wpinv @ (config.Rx[:, r:] @ config.N.T)
        gq += Rf @ lam_q
        gv += Rf @ lam_v
    return np.concatenate([gq, gv])


def impact_jacobian(system, q: np.ndarray, v_minus: np.ndarray, v_plus: np.ndarray, impact: dict | None
                    ) -> tuple[np.ndarray, bool]:
    """(Dg, exact): d(q, q'+)/d(q, q'-) of the impact map with its outcome held (2n x 2n), and whether that
    linear map reproduces the impact (to OUTCOME_TOL of the velocities)."""
    n = system.n
    D = np.eye(2 * n)
    if impact is None:
        return D, True
    cs = system.contacts
    ks = sorted({int(k) for k in impact.get("contacts", [])} | {int(k) for k in impact.get("settled", [])}
                | {int(k) for k in impact.get("set_closure", [])})
    plastic = {int(k) for k in impact.get("plastic", [])} | {int(k) for k in impact.get("settled", [])}
    if impact.get("set_limit"):
        plastic |= set(ks)
    gm, gp = cs.JN.T @ v_minus, cs.JN.T @ v_plus
    vscale = float(np.abs(v_minus).max() + np.abs(v_plus).max()) + 1e-300
    # contacts the integrator settled after the impact LCP without an impulse in it (a micro-lift or a creeping
    # approach: v projected onto g' = 0 of every contact at rest, after the LCP): a second stage of the map
    lcp_impulse = dict(zip((int(k) for k in impact.get("contacts", [])), impact.get("impulse_Ns", [])))
    projected = {int(k) for k in impact.get("settled", []) if lcp_impulse.get(int(k), 0.0) == 0.0}
    cols, rows_v, rows_q, rhs_v, const, at_rest = [], [], [], [], [], []
    for k in ks:
        tol = READ_TOL * (abs(gm[k]) + abs(gp[k])) + OUTCOME_TOL * 1e-3 * vscale * float(np.abs(cs.JN[:, k]).max())
        if abs(gp[k]) <= tol:
            at_rest.append(k)
        if k in projected:
            continue
        e = 0.0 if k in plastic else float(cs.eps[k])
        if abs(gp[k] + e * gm[k]) <= tol:
            ek = e
        elif abs(gp[k]) <= tol:
            ek = 0.0
        else:
            continue   # it separates: no impulse held
        jn = cs.JN[:, k]
        rows_v.append(jn)
        rows_q.append(np.zeros(n))
        rhs_v.append(-ek * jn)
        const.append(0.0)
        d = cs.JS[k].shape[1]
        if d and cs.mu[k] > 0.0:
            s_plus = cs.slip_rate(k, q, v_plus)
            s_minus = cs.slip_rate(k, q, v_minus)
            if np.abs(s_plus).max() <= OUTCOME_TOL * (np.abs(s_minus).max() + abs(gm[k]) + 1e-300):
                cols.append(jn)   # sticking: the tangential impulse is free, the slip after it held at 0
                for j in range(d):
                    cols.append(cs.JS[k][:, j])
                    rows_v.append(cs.JS[k][:, j])
                    rows_q.append(cs.JSq[k][:, j] if cs.moving[k] else np.zeros(n))
                    rhs_v.append(np.zeros(n))
                    const.append(float(cs.wS[k][j]) if cs.moving[k] else 0.0)
                continue
            B = cs.generators(k)
            proj = B.T @ s_plus
            i = int(np.argmin(proj))   # the generator most opposing the slip after the impulse
            r = B.shape[1]
            j = min(((i + 1) % r, (i - 1) % r), key=lambda j_: proj[j_]) if d == 2 and r >= 3 else i
            if j != i and proj[j] - proj[i] <= OUTCOME_TOL * np.abs(s_plus).max():
                # two generators oppose the slip alike: the impulse on their facet, the slip after it along the
                # facet's normal (its component along the facet held at 0, the impulse's position on it free)
                n_f, t_f, c, _ = cs.facet(k, i if j == (i + 1) % r else j)
                cols.append(jn + cs.mu[k] * c * (cs.JS[k] @ n_f))
                cols.append(cs.JS[k] @ t_f)
                rows_v.append(cs.JS[k] @ t_f)
                rows_q.append(np.zeros(n))
                rhs_v.append(np.zeros(n))
                const.append(0.0)
                continue
            cols.append(jn + cs.mu[k] * (cs.JS[k] @ B[:, i]))
        else:
            cols.append(jn)
    predicted = v_minus.copy()
    if cols:
        W = np.column_stack(cols)
        Gv, Gq, Rm = np.array(rows_v), np.array(rows_q), np.array(rhs_v)
        Y = np.linalg.solve(system.M, W)
        A = Gv @ Y
        try:   # (one factorization for the three right-hand sides)
            lam = np.linalg.solve(A, np.hstack([Rm - Gv, -Gq, (Rm @ v_minus - Gv @ v_minus - Gq @ q
                                                                - np.array(const))[:, None]]))
        except np.linalg.LinAlgError:
            return D, False
        lam_v, lam_q, lam0 = lam[:, :n], lam[:, n:2 * n], lam[:, 2 * n]
        D[n:, :n] = Y @ lam_q
        D[n:, n:] += Y @ lam_v
        predicted += Y @ lam0
    if projected:   # then the projection onto g' = 0 of the contacts at rest, in the kinetic metric
        J = cs.JN[:, at_rest]
        Y = np.linalg.solve(system.M, J)
        P = np.eye(n) - Y @ np.linalg.lstsq(J.T @ Y, J.T, rcond=1e-12)[0]
        D[n:] = P @ D[n:]
        predicted = P @ predicted
    exact = bool(np.abs(predicted - v_plus).max() <= 1e3 * OUTCOME_TOL * vscale)
    return D, exact


def saltation(Dg: np.ndarray, f_minus: np.ndarray, f_plus: np.ndarray, grad: np.ndarray, rate: float) -> np.ndarray:
    """S = Dg + (f+ - Dg f-) grad^T / h' (module docstring)."""
    return Dg + np.outer(f_plus - Dg @ f_minus, grad) / rate
