"""The fit's problem: the varied keys and their ranges, the measurement and the runs' settings; one
run of the scene at a point of the box (on a worker)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..errors import IntegrationError, NsfemError
from ..measurement import (MISFITS, Measurement, check_measurement, is_uniform, match_sensors,
                           read_measurement, sample)
from ..scene.overrides import range_ends

#: keys the fit sets itself
FIT_KEYS = ("simulation.t_end", "simulation.output_dt")
#: data off the run's output grid: the runs output this many times per data step, and their signals are
#: interpolated by a cubic spline. Its error is at most 5/384 (omega h)^4 of a sinusoid's amplitude (h the
#: output step): 3e-4 at the data's Nyquist frequency (omega h = pi / 8), 1e-6 at a quarter of it, far
#: below RESOLUTION and any noise (linear interpolation at the data's own step: 5 % at 1 kHz sampling)
REFINE = 8
#: a data time within this fraction of an output step of an output time lies on the grid
ON_GRID = 1e-6
#: the most outputs of one run of a fit: every run holds q and v at each output (n reduced coordinates,
#: 100 or more), 1.6 GB per worker at 1e6 outputs of 100 dofs, and a fit makes 50 runs and more; 5e5 is
#: 500 s at the default output step of 1 ms (the scene's own limit, 1e7, is for one run)
MAX_OUTPUTS = 5e5


def output_step(t: np.ndarray, scene_dt: float) -> float:
    """The runs' ``output_dt`` for data at times ``t``: the smaller of the scene's and the data's smallest
    step, when every data time is a multiple of it (the outputs hold the data's times: exact), else
    the data's smallest step / :data:`REFINE` (or the scene's, if finer)."""
    step = float(np.min(np.diff(t)))
    dt = min(scene_dt, step)
    k = t / dt
    if np.all(np.abs(k - np.rint(k)) <= ON_GRID):
        return dt
    return min(scene_dt, step / REFINE)


def check_span(m: Measurement, dt: float, what: str) -> None:
    """Refuse data whose runs (from the scene's initial state at t = 0 to the last sample, an output
    every ``dt``) would write more than :data:`MAX_OUTPUTS` outputs, naming what sets the span: a
    record that starts late, or its length (too many rows for one run)."""
    outputs = m.t[-1] / dt
    if outputs <= MAX_OUTPUTS:
        return
    row = (lambda i: f"line {m.lines[i]}") if m.lines is not None else (lambda i: f"sample {i}")
    head = (f"{what}: column 't': the runs would simulate 0 to {m.t[-1]:g} s with an output every {dt:.3g} s "
            f"({outputs:.3g} outputs, more than the limit of {MAX_OUTPUTS:.0e} per run of a fit)")
    if m.t[0] >= m.t[-1] - m.t[0]:
        raise NsfemError(f"{head}: the record starts at t = {m.t[0]:g} s ({row(0)}) on the scene's clock, which "
                         "starts at 0 (the [initial] state); shift t, or start the scene where the record starts")
    raise NsfemError(f"{head}: {m.t.size} samples up to {row(m.t.size - 1)}; fit a shorter record")


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
        ends = range_ends("--vary", key, lo, hi)
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
    from ..simulate import run_scene, sensor_signals
    from ..sweep import _message

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

    @property
    def extent(self) -> tuple[float, float]:
        """(a, b): the shaft's ends, the first segment's start and the last one's end [m]."""
        segs = self.base.stack.segments
        return min(s.start for s in segs), max(s.end for s in segs)

    def scene(self, u, extra: Sequence[str] = ()):
        """The scene at ``u`` (unit box), with ``extra`` overrides after the fixed ones."""
        from ..scene import load_scene

        return load_scene(self.scene_path, [*self.fixed, *extra, *overrides_at(self.params, u)])


def _check_item(tree, key: str) -> None:
    """Refuse a varied ``key`` in an item of a list the scene does not have (:func:`~nsfem.scene.overrides.missing_item`)."""
    from ..scene.overrides import missing_item

    item = missing_item(tree, key)
    if item is not None:
        raise NsfemError(f"--vary {key}: the scene has no {item} (vary keys of items the scene has)")


def prepare(scene_path, data, vary, misfit: str = "time", overrides: Sequence[str] = ()) -> Problem:
    """Check every input (one-line errors, nothing run) and set up the problem."""
    from ..scene import load_scene
    from ..sweep import SHARED_TABLES

    if misfit not in MISFITS:
        raise NsfemError(f"--misfit must be {' or '.join(MISFITS)}, got {misfit!r}")
    params = parse_vary(vary)
    fixed = list(overrides)
    for o in fixed:
        key = o.partition("=")[0].strip()
        if any(p.key == key for p in params):
            raise NsfemError(f"{key}: both varied and fixed (drop its --set)")
    if isinstance(data, Measurement):
        m = check_measurement(data.t, dict(zip(data.names, data.values.T)), lines=data.lines)
    elif isinstance(data, (str, Path)):
        m = read_measurement(data)
    else:
        try:
            t, signals = data
        except (TypeError, ValueError):
            raise NsfemError("data: give a CSV path or (t, {sensor name: samples})") from None
        m = check_measurement(t, dict(signals))
    base = load_scene(scene_path, fixed)
    for p in params:
        _check_item(base, p.key)
    columns = match_sensors(m, base.sensors, f"--data {data}" if isinstance(data, (str, Path)) else "data")
    if misfit == "spectrum" and not is_uniform(m.t):
        raise NsfemError("--misfit spectrum: the data's t must be sampled at one step (an FFT needs it)")
    dt = output_step(m.t, base.simulation.output_dt)
    check_span(m, dt, f"--data {data}" if isinstance(data, (str, Path)) else "data")
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
