"""Model reduction: q = V eta with a basis V (n x r) in the constrained coordinates q.

One interface, several methods, as scipy's ``solve_ivp(method=...)``: :func:`reduce`
maps ``[reduction] method`` names to :class:`Reduction` subclasses. A new method
subclasses :class:`Reduction` and implements :meth:`Reduction.basis`, which must return

- a basis V (dense array or sparse matrix, n x r, full column rank) of the coordinates
  the reduced model keeps, and
- its metadata (a dict, reported in outputs).

Everything else is shared: the reduced operators are V^T A V (and V^T f) of the
operators of :mod:`nsfem.fem.rotating`, computed once per model, so a speed sweep never
reduces again; contact gaps are V^T T^T J_N, exact linear functions of eta.

>>> from nsfem import build_model, load_scene
>>> model = build_model(load_scene(None, ["mesh.elements=20"]))
>>> red = reduce(model, "craig-bampton", modes=8)
>>> red.ndof, red.info["boundary_dofs"]          # 9 gaps + 8 fixed-interface modes
(17, 9)
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg  # noqa: F401  (scipy's BLAS loaded, so that threadpool_limits reaches it)
import scipy.sparse as sp
from threadpoolctl import threadpool_limits

from ..errors import NsfemError
from ..fem.assemble import FEModel

if TYPE_CHECKING:
    from ..scene import ReductionOptions, Scene


@dataclass
class Reduction:
    """Base class: a reduction of ``model`` with ``modes`` kept modes (method-specific).

    Subclasses set ``name`` and implement :meth:`basis`. After construction ``V`` is the
    basis (n x r), ``ndof`` = r, ``info`` the method's metadata plus ``wall_s``.
    """

    model: FEModel
    modes: int = 16
    V: np.ndarray | sp.spmatrix = field(init=False)
    info: dict = field(init=False, default_factory=dict)
    _jacobians: tuple | None = field(init=False, default=None, repr=False)
    name = "base"

    def __post_init__(self) -> None:
        t0 = time.perf_counter()
        self.V, info = self.basis()
        self.info = {"method": self.name, **info, "wall_s": time.perf_counter() - t0}

    def basis(self) -> tuple[np.ndarray | sp.spmatrix, dict]:  # pragma: no cover - abstract
        raise NotImplementedError

    @property
    def ndof(self) -> int:
        return self.V.shape[1]

    @property
    def T(self):
        """q_full = T V eta: the map from reduced to full finite-element coordinates."""
        V = self.V
        return (self.model.T @ V).tocsr() if sp.issparse(V) else np.asarray(self.model.T @ V)

    def jacobians(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Contact Jacobians in reduced coordinates, projected once: (J_N, j_N, J_S).

        Gaps are g = J_N^T eta + j_N (r x m); J_S holds the tangential slip rows of the
        contacts with friction (r x 2 m_f). Exact linear functions of eta.
        """
        if self._jacobians is None:
            from ..contact.kinematics import gap_jacobian, slip_jacobian
            from ..fem.constraints import dense

            J, j = gap_jacobian(self.model)
            T = self.T
            self._jacobians = (dense(T.T @ J), j, dense(T.T @ slip_jacobian(self.model)))
        return self._jacobians


class NoReduction(Reduction):
    """The full finite-element model (the reference)."""

    name = "none"

    def basis(self):
        return sp.identity(self.model.n, format="csr"), {}


def reduce(model: FEModel, method: str = "none", modes: int = 16) -> Reduction:
    """Reduce ``model`` with the named method (``none``, ``modal``, ``craig-bampton``)."""
    from .craig_bampton import CraigBampton
    from .modal import ModalTruncation

    methods = {"none": NoReduction, "modal": ModalTruncation, "craig-bampton": CraigBampton}
    if method not in methods:
        raise NsfemError(f"unknown reduction method {method!r} (use {' | '.join(methods)})")
    if isinstance(modes, bool) or not isinstance(modes, (int, np.integer)) or modes < 1:
        raise NsfemError(f"reduction.modes must be a positive integer, got {modes!r}")
    # one BLAS thread, as the integrators have (nsfem.integrate.blas): the shipped scene's eigenproblems take
    # 0.03 s with one, 0.26-0.33 s with two threads on two busy cores
    with threadpool_limits(limits=1, user_api="blas"):
        return methods[method](model, int(modes))


def scene_reduction(options: ReductionOptions | Scene, model: FEModel) -> Reduction:
    """The reduction ``[reduction]`` asks for: ``options``, or a scene's (``scene.reduction``)."""
    from ..scene import ReductionOptions

    if not isinstance(options, ReductionOptions):
        options = options.reduction
    return reduce(model, options.method, options.modes)
