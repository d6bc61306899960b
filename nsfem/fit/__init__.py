"""Parameter estimation (``nsfem fit``): the scene keys that explain measured sensor signals.

The varied keys live in a box (``--vary KEY=LOW:HIGH``), scaled to the unit box for the optimizer
and the statistics. Two stages minimize the relative residuals of :mod:`nsfem.measurement`:

* global: a scrambled Sobol design (scipy.stats.qmc, seeded) over the box, run on Dask like a
  sweep, all runs at once; the best sample starts
* local: scipy.optimize.least_squares (trust region, bounds) with a forward-difference Jacobian
  whose p perturbed runs are submitted together (with the base run, when the cluster has more
  than one worker: a rejected step then wastes p runs but no wall time).

The uncertainty at the optimum is linearized (:mod:`nsfem.analysis.uncertainty`) and widened by
the fitted model's discretization error, measured by refined runs at the estimate
(:mod:`nsfem.fit.discretization`; the refined model's own minimum where one step of it cannot be
trusted, :mod:`nsfem.fit.refit`); structured residuals' autocorrelation widens the noise interval
(:func:`~nsfem.fit.stages.noise_statistics`). Further local stages look past the first basin
(:func:`_further_minima`):

* the mirror image of the estimate about the shaft's middle (:func:`~nsfem.fit.stages.mirror_point`),
  when its misfit is within :data:`CANDIDATE_FACTOR` of the estimate's or the best global sample's,
  the larger: a symmetric shaft sees a defect and its image alike but through the sensors and loads;
* with a global stage, a second basin: the best global sample within :data:`CANDIDATE_FACTOR` of the
  best sample's misfit and at least :data:`SEPARATION` of a range from every minimum found;
* with a global stage, zoomed designs (at most :data:`RESTARTS`, each at most :data:`ZOOM_SAMPLES` runs) while the best minimum's residuals are structured (lag-1
  autocorrelation above the white-noise bound in some sensor, misfit above :data:`RESOLUTION`: a
  local minimum or a model that cannot explain the data): Sobol points within :data:`ZOOM` of each
  range about the minima found, in order of misfit; the best point starts a local stage when it
  beats the minimum it surrounds.

The best minimum is the estimate; every other distinct one is an :class:`Alternative`, compared with
it by an F-test on their residual sums of squares. When the data cannot tell them apart at 95 % (a
mirrored delamination seen by mirrored sensors), the keys that differ are ambiguous and not
identified, however narrow their local intervals. Structured residuals at the estimate are a warning.

How the measurement is simulated: the scene (with its fixed overrides) says how it was made; the
runs end at the data's last time (``simulation.t_end``) and write outputs at least as often as the
data were sampled (``simulation.output_dt`` = the smaller of the scene's and the data's smallest
step; when the data's times are not multiples of it, :data:`~nsfem.fit.problem.REFINE` times finer),
and a cubic spline through the outputs gives their signals at the data's times (exactly the outputs
when the data share the run's grid, else within 3e-4 of the amplitude at the data's Nyquist
frequency). Every input is checked before the first run: the data, its columns
against the scene's sensors, every range (LOW < HIGH, a key varied once) and every key loaded at
both ends and the middle of its range (the others at their middle).

Runs whose varied keys all lie in tables that enter neither the model nor its reduction
(:data:`nsfem.sweep.SHARED_TABLES`: speed, damping, initial state) share one model, built once
here and sent once to every worker; other keys (delaminations, cracks, bearings) build the model
on the worker, per run.

>>> parse_vary(["delamination.0.start=0.1:0.3"])
(Parameter(key='delamination.0.start', low=0.1, high=0.3),)
"""

from __future__ import annotations

import math
import numbers
import os
import time
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

from ..atomic import check_folder
from ..errors import NsfemError
from ..measurement import relative_rms
from .problem import FIT_KEYS, Evaluation, Parameter, Problem, overrides_at, parse_vary, prepare, run_signals
from .result import AT_BOUND, SAME_FIT, Alternative, FitInterrupted, FitResult, _write, evaluations_csv
from . import discretization, refit
from .discretization import Discretization
from .stages import (CANDIDATE_FACTOR, DISTINCT, FAILED_RESIDUAL, RESOLUTION, RESTARTS, SEPARATION, STEP, WHITE_LEVEL, ZOOM,
                     ZOOM_SAMPLES,
                     _point, _perturbed, _Runner, alternative, jacobian, local_stage, mirror_point, noise_statistics, residual_check,
                     second_start, sobol, zoomed)

