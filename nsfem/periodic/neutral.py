"""Orbits that form a continuum: a contact that sticks all period.

A contact that sticks over the whole period holds its slip rate at zero but not its stick position: the rotor
shifted statically along the stuck tangent, its friction force taking up the elastic forces of the shift, is an
orbit too (while that force stays inside the cone). The orbits form a continuum, the monodromy matrix maps such
a static shift w = (dq, 0) onto itself (Phi_T w = w: an exact multiplier +1) and Phi_T - I is singular along it:
Newton's step there is the quotient of two round-off errors. These directions are found at the section as the null
space of Phi_T - I among the static admissible displacements (:func:`stick_continuum`); the shooting's step is the
least-squares solution orthogonal to them (:func:`newton_step`: the phase condition "stay at this stick position"),
the continuation's J_u is made regular by deflating them (:func:`deflated`), and their multipliers +1 are reported
as neutral (a continuum of stick positions) and left out of the stability verdict (:func:`neutral_multipliers`).
"""

from __future__ import annotations

import numpy as np

#: a static admissible displacement w with |(Phi_T - I) w| <= NEUTRAL_TOL |w| (in the norm (q, q' / w)) is neutral:
#: the monodromy is exact to round-off through each event (~1e-12 of its entries on the shipped scenes: the
#: multipliers of a continuum land within 1e-13 of +1 in the tests), 1e-8 leaves four orders of margin, and a genuine
#: multiplier that close to +1 (a fold within 1e-8) is a continuum to the shooting's tolerance anyway
NEUTRAL_TOL = 1e-8
#: the note of a neutral multiplier
NEUTRAL = "neutral (a continuum of stick positions)"


def stick_continuum(monodromy: np.ndarray, Z: np.ndarray, sticking: bool, scale: np.ndarray) -> np.ndarray:
    """The neutral directions (2n x k, orthonormal in the scaled norm ``scale`` * x) among the admissible ones
    ``Z`` (2n x d) of an orbit whose mode at the section has ``sticking`` contacts: the static shifts (dq, 0) in
    span(Z) that Phi_T maps onto themselves (module docstring). None (2n x 0) without sticking contacts."""
    m = monodromy.shape[0]
    n = m // 2
    if not sticking or Z.shape[1] == 0:
        return np.zeros((m, 0))
    # the static admissible shifts: Z a with (Z a)[n:] = 0
    _, s, Vt = np.linalg.svd(Z[n:], full_matrices=True)
    rank = int(np.sum(s > 1e-10 * max(s[0], 1.0))) if s.size else 0
    static = Z @ Vt[rank:].T
    if not static.shape[1]:
        return np.zeros((m, 0))
    S = scale[:, None] * static
    Q, _ = np.linalg.qr(S)                    # orthonormal static shifts in the scaled norm
    D = scale[:, None] * ((monodromy - np.eye(m)) @ (Q / scale[:, None]))
    _, sv, Wt = np.linalg.svd(D, full_matrices=False)
    null = Wt[sv <= NEUTRAL_TOL].T            # (|Q w| = 1: sv is |(Phi_T - I) w| itself)
    return (Q @ null) / scale[:, None]


def stick_positions(system, mode) -> np.ndarray:
    """The rows (s x 2n) of the stick positions the mode's sticking contacts hold: J_S^T dq per tangent direction
    (and the position along the facet of a force held on a cone's facet)."""
    n, cs = system.n, system.contacts
    rows = [np.concatenate([cs.JS[k][:, j], np.zeros(n)]) for k in mode.stick for j in range(cs.JS[k].shape[1])]
    rows += [np.concatenate([cs.JS[k] @ cs.facet(k, i)[1], np.zeros(n)]) for k, i in mode.edge]
    return np.array(rows).reshape(len(rows), 2 * n)


def holding(W: np.ndarray, L: np.ndarray) -> np.ndarray:
    """C (k x 2n) with C W = I that reads a perturbation's part along the neutral directions W (2n x k) from the
    stick positions L (s x 2n) it changes: C = (L W)^+ L. A step with C dx = 0 keeps the stick positions."""
    LW = L @ W
    if LW.size == 0 or np.linalg.matrix_rank(LW) < W.shape[1]:
        return np.linalg.pinv(W)             # (no stick position moves along W: stay orthogonal to it instead)
    return np.linalg.pinv(LW) @ L


def newton_step(J: np.ndarray, rhs: np.ndarray, Z: np.ndarray, W: np.ndarray, L: np.ndarray) -> np.ndarray:
    """The least-squares solution dz (in the coordinates of Z, 2n x d orthonormal) of J dz = rhs that keeps the
    stick positions: the minimum-norm solution on the complement of the neutral directions W (2n x k, in span Z:
    J Z^T W = 0 up to round-off), less its part along W read by :func:`holding` (J is blind to it). Plain least
    squares without neutral directions."""
    if not W.shape[1]:
        return np.linalg.lstsq(J, rhs, rcond=None)[0]
    Wz, _ = np.linalg.qr(Z.T @ W)
    _, _, Vt = np.linalg.svd(Wz.T, full_matrices=True)
    P = Vt[Wz.shape[1]:].T                    # orthonormal complement of the neutral directions
    dz = P @ np.linalg.lstsq(J @ P, rhs, rcond=None)[0]
    return dz - Z.T @ (W @ (holding(W, L) @ (Z @ dz)))


def deflated(J: np.ndarray, W: np.ndarray, L: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """J (m x m, rows and columns of the weighted residual and unknowns weights * x; singular along W: J W = 0)
    made regular: J + sigma_1 U_k C, U_k the left singular vectors of its k smallest singular values, C
    :func:`holding` of W scaled to weighted unit length. A step J' dx = -r then has C dx = -U_k^T r / sigma_1 ~ 0
    (r in J's range): it keeps the stick positions, and off W it is J's own."""
    k = W.shape[1]
    if not k:
        return J
    Wn = W / np.linalg.norm(weights[:, None] * W, axis=0)
    U, s, _ = np.linalg.svd(J / weights[None, :])
    return J + s[0] * U[:, -k:] @ holding(Wn, L)


def neutral_multipliers(mu: np.ndarray, k: int) -> np.ndarray:
    """The indices of the ``k`` multipliers nearest +1 (those of the k neutral directions)."""
    if not k:
        return np.zeros(0, dtype=int)
    return np.argsort(np.abs(np.asarray(mu, dtype=complex) - 1.0), kind="stable")[:k]
