"""Parameter estimation (``nsfem fit``): the scene keys that explain measured sensor signals.

The varied keys live in a box (``--vary KEY=LOW:HIGH``), scaled to the unit box for the optimizer
and the statistics. Two stages minimize the relative residuals of :mod:`nsfem.measurement`:

* global: a scrambled Sobol design (scipy.stats.qmc, seeded) over the box, run on Dask like a
  sweep, all runs at once; the best sample starts
* local: scipy.optimize.least_squares (trust region, bounds) with a forward-difference Jacobian
  whose p perturbed runs are submitted together (with the base run, when the cluster has more
  than one worker: a rejected step then wastes p runs but no wall time).

The uncertainty at the optimum is linearized (:mod:`nsfem.analysis.uncertainty`). Two checks
look past it:

* a second basin: the best global sample within :data:`CANDIDATE_FACTOR` of the best sample's misfit
  and at least :data:`SEPARATION` of a range from the estimate starts a second local stage (after
  the first: its distance is from the estimate). A distinct second minimum is an
  :class:`Alternative`, compared with the estimate (the better of the two) by an F-test on their
  residual sums of squares; when the data cannot tell them apart at 95 % (a mirrored delamination
  seen by mirrored sensors), the keys that differ are ambiguous and not identified, however narrow
  their local intervals;
* the residuals at the estimate: white when the model explains the data to their noise, smooth
  when it does not (a wrong minimum, a wrong model). Structured residuals (lag-1 autocorrelation
  above the white-noise bound in some sensor) with a misfit above :data:`RESOLUTION` are a warning.

How the measurement is simulated: the scene (with its fixed overrides) says how it was made; the
runs end at the data's last time (``simulation.t_end``) and write outputs at least as often as the
data were sampled (``simulation.output_dt`` = the smaller of the scene's and the data's smallest
step), and their signals are interpolated linearly at the data's times (exactly the outputs when
the data share the run's grid). Every input is checked before the first run: the data, its columns
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

import csv
import io
import math
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

from .atomic import check_folder, write_text_atomic
from .errors import IntegrationError, NsfemError
from .measurement import (MISFITS, Measurement, check_measurement, is_uniform, match_sensors, read_measurement,
                          relative_rms, residuals, sample, scales)

#: finite-difference step of the Jacobian in the unit box (1e-4 of a range)
STEP = 1e-4
#: residual of every sample of a failed run: a relative misfit of 1000 %, worse than any fit
FAILED_RESIDUAL = 10.0
#: an estimate within this fraction of its range's width from an end sits on the bound
AT_BOUND = 1e-3
#: keys the fit sets itself
FIT_KEYS = ("simulation.t_end", "simulation.output_dt")
#: a global sample within this factor of the best sample's misfit, and at least SEPARATION (of a
#: range, for some key) from the estimate, starts a second local stage: a second basin
CANDIDATE_FACTOR = 2.0
SEPARATION = 0.25
#: a second minimum that lies within this fraction of every range from the estimate is the same one
DISTINCT = 0.01
#: relative RMS misfit below which residuals are resolution, not information: the optimizer stops
#: within its tolerance of a minimum whose misfit is rugged (noise-free data from the same model:
#: 3e-5 measured from rest, 1e-11 from a stationary state), and no measurement we know of is
#: accurate to 0.1 % of its RMS. The F-test's floor; no residual warning below it
RESOLUTION = 1e-3
#: p-value at or above which two minima explain the data equally well (the F-test at 95 %)
SAME_FIT = 0.05
#: family-wise false-alarm rate of the residuals' whiteness test over the sensors
WHITE_LEVEL = 0.01


@dataclass(frozen=True)
class Parameter:
    """A varied scene key and its range."""

    key: str
    low: float
    high: float

    def value(self, u: float) -> float:
        """The key's value at ``u`` in [0, 1]."""
        return self.low + float(np.clip(u, 0.0, 1.0)) * (self.high - self.low)