__all__ = ["fit", "FitResult", "FitInterrupted", "Alternative", "Evaluation", "Parameter", "Problem", "parse_vary",
           "prepare", "overrides_at", "run_signals", "evaluations_csv", "alternative", "local_stage", "residual_check",
           "second_start", "mirror_point", "Discretization", "RESTARTS", "FIT_KEYS", "AT_BOUND", "SAME_FIT", "CANDIDATE_FACTOR", "DISTINCT", "FAILED_RESIDUAL",
           "RESOLUTION", "SEPARATION", "STEP", "WHITE_LEVEL"]


def default_folder(problem: Problem) -> Path:
    """``<output.dir>/fit-<varied keys>``."""
    return problem.base.output.dir / ("fit-" + ",".join(p.key for p in problem.params))


def fit(scene_path, data, vary, misfit: str = "time", client=None, workers: int | None = None,
        scheduler: str | None = None, n_global: int | None = None, start: Mapping[str, float] | None = None,
        overrides: Sequence[str] = (), out_dir=None, seed: int = 0, max_nfev: int = 40,
        progress: Callable[[str], None] | None = None, plot: bool = True, refine: bool = True) -> FitResult:
    """Estimate the keys of ``vary`` ({key: (low, high)} or ``KEY=LOW:HIGH`` texts) from ``data``
    (a CSV path or (t, {sensor name: samples})); see the module's text.

    ``n_global`` Sobol samples (rounded up to a power of 2; default 2^(3 + p), at most 256; 0 skips the
    global stage); ``start`` {key: value} starts the local stage there instead of at the best sample
    (default without a global stage: the middle of the box). ``client``, ``workers``, ``scheduler``: as
    :func:`nsfem.sweep.run_sweep`. ``progress(line)`` receives a line per run of the global stage and
    per step of the local one. ``refine``: p + 1 more runs at the estimate with the scene's discretization
    refined, whose shift of the minimum widens the interval (:mod:`nsfem.fit.discretization`). Ctrl-C
    writes the runs so far and raises :class:`FitInterrupted`.
    """
    from ..sweep import check_workers

    if workers is not None and (scheduler or client is not None):
        raise NsfemError(("--workers cannot be combined with --scheduler" if scheduler else
                          "workers= cannot be combined with client=") + " (the cluster has its own workers)")
    if scheduler and client is not None:
        raise NsfemError("scheduler= cannot be combined with client= (give one cluster)")
    check_workers(workers)
    t0 = time.perf_counter()
    problem = prepare(scene_path, data, vary, misfit, overrides)
    params, p = problem.params, len(problem.params)
    if n_global is None:
        n_global = min(256, 2 ** (3 + p))
    if not (isinstance(max_nfev, numbers.Integral) and max_nfev > 0):
        raise NsfemError(f"max_nfev must be a positive integer, got {max_nfev!r}")
    if not (isinstance(seed, numbers.Integral) and seed >= 0):
        raise NsfemError(f"seed must be a non-negative integer, got {seed!r}")
    if n_global < 0:
        raise NsfemError(f"n_global must be 0 or more, got {n_global}")
    u_start = None
    if start is not None:
        unknown = [k for k in start if k not in {q.key for q in params}]
        if unknown:
            raise NsfemError(f"start: {unknown[0]} is not varied")
        try:
            u_start = np.array([(float(start.get(q.key, q.value(0.5))) - q.low) / (q.high - q.low) for q in params])
        except (TypeError, ValueError):
            raise NsfemError("start: every value must be a number") from None
        if np.any((u_start < 0) | (u_start > 1)) or not np.all(np.isfinite(u_start)):
            raise NsfemError("start: every value must lie in its key's range")
    out = (Path(out_dir) if out_dir is not None else default_folder(problem)).absolute()
    check_folder(out, "--out")
    from ..outdir import FIT_FILES, claim

    data_files = [data] if isinstance(data, (str, os.PathLike)) else []  # in the folder: kept by later runs
    with claim(out, "fit", {"fit": FIT_FILES}, inputs=data_files):  # one fit at a time; an earlier one's files replaced
        return _estimate(problem, out, u_start, client, workers, scheduler, n_global, max_nfev, seed, misfit,
                         progress, plot, refine, t0)


