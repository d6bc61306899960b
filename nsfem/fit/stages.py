"""The fit's stages: runs submitted to the cluster, least squares from a start, a second basin, the
residuals' check."""

from __future__ import annotations

import math
import uuid
from typing import Callable, Sequence

import numpy as np

from ..errors import NsfemError
from ..measurement import relative_rms, residuals, scales
from .problem import Evaluation, Parameter, Problem, run_signals
from .result import SAME_FIT, Alternative

#: finite-difference step of the Jacobian in the unit box (1e-4 of a range)
STEP = 1e-4
#: residual of every sample of a failed run: a relative misfit of 1000 %, worse than any fit
FAILED_RESIDUAL = 10.0
#: a global sample within this factor of the best sample's misfit, and at least SEPARATION (of a
#: range, for some key) from the estimate, starts a second local stage: a second basin
CANDIDATE_FACTOR = 2.0
SEPARATION = 0.25
#: at most this many zoomed designs, about the minima in order of misfit, while the best minimum's
#: residuals are structured (:func:`residual_check`: a local minimum, or a model that cannot explain the data)
RESTARTS = 2
#: half-width (of each range) of the zoomed design about a structured minimum. Contact dynamics make
#: the misfit rugged: a local stage can stop in a local minimum a few hundredths of a range from a
#: truth whose basin is about as narrow (the delamination falling from rest: 0.017 and 0.014 m off
#: for ranges of 0.3 m, a basin about 0.01 m wide), which a global design over the whole box misses
ZOOM = 0.1
#: the most runs of one zoomed design (the global stage's cap is 256)
ZOOM_SAMPLES = 64
#: a mirror image nearer the estimate than this (of a range, every key) is the estimate's own basin: a
#: basin of contact dynamics is a few hundredths of a range wide (see ZOOM)
MIRROR_SEPARATION = 0.05
#: a second minimum that lies within this fraction of every range from the estimate is the same one
DISTINCT = 0.01
#: relative RMS misfit below which residuals are resolution, not information: the optimizer stops
#: within its tolerance of a minimum whose misfit is rugged (noise-free data from the same model:
#: 3e-5 measured from rest, 1e-11 from a stationary state), and no measurement we know of is
#: accurate to 0.1 % of its RMS. The F-test's floor; no residual warning below it
RESOLUTION = 1e-3
#: family-wise false-alarm rate of the residuals' whiteness test over the sensors
WHITE_LEVEL = 0.01


class _Runner:
    """Submits runs to the cluster, caches them by point, keeps every evaluation in order of arrival."""

    def __init__(self, problem: Problem, cl, say: Callable[[str], None]):
        self.problem, self.cl, self.say = problem, cl, say
        self.cache: dict[bytes, Evaluation] = {}
        self.evaluations: list[Evaluation] = []
        self.pending: list = []
        self.scale = scales(problem.data, problem.kind)
        #: the length of every run's residuals (a failed run's too): the data's, in the misfit's domain
        self.n = residuals(problem.data.values, problem.data, problem.kind, self.scale).size
        self.shared = None
        if problem.shared:
            from ..fem.assemble import build_model
            from ..reduce import scene_reduction

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
            fut = self._submit(scene, self.shared)
            futures[fut] = k
            self.pending.append(fut)     # cancelled on Ctrl-C even while the others are being submitted
        for fut in as_completed(list(futures), loop=self.cl.loop):
            k = futures[fut]
            self._keep(k, self._evaluation(fut, np.frombuffer(k), stage), report)
        self.pending = []
        return [self.cache[np.asarray(u, float).tobytes()] for u in us]

    def run_refined(self, us: Sequence[np.ndarray], overrides: Sequence[str], stage: str = "refined") -> list[Evaluation]:
        """The runs at ``us`` (submitted together) with the extra ``overrides`` (a refined model: built
        on the worker, never the shared one, and not cached by point), kept as ``stage``."""
        from distributed import as_completed

        evs: dict[int, Evaluation] = {}
        futures = {}
        for i, u in enumerate(us):
            try:
                scene = self.problem.scene(u, overrides)
            except NsfemError as exc:
                evs[i] = Evaluation(np.array(u, float), stage, math.inf, error=str(exc))
                self.evaluations.append(evs[i])
                continue
            fut = self._submit(scene, None)
            futures[fut] = i
            self.pending.append(fut)
        for fut in as_completed(list(futures), loop=self.cl.loop):
            i = futures[fut]
            evs[i] = self._evaluation(fut, np.array(us[i], float), stage)
            self.evaluations.append(evs[i])      # kept as it arrives: Ctrl-C loses no finished run
        self.pending = []
        return [evs[i] for i in range(len(us))]

    def _submit(self, scene, shared):
        p = self.problem
        return self.cl.submit(run_signals, scene, shared, p.data.t, p.columns, key=f"nsfem-fit-{uuid.uuid4().hex}",
                              pure=False)

    def _evaluation(self, fut, u: np.ndarray, stage: str) -> Evaluation:
        p = self.problem
        try:
            signals, error = fut.result()
        except Exception as exc:  # noqa: BLE001 - a lost worker
            signals, error = None, f"{type(exc).__name__}: {exc}"
        if signals is None:
            return Evaluation(u, stage, math.inf, error=error or "the run failed without a message")
        with np.errstate(over="ignore", invalid="ignore"):
            r = residuals(signals, p.data, p.kind, self.scale)
            misfit = relative_rms(r)
        if not math.isfinite(misfit):
            return Evaluation(u, stage, math.inf, error="the simulated signals or their misfit are not finite "
                              f"(largest simulated magnitude {np.nanmax(np.abs(signals), initial=0.0):.3g} m): "
                              "the run diverged")
        return Evaluation(u, stage, misfit, r, signals)

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