def parse_vary(items: Sequence[str] | Mapping[str, tuple[float, float]]) -> tuple[Parameter, ...]:
    """Parameters from ``KEY=LOW:HIGH`` texts or {key: (low, high)}: finite ends, LOW < HIGH, no key twice."""
    pairs: list[tuple[str, str, str]] = []
    if isinstance(items, Mapping):
        for key, rng in items.items():
            try:
                lo, hi = rng
            except (TypeError, ValueError):
                raise NsfemError(f"--vary {key}: give (LOW, HIGH), got {rng!r}") from None
            pairs.append((str(key), str(lo), str(hi)))
    else:
        for text in items:
            key, sep, rng = text.partition("=")
            lo, colon, hi = rng.partition(":")
            if not sep or not colon or not key.strip():
                raise NsfemError(f"--vary {text.strip()}: give KEY=LOW:HIGH")
            pairs.append((key.strip(), lo, hi))
    if not pairs:
        raise NsfemError("nsfem fit: nothing to vary; give at least one --vary KEY=LOW:HIGH")
    out: list[Parameter] = []
    for key, lo, hi in pairs:
        ends = []
        for name, text in (("LOW", lo), ("HIGH", hi)):
            try:
                v = float(text)
            except ValueError:
                v = math.nan
            if not math.isfinite(v):
                raise NsfemError(f"--vary {key}: {name} must be a finite number, got {text.strip()!r}")
            ends.append(v)
        if ends[0] >= ends[1]:
            raise NsfemError(f"--vary {key}: LOW must be below HIGH, got {lo.strip()}:{hi.strip()}")
        if any(p.key == key for p in out):
            raise NsfemError(f"--vary {key}: varied twice (give one range per key)")
        if key in FIT_KEYS:
            raise NsfemError(f"--vary {key}: the fit sets it from the data's times (it cannot be varied)")
        out.append(Parameter(key, *ends))
    return tuple(out)


def _num(v: float) -> str:
    return repr(float(v))


def overrides_at(params: Sequence[Parameter], u) -> list[str]:
    """The ``--set`` overrides of the point ``u`` of the unit box."""
    return [f"{p.key}={_num(p.value(x))}" for p, x in zip(params, u)]


# --------------------------------------------------------------------------- one run (on a worker)
def run_signals(scene, shared, t: np.ndarray, columns: Sequence[int]) -> tuple[np.ndarray | None, str]:
    """(signals (len(t), len(columns)), "") of one run at the measurement's times, or (None, error)."""
    from .simulate import run_scene, sensor_signals
    from .sweep import _message

    model, red = shared if shared is not None else (None, None)
    try:
        result, system = run_scene(scene, progress=False, model=model, reduction=red)
    except IntegrationError as exc:
        return None, _message(exc)
    except Exception as exc:  # noqa: BLE001 - a failed run scores FAILED_RESIDUAL, its error is kept
        return None, _message(exc)
    values = sensor_signals(result, system)[:, list(columns)]
    return sample(result.t, values, t), ""


# --------------------------------------------------------------------------- the problem (on the client)
@dataclass(frozen=True)
class Evaluation:
    """One run of the fit: its point ``u`` (unit box), ``stage``, misfit, residuals and signals (None
    when it failed, then ``error``)."""

    u: np.ndarray
    stage: str
    misfit: float
    residuals: np.ndarray | None = field(repr=False, default=None)
    signals: np.ndarray | None = field(repr=False, default=None)
    error: str = ""


@dataclass(frozen=True)
class Problem:
    """Everything a run needs, validated: parameters, the measurement, which sensors, misfit kind,
    fixed overrides (with the fit's time settings), the scene's path and whether runs share a model."""

    scene_path: str | Path | None
    params: tuple[Parameter, ...]
    data: Measurement
    columns: tuple[int, ...]
    kind: str
    fixed: tuple[str, ...]
    shared: bool
    base: object = field(repr=False, default=None)

    def scene(self, u):
        from .scene import load_scene

        return load_scene(self.scene_path, [*self.fixed, *overrides_at(self.params, u)])