def _estimate(problem: Problem, out: Path, u_start, client, workers, scheduler, n_global: int, max_nfev: int,
              seed: int, misfit: str, progress, plot: bool, refine: bool, t0: float) -> FitResult:
    """:func:`fit` in its claimed folder ``out``."""
    from ..analysis.uncertainty import linearized
    from ..sweep import _client, _close, _hold_signals, _release_signals

    params, p = problem.params, len(problem.params)
    say = progress or (lambda line: None)
    cl, closing, runner = None, [], None
    info: dict = {"workers": 0, "seed": seed, "global_samples": 0}
    design = sobol(p, n_global, seed) if n_global else None
    plan_line = (f"global stage: {len(design)} runs over the box ("
                 + ", ".join(f"{q.key} {q.low:g}..{q.high:g}" for q in params) + ")") if n_global else None
    local = client is None and not scheduler
    if local and plan_line:      # at once, before the seconds a local cluster takes to start
        say(plan_line)
    try:
        cl, closing = _client(client, workers, scheduler, max(n_global, p + 1))
        info["workers"] = len(cl.nthreads())
        runner = _Runner(problem, cl, say)
        best = None
        if n_global:
            info["global_samples"] = len(design)
            if not local:        # once connected: a scheduler that cannot be reached is one line
                say(plan_line)
            evs = runner.run(list(design), "global", report=True)
            ok = [e for e in evs if math.isfinite(e.misfit)]
            if not ok:
                raise NsfemError(f"every run of the global stage failed (first: {evs[0].error or 'no reason given'})")
            best = min(ok, key=lambda e: e.misfit)
        u0 = u_start if u_start is not None else (best.u if best is not None else np.full(p, 0.5))
        say(f"local stage from {_point(params, u0)}")
        speculate = info["workers"] > 1
        u, r, J, sol = local_stage(runner, np.array(u0, float), speculate, max_nfev)
        info["local"] = {"nfev": int(sol.nfev), "njev": int(sol.njev or 0), "status": int(sol.status),
                         "message": str(sol.message)}
        minima = _further_minima(runner, problem, (u, r, J), speculate, max_nfev, info, seed, explore=n_global > 0,
                                 level=best.misfit if best is not None else 0.0)
        u, r, J = min(minima, key=lambda m: relative_rms(m[1]))
        unc = linearized(J, r, u, floor=RESOLUTION)
        unc, failed = _without_failed_steps(runner, params, u, unc)
        ev = runner.run([u], "local")[0]
        unc, tau = noise_statistics(unc, J, r, u, problem.data.names, misfit, relative_rms(r))
        disc = _refined(runner, problem, u, unc, say) if refine else None
        if disc is not None:
            disc = refit.check(runner, problem, u, r, unc, disc, say)
        interval = discretization.reported(unc.interval, disc)
        alternatives = []
        for u2, r2, _ in minima:
            alt = alternative(params, u, r, interval, u2, r2) if u2 is not u else None
            if alt is not None:
                alternatives.append(alt)
                say(f"another minimum at {_point(params, u2)}: misfit {100 * alt.misfit:.4g} %, F-test p = "
                    f"{alt.p_value:.3g}" + (" (as good as the estimate)" if alt.indistinguishable else ""))
    except KeyboardInterrupt:
        held = _hold_signals()  # a second Ctrl-C must not cut the writing short
        if runner is not None:
            runner.cancel()
        _close(closing)
        closing = []
        try:
            info["interrupted"] = True
            res = _partial(problem, runner, out, info, t0)
            res = _write(res, plot=False)
        finally:
            _release_signals(held)
        raise FitInterrupted(res) from None
    finally:
        _close(closing)
    est = np.array([q.value(x) for q, x in zip(params, u)])
    stats, warning = residual_check(ev.residuals, problem.data.names, misfit, ev.misfit)
    if stats is not None:
        info["residuals"] = {**stats, "autocorrelation_time": {n: float(x) for n, x in zip(problem.data.names, tau)}}
    warnings = [failed] if failed else []
    if warning:
        warnings.append(warning)
    if disc is not None and disc.error:
        warnings.append(f"{disc.error}: the interval leaves out the model's discretization error")
    elif disc is not None:
        big = discretization.warning(params, disc, unc.interval, u)
        lost = discretization.unpromised(params, disc)
        warnings += [w for w in (big, lost) if w]
    for w in warnings:
        say(f"warning: {w}")
    info["wall_s"] = time.perf_counter() - t0
    res = FitResult(params, est, ev.misfit, misfit, problem.data, ev.signals, tuple(runner.evaluations), unc, out,
                    info=info, alternatives=tuple(alternatives), warnings=tuple(warnings), discretization=disc)
    return _write(res, plot=plot)


