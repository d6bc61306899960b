"""Craig-Bampton reduction with the contact dofs kept as boundary dofs.

q = [q_b; q_i] with q_b the coordinates the contact kinematics touch (normal gaps, and
tangential slips where mu > 0). The basis

    V = [ I            0     ]
        [ -K_ii^-1 K_ib  Phi_i ]

holds the static constraint modes (one sparse LU of K_ii, solved for all boundary dofs at
once) and ``modes`` fixed-interface normal modes Phi_i (K_ii phi = omega^2 M_ii phi). The
boundary dofs are coordinates of the reduced model, so gaps stay exact linear functions of
it and a static load at the contacts is reproduced exactly. Rigid motions that leave every
boundary dof at rest would make K_ii singular; one interior dof per such motion joins the
boundary (chosen by a pivoted QR), so free structures reduce too.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..analysis.modes import eigenpairs
from ..contact.kinematics import gap_jacobian, slip_jacobian
from ..errors import NsfemError
from ..fem.rigid import admissible, rigid_fields
from . import Reduction


def boundary_dofs(model) -> np.ndarray:
    """Coordinates q (of q_full = T q) that the gaps and, with friction, the slips involve."""
    J, _ = gap_jacobian(model)
    parts = [sp.csr_matrix(model.T.T @ J)]
    S = slip_jacobian(model)
    if S.shape[1]:
        parts.append(sp.csr_matrix(model.T.T @ S))
    rows = np.unique(np.concatenate([p.tocoo().row[p.tocoo().data != 0] for p in parts]))
    return rows.astype(int)


def _restrain_rigid(model, b: np.ndarray) -> np.ndarray:
    """Add interior dofs until no rigid motion leaves all boundary dofs at rest."""
    R = admissible(model.T, rigid_fields(model))
    if R.shape[1] == 0:
        return b
    b = list(b)
    while True:
        N = sla.null_space(R[b]) if b else np.eye(R.shape[1])
        if N.shape[1] == 0:
            return np.array(sorted(b), dtype=int)
        free = R @ N  # rigid motions with q_b = 0
        _, _, piv = sla.qr(free.T, pivoting=True, mode="economic")
        b.append(int(piv[0]))


class CraigBampton(Reduction):
    """Boundary = contact dofs; ``modes`` fixed-interface normal modes."""

    name = "craig-bampton"

    def basis(self):
        m = self.model
        n = m.n
        b = _restrain_rigid(m, boundary_dofs(m))
        inner = np.setdiff1d(np.arange(n), b)
        K, M = m.K.tocsr(), m.M.tocsr()
        Kii = K[inner][:, inner].tocsc()
        Kib = K[inner][:, b]
        try:
            lu = spla.splu(Kii)
        except RuntimeError as exc:
            raise NsfemError(f"interior stiffness is singular ({exc}): a part is held by no support, "
                             "junction or contact") from None
        psi = -lu.solve(Kib.toarray()) if len(b) else np.zeros((len(inner), 0))
        nm = min(self.modes, len(inner) - 1)
        if nm > 0:
            lam, phi = eigenpairs(Kii, M[inner][:, inner].tocsc(), nm)
        else:
            lam, phi = np.zeros(0), np.zeros((len(inner), 0))
        V = np.zeros((n, len(b) + nm))
        V[b, np.arange(len(b))] = 1.0
        V[np.ix_(inner, np.arange(len(b)))] = psi
        V[np.ix_(inner, len(b) + np.arange(nm))] = phi
        info = {"modes": nm, "boundary_dofs": len(b),
                "max_frequency_hz": float(np.sqrt(max(lam[-1], 0.0)) / (2 * np.pi)) if nm else 0.0}
        return V, info