def prepare(scene_path, data, vary, misfit: str = "time", overrides: Sequence[str] = ()) -> Problem:
    """Check every input (one-line errors, nothing run) and set up the problem."""
    from .scene import load_scene
    from .sweep import SHARED_TABLES

    if misfit not in MISFITS:
        raise NsfemError(f"--misfit must be {' or '.join(MISFITS)}, got {misfit!r}")
    params = parse_vary(vary)
    fixed = list(overrides)
    for o in fixed:
        key = o.partition("=")[0].strip()
        if any(p.key == key for p in params):
            raise NsfemError(f"{key}: both varied and fixed (drop its --set)")
    if isinstance(data, Measurement):
        m = check_measurement(data.t, dict(zip(data.names, data.values.T)))
    elif isinstance(data, (str, Path)):
        m = read_measurement(data)
    else:
        try:
            t, signals = data
        except (TypeError, ValueError):
            raise NsfemError("data: give a CSV path or (t, {sensor name: samples})") from None
        m = check_measurement(t, dict(signals))
    base = load_scene(scene_path, fixed)
    columns = match_sensors(m, base.sensors, f"--data {data}" if isinstance(data, (str, Path)) else "data")
    if misfit == "spectrum" and not is_uniform(m.t):
        raise NsfemError("--misfit spectrum: the data's t must be sampled at one step (an FFT needs it)")
    dt = min(base.simulation.output_dt, float(np.min(np.diff(m.t))))
    fixed += [f"simulation.t_end={_num(m.t[-1])}", f"simulation.output_dt={_num(dt)}"]
    base = load_scene(scene_path, fixed)
    mid = [0.5] * len(params)
    for i, p in enumerate(params):
        for u in (0.0, 0.5, 1.0):
            point = mid.copy()
            point[i] = u
            try:
                load_scene(scene_path, [*fixed, *overrides_at(params, point)])
            except NsfemError as exc:
                others = ", ".join(f"{q.key}={_num(q.value(0.5))}" for q in params if q is not p)
                raise NsfemError(f"--vary {p.key}={_num(p.low)}:{_num(p.high)}: at {p.key}={_num(p.value(u))}"
                                 + (f" (with {others})" if others else "") + f": {exc}") from None
    shared = all(p.key.split(".")[0] in SHARED_TABLES for p in params)
    return Problem(scene_path, params, m, tuple(columns), misfit, tuple(fixed), shared, base)


@dataclass(frozen=True)
class Alternative:
    """A second minimum of the misfit, far from the estimate: its point ``u`` (unit box), ``estimate``
    (physical values), ``misfit``, the F-test against the estimate (``F`` = RSS ratio with the
    floor of :data:`RESOLUTION`, ``p_value``) and ``differs``: per parameter, whether its value lies
    outside the estimate's interval and more than :data:`DISTINCT` of its range away."""

    u: np.ndarray
    estimate: np.ndarray
    misfit: float
    F: float
    p_value: float
    differs: np.ndarray

    @property
    def indistinguishable(self) -> bool:
        """Whether the data cannot tell it from the estimate (F-test p-value >= :data:`SAME_FIT`)."""
        return bool(self.p_value >= SAME_FIT)


class FitInterrupted(KeyboardInterrupt):
    """Ctrl-C (or SIGTERM from the command line) during a fit: ``result`` holds the best run so far,
    its evaluations already written to the output folder."""

    def __init__(self, result: "FitResult"):
        super().__init__(f"fit interrupted; the runs so far are in {result.out_dir}")
        self.result = result


