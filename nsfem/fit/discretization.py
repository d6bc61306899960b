"""The fitted model's discretization error, carried into the estimate's interval.

A fit explains the data with a discretized model: a finite mesh, a reduced basis, an integrator's
tolerance. Its minimum is shifted from the one the continuous model would give by the model's
error, and with long records the linearized noise interval is narrower than that shift (the
identification study: the delamination's ends moved by up to three noise half-widths with the
shipped 40 elements and 16 modes, by twenty with 20 and 6). The fit
measures the shift instead of assuming it away:

* the scene is run again at the estimate, and one step from it per key, with every discretization
  setting refined (:func:`refined_overrides`: twice the elements, twice the kept modes, a tenth of
  rk's and penalty's tolerances, half moreau's step);
* one Gauss-Newton step of the refined model from the estimate, on the refined model's own
  Jacobian J_r and residuals r_r, gives the shift of the minimum, du = -J_r^+ r_r (:func:`shift`):
  where a fit with the refined settings would go, if the refined model is nearly linear between the
  two minima; :mod:`nsfem.fit.refit` checks that with one more run and, where it fails, replaces the
  step by the refined model's own minimum. Measured on the delaminated shaft (20 elements
  and 6 modes refined to 40 and 12, noise-free data from 40 and 12): 97.4-100.4 % of the
  estimate's offset from the truth, from 5e-6 to 2e-3 m. The fitted model's Jacobian in the
  refined one's place got the sign wrong where the two models differ by a misfit of 2 %. The step
  assumes that the estimate is the fitted model's minimum, and stays in the box: at a range end
  beyond which the fitted minimum lies, the refined one's usually lies too and that key's step is
  zero. Subtracting the fitted model's own step (zero at an exact minimum) fails: the spurious part
  of a Gauss-Newton step, from the forward-difference Jacobian's error, grows with the residual it
  multiplies, and the fitted model's misfit is the larger (1.8 % against the refined 0.25 % on
  data of 80 elements): that step was 8e-4 m where the optimizer had converged, against a shift of
  6e-4 m;
* if the model error falls like h^q when the settings double, the refined model keeps 2^-q of it
  and du is (1 - 2^-q) of the whole shift. Hermite elements converge with q = 4 in the
  frequencies, a doubled modal basis with q of 2 or more (the residual flexibility of mode k falls
  like k^-4), rk's tolerance a tenth: q = 3.3; :data:`ORDER` = 2 is the slowest of these, so the
  whole shift is taken as du / (1 - 2^-2) = 4/3 du. Moreau's time stepping with impacts is first
  order (:data:`MOREAU_ORDER`): 2 du. The interval becomes the hull of the noise interval and the
  noise interval moved by that shift (:func:`widen`). It is an estimate, not a bound: a model
  whose error does not fall steadily with refinement (error terms of opposite sign) can keep more
  than the doubling shows (data of 80 elements and 24 modes, fitted with 20 and 6 from rest: a
  shift of 1.5e-5 m for an offset of 3.7e-5 m).

Not refined, and listed as kept: the contact discretization (a delamination's contact points, a
stator's facets, friction cone generators), which is part of the model's geometry, and a penalty
stiffness, which is part of its physics.

A shift larger than the noise half-width is a warning: the estimate is limited by the model, and
fitting with the refined settings would sharpen it.

>>> iv = widen(np.array([[0.4, 0.6]]), np.array([0.15]), factor(2))
>>> np.round(iv, 3).tolist()
[[0.4, 0.8]]
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: the slowest convergence order assumed for the fitted model's error when its settings double
ORDER = 2
#: moreau's order: time stepping through impacts is first order in its step
MOREAU_ORDER = 1
#: the whole discretization shift over the one measured by a doubling: 1 / (1 - 2^-ORDER)
FACTOR = 1.0 / (1.0 - 2.0**-ORDER)
#: rk's and penalty's tolerances in the refined run, as a fraction of the scene's
TOLERANCE = 0.1
#: the smallest relative tolerance per integrator: solve_ivp's (100 machine epsilons) for rk, the
#: penalty integrator's own limit for penalty; a refined tolerance is raised to it
RTOL_FLOOR = {"rk": float(100 * np.finfo(float).eps), "penalty": 1e-13}
#: a tolerance tightened less than this many times measures too little of its error for ORDER: kept
MIN_TIGHTENING = 4.0


def order(method: str) -> int:
    """The convergence order assumed for a scene integrated by ``method``."""
    return MOREAU_ORDER if method == "moreau" else ORDER


def factor(q: int) -> float:
    """The whole shift over the one a doubling measures, for order ``q``: 1 / (1 - 2^-q)."""
    return 1.0 / (1.0 - 2.0**-q)


@dataclass(frozen=True)
class Discretization:
    """The refined runs at the estimate: their ``overrides``, what was ``kept`` as it was (and why),
    the relative RMS ``misfit`` at the estimate, the ``shift`` du of the minimum in the unit box (NaN
    per key whose Jacobian column is undetermined, all NaN without refined runs), the assumed
    convergence ``order`` and ``error`` (the refined runs failed, or there was nothing to refine:
    no shift). The check of :mod:`nsfem.fit.refit` adds the ``ratio`` of the actual to the predicted
    reduction of the linear step, and when the refined model was fitted itself its ``refit`` (how it
    went), the ``linear_shift`` it replaced and the keys with ``no_interval`` (their interval is the
    whole range) with the reason. ``jacobian`` and ``residuals``: the refined model's at the estimate."""

    overrides: tuple[str, ...]
    kept: tuple[str, ...]
    misfit: float
    shift: np.ndarray
    order: int = ORDER
    error: str = ""
    ratio: float = math.nan
    linear_shift: np.ndarray | None = None
    refit: dict | None = None
    no_interval: np.ndarray | None = None
    no_interval_reason: str = ""
    jacobian: np.ndarray | None = field(default=None, repr=False, compare=False)
    residuals: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def factor(self) -> float:
        """The whole shift over ``shift``: 1 / (1 - 2^-order)."""
        return factor(self.order)