def _steps(u: np.ndarray) -> np.ndarray:
    """Per parameter, the forward step (backward at the upper end of the box)."""
    return np.where(u + STEP <= 1.0, STEP, -STEP)


def jacobian(r0: np.ndarray, evs: Sequence[Evaluation], u: np.ndarray, n: int) -> np.ndarray:
    """Forward differences (N, p) from the residuals ``r0`` at ``u`` and the runs ``evs`` at :func:`_perturbed` (u)."""
    return np.column_stack([(_residual_vector(e, n) - r0) / hi for e, hi in zip(evs, _steps(u))])


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

    n = runner.n
    params = runner.problem.params

    def fun(u):
        batch = [u, *_perturbed(u)] if speculate else [u]
        ev = runner.run(batch, stage)[0]
        runner.say(f"[{stage} {len(runner.evaluations)} runs] {_point(params, u)}: "
                   + (f"failed: {ev.error}" if ev.error else f"misfit {100 * ev.misfit:.4g} %"))
        return _residual_vector(ev, n)

    def jac(u):
        r0 = _residual_vector(runner.run([u], stage)[0], n)
        return jacobian(r0, runner.run(_perturbed(u), stage), u, n)

    sol = least_squares(fun, u0, jac=jac, bounds=(0.0, 1.0), method="trf", x_scale=1.0, xtol=1e-10, ftol=1e-10,
                        gtol=1e-10, max_nfev=max_nfev)
    u = np.clip(sol.x, 0.0, 1.0)
    return u, _residual_vector(runner.run([u], stage)[0], n), jac(u), sol


def second_start(evaluations: Sequence[Evaluation], found: Sequence[np.ndarray],
                 used: Sequence[np.ndarray] = ()) -> Evaluation | None:
    """The global sample that starts a further local stage: the best of those within
    :data:`CANDIDATE_FACTOR` of the best sample's misfit (another basin as good as the first) that lie
    at least :data:`SEPARATION` of a range (for some key) from every minimum ``found`` and every start
    ``used`` before; None when there is none."""
    ok = [e for e in evaluations if e.stage == "global" and math.isfinite(e.misfit)]
    if not ok:
        return None
    best = min(e.misfit for e in ok)
    away = [*found, *used]
    far = [e for e in ok if e.misfit <= CANDIDATE_FACTOR * best
           and all(np.max(np.abs(e.u - v)) >= SEPARATION for v in away)]
    return min(far, key=lambda e: e.misfit) if far else None


def sobol(p: int, n: int, seed: int) -> np.ndarray:
    """A scrambled Sobol design (scipy.stats.qmc, seeded) of 2^ceil(log2 n) points in the unit box of
    dimension ``p``."""
    from scipy.stats import qmc

    return qmc.Sobol(d=p, scramble=True, seed=seed).random_base2(max(0, math.ceil(math.log2(n))))


def zoomed(u: np.ndarray, n: int, seed: int) -> np.ndarray:
    """:func:`sobol`'s design of ``n`` points in the box ``u`` +- :data:`ZOOM`, clipped to the unit box."""
    low, high = np.clip(u - ZOOM, 0.0, 1.0), np.clip(u + ZOOM, 0.0, 1.0)
    return low + sobol(u.size, n, seed) * (high - low)