@dataclass(frozen=True)
class FitResult:
    """A fit: the ``estimate`` (physical values), its ``misfit``, the statistics (None when the fit was
    interrupted before its end), every run, the signals fitted and measured, the files written."""

    params: tuple[Parameter, ...]
    estimate: np.ndarray
    misfit: float
    kind: str
    data: Measurement
    fitted: np.ndarray | None
    evaluations: tuple[Evaluation, ...]
    uncertainty: object | None
    out_dir: Path
    outputs: tuple[str, ...] = ()
    info: dict = field(default_factory=dict)
    alternatives: tuple[Alternative, ...] = ()
    warnings: tuple[str, ...] = ()

    @property
    def keys(self) -> list[str]:
        return [p.key for p in self.params]

    @property
    def interval(self) -> np.ndarray:
        """(p, 2) 95 % intervals in the keys' units (NaN without statistics)."""
        if self.uncertainty is None:
            return np.full((len(self.params), 2), np.nan)
        width = np.array([p.high - p.low for p in self.params])
        low = np.array([p.low for p in self.params])
        return low[:, None] + self.uncertainty.interval * width[:, None]

    @property
    def at_bound(self) -> np.ndarray:
        """Per parameter, whether the estimate lies within :data:`AT_BOUND` of its range's width of an end."""
        return np.array([min(x - p.low, p.high - x) <= AT_BOUND * (p.high - p.low)
                         for p, x in zip(self.params, self.estimate)])

    @property
    def ambiguous(self) -> np.ndarray:
        """Per parameter, whether a second minimum the data cannot tell from the estimate puts it
        elsewhere (its interval is then not a confident statement: the data allow both)."""
        out = np.zeros(len(self.params), dtype=bool)
        for alt in self.alternatives:
            if alt.indistinguishable:
                out |= alt.differs
        return out

    @property
    def identified(self) -> np.ndarray:
        """Per parameter, whether its interval is narrower than its whole range and no equally good
        second minimum puts it elsewhere."""
        if self.uncertainty is None:
            return np.zeros(len(self.params), dtype=bool)
        return ~self.uncertainty.spans_range & ~self.ambiguous

    @property
    def identifiable(self) -> bool | None:
        """Whether the data determine every key (None without statistics)."""
        return None if self.uncertainty is None else bool(np.all(self.identified))

    @property
    def identifiable_reason(self) -> str | None:
        """Why the data do not determine every key, naming them (None when they do)."""
        if self.uncertainty is None:
            return None
        why = []
        unseen = [p.key for p, s in zip(self.params, self.uncertainty.spans_range) if s]
        if unseen:
            why.append(f"the data do not determine {', '.join(unseen)} (interval spans the range)")
        for alt in self.alternatives:
            if alt.indistinguishable:
                keys = [p.key for p, d in zip(self.params, alt.differs) if d]
                why.append(f"a second minimum at {_values(self.params, alt.estimate)} (misfit {100 * alt.misfit:.3g} % "
                           f"against {100 * self.misfit:.3g} %) explains the data as well (F-test p = "
                           f"{alt.p_value:.3g}): the data cannot tell {', '.join(keys)} there from here")
        return "; ".join(why) or None

    def to_json(self) -> dict:
        """design.md section 8's JSON, plus ``correlation``, ``identifiability``, ``global_stage`` and more."""
        from .analysis.uncertainty import RANK_RTOL

        keys = self.keys
        unc = self.uncertainty
        params = {}
        for p, x, iv, b, ok, amb in zip(self.params, self.estimate, self.interval, self.at_bound, self.identified,
                                        self.ambiguous):
            params[p.key] = {"estimate": float(x), "interval": [_finite(iv[0]), _finite(iv[1])],
                             "at_bound": bool(b), "identified": bool(ok), "ambiguous": bool(amb),
                             "range": [p.low, p.high]}
        glob = [e for e in self.evaluations if e.stage == "global"]
        payload = {
            "parameters": params, "misfit": _finite(self.misfit), "misfit_kind": self.kind, "runs": len(self.evaluations),
            "wall_s": self.info.get("wall_s"), "outputs": list(self.outputs), "sensors": list(self.data.names),
            "samples": int(self.data.t.size), "out": str(self.out_dir),
            "identifiable": self.identifiable, "identifiable_reason": self.identifiable_reason,
            "alternatives": [{"parameters": {p.key: float(x) for p, x in zip(self.params, a.estimate)},
                              "misfit": _finite(a.misfit), "F": _finite(a.F), "p_value": _finite(a.p_value),
                              "indistinguishable": a.indistinguishable,
                              "differs": [p.key for p, d in zip(self.params, a.differs) if d]}
                             for a in self.alternatives],
            "warnings": list(self.warnings),
            "correlation": None, "identifiability": None,
            "global_stage": {"keys": keys, "samples": [[p.value(x) for p, x in zip(self.params, e.u)] for e in glob],
                             "misfit": [_finite(e.misfit) for e in glob]},
            **{k: v for k, v in self.info.items() if k != "wall_s"}}
        if unc is not None:
            payload["correlation"] = {"keys": keys, "matrix": [[_finite(c) for c in row] for row in unc.correlation]}
            payload["identifiability"] = {
                "rank": unc.rank, "singular_values": [float(s) for s in unc.singular],
                "rank_tolerance": RANK_RTOL, "residual_variance": _finite(unc.s2), "dof": unc.dof,
                "t_quantile": _finite(unc.t),
                "not_identified": [k for k, ok in zip(keys, self.identified) if not ok],
                "directions": [{"reason": w.reason, "singular_value": w.singular_value,
                                "components": {k: float(c) for k, c in zip(keys, w.direction)},
                                "keys": [keys[i] for i in w.dominant()]} for w in unc.weak]}
        return payload


