"""Whether one Gauss-Newton step of the refined model can be trusted as the discretization shift, and
the refined model's own minimum when it cannot.

The shift of :mod:`nsfem.fit.discretization` is one linear step, du = -J_r^+ r_r, of the refined
model from the estimate. It is where the refined model's minimum lies only if that model is nearly
linear in the keys between the two minima. Contact dynamics are not: impacts come and go, and the
forward-difference Jacobian (a step of 1e-4 of a range) sees the local slope of a rugged misfit. On
the delamination falling from rest (the identification study's ``delam_rest_asym``), the step found
0.22 mm of an offset of 1.5 mm, and the interval built on it missed the truth by 1.2 mm. So the step
is checked, as a trust-region method checks its model:

* one more refined run at u + du gives the actual reduction of the refined residuals' sum of squares
  against the reduction the linear model predicts, |r_r|^2 - |r_r + J_r du|^2
  (:func:`reduction_ratio`); a ratio within :data:`TRUST` of 1 trusts the step;
* otherwise, or when the fitted model's residuals at the estimate are structured (the model leaves a
  smooth error: it cannot explain the data, and how far its minimum lies from the refined one is
  not a local question), the refined model is fitted itself (:func:`check`): a local least-squares
  stage of the refined model from the better of u and u + du, at most :data:`REFIT_NFEV`
  evaluations, its steps judged converged below a tenth of the smallest noise standard deviation. The
  shift is then the difference of the two minima, u_r - u, and the interval is widened by it as by
  the linear step (4/3 of it: Richardson's extrapolation at order 2);
* where that cannot be trusted either, the fit has no interval to promise: the refined stage did not
  converge, its minimum failed to run, or it ended on a range end the estimate is not on (the refined
  model's minimum may lie beyond the range). The keys concerned (all of them but for the range end)
  are given their whole range, are not identified, and a warning names them and the reason.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..measurement import relative_rms
from .discretization import Discretization
from .problem import Evaluation, Problem
from .stages import _Runner, local_stage, residual_check

#: a linear step whose actual reduction of the refined sum of squares differs from the predicted one by
#: more than this fraction is not trusted (trust-region methods expand their region above 0.75)
TRUST = 0.25
#: the most residual evaluations of the refined model's own local stage (each with p more runs for its
#: Jacobian: about 3 (p + 1) of them when it converges in three steps)
REFIT_NFEV = 12
#: the refit's step tolerance as a fraction of the smallest noise standard deviation (unit box)
STEP_TOLERANCE = 0.1
#: a refined minimum within this fraction of a range of an end sits on it (as the fit's AT_BOUND)
AT_END = 1e-3


def reduction_ratio(J: np.ndarray, r: np.ndarray, du: np.ndarray, r_new: np.ndarray) -> float:
    """The actual reduction of |r|^2 by the step ``du`` (residuals ``r_new`` there) over the one the
    linear model ``r + J du`` predicts; NaN when the linear model predicts none.

    >>> J, r = np.array([[1.0], [2.0]]), np.array([1.0, 2.0])
    >>> du = np.array([-1.0])
    >>> reduction_ratio(J, r, du, r + J @ du)           # a linear model: exactly as predicted
    1.0
    >>> round(reduction_ratio(J, r, du, r + 0.5 * J @ du), 3)   # half the way: 3/4 of the reduction
    0.75
    """
    rr = float(r @ r)
    predicted = rr - float(np.sum((r + J @ du) ** 2))
    actual = rr - float(r_new @ r_new)
    return actual / predicted if predicted > 0 else math.nan


class _RefinedRunner:
    """The refined model's runs, cached by point, in :func:`local_stage`'s runner interface."""

    def __init__(self, runner: _Runner, overrides, stage: str):
        self.base, self.overrides, self.stage = runner, list(overrides), stage
        self.problem, self.n, self.say = runner.problem, runner.n, runner.say
        self.cache: dict[bytes, Evaluation] = {}

    @property
    def evaluations(self) -> list[Evaluation]:
        return self.base.evaluations

    def run(self, us, stage: str, report: bool = False) -> list[Evaluation]:
        todo = list({np.asarray(u, float).tobytes(): np.asarray(u, float) for u in us
                     if np.asarray(u, float).tobytes() not in self.cache}.values())
        if todo:
            for u, ev in zip(todo, self.base.run_refined(todo, self.overrides, self.stage)):
                self.cache[u.tobytes()] = ev
        return [self.cache[np.asarray(u, float).tobytes()] for u in us]


def check(runner: _Runner, problem: Problem, u: np.ndarray, r: np.ndarray, unc, d: Discretization,
          speculate: bool, say) -> Discretization:
    """``d`` (the linear step of the refined model at the estimate ``u``, the fitted model's residuals
    ``r`` there and its statistics ``unc``) checked, and replaced by the refined model's own minimum
    when it cannot be trusted (see the module's text). The result records the ``ratio``, the linear
    step (``linear_shift``) when a refit replaced it, the ``refit``'s course and the keys with
    ``no_interval`` and why."""
    if d.error or d.jacobian is None or d.residuals is None:
        return d
    p = len(problem.params)
    step = np.nan_to_num(d.shift)
    ratio = math.nan
    start_ev = None
    if np.any(step != 0.0):
        start_ev = runner.run_refined([np.clip(u + step, 0.0, 1.0)], d.overrides, "refined")[0]
        if start_ev.residuals is not None:
            ratio = reduction_ratio(d.jacobian, d.residuals, step, start_ev.residuals)
    why = []
    if np.any(step != 0.0) and not abs(ratio - 1.0) <= TRUST:
        why.append("the refined run at the shifted point failed" if start_ev is None or start_ev.error else
                   f"the refined model's sum of squares fell by {ratio:.3g} times what its linear step predicts")
    if r is not None and residual_check(r, problem.data.names, problem.kind, relative_rms(r))[1] is not None:
        why.append("the fitted model's residuals are structured")
    d = replace(d, ratio=ratio)
    if not why:
        return d
    reason = " and ".join(why)
    start = u if start_ev is None or not start_ev.misfit < d.misfit else np.clip(u + step, 0.0, 1.0)
    say(f"refined local stage ({reason}): the refined model's own minimum, from its run "
        + ("at the estimate" if start is u else "one linear step from it"))
    sigma = unc.sigma[np.isfinite(unc.sigma) & (unc.sigma > 0)]
    xtol = STEP_TOLERANCE * float(np.min(sigma)) / max(float(np.linalg.norm(start)), 1e-3) if sigma.size else 1e-8
    sub = _RefinedRunner(runner, d.overrides, "refined-local")
    ur, rr, _, sol = local_stage(sub, np.array(start, float), speculate, REFIT_NFEV, "refined-local",
                                 xtol=max(xtol, 1e-12), ftol=1e-8)
    end = sub.run([ur], "refined-local")[0]
    refit = {"why": reason, "start": _values(problem, start), "end": _values(problem, ur),
             "misfit": float(end.misfit) if math.isfinite(end.misfit) else None, "nfev": int(sol.nfev),
             "status": int(sol.status), "message": str(sol.message), "runs": len(sub.cache)}
    shift = np.where(np.isfinite(d.shift), ur - u, np.nan) + 0.0
    lost = np.zeros(p, dtype=bool)
    lost_why = ""
    if end.error:
        lost[:], lost_why = True, f"the refined model's run at its own minimum failed ({end.error})"
    elif sol.status <= 0:
        lost[:], lost_why = True, (f"the refined model's own least squares did not converge in {sol.nfev} "
                                   f"evaluations ({sol.message})")
    else:
        for i in range(p):
            for end_u in (0.0, 1.0):
                if abs(ur[i] - end_u) <= AT_END and abs(u[i] - end_u) > AT_END:
                    lost[i] = True
        if lost.any():
            lost_why = "the refined model's own minimum lies on a range end the estimate is not on"
    lost &= np.isfinite(d.shift)
    say("refined minimum at " + ", ".join(f"{q.key}={q.value(x):.6g}" for q, x in zip(problem.params, ur))
        + f" (misfit {100 * end.misfit:.4g} %): shift " + ", ".join(
            f"{q.key} {s * (q.high - q.low):+.3g}" for q, s in zip(problem.params, shift)))
    return replace(d, shift=shift, linear_shift=d.shift, refit=refit, no_interval=lost,
                   no_interval_reason=lost_why if lost.any() else "")


def _values(problem: Problem, u: np.ndarray) -> dict:
    return {q.key: float(q.value(x)) for q, x in zip(problem.params, u)}
