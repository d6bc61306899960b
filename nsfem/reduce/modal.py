"""Modal truncation (the paper's reduction): the lowest mass-normalized modes, contacts open."""

from __future__ import annotations

import numpy as np

from ..analysis.modes import eigenpairs
from ..errors import NsfemError
from ..fem.rigid import rigid_modes
from . import Reduction


class ModalTruncation(Reduction):
    """V = the ``modes`` lowest eigenvectors of K0 phi = omega^2 M phi (contacts open).

    Gaps then depend on few global shapes: holding them closed over-constrains the
    retained space and stiffens the closed state (the paper's "artificial rigidity"),
    which fades as modes are added.
    """

    name = "modal"

    def basis(self):
        m = self.model
        if self.modes > m.n:
            raise NsfemError(f"reduction.modes = {self.modes} exceeds the model's {m.n} dofs")
        lam, X = eigenpairs(m.K, m.M, self.modes, rigid_modes(m, m.T))
        return np.asarray(X), {"modes": self.modes,
                               "max_frequency_hz": float(np.sqrt(max(lam[-1], 0.0)) / (2 * np.pi))}