def _finite(x) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


# --------------------------------------------------------------------------- running
class _Runner:
    """Submits runs to the cluster, caches them by point, keeps every evaluation in order of arrival."""

    def __init__(self, problem: Problem, cl, say: Callable[[str], None]):
        self.problem, self.cl, self.say = problem, cl, say
        self.cache: dict[bytes, Evaluation] = {}
        self.evaluations: list[Evaluation] = []
        self.pending: list = []
        self.scale = scales(problem.data, problem.kind)
        self.shared = None
        if problem.shared:
            from .fem.assemble import build_model
            from .reduce import scene_reduction

            model = build_model(problem.base)
            [self.shared] = cl.scatter([(model, scene_reduction(problem.base.reduction, model))], broadcast=True,
                                       hash=False)

    def run(self, us: Sequence[np.ndarray], stage: str, report: bool = False) -> list[Evaluation]:
        """The evaluations at ``us`` (the new ones submitted together)."""
        from distributed import as_completed

        p = self.problem
        futures = {}
        for u in us:
            k = np.asarray(u, float).tobytes()
            if k in self.cache or any(k == kk for kk in futures.values()):
                continue
            try:
                scene = p.scene(u)
            except NsfemError as exc:  # a combination of values the scene refuses (start past end, say)
                self._keep(k, Evaluation(np.array(u, float), stage, math.inf, error=str(exc)), report)
                continue
            fut = self.cl.submit(run_signals, scene, self.shared, p.data.t, p.columns,
                                 key=f"nsfem-fit-{uuid.uuid4().hex}", pure=False)
            futures[fut] = k
        self.pending = list(futures)
        for fut in as_completed(list(futures), loop=self.cl.loop):
            k = futures[fut]
            u = np.frombuffer(k)
            try:
                signals, error = fut.result()
            except Exception as exc:  # noqa: BLE001 - a lost worker
                signals, error = None, f"{type(exc).__name__}: {exc}"
            if signals is None:
                ev = Evaluation(u, stage, math.inf, error=error)
            else:
                r = residuals(signals, p.data, p.kind, self.scale)
                ev = Evaluation(u, stage, relative_rms(r), r, signals)
            self._keep(k, ev, report)
        self.pending = []
        return [self.cache[np.asarray(u, float).tobytes()] for u in us]

    def _keep(self, k: bytes, ev: Evaluation, report: bool) -> None:
        self.cache[k] = ev
        self.evaluations.append(ev)
        if report:
            self.say(f"[{ev.stage} {len(self.evaluations)}] {_point(self.problem.params, ev.u)}: "
                     + (f"failed: {ev.error}" if ev.error else f"misfit {100 * ev.misfit:.4g} %"))

    def cancel(self) -> None:
        try:
            self.cl.cancel([f for f in self.pending if not f.done()])
        except Exception:  # noqa: BLE001 - the cluster may be going away too
            pass


def _point(params, u) -> str:
    return ", ".join(f"{p.key}={p.value(x):.6g}" for p, x in zip(params, u))


def _values(params, x) -> str:
    return ", ".join(f"{p.key}={v:.6g}" for p, v in zip(params, x))


def _steps(u: np.ndarray) -> np.ndarray:
    """Per parameter, the forward step (backward at the upper end of the box)."""
    return np.where(u + STEP <= 1.0, STEP, -STEP)


def _perturbed(u: np.ndarray) -> list[np.ndarray]:
    h = _steps(u)
    out = []
    for i in range(u.size):
        v = u.copy()
        v[i] += h[i]
        out.append(v)
    return out


def _residual_vector(ev: Evaluation, n: int) -> np.ndarray:
    return ev.residuals if ev.residuals is not None else np.full(n, FAILED_RESIDUAL)