def mirror_point(params: Sequence[Parameter], u: np.ndarray, extent: tuple[float, float]) -> np.ndarray | None:
    """The point ``u`` reflected about the middle of the shaft (``extent`` = (a, b)): x -> a + b - x for
    the position ``x`` of an item (crack, disk, unbalance, bearing, obstacle, stator; not a sensor),
    (start, end) -> (a + b - end, a + b - start) for a delamination whose two ends are both varied;
    the other keys as they are. A shaft symmetric about its middle (supports, sections) sees a defect
    and its mirror image alike but through the sensors and loads, so the image is where a second
    minimum as good as the estimate is most likely (a crack seen by probes near mid-span). None when
    no key is a position, a reflected value leaves its range, or the image lies within
    :data:`MIRROR_SEPARATION` of ``u`` (a defect at the middle: the image is the estimate).

    >>> from nsfem.fit.problem import Parameter
    >>> ps = (Parameter("crack.0.x", 0.1, 0.7), Parameter("crack.0.depth", 0.1, 0.5))
    >>> mirror_point(ps, np.array([0.5, 0.25]), (0.0, 0.8)) is None   # x = 0.4: its own image
    True
    >>> np.round(mirror_point(ps, np.array([1 / 6, 0.25]), (0.0, 0.8)), 6).tolist()   # x = 0.2 -> 0.6
    [0.833333, 0.25]
    """
    a, b = extent
    values = np.array([q.value(x) for q, x in zip(params, u)])
    out = values.copy()
    index = {q.key: i for i, q in enumerate(params)}
    moved = False
    for i, q in enumerate(params):
        table, _, rest = q.key.partition(".")
        item, _, field = rest.partition(".")
        if field == "x" and table != "sensor":
            out[i] = a + b - values[i]
            moved = True
        elif table == "delamination" and field == "start" and f"delamination.{item}.end" in index:
            j = index[f"delamination.{item}.end"]
            out[i], out[j] = a + b - values[j], a + b - values[i]
            moved = True
    if not moved:
        return None
    low = np.array([q.low for q in params])
    width = np.array([q.high - q.low for q in params])
    v = (out - low) / width
    if np.any(v < -1e-12) or np.any(v > 1.0 + 1e-12) or np.max(np.abs(v - u)) < MIRROR_SEPARATION:
        return None
    return np.clip(v, 0.0, 1.0)


def alternative(params: Sequence[Parameter], u: np.ndarray, r: np.ndarray, interval: np.ndarray, u2: np.ndarray,
                r2: np.ndarray) -> Alternative | None:
    """The minimum ``u2`` (residuals ``r2``) as an alternative to the estimate ``u`` (``r``, its reported
    ``interval`` (p, 2) in the unit box, the discretization shift included), None when it is the same
    minimum (every key within :data:`DISTINCT` of its range or inside the estimate's interval). When the
    data cannot tell it from the estimate, every key it puts outside the interval differs, however near:
    the interval would promise what the data do not say (a delamination's start 2.8 mm from an interval
    0.6 mm wide, its end 7 mm away, F-test p = 0.35)."""
    from ..analysis.uncertainty import same_fit

    iv = interval
    outside = (u2 < iv[:, 0]) | (u2 > iv[:, 1])
    differs = (np.abs(u2 - u) > DISTINCT) & outside
    if not np.any(differs):
        return None
    F, pv = same_fit(float(r @ r), float(r2 @ r2), r.size, len(params), RESOLUTION)
    if pv >= SAME_FIT:
        differs = outside
    return Alternative(np.array(u2, float), np.array([q.value(x) for q, x in zip(params, u2)]), relative_rms(r2),
                       F, pv, differs)


def residual_check(r: np.ndarray, names: Sequence[str], kind: str, misfit: float) -> tuple[dict | None, str | None]:
    """({sensor: lag-1 autocorrelation, bound}, a warning or None) of the residuals at the estimate
    (:func:`nsfem.analysis.uncertainty.whiteness`, time misfit only: a spectrum's bins are correlated
    by its window). It warns when some sensor's residuals are structured and the misfit is above
    :data:`RESOLUTION`: a fit to round-off (noise-free data from the same model) leaves structured
    but negligible residuals and is not warned about."""
    from ..analysis.uncertainty import whiteness

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


def noise_statistics(unc, J: np.ndarray, r: np.ndarray, u: np.ndarray, names: Sequence[str], kind: str,
                     misfit: float) -> tuple[object, np.ndarray]:
    """The linearized statistics ``unc`` at ``u`` with the autocorrelation of structured residuals
    taken in (:func:`nsfem.analysis.uncertainty.correlated`: a smooth residual carries fewer independent
    samples than it has, and the white-noise interval would claim them all), and each sensor's
    autocorrelation time (1 for white ones). As :func:`residual_check`: time misfit only, and only
    above :data:`RESOLUTION` (a fit to round-off is floored there instead)."""
    from ..analysis.uncertainty import correlated, whiteness

    ones = np.ones(len(names))
    if kind != "time" or r is None or not misfit > RESOLUTION:
        return unc, ones
    return correlated(unc, J, r, u, len(names), whiteness(r, len(names), WHITE_LEVEL).structured)
