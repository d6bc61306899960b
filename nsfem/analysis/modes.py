"""Natural frequencies of the non-rotating structure with the contacts open or closed.

Open: every contact inactive (delaminated sub-beams free, stops away). Closed: every
normal gap held at zero (J_N^T q = 0) with frictionless sliding, imposed exactly by a
second constraint basis. The eigenproblem K phi = omega^2 M phi is solved densely for
small models and by shift-invert Lanczos above :data:`DENSE_LIMIT` dofs.

>>> from nsfem import load_scene, build_model
>>> model = build_model(load_scene(None, ["mesh.elements=20"]))
>>> f_open = natural_frequencies(model, "open", 2).frequencies_hz
>>> f_closed = natural_frequencies(model, "closed", 2).frequencies_hz
>>> bool(f_closed[0] > f_open[0])          # closing the gap stiffens the shaft
True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import NsfemError
from ..fem.assemble import FEModel
from ..fem.constraints import project

CONTACT_STATES = ("open", "closed")
#: Models up to this many dofs are solved with dense LAPACK (robust with rigid-body modes).
DENSE_LIMIT = 2500


@dataclass(frozen=True)
class Modes:
    """Frequencies [Hz] (ascending) and mass-normalized shapes in full coordinates.

    ``ndof_full`` counts the finite-element model's independent dofs, ``ndof`` the
    coordinates of the (possibly reduced) model the analysis ran on.
    """

    frequencies_hz: np.ndarray
    shapes: np.ndarray
    contact: str
    ndof_full: int
    ndof: int

    def to_json(self) -> dict:
        return {"contact": self.contact, "ndof_full": self.ndof_full, "ndof": self.ndof,
                "frequencies_hz": [float(f) for f in self.frequencies_hz]}


def contact_basis(model: FEModel, contact: str) -> sp.csr_matrix:
    """q_full = T q for the open (supports, junctions) or closed (plus J_N^T q = 0) structure."""
    if contact not in CONTACT_STATES:
        raise NsfemError(f"contact must be open or closed, got {contact!r}")
    if contact == "open" or not model.stack.contacts:
        return model.T
    from ..contact.kinematics import normal_jacobian

    J, _ = normal_jacobian(model)
    return model.constrain(J.T)


def eigenpairs(K: sp.spmatrix, M: sp.spmatrix, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Lowest ``count`` eigenpairs of K x = lam M x (K psd, M pd), mass-normalized."""
    n = K.shape[0]
    count = min(count, n)
    if n <= DENSE_LIMIT or count >= n - 1:
        lam, X = sla.eigh(K.toarray(), M.toarray(), subset_by_index=[0, count - 1])
        return lam, X
    # shift below zero so rigid-body modes keep K - sigma M non-singular; scale from the
    # Rayleigh quotient of a smooth vector keeps sigma near the low end of the spectrum
    ones = np.ones(n)
    sigma = -1e-3 * abs(ones @ (K @ ones)) / max(ones @ (M @ ones), 1e-300) - 1.0
    lam, X = spla.eigsh(K.tocsc(), k=count, M=M.tocsc(), sigma=sigma, which="LM")
    order = np.argsort(lam)
    lam, X = lam[order], X[:, order]
    X /= np.sqrt(np.einsum("ij,ij->j", X, M @ X))
    return lam, X


def natural_frequencies(model: FEModel, contact: str = "open", count: int = 10) -> Modes:
    """Lowest ``count`` natural frequencies of the non-rotating structure [Hz].

    Rigid-body modes (free-free) appear as 0 Hz; round-off below zero is clipped.
    """
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
        raise NsfemError(f"count must be a positive integer, got {count!r}")
    T = contact_basis(model, contact)
    K, M = project(T, model.K_full), project(T, model.M_full)
    lam, X = eigenpairs(K, M, int(count))
    # rigid-body eigenvalues come out at round-off relative to the largest eigenvalue,
    # which the largest diagonal ratio K_ii / M_ii bounds from below in order of magnitude
    d = K.diagonal() / M.diagonal()
    floor = 1e-10 * max(float(d.max()), 1e-300)
    lam = np.where(np.abs(lam) < floor, 0.0, lam)
    freqs = np.sqrt(np.maximum(lam, 0.0)) / (2.0 * np.pi)
    return Modes(freqs, np.asarray(T @ X), contact, model.n, model.n)