def _further_minima(runner: _Runner, problem: Problem, first, speculate: bool, max_nfev: int, info: dict,
                    seed: int = 0, explore: bool = True, level: float = 0.0) -> list:
    """The minima (u, residuals, Jacobian) of the first local stage and the further ones: from the mirror
    image of the first minimum (:func:`~nsfem.fit.stages.mirror_point`) when its misfit is within
    :data:`CANDIDATE_FACTOR` of the minimum's or of ``level`` (the best global sample's), the larger;
    with ``explore`` (a global stage ran): from the best distant global sample within that factor of
    the best sample (:func:`second_start`); then, while the best minimum's residuals are structured, up to
    :data:`RESTARTS` zoomed designs (:func:`zoomed`, 2^(4 + p) runs, at most :data:`ZOOM_SAMPLES`, within
    :data:`ZOOM` of each range)
    about the minima in order of misfit, each starting a local stage from its best point when that beats
    the minimum it surrounds and lies off every known one. A further stage that ends within
    :data:`DISTINCT` of a known minimum adds none."""
    params, say = problem.params, runner.say
    minima, used, runs = [first], [], []
    info["further_local"] = runs          # filled as the stages end: a Ctrl-C keeps those that did

    def start(u0: np.ndarray, kind: str, why: str) -> None:
        used.append(np.array(u0, float))
        say(f"{kind} local stage from {_point(params, u0)} ({why})")
        # its runs' stage in evaluations.csv: apart from the mirror's and the zoomed design's own runs
        label = kind if kind == "second" else f"{kind}-local"
        u2, r2, J2, sol = local_stage(runner, np.array(u0, float), speculate, max_nfev, label)
        runs.append({"stage": kind, "why": why, "start": {q.key: q.value(x) for q, x in zip(params, u0)},
                     "end": {q.key: q.value(x) for q, x in zip(params, u2)}, "misfit": relative_rms(r2),
                     "nfev": int(sol.nfev), "njev": int(sol.njev or 0), "status": int(sol.status),
                     "message": str(sol.message)})
        if not any(np.all(np.abs(u2 - m[0]) <= DISTINCT) for m in minima):
            minima.append((u2, r2, J2))

    u, r, _ = first
    image = mirror_point(params, u, problem.extent)
    if image is not None:
        ev = runner.run([image], "mirror")[0]
        if ev.misfit <= CANDIDATE_FACTOR * max(relative_rms(r), level):
            start(image, "mirror", f"the estimate reflected about the shaft's middle: misfit {100 * ev.misfit:.4g} %")
    if not explore:
        return minima
    cand = second_start(runner.evaluations, [m[0] for m in minima], used=used)
    if cand is not None:
        start(cand.u, "second", f"a good global sample far from the estimate: misfit {100 * cand.misfit:.4g} %; "
                "another basin?")
    zoomed_about: list[np.ndarray] = []
    for _ in range(RESTARTS):
        best = min(minima, key=lambda m: relative_rms(m[1]))
        if residual_check(best[1], problem.data.names, problem.kind, relative_rms(best[1]))[1] is None:
            break
        todo = [m for m in sorted(minima, key=lambda m: relative_rms(m[1]))
                if not any(np.array_equal(m[0], z) for z in zoomed_about)]
        if not todo:
            break
        centre, around = todo[0][0], relative_rms(todo[0][1])
        zoomed_about.append(centre)
        design = zoomed(centre, min(ZOOM_SAMPLES, 2 ** (4 + len(params))), seed)
        say(f"zoomed stage: {len(design)} runs within {ZOOM:g} of each range about {_point(params, centre)} (the "
            f"residuals at the best minimum, {100 * relative_rms(best[1]):.4g} %, are structured: a local minimum?)")
        evs = [e for e in runner.run(list(design), "zoom") if math.isfinite(e.misfit)]
        far = [e for e in evs if not any(np.all(np.abs(e.u - m[0]) <= ZOOM / 4) for m in minima)]
        cand = min(far, key=lambda e: e.misfit) if far else None
        if cand is not None and cand.misfit < around:
            start(cand.u, "zoom", f"the best of the zoomed design: misfit {100 * cand.misfit:.4g} %")
    return minima