def local_stage(runner: _Runner, u0: np.ndarray, speculate: bool, max_nfev: int,
                stage: str = "local") -> tuple[np.ndarray, np.ndarray, np.ndarray, object]:
    """least_squares from ``u0`` in the unit box; (u, residuals, Jacobian at u, scipy's result); its
    runs are labelled ``stage``."""
    from scipy.optimize import least_squares

    n = runner.problem.data.values.size
    params = runner.problem.params

    def fun(u):
        batch = [u, *_perturbed(u)] if speculate else [u]
        ev = runner.run(batch, stage)[0]
        runner.say(f"[{stage} {len(runner.evaluations)} runs] {_point(params, u)}: "
                   + (f"failed: {ev.error}" if ev.error else f"misfit {100 * ev.misfit:.4g} %"))
        return _residual_vector(ev, n)

    def jac(u):
        r0 = _residual_vector(runner.run([u], stage)[0], n)
        evs = runner.run(_perturbed(u), stage)
        h = _steps(u)
        return np.column_stack([(_residual_vector(e, n) - r0) / hi for e, hi in zip(evs, h)])

    sol = least_squares(fun, u0, jac=jac, bounds=(0.0, 1.0), method="trf", x_scale=1.0, xtol=1e-10, ftol=1e-10,
                        gtol=1e-10, max_nfev=max_nfev)
    u = np.clip(sol.x, 0.0, 1.0)
    return u, _residual_vector(runner.run([u], stage)[0], n), jac(u), sol


def second_start(evaluations: Sequence[Evaluation], u: np.ndarray) -> Evaluation | None:
    """The global sample that starts a second local stage: the best of those within
    :data:`CANDIDATE_FACTOR` of the best sample's misfit that lie at least :data:`SEPARATION` of a
    range (for some key) from the estimate ``u``; None when there is none (one basin)."""
    ok = [e for e in evaluations if e.stage == "global" and math.isfinite(e.misfit)]
    if not ok:
        return None
    best = min(e.misfit for e in ok)
    far = [e for e in ok if e.misfit <= CANDIDATE_FACTOR * best and np.max(np.abs(e.u - u)) >= SEPARATION]
    return min(far, key=lambda e: e.misfit) if far else None


def alternative(params: Sequence[Parameter], u: np.ndarray, r: np.ndarray, unc, u2: np.ndarray,
                r2: np.ndarray) -> Alternative | None:
    """The minimum ``u2`` (residuals ``r2``) as an alternative to the estimate ``u`` (``r``, statistics
    ``unc``), None when it is the same minimum (every key within :data:`DISTINCT` of its range or
    inside the estimate's interval)."""
    from .analysis.uncertainty import same_fit

    iv = unc.interval
    differs = (np.abs(u2 - u) > DISTINCT) & ((u2 < iv[:, 0]) | (u2 > iv[:, 1]))
    if not np.any(differs):
        return None
    F, pv = same_fit(float(r @ r), float(r2 @ r2), r.size, len(params), RESOLUTION)
    return Alternative(np.array(u2, float), np.array([q.value(x) for q, x in zip(params, u2)]), relative_rms(r2),
                       F, pv, differs)


def residual_check(r: np.ndarray, names: Sequence[str], kind: str, misfit: float) -> tuple[dict | None, str | None]:
    """({sensor: lag-1 autocorrelation, bound}, a warning or None) of the residuals at the estimate
    (:func:`nsfem.analysis.uncertainty.whiteness`, time misfit only: a spectrum's bins are correlated
    by its window). It warns when some sensor's residuals are structured and the misfit is above
    :data:`RESOLUTION`: a fit to round-off (noise-free data from the same model) leaves structured
    but negligible residuals and is not warned about."""
    from .analysis.uncertainty import whiteness

    if kind != "time" or r is None:
        return None, None
    w = whiteness(r, len(names), WHITE_LEVEL)
    stats = {"lag1_autocorrelation": {n: float(x) for n, x in zip(names, w.rho)}, "bound": w.bound,
             "structured": [n for n, s in zip(names, w.structured) if s]}
    if not (np.any(w.structured) and misfit > RESOLUTION):
        return stats, None
    rhos = ", ".join(f"{n} {x:.3g}" for n, x, s in zip(names, w.rho, w.structured) if s)
    return stats, (f"the residuals are structured, not noise-like (lag-1 autocorrelation {rhos} above "
                   f"{w.bound:.3g}, the bound for white noise; misfit {100 * misfit:.3g} %): the estimate may be a "
                   "local minimum or the model cannot explain the data (try more global samples, other starts or "
                   "ranges, or check the scene)")


