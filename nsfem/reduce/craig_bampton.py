"""Craig-Bampton reduction whose boundary coordinates are the contact gaps and slips.

Let C (b x n) hold the contact functionals in the coordinates q: the normal gaps
J_N^T T and, where mu > 0, the tangential slips J_S^T T (independent rows only). The
basis

    V = [Psi, T_c Phi],   Psi = K^-1 C^T (C K^-1 C^T)^-1,   C T_c = 0,

holds b static constraint modes (each sets one functional to 1, the others to 0, at least
strain energy; computed from one sparse LU of the bordered matrix [K C^T; C 0]) and N
fixed-interface normal modes Phi of K, M restricted to C q = 0. Then C V = [I 0]: the
first b reduced coordinates *are* the gaps and slips, so contact kinematics are exact,
static contact loads (f = C^T lambda) are reproduced exactly, and holding gaps closed
just removes coordinates, which leaves the closed structure's own fixed-interface modes.
With Dirac contacts C picks two dofs per point; a hat-weighted gap is one functional
however many dofs it spans, so the reduced size does not grow with the mesh. Rigid
motions that leave every functional at zero are restrained by one extra dof each
(chosen by a pivoted QR), so free structures reduce too.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..analysis.modes import eigenpairs
from ..contact.kinematics import gap_jacobian, slip_jacobian
from ..errors import NsfemError
from ..fem.constraints import constraint_basis, project
from ..fem.rigid import rigid_modes
from . import Reduction

#: Fixed-interface modes whose frequencies agree to this relative tolerance with the last
#: one kept are kept too (a cut through a repeated frequency would be arbitrary).
REPEATED = 1e-9


def contact_functionals(model) -> sp.csr_matrix:
    """Rows C (b x n) of the gaps and, with friction, the slips in coordinates q; independent."""
    J, _ = gap_jacobian(model)
    S = slip_jacobian(model)
    C = sp.vstack([sp.csr_matrix(J.T @ model.T), sp.csr_matrix(S.T @ model.T)]).tocsr()
    if C.shape[0] == 0:
        return C
    cols = np.unique(C.indices)
    dense = C[:, cols].toarray()
    _, r, piv = sla.qr(dense.T, pivoting=True, mode="economic")
    d = np.abs(np.diag(r))
    rank = int(np.sum(d > 1e-10 * d.max())) if len(d) else 0
    return C[np.sort(piv[:rank])]


def _restrain_rigid(model, C: sp.csr_matrix) -> sp.csr_matrix:
    """Add unit rows (single dofs) until no rigid motion leaves every row of C at zero."""
    R = rigid_modes(model, model.T)
    if R.shape[1] == 0:
        return C
    n = model.n
    extra: list[int] = []
    while True:
        rows = sp.vstack([C, sp.csr_matrix((np.ones(len(extra)), (np.arange(len(extra)), extra)),
                                           shape=(len(extra), n))]).tocsr() if extra else C
        N = sla.null_space(np.asarray(rows @ R)) if rows.shape[0] else np.eye(R.shape[1])
        if N.shape[1] == 0:
            return rows
        _, _, piv = sla.qr((R @ N).T, pivoting=True, mode="economic")  # dof moved most
        extra.append(int(piv[0]))


class CraigBampton(Reduction):
    """Boundary coordinates = contact gaps (and slips); ``modes`` fixed-interface normal modes."""

    name = "craig-bampton"

    def basis(self):
        m = self.model
        n = m.n
        C = _restrain_rigid(m, contact_functionals(m))
        b = C.shape[0]
        K, M = m.K.tocsc(), m.M.tocsc()
        if b:
            # constraint modes from the bordered system [K C^T; C 0] [Psi; L] = [0; I]
            A = sp.bmat([[K, C.T], [C, None]], format="csc")
            try:
                lu = spla.splu(A)
            except RuntimeError as exc:
                raise NsfemError(f"the stiffness with the contacts held is singular ({exc}): a part is held "
                                 "by no support, junction or contact") from None
            rhs = np.zeros((n + b, b))
            rhs[n:] = np.eye(b)
            psi = lu.solve(rhs)[:n]
            Tc, _ = constraint_basis(C, n)
        else:
            psi, Tc = np.zeros((n, 0)), sp.identity(n, format="csr")
        nc = Tc.shape[1]
        if self.modes > nc:
            raise NsfemError(f"reduction.modes = {self.modes} exceeds the {nc} interior coordinates")
        want = min(self.modes + 4, nc)
        lam, phi = eigenpairs(project(Tc, K), project(Tc, M), want)
        nm = self.modes
        while nm < len(lam) and abs(lam[nm] - lam[nm - 1]) <= REPEATED * abs(lam[nm - 1]):
            nm += 1  # keep a repeated frequency whole
        V = np.hstack([psi, np.asarray(Tc @ phi[:, :nm])])
        info = {"modes": nm, "boundary_dofs": b,
                "max_frequency_hz": float(np.sqrt(max(lam[nm - 1], 0.0)) / (2 * np.pi)) if nm else 0.0}
        return V, info
