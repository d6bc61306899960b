"""The exact flow's sensitivity between events: a phase's transition matrix in (q, q').

In a configuration (:class:`~nsfem.integrate.configuration.Configuration`) the motion is
q = q_p + N y with G^T q_p + g0 = 0 and x = (y, y') obeying x' = A x + B (f(t) - Q q_p). The
constraint values g0 of a phase are its closed gaps' constants (fixed: the phase starts with
those gaps at 0, a perturbation of them is dropped) and, for sticking and edge contacts, the slip
they hold, which is the slip of the state the phase starts from (a perturbation keeps it). So
dq_p = P_H dq0 with P_H = pinv(G^T) E G^T, E = diag(0 on the gap rows, 1 on the slip rows), and

    dx(s) = e^{A s} (N^T dq0, N^T dv0) - (int_0^s e^{A sigma} d sigma) B Q P_H dq0,
    dq(s) = P_H dq0 + N dy(s),   dv(s) = N dy'(s).

(Keeping a closed gap's perturbation instead would make the gap's row of Phi_T - I zero at a section
where the contact stays closed: a singular Jacobian for a Newton on all of (q, q').)

Both exponentials come from the configuration's eigen-decomposition A = V diag(lam) V^-1 where the flow
itself uses one (:func:`modal_transition`; no rigid coordinates, no critically damped pair, cond(V) < 1e8: the
error ~cond(V) eps of the largest term, the flow's own accuracy), else from one matrix exponential,
expm([[A, I], [0, 0]] s) (Van Loan), exact to round-off for any A (rigid-body coordinates and repeated or
defective eigenvalues included). The quotient (e^{lam s} - 1) / lam is its series where |lam s| < 1e-3 (there the
series' truncation |lam s|^4 / 120 and the quotient's cancellation 2 eps / |lam s| are both below 5e-13). Perturbations
off the configuration's constraints (G^T dv0 != 0) are not motions of the phase: their velocity
part is dropped (the phase starts on its constraints; an event's saltation matrix puts it there).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla


def constraint_projector(config) -> np.ndarray:
    """P_H (n x n): dq_p = P_H dq0, the part of a displacement the configuration's slip rows hold (sticking and
    edge contacts keep the slip they start with; closed gaps are held at their constants, whatever the start).
    Formed once per configuration (read-only)."""
    PH = config.__dict__.get("_periodic_PH")
    if PH is None:
        n = config.system.n
        if not config.G.shape[1]:
            PH = np.zeros((n, n))
        else:
            held = np.array([kind != "normal" for kind, _, _ in config.rows], dtype=float)
            PH = config.Gpinv @ (held[:, None] * config.G.T)
        PH.flags.writeable = False
        config._periodic_PH = PH
    return PH


def phase_transition(config, s: float) -> np.ndarray:
    """d(q(t0 + s), q'(t0 + s)) / d(q(t0), q'(t0)) of a phase of ``config`` (2n x 2n): eq. above, exact. Where
    the configuration has a usable eigen-decomposition (:func:`exponentials`) the products with it are formed once
    per configuration (:func:`modal_transition`): a phase then costs one product of its exponentials."""
    parts = modal_transition(config)
    if parts is not None:
        lam, L, R, PH = parts
        e, phi = _modal_exponentials(lam, s)
        Phi = (L * np.concatenate([e, phi])) @ R
        Phi = Phi.real.copy() if np.iscomplexobj(Phi) else Phi
        Phi[: config.system.n, : config.system.n] += PH
        return Phi
    n, r = config.system.n, config.r
    PH = constraint_projector(config)
    Phi = np.zeros((2 * n, 2 * n))
    Phi[:n, :n] = PH
    if not r:
        return Phi
    N = config.N
    eA, iA = exponentials(config, s)
    dx = np.zeros((2 * r, 2 * n))
    dx[:, :n] = eA[:, :r] @ N.T
    dx[:, n:] = eA[:, r:] @ N.T
    if config.G.shape[1]:
        dx[:, :n] -= iA @ (config.B @ (config.Q @ PH))
    Phi[:n] += N @ dx[:r]
    Phi[n:] = N @ dx[r:]
    return Phi


def _has_modal_exponentials(config) -> bool:
    """Whether :func:`exponentials` uses the configuration's eigen-decomposition (no rigid coordinates, every
    eigenvalue kept)."""
    return config.eig is not None and config.k == 0 and config.eig[0].size == 2 * config.r


def modal_transition(config):
    """(lam, L, R, P_H) with Phi(s) = Re(L diag(e^{lam s}, phi(lam, s)) R) + [[P_H, 0], [0, 0]] (phi(lam, s) =
    (e^{lam s} - 1) / lam): L = [diag(N, N) V, diag(N, N) V] (2n x 4r), R = [V^-1 diag(N^T, N^T);
    -V^-1 B Q P_H, 0] (4r x 2n), formed once per configuration from its eigen-decomposition A = V diag(lam) V^-1
    (of a conjugate pair one member, its rows of R doubled: :func:`_one_of_each_pair`);
    None where :func:`exponentials` takes Van Loan's expm (rigid coordinates, a decomposition not kept) or the
    configuration has no motion (r = 0)."""
    cache = config.__dict__
    if "_periodic_modal" in cache:
        return cache["_periodic_modal"]
    parts = None
    if config.r and _has_modal_exponentials(config):
        n, r = config.system.n, config.r
        lam, V, Vi = config.eig
        N, PH = config.N, constraint_projector(config)
        NV = np.vstack([N @ V[:r], N @ V[r:]])   # diag(N, N) V
        R = np.zeros((4 * r, 2 * n), dtype=complex)
        R[: 2 * r, :n], R[: 2 * r, n:] = Vi[:, :r] @ N.T, Vi[:, r:] @ N.T
        if config.G.shape[1]:
            R[2 * r:, :n] = -(Vi @ (config.B @ (config.Q @ PH)))
        # a conjugate pair's two terms are conjugates: Re of one of them, twice (where the decomposition holds the
        # pairs exactly: the closed form's classical modes do), half the product
        keep, twice, partner = _one_of_each_pair(lam, V, Vi)
        if partner:   # (a pair's rows: the mean of one and the other's conjugate)
            up, low = np.array(list(partner)), np.array(list(partner.values()))
            for off in (0, 2 * r):
                R[off + up] = 0.5 * (R[off + up] + np.conj(R[off + low]))
        cols = np.concatenate([keep, keep + 2 * r])
        weight = np.concatenate([twice, twice])[:, None]
        parts = (lam[keep], np.hstack([NV[:, keep], NV[:, keep]]), R[cols] * weight, PH)
    cache["_periodic_modal"] = parts
    return parts


#: a pair's left vectors count as conjugates when they differ by at most this fraction of their size (V^-1 from an
#: inverse holds them to cond(V) eps: 3e-13 on the crack)
PAIR_TOL = 1e-9


def _one_of_each_pair(lam: np.ndarray, V: np.ndarray, Vi: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
    """(indices, weights, partners): each real eigenvalue (weight 1) and the upper member of each conjugate pair
    (weight 2) whose partner's eigenvalue and right vector are its exact conjugates and whose left vector is its
    conjugate to PAIR_TOL (partners: upper -> lower index); every index, weight 1, otherwise."""
    every = (np.arange(lam.size), np.ones(lam.size), {})
    upper, real = np.flatnonzero(lam.imag > 0), np.flatnonzero(lam.imag == 0)
    match = lam[upper][:, None] == np.conj(lam)[None, :]   # (upper x all) exact conjugates
    if np.any(match.sum(axis=1) != 1):
        return every
    lower = np.argmax(match, axis=1)
    if len(set(lower.tolist())) != lower.size or 2 * upper.size + real.size != lam.size:
        return every
    if not np.array_equal(V[:, lower], np.conj(V[:, upper])) or np.any(
            np.abs(Vi[lower] - np.conj(Vi[upper])).max(axis=1, initial=0.0)
            > PAIR_TOL * np.abs(Vi[upper]).max(axis=1, initial=0.0)):
        return every
    keep = np.sort(np.concatenate([real, upper]))
    return keep, np.where(lam[keep].imag > 0, 2.0, 1.0), dict(zip(upper.tolist(), lower.tolist()))


def _modal_exponentials(lam: np.ndarray, s: float) -> tuple[np.ndarray, np.ndarray]:
    """(e^{lam s}, (e^{lam s} - 1) / lam), the second without cancellation where |lam s| is small (its series)."""
    z = lam * s
    e = np.exp(z)
    small = np.abs(z) < 1e-3
    phi = np.where(small, s * (1 + z / 2 + z * z / 6 + z ** 3 / 24), (e - 1) / np.where(small, 1.0, lam))
    return e, phi


def exponentials(config, s: float) -> tuple[np.ndarray, np.ndarray]:
    """(e^{A s}, int_0^s e^{A r} dr) of a configuration: from its eigen-decomposition A = V diag(lam) V^-1 where the
    flow uses one (no rigid coordinates; cond(V) < 1e8, so the same accuracy as the flow's own closed form), else
    from expm([[A, I], [0, 0]] s)."""
    r = config.r
    if _has_modal_exponentials(config):
        lam, V, Vi = config.eig
        e, phi = _modal_exponentials(lam, s)
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
