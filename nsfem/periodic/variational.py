"""The exact flow's sensitivity between events: a phase's transition matrix in (q, q').

In a configuration (:class:`~nsfem.integrate.configuration.Configuration`) the motion is
q = q_p + N y with G^T q_p + g0 = 0 and x = (y, y') obeying x' = A x + B (f(t) - Q q_p). The
constraint values g0 of a phase are its closed gaps' constants and, for sticking contacts, the
slip they hold, which is the slip of the state the phase starts from: a perturbation keeps
G^T dq, so dq_p = P_G dq0 with P_G = pinv(G^T) G^T the projector on range(G), and

    dx(s) = e^{A s} (N^T dq0, N^T dv0) - (int_0^s e^{A sigma} d sigma) B Q P_G dq0,
    dq(s) = P_G dq0 + N dy(s),   dv(s) = N dy'(s).

Both exponentials come from one matrix exponential, expm([[A, I], [0, 0]] s) (Van Loan), exact to
round-off for any A (rigid-body coordinates and repeated eigenvalues included). Perturbations
off the configuration's constraints (G^T dv0 != 0) are not motions of the phase: their velocity
part is dropped (the phase starts on its constraints; an event's saltation matrix puts it there).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla


def constraint_projector(config) -> np.ndarray:
    """P_G (n x n): dq_p = P_G dq0, the part of a displacement the configuration's constraint rows hold."""
    n = config.system.n
    if not config.G.shape[1]:
        return np.zeros((n, n))
    return config.Gpinv @ config.G.T


def phase_transition(config, s: float) -> np.ndarray:
    """d(q(t0 + s), q'(t0 + s)) / d(q(t0), q'(t0)) of a phase of ``config`` (2n x 2n): eq. above, exact."""
    n, r = config.system.n, config.r
    PG = constraint_projector(config)
    Phi = np.zeros((2 * n, 2 * n))
    Phi[:n, :n] = PG
    if not r:
        return Phi
    N = config.N
    eA, iA = exponentials(config, s)
    dx = np.zeros((2 * r, 2 * n))
    dx[:, :n] = eA[:, :r] @ N.T
    dx[:, n:] = eA[:, r:] @ N.T
    if config.G.shape[1]:
        dx[:, :n] -= iA @ (config.B @ (config.Q @ PG))
    Phi[:n] += N @ dx[:r]
    Phi[n:] = N @ dx[r:]
    return Phi


def exponentials(config, s: float) -> tuple[np.ndarray, np.ndarray]:
    """(e^{A s}, int_0^s e^{A r} dr) of a configuration: from its eigen-decomposition A = V diag(lam) V^-1 where the
    flow uses one (no rigid coordinates; cond(V) < 1e8, so the same accuracy as the flow's own closed form), else
    from expm([[A, I], [0, 0]] s)."""
    r = config.r
    if config.eig is not None and config.k == 0 and config.eig[0].size == 2 * r:
        lam, V, Vi = config.eig
        z = lam * s
        e = np.exp(z)
        small = np.abs(z) < 1e-3
        # (e^z - 1) / lam without cancellation: the series where |z| is small
        phi = np.where(small, s * (1 + z / 2 + z * z / 6 + z ** 3 / 24), (e - 1) / np.where(small, 1.0, lam))
        return ((V * e) @ Vi).real, ((V * phi) @ Vi).real
    big = np.zeros((4 * r, 4 * r))
    big[: 2 * r, : 2 * r] = config.A * s
    big[: 2 * r, 2 * r:] = np.eye(2 * r) * s
    E = sla.expm(big)
    return E[: 2 * r, : 2 * r], E[: 2 * r, 2 * r:]


def state_rate(phase, t: float) -> np.ndarray:
    """(q', q'') at time t of a phase (2n,): the flow's vector field there, explicit time dependence included."""
    xi = phase.xi(float(t))
    Pv = phase.v_map()
    return np.concatenate([Pv @ xi, Pv @ (phase.A_aug @ xi)])