def _refined(runner: _Runner, problem: Problem, u: np.ndarray, unc, say: Callable[[str], None]) -> Discretization:
    """The refined runs at the estimate ``u`` (and one step from it per key) and the discretization shift
    they give (:mod:`nsfem.fit.discretization`). Kept modes that the refined model cannot hold (a mesh from a file)
    are kept as they were in a second try; with nothing to refine, or when the refined runs fail, the
    result says so in ``error`` and has no shift."""
    sets, kept = discretization.refined_overrides(problem.base)
    p = len(problem.params)
    q = discretization.order(problem.base.simulation.method)
    nothing = np.full(p, np.nan)
    if not sets:
        return discretization.Discretization((), tuple(kept), math.nan, nothing, q,
                                             "the scene has no discretization setting to refine")
    say(f"refined runs at the estimate ({', '.join(sets)}): the model's discretization error")
    evs = runner.run_refined([u, *_perturbed(u)], sets)
    failed = next((e.error for e in evs if e.error), "")
    modes = [o for o in sets if o.startswith("reduction.modes=")]
    if failed and modes and "reduction.modes" in failed:
        sets = [o for o in sets if o not in modes]
        kept.append(f"{modes[0]}: the refined model cannot keep them ({failed})")
        if not sets:
            return discretization.Discretization((), tuple(kept), math.nan, nothing, q,
                                                 f"nothing left to refine ({modes[0]} cannot be held)")
        say(f"refined runs again without {modes[0]}")
        evs = runner.run_refined([u, *_perturbed(u)], sets)
        failed = next((e.error for e in evs if e.error), "")
    # the run at the estimate must succeed; a key whose refined step failed gets no shift (its fitted step
    # usually failed too, and _without_failed_steps left it undetermined), the others keep theirs
    if evs[0].error:
        return discretization.Discretization(tuple(sets), tuple(kept), evs[0].misfit, nothing, q,
                                             f"the refined run at the estimate ({', '.join(sets)}) failed: "
                                             f"{evs[0].error}")
    stepped = np.array([not e.error for e in evs[1:]])
    if not stepped.all():
        kept.append("no shift for " + ", ".join(k.key for k, ok in zip(problem.params, stepped) if not ok)
                    + f": the refined run one step away failed ({next(e.error for e in evs[1:] if e.error)})")
    Jr = jacobian(evs[0].residuals, evs[1:], u, runner.n)
    du = discretization.shift(Jr, evs[0].residuals, u, np.isfinite(unc.sigma) & stepped)
    say("discretization shift: " + ", ".join(f"{k.key} {d * (k.high - k.low):+.3g}" for k, d in zip(problem.params, du)))
    return discretization.Discretization(tuple(sets), tuple(kept), evs[0].misfit, du, q, jacobian=Jr,
                                         residuals=evs[0].residuals)


def _without_failed_steps(runner: _Runner, params, u: np.ndarray, unc) -> tuple[object, str | None]:
    """The statistics at ``u`` without the keys whose step of the final Jacobian failed (a failed run's
    residuals are a penalty, not a derivative: its column would claim a confident, wrong interval):
    their interval is the whole range and their sigma and correlations undetermined; and a warning
    naming them (None when every step ran)."""
    from dataclasses import replace

    bad = np.array([bool(e.error) for e in runner.run(_perturbed(u), "local")])
    if not bad.any():
        return unc, None
    interval, sigma, corr = unc.interval.copy(), unc.sigma.copy(), unc.correlation.copy()
    interval[bad] = [0.0, 1.0]
    sigma[bad] = np.inf
    corr[bad, :] = np.nan
    corr[:, bad] = np.nan
    keys = ", ".join(q.key for q, b in zip(params, bad) if b)
    return replace(unc, interval=interval, sigma=sigma, correlation=corr), (
        f"the run one step from the estimate failed for {keys}: no derivative, no statistics; the interval of "
        f"{keys} is its whole range (not identified). A region where runs fail borders the estimate: check the "
        "failed runs in evaluations.csv, or narrow the range")


def _partial(problem: Problem, runner: _Runner | None, out: Path, info: dict, t0: float) -> FitResult:
    """The best run so far as a result without statistics."""
    evs = tuple(runner.evaluations) if runner is not None else ()
    ok = [e for e in evs if math.isfinite(e.misfit) and not e.stage.startswith("refined")]   # refined: another model's signals
    best = min(ok, key=lambda e: e.misfit) if ok else None
    u = best.u if best is not None else np.full(len(problem.params), np.nan)
    est = np.array([q.low + x * (q.high - q.low) for q, x in zip(problem.params, u)])
    info["wall_s"] = time.perf_counter() - t0
    return FitResult(problem.params, est, best.misfit if best else math.nan, problem.kind, problem.data,
                     best.signals if best else None, evs, None, out, info=info)
