"""A turned round ring's configuration by rotating another about the shaft axis, without an eigen-decomposition.

A round ring (:mod:`.round`) turns its polygon at events: every turn of a closed facet is a new configuration
(:class:`.configuration.Configuration`: a null-space basis, a rigid-body split, an eigen-decomposition). On an
axisymmetric rotor the rotation R(beta) of the coordinates about the shaft axis commutes with the dynamics:
R^T M R = M, R^T C R = C, R^T Q R = Q (in the reduced coordinates q, whose rotation is not orthogonal: these
say that R preserves the operators' quadratic forms), and the ring's centre u = P q turns with it,
P R = R2(beta) P. A facet turned by beta then has the constraint column R^-T of the old one, and the
configuration of the turned facet is the old one in the coordinates R y: its null-space basis is R N (made
orthonormal again by a QR factorization R N = N' Rn, Rn upper triangular, so the rigid coordinates stay first),
its eigenvalues are the old ones and its eigenvectors the old ones times blockdiag(Rn, Rn) (restricted to the
modal part w = (b, y')).

R(beta) = I + sin(beta) J + (1 - cos(beta)) J^2 with J the rotation's generator in the reduced coordinates:
J = V^+ J_full V, J_full the quarter turn (v, w) -> (-w, v) of every node's lateral displacements and slopes,
V the map from the reduced coordinates to the model's dofs. :func:`generator` builds it once per system and
checks, to the reduction's round-off, that V's span is invariant (J_full V = V J), that J^3 = -J, that M, C and
Q are invariant (J^T X + X J = 0) and that every round ring's centre turns with it (P J = R2' P); a rotor that
fails any of these (anisotropic bearings, a disk off the axis, a reduction that splits a pair of modes) gets
None, and every turn its own decomposition as before.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from .configuration import Configuration, Mode

#: relative tolerance of the invariance checks: the reduced operators V^T X V and the generator's least-squares
#: solve carry round-off of about eps cond(V) |X| (measured at most 9e-14 on retainer_drop and a round rub, cond(V)
#: 264 and 115); a broken
#: symmetry (an anisotropic bearing, a disk's eccentric mass) is of order 1e-3 to 1
TOL = 1e-10
#: the quarter turn of the ring's plane, R2(pi / 2)
QUARTER = np.array([[0.0, -1.0], [1.0, 0.0]])


def _quarter_turn(model) -> sp.csr_matrix:
    """J_full: (v, w) -> (-w, v) on every segment's lateral fields (values and slopes: the same bending basis)."""
    rows, cols, vals = [], [], []
    for space in model.spaces.values():
        v, w = np.asarray(space.dofs["V"]), np.asarray(space.dofs["W"])
        rows += [v, w]
        cols += [w, v]
        vals += [-np.ones(v.size), np.ones(w.size)]
    n = model.n_full
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))


def generator(system, rings) -> np.ndarray | None:
    """J (n x n) of the rotation about the shaft axis in the system's coordinates, or None where the model does
    not allow it (no model, a broken symmetry, a ring that does not turn with it: the module docstring)."""
    model, red = system.info.get("model"), system.info.get("reduction")
    if model is None or red is None or not getattr(model, "spaces", None):
        return None
    try:
        V = model.T @ (red.V.toarray() if sp.issparse(red.V) else np.asarray(red.V))
        V = V.toarray() if sp.issparse(V) else np.asarray(V)
        JV = _quarter_turn(model) @ V
    except (AttributeError, KeyError, ValueError):
        return None
    if V.shape[1] != system.n:
        return None
    J = np.linalg.lstsq(V, JV, rcond=None)[0]
    if np.abs(V @ J - JV).max() > TOL * np.abs(JV).max(initial=1.0):
        return None   # the reduced coordinates are not closed under the rotation
    if np.abs(J @ J @ J + J).max() > TOL * max(np.abs(J).max(), 1.0):
        return None
    for X in (system.M, system.C, system.Q):
        if np.abs(J.T @ X + X @ J).max() > TOL * max(np.abs(X).max(), 1e-300):
            return None
    for ring in rings:
        if np.abs(ring.P @ J - QUARTER @ ring.P).max() > TOL * np.abs(ring.P).max():
            return None
    return J


def rotation(J: np.ndarray, beta: float) -> tuple[np.ndarray, np.ndarray]:
    """(R(beta), R(beta)^-1 = R(-beta)) from the generator J (J^3 = -J)."""
    J2 = J @ J
    s, c = math.sin(beta), 1.0 - math.cos(beta)
    I = np.eye(J.shape[0])
    return I + s * J + c * J2, I - s * J + c * J2


def canonical(mode: Mode, ring) -> tuple[Mode, int] | None:
    """(the mode with its contacts numbered from the first closed facet of ``ring``, that facet's place in the
    ring), or None when a contact of the mode is not one of the ring's facets or the mode engages elastic rings."""
    if not mode.closed or mode.ring or mode.latent:
        return None
    place = {j: i for i, j in enumerate(ring.facets)}
    if any(j not in place for j in mode.closed):
        return None
    F, first = len(ring.facets), place[mode.closed[0]]

    def f(j):
        return (place[j] - first) % F

    return Mode(tuple(f(j) for j in mode.closed), tuple(f(j) for j in mode.stick),
                tuple((f(j), g) for j, g in mode.slide), tuple((f(j), i) for j, i in mode.edge)), first


def rotated(template: Configuration, system, mode: Mode, R: np.ndarray, Rinv: np.ndarray) -> Configuration | None:
    """The configuration of ``mode`` on ``system`` as ``template`` rotated by R (its constraints R^-T the
    template's): N' Rn = R N by QR, the eigenvectors times blockdiag(Rn, Rn) on the modal part; None when the
    template has no eigen-decomposition or the constraints are not the rotated ones (checked, to round-off)."""
    if template.eig is None or template.G.shape[1] == 0:
        return None
    N, Rn = np.linalg.qr(R @ template.N)
    L = N if template.L is template.N else np.linalg.qr(R @ template.L)[0]
    k, r = template.k, template.r
    lam, V, Vi = template.eig
    Tw = sla.block_diag(Rn[k:, k:], Rn)                        # on w = (y[k:], y'), upper triangular
    eig = (lam, Tw @ V, sla.solve_triangular(Tw, Vi.T, trans="T").T)
    cfg = Configuration(system, mode, basis=(N, L, k, eig, template.redundant))
    if cfg.G.shape != template.G.shape or \
            np.abs(cfg.G - Rinv.T @ template.G).max() > TOL * np.abs(cfg.G).max(initial=1e-300):
        return None
    return cfg
