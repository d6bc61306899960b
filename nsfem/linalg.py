"""One factorization of a square operator (dense or sparse), with a singularity check.

>>> import numpy as np
>>> f = factorize(np.array([[2.0, 1.0], [1.0, 3.0]]), "Q")
>>> f.solve(np.array([3.0, 4.0])).round(12).tolist()
[1.0, 1.0]
>>> factorize(np.zeros((2, 2)), "Q")
Traceback (most recent call last):
...
nsfem.errors.NsfemError: Q is singular (reciprocal condition number 0.0e+00): ...
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .errors import NsfemError

#: below this reciprocal condition number an operator is treated as singular
RCOND_MIN = 1e-13


@dataclass
class Factorization:
    """``solve(B)`` returns A^-1 B for a vector or a matrix B."""

    n: int
    _solve: object
    rcond: float

    def solve(self, B: np.ndarray) -> np.ndarray:
        B = np.asarray(B, dtype=float)
        if B.ndim == 2 and B.shape[1] == 0:
            return np.zeros((self.n, 0))
        return self._solve(B)


def factorize(A, name: str = "the operator", hint: str = "") -> Factorization:
    """LU-factorize A (dense or sparse); raise NsfemError naming ``name`` if it is singular.

    The reciprocal condition number is LAPACK's 1-norm estimate for dense A and
    min|U_ii| / max|U_ii| of the sparse LU for sparse A (a cheap, conservative proxy).
    """
    hint = hint or ("rigid-body motion that no support restrains, or a speed where the "
                    "stiffness loses definiteness")
    if sp.issparse(A) and A.shape[0] > 400:
        A = sp.csc_matrix(A)
        try:
            lu = spla.splu(A)
        except RuntimeError:
            raise NsfemError(f"{name} is singular (exactly): {hint}") from None
        d = np.abs(lu.U.diagonal())
        rcond = float(d.min() / d.max()) if d.size and d.max() > 0 else 0.0
        solve = lu.solve
    else:
        Ad = A.toarray() if sp.issparse(A) else np.asarray(A, dtype=float)
        norm = np.linalg.norm(Ad, 1)
        with warnings.catch_warnings():  # singularity is judged below, by rcond
            warnings.simplefilter("ignore", sla.LinAlgWarning)
            lu, piv = sla.lu_factor(Ad, check_finite=False) if norm > 0 else (Ad, None)
        if norm == 0:
            rcond = 0.0
        else:
            rcond = float(sla.lapack.dgecon(lu, norm)[0])
        getrs = sla.lapack.dgetrs   # what lu_solve calls, without its checks (a few us per event)
        solve = lambda B: getrs(lu, piv, B)[0]  # noqa: E731
    if not rcond > RCOND_MIN:
        raise NsfemError(f"{name} is singular (reciprocal condition number {rcond:.1e}): {hint}")
    return Factorization(A.shape[0], solve, rcond)
