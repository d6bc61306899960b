"""A fit's result: estimates, intervals, identifiability, alternatives; its files."""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..atomic import write_text_atomic
from ..measurement import Measurement
from .discretization import Discretization, reported
from .problem import Evaluation, Parameter

#: an estimate within this fraction of its range's width from an end sits on the bound
AT_BOUND = 1e-3
#: p-value at or above which two minima explain the data equally well (the F-test at 95 %)
SAME_FIT = 0.05


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
    discretization: Discretization | None = None

    @property
    def keys(self) -> list[str]:
        return [p.key for p in self.params]

    @property
    def unit_interval(self) -> np.ndarray:
        """(p, 2) 95 % intervals in the unit box: the noise interval widened by the discretization shift,
        the whole range where the fit has no interval to promise (:func:`nsfem.fit.discretization.reported`;
        NaN without statistics)."""
        if self.uncertainty is None:
            return np.full((len(self.params), 2), np.nan)
        return reported(self.uncertainty.interval, self.discretization)

    @property
    def interval(self) -> np.ndarray:
        """(p, 2) 95 % intervals in the keys' units, the model's discretization error included (NaN
        without statistics)."""
        return self._physical(self.unit_interval)

    @property
    def noise_interval(self) -> np.ndarray:
        """(p, 2) 95 % intervals from the noise alone (the linearized statistics, structured residuals'
        autocorrelation included), in the keys' units."""
        if self.uncertainty is None:
            return np.full((len(self.params), 2), np.nan)
        return self._physical(self.uncertainty.interval)

    @property
    def discretization_shift(self) -> np.ndarray:
        """(p,) the shift of the estimate a refined model gives, in the keys' units (NaN when not measured)."""
        d = self.discretization
        if d is None or d.error:
            return np.full(len(self.params), np.nan)
        return d.shift * np.array([p.high - p.low for p in self.params])

    def _physical(self, unit: np.ndarray) -> np.ndarray:
        width = np.array([p.high - p.low for p in self.params])
        low = np.array([p.low for p in self.params])
        return low[:, None] + unit * width[:, None]

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
        return ~self._spans_range & ~self.ambiguous

    @property
    def _spans_range(self) -> np.ndarray:
        iv = self.unit_interval
        return (iv[:, 0] <= 0.0) & (iv[:, 1] >= 1.0)

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
        d = self.discretization
        lost = np.zeros(len(self.params), bool)
        if d is not None and not d.error and d.no_interval is not None:
            lost = d.no_interval
        if lost.any():
            why.append(f"no interval for {', '.join(p.key for p, x in zip(self.params, lost) if x)} "
                       f"({d.no_interval_reason})")
        unseen = [p.key for p, s, x in zip(self.params, self._spans_range, lost) if s and not x]
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
        from ..analysis.uncertainty import RANK_RTOL

        keys = self.keys
        unc = self.uncertainty
        params = {}
        for p, x, iv, ni, d, b, ok, amb in zip(self.params, self.estimate, self.interval, self.noise_interval,
                                               self.discretization_shift, self.at_bound, self.identified, self.ambiguous):
            params[p.key] = {"estimate": _finite(x), "interval": [_finite(iv[0]), _finite(iv[1])],
                             "noise_interval": [_finite(ni[0]), _finite(ni[1])], "discretization_shift": _finite(d),
                             "at_bound": bool(b), "identified": bool(ok), "ambiguous": bool(amb),
                             "range": [p.low, p.high]}
        disc = self.discretization
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
            "discretization": None if disc is None else {
                "refined": list(disc.overrides), "kept": list(disc.kept), "misfit": _finite(disc.misfit),
                "error": disc.error or None, "order": disc.order, "factor": disc.factor,
                "reduction_ratio": _finite(disc.ratio), "refit": disc.refit,
                "linear_shift": None if disc.linear_shift is None else {
                    p.key: _finite(x * (p.high - p.low)) for p, x in zip(self.params, disc.linear_shift)},
                "no_interval": [] if disc.no_interval is None else [
                    p.key for p, x in zip(self.params, disc.no_interval) if x],
                "no_interval_reason": disc.no_interval_reason or None},
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


def _values(params, x) -> str:
    return ", ".join(f"{p.key}={v:.6g}" for p, v in zip(params, x))


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
    """Write evaluations.csv, the PNGs (``plot``) and fit.json (last, listing them) atomically; a
    Ctrl-C or SIGTERM meanwhile is acted on once fit.json is written (the estimates are kept)."""
    from ..atomic import signals_deferred

    with signals_deferred():
        return _write_files(res, plot)


def _write_files(res: FitResult, plot: bool) -> FitResult:
    import dataclasses
    from ..jsonio import as_text, dumps

    out = res.out_dir
    outputs = [str(write_text_atomic(out / "evaluations.csv", evaluations_csv(res)))]
    if plot:
        from ..plot.fit import fit_plot, landscape_plot

        if res.fitted is not None:
            outputs.append(str(fit_plot(out / "fit.png", res.data.t, res.data.values, res.fitted, res.data.names,
                                        res.misfit)))
        glob = [e for e in res.evaluations if e.stage == "global"]
        if glob:
            x = np.array([[q.value(v) for q, v in zip(res.params, e.u)] for e in glob])
            outputs.append(str(landscape_plot(out / "landscape.png", res.keys, x, np.array([e.misfit for e in glob]),
                                              res.estimate)))
    res = dataclasses.replace(res, outputs=tuple([str(out / "fit.json"), *outputs]))
    write_text_atomic(out / "fit.json", dumps(res.to_json(), as_text, indent=1) + "\n")
    return res