def default_folder(problem: Problem) -> Path:
    """``<output.dir>/fit-<varied keys>``."""
    return problem.base.output.dir / ("fit-" + ",".join(p.key for p in problem.params))


def fit(scene_path, data, vary, misfit: str = "time", client=None, workers: int | None = None,
        scheduler: str | None = None, n_global: int | None = None, start: Mapping[str, float] | None = None,
        overrides: Sequence[str] = (), out_dir=None, seed: int = 0, max_nfev: int = 40,
        progress: Callable[[str], None] | None = None, plot: bool = True) -> FitResult:
    """Estimate the keys of ``vary`` ({key: (low, high)} or ``KEY=LOW:HIGH`` texts) from ``data``
    (a CSV path or (t, {sensor name: samples})); see the module's text.

    ``n_global`` Sobol samples (rounded up to a power of 2; default 2^(3 + p), at most 256; 0 skips the
    global stage); ``start`` {key: value} starts the local stage there instead of at the best sample
    (default without a global stage: the middle of the box). ``client``, ``workers``, ``scheduler``: as
    :func:`nsfem.sweep.run_sweep`. ``progress(line)`` receives a line per run of the global stage and
    per step of the local one. Ctrl-C writes the runs so far and raises :class:`FitInterrupted`.
    """
    from .analysis.uncertainty import linearized
    from .sweep import _client, _close, _hold_signals, _release_signals

    if workers is not None and (scheduler or client is not None):
        raise NsfemError("--workers cannot be combined with --scheduler (the cluster has its own workers)")
    if workers is not None and workers < 1:
        raise NsfemError(f"--workers must be a positive integer, got {workers}")
    t0 = time.perf_counter()
    problem = prepare(scene_path, data, vary, misfit, overrides)
    params, p = problem.params, len(problem.params)
    if n_global is None:
        n_global = min(256, 2 ** (3 + p))
    if n_global < 0:
        raise NsfemError(f"n_global must be 0 or more, got {n_global}")
    u_start = None
    if start is not None:
        unknown = [k for k in start if k not in {q.key for q in params}]
        if unknown:
            raise NsfemError(f"start: {unknown[0]} is not varied")
        u_start = np.array([(float(start.get(q.key, q.value(0.5))) - q.low) / (q.high - q.low) for q in params])
        if np.any((u_start < 0) | (u_start > 1)) or not np.all(np.isfinite(u_start)):
            raise NsfemError("start: every value must lie in its key's range")
    out = (Path(out_dir) if out_dir is not None else default_folder(problem)).absolute()
    check_folder(out, "--out")
    say = progress or (lambda line: None)
    cl, closing, runner = None, [], None
    info: dict = {"workers": 0, "seed": seed, "global_samples": 0}
    try:
        cl, closing = _client(client, workers, scheduler, max(n_global, p + 1))
        info["workers"] = len(cl.nthreads())
        runner = _Runner(problem, cl, say)
        best = None
        if n_global:
            from scipy.stats import qmc

            m = max(0, math.ceil(math.log2(n_global)))
            design = qmc.Sobol(d=p, scramble=True, seed=seed).random_base2(m)
            info["global_samples"] = len(design)
            say(f"global stage: {len(design)} runs over the box ({', '.join(f'{q.key} {q.low:g}..{q.high:g}' for q in params)})")
            evs = runner.run(list(design), "global", report=True)
            ok = [e for e in evs if math.isfinite(e.misfit)]
            if not ok:
                raise NsfemError(f"every run of the global stage failed (first: {evs[0].error})")
            best = min(ok, key=lambda e: e.misfit)
        u0 = u_start if u_start is not None else (best.u if best is not None else np.full(p, 0.5))
        say(f"local stage from {_point(params, u0)}")
        u, r, J, sol = local_stage(runner, np.array(u0, float), info["workers"] > 1, max_nfev)
        info["local"] = {"nfev": int(sol.nfev), "njev": int(sol.njev or 0), "status": int(sol.status),
                         "message": str(sol.message)}
        unc = linearized(J, r, u)
        alternatives = []
        cand = second_start(runner.evaluations, u)
        if cand is not None:
            say(f"second local stage from {_point(params, cand.u)} (misfit {100 * cand.misfit:.4g} %, far from "
                "the estimate: another basin?)")
            u2, r2, J2, sol2 = local_stage(runner, np.array(cand.u, float), info["workers"] > 1, max_nfev, "second")
            info["second_local"] = {"start": {q.key: q.value(x) for q, x in zip(params, cand.u)},
                                    "nfev": int(sol2.nfev), "njev": int(sol2.njev or 0), "status": int(sol2.status),
                                    "message": str(sol2.message)}
            if relative_rms(r2) < relative_rms(r):      # the better minimum is the estimate
                u, r, J, u2, r2 = u2, r2, J2, u, r
                unc = linearized(J, r, u)
            alt = alternative(params, u, r, unc, u2, r2)
            if alt is not None:
                alternatives.append(alt)
                say(f"second minimum at {_point(params, u2)}: misfit {100 * alt.misfit:.4g} %, F-test p = "
                    f"{alt.p_value:.3g}" + (" (as good as the estimate)" if alt.indistinguishable else ""))
        ev = runner.run([u], "local")[0]
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
        info["residuals"] = stats
    if warning:
        say(f"warning: {warning}")
    info["wall_s"] = time.perf_counter() - t0
    res = FitResult(params, est, ev.misfit, misfit, problem.data, ev.signals, tuple(runner.evaluations), unc, out,
                    info=info, alternatives=tuple(alternatives), warnings=(warning,) if warning else ())
    return _write(res, plot=plot)


