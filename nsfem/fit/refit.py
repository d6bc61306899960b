"""Whether one Gauss-Newton step of the refined model can be trusted as the discretization shift, and
the refined model's own minimum when it cannot.

The shift of :mod:`nsfem.fit.discretization` is one linear step, du = -J_r^+ r_r, of the refined
model from the estimate. It is where the refined model's minimum lies only if that model is nearly
linear in the keys between the two minima. Contact dynamics are not: on the delamination falling from
rest (the identification study's ``delam_rest_asym``) the step found 0.22 of a 1.5 mm offset, and the
interval built on it missed the truth by 1.2 mm; a Jacobian of wider differences (1e-3 and 4e-3 of the
ranges) gave as short a step, so the misfit, not its ruggedness, is far from quadratic there. So:

* the step is checked as a trust-region method checks its model: one more refined run at u + du gives
  the actual reduction of the refined residuals' sum of squares against the one the linear model
  predicts, |r_r|^2 - |r_r + J_r du|^2 (:func:`reduction_ratio`); within :data:`TRUST` of 1 the step
  is trusted;
* otherwise, or when the fitted model's residuals at the estimate are structured (the lag-1 test, or
  mostly a coherent signal at some lag up to :data:`LAGS`, :func:`coherent_share`: it cannot explain
  the data, and how far its minimum lies from the refined one is no local question), the refined
  model's own minimum is found (:func:`secant_minimum`: Gauss-Newton steps, one refined run each, on a
  Jacobian updated along every step taken; a step that does better than predicted is doubled). The
  shift is the difference of the two minima, u_r - u, and the interval is widened by it as by the linear
  step (4/3 of it: Richardson's extrapolation at order 2);
* where that cannot be trusted either, the fit has no interval to promise: the minimization did not
  settle in :data:`REFIT_RUNS` runs (the keys its next step would still move), a run failed (every
  key), or its minimum lies on a range end the estimate is not on (that key: the refined model's
  minimum may lie beyond the range); or the refined model explains the data no better than the fitted
  one (structured residuals at both minima, refinement explaining less than :data:`EXPLAINED` of the
  sum of squares: a local minimum, or a model error that no refinement reduces; every key but those
  whose estimate sits on a range end, which the result reports as such). Those keys
  get their whole range, are not identified, and a warning names them and the reason.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..measurement import relative_rms
from .discretization import Discretization
from .problem import Problem
from .stages import RESOLUTION, _Runner, residual_check

#: a linear step whose actual reduction of the refined sum of squares differs from the predicted one by
#: more than this fraction is not trusted (trust-region methods expand their region above 0.75)
TRUST = 0.25
#: the most runs of the refined model's own minimization (one per step, p per measured Jacobian; the
#: delamination from rest took 21)
REFIT_RUNS = 24
#: its steps end (converged) when the next one moves every key by less than this fraction of its noise
#: standard deviation: the interval's margins (1.96 of them about each minimum) hold what is left
STEP_TOLERANCE = 0.5
#: structured residuals at the fitted and at the refined minimum, the refined explaining less than this
#: share of the fitted sum of squares: the misfit is not the discretization's (a local minimum, a wrong
#: model), and no interval is promised
EXPLAINED = 0.5
#: a residual whose largest autocorrelation over lags 1..:data:`LAGS` (any sign) exceeds this in some sensor
#: is mostly a coherent signal, not noise (noise plus a signal of a share f of its variance correlates up to
#: about f): the lag-1 test misses one of high frequency (a wrong basin of the delamination from rest: lag 1
#: 0.07-0.11 against a bound of 0.125, lag 2 -0.76, share 0.85; in the truth's basin 0.16 and refined 0.10)
COHERENT = 0.5
LAGS = 20
#: the forward-difference step of the Jacobian that confirms the end, in tolerances (2 noise sigmas): wide
#: enough to step over a rugged misfit's small jumps
PROBE = 4.0
#: a refined minimum within this fraction of a range of an end sits on it (as the fit's AT_BOUND)
AT_END = 1e-3


def coherent_share(r: np.ndarray, sensors: int) -> float:
    """The largest |autocorrelation| of the residuals ``r`` (sample-major, ``sensors`` columns) over lags
    1..:data:`LAGS` (at most a quarter of the record), over the sensors: about the share of their variance
    that is a coherent signal (0 for too short a record).

    >>> t = np.arange(400)
    >>> bool(coherent_share(np.cos(np.pi * t / 2), 1) > 0.99)     # a period of 4 samples: rho(2) = -1
    True
    >>> bool(coherent_share(np.random.default_rng(0).standard_normal(2000), 2) < 0.1)   # white: ~3 / sqrt(k)
    True
    """
    R = np.asarray(r, float).reshape(-1, sensors)
    R = R - R.mean(axis=0)
    k = R.shape[0]
    lags = min(LAGS, k // 4)
    c0 = np.sum(R**2, axis=0)
    if lags < 1 or not np.all(c0 > 0):
        return 0.0
    rho = np.array([np.sum(R[:-lag] * R[lag:], axis=0) / c0 for lag in range(1, lags + 1)])
    return float(np.max(np.abs(rho)))


def _unexplained(r: np.ndarray, problem: Problem) -> bool:
    """Whether the residuals ``r`` are not noise: structured by the lag-1 test
    (:func:`~nsfem.fit.stages.residual_check`) or mostly coherent (:func:`coherent_share` above
    :data:`COHERENT`, time misfit above the resolution)."""
    misfit = relative_rms(r)
    if residual_check(r, problem.data.names, problem.kind, misfit)[1] is not None:
        return True
    sensors = len(problem.data.names)
    return problem.kind == "time" and misfit > RESOLUTION and coherent_share(r, sensors) > coherent_bound(
        np.asarray(r).size // sensors, sensors)


def coherent_bound(k: int, sensors: int, level: float = 0.01) -> float:
    """The share above which :func:`coherent_share` calls residuals of ``k`` samples per sensor coherent:
    :data:`COHERENT`, or, for a short record, what white noise reaches with probability ``level`` (each
    autocorrelation about normal with variance 1 / k; the largest of LAGS x sensors of them, Bonferroni):
    white noise of 16 samples and 8 sensors passed 0.5 in 47 % of records.

    >>> bool(coherent_bound(4000, 4) == COHERENT)
    True
    >>> round(float(coherent_bound(16, 8)), 2)
    0.9
    """
    from scipy.stats import norm

    lags = max(1, min(LAGS, k // 4))
    return max(COHERENT, float(norm.ppf(1.0 - level / (2 * lags * sensors))) / np.sqrt(max(k, 1)))


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


def broyden(J: np.ndarray, du: np.ndarray, dr: np.ndarray) -> np.ndarray:
    """``J`` corrected along the step ``du`` to the change ``dr`` it made (Broyden's rank-one update):
    a secant over the whole step, blind to the misfit's ruggedness below it.

    >>> broyden(np.array([[1.0, 0.0]]), np.array([1.0, 0.0]), np.array([3.0])).tolist()
    [[3.0, 0.0]]
    """
    dd = float(du @ du)
    return J + np.outer(dr - J @ du, du) / dd if dd > 0 else J


def secant_minimum(run, J: np.ndarray, u: np.ndarray, r: np.ndarray, tol: np.ndarray, tried=None,
                   max_runs: int = REFIT_RUNS) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """The minimum of a model's residuals near ``u`` (residuals ``r``, Jacobian ``J`` there), by
    Gauss-Newton steps in the unit box on a Jacobian updated by :func:`broyden` after every run
    (``run([u, ...])`` -> their residuals, None for a failed run). A Gauss-Newton step of a misfit far from
    quadratic (large residuals, contact events) falls short: while a step lowers the sum of squares by
    more than its linear model predicted (:func:`reduction_ratio` above 1 + :data:`TRUST`), it is
    doubled. A secant knows only the directions stepped along (a column left too steep stops it
    anywhere): when a step does not lower the sum of squares, or the next step moves every key with a
    finite ``tol`` by less than it (keys with an infinite one are not stepped), the Jacobian is measured
    afresh by forward differences of :data:`PROBE` tolerances (p runs submitted together); a measured
    Jacobian's step that does not lower it halves the next one. It ends when the step on a measured
    Jacobian is below ``tol``; else after ``max_runs`` runs, or at a failed run. ``tried``: a point
    already run (u, residuals). (u, residuals, the next step, why it did not converge
    ("" when it did))."""
    from .discretization import shift

    moving = np.isfinite(tol)
    cols = np.flatnonzero(moving)
    radius, runs, fresh = np.inf, 0, False
    if tried is not None:
        J = broyden(J, tried[0] - u, tried[1] - r)
        if tried[1] @ tried[1] < r @ r:
            u, r = tried

    def measured(u: np.ndarray, r: np.ndarray, J: np.ndarray):
        """J with the moving columns by forward differences of PROBE tolerances (None: a run failed)."""
        h = np.where(u + PROBE * tol <= 1.0, PROBE * tol, -PROBE * tol)
        rvs = run([u + h[i] * np.eye(u.size)[i] for i in cols])          # submitted together
        if any(rv is None for rv in rvs):
            return None
        J = J.copy()
        for i, rv in zip(cols, rvs):
            J[:, i] = (rv - r) / h[i]
        return J

    while True:
        step = np.nan_to_num(shift(J, r, u, moving))
        if np.all(np.abs(step[moving]) <= tol[moving]) and fresh:
            return u, r, step, ""
        if runs >= max_runs:
            return u, r, step, f"its steps did not settle in {max_runs} runs"
        if np.all(np.abs(step[moving]) <= tol[moving]):   # confirm the end on a measured Jacobian
            if runs + cols.size > max_runs:
                return u, r, step, f"its steps did not settle in {max_runs} runs"
            J, runs, fresh = measured(u, r, J), runs + cols.size, True
            if J is None:
                return u, r, step, "its run at a step failed"
            continue
        big = float(np.max(np.abs(step)))
        if big > radius:
            step = step * radius / big
        un = np.clip(u + step, 0.0, 1.0)
        rn, runs = run([un])[0], runs + 1
        if rn is None:
            return u, r, step, "its run at a step failed"
        ratio = reduction_ratio(J, r, un - u, rn)
        J = broyden(J, un - u, rn - r)
        if not rn @ rn < r @ r:
            if fresh:          # a measured Jacobian's step failed: shorter steps
                radius = min(big, radius) / 2    # (the step as taken: repeated failures keep shrinking)
            elif runs + cols.size <= max_runs:                # a secant's step failed: measure it first
                J, runs, fresh = measured(u, r, J), runs + cols.size, True
                if J is None:
                    return u, r, step, "its run at a step failed"
            continue
        while ratio > 1.0 + TRUST and runs < max_runs:      # the linear model is pessimistic: go further
            far = np.clip(u + 2.0 * (un - u), 0.0, 1.0)
            if np.array_equal(far, un):
                break
            rf, runs = run([far])[0], runs + 1
            if rf is None:
                break
            ratio = reduction_ratio(J, rn, far - un, rf)
            J = broyden(J, far - un, rf - rn)
            if not rf @ rf < rn @ rn:
                break
            un, rn = far, rf
        u, r, radius, fresh = un, rn, np.inf, False


def check(runner: _Runner, problem: Problem, u: np.ndarray, r: np.ndarray, unc, d: Discretization,
          say) -> Discretization:
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
    structured = r is not None and _unexplained(r, problem)
    if np.any(step != 0.0) and not abs(ratio - 1.0) <= TRUST:
        why.append("the refined run at the shifted point failed" if start_ev is None or start_ev.error else
                   f"the refined model's sum of squares fell by {ratio:.3g} times what its linear step predicts")
    if structured:
        why.append("the fitted model's residuals are structured (not noise)")
    d = replace(d, ratio=ratio)
    if not why:
        return d
    reason = " and ".join(why)
    say(f"refined minimum ({reason}): Gauss-Newton steps of the refined model with secant updates")
    tol = STEP_TOLERANCE * np.where(np.isfinite(d.shift) & np.isfinite(unc.sigma), unc.sigma, np.inf)
    runs = []

    def run(vs: list) -> list:
        evs = runner.run_refined(vs, d.overrides, "refined-local")
        runs.extend(evs)
        return [None if ev.error else ev.residuals for ev in evs]

    tried = None
    if start_ev is not None and not start_ev.error:
        tried = (np.clip(u + step, 0.0, 1.0), start_ev.residuals)
    ur, rr, last, failed = secant_minimum(run, d.jacobian, u, d.residuals, tol, tried, REFIT_RUNS)
    refit = {"why": reason, "end": _values(problem, ur), "misfit": relative_rms(rr), "runs": len(runs),
             "converged": not failed, "message": failed or "the next step is below half a noise standard deviation",
             "next_step": _values(problem, last, offset=False)}
    shift = np.where(np.isfinite(d.shift), ur - u, np.nan) + 0.0
    lost = np.zeros(p, dtype=bool)
    lost_why = []
    if failed:
        lost = np.ones(p, bool) if "failed" in failed else np.abs(last) > tol
        if not lost.any():                 # its last small step was never confirmed: none is promised
            lost = np.isfinite(tol)
        lost_why.append(f"the refined model's own minimization failed: {failed}")
    # the share of the fitted sum of squares the refined minimum explains (undefined, NaN, for fitted residuals
    # that vanish: noise-free data of the fitted model, started at the truth)
    explained = 1.0 - (relative_rms(rr) / relative_rms(r)) ** 2 if relative_rms(r) > 0 else math.nan
    refit["explained"] = explained
    # a key on a range end keeps its interval (at_bound says its minimum may lie beyond); the others are
    # estimated in a model that explains the data no better refined, whatever that key does
    on_end = (u <= AT_END) | (u >= 1.0 - AT_END)
    if structured and not (lost | on_end).all() and explained < EXPLAINED and _unexplained(rr, problem):
        lost |= ~on_end
        lost_why.append(f"neither the fitted nor the refined model explains the data (structured residuals at both "
                        f"minima, misfit {100 * relative_rms(r):.3g} % and {100 * relative_rms(rr):.3g} %: refining "
                        f"explains {100 * max(explained, 0.0):.2g} % of the sum of squares); a local minimum, or a "
                        "model error that refinement does not reduce")
    for i in range(p):
        for end_u in (0.0, 1.0):
            if abs(ur[i] - end_u) <= AT_END and abs(u[i] - end_u) > AT_END and not lost[i]:
                lost[i] = True
                lost_why.append(f"the refined model's own minimum lies on the {'lower' if end_u == 0 else 'upper'} "
                                f"end of {problem.params[i].key}'s range, the estimate does not")
    lost &= np.isfinite(d.shift)
    say("refined minimum at " + ", ".join(f"{q.key}={q.value(x):.6g}" for q, x in zip(problem.params, ur))
        + f" (misfit {100 * relative_rms(rr):.4g} %, {len(runs)} runs): shift " + ", ".join(
            f"{q.key} {s * (q.high - q.low):+.3g}" for q, s in zip(problem.params, shift)))
    return replace(d, shift=shift, linear_shift=d.shift, refit=refit, no_interval=lost,
                   no_interval_reason="; ".join(lost_why) if lost.any() else "")


def _values(problem: Problem, u: np.ndarray, offset: bool = True) -> dict:
    return {q.key: float(q.low * offset + x * (q.high - q.low)) for q, x in zip(problem.params, u)}
