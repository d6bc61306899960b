"""The fitted model's discretization error, carried into the estimate's interval.

A fit explains the data with a discretized model: a finite mesh, a reduced basis, an integrator's
tolerance. Its minimum is shifted from the one the continuous model would give by the model's
error, and with long records the linearized noise interval is narrower than that shift (the
identification study: the delamination's ends moved by one to four half-widths). The fit
measures the shift instead of assuming it away:

* the scene is run again at the estimate, and one step from it per key, with every discretization
  setting refined (:func:`refined_overrides`: twice the elements, twice the kept modes, a tenth of
  rk's and penalty's tolerances, half moreau's step);
* one Gauss-Newton step of the refined model from the estimate, on the refined model's own
  Jacobian J_r and residuals r_r, gives the shift of the minimum, du = -J_r^+ r_r (:func:`shift`):
  where a fit with the refined settings would go. Measured on the delaminated shaft (20 elements
  and 6 modes refined to 40 and 12, noise-free data from 40 and 12): 97.4-100.4 % of the estimate's
  offset from the truth, from 5e-6 to 2e-3 m. The fitted model's Jacobian in its place got the
  sign wrong where the two models differ by a misfit of 2 %;
* if the model error falls like h^q when the settings double, the refined model keeps 2^-q of it
  and du is (1 - 2^-q) of the whole shift. Hermite elements converge with q = 4 in the
  frequencies, a doubled modal basis with q of 2 or more (the residual flexibility of mode k falls
  like k^-4); :data:`ORDER` = 2 is the slower, so the whole shift is at most du / (1 - 2^-2) =
  4/3 du (:data:`FACTOR`). The interval becomes the hull of the noise interval and the noise
  interval moved by that shift (:func:`widen`): the truth lies in it when it lies in the noise
  interval around the continuous model's minimum.

A shift larger than the noise half-width is a warning: the estimate is limited by the model, and
fitting with the refined settings would sharpen it.

>>> iv = widen(np.array([[0.4, 0.6]]), np.array([0.5]), np.array([0.15]))
>>> np.round(iv, 3).tolist()
[[0.4, 0.8]]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: the slowest convergence order assumed for the fitted model's error when its settings double
ORDER = 2
#: the whole discretization shift over the one measured by a doubling: 1 / (1 - 2^-ORDER)
FACTOR = 1.0 / (1.0 - 2.0**-ORDER)
#: rk's and penalty's tolerances in the refined run, as a fraction of the scene's
TOLERANCE = 0.1


@dataclass(frozen=True)
class Discretization:
    """The refined run at the estimate: its ``overrides``, what was ``kept`` as it was (and why),
    its relative RMS ``misfit``, the ``shift`` du of the minimum in the unit box (NaN per key
    whose Jacobian column is undetermined) and ``error`` (the refined run failed: no shift)."""

    overrides: tuple[str, ...]
    kept: tuple[str, ...]
    misfit: float
    shift: np.ndarray
    error: str = ""


def refined_overrides(scene) -> tuple[list[str], list[str]]:
    """(``--set`` overrides that refine every discretization setting of ``scene``, notes on the
    settings left as they are). Elements double unless the mesh comes from a file or would pass
    the schema's element limit; kept modes double (capped by the model in the run: a reduction that
    cannot keep them fails the refined run, reported); the integrator's own accuracy is refined
    (rk and penalty: tolerances x :data:`TOLERANCE`; moreau: half the step; exact: nothing, it is
    exact between events)."""
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
        sets += [f"simulation.rtol={sim.rtol * TOLERANCE!r}", f"simulation.atol={sim.atol * TOLERANCE!r}"]
    elif sim.method == "moreau":
        step = sim.moreau_step if sim.moreau_step > 0 else sim.output_dt / 10
        sets.append(f"simulation.moreau_step={step / 2!r}")
    return sets, kept


def shift(J: np.ndarray, r: np.ndarray, determined: np.ndarray, rtol: float = 1e-6) -> np.ndarray:
    """The Gauss-Newton step du = -J^+ r of the refined model from the estimate (its Jacobian ``J`` and
    residuals ``r`` there) in the unit box, over the ``determined`` columns (the others get NaN);
    singular values below ``rtol`` of the largest are dropped (as the rank of
    :func:`nsfem.analysis.uncertainty.linearized`).

    >>> shift(np.array([[1.0], [1.0]]), np.array([0.2, 0.2]), np.array([True])).tolist()
    [-0.2]
    """
    out = np.full(J.shape[1], np.nan)
    cols = np.flatnonzero(determined)
    if cols.size:
        du, *_ = np.linalg.lstsq(J[:, cols], -np.asarray(r), rcond=rtol)
        out[cols] = du
    return out


def widen(interval: np.ndarray, u: np.ndarray, du: np.ndarray) -> np.ndarray:
    """The hull of the noise ``interval`` (p, 2) around ``u`` and the same interval moved by
    :data:`FACTOR` x ``du`` (the whole discretization shift), clipped to the unit box; keys with an
    undetermined shift (NaN) keep their noise interval."""
    move = np.where(np.isfinite(du), FACTOR * np.nan_to_num(du), 0.0)
    low = np.minimum(interval[:, 0], interval[:, 0] + move)
    high = np.maximum(interval[:, 1], interval[:, 1] + move)
    return np.column_stack([np.clip(low, 0.0, 1.0), np.clip(high, 0.0, 1.0)])


def warning(params, du: np.ndarray, interval: np.ndarray, u: np.ndarray, overrides) -> str | None:
    """The warning when the whole discretization shift (:data:`FACTOR` x ``du``) of some key exceeds
    its noise half-width (None if none does); it names the measured shift ``du``."""
    half = np.maximum(u - interval[:, 0], interval[:, 1] - u)
    big = [i for i in range(len(params)) if math.isfinite(du[i]) and abs(FACTOR * du[i]) > half[i]]
    if not big:
        return None
    what = "; ".join(f"{params[i].key} by {du[i] * (params[i].high - params[i].low):+.3g} against a noise "
                     f"half-width of {half[i] * (params[i].high - params[i].low):.3g}" for i in big)
    return (f"the model's discretization limits the estimate: refining it ({', '.join(overrides)}) moves {what}; "
            "the interval includes the shift. Fit with finer settings for a sharper estimate")