def _partial(problem: Problem, runner: _Runner | None, out: Path, info: dict, t0: float) -> FitResult:
    """The best run so far as a result without statistics."""
    evs = tuple(runner.evaluations) if runner is not None else ()
    ok = [e for e in evs if math.isfinite(e.misfit)]
    best = min(ok, key=lambda e: e.misfit) if ok else None
    u = best.u if best is not None else np.full(len(problem.params), np.nan)
    est = np.array([q.low + x * (q.high - q.low) for q, x in zip(problem.params, u)])
    info["wall_s"] = time.perf_counter() - t0
    return FitResult(problem.params, est, best.misfit if best else math.nan, problem.kind, problem.data,
                     best.signals if best else None, evs, None, out, info=info)


# --------------------------------------------------------------------------- outputs
def evaluations_csv(res: FitResult) -> str:
    """Every run in order: stage, the keys' values, misfit (empty when failed), error."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["run", "stage", *res.keys, "misfit", "error"])
    for i, e in enumerate(res.evaluations):
        w.writerow([i + 1, e.stage, *(repr(q.value(x)) for q, x in zip(res.params, e.u)),
                    repr(e.misfit) if math.isfinite(e.misfit) else "", " ".join(e.error.split())])
    return buf.getvalue()


def _write(res: FitResult, plot: bool = True) -> FitResult:
    """Write evaluations.csv, the PNGs (``plot``) and fit.json (last, listing them) atomically."""
    import dataclasses
    import json

    from .sweep import _default

    out = res.out_dir
    outputs = [str(write_text_atomic(out / "evaluations.csv", evaluations_csv(res)))]
    if plot:
        from .plot.fit import fit_plot, landscape_plot

        if res.fitted is not None:
            outputs.append(str(fit_plot(out / "fit.png", res.data.t, res.data.values, res.fitted, res.data.names,
                                        res.misfit)))
        glob = [e for e in res.evaluations if e.stage == "global"]
        if glob:
            x = np.array([[q.value(v) for q, v in zip(res.params, e.u)] for e in glob])
            outputs.append(str(landscape_plot(out / "landscape.png", res.keys, x, np.array([e.misfit for e in glob]),
                                              res.estimate)))
    res = dataclasses.replace(res, outputs=tuple([str(out / "fit.json"), *outputs]))
    write_text_atomic(out / "fit.json", json.dumps(res.to_json(), indent=1, default=_default) + "\n")
    return res