def refined_overrides(scene) -> tuple[list[str], list[str]]:
    """(``--set`` overrides that refine the discretization settings of ``scene``, notes on the
    settings left as they are). Elements double unless the mesh comes from a file or would pass
    the schema's element limit; kept modes double (a reduction that cannot keep them fails the
    refined runs, which are then run again without it); the integrator's own accuracy is refined
    (rk and penalty: tolerances x :data:`TOLERANCE`, rtol no lower than the integrator's floor and
    kept when that tightens it less than :data:`MIN_TIGHTENING` times; moreau:
    half the step; exact: nothing, it is exact between events). The contact discretization and a
    penalty stiffness are noted as kept."""
    from ..scene.schema import MAX_ELEMENTS

    sets, kept = [], []
    mesh = scene.mesh_options
    if mesh.file is not None:
        kept.append("mesh: read from a file (refine it by hand)")
    elif 2 * mesh.elements > MAX_ELEMENTS:
        kept.append(f"mesh.elements: {2 * mesh.elements} would pass the limit {MAX_ELEMENTS}")
    else:
        sets.append(f"mesh.elements={2 * mesh.elements}")
    if scene.reduction.method != "none":
        sets.append(f"reduction.modes={2 * scene.reduction.modes}")
    sim = scene.simulation
    if sim.method in ("rk", "penalty"):
        rtol = max(sim.rtol * TOLERANCE, RTOL_FLOOR[sim.method])
        if rtol * MIN_TIGHTENING <= sim.rtol:
            sets.append(f"simulation.rtol={rtol!r}")
        else:
            kept.append(f"simulation.rtol: {sim.rtol:g} is within {MIN_TIGHTENING:g} times of {sim.method}'s "
                        f"smallest, {RTOL_FLOOR[sim.method]:.3g}")
        sets.append(f"simulation.atol={sim.atol * TOLERANCE!r}")
        if sim.method == "penalty":
            kept.append("the penalty stiffness: part of the model, not of its discretization")
    elif sim.method == "moreau":
        step = sim.moreau_step if sim.moreau_step > 0 else sim.output_dt / 10
        sets.append(f"simulation.moreau_step={step / 2!r}")
    if scene.get("delamination") or scene.get("stator") or scene.get("obstacle") or scene.get("contact"):
        kept.append("the contact discretization (contact points, stator facets, friction cone generators): part "
                    "of the model's geometry")
    return sets, kept


def shift(J: np.ndarray, r: np.ndarray, u: np.ndarray, determined: np.ndarray, rtol: float = 1e-6) -> np.ndarray:
    """The shift du of the minimum in the unit box: the refined model's Gauss-Newton step from the
    estimate ``u`` (its Jacobian ``J`` and residuals ``r`` there), kept in the box (u + du in [0, 1]:
    at a range end where the fitted model's minimum lies beyond it the refined one's usually does too,
    and the step along that key is zero; a step back into the range is a shift like any other), over
    the ``determined`` columns (the others NaN); singular values below ``rtol`` of the largest are
    dropped (as the rank of :func:`nsfem.analysis.uncertainty.linearized`).

    >>> J = np.array([[1.0], [1.0]])
    >>> np.round(shift(J, np.array([0.2, 0.2]), np.array([0.5]), np.array([True])), 12).tolist()
    [-0.2]
    >>> shift(J, np.array([0.2, 0.2]), np.array([0.0]), np.array([True])).tolist() == [0.0]   # held at 0
    True
    """
    from scipy.optimize import lsq_linear

    out = np.full(J.shape[1], np.nan)
    cols = np.flatnonzero(determined)
    if not cols.size:
        return out
    A, b = J[:, cols], -np.asarray(r)
    lo, hi = -u[cols], 1.0 - u[cols]
    du = np.linalg.lstsq(A, b, rcond=rtol)[0]
    if np.any(du < lo) or np.any(du > hi):
        du = np.clip(lsq_linear(A, b, bounds=(lo, hi), method="bvls").x, lo, hi)   # bvls: the exact active set
    out[cols] = du + 0.0       # a held key's -0.0 is 0
    return out


def widen(interval: np.ndarray, du: np.ndarray, whole: float = FACTOR) -> np.ndarray:
    """The hull of the noise ``interval`` (p, 2) and the same interval moved by ``whole`` x ``du`` (the
    whole discretization shift), clipped to the unit box; keys with an undetermined shift (NaN) keep
    their noise interval."""
    move = np.where(np.isfinite(du), whole * np.nan_to_num(du), 0.0)
    low = np.minimum(interval[:, 0], interval[:, 0] + move)
    high = np.maximum(interval[:, 1], interval[:, 1] + move)
    return np.column_stack([np.clip(low, 0.0, 1.0), np.clip(high, 0.0, 1.0)])


def reported(interval: np.ndarray, d: Discretization | None) -> np.ndarray:
    """The reported (p, 2) intervals in the unit box: the noise ``interval`` widened by ``d``'s shift
    (:func:`widen`; as it is without refined runs or when they failed), the whole range for the keys
    ``d`` has no interval for."""
    if d is None or d.error:
        return interval
    out = widen(interval, d.shift, d.factor)
    if d.no_interval is not None:
        out[d.no_interval] = [0.0, 1.0]
    return out


def unpromised(params, d: Discretization | None) -> str | None:
    """The warning naming the keys without an interval and why (None when there are none)."""
    if d is None or d.no_interval is None or not d.no_interval.any():
        return None
    keys = ", ".join(q.key for q, lost in zip(params, d.no_interval) if lost)
    return (f"no interval for {keys}: {d.no_interval_reason}, so the model's discretization error cannot be "
            f"bounded; the interval of {keys} is its whole range (not identified). Fit with finer settings "
            "(mesh.elements, reduction.modes) or narrower ranges")


def warning(params, d: Discretization, interval: np.ndarray, u: np.ndarray) -> str | None:
    """The warning when the whole discretization shift (``d.factor`` x ``d.shift``) of some key exceeds
    its noise half-width (None if none does)."""
    du, whole = d.shift, d.factor
    half = np.maximum(u - interval[:, 0], interval[:, 1] - u)
    big = [i for i in range(len(params)) if math.isfinite(du[i]) and abs(whole * du[i]) > half[i]]
    if not big:
        return None
    what = "; ".join(f"{params[i].key} by {du[i] * (params[i].high - params[i].low):+.3g} (the whole shift taken as "
                     f"{whole * du[i] * (params[i].high - params[i].low):+.3g}) against a noise half-width of "
                     f"{half[i] * (params[i].high - params[i].low):.3g}" for i in big)
    return (f"the model's discretization limits the estimate: refining it ({', '.join(d.overrides)}) moves {what}; "
            "the interval includes the shift. Fit with finer settings for a sharper estimate")
